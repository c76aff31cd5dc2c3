//! Stage 2: nearest hits of a ray queue: the unbounded planes first, then the BVH with the SIMD
//! primitive kernels at the leaves. Coherent queues (camera rays, and any queue with at most one
//! direction-octant change per 64 rays) traverse the wide BVH in groups of up to 32 8-ray packets
//! (`accel/wide_group.rs`; the binary tree's groups of 16, `accel/group.rs`, only for a scene without a
//! wide tree, i.e. without bounded primitives). Queues of incoherent rays are first partitioned by
//! direction (octant, then, in queues of many rays per pixel, a patch of directions within it) and
//! gathered into packets, which traverse the wide BVH one packet at a time (`accel/wide_traverse.rs`) when `scene.wide_incoherent` (trees of at least `WIDE_MIN_NODES` binary
//! nodes), else the binary tree in groups of 16 packets. CSG solids are not solved here: a packet that
//! reaches a solid's bounds records (ray, solid) candidates for `csg_merge`.

use super::queues::{CsgCandidates, HitQueue, RayQueue, NONE};
use crate::accel::{intersect_aabb_x8, PacketRay, GROUP, WIDE_GROUP};
use crate::csg::CsgArena;
use crate::geometry::{
    intersect_disk_f64, intersect_disk_x8, intersect_ellipsoid_f64, intersect_ellipsoid_x8, intersect_obox_f64, intersect_obox_x8,
    intersect_plane_f64, intersect_plane_x8, intersect_quad_f64, intersect_quad_x8, intersect_sphere_f64, intersect_sphere_x8,
    spheres_lanes_x8, MISS,
};
use crate::scene::{Prim, Scene, Shape};
use crate::simd::{f32x8, i32x8, load8, store8, Ray8, Vec3x8, LANES};
use glam::{DVec3, Vec3};

/// Distance to a (non-CSG) primitive for 8 rays; MISS where there is none.
#[inline(always)]
pub fn prim_t_x8(prim: &Prim, ray: &Ray8) -> f32x8 {
    match &prim.shape {
        Shape::Sphere { center, radius } => intersect_sphere_x8(*center, *radius, ray),
        Shape::Ellipsoid(e) => intersect_ellipsoid_x8(e, ray),
        Shape::Plane(p) => intersect_plane_x8(p, ray),
        Shape::Quad(q) => intersect_quad_x8(q, ray),
        Shape::Disk(d) => intersect_disk_x8(d, ray),
        Shape::Box(b) => intersect_obox_x8(b, ray),
        Shape::Csg { .. } => f32x8::splat(MISS),
    }
}

/// Scalar f64 twin of [`prim_t_x8`] (the reference path of tests and benchmark validation).
pub fn prim_t_f64(prim: &Prim, o: DVec3, d: DVec3, tmax: f64) -> f64 {
    match &prim.shape {
        Shape::Sphere { center, radius } => intersect_sphere_f64(center.as_dvec3(), *radius as f64, o, d, tmax),
        Shape::Ellipsoid(e) => intersect_ellipsoid_f64(e.world_to_object_f64(), o, d, tmax),
        Shape::Plane(p) => intersect_plane_f64(p.normal.as_dvec3(), p.offset as f64, o, d, tmax),
        Shape::Quad(q) => intersect_quad_f64(q.origin.as_dvec3(), q.u.as_dvec3(), q.v.as_dvec3(), o, d, tmax),
        Shape::Disk(k) => intersect_disk_f64(k.center.as_dvec3(), k.normal.as_dvec3(), k.radius as f64, o, d, tmax),
        Shape::Box(b) => intersect_obox_f64(b.world_to_object_f64(), b.half.as_dvec3(), o, d, tmax),
        Shape::Csg { .. } => f64::INFINITY,
    }
}

/// The packet in the frame of a moving primitive: origin moved by -motion * time (translation motion).
#[inline(always)]
pub fn in_prim_frame(ray: &Ray8, motion: Vec3, time: Option<f32x8>) -> Ray8 {
    match time {
        Some(t) if motion != Vec3::ZERO => Ray8 { o: Vec3x8::splat(-motion).mul_add(t, ray.o), ..*ray },
        _ => *ray,
    }
}

/// [`prim_t_x8`] at the packet's shutter times: only moving prims pay for a packet in their own frame
/// (static prims test the packet in place, no copy).
#[inline(always)]
pub fn prim_t_at_x8(prim: &Prim, ray: &Ray8, time: Option<f32x8>) -> f32x8 {
    match time {
        Some(_) if prim.motion != Vec3::ZERO => prim_t_x8(prim, &in_prim_frame(ray, prim.motion, time)),
        _ => prim_t_x8(prim, ray),
    }
}

/// Distance to `prim` for the packet, reporting hits at *exactly* the current best distance too (on
/// lanes that have one): kernels accept `t < tmax`, so `tmax` is raised by one ulp for the call. With
/// [`record`]'s tie rule, equal distances then go to the lower primitive id whatever the order in which
/// primitives are met (traversal order depends on the packet's other rays, hence on tiles and queues).
#[inline(always)]
fn prim_t_ties(prim: &Prim, ray: &mut Ray8, ids: &i32x8, time: Option<f32x8>) -> f32x8 {
    t_ties(ray, ids, |r| prim_t_at_x8(prim, r, time))
}

/// `kernel(ray)` with `tmax` raised by one ulp on the lanes that have a hit ([`prim_t_ties`]).
#[inline(always)]
fn t_ties(ray: &mut Ray8, ids: &i32x8, kernel: impl FnOnce(&Ray8) -> f32x8) -> f32x8 {
    let tm = ray.tmax;
    let found = !bytemuck::cast::<i32x8, f32x8>(ids.simd_eq(i32x8::splat(NONE as i32)));
    let finite = tm.simd_lt(f32x8::splat(f32::INFINITY)) & tm.simd_gt(f32x8::ZERO);
    let up = bytemuck::cast::<i32x8, f32x8>(bytemuck::cast::<f32x8, i32x8>(tm) + i32x8::splat(1));
    ray.tmax = (found & finite).select(up, tm);
    let t = kernel(ray);
    ray.tmax = tm;
    t
}

