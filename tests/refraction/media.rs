//! Which side is which: nested and overlapping media against f64 traces through concentric spheres.

use super::*;

const CAMERA: &str = "[image]\nwidth = 8\nheight = 8\n[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\nfov = 30\n";

/// Rays parallel to -z at the given heights (in x), plus a few oblique ones, starting at z = 3.
fn probe_rays(heights: &[f32]) -> Vec<RayItem> {
    let mut v: Vec<RayItem> = heights.iter().map(|&h| ray(Vec3::new(h, 0.0, 3.0), Vec3::NEG_Z)).collect();
    for &h in heights {
        v.push(ray(Vec3::new(h, 0.3 * h, 3.0), Vec3::new(-0.05, 0.02, -1.0)));
    }
    v
}

/// Largest angle (rad) between the renderer's exit directions and the f64 reference, and largest
/// distance from the reference exit point to the renderer's exit line.
fn compare(scene_text: &str, radii: &[f64], index: impl Fn(f64) -> f64 + Copy, heights: &[f32]) -> (f64, f64) {
    let s = scene(scene_text);
    let start = probe_rays(heights);
    let exits = trace_transmitted(&s, &start);
    for e in &exits { eprintln!("exit {} {:?} {:?} depth {}", e.path, e.o, e.d, e.depth); }
    assert_eq!(exits.len(), start.len(), "every probe ray leaves the scene once");
    let (mut worst_angle, mut worst_dist) = (0.0f64, 0.0f64);
    for (e, r) in exits.iter().zip(&start) {
        let (p, d) = trace_concentric(radii, index, v64(r.o), v64(r.d)).expect("probe rays avoid total internal reflection");
        let got = v64(e.d).normalize();
        worst_angle = worst_angle.max(got.cross(d).length().asin());
        let w = p - v64(e.o);
        eprintln!("  ray {:?} {:?}: angle {:.2e} off {:.2e}", r.o, r.d, got.cross(d).length().asin(), (w - got * w.dot(got)).length());
        worst_dist = worst_dist.max((w - got * w.dot(got)).length());
    }
    (worst_angle, worst_dist)
}

fn glass_in_water() -> String {
    format!(
        "{CAMERA}[materials.water]\ntype = \"dielectric\"\nior = 1.33\n[materials.glass]\ntype = \"dielectric\"\nior = 1.5\n\
         [[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1.0\nmaterial = \"water\"\n\
         [[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 0.5\nmaterial = \"glass\"\n"
    )
}

#[test]
fn glass_sphere_inside_water_sphere() {
    let idx = |r: f64| if r < 0.5 { 1.5 } else if r < 1.0 { 1.33 } else { 1.0 };
    let (a, d) = compare(&glass_in_water(), &[0.5, 1.0], idx, &[0.02, 0.1, 0.2, 0.35, 0.45, 0.7, 0.9]);
    eprintln!("glass in water: worst exit angle {a:.2e} rad, worst exit line offset {d:.2e}");
    assert!(a < 2e-5 && d < 2e-5, "angle {a}, offset {d}");
}

#[test]
fn air_bubble_inside_glass_sphere() {
    let text = format!(
        "{CAMERA}[materials.glass]\ntype = \"dielectric\"\nior = 1.5\n[materials.air]\ntype = \"dielectric\"\nior = 1.0\n\
         [[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1.0\nmaterial = \"glass\"\n\
         [[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 0.4\nmaterial = \"air\"\n"
    );
    let idx = |r: f64| if r < 0.4 { 1.0 } else if r < 1.0 { 1.5 } else { 1.0 };
    let (a, d) = compare(&text, &[0.4, 1.0], idx, &[0.02, 0.1, 0.2, 0.3, 0.38, 0.9]);
    eprintln!("bubble in glass: worst exit angle {a:.2e} rad, worst exit line offset {d:.2e}");
    assert!(a < 2e-5 && d < 2e-5, "angle {a}, offset {d}");
}

