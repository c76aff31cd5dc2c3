//! Seeded random inputs shared by the BVH test files (`tests/bvh.rs`, `tests/wide_bvh.rs`) and
//! `tests/shadow_single.rs`, included
//! with `#[path]`: each file uses a different subset, hence the `dead_code` allowance.
#![allow(dead_code)]

use glam::Vec3;
use rand_core::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use strata::accel::Aabb;

pub struct Rand(pub Xoshiro256PlusPlus);

impl Rand {
    pub fn new(seed: u64) -> Self {
        Self(Xoshiro256PlusPlus::seed_from_u64(seed))
    }
    /// Uniform in [0, 1).
    pub fn f(&mut self) -> f32 {
        (self.0.next_u32() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
    }
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f()
    }
    pub fn vec(&mut self, lo: f32, hi: f32) -> Vec3 {
        Vec3::new(self.range(lo, hi), self.range(lo, hi), self.range(lo, hi))
    }
    pub fn chance(&mut self, p: f32) -> bool {
        self.f() < p
    }
    pub fn below(&mut self, n: u32) -> u32 {
        self.0.next_u32() % n
    }
    /// A direction with components in [-1, 1], length at least 0.2.
    pub fn dir(&mut self) -> Vec3 {
        loop {
            let d = self.vec(-1.0, 1.0);
            if d.length() > 0.2 {
                return d;
            }
        }
    }
}

pub fn random_boxes(rng: &mut Rand, n: usize, half_extent: f32, max_size: f32) -> Vec<Aabb> {
    (0..n)
        .map(|_| {
            let c = rng.vec(-half_extent, half_extent);
            let h = rng.vec(0.0, max_size * 0.5);
            Aabb::new(c - h, c + h)
        })
        .collect()
}

/// `n` boxes on a line with exponentially growing spacing (ratio 1.0007, the fastest that stays finite
/// in f32 over 100,000 steps): the pathological input that drives binned SAH builds deep.
pub fn exponential_line(n: i32) -> Vec<Aabb> {
    let r = 1.0007f64;
    (0..n)
        .map(|i| {
            let x = (r.powi(i) - 1.0) / (r - 1.0);
            let h = 0.25 * r.powi(i);
            Aabb::new(Vec3::new((x - h) as f32, 0.0, 0.0), Vec3::new((x + h) as f32, 1.0, 1.0))
        })
        .collect()
}
