//! Mirror reflection and Snell refraction of unit directions (see the conventions in `mod.rs`:
//! `wo` points away from the surface, `n` is on `wo`'s side, `eta = n_incident / n_transmitted`).

use crate::simd::{f32x8, Vec3x8};
use glam::Vec3;

use super::fresnel::{clamp01, cos_t_sq};

/// Mirror `wo` about `n`: the reflected direction, pointing away from the surface.
#[inline]
pub fn reflect(wo: Vec3, n: Vec3) -> Vec3 {
    (2.0 * wo.dot(n)) * n - wo
}

/// Refracted direction (pointing away from the surface, on the far side), or `None` under total
/// internal reflection — exactly when [`super::fresnel_dielectric`] returns 1 because
/// `cos_t^2 <= 0` (both use [`super::cos_t_sq`]).
///
/// `t = -eta wo + (eta cos_i - cos_t) n` (Snell's law in vector form: the tangential component is
/// scaled by `eta`, the normal component fixed by `|t| = 1`). The result is renormalised.
/// `eta == 1` (index-matched interface) returns `-wo` exactly.
#[inline]
pub fn refract(wo: Vec3, n: Vec3, eta: f32) -> Option<Vec3> {
    if eta == 1.0 {
        return Some(-wo);
    }
    let c = clamp01(wo.dot(n));
    let ct2 = cos_t_sq(c, eta);
    if !(ct2 > 0.0) {
        return None;
    }
    let t = eta.mul_add(c, -ct2.sqrt()) * n - eta * wo;
    Some(t.normalize_or(-n))
}

/// Eight lanes of [`reflect`], bit-identical to it (the same unfused operations).
#[inline(always)]
pub fn reflect_x8(wo: Vec3x8, n: Vec3x8) -> Vec3x8 {
    let k = f32x8::splat(2.0) * wo.dot_unfused(n);
    let kn = n.scale(k);
    Vec3x8::new(kn.x - wo.x, kn.y - wo.y, kn.z - wo.z)
}

/// [`cos_t_sq`] in 8 lanes (both branches computed, selected by `eta <= 1`), bit-identical to it.
#[inline(always)]
fn cos_t_sq_x8(c: f32x8, eta: f32x8) -> f32x8 {
    let one = f32x8::ONE;
    let ec = eta * c;
    let lo = ec.mul_add(ec, (one - eta) * (one + eta));
    let hi = (-eta * eta).mul_add((one - c) * (one + c), one);
    eta.simd_le(one).select(lo, hi)
}

/// [`fresnel_dielectric`](super::fresnel_dielectric) in 8 lanes, bit-identical to it (same operations,
/// same fused multiply-adds; both branches of `cos_t_sq` computed and selected).
#[inline(always)]
pub fn fresnel_dielectric_x8(cos_i: f32x8, eta: f32x8) -> f32x8 {
    fresnel_parts_x8(cos_i, eta).0
}

/// The reflectance of [`fresnel_dielectric_x8`], the clamped cosine `c` and `cos_t^2` (for the refracted
/// direction).
#[inline(always)]
fn fresnel_parts_x8(cos_i: f32x8, eta: f32x8) -> (f32x8, f32x8, f32x8) {
    let (zero, one) = (f32x8::ZERO, f32x8::ONE);
    // clamp01: NaN and negatives to 0 (the sign of a zero cosine changes no result below).
    let c = cos_i.simd_gt(zero).select(cos_i, zero);
    let c = c.simd_lt(one).select(c, one);
    let ct2 = cos_t_sq_x8(c, eta);
    let ok = ct2.simd_gt(zero);
    let ct = ct2.sqrt();
    let e = eta.simd_gt(f32x8::splat(f32::MIN_POSITIVE)).select(eta, f32x8::splat(f32::MIN_POSITIVE));
    // Near eta = 1 the numerators from Snell's identities, as `fresnel_dielectric` forms them.
    let near = (e - one).abs().simd_lt(f32x8::splat(0.5));
    let (m, q, e2) = (e - one, e + one, e * e);
    let (s, p) = (e * c + ct, c + e * ct);
    let g = c * c - e2 * ((one - c) * (one + c));
    let rs = near.select((m / s) * (q / s), (e * c - ct) / s);
    let rp = near.select(-((m / p) * (q / p)) * g, (c - e * ct) / p);
    (ok.select(f32x8::splat(0.5) * (rs * rs + rp * rp), one), c, ct2)
}

