//! Wide BVH tests (16 or 8 children per node, `WIDTH`): `WideBvh` invariants, the single-ray node
//! kernel against the packet slab test, the single-ray and packet traversals against brute force f64, and the intersect stage with and without
//! the wide BVH (same `t` bits, same primitive ids). All seeds fixed.

use std::collections::BTreeSet;
use std::path::Path;

use glam::{DVec3, Vec3};
use rand_core::Rng;
use strata::accel::{
    build_bvh, intersect_aabb_f64, intersect_aabb_x8, intersect_children_single, transpose8x8, Aabb, BuildOptions, Bvh, Collapse,
    PacketRay, WideBvh, WideNode, WideStack, MAX_DEPTH, WIDE_GROUP, WIDTH,
};
use strata::csg::CsgArena;
use strata::scene::{parse_scene, Scene};
use strata::simd::{f32x8, Ray8, Vec3x8, LANES};
use strata::wavefront::csg_merge::csg_merge;
use strata::wavefront::intersect::{intersect_with, Traversal};
use strata::wavefront::{CsgCandidates, HitQueue, RayItem, RayQueue};

// ---------------------------------------------------------------- random inputs

#[path = "common/rand.rs"]
mod common_rand;
use common_rand::{exponential_line, random_boxes, Rand};

impl Rand {
    /// A direction with components in [-1, 1], length at least 0.2; sometimes one or two components
    /// are zero (+0 or -0).
    fn dir_with_zeros(&mut self) -> Vec3 {
        let mut d = loop {
            let d = self.vec(-1.0, 1.0);
            if d.length() > 0.2 {
                break d;
            }
        };
        if self.chance(0.15) {
            let a = self.below(3) as usize;
            d[a] = if self.chance(0.5) { 0.0 } else { -0.0 };
            if self.chance(0.3) {
                d[(a + 1) % 3] = 0.0;
            }
        }
        d
    }
}

fn collapse_ok(bounds: &[Aabb], opts: &BuildOptions) -> (Bvh, WideBvh) {
    let bvh = build_bvh(bounds, opts);
    let greedy = WideBvh::from_bvh(&bvh, Collapse::Greedy);
    if let Err(e) = greedy.validate(bounds) {
        panic!("WideBvh::validate failed for {} boxes ({opts:?}, greedy collapse): {e}", bounds.len());
    }
    let w = WideBvh::from_bvh(&bvh, Collapse::Sah);
    if let Err(e) = w.validate(bounds) {
        panic!("WideBvh::validate failed for {} boxes ({opts:?}, SAH collapse): {e}", bounds.len());
    }
    // The SAH collapse is optimal over all cuts of the binary tree, the greedy one is one of them.
    assert!(w.sah_cost() <= greedy.sah_cost() * (1.0 + 1e-5), "SAH collapse {} > greedy {}", w.sah_cost(), greedy.sah_cost());
    (bvh, w)
}

/// Leaves as (first, count, box bits).
type Leaves = BTreeSet<(u32, u32, [u32; 6])>;

/// The leaves of the binary and of the wide tree.
fn leaves(bvh: &Bvh, w: &WideBvh) -> (Leaves, Leaves) {
    let bits = |b: Aabb| [b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z].map(f32::to_bits);
    let bin = bvh.nodes.iter().filter(|n| n.is_leaf()).map(|n| (n.left_first, n.count(), bits(n.aabb()))).collect();
    let wide = w
        .nodes
        .iter()
        .flat_map(|n| (0..WIDTH).filter(|&i| n.count[i] > 0).map(move |i| (n.child[i], n.count[i], bits(n.child_aabb(i)))))
        .collect();
    (bin, wide)
}

// ---------------------------------------------------------------- collapse invariants

#[test]
fn bvh8_invariants_on_random_and_degenerate_sets() {
    let mut rng = Rand::new(81);
    for (n, max_leaf) in [(1usize, 4u32), (2, 4), (3, 1), (9, 1), (100, 4), (3000, 4), (3000, 1), (500, 16)] {
        let bounds = random_boxes(&mut rng, n, 100.0, 5.0);
        let (bvh, w) = collapse_ok(&bounds, &BuildOptions { max_leaf, bins: 16 });
        assert_eq!(w.indices, bvh.indices);
        // Binary leaves stay leaves: same ranges, same boxes.
        let (bin, wide) = leaves(&bvh, &w);
        assert_eq!(bin, wide, "{n} boxes, max_leaf {max_leaf}");
        let inner = bvh.nodes.iter().filter(|n| !n.is_leaf()).count();
        assert!(w.nodes.len() <= inner.max(1), "{} wide nodes for {inner} binary inner nodes", w.nodes.len());
        if n >= 100 {
            // Greedy collapse fills nodes: on random sets, at least 5 children per node on average.
            let slots: usize = w.nodes.iter().map(|n| n.child_count()).sum();
            // Most binary inner nodes are flattened into their wide parents.
            assert!(
                2 * w.nodes.len() < inner,
                "{n} boxes, max_leaf {max_leaf}: {slots} slots in {} nodes, {inner} binary inner",
                w.nodes.len()
            );
        }
    }
    // Empty input: an empty tree.
    let (_, w) = collapse_ok(&[], &BuildOptions::default());
    assert!(w.is_empty());
    // Identical boxes (one leaf under the root), and a deep tree (exponentially spaced boxes on a line).
    let same = vec![Aabb::new(Vec3::ZERO, Vec3::ONE); 1000];
    let (_, w) = collapse_ok(&same, &BuildOptions::default());
    assert_eq!((w.nodes.len(), w.nodes[0].child_count()), (1, 1));
    let line = exponential_line(20_000);
    let (bvh, _) = collapse_ok(&line, &BuildOptions { max_leaf: 1, bins: 2 });
    assert!(bvh.depth() > 20 && bvh.depth() <= MAX_DEPTH);
}

