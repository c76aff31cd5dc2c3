//! CSG tests: set identities, first hits against the f64 reference, coincident surfaces, deep trees, bounds
//! and errors, and the arena's allocation behaviour. The kernel tests (x8 against the f64 twins, the torus
//! against bisection) and the volume tests live in `csg_cases/`. Fixed seeds throughout; every expected
//! value is analytic or comes from the f64 reference.

mod csg_cases;

use csg_cases::*;
use glam::{Affine3A, DVec3, Quat, Vec3};
use strata::csg::*;

// ---------------------------------------------------------------------------------------------------------
// Set identities on random solids and rays (reference and fast path)
// ---------------------------------------------------------------------------------------------------------

/// On 60 random pairs of solids and 150 rays each, in world length units (`measure × |d|`), for both the
/// f64 reference and the fast path (boundaries walked with `first_hit`): `A ∪ B ⊇ A`, `A ∩ B ⊆ A`,
/// `A - A = ∅` (exactly: no boundary), `(A - B) ∪ (A ∩ B) = A`, `A ∪ B = B ∪ A`, `A ∩ B = B ∩ A`, within
/// 2e-3 (the coincidence tolerance is about 1e-4 here; a wrong merge is off by O(0.1)). The fast path also
/// matches the reference on every solid within the same bound.
#[test]
fn set_identities_on_random_solids() {
    let mut r = R::new(21);
    let mut arena = CsgArena::new();
    let (mut iv, mut checked) = (Vec::new(), 0);
    for _ in 0..60 {
        let (a, b) = (r.tree(2), r.tree(2));
        let mut csg = Csg::new();
        let trees = [
            a.clone(),
            node(Op::Union, vec![a.clone(), b.clone()]),
            node(Op::Intersection, vec![a.clone(), b.clone()]),
            node(Op::Difference, vec![a.clone(), a.clone()]),
            node(Op::Union, vec![node(Op::Difference, vec![a.clone(), b.clone()]), node(Op::Intersection, vec![a.clone(), b.clone()])]),
            node(Op::Union, vec![b.clone(), a.clone()]),
            node(Op::Intersection, vec![b.clone(), a.clone()]),
        ];
        let ids: Vec<u32> = trees.iter().map(|t| csg.add_solid(t).unwrap()).collect();
        let (lo, hi) = csg.bounds(ids[1]);
        for _ in 0..150 {
            let (o, d) = r.ray(lo, hi);
            let w = d.length() as f64;
            let reference: Vec<Vec<(f64, f64)>> = ids
                .iter()
                .map(|&s| {
                    intervals_f64(&csg, s, dv(o), dv(d), &mut iv);
                    iv.clone()
                })
                .collect();
            let fast: Vec<Vec<(f64, f64)>> =
                ids.iter().map(|&s| fast_intervals(&csg, s, o, d, &mut arena).expect("unpaired boundaries")).collect();
            for (k, (f, rf)) in fast.iter().zip(&reference).enumerate() {
                assert!(sym_diff(f, rf) * w <= 2e-3, "solid {k}: fast {f:?} vs reference {rf:?}");
            }
            for (name, s) in [("reference", &reference), ("fast", &fast)] {
                let tol = 2e-3 / w;
                assert!(minus_measure(&s[0], &s[1]) <= tol, "{name}: A ∪ B misses part of A");
                assert!(minus_measure(&s[2], &s[0]) <= tol, "{name}: A ∩ B leaves A");
                assert!(s[3].is_empty(), "{name}: A - A = {:?}", s[3]);
                assert!(sym_diff(&s[4], &s[0]) <= tol, "{name}: (A-B) ∪ (A∩B) = {:?} vs A = {:?}", s[4], s[0]);
                assert!(sym_diff(&s[1], &s[5]) <= tol, "{name}: union does not commute");
                assert!(sym_diff(&s[2], &s[6]) <= tol, "{name}: intersection does not commute");
            }
            checked += usize::from(!reference[1].is_empty());
        }
    }
    assert!(checked > 3000, "only {checked} rays hit A ∪ B");
}

// ---------------------------------------------------------------------------------------------------------
// first_hit / first_hit_x8 against the f64 reference
// ---------------------------------------------------------------------------------------------------------

