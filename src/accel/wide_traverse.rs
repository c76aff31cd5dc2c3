//! Traversal of the wide BVH ([`WideBvh`], [`WIDTH`] = 16 or 8 children per node): 8-ray packets
//! whose lanes each test a node's children at once (the intersect stage's traversal of incoherent
//! rays), and one ray at a time (closest and any hit).
//!
//! Node test: one ray against the node's child boxes, one [`NodeF`] (`f32x16` or `f32x8`) per plane
//! (Wald, Benthin & Boulos 2008,
//! "Getting Rid of Packets"; Embree's single-ray kernels). The per-ray constants are the packet test's
//! ([`PacketRay`]: every lane of it holds that lane's ray's constants bit for bit), and each plane
//! distance is the same FMA with the same operands as in
//! [`intersect_aabb_x8`](super::aabb::intersect_aabb_x8). The one difference:
//! the packet test sorts a slab's two distances with min/max, the single-ray test takes the near plane
//! by the ray's direction sign (the min plane where `PacketRay`'s clamped `inv_d >= 0`, so a zero
//! component counts with the sign of its zero, as there). The two agree whenever the padded distances
//! are in order (near <= far). They are out of order only when the relative padding of `inv_d` exceeds
//! the slab's width, which needs the slab to lie behind the origin on that axis (`(min + max) / 2 < o`
//! for a positive direction); the near-plane value is then a negative far distance for the packet
//! test, which misses as the single-ray test does (`tests/wide_bvh.rs` compares the two masks and
//! entry distances bit for bit on random, flat and one-ulp boxes, at scales 1e-4 to 1e4). The octant
//! is a const parameter of the kernel (`slab8`), so the bounds rows are fixed offsets.
//!
//! Knowing the near plane is also what makes an empty slot (min = +inf, max = -inf) miss: its near
//! distance is +inf, its far distance -inf, and no NaN arises (`inf * inv + c` with `inv` finite and
//! non-zero, `c` finite).
//!
//! Children that pass are pushed far-to-near, so the nearest is popped first; each entry keeps its
//! entry distance and is skipped when popped after a closer hit lowered `tmax` below it (the box test
//! with the new `tmax` would fail too). The order is computed without branches: a child's stack
//! position is the number of hit children farther than it (ties: the higher slot is farther).
//!
//! The stack is caller-owned scratch ([`WideStack`]): it has room for the worst case, `(WIDTH - 1) *
//! MAX_DEPTH + 1` entries (7 KiB at 8 children, 15 at 16), and zeroing a local array that size on
//! each call cost about 30% of the single-ray time (140 -> 97 ns/ray) and 10% of the packet time (62
//! -> 55 ns/ray).
//!
//! Packet variants measured (single thread, best of 9, secondary rays of the intersect benchmark,
//! traversal with the bare sphere kernel at the leaves; binary packets 53 ns/ray, groups 54):
//!
//! | packet traversal of the wide BVH                                          | ns/ray |
//! |---------------------------------------------------------------------------|--------|
//! | each child box tested with the packet (8 x 8-lane tests, horizontal min)  | 65     |
//! | each lane tests the 8 children, lanes of the entry only (kept)            | 55     |
//! | the same, all 8 lanes every node (no data-dependent loop)                 | 73     |
//! | kept, with the SAH collapse instead of the greedy one                     | 52.5   |
//! | one ray at a time (single-ray traversal)                                  | 108    |

use glam::Vec3;

use super::aabb::PacketRay;
use super::wide::{NodeF, WideBvh, WideNode, WIDTH};
use super::MAX_DEPTH;
use crate::simd::{f32x8, i32x8, Ray8, Vec3x8};

/// Stack entries of wide traversal: a wide node is no deeper than the binary node it collapses (each
/// wide level consumes at least one binary level, so depth <= [`MAX_DEPTH`]), and visiting it leaves at
/// most `WIDTH - 1` more entries pending.
const STACK: usize = (WIDTH - 1) * MAX_DEPTH + 1;

