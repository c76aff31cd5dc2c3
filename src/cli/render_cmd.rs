//! `strata render`, including sample ranges, film files, checkpoints and resume (see the README, "Rendering on many machines").

use super::{Failure, Progress};
use crate::film::file::{
    build_id, check_film_writable, other_builds_warning, verify_film, write_film, write_film_unless, FilmHeader, FilmReader,
};
use crate::film::output::{check_file_writable, check_writable, write_image_with, Provenance};
use crate::film::Film;
use crate::render::{check_render_size, render_resumable, Checkpoint, RenderJob, RenderStats};
use crate::sample::Strategy;
use crate::scene::{load_scene_sized, LightSelection, Material, MaterialKind, Profile, Scene, NOT_A_LIGHT};
use crate::wavefront::Settings;
use clap::Args;
use glam::Vec3;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

#[derive(Args, Debug, Clone)]
pub struct RenderArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Output image: .png (sRGB 8-bit) or .exr (linear float). Default: `<scene name>.png`.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Quality profile: a shipped name (preview, final, reference, bench, light1/9/36/100, caustic) or a path.
    #[arg(long, default_value = "preview")]
    pub profile: String,
    /// Samples per pixel (overrides the profile).
    #[arg(long, allow_negative_numbers = true, value_parser = super::count_parser("camera samples per pixel", crate::scene::MAX_SPP))]
    pub spp: Option<u32>,
    /// One strategy for every integral: center, grid, random, jittered, sobol (overrides the profile).
    #[arg(long)]
    pub strategy: Option<String>,
    /// Samples per area light per shading point (overrides the profile).
    #[arg(long, allow_negative_numbers = true, value_parser = super::count_parser("light samples", crate::scene::MAX_LIGHT_SAMPLES))]
    pub light_samples: Option<u32>,
    /// Maximum bounces (overrides the profile).
    #[arg(long, allow_negative_numbers = true, value_parser = super::range_parser::<u32>("bounces", 0, crate::scene::MAX_DEPTH as u64))]
    pub max_depth: Option<u32>,
    /// Image size WxH instead of the scene's (e.g. 160x100 for a quick look; the camera keeps its fov).
    #[arg(long, allow_hyphen_values = true, value_name = "WxH")]
    pub size: Option<String>,
    /// Override any profile field: --set key=value (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Worker threads (default: all cores).
    #[arg(long, allow_negative_numbers = true, default_value_t = 0, value_parser = super::range_parser::<usize>("threads", 0, super::MAX_THREADS))]
    pub threads: usize,
    /// Random seed: same seed, same image.
    #[arg(long, allow_negative_numbers = true, default_value_t = 1, value_parser = super::range_parser::<u64>("seed", 0, u64::MAX))]
    pub seed: u64,
    /// Tile side in pixels (does not change the image).
    #[arg(long, allow_negative_numbers = true, default_value_t = crate::render::TILE, value_parser = super::range_parser::<u32>("tile side in pixels", 1, 1024))]
    pub tile: u32,
    /// Write the render summary as JSON.
    #[arg(long)]
    pub stats_json: Option<PathBuf>,
    /// No progress bar or summary.
    #[arg(short, long)]
    pub quiet: bool,
    /// Render only the sample indices A..B (0 <= A < B <= spp); combine ranges with `strata merge`.
    #[arg(long, value_name = "A..B")]
    pub samples: Option<String>,
    /// Also write the raw film (exact sums, sample range, completed work units) for resume and merge.
    #[arg(long, value_name = "PATH")]
    pub film: Option<PathBuf>,
    /// Write the film every SECONDS while rendering (to --film, else back to the --resume film).
    #[arg(long, allow_negative_numbers = true, value_name = "SECONDS")]
    pub checkpoint_every: Option<f64>,
    /// Continue the render saved in FILM (a checkpoint or the film of an interrupted render): completed
    /// work units are skipped, and the result is bit-identical to an uninterrupted render.
    #[arg(long, value_name = "FILM")]
    pub resume: Option<PathBuf>,
}

/// Load the profile named on the command line and apply the overrides.
pub fn resolve_profile(a: &RenderArgs) -> Result<Profile, Failure> {
    // A field set by its own flag and by `--set` too: one of them would be dropped without a word.
    let flagged = [
        ("spp", "--spp", a.spp.is_some()),
        ("strategy", "--strategy", a.strategy.is_some()),
        ("light_samples", "--light-samples", a.light_samples.is_some()),
        ("max_depth", "--max-depth", a.max_depth.is_some()),
    ];
    let key_of = |s: &str| s.split_once('=').map_or(s, |(k, _)| k).trim().to_string();
    for (i, s) in a.set.iter().enumerate() {
        let key = key_of(s);
        if let Some((_, flag, _)) = flagged.iter().find(|(k, _, given)| *given && *k == key) {
            return Err(Failure::input(format!("{flag} and --set {s} both set {key}: give one")));
        }
        // The same key twice: one value would be dropped without a word, as above.
        if let Some(first) = a.set[..i].iter().find(|t| key_of(t) == key) {
            return Err(Failure::input(format!("--set {first} and --set {s} both set {key}: give one")));
        }
    }
    super::load_profile(
        &a.profile,
        |p| {
            let mut flags: Vec<(&str, String)> = Vec::new();
            if let Some(v) = a.spp {
                flags.push(("spp", v.to_string()));
            }
            if let Some(v) = &a.strategy {
                flags.push(("strategy", v.clone()));
            }
            if let Some(v) = a.light_samples {
                flags.push(("light_samples", v.to_string()));
            }
            if let Some(v) = a.max_depth {
                flags.push(("max_depth", v.to_string()));
                if p.diffuse_depth > v {
                    flags.push(("diffuse_depth", v.to_string()));
                }
            }
            flags
        },
        &a.set,
    )
}

pub fn default_output(scene: &Path, ext: &str) -> PathBuf {
    let stem = scene.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "out".into());
    PathBuf::from(format!("{stem}.{ext}"))
}

/// Parse `--size WxH` within the scene format's limits on the image.
pub fn parse_size(text: &str) -> Result<(u32, u32), Failure> {
    let side = crate::scene::MAX_IMAGE_SIDE;
    let bad = |why: String| Failure::input(format!("--size {text}: {why}"));
    let (w, h) = text.split_once(['x', 'X']).ok_or_else(|| bad("expected WxH, e.g. 320x200".into()))?;
    let parse = |s: &str| s.trim().parse::<i64>().ok().filter(|v| (1..=side).contains(v)).map(|v| v as u32);
    let (w, h) = parse(w).zip(parse(h)).ok_or_else(|| bad(format!("each side must be a whole number in 1..={side}")))?;
    if w as u64 * h as u64 > crate::scene::MAX_PIXELS {
        return Err(bad(format!("{} pixels; the limit is {}", w as u64 * h as u64, crate::scene::MAX_PIXELS)));
    }
    Ok((w, h))
}

