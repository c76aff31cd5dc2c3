//! The shipped distribution scenes render cleanly, and the "how many samples?" profiles say what they
//! promise.

use super::*;

fn shipped(name: &str) -> Scene {
    let path = format!("{}/scenes/{name}", env!("CARGO_MANIFEST_DIR"));
    strata::scene::load_scene(Path::new(&path)).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn distribution_scenes_render_without_non_finite_samples() {
    let mut p = Profile::builtin("preview");
    p.spp = 2;
    p.light_samples = 2;
    for (name, feature) in [("glossy.toml", "glossy"), ("dof.toml", "lens"), ("motion.toml", "motion"), ("cornell.toml", "area_lights")] {
        let s = shipped(name);
        let f = s.features;
        let has = match feature {
            "glossy" => f.glossy,
            "lens" => f.lens,
            "motion" => f.motion,
            _ => f.area_lights,
        };
        assert!(has, "{name} should use {feature}");
        // render_image asserts zero non-finite samples.
        let (img, stats) = render_image(&s, &p, 1);
        let mean = img.iter().map(|v| v.as_dvec3()).sum::<DVec3>() / img.len() as f64;
        eprintln!("{name}: {}x{}, mean {mean:.3}, {} rays", stats.width, stats.height, stats.rays.total);
        assert!(img.iter().all(|v| v.is_finite()));
        assert!(mean.min_element() > 0.01, "{name} renders (nearly) black");
    }
}

#[test]
fn light_sample_profiles_are_the_how_many_samples_series() {
    for n in [1u32, 9, 36, 100] {
        let path = format!("{}/profiles/light{n}.toml", env!("CARGO_MANIFEST_DIR"));
        let p = Profile::load(&path).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!((p.spp, p.light_samples, p.diffuse_depth), (1, n, 0), "light{n}");
        assert_eq!(p.pixel_strategy, strata::sample::Strategy::Center, "light{n}: one centre pixel sample");
        assert_eq!(p.light_strategy, strata::sample::Strategy::Jittered, "light{n}");
        // n is a square: the jittered strata are a sqrt(n) x sqrt(n) grid on the light.
        let k = n.isqrt();
        assert_eq!(strata::sample::grid_shape(n), [k, k]);
    }
}

/// Lens, time and glossy samples are functions of (seed, pixel, sample, dimension): the same image for
/// any thread count, tile size and split of the sample range.
#[test]
fn lens_time_and_glossy_images_do_not_depend_on_threads_tiles_or_sample_split() {
    use strata::film::Film;
    use strata::render::{render_into, RenderJob};
    for name in ["dof.toml", "motion.toml", "glossy.toml"] {
        let path = format!("{}/scenes/{name}", env!("CARGO_MANIFEST_DIR"));
        let text = std::fs::read_to_string(&path).unwrap().replacen("width = 480", "width = 40", 1).replacen("height = 2", "height = 1", 1);
        let s = parse_scene(Path::new(name), &text).unwrap();
        let p = profile(6, "jittered", 2, "jittered");
        let run = |threads: usize, tile: u32, samples: std::ops::Range<u32>, film: Film| {
            let mut job = RenderJob::new(&s, Settings { profile: p.clone(), seed: 3 });
            (job.threads, job.tile, job.samples) = (threads, tile, samples);
            render_into(&job, film).0
        };
        let a = run(1, 16, 0..6, Film::new(s.width, s.height));
        let b = run(2, 7, 0..6, Film::new(s.width, s.height));
        let c = run(2, 5, 4..6, run(1, 9, 0..4, Film::new(s.width, s.height)));
        assert!(a.total_samples() == (s.width * s.height * 6) as u64);
        assert!(a == b, "{name}: threads / tiles change the image");
        assert!(a == c, "{name}: splitting the sample range changes the image");
    }
}
