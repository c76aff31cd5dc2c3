//! `strata render`.

use super::Failure;
use crate::film::output::{check_writable, write_image};
use crate::film::Film;
use crate::render::{render_into, RenderJob, RenderStats};
use crate::scene::{load_scene, Profile, Scene};
use crate::wavefront::Settings;
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

#[derive(Args, Debug, Clone)]
pub struct RenderArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Output image: .png (sRGB 8-bit) or .exr (linear float). Default: <scene name>.png.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Quality profile: a name in profiles/ (preview, final, reference, bench) or a path.
    #[arg(long, default_value = "preview")]
    pub profile: String,
    /// Samples per pixel (overrides the profile).
    #[arg(long)]
    pub spp: Option<u32>,
    /// One strategy for every integral: center, grid, random, jittered, sobol (overrides the profile).
    #[arg(long)]
    pub strategy: Option<String>,
    /// Samples per area light per shading point (overrides the profile).
    #[arg(long)]
    pub light_samples: Option<u32>,
    /// Maximum bounces (overrides the profile).
    #[arg(long)]
    pub max_depth: Option<u32>,
    /// Override any profile field: --set key=value (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Worker threads (default: all cores).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Random seed: same seed, same image.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Tile side in pixels (does not change the image).
    #[arg(long, default_value_t = crate::render::TILE)]
    pub tile: u32,
    /// Write the render summary as JSON.
    #[arg(long)]
    pub stats_json: Option<PathBuf>,
    /// No progress bar or summary.
    #[arg(short, long)]
    pub quiet: bool,
}

/// Load the profile named on the command line and apply the overrides.
pub fn resolve_profile(a: &RenderArgs) -> Result<Profile, Failure> {
    let mut p = Profile::load(&a.profile).map_err(Failure::input)?;
    let mut sets: Vec<(String, String)> = Vec::new();
    if let Some(v) = a.spp {
        sets.push(("spp".into(), v.to_string()));
    }
    if let Some(v) = &a.strategy {
        sets.push(("strategy".into(), v.clone()));
    }
    if let Some(v) = a.light_samples {
        sets.push(("light_samples".into(), v.to_string()));
    }
    if let Some(v) = a.max_depth {
        sets.push(("max_depth".into(), v.to_string()));
        if p.diffuse_depth > v {
            sets.push(("diffuse_depth".into(), v.to_string()));
        }
    }
    for s in &a.set {
        let (k, v) = s.split_once('=').ok_or_else(|| Failure::input(format!("--set {s}: expected KEY=VALUE")))?;
        sets.push((k.trim().to_string(), v.to_string()));
    }
    for (k, v) in sets {
        p.set(&k, &v).map_err(|e| Failure::input(format!("command line: {e}")))?;
    }
    Ok(p)
}

pub fn default_output(scene: &Path, ext: &str) -> PathBuf {
    let stem = scene.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "out".into());
    PathBuf::from(format!("{stem}.{ext}"))
}

pub fn run(a: RenderArgs) -> Result<u8, Failure> {
    let scene = load_scene(&a.scene).map_err(Failure::input)?;
    let profile = resolve_profile(&a)?;
    if a.threads > 1024 {
        return Err(Failure::input("--threads must be at most 1024"));
    }
    if a.tile == 0 || a.tile > 1024 {
        return Err(Failure::input("--tile must be in 1..=1024"));
    }
    let out = a.output.clone().unwrap_or_else(|| default_output(&a.scene, "png"));
    check_writable(&out).map_err(Failure::input)?;
    if let Some(j) = &a.stats_json {
        check_writable_any(j).map_err(Failure::input)?;
    }

    let cancel = Arc::new(AtomicBool::new(false));
    {
        let c = cancel.clone();
        // A second Ctrl-C while stopping exits at once.
        let _ = ctrlc::set_handler(move || {
            if c.swap(true, Ordering::SeqCst) {
                std::process::exit(130);
            }
        });
    }
    let settings = Settings { profile, seed: a.seed };
    let bar = if a.quiet { ProgressBar::hidden() } else { ProgressBar::new(0) };
    bar.set_style(ProgressStyle::with_template("{spinner} [{elapsed_precise}] {wide_bar} {pos}/{len} tiles (eta {eta})").unwrap());
    let progress = |d: usize, n: usize| {
        bar.set_length(n as u64);
        bar.set_position(d as u64);
    };
    let mut job = RenderJob::new(&scene, settings);
    job.threads = a.threads;
    job.tile = a.tile;
    job.cancel = Some(&cancel);
    job.progress = Some(&progress);
    let (film, stats) = render_into(&job, Film::new(scene.width, scene.height));
    bar.finish_and_clear();

    write_image(&out, film.width, film.height, &film.to_rgb()).map_err(Failure::runtime)?;
    if !a.quiet {
        print_summary(&a.scene, &scene, &job, &stats, &out);
    }
    if let Some(j) = &a.stats_json {
        let text = serde_json::to_string_pretty(&stats).map_err(Failure::runtime)?;
        crate::film::output::write_atomic(j, |tmp| std::fs::write(tmp, text).map_err(|e| e.to_string())).map_err(Failure::runtime)?;
    }
    if !stats.completed {
        eprintln!("interrupted: wrote the {} samples accumulated so far to {}", film.total_samples(), out.display());
        return Ok(130);
    }
    Ok(0)
}

fn check_writable_any(path: &Path) -> Result<(), String> {
    let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    if !dir.is_dir() {
        return Err(format!("{}: directory {} does not exist", path.display(), dir.display()));
    }
    Ok(())
}

fn mega(x: u64) -> String {
    format!("{:.2}M", x as f64 / 1e6)
}

pub fn print_summary(path: &Path, scene: &Scene, job: &RenderJob, s: &RenderStats, out: &Path) {
    let p = &job.settings.profile;
    println!("strata: {}  {}x{}  profile {}  seed {}  {} threads", path.display(), s.width, s.height, p.name, s.seed, s.threads);
    println!("  sampling: {}", crate::wavefront::pipeline::describe(p));
    println!(
        "  scene: {} prims, {} CSG solids, {} lights; features {}",
        scene.prims.len(),
        scene.csg.solid_count(),
        scene.lights.len(),
        feature_list(&scene.features)
    );
    println!(
        "  rays: camera {}, secondary {}, shadow {}, total {}",
        mega(s.rays.camera),
        mega(s.rays.secondary),
        mega(s.rays.shadow),
        mega(s.rays.total)
    );
    println!("  time: {:.3} s wall, {:.2} M rays/s", s.seconds, s.rays_per_second / 1e6);
    let t = &s.stage_seconds;
    println!(
        "  stages (cpu s): generate {:.3}, intersect {:.3}, csg_merge {:.3}, shade {:.3}, shadow {:.3}, accumulate {:.3}",
        t.generate, t.intersect, t.csg_merge, t.shade, t.shadow, t.accumulate
    );
    if scene.features.csg {
        println!("  csg candidates: {}", s.csg_candidates);
    }
    println!("  nonfinite samples: {}", s.nonfinite_samples);
    println!("  wrote {}", out.display());
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
