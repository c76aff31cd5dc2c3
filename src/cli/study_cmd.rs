//! `strata study`: the speed/accuracy trade of sampling strategies, measured against a reference.

use super::Failure;
use crate::sample::Strategy;
use crate::scene::{load_scene_sized, Profile, Scene, MAX_LIGHT_SAMPLES};
use crate::study::reference::{obtain, reference_profile, RefError, ReferenceSource};
use crate::study::run::{
    configure, light_only, run_series, slopes, summarize, Plan, RunResult, Summary, BIAS_Z, TIME_SLOPE_MIN_COUNTS, TIME_SLOPE_MIN_GROWTH,
    TIME_SLOPE_MIN_SPAN,
};
use crate::study::{csv, plot, sheet, Integral, IntegralSet};
use clap::Args;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// A `--reference-spp` below this multiple of the largest count is warned about.
pub const REFERENCE_MIN_FACTOR: u32 = 4;

const MAPPING_HELP: &str = "\
How the sample counts (--spp) map onto the integrals (--integrals):
  * `light` alone: n = light samples per shading point with the strategy, and one camera path per pixel
    through the pixel centre (pixel, lens, time, glossy, diffuse bounces and wavelength held at `center`):
    the error measured is that of the light integral alone. Counts above 4096 must be multiples of 4096
    (4096 per camera pass), and are refused for `grid` (each pass would repeat the same grid).
  * anything else: n = camera samples per pixel (spp). Each studied camera integral (pixel, lens, time,
    glossy) uses the strategy; the others are held at `center` (pixel centre, lens centre, mid-shutter,
    the lobe's central direction). A studied `light` uses the strategy with the profile's light_samples
    per shading point (n of them with --light-samples-from-spp); an unstudied light is held at one sample
    at its centre (hard shadows).
  * The wavelength (dispersion) and diffuse-bounce dimensions follow the pixel integral: the strategy
    when `pixel` is studied, `center` otherwise (never the profile's own strategies).
The reference is the converged value of that same estimator: --reference-spp N renders it once with the
jittered strategy and N samples under the same mapping (seed distinct from the study's seeds 1..K) and
caches it in DIR, keyed by the scene file's hash, the full reference profile and N (default N: 16 x the
largest count; a warning below 4 x, where the reference's own noise is a large part of what is measured).
With --light-samples-from-spp the reference takes N spp x (largest count) light samples, so it has N /
(largest count) times the largest run's light samples too. --reference analytic computes the reference
exactly for a Lambert plane under one quad light (at pixel centres with --integrals light).

Progress: a line per 10% of a rendered reference and per finished run on stderr (--quiet: none). Ctrl-C
stops the study: study.csv is written with the runs that finished (the run in flight is dropped), and the
exit code is 130; during the reference, its finished work units are kept in DIR/reference-<key>.film and
the same study run again continues them. A reference file is checked against the runs' estimator (its
EXR records the filter, depths and integrals it was rendered with): a difference is warned of.

Outputs in DIR: study.csv (one row per render: strategy,spp,seed,seconds,rays,mse,relmse,efficiency,
camera_spp,light_samples,mean_ratio,mean_z), study.png (log-log MSE vs samples and vs seconds, mean
over seeds, fitted slopes in the legend; the slope against seconds only for 3+ counts whose times span
4x and grow at least as n^0.5, else n/a), sheet.png with --sheet. relMSE = mean (x - ref)^2 / (ref^2 +
0.01) per channel; efficiency = 1 / (MSE x seconds), seconds being the render's own wall time and its
light selection's build. mean/ref = the image's mean over the reference's; z = their difference over
its standard error (from the pixels' spread), both of the mean of the seeds' images: rows past |z| > 5
are marked ! as biased (the render's or the reference's), which the MSE alone does not show; a bias that
changes sign across the image and averages out shows in the MSE's slope instead.";

#[derive(Args, Debug, Clone)]
#[command(after_long_help = MAPPING_HELP)]
pub struct StudyArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Base quality profile: a shipped name (preview, final, reference, bench, light1, light9, light36, light100, caustic) or a path.
    #[arg(long, default_value = "preview")]
    pub profile: String,
    /// Override a profile field of the base profile: --set key=value (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Strategies to compare, comma-separated: center, grid, random, jittered, sobol.
    #[arg(long, default_value = "random,jittered")]
    pub strategies: String,
    /// Sample counts, comma-separated (see --help for what a count means for each integral).
    #[arg(long, allow_negative_numbers = true, default_value = "1,4,16,64")]
    pub spp: String,
    /// Integrals to sample with the strategy: pixel, light, lens, time, glossy (comma-separated), or all.
    #[arg(long, default_value = "all")]
    pub integrals: String,
    /// Independent seeds (1..=K) per strategy and count; the error is averaged over them.
    #[arg(long, allow_negative_numbers = true, default_value_t = 4, value_parser = super::range_parser::<u32>("seeds", 1, 1000))]
    pub seeds: u32,
    /// Reference: a linear EXR of the scene's size, or `analytic` (Lambert plane under one quad light).
    #[arg(long, value_name = "FILE.exr|analytic", conflicts_with = "reference_spp")]
    pub reference: Option<String>,
    /// Render the reference with N jittered samples (cached in the output directory).
    #[arg(long, allow_negative_numbers = true, value_name = "N")]
    pub reference_spp: Option<u32>,
    /// Output directory (created if missing).
    #[arg(long, default_value = "study")]
    pub out: PathBuf,
    /// Also write sheet.png: the renders side by side, a row per strategy, a column per count.
    #[arg(long)]
    pub sheet: bool,
    /// Worker threads (default: all cores).
    #[arg(long, allow_negative_numbers = true, default_value_t = 0, value_parser = super::range_parser::<usize>("threads", 0, super::MAX_THREADS))]
    pub threads: usize,
    /// Image size WxH instead of the scene's (the camera keeps its fov), as `render --size`.
    #[arg(long, allow_hyphen_values = true, value_name = "WxH")]
    pub size: Option<String>,
    /// With `light` among several integrals: n light samples per shading point as well as n spp.
    #[arg(long)]
    pub light_samples_from_spp: bool,
    /// No progress lines on stderr (warnings and errors are still printed).
    #[arg(long, short)]
    pub quiet: bool,
}

/// Parse a comma-separated list with `parse`; empty items are ignored, an empty list is an error.
/// A comma-separated list: no empty item (`1,,4`), no item twice (`4,4`: a silent merge would run
/// fewer series than asked for).
fn parse_list<T: PartialEq>(flag: &str, text: &str, parse: impl Fn(&str) -> Result<T, String>) -> Result<Vec<T>, Failure> {
    if text.split(',').all(|i| i.trim().is_empty()) {
        return Err(Failure::input(format!("{flag}: the list is empty")));
    }
    let mut out: Vec<T> = Vec::new();
    for item in text.split(',').map(str::trim) {
        if item.is_empty() {
            return Err(Failure::input(format!("{flag} {text}: an empty item")));
        }
        let v = parse(item).map_err(|e| Failure::input(format!("{flag}: {e}")))?;
        if out.contains(&v) {
            return Err(Failure::input(format!("{flag} {text}: `{item}` is listed twice")));
        }
        out.push(v);
    }
    Ok(out)
}

fn parse_strategy(s: &str) -> Result<Strategy, String> {
    Strategy::parse_or_explain(s)
}

/// A count of `--spp`, at most `max` (`what` names its unit: camera samples per pixel, or light samples
/// per shading point where the light integral is studied alone). (Other limits of an integral, such as
/// a light grid's, are checked with the plan, which knows what a count means.)
fn parse_count(s: &str, max: u32, what: &str) -> Result<u32, String> {
    match crate::scene::profile::parse_count(s, max) {
        Ok(0) => Err(format!("`{s}` is not a sample count (an integer >= 1)")),
        Ok(n) if n > max => Err(format!("sample count `{s}` is too large (at most {max} {what})")),
        Ok(n) => Ok(n),
        Err(_) if s.trim().parse::<f64>().is_ok_and(|x| x > u32::MAX as f64) => {
            Err(format!("sample count `{s}` is too large (at most {max} {what})"))
        }
        Err(e) => Err(format!("sample count {e}")),
    }
}

/// Everything a study needs, validated before any rendering.
struct Setup {
    scene: Scene,
    profile: Profile,
    plan: Plan,
    source: ReferenceSource,
}

fn setup(a: &StudyArgs) -> Result<Setup, Failure> {
    let size = a.size.as_deref().map(super::render_cmd::parse_size).transpose()?;
    let scene = load_scene_sized(&a.scene, size).map_err(Failure::input)?;
    let profile = super::load_profile(&a.profile, |_| Vec::new(), &a.set)?;
    for w in &scene.warnings {
        errln!("warning: {w}");
    }
    let strategies = parse_list("--strategies", &a.strategies, parse_strategy)?;
    let integrals = if a.integrals.trim().eq_ignore_ascii_case("all") {
        IntegralSet::all()
    } else {
        let list = parse_list("--integrals", &a.integrals, |i| {
            if i.eq_ignore_ascii_case("all") {
                return Err("`all` (every integral) stands alone, not in a list".to_string());
            }
            crate::study::Integral::parse_or_explain(i)
        })?;
        IntegralSet::of(&list)
    };
    // n counts camera samples per pixel, or light samples per shading point with the light integral
    // alone (taken in passes of MAX_LIGHT_SAMPLES, up to MAX_SPP passes: beyond u32), or both under
    // --light-samples-from-spp (at most MAX_LIGHT_SAMPLES).
    let (max, what) = if light_only(&integrals) {
        (u32::MAX / MAX_LIGHT_SAMPLES * MAX_LIGHT_SAMPLES, "light samples per shading point, in multiples of 4096 above 4096")
    } else if a.light_samples_from_spp {
        (MAX_LIGHT_SAMPLES, "with --light-samples-from-spp, where n is also the light samples")
    } else {
        (crate::scene::MAX_SPP, "camera samples per pixel")
    };
    let mut counts = parse_list("--spp", &a.spp, |c| parse_count(c, max, what))?;
    counts.sort_unstable();
    if a.light_samples_from_spp && (!integrals.contains(Integral::Light) || light_only(&integrals)) {
        return Err(Failure::input(format!(
            "--light-samples-from-spp needs `light` among several studied integrals (--integrals {}): {}",
            integrals.names(),
            if light_only(&integrals) { "with `light` alone the count already is light samples" } else { "the light is not studied" }
        )));
    }
    // A `--set` of a field every run sets would be silently dropped.
    let studied = crate::study::run::fields_set_by_study(&integrals, a.light_samples_from_spp);
    for kv in &a.set {
        let key = kv.split('=').next().unwrap_or("").trim();
        if let Some((_, by)) = studied.iter().find(|(f, _)| *f == key) {
            return Err(Failure::input(format!(
                "--set {kv}: `strata study` sets {key} itself for each run ({by}), so this would change nothing"
            )));
        }
    }
    // One light is picked per camera path: with `light` alone (one path per pixel) every one of a pixel's
    // n light samples goes to the one light it picked, and no count converges.
    if light_only(&integrals) && profile.light_selection != crate::scene::LightSelection::All && scene.lights.len() > 1 {
        return Err(Failure::input(format!(
            "--integrals light with light_selection `{}`: a shading point picks one light per camera path, and the light \
             study traces one path per pixel, so all n light samples of a pixel go to the one light it picked and the \
             error cannot fall with n; study `light` with `pixel` (n = camera samples, each with its own pick), or \
             light_selection = \"all\"",
            profile.light_selection.name()
        )));
    }
    // (Before the runs' warnings: a study of nothing the scene uses is refused, and its runs not warned of.)
    let unused = unused_integrals(&scene, &integrals);
    if unused.len() == integrals.len() {
        return Err(Failure::input(format!(
            "{}: the scene does not exercise {} (no {}): every run would render the same image; study another integral",
            a.scene.display(),
            unused.join(", "),
            integrals.iter().map(|i| exercised(&scene, i).1).collect::<Vec<_>>().join(", ")
        )));
    }
    // The runs' sampling warnings, as `render` gives them, each once with the first run it concerns.
    let mut warned: Vec<(String, String, Strategy)> = Vec::new();
    for &s in &strategies {
        for &n in &counts {
            let p = configure(&profile, &integrals, s, n, a.light_samples_from_spp).map_err(|e| Failure::input(format!("--spp: {e}")))?;
            crate::render::check_render_size(scene.width, scene.height, &(0..p.spp))
                .map_err(|e| Failure::input(format!("--spp {n}: {e}")))?;
            let identical = super::render_cmd::identical_samples_warning(&scene, &p);
            for w in super::render_cmd::sampling_warnings(&scene, &p).into_iter().chain(identical) {
                if !warned.iter().any(|(_, seen, _)| *seen == w) {
                    warned.push((format!("warning: {} n = {n}: {w}", s.name()), w, s));
                }
            }
        }
    }
    let largest = *counts.last().expect("non-empty");
    let source = match (&a.reference, a.reference_spp) {
        (Some(r), _) if r.eq_ignore_ascii_case("analytic") => ReferenceSource::Analytic,
        (Some(r), _) => ReferenceSource::File(PathBuf::from(r)),
        (None, Some(0)) => return Err(Failure::input("--reference-spp must be at least 1")),
        (None, Some(n)) => ReferenceSource::Samples(n),
        (None, None) => {
            // (16 x a count beyond 2^28 passes u32: refused here, in u64, rather than saturated to a
            // count that is neither 16 x nor, for the light, a multiple of 4096.)
            let wanted = 16 * largest as u64;
            if wanted > u32::MAX as u64 {
                return Err(Failure::input(format!(
                    "the default reference (16 x the largest count {largest} = {wanted} samples) is more than {} samples: give a \
                     smaller --reference-spp, or a reference image with --reference FILE.exr",
                    u32::MAX
                )));
            }
            let mut n = largest.saturating_mul(16);
            if light_only(&integrals) && n > 4096 {
                n = n.div_ceil(4096).saturating_mul(4096);
            }
            ReferenceSource::Samples(n)
        }
    };
    let plan =
        Plan { integrals, strategies, counts, seeds: a.seeds, light_from_spp: a.light_samples_from_spp, threads: a.threads, cancel: None };
    if a.sheet {
        crate::study::sheet::check_size(scene.width, scene.height, plan.strategies.len(), plan.counts.len()).map_err(Failure::input)?;
    }
    // The reference's own profile, checked before any run (the default's count is 16 x the largest).
    if let ReferenceSource::Samples(n) = source {
        if let Err(e) = reference_profile(&profile, &plan, n) {
            return Err(Failure::input(if a.reference_spp.is_some() {
                format!("--reference-spp: {e}")
            } else {
                format!(
                    "the default reference ({n} samples, 16 x the largest count {largest}{}) is beyond the profile's limits ({e}): \
                     give a smaller --reference-spp, or a reference image with --reference FILE.exr",
                    if light_only(&plan.integrals) && n != largest.saturating_mul(16) { ", rounded up to a multiple of 4096" } else { "" }
                )
            }));
        }
    }
    // (Printed once nothing is refused: a refused study is not also warned of.)
    // (The first 4 of each strategy, then how many more: a study of thousands of counts printed a
    // warning or two for each.)
    const SHOWN: usize = 4;
    for &s in &plan.strategies {
        let of: Vec<&String> = warned.iter().filter(|(_, _, by)| *by == s).map(|(line, _, _)| line).collect();
        for line in of.iter().take(SHOWN) {
            errln!("{line}");
        }
        if of.len() > SHOWN {
            errln!("warning: and {} more sampling warnings of the `{}` runs at other counts", of.len() - SHOWN, s.name());
        }
    }
    if let Some(l) = fixed_light_grid(&scene, &profile, &plan) {
        errln!(
            "warning: the `grid` runs take the same {l} light point{} of each light at every camera sample (light_samples {l}), so \
             their light integral does not converge as n grows: their error levels off at the bias of {l} point light{} against the \
             reference (a slope near 0, marked below). --light-samples-from-spp makes n the light samples (a grid of n points), \
             and --integrals light studies the light grid alone",
            if l == 1 { "" } else { "s" },
            if l == 1 { "" } else { "s" }
        );
    }
    Ok(Setup { scene, profile, plan, source })
}

/// The light samples per shading point when the study's `grid` runs hold the light integral at a fixed
/// grid (the light studied with other integrals, its count not following n, area lights present):
/// those runs converge to the grid's points as lights, not to the reference.
fn fixed_light_grid(scene: &Scene, profile: &Profile, plan: &Plan) -> Option<u32> {
    let fixed = plan.integrals.contains(Integral::Light) && !light_only(&plan.integrals) && !plan.light_from_spp;
    (fixed && scene.features.area_lights && plan.strategies.contains(&Strategy::Grid)).then_some(profile.light_samples)
}

/// Integrals the scene does not exercise (their strategy changes nothing).
fn unused_integrals(scene: &Scene, integrals: &IntegralSet) -> Vec<&'static str> {
    integrals.iter().filter(|&i| !exercised(scene, i).0).map(|i| i.name()).collect()
}

/// Whether the scene exercises integral `i`, and what it needs to (its features: a glossy material
/// defined but on no surface exercises nothing).
fn exercised(scene: &Scene, i: crate::study::Integral) -> (bool, &'static str) {
    use crate::study::Integral as I;
    let f = &scene.features;
    match i {
        I::Lens => (f.lens, "camera aperture"),
        // (A zero-length shutter with moving shapes renders them at one instant: nothing to integrate.)
        I::Time if scene.motion_at_one_instant() => (false, "shutter of non-zero length"),
        I::Time => (f.motion, "moving shapes"),
        I::Glossy => (f.glossy, "glossy surface"),
        I::Light => (f.area_lights, "area light"),
        I::Pixel => (true, "pixels"),
    }
}

/// The warning for a rendered reference of `n` samples when the largest count is `largest`: None if
/// `n >= REFERENCE_MIN_FACTOR x largest`.
///
/// The measured MSE is the run's error plus the reference's own variance; for independent samples the
/// latter is `largest / n` of the largest run's error (1/16 at the default), so a small `n` measures the
/// reference as much as the runs.
pub fn reference_warning(n: u32, largest: u32) -> Option<String> {
    if n as u64 >= REFERENCE_MIN_FACTOR as u64 * largest as u64 {
        return None;
    }
    Some(format!(
        "warning: --reference-spp {n} is less than {REFERENCE_MIN_FACTOR} x the largest count {largest}: the reference's own noise \
         (about {largest}/{n} of the largest run's MSE with independent samples) is measured with the runs' error; \
         use at least {} (the default is {})",
        REFERENCE_MIN_FACTOR as u64 * largest as u64,
        16 * largest as u64
    ))
}

fn describe_mapping(plan: &Plan) -> String {
    if light_only(&plan.integrals) {
        "n = light samples per shading point; one camera path through each pixel centre".into()
    } else {
        let light = if !plan.integrals.contains(crate::study::Integral::Light) {
            "light held at its centre"
        } else if plan.light_from_spp {
            "n light samples per shading point"
        } else {
            "the profile's light samples per shading point"
        };
        format!("n = camera samples per pixel; studied: {}; {light}", plan.integrals.names())
    }
}

pub fn run(a: StudyArgs) -> Result<u8, Failure> {
    let Setup { scene, profile, mut plan, source } = setup(&a)?;
    if let ReferenceSource::Samples(n) = source {
        if let Some(w) = reference_warning(n, *plan.counts.last().expect("non-empty")) {
            errln!("{w}");
        }
    }
    let cancel = Arc::new(AtomicBool::new(false));
    {
        let c = cancel.clone();
        // A second Ctrl-C while stopping exits at once (one within the render's debounce is the same
        // interrupt delivered twice, as GNU `timeout` does).
        let first = std::sync::OnceLock::new();
        super::on_signal(move || {
            if !c.swap(true, Ordering::SeqCst) {
                let _ = first.set(std::time::Instant::now());
            } else if first.get().is_none_or(|t: &std::time::Instant| t.elapsed() >= super::render_cmd::DEBOUNCE) {
                std::process::exit(130);
            }
        });
    }
    plan.cancel = Some(cancel);
    let unused = unused_integrals(&scene, &plan.integrals);
    if !unused.is_empty() {
        errln!("note: the scene does not exercise {} (their strategy changes nothing)", unused.join(", "));
    }
    let created = !a.out.exists();
    std::fs::create_dir_all(&a.out).map_err(|e| Failure::input(format!("--out {}: cannot create: {e}", a.out.display())))?;
    outln!("strata study: {}  {}x{}  profile {}", a.scene.display(), scene.width, scene.height, profile.name);
    // (The pick of `light_selection` is a light integral of its own: jittered across the pixel's
    // samples unless the light strategy is random or sobol, even where the light is held at its centre.)
    let pick = match profile.light_selection {
        crate::scene::LightSelection::All => String::new(),
        _ if scene.lights.len() <= 1 => String::new(),
        sel => format!("; 1 of {} lights picked per shading point ({})", scene.lights.len(), sel.name()),
    };
    outln!("  sampling: {}{pick}", describe_mapping(&plan));
    if !a.quiet {
        errln!("  reference: preparing...");
    }
    // (A line per 10% of the rendered reference's work units, as `render` prints: it can take minutes.)
    // (Made at the first report: a file, analytic or cached reference shows no bar.)
    let progress = std::sync::OnceLock::new();
    let report =
        |done: usize, total: usize| progress.get_or_init(|| super::Progress::new("  reference", a.quiet, total, 0)).update(done, total);
    let obtained = obtain(&source, &scene, &profile, &plan, &a.out, Some(&report));
    if let Some(p) = progress.get() {
        p.finish();
    }
    let reference = match obtained {
        Ok(r) => r,
        Err(e) => {
            // A study that never started leaves no empty output directory behind.
            if created {
                let _ = std::fs::remove_dir(&a.out);
            }
            return match e {
                RefError::Input(m) => Err(Failure::input(m)),
                RefError::Runtime(m) => Err(Failure::runtime(m)),
                RefError::Interrupted(kept) => {
                    errln!("interrupted while rendering the reference: no run had started{kept}");
                    Ok(130)
                }
            };
        }
    };
    if reference.image.iter().any(|p| !p.is_finite()) {
        return Err(Failure::input("the reference image has non-finite pixels"));
    }
    outln!("  reference: {}", reference.description);
    for w in &reference.warnings {
        errln!("{w}");
    }
    // A previous study's outputs that this one will not rewrite must not sit beside its CSV (an
    // interrupted study writes no plot or sheet; one without --sheet no sheet).
    for stale in ["study.csv", "study.png", "sheet.png"] {
        match std::fs::remove_file(a.out.join(stale)) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => {
                return Err(Failure::runtime(format!("{}: cannot remove the previous study's file: {e}", a.out.join(stale).display())))
            }
        }
    }
    let total = plan.strategies.len() * plan.counts.len() * plan.seeds as usize;
    let mut done = 0;
    let mut report = |r: &RunResult| {
        done += 1;
        if !a.quiet {
            errln!(
                "  run {done}/{total}: {} n={} seed {}: {:.3} s, mse {:.3e}, mean/ref {:.4}",
                r.strategy,
                r.n,
                r.seed,
                r.seconds,
                r.mse,
                r.mean_ratio
            );
        }
    };
    let series = run_series(&scene, &profile, &plan, &reference.image, a.sheet, &mut report).map_err(Failure::input)?;
    let mut summary = summarize(&series.runs, &series.rows);
    if series.interrupted {
        // Only the rows whose every seed finished: a partial row's means are over fewer seeds than the
        // table says, and slopes over a partial series compare unlike rows.
        let rows = summary.len();
        summary.retain(|s| s.seeds == plan.seeds as usize);
        outln!(
            "\ninterrupted: the table below holds the {} of {rows} started rows whose every seed finished; no slopes fitted",
            summary.len()
        );
    }
    // The MSE of rounding the reference's values to f32 (an error uniform within half an ulp, ulp^2 / 12,
    // with the ulp about 2^-23 of the value): where the runs' error cannot go much lower.
    let ref_ms = reference.image.iter().map(|p| p.length_squared() / 3.0).sum::<f64>() / reference.image.len().max(1) as f64;
    let f32_floor = ref_ms * (f32::EPSILON as f64).powi(2) / 12.0;
    print_table(&summary, &plan, fixed_light_grid(&scene, &profile, &plan).is_some(), !series.interrupted, f32_floor);

    let unit = if light_only(&plan.integrals) { "light samples" } else { "spp" };
    let csv_path = a.out.join("study.csv");
    csv::write(&csv_path, &series.runs).map_err(Failure::runtime)?;
    if series.interrupted {
        errln!(
            "interrupted: wrote {} with the {} of {total} runs that finished (the run in flight was dropped); \
             study.png and sheet.png not written",
            csv_path.display(),
            series.runs.len()
        );
        return Ok(130);
    }
    let plot_path = a.out.join("study.png");
    plot::write(&plot_path, &summary, &plan.strategies, unit).map_err(Failure::runtime)?;
    outln!("wrote {}", csv_path.display());
    outln!("wrote {}", plot_path.display());
    let zero = plot::undrawn(&summary, &plan.strategies);
    if zero > 0 {
        outln!(
            "  ({zero} of {} rows have MSE 0, equal to the reference: a log scale has no 0, so study.png leaves them out)",
            summary.len()
        );
    }
    if a.sheet {
        let sheet_path = a.out.join("sheet.png");
        sheet::write(&sheet_path, &series.images, &plan.strategies, &plan.counts, scene.width, scene.height, unit)
            .map_err(Failure::runtime)?;
        outln!("wrote {}", sheet_path.display());
    }
    Ok(0)
}