/// Live lanes at or below which [`WideBvh::occluded_lanes_hybrid`] leaves a node to one-ray traversals.
pub const SWITCH_LANES: usize = 2;

/// A pending child: its slot fields (`count` 0: an inner node), the smallest entry distance over the
/// lanes that entered it, and those lanes (bit `l` = lane `l`; bit 0 for a single ray).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Entry {
    pub(super) child: u32,
    pub(super) count: u32,
    pub(super) tn: f32,
    pub(super) lanes: u32,
}

/// Caller-owned traversal stack of [`WideBvh`], reused across traversals (see the module doc).
#[derive(Clone, Debug)]
pub struct WideStack(pub(super) Vec<Entry>);

impl Default for WideStack {
    fn default() -> Self {
        // (WIDTH more: at 8 children the one-ray any-hit writes all of a node's slots past the top. The second half:
        // the packet stack of `WideBvh::occluded_lanes_hybrid`, which never holds more entries.)
        Self(vec![Entry::default(); 2 * (STACK + WIDTH)])
    }
}

/// The folded slab constants of one ray per axis, splatted: `(inv, c)` of the near plane and of the
/// far plane.
#[derive(Clone, Copy, Debug)]
struct Slab {
    inv_n: [NodeF; 3],
    c_n: [NodeF; 3],
    inv_f: [NodeF; 3],
    c_f: [NodeF; 3],
}

/// Distances of one ray to the child boxes of `n`: `(tnear, hit)`, `tnear = max(0, near planes)`,
/// `hit` where `tnear <= min(far planes, tmax)`. Bit `a` of `OCT` is set when the ray's direction is
/// negative on axis `a` (near plane = the box max).
#[inline(always)]
fn slab8<const OCT: usize>(n: &WideNode, s: &Slab, tmax: NodeF) -> (NodeF, NodeF) {
    let row = |i: usize| NodeF::from(n.bounds[i]);
    let d = |a: usize| {
        let neg = (OCT >> a) & 1 == 1;
        let (near, far) = if neg { (a + 3, a) } else { (a, a + 3) };
        (row(near).mul_add(s.inv_n[a], s.c_n[a]), row(far).mul_add(s.inv_f[a], s.c_f[a]))
    };
    let ((nx, fx), (ny, fy), (nz, fz)) = (d(0), d(1), d(2));
    let tn = nx.fast_max(ny).fast_max(nz.fast_max(NodeF::ZERO));
    let tf = fx.fast_min(fy).fast_min(fz.fast_min(tmax));
    (tn, tn.simd_le(tf))
}

/// [`slab8`] for a run-time octant (a predictable branch: a ray's octant never changes, and an
/// octant-sorted packet's lanes share one).
#[inline(always)]
fn slab8_oct(oct: u32, n: &WideNode, s: &Slab, tmax: NodeF) -> (NodeF, NodeF) {
    match oct & 7 {
        0 => slab8::<0>(n, s, tmax),
        1 => slab8::<1>(n, s, tmax),
        2 => slab8::<2>(n, s, tmax),
        3 => slab8::<3>(n, s, tmax),
        4 => slab8::<4>(n, s, tmax),
        5 => slab8::<5>(n, s, tmax),
        6 => slab8::<6>(n, s, tmax),
        _ => slab8::<7>(n, s, tmax),
    }
}

/// The slab constants of the 8 rays of a packet (lane `l` of each vector is ray `l`'s), with each lane's
/// octant bits.
#[derive(Clone, Copy, Debug)]
struct LaneSlabs {
    oct: [u32; 8],
    inv_n: [[f32; 8]; 3],
    c_n: [[f32; 8]; 3],
    inv_f: [[f32; 8]; 3],
    c_f: [[f32; 8]; 3],
}

