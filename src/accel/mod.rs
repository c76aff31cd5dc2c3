//! Bounding volume hierarchies: a binary tree (binned SAH build, packet and group traversal) and an
//! wide tree collapsed from it (16 children per node with AVX-512, else 8; 8-ray packet and single-ray
//! traversal).
//!
//! - `aabb.rs`: the box type and the ray-box slab kernels (`intersect_aabb_x8` and its f64 twin).
//! - `node.rs`: the 32-byte node layout, a `Pod` contract.
//! - `build.rs`: binned SAH build (Wald 2007, "On fast Construction of SAH-based Bounding Volume
//!   Hierarchies"), large subtrees in parallel, with a median-split fallback that bounds the depth.
//! - `traverse.rs`: closest-hit and any-hit traversal of 8-ray packets, and a scalar f64 reference.
//! - `group.rs`: traversal of up to 16 packets together through the binary tree (shadow rays, and the
//!   octant-sorted incoherent rays of trees under `WIDE_MIN_NODES`).
//! - `wide_group.rs`: closest-hit traversal of up to 32 packets together through the wide tree, by an
//!   interval test of a node's children at once (camera rays).
//! - `validate.rs`: `validate()` (tree invariants), `depth()`, `sah_cost()`.
//! - `wide.rs`: [`WideBvh`], [`WIDTH`] (16 or 8) children per node (a `32 * WIDTH`-byte `Pod` node:
//!   child boxes as 6 rows of `WIDTH` floats, one vector register each), collapsed from a built [`Bvh`] (greedy, or SAH-optimal as scenes do), its `validate()`
//!   and `sah_cost()`, and [`WIDE_MIN_NODES`], the tree size from which incoherent rays take it.
//! - `wide_traverse.rs`: the wide tree's node kernel (one ray against a node's boxes, one vector per
//!   plane, the same padded distances as `intersect_aabb_x8`), closest-hit traversal of 8-ray packets
//!   whose lanes enter children separately (the intersect stage's path for incoherent rays), and
//!   closest-hit and any-hit traversal of one ray.
//!
//! Conventions a caller must know:
//! - The BVH knows only boxes. Primitives are identified by their index into the `bounds` slice given
//!   to [`build_bvh`]; leaves reference them through `Bvh::indices`, so a renderer may reorder its
//!   primitive arrays by `indices` once after the build and then read leaf ranges contiguously. A
//!   [`WideBvh`] keeps the binary tree's leaves (same `indices` ranges), so it reports the same ids.
//! - Node 0 is the root. The children of an inner node are adjacent: right = left + 1. A wide node's
//!   children fill its first slots; empty slots hold the box (+inf, -inf), which no ray enters.
//! - Depth (levels, root = 1) is at most [`MAX_DEPTH`], so traversal uses a fixed stack of
//!   `MAX_DEPTH` entries and never allocates; the wide tree is no deeper, and its traversals take a
//!   caller-owned [`WideStack`] (`(WIDTH - 1) * MAX_DEPTH + 1` entries), allocated once per caller.
//! - A packet lane is inactive when its `tmax < 0` (the team's convention is `-1`).

mod aabb;
mod build;
mod group;
mod light_buffer;
mod node;
mod traverse;
mod validate;
mod wide;
mod wide_group;
mod wide_traverse;

pub use aabb::{intersect_aabb_f64, intersect_aabb_x8, slab_interval_f64, Aabb, PacketRay, INV_D_CLAMP};
pub use build::build_bvh;
pub use group::GROUP;
pub use light_buffer::{Bound, LightBuffer, NO_CELL};
pub use node::{BvhNode, MAX_LEAF_COUNT};
pub use wide::{Collapse, NodeF, NodeI, WideBvh, WideNode, WIDE_MIN_NODES, WIDTH};
pub use wide_group::WIDE_GROUP;
pub use wide_traverse::{intersect_children_single, transpose8x8, WideStack};

/// Maximum number of levels of a built tree (a root-only tree has depth 1). The build guarantees it
/// by switching to object-median splits when an SAH split would leave too few levels; traversal
/// relies on it for its fixed-size stack (at most `MAX_DEPTH - 1` far children are pending at once).
pub const MAX_DEPTH: usize = 64;

/// SAH cost of visiting an inner node (one packet box test), relative to [`SAH_INTERSECT_COST`].
pub const SAH_TRAVERSAL_COST: f32 = 1.0;
/// SAH cost of testing one primitive.
pub const SAH_INTERSECT_COST: f32 = 1.0;

/// Build parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuildOptions {
    /// Largest leaf the build creates (clamped to `1..=MAX_LEAF_COUNT`); larger leaves occur only
    /// when all their primitives have bit-identical centroids (binning cannot separate them and the
    /// SAH prefers one leaf to a split whose children have the parent's box).
    pub max_leaf: u32,
    /// SAH bins per axis (clamped to `2..=64`).
    pub bins: u32,
}

impl Default for BuildOptions {
    fn default() -> Self {
        Self { max_leaf: 4, bins: 16 }
    }
}

/// A built hierarchy. `nodes[0]` is the root; an empty `nodes` is an empty tree that hits nothing.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Bvh {
    pub nodes: Vec<BvhNode>,
    /// Primitive indices, grouped by leaf: a leaf owns `indices[first..first + count]`.
    pub indices: Vec<u32>,
    /// The `max_leaf` the tree was built with (after clamping); `validate` checks leaves against it.
    pub max_leaf: u32,
}

impl Bvh {
    /// True when the tree holds no primitive.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Calls `f` with every primitive id (as given to the build) of the leaves whose boxes meet the
    /// closed box `lo..hi`: a superset of the primitives whose own boxes meet it, which the caller
    /// tests. `stack` is scratch space.
    pub fn for_each_in_box(&self, lo: glam::Vec3, hi: glam::Vec3, stack: &mut Vec<u32>, mut f: impl FnMut(u32)) {
        if self.is_empty() {
            return;
        }
        stack.clear();
        stack.push(0);
        while let Some(n) = stack.pop() {
            let node = &self.nodes[n as usize];
            let (nmin, nmax) = (glam::Vec3::from_array(node.min), glam::Vec3::from_array(node.max));
            if nmin.cmpgt(hi).any() || nmax.cmplt(lo).any() {
                continue;
            }
            if node.is_leaf() {
                for &k in &self.indices[node.left_first as usize..(node.left_first + node.count()) as usize] {
                    f(k);
                }
            } else {
                stack.extend([node.left_first, node.left_first + 1]);
            }
        }
    }
}
