//! The static spheres of the BVH's leaves as lanes: per slot of `bvh.indices` (the order in which
//! leaves list their primitives), the sphere's centre and radius terms, so that one ray meets a
//! whole leaf's spheres in one 8-lane any-hit call ([`crate::geometry::occludes_spheres_lanes`]), and a packet
//! meets a leaf's sphere from these lanes (the intersect stage's closest-hit leaves) instead of through
//! `indices`, `bounded` and the 176-byte `Prim`: three dependent loads, each a cache miss once the scene
//! outgrows the caches (at a million spheres they were two thirds of the leaf test's time). Slots of
//! other primitives (and of moving spheres) are flagged, and their leaves test those one by one.

use super::{Prim, Shape};
use crate::accel::Bvh;
use crate::geometry::SphereConsts;
use glam::Vec3;

/// Sphere lanes of a BVH's leaf slots. Each row has 8 padding slots past the last, so an 8-lane load
/// at any leaf's first slot stays inside.
#[derive(Clone, Debug, Default)]
pub struct LeafSpheres {
    pub cx: Vec<f32>,
    pub cy: Vec<f32>,
    pub cz: Vec<f32>,
    pub r2: Vec<f32>,
    pub r2_lo: Vec<f32>,
    pub graze: Vec<f32>,
    /// Per slot `k`: bit `j` set when slot `k + j` (j < 8) is a static sphere (its lane above holds
    /// it): a leaf's sphere lanes in one load, not a loop per leaf visit.
    pub window: Vec<u8>,
    /// Per slot: the scene's prim id (`bounded[indices[k]]`, for every kind of prim), read in leaf
    /// order instead of through two dependent lookups.
    pub prim: Vec<u32>,
}

impl LeafSpheres {
    /// From the BVH over `bounded` (prim ids of the tree's indices).
    pub fn new(bvh: &Bvh, bounded: &[u32], prims: &[Prim]) -> Self {
        let n = bvh.indices.len() + 8;
        let mut s = LeafSpheres {
            cx: vec![0.0; n],
            cy: vec![0.0; n],
            cz: vec![0.0; n],
            r2: vec![0.0; n],
            r2_lo: vec![0.0; n],
            graze: vec![0.0; n],
            window: vec![0; n],
            prim: vec![0; n],
        };
        let mut sphere = vec![false; n];
        for (k, &bi) in bvh.indices.iter().enumerate() {
            s.prim[k] = bounded[bi as usize];
            let prim = &prims[s.prim[k] as usize];
            if let Shape::Sphere { center, radius } = prim.shape {
                if prim.motion == Vec3::ZERO {
                    let c = SphereConsts::of(radius);
                    (s.cx[k], s.cy[k], s.cz[k]) = (center.x, center.y, center.z);
                    (s.r2[k], s.r2_lo[k], s.graze[k], sphere[k]) = (c.r2, c.r2_lo, c.graze, true);
                }
            }
        }
        for k in 0..n {
            s.window[k] = (0..8).filter(|&j| sphere.get(k + j) == Some(&true)).fold(0, |w, j| w | 1 << j);
        }
        s
    }

    /// The static sphere in slot `k` (its bit in `window[k]` set): centre and radius terms.
    #[inline(always)]
    pub fn sphere(&self, k: usize) -> (Vec3, SphereConsts) {
        (Vec3::new(self.cx[k], self.cy[k], self.cz[k]), SphereConsts { r2: self.r2[k], r2_lo: self.r2_lo[k], graze: self.graze[k] })
    }

    /// Bits of the slots `first..first + count` (at most 8) that are static spheres.
    #[inline(always)]
    pub fn sphere_bits(&self, first: usize, count: usize) -> u32 {
        self.window[first] as u32 & ((1u32 << count) - 1)
    }
}
