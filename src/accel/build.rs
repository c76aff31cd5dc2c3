//! Binned SAH build, after Wald 2007 ("On fast Construction of SAH-based Bounding Volume
//! Hierarchies", IEEE RT'07): primitives are binned by centroid into `bins` equal intervals of the
//! node's centroid box on each axis, the SAH is evaluated only at the bin borders (two sweeps over
//! the bins), and the index array is partitioned in place. O(n log n); the two subtrees of a range
//! of 16,384 primitives or more are built in parallel, into the tree one thread builds.
//!
//! Depth bound: a node at level `L` (root = 1) with `n` primitives keeps the invariant
//! `levels_needed(n) <= MAX_DEPTH - L`, where `levels_needed(n) = ceil(log2(ceil(n / max_leaf)))`
//! is what object-median splits need to reach leaves of `max_leaf`. An SAH split whose larger child
//! would break the invariant is replaced by an object-median split, which lowers `levels_needed` by
//! one per level; so every leaf is at level `<= MAX_DEPTH`.

use glam::Vec3;

use super::{Aabb, BuildOptions, Bvh, BvhNode, MAX_DEPTH, MAX_LEAF_COUNT, SAH_INTERSECT_COST, SAH_TRAVERSAL_COST};

const MAX_BINS: usize = 64;

/// A node still to be built: its slot in `nodes`, its range of `indices`, its level (root = 1).
struct Task {
    node: usize,
    first: usize,
    count: usize,
    level: usize,
}

#[derive(Clone, Copy)]
struct Bin {
    bounds: Aabb,
    count: u32,
}

const EMPTY_BIN: Bin = Bin { bounds: Aabb::EMPTY, count: 0 };

/// The best SAH split found by binning.
struct SahSplit {
    axis: usize,
    /// Primitives in bins `0..=last_left` go left.
    last_left: usize,
    left_count: usize,
    /// `SAH_TRAVERSAL_COST + SAH_INTERSECT_COST * (m_l n_l + m_r n_r) / m_node`.
    cost: f32,
}

/// Maps a centroid coordinate to its bin: `k = floor((c - cmin) * scale)`, `scale = bins (1 - 1e-6)
/// / extent` (Wald's `k1`), clamped to the last bin against rounding.
#[derive(Clone, Copy)]
struct BinMap {
    cmin: Vec3,
    scale: [f32; 3],
    bins: usize,
}

impl BinMap {
    #[inline(always)]
    fn bin(&self, c: Vec3, axis: usize) -> usize {
        // `as usize` saturates: a (impossible) negative product gives bin 0.
        (((c[axis] - self.cmin[axis]) * self.scale[axis]) as usize).min(self.bins - 1)
    }
}

/// Build a BVH over `bounds` (finite boxes; the index of a box is its primitive id).
///
/// An empty slice gives an empty tree (no nodes) that hits nothing. More than `MAX_LEAF_COUNT`
/// (2^30 - 1) boxes is a documented limit and panics.
pub fn build_bvh(bounds: &[Aabb], opts: &BuildOptions) -> Bvh {
    build(bounds, opts, PAR_MIN)
}

/// Ranges of at least this many primitives build their two children's subtrees in parallel (rayon's
/// global pool); smaller ones are built by one thread, depth first.
const PAR_MIN: usize = 1 << 14;

/// [`build_bvh`], parallel from ranges of `par_min` primitives up. The tree is the same whatever
/// `par_min` and the thread count: each subtree is numbered as the depth-first build numbers it, and
/// a parent lays out its children's subtrees as that build would (see [`Builder::subtree`]).
fn build(bounds: &[Aabb], opts: &BuildOptions, par_min: usize) -> Bvh {
    let n = bounds.len();
    let max_leaf = opts.max_leaf.clamp(1, MAX_LEAF_COUNT) as usize;
    let bins = (opts.bins as usize).clamp(2, MAX_BINS);
    if n == 0 {
        return Bvh { nodes: Vec::new(), indices: Vec::new(), max_leaf: max_leaf as u32 };
    }
    assert!(n <= MAX_LEAF_COUNT as usize, "build_bvh: at most 2^30 - 1 primitives");

    let centroids: Vec<Vec3> = bounds.iter().map(Aabb::centroid).collect();
    let mut indices: Vec<u32> = (0..n as u32).collect();
    let builder = Builder { bounds, centroids: &centroids, max_leaf, bins, par_min: par_min.max(2) };
    let nodes = builder.subtree(&mut indices, 0, 1);
    Bvh { nodes, indices, max_leaf: max_leaf as u32 }
}

