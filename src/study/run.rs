//! The series of renders: for every strategy, sample count and seed, one render compared with the
//! reference; and how a sample count maps onto the profile ([`configure`]).

use super::metrics::{efficiency, fit_loglog, mean_check, mean_check_f64, mse, relmse, LogLogFit};
use super::{Integral, IntegralSet};
use crate::film::Film;
use crate::render::{render_resumable, unit_count, RenderJob, RenderStats};
use crate::sample::Strategy;
use crate::scene::profile::MAX_LIGHT_SAMPLES;
use crate::scene::{Profile, Scene};
use crate::wavefront::Settings;
use glam::{DVec3, Vec3};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// The seed of the high-sample reference render: never one of the study's seeds `1..=K`, so the
/// reference's error is independent of every run's.
pub const REFERENCE_SEED: u64 = 0x7265_6665_7265_6e63;

/// Whether the sample count `n` is the light's (only `light` studied) or the camera's.
pub fn light_only(integrals: &IntegralSet) -> bool {
    integrals.contains(Integral::Light) && integrals.len() == 1
}

/// The profile of one run: `n` samples of the studied integrals with `strategy`.
///
/// - Only `light` studied: `light_samples = n` per shading point with `strategy`, and one camera path per
///   pixel through the pixel centre (pixel, lens, time, glossy, diffuse bounces and wavelength all held
///   at `center`), so the error measured is that of the light integral alone. Above 4096 (the profile's limit) `n` must be a
///   multiple of 4096 and is split into `n / 4096` camera passes of 4096 light samples (jittered and
///   Sobol passes are one stratified set of `n` up to 2^24, past which each pass is a set of its own, with
///   a warning; refused for `grid`, whose passes would repeat one grid).
/// - Otherwise: `spp = n` camera samples per pixel; every studied camera integral (pixel, lens, time,
///   glossy) uses `strategy`, the others are held at `center` (pixel centre, lens centre, mid-shutter,
///   the lobe's central direction). If `light` is studied too, the light uses `strategy` with the
///   profile's `light_samples` per shading point, or `n` of them with `light_from_spp`; if it is not
///   studied it is held at one `center` sample (the light's centre: hard shadows).
///
/// The wavelength (dispersion) and diffuse-bounce dimensions have no integral of their own in a study:
/// they follow the pixel integral (the studied strategy when `pixel` is studied, `center` otherwise).
/// They are always set here, never left at the base profile's value: a profile's `jittered` wavelength
/// under a `random` study would make `random` converge faster than independent samples can.
pub fn configure(base: &Profile, integrals: &IntegralSet, strategy: Strategy, n: u32, light_from_spp: bool) -> Result<Profile, String> {
    if n == 0 {
        return Err("sample counts must be at least 1".into());
    }
    let mut p = base.clone();
    let pick = |i: Integral| if integrals.contains(i) { strategy } else { Strategy::Center };
    if light_only(integrals) {
        let (passes, per_pass) = if n <= MAX_LIGHT_SAMPLES {
            (1, n)
        } else if strategy == Strategy::Grid {
            return Err(format!(
                "{n} light samples: a grid of the light integral has at most {MAX_LIGHT_SAMPLES} points (more would repeat the same grid pass after pass)"
            ));
        } else if n.is_multiple_of(MAX_LIGHT_SAMPLES) {
            (n / MAX_LIGHT_SAMPLES, MAX_LIGHT_SAMPLES)
        } else {
            return Err(format!(
                "{n} light samples: counts of the light integral above {MAX_LIGHT_SAMPLES} must be multiples of {MAX_LIGHT_SAMPLES}"
            ));
        };
        p.spp = passes;
        p.light_samples = per_pass;
        p.light_strategy = strategy;
        p.pixel_strategy = Strategy::Center;
        p.lens_strategy = Strategy::Center;
        p.time_strategy = Strategy::Center;
        p.glossy_strategy = Strategy::Center;
        p.diffuse_strategy = Strategy::Center;
        p.wavelength_strategy = Strategy::Center;
    } else {
        p.spp = n;
        p.pixel_strategy = pick(Integral::Pixel);
        p.lens_strategy = pick(Integral::Lens);
        p.time_strategy = pick(Integral::Time);
        p.glossy_strategy = pick(Integral::Glossy);
        p.diffuse_strategy = pick(Integral::Pixel);
        p.wavelength_strategy = pick(Integral::Pixel);
        if integrals.contains(Integral::Light) {
            p.light_strategy = strategy;
            if light_from_spp {
                if n > MAX_LIGHT_SAMPLES {
                    return Err(format!("--light-samples-from-spp: {n} light samples exceed the limit of {MAX_LIGHT_SAMPLES}"));
                }
                p.light_samples = n;
            }
        } else {
            p.light_strategy = Strategy::Center;
            p.light_samples = 1;
        }
    }
    p.name = format!("{} ({strategy} x {n})", base.name);
    p.validate().map_err(|(f, m)| format!("{f}: {m}"))?;
    Ok(p)
}

