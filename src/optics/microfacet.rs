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

use crate::simd::{f32x8, Vec3x8};
use glam::Vec3;
use std::f32::consts::FRAC_1_PI;

use super::lambert::{onb, onb_x8, to_local, to_world};
use crate::sample::warp::{sin_cos_turns, sin_cos_turns_x8};

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
    let (sp, cp) = sin_cos_turns(u[1]);
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

/// [`sample_ggx_reflect`] in 8 lanes, the same operations in the same order (the sine and cosine of the
/// angle by [`sin_cos_turns_x8`], the scalar's [`sin_cos_turns`] in 8 lanes), so each lane's bits equal the scalar call's: the directions, and the
/// lanes where it returns `Some`.
#[inline(always)]
pub fn sample_ggx_reflect_x8(wo: Vec3x8, n: Vec3x8, alpha: f32x8, u: [f32x8; 2]) -> (Vec3x8, f32x8) {
    let (zero, one) = (f32x8::ZERO, f32x8::ONE);
    let a = alpha.max(f32x8::splat(GGX_ALPHA_MIN)).min(one);
    let (t, b) = onb_x8(n);
    let wo_l = Vec3x8::new(wo.dot_unfused(t), wo.dot_unfused(b), wo.dot_unfused(n));
    let vh = Vec3x8::new(a * wo_l.x, a * wo_l.y, wo_l.z).normalize();
    let len2 = vh.x.mul_add(vh.x, vh.y * vh.y);
    let len = len2.sqrt();
    let t1 =
        Vec3x8::select(len2.simd_gt(f32x8::splat(1e-14)), Vec3x8::new(-vh.y / len, vh.x / len, zero / len), Vec3x8::new(one, zero, zero));
    let t2 = vh.cross(t1);
    let r = u[0].max(zero).min(one).sqrt();
    let (sp, cp) = sin_cos_turns_x8(u[1]);
    let p1 = r * cp;
    let s = f32x8::splat(0.5) * (one + vh.z);
    let p2 = (one - s) * (one - p1 * p1).max(zero).sqrt() + s * (r * sp);
    let nz = (one - p1 * p1 - p2 * p2).max(zero).sqrt();
    let nh = t1.scale(p1) + t2.scale(p2) + vh.scale(nz);
    let m = Vec3x8::new(a * nh.x, a * nh.y, nh.z.max(zero)).normalize_or(Vec3x8::splat(Vec3::Z));
    let wi_l = m.scale(f32x8::splat(2.0) * wo_l.dot_unfused(m)) - wo_l;
    let wi = (t.scale(wi_l.x) + b.scale(wi_l.y) + n.scale(wi_l.z)).normalize_or(n);
    (wi, wo_l.z.simd_gt(zero) & wi_l.z.simd_gt(zero))
}

/// [`sample_ggx_reflect_weight`] in 8 lanes, the same operations (bit-identical lane by lane).
#[inline(always)]
pub fn sample_ggx_reflect_weight_x8(wo: Vec3x8, n: Vec3x8, wi: Vec3x8, alpha: f32x8) -> f32x8 {
    let (zero, one) = (f32x8::ZERO, f32x8::ONE);
    let (co, ci) = (wo.dot_unfused(n), wi.dot_unfused(n));
    let a2 = clamped_a2_x8(alpha);
    let (cm, im) = (co.min(one), ci.min(one));
    let qo = q_x8(cm, a2);
    let w = (im * (cm + qo) / im.mul_add(qo, cm * q_x8(im, a2))).min(one);
    (co.simd_gt(zero) & ci.simd_gt(zero)).select(w, zero)
}

/// `q(c)` and the clamped `alpha^2`, lane-wise, as [`q`] and [`clamp_alpha`] round them.
#[inline(always)]
fn q_x8(c: f32x8, a2: f32x8) -> f32x8 {
    c.mul_add(c, a2 * ((f32x8::ONE - c) * (f32x8::ONE + c)).max(f32x8::ZERO)).sqrt()
}

#[inline(always)]
fn clamped_a2_x8(alpha: f32x8) -> f32x8 {
    let a = alpha.max(f32x8::splat(GGX_ALPHA_MIN)).min(f32x8::ONE);
    a * a
}