/// The exact Fresnel reflectance and the refracted direction of 8 lanes at once: lane by lane,
/// `fresnel_dielectric(clamp(wo . n, 0, 1), eta)` and `refract(wo, n, eta)`, bit-identical to them
/// (same operations, same fused multiply-adds). Returns `(reflectance, refracted, tir)`: under total
/// internal reflection (`tir` lanes, where `refract` gives `None`) the reflectance is 1 and the
/// direction unspecified.
#[inline(always)]
pub fn fresnel_refract_x8(wo: Vec3x8, n: Vec3x8, eta: f32x8) -> (f32x8, Vec3x8, f32x8) {
    let (zero, one) = (f32x8::ZERO, f32x8::ONE);
    let (fres, c, ct2) = fresnel_parts_x8(wo.dot_unfused(n), eta);
    let ok = ct2.simd_gt(zero);
    let ct = ct2.sqrt();
    // refract: eta == 1 passes straight through; else Snell, renormalised (falling back to -n).
    let matched = eta.simd_eq(one);
    let s = eta.mul_add(c, -ct);
    let sn = n.scale(s);
    let ew = wo.scale(eta);
    let t = Vec3x8::new(sn.x - ew.x, sn.y - ew.y, sn.z - ew.z);
    let rcp = one / t.dot_unfused(t).sqrt();
    let good = rcp.is_finite() & rcp.simd_gt(zero);
    let neg = |v: Vec3x8| Vec3x8::new(-v.x, -v.y, -v.z);
    let dir = Vec3x8::select(good, t.scale(rcp), neg(n));
    let dir = Vec3x8::select(matched, neg(wo), dir);
    let tir = !ok & !matched;
    // `dielectric` uses reflectance 1 exactly when there is no refracted ray.
    (tir.select(one, fres), dir, tir)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optics::fresnel_dielectric;

    /// `fresnel_dielectric_x8` equals `fresnel_dielectric` bit for bit on any cosine (negative, above 1,
    /// zero, NaN) and index ratio (around 1, both sides of glass, extreme, total internal reflection).
    #[test]
    fn fresnel_x8_equals_scalar() {
        let mut f = crate::sample::hash::test_uniforms(0xf2e5_3e11);
        let etas = [1.0, 0.999_999, 1.000_001, 1.0 / 1.5, 1.5, 2.42, 1.0 / 2.42, 1e-3, 40.0, f32::MIN_POSITIVE];
        let mut tir = 0;
        for round in 0..2000 {
            let cos: [f32; 8] = std::array::from_fn(|l| match (round + l) % 9 {
                0 => 0.0,
                1 => 1.0,
                2 => f32::NAN,
                3 => -f(),
                4 => 1.0 + f(),
                _ => f(),
            });
            let eta: [f32; 8] = std::array::from_fn(|l| etas[(round * 3 + l) % etas.len()]);
            let got = fresnel_dielectric_x8(f32x8::from(cos), f32x8::from(eta)).to_array();
            for l in 0..8 {
                let want = fresnel_dielectric(cos[l], eta[l]);
                assert_eq!(got[l].to_bits(), want.to_bits(), "cos {} eta {}: {} vs {want}", cos[l], eta[l], got[l]);
                tir += (want == 1.0) as usize;
            }
        }
        assert!(tir > 500, "{tir} lanes at reflectance 1");
    }

    /// The 8-lane kernels equal their scalar twins bit for bit: random unit directions and normals
    /// (grazing, normal and back-facing included), eta around 1 (0.999999 .. 1.000001, exactly 1),
    /// glass from both sides and extreme contrasts; total internal reflection where `refract` gives None.
    #[test]
    fn x8_kernels_equal_scalar() {
        let mut s = 0x1234_5678_9abc_def0u64;
        let mut rnd = move || {
            s = crate::sample::hash::mix64(s);
            (s >> 40) as f32 / (1u64 << 24) as f32
        };
        let etas = [1.0, 0.999_999, 1.000_001, 1.0 / 1.5, 1.5, 1.33 / 1.5, 2.42, 1.0 / 2.42, 1e-3, 40.0];
        let (mut tirs, mut total) = (0, 0);
        for round in 0..4000 {
            let mut wo = [Vec3::ZERO; 8];
            let mut n = [Vec3::ZERO; 8];
            let mut eta = [0.0f32; 8];
            for l in 0..8 {
                n[l] = Vec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5).normalize_or(Vec3::Z);
                let v = Vec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5);
                // Every fourth lane grazing: wo nearly in the tangent plane.
                wo[l] = if l % 4 == 3 {
                    (v - n[l] * v.dot(n[l]) + n[l] * (rnd() * 1e-4)).normalize_or(Vec3::X)
                } else {
                    v.normalize_or(Vec3::X)
                };
                if l % 4 == 1 {
                    // Normal incidence.
                    wo[l] = n[l];
                }
                eta[l] = if round % 3 == 0 { etas[(round / 3 + l) % etas.len()] } else { 0.2 + 3.0 * rnd() };
            }
            let v3 = |a: &[Vec3; 8]| Vec3x8::new(f32x8::from(a.map(|v| v.x)), f32x8::from(a.map(|v| v.y)), f32x8::from(a.map(|v| v.z)));
            let (f, dir, tir) = fresnel_refract_x8(v3(&wo), v3(&n), f32x8::from(eta));
            let refl = reflect_x8(v3(&wo), v3(&n));
            let (f, tir) = (f.to_array(), tir.to_bitmask());
            for l in 0..8 {
                let want_t = refract(wo[l], n[l], eta[l]);
                let want_f = if want_t.is_none() { 1.0 } else { fresnel_dielectric(wo[l].dot(n[l]).clamp(0.0, 1.0), eta[l]) };
                assert_eq!(f[l].to_bits(), want_f.to_bits(), "reflectance, lane {l}: wo {:?} n {:?} eta {}", wo[l], n[l], eta[l]);
                assert_eq!(tir & (1 << l) != 0, want_t.is_none(), "tir, lane {l}");
                if let Some(t) = want_t {
                    assert_eq!(dir.lane(l).to_array().map(f32::to_bits), t.to_array().map(f32::to_bits), "refracted, lane {l}");
                }
                let r = reflect(wo[l], n[l]);
                assert_eq!(refl.lane(l).to_array().map(f32::to_bits), r.to_array().map(f32::to_bits), "reflected, lane {l}");
                tirs += want_t.is_none() as u32;
                total += 1;
            }
        }
        // The inputs reach total internal reflection often enough to test it, and not always.
        assert!(tirs > total / 50 && tirs < total / 2, "{tirs} of {total}");
    }
}
