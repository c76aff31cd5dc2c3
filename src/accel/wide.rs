//! The 8-wide BVH: [`Bvh8`], collapsed from the binary [`Bvh`], with single-ray and packet traversal.
//!
//! Collapse after Wald, Benthin & Boulos 2008 ("Getting Rid of Packets: Efficient SIMD Single-Ray
//! Traversal using Multi-branching BVHs"): each wide node takes the two children of a binary inner node
//! and, greedily, replaces the inner child of largest surface area by its two children until it holds 8
//! children or only leaves. Binary leaves stay leaves and keep their `indices` ranges, so a primitive id
//! met at a wide leaf is the one the binary tree would report; the child boxes are the binary nodes'
//! boxes, bit for bit.
//!
//! Node test: one ray against the 8 child boxes with one `f32x8` per plane (Embree's "single ray" mode).
//! The per-ray constants are those of the packet test ([`PacketRay`], built from a splatted packet, so
//! every lane holds this ray's constants bit for bit), and each plane distance is the same FMA as in
//! [`intersect_aabb_x8`]. The one difference: the packet test sorts each slab's two distances with
//! min/max, the single-ray test knows the ray's direction signs and takes the near plane directly (min
//! plane where `inv_d >= 0`, as `PacketRay` decides it). The two agree whenever the padded distances are
//! in order (near <= far); they can be out of order only when the slab lies behind the origin on that
//! axis (the relative padding then narrows the interval), where both tests miss: the packet test's far
//! distance is then negative (`tests/wide_bvh.rs` compares the two masks on random boxes). Knowing the
//! near plane is also what makes an empty slot (min = +inf, max = -inf) miss: its near distance is
//! +inf and its far distance -inf, with no NaN (`inf * inv + c` with finite, non-zero `inv` and `c`).
//!
//! Children that pass are pushed on a fixed stack far-to-near (insertion sort on the entry distance), so
//! the nearest is popped first; each entry keeps its entry distance and is skipped when popped after a
//! closer hit lowered `tmax` below it (the same decision as re-testing its box).

use glam::Vec3;

use super::aabb::{intersect_aabb_x8, PacketRay};
use super::{Aabb, Bvh, MAX_DEPTH};
use crate::simd::{f32x8, Ray8, Vec3x8};
use bytemuck::{Pod, Zeroable};

/// Children per wide node.
pub const WIDTH: usize = 8;

/// Stack entries of wide traversal: a wide node is no deeper than the binary node it collapses (each
/// wide level consumes at least one binary level, so depth <= [`MAX_DEPTH`]), and visiting it leaves at
/// most `WIDTH - 1` more entries pending.
const STACK: usize = (WIDTH - 1) * MAX_DEPTH + 1;

/// One wide node: `repr(C, align(64))`, `Pod`, 256 bytes (4 cache lines), no padding.
///
/// | bytes    | field    | content                                                                    |
/// |----------|----------|----------------------------------------------------------------------------|
/// | 0..192   | `bounds` | 6 rows of 8 f32: child box min x, min y, min z, max x, max y, max z        |
/// | 192..224 | `child`  | per child: inner: index of its wide node; leaf: first slot in `indices`    |
/// | 224..256 | `count`  | per child: leaf: primitive count (>= 1); inner or empty slot: 0            |
///
/// Children fill slots `0..k` (k >= 1); empty slots `k..8` hold the box min = +inf, max = -inf, which the
/// slab test never enters, and `child = count = 0`. Rows are 32-byte aligned: one `f32x8` load each.
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct Bvh8Node {
    pub bounds: [[f32; WIDTH]; 6],
    pub child: [u32; WIDTH],
    pub count: [u32; WIDTH],
}

const _: () = assert!(std::mem::size_of::<Bvh8Node>() == 256);
const _: () = assert!(std::mem::align_of::<Bvh8Node>() == 64);