/// Random solids (depth 3, with half-spaces), rays from outside and inside, random `tmin`/`tmax`:
/// `first_hit` and `first_hit_x8` agree bit for bit, and with the first boundary of `intervals_f64` in
/// `(tmin, tmax)`: same `entering`, `t` within `1e-4 (|t| + max(1, |o|) / |d|)`. The only accepted
/// disagreement is a sliver: when one side sees a boundary the other does not, the reference interval or gap
/// it belongs to is shorter than 1e-3 (world units), i.e. a near-tangent graze (at most 0.1% of rays).
/// Normals: at every hit the solid's outward normal (`hit_normal`, i.e. `flip` applied) faces against the
/// ray exactly when `entering` (for `|cos| > 0.05`), and a finite difference of `inside` across the surface
/// goes from inside to outside along it (all but 0.5% of hits, which lie within 1e-3 of an edge).
#[test]
fn first_hit_matches_reference() {
    let mut r = R::new(33);
    let mut arena = CsgArena::new();
    let mut iv = Vec::new();
    let (mut rays_done, mut hits, mut slivers, mut fd_fail, mut inside_starts) = (0, 0, 0, 0, 0);
    r.packets(300, 40, 0.7, (0.1, 5.0), |csg, s, rays, packet, tmin8| {
        let mut out = [None; 8];
        first_hit_x8(csg, s, packet, tmin8, &mut arena, &mut out);
        for (i, &(o, d, tmin, tmax)) in rays.iter().enumerate() {
            rays_done += 1;
            inside_starts += usize::from(csg.inside(s, o));
            let fast = first_hit(csg, s, o, d, tmin, tmax, &mut arena);
            assert_eq!(fast, out[i], "scalar and x8 differ");
            intervals_f64(csg, s, dv(o), dv(d), &mut iv);
            let bs = boundaries(&iv);
            let want = bs.iter().find(|b| b.0 > tmin as f64 && b.0 < tmax as f64);
            let w = d.length() as f64;
            let tol = |t: f64| 1e-4 * (t.abs() + scale(o, d));
            // Length (world) of the reference piece (interval or gap) that ends or starts at boundary k.
            let piece = |k: usize| {
                let prev = if k > 0 { bs[k].0 - bs[k - 1].0 } else { f64::INFINITY };
                let next = if k + 1 < bs.len() { bs[k + 1].0 - bs[k].0 } else { f64::INFINITY };
                prev.min(next) * w
            };
            let agree = match (fast, want) {
                (None, None) => true,
                (Some(h), Some(&(t, e))) => h.entering == e && (h.t as f64 - t).abs() <= tol(t),
                _ => false,
            };
            if !agree {
                // A sliver: the first reference boundary is (or the fast one sits in) a tiny piece.
                let k = bs.iter().position(|b| b.0 > tmin as f64 && b.0 < tmax as f64);
                let tiny = k.is_some_and(|k| piece(k) < 1e-3)
                    || fast.is_some_and(|h| bs.iter().enumerate().any(|(j, b)| (b.0 - h.t as f64).abs() <= tol(b.0) && piece(j) < 1e-3));
                assert!(tiny, "o={o} d={d} tmin={tmin} tmax={tmax}: fast {fast:?} vs reference {iv:?}");
                slivers += 1;
            }
            if let Some(h) = fast {
                hits += 1;
                let p = o + d * h.t;
                let n = csg.hit_normal(&h, p);
                let cos = n.dot(d.normalize());
                if cos.abs() > 0.05 {
                    assert_eq!(cos < 0.0, h.entering, "normal vs entering: {h:?} n={n} o={o} d={d}");
                }
                let delta = 1e-3;
                fd_fail += usize::from(!csg.inside(s, p - n * delta) || csg.inside(s, p + n * delta));
            }
        }
    });
    println!("first_hit: {rays_done} rays, {hits} hits, {inside_starts} inside starts, {slivers} slivers, {fd_fail} fd failures");
    assert!(hits > 20_000 && inside_starts > 4_000, "{hits} hits, {inside_starts} inside starts");
    assert!(slivers * 1000 <= rays_done, "{slivers} slivers");
    assert!(fd_fail * 200 <= hits, "{fd_fail} finite-difference failures");
}

/// `lanes_may_cross_x8` (the 8-lane pre-test alone, which the shadow stage uses for solids that shadow rays
/// walk through) keeps every lane on which `first_hit_x8` finds a boundary, and `crossings_x8` visits no
/// lane outside it: random solids of depth 3, rays through and around their bounds, random `(tmin, tmax)`.
#[test]
fn lanes_may_cross_keep_every_lane_with_a_boundary() {
    let mut r = R::new(71);
    let mut arena = CsgArena::new();
    let (mut kept, mut dropped, mut with_hit) = (0usize, 0usize, 0usize);
    r.packets(200, 30, 0.5, (0.01, 3.0), |csg, s, rays, packet, tmin8| {
        let may = lanes_may_cross_x8(csg, s, packet, tmin8, &mut arena);
        let mut out = [None; 8];
        first_hit_x8(csg, s, packet, tmin8, &mut arena, &mut out);
        let mut visited = 0u32;
        crossings_x8(csg, s, packet, tmin8, &mut arena, |l, _| visited |= 1 << l);
        for (l, h) in out.iter().enumerate() {
            assert!(h.is_none() || may & (1 << l) != 0, "lane {l} has a boundary {h:?} but was dropped: {:?}", rays[l]);
            with_hit += h.is_some() as usize;
            kept += (may >> l & 1) as usize;
            dropped += (rays[l].3 > rays[l].2 && may & (1 << l) == 0) as usize;
        }
        assert_eq!(visited & !may, 0, "crossings outside the kept lanes");
    });
    assert!(with_hit > 5000 && dropped > 10_000 && kept > with_hit, "{with_hit} hits, {kept} kept, {dropped} dropped");
}

// ---------------------------------------------------------------------------------------------------------
// Coincident surfaces
// ---------------------------------------------------------------------------------------------------------

