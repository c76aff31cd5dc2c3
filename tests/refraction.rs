//! Refraction through the renderer's own stages (intersect, csg_merge, shade, shadow): lenses, nested media,
//! absorption, index-matched glass, white furnace, transmissive shadows, the prism spectrum, and the shipped
//! glass scenes. References are analytic or f64 ray traces written here, independent of the renderer.

use glam::{DVec3, Vec3};
use std::path::Path;
use strata::csg::CsgArena;
use strata::scene::{parse_scene, Branching, Profile, Scene};
use strata::wavefront::csg_merge::csg_merge;
use strata::wavefront::intersect::intersect;
use strata::wavefront::queues::NONE;
use strata::wavefront::shade::{shade, ShadeOut};
use strata::wavefront::{CsgCandidates, HitQueue, MediumStack, NeeQueue, PathTable, RayItem, RayQueue};

// Sub-modules live in tests/refraction/ (not separate test targets).
#[path = "refraction/images.rs"]
mod images;
#[path = "refraction/lens.rs"]
mod lens;
#[path = "refraction/media.rs"]
mod media;
#[path = "refraction/prism.rs"]
mod prism;
#[path = "refraction/shadows.rs"]
mod shadows;

pub fn scene(text: &str) -> Scene {
    parse_scene(Path::new("test.toml"), text).unwrap_or_else(|e| panic!("{e}"))
}

/// Split branching (both children), a generous depth, no low-throughput roulette in the way.
pub fn split_profile() -> Profile {
    let mut p = Profile::builtin("final");
    p.branching = Branching::Split;
    p.max_depth = 32;
    p.throughput_cutoff = 1e-6;
    p
}

/// A ray leaving the scene (its last segment, which hit nothing).
#[derive(Clone, Copy, Debug)]
pub struct Exit {
    pub o: Vec3,
    pub d: Vec3,
    pub throughput: Vec3,
    pub path: u32,
    /// Shading events the ray went through (its `depth` field).
    pub depth: u16,
}

/// Trace rays through the renderer's stages bounce by bounce (intersect, csg_merge, shade with the split
/// policy) and follow only the main branch (`branch == 0`): under `Split` the transmitted child keeps its
/// parent's branch and the reflected child gets a new one, so this follows the chain of refractions.
/// Returns the rays that escaped (hit nothing), in path order.
pub fn trace_transmitted(scene: &Scene, start: &[RayItem]) -> Vec<Exit> {
    let profile = split_profile();
    let f = &scene.features;
    let mut cur = RayQueue::new(f.motion, f.dispersion);
    let mut next = RayQueue::new(f.motion, f.dispersion);
    let (mut hits, mut cands, mut arena) = (HitQueue::default(), CsgCandidates::default(), CsgArena::new());
    let (mut nee, mut paths, mut order) = (NeeQueue::default(), PathTable::default(), Vec::new());
    for (i, r) in start.iter().enumerate() {
        paths.push(i as u32, 0);
        cur.push(&RayItem { path: i as u32, ..*r });
    }
    let mut exits = Vec::new();
    for _ in 0..64 {
        if cur.is_empty() {
            break;
        }
        cur.pad();
        next.clear();
        nee.clear();
        intersect(scene, &cur, &mut hits, &mut cands);
        if f.csg {
            csg_merge(scene, &cur, &mut cands, &mut hits, &mut arena);
        }
        shade(scene, &profile, 1, &cur, &hits, &mut order, ShadeOut { paths: &mut paths, next: &mut next, nee: &mut nee });
        for i in 0..cur.len() {
            if hits.prim[i] == NONE {
                let r = cur.get(i);
                exits.push(Exit { o: r.o, d: r.d, throughput: r.throughput, path: r.path, depth: r.depth });
            }
        }
        cur.clear();
        for i in 0..next.len() {
            let r = next.get(i);
            if r.branch == 0 {
                cur.push(&r);
            }
        }
    }
    exits.sort_by_key(|e| e.path);
    exits
}

pub fn ray(o: Vec3, d: Vec3) -> RayItem {
    RayItem {
        o,
        d: d.normalize(),
        tmax: f32::INFINITY,
        time: 0.0,
        lambda: 550.0,
        throughput: Vec3::ONE,
        path: 0,
        branch: 0,
        depth: 0,
        diffuse: 0,
        flags: 0,
        media: MediumStack::default(),
        pdf: 0.0,
        travel: 0.0,
    }
}

/// f64 Snell refraction of unit `d` at a surface with unit normal `n` (any side), from index `n1` to
/// `n2`. None under total internal reflection.
pub fn refract64(d: DVec3, n: DVec3, n1: f64, n2: f64) -> Option<DVec3> {
    let n = if d.dot(n) > 0.0 { -n } else { n };
    let eta = n1 / n2;
    let ci = -d.dot(n);
    let st2 = eta * eta * (1.0 - ci * ci);
    if st2 >= 1.0 {
        return None;
    }
    Some((eta * d + (eta * ci - (1.0 - st2).sqrt()) * n).normalize())
}

/// f64 reference: a ray through concentric spheres centred at the origin, with index `index(r, outward)`
/// at radius `r` for a ray crossing outwards or inwards (the radii in `radii` are the surfaces). Returns
/// the exit point and direction, or None on total internal reflection.
pub fn trace_concentric(radii: &[f64], index: impl Fn(f64, bool) -> f64, mut o: DVec3, mut d: DVec3) -> Option<(DVec3, DVec3)> {
    d = d.normalize();
    for _ in 0..64 {
        // Nearest crossing ahead of o.
        let mut best = f64::INFINITY;
        for &r in radii {
            let b = o.dot(d);
            let c = o.dot(o) - r * r;
            let disc = b * b - c;
            if disc < 0.0 {
                continue;
            }
            for t in [-b - disc.sqrt(), -b + disc.sqrt()] {
                if t > 1e-9 && t < best {
                    best = t;
                }
            }
        }
        if !best.is_finite() {
            return Some((o, d));
        }
        let p = o + d * best;
        let n = p.normalize();
        let (r_before, r_after) = ((p - d * 1e-7).length(), (p + d * 1e-7).length());
        let out = d.dot(n) > 0.0;
        d = refract64(d, n, index(r_before, out), index(r_after, out))?;
        o = p;
    }
    None
}

pub fn v64(v: Vec3) -> DVec3 {
    v.as_dvec3()
}

/// The `priority` field: range-checked, refused on thin sheets and non-dielectrics, errors name the line.
#[test]
fn priority_field_is_validated() {
    let base = "[image]\nwidth = 2\nheight = 2\n[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\nfov = 30\n";
    for (mat, needle) in [
        ("[materials.g]\ntype = \"dielectric\"\npriority = 5000000\n", "must be an integer in -1000000..=1000000"),
        ("[materials.g]\ntype = \"dielectric\"\nthin = true\npriority = 2\n", "a thin sheet is not a medium"),
        ("[materials.g]\ntype = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\npriority = 2\n", "does not apply"),
    ] {
        let e = parse_scene(Path::new("p.toml"), &format!("{base}{mat}")).unwrap_err().to_string();
        eprintln!("{e}");
        assert!(e.contains("materials.g.priority") && e.contains(needle) && e.starts_with("p.toml:"), "{e}");
        assert!(e.contains(&format!(":{}:", base.lines().count() + mat.lines().count())), "line of the field: {e}");
    }
    let ok = parse_scene(Path::new("p.toml"), &format!("{base}[materials.g]\ntype = \"dielectric\"\npriority = -3\n"));
    assert!(ok.is_ok());
}