impl Bvh8Node {
    /// A node with no child (every slot empty).
    pub const EMPTY: Bvh8Node = Bvh8Node {
        bounds: [[f32::INFINITY; WIDTH], [f32::INFINITY; WIDTH], [f32::INFINITY; WIDTH], [f32::NEG_INFINITY; WIDTH], [f32::NEG_INFINITY; WIDTH], [f32::NEG_INFINITY; WIDTH]],
        child: [0; WIDTH],
        count: [0; WIDTH],
    };

    /// Box of child slot `i` (empty for an empty slot).
    #[inline]
    pub fn child_aabb(&self, i: usize) -> Aabb {
        let b = &self.bounds;
        Aabb::new(Vec3::new(b[0][i], b[1][i], b[2][i]), Vec3::new(b[3][i], b[4][i], b[5][i]))
    }

    /// Number of occupied slots (they come first).
    #[inline]
    pub fn child_count(&self) -> usize {
        (0..WIDTH).take_while(|&i| !self.child_aabb(i).is_empty()).count()
    }

    fn set_child(&mut self, i: usize, b: Aabb, child: u32, count: u32) {
        for a in 0..3 {
            self.bounds[a][i] = b.min[a];
            self.bounds[a + 3][i] = b.max[a];
        }
        self.child[i] = child;
        self.count[i] = count;
    }
}

/// An 8-wide BVH. `nodes[0]` is the root (always an inner wide node, even over a single leaf); an empty
/// `nodes` hits nothing. `indices` is the binary tree's, and every leaf keeps its binary range.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Bvh8 {
    pub nodes: Vec<Bvh8Node>,
    pub indices: Vec<u32>,
}

impl Bvh8 {
    /// Collapse a binary tree (see the module doc). Linear in its node count.
    pub fn from_bvh(bvh: &Bvh) -> Self {
        if bvh.is_empty() {
            return Self { nodes: Vec::new(), indices: bvh.indices.clone() };
        }
        let mut nodes = vec![Bvh8Node::EMPTY];
        // (wide node to fill, binary node it stands for)
        let mut todo = vec![(0usize, 0usize)];
        while let Some((w, b)) = todo.pop() {
            let mut node = Bvh8Node::EMPTY;
            for (i, &c) in collapse(bvh, b).iter().enumerate() {
                let n = &bvh.nodes[c];
                if n.is_leaf() {
                    node.set_child(i, n.aabb(), n.left_first, n.count());
                } else {
                    node.set_child(i, n.aabb(), nodes.len() as u32, 0);
                    todo.push((nodes.len(), c));
                    nodes.push(Bvh8Node::EMPTY);
                }
            }
            nodes[w] = node;
        }
        Self { nodes, indices: bvh.indices.clone() }
    }

    /// True when the tree holds no primitive.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }
}

/// The binary nodes that become the children of the wide node standing for binary node `b`: its two
/// children, then repeatedly the two children of the inner one of largest surface area in its place,
/// up to [`WIDTH`]. A leaf `b` (a root-only tree) gives itself.
fn collapse(bvh: &Bvh, b: usize) -> Vec<usize> {
    let n = &bvh.nodes[b];
    if n.is_leaf() {
        return vec![b];
    }
    let l = n.left_first as usize;
    let mut ch = vec![l, l + 1];
    while ch.len() < WIDTH {
        let area = |c: usize| bvh.nodes[c].aabb().surface_area();
        let Some(i) = (0..ch.len()).filter(|&i| !bvh.nodes[ch[i]].is_leaf()).max_by(|&i, &j| area(ch[i]).total_cmp(&area(ch[j])).then(j.cmp(&i)))
        else {
            break;
        };
        let l = bvh.nodes[ch[i]].left_first as usize;
        ch[i] = l;
        ch.insert(i + 1, l + 1);
    }
    ch
}