/// The five bounded shapes under random placements, as solids `A`, `A - A`, `A ∪ A`, `A ∩ A`: `A - A` has
/// no boundary on any ray (scalar, x8 and reference); `A - A'`, with `A'` the same solid through another
/// transform (rounding differs), is empty but for near-tangent slivers below 1e-3 on under 0.2% of rays; `A ∪ A` and `A ∩ A` have the first hit of `A` (or
/// none, when `A`'s interval is a sliver shorter than the coincidence tolerance).
#[test]
fn self_difference_union_intersection() {
    let mut r = R::new(44);
    let mut arena = CsgArena::new();
    let mut iv = Vec::new();
    let (mut hits, mut slivers) = (0, 0);
    for k in 0..40 {
        let shape =
            [Shape::Sphere, Shape::Box, Shape::Cylinder, Shape::Cone { r0: 0.0, r1: 0.7 }, Shape::Torus { major: 0.8, minor: 0.3 }][k % 5];
        let m = r.affine();
        let a = CsgTree::Leaf(Leaf::new(shape, m, 1));
        // The same solid through a different transform: composed with a symmetry of the canonical shape
        // (quarter turns for the box, any turn about z for the others), so its crossings differ by rounding.
        let sym = match shape {
            Shape::Box => Affine3A::from_rotation_x(std::f32::consts::FRAC_PI_2) * Affine3A::from_rotation_z(-std::f32::consts::FRAC_PI_2),
            _ => Affine3A::from_rotation_z(r.range(0.1, 6.0) as f32),
        };
        let a2 = CsgTree::Leaf(Leaf::new(shape, m * sym, 2));
        let mut csg = Csg::new();
        let sa = csg.add_solid(&a).unwrap();
        let empty = csg.add_solid(&node(Op::Difference, vec![a.clone(), a.clone()])).unwrap();
        let empty2 = csg.add_solid(&node(Op::Difference, vec![a.clone(), a2])).unwrap();
        let uni = csg.add_solid(&node(Op::Union, vec![a.clone(), a.clone()])).unwrap();
        let int = csg.add_solid(&node(Op::Intersection, vec![a.clone(), a.clone(), a.clone()])).unwrap();
        let (lo, hi) = csg.bounds(sa);
        for _ in 0..200 {
            let rays: [TestRay; 8] = std::array::from_fn(|_| {
                let (o, d) = r.ray(lo, hi);
                (o, d, 0.0, f32::INFINITY)
            });
            let (packet, tmin) = ray8(&rays);
            let mut out = [None; 8];
            first_hit_x8(&csg, empty, &packet, tmin, &mut arena, &mut out);
            assert!(out.iter().all(|h| h.is_none()), "A - A hit (x8): {out:?}");
            for &(o, d, _, _) in &rays {
                assert_eq!(first_hit(&csg, empty, o, d, 0.0, f32::INFINITY, &mut arena), None, "A - A hit");
                intervals_f64(&csg, empty, dv(o), dv(d), &mut iv);
                assert!(iv.is_empty(), "A - A reference {iv:?}");
                // A - A' : empty but for near-tangent slivers (where f32 roots are sqrt(eps)-sensitive).
                if let Some(h) = first_hit(&csg, empty2, o, d, -1e6, f32::INFINITY, &mut arena) {
                    let exit = first_hit(&csg, empty2, o, d, h.t, f32::INFINITY, &mut arena).unwrap();
                    assert!(((exit.t - h.t) * d.length()) < 1e-3, "{shape:?}: A - A' = {h:?}..{exit:?}");
                    slivers += 1;
                }
                let want = first_hit(&csg, sa, o, d, 0.0, f32::INFINITY, &mut arena);
                hits += usize::from(want.is_some());
                for s in [uni, int] {
                    let got = first_hit(&csg, s, o, d, 0.0, f32::INFINITY, &mut arena);
                    match (got, want) {
                        (None, None) => {}
                        (Some(g), Some(w)) => {
                            assert_eq!(g.entering, w.entering);
                            assert!(!g.flip);
                            assert!((g.t - w.t).abs() as f64 <= 1e-5 * (w.t.abs() as f64 + scale(o, d)));
                        }
                        (None, Some(w)) => {
                            // Allowed only for a sliver of A shorter than the tolerance (entry and exit
                            // are one event under the coincidence rule).
                            let exit = first_hit(&csg, sa, o, d, w.t, f32::INFINITY, &mut arena).unwrap();
                            let tol = 1e-5 * (w.t.abs() as f64 + scale(o, d));
                            assert!(((exit.t - w.t) as f64) <= tol, "{shape:?}: A op A misses {w:?}");
                        }
                        _ => panic!("{shape:?}: A op A {got:?} vs A {want:?}"),
                    }
                }
            }
        }
    }
    assert!(hits > 20_000, "{hits}");
    println!("A - A': {slivers} sliver rays of 64000");
    assert!(slivers * 500 < 64_000, "{slivers} rays see slivers of A - A'");
}

/// A 4 × 4 × 2 box with a radius-0.5 hole whose top cap lies exactly in the box's top face (`z = 1` before
/// the placement): a blind hole to `z = -0.25` and a through hole (`z = ±1`, flush with both faces). Under
/// several placements (identity, quarter turns, arbitrary rotations with translation), rays from above that
/// enter within radius 0.45 and stay inside the hole see the hole's bottom (a flipped cylinder cap,
/// entering) or pass straight through; never the top face. Rays that land on the top face outside radius
/// 0.55 see the box's top. Scalar, x8 and reference agree.
#[test]
fn flush_hole_is_a_clean_opening() {
    let mut r = R::new(55);
    let mut arena = CsgArena::new();
    let mut iv = Vec::new();
    let placements = [
        Affine3A::IDENTITY,
        Affine3A::from_rotation_x(std::f32::consts::FRAC_PI_2),
        Affine3A::from_rotation_y(std::f32::consts::PI),
        placement(),
        Affine3A::from_rotation_translation(Quat::from_euler(glam::EulerRot::ZYX, 2.1, 0.4, -0.9), Vec3::new(3.0, -7.5, 11.0)),
    ];
    for g in placements {
        let bx = leaf(Shape::Box, g * Affine3A::from_scale(Vec3::new(2.0, 2.0, 1.0)));
        let blind_cyl = Affine3A::from_scale_rotation_translation(Vec3::new(0.5, 0.5, 0.625), Quat::IDENTITY, Vec3::new(0.0, 0.0, 0.375));
        let blind = node(Op::Difference, vec![bx.clone(), leaf(Shape::Cylinder, g * blind_cyl)]);
        let through = node(Op::Difference, vec![bx, leaf(Shape::Cylinder, g * Affine3A::from_scale(Vec3::new(0.5, 0.5, 1.0)))]);
        let mut csg = Csg::new();
        let (sb, st) = (csg.add_solid(&blind).unwrap(), csg.add_solid(&through).unwrap());
        let to_world = |p: DVec3| g.transform_point3(p.as_vec3());
        let disk = |r: &mut R, rad: f64| loop {
            let (x, y) = (r.range(-rad, rad), r.range(-rad, rad));
            if x * x + y * y <= rad * rad {
                return (x, y);
            }
        };
        for _ in 0..2000 {
            // Into the hole: from (x0, y0, 3) to (x1, y1, -0.25 or -1.5), both within radius 0.45.
            let (x0, y0) = disk(&mut r, 0.45);
            let (x1, y1) = disk(&mut r, 0.45);
            let o_local = DVec3::new(x0, y0, 3.0);
            for (solid, bottom) in [(sb, -0.25), (st, -1.0)] {
                let target = DVec3::new(x1, y1, bottom);
                let (o, d) = (to_world(o_local), to_world(target) - to_world(o_local));
                // d spans o -> target, so the bottom is at t = 1.
                let h = first_hit(&csg, solid, o, d, 0.0, f32::INFINITY, &mut arena);
                let (packet, tmin) = ray8(&[(o, d, 0.0, f32::INFINITY); 8]);
                let mut out = [None; 8];
                first_hit_x8(&csg, solid, &packet, tmin, &mut arena, &mut out);
                assert_eq!(h, out[3]);
                intervals_f64(&csg, solid, dv(o), dv(d), &mut iv);
                if solid == sb {
                    let h = h.expect("blind hole: no hit");
                    assert!((h.t - 1.0).abs() < 1e-4, "blind hole hit at t={} (bottom at 1)", h.t);
                    assert!(h.flip && h.entering && h.leaf == csg.solid_leaves(sb).start + 1, "{h:?}");
                    let n = csg.hit_normal(&h, o + d * h.t);
                    assert!(n.dot(g.transform_vector3(Vec3::Z)) > 0.999, "bottom normal {n}");
                    assert!((iv[0].0 - 1.0).abs() < 1e-6, "reference {iv:?}");
                } else {
                    assert_eq!(h, None, "through hole: {h:?}");
                    assert!(iv.is_empty(), "through hole reference {iv:?}");
                }
            }
            // Onto the top face outside the hole.
            let (x, y) = loop {
                let (x, y) = (r.range(-1.9, 1.9), r.range(-1.9, 1.9));
                if x * x + y * y > 0.55 * 0.55 {
                    break (x, y);
                }
            };
            let target = DVec3::new(x, y, 1.0);
            let o_local = target + DVec3::new(r.range(-1.0, 1.0), r.range(-1.0, 1.0), 2.0);
            for solid in [sb, st] {
                let (o, d) = (to_world(o_local), to_world(target) - to_world(o_local));
                let h = first_hit(&csg, solid, o, d, 0.0, f32::INFINITY, &mut arena).expect("top face");
                assert!((h.t - 1.0).abs() < 1e-4 && !h.flip && h.entering, "{h:?}");
                assert_eq!(h.leaf, csg.solid_leaves(solid).start);
            }
        }
    }
}