/// [`d_of_pair`] in 8 lanes, the same operations (bit-identical lane by lane).
#[inline(always)]
fn d_of_pair_x8(wo: Vec3x8, wi: Vec3x8, n: Vec3x8, a2: f32x8) -> f32x8 {
    let h = (wo + wi).normalize_or(n);
    let c = h.dot_unfused(n);
    let s = h.cross(n);
    let cc = c.min(f32x8::ONE);
    let k = (a2 * cc).mul_add(cc, s.dot_unfused(s));
    c.simd_gt(f32x8::ZERO).select(a2 * f32x8::splat(FRAC_1_PI) / (k * k), f32x8::ZERO)
}

/// [`eval_ggx_reflect`] in 8 lanes, the same operations (bit-identical lane by lane).
#[inline(always)]
pub fn eval_ggx_reflect_x8(wo: Vec3x8, n: Vec3x8, wi: Vec3x8, alpha: f32x8) -> f32x8 {
    let zero = f32x8::ZERO;
    let (co, ci) = (wo.dot_unfused(n), wi.dot_unfused(n));
    let a2 = clamped_a2_x8(alpha);
    let (cm, im) = (co.min(f32x8::ONE), ci.min(f32x8::ONE));
    let d = d_of_pair_x8(wo, wi, n, a2);
    let v = d * im / (f32x8::splat(2.0) * im.mul_add(q_x8(cm, a2), cm * q_x8(im, a2)));
    (co.simd_gt(zero) & ci.simd_gt(zero)).select(v, zero)
}

