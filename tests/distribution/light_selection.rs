//! Light selection (`light_selection`: one light picked per shading point, divided by its probability)
//! against ground truth: a Lambert plane under several quad lights, whose radiance is the sum of each
//! light's Lambert polygon irradiance; and on a glossy floor, where lobe rays find the lights too and the
//! MIS weights must count the pick's probability, against the render that samples every light.

use super::irradiance::{floor, mean_rel_error, polygon_irradiance, receiver_text, ALBEDO, SIZE};
use super::*;
use strata::film::Film;
use strata::scene::LightSelection;

/// Quad lights in one plane above the floor camera (none shades another), as origin, u, v, radiance:
/// all facing down but the last, which faces up and gives the floor nothing; broad dim ones, a small
/// one and a tiny bright one.
/// A quad light: origin, u, v and (grey) radiance.
type QuadLight = ([f64; 3], [f64; 3], [f64; 3], f64);

const LIGHTS: [QuadLight; 5] = [
    ([-0.8, 1.5, -0.5], [0.4, 0.0, 0.0], [0.0, 0.0, 0.4], 2.0),
    ([0.5, 1.5, 0.2], [0.3, 0.0, 0.0], [0.0, 0.0, 0.3], 6.0),
    ([-0.2, 1.5, 0.6], [0.1, 0.0, 0.0], [0.0, 0.0, 0.1], 50.0),
    ([0.3, 1.5, -0.9], [0.9, 0.0, 0.0], [0.0, 0.0, 0.6], 0.7),
    ([1.5, 1.5, 0.0], [0.0, 0.0, 0.5], [0.5, 0.0, 0.0], 5.0),
];

fn lights_text() -> String {
    LIGHTS
        .iter()
        .map(|(o, u, v, l)| {
            let f = |a: &[f64; 3]| v3(DVec3::from_array(*a));
            format!("[[lights]]\ntype = \"quad\"\norigin = {}\nu = {}\nv = {}\nradiance = [{l}, {l}, {l}]\n", f(o), f(u), f(v))
        })
        .collect()
}

/// The floor scene and, per pixel (through its centre), `albedo / pi x sum_l L_l E_l(p)`.
fn many_lights() -> (Scene, Vec<DVec3>) {
    let rc = floor();
    let c = &rc.cam;
    let text = receiver_text(&rc, &lights_text());
    let mut truth = Vec::new();
    for y in 0..SIZE {
        for x in 0..SIZE {
            let d = c.dir(x as f64 + 0.5, y as f64 + 0.5);
            let p = c.pos + d * (-c.pos.y / d.y);
            let mut e = 0.0;
            for (o, u, v, l) in LIGHTS {
                let (o, u, v) = (DVec3::from_array(o), DVec3::from_array(u), DVec3::from_array(v));
                if u.cross(v).y < 0.0 {
                    e += l * polygon_irradiance(p, DVec3::Y, &[o, o + u, o + u + v, o + v]);
                }
            }
            truth.push(DVec3::from_array(ALBEDO) * (e / std::f64::consts::PI));
        }
    }
    (scene(&text), truth)
}

fn with_selection(mut p: Profile, mode: LightSelection) -> Profile {
    p.light_selection = mode;
    p
}

/// Per pixel, |mean - truth| in standard errors of the mean (largest channel), and their mean square.
fn z_scores(film: &Film, truth: &[DVec3]) -> (f64, f64) {
    let zs: Vec<f64> = film
        .pixels()
        .zip(truth)
        .map(|(px, t)| ((px.mean().as_dvec3() - *t) / px.variance_of_mean().as_dvec3().max(DVec3::splat(1e-30)).sqrt()).abs().max_element())
        .collect();
    let worst = zs.iter().copied().fold(0.0, f64::max);
    (worst, zs.iter().map(|z| z * z).sum::<f64>() / zs.len() as f64)
}