/// Record hits of `t` on the lanes where it is nearer than the current best. Equal distances go to the
/// lower primitive id (the kernels report them through [`prim_t_ties`]), so the result does not depend
/// on traversal order (packet composition).
#[inline(always)]
fn record(ray: &mut Ray8, ids: &mut i32x8, t: f32x8, prim: u32) {
    let closer = t.simd_lt(ray.tmax);
    let tie = t.simd_eq(ray.tmax) & t.simd_ne(f32x8::splat(MISS));
    if tie.any() {
        // Rare: exact ties are settled lane by lane (ids compare as unsigned, NONE = u32::MAX last).
        let (mut ia, tie) = (ids.to_array(), tie.to_bitmask());
        for (l, id) in ia.iter_mut().enumerate() {
            if tie & (1 << l) != 0 && prim < *id as u32 {
                *id = prim as i32;
            }
        }
        *ids = i32x8::from(ia);
    }
    if closer.any() {
        ray.tmax = closer.select(t, ray.tmax);
        *ids = bytemuck::cast::<f32x8, i32x8>(closer).select(i32x8::splat(prim as i32), *ids);
    }
}

/// An 8-lane packet that carries no ray (every lane `tmax = -1`): fills unused slots of a group.
#[inline(always)]
fn empty_packet() -> Ray8 {
    let z = Vec3x8::splat(Vec3::ZERO);
    Ray8 { o: z, d: Vec3x8::splat(Vec3::ONE), inv_d: Vec3x8::splat(Vec3::ONE), tmax: f32x8::splat(-1.0) }
}

/// Rays of one packet gathered through `order` (queue positions `q..q + 8`; positions past `len`
/// are inactive lanes).
#[inline(always)]
fn gather_packet(rays: &RayQueue, order: &[u32], q: usize, len: usize) -> (Ray8, Option<f32x8>) {
    let mut a = [[0.0f32; LANES]; 8];
    a[3] = [1.0; LANES];
    a[6] = [-1.0; LANES];
    for l in 0..LANES.min(len.saturating_sub(q)) {
        let i = order[q + l] as usize;
        let v = [rays.ox[i], rays.oy[i], rays.oz[i], rays.dx[i], rays.dy[i], rays.dz[i], rays.tmax[i]];
        for (k, x) in v.into_iter().enumerate() {
            a[k][l] = x;
        }
        if rays.with_time {
            a[7][l] = rays.time[i];
        }
    }
    let f = |k: usize| f32x8::from(a[k]);
    (Ray8::new(Vec3x8::new(f(0), f(1), f(2)), Vec3x8::new(f(3), f(4), f(5)), f(6)), rays.with_time.then(|| f(7)))
}

/// Direction cells per axis within an octant ([`direction_bin`]), in queues of at least
/// [`MIN_RAYS_PER_PIXEL`] rays per pixel.
const DIR_BINS: usize = 6;

/// Rays per pixel from which a queue is sorted by direction cells within octants. A pixel's samples
/// leave from nearly one point, so that sorting them by direction keeps a packet's origins together;
/// with a ray or two per pixel, queue (image) order within an octant is what does (the criterion row
/// `intersect/secondary`, one ray per pixel of 64 x 64-pixel queues, ran 15-19% slower with the cells).
const MIN_RAYS_PER_PIXEL: usize = 8;

/// Direction bin of ray `i`: its octant (3 sign bits), then within the octant the cell of `(|dx|, |dz|)
/// / (|dx| + |dy| + |dz|)` on a `cells`-square grid (the octahedral map of the direction; at
/// [`DIR_BINS`] a patch about 15 degrees across). The result only orders rays into packets: any
/// function of the ray would give the same hits.
#[inline(always)]
fn direction_bin(rays: &RayQueue, i: usize, cells: usize) -> usize {
    let octant = octant(rays, i);
    let (dx, dy, dz) = (rays.dx[i], rays.dy[i], rays.dz[i]);
    let (x, z) = (dx.abs(), dz.abs());
    let scale = cells as f32 / (x + dy.abs() + z);
    // (`as` saturates: NaN -> 0; the min keeps the |x| = L1 edge in the last bin.)
    let cell = |c: f32| ((c * scale) as usize).min(cells - 1);
    (octant * cells + cell(x)) * cells + cell(z)
}

/// Direction octant of ray `i` (3 sign bits, x first).
#[inline(always)]
fn octant(rays: &RayQueue, i: usize) -> usize {
    rays.dx[i].is_sign_negative() as usize | (rays.dy[i].is_sign_negative() as usize) << 1 | (rays.dz[i].is_sign_negative() as usize) << 2
}

/// Partition the queue's rays by direction bin ([`direction_bin`]: octant, then, in queues of many rays
/// per pixel, a patch of directions within it; stable: queue order, i.e. image order, within a bin)
/// into `order`, so that packets hold rays of one octant and, where the queue allows, of like
/// directions; `false` (and `order` untouched) when the queue is already coherent (at most one octant
/// change per 64 rays, as camera rays are) and sorting would only cost. `cells_allowed`: whether the
/// queue's packets take the wide tree (where the cells were measured). The cells within octants
/// (session 20) cut the node visits of peer scene (b)'s diffuse bounces at 16 spp by 15% and the leaf
/// visits by 17% against octants alone (the same node tests per ray: a packet's lanes share more of
/// them); the stage 3-5% faster at 16 and 64 spp (with more instructions: fewer stalls).
fn direction_order(rays: &RayQueue, order: &mut Vec<u32>, cells_allowed: bool) -> bool {
    let len = rays.len();
    // Octant changes, counted per packet from sign masks (padding lanes have d = +x, ignored).
    let (mut changes, mut prev) = (0usize, u32::MAX);
    for q in (0..len).step_by(LANES) {
        let live = (1u32 << (len - q).min(LANES)) - 1;
        let m = [&rays.dx, &rays.dy, &rays.dz].map(|v| load8(v, q).to_bitmask() & live);
        let uniform = m.iter().all(|&b| b == 0 || b == live);
        let oct = (m[0] & 1) | (m[1] & 1) << 1 | (m[2] & 1) << 2;
        changes += (!uniform || (prev != u32::MAX && oct != prev)) as usize;
        prev = oct;
    }
    if changes * 64 <= len {
        return false;
    }
    if cells_allowed && rays.pixels > 0 && len >= MIN_RAYS_PER_PIXEL * rays.pixels as usize {
        counting_sort(&mut [0; 8 * DIR_BINS * DIR_BINS + 1], order, len, |i| direction_bin(rays, i, DIR_BINS));
    } else {
        // (Octants alone: 9 counters, and no division per ray.)
        counting_sort(&mut [0; 9], order, len, |i| octant(rays, i));
    }
    true
}

