//! CSG with coincident and nearly coincident faces, seen from above: a box with a square hole cut by a
//! second box whose top is flush with, slightly above, or slightly below (a skin over the hole) the top
//! face. The light sits at the eye, so everything visible is lit and every pixel's value is analytic.

use super::support::*;
use glam::DVec3;

const EYE: f64 = 6.0;
const FLOOR: f64 = 0.3;
const INTENSITY: f64 = 30.0;

/// A 2 x 1 x 2 box minus a 1 x 1 square prism from y = FLOOR up to `cut_top`, under `x -> t + s x`.
fn holed_box(x: Xf, cut_top: f64) -> String {
    format!(
        r#"
[image]
width = 64
height = 64
[camera]
position = {eye}
look_at = {c}
up = [0, 0, -1]
fov = 30
[materials.m]
type = "lambert"
albedo = [0.5, 0.5, 0.5]
[[shapes]]
type = "csg"
op = "difference"
material = "m"
children = [
  {{ type = "box", min = {a0}, max = {a1} }},
  {{ type = "box", min = {b0}, max = {b1} }},
]
[[lights]]
type = "point"
position = {eye}
intensity = {li}
"#,
        eye = x.point([0.0, EYE, 0.0]),
        c = x.point([0.0, 0.0, 0.0]),
        a0 = x.point([-1.0, 0.0, -1.0]),
        a1 = x.point([1.0, 1.0, 1.0]),
        b0 = x.point([-0.5, FLOOR, -0.5]),
        b1 = x.point([0.5, cut_top, 0.5]),
        li = vec3([INTENSITY * x.s * x.s; 3]),
    )
}

/// What the hole region shows.
#[derive(Debug, PartialEq, Eq, Clone, Copy)]
enum Seen {
    /// Every hole pixel shows the top face (a skin closes the hole).
    Skin,
    /// Every hole pixel shows the floor of the hole.
    Open,
    /// Every hole pixel shows the floor, in shadow: the camera rays merged the skin with the top face,
    /// the shadow rays (which start 0.7 from the skin, not 5) resolved it.
    Shadowed,
    /// Some of each, or other values: speckles.
    Mixed { top: usize, floor: usize, dark: usize, neither: usize },
}

/// Render with one ray per pixel centre and classify: pixels well inside the square opening (|x|, |z|
/// < 0.4 at y = 1; the walls hide nothing there) and pixels on the solid top face around it (0.6 ..
/// 0.95). Returns what the hole shows and how many top-face pixels are wrong.
fn classify(x: Xf, cut_top: f64) -> (Seen, usize) {
    let scene = parse(&holed_box(x, cut_top));
    let img = render_scene(&scene, profile(&[("spp", "1"), ("pixel_strategy", "center"), ("max_depth", "1")]));
    // Lambert under a point light at the eye: rho / pi * I * cos / d^2 at the point the ray meets height h.
    let value = |o: DVec3, d: DVec3, h: f64| {
        let p = o + d * ((h - o.y) / d.y);
        let l = o - p;
        0.5 / std::f64::consts::PI * INTENSITY * x.s * x.s * (l.y / l.length()) / l.length_squared()
    };
    let (mut top, mut floor, mut dark, mut neither, mut bad_face) = (0, 0, 0, 0, 0);
    for py in 0..img.height {
        for px in 0..img.width {
            let (o, d) = scene.camera.ray(px as f32 + 0.5, py as f32 + 0.5, [0.0, 0.0]);
            let (o, d) = (o.as_dvec3(), d.as_dvec3());
            // Where the ray crosses the top face's height, in unscaled scene coordinates.
            let q = (o + d * ((x.t[1] + x.s - o.y) / d.y) - DVec3::from_array(x.t)) / x.s;
            let r = q.x.abs().max(q.z.abs());
            let v = img.at(px, py).x as f64;
            let (e_top, e_floor) = (value(o, d, x.t[1] + x.s), value(o, d, x.t[1] + FLOOR * x.s));
            let near = |e: f64| (v - e).abs() <= 1e-3 * e;
            if r < 0.4 {
                match (near(e_top), near(e_floor)) {
                    (true, _) => top += 1,
                    (_, true) => floor += 1,
                    _ if v == 0.0 => dark += 1,
                    _ => neither += 1,
                }
            } else if r > 0.6 && r < 0.95 {
                bad_face += !near(e_top) as usize;
            }
        }
    }
    let seen = match (top, floor, dark, neither) {
        (t, 0, 0, 0) if t > 0 => Seen::Skin,
        (0, f, 0, 0) if f > 0 => Seen::Open,
        (0, 0, k, 0) if k > 0 => Seen::Shadowed,
        _ => Seen::Mixed { top, floor, dark, neither },
    };
    (seen, bad_face)
}

