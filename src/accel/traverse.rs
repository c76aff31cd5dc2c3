//! BVH traversal: 8-ray packets (closest hit, any hit) and a scalar f64 reference.
//!
//! Packet traversal after Wald, Slusallek, Benthin & Wagner 2001 ("Interactive Rendering with
//! Coherent Ray Tracing"): the packet descends as a whole; a node is entered when any lane's slab
//! interval overlaps `[0, tmax]` of that lane; the far child goes on a stack and the near child is
//! visited next. The stack is a fixed array of `MAX_DEPTH` entries (the build guarantees depth <=
//! `MAX_DEPTH`, and descending pushes one entry per level), so traversal neither allocates nor
//! recurses. Each node's box is tested when the node is popped, so a far child whose lanes all found
//! a closer hit meanwhile is culled by the lowered `tmax` at no extra cost.
//!
//! Near child: the side the packet points to on the node's split axis, decided once per packet by
//! the sign of the *sum* of the active lanes' direction components (3 reductions per packet, nothing
//! per node). The brief asked for the sign of the first active lane; the sum visits fewer nodes.
//!
//! Ordering and layout experiments, counted (not timed: the machine is shared) on 20,000 random
//! spheres (r up to 0.4 "sparse" / 1.0 "dense") with the tests' packet mix (half coherent, half
//! incoherent, inactive lanes, zero components), box tests / leaf calls per packet:
//!
//! | near child chosen by                         | sparse        | dense         | dense, coherent only |
//! |----------------------------------------------|---------------|---------------|----------------------|
//! | always left (no ordering)                    | 315.4 / 23.25 | 415.7 / 89.13 | 250.4 / 60.02        |
//! | sign of the first active lane (the brief)    | 237.8 / 15.14 | 306.6 / 59.45 |  71.3 / 11.52        |
//! | majority sign of the active lanes            | 219.8 / 13.52 | 280.5 / 52.44 |  61.8 /  9.18        |
//! | sign of the summed directions (kept)         | 213.9 / 12.95 | 271.2 / 49.65 |  61.6 /  9.13        |
//! | test both children at the parent, push the hit ones, nearer = smaller min tnear over lanes | 212.4 / 10.29 | 267.9 / 37.26 | 72.7 / 8.73 |
//!
//! The last row saves leaf calls on incoherent packets (-25% dense) but tests two boxes per inner
//! node, re-tests popped nodes against the lowered tmax, and needs two horizontal minimums per
//! node; coherent packets get more box tests. Not kept without a timing that shows the trade pays;
//! a candidate for the benchmark (`benches/stages.rs`) once primitive kernels exist.
//! A scalar early test of the first active lane before the 8-lane test (Reshetov's "first hit")
//! was not tried: one 8-lane box test is the same instruction count as one scalar test on AVX.

use glam::{DVec3, Vec3};

use super::aabb::{intersect_aabb_f64, intersect_aabb_x8, PacketRay};
use super::{Bvh, MAX_DEPTH};
use crate::simd::{f32x8, Ray8};

/// Stack entries of the traversal: at most `MAX_DEPTH - 1` far children are pending at once.
const STACK: usize = MAX_DEPTH;

/// Bit `a` set when the sum of the `active` lanes' directions is negative on axis `a`: the near child
/// on axis `a` is then the right one (the build puts smaller centroids left).
#[inline(always)]
fn near_is_right_bits(ray: &Ray8, active: f32x8) -> u32 {
    let bit = |v: f32x8| (active.select(v, f32x8::ZERO).reduce_add() < 0.0) as u32;
    bit(ray.d.x) | (bit(ray.d.y) << 1) | (bit(ray.d.z) << 2)
}

impl Bvh {
    /// Closest-hit packet traversal. `leaf(slot, &mut ray)` is called for each primitive of each
    /// visited leaf (`slot`: its position in `indices`, which holds the primitive; data a renderer keeps
    /// in slot order is then read in leaf order); it tests the primitive against all lanes and lowers
    /// `ray.tmax` on lanes it hits (the caller records ids). It must not change `o`, `d` or `inv_d`
    /// (they are precomputed once).
    /// Children are visited near-first (by the sign of the summed directions of the lanes with
    /// `tmax >= 0` on the node's split axis, see the module doc); a node is skipped when no lane's
    /// slab interval overlaps `[0, tmax]` (conservatively, see `PacketRay`). Lanes with `tmax < 0`
    /// are inactive.
    pub fn traverse_closest_x8(&self, ray: &mut Ray8, mut leaf: impl FnMut(u32, &mut Ray8)) {
        let active = ray.tmax.simd_ge(f32x8::ZERO);
        if !active.any() || self.nodes.is_empty() {
            return;
        }
        let pr = PacketRay::new(ray);
        let near_right = near_is_right_bits(ray, active);
        let mut stack = [0u32; STACK];
        let mut sp = 0usize;
        let mut node = 0usize;
        loop {
            let n = &self.nodes[node];
            let (_, hit) = intersect_aabb_x8(Vec3::from_array(n.min), Vec3::from_array(n.max), &pr, ray.tmax);
            if hit.any() {
                let count = n.count() as usize;
                if count == 0 {
                    let r = (near_right >> n.axis()) & 1;
                    stack[sp] = n.left_first + (r ^ 1);
                    sp += 1;
                    node = (n.left_first + r) as usize;
                    continue;
                }
                let first = n.left_first as usize;
                for slot in first..first + count {
                    leaf(slot as u32, ray);
                }
            }
            if sp == 0 {
                return;
            }
            sp -= 1;
            node = stack[sp] as usize;
        }
    }