/// A glass bowl (a shell: sphere minus sphere, radii 1 and 0.8) full of liquid modelled as a sphere of
/// radius 0.81: the liquid's surface lies inside the glass wall, as the usual modelling advice has it
/// (never exactly coincident). `prio` gives (glass, liquid) priorities, or None for the plain rule.
fn liquid_in_glass(prio: Option<(i32, i32)>) -> String {
    let (pg, pl) = match prio {
        Some((g, l)) => (format!("priority = {g}\n"), format!("priority = {l}\n")),
        None => (String::new(), String::new()),
    };
    format!(
        "{CAMERA}[materials.glass]\ntype = \"dielectric\"\nior = 1.5\n{pg}[materials.liquid]\ntype = \"dielectric\"\nior = 1.33\n{pl}\
         [[shapes]]\ntype = \"csg\"\nop = \"difference\"\nmaterial = \"glass\"\nchildren = [\n\
           {{ type = \"sphere\", center = [0, 0, 0], radius = 1.0 }},\n  {{ type = \"sphere\", center = [0, 0, 0], radius = 0.8 }},\n]\n\
         [[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 0.81\nmaterial = \"liquid\"\n"
    )
}

pub const LIQUID_HEIGHTS: [f32; 6] = [0.02, 0.1, 0.25, 0.4, 0.55, 0.7];

/// With the glass ranked above the liquid, the overlap belongs to the glass: the interfaces are the
/// glass's (r = 1 and r = 0.8) and the liquid's own surface inside the wall is a null crossing.
#[test]
fn liquid_in_glass_with_priorities() {
    let idx = |r: f64| if r < 0.8 { 1.33 } else if r < 1.0 { 1.5 } else { 1.0 };
    let (a, d) = compare(&liquid_in_glass(Some((2, 1))), &[0.8, 1.0], idx, &LIQUID_HEIGHTS);
    eprintln!("liquid in glass (priorities): worst exit angle {a:.2e} rad, worst exit line offset {d:.2e}");
    assert!(a < 2e-5 && d < 2e-5, "angle {a}, offset {d}");
}

#[test]
fn probe_liquid_plain() {
    let idx = |r: f64| if r < 0.8 { 1.33 } else if r < 1.0 { 1.5 } else { 1.0 };
    let (a, d) = compare(&liquid_in_glass(None), &[0.8, 1.0], idx, &LIQUID_HEIGHTS);
    eprintln!("liquid in glass (plain): worst exit angle {a:.2e} rad, worst exit line offset {d:.2e}");
}

#[test]
fn debug_steps() {
    let s = scene(&glass_in_water());
    let r0 = ray(Vec3::new(0.7, 0.21, 3.0), Vec3::new(-0.05, 0.02, -1.0));
    let mut r = r0;
    let idx = |r: f64| if r < 0.5 { 1.5 } else if r < 1.0 { 1.33 } else { 1.0 };
    let (mut o64, mut d64) = (v64(r0.o), v64(r0.d).normalize());
    for k in 0..5 {
        let ex = trace_transmitted(&s, &[r]);
        let _ = ex;
        // one step in f64
        let mut best = f64::INFINITY;
        for rr in [0.5f64, 1.0] {
            let b = o64.dot(d64); let c = o64.dot(o64) - rr * rr; let disc = b * b - c;
            if disc < 0.0 { continue; }
            for t in [-b - disc.sqrt(), -b + disc.sqrt()] { if t > 1e-9 && t < best { best = t; } }
        }
        if !best.is_finite() { break; }
        let p = o64 + d64 * best;
        let (n1, n2) = (idx((p - d64 * 1e-7).length()), idx((p + d64 * 1e-7).length()));
        eprintln!("n1 {n1} n2 {n2} {} {} o64 {:?} d64 {:?}", (p - d64 * 1e-7).length(), (p + d64 * 1e-7).length(), o64, d64);
        d64 = refract64(d64, p.normalize(), n1, n2).unwrap();
        o64 = p;
        // renderer one step
        let mut one = strata::wavefront::RayQueue::new(false, false);
        one.push(&r);
        one.pad();
        let mut hits = HitQueue::default();
        let mut c = CsgCandidates::default();
        intersect(&s, &one, &mut hits, &mut c);
        let mut next = RayQueue::new(false, false);
        let (mut nee, mut paths, mut order) = (NeeQueue::default(), PathTable::default(), Vec::new());
        paths.push(0, 0);
        shade(&s, &split_profile(), 1, &one, &hits, &mut order, ShadeOut { paths: &mut paths, next: &mut next, nee: &mut nee });
        let t = hits.t[0];
        let p32 = r.o + r.d * t;
        for i in 0..next.len() { let q = next.get(i); if q.branch == 0 { r = q; } }
        eprintln!("step {k}: p64 {:?} p32 {:?} |p|={} dp={:.2e}  d64 {:?} d32 {:?} ang {:.2e}", p, p32, p32.length(), (v64(p32)-p).length(), d64, r.d, v64(r.d).normalize().cross(d64).length());
    }
}

