//! Glass at the extremes of the index (1.0, 1.0001, 4.0) and nested media whose surfaces touch.

use super::support::*;

/// A floor, a lambert ball and a point light, optionally with `extra` shapes (and their materials).
fn stage(materials: &str, extra: &str, background: f32) -> String {
    format!(
        r#"
[image]
width = 48
height = 36
background = [{background}, {background}, {background}]
[camera]
position = [0, 1.6, 5]
look_at = [0, 0.6, 0]
fov = 40
[materials.floor]
type = "lambert"
albedo = [0.6, 0.6, 0.6]
[materials.ball]
type = "lambert"
albedo = [0.8, 0.3, 0.2]
{materials}
[[shapes]]
type = "plane"
point = [0, 0, 0]
normal = [0, 1, 0]
material = "floor"
[[shapes]]
type = "sphere"
center = [1.3, 0.5, -1]
radius = 0.5
material = "ball"
{extra}
[[lights]]
type = "point"
position = [2, 5, 3]
intensity = [30, 30, 30]
"#
    )
}

fn glass(name: &str, ior: f64) -> String {
    format!("[materials.{name}]\ntype = \"dielectric\"\nior = {ior:e}\n")
}

fn sphere(c: [f64; 3], r: f64, m: &str) -> String {
    format!("[[shapes]]\ntype = \"sphere\"\ncenter = {}\nradius = {}\nmaterial = \"{m}\"\n", vec3(c), num(r))
}

fn cube(lo: [f64; 3], hi: [f64; 3], m: &str) -> String {
    format!("[[shapes]]\ntype = \"box\"\nmin = {}\nmax = {}\nmaterial = \"{m}\"\n", vec3(lo), vec3(hi),)
}

/// Index 1.0: the glass sphere must vanish. Shadow rays pass dielectrics (`transmissive_shadows`, else
/// the sphere would cast a shadow that a distribution ray tracer cannot fill in), the light is a point
/// light (no random numbers in the light sample, which is drawn at a different depth behind the
/// sphere). Camera rays go straight through (Fresnel 0, `refract` returns the direction unchanged) and
/// leave the sphere offset by 2 x 256 ULPs, so the floor behind is hit ~1e-4 away from where it
/// would be: the image equals the one without the sphere to float noise (measured: 3e-6 largest
/// difference; bound 1e-4, far below a single sample's worth of any edge, >= 1e-2).
#[test]
fn glass_of_index_one_vanishes() {
    let p = profile(&[("spp", "4"), ("max_depth", "6"), ("transmissive_shadows", "true")]);
    let with = render(&stage(&glass("g", 1.0), &sphere([0.0, 0.8, 0.0], 0.8, "g"), 0.1), p.clone());
    let without = render(&stage(&glass("g", 1.0), "", 0.1), p);
    let d = diff(&without, &with, 1e-4);
    eprintln!("ior 1.0 vs no sphere: {d:?}");
    dump("ior1", &[&without, &with]);
    assert_eq!(d.over, 0, "{d:?}\n{}", diff_map(&without, &with, 1e-4));
}

/// Index 1.0001: nearly invisible (deviations of ~1e-4 rad; from inside, the critical angle is 89.2
/// degrees, met only at the very rim). Measured: largest pixel difference from the empty scene 1e-3,
/// mean 3e-5 of the image mean. Bound: no pixel off by 1e-2, mean below 1e-3.
#[test]
fn glass_of_index_1_0001_is_nearly_invisible() {
    let p = profile(&[("spp", "4"), ("max_depth", "6"), ("transmissive_shadows", "true")]);
    let with = render(&stage(&glass("g", 1.0001), &sphere([0.0, 0.8, 0.0], 0.8, "g"), 0.1), p.clone());
    let without = render(&stage(&glass("g", 1.0001), "", 0.1), p);
    let d = diff(&without, &with, 0.01);
    eprintln!("ior 1.0001 vs no sphere: {d:?}");
    assert!(d.over == 0 && d.mean_rel < 1e-3, "{d:?}\n{}", diff_map(&without, &with, 0.01));
}