/// The profile fields [`configure`] sets for every run of a study of `integrals` (so a `--set` of one
/// would change nothing), each with what sets it.
pub fn fields_set_by_study(integrals: &IntegralSet, light_from_spp: bool) -> Vec<(&'static str, &'static str)> {
    let strategies = "--strategies for the studied integrals, `center` for the others";
    let mut out = vec![("spp", "the counts of --spp"), ("strategy", strategies)];
    for f in
        ["pixel_strategy", "lens_strategy", "time_strategy", "glossy_strategy", "diffuse_strategy", "wavelength_strategy", "light_strategy"]
    {
        out.push((f, strategies));
    }
    if light_only(integrals) {
        out[0].1 = "the passes of the light counts of --spp";
        out.push(("light_samples", "the light counts of --spp"));
    } else if light_from_spp {
        out.push(("light_samples", "--light-samples-from-spp: the counts of --spp"));
    } else if !integrals.contains(Integral::Light) {
        out.push(("light_samples", "1: the light integral is not studied"));
    }
    out
}

/// One render of the series.
#[derive(Clone, Debug, PartialEq)]
pub struct RunResult {
    pub strategy: Strategy,
    /// Samples of the studied integral (the `spp` column).
    pub n: u32,
    pub seed: u64,
    /// The profile's camera samples per pixel and light samples per shading point for this run.
    pub camera_spp: u32,
    pub light_samples: u32,
    /// Wall seconds of the render (the renderer's own `RenderStats.seconds`) and of its light selection
    /// (`selection_seconds`: the power table or light tree it makes first).
    pub seconds: f64,
    pub rays: u64,
    pub mse: f64,
    pub relmse: f64,
    pub efficiency: f64,
    /// The image's mean over the reference's, and the z-score of their difference
    /// ([`mean_check`]): a bias check that the MSE does not make.
    pub mean_ratio: f64,
    pub mean_z: f64,
}

/// What a series runs over.
#[derive(Clone, Debug)]
pub struct Plan {
    pub integrals: IntegralSet,
    pub strategies: Vec<Strategy>,
    pub counts: Vec<u32>,
    /// Seeds `1..=seeds`.
    pub seeds: u32,
    pub light_from_spp: bool,
    pub threads: usize,
    /// Set (by Ctrl-C) to stop: the render in flight is abandoned and the series ends with the runs
    /// finished so far ([`Series::interrupted`]).
    pub cancel: Option<Arc<AtomicBool>>,
}

impl Plan {
    /// Whether the plan's cancel flag is set.
    pub fn cancelled(&self) -> bool {
        self.cancel.as_ref().is_some_and(|c| c.load(Ordering::SeqCst))
    }
}

