//! Group traversal: up to [`GROUP`] 8-ray packets (128 rays) descend the BVH together.
//!
//! One 8-ray packet per traversal pays one box test per visited node for 8 rays; coherent rays (camera
//! rays of an 8x8 pixel block, shadow rays of neighbouring points towards one light) visit nearly the
//! same nodes, so a group shares the walk, after Wald, Boulos & Shirley 2007 ("Ray Tracing Deformable
//! Scenes Using Dynamic Bounding Volume Hierarchies", their "first active ray" and interval-arithmetic
//! culling; here the unit is an 8-lane packet, not a ray):
//!
//! - Each stack entry carries the index `first` of the first packet that may still hit the node.
//!   A node is entered by testing packet `first` alone (one 8-lane slab test); only when it misses is
//!   the whole group's interval test tried, and only when that cannot cull are packets `first + 1..`
//!   tested until one hits. Packets before `first` are never tested below the node that dropped them.
//! - The interval test bounds the slab distances of all rays of the group at once from the boxes of
//!   their origins and inverse directions (`GroupBounds`): a node it culls is missed by every ray.
//!   It is exact-conservative (computed in f64 from widened f32 inputs). An axis on which the group's
//!   directions have both signs bounds nothing and is left out (shadow rays around the foot of their
//!   light, camera rays at the image's centre lines); with two or three such axes the group is not
//!   coherent and [`Bvh::traverse_closest_group`] falls back to one traversal per packet.
//! - At a leaf, packets `first..` each test the leaf's box before their primitives (a box test is
//!   cheaper than the primitives of a leaf).
//!
//! Results do not depend on grouping: every (primitive, packet) pair a per-packet traversal would reach
//! is reached (the group test is at least as permissive as the padded per-lane test), possibly with
//! more, and the callers' hit recording is order-independent (equal distances go to the lower
//! primitive id: the intersect stage lets kernels report a hit at exactly the current distance).

use glam::{BVec3A, Vec3, Vec3A};

use super::aabb::{intersect_aabb_x8, PacketRay};
use super::{Bvh, BvhNode, MAX_DEPTH};
use crate::simd::{f32x8, Ray8, Vec3x8};

/// Packets per group. Shadow any-hit on bench_spheres, one thread (local probe, best of 30, M rays/s):
/// 8 packets 58.5-60.7, 16 packets 68.2-70.2, 32 packets 64.5-69.3 (session 5; images unchanged).
pub const GROUP: usize = 16;

/// Interval bounds of a group of rays, mirrored so that every axis has positive directions: on an axis
/// whose directions are negative, origins and boxes are negated (then `t = (b - o) * inv` with `inv > 0`).
/// An axis with directions of both signs is not mirrored: its origins span -inf..+inf with a unit
/// inverse, which makes its entry -inf and its exit +inf (it culls nothing).
/// Kept in SSE vectors (`Vec3A`): the test costs about 15 vector instructions per node.
#[derive(Clone, Copy, Debug)]
pub(super) struct GroupBounds {
    /// Set on axes whose directions are negative.
    pub(super) neg: BVec3A,
    /// Widening of node boxes in space: `PAD * max |o|` per axis, at least the per-lane test's absolute
    /// padding (`ABS_PAD * |o|`, see `aabb.rs`), so the group never culls what one packet would enter.
    pub(super) pad: Vec3A,
    pub(super) o_lo: Vec3A,
    pub(super) o_hi: Vec3A,
    pub(super) inv_lo: Vec3A,
    pub(super) inv_hi: Vec3A,
}