#[test]
fn bvh8_validate_catches_corruption() {
    let mut rng = Rand::new(82);
    let bounds = random_boxes(&mut rng, 300, 50.0, 3.0);
    let (_, good) = collapse_ok(&bounds, &BuildOptions::default());
    let corrupt = |f: &dyn Fn(&mut WideBvh)| {
        let mut w = good.clone();
        f(&mut w);
        w.validate(&bounds)
    };
    let leaf_slot =
        |w: &WideBvh| w.nodes.iter().enumerate().find_map(|(k, n)| (0..WIDTH).find(|&i| n.count[i] > 0).map(|i| (k, i))).unwrap();
    // A leaf slot shrunk (its last primitive then belongs to no leaf).
    assert!(corrupt(&|w| {
        let (k, i) = leaf_slot(w);
        w.nodes[k].count[i] -= 1;
    })
    .is_err());
    // A child box that no longer contains its primitives.
    assert!(corrupt(&|w| {
        let (k, i) = leaf_slot(w);
        w.nodes[k].bounds[3][i] = w.nodes[k].bounds[0][i];
    })
    .is_err());
    // An inner slot pointing at the root (a cycle).
    assert!(corrupt(&|w| {
        let k = w.nodes.iter().position(|n| (0..WIDTH).any(|i| n.count[i] == 0 && n.child_count() > i)).unwrap();
        let i = (0..WIDTH).find(|&i| w.nodes[k].count[i] == 0).unwrap();
        w.nodes[k].child[i] = 0;
    })
    .is_err());
    // An empty slot that is not (+inf, -inf).
    assert!(corrupt(&|w| {
        let k = w.nodes.iter().position(|n| n.child_count() < WIDTH).unwrap();
        w.nodes[k].bounds[0][WIDTH - 1] = 0.0;
    })
    .is_err());
}

#[test]
fn node_layout_is_the_documented_bytes() {
    // With W = WIDTH: bounds at 0..24W (6 rows of W), child at 24W..28W, count at 28W..32W.
    let w = WIDTH;
    assert_eq!(std::mem::size_of::<WideNode>(), 32 * w);
    assert_eq!(std::mem::align_of::<WideNode>(), 64);
    let mut n = WideNode::EMPTY;
    n.bounds[4][2] = 7.0; // max y of child 2
    n.child[5] = 0xAABB_CCDD;
    n.count[w - 1] = 3;
    let bytes: &[u8] = bytemuck::bytes_of(&n);
    assert_eq!(&bytes[(4 * w + 2) * 4..(4 * w + 3) * 4], &7.0f32.to_ne_bytes());
    assert_eq!(&bytes[24 * w + 5 * 4..24 * w + 6 * 4], &0xAABB_CCDDu32.to_ne_bytes());
    assert_eq!(&bytes[32 * w - 4..32 * w], &3u32.to_ne_bytes());
}

#[test]
fn transpose8x8_matches_naive() {
    let mut rng = Rand::new(83);
    for k in 0..2000u64 {
        let x = match k {
            0 => 0,
            1 => u64::MAX,
            2 => 1,
            3 => 1 << 63,
            _ => (rng.0.next_u32() as u64) << 32 | rng.0.next_u32() as u64,
        };
        let mut naive = 0u64;
        for r in 0..8 {
            for c in 0..8 {
                naive |= ((x >> (8 * r + c)) & 1) << (8 * c + r);
            }
        }
        assert_eq!(transpose8x8(x), naive, "{x:#018x}");
    }
}

// ---------------------------------------------------------------- node kernel

fn packet(o: [Vec3; LANES], d: [Vec3; LANES], tmax: [f32; LANES]) -> Ray8 {
    let v = |f: &dyn Fn(usize) -> f32| f32x8::from(std::array::from_fn::<f32, LANES, _>(f));
    Ray8::new(
        Vec3x8::new(v(&|i| o[i].x), v(&|i| o[i].y), v(&|i| o[i].z)),
        Vec3x8::new(v(&|i| d[i].x), v(&|i| d[i].y), v(&|i| d[i].z)),
        f32x8::from(tmax),
    )
}

