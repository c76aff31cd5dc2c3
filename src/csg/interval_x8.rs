//! Leaf crossing kernels over 8 lanes, in object space (canonical forms in `solid.rs`).
//!
//! Every kernel returns the parameter interval(s) of the whole line `o + t d` (`t` over all reals, `d` not
//! unit) that lie inside the solid. The common output is [`Cross8`] = `[a0, b0, a1, b1]`: up to two
//! intervals `[a0, b0]`, `[a1, b1]` with `a0 < b0 <= a1 < b1`; an absent interval has NaN ends. Only the
//! torus (in `quartic.rs`) uses the second one; the half-space uses `±inf` ends. Tangent rays (zero-length
//! intervals) report nothing. Each kernel has an f64 twin in `reference.rs` that follows the same steps.
//!
//! Quadrics use the stable root pair `q = -(b + sign(b) sqrt(disc))`, `t = q / a` and `t = c / q`
//! (Press et al., Numerical Recipes, §5.6), with the discriminant of the sphere and cylinder taken as
//! `a (1 - |f|²)`, `f` the point of the line closest to the axis, which removes the cancellation of
//! `b² - a c` for distant origins (Haines et al., "Precision Improvements for Ray/Sphere Intersection",
//! Ray Tracing Gems, 2019). The cone first moves the origin to the point of the line closest to the
//! object-space origin, for the same reason.

use super::quartic::torus_x8;
use super::solid::{cone_line, Leaf, Shape};
use crate::simd::{f32x8, Vec3x8};
use glam::{Affine3A, Vec3};

/// Crossings of one leaf for 8 rays: `[a0, b0, a1, b1]`, NaN for absent intervals.
pub type Cross8 = [f32x8; 4];

const NAN: f32x8 = f32x8::NAN;
const INF: f32x8 = f32x8::INFINITY;
const NEG_INF: f32x8 = f32x8::NEG_INFINITY;

/// Take a world-space packet to the leaf's object space (the direction is not renormalised).
#[inline]
pub fn object_ray_x8(w2o: &Affine3A, o: &Vec3x8, d: &Vec3x8) -> (Vec3x8, Vec3x8) {
    let m = &w2o.matrix3;
    let cx = Vec3x8::splat(Vec3::from(m.x_axis));
    let cy = Vec3x8::splat(Vec3::from(m.y_axis));
    let cz = Vec3x8::splat(Vec3::from(m.z_axis));
    let dd = cx.scale(d.x) + cy.scale(d.y) + cz.scale(d.z);
    let oo = cz.mul_add(o.z, cy.mul_add(o.y, cx.mul_add(o.x, Vec3x8::splat(Vec3::from(w2o.translation)))));
    (oo, dd)
}

/// Crossings of a leaf for a world-space packet.
#[inline]
pub fn leaf_x8(leaf: &Leaf, o: &Vec3x8, d: &Vec3x8) -> Cross8 {
    let (o, d) = object_ray_x8(leaf.world_to_object(), o, d);
    let (a, b) = match leaf.shape {
        Shape::Sphere => sphere_x8(o, d),
        Shape::Box => box_x8(o, d),
        Shape::Cylinder => cylinder_x8(o, d),
        Shape::Cone { r0, r1 } => cone_x8(o, d, r0, r1),
        Shape::HalfSpace => half_space_x8(o, d),
        Shape::Torus { major, minor } => return torus_x8(o, d, major, minor),
    };
    [a, b, NAN, NAN]
}

/// Roots of `a t² + 2 b t + c` for `a > 0`, as (smaller, larger); NaN where `disc <= 0` (miss or tangent).
#[inline(always)]
fn quadratic_x8(a: f32x8, b: f32x8, c: f32x8, disc: f32x8) -> (f32x8, f32x8) {
    let sq = disc.max(f32x8::ZERO).sqrt();
    let q = -(b + sq.flip_signs(b));
    let (r1, r2) = (q / a, c / q);
    let (lo, hi) = (r1.min(r2), r1.max(r2));
    let ok = disc.simd_gt(f32x8::ZERO) & lo.simd_lt(hi);
    (ok.select(lo, NAN), ok.select(hi, NAN))
}

/// Unit sphere.
#[inline]
pub fn sphere_x8(o: Vec3x8, d: Vec3x8) -> (f32x8, f32x8) {
    let a = d.dot(d);
    let b = o.dot(d);
    let c = o.dot(o) - f32x8::ONE;
    let f = d.mul_add(-(b / a), o);
    let disc = a * (f32x8::ONE - f.dot(f));
    quadratic_x8(a, b, c, disc)
}

/// Slab `|x| <= 1` along one axis: (entry, exit), `(-inf, inf)` when parallel inside, an empty pair when
/// parallel outside or exactly in a face plane (the `0 * inf = NaN` there is dropped by `min`/`max`).
#[inline(always)]
fn slab_x8(o: f32x8, d: f32x8) -> (f32x8, f32x8) {
    let inv = f32x8::ONE / d;
    let t1 = (-f32x8::ONE - o) * inv;
    let t2 = (f32x8::ONE - o) * inv;
    (t1.min(t2), t1.max(t2))
}

/// The cube `[-1, 1]^3` (slab method, Kay and Kajiya 1986).
#[inline]
pub fn box_x8(o: Vec3x8, d: Vec3x8) -> (f32x8, f32x8) {
    let (x0, x1) = slab_x8(o.x, d.x);
    let (y0, y1) = slab_x8(o.y, d.y);
    let (z0, z1) = slab_x8(o.z, d.z);
    let enter = x0.max(y0).max(z0);
    let exit = x1.min(y1).min(z1);
    let ok = enter.simd_lt(exit);
    (ok.select(enter, NAN), ok.select(exit, NAN))
}