struct Builder<'a> {
    bounds: &'a [Aabb],
    centroids: &'a [Vec3],
    max_leaf: usize,
    bins: usize,
    par_min: usize,
}

impl Builder<'_> {
    /// The subtree over `idx` (`indices[first..]`), whose root is at `level`: its root at 0 and the
    /// rest numbered as the depth-first build numbers them, leaves pointing into the whole `indices`.
    ///
    /// That build gives a node's two children consecutive slots when it splits the node, and builds
    /// the left subtree (allocating all of its nodes) before it takes up the right: a tree is laid out
    /// `[root, left, right, left's descendants, right's descendants]`, each descendants' run as their
    /// subtree numbers it from its root, moved. So both children's subtrees may be built apart (here
    /// in parallel) and joined by shifting their child links.
    fn subtree(&self, idx: &mut [u32], first: usize, level: usize) -> Vec<BvhNode> {
        if idx.len() < self.par_min {
            return self.depth_first(idx, first, level);
        }
        let t = Task { node: 0, first, count: idx.len(), level };
        let (node_box, split) = self.decide(idx, &t, &mut self.scratch());
        let Some((axis, left_count)) = split else {
            return vec![BvhNode::leaf(node_box, first as u32, idx.len() as u32)];
        };
        let (l, r) = idx.split_at_mut(left_count);
        let (left, right) = rayon::join(|| self.subtree(l, first, level + 1), || self.subtree(r, first + left_count, level + 1));
        // Left's node j >= 1 goes to slot j + 2, right's to j + 1 + left.len(); the roots to 1 and 2.
        let moved = |node: &BvhNode, by: usize| {
            let mut node = *node;
            if !node.is_leaf() {
                node.left_first += by as u32;
            }
            node
        };
        let mut nodes = Vec::with_capacity(1 + left.len() + right.len());
        nodes.push(BvhNode::inner(node_box, 1, axis as u32));
        nodes.push(moved(&left[0], 2));
        nodes.push(moved(&right[0], 1 + left.len()));
        nodes.extend(left[1..].iter().map(|node| moved(node, 2)));
        nodes.extend(right[1..].iter().map(|node| moved(node, 1 + left.len())));
        nodes
    }

    /// The bins and right-sweep costs [`Builder::decide`] works in.
    fn scratch(&self) -> (Vec<Bin>, Vec<(f32, u32)>) {
        (vec![EMPTY_BIN; 3 * self.bins], vec![(0.0f32, 0u32); self.bins])
    }

    /// The node over `idx` (task `t`): its box, and its split (`choose_split`, which partitions `idx`).
    fn decide(&self, idx: &mut [u32], t: &Task, scratch: &mut (Vec<Bin>, Vec<(f32, u32)>)) -> (Aabb, Option<(usize, usize)>) {
        let boxes = range_bounds(self.bounds, self.centroids, idx);
        (boxes.0, choose_split(self.bounds, self.centroids, idx, boxes, t, self.max_leaf, (&mut scratch.0, &mut scratch.1)))
    }

    /// The subtree over `idx` built by one thread, depth first (left child first), its root at 0.
    fn depth_first(&self, idx: &mut [u32], first: usize, level: usize) -> Vec<BvhNode> {
        let mut nodes = Vec::with_capacity(2 * idx.len() - 1);
        nodes.push(BvhNode::leaf(Aabb::EMPTY, 0, 1));
        let mut scratch = self.scratch();
        // (`Task::first` is relative to `idx` here; leaves add `first`.)
        let mut work = vec![Task { node: 0, first: 0, count: idx.len(), level }];
        while let Some(t) = work.pop() {
            let (node_box, split) = self.decide(&mut idx[t.first..t.first + t.count], &t, &mut scratch);
            match split {
                None => nodes[t.node] = BvhNode::leaf(node_box, (first + t.first) as u32, t.count as u32),
                Some((axis, left_count)) => {
                    let left = nodes.len();
                    nodes.push(BvhNode::leaf(Aabb::EMPTY, 0, 1));
                    nodes.push(BvhNode::leaf(Aabb::EMPTY, 0, 1));
                    nodes[t.node] = BvhNode::inner(node_box, left as u32, axis as u32);
                    let level = t.level + 1;
                    // Right first so the left subtree is built (and laid out) next: depth-first order.
                    work.push(Task { node: left + 1, first: t.first + left_count, count: t.count - left_count, level });
                    work.push(Task { node: left, first: t.first, count: left_count, level });
                }
            }
        }
        nodes
    }
}

