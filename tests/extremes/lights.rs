//! Lights of zero size (input errors), tiny size (they converge to the point-light limit) and huge
//! size (a sphere light larger than the scene, against the analytic irradiance).

use super::support::*;
use glam::DVec3;
use std::f64::consts::PI;
use std::path::Path;
use strata::scene::parse_scene;

/// A lambert floor (albedo 0.5) seen from above, optionally a unit ball on it, and `light`.
fn floor_scene(light: &str, ball: bool) -> String {
    let ball = if ball { "[[shapes]]\ntype = \"sphere\"\ncenter = [0, 1, 0]\nradius = 1\nmaterial = \"m\"\n" } else { "" };
    format!(
        "[image]\nwidth = 48\nheight = 36\n[camera]\nposition = [0, 4, 6]\nlook_at = [0, 0, 0]\nfov = 50\n\
         [materials.m]\ntype = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\n\
         [[shapes]]\ntype = \"plane\"\npoint = [0, 0, 0]\nnormal = [0, 1, 0]\nmaterial = \"m\"\n{ball}[[lights]]\n{light}\n"
    )
}

/// Zero size is an input error: an area light of zero area emits nothing, which is never what a scene
/// means (a point light is the zero-size light). The error names the file, the line and the field.
#[test]
fn zero_size_lights_are_input_errors() {
    let cases = [
        ("type = \"sphere\"\ncenter = [0, 3, 0]\nradius = 0\nradiance = [1, 1, 1]", "lights[0].radius", "radius"),
        ("type = \"disk\"\ncenter = [0, 3, 0]\nnormal = [0, -1, 0]\nradius = 0.0\nradiance = [1, 1, 1]", "lights[0].radius", "radius"),
        // (The zero edge itself is named.)
        ("type = \"quad\"\norigin = [0, 3, 0]\nu = [0, 0, 0]\nv = [0, 0, 1]\nradiance = [1, 1, 1]", "lights[0].u", "u ="),
        ("type = \"quad\"\norigin = [0, 3, 0]\nu = [1, 0, 0]\nv = [2, 0, 0]\nradiance = [1, 1, 1]", "lights[0].v", "v ="),
        ("type = \"disk\"\ncenter = [0, 3, 0]\nnormal = [0, 0, 0]\nradius = 1\nradiance = [1, 1, 1]", "lights[0].normal", "normal"),
    ];
    for (light, field, key) in cases {
        let text = floor_scene(light, false);
        let e = match parse_scene(Path::new("lights.toml"), &text) {
            Ok(_) => panic!("accepted a zero-size light:\n{light}"),
            Err(e) => e,
        };
        let lights_at = text.lines().position(|l| l == "[[lights]]").unwrap();
        let line = lights_at + text.lines().skip(lights_at).position(|l| l.starts_with(key)).unwrap() + 1;
        eprintln!("{e}");
        assert_eq!((e.field.as_str(), e.line), (field, line), "{e}");
        assert!(e.to_string().starts_with(&format!("lights.toml:{line}:")), "{e}");
    }
}

/// A sphere light of radius r and radiance I / (pi r^2) has intensity I in every direction, exactly:
/// the irradiance it gives a surface that sees all of it is that of a point light I at its centre.
/// So r -> 0 must converge to the point light (the ball's shadow softens by only ~r). Measured: mean
/// difference 7e-6, 7e-7, 8e-8 of the image mean at r = 1e-3, 1e-4, 1e-5, largest pixel difference
/// 5e-6 (before the cone sampling used 1 - cos = sin^2 / (1 + cos), the image was 2.3x too bright at
/// r = 1e-3, black at 1e-4 and 68x too bright at 1e-6). Bound: mean 1e-4, at most one pixel off by more
/// than 1e-3 (a sample at the shadow edge may flip when the light's size changes).
#[test]
fn tiny_sphere_lights_converge_to_a_point_light() {
    let p = profile(&[("spp", "4"), ("light_samples", "4")]);
    let point = render(&floor_scene("type = \"point\"\nposition = [2, 5, 3]\nintensity = [20, 20, 20]", true), p.clone());
    for r in [1e-3, 1e-4, 1e-5] {
        let l = 20.0 / (PI * r * r);
        let light = format!("type = \"sphere\"\ncenter = [2, 5, 3]\nradius = {}\nradiance = {}", num(r), vec3([l; 3]));
        let img = render(&floor_scene(&light, true), p.clone());
        let d = diff(&point, &img, 1e-3);
        eprintln!("sphere light r = {r:e}: {d:?}");
        assert!(d.mean_rel < 1e-4 && d.over <= 1, "r = {r:e}: {d:?}\n{}", diff_map(&point, &img, 1e-3));
    }
}