impl GroupBounds {
    /// Bounds of the active lanes (`tmax >= 0`) of `rays`; `None` when their directions have both signs
    /// on more than [`MAX_MIXED_AXES`] axes or no lane is active. A zero direction component (infinite
    /// inverse) gives `None`; an infinite one (zero inverse) counts as a mixed axis (left out, so still
    /// conservative); NaN inverses are skipped by the min/max folds, as before.
    pub(super) fn new(rays: &[Ray8]) -> Option<Self> {
        let inf = f32x8::splat(f32::INFINITY);
        let mut lo = [inf; 6];
        let mut hi = [-inf; 6];
        for r in rays {
            let act = r.tmax.simd_ge(f32x8::ZERO);
            let fields = [r.o.x, r.o.y, r.o.z, r.inv_d.x, r.inv_d.y, r.inv_d.z];
            if act.all() {
                // Every lane active (camera packets): no masking.
                for (k, v) in fields.into_iter().enumerate() {
                    (lo[k], hi[k]) = (lo[k].fast_min(v), hi[k].fast_max(v));
                }
            } else {
                for (k, v) in fields.into_iter().enumerate() {
                    lo[k] = lo[k].fast_min(act.select(v, inf));
                    hi[k] = hi[k].fast_max(act.select(v, -inf));
                }
            }
        }
        let lo = lo.map(|v| v.to_array().into_iter().fold(f32::INFINITY, f32::min));
        let hi = hi.map(|v| v.to_array().into_iter().fold(f32::NEG_INFINITY, f32::max));
        // No active lane leaves infinities; so does a zero direction component (1/0).
        if lo.iter().chain(hi.iter()).any(|v| !v.is_finite()) {
            return None;
        }
        let (o_lo, o_hi) = (Vec3A::new(lo[0], lo[1], lo[2]), Vec3A::new(hi[0], hi[1], hi[2]));
        let (i_lo, i_hi) = (Vec3A::new(lo[3], lo[4], lo[5]), Vec3A::new(hi[3], hi[4], hi[5]));
        let pos = i_lo.cmpgt(Vec3A::ZERO);
        let neg = i_hi.cmplt(Vec3A::ZERO);
        // An axis whose directions have both signs bounds nothing: its slab interval over the group is
        // widened to the whole line (origins at -inf..+inf, unit inverse: entry -inf, exit +inf, with no
        // extra instruction in the tests). The other axes still cull; with two or three such axes too
        // little is left to cull and the callers trace packet by packet.
        let mixed = !(pos | neg);
        if mixed.bitmask().count_ones() > MAX_MIXED_AXES {
            return None;
        }
        let inf = Vec3A::splat(f32::INFINITY);
        let (o_lo_m, o_hi_m) = (Vec3A::select(neg, -o_hi, o_lo), Vec3A::select(neg, -o_lo, o_hi));
        Some(Self {
            neg,
            pad: o_lo.abs().max(o_hi.abs()) * PAD + Vec3A::splat(f32::MIN_POSITIVE),
            o_lo: Vec3A::select(mixed, -inf, o_lo_m),
            o_hi: Vec3A::select(mixed, inf, o_hi_m),
            inv_lo: Vec3A::select(mixed, Vec3A::ONE, Vec3A::select(neg, -i_hi, i_lo)),
            inv_hi: Vec3A::select(mixed, Vec3A::ONE, Vec3A::select(neg, -i_lo, i_hi)),
        })
    }

    /// True when no ray of the group can meet the box within `[0, tmax]`, and no packet of it would
    /// pass the padded per-lane slab test either (so grouping never changes which leaves a packet sees).
    ///
    /// Over the group, the entry distance of an axis is at least `(near plane - farthest origin) * inv`
    /// at the inverse that makes it smallest, and the exit at most `(far plane - nearest origin) * inv`
    /// at the one that makes it largest (for a fixed numerator the product is monotonic in `inv`, so
    /// the extreme is the min or max of the two end products). The box is first widened by `pad`
    /// (2^-20 of the largest origin coordinate, twice the lane test's absolute padding, which also
    /// covers the roundings of `b - o`; primitive boxes rounded to nearest can cut off half an ulp of
    /// a surface, and the lane test's padding is what catches such rays). Each computed distance is
    /// then within 2^-23 (relative) of its exact value, the group's `inv` bounds within 2^-24 of each
    /// lane's exact `1/d`, and the lane test scales `inv` by 1 +- 2^-21: culling only when `tn` exceeds
    /// `tf` by 2^-19 of their magnitudes plus the smallest normal float (for subnormal distances) is
    /// conservative.
    #[inline(always)]
    pub(super) fn misses(&self, bmin: Vec3A, bmax: Vec3A, tmax: f32) -> bool {
        let b0 = Vec3A::select(self.neg, -bmax, bmin) - self.pad;
        let b1 = Vec3A::select(self.neg, -bmin, bmax) + self.pad;
        let (d0, d1) = (b0 - self.o_hi, b1 - self.o_lo);
        let near = (d0 * self.inv_lo).min(d0 * self.inv_hi);
        let far = (d1 * self.inv_lo).max(d1 * self.inv_hi);
        culled(near.max_element().max(0.0), far.min_element().min(tmax))
    }
}