/// Every selection is unbiased: with independent (random) numbers each pixel lies within its noise of
/// the closed form (E[z^2] is about 1 for an unbiased pixel; the largest channel of three is taken, so
/// somewhat above), and with stratified (jittered) ones the image mean is within 1%. A pick that
/// forgot its probability, or a light wrongly never picked, is off by far more.
#[test]
fn picked_lights_sum_to_lambert_polygon_irradiance() {
    let (s, truth) = many_lights();
    assert_eq!(s.lights.len(), 5);
    for mode in LightSelection::ALL {
        let p = with_selection(profile(256, "center", 1, "random"), mode);
        let (film, stats) = render(&s, Settings { profile: p, seed: 17 }, 0);
        assert_eq!(stats.nonfinite_samples, 0);
        let (worst, mean_z2) = z_scores(&film, &truth);
        let e = mean_rel_error(&film.to_rgb(), &truth);
        let (img, stats) = render_image(&s, &with_selection(profile(64, "center", 1, "jittered"), mode), 17);
        let ej = mean_rel_error(&img, &truth);
        eprintln!(
            "{:>7}: random: mean rel. error {e:.2e}, mean z^2 {mean_z2:.3}, worst |z| {worst:.2}; jittered: mean rel. error {ej:.2e}, {} shadow rays",
            mode.name(),
            (stats.rays.shadow + stats.rays.shadow_cleared)
        );
        assert!(mean_z2 < 1.6, "{}: mean z^2 {mean_z2:.2}: pixels are off by more than their noise", mode.name());
        assert!(worst < 8.0, "{}: a pixel is {worst:.1} standard errors off", mode.name());
        assert!(e < 0.01 && ej < 0.01, "{}: image mean off by {:.3}% (random), {:.3}% (jittered)", mode.name(), e * 100.0, ej * 100.0);
        // One light per shading point (the lit floor's 64 x 1024 points), against all five.
        let per_point = (stats.rays.shadow + stats.rays.shadow_cleared) as f64 / (64.0 * 1024.0);
        let expect = if mode == LightSelection::All { 4.0 } else { 1.0 };
        assert!(per_point <= expect + 1e-9, "{}: {per_point} shadow rays per point", mode.name());
    }
}