impl LaneSlabs {
    #[inline(always)]
    fn new(ray: &Ray8) -> Self {
        let pr = PacketRay::new(ray);
        let ax = |v: Vec3x8| [v.x, v.y, v.z];
        let (il, cl, ih, ch) = (ax(pr.inv_lo), ax(pr.c_lo), ax(pr.inv_hi), ax(pr.c_hi));
        let mut r = Self { oct: [0; 8], inv_n: [[0.0; 8]; 3], c_n: [[0.0; 8]; 3], inv_f: [[0.0; 8]; 3], c_f: [[0.0; 8]; 3] };
        let mut neg = i32x8::ZERO;
        for a in 0..3 {
            // `PacketRay` takes the min plane as the near one exactly where its clamped inv_d >= 0; the
            // scaled `inv_lo` keeps that sign (it is never 0 for a finite direction).
            let pos = il[a].simd_ge(f32x8::ZERO);
            r.inv_n[a] = pos.select(il[a], ih[a]).to_array();
            r.c_n[a] = pos.select(cl[a], ch[a]).to_array();
            r.inv_f[a] = pos.select(ih[a], il[a]).to_array();
            r.c_f[a] = pos.select(ch[a], cl[a]).to_array();
            neg |= !bytemuck::cast::<f32x8, i32x8>(pos) & i32x8::splat(1 << a);
        }
        r.oct = bytemuck::cast(neg.to_array());
        r
    }

    /// Lane `l`'s constants, splatted.
    #[inline(always)]
    fn lane(&self, l: usize) -> Slab {
        let s = |v: &[[f32; 8]; 3]| [NodeF::splat(v[0][l]), NodeF::splat(v[1][l]), NodeF::splat(v[2][l])];
        Slab { inv_n: s(&self.inv_n), c_n: s(&self.c_n), inv_f: s(&self.inv_f), c_f: s(&self.c_f) }
    }
}

/// Transpose an 8x8 bit matrix held row by row in the bytes of `x` (row `r` in byte `r`, column `c` in
/// bit `c` of it): Hacker's Delight, 2nd ed., 7-3 ("transpose8"), stated there for the layout mirrored
/// on both axes, which commutes with transposition.
#[inline(always)]
pub fn transpose8x8(mut x: u64) -> u64 {
    let t = (x ^ (x >> 7)) & 0x00AA_00AA_00AA_00AA;
    x ^= t ^ (t << 7);
    let t = (x ^ (x >> 14)) & 0x0000_CCCC_0000_CCCC;
    x ^= t ^ (t << 14);
    let t = (x ^ (x >> 28)) & 0x0000_0000_F0F0_F0F0;
    x ^ t ^ (t << 28)
}

/// Push the children of `n` in `hit` (bit `i` = child `i`), farthest (by `key`, the entry distance)
/// deepest, so that the nearest is on top; `lanes(i)` gives child `i`'s lane mask. (An entry distance
/// can be +inf, for a box beyond the f32 range that a ray with `tmax = inf` enters: it is pushed last.)
#[inline(always)]
pub(super) fn push_children(n: &WideNode, key: NodeF, hit: u32, lanes: impl Fn(usize) -> u32, stack: &mut [Entry], sp: &mut usize) {
    if let Some(e) = push_children_but_nearest(n, key, hit, lanes, stack, sp) {
        stack[*sp] = e;
        *sp += 1;
    }
}

/// [`push_children`], except that the nearest child (the one that would be on top) is returned
/// instead of pushed: the traversal goes on with it at once, without a store and a load through the
/// stack. `None` when no child is hit.
#[inline(always)]
pub(super) fn push_children_but_nearest(
    n: &WideNode,
    key: NodeF,
    hit: u32,
    lanes: impl Fn(usize) -> u32,
    stack: &mut [Entry],
    sp: &mut usize,
) -> Option<Entry> {
    let ka = key.to_array();
    let top = hit.count_ones() as usize;
    let mut nearest = None;
    let mut bits = hit;
    while bits != 0 {
        let i = bits.trailing_zeros() as usize;
        bits &= bits - 1;
        let k = NodeF::splat(ka[i]);
        let higher = !((2u32 << i) - 1);
        let farther = ((key.simd_gt(k).to_bitmask() | (key.simd_eq(k).to_bitmask() & higher)) & hit).count_ones() as usize;
        let e = Entry { child: n.child[i], count: n.count[i], tn: ka[i], lanes: lanes(i) };
        if farther + 1 == top {
            nearest = Some(e);
        } else {
            stack[*sp + farther] = e;
        }
    }
    *sp += top.saturating_sub(1);
    nearest
}