/// The results of a series, and the first seed's image of every (strategy, count) for the sheet.
pub struct Series {
    pub runs: Vec<RunResult>,
    pub images: Vec<(Strategy, u32, Vec<Vec3>)>,
    /// The series was cancelled: `runs` holds only the runs that finished (an unfinished render is
    /// dropped, never measured).
    pub interrupted: bool,
    /// Per (strategy, count): the bias check of the mean of its seeds' images.
    pub rows: Vec<RowCheck>,
}

/// The bias check of one (strategy, count): [`mean_check_f64`] of the mean of its seeds' images. (Not
/// a combination of the runs' own z-scores: the seeds share one reference, whose noise is in every
/// run's difference, so Stouffer's `sum z / sqrt(k)` grew with the seeds (a user trial's 1,000 unbiased
/// seeds read -6.1, caustics' skewed errors -6.4), and their mean would not grow with a real bias.)
#[derive(Clone, Debug, PartialEq)]
pub struct RowCheck {
    pub strategy: Strategy,
    pub n: u32,
    pub mean_ratio: f64,
    pub mean_z: f64,
}

impl RowCheck {
    /// The check of the mean of `count` images summed in `sum`.
    fn of(strategy: Strategy, n: u32, sum: &[DVec3], count: usize, reference: &[DVec3]) -> RowCheck {
        let mean: Vec<DVec3> = sum.iter().map(|s| *s / count as f64).collect();
        let (mean_ratio, mean_z) = mean_check_f64(&mean, reference);
        RowCheck { strategy, n, mean_ratio, mean_z }
    }
}

/// Render one image with `profile` and `seed`; returns the linear image, seconds and rays.
pub fn render_once(scene: &Scene, profile: Profile, seed: u64, threads: usize) -> (Film, f64, u64) {
    render_cancellable(scene, profile, seed, threads, None, None)
        .unwrap_or_else(|e| panic!("{e}"))
        .expect("a render without a cancel flag completes")
}

/// [`render_once`] that stops when `cancel` is set: None if the render did not complete; an error where a
/// pass outgrew its ray limit (the same settings would at every seed: nothing can be measured).
pub fn render_cancellable(
    scene: &Scene,
    profile: Profile,
    seed: u64,
    threads: usize,
    cancel: Option<&AtomicBool>,
    progress: Option<&(dyn Fn(usize, usize) + Sync)>,
) -> Result<Option<(Film, f64, u64)>, String> {
    let mut job = RenderJob::new(scene, Settings { profile, seed });
    job.threads = threads;
    job.cancel = cancel;
    job.progress = progress;
    let n = unit_count(scene.width, scene.height, job.tile, job.samples.clone());
    let (film, _, stats) = render_units(&job, Film::new(scene.width, scene.height), vec![false; n])?;
    Ok(stats.completed.then_some((film, stats.seconds + stats.selection_seconds, stats.rays.total)))
}

/// The study's render of `job`'s work units not flagged in `completed` into `film` (which holds the
/// flagged ones): the film, the flags after it and its statistics; an error where a pass outgrew its ray
/// limit. A completed render's discarded samples, lost media and dimness are warned of.
pub fn render_units(job: &RenderJob, film: Film, completed: Vec<bool>) -> Result<(Film, Vec<bool>, RenderStats), String> {
    let scene = job.scene;
    let (film, completed, stats) = render_resumable(job, film, completed);
    if stats.overflow {
        return Err(crate::render::overflow_message(job));
    }
    if !stats.completed {
        return Ok((film, completed, stats));
    }
    // (Discarded samples would bias every error measured from this image.)
    crate::film::warn_discarded(stats.nonfinite_samples);
    crate::film::warn_lost_media(stats.lost_media);
    // (Once per study: every run of a dim scene is as dim.)
    static DIM_WARNED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);
    if let Some(w) = crate::film::dim_warning(&film, scene.has_light()) {
        if !DIM_WARNED.swap(true, std::sync::atomic::Ordering::Relaxed) {
            errln!("warning: {w}");
        }
    }
    // (The light selection, a power table or a light tree, is made for each render before its clock:
    // a cost of the run all the same, which a study of selection modes must weigh.)
    Ok((film, completed, stats))
}