    /// Any-hit (occlusion) packet traversal. Its loop mirrors `traverse_closest_x8` on purpose (as
    /// tinybvh keeps `Intersect` and `IsOccluded` apart): a shared walker would need the leaf callback and
    /// the node test to share the ray's `tmax` through one closure, in the hottest loop of the renderer.
    /// Active lanes are those with `tmax > 0`. `leaf(slot, &ray)` (a primitive's slot in `indices`, as
    /// for [`Bvh::traverse_closest_x8`]) returns the lanes the primitive occludes (all-ones lanes); in
    /// the `ray` it receives, inactive and already occluded lanes have `tmax = -1`, so a kernel that
    /// accepts hits in `(tmin, tmax)` ignores them without a mask. Traversal stops as soon as every
    /// active lane is occluded. Returns the occluded mask (only active lanes can be set).
    pub fn traverse_any_x8(&self, ray: &Ray8, mut leaf: impl FnMut(u32, &Ray8) -> f32x8) -> f32x8 {
        let active = ray.tmax.simd_gt(f32x8::ZERO);
        let active_bits = active.to_bitmask();
        if active_bits == 0 || self.nodes.is_empty() {
            return f32x8::ZERO;
        }
        let off = f32x8::splat(-1.0);
        let mut r = *ray;
        r.tmax = active.select(r.tmax, off);
        let pr = PacketRay::new(&r);
        let near_right = near_is_right_bits(&r, active);
        let mut occluded = f32x8::ZERO;
        let mut stack = [0u32; STACK];
        let mut sp = 0usize;
        let mut node = 0usize;
        loop {
            let n = &self.nodes[node];
            let (_, hit) = intersect_aabb_x8(Vec3::from_array(n.min), Vec3::from_array(n.max), &pr, r.tmax);
            if hit.any() {
                let count = n.count() as usize;
                if count == 0 {
                    let rb = (near_right >> n.axis()) & 1;
                    stack[sp] = n.left_first + (rb ^ 1);
                    sp += 1;
                    node = (n.left_first + rb) as usize;
                    continue;
                }
                let first = n.left_first as usize;
                for slot in first..first + count {
                    let occ = leaf(slot as u32, &r) & active;
                    if occ.any() {
                        occluded |= occ;
                        if occluded.to_bitmask() == active_bits {
                            return occluded;
                        }
                        // Occluded lanes drop out of the box tests too.
                        r.tmax = occluded.select(off, r.tmax);
                    }
                }
            }
            if sp == 0 {
                return occluded;
            }
            sp -= 1;
            node = stack[sp] as usize;
        }
    }

    /// Scalar f64 reference of the closest-hit traversal: returns the closest `(t, prim)` with
    /// `0 <= t < tmax`. `leaf(prim, o, d, tmax)` returns the primitive's hit distance, or anything
    /// outside `[0, tmax)` (e.g. `f64::INFINITY`) for a miss. Nodes are visited near-first by the
    /// sign of `d` on the split axis and culled by the unpadded f64 slab test against the closest
    /// hit so far.
    pub fn traverse_closest_f64(
        &self,
        o: DVec3,
        d: DVec3,
        tmax: f64,
        mut leaf: impl FnMut(u32, DVec3, DVec3, f64) -> f64,
    ) -> Option<(f64, u32)> {
        if self.nodes.is_empty() || tmax.is_nan() || tmax <= 0.0 {
            return None;
        }
        let near_right = (d.x < 0.0) as u32 | ((d.y < 0.0) as u32) << 1 | ((d.z < 0.0) as u32) << 2;
        let (mut best_t, mut best) = (tmax, None);
        let mut stack = [0u32; STACK];
        let mut sp = 0usize;
        let mut node = 0usize;
        loop {
            let n = &self.nodes[node];
            if intersect_aabb_f64(Vec3::from_array(n.min), Vec3::from_array(n.max), o, d, best_t).is_some() {
                let count = n.count() as usize;
                if count == 0 {
                    let r = (near_right >> n.axis()) & 1;
                    stack[sp] = n.left_first + (r ^ 1);
                    sp += 1;
                    node = (n.left_first + r) as usize;
                    continue;
                }
                let first = n.left_first as usize;
                for &p in &self.indices[first..first + count] {
                    let t = leaf(p, o, d, best_t);
                    if t >= 0.0 && t < best_t {
                        (best_t, best) = (t, Some(p));
                    }
                }
            }
            if sp == 0 {
                return best.map(|p| (best_t, p));
            }
            sp -= 1;
            node = stack[sp] as usize;
        }
    }
}