/// Stable counting sort of `0..len` by `key` (below `start.len() - 1`; `start` zeroed) into `order`
/// (resized to `len`). Each key is computed once: kept in `order`'s second half until the scatter.
#[inline(always)]
fn counting_sort(start: &mut [usize], order: &mut Vec<u32>, len: usize, key: impl Fn(usize) -> usize) {
    order.clear();
    order.resize(2 * len, 0);
    let (out, keys) = order.split_at_mut(len);
    for (i, k) in keys.iter_mut().enumerate() {
        let b = key(i);
        *k = b as u32;
        start[b + 1] += 1;
    }
    for b in 1..start.len() {
        start[b] += start[b - 1];
    }
    for (i, &b) in keys.iter().enumerate() {
        out[start[b as usize]] = i as u32;
        start[b as usize] += 1;
    }
    order.truncate(len);
}

/// How [`intersect_with`] traverses a queue of incoherent rays (one that `direction_order` partitions).
/// Coherent queues (camera rays) never do: they take the wide group traversal. Results do not depend on
/// the choice (same `t`
/// bits, same primitive ids: the tie rule makes recording order-independent); `tests/wide_bvh.rs`
/// holds them equal.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Traversal {
    /// Groups of up to `GROUP` (16) octant-sorted packets through the binary BVH (`accel/group.rs`).
    Groups,
    /// Octant-sorted 8-ray packets through the wide BVH (`accel/wide_traverse.rs`), when the scene
    /// says so (`scene.wide_incoherent`: trees of at least `WIDE_MIN_NODES` binary nodes); else
    /// `Groups`.
    Wide,
}

/// Nearest hits of `rays` (see the module doc), incoherent queues by [`INCOHERENT`].
pub fn intersect(scene: &Scene, rays: &RayQueue, hits: &mut HitQueue, cands: &mut CsgCandidates) {
    intersect_with(scene, rays, hits, cands, INCOHERENT);
    // (In CSG scenes after the CSG stage, which may find nearer glass.)
    if !scene.features.csg {
        glass_gives_way(scene, rays, hits, &mut CsgArena::default());
    }
}

/// The traversal of incoherent queues that [`intersect`] uses. Chosen by measurement
/// (`cargo bench --bench stages -- intersect/secondary`, and per scene size, see `WIDE_MIN_NODES`):
/// on the benchmark's secondary rays (1000 spheres) the wide packets intersect 8% more rays per second
/// than groups. One ray at a time through the wide BVH (`WideBvh::traverse_closest_single`, leaves
/// testing the ray splatted over 8 lanes) was measured too and dropped: 7.6 M rays/s against 13.9 for
/// groups and 15.1 for wide packets (one thread, best of 15): octant-sorted secondary rays of one tile
/// are coherent enough that a packet shares most node tests and leaf calls (0.36 leaf calls per ray
/// for packets, 0.84 primitive tests per ray alone), and a lone ray's node loop is bound by latency.
pub const INCOHERENT: Traversal = Traversal::Wide;

/// Test bounded primitive `pid` (a prim id) against the packet and record its hits; a CSG solid
/// instead records a (ray, solid) candidate for each lane whose slab interval reaches its bounds,
/// `ray_of(lane)` naming the ray.
#[inline(always)]
fn hit_bounded(
    scene: &Scene,
    pid: u32,
    ray: &mut Ray8,
    ids: &mut i32x8,
    time: Option<f32x8>,
    cands: &mut CsgCandidates,
    ray_of: impl Fn(usize) -> u32,
) {
    let prim = &scene.prims[pid as usize];
    if let Shape::Csg { .. } = prim.shape {
        let b = &scene.bounds[pid as usize];
        // The swept bounds already cover the motion: test the world-space packet.
        let (_, mask) = intersect_aabb_x8(b.min, b.max, &PacketRay::new(ray), ray.tmax);
        let mut bits = mask.to_bitmask();
        while bits != 0 {
            let l = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            cands.ray.push(ray_of(l));
            cands.prim.push(pid);
        }
        return;
    }
    let t = prim_t_ties(prim, ray, ids, time);
    record(ray, ids, t, pid);
}

/// [`hit_bounded`] for the primitive in slot `slot` of the BVH's leaves, from the slot-ordered
/// [`LeafSpheres`](crate::scene::leaf_spheres::LeafSpheres) rows (read in leaf order, without the
/// dependent loads of `indices`, `bounded` and the `Prim`): a static sphere's terms (the kernel
/// [`spheres_lanes_x8`] with one sphere splatted is [`intersect_sphere_x8`] bit for bit), any other
/// primitive's id for [`hit_bounded`].
#[inline(always)]
fn hit_slot(
    scene: &Scene,
    slot: u32,
    ray: &mut Ray8,
    ids: &mut i32x8,
    time: Option<f32x8>,
    cands: &mut CsgCandidates,
    ray_of: impl Fn(usize) -> u32,
) {
    let (ls, k) = (&scene.leaf_spheres, slot as usize);
    if ls.window[k] & 1 == 0 {
        hit_bounded(scene, ls.prim[k], ray, ids, time, cands, ray_of);
        return;
    }
    let (c, sc) = ls.sphere(k);
    let s = f32x8::splat;
    let t = t_ties(ray, ids, |r| spheres_lanes_x8(Vec3x8::splat(c), s(sc.r2), s(sc.r2_lo), s(sc.graze), r));
    record(ray, ids, t, ls.prim[k]);
}

