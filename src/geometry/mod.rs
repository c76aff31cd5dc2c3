//! Ray/surface intersection kernels (nearest hit) and the surface helpers a shader needs next
//! (normals, hit-point refinement, robust spawn offsets).
//!
//! Every `_x8` kernel intersects the 8 rays of a [`Ray8`] with ONE primitive whose parameters are
//! broadcast to all lanes, and returns per lane the nearest hit distance `t` with
//! `0 < t < ray.tmax`, or [`MISS`] (`+inf`). `t` is in units of the given direction (directions need
//! not be unit length). Lanes whose origin or direction has a NaN or infinite component, and lanes
//! with `tmax <= 0` or NaN, return `MISS`; no kernel ever returns NaN. Kernels are branch-free over
//! lanes (masks + select) and allocation-free.
//!
//! Each kernel has an `_f64` twin with the same contract (`INFINITY` on a miss), written
//! independently in textbook form; the tests hold the two together.
//!
//! Boundary conventions shared by all shapes:
//! - `t` must be strictly positive: a surface through the ray origin is not hit at `t = 0`; the
//!   next surface along the ray is reported instead (or MISS). Spawned rays must be offset with
//!   [`offset_ray_origin`].
//! - A ray parallel to a plane, quad or disk misses it (also when it lies in it).
//! - Boxes are closed: a ray lying exactly in a face plane is inside that slab (see `obox.rs`).
//! - Sphere and ellipsoid tangents: a computed discriminant in `[-GRAZE r^2, 0)` counts as a
//!   tangent hit (double root), below it a miss (see `sphere.rs`).
//!
//! The accuracy-critical arithmetic relies on fused multiply-add (`target-cpu=native` gives FMA;
//! `wide` falls back to an unfused multiply-add without it, which keeps every result finite but
//! loses the exact-product error terms used by the sphere kernel).

mod disk;
mod ellipsoid;
mod obox;
mod offset;
mod plane;
mod quad;
mod refine;
mod sphere;

pub use disk::{intersect_disk_f64, intersect_disk_x8, Disk};
pub use ellipsoid::{
    ellipsoid_hits_x8, ellipsoid_interval_x8, intersect_ellipsoid_f64, intersect_ellipsoid_x8, normal_ellipsoid, Ellipsoid,
};
pub use obox::{intersect_obox_f64, intersect_obox_x8, normal_obox, obox_hits_x8, obox_interval_x8, OBox};
pub use offset::{
    offset_distance, offset_distance_x8, offset_ray_origin, offset_ray_origin_scaled, offset_ray_origin_scaled_x8, ulp_at, OFFSET_ULPS,
};
pub use plane::{intersect_plane_f64, intersect_plane_x8, occludes_plane, Plane};
pub use quad::{intersect_quad_f64, intersect_quad_x8, Quad};
pub use refine::{refine_ellipsoid_point, refine_flat_point, refine_flat_point_x8, refine_obox_point};
pub use sphere::{
    intersect_sphere_f64, intersect_sphere_moving_x8, intersect_sphere_x8, normal_sphere, occludes_sphere, occludes_sphere_consts,
    occludes_sphere_x8, occludes_spheres_lanes, refine_sphere_point, refine_sphere_point_x8, sphere_interval_x8, spheres_lanes_x8,
    SphereConsts, SpherePacket, SpherePacketOf, GRAZE,
};

use crate::simd::{f32x8, Lanes, Ray8};
use glam::DVec3;

/// The "no hit" distance.
pub const MISS: f32 = f32::INFINITY;

/// Lane mask: origin and direction are entirely finite.
///
/// `x * 0` is exactly +-0 for every finite `x` and NaN for NaN and +-inf, so the fused sum of the
/// six products is 0 exactly when all six components are finite (it cannot overflow).
#[inline(always)]
pub fn ray_finite_x8(ray: &Ray8) -> f32x8 {
    ray_finite([ray.o.x, ray.o.y, ray.o.z], [ray.d.x, ray.d.y, ray.d.z])
}

/// [`ray_finite_x8`] at any lane width, from the rays' origins and directions by axis.
#[inline(always)]
pub(crate) fn ray_finite<F: Lanes>(o: [F; 3], d: [F; 3]) -> F {
    let z = F::splat(0.0);
    let s = o[0].mul_add(z, o[1].mul_add(z, o[2].mul_add(z, d[0].mul_add(z, d[1].mul_add(z, d[2] * z)))));
    s.eq(z)
}

/// The common tail of every kernel: keep `t` where the shape test passed, the ray is valid and
/// `0 < t < tmax`; MISS elsewhere. NaN `t` fails both comparisons, so NaN never escapes.
#[inline(always)]
pub(crate) fn finish_x8(t: f32x8, hit: f32x8, ray: &Ray8) -> f32x8 {
    finish_all_x8(t, ray, hit)
}

/// [`finish_x8`] for kernels whose only hit condition is the range of `t` (planes): `t` from a
/// parallel ray is +-inf or NaN and fails the range test by itself.
#[inline(always)]
pub(crate) fn finish_t_x8(t: f32x8, ray: &Ray8) -> f32x8 {
    finish_all_x8(t, ray, f32x8::splat(f32::from_bits(u32::MAX)))
}

#[inline(always)]
fn finish_all_x8(t: f32x8, ray: &Ray8, hit: f32x8) -> f32x8 {
    let ok = hit & ray_finite_x8(ray) & t.simd_gt(f32x8::ZERO) & t.simd_lt(ray.tmax);
    ok.select(t, f32x8::splat(MISS))
}

/// `a - b` as an unevaluated sum `s + e` with `s = fl(a - b)`, exactly (Knuth's branch-free
/// TwoSum; Ogita, Rump & Oishi, "Accurate Sum and Dot Product", SIAM J. Sci. Comput. 2005, alg. 3.1).
#[inline(always)]
pub(crate) fn two_diff_x8(a: f32x8, b: f32x8) -> (f32x8, f32x8) {
    two_sum(a, -b)
}

/// `a + b = s + e` exactly, `s = fl(a + b)` (Knuth TwoSum, 6 flops, no ordering requirement), at any
/// lane width.
#[inline(always)]
pub(crate) fn two_sum<F: Lanes>(a: F, b: F) -> (F, F) {
    let s = a + b;
    let bb = s - a;
    let e = (a - (s - bb)) + (b - bb);
    (s, e)
}

/// Validity of an f64 twin's input: finite origin and direction, `tmax > 0` (false for NaN).
#[inline]
pub(crate) fn valid_f64(o: DVec3, d: DVec3, tmax: f64) -> bool {
    o.is_finite() && d.is_finite() && tmax > 0.0
}

/// The nearest of two roots of an f64 twin that lies in `(0, tmax)`, or `INFINITY`.
#[inline]
pub(crate) fn nearest_f64(t0: f64, t1: f64, tmax: f64) -> f64 {
    let (lo, hi) = if t0 <= t1 { (t0, t1) } else { (t1, t0) };
    if lo > 0.0 && lo < tmax {
        lo
    } else if hi > 0.0 && hi < tmax {
        hi
    } else {
        f64::INFINITY
    }
}