/// A node over up to `WIDTH` random boxes at scale `s`: some flat on an axis (min = max), some hairline
/// (one ulp wide), some far away, the rest of the slots empty.
fn random_node(rng: &mut Rand, s: f32) -> WideNode {
    let mut n = WideNode::EMPTY;
    for i in 0..1 + rng.below(WIDTH as u32) as usize {
        let c = rng.vec(-10.0, 10.0) * s;
        let mut h = rng.vec(0.0, 3.0) * s;
        match rng.below(6) {
            0 => h[rng.below(3) as usize] = 0.0,
            1 => h = Vec3::splat(0.0),
            _ => {}
        }
        let (mut min, mut max) = (c - h, c + h);
        if rng.chance(0.1) {
            let a = rng.below(3) as usize;
            max[a] = min[a].next_up();
        }
        if rng.chance(0.05) {
            min += Vec3::splat(1e3 * s);
            max += Vec3::splat(1e3 * s);
        }
        if rng.chance(0.03) {
            // Beyond the f32 range in t for rays parallel to an axis (1e30 * 2^60 overflows): entry
            // distances of +inf, which a ray with tmax = inf still enters.
            let a = rng.below(3) as usize;
            min[a] = 1e30;
            max[a] = 2e30;
        }
        for a in 0..3 {
            n.bounds[a][i] = min[a];
            n.bounds[a + 3][i] = max[a];
        }
    }
    n
}

#[test]
fn single_ray_slab_matches_packet_slab() {
    let mut rng = Rand::new(84);
    let mut hits = 0usize;
    for k in 0..20_000 {
        let s = [1.0, 1e4, 1e-4][k % 3];
        let node = random_node(&mut rng, s);
        // Origins inside, on and beside the boxes; on a box plane sometimes (grazing parallel rays).
        let o: [Vec3; LANES] = std::array::from_fn(|_| {
            let mut o = rng.vec(-14.0, 14.0) * s;
            if rng.chance(0.3) {
                let i = rng.below(node.child_count() as u32) as usize;
                let a = rng.below(3) as usize;
                let plane = node.bounds[a + 3 * rng.below(2) as usize][i];
                // (Origins stay within the packet test's domain, |o| < 2^68.)
                if plane.abs() < 1e20 {
                    o[a] = plane;
                }
            }
            o
        });
        // Half the rays aim at a point of a random child box (with zero components kept from `dir`).
        let d: [Vec3; LANES] = std::array::from_fn(|l| {
            let d = rng.dir_with_zeros();
            if rng.chance(0.5) {
                let b = node.child_aabb(rng.below(node.child_count() as u32) as usize);
                let t = Vec3::new(rng.f(), rng.f(), rng.f());
                let aim = b.min + (b.max - b.min) * t - o[l];
                Vec3::select(d.cmpeq(Vec3::ZERO), d, aim)
            } else {
                d
            }
        });
        let tmax: [f32; LANES] = std::array::from_fn(|_| match rng.below(6) {
            0 => -1.0,
            1 => 0.0,
            2 | 3 => f32::INFINITY,
            _ => rng.range(0.0, 30.0) * s,
        });
        let ray = packet(o, d, tmax);
        let pr = PacketRay::new(&ray);
        for l in 0..LANES {
            let (tn, bits) = intersect_children_single(&node, &ray, l);
            for i in 0..WIDTH {
                let b = node.child_aabb(i);
                let single = bits & (1 << i) != 0;
                if b.is_empty() {
                    assert!(!single, "an empty slot was entered");
                    continue;
                }
                let (ptn, pm) = intersect_aabb_x8(b.min, b.max, &pr, ray.tmax);
                let packet = pm.to_bitmask() & (1 << l) != 0;
                assert_eq!(single, packet, "box {b:?}, ray o {:?} d {:?} tmax {}", o[l], d[l], tmax[l]);
                if single {
                    assert_eq!(tn.to_array()[i].to_bits(), ptn.to_array()[l].to_bits());
                    hits += 1;
                }
            }
        }
    }
    assert!(hits > 30_000, "{hits} hits");
    println!("{hits} (lane, box) hits agree");
}

// ---------------------------------------------------------------- traversal against brute force

/// Test primitives: spheres (bounded by their widened boxes) and axis-aligned boxes (their own bounds;
/// a box is hit at `max(0, entry)`, so rays from inside hit at 0 and tie).
#[derive(Clone, Copy, Debug)]
enum Prim {
    Sphere(Vec3, f32),
    Box(Aabb),
}

impl Prim {
    fn bounds(&self) -> Aabb {
        match *self {
            Prim::Sphere(c, r) => Aabb::new(c - r, c + r).widened_ulps(),
            Prim::Box(b) => b,
        }
    }

    /// Nearest hit distance `>= 0` (any distance: the caller applies `tmax`).
    fn hit(&self, o: DVec3, d: DVec3) -> Option<f64> {
        match *self {
            Prim::Sphere(c, r) => {
                let (oc, r) = (o - c.as_dvec3(), r as f64);
                let (a, b, c) = (d.dot(d), oc.dot(d), oc.dot(oc) - r * r);
                let disc = b * b - a * c;
                if a == 0.0 || disc < 0.0 {
                    return None;
                }
                let q = -(b + disc.sqrt().copysign(b));
                let (t0, t1) = (q / a, c / q);
                let (t0, t1) = (t0.min(t1), t0.max(t1));
                let t = if t0 >= 0.0 { t0 } else { t1 };
                (t >= 0.0).then_some(t)
            }
            Prim::Box(b) => intersect_aabb_f64(b.min, b.max, o, d, f64::INFINITY),
        }
    }
}