/// Smallest gap between two faces still resolved as two faces: the union of the slabs `z ∈ [-1, 0]` and
/// `z ∈ [g, 1 + g]` (4 × 4 wide), seen from above by a slightly oblique ray. It is resolved when the
/// boundary after the entry is the exit at `z = g` (fast path) / the reference has two intervals. The
/// measured threshold must be within a factor 1.5 of the documented tolerance
/// `1e-5 (max(L, |o'|_inf) + |t' d|)` at the gap (world units along the ray), with `o'` the origin re-based
/// to just above the solid (`t'` from it) and `L` = 2 the solid's scale: the same whether the origin is
/// 4 or 50 above (before re-basing, 50 above merged gaps 10x wider).
#[test]
fn smallest_resolved_gap() {
    let mut arena = CsgArena::new();
    let mut iv = Vec::new();
    for height in [4.0f32, 50.0] {
        let o = Vec3::new(0.1, 0.2, height);
        let d = Vec3::new(0.01, -0.02, -1.0) * 0.7;
        let resolved = |g: f32, fast: bool, arena: &mut CsgArena, iv: &mut Vec<(f64, f64)>| {
            let lower = leaf(
                Shape::Box,
                Affine3A::from_scale_rotation_translation(Vec3::new(2.0, 2.0, 0.5), Quat::IDENTITY, Vec3::new(0.0, 0.0, -0.5)),
            );
            let upper = leaf(
                Shape::Box,
                Affine3A::from_scale_rotation_translation(Vec3::new(2.0, 2.0, 0.5), Quat::IDENTITY, Vec3::new(0.0, 0.0, 0.5 + g)),
            );
            let mut csg = Csg::new();
            let s = csg.add_solid(&node(Op::Union, vec![lower, upper])).unwrap();
            if fast {
                let h1 = first_hit(&csg, s, o, d, 0.0, f32::INFINITY, arena).unwrap();
                let h2 = first_hit(&csg, s, o, d, h1.t, f32::INFINITY, arena).unwrap();
                !h2.entering && (o.z + d.z * h2.t) > -0.5
            } else {
                intervals_f64(&csg, s, dv(o), dv(d), iv);
                iv.len() == 2
            }
        };
        // Distance along the ray per unit gap, and the tolerance at the gap from the re-based origin.
        let along = (d.length() / d.z.abs()) as f64;
        let bounds = (Vec3::new(-2.0, -2.0, -1.0), Vec3::new(2.0, 2.0, 1.0));
        let o2 = dv(o) + dv(d) * strata::csg::reference::rebase_shift_f64(bounds, dv(o), dv(d));
        assert!(o2.z > 1.0 && o2.z < 1.2, "re-based to {o2}");
        let predicted = 1e-5 * (o2.abs().max_element().max(2.0) + o2.z * along);
        for fast in [true, false] {
            let mut smallest = f64::NAN;
            let mut g = 2e-3f64;
            while g > 1e-7 {
                if !resolved(g as f32, fast, &mut arena, &mut iv) {
                    break;
                }
                smallest = g * along;
                g *= 0.97;
            }
            assert!(!resolved((0.6 * predicted / along) as f32, fast, &mut arena, &mut iv));
            println!(
                "smallest resolved gap ({}, origin {height} away): {smallest:.3e} world units along the ray (documented tolerance {predicted:.3e})",
                if fast { "first_hit" } else { "intervals_f64" }
            );
            assert!(smallest > predicted / 1.5 && smallest < predicted * 1.5, "{smallest} vs {predicted}");
        }
    }
}

/// A box `[-w, w]^2 × [z0, z1]` (material `m`) in the frame `g`.
fn slab(g: Affine3A, w: f32, z0: f32, z1: f32, m: u32) -> CsgTree {
    let local =
        Affine3A::from_scale_rotation_translation(Vec3::new(w, w, 0.5 * (z1 - z0)), Quat::IDENTITY, Vec3::new(0.0, 0.0, 0.5 * (z0 + z1)));
    CsgTree::Leaf(Leaf::new(Shape::Box, g * local, m))
}

/// Rigid frames for the stacked-box tests: identity, a quarter turn, the assembly placement, and an
/// arbitrary rotation far from the origin (larger tolerance, coarser f32 rounding).
fn rigid_frames() -> [Affine3A; 4] {
    [
        Affine3A::IDENTITY,
        Affine3A::from_rotation_x(std::f32::consts::FRAC_PI_2),
        placement(),
        Affine3A::from_rotation_translation(Quat::from_euler(glam::EulerRot::ZYX, 2.1, 0.4, -0.9), Vec3::new(3.0, -7.5, 11.0)),
    ]
}

