//! (b) Paraxial focus of the CSG biconvex glass lens and (c) glass CSG solids refract as one solid.
//!
//! Rays are followed through the renderer's own stages: intersect -> csg_merge -> shade with Fresnel
//! splitting; of the children shade spawns, the transmitted one (the child that keeps going forwards) is
//! followed, the reflected one dropped. Every hit along the path is recorded with its side
//! (`surface_hit(..).front`) and the medium stack after it.

use super::scene_from;
use glam::{DVec2, Vec3};
use strata::csg::CsgArena;
use strata::scene::{Branching, Profile, Scene};
use strata::wavefront::csg_merge::csg_merge;
use strata::wavefront::intersect::intersect;
use strata::wavefront::queues::NONE;
use strata::wavefront::shade::{shade, surface_hit, ShadeOut};
use strata::wavefront::{CsgCandidates, HitQueue, MediumStack, NeeQueue, PathTable, RayItem, RayQueue};

const N: f64 = 1.5;

fn glass_scene(shapes: &str) -> Scene {
    let text = format!(
        r#"
[image]
width = 8
height = 8
[camera]
position = [0.0, 0.0, 10.0]
look_at = [0.0, 0.0, 0.0]
fov = 30.0
[materials.glass]
type = "dielectric"
ior = {N}
{shapes}
"#
    );
    scene_from("glass.toml", &text)
}

/// One followed path: the surfaces it crossed and the ray after the last one.
#[derive(Debug, Default)]
struct Followed {
    /// (hit point, the ray arrived on the outside of the surface, medium stack after the hit).
    hits: Vec<(Vec3, bool, MediumStack)>,
    /// Origin and direction of the last transmitted ray.
    last: Option<(Vec3, Vec3)>,
}

/// Follow the transmitted branch of each start ray through the stages until it leaves the scene.
fn follow(scene: &Scene, starts: &[(Vec3, Vec3)]) -> Vec<Followed> {
    let mut profile = Profile::builtin("final");
    profile.spp = 1;
    profile.max_depth = 12;
    profile.branching = Branching::Split;
    profile.throughput_cutoff = 0.0; // no roulette: every transmitted child is spawned
    let mut paths = PathTable::default();
    let mut cur = RayQueue::new(false, false);
    for (i, &(o, d)) in starts.iter().enumerate() {
        let path = paths.push(i as u32, 0);
        cur.push(&RayItem {
            o,
            d,
            tmax: f32::INFINITY,
            time: 0.0,
            lambda: 0.0,
            throughput: Vec3::ONE,
            path,
            branch: 0,
            depth: 0,
            diffuse: 0,
            flags: 0,
            media: MediumStack::default(),
            pdf: 0.0,
            travel: 0.0,
        });
    }
    let mut out: Vec<Followed> = starts.iter().map(|_| Followed::default()).collect();
    let (mut hits, mut cands, mut arena) = (HitQueue::default(), CsgCandidates::default(), CsgArena::new());
    let (mut next, mut nee, mut order) = (RayQueue::new(false, false), NeeQueue::default(), Vec::new());
    for _ in 0..profile.max_depth {
        if cur.is_empty() {
            break;
        }
        cur.pad();
        intersect(scene, &cur, &mut hits, &mut cands);
        csg_merge(scene, &cur, &mut cands, &mut hits, &mut arena);
        let mut parent_dir = vec![Vec3::ZERO; starts.len()];
        for i in 0..cur.len() {
            let r = cur.get(i);
            parent_dir[r.path as usize] = r.d;
            if hits.prim[i] != NONE {
                let h = surface_hit(scene, &r, hits.t[i], hits.prim[i], hits.leaf[i], hits.flip[i]);
                out[r.path as usize].hits.push((h.p, h.front, MediumStack::default()));
            }
        }
        next.clear();
        nee.clear();
        shade(scene, &profile, 1, &cur, &hits, &mut order, ShadeOut { paths: &mut paths, next: &mut next, nee: &mut nee });
        let mut kept = RayQueue::new(false, false);
        for i in 0..next.len() {
            let c = next.get(i);
            if c.d.dot(parent_dir[c.path as usize]) > 0.0 {
                let f = &mut out[c.path as usize];
                f.hits.last_mut().expect("a child without a hit").2 = c.media;
                f.last = Some((c.o, c.d));
                kept.push(&c);
            }
        }
        cur = kept;
    }
    assert!(cur.is_empty(), "paths still bouncing after {} hits", profile.max_depth);
    out
}

/// Where a ray crosses the lens axis (the z axis): the point of closest approach of a meridional ray.
fn axis_crossing_z(o: Vec3, d: Vec3) -> f64 {
    let (o, d) = (o.as_dvec3(), d.as_dvec3());
    let (oxy, dxy) = (DVec2::new(o.x, o.y), DVec2::new(d.x, d.y));
    let s = -oxy.dot(dxy) / dxy.length_squared();
    o.z + s * d.z
}