/// A random scene at scale `s`: spheres and boxes, some duplicated (exact ties).
fn random_prims(rng: &mut Rand, n: usize, s: f32) -> Vec<Prim> {
    let mut p: Vec<Prim> = (0..n)
        .map(|_| {
            if rng.chance(0.6) {
                Prim::Sphere(rng.vec(-10.0, 10.0) * s, rng.range(0.05, 1.0) * s)
            } else {
                let c = rng.vec(-10.0, 10.0) * s;
                let h = rng.vec(0.0, 1.0) * s;
                Prim::Box(Aabb::new(c - h, c + h))
            }
        })
        .collect();
    for _ in 0..n / 20 {
        let q = p[rng.below(n as u32) as usize];
        p.push(q);
    }
    p
}

/// Incoherent rays at scale `s`: from random points (often inside boxes and spheres), from sphere and
/// box surfaces, and grazing rays tangent to a sphere or along a box face; zero direction components
/// (`Rand::dir`). tmax: infinite, finite, 0 or -1 (inactive).
fn random_rays(rng: &mut Rand, prims: &[Prim], n: usize, s: f32) -> Vec<(Vec3, Vec3, f32)> {
    (0..n)
        .map(|_| {
            let mut d = rng.dir_with_zeros();
            let p = prims[rng.below(prims.len() as u32) as usize];
            let o = match (rng.below(4), p) {
                (0, Prim::Sphere(c, r)) => {
                    // Tangent: o + d t touches the sphere at c + r u, u perpendicular to d.
                    let u = d.any_orthonormal_vector();
                    c + u * r - d * rng.range(0.5, 5.0) * s
                }
                (0, Prim::Box(b)) => {
                    // In the plane of a face, moving parallel to it.
                    let a = rng.below(3) as usize;
                    let mut o = rng.vec(-12.0, 12.0) * s;
                    o[a] = if rng.chance(0.5) { b.min[a] } else { b.max[a] };
                    d[a] = 0.0;
                    if d == Vec3::ZERO {
                        d[(a + 1) % 3] = 1.0;
                    }
                    o
                }
                (1, Prim::Sphere(c, r)) => c + rng.dir_with_zeros().normalize_or(Vec3::X) * r,
                (1, Prim::Box(b)) => b.centroid(),
                _ => rng.vec(-12.0, 12.0) * s,
            };
            let tmax = match rng.below(8) {
                0 => -1.0,
                1 => 0.0,
                2..=4 => f32::INFINITY,
                _ => rng.range(0.0, 20.0) * s,
            };
            (o, d, tmax)
        })
        .collect()
}

/// The smallest f32 >= `t`.
fn up(t: f64) -> f32 {
    let f = t as f32;
    if (f as f64) < t {
        f.next_up()
    } else {
        f
    }
}

/// Closest hit in `[0, tmax)`, equal distances to the lower id.
fn brute_closest(prims: &[Prim], o: Vec3, d: Vec3, tmax: f32) -> Option<(f64, u32)> {
    let (o, d, tmax) = (o.as_dvec3(), d.as_dvec3(), tmax as f64);
    let mut best: Option<(f64, u32)> = None;
    for (i, p) in prims.iter().enumerate() {
        if let Some(t) = p.hit(o, d).filter(|&t| t < tmax) {
            if best.is_none_or(|b| t < b.0) {
                best = Some((t, i as u32));
            }
        }
    }
    best
}

/// Record a leaf hit with the tie rule; returns the new f32 `tmax` for traversal (rounded up, so that a
/// box reaching exactly the best distance is still entered).
fn record(best: &mut Option<(f64, u32)>, p: u32, t: f64) -> Option<f32> {
    let better = best.is_none_or(|b| t < b.0 || (t == b.0 && p < b.1));
    better.then(|| {
        *best = Some((t, p));
        up(t)
    })
}

fn scenes() -> Vec<(f32, Vec<Prim>, WideBvh)> {
    let mut rng = Rand::new(85);
    [(1.0f32, 400usize), (1e4, 300), (1e-4, 300), (1.0, 3)]
        .into_iter()
        .map(|(s, n)| {
            let prims = random_prims(&mut rng, n, s);
            let bounds: Vec<Aabb> = prims.iter().map(Prim::bounds).collect();
            let (_, w) = collapse_ok(&bounds, &BuildOptions::default());
            (s, prims, w)
        })
        .collect()
}

#[test]
fn single_ray_closest_and_any_hit_match_brute_force() {
    let mut rng = Rand::new(86);
    let mut st = WideStack::default();
    let (mut hit_count, mut occluded_count) = (0, 0);
    for (s, prims, w) in scenes() {
        for (o, d, tmax) in random_rays(&mut rng, &prims, 2500, s) {
            let (od, dd, tm64) = (o.as_dvec3(), d.as_dvec3(), tmax as f64);
            let mut best = None;
            w.traverse_closest_single(o, d, tmax, &mut st, |slot, tm| {
                let p = w.indices[slot as usize];
                if let Some(t) = prims[p as usize].hit(od, dd).filter(|&t| t < tm64) {
                    if let Some(nt) = record(&mut best, p, t) {
                        *tm = nt;
                    }
                }
            });
            let want = brute_closest(&prims, o, d, tmax);
            assert_eq!(best, want, "closest: scale {s}, o {o:?} d {d:?} tmax {tmax}");
            hit_count += want.is_some() as usize;
            let occluded = w.traverse_any_single(o, d, tmax, &mut st, |p, _| prims[p as usize].hit(od, dd).is_some_and(|t| t < tm64));
            let want = tmax > 0.0 && prims.iter().any(|p| p.hit(od, dd).is_some_and(|t| t < tm64));
            assert_eq!(occluded, want, "any-hit: scale {s}, o {o:?} d {d:?} tmax {tmax}");
            occluded_count += want as usize;
        }
    }
    assert!(hit_count > 3000 && occluded_count > 3000, "{hit_count} hits, {occluded_count} occluded");
}

