//! Shared helpers of the CSG tests (seeded random shapes, solids and rays, interval-set measures, the full
//! boundary list of the fast path by repeated `first_hit`), and two groups of tests: `kernels`, `volumes`.
#![allow(dead_code)]

mod kernels;
mod volumes;

use glam::{Affine3A, DVec3, Quat, Vec3};
use rand_core::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use strata::csg::{first_hit, Csg, CsgArena, CsgTree, Leaf, Op, Shape};
use strata::simd::{f32x8, Ray8, Vec3x8};

/// A test ray: origin, direction, tmin, tmax.
pub type TestRay = (Vec3, Vec3, f32, f32);
/// A kernel edge case: shape, origin, direction, expected intervals (`None`: tangent, tiny or empty).
pub type EdgeCase = (Shape, Vec3, Vec3, Option<Vec<(f64, f64)>>);

pub fn leaf(shape: Shape, m: Affine3A) -> CsgTree {
    CsgTree::Leaf(Leaf::new(shape, m, 0))
}

pub fn node(op: Op, children: Vec<CsgTree>) -> CsgTree {
    CsgTree::Node { op, children }
}

/// A placement applied to a whole assembly (rotation + translation).
pub fn placement() -> Affine3A {
    Affine3A::from_rotation_translation(Quat::from_euler(glam::EulerRot::XYZ, 0.3, -0.7, 1.1), Vec3::new(0.2, -0.4, 0.3))
}

/// Pack 8 test rays into a packet and its `tmin`.
pub fn ray8(rays: &[TestRay; 8]) -> (Ray8, f32x8) {
    let lane = |f: &dyn Fn(&TestRay) -> f32| f32x8::new(std::array::from_fn(|i| f(&rays[i])));
    let o = Vec3x8::new(lane(&|r| r.0.x), lane(&|r| r.0.y), lane(&|r| r.0.z));
    let d = Vec3x8::new(lane(&|r| r.1.x), lane(&|r| r.1.y), lane(&|r| r.1.z));
    (Ray8::new(o, d, lane(&|r| r.3)), lane(&|r| r.2))
}

pub struct R(Xoshiro256PlusPlus);

