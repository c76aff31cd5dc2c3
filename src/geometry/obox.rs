//! Oriented boxes: the axis-aligned box `[-half, half]` in object space, placed in the world by an
//! affine transform (rotation, translation, non-uniform scale, shear).

use super::{finish_x8, nearest_f64, valid_f64};
use crate::simd::{f32x8, Ray8, Vec3x8};
use glam::{Affine3A, DAffine3, DMat3, DVec3, Mat3, Vec3};

/// An oriented box. The kernel maps a world point `p` to object space as `M (p - center)` with
/// `M = world_to_object.matrix3`: subtracting the centre first keeps the object coordinates of
/// points near a box far from the world origin accurate to `eps |p - center|` instead of
/// `eps |p|` (`world_to_object.translation = -M center` is kept for callers).
#[derive(Clone, Copy, Debug)]
pub struct OBox {
    pub world_to_object: Affine3A,
    /// Transpose of the inverse of `object_to_world`'s linear part (object normals -> world).
    pub normal_matrix: Mat3,
    /// The box centre in world space (`object_to_world.translation`).
    pub center: Vec3,
    /// `object_to_world`'s linear part (object points back to world, by [`super::refine_obox_point`]).
    pub to_world: Mat3,
    pub half: Vec3,
}

impl OBox {
    /// Place the box `[-half, half]` by `object_to_world` (must be invertible; a singular
    /// transform gives non-finite fields and a box that is never hit).
    pub fn new(object_to_world: Affine3A, half: Vec3) -> OBox {
        OBox {
            world_to_object: object_to_world.inverse(),
            normal_matrix: Mat3::from(object_to_world.matrix3).inverse().transpose(),
            center: object_to_world.translation.into(),
            half,
            to_world: Mat3::from(object_to_world.matrix3),
        }
    }

    /// The map the kernel actually applies, `p -> M (p - center)`, as an f64 affine (the f32
    /// matrix entries are exact in f64; the translation `-M center` is rounded once, in f64).
    /// Use it with [`intersect_obox_f64`] to get the reference for this box.
    pub fn world_to_object_f64(&self) -> DAffine3 {
        object_map_f64(Mat3::from(self.world_to_object.matrix3), self.center)
    }
}

pub(super) fn object_map_f64(m: Mat3, center: Vec3) -> DAffine3 {
    let m = DMat3::from_cols(m.x_axis.as_dvec3(), m.y_axis.as_dvec3(), m.z_axis.as_dvec3());
    DAffine3 { matrix3: m, translation: -(m * center.as_dvec3()) }
}

/// Ray/oriented box: transform the ray to object space (`o' = M (o - center)`, `d' = M d`;
/// `t` is unchanged by an affine map) and run the slab test (Kay & Kajiya, "Ray Tracing Complex
/// Scenes", SIGGRAPH 1986), choosing each slab's near/far plane by the sign of `1 / d'_i`
/// (Williams, Barrus, Morley & Shirley, "An Efficient and Robust Ray-Box Intersection
/// Algorithm", JGT 2005).
///
/// IEEE handling: `1 / d'_i` is `+-inf` for `d'_i = +-0`, and the sign test is on `1 / d'_i`, so
/// `-0` goes the right way. A ray parallel to slab `i` then gets `(-inf, +inf)` from inside the
/// slab and an empty interval from outside it. The only NaN is `0 * inf` when the origin lies
/// exactly on a face plane of a slab the ray is parallel to (it lies IN the face plane). That NaN
/// is dropped by the reductions: `wide`'s `max`/`min` return the non-NaN operand (IEEE
/// maxNum/minNum; asserted by a test), so that slab constrains nothing, i.e. a box is CLOSED and
/// the ray counts as inside the slab. (All three slabs NaN needs `d' = 0`: the lane misses.)
/// An origin exactly on a face with the ray going inward reports the exit on the far side (the
/// entry is at `t = 0`, not `> 0`); going outward it misses. A ray lying in a face plane reports
/// where it enters the face rectangle, or, starting inside it, where it leaves it.
#[inline]
pub fn intersect_obox_x8(b: &OBox, ray: &Ray8) -> f32x8 {
    let ([nx, ny, nz], [fx, fy, fz]) = obox_slabs_x8(b, ray);
    let (tnear, tfar) = (nx.max(ny).max(nz), fx.min(fy).min(fz));
    let t = tnear.simd_gt(f32x8::ZERO).select(tnear, tfar);
    finish_x8(t, tnear.simd_le(tfar), ray)
}

