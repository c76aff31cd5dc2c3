//! The wide BVH ([`WideBvh`], [`WIDTH`] = 16 or 8 children per node): its node layout, the collapse
//! from the binary [`Bvh`], and `validate`.
//! Traversal is in `wide_traverse.rs`.
//!
//! A wide node stands for a binary inner node; its children are binary nodes of that node's subtree
//! that cut it (every leaf below lies under exactly one of them), at most [`WIDTH`]. Binary leaves stay
//! leaves and keep their `indices` ranges, so a primitive id met at a wide leaf is the one the binary
//! tree would report, and the child boxes are the binary nodes' boxes, bit for bit: a wide traversal
//! tests a subset of the boxes the binary one tests (the flattened inner nodes' boxes are skipped).
//! Two ways to choose the cut ([`Collapse`]):
//! - greedy (Wald, Benthin & Boulos 2008, "Getting Rid of Packets: Efficient SIMD Single-Ray Traversal
//!   using Multi-branching BVHs"): start from the two children and replace the inner child of largest
//!   surface area by its two children until `WIDTH` children or only leaves;
//! - SAH-optimal ([`SahCollapse`], after Ylitie, Karras & Laine 2017), which the scene uses: on
//!   `bench_spheres.toml`, 8 children per node, 228 wide nodes instead of 377, and 5% faster packet
//!   traversal.

use glam::Vec3;

use super::{Aabb, Bvh, MAX_DEPTH, SAH_INTERSECT_COST, SAH_TRAVERSAL_COST};
use bytemuck::{Pod, Zeroable};

/// Children per wide node: one node row (a bound of every child) fills one vector register, 16 floats
/// where the target has AVX-512 (a zmm register), else 8 (ymm). With AVX-512, 16 children against 8
/// took the intersect stage of peer scene (b) (path tracing, 1,000 spheres) from 0.329 to 0.293 CPU s
/// at 16 spp (one thread, 8 interleaved rounds, `benches/ab.py`), by fewer levels per ray (session
/// 23, README "Intersection"); on an AVX2 build of the same machine (`-C target-cpu=znver3`, a 16-float
/// row as two ymm) the two widths tied (0.372 against 0.371 s), so 8 stays there.
#[cfg(target_feature = "avx512f")]
pub const WIDTH: usize = 16;
/// Children per wide node (see the AVX-512 definition).
#[cfg(not(target_feature = "avx512f"))]
pub const WIDTH: usize = 8;

/// One node row (a value per child) as lanes.
#[cfg(target_feature = "avx512f")]
pub type NodeF = crate::simd::f32x16;
/// One node row as lanes.
#[cfg(not(target_feature = "avx512f"))]
pub type NodeF = crate::simd::f32x8;
/// One node row of integers as lanes.
#[cfg(target_feature = "avx512f")]
pub type NodeI = crate::simd::i32x16;
/// One node row of integers as lanes.
#[cfg(not(target_feature = "avx512f"))]
pub type NodeI = crate::simd::i32x8;

/// Smallest binary tree (in nodes) for which the intersect stage sends incoherent rays through the
/// [`WideBvh`] (`Scene::wide_incoherent`; camera rays take it at every size, `wide_group.rs`). Below it, groups of packets
/// through the binary tree were faster: the top levels, where a packet's rays still enter the same
/// nodes, are most of a small tree, and there a group shares one box test among 64 rays (groups of 8
/// packets then; 16 since session 5) while the wide
/// packet traversal tests each ray. Secondary rays of the intersect benchmark's construction, one
/// thread, best of 15, M rays/s groups / wide:
///
/// | scene (binary nodes)                        | groups | wide  |
/// |---------------------------------------------|--------|-------|
/// | glass.toml (3 shapes)                       | 54.0   | 48.0  |
/// | showcase.toml (7 shapes)                    | 44.6   | 42.4  |
/// | first 40 of bench_spheres' spheres (77)     | 44.6   | 41.9  |
/// | first 160 (313)                             | 29.9   | 29.1  |
/// | bench_csg.toml (415)                        | 22.0   | 25.3  |
/// | first 320 (603)                             | 22.4   | 23.3  |
/// | first 640 (1189)                            | 16.7   | 18.1  |
/// | bench_spheres.toml, 1000 spheres (1811)     | 13.9   | 15.1  |
pub const WIDE_MIN_NODES: usize = 400;