/// A fixed grid of rays in the frame `g`, given in local coordinates: origins `(x, y, z)` for `x, y` in
/// `{-0.6, -0.2, 0.2, 0.6}`, directions `(dx, dy, ±1) × len` for `dx, dy` in `{-0.2, 0, 0.15}`, lengths
/// 0.7 and 1.3 (`d` not unit). Returned as (local origin, local direction, world origin, world direction);
/// `g` is rigid, so `t` is the same in both frames.
fn ray_grid(g: Affine3A, z: f64, up: bool) -> Vec<(DVec3, DVec3, Vec3, Vec3)> {
    let mut rays = Vec::new();
    let c = [-0.6, -0.2, 0.2, 0.6];
    let tilt = [-0.2, 0.0, 0.15];
    for &len in &[0.7, 1.3] {
        for &dx in &tilt {
            for &dy in &tilt {
                for &x in &c {
                    for &y in &c {
                        let (ol, dl) = (DVec3::new(x, y, z), DVec3::new(dx, dy, if up { 1.0 } else { -1.0 }) * len);
                        rays.push((ol, dl, g.transform_point3(ol.as_vec3()), g.transform_vector3(dl.as_vec3())));
                    }
                }
            }
        }
    }
    rays
}

/// `first_hit` for one ray, held bit for bit to `first_hit_x8` (the ray in every lane).
fn hit_both(csg: &Csg, s: u32, o: Vec3, d: Vec3, tmin: f32, arena: &mut CsgArena) -> Option<CsgHit> {
    let h = first_hit(csg, s, o, d, tmin, f32::INFINITY, arena);
    let (packet, tmin8) = ray8(&[(o, d, tmin, f32::INFINITY); 8]);
    let mut out = [None; 8];
    first_hit_x8(csg, s, &packet, tmin8, arena, &mut out);
    assert!(out.iter().all(|&x| x == h), "scalar {h:?} vs x8 {out:?}");
    h
}

/// Two stacked boxes whose shared face is not quite shared: the lower box `z ∈ [-1, 0]`, the upper one
/// `z ∈ [δ, 1 + δ]` with `δ` = 1e-6 and 3e-6 (a gap, so the lower box's exit comes strictly before the
/// upper one's entry in f32) or -2e-6 (an overlap), placed through a different transform (`g · T(δ z) ·
/// box`), in four rigid frames, both operand orders. `δ` is far below the coincidence tolerance (≥ 1e-5
/// world units), so the union is one solid. Rays start inside the lower box (`z = -0.5`, a 4 × 4 × 9 × 2
/// grid) going up, `tmin = 0`: the f64 reference has one interval, and its exit is the upper box's far face
/// `z = 1 + δ` (analytic); the first hit of `first_hit` / `first_hit_x8` is that exit, on the upper box's
/// leaf, not an exit at the joint (merge shortcut for "disjoint" operands taken without the tolerance).
#[test]
fn union_of_nearly_touching_boxes_has_no_joint() {
    let mut arena = CsgArena::new();
    let mut iv = Vec::new();
    let mut rays = 0;
    for g in rigid_frames() {
        for delta in [1e-6f32, 3e-6, -2e-6] {
            let lower = slab(g, 2.0, -1.0, 0.0, 1);
            let upper = slab(g * Affine3A::from_translation(Vec3::new(0.0, 0.0, delta)), 2.0, 0.0, 1.0, 2);
            let mut csg = Csg::new();
            let lu = csg.add_solid(&node(Op::Union, vec![lower.clone(), upper.clone()])).unwrap();
            let ul = csg.add_solid(&node(Op::Union, vec![upper, lower])).unwrap();
            let upper_leaf = [csg.solid_leaves(lu).start + 1, csg.solid_leaves(ul).start];
            for (ol, dl, o, d) in ray_grid(g, -0.5, true) {
                let exit = (1.0 + delta as f64 - ol.z) / dl.z;
                let tol = 1e-4 * (exit + scale(o, d));
                for (s, up) in [(lu, upper_leaf[0]), (ul, upper_leaf[1])] {
                    intervals_f64(&csg, s, dv(o), dv(d), &mut iv);
                    assert!(iv.len() == 1 && iv[0].0 < 0.0 && (iv[0].1 - exit).abs() <= tol, "reference {iv:?}, exit at {exit}");
                    let h = hit_both(&csg, s, o, d, 0.0, &mut arena).expect("no exit");
                    assert!(
                        !h.entering && (h.t as f64 - iv[0].1).abs() <= tol && h.leaf == up && !h.flip,
                        "δ={delta} g={g:?} o={o} d={d}: first hit {h:?}, reference exit {} (upper box's far face, leaf {up})",
                        iv[0].1
                    );
                    rays += 1;
                }
            }
        }
    }
    assert_eq!(rays, 4 * 3 * 288 * 2);
}

/// `A ∪ B` with a gap smaller than the coincidence tolerance and `tmin` inside the gap: the lower box
/// `z ∈ [-1, 0]` and the upper box `z ∈ [δ, 1 + δ]`, `δ` = 4e-6 and 8e-6, both orders, four rigid frames,
/// rays from below (`z = -2`, a 4 × 4 × 9 × 2 grid) going up with `tmin` at `z = δ / 2` (analytic).
/// The gap is one event under the rule, so the ray is inside the union at `tmin`: the f64 reference has
/// one interval around `tmin`, and the first hit must be its exit at `z = 1 + δ` (analytic), not an entry
/// at the upper box's near face (the lower box's interval, which ends just before `tmin`, must still be
/// merged with it).
#[test]
fn union_gap_below_tolerance_with_tmin_inside() {
    let mut arena = CsgArena::new();
    let mut iv = Vec::new();
    let mut rays = 0;
    for g in rigid_frames() {
        for delta in [4e-6f32, 8e-6] {
            let lower = slab(g, 2.0, -1.0, 0.0, 1);
            let upper = slab(g, 2.0, delta, 1.0 + delta, 2);
            let mut csg = Csg::new();
            let lu = csg.add_solid(&node(Op::Union, vec![lower.clone(), upper.clone()])).unwrap();
            let ul = csg.add_solid(&node(Op::Union, vec![upper, lower])).unwrap();
            for (ol, dl, o, d) in ray_grid(g, -2.0, true) {
                let at = |z: f64| (z - ol.z) / dl.z;
                let (tmin, exit) = (at(0.5 * delta as f64), at(1.0 + delta as f64));
                let tol = 1e-4 * (exit + scale(o, d));
                for s in [lu, ul] {
                    intervals_f64(&csg, s, dv(o), dv(d), &mut iv);
                    assert!(iv.len() == 1 && iv[0].0 < tmin && (iv[0].1 - exit).abs() <= tol, "reference {iv:?}, tmin {tmin}");
                    let h = hit_both(&csg, s, o, d, tmin as f32, &mut arena).expect("no exit");
                    assert!(
                        !h.entering && (h.t as f64 - iv[0].1).abs() <= tol,
                        "δ={delta} g={g:?} o={o} d={d} tmin={tmin}: first hit {h:?}, reference exit {} (upper box's far face)",
                        iv[0].1
                    );
                    rays += 1;
                }
            }
        }
    }
    assert_eq!(rays, 4 * 2 * 288 * 2);
}