/// Run the whole series against `reference`. `report` is called after each run (progress output). If
/// the plan's cancel flag is set the series stops and returns the finished runs, `interrupted` set.
pub fn run_series(
    scene: &Scene,
    base: &Profile,
    plan: &Plan,
    reference: &[DVec3],
    keep_images: bool,
    report: &mut dyn FnMut(&RunResult),
) -> Result<Series, String> {
    let mut runs = Vec::new();
    let mut images = Vec::new();
    let mut rows = Vec::new();
    // One unmeasured render first: the first render of a process pays for page faults and cold caches,
    // which would otherwise be charged to the first run's seconds.
    let cancel = plan.cancel.as_deref();
    if let (Some(&s), Some(&n)) = (plan.strategies.first(), plan.counts.first()) {
        render_cancellable(scene, configure(base, &plan.integrals, s, n, plan.light_from_spp)?, 0, plan.threads, cancel, None)?;
    }
    for &strategy in &plan.strategies {
        for &n in &plan.counts {
            let profile = configure(base, &plan.integrals, strategy, n, plan.light_from_spp)?;
            let mut sum = vec![DVec3::ZERO; reference.len()];
            for seed in 1..=plan.seeds as u64 {
                let done =
                    if plan.cancelled() { None } else { render_cancellable(scene, profile.clone(), seed, plan.threads, cancel, None)? };
                let Some((film, seconds, rays)) = done else {
                    if seed > 1 {
                        rows.push(RowCheck::of(strategy, n, &sum, seed as usize - 1, reference));
                    }
                    return Ok(Series { runs, images, interrupted: true, rows });
                };
                let img = film.to_rgb();
                for (s, x) in sum.iter_mut().zip(&img) {
                    *s += x.as_dvec3();
                }
                let e = mse(&img, reference);
                let (mean_ratio, mean_z) = mean_check(&img, reference);
                let r = RunResult {
                    strategy,
                    n,
                    seed,
                    camera_spp: profile.spp,
                    light_samples: profile.light_samples,
                    seconds,
                    rays,
                    mse: e,
                    relmse: relmse(&img, reference),
                    efficiency: efficiency(e, seconds),
                    mean_ratio,
                    mean_z,
                };
                report(&r);
                runs.push(r);
                if keep_images && seed == 1 {
                    images.push((strategy, n, img));
                }
            }
            rows.push(RowCheck::of(strategy, n, &sum, plan.seeds as usize, reference));
        }
    }
    Ok(Series { runs, images, interrupted: false, rows })
}

/// The runs of one (strategy, count) averaged over seeds.
#[derive(Clone, Debug, PartialEq)]
pub struct Summary {
    pub strategy: Strategy,
    pub n: u32,
    pub seeds: usize,
    pub seconds: f64,
    pub rays: f64,
    pub mse: f64,
    pub relmse: f64,
    /// `1 / (mean MSE x mean seconds)`.
    pub efficiency: f64,
    /// The bias check of the mean of the seeds' images ([`RowCheck`]; NaN where no check was given).
    pub mean_ratio: f64,
    pub mean_z: f64,
}

/// Where `|z|` of a row's image mean against the reference's passes this, the table marks the row: a
/// bias in the renders or in the reference rather than noise (about 6e-7 of unbiased rows).
pub const BIAS_Z: f64 = 5.0;

impl Summary {
    /// Whether the image mean differs from the reference's by more than noise explains ([`BIAS_Z`]).
    pub fn biased(&self) -> bool {
        self.mean_z.abs() > BIAS_Z
    }
}