/// Capped cylinder: radius 1 around z, `|z| <= 1`.
#[inline]
pub fn cylinder_x8(o: Vec3x8, d: Vec3x8) -> (f32x8, f32x8) {
    let a = d.x.mul_add(d.x, d.y * d.y);
    let b = o.x.mul_add(d.x, o.y * d.y);
    let c = o.x.mul_add(o.x, o.y * o.y) - f32x8::ONE;
    let s = -(b / a);
    let (fx, fy) = (d.x.mul_add(s, o.x), d.y.mul_add(s, o.y));
    let disc = a * (f32x8::ONE - fx.mul_add(fx, fy * fy));
    let (l0, l1) = quadratic_x8(a, b, c, disc);
    // Parallel to the axis: inside the whole line or nowhere.
    let par = a.simd_eq(f32x8::ZERO);
    let inside = c.simd_le(f32x8::ZERO);
    let l0 = par.select(inside.select(NEG_INF, NAN), l0);
    let l1 = par.select(inside.select(INF, NAN), l1);
    let (z0, z1) = slab_x8(o.z, d.z);
    let enter = l0.max(z0);
    let exit = l1.min(z1);
    // NaN lateral ends make the comparisons false (min/max would have dropped them).
    let ok = l0.simd_le(l1) & enter.simd_lt(exit);
    (ok.select(enter, NAN), ok.select(exit, NAN))
}

/// Capped cone frustum: radius `r0` at `z = -1`, `r1` at `z = +1`.
///
/// The lateral quadric `x² + y² - (m z + k)²` is a double cone; the slab `|z| <= 1` holds only the nappe
/// with `m z + k >= 0` (both radii are non-negative), so the frustum is the slab intersected with the
/// quadric's inside. Along a line that inside is `[lo, hi]` when `A >= 0` and `(-inf, lo] ∪ [hi, inf)`
/// when `A < 0`; within the slab at most one of the two pieces survives (up to rounding at the apex,
/// where their hull is taken).
#[inline]
pub fn cone_x8(o: Vec3x8, d: Vec3x8, r0: f32, r1: f32) -> (f32x8, f32x8) {
    let (m, k) = cone_line(r0, r1);
    let (m, k) = (f32x8::splat(m), f32x8::splat(k));
    let ts = -(o.dot(d) / d.dot(d));
    let o = d.mul_add(ts, o);
    let w = m.mul_add(o.z, k);
    let mdz = m * d.z;
    // `+ 0` turns -0 into +0 so that `A = 0` (ray parallel to a generator) behaves as `A > 0` below.
    let a = d.x.mul_add(d.x, d.y.mul_add(d.y, -(mdz * mdz))) + f32x8::ZERO;
    let b = o.x.mul_add(d.x, o.y.mul_add(d.y, -(mdz * w)));
    let c = o.x.mul_add(o.x, o.y.mul_add(o.y, -(w * w)));
    let ac = a * c;
    let disc = b.mul_add(b, -ac);
    // A discriminant within rounding of 0 is a double root: through the apex (or tangent) the two roots
    // are sqrt(eps)-sensitive, and snapping makes a ray through the apex see the whole nappe.
    let noise = f32x8::splat(4.0 * f32::EPSILON) * b.mul_add(b, ac.abs());
    let disc = disc.abs().simd_le(noise).select(f32x8::ZERO, disc);
    let sq = disc.max(f32x8::ZERO).sqrt();
    let q = -(b + sq.flip_signs(b));
    let (r1, r2) = (q / a, c / q);
    let (lo, hi) = (r1.min(r2), r1.max(r2));
    let neg = disc.simd_lt(f32x8::ZERO);
    let two_rays = a.simd_lt(f32x8::ZERO);
    // Missing roots: the whole line (two-ray form) or nothing (interval form).
    let lo = neg.select(INF, lo);
    let hi = neg.select(two_rays.select(INF, NEG_INF), hi);
    // A = B = 0: the quadric is constant along the line.
    let flat = a.simd_eq(f32x8::ZERO) & b.simd_eq(f32x8::ZERO);
    let inside = c.simd_le(f32x8::ZERO);
    let lo = flat.select(inside.select(NEG_INF, INF), lo);
    let hi = flat.select(inside.select(INF, NEG_INF), hi);
    let (s0, s1) = slab_x8(o.z, d.z);
    // Interval form.
    let e1 = s0.max(lo);
    let x1 = s1.min(hi);
    // Two-ray form: [s0, min(s1, lo)] and [max(s0, hi), s1], hull of the non-empty ones.
    let cut_lo = s1.min(lo);
    let cut_hi = s0.max(hi);
    let v1 = s0.simd_lt(cut_lo);
    let v2 = cut_hi.simd_lt(s1);
    let e2 = v1.select(s0, cut_hi);
    let x2 = v2.select(s1, cut_lo);
    let enter = two_rays.select(e2, e1);
    let exit = two_rays.select(x2, x1);
    let ok = two_rays.select(v1 | v2, e1.simd_lt(x1)) & s0.simd_lt(s1);
    (ok.select(enter + ts, NAN), ok.select(exit + ts, NAN))
}

/// Half-space `z <= 0`.
#[inline]
pub fn half_space_x8(o: Vec3x8, d: Vec3x8) -> (f32x8, f32x8) {
    let t = -(o.z / d.z);
    let enter = d.z.simd_lt(f32x8::ZERO).select(t, NEG_INF);
    let exit = d.z.simd_gt(f32x8::ZERO).select(t, INF);
    let par = d.z.simd_eq(f32x8::ZERO);
    let out = par & o.z.simd_gt(f32x8::ZERO);
    (out.select(NAN, enter), out.select(NAN, exit))
}
