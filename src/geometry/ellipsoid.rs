//! Ellipsoids: the unit sphere in object space under a general affine map.

use super::obox::{mat3_x8, object_map_f64};
use super::sphere::{intersect_sphere_f64, nearest_x8, roots_x8, GRAZE};
use super::{finish_x8, valid_f64};
use crate::simd::{f32x8, Ray8, Vec3x8};
use glam::{Affine3A, DAffine3, DVec3, Mat3, Vec3};

/// An ellipsoid: the unit sphere placed by an affine `object_to_world`. As for [`super::OBox`],
/// the kernel maps `p` to object space as `M (p - center)`, `M = world_to_object.matrix3`.
#[derive(Clone, Copy, Debug)]
pub struct Ellipsoid {
    pub world_to_object: Affine3A,
    /// Transpose of the inverse of `object_to_world`'s linear part (object normals -> world).
    pub normal_matrix: Mat3,
    /// The centre in world space (`object_to_world.translation`).
    pub center: Vec3,
    /// `object_to_world`'s linear part (object points back to world, by [`super::refine_ellipsoid_point`]).
    pub to_world: Mat3,
}

impl Ellipsoid {
    /// Place the unit sphere by `object_to_world` (must be invertible).
    pub fn new(object_to_world: Affine3A) -> Ellipsoid {
        Ellipsoid {
            world_to_object: object_to_world.inverse(),
            normal_matrix: Mat3::from(object_to_world.matrix3).inverse().transpose(),
            center: object_to_world.translation.into(),
            to_world: Mat3::from(object_to_world.matrix3),
        }
    }

    /// The map the kernel applies, `p -> M (p - center)`, in f64 (for [`intersect_ellipsoid_f64`]).
    pub fn world_to_object_f64(&self) -> DAffine3 {
        object_map_f64(Mat3::from(self.world_to_object.matrix3), self.center)
    }
}

/// Ray/ellipsoid: transform the ray to object space (`o' = M (o - center)`, `d' = M d`, same `t`)
/// and intersect the unit sphere with the stable quadratic of Haines, Guenther & Akenine-Moeller,
/// "Precision Improvements for Ray/Sphere Intersection", Ray Tracing Gems ch. 7 (2019):
/// discriminant `1 - |l|^2` from the perpendicular `l = o' - (o'.d'/d'.d') d'`, roots `c/q`,
/// `q/a`. Same tangent rule as the sphere ([`GRAZE`], with `r = 1`). `c = |o'|^2 - 1` is one
/// FMA chain (no compensation: `o'` itself already carries the transform's rounding).
#[inline]
pub fn intersect_ellipsoid_x8(e: &Ellipsoid, ray: &Ray8) -> f32x8 {
    let (near, far, hit) = ellipsoid_roots_x8(e, ray);
    finish_x8(nearest_x8(near, far), hit, ray)
}

/// Both crossings of the ellipsoid along the packet, `(entry, exit)` (any sign; NaN where a lane
/// misses), the arithmetic of [`intersect_ellipsoid_x8`].
#[inline]
pub fn ellipsoid_interval_x8(e: &Ellipsoid, ray: &Ray8) -> (f32x8, f32x8) {
    let (near, far, hit) = ellipsoid_roots_x8(e, ray);
    let nan = f32x8::splat(f32::NAN);
    (hit.select(near, nan), hit.select(far, nan))
}

#[inline(always)]
fn ellipsoid_roots_x8(e: &Ellipsoid, ray: &Ray8) -> (f32x8, f32x8, f32x8) {
    let m = Mat3::from(e.world_to_object.matrix3);
    let (r0, r1, r2) = (m.row(0), m.row(1), m.row(2));
    let w = ray.o - Vec3x8::splat(e.center);
    let o = Vec3x8::new(w.dot3(r0), w.dot3(r1), w.dot3(r2));
    let d = Vec3x8::new(ray.d.dot3(r0), ray.d.dot3(r1), ray.d.dot3(r2));
    let a = d.dot(d);
    let inv_a = f32x8::ONE / a;
    let b = o.dot(d);
    let k = b * inv_a;
    let l = Vec3x8::new(k.mul_neg_add(d.x, o.x), k.mul_neg_add(d.y, o.y), k.mul_neg_add(d.z, o.z));
    let one = f32x8::ONE;
    let disc = l.x.mul_neg_add(l.x, l.y.mul_neg_add(l.y, l.z.mul_neg_add(l.z, one)));
    let hit = disc.simd_ge(f32x8::splat(-GRAZE));
    let c = o.x.mul_add(o.x, o.y.mul_add(o.y, o.z.mul_sub(o.z, one)));
    let (near, far) = roots_x8(a, inv_a, b, disc, c);
    (near, far, hit)
}

/// f64 twin of [`intersect_ellipsoid_x8`]: transform by `world_to_object` (see
/// [`Ellipsoid::world_to_object_f64`]) and solve the textbook quadratic for the unit sphere.
pub fn intersect_ellipsoid_f64(world_to_object: DAffine3, o: DVec3, d: DVec3, tmax: f64) -> f64 {
    if !valid_f64(o, d, tmax) {
        return f64::INFINITY;
    }
    let oo = world_to_object.transform_point3(o);
    let dd = world_to_object.transform_vector3(d);
    intersect_sphere_f64(DVec3::ZERO, 1.0, oo, dd, tmax)
}

/// [`refine_ellipsoid_point`](super::refine_ellipsoid_point) and [`normal_ellipsoid`] of 8 points `p`
/// in the ellipsoid's frame (at the rays' time), the same operations lane by lane: the refined points,
/// their error magnitudes, which lanes were refined (the others' points are undefined), and the normals
/// at `at(point, refined)` (the final point taken back into the frame, as the caller moves it).
#[inline(always)]
pub fn ellipsoid_hits_x8(e: &Ellipsoid, p: Vec3x8, at: impl Fn(Vec3x8, f32x8) -> Vec3x8) -> (Vec3x8, f32x8, f32x8, Vec3x8) {
    let (m, c, zero) = (Mat3::from(e.world_to_object.matrix3), Vec3x8::splat(e.center), Vec3x8::splat(Vec3::ZERO));
    let v = mat3_x8(&m, p - c);
    // glam's `normalize_or_zero`, and the lanes where it gave zero (`refine_ellipsoid_point`'s `None`).
    let rcp = f32x8::ONE / v.dot_unfused(v).sqrt();
    let unit = rcp.is_finite() & rcp.simd_gt(f32x8::ZERO);
    let w = mat3_x8(&e.to_world, Vec3x8::select(unit, v.scale(rcp), zero));
    let out = c + w;
    let ok = unit & out.x.is_finite() & out.y.is_finite() & out.z.is_finite();
    let scale = f32x8::splat(e.center.abs().max_element()).max(w.max_abs_element());
    let q = mat3_x8(&m, at(out, ok) - c);
    (out, scale, ok, mat3_x8(&e.normal_matrix, q).normalize_or(zero))
}

/// Outward unit normal at a world point `p` on the ellipsoid: the gradient of `|M (p - c)|^2`,
/// `M^T M (p - c)`, i.e. the normal matrix applied to the object-space point.
pub fn normal_ellipsoid(e: &Ellipsoid, p: Vec3) -> Vec3 {
    let q = Mat3::from(e.world_to_object.matrix3) * (p - e.center);
    (e.normal_matrix * q).normalize_or_zero()
}