#[test]
fn packet_closest_hit_matches_brute_force() {
    let mut rng = Rand::new(87);
    let mut st = WideStack::default();
    for (s, prims, w) in scenes() {
        let rays = random_rays(&mut rng, &prims, 4000, s);
        for chunk in rays.chunks(LANES) {
            let mut o = [Vec3::ZERO; LANES];
            let mut d = [Vec3::X; LANES];
            let mut tmax = [-1.0f32; LANES];
            for (l, &(ro, rd, rt)) in chunk.iter().enumerate() {
                (o[l], d[l], tmax[l]) = (ro, rd, rt);
            }
            let mut ray = packet(o, d, tmax);
            let mut best = [None; LANES];
            w.traverse_closest_x8(&mut ray, &mut st, |slot, r| {
                let p = w.indices[slot as usize];
                let mut tm = r.tmax.to_array();
                for l in 0..LANES {
                    if let Some(t) = prims[p as usize].hit(o[l].as_dvec3(), d[l].as_dvec3()).filter(|&t| t < tmax[l] as f64) {
                        if let Some(nt) = record(&mut best[l], p, t) {
                            tm[l] = nt;
                        }
                    }
                }
                r.tmax = f32x8::from(tm);
            });
            for l in 0..LANES {
                let want = if tmax[l] < 0.0 { None } else { brute_closest(&prims, o[l], d[l], tmax[l]) };
                assert_eq!(best[l], want, "scale {s}, o {:?} d {:?} tmax {}", o[l], d[l], tmax[l]);
            }
        }
    }
}

/// Groups of up to `WIDE_GROUP` packets of camera-like rays (one eye, or an eye spread like a lens,
/// aimed around a random primitive), full and partial groups, inactive and zero-length lanes, groups
/// whose lanes all have a finite `tmax`, and groups
/// with an exactly zero direction component (no shared octant: the per-packet fallback), through
/// `WideBvh::traverse_closest_group` against brute force (t and id, equal distances to the lower id).
#[test]
fn group_closest_hit_matches_brute_force() {
    let mut rng = Rand::new(90);
    let mut st = WideStack::default();
    let (mut hits, mut full, mut fallback) = (0usize, 0usize, 0usize);
    for (s, prims, w) in scenes() {
        for g in 0..60 {
            let k = [WIDE_GROUP, WIDE_GROUP, 1, 7, 19, 32][g % 6];
            full += (k == WIDE_GROUP) as usize;
            let eye = rng.vec(-15.0, 15.0) * s;
            let spread = [0.0, 0.0, 0.05, 1.0][g % 4] * s;
            let aim = prims[rng.below(prims.len() as u32) as usize].bounds().centroid();
            let zero_axis = (g % 10 == 9).then(|| rng.below(3) as usize);
            fallback += zero_axis.is_some() as usize;
            let mut o = vec![[Vec3::ZERO; LANES]; k];
            let mut d = vec![[Vec3::X; LANES]; k];
            let mut tmax = vec![[-1.0f32; LANES]; k];
            for j in 0..k {
                for l in 0..LANES {
                    o[j][l] = eye + rng.vec(-1.0, 1.0) * spread;
                    let mut dir = (aim + rng.vec(-3.0, 3.0) * s - eye).normalize_or(Vec3::X);
                    if let Some(a) = zero_axis.filter(|_| l % 2 == 0) {
                        dir[a] = 0.0;
                    }
                    d[j][l] = dir;
                    // Every third group all finite (its largest tmax then drives the pop-time cull).
                    tmax[j][l] = match (g % 3, rng.below(10)) {
                        (2, _) => rng.range(1.0, 30.0) * s,
                        (_, 0) => -1.0,
                        (_, 1) => 0.0,
                        (_, 2) => rng.range(0.0, 20.0) * s,
                        _ => f32::INFINITY,
                    };
                }
            }
            let mut rays: Vec<Ray8> = (0..k).map(|j| packet(o[j], d[j], tmax[j])).collect();
            let mut best = vec![[None; LANES]; k];
            w.traverse_closest_group(&mut rays, &mut st, |slot, j, r| {
                let p = w.indices[slot as usize];
                let mut tm = r.tmax.to_array();
                for l in 0..LANES {
                    if let Some(t) = prims[p as usize].hit(o[j][l].as_dvec3(), d[j][l].as_dvec3()).filter(|&t| t < tmax[j][l] as f64) {
                        if let Some(nt) = record(&mut best[j][l], p, t) {
                            tm[l] = nt;
                        }
                    }
                }
                r.tmax = f32x8::from(tm);
            });
            for j in 0..k {
                for l in 0..LANES {
                    let want = if tmax[j][l] < 0.0 { None } else { brute_closest(&prims, o[j][l], d[j][l], tmax[j][l]) };
                    assert_eq!(best[j][l], want, "scale {s}, group {g} (k {k}), packet {j} lane {l}: o {:?} d {:?}", o[j][l], d[j][l]);
                    hits += want.is_some() as usize;
                }
            }
        }
    }
    assert!(full >= 80 && fallback >= 20 && hits > 8_000, "{full} full groups, {fallback} fallback groups, {hits} hits");
}