/// The slab constants of one ray, splatted over the 8 children (see the module doc): per axis, the
/// bounds row of the near and of the far plane and the folded `(inv, c)` of each.
#[derive(Clone, Copy, Debug)]
struct SingleRay {
    near: [usize; 3],
    far: [usize; 3],
    inv_n: [f32x8; 3],
    c_n: [f32x8; 3],
    inv_f: [f32x8; 3],
    c_f: [f32x8; 3],
}

impl SingleRay {
    /// From a packet whose 8 lanes hold the same ray.
    #[inline(always)]
    fn new(splat: &Ray8) -> Self {
        let pr = PacketRay::new(splat);
        let ax = |v: Vec3x8| [v.x, v.y, v.z];
        let (il, cl, ih, ch) = (ax(pr.inv_lo), ax(pr.c_lo), ax(pr.inv_hi), ax(pr.c_hi));
        let mut r = Self { near: [0; 3], far: [0; 3], inv_n: il, c_n: cl, inv_f: ih, c_f: ch };
        for a in 0..3 {
            // `PacketRay` pads the min plane as the near one exactly where its clamped inv_d >= 0; the
            // scaled `inv_lo` keeps that sign (it is never 0: |inv_d| >= 1 / f32::MAX).
            let pos = il[a].to_array()[0] >= 0.0;
            (r.near[a], r.far[a]) = if pos { (a, a + 3) } else { (a + 3, a) };
            if !pos {
                (r.inv_n[a], r.c_n[a], r.inv_f[a], r.c_f[a]) = (ih[a], ch[a], il[a], cl[a]);
            }
        }
        r
    }

    /// `(tnear, hit bits)` of the 8 children: the mask [`intersect_aabb_x8`] gives this ray's lane for
    /// each child box (see the module doc), empty slots never set.
    #[inline(always)]
    fn test(&self, n: &Bvh8Node, tmax: f32x8) -> (f32x8, u32) {
        let row = |i: usize| f32x8::from(n.bounds[i]);
        let d = |a: usize| (row(self.near[a]).mul_add(self.inv_n[a], self.c_n[a]), row(self.far[a]).mul_add(self.inv_f[a], self.c_f[a]));
        let ((nx, fx), (ny, fy), (nz, fz)) = (d(0), d(1), d(2));
        let tn = nx.fast_max(ny).fast_max(nz.fast_max(f32x8::ZERO));
        let tf = fx.fast_min(fy).fast_min(fz.fast_min(tmax));
        (tn, tn.simd_le(tf).to_bitmask())
    }
}

/// A pending child: its `child`/`count` slot fields and the entry distance it was pushed with.
#[derive(Clone, Copy, Debug, Default)]
struct Entry {
    child: u32,
    count: u32,
    tn: f32,
}

/// Push the children in `bits` (entry distances `tn`) so that the nearest ends on top.
#[inline(always)]
fn push_sorted(n: &Bvh8Node, tn: f32x8, mut bits: u32, stack: &mut [Entry], sp: &mut usize) {
    let tn = tn.to_array();
    let base = *sp;
    while bits != 0 {
        let i = bits.trailing_zeros() as usize;
        bits &= bits - 1;
        let e = Entry { child: n.child[i], count: n.count[i], tn: tn[i] };
        let mut k = *sp;
        while k > base && stack[k - 1].tn < e.tn {
            stack[k] = stack[k - 1];
            k -= 1;
        }
        stack[k] = e;
        *sp += 1;
    }
}

/// A packet whose 8 lanes are the one ray `(o, d)` (`inv_d = 1 / d` as [`Ray8::new`] computes it).
#[inline(always)]
pub fn splat_ray(o: Vec3, d: Vec3, tmax: f32) -> Ray8 {
    Ray8::new(Vec3x8::splat(o), Vec3x8::splat(d), f32x8::splat(tmax))
}