/// White furnace for clear dielectrics: background 1, no light, nothing else. With Fresnel roulette a
/// path keeps throughput exactly 1 through every interface, so each sample is 1 (it escaped) or 0 (it
/// hit `max_depth`): no pixel may exceed 1, and with depth 256 the paths cut off must be rare (a sphere
/// cannot trap light by total internal reflection: the internal angle is the same at every bounce).
/// The same with Fresnel splitting: each interface splits the throughput into R and 1 - R, so the
/// expectation is still 1 (Russian roulette below the cut-off is unbiased): mean within 1%.
fn furnace(materials: &str, shapes: &str) -> (f32, f32, f32) {
    let text = format!(
        "[image]\nwidth = 32\nheight = 24\nbackground = [1, 1, 1]\n[camera]\nposition = [0, 0.5, 4]\nlook_at = [0, 0.5, 0]\nfov = 45\n{materials}\n{shapes}"
    );
    let exact = render(&text, profile(&[("spp", "16"), ("max_depth", "256"), ("branching", "roulette"), ("throughput_cutoff", "0")]));
    let split = render(&text, profile(&[("spp", "4"), ("max_depth", "64"), ("branching", "split"), ("throughput_cutoff", "0.01")]));
    (exact.max(), exact.mean().x, split.mean().x)
}

#[test]
fn dielectric_furnace_conserves_energy() {
    for ior in [1.0, 1.0001, 1.5, 4.0] {
        let (max, mean, split) =
            furnace(&glass("g", ior), &(sphere([0.0, 0.5, 0.0], 1.0, "g") + &cube([-1.8, -0.4, -0.5], [-0.8, 0.6, 0.5], "g")));
        eprintln!("furnace ior {ior}: max {max}, mean {mean} (roulette), {split} (split)");
        assert!(max <= 1.0 + 1e-6, "ior {ior}: {max}");
        assert!(mean > 0.999, "ior {ior}: {mean}");
        assert!((split - 1.0).abs() < 0.01, "ior {ior}: {split}");
    }
}

/// Nested media whose surfaces touch, in the furnace: a water sphere inside a glass sphere touching it
/// from inside at one point; two glass spheres touching outside; a glass cube with a water cube resting
/// on it (a shared face); a glass sphere in a glass cube touching all six faces.
#[test]
fn touching_media_in_the_furnace() {
    let m = glass("glass", 1.5) + &glass("water", 1.33);
    let cases = [
        (
            "water sphere touching the inside of a glass sphere",
            sphere([0.0, 0.5, 0.0], 1.0, "glass") + &sphere([0.0, 0.0, 0.0], 0.5, "water"),
        ),
        ("glass spheres touching outside", sphere([-0.6, 0.5, 0.0], 0.6, "glass") + &sphere([0.6, 0.5, 0.0], 0.6, "glass")),
        (
            "water cube on a glass cube",
            cube([-0.8, -0.5, -0.8], [0.8, 0.5, 0.8], "glass") + &cube([-0.8, 0.5, -0.8], [0.8, 1.5, 0.8], "water"),
        ),
        (
            "glass sphere inscribed in a water cube",
            cube([-0.7, -0.2, -0.7], [0.7, 1.2, 0.7], "water") + &sphere([0.0, 0.5, 0.0], 0.7, "glass"),
        ),
    ];
    for (name, shapes) in cases {
        let (max, mean, split) = furnace(&m, &shapes);
        eprintln!("furnace, {name}: max {max}, mean {mean} (roulette), {split} (split)");
        assert!(max <= 1.0 + 1e-6, "{name}: {max}");
        assert!(mean > 0.99, "{name}: {mean}");
        assert!((split - 1.0).abs() < 0.02, "{name}: {split}");
    }
}