/// One wide node: `repr(C, align(64))`, `Pod`, `32 * WIDTH` bytes (512 with 16 children: 8 cache lines;
/// 256 with 8), no padding. With `W = WIDTH`:
///
/// | bytes          | field    | content                                                                  |
/// |----------------|----------|--------------------------------------------------------------------------|
/// | 0..24W         | `bounds` | 6 rows of W f32: child box min x, min y, min z, max x, max y, max z      |
/// | 24W..28W       | `child`  | per child: inner: index of its wide node; leaf: first slot in `indices`  |
/// | 28W..32W       | `count`  | per child: leaf: primitive count (>= 1); inner or empty slot: 0          |
///
/// Children fill slots `0..k` (k >= 1); empty slots `k..W` hold the box min = +inf, max = -inf, which the
/// slab test never enters, and `child = count = 0`. Rows are `4 * W`-byte aligned: one [`NodeF`] load
/// each.
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct WideNode {
    pub bounds: [[f32; WIDTH]; 6],
    pub child: [u32; WIDTH],
    pub count: [u32; WIDTH],
}

const _: () = assert!(std::mem::size_of::<WideNode>() == 32 * WIDTH);
const _: () = assert!(std::mem::align_of::<WideNode>() == 64);

impl WideNode {
    /// A node with no child (every slot empty).
    pub const EMPTY: WideNode = WideNode {
        bounds: [
            [f32::INFINITY; WIDTH],
            [f32::INFINITY; WIDTH],
            [f32::INFINITY; WIDTH],
            [f32::NEG_INFINITY; WIDTH],
            [f32::NEG_INFINITY; WIDTH],
            [f32::NEG_INFINITY; WIDTH],
        ],
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

/// A wide BVH ([`WIDTH`] children per node). `nodes[0]` is the root (always an inner wide node, even over a single leaf); an empty
/// `nodes` hits nothing. `indices` is the binary tree's, and every leaf keeps its binary range.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct WideBvh {
    pub nodes: Vec<WideNode>,
    pub indices: Vec<u32>,
}

impl WideBvh {
    /// Collapse a binary tree (see the module doc). Linear in its node count (the SAH collapse does
    /// `WIDTH^2` work per binary node).
    pub fn from_bvh(bvh: &Bvh, how: Collapse) -> Self {
        if bvh.is_empty() {
            return Self { nodes: Vec::new(), indices: bvh.indices.clone() };
        }
        let dp = (how == Collapse::Sah).then(|| SahCollapse::new(bvh));
        let mut nodes = vec![WideNode::EMPTY];
        // (wide node to fill, binary node it stands for)
        let mut todo = vec![(0usize, 0usize)];
        while let Some((w, b)) = todo.pop() {
            let mut node = WideNode::EMPTY;
            let slots = match &dp {
                Some(dp) => dp.slots(bvh, b),
                None => collapse_greedy(bvh, b),
            };
            for (i, &c) in slots.iter().enumerate() {
                let n = &bvh.nodes[c];
                if n.is_leaf() {
                    node.set_child(i, n.aabb(), n.left_first, n.count());
                } else {
                    node.set_child(i, n.aabb(), nodes.len() as u32, 0);
                    todo.push((nodes.len(), c));
                    nodes.push(WideNode::EMPTY);
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

    /// The cost [`Collapse::Sah`] minimises: the areas of the inner child boxes times
    /// `SAH_TRAVERSAL_COST`, plus area times primitive count of the leaf child boxes times
    /// `SAH_INTERSECT_COST` (the root's own box is the same for every collapse and left out).
    pub fn sah_cost(&self) -> f64 {
        let mut c = 0.0;
        for n in &self.nodes {
            for i in 0..n.child_count() {
                let a = area_f64(&n.child_aabb(i));
                c += if n.count[i] == 0 { a * SAH_TRAVERSAL_COST as f64 } else { a * n.count[i] as f64 * SAH_INTERSECT_COST as f64 };
            }
        }
        c
    }
}

/// How [`WideBvh::from_bvh`] picks the binary nodes that become the children of a wide node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Collapse {
    /// Top-down: the two children, then repeatedly the inner child of largest surface area replaced by
    /// its two children, until `WIDTH` children or only leaves (`collapse_greedy`).
    Greedy,
    /// The least SAH cost over all ways to cut the binary tree into wide nodes (`SahCollapse`).
    Sah,
}

/// SAH-optimal collapse (Ylitie, Karras & Laine 2017, "Efficient Incoherent Ray Traversal on GPUs
/// Through Compressed Wide BVHs", section 3.1, without their leaf merging: binary leaves stay leaves).
/// Bottom-up, `cost[n][j]` is the least SAH cost of binary node `n`'s subtree when it may take at most
/// `j` slots of its wide parent: one slot holding `n` (then `n` is a wide node, costing its area times
/// [`SAH_TRAVERSAL_COST`](super::SAH_TRAVERSAL_COST) plus its children's best use of `WIDTH` slots),
/// or `a + b <= j` slots shared by its two children (then `n` is flattened into the parent). Leaves
/// always take one slot; as their costs are fixed, the collapse minimises the summed area of the wide
/// nodes, which fills nodes near the leaves that the greedy collapse leaves with 2 or 3 children.
///
/// On `scenes/bench_spheres.toml` (1811 binary nodes): 377 wide nodes greedy, 228 with this; on the
/// secondary rays of the intersect benchmark, single-thread packet traversal took 55 ns/ray with the
/// greedy tree and 52.5 with this one (binary packets: 53).
struct SahCollapse {
    /// For binary node `n` and `j` slots: `(0, 0)` = one slot holding `n`; `(a, b)` = `a` slots for
    /// the left child's subtree and `b` for the right one's. Index 0: the split of the `WIDTH` slots
    /// of the wide node that `n` becomes.
    split: Vec<[(u8, u8); WIDTH + 1]>,
}

impl SahCollapse {
    fn new(bvh: &Bvh) -> Self {
        let m = bvh.nodes.len();
        // f64: the surface area of a finite f32 box can overflow f32.
        let mut cost = vec![[f64::INFINITY; WIDTH + 1]; m];
        let mut split = vec![[(0u8, 0u8); WIDTH + 1]; m];
        // Children come after their parent in `nodes`: reverse order visits children first.
        for n in (0..m).rev() {
            let node = &bvh.nodes[n];
            let area = area_f64(&node.aabb());
            if node.is_leaf() {
                cost[n] = [area * node.count() as f64 * SAH_INTERSECT_COST as f64; WIDTH + 1];
                continue;
            }
            let (l, r) = (node.left_first as usize, node.left_first as usize + 1);
            // dist[j]: the children's best use of at most j slots together.
            let mut dist = [(f64::INFINITY, (0u8, 0u8)); WIDTH + 1];
            for (j, dj) in dist.iter_mut().enumerate().skip(2) {
                for k in 1..j {
                    let c = cost[l][k] + cost[r][j - k];
                    // The first split is taken whatever its cost (a valid choice even if not finite).
                    if c < dj.0 || k == 1 {
                        *dj = (c, (k as u8, (j - k) as u8));
                    }
                }
            }
            cost[n][1] = area * SAH_TRAVERSAL_COST as f64 + dist[WIDTH].0;
            for j in 2..=WIDTH {
                (cost[n][j], split[n][j]) = if dist[j].0 < cost[n][j - 1] { dist[j] } else { (cost[n][j - 1], split[n][j - 1]) };
            }
            split[n][0] = dist[WIDTH].1;
        }
        Self { split }
    }

    /// The children of the wide node that binary node `b` becomes.
    fn slots(&self, bvh: &Bvh, b: usize) -> Vec<usize> {
        let n = &bvh.nodes[b];
        if n.is_leaf() {
            return vec![b];
        }
        let mut out = Vec::with_capacity(WIDTH);
        let (a, c) = self.split[b][0];
        self.gather(bvh, n.left_first as usize, a as usize, &mut out);
        self.gather(bvh, n.left_first as usize + 1, c as usize, &mut out);
        out
    }

    fn gather(&self, bvh: &Bvh, n: usize, j: usize, out: &mut Vec<usize>) {
        match self.split[n][j] {
            (0, 0) => out.push(n),
            (a, c) => {
                let l = bvh.nodes[n].left_first as usize;
                self.gather(bvh, l, a as usize, out);
                self.gather(bvh, l + 1, c as usize, out);
            }
        }
    }
}

/// Surface area in f64 (that of a finite f32 box can overflow f32); 0 for an empty box.
fn area_f64(b: &Aabb) -> f64 {
    if b.is_empty() {
        return 0.0;
    }
    let e = b.max.as_dvec3() - b.min.as_dvec3();
    2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
}

/// The binary nodes that become the children of the wide node standing for binary node `b`: its two
/// children, then repeatedly the two children of the inner one of largest surface area in its place,
/// up to [`WIDTH`]. A leaf `b` (a root-only tree) gives itself.
fn collapse_greedy(bvh: &Bvh, b: usize) -> Vec<usize> {
    let n = &bvh.nodes[b];
    if n.is_leaf() {
        return vec![b];
    }
    let l = n.left_first as usize;
    let mut ch = vec![l, l + 1];
    while ch.len() < WIDTH {
        let area = |c: usize| area_f64(&bvh.nodes[c].aabb());
        let Some(i) =
            (0..ch.len()).filter(|&i| !bvh.nodes[ch[i]].is_leaf()).max_by(|&i, &j| area(ch[i]).total_cmp(&area(ch[j])).then(j.cmp(&i)))
        else {
            break;
        };
        let l = bvh.nodes[ch[i]].left_first as usize;
        ch[i] = l;
        ch.insert(i + 1, l + 1);
    }
    ch
}

impl WideNode {
    /// Occupied slots, from the min-x row (an empty slot's min is +inf, an occupied one's is finite).
    #[inline(always)]
    pub(super) fn child_count_fast(&self) -> usize {
        NodeF::from(self.bounds[0]).simd_lt(NodeF::splat(f32::INFINITY)).to_bitmask().count_ones() as usize
    }
}

impl WideBvh {
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