impl Bvh8 {
    /// Closest-hit traversal of one ray. `leaf(prim, &mut tmax)` is called for each primitive of each
    /// visited leaf; it lowers `tmax` when the primitive is hit nearer (the caller records which). Nodes
    /// whose box the ray's padded slab interval does not overlap within `[0, tmax]` are skipped, exactly
    /// as the packet test decides for this ray's lane. Nothing happens when `tmax < 0` (an inactive ray).
    pub fn traverse_closest_single(&self, o: Vec3, d: Vec3, tmax: f32, leaf: impl FnMut(u32, &mut f32)) {
        self.traverse_closest_splat(&splat_ray(o, d, tmax), leaf);
    }

    /// [`Bvh8::traverse_closest_single`] for a ray given as a splatted packet (every lane the same ray,
    /// as [`splat_ray`] makes it); its `tmax` lane 0 is the starting `tmax`.
    pub fn traverse_closest_splat(&self, ray: &Ray8, mut leaf: impl FnMut(u32, &mut f32)) {
        let mut tmax = ray.tmax.to_array()[0];
        if self.nodes.is_empty() || !(tmax >= 0.0) {
            return;
        }
        let r = SingleRay::new(ray);
        let mut stack = [Entry::default(); STACK];
        let mut sp = 0usize;
        let mut node = 0usize;
        loop {
            let n = &self.nodes[node];
            let (tn, bits) = r.test(n, f32x8::splat(tmax));
            push_sorted(n, tn, bits, &mut stack, &mut sp);
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
                for &p in &self.indices[e.child as usize..(e.child + e.count) as usize] {
                    leaf(p, &mut tmax);
                }
            }
        }
    }

    /// Any-hit (occlusion) traversal of one ray: true as soon as `leaf(prim, tmax)` returns true. The
    /// loop mirrors the closest-hit one (as `traverse.rs` keeps its two loops apart). Nothing is visited
    /// when `tmax <= 0` (the packet any-hit convention).
    pub fn traverse_any_single(&self, o: Vec3, d: Vec3, tmax: f32, mut leaf: impl FnMut(u32, f32) -> bool) -> bool {
        if self.nodes.is_empty() || !(tmax > 0.0) {
            return false;
        }
        let r = SingleRay::new(&splat_ray(o, d, tmax));
        let tm = f32x8::splat(tmax);
        let mut stack = [Entry::default(); STACK];
        let mut sp = 0usize;
        let mut node = 0usize;
        loop {
            let n = &self.nodes[node];
            let (tn, bits) = r.test(n, tm);
            push_sorted(n, tn, bits, &mut stack, &mut sp);
            loop {
                if sp == 0 {
                    return false;
                }
                sp -= 1;
                let e = stack[sp];
                if e.count == 0 {
                    node = e.child as usize;
                    break;
                }
                for &p in &self.indices[e.child as usize..(e.child + e.count) as usize] {
                    if leaf(p, tmax) {
                        return true;
                    }
                }
            }
        }
    }

    /// Closest-hit traversal of an 8-ray packet: each node tests its occupied children one by one with
    /// [`intersect_aabb_x8`] (8 rays x 1 box per test), and pushes those some lane enters, ordered by
    /// the smallest entry distance over the lanes that enter. The callback contract is
    /// [`Bvh::traverse_closest_x8`]'s (lanes with `tmax < 0` are inactive).
    pub fn traverse_closest_x8_per_child(&self, ray: &mut Ray8, mut leaf: impl FnMut(u32, &mut Ray8)) {
        if self.nodes.is_empty() || !ray.tmax.simd_ge(f32x8::ZERO).any() {
            return;
        }
        let pr = PacketRay::new(ray);
        let lanes_max = |r: &Ray8| r.tmax.to_array().into_iter().fold(f32::NEG_INFINITY, f32::max);
        let mut tmax = lanes_max(ray);
        let inf = f32x8::splat(f32::INFINITY);
        let mut stack = [Entry::default(); STACK];
        let mut sp = 0usize;
        let mut node = 0usize;
        loop {
            let n = &self.nodes[node];
            let k = n.child_count_fast();
            let mut tn = [f32::INFINITY; WIDTH];
            let mut bits = 0u32;
            for (i, t) in tn.iter_mut().enumerate().take(k) {
                let b = &n.bounds;
                let (bmin, bmax) = (Vec3::new(b[0][i], b[1][i], b[2][i]), Vec3::new(b[3][i], b[4][i], b[5][i]));
                let (near, hit) = intersect_aabb_x8(bmin, bmax, &pr, ray.tmax);
                if hit.any() {
                    *t = hit.select(near, inf).to_array().into_iter().fold(f32::INFINITY, f32::min);
                    bits |= 1 << i;
                }
            }
            push_sorted(n, f32x8::from(tn), bits, &mut stack, &mut sp);
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
                for &p in &self.indices[e.child as usize..(e.child + e.count) as usize] {
                    leaf(p, ray);
                }
                tmax = lanes_max(ray);
            }
        }
    }
}