/// Two glass blocks of the same index stacked face to face are optically one block, but the renderer
/// does not know that: a ray leaving the lower block is spawned past the shared face, inside the upper
/// block, so its entry there is never seen; the exit is refracted as glass to air and the ray then
/// travels the upper block as if it had entered it from air. A documented limitation (coincident surfaces
/// are ambiguous; `docs/refraction.md` advises overlapping media ranked by `priority` instead; here the
/// side faces of overlapping blocks would coincide in turn), measured against a single block of the same
/// outline, Fresnel split without randomness above the cut-off: a faint seam, 11 of 1728
/// pixels off by more than 0.02 (largest 0.14), mean 0.4%. Checked so that a change is noticed: a fix
/// brings it to 0, a regression past 1% of the pixels fails.
#[test]
fn touching_blocks_of_equal_index_leave_a_faint_seam() {
    let m = glass("a", 1.5) + &glass("b", 1.5);
    let p = profile(&[("spp", "4"), ("max_depth", "10"), ("branching", "split"), ("throughput_cutoff", "0.001")]);
    let stacked = render(
        &stage(&m, &(cube([-0.7, 0.0, -0.5], [0.7, 0.7, 0.5], "a") + &cube([-0.7, 0.7, -0.5], [0.7, 1.4, 0.5], "b")), 0.3),
        p.clone(),
    );
    let single = render(&stage(&m, &cube([-0.7, 0.0, -0.5], [0.7, 1.4, 0.5], "a"), 0.3), p);
    let d = diff(&single, &stacked, 0.02);
    eprintln!("stacked vs single block: {d:?}");
    dump("stacked", &[&single, &stacked]);
    assert!(d.over * 100 <= single.px.len() && d.mean_rel < 0.01, "{d:?}\n{}", diff_map(&single, &stacked, 0.02));
}

/// Beer-Lambert through a 2 mm absorbing glass cube (e^-4 in red) seen head-on against an emissive
/// panel, at the origin and 1 and 1.7 away from it: the centre pixel is `(1 - R)^2 a / (1 - R^2 a^2)`
/// (all inter-reflections, `split` branching) wherever the cube is. Each segment inside the glass used
/// to be counted from the spawned origin, 256 ULPs of the coordinates into the glass: at (1, 1, 1) the
/// cube let through 6.3% too much (a trial's f64 reference), 0.01% after the skipped stretch was
/// absorbed at the spawn.
#[test]
fn absorption_of_a_small_cube_does_not_depend_on_where_it_is() {
    let (sigma, edge) = (2000.0f64, 0.002f64);
    let r = (0.5f64 / 2.5).powi(2);
    let a = (-sigma * edge).exp();
    let want = (1.0 - r).powi(2) * a / (1.0 - r * r * a * a);
    for c in [0.0f64, 1.0, 1.7] {
        let text = format!(
            "[image]\nwidth = 9\nheight = 9\n[camera]\nposition = [{c}, {c}, {z}]\nlook_at = [{c}, {c}, {c}]\nfov = 1.0\n\
             [materials.glass]\ntype = \"dielectric\"\nior = 1.5\nabsorption = [{sigma}, 0.0, 0.0]\n\
             [materials.lamp]\ntype = \"emissive\"\nradiance = [1.0, 1.0, 1.0]\n\
             [[shapes]]\ntype = \"quad\"\norigin = [{q}, {q}, {q}]\nu = [0.01, 0.0, 0.0]\nv = [0.0, 0.01, 0.0]\nmaterial = \"lamp\"\n\
             [[shapes]]\ntype = \"group\"\nmaterial = \"glass\"\n\
             transform = {{ scale = [0.001, 0.001, 0.001], translate = [{c}, {c}, {c}] }}\n\
             children = [ {{ type = \"box\", min = [-1.0, -1.0, -1.0], max = [1.0, 1.0, 1.0] }} ]\n",
            z = c + 0.05,
            q = c - 0.005,
        );
        let img = render(
            &text,
            profile(&[
                ("spp", "1"),
                ("pixel_strategy", "center"),
                ("max_depth", "32"),
                ("branching", "split"),
                ("throughput_cutoff", "1e-6"),
            ]),
        );
        let got = img.at(4, 4).x as f64;
        eprintln!("cube at {c}: {got:.6} against {want:.6}");
        assert!((got / want - 1.0).abs() < 1e-3, "cube at {c}: {got} against {want}");
    }
}