/// Union of the primitive boxes and of the centroids of a range.
fn range_bounds(bounds: &[Aabb], centroids: &[Vec3], idx: &[u32]) -> (Aabb, Aabb) {
    let (mut b, mut c) = (Aabb::EMPTY, Aabb::EMPTY);
    for &i in idx {
        b = b.union(bounds[i as usize]);
        c.grow(centroids[i as usize]);
    }
    (b, c)
}

/// Object-median levels needed below a node of `n` primitives: `ceil(log2(ceil(n / max_leaf)))`.
fn levels_needed(n: usize, max_leaf: usize) -> usize {
    let k = n.div_ceil(max_leaf);
    (usize::BITS - (k - 1).leading_zeros()) as usize
}

/// Decide a node: `None` makes a leaf, `Some((axis, left_count))` a split whose left child is
/// `idx[..left_count]` (partitioned in place).
fn choose_split(
    bounds: &[Aabb],
    centroids: &[Vec3],
    idx: &mut [u32],
    (node_box, centroid_box): (Aabb, Aabb),
    t: &Task,
    max_leaf: usize,
    scratch: (&mut [Bin], &mut [(f32, u32)]),
) -> Option<(usize, usize)> {
    let n = idx.len();
    let ext = centroid_box.extent();
    // Identical centroids: binning cannot separate them, and any split has children with the
    // parent's box, which the SAH rates worse than one leaf. Documented exception to max_leaf.
    if n == 1 || t.level >= MAX_DEPTH || ext.max_element() <= 0.0 {
        return None;
    }
    let budget = MAX_DEPTH - t.level - 1;
    let bins = scratch.1.len();
    if let Some(s) = binned_sah(bounds, centroids, idx, node_box, centroid_box, bins, scratch) {
        let leaf_cost = SAH_INTERSECT_COST * n as f32;
        if n <= max_leaf && leaf_cost <= s.cost {
            return None;
        }
        if levels_needed(s.left_count.max(n - s.left_count), max_leaf) <= budget {
            let map = bin_map(centroid_box, bins);
            let left = partition(idx, |i| map.bin(centroids[i as usize], s.axis) <= s.last_left);
            debug_assert_eq!(left, s.left_count);
            return Some((s.axis, left));
        }
    } else if n <= max_leaf {
        return None;
    }
    // Object median on the axis of largest centroid extent: keeps the depth bound (see module doc),
    // and is the fallback when binning finds no split (centroid extent too small to bin).
    let axis = ext.max_position();
    let mid = n / 2;
    idx.select_nth_unstable_by(mid, |&a, &b| centroids[a as usize][axis].total_cmp(&centroids[b as usize][axis]));
    Some((axis, mid))
}

fn bin_map(centroid_box: Aabb, bins: usize) -> BinMap {
    let ext = centroid_box.extent();
    let mut scale = [0.0f32; 3];
    for (a, s) in scale.iter_mut().enumerate() {
        let k = bins as f32 * (1.0 - 1e-6) / ext[a];
        // A zero (or subnormal, overflowing) extent cannot be binned: the axis is skipped.
        *s = if ext[a] > 0.0 && k.is_finite() { k } else { 0.0 };
    }
    BinMap { cmin: centroid_box.min, scale, bins }
}