/// Entry and exit of the box along the packet (any sign; NaN where a lane misses), from the one slab
/// computation of [`intersect_obox_x8`], with the object axis (0, 1, 2) of the face each is on: the
/// slab entered last and the slab left first (at an edge, the slab the kernel decided by; the point
/// alone cannot tell the faces apart there).
#[inline]
pub fn obox_interval_x8(b: &OBox, ray: &Ray8) -> (f32x8, f32x8, [u32; 8], [u32; 8]) {
    let ([nx, ny, nz], [fx, fy, fz]) = obox_slabs_x8(b, ray);
    let (tnear, tfar) = (nx.max(ny).max(nz), fx.min(fy).min(fz));
    let (hit, nan) = (tnear.simd_le(tfar), f32x8::splat(f32::NAN));
    let axis = |x: f32x8, y: f32x8, t: f32x8| {
        let (bx, by) = (x.simd_eq(t).to_bitmask(), y.simd_eq(t).to_bitmask());
        std::array::from_fn(|l| {
            if bx & (1 << l) != 0 {
                0
            } else if by & (1 << l) != 0 {
                1
            } else {
                2
            }
        })
    };
    (hit.select(tnear, nan), hit.select(tfar, nan), axis(nx, ny, tnear), axis(fx, fy, tfar))
}

/// Entry and exit distances of the three slabs of the box (object axes x, y, z).
#[inline(always)]
fn obox_slabs_x8(b: &OBox, ray: &Ray8) -> ([f32x8; 3], [f32x8; 3]) {
    let m = Mat3::from(b.world_to_object.matrix3);
    let (r0, r1, r2) = (m.row(0), m.row(1), m.row(2));
    let w = ray.o - Vec3x8::splat(b.center);
    let (nx, fx) = slab_x8(w.dot3(r0), ray.d.dot3(r0), b.half.x);
    let (ny, fy) = slab_x8(w.dot3(r1), ray.d.dot3(r1), b.half.y);
    let (nz, fz) = slab_x8(w.dot3(r2), ray.d.dot3(r2), b.half.z);
    ([nx, ny, nz], [fx, fy, fz])
}

/// Entry and exit of one slab `[-h, h]` along `o + t d` (object space).
#[inline(always)]
fn slab_x8(o: f32x8, d: f32x8, h: f32) -> (f32x8, f32x8) {
    let inv = f32x8::ONE / d;
    let h = f32x8::splat(h);
    let t_lo = (-h - o) * inv;
    let t_hi = (h - o) * inv;
    let neg = inv.simd_lt(f32x8::ZERO); // true for d = -0 too (inv = -inf)
    (neg.select(t_hi, t_lo), neg.select(t_lo, t_hi))
}

/// f64 twin of [`intersect_obox_x8`]: `world_to_object` (see [`OBox::world_to_object_f64`]) and
/// the textbook slab loop with an explicit parallel-ray branch (closed box: a parallel ray with
/// `-h <= o'_i <= h` is inside slab `i`).
pub fn intersect_obox_f64(world_to_object: DAffine3, half: DVec3, o: DVec3, d: DVec3, tmax: f64) -> f64 {
    if !valid_f64(o, d, tmax) {
        return f64::INFINITY;
    }
    let oo = world_to_object.transform_point3(o);
    let dd = world_to_object.transform_vector3(d);
    let (mut tn, mut tf) = (f64::NEG_INFINITY, f64::INFINITY);
    for i in 0..3 {
        if dd[i] == 0.0 {
            if oo[i] < -half[i] || oo[i] > half[i] {
                return f64::INFINITY;
            }
            continue;
        }
        let t1 = (-half[i] - oo[i]) / dd[i];
        let t2 = (half[i] - oo[i]) / dd[i];
        tn = tn.max(t1.min(t2));
        tf = tf.min(t1.max(t2));
    }
    if tn > tf {
        return f64::INFINITY;
    }
    nearest_f64(tn, tf, tmax)
}