/// The next entry of a traversal: `nearest` (the child [`push_children_but_nearest`] held back) if
/// any, else the top of the stack; `None` when both are empty.
#[inline(always)]
pub(super) fn pop(nearest: &mut Option<Entry>, stack: &[Entry], sp: &mut usize) -> Option<Entry> {
    if let Some(e) = nearest.take() {
        return Some(e);
    }
    if *sp == 0 {
        return None;
    }
    *sp -= 1;
    Some(stack[*sp])
}

/// Each child's lanes: the transposed lane-by-child hit matrix of [`lanes_children`], 8 children per
/// word (lane `l`'s bit of child `i` is bit `8 * (i % 8) + l` of word `i / 8`).
#[derive(Clone, Copy)]
struct ChildLanes([u64; WIDTH / 8]);

impl ChildLanes {
    /// The lanes (bit `l` = lane `l`) that enter child `i`.
    #[inline(always)]
    fn lanes(&self, i: usize) -> u32 {
        ((self.0[i / 8] >> (8 * (i % 8))) & 0xff) as u32
    }
}

/// The lanes `lanes` of a packet (slab constants `ls`, `tmax` per lane) each against the children of
/// `n` with the one-ray node test, independent of each other (so they overlap): the children some lane
/// enters (bit `i` = child `i`) and each child's lanes. `per_lane(tn, hit)` sees each lane's entry
/// distances and hit mask (the closest-hit traversal takes its children's keys from them).
#[inline(always)]
fn lanes_children(n: &WideNode, ls: &LaneSlabs, tmax: &[f32; 8], lanes: u32, mut per_lane: impl FnMut(NodeF, NodeF)) -> (u32, ChildLanes) {
    // Lane l's child mask in byte l of one word per 8 children, then transposed.
    let (mut by_lane, mut any, mut rest) = ([0u64; WIDTH / 8], 0u32, lanes);
    while rest != 0 {
        let l = rest.trailing_zeros() as usize;
        rest &= rest - 1;
        let (tn, hit) = slab8_oct(ls.oct[l], n, &ls.lane(l), NodeF::splat(tmax[l]));
        per_lane(tn, hit);
        let bits = hit.to_bitmask();
        any |= bits;
        for (g, row) in by_lane.iter_mut().enumerate() {
            *row |= (((bits >> (8 * g)) & 0xff) as u64) << (8 * l);
        }
    }
    (any, ChildLanes(by_lane.map(transpose8x8)))
}

/// Ray `lane` of `ray` against the children of `n` with the single-ray kernel the traversals use:
/// `(tnear, hit bits)`, bit `i` for child `i` (tnear of missed children is unspecified). Against
/// [`intersect_aabb_x8`](super::aabb::intersect_aabb_x8) in `tests/wide_bvh.rs`.
pub fn intersect_children_single(n: &WideNode, ray: &Ray8, lane: usize) -> (NodeF, u32) {
    let ls = LaneSlabs::new(ray);
    let (tn, hit) = slab8_oct(ls.oct[lane], n, &ls.lane(lane), NodeF::splat(ray.tmax.to_array()[lane]));
    (tn, hit.to_bitmask())
}

/// A packet whose 8 lanes are the one ray `(o, d)` (`inv_d = 1 / d` as [`Ray8::new`] computes it).
#[inline(always)]
fn splat_ray(o: Vec3, d: Vec3, tmax: f32) -> Ray8 {
    Ray8::new(Vec3x8::splat(o), Vec3x8::splat(d), f32x8::splat(tmax))
}

