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