/// Average the runs over seeds, in the order the (strategy, count) pairs first appear, with each pair's
/// bias check from `rows`.
pub fn summarize(runs: &[RunResult], rows: &[RowCheck]) -> Vec<Summary> {
    let mut keys: Vec<(Strategy, u32)> = Vec::new();
    for r in runs {
        if !keys.contains(&(r.strategy, r.n)) {
            keys.push((r.strategy, r.n));
        }
    }
    keys.into_iter()
        .map(|(strategy, n)| {
            let g: Vec<&RunResult> = runs.iter().filter(|r| r.strategy == strategy && r.n == n).collect();
            let k = g.len() as f64;
            let mean = |f: &dyn Fn(&RunResult) -> f64| g.iter().map(|r| f(r)).sum::<f64>() / k;
            let (seconds, e) = (mean(&|r| r.seconds), mean(&|r| r.mse));
            let check = rows.iter().find(|c| c.strategy == strategy && c.n == n);
            Summary {
                strategy,
                n,
                seeds: g.len(),
                seconds,
                rays: mean(&|r| r.rays as f64),
                mse: e,
                relmse: mean(&|r| r.relmse),
                efficiency: efficiency(e, seconds),
                mean_ratio: check.map_or(f64::NAN, |c| c.mean_ratio),
                mean_z: check.map_or(f64::NAN, |c| c.mean_z),
            }
        })
        .collect()
}

/// Fewest sample counts for a slope against seconds.
pub const TIME_SLOPE_MIN_COUNTS: usize = 3;
/// Least ratio of the slowest to the fastest mean time for a slope against seconds.
pub const TIME_SLOPE_MIN_SPAN: f64 = 4.0;
/// Least log-log slope of seconds against samples for a slope against seconds.
pub const TIME_SLOPE_MIN_GROWTH: f64 = 0.5;

/// Fitted slopes of one strategy's mean MSE against samples and against seconds.
///
/// The slope against seconds is None unless [`time_slope_meaningful`]: wall time is noisy (thread
/// start-up, a shared machine), and where it barely grows with the samples that noise and fixed costs,
/// not the cost of samples, set the slope (a 48 x 32 image renders 1 and 256 samples in about 4 ms).
pub fn slopes(summary: &[Summary], strategy: Strategy) -> (Option<LogLogFit>, Option<LogLogFit>) {
    let s: Vec<&Summary> = summary.iter().filter(|s| s.strategy == strategy).collect();
    let vs_n: Vec<(f64, f64)> = s.iter().map(|s| (s.n as f64, s.mse)).collect();
    let vs_t: Vec<(f64, f64)> = s.iter().map(|s| (s.seconds, s.mse)).collect();
    let t_vs_n: Vec<(f64, f64)> = s.iter().map(|s| (s.n as f64, s.seconds)).collect();
    (fit_loglog(&vs_n), if time_slope_meaningful(&t_vs_n) { fit_loglog(&vs_t) } else { None })
}

/// Whether the (samples, mean seconds) of one strategy's counts support a slope of MSE against seconds:
/// at least [`TIME_SLOPE_MIN_COUNTS`] counts, the times spanning a factor [`TIME_SLOPE_MIN_SPAN`], and
/// growing at least as `n^`[`TIME_SLOPE_MIN_GROWTH`] (fitted).
pub fn time_slope_meaningful(points: &[(f64, f64)]) -> bool {
    let t: Vec<f64> = points.iter().map(|p| p.1).filter(|t| t.is_finite() && *t > 0.0).collect();
    let (lo, hi) = t.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &t| (lo.min(t), hi.max(t)));
    t.len() >= TIME_SLOPE_MIN_COUNTS
        && t.len() == points.len()
        && hi >= TIME_SLOPE_MIN_SPAN * lo
        && fit_loglog(points).is_some_and(|f| f.slope >= TIME_SLOPE_MIN_GROWTH)
}
