//! Group traversal of the wide BVH: up to [`WIDE_GROUP`] 8-ray packets (256 coherent rays: camera
//! rays of four 8x8 pixel blocks) descend [`WideBvh`] together, deciding each node's children (16 or
//! 8, [`WIDTH`]) by the group's interval test alone.
//!
//! The binary group traversal (`group.rs`) enters a node by one packet's slab test and falls back to
//! the interval test when that packet misses: about 60 instructions per binary node, and a coherent
//! group of 64 camera rays visits ~32 binary nodes; a group of 256 visits ~6 wide nodes of 8 children
//! here. Here the interval test of `GroupBounds` runs on a wide node's children at once, one
//! [`NodeF`] per quantity (the child boxes are rows of `WIDTH` floats): the same
//! operations on the same operands as the scalar test, lane by lane, so its verdicts are the scalar
//! test's, which is conservative against the padded per-lane slab test (see `GroupBounds::misses`).
//! Packets are tested only at leaves: when a wide node enters a leaf child, each packet runs the
//! padded slab test on the leaf's box, and the leaf keeps the mask of packets that passed. Children
//! are pushed far-to-near by their entry bound and skipped when popped after closer hits lowered the
//! group's largest `tmax` below it (by the same verdict: it only culls more as `tmax` falls).
//!
//! Results equal the other traversals' (same `t` bits and primitive ids): a primitive a lane hits at
//! `t` lies in its leaf's box, so the lane passes the padded slab test of that leaf and of every
//! ancestor with any `tmax >= t`, the interval test never culls what a lane passes, and the intersect
//! stage's recording is order-independent.

use super::aabb::{intersect_aabb_x8, PacketRay};
use super::group::{culled, group_tmax, GroupBounds, SLACK};
use super::wide::{NodeF, NodeI, WideBvh, WideNode, WIDTH};
use super::wide_traverse::{pop, push_children_but_nearest, WideStack};
use crate::simd::Ray8;
use glam::Vec3;

/// Packets per group of the wide group traversal. Camera rays of `bench_spheres` (one thread, best of
/// 40, M rays/s): 8 packets 93, 16 packets 97-102, 32 packets 102-103. Larger groups share each node
/// test among more rays; their interval bounds are looser, and each leaf a group enters tests every
/// packet's slab.
pub const WIDE_GROUP: usize = 32;

impl GroupBounds {
    /// [`GroupBounds::misses`] for the children of `n` at once: `(tn, enter)`, the entry bound of each
    /// child and the mask (bit `i` = child `i`) of occupied children the test does not cull.
    #[inline(always)]
    fn children(&self, n: &WideNode, tmax: f32) -> (NodeF, u32) {
        let row = |i: usize| NodeF::from(n.bounds[i]);
        let axis = |a: usize| {
            let (pad, o_lo, o_hi) = (NodeF::splat(self.pad[a]), NodeF::splat(self.o_lo[a]), NodeF::splat(self.o_hi[a]));
            let (inv_lo, inv_hi) = (NodeF::splat(self.inv_lo[a]), NodeF::splat(self.inv_hi[a]));
            let (b0, b1) = if self.neg.test(a) { (-row(a + 3), -row(a)) } else { (row(a), row(a + 3)) };
            let (d0, d1) = (b0 - pad - o_hi, b1 + pad - o_lo);
            ((d0 * inv_lo).fast_min(d0 * inv_hi), (d1 * inv_lo).fast_max(d1 * inv_hi))
        };
        let ((nx, fx), (ny, fy), (nz, fz)) = (axis(0), axis(1), axis(2));
        let tn = nx.fast_max(ny).fast_max(nz).fast_max(NodeF::ZERO);
        let tf = fx.fast_min(fy).fast_min(fz).fast_min(NodeF::splat(tmax));
        let cull = (tn - tf).simd_gt(NodeF::splat(SLACK) * (tn.abs() + tf.abs()) + NodeF::splat(f32::MIN_POSITIVE));
        // Empty slots (min = +inf, max = -inf) give tn = +inf, tf = -inf (NaN on a mixed axis, whose
        // origins are infinite), which the verdict's arithmetic does not cull: they are excluded by
        // their box.
        let occupied = row(0).simd_le(row(3));
        (tn, (!cull & occupied).to_bitmask())
    }
}