/// The slab constants of the 8 rays of a packet, lane by lane (scalars, broadcast at use): the
/// [`SingleRay`] of each lane.
#[derive(Clone, Copy, Debug)]
struct LaneRays {
    near: [[usize; 3]; 8],
    far: [[usize; 3]; 8],
    inv_n: [[f32; 8]; 3],
    c_n: [[f32; 8]; 3],
    inv_f: [[f32; 8]; 3],
    c_f: [[f32; 8]; 3],
}

impl LaneRays {
    #[inline(always)]
    fn new(ray: &Ray8) -> Self {
        let pr = PacketRay::new(ray);
        let ax = |v: Vec3x8| [v.x, v.y, v.z];
        let (il, cl, ih, ch) = (ax(pr.inv_lo), ax(pr.c_lo), ax(pr.inv_hi), ax(pr.c_hi));
        let mut r = Self { near: [[0; 3]; 8], far: [[0; 3]; 8], inv_n: [[0.0; 8]; 3], c_n: [[0.0; 8]; 3], inv_f: [[0.0; 8]; 3], c_f: [[0.0; 8]; 3] };
        for a in 0..3 {
            let pos = il[a].simd_ge(f32x8::ZERO);
            r.inv_n[a] = pos.select(il[a], ih[a]).to_array();
            r.c_n[a] = pos.select(cl[a], ch[a]).to_array();
            r.inv_f[a] = pos.select(ih[a], il[a]).to_array();
            r.c_f[a] = pos.select(ch[a], cl[a]).to_array();
            let bits = pos.to_bitmask();
            for l in 0..8 {
                let p = bits & (1 << l) != 0;
                (r.near[l][a], r.far[l][a]) = if p { (a, a + 3) } else { (a + 3, a) };
            }
        }
        r
    }

    /// [`SingleRay::test`] for lane `l`.
    #[inline(always)]
    fn test(&self, l: usize, n: &Bvh8Node, tmax: f32) -> (f32x8, f32x8) {
        let row = |i: usize| f32x8::from(n.bounds[i]);
        let s = |v: &[f32; 8]| f32x8::splat(v[l]);
        let d = |a: usize| {
            (row(self.near[l][a]).mul_add(s(&self.inv_n[a]), s(&self.c_n[a])), row(self.far[l][a]).mul_add(s(&self.inv_f[a]), s(&self.c_f[a])))
        };
        let ((nx, fx), (ny, fy), (nz, fz)) = (d(0), d(1), d(2));
        let tn = nx.fast_max(ny).fast_max(nz.fast_max(f32x8::ZERO));
        let tf = fx.fast_min(fy).fast_min(fz.fast_min(f32x8::splat(tmax)));
        (tn, tn.simd_le(tf))
    }
}