/// The lens: front vertex at z = +T/2 with radius R1 > 0 (centre behind it), back vertex at z = -T/2 with
/// radius R2 < 0 (centre in front of it), as the intersection of two spheres. Light travels along -z.
const R1: f64 = 1.2;
const R2: f64 = -0.9;
const T: f64 = 0.35;

fn lens_scene() -> Scene {
    glass_scene(&format!(
        r#"
[[shapes]]
type = "csg"
op = "intersection"
material = "glass"
children = [
  {{ type = "sphere", center = [0.0, 0.0, {c1}], radius = {r1} }},
  {{ type = "sphere", center = [0.0, 0.0, {c2}], radius = {r2} }},
]
"#,
        c1 = T / 2.0 - R1,
        r1 = R1,
        c2 = -T / 2.0 - R2,
        r2 = -R2
    ))
}

/// Rays parallel to the axis at height h, azimuth phi, travelling along -z from z = 3.
fn parallel_ray(h: f64, phi_deg: f64) -> (Vec3, Vec3) {
    let (s, c) = phi_deg.to_radians().sin_cos();
    (Vec3::new((h * c) as f32, (h * s) as f32, 3.0), Vec3::new(0.0, 0.0, -1.0))
}

/// (b) Paraxial rays focus at the thick-lens back focal distance within 1%.
///
/// Lensmaker's equation for a thick lens in air: 1/f = (n-1) [1/R1 - 1/R2 + (n-1) T / (n R1 R2)]; the back
/// focal distance, measured from the back vertex (z = -T/2) along the light, is BFD = f (1 - (n-1) T / (n R1)).
/// The measured BFD(h) of rays at heights h carries spherical aberration ~ h^2: a least-squares fit
/// BFD(h) = a + b h^2 over h in 0.005..0.05 gives the paraxial value a.
#[test]
fn lens_focuses_at_the_thick_lens_back_focal_distance() {
    let scene = lens_scene();
    let inv_f = (N - 1.0) * (1.0 / R1 - 1.0 / R2 + (N - 1.0) * T / (N * R1 * R2));
    let f = 1.0 / inv_f;
    let bfd = f * (1.0 - (N - 1.0) * T / (N * R1));
    let heights = [0.005, 0.01, 0.02, 0.03, 0.04, 0.05];
    let mut starts = Vec::new();
    for &h in &heights {
        for phi in [0.0, 90.0, 215.0] {
            starts.push((h, parallel_ray(h, phi)));
        }
    }
    let followed = follow(&scene, &starts.iter().map(|s| s.1).collect::<Vec<_>>());
    let mut samples = Vec::new();
    for ((h, _), p) in starts.iter().zip(&followed) {
        assert_eq!(p.hits.len(), 2, "h = {h}: {:?}", p.hits);
        let (o, d) = p.last.unwrap();
        let measured = -T / 2.0 - axis_crossing_z(o, d);
        samples.push((h * h, measured));
    }
    // Least squares for measured = a + b h^2.
    let n = samples.len() as f64;
    let (sx, sy) = samples.iter().fold((0.0, 0.0), |(a, b), &(x, y)| (a + x, b + y));
    let (mx, my) = (sx / n, sy / n);
    let sxx: f64 = samples.iter().map(|&(x, _)| (x - mx) * (x - mx)).sum();
    let sxy: f64 = samples.iter().map(|&(x, y)| (x - mx) * (y - my)).sum();
    let b = sxy / sxx;
    let a = my - b * mx;
    let rel = (a - bfd) / bfd;
    println!("thick lens: f = {f:.6}, BFD = {bfd:.6}; paraxial fit BFD = {a:.6} (rel. error {rel:.2e}), aberration {b:.4} h^2");
    for (i, &h) in heights.iter().enumerate() {
        println!("  h = {h}: BFD {:.6}", samples[3 * i].1);
    }
    assert!(rel.abs() < 0.01, "paraxial BFD {a} vs thick-lens {bfd}");
    // The smallest heights alone are within 1% too (no extrapolation needed there).
    for &(h2, m) in samples.iter().take(6) {
        assert!(((m - bfd) / bfd).abs() < 0.01, "h = {}: BFD {m} vs {bfd}", h2.sqrt());
    }
}

/// Sides of the hits of one path (true: the ray arrived from outside the surface).
fn sides(p: &Followed) -> Vec<bool> {
    p.hits.iter().map(|h| h.1).collect()
}