/// `Mat3 * Vec3` in 8 lanes, as glam rounds it: `(x v.x + y v.y) + z v.z`, no FMA.
#[inline(always)]
pub(crate) fn mat3_x8(m: &Mat3, v: Vec3x8) -> Vec3x8 {
    Vec3x8::splat(m.x_axis).scale(v.x) + Vec3x8::splat(m.y_axis).scale(v.y) + Vec3x8::splat(m.z_axis).scale(v.z)
}

/// [`obox_face`] of 8 world points: their object points and the face axis as three lane masks.
#[inline(always)]
fn obox_face_x8(b: &OBox, p: Vec3x8) -> (Vec3x8, [f32x8; 3]) {
    let q = mat3_x8(&Mat3::from(b.world_to_object.matrix3), p - Vec3x8::splat(b.center));
    let (rx, ry, rz) = ((q.x / f32x8::splat(b.half.x)).abs(), (q.y / f32x8::splat(b.half.y)).abs(), (q.z / f32x8::splat(b.half.z)).abs());
    let x = rx.simd_ge(ry) & rx.simd_ge(rz);
    let y = !x & ry.simd_ge(rz);
    (q, [x, y, !(x | y)])
}

/// [`normal_obox`] and [`super::refine_obox_point`] of 8 world points `p` at once, rounded as they
/// round them: the refined points, their error magnitudes, the lanes where the refinement is defined
/// (finite), and the normals at `at(refined or p)` (the scalar code takes the normal at the refined
/// point, moved by the caller's shift: `at` gives that point).
#[inline]
pub fn obox_hits_x8(b: &OBox, p: Vec3x8, at: impl Fn(Vec3x8, f32x8) -> Vec3x8) -> (Vec3x8, f32x8, f32x8, Vec3x8) {
    let (zero, one) = (f32x8::ZERO, f32x8::ONE);
    let (q, axis) = obox_face_x8(b, p);
    // The face's coordinate set to `+-half` (`q < 0` gives the minus side).
    let onto = |v: f32x8, h: f32, on: f32x8| on.select(v.simd_lt(zero).select(f32x8::splat(-h), f32x8::splat(h)), v);
    let moved = Vec3x8::new(onto(q.x, b.half.x, axis[0]), onto(q.y, b.half.y, axis[1]), onto(q.z, b.half.z, axis[2]));
    let w = mat3_x8(&b.to_world, moved);
    let out = Vec3x8::splat(b.center) + w;
    let ok = out.x.is_finite() & out.y.is_finite() & out.z.is_finite();
    let scale = f32x8::splat(b.center.abs().max_element()).max(w.max_abs_element());
    let (qn, axis) = obox_face_x8(b, at(out, ok));
    let sign = |v: f32x8| v.simd_lt(zero).select(-one, one);
    let col = |i: usize, s: f32x8| Vec3x8::splat(b.normal_matrix.col(i)).scale(s);
    let n = Vec3x8::select(axis[0], col(0, sign(qn.x)), Vec3x8::select(axis[1], col(1, sign(qn.y)), col(2, sign(qn.z))));
    (out, scale, ok, n.normalize_or(Vec3x8::splat(Vec3::ZERO)))
}

/// Outward unit normal at a world point `p` on the box: the face whose object-space coordinate
/// is closest to `+-half` relative to `half` (largest `|p'_i| / half_i`), mapped by the normal
/// matrix.
pub fn normal_obox(b: &OBox, p: Vec3) -> Vec3 {
    let (q, i) = obox_face(b, p);
    let sign = if q[i] < 0.0 { -1.0 } else { 1.0 };
    (b.normal_matrix.col(i) * sign).normalize_or_zero()
}

/// A world point `p` in the box's object frame (`q`, the box `[-half, half]`) and the axis of the face it
/// lies on: the largest `|q_i| / half_i` (the face [`normal_obox`] and `refine_obox_point` take).
#[inline]
pub(crate) fn obox_face(b: &OBox, p: Vec3) -> (Vec3, usize) {
    let q = Mat3::from(b.world_to_object.matrix3) * (p - b.center);
    let r = (q / b.half).abs();
    let i = if r.x >= r.y && r.x >= r.z {
        0
    } else if r.y >= r.z {
        1
    } else {
        2
    };
    (q, i)
}