/// Transpose an 8x8 bit matrix held row by row in the bytes of `x` (row `r` in byte `r`, column `c` in
/// bit `c` of it): Hacker's Delight, 2nd ed., 7-3 ("transpose8"), which is stated for the mirrored
/// layout; mirroring both axes commutes with transposition.
#[inline(always)]
pub fn transpose8x8(mut x: u64) -> u64 {
    let t = (x ^ (x >> 7)) & 0x00AA_00AA_00AA_00AA;
    x ^= t ^ (t << 7);
    let t = (x ^ (x >> 14)) & 0x0000_CCCC_0000_CCCC;
    x ^= t ^ (t << 14);
    let t = (x ^ (x >> 28)) & 0x0000_0000_F0F0_F0F0;
    x ^ t ^ (t << 28)
}

/// A pending child of packet traversal: its slot fields, the smallest entry distance over the lanes
/// that entered it, and those lanes.
#[derive(Clone, Copy, Debug, Default)]
struct LaneEntry {
    child: u32,
    count: u32,
    tn: f32,
    lanes: u32,
}

impl Bvh8 {
    /// Closest-hit traversal of an 8-ray packet in which each lane tests a node's 8 children with one
    /// single-ray test (the lanes' own [`SingleRay`] constants), and only the lanes that entered a child
    /// go on to test that child's children: every stack entry carries its lane mask (a transposed 8x8
    /// bit matrix turns the lanes' child masks into the children's lane masks). Children are pushed
    /// near-first by the smallest entry distance over their lanes. Leaves test the whole packet. The
    /// callback contract is [`Bvh::traverse_closest_x8`]'s (lanes with `tmax < 0` are inactive).
    pub fn traverse_closest_x8(&self, ray: &mut Ray8, mut leaf: impl FnMut(u32, &mut Ray8)) {
        let active = ray.tmax.simd_ge(f32x8::ZERO).to_bitmask();
        if self.nodes.is_empty() || active == 0 {
            return;
        }
        let lr = LaneRays::new(ray);
        let inf = f32x8::splat(f32::INFINITY);
        let mut tm = ray.tmax.to_array();
        let mut stack = [LaneEntry::default(); STACK];
        let mut sp = 0usize;
        let (mut node, mut lanes) = (0usize, active);
        loop {
            let n = &self.nodes[node];
            let (mut key, mut m) = (inf, 0u64);
            let mut ls = lanes;
            while ls != 0 {
                let l = ls.trailing_zeros() as usize;
                ls &= ls - 1;
                let (tn, hit) = lr.test(l, n, tm[l]);
                key = key.fast_min(hit.select(tn, inf));
                m |= (hit.to_bitmask() as u64) << (8 * l);
            }
            let m = transpose8x8(m);
            let key = key.to_array();
            let base = sp;
            let mut bits = f32x8::from(key).simd_lt(inf).to_bitmask();
            while bits != 0 {
                let i = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let e = LaneEntry { child: n.child[i], count: n.count[i], tn: key[i], lanes: ((m >> (8 * i)) & 0xff) as u32 };
                let mut k = sp;
                while k > base && stack[k - 1].tn < e.tn {
                    stack[k] = stack[k - 1];
                    k -= 1;
                }
                stack[k] = e;
                sp += 1;
            }
            loop {
                if sp == 0 {
                    return;
                }
                sp -= 1;
                let e = stack[sp];
                // Lanes whose tmax fell below the smallest entry distance cannot enter any more.
                let live = f32x8::splat(e.tn).simd_le(f32x8::from(tm)).to_bitmask() & e.lanes;
                if live == 0 {
                    continue;
                }
                if e.count == 0 {
                    (node, lanes) = (e.child as usize, live);
                    break;
                }
                for &p in &self.indices[e.child as usize..(e.child + e.count) as usize] {
                    leaf(p, ray);
                }
                tm = ray.tmax.to_array();
            }
        }
    }
}

impl Bvh8Node {
    /// Occupied slots, from the min-x row (an empty slot's min is +inf, an occupied one's is finite).
    #[inline(always)]
    fn child_count_fast(&self) -> usize {
        f32x8::from(self.bounds[0]).simd_lt(f32x8::splat(f32::INFINITY)).to_bitmask().count_ones() as usize
    }
}