impl WideBvh {
    /// Closest-hit traversal of one ray. `leaf(slot, &mut tmax)` is called for each primitive of each
    /// visited leaf (`slot`: its position in `indices`, which holds the primitive); it lowers `tmax`
    /// when the primitive is hit nearer (the caller records which).
    /// Children whose box the ray's padded slab interval does not overlap within `[0, tmax]` are
    /// skipped, as the packet test decides for this ray's lane (see the module doc). Nothing happens
    /// when `tmax < 0` (an inactive ray).
    ///
    /// Not used by the intersect stage (`wavefront::intersect::INCOHERENT` has the measurement: its
    /// octant-sorted packets share node tests and leaf calls that a lone ray pays alone).
    pub fn traverse_closest_single(&self, o: Vec3, d: Vec3, tmax: f32, stack: &mut WideStack, mut leaf: impl FnMut(u32, &mut f32)) {
        let mut tmax = tmax;
        if self.nodes.is_empty() || !(tmax >= 0.0) {
            return;
        }
        let ls = LaneSlabs::new(&splat_ray(o, d, tmax));
        let (s, oct) = (ls.lane(0), ls.oct[0]);
        let stack = &mut stack.0[..];
        let mut sp = 0usize;
        let mut node = 0usize;
        loop {
            let n = &self.nodes[node];
            let (tn, hit) = slab8_oct(oct, n, &s, NodeF::splat(tmax));
            push_children(n, tn, hit.to_bitmask(), |_| 1, stack, &mut sp);
            loop {
                if sp == 0 {
                    return;
                }
                sp -= 1;
                let e = stack[sp];
                if e.tn > tmax {
                    continue;
                }
                if e.count == 0 {
                    node = e.child as usize;
                    break;
                }
                for slot in e.child..e.child + e.count {
                    leaf(slot, &mut tmax);
                }
            }
        }
    }

    /// Any-hit (occlusion) traversal of one ray: true as soon as `leaf(prim, tmax)` returns true
    /// ([`WideBvh::occluded_lanes`] with the ray in one lane). Nothing is visited when `tmax <= 0` (the
    /// packet any-hit convention).
    pub fn traverse_any_single(&self, o: Vec3, d: Vec3, tmax: f32, stack: &mut WideStack, mut leaf: impl FnMut(u32, f32) -> bool) -> bool {
        let ray = splat_ray(o, d, tmax);
        let hit = self.occluded_lanes(&ray, 1, stack, |_, first, count| self.indices[first..first + count].iter().any(|&p| leaf(p, tmax)));
        hit != 0
    }

    /// Any-hit traversal of the lanes `lanes` of a packet, one ray at a time (for incoherent shadow
    /// rays, whose lanes share few nodes): lane `l` as [`WideBvh::traverse_any_single`] would traverse
    /// that ray, with the packet's slab constants. `leaf(l, first, count)` tests lane `l` against the
    /// leaf's primitives `indices[first..first + count]` and returns whether one occludes it; the lane
    /// stops at the first that does. Returns the occluded lanes.
    pub fn occluded_lanes(&self, ray: &Ray8, lanes: u32, stack: &mut WideStack, mut leaf: impl FnMut(usize, usize, usize) -> bool) -> u32 {
        if self.nodes.is_empty() {
            return 0;
        }
        let live = lanes & ray.tmax.simd_gt(f32x8::ZERO).to_bitmask();
        self.occluded_each(0, live, &LaneSlabs::new(ray), &ray.tmax.to_array(), &mut stack.0[..STACK + WIDTH], &mut leaf)
    }

