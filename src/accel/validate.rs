//! Tree invariants and statistics: `validate`, `depth`, `sah_cost`.

use super::{Aabb, Bvh, MAX_DEPTH, SAH_INTERSECT_COST, SAH_TRAVERSAL_COST};

impl Bvh {
    /// Check the invariants of a tree built over `bounds`:
    /// - an empty `bounds` has an empty tree, a non-empty one a root;
    /// - every primitive index appears exactly once in `indices`, and every slot of `indices` is
    ///   owned by exactly one leaf;
    /// - every node is reached exactly once from the root (children after their parent, right =
    ///   left + 1, in range), so there are no cycles and no orphans;
    /// - every node's box contains its children's boxes (inner) or its primitives' boxes (leaf),
    ///   compared exactly, and is not NaN;
    /// - no empty leaf (count 0 means inner node), split axis < 3;
    /// - leaves hold at most `max_leaf` primitives, unless all their centroids are bit-identical
    ///   (binning cannot split those; see `BuildOptions::max_leaf`);
    /// - node count <= 2n - 1 and depth <= `MAX_DEPTH` (the traversal stack depends on it).
    pub fn validate(&self, bounds: &[Aabb]) -> Result<(), String> {
        let n = bounds.len();
        if n == 0 {
            return match (self.nodes.is_empty(), self.indices.is_empty()) {
                (true, true) => Ok(()),
                _ => Err("empty input but non-empty tree".into()),
            };
        }
        if self.nodes.is_empty() {
            return Err(format!("{n} primitives but no nodes"));
        }
        if self.nodes.len() > 2 * n - 1 {
            return Err(format!("{} nodes for {n} primitives (max 2n - 1)", self.nodes.len()));
        }
        if self.indices.len() != n {
            return Err(format!("{} indices for {n} primitives", self.indices.len()));
        }
        let mut seen = vec![false; n];
        for (slot, &p) in self.indices.iter().enumerate() {
            let s = seen.get_mut(p as usize).ok_or(format!("indices[{slot}] = {p} out of range"))?;
            if *s {
                return Err(format!("primitive {p} appears twice in indices (slot {slot})"));
            }
            *s = true;
        }
        let mut visited = vec![false; self.nodes.len()];
        let mut owned = vec![false; n];
        let mut stack = vec![(0usize, 1usize)];
        while let Some((i, level)) = stack.pop() {
            if level > MAX_DEPTH {
                return Err(format!("node {i} at level {level} > MAX_DEPTH"));
            }
            if std::mem::replace(&mut visited[i], true) {
                return Err(format!("node {i} reached twice"));
            }
            let node = &self.nodes[i];
            let b = node.aabb();
            if b.min.is_nan() || b.max.is_nan() {
                return Err(format!("node {i} has a NaN box"));
            }
            if node.is_leaf() {
                self.check_leaf(i, bounds, &mut owned)?;
                continue;
            }
            if node.axis() > 2 {
                return Err(format!("node {i}: split axis {}", node.axis()));
            }
            let l = node.left_first as usize;
            if l <= i || l + 1 >= self.nodes.len() {
                return Err(format!("node {i}: children {l}, {} out of order or range", l + 1));
            }
            for c in [l, l + 1] {
                if !b.contains(&self.nodes[c].aabb()) {
                    return Err(format!("node {i}: box {b:?} does not contain child {c} {:?}", self.nodes[c].aabb()));
                }
                stack.push((c, level + 1));
            }
        }
        if let Some(i) = visited.iter().position(|v| !v) {
            return Err(format!("node {i} is not reachable from the root"));
        }
        if let Some(s) = owned.iter().position(|v| !v) {
            return Err(format!("indices slot {s} belongs to no leaf"));
        }
        Ok(())
    }

    fn check_leaf(&self, i: usize, bounds: &[Aabb], owned: &mut [bool]) -> Result<(), String> {
        let node = &self.nodes[i];
        let (first, count) = (node.left_first as usize, node.count() as usize);
        if node.axis() != 0 {
            return Err(format!("leaf {i}: axis bits set"));
        }
        if first + count > self.indices.len() {
            return Err(format!("leaf {i}: range {first}..{} out of indices", first + count));
        }
        let b = node.aabb();
        let prims = &self.indices[first..first + count];
        for (slot, &p) in (first..).zip(prims) {
            if std::mem::replace(&mut owned[slot], true) {
                return Err(format!("indices slot {slot} belongs to two leaves"));
            }
            if !b.contains(&bounds[p as usize]) {
                return Err(format!("leaf {i}: box {b:?} does not contain primitive {p} {:?}", bounds[p as usize]));
            }
        }
        if count > self.max_leaf as usize {
            let c0 = bounds[prims[0] as usize].centroid();
            if prims.iter().any(|&p| bounds[p as usize].centroid() != c0) {
                return Err(format!("leaf {i}: {count} primitives > max_leaf {} with distinct centroids", self.max_leaf));
            }
        }
        Ok(())
    }

    /// Levels of the tree: 0 when empty, 1 for a root-only tree.
    pub fn depth(&self) -> usize {
        if self.nodes.is_empty() {
            return 0;
        }
        let mut deepest = 0;
        let mut stack = vec![(0usize, 1usize)];
        while let Some((i, level)) = stack.pop() {
            deepest = deepest.max(level);
            let node = &self.nodes[i];
            if !node.is_leaf() {
                let l = node.left_first as usize;
                stack.push((l, level + 1));
                stack.push((l + 1, level + 1));
            }
        }
        deepest
    }

    /// SAH cost (MacDonald & Booth 1990) of the tree, with the constants of the build:
    /// `sum(inner) C_t A(node) / A(root) + sum(leaves) C_i count A(leaf) / A(root)`.
    /// When the root's area is 0 the half perimeter is used, and when that is 0 too every ratio
    /// is 1. 0 for an empty tree.
    pub fn sah_cost(&self) -> f32 {
        let Some(root) = self.nodes.first() else { return 0.0 };
        let rb = root.aabb();
        let metric: fn(&Aabb) -> f32 = if rb.surface_area() > 0.0 { Aabb::surface_area } else { Aabb::half_perimeter };
        let root_m = metric(&rb);
        let ratio = |b: &Aabb| if root_m > 0.0 { metric(b) / root_m } else { 1.0 };
        let mut cost = 0.0f64;
        for node in &self.nodes {
            let r = ratio(&node.aabb()) as f64;
            cost += if node.is_leaf() { (SAH_INTERSECT_COST * node.count() as f32) as f64 * r } else { SAH_TRAVERSAL_COST as f64 * r };
        }
        cost as f32
    }
}