/// Which leaf a coincident boundary reports: where both operands' crossings form the group and both
/// moved the way the result did, the boundary belongs to the left operand (`merge.rs`: "from the operand
/// whose own state changed the same way as the result's (`a` preferred)"), so its material and `flip` are
/// the left operand's. Analytic cases in four rigid frames, rays on a 4 × 4 × 9 × 2 grid:
/// - `A ∪ B` and `B ∪ A`, `A = [-1, 1]^3`, `B = [-1.5, 1.5]^2 × [-1, 0.5]` (same bottom face, built
///   through another scale and translation): from below, the entry at `z = -1` is the left operand's
///   leaf (material 1 or 2), unflipped;
/// - `A - B`, `A = [-1.5, 1.5]^2 × [0, 1]`, `B = [-2, 2]^2 × [-1, 0]`: from below, the entry at `z = 0`
///   (A's bottom face flush with B's top) is A's leaf, `flip = false`; from above, the exit at `z = 0`
///   after the entry at `z = 1` is A's leaf, `flip = false`.
///
/// Every `t` is held to the analytic face and to the f64 reference.
#[test]
fn coincident_boundary_belongs_to_left_operand() {
    let mut arena = CsgArena::new();
    let mut iv = Vec::new();
    let mut rays = 0;
    for g in rigid_frames() {
        let a = slab(g, 1.0, -1.0, 1.0, 1);
        let b = slab(g, 1.5, -1.0, 0.5, 2);
        let (da, db) = (slab(g, 1.5, 0.0, 1.0, 3), slab(g, 2.0, -1.0, 0.0, 4));
        let mut csg = Csg::new();
        let ab = csg.add_solid(&node(Op::Union, vec![a.clone(), b.clone()])).unwrap();
        let ba = csg.add_solid(&node(Op::Union, vec![b, a])).unwrap();
        let diff = csg.add_solid(&node(Op::Difference, vec![da, db])).unwrap();
        let first_boundary = |csg: &Csg, s: u32, o: Vec3, d: Vec3, iv: &mut Vec<(f64, f64)>| {
            intervals_f64(csg, s, dv(o), dv(d), iv);
            iv[0]
        };
        for (ol, dl, o, d) in ray_grid(g, -2.0, true) {
            let at = |z: f64| (z - ol.z) / dl.z;
            let tol = |t: f64| 1e-4 * (t.abs() + scale(o, d));
            for (s, want) in [(ab, 1), (ba, 2), (diff, 3)] {
                let face = at(if s == diff { 0.0 } else { -1.0 });
                let (entry, _) = first_boundary(&csg, s, o, d, &mut iv);
                assert!((entry - face).abs() <= tol(face), "reference {iv:?}, face at {face}");
                let h = hit_both(&csg, s, o, d, 0.0, &mut arena).expect("no entry");
                assert!(
                    h.entering && (h.t as f64 - entry).abs() <= tol(entry) && csg.leaf(h.leaf).material == want && !h.flip,
                    "g={g:?} o={o} d={d}: entry {h:?} (material {}), want the left operand's (material {want}), unflipped",
                    csg.leaf(h.leaf).material
                );
                rays += 1;
            }
        }
        for (ol, dl, o, d) in ray_grid(g, 2.0, false) {
            let at = |z: f64| (z - ol.z) / dl.z;
            let face = at(0.0);
            let tol = 1e-4 * (face + scale(o, d));
            let (top, exit) = first_boundary(&csg, diff, o, d, &mut iv);
            assert!((top - at(1.0)).abs() <= tol && (exit - face).abs() <= tol, "reference {iv:?}, exit at {face}");
            let entry = hit_both(&csg, diff, o, d, 0.0, &mut arena).expect("no entry");
            assert!(entry.entering && csg.leaf(entry.leaf).material == 3 && !entry.flip, "{entry:?}");
            let h = hit_both(&csg, diff, o, d, entry.t, &mut arena).expect("no exit");
            assert!(
                !h.entering && (h.t as f64 - exit).abs() <= tol && csg.leaf(h.leaf).material == 3 && !h.flip,
                "g={g:?} o={o} d={d}: exit {h:?} (material {}), want A's bottom face (material 3), unflipped",
                csg.leaf(h.leaf).material
            );
            rays += 1;
        }
    }
    assert_eq!(rays, 4 * 288 * 4);
}

// ---------------------------------------------------------------------------------------------------------
// Deep trees, errors, bounds, arena
// ---------------------------------------------------------------------------------------------------------

/// `n` nested differences. Left: `(((box - s1) - s2) ...)`; right: `b1 - (b2 - (b3 - ...))`, which needs an
/// evaluation stack as deep as the tree.
fn difference_chain(n: usize, right: bool, r: &mut R) -> CsgTree {
    let sphere = |r: &mut R| {
        let c = r.in_box(DVec3::splat(-1.0), DVec3::splat(1.0)).as_vec3();
        leaf(Shape::Sphere, Affine3A::from_scale_rotation_translation(Vec3::splat(0.3), Quat::IDENTITY, c))
    };
    if right {
        let mut t = leaf(Shape::Box, Affine3A::from_scale(Vec3::splat(0.2)));
        for i in 0..n {
            let s = 0.2 + 0.02 * (i + 1) as f32;
            t = node(Op::Difference, vec![leaf(Shape::Box, Affine3A::from_scale(Vec3::splat(s))), t]);
        }
        t
    } else {
        let mut t = leaf(Shape::Box, Affine3A::IDENTITY);
        for _ in 0..n {
            t = node(Op::Difference, vec![t, sphere(r)]);
        }
        t
    }
}