/// Tiny quad and disk lights (sides 1e-3 and 1e-5, facing down) over a bare floor: every pixel has the
/// analytic radiance rho / pi * L A cos_l cos / d^2 (the light is far smaller than its distance, ~4).
/// Measured: 2.2e-4 relative at side 1e-3 (the light's extent), 1.2e-5 at 1e-5; bound 1e-3.
#[test]
fn tiny_quad_and_disk_lights_have_analytic_radiance() {
    let c = DVec3::new(0.5, 4.0, -0.5);
    for size in [1e-3, 1e-5] {
        let l = 1.0 / (size * size);
        let lights = [
            (
                format!(
                    "type = \"quad\"\norigin = {}\nu = {}\nv = {}\nradiance = {}",
                    vec3([c.x - size / 2.0, c.y, c.z - size / 2.0]),
                    vec3([size, 0.0, 0.0]),
                    vec3([0.0, 0.0, size]),
                    vec3([l; 3])
                ),
                size * size,
            ),
            (
                format!(
                    "type = \"disk\"\ncenter = {}\nnormal = [0, -1, 0]\nradius = {}\nradiance = {}",
                    vec3(c.to_array()),
                    num(size),
                    vec3([l; 3])
                ),
                PI * size * size,
            ),
        ];
        for (light, area) in lights {
            let scene = parse(&floor_scene(&light, false));
            let img = render_scene(&scene, profile(&[("spp", "1"), ("pixel_strategy", "center"), ("light_samples", "4")]));
            let mut worst = 0.0f64;
            for y in 0..img.height {
                for x in 0..img.width {
                    let (o, d) = scene.camera.ray(x as f32 + 0.5, y as f32 + 0.5, [0.0, 0.0]);
                    let (o, d) = (o.as_dvec3(), d.as_dvec3());
                    if d.y >= 0.0 {
                        continue;
                    }
                    let p = o + d * (-o.y / d.y);
                    let v = c - p;
                    let cos = v.y / v.length();
                    let e = 0.5 / PI * l * area * cos * cos / v.length_squared();
                    worst = worst.max((img.at(x, y).x as f64 - e).abs() / e);
                }
            }
            eprintln!("light of size {size:e} ({}): worst rel {worst:.2e}", &light[6..10]);
            assert!(worst < 1e-3, "{light}: {worst}");
        }
    }
}

/// A sphere light of radius 1e3 and 1e5 hanging 6 above the floor (the camera is at 4): it fills 84 and 89.6 degrees of the
/// sky, and the floor under it must get E = pi L sin^2(alpha) cos(theta) (alpha: the half-angle it
/// subtends, theta: the angle of its centre from the normal; exact while it is all above the horizon,
/// true for every visible floor point). Floor radiance rho L sin^2(alpha) cos(theta), against the image
/// mean (cone sampling: per-sample noise only from the cosine over the cone, ~30%; 64 samples per
/// pixel, 1728 pixels: the mean is good to 0.1%; bound 1%). Also: every pixel within 20% of its own
/// analytic value (its 64 samples: ~4% noise).
#[test]
fn huge_sphere_light_gives_the_analytic_irradiance() {
    for r in [1e3, 1e5] {
        let c = DVec3::new(0.0, r + 6.0, 0.0);
        let light = format!("type = \"sphere\"\ncenter = {}\nradius = {}\nradiance = [2, 2, 2]", vec3(c.to_array()), num(r));
        let scene = parse(&floor_scene(&light, false));
        let img = render_scene(&scene, profile(&[("spp", "4"), ("light_samples", "16")]));
        // The compiled centre and radius (f32), in f64.
        let strata::scene::Light::Sphere { center, radius, .. } = scene.lights[0] else { unreachable!() };
        let (c, r) = (center.as_dvec3(), radius as f64);
        let (mut sum_v, mut sum_e, mut worst) = (0.0, 0.0, 0.0f64);
        for y in 0..img.height {
            for x in 0..img.width {
                let (o, d) = scene.camera.ray(x as f32 + 0.5, y as f32 + 0.5, [0.0, 0.0]);
                let (o, d) = (o.as_dvec3(), d.as_dvec3());
                let p = o + d * (-o.y / d.y);
                let v = c - p;
                let sin2 = (r / v.length()).powi(2);
                let e = 0.5 * 2.0 * sin2 * (v.y / v.length());
                let px = img.at(x, y).x as f64;
                sum_v += px;
                sum_e += e;
                worst = worst.max((px - e).abs() / e);
            }
        }
        eprintln!("sphere light r = {r:e}: image mean {:.5}, analytic {:.5}, worst pixel {worst:.3}", sum_v / 1728.0, sum_e / 1728.0);
        assert!((sum_v / sum_e - 1.0).abs() < 0.01, "r = {r:e}: {sum_v} vs {sum_e}");
        assert!(worst < 0.2, "r = {r:e}: {worst}");
    }
}

