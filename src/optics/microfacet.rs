//! GGX (Trowbridge-Reitz) microfacet reflection for glossy, conductor-like surfaces.
//!
//! * Distribution `D(h) = alpha^2 / (pi (cos^2 (alpha^2 - 1) + 1)^2)` (Walter, Marschner, Li &
//!   Torrance 2007, "Microfacet Models for Refraction through Rough Surfaces"). The bracket is
//!   evaluated as `sin^2 + alpha^2 cos^2`, which stays exact as `alpha -> 0` (the textbook form
//!   cancels to 0 in f32 at the peak once `alpha^2 < 6e-8`).
//! * Masking: Smith, height-correlated `G2 = 1 / (1 + L(wo) + L(wi))`, with
//!   `L = (sqrt(1 + alpha^2 tan^2) - 1) / 2` (Heitz 2014, "Understanding the Masking-Shadowing Function
//!   in Microfacet-Based BRDFs"). Everything is multiplied through by the cosines so no `tan` (and no
//!   division by a grazing cosine) appears: with `q(c) = sqrt(c^2 + alpha^2 (1 - c^2))`,
//!   `G1(c) = 2c / (c + q)` and `G2 = 2 c_o c_i / (c_i q_o + c_o q_i)`.
//! * Sampling: the distribution of visible normals (Heitz 2018, "Sampling the GGX Distribution of
//!   Visible Normals", JCGT 7(4)): `D_wo(h) = G1(wo) max(0, wo.h) D(h) / cos_o`, reflected about `h`.
//!   Its density over `wi` is `D_wo(h) / (4 wo.h) = D(h) / (2 (c_o + q_o))`, and the sample weight
//!   `eval / pdf = G2 / G1(wo) = c_i (c_o + q_o) / (c_i q_o + c_o q_i)`, in `[0, 1]`.
//!   Reflected directions that fall below the surface (a visible microfacet can still send light
//!   down) are returned as `None`: that probability mass is lost, which is why the pdf over the
//!   upper hemisphere integrates to `1 - P(None)`.
//!
//! `alpha` is clamped to `[GGX_ALPHA_MIN, 1]` everywhere: at `1e-4` the lobe is narrower than an
//! f32 direction can resolve usefully, yet every quantity stays finite (`D <= 1 / (pi alpha^2)`).
//! No Fresnel term: the caller tints by its conductor/dielectric Fresnel at `dot(wo, h)`.

use glam::Vec3;
use std::f32::consts::{FRAC_1_PI, TAU};

use super::lambert::{onb, to_local, to_world};

/// Smallest roughness used (smaller values are clamped). Sampled directions converge to the mirror
/// direction as alpha approaches it.
pub const GGX_ALPHA_MIN: f32 = 1e-4;

#[inline(always)]
fn clamp_alpha(alpha: f32) -> f32 {
    // max/min (not clamp) so that a NaN alpha becomes GGX_ALPHA_MIN instead of propagating.
    alpha.max(GGX_ALPHA_MIN).min(1.0)
}

/// `q(c) = sqrt(c^2 + alpha^2 (1 - c^2)) = c sqrt(1 + alpha^2 tan^2)`, for `c` in `[0, 1]`.
#[inline(always)]
fn q(c: f32, a2: f32) -> f32 {
    let s2 = ((1.0 - c) * (1.0 + c)).max(0.0);
    c.mul_add(c, a2 * s2).sqrt()
}

/// GGX normal distribution `D(h)` for `cos_h = dot(h, n)`, 0 for `cos_h <= 0`. Normalised so that
/// `∫ D(h) cos_h dh = 1` over the hemisphere.
///
/// An f32 cosine resolves angles near the normal only to ~3.5e-4 rad, so for `alpha` below ~1e-2
/// this form is coarse at the peak; [`eval_ggx_reflect`] and [`sample_ggx_reflect_pdf`] therefore
/// evaluate `D` from `sin^2 = |h × n|^2` instead, which keeps full precision there.
#[inline]
pub fn ggx_d(cos_h: f32, alpha: f32) -> f32 {
    if !(cos_h > 0.0) {
        return 0.0;
    }
    let c = cos_h.min(1.0);
    let a = clamp_alpha(alpha);
    d_sin_cos(((1.0 - c) * (1.0 + c)).max(0.0), c, a * a)
}

/// `D` from `sin^2` and `cos` of the half-vector angle (`cos > 0`), `a2 = alpha^2`.
#[inline(always)]
fn d_sin_cos(s2: f32, c: f32, a2: f32) -> f32 {
    let k = (a2 * c).mul_add(c, s2);
    a2 * FRAC_1_PI / (k * k)
}

/// `D(normalize(wo + wi))` with the sine taken from a cross product (precise near the normal).
/// 0 when the half vector is at or below the surface.
#[inline(always)]
fn d_of_pair(wo: Vec3, wi: Vec3, n: Vec3, a2: f32) -> f32 {
    let h = (wo + wi).normalize_or(n);
    let c = h.dot(n);
    if !(c > 0.0) {
        return 0.0;
    }
    d_sin_cos(h.cross(n).length_squared(), c.min(1.0), a2)
}