/// Bin the range on all three axes in one pass and sweep each axis for the cheapest border.
fn binned_sah(
    bounds: &[Aabb],
    centroids: &[Vec3],
    idx: &[u32],
    node_box: Aabb,
    centroid_box: Aabb,
    bins: usize,
    (store, right): (&mut [Bin], &mut [(f32, u32)]),
) -> Option<SahSplit> {
    let map = bin_map(centroid_box, bins);
    let axes: Vec3 = Vec3::from_array(map.scale);
    store.fill(EMPTY_BIN);
    for &i in idx {
        let (c, b) = (centroids[i as usize], bounds[i as usize]);
        for a in 0..3 {
            if axes[a] > 0.0 {
                let bin = &mut store[a * bins + map.bin(c, a)];
                bin.bounds = bin.bounds.union(b);
                bin.count += 1;
            }
        }
    }
    // The SAH weighs children by surface area; a node whose area is 0 (all boxes on one line) uses
    // the half perimeter instead, for all candidates of that node, so costs stay comparable.
    let use_area = node_box.surface_area() > 0.0;
    let metric = |b: &Aabb| if use_area { b.surface_area() } else { b.half_perimeter() };
    let node_metric = metric(&node_box);
    if node_metric <= 0.0 {
        return None;
    }
    let mut best: Option<SahSplit> = None;
    for a in 0..3 {
        if axes[a] <= 0.0 {
            continue;
        }
        let bins_a = &store[a * bins..(a + 1) * bins];
        // right[k] = (metric, count) of bins k..bins.
        let (mut acc, mut cnt) = (Aabb::EMPTY, 0u32);
        for k in (1..bins).rev() {
            acc = acc.union(bins_a[k].bounds);
            cnt += bins_a[k].count;
            right[k] = (metric(&acc), cnt);
        }
        let (mut acc, mut cnt) = (Aabb::EMPTY, 0u32);
        for k in 0..bins - 1 {
            acc = acc.union(bins_a[k].bounds);
            cnt += bins_a[k].count;
            let (m_r, n_r) = right[k + 1];
            if cnt == 0 || n_r == 0 {
                continue;
            }
            let cost = SAH_TRAVERSAL_COST + SAH_INTERSECT_COST * (metric(&acc) * cnt as f32 + m_r * n_r as f32) / node_metric;
            if best.as_ref().is_none_or(|b| cost < b.cost) {
                best = Some(SahSplit { axis: a, last_left: k, left_count: cnt as usize, cost });
            }
        }
    }
    best
}

/// In-place partition; returns the number of elements for which `goes_left` holds (now in front).
fn partition(idx: &mut [u32], goes_left: impl Fn(u32) -> bool) -> usize {
    let (mut i, mut j) = (0, idx.len());
    while i < j {
        if goes_left(idx[i]) {
            i += 1;
        } else {
            j -= 1;
            idx.swap(i, j);
        }
    }
    i
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The parallel build gives the depth-first build's tree, node for node and index for index,
    /// whatever the size from which ranges split across threads and whatever the thread count: on
    /// clustered boxes of mixed sizes, runs of identical centroids (leaves past `max_leaf`) and boxes
    /// on one line (the half-perimeter metric).
    #[test]
    fn parallel_build_equals_the_depth_first_one() {
        let mut f = crate::sample::hash::test_uniforms(0xb1d);
        let mut bounds = Vec::new();
        for i in 0..20_000 {
            let cluster = Vec3::splat((i % 7) as f32 * 30.0);
            let c = cluster + Vec3::new(f(), f(), f()) * 10.0;
            let h = Vec3::new(f(), f(), f()) * if i % 13 == 0 { 8.0 } else { 0.3 };
            bounds.push(Aabb::new(c - h, c + h));
        }
        bounds.extend(std::iter::repeat_n(Aabb::new(Vec3::splat(-1.0), Vec3::splat(1.0)), 40));
        bounds.extend((0..3000).map(|i| Aabb::new(Vec3::new(i as f32, 0.0, 0.0), Vec3::new(i as f32 + 0.5, 0.0, 0.0))));
        for opts in [BuildOptions::default(), BuildOptions { max_leaf: 1, bins: 7 }] {
            for part in [&bounds[..], &bounds[20_000..]] {
                let serial = build(part, &opts, usize::MAX);
                assert!(serial.nodes.len() > 1000);
                serial.validate(part).unwrap();
                for (threads, par_min) in [(1, 2), (2, 2), (2, 100), (3, 3000), (2, PAR_MIN)] {
                    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                    let tree = pool.install(|| build(part, &opts, par_min));
                    assert!(tree == serial, "{threads} threads, parallel from {par_min}: another tree");
                }
            }
        }
    }
}