impl R {
    pub fn new(seed: u64) -> R {
        R(Xoshiro256PlusPlus::seed_from_u64(seed))
    }
    /// Uniform in [0, 1).
    pub fn f(&mut self) -> f64 {
        (self.0.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
    pub fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.f()
    }
    pub fn below(&mut self, n: usize) -> usize {
        (self.f() * n as f64) as usize % n
    }
    pub fn unit(&mut self) -> DVec3 {
        loop {
            let v = DVec3::new(self.range(-1.0, 1.0), self.range(-1.0, 1.0), self.range(-1.0, 1.0));
            let l = v.length_squared();
            if l > 1e-4 && l <= 1.0 {
                return v / l.sqrt();
            }
        }
    }
    pub fn in_box(&mut self, lo: DVec3, hi: DVec3) -> DVec3 {
        DVec3::new(self.range(lo.x, hi.x), self.range(lo.y, hi.y), self.range(lo.z, hi.z))
    }
    pub fn rotation(&mut self) -> Quat {
        loop {
            let v = [self.range(-1.0, 1.0), self.range(-1.0, 1.0), self.range(-1.0, 1.0), self.range(-1.0, 1.0)];
            let l = v.iter().map(|x| x * x).sum::<f64>();
            if l > 1e-3 && l <= 1.0 {
                let s = l.sqrt();
                return Quat::from_xyzw((v[0] / s) as f32, (v[1] / s) as f32, (v[2] / s) as f32, (v[3] / s) as f32).normalize();
            }
        }
    }
    /// Rotation, non-uniform scale in [0.4, 1.4], translation in [-0.6, 0.6]^3.
    pub fn affine(&mut self) -> Affine3A {
        let s = Vec3::new(self.range(0.4, 1.4) as f32, self.range(0.4, 1.4) as f32, self.range(0.4, 1.4) as f32);
        let t = self.in_box(DVec3::splat(-0.6), DVec3::splat(0.6)).as_vec3();
        Affine3A::from_scale_rotation_translation(s, self.rotation(), t)
    }
    /// One of the five bounded shapes.
    pub fn bounded_shape(&mut self) -> Shape {
        match self.below(5) {
            0 => Shape::Sphere,
            1 => Shape::Box,
            2 => Shape::Cylinder,
            3 => {
                let r0 = if self.f() < 0.25 { 0.0 } else { self.range(0.1, 1.0) as f32 };
                Shape::Cone { r0, r1: self.range(0.1, 1.0) as f32 }
            }
            _ => {
                let major = self.range(0.6, 1.0) as f32;
                Shape::Torus { major, minor: major * self.range(0.15, 0.6) as f32 }
            }
        }
    }
    pub fn leaf(&mut self, material: u32) -> CsgTree {
        let s = self.bounded_shape();
        CsgTree::Leaf(Leaf::new(s, self.affine(), material))
    }
    /// A random bounded tree of the given depth (half-spaces only inside intersections/differences).
    pub fn tree(&mut self, depth: usize) -> CsgTree {
        if depth == 0 || self.f() < 0.2 {
            let m = self.below(8) as u32;
            return self.leaf(m);
        }
        let op = [Op::Union, Op::Intersection, Op::Difference][self.below(3)];
        let n = 2 + self.below(2);
        let mut children: Vec<CsgTree> = (0..n).map(|_| self.tree(depth - 1)).collect();
        if op != Op::Union && self.f() < 0.3 {
            let n = self.unit().as_vec3();
            children.push(CsgTree::Leaf(Leaf::half_space(n, self.range(-0.3, 0.5) as f32, 9)));
        }
        CsgTree::Node { op, children }
    }
    /// `solids` random solids of depth 3 (those with empty bounds skipped) and `packets` packets of 8 rays
    /// each ([`R::ray`]; `tmin` 0 for 60% of the rays, else in [-1, 2]; `tmax` infinite with probability
    /// `p_inf`, else `tmin` plus a length in `len`): `f(csg, solid, rays, packet, tmin)` for each packet.
    pub fn packets(
        &mut self,
        solids: usize,
        packets: usize,
        p_inf: f64,
        len: (f64, f64),
        mut f: impl FnMut(&Csg, u32, &[TestRay; 8], &Ray8, f32x8),
    ) {
        for _ in 0..solids {
            let mut csg = Csg::new();
            let s = csg.add_solid(&self.tree(3)).unwrap();
            let (lo, hi) = csg.bounds(s);
            if lo.cmpgt(hi).any() {
                continue;
            }
            for _ in 0..packets {
                let rays: [TestRay; 8] = std::array::from_fn(|_| {
                    let (o, d) = self.ray(lo, hi);
                    let tmin = if self.f() < 0.6 { 0.0 } else { self.range(-1.0, 2.0) as f32 };
                    let tmax = if self.f() < p_inf { f32::INFINITY } else { tmin + self.range(len.0, len.1) as f32 };
                    (o, d, tmin, tmax)
                });
                let (packet, tmin8) = ray8(&rays);
                f(&csg, s, &rays, &packet, tmin8);
            }
        }
    }

    /// A ray for a solid with bounds (lo, hi): half from outside aimed at the bounds, half from inside
    /// the bounds; direction length in [0.5, 2].
    pub fn ray(&mut self, lo: Vec3, hi: Vec3) -> (Vec3, Vec3) {
        let (lo, hi) = (lo.as_dvec3(), hi.as_dvec3());
        let c = 0.5 * (lo + hi);
        let r = 0.5 * (hi - lo).length();
        let target = self.in_box(lo, hi);
        let scale = self.range(0.5, 2.0);
        if self.f() < 0.5 {
            let o = c + self.unit() * (r * self.range(1.2, 3.0) + 0.5);
            (o.as_vec3(), ((target - o).normalize() * scale).as_vec3())
        } else {
            (target.as_vec3(), (self.unit() * scale).as_vec3())
        }
    }
}

/// Total length of a sorted interval list.
pub fn measure(a: &[(f64, f64)]) -> f64 {
    a.iter().map(|(x, y)| y - x).sum()
}

/// Length of `a \ b` (both sorted, disjoint).
pub fn minus_measure(a: &[(f64, f64)], b: &[(f64, f64)]) -> f64 {
    let mut total = 0.0;
    for &(a0, a1) in a {
        let mut covered = 0.0;
        for &(b0, b1) in b {
            let (x, y) = (a0.max(b0), a1.min(b1));
            if y > x {
                covered += y - x;
            }
        }
        total += (a1 - a0) - covered;
    }
    total
}

/// Length of the symmetric difference.
pub fn sym_diff(a: &[(f64, f64)], b: &[(f64, f64)]) -> f64 {
    minus_measure(a, b) + minus_measure(b, a)
}

/// Intervals of the fast path, by walking `first_hit` from `tmin = -1e6` (pairs of entry/exit; an
/// unpaired or misordered list is returned as `None`).
pub fn fast_intervals(csg: &Csg, solid: u32, o: Vec3, d: Vec3, arena: &mut CsgArena) -> Option<Vec<(f64, f64)>> {
    let mut t = -1e6f32;
    let mut out = Vec::new();
    let mut entry: Option<f64> = None;
    for _ in 0..1000 {
        let Some(h) = first_hit(csg, solid, o, d, t, f32::INFINITY, arena) else {
            return if entry.is_none() { Some(out) } else { None };
        };
        match (h.entering, entry) {
            (true, None) => entry = Some(h.t as f64),
            (false, Some(e)) => {
                out.push((e, h.t as f64));
                entry = None;
            }
            _ => return None,
        }
        t = h.t;
    }
    None
}

/// The boundary `(t, entering)` list of intervals.
pub fn boundaries(iv: &[(f64, f64)]) -> Vec<(f64, bool)> {
    iv.iter().flat_map(|&(a, b)| [(a, true), (b, false)]).collect()
}

/// Ray scale used by the tolerance: `max(1, |o|) / |d|`.
pub fn scale(o: Vec3, d: Vec3) -> f64 {
    (o.length().max(1.0) / d.length()) as f64
}

pub fn dv(v: Vec3) -> DVec3 {
    v.as_dvec3()
}