/// The interval test's verdict from the group's entry bound `tn` and exit bound `tf` (already limited
/// by `tmax`): true when `tn` exceeds `tf` by more than the slack (see [`GroupBounds::misses`]).
#[inline(always)]
pub(super) fn culled(tn: f32, tf: f32) -> bool {
    tn - tf > SLACK * (tn.abs() + tf.abs()) + f32::MIN_POSITIVE
}

/// Axes with directions of both signs a group may have (see [`GroupBounds::new`]).
const MAX_MIXED_AXES: u32 = 1;

/// Relative slack of the interval test (see [`GroupBounds::misses`]).
pub(super) const SLACK: f32 = 1.0 / (1u32 << 19) as f32;
/// Spatial widening of node boxes relative to the largest origin coordinate (see [`GroupBounds::misses`]).
const PAD: f32 = 1.0 / (1u32 << 20) as f32;

/// Sum of the active lanes' directions of all packets, as `near_is_right_bits` (see `traverse.rs`).
fn near_bits(rays: &[Ray8]) -> u32 {
    let mut s = Vec3x8::splat(Vec3::ZERO);
    for r in rays {
        let act = r.tmax.simd_ge(f32x8::ZERO);
        s = s + Vec3x8::new(act.select(r.d.x, f32x8::ZERO), act.select(r.d.y, f32x8::ZERO), act.select(r.d.z, f32x8::ZERO));
    }
    let bit = |v: f32x8| (v.reduce_add() < 0.0) as u32;
    bit(s.x) | (bit(s.y) << 1) | (bit(s.z) << 2)
}

/// Largest `tmax` of the group's packets (negative when none is active).
pub(super) fn group_tmax(rays: &[Ray8]) -> f32 {
    let m = rays.iter().fold(f32x8::splat(f32::NEG_INFINITY), |m, r| m.fast_max(r.tmax));
    m.to_array().into_iter().fold(f32::NEG_INFINITY, f32::max)
}

impl Bvh {
    /// Closest-hit traversal of up to [`GROUP`] packets together (see the module doc). `leaf(slot, j,
    /// &mut rays[j])` has the contract of [`Bvh::traverse_closest_x8`]'s callback, for packet `j`.
    /// A group without `GroupBounds` (directions of both signs on two axes) is traversed packet by packet.
    // Out of line (one call per group): inlined into the intersect stage, which one codegen partition
    // did, it measured 3-9% slower (session 29).
    #[inline(never)]
    pub fn traverse_closest_group(&self, rays: &mut [Ray8], mut leaf: impl FnMut(u32, usize, &mut Ray8)) {
        assert!(rays.len() <= GROUP, "at most {GROUP} packets per group");
        if self.nodes.is_empty() || rays.is_empty() {
            return;
        }
        let Some(gb) = (rays.len() > 1).then(|| GroupBounds::new(rays)).flatten() else {
            for (j, r) in rays.iter_mut().enumerate() {
                self.traverse_closest_x8(r, |p, r| leaf(p, j, r));
            }
            return;
        };
        let k = rays.len();
        let mut pr = [PacketRay::new(&rays[0]); GROUP];
        for j in 1..k {
            pr[j] = PacketRay::new(&rays[j]);
        }
        let near_right = near_bits(rays);
        let mut tmax = group_tmax(rays);
        let mut stack = [(0u32, 0u8); MAX_DEPTH];
        let mut sp = 0usize;
        let (mut node, mut first) = (0usize, 0usize);
        loop {
            let n = &self.nodes[node];
            if let Some(f) = first_hit(n, &pr[..k], rays, first, &gb, tmax) {
                let count = n.count() as usize;
                if count == 0 {
                    (node, first) = (descend(n, near_right, f, &mut stack, &mut sp), f);
                    continue;
                }
                let (slots, bmin, bmax) = self.leaf(n, count);
                for j in f..k {
                    if j != f && !intersect_aabb_x8(bmin, bmax, &pr[j], rays[j].tmax).1.any() {
                        continue;
                    }
                    for slot in slots.clone() {
                        leaf(slot, j, &mut rays[j]);
                    }
                }
                tmax = group_tmax(rays);
            }
            if sp == 0 {
                return;
            }
            sp -= 1;
            (node, first) = (stack[sp].0 as usize, stack[sp].1 as usize);
        }
    }

