//! End-to-end renders (generate through accumulate, all ray kinds counted) on 2 threads.

mod support;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use strata::render::render;
use strata::scene::Profile;
use strata::wavefront::Settings;

fn bench_render(c: &mut Criterion) {
    let mut g = c.benchmark_group("render");
    g.sample_size(10);
    for (name, spp) in [("bench_spheres.toml", 4), ("showcase.toml", 4)] {
        let scene = support::scene(name);
        let mut profile = Profile::builtin("bench");
        profile.spp = spp;
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
        g.bench_function(name, |b| b.iter(|| render(&scene, settings.clone(), support::THREADS)));
    }
    g.finish();
}

criterion_group!(benches, bench_render);
criterion_main!(benches);