/// A glossy floor reflecting quad lights: its light is sampled by the lights (picked) and by the lobe,
/// weighted by MIS. The weights must use the pick's probability on both sides; the render that picks
/// then equals the one that samples every light within their noise, pixel by pixel. Behind it a Lambert
/// wall, lit at grazing angles by a point light 0.05 in front of it and a sphere light on the floor
/// below it: `local`'s horizon test must not leave out a light that reaches a point.
#[test]
fn glossy_mis_counts_the_pick_probability() {
    let text = r#"
[image]
width = 40
height = 30
[camera]
position = [0.0, 1.0, 3.0]
look_at = [0.0, 0.2, -0.5]
fov = 50.0
[materials.floor]
type = "glossy"
tint = [0.9, 0.9, 0.9]
roughness = 0.35
[[shapes]]
type = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 1.0, 0.0]
material = "floor"
[[lights]]
type = "quad"
origin = [-1.2, 1.3, -2.0]
u = [0.6, 0.0, 0.0]
v = [0.0, 0.0, 0.6]
radiance = [3.0, 3.0, 3.0]
[[lights]]
type = "quad"
origin = [0.3, 0.8, -1.6]
u = [0.25, 0.0, 0.0]
v = [0.0, 0.0, 0.25]
radiance = [12.0, 6.0, 3.0]
[[lights]]
type = "disk"
center = [1.0, 1.6, -2.5]
normal = [0.0, -1.0, 0.3]
radius = 0.4
radiance = [2.0, 3.0, 6.0]
[[lights]]
type = "point"
position = [0.0, 2.0, 0.5]
intensity = [1.0, 1.0, 1.0]
[materials.wall]
type = "lambert"
albedo = [0.7, 0.7, 0.7]
[[shapes]]
type = "quad"
origin = [-3.0, 0.0, -3.2]
u = [6.0, 0.0, 0.0]
v = [0.0, 2.5, 0.0]
material = "wall"
[[lights]]
type = "point"
position = [0.4, 1.0, -3.15]
intensity = [0.3, 0.3, 0.3]
[[lights]]
type = "sphere"
center = [-1.5, 0.05, -3.0]
radius = 0.15
radiance = [3.0, 3.0, 3.0]
"#;
    let s = scene(text);
    let run = |mode: LightSelection| {
        let p = with_selection(profile(1024, "center", 1, "random"), mode);
        let (film, stats) = render(&s, Settings { profile: p, seed: 23 }, 0);
        assert_eq!(stats.nonfinite_samples, 0);
        film
    };
    let all = run(LightSelection::All);
    let all_px: Vec<_> = all.pixels().collect();
    let lit = all_px.iter().filter(|p| p.mean().max_element() > 0.05).count();
    assert!(lit > 300, "the floor reflects the lights ({lit} lit pixels)");
    for mode in [LightSelection::Uniform, LightSelection::Power, LightSelection::Local, LightSelection::Tree] {
        let film = run(mode);
        // (Pixels whose light is below 1e-3 are left out: the film's fixed-point squares cannot hold
        // their variance.)
        let zs: Vec<f64> = film
            .pixels()
            .zip(&all_px)
            .filter(|(_, b)| b.mean().max_element() > 1e-3)
            .map(|(a, b)| {
                let v = (a.variance_of_mean() + b.variance_of_mean()).as_dvec3().max(DVec3::splat(1e-30));
                ((a.mean() - b.mean()).as_dvec3() / v.sqrt()).abs().max_element()
            })
            .collect();
        let worst = zs.iter().copied().fold(0.0, f64::max);
        let mean_z2 = zs.iter().map(|z| z * z).sum::<f64>() / zs.len() as f64;
        let m = |f: &Film| f.to_rgb().iter().map(|c| c.as_dvec3()).sum::<DVec3>();
        let rel = ((m(&film) - m(&all)) / m(&all)).abs().max_element();
        eprintln!(
            "glossy floor, {:>7} against all: image mean rel. difference {rel:.2e}, mean z^2 {mean_z2:.3}, worst |z| {worst:.2} ({} pixels)",
            mode.name(),
            zs.len()
        );
        assert!(mean_z2 < 1.6, "{}: mean z^2 {mean_z2:.2}", mode.name());
        assert!(worst < 8.0, "{}: a pixel is {worst:.1} standard errors off", mode.name());
        assert!(rel < 0.01, "{}: image mean differs by {:.3}%", mode.name(), rel * 100.0);
    }
}

/// Lamps under an opaque roof, and above it a sun 1e13 times as powerful as a lamp: the importances
/// of `local` and `tree` know no visibility, so nearly every pick goes to the blocked sun. Their
/// uniform floor (5% of the picks, as `power`'s) keeps each lamp's probability at about 0.3%, and the
/// roofed floor converges to the lamps' irradiance `sum_l I cos / d^2`. Without the floor a lamp's
/// probability was about 1e-9: the image came out black, or black with a firefly of weight 1e9.
#[test]
fn a_blocked_sun_leaves_the_lamps_it_outshines_sampled() {
    let rc = floor();
    let c = &rc.cam;
    let lamps: Vec<DVec3> = (0..16).map(|i| DVec3::new(-1.5 + (i % 4) as f64, 1.4, -1.5 + (i / 4) as f64)).collect();
    const I: f64 = 0.05;
    let mut lights: String =
        lamps.iter().map(|p| format!("[[lights]]\ntype = \"point\"\nposition = {}\nintensity = [{I}, {I}, {I}]\n", v3(*p))).collect();
    lights += "[[lights]]\ntype = \"quad\"\norigin = [-20.0, 100.0, -20.0]\nu = [40.0, 0.0, 0.0]\nv = [0.0, 0.0, 40.0]\nradiance = [1e9, 1e9, 1e9]\n";
    lights += "[materials.roof]\ntype = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\n[[shapes]]\ntype = \"box\"\nmin = [-30.0, 1.6, -30.0]\nmax = [30.0, 1.8, 30.0]\nmaterial = \"roof\"\n";
    let s = scene(&receiver_text(&rc, &lights));
    let mut truth = Vec::new();
    for y in 0..SIZE {
        for x in 0..SIZE {
            let d = c.dir(x as f64 + 0.5, y as f64 + 0.5);
            let p = c.pos + d * (-c.pos.y / d.y);
            let e: f64 = lamps.iter().map(|&l| I * (l - p).y / (l - p).length().powi(3)).sum();
            truth.push(DVec3::from_array(ALBEDO) * (e / std::f64::consts::PI));
        }
    }
    for mode in [LightSelection::All, LightSelection::Power, LightSelection::Local, LightSelection::Tree] {
        let (img, _) = render_image(&s, &with_selection(profile(256, "jittered", 1, "jittered"), mode), 29);
        let e = mean_rel_error(&img, &truth);
        eprintln!("{:>7}: roofed floor's mean off by {:.2}%", mode.name(), e * 100.0);
        assert!(e < 0.05, "{}: the roofed floor's mean is off by {:.1}%", mode.name(), e * 100.0);
    }
}