    /// Any-hit traversal of up to [`GROUP`] packets together. Its loop mirrors the closest-hit one on
    /// purpose, as in `traverse.rs`: the two differ in what the leaf does to the packets and in the
    /// early exit, inside the hottest loop of the renderer.
    ///
    /// Returns each packet's occluded mask, as
    /// [`Bvh::traverse_any_x8`] would for that packet alone (same callback contract, for packet `j`).
    /// Stops when every active lane of the group is occluded. A group without `GroupBounds` is
    /// traversed packet by packet. The packets' `tmax` are used as working
    /// state (inactive and occluded lanes end at -1); nothing else of them changes.
    pub fn traverse_any_group(&self, rays: &mut [Ray8], mut leaf: impl FnMut(u32, usize, &Ray8) -> f32x8) -> [f32x8; GROUP] {
        assert!(rays.len() <= GROUP, "at most {GROUP} packets per group");
        let mut occluded = [f32x8::ZERO; GROUP];
        if self.nodes.is_empty() || rays.is_empty() {
            return occluded;
        }
        let Some(gb) = (rays.len() > 1).then(|| GroupBounds::new(rays)).flatten() else {
            for (j, r) in rays.iter().enumerate() {
                occluded[j] = self.traverse_any_x8(r, |p, r| leaf(p, j, r));
            }
            return occluded;
        };
        let k = rays.len();
        let off = f32x8::splat(-1.0);
        // Inactive and occluded lanes get tmax = -1 (the any-hit callback contract).
        let rs = rays;
        let mut active = [f32x8::ZERO; GROUP];
        let mut pending = 0u32; // packets with an active lane not yet occluded
        for j in 0..k {
            active[j] = rs[j].tmax.simd_gt(f32x8::ZERO);
            rs[j].tmax = active[j].select(rs[j].tmax, off);
            if active[j].any() {
                pending |= 1 << j;
            }
        }
        if pending == 0 {
            return occluded;
        }
        let mut pr = [PacketRay::new(&rs[0]); GROUP];
        for j in 1..k {
            pr[j] = PacketRay::new(&rs[j]);
        }
        let near_right = near_bits(rs);
        let tmax = group_tmax(rs);
        let mut stack = [(0u32, 0u8); MAX_DEPTH];
        let mut sp = 0usize;
        let (mut node, mut first) = (0usize, 0usize);
        loop {
            // Packets that are done are skipped as `first`.
            first += (pending >> first).trailing_zeros() as usize;
            let n = &self.nodes[node];
            if first < k {
                if let Some(f) = first_hit(n, &pr[..k], rs, first, &gb, tmax) {
                    let count = n.count() as usize;
                    if count == 0 {
                        (node, first) = (descend(n, near_right, f, &mut stack, &mut sp), f);
                        continue;
                    }
                    let (slots, bmin, bmax) = self.leaf(n, count);
                    for j in f..k {
                        if pending & (1 << j) == 0 || (j != f && !intersect_aabb_x8(bmin, bmax, &pr[j], rs[j].tmax).1.any()) {
                            continue;
                        }
                        for slot in slots.clone() {
                            let occ = leaf(slot, j, &rs[j]) & active[j];
                            if occ.any() {
                                occluded[j] |= occ;
                                rs[j].tmax = occluded[j].select(off, rs[j].tmax);
                                if occluded[j].to_bitmask() == active[j].to_bitmask() {
                                    pending &= !(1 << j);
                                    if pending == 0 {
                                        return occluded;
                                    }
                                    break;
                                }
                            }
                        }
                    }
                }
            }
            if sp == 0 {
                return occluded;
            }
            sp -= 1;
            (node, first) = (stack[sp].0 as usize, stack[sp].1 as usize);
        }
    }
}