// ---------------------------------------------------------------- the intersect stage

/// A scene of `n` random shapes at scale `s` (spheres, some duplicated; rotated boxes; quads; disks;
/// a plane; with `csg`, intersections of a box and a sphere), moving over the shutter with `motion`.
fn stage_scene(rng: &mut Rand, n: usize, s: f32, motion: bool, csg: bool) -> Scene {
    let v = |v: Vec3| format!("[{:e}, {:e}, {:e}]", v.x, v.y, v.z);
    let mut t = format!(
        "[image]\nwidth = 8\nheight = 8\n[camera]\nposition = {}\nlook_at = [0.0, 0.0, 0.0]\nfov = 40.0\n{}\
         [materials.m]\ntype = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\n\
         [[lights]]\ntype = \"point\"\nposition = {}\nintensity = [1.0, 1.0, 1.0]\n\
         [[shapes]]\ntype = \"plane\"\npoint = {}\nnormal = [0.0, 1.0, 0.0]\nmaterial = \"m\"\n",
        v(Vec3::new(0.0, 5.0, 30.0) * s),
        if motion { "shutter = [0.0, 1.0]\n" } else { "" },
        v(Vec3::splat(20.0) * s),
        v(Vec3::new(0.0, -11.0, 0.0) * s),
    );
    let mut spheres = Vec::new();
    for k in 0..n {
        let c = rng.vec(-10.0, 10.0) * s;
        let mv = if motion && rng.chance(0.5) { format!("motion = {}\n", v(rng.vec(-1.0, 1.0) * s)) } else { String::new() };
        let shape = match k % 6 {
            0 | 1 => {
                let r = rng.range(0.1, 1.2) * s;
                spheres.push((c, r));
                format!("type = \"sphere\"\ncenter = {}\nradius = {r:e}\n", v(c))
            }
            2 => {
                let h = rng.vec(0.05, 1.0) * s;
                let rot = rng.vec(0.0, 90.0);
                format!("type = \"box\"\nmin = {}\nmax = {}\ntransform = {{ rotate = {} }}\n", v(c - h), v(c + h), v(rot))
            }
            3 => format!("type = \"quad\"\norigin = {}\nu = {}\nv = {}\n", v(c), v(rng.vec(-2.0, 2.0) * s), v(rng.vec(-2.0, 2.0) * s)),
            4 => format!(
                "type = \"disk\"\ncenter = {}\nnormal = {}\nradius = {:e}\n",
                v(c),
                v(rng.dir_with_zeros().normalize()),
                rng.range(0.2, 1.5) * s
            ),
            _ if csg => {
                let h = rng.range(0.3, 1.0) * s;
                format!(
                    "type = \"csg\"\nop = \"intersection\"\nchildren = [\n {{ type = \"box\", min = {}, max = {} }},\n \
                     {{ type = \"sphere\", center = {}, radius = {:e} }},\n]\n",
                    v(c - Vec3::splat(h)),
                    v(c + Vec3::splat(h)),
                    v(c),
                    1.3 * h
                )
            }
            _ => {
                let r = rng.range(0.1, 1.2) * s;
                format!("type = \"sphere\"\ncenter = {}\nradius = {r:e}\n", v(c))
            }
        };
        t += &format!("[[shapes]]\n{shape}{mv}material = \"m\"\n");
    }
    // Exact duplicates: equal distances, decided by the lower id.
    for &(c, r) in spheres.iter().take(n / 10) {
        t += &format!("[[shapes]]\ntype = \"sphere\"\ncenter = {}\nradius = {r:e}\nmaterial = \"m\"\n", v(c));
    }
    parse_scene(Path::new("wide_stage.toml"), &t).unwrap_or_else(|e| panic!("{e}\n{t}"))
}

/// An incoherent queue (random origins and directions, grazing and axis-parallel rays, rays from
/// sphere surfaces), or with `coherent` camera-like rays (one eye or a lens-spread one, nearby
/// directions, inactive lanes).
fn stage_queue(rng: &mut Rand, scene: &Scene, n: usize, s: f32, coherent: bool) -> RayQueue {
    let mut q = RayQueue::new(scene.features.motion, false);
    let eye = Vec3::new(0.0, 5.0, 30.0) * s;
    for i in 0..n {
        let (o, d) = if coherent {
            // A pinhole's eye, or (every third ray) an eye spread like a lens; some 64-ray blocks with an
            // exactly zero x direction (no shared octant: those groups fall back to single packets).
            let o = if i % 3 == 1 { eye + rng.vec(-0.5, 0.5) * s } else { eye };
            let mut d = (Vec3::new(i as f32 / n as f32 - 0.5, -0.3, -1.0) + rng.vec(-0.01, 0.01)).normalize();
            if (i / 64) % 7 == 3 {
                d.x = 0.0;
            }
            (o, d)
        } else if rng.chance(0.3) {
            // From the surface of a random sphere (a secondary ray), sometimes into it.
            let p = &scene.prims[rng.below(scene.prims.len() as u32) as usize];
            let o = match p.shape {
                strata::scene::Shape::Sphere { center, radius } => center + rng.dir_with_zeros().normalize_or(Vec3::Y) * radius,
                _ => rng.vec(-12.0, 12.0) * s,
            };
            (o, rng.dir_with_zeros())
        } else {
            (rng.vec(-12.0, 12.0) * s, rng.dir_with_zeros())
        };
        let tmax = match rng.below(8) {
            0 => 0.0,
            1..=5 => f32::INFINITY,
            6 if coherent && rng.chance(0.3) => -1.0,
            _ => rng.range(0.0, 25.0) * s,
        };
        q.push(&RayItem { o, d, tmax, time: rng.f(), path: i as u32, ..RayItem::default() });
    }
    q.pad();
    q
}

