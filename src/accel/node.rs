//! The BVH node layout: a 32-byte `Pod` contract.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

use super::Aabb;

/// Bits of `count_axis` that hold the primitive count; the top 2 bits hold the split axis.
const COUNT_BITS: u32 = 30;
const COUNT_MASK: u32 = (1 << COUNT_BITS) - 1;

/// Largest primitive count a leaf can store (30 bits), hence the largest input of `build_bvh`.
pub const MAX_LEAF_COUNT: u32 = COUNT_MASK;

/// One BVH node: `repr(C, align(32))`, `Pod`, 32 bytes, no padding. The 32-byte alignment keeps each
/// node inside one 64-byte cache line (two per line).
///
/// | bytes  | field        | content                                                              |
/// |--------|--------------|----------------------------------------------------------------------|
/// | 0..12  | `min`        | box min x, y, z (f32)                                                |
/// | 12..16 | `left_first` | inner: index of the left child (right = left + 1); leaf: index of the first primitive slot in `Bvh::indices` |
/// | 16..28 | `max`        | box max x, y, z (f32)                                                |
/// | 28..32 | `count_axis` | bits 0..30: primitive count, 0 for an inner node; bits 30..32: split axis of an inner node (0 = x, 1 = y, 2 = z), 0 in a leaf |
///
/// Layout chosen so that the box halves load as two 16-byte vectors and the leaf test is one load
/// and mask of the last word.
#[repr(C, align(32))]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct BvhNode {
    pub min: [f32; 3],
    pub left_first: u32,
    pub max: [f32; 3],
    pub count_axis: u32,
}

const _: () = assert!(std::mem::size_of::<BvhNode>() == 32);
const _: () = assert!(std::mem::align_of::<BvhNode>() == 32);

impl BvhNode {
    /// A leaf over `indices[first..first + count]`; `count` must be in `1..=MAX_LEAF_COUNT`.
    #[inline]
    pub fn leaf(b: Aabb, first: u32, count: u32) -> Self {
        debug_assert!((1..=COUNT_MASK).contains(&count));
        Self { min: b.min.to_array(), left_first: first, max: b.max.to_array(), count_axis: count & COUNT_MASK }
    }

    /// An inner node whose children are `left` and `left + 1`, split on `axis` (0..3).
    #[inline]
    pub fn inner(b: Aabb, left: u32, axis: u32) -> Self {
        debug_assert!(axis < 3);
        Self { min: b.min.to_array(), left_first: left, max: b.max.to_array(), count_axis: (axis & 3) << COUNT_BITS }
    }

    /// Primitives in a leaf; 0 for an inner node.
    #[inline(always)]
    pub fn count(&self) -> u32 {
        self.count_axis & COUNT_MASK
    }

    #[inline(always)]
    pub fn is_leaf(&self) -> bool {
        self.count() != 0
    }

    /// Split axis of an inner node (0 = x, 1 = y, 2 = z); 3 never occurs in a valid tree.
    #[inline(always)]
    pub fn axis(&self) -> u32 {
        self.count_axis >> COUNT_BITS
    }

    #[inline(always)]
    pub fn aabb(&self) -> Aabb {
        Aabb::new(Vec3::from_array(self.min), Vec3::from_array(self.max))
    }
}