    /// [`WideBvh::occluded_lanes`] starting with the packet: from the root, the packet's live lanes
    /// each test a node's children with the one-ray node test (as [`WideBvh::traverse_closest_x8`]
    /// does: the lanes' tests are independent of each other, so they overlap), and a child is entered
    /// by the lanes that pass; a node reached by at most `SWITCH_LANES` lanes is left to one-ray
    /// traversals of its subtree, one per lane. Rays towards one light from nearby points share the
    /// nodes near the root: there the lanes' node tests overlap where one ray at a time pays a chain of
    /// dependent node visits per lane (Embree's hybrid traversal, Benthin et al. 2012, "Combining
    /// single and packet ray tracing for arbitrary ray distributions on the Intel MIC architecture",
    /// switches the same way). Every lane's verdict at every node is the one-ray test's, and leaves
    /// call `leaf` per lane as the one-ray traversal does, so the occluded lanes are
    /// [`WideBvh::occluded_lanes`]'.
    ///
    /// Session 22 tested each child with the packet's slab test (`intersect_aabb_x8`, one child at a
    /// time for all lanes); at 16 children per node that is 16 tests per node where the lanes' own tests
    /// are as many as the live lanes: scattered shadow rays of peer scene (b) 14.5-15.0 -> 17.8-18.1 M
    /// rays/s on one thread (session 23).
    pub fn occluded_lanes_hybrid(
        &self,
        ray: &Ray8,
        lanes: u32,
        stack: &mut WideStack,
        mut leaf: impl FnMut(usize, usize, usize) -> bool,
    ) -> u32 {
        if self.nodes.is_empty() {
            return 0;
        }
        let live = lanes & ray.tmax.simd_gt(f32x8::ZERO).to_bitmask();
        if live.count_ones() as usize <= SWITCH_LANES {
            return self.occluded_lanes(ray, live, stack, leaf);
        }
        let (ls, tmax) = (LaneSlabs::new(ray), ray.tmax.to_array());
        let (single, packet) = stack.0.split_at_mut(STACK + WIDTH);
        let (mut occluded, mut psp) = (0u32, 1usize);
        packet[0] = Entry { child: 0, count: 0, tn: 0.0, lanes: live };
        while psp > 0 {
            psp -= 1;
            let e = packet[psp];
            let m = e.lanes & !occluded;
            if m.count_ones() as usize <= SWITCH_LANES {
                occluded |= self.occluded_each(e.child as usize, m, &ls, &tmax, single, &mut leaf);
                continue;
            }
            let n = &self.nodes[e.child as usize];
            // Each live lane's children with the one-ray node test (lanes independent of each
            // other), then each child's lanes.
            let (mut any, by_child) = lanes_children(n, &ls, &tmax, m, |_, _| {});
            while any != 0 {
                let i = any.trailing_zeros() as usize;
                any &= any - 1;
                let hit = by_child.lanes(i) & !occluded;
                if hit == 0 {
                    continue;
                }
                if n.count[i] == 0 {
                    packet[psp] = Entry { child: n.child[i], count: 0, tn: 0.0, lanes: hit };
                    psp += 1;
                    continue;
                }
                let mut rest = hit;
                while rest != 0 {
                    let l = rest.trailing_zeros() as usize;
                    rest &= rest - 1;
                    if leaf(l, n.child[i] as usize, n.count[i] as usize) {
                        occluded |= 1 << l;
                    }
                }
            }
        }
        occluded
    }

    /// The lanes `lanes` (each with `tmax` > 0) one at a time through the subtree of node `start`
    /// ([`WideBvh::occluded_from`] per lane): the occluded ones.
    #[inline(always)]
    fn occluded_each(
        &self,
        start: usize,
        lanes: u32,
        ls: &LaneSlabs,
        tmax: &[f32; 8],
        stack: &mut [Entry],
        leaf: &mut impl FnMut(usize, usize, usize) -> bool,
    ) -> u32 {
        let (mut occluded, mut rest) = (0, lanes);
        while rest != 0 {
            let l = rest.trailing_zeros() as usize;
            rest &= rest - 1;
            if self.occluded_from(start, l, ls, tmax[l], stack, leaf) {
                occluded |= 1 << l;
            }
        }
        occluded
    }

