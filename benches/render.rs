//! End-to-end renders (generate through accumulate, all ray kinds counted) on 2 threads.
//!
//! Each iteration renders into a fresh film made outside the timed part, as the render summary's time
//! excludes it: a film is 64 bytes a pixel (16 MB at 640 x 400), and on this project's VM the kernel's
//! zeroing of fresh pages for it took from 1 to 30 ms per allocation depending on the host, which swamped
//! the 40 ms of the render it measured.

mod support;

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use std::path::Path;
use strata::film::Film;
use strata::render::{render, render_into, RenderJob};
use strata::scene::{parse_scene, LightSelection, Profile, Scene};
use strata::wavefront::Settings;

/// `bench_spheres` with a lens (tiny aperture) and one moving sphere far behind the camera: the image is
/// the same to the eye, but every ray now carries a shutter time and a lens sample and every primitive
/// test handles time. Beside `render/bench_spheres.toml` it shows what a scene without those features
/// does not pay.
fn spheres_with_lens_and_motion() -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/bench_spheres.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let text = text.replacen("fov = 45.0", "fov = 45.0\naperture = 0.001\nshutter = [0.0, 1.0]", 1)
        + "\n[[shapes]]\ntype = \"sphere\"\ncenter = [0.0, 0.0, 60.0]\nradius = 0.5\nmaterial = \"ground\"\nmotion = [0.1, 0.0, 0.0]\n";
    let scene = parse_scene(&path, &text).unwrap_or_else(|e| panic!("{e}"));
    assert!(scene.features.lens && scene.features.motion);
    scene
}

/// Name, samples per pixel, loader, light selection.
type BenchScene = (&'static str, u32, fn() -> Scene, LightSelection);

fn bench_render(c: &mut Criterion) {
    let mut g = c.benchmark_group("render");
    g.sample_size(10);
    // 4 samples per pixel keeps each iteration short; the showcase also at the bench profile's own 16
    // (what the render summary, `examples/scaling.rs` and the end-to-end target measure: at 4,
    // per-pixel work of generation and accumulation weighs more per ray).
    // (256 lamps, one picked per shading point: `all` would take 60 times as long.)
    let all = LightSelection::All;
    let scenes: [BenchScene; 8] = [
        ("bench_spheres.toml", 4, || support::scene("bench_spheres.toml"), all),
        ("bench_spheres+lens+motion", 4, spheres_with_lens_and_motion, all),
        ("bench_csg.toml", 4, || support::scene("bench_csg.toml"), all),
        ("glass.toml", 4, || support::scene("glass.toml"), all),
        ("showcase.toml", 4, || support::scene("showcase.toml"), all),
        ("showcase.toml@16spp", 16, || support::scene("showcase.toml"), all),
        ("many_lights.toml+local", 4, || support::scene("many_lights.toml"), LightSelection::Local),
        ("many_lights.toml+tree", 4, || support::scene("many_lights.toml"), LightSelection::Tree),
    ];
    for (name, spp, load, selection) in scenes {
        let scene = load();
        let mut profile = Profile::builtin("bench");
        profile.spp = spp;
        profile.light_selection = selection;
        let settings = Settings { profile, seed: 1 };
        // Validate: a render produces finite samples and a deterministic ray count.
        let (film, stats) = render(&scene, settings.clone(), support::THREADS);
        assert_eq!(stats.nonfinite_samples, 0);
        assert_eq!(film.total_samples(), scene.width as u64 * scene.height as u64 * spp as u64);
        let (_, again) = render(&scene, settings.clone(), support::THREADS);
        assert_eq!(again.rays.total, stats.rays.total);
        println!(
            "{name}: {} rays per render ({} camera, {} secondary, {} shadow)",
            stats.rays.total, stats.rays.camera, stats.rays.secondary, stats.rays.shadow
        );
        g.throughput(Throughput::Elements(stats.rays.total));
        let mut job = RenderJob::new(&scene, settings.clone());
        job.threads = support::THREADS;
        let film = || Film::new(scene.width, scene.height);
        g.bench_function(name, |b| b.iter_batched(film, |f| render_into(&job, f), BatchSize::PerIteration));
    }
    g.finish();
}

criterion_group!(benches, bench_render);
criterion_main!(benches);