/// The coincidence tolerance along these rays, in world units (`csg::merge`): 1e-5 (max(L, |o'|_inf) +
/// |t' d|) with L = 1 (the solid's scale) and `o'` the camera ray re-based to 1% of the bounds' diagonal
/// (3) above the top face (`csg::hit`): |o'|_inf = 1.03 and |t' d| = 0.03 at the top face (the rays are
/// within 10 degrees of vertical, so the gap along the ray is the gap). Before re-basing it was
/// 1e-5 (|o| + |t d|) = 1.1e-4, from the eye 6 away.
const PREDICTED_GAP: f64 = 1e-5 * (1.03 + 0.03);

/// Flush hole (gap 0): a clean opening; a hole sticking out by any gap: a clean opening; a skin
/// thinner than the tolerance merges with the top face (clean opening), a thicker one is a clean top
/// face. Never a speckle, never a wrong pixel on the top face. The smallest skin resolved is found on
/// a 1.25x grid from 1e-3 down to 1e-7 and must be within 1.5x of the documented tolerance (measured:
/// 1.15e-5 against 1.06e-5 predicted, the next grid step above). The shadow rays (from the floor, 0.7
/// away: tolerance 1e-5 (1 + 0.7)) merge no skin the camera rays resolve, so no skin shows an open hole
/// with a dark floor (before re-basing, skins of 1.8e-5 .. 1.07e-4 did). At scales 1e-3 and 1e3 (since
/// the tolerance floor is the solid's own scale) the same, in proportion.
#[test]
fn coincident_and_nearly_coincident_faces() {
    for x in [Xf::ID, Xf::scale(1e-3), Xf::scale(1e3)] {
        let (seen, bad) = classify(x, 1.0);
        assert_eq!((seen, bad), (Seen::Open, 0), "flush hole at scale {}", x.s);
        let (mut smallest_skin, mut shadowed) = (f64::NAN, Vec::new());
        let mut g = 1e-3;
        while g > 1e-7 {
            let (above, bad_above) = classify(x, 1.0 + g);
            assert_eq!((above, bad_above), (Seen::Open, 0), "hole sticking out by {g:e} at scale {}", x.s);
            let (below, bad_below) = classify(x, 1.0 - g);
            assert_eq!(bad_below, 0, "skin {g:e} at scale {}", x.s);
            match below {
                Seen::Skin => smallest_skin = g,
                Seen::Shadowed => shadowed.push(g),
                Seen::Open => {}
                Seen::Mixed { .. } => panic!("skin {g:e} at scale {}: speckles {below:?}", x.s),
            }
            g /= 1.25;
        }
        eprintln!("scale {}: smallest skin resolved {smallest_skin:.3e} (predicted {PREDICTED_GAP:.3e}); skins seen open but casting a shadow: {shadowed:?}", x.s);
        assert!(smallest_skin < 1.5 * PREDICTED_GAP && smallest_skin > PREDICTED_GAP / 1.5, "{smallest_skin:e}");
        // The camera rays' tolerance is below the shadow rays': no skin they merge is resolved by the
        // shadow rays, so none leaves the floor dark.
        assert!(shadowed.is_empty(), "{shadowed:?}");
    }
}