    /// Lane `l` of the packet whose slab constants are `ls` (its `tmax` > 0), one ray at a time through
    /// the subtree of node `start` (see [`WideBvh::occluded_lanes`]): whether a leaf's `leaf` call found
    /// it occluded.
    #[inline(always)]
    fn occluded_from(
        &self,
        start: usize,
        l: usize,
        ls: &LaneSlabs,
        tmax: f32,
        stack: &mut [Entry],
        leaf: &mut impl FnMut(usize, usize, usize) -> bool,
    ) -> bool {
        let (s, oct, tm) = (ls.lane(l), ls.oct[l], NodeF::splat(tmax));
        let mut sp = 0usize;
        let mut node = start;
        loop {
            let n = &self.nodes[node];
            let (_, hit) = slab8_oct(oct, n, &s, tm);
            // Any hit ends the lane, so the order of the children does not matter: with 8 children all
            // slots are written and the hit ones kept, without a branch per child.
            let hit = hit.to_bitmask();
            if WIDTH <= 8 {
                for i in 0..WIDTH {
                    stack[sp] = Entry { child: n.child[i], count: n.count[i], tn: 0.0, lanes: 1 };
                    sp += ((hit >> i) & 1) as usize;
                }
            } else {
                // 16 slots: writing them all cost more than a loop over the hit ones (scattered
                // shadow rays of peer scene (b), session 23).
                let mut bits = hit;
                while bits != 0 {
                    let i = bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    stack[sp] = Entry { child: n.child[i], count: n.count[i], tn: 0.0, lanes: 1 };
                    sp += 1;
                }
            }
            // The last child pushed (the highest hit slot) is taken from the node, not back from
            // the stack (no store-to-load round trip on the way down).
            let mut top = (hit != 0).then(|| {
                let i = 31 - hit.leading_zeros() as usize;
                sp -= 1;
                (n.child[i], n.count[i])
            });
            loop {
                let (child, count) = match top.take() {
                    Some(c) => c,
                    None if sp == 0 => return false,
                    None => {
                        sp -= 1;
                        (stack[sp].child, stack[sp].count)
                    }
                };
                if count == 0 {
                    node = child as usize;
                    break;
                }
                if leaf(l, child as usize, count as usize) {
                    return true;
                }
            }
        }
    }

    /// Closest-hit traversal of an 8-ray packet in which each lane tests a node's children with one
    /// single-ray test, and only the lanes that entered a child test that child's children: every stack
    /// entry carries its lane mask ([`transpose8x8`], per 8 children, turns the lanes' child masks into
    /// the children's lane masks). Children are pushed near-first by the smallest entry distance over their lanes; a
    /// popped entry keeps only the lanes whose `tmax` still reaches that distance. Leaves test the whole
    /// packet. The callback contract is [`super::Bvh::traverse_closest_x8`]'s (lanes with `tmax < 0`
    /// are inactive), except that it is given each primitive's slot, its position in `indices` (leaf
    /// data kept in slot order, `scene::LeafSpheres`, is then read in order).
    pub fn traverse_closest_x8(&self, ray: &mut Ray8, stack: &mut WideStack, mut leaf: impl FnMut(u32, &mut Ray8)) {
        let active = ray.tmax.simd_ge(f32x8::ZERO).to_bitmask();
        if self.nodes.is_empty() || active == 0 {
            return;
        }
        let ls = LaneSlabs::new(ray);
        let inf = NodeF::splat(f32::INFINITY);
        let mut tm = ray.tmax.to_array();
        let stack = &mut stack.0[..];
        let mut sp = 0usize;
        let (mut node, mut lanes) = (0usize, active);
        loop {
            let n = &self.nodes[node];
            // key: each child's smallest entry distance over the lanes that enter it; m: lane l's child
            // mask in byte l; any: the children some lane enters.
            let mut key = inf;
            let (any, by_child) = lanes_children(n, &ls, &tm, lanes, |tn, hit| key = key.fast_min(hit.select(tn, inf)));
            let mut nearest = push_children_but_nearest(n, key, any, |i| by_child.lanes(i), stack, &mut sp);
            loop {
                let Some(e) = pop(&mut nearest, stack, &mut sp) else {
                    return;
                };
                // Lanes whose tmax fell below the smallest entry distance cannot enter any more.
                let live = f32x8::splat(e.tn).simd_le(ray.tmax).to_bitmask() & e.lanes;
                if live == 0 {
                    continue;
                }
                if e.count == 0 {
                    (node, lanes) = (e.child as usize, live);
                    break;
                }
                for slot in e.child..e.child + e.count {
                    leaf(slot, ray);
                }
                tm = ray.tmax.to_array();
            }
        }
    }
}