impl WideBvh {
    /// Closest-hit traversal of up to [`WIDE_GROUP`] packets together (see the module doc). `leaf(slot, j,
    /// &mut rays[j])` has the contract of [`WideBvh::traverse_closest_x8`]'s callback (a primitive's
    /// slot in `indices`), for packet `j`. A group without `GroupBounds` (directions of both signs on
    /// two axes) is traversed packet by packet ([`WideBvh::traverse_closest_x8`]).
    // Out of line (one call per group): inlined into the intersect stage, which one codegen partition
    // did, it measured 3-9% slower (session 29).
    #[inline(never)]
    pub fn traverse_closest_group(&self, rays: &mut [Ray8], stack: &mut WideStack, mut leaf: impl FnMut(u32, usize, &mut Ray8)) {
        assert!(rays.len() <= WIDE_GROUP, "at most {WIDE_GROUP} packets per group");
        if self.nodes.is_empty() || rays.is_empty() {
            return;
        }
        let Some(gb) = GroupBounds::new(rays) else {
            for (j, r) in rays.iter_mut().enumerate() {
                self.traverse_closest_x8(r, stack, |p, r| leaf(p, j, r));
            }
            return;
        };
        let k = rays.len();
        // The packets' slab constants, made when the group first reaches a leaf: a group that reaches
        // none (sky, or ground in front of every box) makes only packet 0's.
        let mut pr = [PacketRay::new(&rays[0]); WIDE_GROUP];
        let mut ready = k == 1;
        let mut tmax = group_tmax(rays);
        let all = u32::MAX >> (u32::BITS as usize - k);
        let stack = &mut stack.0[..];
        let mut sp = 0usize;
        let mut node = 0usize;
        loop {
            let n = &self.nodes[node];
            let (tn, mut enter) = gb.children(n, tmax);
            // Leaf children: the packets that pass the slab test of the leaf's box.
            let mut packets = [0u32; WIDTH];
            let mut leaves = enter & leaf_slots(n);
            while leaves != 0 {
                let i = leaves.trailing_zeros() as usize;
                leaves &= leaves - 1;
                if !ready {
                    for j in 1..k {
                        pr[j] = PacketRay::new(&rays[j]);
                    }
                    ready = true;
                }
                packets[i] = packets_entering(n, i, &pr[..k], rays, all);
                if packets[i] == 0 {
                    enter &= !(1 << i);
                }
            }
            let mut nearest = push_children_but_nearest(n, tn, enter, |i| packets[i], stack, &mut sp);
            loop {
                let Some(e) = pop(&mut nearest, stack, &mut sp) else {
                    return;
                };
                // Culled with tmax then, or now that closer hits lowered it.
                if culled(e.tn, tmax) {
                    continue;
                }
                if e.count == 0 {
                    node = e.child as usize;
                    break;
                }
                let mut bits = e.lanes;
                while bits != 0 {
                    let j = bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    for slot in e.child..e.child + e.count {
                        leaf(slot, j, &mut rays[j]);
                    }
                }
                tmax = group_tmax(&rays[..k]);
            }
        }
    }
}

/// Slots of `n` that hold a leaf (bit `i` = slot `i`).
#[inline(always)]
fn leaf_slots(n: &WideNode) -> u32 {
    let c = NodeI::from(bytemuck::cast::<[u32; WIDTH], [i32; WIDTH]>(n.count));
    (!c.simd_eq(NodeI::ZERO)).to_bitmask() as u32
}