/// [`intersect`] with the traversal of incoherent queues chosen by the caller (tests and benchmarks
/// compare them).
pub fn intersect_with(scene: &Scene, rays: &RayQueue, hits: &mut HitQueue, cands: &mut CsgCandidates, incoherent: Traversal) {
    let n = rays.padded_len();
    let len = rays.len();
    // Coherent queues store every packet's 8 lanes below; sorted ones scatter their results through
    // `order`, and their padding keeps misses (`HitQueue::fill_misses`).
    debug_assert_eq!(n % LANES, 0, "queues are padded to whole packets");
    hits.reset_for_overwrite(n);
    cands.clear();
    let mut order = std::mem::take(&mut hits.order);
    // Incoherent queues go one packet at a time through the wide tree, else in groups through the binary
    // one (direction cells were measured on the wide packets only: the groups keep octants alone).
    let wide_packets = incoherent == Traversal::Wide && scene.wide_incoherent && !scene.wide_bvh.is_empty();
    let sorted = direction_order(rays, &mut order, wide_packets);
    if sorted {
        hits.fill_misses();
    }
    hits.scattered = sorted;
    if sorted && wide_packets {
        intersect_wide(scene, rays, &order, hits, cands);
        hits.order = order;
        return;
    }
    // Queue position -> ray index.
    let ray_at = |q: usize| if sorted { order[q] as usize } else { q };
    // Packets traverse together: coherent queues up to WIDE_GROUP packets (256 rays) through the wide
    // tree when the scene has one (`accel/wide_group.rs`), else up to GROUP (128 rays) through the
    // binary tree (`accel/group.rs`).
    let wide = !sorted && !scene.wide_bvh.is_empty();
    let group = if wide { WIDE_GROUP } else { GROUP };
    let none = i32x8::splat(NONE as i32);
    let mut times = [None; WIDE_GROUP];
    let mut rs = [empty_packet(); WIDE_GROUP];
    let mut ids = [none; WIDE_GROUP];
    for gbase in (0..n).step_by(LANES * group) {
        let k = ((n - gbase) / LANES).min(group);
        for j in 0..k {
            let q = gbase + j * LANES;
            if sorted {
                (rs[j], times[j]) = gather_packet(rays, &order, q, len);
            } else {
                rs[j].load_into([&rays.ox, &rays.oy, &rays.oz], [&rays.dx, &rays.dy, &rays.dz], &rays.tmax, q);
                if rays.with_time {
                    times[j] = Some(load8(&rays.time, q));
                }
            }
        }
        ids[..k].fill(none);
        // Unbounded planes first: their hits lower tmax, which culls the BVH beyond them.
        for j in 0..k {
            for &pid in &scene.unbounded {
                let prim = &scene.prims[pid as usize];
                // Planes (the usual unbounded prim) by their kernel inline, not through the shape match.
                let t = match &prim.shape {
                    Shape::Plane(p) => t_ties(&mut rs[j], &ids[j], |r| intersect_plane_x8(p, r)),
                    _ => prim_t_ties(prim, &mut rs[j], &ids[j], None),
                };
                record(&mut rs[j], &mut ids[j], t, pid);
            }
        }
        let hit = |slot: u32, j: usize, ray: &mut Ray8| {
            hit_slot(scene, slot, ray, &mut ids[j], times[j], cands, |l| ray_at(gbase + j * LANES + l) as u32);
        };
        if wide {
            scene.wide_bvh.traverse_closest_group(&mut rs[..k], &mut hits.wide_stack, hit);
        } else {
            scene.bvh.traverse_closest_group(&mut rs[..k], hit);
        }
        for j in 0..k {
            let base = gbase + j * LANES;
            let found = ids[j].simd_eq(none);
            // Lanes without a hit keep the reset values (t = inf, NONE).
            let t = bytemuck::cast::<i32x8, f32x8>(found).select(f32x8::splat(f32::INFINITY), rs[j].tmax);
            if sorted {
                let (ta, ia) = (t.to_array(), ids[j].to_array());
                for l in 0..LANES.min(len.saturating_sub(base)) {
                    let i = order[base + l] as usize;
                    (hits.t[i], hits.prim[i]) = (ta[l], ia[l] as u32);
                }
            } else {
                store8(&mut hits.t, base, t);
                hits.prim[base..base + LANES].copy_from_slice(bytemuck::cast_slice(&ids[j].to_array()));
            }
        }
    }
    hits.order = order;
}

/// Where a dielectric surface lies on an opaque one (a glass resting on a floor plane or a table top, an
/// opaque part set into glass), the ray meets the opaque surface. Without the rule the two kernels'
/// roundings, or the tie rule's prim ids, decide ray by ray which of the two is nearer: a ray inside the
/// glass that takes the glass face refracts out *into* the table or below the floor and sees what lies
/// beyond, and which rays do changes with the scene's scale and the order of its shapes. So after the
/// intersect and CSG stages, a dielectric hit (a prim's, or a CSG leaf's) of a ray inside a medium is
/// replaced by an opaque hit found at the same distance or beyond it within the CSG stage's coincidence
/// tolerance (`COINCIDENT_EPS (|o|_inf / |d| + t)`, `csg/merge.rs`), the nearest such (lower id on a
/// tie): the same `t` bits, prim, leaf and side as if the opaque surface had been nearest. Candidates
/// are the glass prim's neighbours (`Scene::glass_neighbours`: opaque prims whose bounds touch it, and
/// opaque planes); scenes where no glass touches an opaque surface skip the pass.
#[inline(never)]
pub fn glass_gives_way(scene: &Scene, rays: &RayQueue, hits: &mut HitQueue, arena: &mut CsgArena) {
    use crate::scene::MaterialKind;
    if scene.glass_neighbours.is_empty() {
        return;
    }
    // Only rays inside a medium can meet a glass face that lies on an opaque one from the glass side,
    // which is where the roundings matter (from outside, such a face is a sliver at the opaque
    // surface's edge of the glass). Their mask first, 64 rays at a time, without a branch per ray.
    let dielectric = |hits: &HitQueue, i: usize| {
        let kind = match (hits.prim[i], hits.leaf[i]) {
            (NONE, _) => None,
            (p, NONE) => scene.prim_kind.get(p as usize),
            (_, leaf) => scene.leaf_kind.get(leaf as usize),
        };
        kind == Some(&MaterialKind::Dielectric)
    };
    let media = &rays.media[..rays.len()];
    for (c, chunk) in media.chunks(64).enumerate() {
        // (Most blocks of a queue have no ray inside a medium: one vectorised OR tells.)
        if chunk.iter().fold(0u64, |a, m| a | m.0) == 0 {
            continue;
        }
        let mut bits = chunk.iter().enumerate().fold(0u64, |b, (k, m)| b | ((m.0 != 0) as u64) << k);
        while bits != 0 {
            let i = c * 64 + bits.trailing_zeros() as usize;
            bits &= bits - 1;
            if dielectric(hits, i) && !scene.glass_neighbours.of(hits.prim[i]).is_empty() {
                glass_hit_on_opaque(scene, rays, hits, i, arena);
            }
        }
    }
}

