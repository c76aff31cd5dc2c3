//! Infinite two-sided planes `normal . p = offset`.

use super::{finish_t_x8, valid_f64};
use crate::simd::{f32x8, Lanes, Ray8};
use glam::{DVec3, Vec3};

/// The plane of points `p` with `normal . p = offset`. `normal` need not be unit length (the
/// kernel divides it out); [`Plane::from_point_normal`] builds a unit-normal plane.
#[derive(Clone, Copy, Debug)]
pub struct Plane {
    pub normal: Vec3,
    pub offset: f32,
}

impl Plane {
    /// The plane through `point` with unit normal `normalize(normal)`.
    pub fn from_point_normal(point: Vec3, normal: Vec3) -> Plane {
        let n = normal.normalize_or_zero();
        Plane { normal: n, offset: n.dot(point) }
    }
}

/// Ray/plane: `t = (offset - n.o) / (n.d)`, one division (textbook; Haines, "Essential Ray
/// Tracing Algorithms", in Glassner (ed.), An Introduction to Ray Tracing, 1989, ch. 2).
/// The numerator is one FMA chain starting from `offset`, so an origin close to the plane keeps
/// the relative accuracy of its distance. A parallel ray (`n.d = 0`) gives `t = +-inf` or NaN
/// (origin in the plane: 0/0) and misses; an origin in the plane gives `t = 0` and misses.
#[inline]
pub fn intersect_plane_x8(p: &Plane, ray: &Ray8) -> f32x8 {
    let (nx, ny, nz) = (f32x8::splat(p.normal.x), f32x8::splat(p.normal.y), f32x8::splat(p.normal.z));
    let o = ray.o;
    let num = nx.mul_neg_add(o.x, ny.mul_neg_add(o.y, nz.mul_neg_add(o.z, f32x8::splat(p.offset))));
    let den = ray.d.dot3(p.normal);
    finish_t_x8(num / den, ray)
}

/// Any-hit twin of [`intersect_plane_x8`] at any lane width (rays by axis; `finite` the rays'
/// [`ray_finite`](super::ray_finite) mask): the lanes where `intersect_plane_x8(..) < tmax`, by the
/// same operations on the same operands (`MISS` is +inf, which no `tmax` of a shadow ray exceeds).
#[inline(always)]
pub fn occludes_plane<F: Lanes>(o: [F; 3], d: [F; 3], tmax: F, p: &Plane, finite: F) -> F {
    let (nx, ny, nz) = (F::splat(p.normal.x), F::splat(p.normal.y), F::splat(p.normal.z));
    let num = nx.mul_neg_add(o[0], ny.mul_neg_add(o[1], nz.mul_neg_add(o[2], F::splat(p.offset))));
    let den = d[0].mul_add(nx, d[1].mul_add(ny, d[2] * nz));
    let t = num / den;
    finite & t.gt(F::splat(0.0)) & t.lt(tmax)
}

/// f64 twin of [`intersect_plane_x8`] (textbook form, branches on the parallel case).
pub fn intersect_plane_f64(normal: DVec3, offset: f64, o: DVec3, d: DVec3, tmax: f64) -> f64 {
    if !valid_f64(o, d, tmax) {
        return f64::INFINITY;
    }
    let den = normal.dot(d);
    if den == 0.0 {
        return f64::INFINITY;
    }
    let t = (offset - normal.dot(o)) / den;
    if t > 0.0 && t < tmax {
        t
    } else {
        f64::INFINITY
    }
}