/// Parse `--samples A..B` against the profile's spp.
pub fn parse_samples(text: &str, spp: u32) -> Result<Range<u32>, Failure> {
    let bad = || Failure::input(format!("--samples {text}: expected A..B with 0 <= A < B <= spp ({spp})"));
    let (a, b) = text.split_once("..").ok_or_else(bad)?;
    let (a, b): (u32, u32) = (a.trim().parse().map_err(|_| bad())?, b.trim().parse().map_err(|_| bad())?);
    if a < b && b <= spp {
        Ok(a..b)
    } else {
        Err(bad())
    }
}

/// The film written when a render is interrupted and no --film or --resume names one: beside the image
/// (`out.film`), or where that is taken by a file already, the first free `out.2.film`, `out.3.film`, ...
/// (an interrupt never replaces a film it did not write: a trial lost 30% of another render's film so).
fn interrupt_film_path(out: &Path) -> PathBuf {
    std::iter::once(out.with_extension("film"))
        .chain((2u32..).map(|n| out.with_extension(format!("{n}.film"))))
        .find(|p| !p.exists())
        .expect("a free name")
}

/// The films an interrupt of a render writing `out` may have left (see [`interrupt_film_path`]): `out`
/// with the extension `.film`, and `out` with `.N.film` (N a number), those that exist, in that order.
fn interrupt_films(out: &Path) -> Vec<PathBuf> {
    let first = out.with_extension("film");
    let mut found: Vec<(u64, PathBuf)> = Vec::new();
    if first.exists() {
        found.push((1, first));
    }
    let dir = match out.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let stem = out.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    if let Ok(entries) = std::fs::read_dir(dir) {
        for e in entries.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            let n = name
                .strip_prefix(&format!("{stem}."))
                .and_then(|r| r.strip_suffix(".film"))
                .filter(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()))
                .and_then(|n| n.parse::<u64>().ok());
            if let Some(n) = n {
                found.push((n, out.with_file_name(&name)));
            }
        }
    }
    found.sort();
    found.into_iter().map(|(_, p)| p).collect()
}

/// Write a film that could not be written at `path` (its directory removed, a full disk) where it can
/// be: under its file name in the working directory, else in the temporary directory, at the first free
/// name (`x.film`, `x.2.film`, ...: never replacing a file). Returns where it went, or None and why each
/// place failed.
fn write_film_elsewhere(path: &Path, header: &FilmHeader, film: &Film) -> (Option<PathBuf>, Vec<String>) {
    let file = path.file_name().unwrap_or("render.film".as_ref());
    let mut tried = Vec::new();
    for dir in [std::env::current_dir().ok(), Some(std::env::temp_dir())].into_iter().flatten() {
        // (The free name as an interrupt picks it: `x.film`, `x.2.film`, ...)
        let name = interrupt_film_path(&dir.join(file));
        match write_film(&name, header, film) {
            Ok(()) => return (Some(name), tried),
            Err(e) => tried.push(e),
        }
    }
    (None, tried)
}

/// Why a film cannot be resumed by this render, if it cannot.
fn resume_mismatch(film: &FilmHeader, this: &FilmHeader) -> Option<String> {
    let mut d = film.identity_differences(this, ("film", "this render"));
    if film.samples != this.samples {
        d.push(format!(
            "sample range: film {}..{}, this render {}..{} (pass --samples {}..{})",
            film.samples.start, film.samples.end, this.samples.start, this.samples.end, film.samples.start, film.samples.end
        ));
    }
    if film.tile != this.tile {
        d.push(format!("tile: film {}, this render {} (pass --tile {})", film.tile, this.tile, film.tile));
    }
    (!d.is_empty()).then(|| d.join("; "))
}

/// What `flag` writing a film of the render `this` at `path` would replace: a partial film of another
/// render (or of another sample range or tile of the same scene) is refused, since it is work in
/// progress (a trial's 6% of a `final` render went so without a word); a complete one is replaced, with
/// a warning (returned). A partial film of this same render is refused too, with `advice` (how to
/// continue it): no command replaces a partial film (`--resume A --film B` and `merge ... --film B`
/// replaced a partial B of their render without a word). Nothing there, a complete film of this very
/// render, or a file that is no film: `Ok(None)`; but a render (`render`) refuses a complete film of
/// this very render too ([`refuse_complete_same`]).
pub(super) fn check_film_replaced(
    path: &Path,
    flag: &str,
    this: &FilmHeader,
    advice: &str,
    render: bool,
) -> Result<Option<String>, Failure> {
    // (Read whole and checked, as a film to resume is, but only its header kept: a file that is no
    // intact film is replaced.)
    let Ok(saved) = verify_film(path) else { return Ok(None) };
    if render {
        refuse_complete_same(path, &saved, this)?;
    }
    if !saved.is_complete() && resume_mismatch(&saved, this).is_none() {
        return Err(Failure::input(format!(
            "{}: a partial film of this same render ({} of {} work units) is there, which {flag} would replace: {advice}, \
             name another film, or remove it first",
            path.display(),
            saved.units_done(),
            saved.completed.len()
        )));
    }
    check_film_header_replaced(path, &saved, flag, this)
}

/// A complete film of this very render where a render's --film would write: refused. Rendering it again
/// gives the same film, and an interrupt or a checkpoint on the way replaced the complete film with a
/// partial one (a finished command run again by mistake and stopped with Ctrl-C lost the render, its
/// image too). `merge --film` replaces it (a merge is not interrupted half way, and gives the same film).
fn refuse_complete_same(path: &Path, saved: &FilmHeader, this: &FilmHeader) -> Result<(), Failure> {
    if saved.is_complete() && resume_mismatch(saved, this).is_none() {
        return Err(Failure::input(format!(
            "{}: a complete film of this same render is there, which --film would replace: its image is `strata merge {} -o IMAGE`; \
             remove it or name another film to render again",
            path.display(),
            path.display()
        )));
    }
    Ok(())
}