/// Smith masking `G1` for a direction with cosine `cos` to the normal (0 at or below the horizon).
#[inline]
pub fn ggx_g1(cos: f32, alpha: f32) -> f32 {
    if !(cos > 0.0) {
        return 0.0;
    }
    let a = clamp_alpha(alpha);
    let c = cos.min(1.0);
    2.0 * c / (c + q(c, a * a))
}

/// Smith height-correlated masking-shadowing `G2(wo, wi)` from the two cosines (0 if either is <= 0).
#[inline]
pub fn ggx_g2(cos_o: f32, cos_i: f32, alpha: f32) -> f32 {
    if !(cos_o > 0.0 && cos_i > 0.0) {
        return 0.0;
    }
    let a = clamp_alpha(alpha);
    let a2 = a * a;
    let (co, ci) = (cos_o.min(1.0), cos_i.min(1.0));
    2.0 * co * ci / ci.mul_add(q(co, a2), co * q(ci, a2))
}

/// GGX reflection `BRDF(wo, wi) * cos(wi)` without Fresnel: `D G2 / (4 c_o)`, evaluated as
/// `D c_i / (2 (c_i q_o + c_o q_i))`. 0 when either direction is at or below the surface.
#[inline]
pub fn eval_ggx_reflect(wo: Vec3, n: Vec3, wi: Vec3, alpha: f32) -> f32 {
    let (co, ci) = (wo.dot(n), wi.dot(n));
    if !(co > 0.0 && ci > 0.0) {
        return 0.0;
    }
    let a = clamp_alpha(alpha);
    let a2 = a * a;
    let (co, ci) = (co.min(1.0), ci.min(1.0));
    let d = d_of_pair(wo, wi, n, a2);
    d * ci / (2.0 * ci.mul_add(q(co, a2), co * q(ci, a2)))
}

/// Sample `wi` by reflecting `wo` about a visible GGX normal (Heitz 2018), from `u` in `[0, 1)^2`.
/// `None` when `wo` is at or below the surface or the reflected direction goes below it.
#[inline]
pub fn sample_ggx_reflect(wo: Vec3, n: Vec3, alpha: f32, u: [f32; 2]) -> Option<Vec3> {
    let a = clamp_alpha(alpha);
    let (t, b) = onb(n);
    let wo_l = to_local(wo, t, b, n);
    if !(wo_l.z > 0.0) {
        return None;
    }
    // Stretch to the alpha = 1 configuration, where visible normals are a projected hemisphere.
    let vh = Vec3::new(a * wo_l.x, a * wo_l.y, wo_l.z).normalize();
    let len2 = vh.x.mul_add(vh.x, vh.y * vh.y);
    let t1 = if len2 > 1e-14 { Vec3::new(-vh.y, vh.x, 0.0) / len2.sqrt() } else { Vec3::X };
    let t2 = vh.cross(t1);
    // Uniform point on the unit disk, then the half of the disk that is hidden from vh is squeezed
    // by the projection factor s (Heitz 2018, listing 1, written out independently).
    let r = u[0].max(0.0).min(1.0).sqrt();
    let (sp, cp) = (TAU * u[1]).sin_cos();
    let p1 = r * cp;
    let s = 0.5 * (1.0 + vh.z);
    let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * (r * sp);
    let nz = (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
    let nh = t1 * p1 + t2 * p2 + vh * nz;
    // Unstretch: back to the alpha configuration.
    let m = Vec3::new(a * nh.x, a * nh.y, nh.z.max(0.0)).normalize_or(Vec3::Z);
    let wi_l = (2.0 * wo_l.dot(m)) * m - wo_l;
    if !(wi_l.z > 0.0) {
        return None;
    }
    Some(to_world(wi_l, t, b, n).normalize_or(n))
}

/// Density over solid angle of `wi` under [`sample_ggx_reflect`]: `D(h) / (2 (c_o + q_o))` for `wi`
/// above the surface, 0 otherwise (those directions are never returned).
#[inline]
pub fn sample_ggx_reflect_pdf(wo: Vec3, n: Vec3, wi: Vec3, alpha: f32) -> f32 {
    let (co, ci) = (wo.dot(n), wi.dot(n));
    if !(co > 0.0 && ci > 0.0) {
        return 0.0;
    }
    let a = clamp_alpha(alpha);
    let (co, a2) = (co.min(1.0), a * a);
    d_of_pair(wo, wi, n, a2) / (2.0 * (co + q(co, a2)))
}

/// `eval_ggx_reflect / sample_ggx_reflect_pdf` for a sampled `wi`, without forming either:
/// `G2 / G1(wo) = c_i (c_o + q_o) / (c_i q_o + c_o q_i)`, in `[0, 1]`; 0 below the surface.
#[inline]
pub fn sample_ggx_reflect_weight(wo: Vec3, n: Vec3, wi: Vec3, alpha: f32) -> f32 {
    let (co, ci) = (wo.dot(n), wi.dot(n));
    if !(co > 0.0 && ci > 0.0) {
        return 0.0;
    }
    let a = clamp_alpha(alpha);
    let a2 = a * a;
    let (co, ci) = (co.min(1.0), ci.min(1.0));
    let qo = q(co, a2);
    (ci * (co + qo) / ci.mul_add(qo, co * q(ci, a2))).min(1.0)
}
