//! Lens and time integrals: the thin-lens circle of confusion and the exposure fraction of a moving
//! sphere, measured from rendered images.

use super::*;

const W: u32 = 64;
const FOV: f64 = 30.0;
const APERTURE: f64 = 0.25;
const FOCUS: f64 = 5.0;

/// A camera at the origin looking down -z with a thin lens, and one small emissive sphere centred on
/// the ray through the centre of pixel (32, 32), at distance `depth` along the view axis.
fn dof_scene(depth: f64, radius: f64) -> (Scene, PinholeF64) {
    let cam = PinholeF64::new(DVec3::ZERO, DVec3::NEG_Z, DVec3::Y, FOV, W, W);
    let d = cam.dir(32.5, 32.5);
    let centre = d * (depth / d.dot(cam.forward));
    let s = scene(&format!(
        r#"
[image]
width = {W}
height = {W}
[camera]
position = [0.0, 0.0, 0.0]
look_at = [0.0, 0.0, -1.0]
fov = {FOV}
aperture = {APERTURE}
focus_distance = {FOCUS}
[materials.glow]
type = "emissive"
radiance = [1.0, 1.0, 1.0]
[[shapes]]
type = "sphere"
center = {}
radius = {radius}
material = "glow"
"#,
        v3(centre)
    ));
    (s, cam)
}

#[test]
fn point_in_focus_images_to_one_pixel() {
    // Radius 0.01 projects to 0.24 px around the centre of pixel (32, 32).
    let (s, _) = dof_scene(FOCUS, 0.01);
    let (img, _) = render_image(&s, &profile(64, "jittered", 1, "jittered"), 3);
    let lit: Vec<usize> = (0..img.len()).filter(|&i| img[i].x > 0.0).collect();
    eprintln!("in focus: lit pixels {:?}", lit.iter().map(|i| (i % W as usize, i / W as usize)).collect::<Vec<_>>());
    assert_eq!(lit, vec![32 * W as usize + 32], "an in-focus point must light exactly pixel (32, 32)");
}

#[test]
fn point_off_focus_spreads_to_thin_lens_circle_of_confusion() {
    let (depth, radius) = (2.0, 0.04);
    let (s, cam) = dof_scene(depth, radius);
    let (img, _) = render_image(&s, &profile(256, "jittered", 1, "jittered"), 3);
    // Thin lens: the rays from the lens disk (radius A) through a point at depth z meet the plane of
    // focus F in a disk of radius A |1 - F / z|; the image maps that plane to pixels at
    // `pixel_size_at(F)` world units per pixel.
    let pix = cam.pixel_size_at(FOCUS);
    let coc = 2.0 * APERTURE * (1.0 - FOCUS / depth).abs() / pix;
    // The image is the CoC disk convolved with the sphere's own disk (radius r F / z on the plane of
    // focus) and binned into pixels: per-axis variances add, R^2/4 + rp^2/4 + 1/12 (Sheppard).
    let rp = radius * FOCUS / depth / pix;
    let (mut s0, mut sx, mut sy) = (0.0, 0.0, 0.0);
    for (i, v) in img.iter().enumerate() {
        let (x, y, w) = ((i % W as usize) as f64 + 0.5, (i / W as usize) as f64 + 0.5, v.x as f64);
        s0 += w;
        sx += w * x;
        sy += w * y;
    }
    let (cx, cy) = (sx / s0, sy / s0);
    let m2: f64 = img
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let (x, y) = ((i % W as usize) as f64 + 0.5 - cx, (i / W as usize) as f64 + 0.5 - cy);
            v.x as f64 * (x * x + y * y)
        })
        .sum::<f64>()
        / (2.0 * s0);
    let measured = 4.0 * (m2 - rp * rp / 4.0 - 1.0 / 12.0).sqrt();
    // Second check, independent of the moment model: the area lit above half the plateau.
    let plateau = {
        let mut v: Vec<f64> = img.iter().map(|p| p.x as f64).filter(|&x| x > 0.0).collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2..].iter().sum::<f64>() / (v.len() - v.len() / 2) as f64
    };
    let area = img.iter().filter(|p| p.x as f64 > 0.5 * plateau).count() as f64;
    let from_area = 2.0 * (area / std::f64::consts::PI).sqrt();
    eprintln!(
        "off focus: centroid ({cx:.2}, {cy:.2}); CoC thin lens {coc:.3} px, from second moment {measured:.3} px, from half-max area {from_area:.3} px"
    );
    assert!((cx - 32.5).abs() < 0.3 && (cy - 32.5).abs() < 0.3, "blur disk not centred on the point's image");
    assert!((measured / coc - 1.0).abs() < 0.05, "CoC from moments {measured:.3} px vs thin lens {coc:.3} px");
    // The plateau is noisy (few lens samples per pixel hit the sphere), hence a looser check here.
    assert!((from_area / coc - 1.0).abs() < 0.1, "CoC from area {from_area:.3} px vs thin lens {coc:.3} px");
}