#[test]
fn deep_nesting_limit() {
    let mut r = R::new(66);
    let mut arena = CsgArena::new();
    let mut iv = Vec::new();
    for right in [false, true] {
        let mut csg = Csg::new();
        for n in [60, 64] {
            let s = csg.add_solid(&difference_chain(n, right, &mut r)).unwrap();
            let (lo, hi) = csg.bounds(s);
            let mut hits = 0;
            for _ in 0..500 {
                let (o, d) = r.ray(lo, hi);
                let h = first_hit(&csg, s, o, d, 0.0, f32::INFINITY, &mut arena);
                intervals_f64(&csg, s, dv(o), dv(d), &mut iv);
                let want = boundaries(&iv).into_iter().find(|b| b.0 > 0.0);
                match (h, want) {
                    (None, None) => {}
                    (Some(h), Some((t, e))) => {
                        assert_eq!(h.entering, e);
                        assert!((h.t as f64 - t).abs() <= 1e-4 * (t.abs() + scale(o, d)), "{h:?} vs {t}");
                        hits += 1;
                    }
                    _ => panic!("depth {n}: {h:?} vs {iv:?}"),
                }
            }
            assert!(hits > 100, "{hits}");
        }
        let (leaves, solids) = (csg.leaf_count(), csg.solid_count());
        assert_eq!(csg.add_solid(&difference_chain(65, right, &mut r)), Err(CsgError::TooDeep { limit: 64 }));
        assert_eq!((csg.leaf_count(), csg.solid_count()), (leaves, solids), "a rejected tree left data behind");
    }
}

#[test]
fn errors_and_bounds() {
    let mut csg = Csg::new();
    let unit = |s: Shape| leaf(s, Affine3A::IDENTITY);
    let hs = |n: Vec3, d: f32| CsgTree::Leaf(Leaf::half_space(n, d, 0));
    assert_eq!(csg.add_solid(&node(Op::Union, vec![])), Err(CsgError::EmptyNode));
    assert_eq!(csg.add_solid(&node(Op::Union, vec![unit(Shape::Box), node(Op::Intersection, vec![])])), Err(CsgError::EmptyNode));
    assert_eq!(csg.add_solid(&hs(Vec3::Z, 0.0)), Err(CsgError::Unbounded));
    assert_eq!(csg.add_solid(&node(Op::Union, vec![unit(Shape::Sphere), hs(Vec3::Z, 0.0)])), Err(CsgError::Unbounded));
    assert_eq!(csg.add_solid(&node(Op::Intersection, vec![hs(Vec3::Z, 0.0), hs(Vec3::X, 0.0)])), Err(CsgError::Unbounded));
    assert_eq!(csg.add_solid(&node(Op::Difference, vec![hs(Vec3::Z, 0.0), unit(Shape::Sphere)])), Err(CsgError::Unbounded));
    assert_eq!(csg.solid_count(), 0);
    assert_eq!(csg.leaf_count(), 0);
    let close = |a: (Vec3, Vec3), b: (Vec3, Vec3)| (a.0 - b.0).abs().max_element() < 1e-5 && (a.1 - b.1).abs().max_element() < 1e-5;
    let at = |x: f32| Affine3A::from_translation(Vec3::new(x, 0.0, 0.0));
    // Union, intersection (overlap), difference (left child).
    let u = csg.add_solid(&node(Op::Union, vec![unit(Shape::Box), leaf(Shape::Sphere, at(1.5))])).unwrap();
    assert!(close(csg.bounds(u), (Vec3::new(-1.0, -1.0, -1.0), Vec3::new(2.5, 1.0, 1.0))));
    let i = csg.add_solid(&node(Op::Intersection, vec![unit(Shape::Box), leaf(Shape::Sphere, at(1.5))])).unwrap();
    assert!(close(csg.bounds(i), (Vec3::new(0.5, -1.0, -1.0), Vec3::new(1.0, 1.0, 1.0))));
    let d = csg.add_solid(&node(Op::Difference, vec![unit(Shape::Box), leaf(Shape::Sphere, at(1.5))])).unwrap();
    assert!(close(csg.bounds(d), (Vec3::splat(-1.0), Vec3::splat(1.0))));
    // Half-spaces clip inside intersections: axis-aligned, oblique (the box corner cut off), and the
    // first child of a difference inside an intersection.
    let c = csg.add_solid(&node(Op::Intersection, vec![hs(Vec3::Z, 0.25), unit(Shape::Box)])).unwrap();
    assert!(close(csg.bounds(c), (Vec3::splat(-1.0), Vec3::new(1.0, 1.0, 0.25))));
    let c = csg.add_solid(&node(Op::Intersection, vec![unit(Shape::Box), hs(Vec3::ONE, -2.0)])).unwrap();
    assert!(close(csg.bounds(c), (Vec3::splat(-1.0), Vec3::splat(0.0))));
    let c = csg
        .add_solid(&node(Op::Intersection, vec![unit(Shape::Box), node(Op::Difference, vec![hs(-Vec3::X, 0.5), unit(Shape::Sphere)])]))
        .unwrap();
    assert!(close(csg.bounds(c), (Vec3::new(-0.5, -1.0, -1.0), Vec3::splat(1.0))));
    // Disjoint intersection: empty bounds, no hits.
    let e = csg.add_solid(&node(Op::Intersection, vec![unit(Shape::Box), leaf(Shape::Sphere, at(5.0))])).unwrap();
    let (lo, hi) = csg.bounds(e);
    assert!(lo.cmpgt(hi).all());
    let mut arena = CsgArena::new();
    assert_eq!(first_hit(&csg, e, Vec3::new(-9.0, 0.0, 0.0), Vec3::X, 0.0, f32::INFINITY, &mut arena), None);
    // Unknown ids and empty ranges do not panic.
    assert_eq!(first_hit(&csg, 999, Vec3::ZERO, Vec3::X, 0.0, 1.0, &mut arena), None);
    assert_eq!(first_hit(&csg, u, Vec3::ZERO, Vec3::X, 1.0, 1.0, &mut arena), None);
    // Directions that are not rays (zero, non-finite) give nothing and return (the reference once
    // looped for ever on a zero direction), from inside the solid and from outside.
    let mut iv = vec![(0.0, 1.0)];
    for o in [Vec3::ZERO, Vec3::new(-9.0, 0.2, 0.1)] {
        for d in [Vec3::ZERO, Vec3::new(f32::NAN, 0.0, 1.0), Vec3::new(f32::INFINITY, 0.0, 0.0)] {
            intervals_f64(&csg, u, dv(o), dv(d), &mut iv);
            assert!(iv.is_empty(), "{o} + t {d}: {iv:?}");
            assert_eq!(first_hit(&csg, u, o, d, 0.0, f32::INFINITY, &mut arena), None, "{o} + t {d}");
        }
    }
}