#[test]
fn debug_kernel() {
    use strata::simd::{f32x8, Ray8, Vec3x8};
    let o = Vec3::new(0.58837223, 0.2546511, 0.7674444);
    let d = Vec3::new(-0.21009097, -0.059665445, -0.9758596);
    let ray = Ray8::new(Vec3x8::splat(o), Vec3x8::splat(d), f32x8::splat(f32::INFINITY));
    let t32 = strata::geometry::intersect_sphere_x8(Vec3::ZERO, 0.5, &ray).to_array()[0];
    let t64 = strata::geometry::intersect_sphere_f64(DVec3::ZERO, 0.5, v64(o), v64(d), f64::INFINITY);
    eprintln!("t32 {t32} t64 {t64} rel {:.2e} |d| {}", (t32 as f64 - t64) / t64, d.length());
    let s = scene(&glass_in_water());
    eprintln!("prims {:?}", s.prims.iter().map(|p| p.shape).collect::<Vec<_>>());
}

#[test]
fn debug_csg() {
    let s = scene(&liquid_in_glass(Some((2, 1))));
    let o = Vec3::new(0.39857844, 0.0, -0.70516664);
    let d = Vec3::new(-0.099342175, 0.0, -0.9950533);
    let mut arena = CsgArena::new();
    for (i, p) in s.prims.iter().enumerate() {
        if let strata::scene::Shape::Csg { solid } = p.shape {
            let h = strata::csg::first_hit(&s.csg, solid, o, d, 0.0, f32::INFINITY, &mut arena);
            eprintln!("prim {i} solid {solid} hit {:?} bounds {:?}", h, s.bounds[i]);
        }
    }
    let exits = trace_transmitted(&s, &[ray(o, d)]);
    eprintln!("{exits:?}");
}

#[test]
fn debug_csg2() {
    let s = scene(&liquid_in_glass(Some((2, 1))));
    let mut arena = CsgArena::new();
    for (o, d) in [
        (Vec3::new(0.0, 0.0, -0.9), Vec3::new(0.0, 0.0, -1.0)),
        (Vec3::new(0.0, 0.0, -0.9), Vec3::new(0.0, 0.0, 1.0)),
        (Vec3::new(0.0, 0.0, 0.9), Vec3::new(0.0, 0.0, 1.0)),
        (Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.0, 0.0, -1.0)),
        (Vec3::new(0.0, 0.0, 3.0), Vec3::new(0.0, 0.0, -1.0)),
        (Vec3::new(0.1, 0.0, -0.9), Vec3::new(0.0, 0.0, -1.0)),
    ] {
        let h = strata::csg::first_hit(&s.csg, 0, o, d, 0.0, 1e30, &mut arena);
        let mut iv = Vec::new(); strata::csg::intervals_f64(&s.csg, 0, o.as_dvec3(), d.as_dvec3(), &mut iv);
        eprintln!("o {o:?} d {d:?} hit {:?} ref {:?}", h.map(|h| (h.t, h.entering)), iv);
    }
}