/// [`check_film_replaced`] for a film already read (`saved`, the header of the film at `path`).
fn check_film_header_replaced(path: &Path, saved: &FilmHeader, flag: &str, this: &FilmHeader) -> Result<Option<String>, Failure> {
    let Some(why) = resume_mismatch(saved, this) else { return Ok(None) };
    if !saved.is_complete() {
        return Err(Failure::input(format!(
            "{}: a partial film of another render ({} of {} work units; {why}) is there, which {flag} would replace: \
             name another film, or remove it first",
            path.display(),
            saved.units_done(),
            saved.completed.len()
        )));
    }
    Ok(Some(format!("{}: {flag} replaces a complete film of another render ({why})", path.display())))
}

pub fn run(a: RenderArgs) -> Result<u8, Failure> {
    // Until the render's own handler: a signal during setup (reading the scene, its BVH) quits at once.
    super::on_signal(|| {
        errln!("interrupted while setting up the render: no sample was rendered, nothing was written");
        std::process::exit(130);
    });
    // The arguments first, all that can be checked without the scene: a mistake in them is told at
    // once, not after the setup of a large scene.
    let size = a.size.as_deref().map(parse_size).transpose()?;
    let profile = resolve_profile(&a)?;
    if let Some(w) = oversubscribed(a.threads, std::thread::available_parallelism().map_or(0, |n| n.get())) {
        errln!("warning: {w}");
    }
    let samples = match &a.samples {
        Some(t) => parse_samples(t, profile.spp)?,
        None => 0..profile.spp,
    };
    // With --size the render's samples are known without the scene: too many is told at once (it was
    // told after the parse, 1.5 s and 563 MB into a 16 MB scene).
    if let Some((w, h)) = size {
        check_render_size(w, h, &samples).map_err(Failure::input)?;
    }
    let out = a.output.clone().unwrap_or_else(|| default_output(&a.scene, "png"));
    check_writable(&out).map_err(Failure::input)?;
    if let Some(j) = &a.stats_json {
        check_file_writable(j).map_err(Failure::input)?;
    }
    // Where the film goes: --film, else back into the film being resumed.
    let film_path = a.film.clone().or_else(|| a.resume.clone());
    if let Some(f) = &a.film {
        crate::film::file::check_film_name(f).map_err(Failure::input)?;
    }
    if let Some(f) = &film_path {
        check_film_writable(f).map_err(Failure::input)?;
    }
    let mut outputs: Vec<(&str, &Path)> = vec![("-o", &out)];
    if let Some(j) = &a.stats_json {
        outputs.push(("--stats-json", j));
    }
    if let Some(f) = &film_path {
        outputs.push((if a.film.is_some() { "--film" } else { "--resume" }, f));
    }
    let profile_file =
        [PathBuf::from(&a.profile), Path::new("profiles").join(format!("{}.toml", a.profile))].into_iter().find(|p| p.is_file());
    let mut inputs: Vec<(&str, &Path)> = vec![("the scene file", &a.scene)];
    if let Some(p) = &profile_file {
        inputs.push(("the profile file", p));
    }
    if let Some(r) = &a.resume {
        inputs.push(("the --resume film", r));
    }
    super::check_distinct_files(&outputs, &inputs, &[("--film", "the --resume film"), ("--resume", "the --resume film")])?;
    if let Some(r) = &a.resume {
        // (Read after the scene's setup, which it must match: whether it is there at all, told at once.)
        std::fs::File::open(r).map_err(|e| Failure::input(format!("--resume {}: {e}", r.display())))?;
    }
    let checkpoint_every = match a.checkpoint_every {
        None => None,
        Some(s) if s.is_finite() && s > 0.0 && s < 1e9 => Some(Duration::from_secs_f64(s)),
        Some(s) => {
            return Err(Failure::input(format!(
                "--checkpoint-every {s}: expected a number of seconds above 0 and below 1000000000 (31.7 years)"
            )))
        }
    };
    if checkpoint_every.is_some() && film_path.is_none() {
        return Err(Failure::input("--checkpoint-every needs --film PATH (where the checkpoints go) or --resume FILM"));
    }

    let setup = Instant::now();
    let notice = super::SetupNotice::start("setting up the scene (reading, parsing, checks, BVH)", a.quiet);
    let scene = load_scene_sized(&a.scene, size).map_err(Failure::input);
    drop(notice);
    let scene = scene?;
    // Reading, parsing, the BVHs and the light buffers: not in the render's time, so said apart.
    let setup_seconds = setup.elapsed().as_secs_f64();
    for w in &scene.warnings {
        errln!("warning: {w}");
    }
    if let Some(w) = identical_samples_warning(&scene, &profile) {
        errln!("warning: {w}");
    }
    for w in sampling_warnings(&scene, &profile) {
        errln!("warning: {w}");
    }
    if let Some(n) = every_light_note(&scene, &profile) {
        errln!("note: {n}");
    }
    check_render_size(scene.width, scene.height, &samples).map_err(Failure::input)?;

    let mut header = FilmHeader::fresh(&scene, &profile, samples.clone(), a.tile, a.seed);
    // Whether the film resumed holds samples of another build (a film of several builds records none).
    let mut mixed = false;
    let n_units = header.completed.len();
    // A partial film of this very render where --film would write (or beside the image, where an earlier
    // interrupt left it: `OUT.film`, or `OUT.2.film`, ... where that name was taken): refused, so that
    // running the command again does not throw its work away.
    if a.resume.is_none() {
        let candidates = match &a.film {
            Some(f) => vec![f.clone()],
            None => interrupt_films(&out),
        };
        let mut partial = Vec::new();
        for here in candidates {
            let Ok(saved) = verify_film(&here) else { continue };
            // (Where --film names it, a film of another render: refused if partial, else replaced with a
            // warning; read once for both checks.)
            if a.film.is_some() {
                refuse_complete_same(&here, &saved, &header)?;
                if let Some(w) = check_film_header_replaced(&here, &saved, "--film", &header)? {
                    errln!("warning: {w}");
                }
            }
            if !saved.is_complete() && resume_mismatch(&saved, &header).is_none() {
                partial.push((here, saved.units_done(), saved.completed.len()));
            }
        }
        // The one holding the most work is the one to continue; the others are named too.
        partial.sort_by_key(|&(_, done, _)| std::cmp::Reverse(done));
        if let Some((here, done, total)) = partial.first() {
            let others: Vec<String> = partial[1..].iter().map(|(p, d, t)| format!("{} ({d} of {t})", p.display())).collect();
            return Err(Failure::input(format!(
                "{}: a partial film of this same render ({done} of {total} work units) is there{}: continue it with --resume {}, \
                 or remove it to start again{}",
                here.display(),
                if a.film.is_some() { ", which --film would replace" } else { "" },
                here.display(),
                if others.is_empty() { String::new() } else { format!(" (more partial films of this render: {})", others.join(", ")) }
            )));
        }
    }
    if let Some(f) = a.film.as_deref().filter(|&f| a.resume.as_deref().is_some_and(|r| r != f)) {
        let advice = format!("continue it with --resume {} instead", f.display());
        if let Some(w) = check_film_replaced(f, "--film", &header, &advice, true)? {
            errln!("warning: {w}");
        }
    }
    // The film: the one resumed, read straight into it (its header checked first, before a pixel is
    // read), else a new one; memory for either taken fallibly (an error, not an abort, where it runs out).
    let no_memory = |what: String, e: String| Failure::runtime(format!("{what}: {e}"));
    let mut resumed_film = None;
    if let Some(r) = &a.resume {
        let reader = FilmReader::open(r).map_err(|e| Failure::input(format!("--resume {e}")))?;
        if let Some(why) = resume_mismatch(reader.header(), &header) {
            return Err(Failure::input(format!("{}: cannot resume: the film is from a different render: {why}", r.display())));
        }
        let mut f = Film::try_new(scene.width, scene.height).map_err(|e| no_memory(format!("--resume {}", r.display()), e))?;
        let saved = reader.read_into(&mut f).map_err(|e| Failure::input(format!("--resume {}: {e}", r.display())))?;
        resumed_film = Some(f);
        let this = build_id();
        if let Some(w) = other_builds_warning(&[(r.display().to_string(), saved.build)], this, "this one") {
            errln!("{w}");
        }
        // A film of unknown build (0: a version-1 film, before builds were recorded, or one already of
        // several builds' samples) makes the result one of unknown build too (it was stamped with this
        // build's, which a user trial found claiming samples it never rendered).
        if saved.units_done() > 0 && saved.build == 0 {
            errln!(
                "note: {} records no build (a film from before builds were recorded, or of several builds' samples): the film \
                 this render writes records none either (build 0, unknown)",
                r.display()
            );
        }
        mixed = saved.units_done() > 0 && saved.build != this;
        header.completed = saved.completed;
    }
    // (The film's first touch is setup too: 0.25 s for a 4K film, more where the kernel compacts memory.)
    let allocating = Instant::now();
    let film = match resumed_film {
        Some(f) => f,
        None => Film::try_new(scene.width, scene.height).map_err(|e| no_memory("the render's film".into(), e))?,
    };
    let setup_seconds = setup_seconds + allocating.elapsed().as_secs_f64();
    let resumed_units = header.units_done();
    let start_completed = std::mem::take(&mut header.completed);

    let settings = Settings { profile, seed: a.seed };
    let label = format!("samples {}..{}", samples.start, samples.end);
    let progress = Progress::new(&label, a.quiet, n_units, resumed_units);
    let report = |d: usize, n: usize| progress.update(d, n);
    // The film an interrupted render writes (an interrupted render always leaves one, to resume).
    let film_out_interrupted = film_path.clone().unwrap_or_else(|| interrupt_film_path(&out));
    let cancel = Arc::new(AtomicBool::new(false));
    let state = Arc::new(AtomicU8::new(RUNNING));
    let checkpointed = Arc::new(AtomicBool::new(false));
    install_interrupt_handler(
        &cancel,
        &state,
        &checkpointed,
        &progress,
        &out,
        &film_out_interrupted,
        film_path.as_deref(),
        a.resume.as_deref(),
    );
    // Checkpoints are written by a thread of the render's while the workers go on, one at a time: one
    // that takes longer than the interval delays the next, which is said once. One still being written
    // when the render stops is given up (the previous one stays): the film written next supersedes it.
    let slow_warned = AtomicBool::new(false);
    let render_ended = AtomicBool::new(false);
    let write_checkpoint = |f: &Film, completed: &[bool]| {
        let path = film_path.as_deref().expect("checkpoints need a film path");
        let t = Instant::now();
        match write_film_unless(path, &header.stamped(completed.to_vec(), mixed), f, &render_ended) {
            Ok(true) => checkpointed.store(true, Ordering::SeqCst),
            Ok(false) => return,
            Err(e) => progress.println(&format!("warning: checkpoint not written: {e}")),
        }
        let (took, every) = (t.elapsed(), checkpoint_every.unwrap_or_default());
        if took > every && !slow_warned.swap(true, Ordering::Relaxed) {
            progress.println(&format!(
                "warning: a checkpoint of {} took {:.1} s to write, longer than --checkpoint-every {}: checkpoints are written \
                 one at a time, so the next comes when one is written (the render goes on meanwhile)",
                path.display(),
                took.as_secs_f64(),
                every.as_secs_f64()
            ));
        }
    };
    let checkpoint_failed = |e: String| progress.println(&format!("warning: checkpoint skipped: {e}"));
    let mut job = RenderJob::new(&scene, settings);
    job.threads = a.threads;
    job.tile = a.tile;
    job.samples = samples.clone();
    job.cancel = Some(&cancel);
    job.progress = Some(&report);
    job.checkpoint = checkpoint_every.map(|every| Checkpoint {
        every,
        write: &write_checkpoint,
        failed: Some(&checkpoint_failed),
        ended: Some(&render_ended),
    });
    let (film, completed, stats) = render_resumable(&job, film, start_completed);
    // From here on a signal no longer quits: the outputs are written (quickly, and all or nothing).
    // Unless a second signal has just started quitting: then wait for the handler to end the process.
    loop {
        match state.load(Ordering::SeqCst) {
            QUITTING => std::thread::sleep(Duration::from_millis(50)),
            s if state.compare_exchange(s, WRITING, Ordering::SeqCst, Ordering::SeqCst).is_ok() => break,
            _ => {}
        }
    }
    let header = FilmHeader { completed, ..header.clone() };
    progress.finish();
    if stats.overflow {
        return Err(Failure::runtime(format!("{}; no image or film was written", crate::render::overflow_message(&job))));
    }
    if !stats.completed && header.units_done() == resumed_units {
        // Interrupted before a work unit finished (while the light selection was made): nothing to add
        // to what the outputs hold, so they are left as they were.
        let resume = match &a.resume {
            Some(r) => format!("; {} is as it was", r.display()),
            None => String::new(),
        };
        errln!("interrupted before any work unit finished: nothing was written ({} untouched{resume})", out.display());
        return Ok(130);
    }

    let writing = Instant::now();
    let image = write_image_with(&out, film.width, film.height, &film.to_rgb(), Some(&Provenance::of(&header)));
    let write_stats = |output_seconds: f64| -> Result<(), String> {
        let Some(j) = &a.stats_json else { return Ok(()) };
        let json = StatsJson {
            stats: &stats,
            // (The summary's setup: the light selection's making included.)
            setup_seconds: setup_seconds + stats.selection_seconds,
            output_seconds,
            work_units: WorkUnitsJson { done: header.units_done(), total: n_units, resumed: resumed_units },
            filter: job.settings.profile.filter.name(),
            strategies: UsedStrategies(used_strategies(&scene, &job.settings.profile)),
        };
        let text = serde_json::to_string_pretty(&json).map_err(|e| e.to_string())?;
        crate::film::output::write_atomic(j, |tmp| std::fs::write(tmp, text).map_err(|e| format!("{}: {e}", j.display())))
    };
    // If the image could not be written (its directory removed, a full disk), what was rendered is still
    // kept wherever it can be: the statistics first, then the film.
    let stats_early = image.is_err().then(|| write_stats(writing.elapsed().as_secs_f64()));
    // The film: the one asked for (--film, --resume); else, for an interrupted render (always, so that
    // it can be resumed) or one whose image failed (the render is kept in it), where an interrupt writes
    // it. Where that write fails too, the film goes to the first place that takes it: the working
    // directory, then the temporary directory (its name there free, never replacing a file).
    let film_wanted = film_path.clone().or_else(|| (!stats.completed || image.is_err()).then(|| film_out_interrupted.clone()));
    let mut film_error = None;
    let film_out = match &film_wanted {
        None => None,
        Some(f) => {
            let stamped = header.stamped(header.completed.clone(), mixed);
            match write_film(f, &stamped, &film) {
                Ok(()) => Some(f.clone()),
                Err(fe) => {
                    let (kept, tried) = write_film_elsewhere(f, &stamped, &film);
                    film_error = Some(match &kept {
                        Some(k) => format!("{fe}; the film was written to {} instead", k.display()),
                        None => format!("{fe}; nor could it be written elsewhere ({})", tried.join("; ")),
                    });
                    kept
                }
            }
        }
    };
    let output_seconds = writing.elapsed().as_secs_f64();
    let stats_error = stats_early.unwrap_or_else(|| write_stats(output_seconds)).err();
    if image.is_err() || film_error.is_some() || stats_error.is_some() {
        let mut m: Vec<String> = Vec::new();
        if let Err(e) = &image {
            m.push(e.clone());
        }
        m.extend(film_error);
        if let (Err(_), Some(f)) = (&image, &film_out) {
            m.push(format!(
                "the render is kept in the film {}: `strata merge {}{} -o IMAGE` writes its image",
                f.display(),
                f.display(),
                if header.is_complete() { "" } else { " --allow-gaps" }
            ));
        }
        match (&a.stats_json, stats_error) {
            (_, Some(e)) => m.push(e),
            (Some(j), None) => m.push(format!("--stats-json {} was written", j.display())),
            (None, None) => {}
        }
        return Err(Failure::runtime(m.join("; ")));
    }
    if !a.quiet {
        let output = Output { seconds: output_seconds, film: film_out.is_some() };
        print_summary(&a.scene, &scene, &job, &stats, setup_seconds + stats.selection_seconds, &out, output);
        let resumed = match &a.resume {
            Some(r) => format!(", resumed {resumed_units} of {n_units} work units from {}", r.display()),
            None => String::new(),
        };
        if stats.completed {
            outln!("  {label} of {}{resumed}", header.spp);
        } else {
            outln!("  interrupted: {} of {n_units} work units of {label} of {}{resumed}", header.units_done(), header.spp);
        }
        if let Some(f) = &film_out {
            outln!("  wrote film {}", f.display());
        }
    }
    crate::film::warn_discarded(stats.nonfinite_samples);
    crate::film::warn_lost_media(stats.lost_media);
    crate::film::warn_dim(&film, scene.has_light());
    if !stats.completed {
        let f = film_out.as_deref().unwrap_or(&out);
        errln!(
            "interrupted: wrote the {} samples accumulated so far to {} and the film to {} ({} of {n_units} work units); \
             continue with the same command and --resume {}",
            film.total_samples(),
            out.display(),
            f.display(),
            header.units_done(),
            f.display()
        );
        return Ok(130);
    }
    Ok(0)
}