/// A quad light 1e4 on a side, 10 above the floor, emitting down: the floor's irradiance is pi L to
/// 0.2%, but uniform area sampling finds the part of the light that matters (within a few tens of
/// units) with probability ~1e-5 per sample: the estimate is unbiased and useless at practical sample
/// counts (a documented limit: use a sphere light for a sky-sized emitter, it is sampled by solid
/// angle). What must hold is robustness: finite (checked by render), and no pixel brighter than one
/// sample can make it: rho / pi * L * A / h^2.
#[test]
fn huge_quad_light_stays_finite() {
    let light = "type = \"quad\"\norigin = [-5e3, 10, -5e3]\nu = [1e4, 0, 0]\nv = [0, 0, 1e4]\nradiance = [1, 1, 1]";
    let img = render(&floor_scene(light, true), profile(&[("spp", "4"), ("light_samples", "4")]));
    eprintln!("huge quad light: image mean {} (pi L rho / pi = 0.5 expected), max {}", img.mean().x, img.max());
    assert!(img.max() as f64 <= 0.5 / PI * 1e8 / 100.0);
}

/// Light so dim that the film's fixed point (each sample rounded to 2^-32) shows is warned of, and the
/// warning's bound holds: a point light scaled by 1e-9 renders each pixel within 2^-33 of 1e-9 times
/// the unit-scale image (rounding moves pixels by more than 1% here: the warning is not idle), and the
/// brightest pixel within the percentage the warning states; scaled by 1e-20 every pixel is 0 and the
/// warning says so; at unit scale there is none.
#[test]
fn light_below_the_films_resolution_is_warned_of() {
    use strata::film::{dim_warning, Film};
    use strata::render::{render_into, RenderJob};
    use strata::wavefront::Settings;
    let film_at = |scale: f64| {
        let light = format!("type = \"point\"\nposition = [0, 3, 0]\nintensity = [{0:e}, {0:e}, {0:e}]", 10.0 * scale);
        let scene = parse(&floor_scene(&light, false));
        let mut job = RenderJob::new(&scene, Settings { profile: profile(&[("spp", "4")]), seed: SEED });
        job.threads = 2;
        render_into(&job, Film::new(scene.width, scene.height)).0
    };
    let unit = film_at(1.0);
    assert_eq!(dim_warning(&unit, true), None);
    let dim = film_at(1e-9);
    let w = dim_warning(&dim, true).expect("a warning at 1e-9");
    assert!(w.starts_with("the brightest pixel is "), "{w}");
    let stated: f64 = w.split("off by up to ").nth(1).and_then(|r| r.split('%').next()).unwrap().parse().unwrap();
    let (mut moved, mut brightest) = (0usize, (0.0f64, 0.0f64));
    for (a, b) in unit.to_rgb().iter().zip(dim.to_rgb()) {
        for c in 0..3 {
            let (want, got) = (a[c] as f64 * 1e-9, b[c] as f64);
            assert!((got - want).abs() <= 0.5 / 4_294_967_296.0 + 1e-5 * want, "{got:e} against {want:e}");
            moved += ((got - want).abs() > 0.01 * want) as usize;
            if want > brightest.0 {
                brightest = (want, got);
            }
        }
    }
    assert!(moved > 0, "no pixel moved by 1%: the warning would be idle");
    let off = 100.0 * (brightest.1 - brightest.0).abs() / brightest.0;
    assert!(off <= stated + 0.01, "brightest pixel off by {off:.3}%, the warning says up to {stated}%");
    let black = film_at(1e-20);
    assert!(black.to_rgb().iter().all(|p| *p == glam::Vec3::ZERO));
    assert!(dim_warning(&black, true).is_some_and(|w| w.starts_with("every pixel of the image is 0")));
    // A scene without light is black as it should be: no warning.
    assert_eq!(dim_warning(&black, false), None);
    assert!(parse(&floor_scene("type = \"point\"\nposition = [0, 3, 0]\nintensity = [1, 1, 1]", false)).has_light());
    let unlit = floor_scene("", false).replace("[[lights]]\n", "");
    assert!(!parse(&unlit).has_light(), "{unlit}");
}