/// [`sample_ggx_reflect_pdf`] in 8 lanes, the same operations (bit-identical lane by lane).
#[inline(always)]
pub fn sample_ggx_reflect_pdf_x8(wo: Vec3x8, n: Vec3x8, wi: Vec3x8, alpha: f32x8) -> f32x8 {
    let zero = f32x8::ZERO;
    let (co, ci) = (wo.dot_unfused(n), wi.dot_unfused(n));
    let a2 = clamped_a2_x8(alpha);
    let cm = co.min(f32x8::ONE);
    let v = d_of_pair_x8(wo, wi, n, a2) / (f32x8::splat(2.0) * (cm + q_x8(cm, a2)));
    (co.simd_gt(zero) & ci.simd_gt(zero)).select(v, zero)
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

#[cfg(test)]
mod x8_tests {
    use super::*;
    use crate::simd::LANES;

    /// The 8-lane GGX sampling and weight against the scalar functions, bit for bit: normals all over
    /// the sphere (poles, both signs of z, -0), outgoing directions from the normal to grazing and
    /// below, roughness from below the clamp to 1 and above, and sample points over the square with its
    /// edges; every lane's direction where the scalar call gives one, and the same `None` lanes.
    #[test]
    fn ggx_x8_equals_scalar() {
        let mut next = crate::sample::hash::test_uniforms(0x66c_0ff1);
        let (mut some, mut none) = (0, 0);
        for round in 0..6000 {
            let unit =
                |next: &mut dyn FnMut() -> f32| Vec3::new(next() * 2.0 - 1.0, next() * 2.0 - 1.0, next() * 2.0 - 1.0).normalize_or(Vec3::X);
            let ns: [Vec3; LANES] = std::array::from_fn(|l| match (round + l) % 61 {
                0 => Vec3::Z,
                1 => -Vec3::Z,
                2 => Vec3::new(0.0, 1.0, -0.0),
                _ => unit(&mut next),
            });
            let wos: [Vec3; LANES] = std::array::from_fn(|l| match (round + 3 * l) % 7 {
                // Near the normal, grazing, and anywhere (often below).
                0 => (ns[l] + unit(&mut next) * 1e-3).normalize(),
                1 => (unit(&mut next).cross(ns[l]).normalize_or(Vec3::X) + ns[l] * 1e-4).normalize(),
                _ => unit(&mut next),
            });
            let alphas: [f32; LANES] =
                std::array::from_fn(|l| [1e-6, 1e-4, 0.02, 0.3, 1.0, 1.5][(round + l) % 6] * if l % 3 == 0 { next() } else { 1.0 });
            let us: [[f32; 2]; LANES] = std::array::from_fn(|l| match (round + l) % 11 {
                0 => [0.0, 0.0],
                1 => [0.99999994, 0.99999994],
                _ => [next(), next()],
            });
            let v3 = |a: &[Vec3; LANES]| Vec3x8::new(f32x8::from(a.map(|v| v.x)), f32x8::from(a.map(|v| v.y)), f32x8::from(a.map(|v| v.z)));
            let (wo, n, alpha) = (v3(&wos), v3(&ns), f32x8::from(alphas));
            let (wi, ok) = sample_ggx_reflect_x8(wo, n, alpha, [f32x8::from(us.map(|u| u[0])), f32x8::from(us.map(|u| u[1]))]);
            let weight = sample_ggx_reflect_weight_x8(wo, n, wi, alpha).to_array();
            let ok = ok.to_bitmask();
            for l in 0..LANES {
                let want = sample_ggx_reflect(wos[l], ns[l], alphas[l], us[l]);
                assert_eq!(ok & (1 << l) != 0, want.is_some(), "lane {l}: wo {} n {} alpha {} u {:?}", wos[l], ns[l], alphas[l], us[l]);
                if let Some(w) = want {
                    some += 1;
                    assert_eq!(wi.lane(l).to_array().map(f32::to_bits), w.to_array().map(f32::to_bits), "lane {l}: direction");
                    let wt = sample_ggx_reflect_weight(wos[l], ns[l], w, alphas[l]);
                    assert_eq!(weight[l].to_bits(), wt.to_bits(), "lane {l}: weight");
                } else {
                    none += 1;
                }
            }
        }
        assert!(some > 15_000 && none > 5_000, "{some} sampled, {none} below");
    }

    /// The 8-lane lobe value and density against the scalar functions, bit for bit, for pairs of
    /// directions anywhere: sampled ones, the mirror direction, near-mirror, grazing, below the surface
    /// (0 in both), `wi = wo`, and `wi = -wo` (a half vector of zero length).
    #[test]
    fn ggx_eval_and_pdf_x8_equal_scalar() {
        let mut next = crate::sample::hash::test_uniforms(0x9e1_7a11);
        let unit =
            |next: &mut dyn FnMut() -> f32| Vec3::new(next() * 2.0 - 1.0, next() * 2.0 - 1.0, next() * 2.0 - 1.0).normalize_or(Vec3::X);
        let (mut positive, mut zero) = (0, 0);
        for round in 0..6000 {
            let ns: [Vec3; LANES] = std::array::from_fn(|l| if (round + l) % 17 == 0 { Vec3::Z } else { unit(&mut next) });
            let wos: [Vec3; LANES] = std::array::from_fn(|l| match (round + 5 * l) % 5 {
                0 => (ns[l] + unit(&mut next) * 1e-3).normalize(),
                1 => (unit(&mut next).cross(ns[l]).normalize_or(Vec3::X) + ns[l] * 1e-4).normalize(),
                _ => unit(&mut next),
            });
            let wis: [Vec3; LANES] = std::array::from_fn(|l| {
                let mirror = (2.0 * wos[l].dot(ns[l])) * ns[l] - wos[l];
                match (round + 3 * l) % 9 {
                    0 => mirror,
                    1 => (mirror + unit(&mut next) * 1e-4).normalize(),
                    2 => wos[l],
                    3 => -wos[l],
                    4 => (unit(&mut next).cross(ns[l]).normalize_or(Vec3::Y) + ns[l] * 1e-5).normalize(),
                    _ => unit(&mut next),
                }
            });
            let alphas: [f32; LANES] =
                std::array::from_fn(|l| [1e-6, 1e-4, 0.02, 0.3, 1.0, 1.5][(round + l) % 6] * if l % 3 == 0 { next() } else { 1.0 });
            let v3 = |a: &[Vec3; LANES]| Vec3x8::new(f32x8::from(a.map(|v| v.x)), f32x8::from(a.map(|v| v.y)), f32x8::from(a.map(|v| v.z)));
            let (wo, n, wi, alpha) = (v3(&wos), v3(&ns), v3(&wis), f32x8::from(alphas));
            let (f, pdf) = (eval_ggx_reflect_x8(wo, n, wi, alpha).to_array(), sample_ggx_reflect_pdf_x8(wo, n, wi, alpha).to_array());
            for l in 0..LANES {
                let (fs, ps) =
                    (eval_ggx_reflect(wos[l], ns[l], wis[l], alphas[l]), sample_ggx_reflect_pdf(wos[l], ns[l], wis[l], alphas[l]));
                let at = || format!("lane {l}: wo {} n {} wi {} alpha {}", wos[l], ns[l], wis[l], alphas[l]);
                assert_eq!(f[l].to_bits(), fs.to_bits(), "eval, {}", at());
                assert_eq!(pdf[l].to_bits(), ps.to_bits(), "pdf, {}", at());
                if fs > 0.0 {
                    positive += 1;
                } else {
                    zero += 1;
                }
            }
        }
        assert!(positive > 10_000 && zero > 10_000, "{positive} positive, {zero} zero");
    }
}
