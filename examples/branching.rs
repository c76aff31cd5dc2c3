//! Efficiency of the two dielectric branching policies (Whitted's Fresnel split vs Russian roulette) on the
//! glass scenes: at equal samples per pixel, the MSE against a high-sample reference, the render time, and
//! efficiency = 1 / (MSE x time).
//!
//! ```text
//! cargo run --release --example branching -- [--spp 4,16,64] [--ref-spp 1024] [--width 128] [--reps 3] [SCENE.toml ...]
//! ```
//!
//! The reference is the average of a split and a roulette render at `--ref-spp` (both are unbiased; using
//! one of them alone would favour it). Its own noise adds to every measured MSE; the table also gives the
//! MSE with that part (the reference's estimated variance) subtracted. Renders use 1 thread; the time is the
//! fastest of `--reps` runs (the machine may be shared). Profile: `final` (max depth 8, throughput cut-off
//! 1e-3, jittered sampling, tent filter) with the policy and spp changed.

use std::path::{Path, PathBuf};
use std::time::Instant;
use strata::film::Film;
use strata::render::{render_into, RenderJob};
use strata::scene::{parse_scene, Branching, Profile, Scene};
use strata::wavefront::Settings;

struct Args {
    spp: Vec<u32>,
    ref_spp: u32,
    width: u32,
    reps: u32,
    scenes: Vec<PathBuf>,
}

fn parse_args() -> Args {
    let mut a = Args { spp: vec![4, 16, 64], ref_spp: 1024, width: 128, reps: 3, scenes: Vec::new() };
    let mut it = std::env::args().skip(1);
    while let Some(x) = it.next() {
        let mut num = |name: &str| -> u32 {
            let v = it.next().unwrap_or_else(|| panic!("{name} needs a value"));
            v.parse().unwrap_or_else(|_| panic!("{name}: `{v}` is not a number"))
        };
        match x.as_str() {
            "--spp" => {
                let v = it.next().expect("--spp needs a value");
                a.spp = v.split(',').map(|x| x.trim().parse().unwrap_or_else(|_| panic!("--spp: `{x}` is not a number"))).collect();
            }
            "--ref-spp" => a.ref_spp = num("--ref-spp"),
            "--width" => a.width = num("--width"),
            "--reps" => a.reps = num("--reps").max(1),
            _ => a.scenes.push(PathBuf::from(x)),
        }
    }
    if a.scenes.is_empty() {
        a.scenes = ["glass", "absorption", "nested"].iter().map(|n| PathBuf::from(format!("scenes/{n}.toml"))).collect();
    }
    a
}

/// The scene with its image scaled to `width` pixels across (aspect kept).
fn load_scaled(path: &Path, width: u32) -> Scene {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let full = parse_scene(path, &text).unwrap_or_else(|e| panic!("{e}"));
    let height = ((full.height as u64 * width as u64) / full.width as u64).max(1);
    let mut seen = (false, false);
    let scaled: String = text
        .lines()
        .map(|l| match l.split('=').next().map(str::trim) {
            Some("width") if !seen.0 => {
                seen.0 = true;
                format!("width = {width}")
            }
            Some("height") if !seen.1 && !l.contains('.') => {
                seen.1 = true;
                format!("height = {height}")
            }
            _ => l.to_string(),
        })
        .collect::<Vec<_>>()
        .join("\n");
    parse_scene(path, &scaled).unwrap_or_else(|e| panic!("{e}"))
}

fn profile(branching: Branching, spp: u32) -> Profile {
    let mut p = Profile::builtin("final");
    p.branching = branching;
    p.spp = spp;
    p
}

/// Render with 1 thread; returns the film, the fastest wall time of `reps` runs, and the rays traced.
fn timed_render(scene: &Scene, profile: Profile, seed: u64, reps: u32) -> (Film, f64, u64) {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..reps {
        let mut job = RenderJob::new(scene, Settings { profile: profile.clone(), seed });
        job.threads = 1;
        let t0 = Instant::now();
        let (film, stats) = render_into(&job, Film::new(scene.width, scene.height));
        best = best.min(t0.elapsed().as_secs_f64());
        assert_eq!(stats.nonfinite_samples, 0);
        out = Some((film, stats.rays.total));
    }
    let (film, rays) = out.unwrap();
    (film, best, rays)
}

fn mse(a: &Film, reference: &[[f64; 3]]) -> f64 {
    let mut s = 0.0;
    for (p, r) in a.pixels().zip(reference) {
        let m = p.mean();
        for c in 0..3 {
            s += (m[c] as f64 - r[c]).powi(2);
        }
    }
    s / (3.0 * reference.len() as f64)
}

fn main() {
    let a = parse_args();
    println!("# branching efficiency: {:?} spp vs a {}-spp reference, {} px wide, 1 thread, best of {}", a.spp, a.ref_spp, a.width, a.reps);
    println!("| scene | policy | spp | time (s) | rays | MSE | MSE - ref. var. | efficiency 1/(MSE t) | ratio |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for path in &a.scenes {
        let scene = load_scaled(path, a.width);
        // Reference: split and roulette at ref_spp, averaged; its variance of the mean per pixel.
        let mut jobs = Vec::new();
        for (k, b) in [Branching::Split, Branching::Roulette].into_iter().enumerate() {
            let mut job = RenderJob::new(&scene, Settings { profile: profile(b, a.ref_spp), seed: 1000 + k as u64 });
            job.threads = 0;
            jobs.push(render_into(&job, Film::new(scene.width, scene.height)).0);
        }
        let reference: Vec<[f64; 3]> = jobs[0]
            .pixels()
            .zip(jobs[1].pixels())
            .map(|(x, y)| {
                let (m0, m1) = (x.mean(), y.mean());
                [0, 1, 2].map(|c| 0.5 * (m0[c] as f64 + m1[c] as f64))
            })
            .collect();
        let ref_var: f64 = jobs[0]
            .pixels()
            .zip(jobs[1].pixels())
            .map(|(x, y)| {
                let (v0, v1) = (x.variance_of_mean(), y.variance_of_mean());
                (0..3).map(|c| 0.25 * (v0[c] as f64 + v1[c] as f64)).sum::<f64>()
            })
            .sum::<f64>()
            / (3.0 * reference.len() as f64);
        let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        for &spp in &a.spp {
            let mut eff = Vec::new();
            for b in [Branching::Split, Branching::Roulette] {
                let (film, secs, rays) = timed_render(&scene, profile(b, spp), 7, a.reps);
                let e = mse(&film, &reference);
                let efficiency = 1.0 / (e * secs);
                eff.push(efficiency);
                println!(
                    "| {name} | {b:?} | {spp} | {secs:.3} | {:.2}M | {e:.3e} | {:.3e} | {efficiency:.0} | {} |",
                    rays as f64 / 1e6,
                    e - ref_var,
                    if eff.len() == 2 { format!("roulette / split = {:.2}", eff[1] / eff[0]) } else { String::new() }
                );
            }
        }
    }
}