impl Bvh8 {
    /// Check the invariants of a tree collapsed from a binary tree over `bounds`:
    /// - an empty `bounds` has an empty tree; else `indices` is a permutation of `0..n`;
    /// - every node is reached exactly once from the root (no cycles, no orphans), at depth <=
    ///   `MAX_DEPTH`;
    /// - occupied slots come first, at least one per node (two below the root); empty slots hold
    ///   (+inf, -inf) and zeros;
    /// - every `indices` slot is owned by exactly one leaf (so every primitive is reachable once);
    /// - a child box contains its primitives' boxes (leaf) or its node's child boxes (inner).
    pub fn validate(&self, bounds: &[Aabb]) -> Result<(), String> {
        let n = bounds.len();
        if n == 0 {
            return if self.nodes.is_empty() && self.indices.is_empty() { Ok(()) } else { Err("empty input but non-empty tree".into()) };
        }
        if self.nodes.is_empty() || self.indices.len() != n {
            return Err(format!("{} nodes and {} indices for {n} primitives", self.nodes.len(), self.indices.len()));
        }
        let mut seen = vec![false; n];
        for &p in &self.indices {
            if std::mem::replace(seen.get_mut(p as usize).ok_or(format!("index {p} out of range"))?, true) {
                return Err(format!("primitive {p} appears twice in indices"));
            }
        }
        let mut visited = vec![false; self.nodes.len()];
        let mut owned = vec![false; n];
        let mut stack = vec![(0usize, 1usize)];
        while let Some((w, level)) = stack.pop() {
            if level > MAX_DEPTH {
                return Err(format!("wide node {w} at level {level} > MAX_DEPTH"));
            }
            if std::mem::replace(visited.get_mut(w).ok_or(format!("wide node {w} out of range"))?, true) {
                return Err(format!("wide node {w} reached twice"));
            }
            let node = &self.nodes[w];
            let k = node.child_count();
            if k == 0 || (w != 0 && k < 2) || k != node.child_count_fast() {
                return Err(format!("wide node {w} has {k} children"));
            }
            for i in k..WIDTH {
                if node.child_aabb(i) != Aabb::EMPTY || node.child[i] != 0 || node.count[i] != 0 {
                    return Err(format!("wide node {w}: empty slot {i} is not (+inf, -inf, 0, 0)"));
                }
            }
            for i in 0..k {
                let b = node.child_aabb(i);
                if b.min.is_nan() || b.max.is_nan() {
                    return Err(format!("wide node {w} slot {i}: NaN box"));
                }
                let (first, count) = (node.child[i] as usize, node.count[i] as usize);
                if count == 0 {
                    let c = self.nodes.get(first).ok_or(format!("wide node {w} slot {i}: child {first} out of range"))?;
                    if let Some(j) = (0..c.child_count()).find(|&j| !b.contains(&c.child_aabb(j))) {
                        return Err(format!("wide node {w} slot {i} does not contain slot {j} of node {first}"));
                    }
                    stack.push((first, level + 1));
                    continue;
                }
                let slots = owned.get_mut(first..first + count).ok_or(format!("wide node {w} slot {i}: leaf range out of bounds"))?;
                if slots.iter().any(|&o| o) {
                    return Err(format!("wide node {w} slot {i}: indices {first}..{} owned twice", first + count));
                }
                slots.fill(true);
                for &p in &self.indices[first..first + count] {
                    if !b.contains(&bounds[p as usize]) {
                        return Err(format!("wide node {w} slot {i} does not contain primitive {p}"));
                    }
                }
            }
        }
        if let Some(i) = owned.iter().position(|&o| !o) {
            return Err(format!("indices slot {i} is in no leaf"));
        }
        if let Some(w) = visited.iter().position(|&v| !v) {
            return Err(format!("wide node {w} is unreachable"));
        }
        Ok(())
    }
}