impl Bvh {
    /// A leaf's primitive slots (positions in `indices`) and box (`count` = `n.count()`, non-zero).
    #[inline(always)]
    fn leaf(&self, n: &BvhNode, count: usize) -> (std::ops::Range<u32>, Vec3, Vec3) {
        let first = n.left_first;
        (first..first + count as u32, Vec3::from_array(n.min), Vec3::from_array(n.max))
    }
}

/// Push the far child of inner node `n` (with `f`, the group's first packet that hit `n`) and return the
/// near child, by the group's `near_right` bits.
#[inline(always)]
fn descend(n: &BvhNode, near_right: u32, f: usize, stack: &mut [(u32, u8)], sp: &mut usize) -> usize {
    let r = (near_right >> n.axis()) & 1;
    stack[*sp] = (n.left_first + (r ^ 1), f as u8);
    *sp += 1;
    (n.left_first + r) as usize
}

/// Index of the first packet at or after `first` that overlaps the node's box, or `None` when none
/// does (decided by the group's interval test when it can, else by testing the packets in turn).
#[inline(always)]
fn first_hit(n: &BvhNode, pr: &[PacketRay], rays: &[Ray8], first: usize, gb: &GroupBounds, tmax: f32) -> Option<usize> {
    let (bmin, bmax) = (Vec3::from_array(n.min), Vec3::from_array(n.max));
    if intersect_aabb_x8(bmin, bmax, &pr[first], rays[first].tmax).1.any() {
        return Some(first);
    }
    if gb.misses(bmin.into(), bmax.into(), tmax) {
        return None;
    }
    (first + 1..pr.len()).find(|&j| intersect_aabb_x8(bmin, bmax, &pr[j], rays[j].tmax).1.any())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn group(dirs: &[Vec3]) -> Vec<Ray8> {
        dirs.chunks(8)
            .map(|c| {
                let d = Vec3x8::from_rows(&std::array::from_fn(|a| std::array::from_fn(|l| c[l % c.len()][a])));
                Ray8::new(Vec3x8::splat(Vec3::new(1.0, 2.0, 3.0)), d, f32x8::splat(10.0))
            })
            .collect()
    }

    /// One axis with directions of both signs is left out of the bounds (entry -inf, exit +inf: the
    /// other axes still cull); two such axes give no bounds (per-packet fallback).
    #[test]
    fn mixed_axes() {
        let one = group(&[Vec3::new(-0.1, 1.0, 1.0), Vec3::new(0.1, 1.0, 1.0)]);
        let gb = GroupBounds::new(&one).expect("one mixed axis keeps the group");
        // A box in the rays' way, a box anywhere along x but behind them in y, and one far to the side
        // in x (not culled: x bounds nothing).
        assert!(!gb.misses(Vec3A::new(0.0, 4.0, 5.0), Vec3A::new(2.0, 6.0, 7.0), 10.0));
        assert!(gb.misses(Vec3A::new(-1e3, -5.0, 4.0), Vec3A::new(1e3, 0.0, 6.0), 10.0));
        assert!(!gb.misses(Vec3A::new(50.0, 4.0, 5.0), Vec3A::new(60.0, 6.0, 7.0), 10.0));
        let two = group(&[Vec3::new(-0.1, -1.0, 1.0), Vec3::new(0.1, 1.0, 1.0)]);
        assert!(GroupBounds::new(&two).is_none());
        let none = group(&[Vec3::new(0.1, 1.0, 1.0), Vec3::new(0.2, 1.0, 1.0)]);
        assert!(GroupBounds::new(&none).is_some_and(|g| g.o_lo.is_finite() && g.o_hi.is_finite()));
    }
}