/// Fraction of the shutter [0, 1] during which the line through the origin along unit `d` passes
/// within `r` of the centre `c0 + v t`.
fn exposure_fraction(d: DVec3, c0: DVec3, v: DVec3, r: f64) -> f64 {
    let a = c0 - d * c0.dot(d);
    let b = v - d * v.dot(d);
    let (qa, qb, qc) = (b.dot(b), 2.0 * a.dot(b), a.dot(a) - r * r);
    let disc = qb * qb - 4.0 * qa * qc;
    if disc <= 0.0 {
        return 0.0;
    }
    let (t0, t1) = ((-qb - disc.sqrt()) / (2.0 * qa), (-qb + disc.sqrt()) / (2.0 * qa));
    (t1.min(1.0) - t0.max(0.0)).max(0.0)
}

#[test]
fn moving_sphere_exposure_matches_analytic_fraction() {
    let (w, h) = (48u32, 6u32);
    let cam = PinholeF64::new(DVec3::ZERO, DVec3::NEG_Z, DVec3::Y, 12.0, w, h);
    // Across most of the image in one shutter interval: the BVH must bound the whole sweep.
    let (c0, v, r) = (DVec3::new(-2.0, 0.02, -6.0), DVec3::new(3.6, 0.05, 0.4), 0.22);
    let s = scene(&format!(
        r#"
[image]
width = {w}
height = {h}
[camera]
position = [0.0, 0.0, 0.0]
look_at = [0.0, 0.0, -1.0]
fov = 12.0
shutter = [0.0, 1.0]
[materials.glow]
type = "emissive"
radiance = [1.0, 1.0, 1.0]
[[shapes]]
type = "sphere"
center = {}
radius = {r}
motion = {}
material = "glow"
"#,
        v3(c0),
        v3(v)
    ));
    assert!(s.features.motion);
    let n = 256u32;
    for strategy in ["jittered", "grid"] {
        let mut p = profile(n, "center", 1, "jittered");
        p.set("time_strategy", strategy).unwrap();
        let (img, _) = render_image(&s, &p, 9);
        let (mut worst, mut covered, mut columns) = (0.0f64, 0, std::collections::BTreeSet::new());
        for y in 0..h {
            for x in 0..w {
                let f = exposure_fraction(cam.dir(x as f64 + 0.5, y as f64 + 0.5), c0, v, r);
                if f > 0.0 {
                    covered += 1;
                    columns.insert(x);
                }
                worst = worst.max((img[(y * w + x) as usize].x as f64 - f).abs());
            }
        }
        eprintln!(
            "motion, time {strategy}: {covered} pixels in {} columns crossed, worst |image - exposure fraction| {worst:.2e}",
            columns.len()
        );
        assert!(columns.len() > 15, "the sphere must sweep many pixel columns ({})", columns.len());
        // Stratified time samples: only the (at most two) strata holding an entry or exit time can be
        // wrong, by at most one stratum each.
        assert!(worst <= 2.0 / n as f64 + 1e-5, "{strategy}: worst error {worst:.3e} above 2 / {n}");
    }
}

/// A shutter of no length at time `t0 != 0` (`shutter = [0.5, 0.5]`) shows each moving prim where it is
/// at `t0`: the same image as the scene with the prims placed there and no motion. (The motion feature
/// was off for such a shutter, so prims were tested at time 0 inside bounds swept at `t0`: clipped.)
#[test]
fn an_instant_shutter_places_moving_prims_at_its_time() {
    let text = |shutter: &str, offset: f64, motion: bool| {
        let m = |v: &str| if motion { format!("motion = {v}\n") } else { String::new() };
        format!(
            "[image]\nwidth = 40\nheight = 30\n[camera]\nposition = [0, 0, 0]\nlook_at = [0, 0, -1]\nfov = 40\nshutter = {shutter}\n\
             [materials.glow]\ntype = \"emissive\"\nradiance = [1, 1, 1]\n\
             [materials.dim]\ntype = \"emissive\"\nradiance = [0.3, 0.5, 0.2]\n\
             [[shapes]]\ntype = \"sphere\"\ncenter = [{}, 0.3, -6]\nradius = 0.8\nmaterial = \"glow\"\n{}\
             [[shapes]]\ntype = \"box\"\nmin = [-0.5, {}, -7]\nmax = [0.5, {}, -6]\nmaterial = \"dim\"\n{}",
            -1.5 + 2.0 * offset,
            m("[2, 0, 0]"),
            -1.6 - 1.2 * offset,
            -0.9 - 1.2 * offset,
            m("[0, -1.2, 0]")
        )
    };
    let p = profile(1, "center", 1, "center");
    for t0 in [0.5, 1.0] {
        let moving = scene(&text(&format!("[{t0}, {t0}]"), 0.0, true));
        let placed = scene(&text("[0, 0]", t0, false));
        assert!(!placed.features.motion);
        let (a, _) = render_image(&moving, &p, 1);
        let (b, _) = render_image(&placed, &p, 1);
        let lit = b.iter().filter(|c| c.max_element() > 0.0).count();
        let differ = a.iter().zip(&b).filter(|(x, y)| (**x - **y).abs().max_element() > 1e-3).count();
        assert!(lit > 100, "the prims cover {lit} pixels");
        // (A silhouette pixel may flip: the moving sphere's test shifts the ray, not the sphere.)
        assert!(differ <= 2, "shutter [{t0}, {t0}]: {differ} of {lit} lit pixels differ from the placed prims");
    }
}
