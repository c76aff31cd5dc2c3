//! Dielectric Fresnel reflectance (unpolarised light) and the critical angle.
//!
//! The exact reflectance is the mean of the s- and p-polarised power reflectances from the Fresnel
//! amplitude equations (Born & Wolf, Principles of Optics, §1.5.2), written in terms of
//! `eta = n1 / n2` so that only `cos_i` and `cos_t` appear:
//!
//! ```text
//! r_s = (eta cos_i - cos_t) / (eta cos_i + cos_t)      r_p = (cos_i - eta cos_t) / (cos_i + eta cos_t)
//! R   = (r_s^2 + r_p^2) / 2,     cos_t^2 = 1 - eta^2 (1 - cos_i^2)   (Snell)
//! ```
//!
//! `cos_t^2 <= 0` is total internal reflection (R = 1). Both denominators are > 0 whenever
//! `cos_t > 0`, so no branch beyond the TIR test is needed.
//!
//! Precision: for `eta <= 1`, `cos_t^2` is formed as `(1 - eta)(1 + eta) + (eta cos_i)^2`: both terms
//! are >= 0, so nothing cancels, in particular not at grazing incidence with `eta ~ 1` (where
//! `1 - eta^2 sin_i^2` cancels to noise and gives a spurious reflectance). For `eta > 1` it is
//! `1 - eta^2 (1 - cos_i)(1 + cos_i)`, exact at normal incidence; the cancellation near the critical
//! angle is inherent: R has a square-root singularity there (`1 - R ~ 2 cos_t (eta + 1/eta) / cos_i`,
//! `cos_t ~ sqrt(angle to critical)`), so an f32 evaluation loses digits in proportion to `1 / cos_t`.
//! Use the f64 twin for reference values.
//!
//! Near `eta = 1` (an index-matched pair, glass of index 1.0001) the amplitudes' numerators
//! `eta cos_i - cos_t` and `cos_i - eta cos_t` cancel to rounding noise: in f32 a reflectance of
//! 2.5e-9 came out 0. For `|eta - 1| < 1/2` they are formed from exact identities instead (Snell:
//! `(eta c)^2 - cos_t^2 = eta^2 - 1` and `c^2 - (eta cos_t)^2 = (1 - eta^2)(c^2 (1 + eta^2) - eta^2)`),
//! `r_s = (eta^2 - 1) / (eta c + cos_t)^2`, `r_p = (1 - eta^2)(c^2 - eta^2 (1 - c^2)) / (c + eta cos_t)^2`,
//! with `eta^2 - 1 = (eta - 1)(eta + 1)` and `eta - 1` exact: relative precision, not absolute.

/// `cos^2` of the transmitted angle for a unit incident cosine `cos_i` and `eta = n1 / n2`.
///
/// `<= 0` means total internal reflection. Shared by [`fresnel_dielectric`] and
/// [`super::refract`] so that "refract returns None" and "Fresnel returns 1" are one predicate.
#[inline]
pub fn cos_t_sq(cos_i: f32, eta: f32) -> f32 {
    let c = clamp01(cos_i);
    if eta <= 1.0 {
        let ec = eta * c;
        ec.mul_add(ec, (1.0 - eta) * (1.0 + eta))
    } else {
        (-eta * eta).mul_add((1.0 - c) * (1.0 + c), 1.0)
    }
}