/// The packets among `among` (bit `j` = packet `j`) that pass the padded slab test of child `i`'s box.
#[inline(always)]
fn packets_entering(n: &WideNode, i: usize, pr: &[PacketRay], rays: &[Ray8], among: u32) -> u32 {
    let b = &n.bounds;
    let (bmin, bmax) = (Vec3::new(b[0][i], b[1][i], b[2][i]), Vec3::new(b[3][i], b[4][i], b[5][i]));
    let mut out = 0;
    let mut bits = among;
    while bits != 0 {
        let j = bits.trailing_zeros() as usize;
        bits &= bits - 1;
        out |= (intersect_aabb_x8(bmin, bmax, &pr[j], rays[j].tmax).1.any() as u32) << j;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::{f32x8, Vec3x8};
    use glam::Vec3A;

    /// The 8-child interval test gives, child by child, the scalar test's verdict (`misses`): random
    /// groups (clustered or spread origins, every octant, one axis with both signs) against random wide nodes (boxes near,
    /// around and behind the group, thin and huge ones, empty slots), finite and infinite `tmax`.
    #[test]
    fn children_verdicts_equal_the_scalar_test() {
        let mut f = crate::sample::hash::test_uniforms(0x5eed_0fc4_11d5);
        let (mut compared, mut entered, mut culled_count) = (0usize, 0usize, 0usize);
        for round in 0..3000 {
            let scale = [1e-3f32, 1.0, 1e4][round % 3];
            let signs = Vec3::new([1.0, -1.0][round & 1], [1.0, -1.0][(round >> 1) & 1], [1.0, -1.0][(round >> 2) & 1]);
            let eye = Vec3::new(f() - 0.5, f() - 0.5, f() - 0.5) * 20.0 * scale;
            let spread = [0.0, 0.01, 1.0][(round / 3) % 3] * scale;
            let rays: Vec<Ray8> = (0..4)
                .map(|_| {
                    let o = Vec3x8::new(
                        f32x8::from(std::array::from_fn(|_| eye.x + (f() - 0.5) * spread)),
                        f32x8::from(std::array::from_fn(|_| eye.y + (f() - 0.5) * spread)),
                        f32x8::from(std::array::from_fn(|_| eye.z + (f() - 0.5) * spread)),
                    );
                    // Every fifth group has directions of both signs on one axis.
                    let mixed = (round % 5 == 4).then_some((round / 5) % 3);
                    let mut dir = |a: usize, s: f32| {
                        f32x8::from(std::array::from_fn(|l| {
                            if mixed == Some(a) {
                                [1.0, -1.0][l % 2] * (0.05 + f())
                            } else {
                                s * (0.05 + f())
                            }
                        }))
                    };
                    Ray8::new(o, Vec3x8::new(dir(0, signs.x), dir(1, signs.y), dir(2, signs.z)), f32x8::splat(1.0))
                })
                .collect();
            let gb = GroupBounds::new(&rays).expect("one octant, or one mixed axis");
            let mut n = WideNode::EMPTY;
            for i in 0..(1 + round % WIDTH) {
                let c = Vec3::new(f() - 0.5, f() - 0.5, f() - 0.5) * 40.0 * scale;
                let h = Vec3::new(f(), f(), f()) * [0.0, 1.0, 10.0][i % 3] * scale;
                for a in 0..3 {
                    n.bounds[a][i] = c[a] - h[a];
                    n.bounds[a + 3][i] = c[a] + h[a];
                }
            }
            let tmax = [f32::INFINITY, 30.0 * scale, 3.0 * scale][round % 3];
            let (_, enter) = gb.children(&n, tmax);
            for i in 0..WIDTH {
                let b = n.child_aabb(i);
                let want = !b.is_empty() && !gb.misses(Vec3A::from(b.min), Vec3A::from(b.max), tmax);
                assert_eq!(enter & (1 << i) != 0, want, "round {round} child {i}: {b:?}, tmax {tmax}");
                compared += 1;
                entered += want as usize;
                culled_count += (!b.is_empty() && !want) as usize;
            }
        }
        assert!(compared == 3000 * WIDTH && entered > 1000 && culled_count > 1000, "{entered} entered, {culled_count} culled");
    }
}