/// A scene whose lights are edited in place between renders renders as the edited scene parsed anew,
/// in every mode: each render makes its light selection and the shadow stage's per-light tables again
/// (a selection kept in the scene across renders had left a light brightened in place at its old
/// probability 0: a mean of 0.76 where 13.1 was right).
#[test]
fn lights_edited_in_place_between_renders_are_seen() {
    let text = |dim: f64, quad: f64| {
        format!(
            r#"
[image]
width = 24
height = 16
[camera]
position = [0.0, 1.5, 3.0]
look_at = [0.0, 0.0, 0.0]
fov = 60.0
[materials.ground]
type = "lambert"
albedo = [0.6, 0.6, 0.6]
[[shapes]]
type = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 1.0, 0.0]
material = "ground"
[[lights]]
type = "point"
position = [-1.0, 1.0, 0.0]
intensity = [{dim}, {dim}, {dim}]
[[lights]]
type = "point"
position = [1.0, 1.0, 0.0]
intensity = [1.0, 1.0, 1.0]
[[lights]]
type = "quad"
origin = [-0.5, 2.0, -1.5]
u = [1.0, 0.0, 0.0]
v = [0.0, 0.0, 1.0]
radiance = [{quad}, {quad}, {quad}]
"#
        )
    };
    for mode in LightSelection::ALL {
        let p = with_selection(profile(16, "jittered", 2, "jittered"), mode);
        let mut edited = scene(&text(0.0, 1.0));
        let before = render(&edited, Settings { profile: p.clone(), seed: 3 }, 2).0.to_rgb();
        // The first lamp from dark to bright; the quad 10x (its light and its emitter's material).
        edited.lights[0] = strata::scene::Light::Point { position: Vec3::new(-1.0, 1.0, 0.0), intensity: Vec3::splat(1000.0) };
        if let strata::scene::Light::Quad { radiance, .. } = &mut edited.lights[2] {
            *radiance = Vec3::splat(10.0);
        }
        let quad_prim = edited.light_of_prim.iter().position(|&l| l == 2).expect("the quad's prim");
        let m = edited.prims[quad_prim].material as usize;
        edited.materials[m] = strata::scene::Material::Emissive { radiance: Vec3::splat(10.0) };
        let after = render(&edited, Settings { profile: p.clone(), seed: 3 }, 2).0.to_rgb();
        let fresh = render(&scene(&text(1000.0, 10.0)), Settings { profile: p, seed: 3 }, 2).0.to_rgb();
        assert!(after != before, "{}: the edit changes the image", mode.name());
        assert!(after == fresh, "{}: the edited scene renders as the same scene parsed anew", mode.name());
    }
}
