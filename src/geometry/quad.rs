//! Parallelograms `origin + a u + b v`, `a, b in [0, 1]` (edges included).

use super::{finish_x8, valid_f64};
use crate::simd::{f32x8, Ray8, Vec3x8};
use glam::{DVec3, Vec3};

/// A parallelogram. Build it with [`Quad::new`], which precomputes the unit normal and the dual
/// (reciprocal) basis of `(u, v)` in the plane: for `p` in the plane, `a = (p - origin) . dual_u`
/// and `b = (p - origin) . dual_v`.
#[derive(Clone, Copy, Debug)]
pub struct Quad {
    pub origin: Vec3,
    pub u: Vec3,
    pub v: Vec3,
    /// `normalize(u x v)`.
    pub unit_normal: Vec3,
    /// `(v x n) / |n|^2` with `n = u x v`: `dual_u . u = 1`, `dual_u . v = 0`.
    pub dual_u: Vec3,
    /// `(n x u) / |n|^2`: `dual_v . v = 1`, `dual_v . u = 0`.
    pub dual_v: Vec3,
    /// `|u x v|`.
    pub area: f32,
}

impl Quad {
    /// Precompute normal and dual basis, in f64: `|u x v|^2` is a fourth power of the sides, which
    /// overflows f32 past sides of ~1e9 and underflows it below ~1e-10 (a quad light of a scene scaled
    /// by 1e12 or 1e-12, a user trial), where the results (a unit vector, `1 / |u|`) are well inside
    /// f32's range. Degenerate `u x v = 0` gives NaN fields: such a quad is never hit.
    pub fn new(origin: Vec3, u: Vec3, v: Vec3) -> Quad {
        let (ud, vd) = (u.as_dvec3(), v.as_dvec3());
        let n = ud.cross(vd);
        let nn = n.dot(n);
        let (unit_normal, dual_u, dual_v) = (n / nn.sqrt(), vd.cross(n) / nn, n.cross(ud) / nn);
        let (unit_normal, dual_u, dual_v, area) = (unit_normal.as_vec3(), dual_u.as_vec3(), dual_v.as_vec3(), nn.sqrt() as f32);
        Quad { origin, u, v, unit_normal, dual_u, dual_v, area }
    }

    /// Unit normal `normalize(u x v)` (the caller flips it to face the ray).
    #[inline]
    pub fn normal(&self) -> Vec3 {
        self.unit_normal
    }

    /// Area `|u x v|`.
    #[inline]
    pub fn area(&self) -> f32 {
        self.area
    }
}

/// Ray/parallelogram: plane hit `t = -(n.w) / (n.d)` with `w = o - origin`, then the in-plane
/// coordinates from the dual basis, `a = w.dual_u + t (d.dual_u)` (one FMA), likewise `b`
/// (the dual-vector form of Shirley, Black & Hollasch, "Ray Tracing: The Next Week", v4, 2024,
/// "Quadrilaterals"). One division. Parallel rays give `t = +-inf`/NaN and miss; edges are
/// inclusive.
#[inline]
pub fn intersect_quad_x8(q: &Quad, ray: &Ray8) -> f32x8 {
    let w = ray.o - Vec3x8::splat(q.origin);
    let d = ray.d;
    let t = -w.dot3(q.unit_normal) / d.dot3(q.unit_normal);
    let a = t.mul_add(d.dot3(q.dual_u), w.dot3(q.dual_u));
    let b = t.mul_add(d.dot3(q.dual_v), w.dot3(q.dual_v));
    let (zero, one) = (f32x8::ZERO, f32x8::ONE);
    let inside = a.simd_ge(zero) & a.simd_le(one) & b.simd_ge(zero) & b.simd_le(one);
    finish_x8(t, inside, ray)
}

/// f64 twin of [`intersect_quad_x8`], written as Moeller & Trumbore ("Fast, Minimum Storage
/// Ray/Triangle Intersection", JGT 1997) with the triangle's `u + v <= 1` replaced by `v <= 1`:
/// Cramer's rule on `o + t d = origin + a u + b v`.
pub fn intersect_quad_f64(origin: DVec3, u: DVec3, v: DVec3, o: DVec3, d: DVec3, tmax: f64) -> f64 {
    if !valid_f64(o, d, tmax) {
        return f64::INFINITY;
    }
    let pvec = d.cross(v);
    let det = u.dot(pvec);
    if det == 0.0 {
        return f64::INFINITY;
    }
    let inv = 1.0 / det;
    let tvec = o - origin;
    let a = tvec.dot(pvec) * inv;
    let qvec = tvec.cross(u);
    let b = d.dot(qvec) * inv;
    let t = v.dot(qvec) * inv;
    if (0.0..=1.0).contains(&a) && (0.0..=1.0).contains(&b) && t > 0.0 && t < tmax {
        t
    } else {
        f64::INFINITY
    }
}