/// Exact unpolarised Fresnel reflectance of a smooth dielectric interface.
///
/// `cos_i = dot(wo, n)` on the incident side (clamped to `[0, 1]`), `eta = n1 / n2`. Returns 1 under
/// total internal reflection (and at grazing incidence). Transmittance is `1 - R`.
#[inline]
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let c = clamp01(cos_i);
    let ct2 = cos_t_sq(c, eta);
    // `!(x > 0)` also catches NaN from an infinite eta.
    if !(ct2 > 0.0) {
        return 1.0;
    }
    let ct = ct2.sqrt();
    let eta = eta.max(f32::MIN_POSITIVE);
    let (rs, rp) = if (eta - 1.0).abs() < 0.5 {
        // (See the module doc: the numerators from identities, without cancellation near eta = 1.)
        // (As quotients of `eta - 1` and `eta + 1`: at normal incidence, `(eta - 1) / (eta + 1)`
        // exactly as Schlick's R0 rounds it.)
        let (m, q, e2) = (eta - 1.0, eta + 1.0, eta * eta);
        let (s, p) = (eta * c + ct, c + eta * ct);
        let g = c * c - e2 * ((1.0 - c) * (1.0 + c));
        ((m / s) * (q / s), -((m / p) * (q / p)) * g)
    } else {
        ((eta * c - ct) / (eta * c + ct), (c - eta * ct) / (c + eta * ct))
    };
    0.5 * (rs * rs + rp * rp)
}

/// f64 twin of [`fresnel_dielectric`] (same formulas), for reference values in tests and tools.
#[inline]
pub fn fresnel_dielectric_f64(cos_i: f64, eta: f64) -> f64 {
    let c = cos_i.max(0.0).min(1.0);
    let ct2 = if eta <= 1.0 {
        let ec = eta * c;
        ec.mul_add(ec, (1.0 - eta) * (1.0 + eta))
    } else {
        (-eta * eta).mul_add((1.0 - c) * (1.0 + c), 1.0)
    };
    if !(ct2 > 0.0) {
        return 1.0;
    }
    let ct = ct2.sqrt();
    let eta = eta.max(f64::MIN_POSITIVE);
    let rs = (eta * c - ct) / (eta * c + ct);
    let rp = (c - eta * ct) / (c + eta * ct);
    0.5 * (rs * rs + rp * rp)
}

/// Schlick's approximation (Schlick 1994, "An Inexpensive BRDF Model for Physically-based
/// Rendering"): `R0 + (1 - R0)(1 - cos)^5`, `R0 = ((eta - 1) / (eta + 1))^2`.
///
/// Only an explicit option; [`fresnel_dielectric`] is the default. The polynomial is only valid with
/// the cosine on the optically *less* dense side, so when `n1 > n2` (`eta > 1`) the transmitted cosine
/// is used, and total internal reflection returns 1. At normal incidence it returns exactly
/// `fresnel_dielectric(1, eta)`.
///
/// Accuracy (max abs. error over all angles): ~0.036 for glass (n = 1.5) from either side, 0.075 for
/// diamond (2.42), 0.2 for n = 4, and poor for low contrast (water/glass 1.33/1.5: 0.17), because the
/// `(1 - cos)^5` tail is independent of the contrast. `eta == 1` (no interface) returns 0.
#[inline]
pub fn fresnel_schlick(cos_i: f32, eta: f32) -> f32 {
    if eta == 1.0 {
        return 0.0;
    }
    let c = clamp01(cos_i);
    let cos = if eta > 1.0 {
        let ct2 = cos_t_sq(c, eta);
        if !(ct2 > 0.0) {
            return 1.0;
        }
        ct2.sqrt()
    } else {
        c
    };
    let r = (eta - 1.0) / (eta + 1.0);
    let r0 = r * r;
    let m = 1.0 - cos;
    let m2 = m * m;
    (1.0 - r0).mul_add(m2 * m2 * m, r0)
}

/// Critical angle `asin(n2 / n1)` in radians, or `None` when `n1 <= n2` (no total internal
/// reflection is possible going from index `n1` into `n2`).
#[inline]
pub fn critical_angle(n1: f32, n2: f32) -> Option<f32> {
    if n1 > n2 && n2 > 0.0 {
        Some((n2 / n1).asin())
    } else {
        None
    }
}

/// Clamp to `[0, 1]`, mapping NaN to 0 (`f32::clamp` would keep the NaN).
#[inline(always)]
pub(crate) fn clamp01(x: f32) -> f32 {
    x.max(0.0).min(1.0)
}