/// `grid_floor`: the grid runs' light integral is a fixed grid (see [`fixed_light_grid`]).
/// `slopes`: fit and print the slopes (not for an interrupted series).
/// `f32_floor`: the MSE of rounding the reference's values to f32; a strategy whose error comes within
/// 10x of it has its slope flattened by rounding, not sampling.
fn print_table(summary: &[Summary], plan: &Plan, grid_floor: bool, slopes_too: bool, f32_floor: f64) {
    outln!(
        "\n{:<9} {:>6} {:>10} {:>12} {:>12} {:>12} {:>12} {:>9} {:>8}   (means over {} seeds; efficiency = 1 / (mean mse x mean seconds))",
        "strategy",
        "spp",
        "seconds",
        "rays",
        "mse",
        "relmse",
        "efficiency",
        "mean/ref",
        "z",
        plan.seeds
    );
    for s in summary {
        let z = if s.mean_z.is_nan() { "n/a".to_string() } else { format!("{:.1}", s.mean_z) };
        outln!(
            "{:<9} {:>6} {:>10.4} {:>12.0} {:>12.3e} {:>12.3e} {:>12.3e} {:>9.4} {:>8}{}",
            s.strategy.name(),
            s.n,
            s.seconds,
            s.rays,
            s.mse,
            s.relmse,
            s.efficiency,
            s.mean_ratio,
            z,
            if s.biased() { " !" } else { "" }
        );
    }
    outln!(
        "  mean/ref, z: the mean of the seeds' images over the reference's mean, and their difference over its standard \
         error (from the pixels' spread)"
    );
    if summary.iter().any(|s| !s.mean_ratio.is_finite()) {
        outln!("  (mean/ref NaN: the reference is black)");
    }
    if summary.iter().any(|s| s.mean_z.is_nan()) {
        outln!("  (z n/a: an image of one pixel has no spread to tell noise from bias; mean/ref stands alone)");
    }
    if summary.iter().any(Summary::biased) {
        outln!(
            "  ! |z| > {BIAS_Z}: the image mean differs from the reference's by more than noise explains: a bias in these \
             renders or in the reference; their MSE understates how far they are (a biased image can have the lower MSE)"
        );
    }
    if plan.strategies.iter().any(|s| matches!(s, Strategy::Grid | Strategy::Center)) {
        outln!("  `grid` and `center` are deterministic: their error at a given count is a bias by nature, which z measures");
    }
    if !slopes_too {
        outln!();
        return;
    }
    outln!("\nfitted slope of log MSE against log samples / log seconds (wall time: noisy):");
    let mut omitted = false;
    for &st in &plan.strategies {
        let (vs_n, vs_t) = slopes(summary, st);
        omitted |= vs_t.is_none();
        let f = |x: Option<crate::study::metrics::LogLogFit>| x.map_or("n/a".to_string(), |f| format!("{:+.3}", f.slope));
        let least = summary.iter().filter(|s| s.strategy == st).map(|s| s.mse).fold(f64::INFINITY, f64::min);
        let floor = if grid_floor && st == Strategy::Grid {
            "   (the light grid's bias floor, not a convergence rate: see the warning)".to_string()
        } else if least <= 10.0 * f32_floor && least.is_finite() {
            // (A user trial: sobol levelling off at 1.2e-16, its slope -0.79 printed without a word.)
            format!("   (its error reaches {least:.1e}, within 10x of the MSE of rounding the image to f32, {f32_floor:.1e}: rounding, not sampling, flattens the slope there)")
        } else {
            String::new()
        };
        outln!("  {:<9} {} / {}{floor}", st.name(), f(vs_n), f(vs_t));
    }
    if omitted {
        outln!(
            "  (n/a against seconds: it needs {TIME_SLOPE_MIN_COUNTS} or more counts whose mean times span at least \
             {TIME_SLOPE_MIN_SPAN}x and grow at least as n^{TIME_SLOPE_MIN_GROWTH}; otherwise timing noise and fixed costs set it)"
        );
    }
    outln!();
}