/// Hits (t bits, prim, leaf, flip) of the intersect stage, and after csg_merge, with `traversal` for
/// incoherent queues. (CSG candidates may differ: which ones are recorded depends on the `tmax` a ray
/// has when it reaches a solid, hence on the visiting order; csg_merge's result does not.)
type Hits = Vec<(u32, u32, u32, bool)>;
fn stage_hits(scene: &Scene, q: &RayQueue, traversal: Traversal, incoherent: bool) -> (Hits, Hits) {
    let (mut hits, mut cands, mut arena) = (HitQueue::default(), CsgCandidates::default(), CsgArena::new());
    intersect_with(scene, q, &mut hits, &mut cands, traversal);
    // The stage fills its octant order only for queues it treats as incoherent (those that take `traversal`).
    assert_eq!(hits.order.len() == q.len(), incoherent, "queue coherence misjudged");
    let list = |h: &HitQueue| (0..q.len()).map(|i| (h.t[i].to_bits(), h.prim[i], h.leaf[i], h.flip[i])).collect();
    let before = list(&hits);
    csg_merge(scene, q, &mut cands, &mut hits, &mut arena);
    (before, list(&hits))
}

#[test]
fn intersect_stage_is_identical_with_the_wide_bvh() {
    let mut rng = Rand::new(88);
    let mut hit = 0usize;
    for (s, motion, csg) in [(1.0f32, false, false), (1.0, true, false), (1.0, false, true), (1e4, false, false), (1e-4, true, true)] {
        let mut scene = stage_scene(&mut rng, 240, s, motion, csg);
        // Incoherent rays take the wide tree whatever its size (the scene decides by `WIDE_MIN_NODES`).
        scene.wide_incoherent = true;
        // Incoherent queues: groups or wide packets by `Traversal`. Coherent queues (judged so: no
        // octant order) take groups through the wide tree when the scene has one, else through the
        // binary tree.
        for coherent in [false, true] {
            // (3001: the coherent queue ends in a padded packet and a partial group.)
            let q = stage_queue(&mut rng, &scene, if coherent { 3001 } else { 3000 }, s, coherent);
            let (groups, wide) = if coherent {
                let wide = stage_hits(&scene, &q, Traversal::Wide, false);
                let wide_bvh = std::mem::take(&mut scene.wide_bvh);
                let binary = stage_hits(&scene, &q, Traversal::Wide, false);
                scene.wide_bvh = wide_bvh;
                (binary, wide)
            } else {
                (stage_hits(&scene, &q, Traversal::Groups, true), stage_hits(&scene, &q, Traversal::Wide, true))
            };
            for (stage, g, w) in [("intersect", &groups.0, &wide.0), ("csg_merge", &groups.1, &wide.1)] {
                for (i, (g, w)) in g.iter().zip(w).enumerate() {
                    let r = q.get(i);
                    assert_eq!(
                        g, w,
                        "after {stage}, scale {s}, motion {motion}, csg {csg}, coherent {coherent}: ray {i} o {:?} d {:?}",
                        r.o, r.d
                    );
                }
            }
            hit += groups.1.iter().filter(|h| h.1 != u32::MAX).count();
        }
    }
    assert!(hit > 10_000, "{hit} hits");
}