/// (c) A glass CSG solid refracts as one solid: across the whole lens aperture a ray has exactly one
/// entry and one exit (the spheres' surfaces inside the other sphere never show), it is inside the glass
/// between them and outside after.
#[test]
fn glass_lens_has_one_entry_and_one_exit() {
    let scene = lens_scene();
    let glass = 0;
    let rim = {
        // The spheres meet where x^2 + (z - c1)^2 = R1^2 and x^2 + (z - c2)^2 = R2^2.
        let (c1, c2) = (T / 2.0 - R1, -T / 2.0 - R2);
        let z = (R1 * R1 - R2 * R2 - c1 * c1 + c2 * c2) / (2.0 * (c2 - c1));
        (R1 * R1 - (z - c1) * (z - c1)).sqrt()
    };
    let starts: Vec<_> = (0..=8).flat_map(|k| [0.0, 130.0, 250.0].map(|phi| parallel_ray(0.9 * rim * k as f64 / 8.0, phi))).collect();
    let followed = follow(&scene, &starts);
    for (s, p) in starts.iter().zip(&followed) {
        assert_eq!(sides(p), [true, false], "ray {s:?}: {:?}", p.hits);
        assert_eq!(p.hits[0].2.top(), Some(glass), "inside the glass after the entry");
        assert_eq!(p.hits[1].2, MediumStack::default(), "outside all media after the exit");
    }
    println!("lens (rim radius {rim:.4}): {} rays, each one entry and one exit", starts.len());
}

/// (c) Unions of overlapping glass solids have no internal faces, and holes are real openings: two
/// overlapping spheres, two overlapping boxes, and those boxes drilled by a vertical hole.
#[test]
fn glass_unions_and_holes_refract_as_one_solid() {
    let spheres = glass_scene(
        r#"
[[shapes]]
type = "csg"
op = "union"
material = "glass"
children = [
  { type = "sphere", center = [0.0, 0.0, 0.3], radius = 0.5 },
  { type = "sphere", center = [0.0, 0.0, -0.3], radius = 0.5 },
]
"#,
    );
    let starts: Vec<_> = [0.0, 0.1, 0.2, 0.3].iter().flat_map(|&h| [0.0, 100.0].map(|phi| parallel_ray(h, phi))).collect();
    for (s, p) in starts.iter().zip(follow(&spheres, &starts)) {
        assert_eq!(sides(&p), [true, false], "two spheres, ray {s:?}: {:?}", p.hits);
    }
    // Boxes [-0.8, 0.4] and [0, 0.8] in x: rays along +x cross both internal faces (x = 0 and x = 0.4) at
    // normal incidence, so they go straight.
    let boxes = |hole: &str| {
        glass_scene(&format!(
            r#"
[[shapes]]
type = "group"
material = "glass"
children = [
  {{ type = "box", min = [-0.8, 0.0, -0.45], max = [0.4, 0.7, 0.45] }},
  {{ type = "box", min = [0.0, 0.0, -0.45], max = [0.8, 0.7, 0.45] }},
  {hole}
]
"#
        ))
    };
    let along_x = |y: f32, z: f32| (Vec3::new(-3.0, y, z), Vec3::X);
    let plain = boxes("");
    let starts = [along_x(0.35, 0.0), along_x(0.1, 0.3), along_x(0.6, -0.4)];
    for (s, p) in starts.iter().zip(follow(&plain, &starts)) {
        assert_eq!(sides(&p), [true, false], "two boxes, ray {s:?}: {:?}", p.hits);
        assert!((p.hits[0].0.x + 0.8).abs() < 1e-4 && (p.hits[1].0.x - 0.8).abs() < 1e-4, "faces at x = -0.8 and 0.8: {:?}", p.hits);
    }
    // A vertical hole of radius 0.2 at the origin, flush with the top and bottom faces. A ray through the
    // axis crosses glass, air, glass: enter, exit (into the hole), enter, exit, with the medium stack
    // following; a ray beside the hole crosses the block once.
    let drilled = boxes(r#"{ type = "cylinder", center = [0.0, 0.35, 0.0], radius = 0.2, height = 0.7, hole = true },"#);
    let starts = [along_x(0.35, 0.0), along_x(0.2, 0.3)];
    let f = follow(&drilled, &starts);
    assert_eq!(sides(&f[0]), [true, false, true, false], "through the hole: {:?}", f[0].hits);
    let xs: Vec<f32> = f[0].hits.iter().map(|h| h.0.x).collect();
    for (x, want) in xs.iter().zip([-0.8, -0.2, 0.2, 0.8]) {
        assert!((x - want).abs() < 1e-4, "hit x {xs:?}");
    }
    let inside: Vec<bool> = f[0].hits.iter().map(|h| h.2.top().is_some()).collect();
    assert_eq!(inside, [true, false, true, false]);
    assert_eq!(sides(&f[1]), [true, false], "beside the hole: {:?}", f[1].hits);
    let last = f[0].last.unwrap();
    assert!((last.1.normalize() - Vec3::X).length() < 1e-5, "normal incidence leaves the direction unchanged");
}