/// [`glass_gives_way`] for ray `i`, whose hit is a dielectric surface of a prim with neighbours.
///
/// An opaque neighbour's hit at `t_n >= t` takes the ray when it lies within the coincidence tolerance
/// beyond the glass hit `p`, or when the neighbour's surface (its tangent plane at that hit) passes
/// within twice the spawn offset of `p`: the ray the glass would spawn at `p` (`offset_ray_origin`,
/// moved off the glass by `OFFSET_ULPS` ULPs of the larger of `|p|` and `|o|`) could start beyond
/// that surface, under the floor a glass sphere touches, and see what lies behind it.
#[inline(always)]
fn glass_hit_on_opaque(scene: &Scene, rays: &RayQueue, hits: &mut HitQueue, i: usize, arena: &mut CsgArena) {
    let eps = crate::csg::COINCIDENT_EPS;
    let (o, d, t) = (Vec3::new(rays.ox[i], rays.oy[i], rays.oz[i]), Vec3::new(rays.dx[i], rays.dy[i], rays.dz[i]), hits.t[i]);
    let (o_inf, d_1) = (o.abs().max_element(), d.abs().element_sum());
    let hit = o + d * t;
    // Twice the spawn offset at the hit (an ULP of the magnitude is at most 2^-23 of it).
    let reach = 2.0 * crate::geometry::OFFSET_ULPS * f32::EPSILON * hit.abs().max_element().max(o_inf);
    // A surface within the tolerance beyond the hit passes within `tol |d| <= eps (|o|_inf + t |d|)`
    // of the hit point, one within reach of the spawn offset within `reach`: no kernel runs for a
    // neighbour farther than both (the usual case); the generous slack covers the roundings of this
    // estimate.
    let near = 2.0 * eps * (o_inf + t * d_1) + 1e-5 * (o_inf + t * d_1) + 2.0 * reach;
    let mut best: Option<(f32, u32, u32, bool)> = None;
    for &pid in scene.glass_neighbours.of(hits.prim[i]) {
        let far = match &scene.prims[pid as usize].shape {
            Shape::Plane(p) => (p.normal.dot(hit) - p.offset).abs() > near + 1e-5 * p.offset.abs(),
            _ => {
                let b = &scene.bounds[pid as usize];
                hit.cmplt(b.min - Vec3::splat(near)).any() || hit.cmpgt(b.max + Vec3::splat(near)).any()
            }
        };
        if far {
            continue;
        }
        if let Some(h) = opaque_neighbour_hit(scene, rays, i, t, pid, reach, arena) {
            if best.is_none_or(|(bt, bp, ..)| h.0 < bt || (h.0 == bt && pid < bp)) {
                best = Some((h.0, pid, h.1, h.2));
            }
        }
    }
    if let Some((tn, pid, leaf, flip)) = best {
        (hits.t[i], hits.prim[i], hits.leaf[i], hits.flip[i]) = (tn, pid, leaf, flip);
    }
}

/// Ray `i`'s hit `(t_n, leaf, flip)` of opaque neighbour `pid` (the packet kernels on the ray splatted,
/// as the intersect and CSG stages compute it), when it takes the ray from the glass hit at `t`: at
/// `t_n >= t` and within the coincidence tolerance, or with the neighbour's tangent plane at its hit
/// within `reach` of the glass hit. Out of line: most rays never get here (the pre-test).
#[cold]
#[inline(never)]
fn opaque_neighbour_hit(
    scene: &Scene,
    rays: &RayQueue,
    i: usize,
    t: f32,
    pid: u32,
    reach: f32,
    arena: &mut CsgArena,
) -> Option<(f32, u32, bool)> {
    let (o, d, tmax) = (Vec3::new(rays.ox[i], rays.oy[i], rays.oz[i]), Vec3::new(rays.dx[i], rays.dy[i], rays.dz[i]), rays.tmax[i]);
    let time = rays.with_time.then(|| f32x8::splat(rays.time[i]));
    let ray = Ray8::new(Vec3x8::splat(o), Vec3x8::splat(d), f32x8::splat(tmax));
    let prim = &scene.prims[pid as usize];
    let (tn, leaf, flip) = match &prim.shape {
        Shape::Plane(p) => (intersect_plane_x8(p, &ray).to_array()[0], NONE, false),
        Shape::Csg { solid } => {
            let mut out = [None; LANES];
            let r = in_prim_frame(&ray, prim.motion, time);
            let r = Ray8 { tmax: crate::simd::mask_from_bits(1).select(r.tmax, f32x8::splat(-1.0)), ..r };
            crate::csg::first_hit_x8(&scene.csg, *solid, &r, f32x8::ZERO, arena, &mut out);
            // (A glass leaf of an opaque neighbour is not an opaque surface.)
            let h = out[0].filter(|h| scene.leaf_kind[h.leaf as usize] != crate::scene::MaterialKind::Dielectric)?;
            (h.t, h.leaf, h.flip)
        }
        _ => (prim_t_at_x8(prim, &ray, time).to_array()[0], NONE, false),
    };
    if !(tn >= t && tn < tmax) {
        return None;
    }
    let o_inf = o.abs().max_element();
    let within = tn - t <= crate::csg::COINCIDENT_EPS * (o_inf / d.length() + t) || {
        // The neighbour's tangent plane at its hit, against the spawn offset at the glass hit.
        let r = crate::wavefront::RayItem { o, d, time: if rays.with_time { rays.time[i] } else { 0.0 }, ..Default::default() };
        let n = crate::wavefront::shade::surface_hit(scene, &r, tn, pid, leaf, flip).n_facing;
        ((tn - t) * d.dot(n)).abs() <= reach
    };
    within.then_some((tn, leaf, flip))
}

