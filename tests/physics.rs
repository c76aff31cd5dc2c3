//! Ground-truth tests of `strata::optics`: analytic values, independent f64 formulas, quadrature of
//! densities and chi-square tests of samplers (fixed xoshiro seeds).

use glam::{DVec3, Vec3};
use rand_core::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use std::f64::consts::{FRAC_PI_2, PI};
use strata::optics::*;

// Lambert and GGX sampling tests (kept in a sub-directory so Cargo does not build it as its own target).
#[path = "physics/sampling.rs"]
mod sampling;

// ---------------------------------------------------------------------------------------------
// helpers

fn rng(seed: u64) -> Xoshiro256PlusPlus {
    Xoshiro256PlusPlus::seed_from_u64(seed)
}

fn uf(r: &mut Xoshiro256PlusPlus) -> f32 {
    (r.next_u32() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

fn uniform_sphere(r: &mut Xoshiro256PlusPlus) -> Vec3 {
    let z = 1.0 - 2.0 * uf(r);
    let phi = std::f32::consts::TAU * uf(r);
    let s = (1.0 - z * z).max(0.0).sqrt();
    Vec3::new(s * phi.cos(), s * phi.sin(), z)
}

/// Unit direction at cosine `c` from `n`, azimuth `phi`, in a frame built here by Gram-Schmidt
/// (independent of `onb`).
fn dir_around(n: DVec3, c: f64, phi: f64) -> DVec3 {
    let helper = if n.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    let t = (helper - n * n.dot(helper)).normalize();
    let b = n.cross(t);
    let s = (1.0 - c * c).max(0.0).sqrt();
    t * (s * phi.cos()) + b * (s * phi.sin()) + n * c
}

/// Cosine and azimuth of `w` relative to `n` in the `dir_around` frame.
fn coords_around(n: DVec3, w: DVec3) -> (f64, f64) {
    let helper = if n.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    let t = (helper - n * n.dot(helper)).normalize();
    let b = n.cross(t);
    let phi = w.dot(b).atan2(w.dot(t)).rem_euclid(2.0 * PI);
    (w.dot(n), phi)
}

/// `∫_{S^2} f(w) dw` with directions parametrised around `axis` by a polar angle that concentrates
/// samples near the axis: `beta = 2 atan(k sqrt(v / (1 - v)))`, midpoint rule in `v` and `phi`.
fn integrate_sphere(axis: DVec3, k: f64, nv: usize, nphi: usize, f: impl Fn(DVec3) -> f64) -> f64 {
    let mut sum = 0.0;
    for i in 0..nv {
        let v = (i as f64 + 0.5) / nv as f64;
        let g = (v / (1.0 - v)).sqrt();
        let beta = 2.0 * (k * g).atan();
        let dbeta = k / (v.sqrt() * (1.0 - v).sqrt() * ((1.0 - v) + k * k * v));
        let w = beta.sin() * dbeta / nv as f64 * (2.0 * PI / nphi as f64);
        let mut ring = 0.0;
        for j in 0..nphi {
            let phi = (j as f64 + 0.5) / nphi as f64 * 2.0 * PI;
            ring += f(dir_around(axis, beta.cos(), phi));
        }
        sum += ring * w;
    }
    sum
}

fn v3(d: DVec3) -> Vec3 {
    d.as_vec3()
}

/// Upper quantile of the chi-square distribution (Wilson-Hilferty), `z` = normal quantile.
fn chi2_critical(dof: usize, z: f64) -> f64 {
    let k = dof as f64;
    let a = 2.0 / (9.0 * k);
    k * (1.0 - a + z * a.sqrt()).powi(3)
}

/// Pearson statistic over bins with expected counts, pooling bins with expectation < 5 into one.
/// Returns (statistic, degrees of freedom).
fn chi2(observed: &[f64], expected: &[f64]) -> (f64, usize) {
    let (mut stat, mut bins) = (0.0, 0usize);
    let (mut po, mut pe) = (0.0, 0.0);
    for (&o, &e) in observed.iter().zip(expected) {
        if e < 5.0 {
            po += o;
            pe += e;
        } else {
            stat += (o - e) * (o - e) / e;
            bins += 1;
        }
    }
    if pe > 0.0 {
        stat += (po - pe) * (po - pe) / pe.max(1e-3);
        bins += 1;
    }
    (stat, bins - 1)
}

// ---------------------------------------------------------------------------------------------
// Fresnel

const INDEX_PAIRS: [(f64, f64); 10] =
    [(1.0, 1.0), (1.0, 1.0001), (1.0, 1.5), (1.0, 2.42), (1.0, 4.0), (1.5, 1.0), (2.42, 1.0), (4.0, 1.0), (1.33, 1.5), (1.5, 1.33)];

/// Independent reference: Fresnel amplitude coefficients in angle form,
/// `r_s = -sin(ti - tt) / sin(ti + tt)`, `r_p = tan(ti - tt) / tan(ti + tt)`.
fn fresnel_reference(theta_i: f64, n1: f64, n2: f64) -> f64 {
    let st = n1 / n2 * theta_i.sin();
    if st >= 1.0 {
        return 1.0;
    }
    let tt = st.asin();
    if (theta_i - tt).abs() < 1e-300 {
        return 0.0;
    }
    let rs = -(theta_i - tt).sin() / (theta_i + tt).sin();
    let rp = (theta_i - tt).tan() / (theta_i + tt).tan();
    0.5 * (rs * rs + rp * rp)
}

#[test]
fn fresnel_normal_incidence_matches_r0() {
    for (n1, n2) in INDEX_PAIRS {
        let r0 = ((n1 - n2) / (n1 + n2)).powi(2);
        let r64 = fresnel_dielectric_f64(1.0, n1 / n2);
        assert!((r64 - r0).abs() <= 1e-12 * r0.max(1e-6), "{n1}->{n2}: {r64} vs {r0}");
        let r32 = fresnel_dielectric(1.0, (n1 / n2) as f32) as f64;
        assert!((r32 - r0).abs() <= 1e-6, "{n1}->{n2}: {r32} vs {r0}");
    }
    assert_eq!(fresnel_dielectric(1.0, 1.0), 0.0);
}

#[test]
fn fresnel_matches_sp_amplitudes_and_f32_matches_f64() {
    for (n1, n2) in INDEX_PAIRS {
        let eta = n1 / n2;
        for k in 0..1000 {
            let theta = (k as f64 + 0.5) / 1000.0 * FRAC_PI_2;
            let reference = fresnel_reference(theta, n1, n2);
            let r64 = fresnel_dielectric_f64(theta.cos(), eta);
            assert!((r64 - reference).abs() < 1e-10, "{n1}->{n2} at {theta}: {r64} vs {reference}");

            // f32 against f64 at the same (f32) inputs.
            let (c32, e32) = (theta.cos() as f32, eta as f32);
            let r64s = fresnel_dielectric_f64(c32 as f64, e32 as f64);
            let r32 = fresnel_dielectric(c32, e32) as f64;
            assert!((r32 - r64s).abs() < 1e-5, "{n1}->{n2} at {theta}: f32 {r32} vs f64 {r64s}");
        }
    }
}

/// Near an index ratio of 1 (glass of index 1.0001, an index-matched pair) the f32 reflectance keeps
/// its relative precision: against the s/p amplitude formula in f64 at the same f32 inputs, within 1e-4
/// of R at every angle (short of the critical angle's neighbourhood for eta > 1), both sides of 1. The plain
/// amplitude numerators cancel there: R of 2.5e-9 at n = 1.0001 came out 0 (a user trial).
#[test]
fn fresnel_near_an_index_ratio_of_one_keeps_relative_precision() {
    for eta in [1.0001f32, 1.0 / 1.0001, 1.001, 0.999, 1.01, 0.99, 1.3, 0.7] {
        for k in 0..200 {
            let c32 = ((k as f64 + 0.5) / 200.0 * FRAC_PI_2).cos() as f32;
            let (c, e) = (c32 as f64, eta as f64);
            let ct2 = 1.0 - e * e * (1.0 - c * c);
            // (Beyond, or within cos_t < 0.1 of, the critical angle the f32 cos_t^2 itself cancels:
            // that conditioning is `fresnel_total_internal_reflection_and_continuity`'s.)
            if ct2 <= 0.0 || (eta > 1.0 && ct2 < 0.01) {
                continue;
            }
            let ct = ct2.sqrt();
            let (rs, rp) = ((e * c - ct) / (e * c + ct), (c - e * ct) / (c + e * ct));
            let want = 0.5 * (rs * rs + rp * rp);
            let got = fresnel_dielectric(c32, eta) as f64;
            // (Where R crosses the p-amplitude's zero it is still rs^2 / 2: no cancellation of R itself.)
            assert!((got - want).abs() <= 1e-4 * want + 1e-30, "eta {eta} cos {c32}: {got:e} against {want:e}");
        }
    }
}

#[test]
fn fresnel_total_internal_reflection_and_continuity() {
    for (n1, n2) in [(1.5f64, 1.0f64), (2.42, 1.0), (4.0, 1.0), (1.5, 1.33)] {
        let eta = n1 / n2;
        let tc = (n2 / n1).asin();
        assert!((critical_angle(n1 as f32, n2 as f32).unwrap() as f64 - tc).abs() < 1e-6);
        // Beyond the critical angle: exactly 1, in both precisions, and refraction fails.
        for k in 0..200 {
            let theta = tc + 1e-5 + (FRAC_PI_2 - tc - 1e-5) * k as f64 / 199.0;
            assert_eq!(fresnel_dielectric_f64(theta.cos(), eta), 1.0);
            assert_eq!(fresnel_dielectric(theta.cos() as f32, eta as f32), 1.0);
            let wo = Vec3::new(theta.sin() as f32, 0.0, theta.cos() as f32);
            assert!(refract(wo, Vec3::Z, eta as f32).is_none(), "{n1}->{n2} at {theta}");
        }
        // Below it: R < 1 and R increases towards 1 with the analytic square-root law
        // 1 - R ~ 2 (eta + 1/eta) cos_t / cos_c,  cos_t ~ sqrt(2 eta cos_c delta).
        let mut prev = 0.0;
        for e in 2..=12 {
            let delta = 10f64.powi(-e);
            let r = fresnel_dielectric_f64((tc - delta).cos(), eta);
            assert!(r < 1.0 && r > prev, "{n1}->{n2}: not increasing at delta {delta}");
            prev = r;
            let cc = tc.cos();
            let law = 2.0 * (eta + 1.0 / eta) * (2.0 * eta * cc * delta).sqrt() / cc;
            if e >= 8 {
                assert!(((1.0 - r) / law - 1.0).abs() < 1e-2, "{n1}->{n2} at {delta}: {r} vs law {law}");
            }
            if e >= 9 {
                assert!(1.0 - r < 1e-3, "{n1}->{n2}: 1-R = {} at {delta}", 1.0 - r);
            }
        }
        // f32 near the critical angle, from below, stays within the conditioning of the problem:
        // |dR/dcos_i| ~ 2 (eta + 1/eta) eta^2 / cos_t, times an f32 rounding of cos_t^2.
        for k in 1..=100 {
            let theta = tc - 1e-4 * k as f64;
            let c32 = theta.cos() as f32;
            let r64 = fresnel_dielectric_f64(c32 as f64, eta as f32 as f64);
            let r32 = fresnel_dielectric(c32, eta as f32) as f64;
            let ct = (1.0 - (eta * theta.sin()).powi(2)).sqrt();
            let bound = 1e-5 + 2.0 * (eta + 1.0 / eta) / tc.cos() * (eta * eta * 4e-7) / ct;
            assert!((r32 - r64).abs() < bound, "{n1}->{n2} at {theta}: {r32} vs {r64}");
            assert!(r32 < 1.0);
        }
    }
    assert!(critical_angle(1.0, 1.5).is_none() && critical_angle(1.5, 1.5).is_none());
}

#[test]
fn schlick_close_to_exact_and_exact_at_normal_incidence() {
    for k in 0..1000 {
        let theta = (k as f32 + 0.5) / 1000.0 * std::f32::consts::FRAC_PI_2;
        let c = theta.cos();
        let (s, e) = (fresnel_schlick(c, 1.0 / 1.5), fresnel_dielectric(c, 1.0 / 1.5));
        assert!((s - e).abs() < 0.05, "air->glass at {theta}: schlick {s} exact {e}");
        // From inside glass Schlick uses the transmitted cosine, and TIR agrees exactly.
        let (s, e) = (fresnel_schlick(c, 1.5), fresnel_dielectric(c, 1.5));
        assert!((s - e).abs() < 0.05, "glass->air at {theta}: schlick {s} exact {e}");
        assert_eq!(s == 1.0, e == 1.0);
    }
    for eta in [1.0 / 1.5, 1.5, 1.0 / 2.42, 2.42, 1.0 / 1.0001, 0.75, 1.0] {
        assert_eq!(fresnel_schlick(1.0, eta), fresnel_dielectric(1.0, eta), "eta {eta}");
    }
    // No interface, no reflection, at any angle.
    assert_eq!(fresnel_schlick(0.01, 1.0), 0.0);
}

// ---------------------------------------------------------------------------------------------
// Reflection and refraction

#[test]
fn refract_obeys_snell_and_round_trips() {
    let mut r = rng(1);
    let mut checked = 0;
    for _ in 0..20_000 {
        let n = uniform_sphere(&mut r);
        let mut wo = uniform_sphere(&mut r);
        if wo.dot(n) < 0.0 {
            wo = -wo;
        }
        let eta = 0.3 + 2.5 * uf(&mut r);
        let ci = wo.dot(n) as f64;
        let (wo64, n64) = (wo.as_dvec3(), n.as_dvec3());
        let sin_i = wo64.cross(n64).length();
        let Some(t) = refract(wo, n, eta) else {
            assert!(eta as f64 * sin_i > 1.0 - 1e-5, "None below the critical angle");
            assert_eq!(fresnel_dielectric(wo.dot(n), eta), 1.0);
            continue;
        };
        assert!(eta as f64 * sin_i < 1.0 + 1e-5, "Some beyond the critical angle");
        assert!(fresnel_dielectric(wo.dot(n), eta) < 1.0);
        let t64 = t.as_dvec3();
        assert!((t64.length() - 1.0).abs() < 1e-6);
        assert!(t.dot(n) <= 0.0, "transmitted direction on the incident side");
        // Snell: n1 sin(t1) = n2 sin(t2)  <=>  eta sin_i = sin_t.
        let sin_t = t64.cross(n64).length();
        assert!((eta as f64 * sin_i - sin_t).abs() < 1e-5, "{eta} {sin_i} {sin_t}");
        // Coplanar with wo and n, on the other side of n from wo's tangential part.
        assert!(t64.dot(wo64.cross(n64)).abs() < 1e-5);
        // Back through the interface from the other side returns wo (away from grazing exits).
        if ci > 0.05 && t.dot(-n) > 0.05 {
            let back = refract(t, -n, 1.0 / eta).expect("reverse path cannot be TIR");
            assert!((back - wo).length() < 2e-5, "{back} vs {wo}, eta {eta}");
            checked += 1;
        }
    }
    assert!(checked > 5_000);
}

#[test]
fn refract_identity_reflect_and_critical_boundary() {
    let mut r = rng(2);
    for _ in 0..1000 {
        let n = uniform_sphere(&mut r);
        let mut wo = uniform_sphere(&mut r);
        if wo.dot(n) < 0.0 {
            wo = -wo;
        }
        assert_eq!(refract(wo, n, 1.0), Some(-wo));
        let m = reflect(wo, n);
        assert!((m.dot(n) - wo.dot(n)).abs() < 1e-6 && (m + wo).cross(n).length() < 1e-5);
        assert!((m.length() - 1.0).abs() < 1e-6);
    }
    // None exactly past the critical angle, Some just before it.
    for (n1, n2) in [(1.5f64, 1.0f64), (2.42, 1.0), (1.33, 1.0)] {
        let tc = (n2 / n1).asin();
        for d in [1e-3, 1e-4, 2e-5] {
            let at = |t: f64| Vec3::new(t.sin() as f32, 0.0, t.cos() as f32);
            assert!(refract(at(tc - d), Vec3::Z, (n1 / n2) as f32).is_some());
            assert!(refract(at(tc + d), Vec3::Z, (n1 / n2) as f32).is_none());
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Beer-Lambert

#[test]
fn beer_lambert_identities() {
    let mut r = rng(3);
    for _ in 0..2000 {
        let s = Vec3::new(uf(&mut r), uf(&mut r), uf(&mut r)) * 5.0;
        let (d1, d2) = (uf(&mut r) * 3.0, uf(&mut r) * 3.0);
        let t = beer_lambert(s, d1);
        for c in 0..3 {
            let want = (-(s[c] as f64) * d1 as f64).exp();
            assert!((t[c] as f64 - want).abs() <= 1e-6 * want + 1e-30);
        }
        let prod = beer_lambert(s, d1) * beer_lambert(s, d2);
        assert!((beer_lambert(s, d1 + d2) - prod).abs().max_element() < 1e-6);
        assert_eq!(beer_lambert(s, 0.0), Vec3::ONE);

        let color = Vec3::new(uf(&mut r), uf(&mut r), uf(&mut r)) * 0.999 + Vec3::splat(1e-3);
        let dist = 0.01 + 100.0 * uf(&mut r);
        let sigma = sigma_from_transmittance(color, dist);
        let back = beer_lambert(sigma, dist);
        assert!(((back - color) / color).abs().max_element() < 2e-5, "{color} -> {back}");
    }
    let inf = f32::INFINITY;
    assert_eq!(beer_lambert(Vec3::new(0.0, 1.0, 0.0), inf), Vec3::new(1.0, 0.0, 1.0));
    // A negative distance is no path at all (documented as 0): transmittance exactly 1, never a gain,
    // also at -inf (where the unclamped exponent would be +inf).
    let sigma = Vec3::new(0.5, 1.0, 3.0);
    assert_eq!(beer_lambert(sigma, -1.0), Vec3::ONE);
    assert_eq!(beer_lambert(sigma, -inf), Vec3::ONE);
    assert_eq!(sigma_from_transmittance(Vec3::ONE, 2.0), Vec3::ZERO);
    let s = sigma_from_transmittance(Vec3::new(0.0, 0.5, 1.0), 0.0);
    assert!(s.is_finite() && s.min_element() >= 0.0);
}

// ---------------------------------------------------------------------------------------------
// Dispersion and spectral weights

#[test]
fn abbe_to_cauchy_reproduces_catalogue() {
    // (nd, Vd): N-BK7, F2, N-SF11, fused silica.
    for (nd, vd) in [(1.5168f32, 64.17f32), (1.62004, 36.37), (1.78472, 25.68), (1.4585, 67.82)] {
        let ior = Ior::Abbe { nd, vd };
        assert!(ior.is_dispersive());
        assert!((ior.at(587.6) - nd).abs() < 1e-4);
        assert!((ior.at_f64(LAMBDA_D as f64) - nd as f64).abs() < 1e-9);
        assert_eq!(ior.nominal(), nd);
        let (nf, nc) = (ior.at_f64(LAMBDA_F as f64), ior.at_f64(LAMBDA_C as f64));
        let v = (nd as f64 - 1.0) / (nf - nc);
        assert!((v - vd as f64).abs() < 1e-4, "Vd {v} vs {vd}");
        // Normal dispersion, and the f32 path agrees with the f64 one.
        let mut prev = f32::INFINITY;
        for l in (380..=720).step_by(10) {
            let n = ior.at(l as f32);
            assert!(n < prev);
            prev = n;
            assert!((n as f64 - ior.at_f64(l as f64)).abs() < 2e-6);
        }
        let (a, b) = ior.cauchy();
        let c = Ior::Cauchy { a, b_um2: b };
        assert!((c.at(500.0) - ior.at(500.0)).abs() < 1e-6 && (c.nominal() - nd).abs() < 1e-4);
    }
    let bk7 = Ior::Abbe { nd: 1.5168, vd: 64.17 };
    assert!((bk7.at(486.1) - 1.5224).abs() < 2e-3 && (bk7.at(656.3) - 1.5143).abs() < 2e-3);
    assert!((bk7.at(486.1) - 1.52238).abs() < 2e-4 && (bk7.at(656.3) - 1.51432).abs() < 2e-4);

    for ior in [Ior::Constant(1.5), Ior::Abbe { nd: 1.5, vd: 0.0 }, Ior::Abbe { nd: 1.5, vd: f32::INFINITY }] {
        assert!(!ior.is_dispersive());
        assert_eq!(ior.at(400.0), 1.5);
        assert_eq!(ior.at(700.0), 1.5);
        assert_eq!(ior.nominal(), 1.5);
    }
    let c = Ior::Cauchy { a: 1.5, b_um2: 0.0042 };
    assert_eq!(c.at(500.0), 1.5 + 0.0042 / 0.25);
    assert!(c.at(0.0).is_finite());
}

#[test]
fn wavelength_sampler_is_consistent_with_its_pdf() {
    // The hard-coded tanh bounds map u = 0 and u = 1 to the ends of the range.
    let (lo, hi) = (sample_wavelength(0.0) as f64, sample_wavelength(1.0) as f64);
    assert!((lo - LAMBDA_MIN as f64).abs() < 0.05 && (hi - LAMBDA_MAX as f64).abs() < 0.05, "{lo} {hi}");
    // pdf = du/dlambda of the sampler (central differences), and it integrates to 1.
    let mut prev = 0.0;
    for i in 1..1000 {
        let u = i as f32 / 1000.0;
        let l = sample_wavelength(u);
        assert!(l > prev && (LAMBDA_MIN..=LAMBDA_MAX).contains(&l));
        prev = l;
        let h = 1e-3f32;
        let dl = (sample_wavelength(u + h) - sample_wavelength(u - h)) as f64 / (2.0 * h as f64);
        let p = sample_wavelength_pdf(l) as f64;
        assert!((p * dl - 1.0).abs() < 2e-3, "u {u}: pdf {p} dlambda/du {dl}");
    }
    let n = 100_000;
    let step = (LAMBDA_MAX - LAMBDA_MIN) as f64 / n as f64;
    let total: f64 = (0..n).map(|i| sample_wavelength_pdf(LAMBDA_MIN + ((i as f64 + 0.5) * step) as f32) as f64 * step).sum();
    assert!((total - 1.0).abs() < 1e-4, "{total}");
    assert_eq!(sample_wavelength_pdf(379.0), 0.0);
    assert_eq!(sample_wavelength_pdf(721.0), 0.0);
}

/// CIE 1931 2° colour matching functions, 380..=720 nm every 10 nm (CIE 15:2004 table).
const CIE_1931: [[f64; 3]; 35] = [
    [0.001368, 0.000039, 0.006450],
    [0.004243, 0.000120, 0.020050],
    [0.014310, 0.000396, 0.067850],
    [0.043510, 0.001210, 0.207400],
    [0.134380, 0.004000, 0.645600],
    [0.283900, 0.011600, 1.385600],
    [0.348280, 0.023000, 1.747060],
    [0.336200, 0.038000, 1.772110],
    [0.290800, 0.060000, 1.669200],
    [0.195360, 0.090980, 1.287640],
    [0.095640, 0.139020, 0.812950],
    [0.032010, 0.208020, 0.465180],
    [0.004900, 0.323000, 0.272000],
    [0.009300, 0.503000, 0.158200],
    [0.063270, 0.710000, 0.078250],
    [0.165500, 0.862000, 0.042160],
    [0.290400, 0.954000, 0.020300],
    [0.433450, 0.994950, 0.008750],
    [0.594500, 0.995000, 0.003900],
    [0.762100, 0.952000, 0.002100],
    [0.916300, 0.870000, 0.001650],
    [1.026300, 0.757000, 0.001100],
    [1.062200, 0.631000, 0.000800],
    [1.002600, 0.503000, 0.000340],
    [0.854450, 0.381000, 0.000190],
    [0.642400, 0.265000, 0.000050],
    [0.447900, 0.175000, 0.000020],
    [0.283500, 0.107000, 0.000000],
    [0.164900, 0.061000, 0.000000],
    [0.087400, 0.032000, 0.000000],
    [0.046770, 0.017000, 0.000000],
    [0.022700, 0.008210, 0.000000],
    [0.011359, 0.004102, 0.000000],
    [0.005790, 0.002091, 0.000000],
    [0.002899, 0.001047, 0.000000],
];

fn hue_deg(c: Vec3) -> f64 {
    let (r, g, b) = (c.x as f64, c.y as f64, c.z as f64);
    (3f64.sqrt() * (g - b)).atan2(2.0 * r - g - b).to_degrees().rem_euclid(360.0)
}

#[test]
fn wavelength_to_rgb_is_white_on_average_and_has_spectral_hues() {
    // Estimator w / pdf averaged over a fine quadrature of the sampling density (u-space).
    let n = 200_000;
    let mut acc = DVec3::ZERO;
    for i in 0..n {
        let l = sample_wavelength((i as f32 + 0.5) / n as f32);
        acc += (wavelength_to_rgb(l) / sample_wavelength_pdf(l)).as_dvec3();
    }
    let avg = acc / n as f64;
    assert!((avg - DVec3::ONE).abs().max_element() < 1e-3, "{avg}");
    // And the same identity directly in wavelength: ∫ w dl = 1.
    let step = (LAMBDA_MAX - LAMBDA_MIN) as f64 / n as f64;
    let mut acc = DVec3::ZERO;
    for i in 0..n {
        acc += wavelength_to_rgb(LAMBDA_MIN + ((i as f64 + 0.5) * step) as f32).as_dvec3() * step;
    }
    assert!((acc - DVec3::ONE).abs().max_element() < 1e-3, "{acc}");
    assert_eq!(wavelength_to_rgb(300.0), Vec3::ZERO);
    assert_eq!(wavelength_to_rgb(800.0), Vec3::ZERO);

    // The fit follows the tabulated CMFs.
    for (i, row) in CIE_1931.iter().enumerate() {
        let l = 380.0 + 10.0 * i as f32;
        let f = cie_xyz_fit(l).as_dvec3();
        assert!((f - DVec3::from(*row)).abs().max_element() < 0.02, "{l} nm: {f} vs {row:?}");
    }
    // Channel peaks of the weights are where the tabulated CMFs put them (within one table step).
    for ch in 0..3 {
        let table_peak = (0..35)
            .max_by(|&a, &b| {
                let t = |i: usize| xyz_to_linear_srgb(DVec3::from(CIE_1931[i]).as_vec3())[ch];
                t(a).total_cmp(&t(b))
            })
            .map(|i| 380.0 + 10.0 * i as f32)
            .unwrap();
        let fit_peak =
            (380..=720).max_by(|&a, &b| wavelength_to_rgb(a as f32)[ch].total_cmp(&wavelength_to_rgb(b as f32)[ch])).unwrap() as f32;
        assert!((fit_peak - table_peak).abs() <= 10.0, "channel {ch}: {fit_peak} vs {table_peak}");
    }
    // 450 nm is blue, 530 green, 620 red, and the dominant channel wins by a wide margin.
    let (b, g, r) = (wavelength_to_rgb(450.0), wavelength_to_rgb(530.0), wavelength_to_rgb(620.0));
    assert!(b.z > 4.0 * b.x.max(b.y) && g.y > 4.0 * g.x.max(g.z) && r.x > 4.0 * r.y.max(r.z));
    let chroma = |c: Vec3, k: usize| c[k] / (c.x + c.y + c.z);
    assert!(chroma(b, 2) > chroma(g, 2) && chroma(b, 2) > chroma(r, 2));
    assert!(chroma(g, 1) > chroma(b, 1) && chroma(g, 1) > chroma(r, 1));
    assert!(chroma(r, 0) > chroma(b, 0) && chroma(r, 0) > chroma(g, 0));
    let (hb, hg, hr) = (hue_deg(b), hue_deg(g), hue_deg(r));
    assert!((225.0..255.0).contains(&hb) && (105.0..135.0).contains(&hg) && !(15.0..345.0).contains(&hr));
    // Hue runs from violet through blue, cyan, green, yellow to red as the wavelength grows
    // (the fit's tails below 420 nm and above 680 nm carry < 5% of the peak and are left out).
    let mut prev = 360.0;
    for l in (420..=680).step_by(5) {
        let h = hue_deg(wavelength_to_rgb(l as f32));
        let h = if h > 300.0 { h - 360.0 } else { h };
        assert!(h <= prev + 2.0, "hue not decreasing at {l} nm: {h} after {prev}");
        prev = prev.min(h);
    }
    for pair in [[450.0, 480.0], [480.0, 500.0], [500.0, 560.0], [560.0, 580.0], [580.0, 600.0]] {
        assert!(hue_deg(wavelength_to_rgb(pair[0])) > hue_deg(wavelength_to_rgb(pair[1])) + 5.0);
    }
}