/// Every reference interval of random solids lies inside the solid's bounds (the bounds are conservative),
/// and `inside` agrees with the reference at interval midpoints and just outside them.
#[test]
fn bounds_contain_intervals_and_inside_agrees() {
    let mut r = R::new(77);
    let mut iv = Vec::new();
    let mut checked = 0;
    for _ in 0..200 {
        let mut csg = Csg::new();
        let s = csg.add_solid(&r.tree(3)).unwrap();
        let (lo, hi) = csg.bounds(s);
        if lo.cmpgt(hi).any() {
            continue;
        }
        for _ in 0..50 {
            let (o, d) = r.ray(lo, hi);
            intervals_f64(&csg, s, dv(o), dv(d), &mut iv);
            for &(a, b) in &iv {
                for t in [a, b] {
                    let p = (dv(o) + dv(d) * t).as_vec3();
                    assert!(p.cmpge(lo - 1e-4).all() && p.cmple(hi + 1e-4).all(), "{p} outside {lo} {hi}");
                }
                // Only pieces well above the tolerance: the midpoint is inside.
                if (b - a) * d.length() as f64 > 1e-3 {
                    let m = (dv(o) + dv(d) * (0.5 * (a + b))).as_vec3();
                    assert!(csg.inside(s, m), "midpoint {m} of {a}..{b} not inside");
                    checked += 1;
                }
            }
        }
    }
    assert!(checked > 2000, "{checked}");
}

/// The arena stops growing: after a warm-up over every solid, 50k more rays (scalar and x8) leave its
/// capacity unchanged.
#[test]
fn arena_does_not_grow_after_warm_up() {
    let mut r = R::new(88);
    let mut csg = Csg::new();
    let mut solids = vec![csg.add_solid(&difference_chain(60, true, &mut r)).unwrap()];
    for _ in 0..20 {
        solids.push(csg.add_solid(&r.tree(3)).unwrap());
    }
    let mut arena = CsgArena::new();
    let run = |n: usize, arena: &mut CsgArena, r: &mut R| {
        for k in 0..n {
            let s = solids[k % solids.len()];
            let (lo, hi) = csg.bounds(s);
            let (lo, hi) = if lo.cmpgt(hi).any() { (Vec3::splat(-1.0), Vec3::splat(1.0)) } else { (lo, hi) };
            let rays: [TestRay; 8] = std::array::from_fn(|_| {
                let (o, d) = r.ray(lo, hi);
                (o, d, 0.0, f32::INFINITY)
            });
            let (packet, tmin) = ray8(&rays);
            let mut out = [None; 8];
            first_hit_x8(&csg, s, &packet, tmin, arena, &mut out);
            first_hit(&csg, s, rays[0].0, rays[0].1, 0.0, f32::INFINITY, arena);
        }
    };
    run(2_000, &mut arena, &mut r);
    let cap = arena.capacity();
    assert!(cap > 0);
    run(50_000 / 8, &mut arena, &mut r);
    assert_eq!(arena.capacity(), cap, "the arena grew after warm-up");
}

/// The setup's probes of a solid (for thin parts, and for volume) take their leaf tests and program
/// instructions from a budget and stop where it runs out: the program runs at every group of crossings,
/// so a ray through n leaves costs ~n^2 (a trial's solid of 10^5 overlapping spheres spent 21 s of its
/// setup in the thin-part probe). Here 40,000 spheres in 800 places along x, which without the budgets
/// took 5.9 s (the volume probe; 0.8 s the thin-part one); with ample budgets small solids are still probed to the end.
#[test]
fn probes_stop_where_their_budget_runs_out() {
    use strata::csg::reference::{probe_finds_volume, thinnest_part};
    let ball =
        |x: f32| leaf(Shape::Sphere, Affine3A::from_scale_rotation_translation(Vec3::splat(0.1), Quat::IDENTITY, Vec3::new(x, 0.0, 0.0)));
    let balls: Vec<CsgTree> = (0..40_000).map(|i| ball((i % 800) as f32 * 0.025)).collect();
    let cover = leaf(Shape::Box, Affine3A::from_scale_rotation_translation(Vec3::splat(30.0), Quat::IDENTITY, Vec3::ZERO));
    let mut csg = Csg::new();
    let many = csg.add_solid(&node(Op::Union, balls.clone())).unwrap();
    let many_empty = csg.add_solid(&node(Op::Difference, vec![node(Op::Union, balls), cover.clone()])).unwrap();
    let mut budget = 1 << 20;
    thinnest_part(&csg, many, 8, 0.1, 1e-7, &mut budget);
    assert_eq!(budget, 0, "the thin-part probe stops where its budget runs out");
    let mut budget = 1 << 20;
    assert_eq!(probe_finds_volume(&csg, many_empty, 24, &mut budget), None, "not known: the budget ran out");
    let few = csg.add_solid(&node(Op::Union, vec![ball(0.0), ball(0.05)])).unwrap();
    let few_empty = csg.add_solid(&node(Op::Difference, vec![ball(0.0), cover])).unwrap();
    for (s, volume) in [(few, true), (few_empty, false)] {
        let mut budget = 1 << 22;
        assert_eq!(probe_finds_volume(&csg, s, 24, &mut budget), Some(volume));
        assert!(budget > 0);
    }
}