#[test]
fn entry_distances_beyond_the_f32_range_are_entered() {
    // A box at x = 1e30 met by rays along +x with d.x = 1e-9: entry at t = 1e39, +inf in f32, where the
    // packet test still enters it (inf <= inf with tmax = inf). The wide traversals must too. (The box
    // spans +-1e30 on the axes the rays are parallel to: a parallel axis's padded slab ends at about
    // its distance times 2^60, `INV_D_CLAMP`, which must overflow too.)
    let mut rng = Rand::new(89);
    let mut prims = random_prims(&mut rng, 60, 1.0);
    prims.push(Prim::Box(Aabb::new(Vec3::new(1e30, -1e30, -1e30), Vec3::new(2e30, 1e30, 1e30))));
    let far = prims.len() as u32 - 1;
    let bounds: Vec<Aabb> = prims.iter().map(Prim::bounds).collect();
    let (_, w) = collapse_ok(&bounds, &BuildOptions::default());
    let mut st = WideStack::default();
    let rays: Vec<(Vec3, Vec3)> = (0..8).map(|k| (Vec3::new(-15.0, 15.5 - k as f32, 15.5), Vec3::new(1e-9, 0.0, -0.0))).collect();
    let mut packet_best = [None; LANES];
    let mut ray = packet(std::array::from_fn(|l| rays[l].0), std::array::from_fn(|l| rays[l].1), [f32::INFINITY; LANES]);
    w.traverse_closest_x8(&mut ray, &mut st, |slot, r| {
        let p = w.indices[slot as usize];
        let mut tm = r.tmax.to_array();
        for (l, &(o, d)) in rays.iter().enumerate() {
            if let Some(t) = prims[p as usize].hit(o.as_dvec3(), d.as_dvec3()) {
                if let Some(nt) = record(&mut packet_best[l], p, t) {
                    tm[l] = nt;
                }
            }
        }
        r.tmax = f32x8::from(tm);
    });
    for (l, &(o, d)) in rays.iter().enumerate() {
        let want = brute_closest(&prims, o, d, f32::INFINITY);
        assert_eq!(want.map(|h| h.1), Some(far), "lane {l}: the far box is the only hit");
        let mut best = None;
        w.traverse_closest_single(o, d, f32::INFINITY, &mut st, |slot, tm| {
            let p = w.indices[slot as usize];
            if let Some(nt) = prims[p as usize].hit(o.as_dvec3(), d.as_dvec3()).and_then(|t| record(&mut best, p, t)) {
                *tm = nt;
            }
        });
        assert_eq!(best, want, "single ray {l}");
        assert_eq!(packet_best[l], want, "packet lane {l}");
    }
}

// ---------------------------------------------------------------- the shade stage's 8-lane geometry

/// Lambert hits are shaded 8 at a time (`lambert_x8`: sphere and flat (plane, quad, disk) geometry in 8 lanes, other shapes
/// one by one, in one chunk): every next-event request's shading point, facing normal and shadow-ray
/// origin must equal, bit for bit, what the scalar `surface_hit` gives for that hit. Mixed shapes (planes,
/// spheres, rotated boxes, quads, disks, CSG solids), back faces (rays from inside spheres), origins
/// far from the hits (scales 1e-4 to 1e4), moving spheres.
#[test]
fn lambert_geometry_in_8_lanes_equals_surface_hit() {
    use strata::scene::Profile;
    use strata::wavefront::shade::{shade, surface_hit, ShadeOut};
    use strata::wavefront::{NeeQueue, PathTable};
    let mut rng = Rand::new(91);
    let (mut checked, mut back, mut planes, mut quads_disks, mut spheres) = (0usize, 0usize, 0usize, 0usize, 0usize);
    for (s, motion, csg) in [(1.0f32, false, true), (1e4, false, false), (1e-4, true, true), (1.0, true, false)] {
        let scene = stage_scene(&mut rng, 200, s, motion, csg);
        let profile = Profile::builtin("bench");
        for coherent in [false, true] {
            let q = stage_queue(&mut rng, &scene, 2003, s, coherent);
            let (mut hits, mut cands, mut arena) = (HitQueue::default(), CsgCandidates::default(), CsgArena::new());
            intersect_with(&scene, &q, &mut hits, &mut cands, Traversal::Wide);
            csg_merge(&scene, &q, &mut cands, &mut hits, &mut arena);
            let (mut paths, mut next, mut nee, mut order) =
                (PathTable::default(), RayQueue::new(q.with_time, false), NeeQueue::default(), Vec::new());
            paths.push_pixel(0, 0..q.len() as u32);
            shade(&scene, &profile, 1, &q, &hits, &mut order, ShadeOut { paths: &mut paths, next: &mut next, nee: &mut nee });
            // Every material is Lambert: one request per hit, in queue order.
            let hit_rays: Vec<usize> = (0..q.len()).filter(|&i| hits.prim[i] != u32::MAX).collect();
            assert_eq!(nee.px.len(), hit_rays.len());
            for (k, &i) in hit_rays.iter().enumerate() {
                let r = q.get(i);
                let h = surface_hit(&scene, &r, hits.t[i], hits.prim[i], hits.leaf[i], hits.flip[i]);
                let o = h.spawn(h.n_facing);
                let got = [nee.px[k], nee.py[k], nee.pz[k], nee.nx[k], nee.ny[k], nee.nz[k], nee.ox[k], nee.oy[k], nee.oz[k]];
                let want = [h.p.x, h.p.y, h.p.z, h.n_facing.x, h.n_facing.y, h.n_facing.z, o.x, o.y, o.z];
                assert_eq!(got.map(f32::to_bits), want.map(f32::to_bits), "scale {s}, ray {i}: {r:?}");
                checked += 1;
                back += !h.front as usize;
                match scene.prims[hits.prim[i] as usize].shape {
                    strata::scene::Shape::Plane(_) => planes += 1,
                    strata::scene::Shape::Quad(_) | strata::scene::Shape::Disk(_) => quads_disks += 1,
                    strata::scene::Shape::Sphere { .. } => spheres += 1,
                    _ => {}
                }
            }
        }
    }
    assert!(
        checked > 5000 && back > 200 && planes > 500 && quads_disks > 300 && spheres > 1000,
        "{checked} hits ({back} back faces, {planes} planes, {quads_disks} quads and disks, {spheres} spheres)"
    );
}