/// An octant-sorted queue through the wide BVH (`scene.wide_bvh`): packets of 8 rays gathered in `order`
/// meet the planes, then traverse the wide BVH (`WideBvh::traverse_closest_x8`).
fn intersect_wide(scene: &Scene, rays: &RayQueue, order: &[u32], hits: &mut HitQueue, cands: &mut CsgCandidates) {
    let len = rays.len();
    let none = i32x8::splat(NONE as i32);
    // The traversal stack is the queue's reusable scratch (7 KiB with 8 children per node, 15 with 16: not allocated per call).
    let HitQueue { t: hit_t, prim: hit_prim, wide_stack: stack, .. } = hits;
    for base in (0..len).step_by(LANES) {
        let (mut ray, time) = gather_packet(rays, order, base, len);
        let mut ids = none;
        for &pid in &scene.unbounded {
            let t = prim_t_ties(&scene.prims[pid as usize], &mut ray, &ids, None);
            record(&mut ray, &mut ids, t, pid);
        }
        scene.wide_bvh.traverse_closest_x8(&mut ray, stack, |slot, r| {
            hit_slot(scene, slot, r, &mut ids, time, cands, |l| order[base + l]);
        });
        let found = ids.simd_eq(none);
        let t = bytemuck::cast::<i32x8, f32x8>(found).select(f32x8::splat(f32::INFINITY), ray.tmax);
        let (ta, ia) = (t.to_array(), ids.to_array());
        for l in 0..LANES.min(len - base) {
            let i = order[base + l] as usize;
            (hit_t[i], hit_prim[i]) = (ta[l], ia[l] as u32);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sample::hash::test_uniforms;
    use crate::wavefront::RayItem;

    /// The partition of an incoherent queue: a permutation of the queue, bins in order, queue order
    /// within a bin, every packet of one octant where its bin's rays fill it; bins in range for
    /// degenerate directions (zero, axis-aligned, huge, tiny, NaN) too; coherent queues left alone.
    #[test]
    fn incoherent_queues_are_partitioned_by_direction_bin() {
        let mut u = test_uniforms(0xd1b5);
        let mut rays = RayQueue::new(false, false);
        let odd = [
            Vec3::ZERO,
            Vec3::X,
            -Vec3::Y,
            Vec3::Z * 1e-30,
            Vec3::new(1e30, -1e30, 1e30),
            Vec3::splat(f32::NAN),
            Vec3::new(-0.0, 0.0, -0.0),
        ];
        for i in 0..5000 {
            let d = if i % 97 == 0 { odd[i / 97 % odd.len()] } else { Vec3::new(u() - 0.5, u() - 0.5, u() - 0.5) };
            rays.push(&RayItem { d, tmax: f32::INFINITY, ..Default::default() });
        }
        // As many rays per pixel as sort by cells, then one per pixel (octants alone).
        for (pixels, cells) in [(100, DIR_BINS), (5000, 1)] {
            rays.pixels = pixels;
            check_partition(&rays, cells);
        }
        // Known cells: +x lies on the x edge of octant 0; +y at the pole; (-1, -1, -1) at a third of
        // the way on both axes of octant 7; NaN in cell 0.
        let mut known = RayQueue::new(false, false);
        for d in [Vec3::X, Vec3::Y, Vec3::splat(-1.0), Vec3::new(0.5, 0.2, -0.3), Vec3::splat(f32::NAN)] {
            known.push(&RayItem { d, tmax: f32::INFINITY, ..Default::default() });
        }
        let want = [5 * 6, 0, (7 * 6 + 2) * 6 + 2, (4 * 6 + 3) * 6 + 1, 0];
        for (i, w) in want.into_iter().enumerate() {
            assert_eq!(direction_bin(&known, i, DIR_BINS), w, "ray {i}");
        }
        // A queue of one direction per 64 rays (camera-like) is not sorted.
        let mut coherent = RayQueue::new(false, false);
        for i in 0..640 {
            let d = if i < 320 { Vec3::new(0.1, -0.2, -1.0) } else { Vec3::new(-0.1, -0.2, -1.0) };
            coherent.push(&RayItem { d, tmax: f32::INFINITY, ..Default::default() });
        }
        assert!(!direction_order(&coherent, &mut Vec::new(), true));
    }

    /// One hit queue reused across queues (as each worker reuses its own) gives, queue after queue, what a
    /// fresh one gives, bit for bit and padding included: coherent queues overwrite every entry without
    /// a fill first (`HitQueue::reset_for_overwrite`), sorted ones fill misses after the sort. The
    /// sequence mixes camera-like and scattered queues of growing and shrinking sizes, and entries that
    /// held a hit in the previous queue miss in the next (else stale hits could pass unseen).
    #[test]
    fn a_reused_hit_queue_gives_what_a_fresh_one_gives() {
        let scene = crate::scene::load_scene(std::path::Path::new("scenes/bench_spheres.toml")).unwrap();
        let mut u = test_uniforms(0x4e05e);
        let camera_queue = |x0: u32, y0: u32, w: u32, h: u32| {
            let mut q = RayQueue::new(false, false);
            for y in y0..y0 + h {
                for x in x0..x0 + w {
                    let (o, d) = scene.camera.ray(x as f32 + 0.5, y as f32 + 0.5, [0.0, 0.0]);
                    q.push(&RayItem { o, d, tmax: f32::INFINITY, ..Default::default() });
                }
            }
            q.pixels = w * h;
            q.pad();
            q
        };
        let mut scattered_queue = |n: usize| {
            let mut q = RayQueue::new(false, false);
            for _ in 0..n {
                let o = Vec3::new(u() * 30.0 - 15.0, u() * 3.0, u() * 30.0 - 15.0);
                let d = Vec3::new(u() - 0.5, u() - 0.5, u() - 0.5);
                q.push(&RayItem { o, d, tmax: f32::INFINITY, ..Default::default() });
            }
            q.pixels = n as u32;
            q.pad();
            q
        };
        // (Rows 0-99 of bench_spheres look over the spheres at the sky; the lower rows meet them. The
        // camera blocks stay off the image's centre column, where a block's directions change octant
        // and the queue is sorted.)
        let queues = [
            (scattered_queue(3001), true),
            (camera_queue(200, 0, 64, 40), false),
            (camera_queue(100, 300, 50, 13), false),
            (scattered_queue(93), true),
            (camera_queue(0, 0, 64, 64), false),
            (camera_queue(400, 250, 64, 64), false),
            (camera_queue(400, 0, 64, 30), false),
        ];
        let (mut reused, mut cands) = (HitQueue::default(), CsgCandidates::default());
        let (mut stale_tested, mut previous) = (0usize, Vec::new());
        for (k, (q, scattered)) in queues.iter().enumerate() {
            let mut fresh = HitQueue::default();
            intersect(&scene, q, &mut fresh, &mut cands);
            intersect(&scene, q, &mut reused, &mut cands);
            assert_eq!(reused.scattered, *scattered, "queue {k}");
            assert_eq!(reused.t.len(), q.padded_len(), "queue {k}");
            assert_eq!(
                reused.t.iter().map(|t| t.to_bits()).collect::<Vec<_>>(),
                fresh.t.iter().map(|t| t.to_bits()).collect::<Vec<_>>(),
                "queue {k}: t"
            );
            assert_eq!(reused.prim, fresh.prim, "queue {k}: prim");
            assert_eq!((&reused.leaf, &reused.flip), (&fresh.leaf, &fresh.flip), "queue {k}: CSG fields");
            stale_tested += (0..fresh.prim.len().min(previous.len())).filter(|&i| previous[i] != NONE && fresh.prim[i] == NONE).count();
            previous = fresh.prim.clone();
        }
        assert!(stale_tested > 500, "{stale_tested} entries went from a hit to a miss");
    }

    fn check_partition(rays: &RayQueue, cells: usize) {
        let mut order = Vec::new();
        assert!(direction_order(rays, &mut order, true), "random directions are incoherent");
        let mut seen = vec![false; rays.len()];
        for &i in &order {
            assert!(!std::mem::replace(&mut seen[i as usize], true), "ray {i} twice");
        }
        assert!(seen.iter().all(|&s| s), "a ray left out");
        let bins: Vec<usize> = order.iter().map(|&i| direction_bin(rays, i as usize, cells)).collect();
        assert!(bins.iter().all(|&b| b < 8 * cells * cells));
        for k in 1..order.len() {
            assert!(bins[k - 1] < bins[k] || (bins[k - 1] == bins[k] && order[k - 1] < order[k]), "{cells} cells, position {k}");
        }
        // Octants (sign bits, x first) are the bins' leading digit, so each octant is one run.
        let octants: Vec<usize> = bins.iter().map(|b| b / (cells * cells)).collect();
        assert!(octants.windows(2).all(|w| w[0] <= w[1]));
        for (&i, &o) in order.iter().zip(&octants) {
            let d = [rays.dx[i as usize], rays.dy[i as usize], rays.dz[i as usize]];
            assert_eq!(o, (0..3).map(|a| (d[a].is_sign_negative() as usize) << a).sum::<usize>());
        }
        let used = bins.iter().collect::<std::collections::BTreeSet<_>>().len();
        assert!(used > 8 * cells * cells / 2, "{cells} cells: {used} bins used");
    }

    /// `hit_slot` (static spheres from the slot-ordered lanes) must record what `hit_bounded` records
    /// for the slot's prim through its `Prim`: the same `t` bits, ids and candidates, for every slot of
    /// scenes with static and moving spheres, planes, boxes, quads and CSG solids, with packets aimed at
    /// the slot's prim (hits, grazes, misses), some lanes already holding a hit at the same distance
    /// (the tie rule) and some inactive.
    #[test]
    fn slot_leaves_record_what_the_prims_record() {
        let (mut compared, mut hits, mut ties) = (0usize, 0usize, 0usize);
        for name in ["bench_spheres", "showcase", "csg", "motion", "cornell"] {
            let scene = crate::scene::load_scene(std::path::Path::new(&format!("scenes/{name}.toml"))).unwrap();
            let ls = &scene.leaf_spheres;
            let mut u = test_uniforms(0x51_07 + name.len() as u64);
            let root = &scene.bvh.nodes[0];
            let (lo, hi) = (Vec3::from_array(root.min), Vec3::from_array(root.max));
            for k in 0..scene.bvh.indices.len() {
                let pid = scene.bounded[scene.bvh.indices[k] as usize];
                assert_eq!(ls.prim[k], pid, "{name}: slot {k}");
                let b = &scene.bounds[pid as usize];
                let (target, spread) = ((b.min + b.max) * 0.5, b.extent().max_element() * 0.8);
                for _ in 0..4 {
                    let mut o = [[0.0f32; LANES]; 3];
                    let mut d = [[0.0f32; LANES]; 3];
                    for l in 0..LANES {
                        let from = lo + (hi - lo) * Vec3::new(u(), u(), u()) * 1.4 - (hi - lo) * 0.2;
                        let to = target + (Vec3::new(u(), u(), u()) - 0.5) * spread;
                        for a in 0..3 {
                            (o[a][l], d[a][l]) = (from[a], to[a] - from[a]);
                        }
                    }
                    let tmax = f32x8::from(std::array::from_fn::<f32, LANES, _>(|l| [f32::INFINITY, 1.5, 0.7, -1.0][(l + k) % 4]));
                    let ray = Ray8::new(Vec3x8::from_rows(&o), Vec3x8::from_rows(&d), tmax);
                    let time = scene.features.motion.then(|| f32x8::from(std::array::from_fn::<f32, LANES, _>(|_| u())));
                    // Lanes with a hit already: at the distance the prim itself gives (a tie), or none.
                    let mut probe = ray;
                    let (mut ids0, mut none_cands) = (i32x8::splat(NONE as i32), CsgCandidates::default());
                    hit_bounded(&scene, pid, &mut probe, &mut ids0, time, &mut none_cands, |l| l as u32);
                    let tie = crate::simd::mask_from_bits(0b0100_1001) & probe.tmax.simd_lt(ray.tmax);
                    ties += tie.to_bitmask().count_ones() as usize;
                    let start = Ray8 { tmax: tie.select(probe.tmax, ray.tmax), ..ray };
                    let ids_start = bytemuck::cast::<f32x8, i32x8>(tie).select(i32x8::splat(pid as i32 + 1), i32x8::splat(NONE as i32));
                    let (mut a, mut b) = (start, start);
                    let (mut ia, mut ib) = (ids_start, ids_start);
                    let (mut ca, mut cb) = (CsgCandidates::default(), CsgCandidates::default());
                    hit_bounded(&scene, pid, &mut a, &mut ia, time, &mut ca, |l| l as u32);
                    hit_slot(&scene, k as u32, &mut b, &mut ib, time, &mut cb, |l| l as u32);
                    let bits = |r: &Ray8| r.tmax.to_array().map(f32::to_bits);
                    assert_eq!(bits(&a), bits(&b), "{name}: slot {k} (prim {pid}): t");
                    assert_eq!(ia.to_array(), ib.to_array(), "{name}: slot {k} (prim {pid}): ids");
                    assert_eq!((ca.ray, ca.prim), (cb.ray, cb.prim), "{name}: slot {k}: CSG candidates");
                    hits += (ia.simd_ne(ids_start)).to_bitmask().count_ones() as usize;
                    compared += LANES;
                }
            }
        }
        assert!(compared > 30_000 && hits > 3_000 && ties > 1_000, "{compared} lanes, {hits} hits, {ties} ties");
    }

    /// Glass resting on an opaque support: rays inside a glass block (a box prim, or a CSG solid) that
    /// leave through its bottom face, which lies on the support's top (a floor plane, a table top as a
    /// box prim, as a CSG solid with a hole beside the glass, or as a quad), meet the support, at every
    /// scale and position, whichever shape the file declares first; without the rule the kernels'
    /// roundings or the tie rule's ids give the glass face to some of them (so the test can fail), and a
    /// ray that takes it refracts out into the support.
    #[test]
    fn glass_resting_on_an_opaque_surface_gives_way_to_it() {
        use crate::wavefront::queues::MediumStack;
        use crate::wavefront::{csg_merge::csg_merge, RayItem};
        let mut u = test_uniforms(0x61a5);
        let (mut raw_glass, mut checked) = (0usize, 0usize);
        let supports = [
            "type = \"plane\"\npoint = [0, 0, 0]\nnormal = [0, 1, 0]",
            "type = \"box\"\nmin = [-2, -0.5, -2]\nmax = [2, 0, 2]",
            "type = \"csg\"\nop = \"difference\"\nchildren = [ { type = \"box\", min = [-2, -0.5, -2], max = [2, 0, 2] }, { type = \"cylinder\", center = [1.6, 0, 1.6], height = 2, radius = 0.2 } ]",
            "type = \"quad\"\norigin = [-2, 0, 2]\nu = [4, 0, 0]\nv = [0, 0, -4]",
        ];
        for scale in [1e-3f32, 1.0, 7.0, 1e3, 3e4] {
            for (k, support) in supports.iter().enumerate() {
                for csg in [false, true] {
                    let block = if csg {
                        "type = \"csg\"\nop = \"difference\"\nmaterial = \"g\"\nchildren = [ { type = \"box\", min = [-1, 0, -1], max = [1, 1.3, 1] }, { type = \"sphere\", center = [0, 1.3, 0], radius = 0.4 } ]"
                    } else {
                        "type = \"box\"\nmin = [-1, 0, -1]\nmax = [1, 1.3, 1]\nmaterial = \"g\""
                    };
                    // Support and glass placed alike (the plane only moves within itself).
                    let place = format!(
                        "transform = {{ scale = [{scale}, {scale}, {scale}], rotate = [0, {r}, 0], translate = [{tx}, 0, {tz}] }}",
                        r = 17 * k,
                        tx = 3.0 * scale,
                        tz = -2.0 * scale
                    );
                    let support = format!("[[shapes]]\n{support}\nmaterial = \"f\"\n{place}\n");
                    let glass = format!("[[shapes]]\n{block}\n{place}\n");
                    // Glass first in odd cases: on an exact tie the lower id would take the ray.
                    let shapes = if (k + csg as usize) % 2 == 1 { glass.clone() + &support } else { support.clone() + &glass };
                    let text = format!(
                        "[image]\nwidth = 4\nheight = 4\n[camera]\nposition = [0, 3, 5]\nlook_at = [0, 0, 0]\nfov = 40\n\
                         [materials.f]\ntype = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\n[materials.g]\ntype = \"dielectric\"\nior = 1.5\n{shapes}"
                    );
                    let scene = crate::scene::parse_scene(std::path::Path::new("g.toml"), &text).unwrap();
                    let glass_m = scene.materials.iter().position(|m| matches!(m, crate::scene::Material::Dielectric(_))).unwrap() as u32;
                    let floor = (0..scene.prims.len() as u32).find(|&p| scene.prims[p as usize].material != glass_m).unwrap();
                    let mut rays = RayQueue::new(false, false);
                    let rot = glam::Quat::from_rotation_y((17.0 * k as f32).to_radians());
                    for _ in 0..1000 {
                        let local = Vec3::new(1.6 * (u() - 0.5), 0.05 + 0.8 * u(), 1.6 * (u() - 0.5));
                        let o = (rot * local + Vec3::new(3.0, 0.0, -2.0)) * scale;
                        let d = Vec3::new(u() - 0.5, -0.2 - u(), u() - 0.5).normalize();
                        rays.push(&RayItem {
                            o,
                            d,
                            tmax: f32::INFINITY,
                            media: MediumStack::default().push(glass_m),
                            ..Default::default()
                        });
                    }
                    let (mut hits, mut cands) = (HitQueue::default(), CsgCandidates::default());
                    rays.pad();
                    intersect_with(&scene, &rays, &mut hits, &mut cands, INCOHERENT);
                    if scene.features.csg {
                        csg_merge(&scene, &rays, &mut cands, &mut hits, &mut crate::csg::CsgArena::default());
                    } else {
                        glass_gives_way(&scene, &rays, &mut hits, &mut crate::csg::CsgArena::default());
                    }
                    for i in 0..rays.len() {
                        let (o, d) = (Vec3::new(rays.ox[i], rays.oy[i], rays.oz[i]), Vec3::new(rays.dx[i], rays.dy[i], rays.dz[i]));
                        // Rays that reach the floor inside the block's footprint (the others leave by a side).
                        let t_floor = -o.y / d.y;
                        let p = rot.inverse() * (o + d * t_floor) / scale - rot.inverse() * Vec3::new(3.0, 0.0, -2.0);
                        if p.x.abs() > 0.98 || p.z.abs() > 0.98 {
                            continue;
                        }
                        checked += 1;
                        assert_eq!(
                            hits.prim[i], floor,
                            "scale {scale}, support {k}, csg {csg}: ray {i} from {o} along {d} takes prim {} at {}",
                            hits.prim[i], hits.t[i]
                        );
                    }
                    // The same rays without the rule: the glass face takes some of them somewhere.
                    let mut raw = HitQueue::default();
                    let mut raw_cands = CsgCandidates::default();
                    intersect_with(&scene, &rays, &mut raw, &mut raw_cands, INCOHERENT);
                    if scene.features.csg {
                        crate::wavefront::csg_merge::csg_merge_candidates(
                            &scene,
                            &rays,
                            &mut raw_cands,
                            &mut raw,
                            &mut crate::csg::CsgArena::default(),
                        );
                    }
                    raw_glass += (0..rays.len())
                        .filter(|&i| {
                            raw.prim[i] != floor && raw.prim[i] != NONE && (rays.oy[i] + rays.dy[i] * raw.t[i]).abs() <= 1e-4 * scale
                        })
                        .count();
                }
            }
        }
        assert!(checked > 20_000, "{checked} rays reach the floor under the glass");
        assert!(raw_glass > 1000, "without the rule only {raw_glass} rays took the glass face: the test would not see a regression");
    }
}