/// `--stats-json`: the render's statistics and what the summary adds to them.
#[derive(serde::Serialize)]
struct StatsJson<'a> {
    #[serde(flatten)]
    stats: &'a RenderStats,
    /// Reading and compiling the scene (parse, BVHs, light buffers), and the film's allocation, before the
    /// render.
    setup_seconds: f64,
    /// Writing the image and the film (where one is written), after the render.
    output_seconds: f64,
    work_units: WorkUnitsJson,
    filter: &'static str,
    strategies: UsedStrategies,
}

#[derive(serde::Serialize)]
struct WorkUnitsJson {
    /// Completed, counting those resumed from a film.
    done: usize,
    total: usize,
    resumed: usize,
}

/// Integral -> strategy name, as a JSON object in the summary's order.
struct UsedStrategies(Vec<(&'static str, Strategy)>);

impl serde::Serialize for UsedStrategies {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_map(self.0.iter().map(|(k, v)| (k, v.name())))
    }
}

/// The integrals this render samples, with their strategies: pixel always, light with area lights,
/// lens with a lens, time with motion, glossy with glossy materials, diffuse with `diffuse_depth > 0`,
/// wavelength with dispersion.
pub fn used_strategies(scene: &Scene, p: &Profile) -> Vec<(&'static str, Strategy)> {
    let f = &scene.features;
    [
        ("pixel", p.pixel_strategy, true),
        ("light", p.light_strategy, f.area_lights),
        ("lens", p.lens_strategy, f.lens),
        // (A shutter of no length places moving shapes at its one instant: no time integral to sample.)
        ("time", p.time_strategy, f.motion && !scene.motion_at_one_instant()),
        ("glossy", p.glossy_strategy, f.glossy),
        ("diffuse", p.diffuse_strategy, p.diffuse_depth > 0),
        ("wavelength", p.wavelength_strategy, f.dispersion),
    ]
    .into_iter()
    .filter(|&(_, _, used)| used)
    .map(|(k, s, _)| (k, s))
    .collect()
}

/// Samples that can only repeat each other: more than one light sample at the light's `center`, or more
/// than one sample per pixel where every integral the scene samples is at `center` in a scene without a
/// random choice per path (no dielectric, whose roulette branching draws, and no diffuse bounces). The
/// image is that of one sample.
pub fn identical_samples_warning(scene: &Scene, p: &Profile) -> Option<String> {
    if p.light_samples > 1 && scene.features.area_lights && p.light_strategy == Strategy::Center {
        return Some(format!(
            "light_samples {}: light_strategy `center` puts every light sample at the light's centre: 1 light sample gives the same image",
            p.light_samples
        ));
    }
    let random_paths = scene.features.dielectric || p.diffuse_depth > 0;
    if p.spp > 1 && !random_paths && used_strategies(scene, p).iter().all(|(_, s)| *s == Strategy::Center) {
        let n = p.spp;
        return Some(format!(
            "spp {n}: every integral this scene uses is sampled at `center`, so the {n} samples per pixel are identical: --spp 1 renders the same image"
        ));
    }
    None
}

/// A shutter holding fewer distinct f32 instants than this is warned about (its motion blur is a
/// staircase of that many steps).
const SHUTTER_MIN_INSTANTS: u64 = 1024;

/// How many distinct f32 times the shutter `[t0, t1]` holds: its length over the f32 spacing at its
/// larger end, plus one (both ends: `t0 + (t1 - t0) u` rounds to `t1` for `u` near 1 where the spacing
/// is coarse); `None` for a shutter of no length.
fn shutter_instants(t0: f32, t1: f32) -> Option<u64> {
    let spacing = crate::geometry::ulp_at(t0.abs().max(t1.abs()).max(f32::MIN_POSITIVE));
    (t1 > t0).then(|| ((t1 as f64 - t0 as f64) / spacing as f64).round() as u64 + 1)
}

/// Samples that do not sample what their integral asks: one light sample on a `grid` (the light's centre
/// for every camera sample: a hard shadow at any spp), 2D grids whose count has no near-square
/// factorisation (`grid_shape` gives one row, 1 x 2 or 1 x 7 for a prime, or strips more than 4 times
/// longer than wide: the integral is sampled along one axis; jittered sets of such counts take equal-area strata in rows,
/// `jitter_rows`), and a shutter of zero length in a scene with motion, or one so far from time 0 for
/// its length that f32 holds few instants in it ([`SHUTTER_MIN_INSTANTS`]).
pub fn sampling_warnings(scene: &Scene, p: &Profile) -> Vec<String> {
    let mut out = Vec::new();
    let [t0, t1] = scene.camera.shutter;
    if scene.motion_at_one_instant() {
        let default = if t0 == 0.0 { " (the default: give camera.shutter, e.g. [0, 1])" } else { "" };
        out.push(scene.located(
            "camera.shutter",
            format!(
                "shutter [{t0}, {t1}] has zero length{default}: every time sample is the instant {t0}, so shapes with `motion` show \
                 no motion blur"
            ),
        ));
    } else if let Some(n) =
        shutter_instants(t0, t1).filter(|&n| n < SHUTTER_MIN_INSTANTS && scene.features.motion && p.time_strategy != Strategy::Center)
    {
        let ulp = (t1 - t0) / (n - 1) as f32;
        out.push(scene.located(
            "camera.shutter",
            format!(
                "shutter [{t0}, {t1}] lies far from time 0 for its length: f32 times there are {ulp} apart, so it holds only {n} \
                 distinct instants and motion blur comes out in {n} steps; give times near 0 (a moving shape is at its `center` at \
                 time 0: shift the centres by `motion` times the same amount)"
            ),
        ));
    }
    if !scene.has_light() {
        out.push(
            "the scene has no light: no [[lights]], no emissive material of radiance > 0 and a black background, so the image is \
             black"
                .to_string(),
        );
    }
    if p.diffuse_depth == 0 && scene.lights.is_empty() {
        // (Emissive shapes of the scene's own, not the surfaces of its area lights, which are sampled. With
        // lights, a panel seen in reflections alone is a choice: `scenes/glossy.toml`'s.)
        let kinds = || scene.prim_kind.iter().chain(&scene.leaf_kind);
        let glowing = scene.materials.iter().any(|m| matches!(m, Material::Emissive { radiance } if *radiance != Vec3::ZERO));
        let emits = glowing
            && (scene.leaf_kind.contains(&MaterialKind::Emissive)
                || scene.prim_kind.iter().zip(&scene.light_of_prim).any(|(&k, &l)| k == MaterialKind::Emissive && l == NOT_A_LIGHT));
        let lambert = kinds().any(|&k| k == MaterialKind::Lambert);
        // (The background too reaches a Lambert surface only by a bounce: a trial's sphere and floor under
        // a white background and no lights rendered black without a word.)
        if scene.background != Vec3::ZERO && lambert {
            out.push(
                scene.located(
                    "image.background",
                    "the background lights surfaces only through the paths that reach it (diffuse bounces, mirrors, glass, glossy \
                 lobes), not as a light sampled at shading points: with no [[lights]] and diffuse_depth 0 (this profile's) the \
                 Lambert surfaces receive no light at all (give diffuse_depth > 0, e.g. --set diffuse_depth=4, or add a \
                 [[lights]] entry)"
                        .to_string(),
                ),
            );
        }
        if emits && lambert {
            out.push(
                "emissive surfaces light others only through the paths that reach them (diffuse bounces, mirrors, glass, glossy \
                 lobes), not as lights sampled at shading points: with diffuse_depth 0 (this profile's) the Lambert surfaces \
                 receive no light at all (give diffuse_depth > 0, e.g. --set diffuse_depth=4, or model the lamp as a \
                 [[lights]] quad, disk or sphere)"
                    .to_string(),
            );
        }
    }
    if p.light_selection != LightSelection::All && scene.lights.len() <= 1 {
        out.push(format!(
            "light_selection `{}` with {} light{}: there is nothing to pick from, every shading point samples every light",
            p.light_selection.name(),
            scene.lights.len(),
            if scene.lights.len() == 1 { "" } else { "s" }
        ));
    }
    if p.light_strategy == Strategy::Grid && scene.features.area_lights && p.light_samples == 1 && p.spp > 1 {
        out.push(
            "light_strategy `grid` with 1 light sample puts it at the light's centre for every camera sample: hard shadows at any \
             spp (jittered and sobol light samples stratify across a pixel's camera samples; a grid needs light_samples > 1)"
                .to_string(),
        );
    }
    let light_set = p.spp as u64 * p.light_samples as u64;
    let across = light_set <= crate::wavefront::shadow::LIGHT_SET_MAX;
    if matches!(p.light_strategy, Strategy::Jittered | Strategy::Sobol) && scene.features.area_lights && !across {
        out.push(format!(
            "spp x light_samples = {light_set} passes 2^24: the light samples are stratified within each camera sample ({} of \
             them) instead of as one set over the pixel's camera samples, so the light integral converges more slowly than below \
             2^24 (fewer spp or light_samples keep the one set)",
            p.light_samples
        ));
    }
    for (name, s) in used_strategies(scene, p) {
        // The set's size: a pixel's samples, or its light samples (over its camera samples, see above).
        let set = if name != "light" {
            p.spp
        } else if across && s == Strategy::Sobol {
            light_set as u32
        } else {
            p.light_samples
        };
        if s == Strategy::Sobol && !set.is_power_of_two() {
            let below = 1u32 << (31 - set.leading_zeros());
            let of = if name == "light" && set != p.light_samples {
                format!(" (spp {} x light_samples {})", p.spp, p.light_samples)
            } else {
                String::new()
            };
            out.push(format!(
                "{name} sobol set of {set} samples{of}: the first n points of the sequence are evenly spread only where n is a power \
                 of two; at {set} the error can be several times that of {below} (use {below} or {}, or jittered)",
                below * 2
            ));
        }
        let n = if name == "light" { p.light_samples } else { p.spp };
        if s != Strategy::Grid || name == "time" || name == "wavelength" || n < 2 {
            continue;
        }
        let [a, b] = crate::sample::strategy::grid_shape(n);
        if a == 1 || b > 4 * a {
            let count = if name == "light" { "light_samples" } else { "spp" };
            let (below, above) = (n.isqrt().pow(2), (n.isqrt() + 1).pow(2));
            let such = if below >= 4 { format!("{below} or {above}") } else { above.to_string() };
            out.push(format!(
                "{name} grid of {n} samples is {a} x {b} strips ({count} {n} has no near-square factors): the {name} integral is \
                 sampled along one axis only; a count such as {such} gives a square grid"
            ));
        }
    }
    out
}

/// Lights past which `light_selection = all` (the default) is noted: each shading point sends a shadow
/// ray to every light, so a render's cost grows with their number, where one picked light per point
/// does not (a trial's 10,000 lamps at 160 x 120, 1 spp: 10.9 s with `all`, 0.05 s with `power` or
/// `tree`, and nothing said).
pub const MANY_LIGHTS: usize = 64;

/// The note for [`MANY_LIGHTS`]: `None` below it or with another selection.
pub fn every_light_note(scene: &Scene, p: &Profile) -> Option<String> {
    (p.light_selection == LightSelection::All && scene.lights.len() > MANY_LIGHTS).then(|| {
        format!(
            "light_selection `all` (the default) with {} lights: every shading point sends {} shadow rays, one per light and light \
             sample; `--set light_selection=tree` samples one light per point, picked by its importance (README, \"Many lights\")",
            scene.lights.len(),
            scene.lights.iter().map(|l| crate::light::samples_for(l, p.light_samples) as u64).sum::<u64>()
        )
    })
}

/// More worker threads than the machine runs at once: the image is the same (any thread count gives the
/// same image), but the threads share the cores, so the summary's per-thread stage times and rates count
/// waiting too. `cores` 0: unknown (no warning).
pub fn oversubscribed(threads: usize, cores: usize) -> Option<String> {
    (cores > 0 && threads > cores).then(|| {
        format!(
            "--threads {threads} on {cores} hardware threads: the threads share the cores (the image is the same; the stage times \
             per thread and their rates then count time spent waiting for a core)"
        )
    })
}

/// The states of a render towards signals (see [`install_interrupt_handler`]).
const RUNNING: u8 = 0;
const STOPPING: u8 = 1;
const QUITTING: u8 = 2;
const WRITING: u8 = 3;

/// A second interrupt sooner than this after the first counts as the same one (see the handler).
pub(crate) const DEBOUNCE: std::time::Duration = std::time::Duration::from_millis(100);

/// SIGINT / SIGTERM: the first stops handing out work units (`cancel`), says so, and lets the units in
/// flight finish, after which the image and the film are written; a second while those finish quits at
/// once, writing nothing, and says so (and which film, if any, still holds a resumable state). A second
/// within [`DEBOUNCE`] of the first is the first delivered twice and ignored. Once rendering has
/// stopped (`state` WRITING) signals wait for the outputs: writing them is quick.
#[allow(clippy::too_many_arguments)]
fn install_interrupt_handler(
    cancel: &Arc<AtomicBool>,
    state: &Arc<AtomicU8>,
    checkpointed: &Arc<AtomicBool>,
    progress: &Progress,
    out: &Path,
    film_out: &Path,
    film_path: Option<&Path>,
    resume: Option<&Path>,
) {
    let (cancel, state, checkpointed, bar) = (cancel.clone(), state.clone(), checkpointed.clone(), progress.bar.clone());
    let (out, film_out) = (out.display().to_string(), film_out.display().to_string());
    let (film_path, resume) = (film_path.map(|p| p.display().to_string()), resume.map(|p| p.display().to_string()));
    let say = move |m: &str| match &bar {
        Some(b) => b.suspend(|| errln!("{m}")),
        None => errln!("{m}"),
    };
    let first = std::sync::OnceLock::new();
    super::on_signal(move || match state.compare_exchange(RUNNING, STOPPING, Ordering::SeqCst, Ordering::SeqCst) {
        Ok(_) => {
            let _ = first.set(std::time::Instant::now());
            cancel.store(true, Ordering::SeqCst);
            say(&format!(
                "interrupted: finishing the work units in flight, then writing {out} and the film {film_out} \
                 (a second Ctrl-C or signal quits at once without writing)"
            ));
        }
        // A signal within DEBOUNCE of the first is the same interrupt: GNU `timeout` (and schedulers that
        // signal the process and then its group) deliver one request twice, microseconds apart.
        Err(STOPPING) if first.get().is_some_and(|t: &std::time::Instant| t.elapsed() < DEBOUNCE) => {}
        Err(STOPPING) if state.compare_exchange(STOPPING, QUITTING, Ordering::SeqCst, Ordering::SeqCst).is_ok() => {
            let kept = match (&film_path, &resume) {
                (Some(f), _) if checkpointed.load(Ordering::SeqCst) => format!("; {f} holds the last checkpoint: --resume {f}"),
                (_, Some(r)) => format!("; {r} is as it was: --resume {r}"),
                _ => String::new(),
            };
            say(&format!("interrupted again: quit at once; nothing was written ({out} and the film {film_out} were not){kept}"));
            std::process::exit(130);
        }
        Err(WRITING) => say(&format!("interrupted: rendering has stopped; writing {out}, please wait")),
        Err(_) => {}
    });
}

/// A count of rays for the summary: `663`, `12.35K`, `72.15M`, `1.20G` (the exact counts are in
/// `--stats-json`).
fn ray_count(x: u64) -> String {
    match x {
        0..10_000 => x.to_string(),
        10_000..1_000_000 => format!("{:.2}K", x as f64 / 1e3),
        1_000_000..1_000_000_000 => format!("{:.2}M", x as f64 / 1e6),
        _ => format!("{:.2}G", x as f64 / 1e9),
    }
}

/// What the summary says of the outputs: the time taken to write them, and whether a film was written
/// beside the image.
#[derive(Clone, Copy, Debug)]
pub struct Output {
    pub seconds: f64,
    pub film: bool,
}

pub fn print_summary(path: &Path, scene: &Scene, job: &RenderJob, s: &RenderStats, setup_seconds: f64, out: &Path, output: Output) {
    let mut o = String::new();
    // Written at once and errors ignored: `strata render ... | head` must not panic on a closed pipe.
    macro_rules! wl { ($($t:tt)*) => {{ use std::fmt::Write as _; let _ = writeln!(o, $($t)*); }}; }
    let p = &job.settings.profile;
    wl!("strata: {}  {}x{}  profile {}  seed {}  {} threads", path.display(), s.width, s.height, p.name, s.seed, s.threads);
    let branching = p.branching.name();
    let strategies: Vec<String> = used_strategies(scene, p).iter().map(|(k, s)| format!("{k} {}", s.name())).collect();
    // (Point lights take one sample whatever the count: without area lights it means nothing.)
    let light_samples = match (scene.features.area_lights, p.light_samples) {
        (false, _) => "no area lights".to_string(),
        (true, 1) => "1 light sample".to_string(),
        (true, n) => format!("{n} light samples"),
    };
    // One light picked per shading point (`light_selection`), where there are lights to pick from.
    let light_samples = match p.light_selection {
        LightSelection::All => light_samples,
        _ if scene.lights.len() <= 1 => light_samples,
        sel => format!("{light_samples}, 1 of {} lights picked per point ({})", scene.lights.len(), sel.name()),
    };
    wl!(
        "  sampling: {} spp, {light_samples}, max depth {}, diffuse depth {}, branching {branching}, filter {}; strategies: {}",
        p.spp,
        p.max_depth,
        p.diffuse_depth,
        p.filter.name(),
        strategies.join(", ")
    );
    wl!(
        "  scene: {} prims, {} CSG solids, {} lights; features {}",
        scene.prims.len(),
        scene.prims.iter().filter(|p| matches!(p.shape, crate::scene::Shape::Csg { .. })).count(),
        scene.lights.len(),
        feature_list(&scene.features)
    );
    wl!(
        "  rays: camera {}, secondary {}, shadow {}, total {}",
        ray_count(s.rays.camera),
        ray_count(s.rays.secondary),
        ray_count(s.rays.shadow),
        ray_count(s.rays.total)
    );
    if s.rays.shadow_cleared > 0 {
        wl!("  shadow rays cleared untraced by the light-cone test: {}", ray_count(s.rays.shadow_cleared));
    }
    wl!("  time: {:.3} s wall, {:.2} M rays/s", s.seconds, s.rays_per_second / 1e6);
    let points = scene.lights.iter().filter(|l| l.is_point()).count();
    let buffers = if points > 0 {
        let built = scene.light_buffers.iter().flatten().count();
        // (Why a point light has none: CSG solids' bounds are loose; past the first 32 point lights, the
        // entry budget, or a cell list too long, the BVH answers its shadow rays.)
        let why = if built == 0 && scene.features.csg {
            ": none in scenes with CSG solids"
        } else if built < points {
            ": the others' shadow rays take the BVH"
        } else {
            ""
        };
        format!(", light buffers for {built} of {points} point lights{why}")
    } else {
        String::new()
    };
    let selection = match job.settings.profile.light_selection {
        LightSelection::Tree if scene.lights.len() > 1 => format!(", light tree {:.3} s", s.selection_seconds),
        LightSelection::All => String::new(),
        _ if scene.lights.len() > 1 => format!(", light table {:.3} s", s.selection_seconds),
        _ => String::new(),
    };
    wl!("  setup: {setup_seconds:.3} s before the render (read, parse, BVH, film{buffers}{selection})");
    let t = &s.stage_seconds;
    wl!(
        "  stages (thread s): generate {:.3}, intersect {:.3}, csg_merge {:.3}, shade {:.3}, shadow {:.3}, accumulate {:.3}",
        t.generate,
        t.intersect,
        t.csg_merge,
        t.shade,
        t.shadow,
        t.accumulate
    );
    // Per stage, the items it processed per CPU second of that stage (one core's rate).
    let rate = |n: u64, secs: f64| if secs > 0.0 { format!("{:.1}", n as f64 / secs / 1e6) } else { "-".into() };
    let traced = s.rays.camera + s.rays.secondary;
    wl!(
        "  stage rates (M per thread s): generate {} camera rays, intersect {} rays, csg_merge {} candidates, shade {} rays, shadow {} shadow rays",
        rate(s.rays.camera, t.generate),
        rate(traced, t.intersect),
        rate(s.csg_candidates, t.csg_merge),
        rate(traced, t.shade),
        rate(s.rays.shadow, t.shadow)
    );
    if scene.features.csg {
        wl!("  csg candidates: {}", s.csg_candidates);
    }
    wl!("  nonfinite samples: {}", s.nonfinite_samples);
    wl!(
        "  wrote {} ({:.3} s after the render: the image{})",
        out.display(),
        output.seconds,
        if output.film { " and the film" } else { "" }
    );
    use std::io::Write as _;
    let _ = std::io::stdout().write_all(o.as_bytes());
}

pub fn feature_list(f: &crate::scene::Features) -> String {
    let mut v = Vec::new();
    macro_rules! add { ($($n:ident),*) => { $( if f.$n { v.push(stringify!($n)); } )* }; }
    add!(csg, dielectric, dispersion, glossy, mirror, point_lights, area_lights, motion, lens, planes);
    if v.is_empty() {
        "none".into()
    } else {
        v.join(" ")
    }
}
