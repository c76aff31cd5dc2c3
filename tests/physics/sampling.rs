//! Sampling lobes: cosine hemisphere (Lambert), orthonormal basis, GGX visible-normal reflection.
//! Quadratures of densities and chi-square tests of samplers against them (fixed seeds).

use super::*;

// ---------------------------------------------------------------------------------------------
// Lambert

#[test]
fn onb_is_orthonormal() {
    let mut r = rng(4);
    let mut normals: Vec<Vec3> = (0..10_000).map(|_| uniform_sphere(&mut r)).collect();
    normals.extend([
        Vec3::Z,
        -Vec3::Z,
        Vec3::X,
        -Vec3::Y,
        Vec3::new(1e-4, -2e-4, -1.0).normalize(),
        Vec3::new(1e-7, 0.0, -1.0).normalize(),
        Vec3::new(0.6, 0.8, -0.0),
        Vec3::new(0.6, 0.8, 0.0),
    ]);
    for n in normals {
        let (t, b) = onb(n);
        for (x, y) in [(t, b), (t, n), (b, n)] {
            assert!(x.dot(y).abs() < 1e-6, "n {n}: {x} . {y}");
        }
        assert!((t.length() - 1.0).abs() < 1e-6 && (b.length() - 1.0).abs() < 1e-6, "n {n}");
        assert!((t.cross(b) - n).length() < 1e-5, "n {n}: not right-handed");
    }
}

#[test]
fn cosine_hemisphere_pdf_integrates_to_one_and_matches_samples() {
    for n in [Vec3::new(0.3, -0.5, 0.8).normalize(), -Vec3::Z, Vec3::new(-0.9, 0.1, 0.05).normalize()] {
        let n64 = n.as_dvec3();
        // Quadrature over the full sphere around an unrelated axis (the pdf is 0 below).
        let axis = DVec3::new(0.2, 0.9, -0.4).normalize();
        let total = integrate_sphere(axis, 1.0, 800, 800, |w| sample_hemisphere_cos_pdf(n, v3(w)) as f64);
        assert!((total - 1.0).abs() < 2e-3, "n {n}: ∫pdf = {total}");

        let (nc, np) = (10, 16);
        let mut obs = vec![0.0; nc * np];
        let mut r = rng(5);
        let samples = 100_000;
        for _ in 0..samples {
            let w = sample_hemisphere_cos(n, [uf(&mut r), uf(&mut r)]);
            assert!((w.length() - 1.0).abs() < 1e-5 && w.dot(n) >= -1e-6);
            let (c, phi) = coords_around(n64, w.as_dvec3());
            let i = ((c.clamp(0.0, 1.0) * nc as f64) as usize).min(nc - 1);
            let j = ((phi / (2.0 * PI) * np as f64) as usize).min(np - 1);
            obs[i * np + j] += 1.0;
        }
        // P(bin) = ∫ cos/pi dw = (c1^2 - c0^2) / 2 * dphi / pi.
        let mut exp = vec![0.0; nc * np];
        for i in 0..nc {
            let (c0, c1) = (i as f64 / nc as f64, (i + 1) as f64 / nc as f64);
            for j in 0..np {
                exp[i * np + j] = samples as f64 * (c1 * c1 - c0 * c0) / 2.0 * (2.0 / np as f64);
            }
        }
        let (stat, dof) = chi2(&obs, &exp);
        assert!(stat < chi2_critical(dof, 3.09), "n {n}: chi2 {stat} dof {dof}");
    }
}

// ---------------------------------------------------------------------------------------------
// GGX

const GGX_ALPHAS: [f32; 3] = [0.05, 0.3, 1.0];

fn wo_at(n: Vec3, cos_o: f64) -> Vec3 {
    v3(dir_around(n.as_dvec3(), cos_o, 0.7))
}

#[test]
fn ggx_d_is_normalised() {
    for alpha in GGX_ALPHAS.into_iter().chain([0.01, 0.7]) {
        let total = integrate_sphere(DVec3::Z, 2.0 * alpha as f64, 4000, 64, |h| h.z.max(0.0) * ggx_d(h.z as f32, alpha) as f64);
        assert!((total - 1.0).abs() < 1e-3, "alpha {alpha}: ∫D cos = {total}");
    }
    // Peak value 1 / (pi alpha^2), finite down to the clamp.
    for alpha in [1e-4f32, 1e-2, 0.5] {
        let d = ggx_d(1.0, alpha) as f64;
        assert!((d * PI * (alpha as f64).powi(2) - 1.0).abs() < 1e-5);
    }
    assert!(ggx_d(1.0, 0.0).is_finite() && ggx_d(0.0, 0.3) == 0.0 && ggx_d(-0.5, 0.3) == 0.0);
}

/// Fraction of `u` in a midpoint grid of `[0,1)^2` for which the sampler returns `None`.
fn ggx_none_fraction(wo: Vec3, n: Vec3, alpha: f32, grid: usize) -> f64 {
    let mut none = 0usize;
    for i in 0..grid {
        for j in 0..grid {
            let u = [(i as f32 + 0.5) / grid as f32, (j as f32 + 0.5) / grid as f32];
            none += sample_ggx_reflect(wo, n, alpha, u).is_none() as usize;
        }
    }
    none as f64 / (grid * grid) as f64
}

#[test]
fn ggx_pdf_integrates_to_one_minus_lost_mass() {
    let n = Vec3::new(0.2, -0.3, 0.9).normalize();
    let mut saw_loss = false;
    for alpha in GGX_ALPHAS.into_iter().chain([0.01]) {
        for cos_o in [1.0, 0.7, 0.15] {
            let wo = wo_at(n, cos_o);
            let mirror = reflect(wo, n).as_dvec3();
            let total = integrate_sphere(mirror, 2.0 * alpha as f64, 2000, 256, |w| sample_ggx_reflect_pdf(wo, n, v3(w), alpha) as f64);
            let lost = ggx_none_fraction(wo, n, alpha, 1024);
            saw_loss |= lost > 0.01;
            if cos_o == 1.0 {
                // At normal incidence the VNDF is D(h) cos(h): P(tan h > 1) = alpha^2 / (1 + alpha^2)
                // of the reflections leave below the horizon.
                let a2 = (alpha as f64).powi(2);
                assert!((lost - a2 / (1.0 + a2)).abs() < 2e-3, "alpha {alpha}: lost {lost}");
            }
            assert!((total + lost - 1.0).abs() < 3e-3, "alpha {alpha} cos {cos_o}: ∫pdf {total} + lost {lost}");
        }
    }
    assert!(saw_loss, "no configuration lost mass: the test does not exercise None");
}

#[test]
fn ggx_samples_follow_pdf_chi_square() {
    let n = Vec3::new(-0.4, 0.1, 0.8).normalize();
    let n64 = n.as_dvec3();
    for (alpha, cos_o, seed) in [(0.3f32, 0.87, 6u64), (0.7, 0.34, 7), (0.15, 0.6, 8)] {
        let wo = wo_at(n, cos_o);
        let (nc, np, sub) = (16, 16, 24);
        let samples = 100_000;
        let mut obs = vec![0.0; nc * np + 1];
        let mut r = rng(seed);
        for _ in 0..samples {
            match sample_ggx_reflect(wo, n, alpha, [uf(&mut r), uf(&mut r)]) {
                None => obs[nc * np] += 1.0,
                Some(w) => {
                    assert!((w.length() - 1.0).abs() < 1e-5 && w.dot(n) > 0.0);
                    let (c, phi) = coords_around(n64, w.as_dvec3());
                    let i = ((c * nc as f64) as usize).min(nc - 1);
                    let j = ((phi / (2.0 * PI) * np as f64) as usize).min(np - 1);
                    obs[i * np + j] += 1.0;
                }
            }
        }
        // Expected: pdf integrated over each (cos, phi) bin by a sub-grid midpoint rule
        // (dw = dcos dphi); the None bin gets the rest.
        let mut exp = vec![0.0; nc * np + 1];
        let (dc, dp) = (1.0 / (nc * sub) as f64, 2.0 * PI / (np * sub) as f64);
        for i in 0..nc * sub {
            let c = (i as f64 + 0.5) * dc;
            for j in 0..np * sub {
                let phi = (j as f64 + 0.5) * dp;
                let w = v3(dir_around(n64, c, phi));
                exp[(i / sub) * np + j / sub] += sample_ggx_reflect_pdf(wo, n, w, alpha) as f64 * dc * dp;
            }
        }
        let inside: f64 = exp.iter().sum();
        exp[nc * np] = 1.0 - inside;
        for e in exp.iter_mut() {
            *e *= samples as f64;
        }
        let (stat, dof) = chi2(&obs, &exp);
        assert!(stat < chi2_critical(dof, 3.09), "alpha {alpha}: chi2 {stat} dof {dof}");
    }
}

#[test]
fn ggx_weight_equals_eval_over_pdf_and_brdf_is_reciprocal() {
    let mut r = rng(9);
    let mut checked = 0;
    for alpha in [0.01f32, 0.1, 0.5, 1.0] {
        for _ in 0..5000 {
            let n = uniform_sphere(&mut r);
            let (mut wo, mut wi) = (uniform_sphere(&mut r), uniform_sphere(&mut r));
            if wo.dot(n) < 0.0 {
                wo = -wo;
            }
            if wi.dot(n) < 0.0 {
                wi = -wi;
            }
            let (e, p, w) =
                (eval_ggx_reflect(wo, n, wi, alpha), sample_ggx_reflect_pdf(wo, n, wi, alpha), sample_ggx_reflect_weight(wo, n, wi, alpha));
            assert!(e.is_finite() && p.is_finite() && (0.0..=1.0).contains(&w));
            if p > 1e-20 && wo.dot(n) > 1e-3 && wi.dot(n) > 1e-3 {
                assert!(((e / p) as f64 / w as f64 - 1.0).abs() < 1e-4, "alpha {alpha}: {e}/{p} vs {w}");
                // BRDF symmetry: eval / cos_i is the BRDF.
                let f1 = e / wi.dot(n);
                let f2 = eval_ggx_reflect(wi, n, wo, alpha) / wo.dot(n);
                assert!((f1 / f2 - 1.0).abs() < 1e-3, "alpha {alpha}: {f1} vs {f2}");
                // Weight is G2 / G1(wo).
                let g = ggx_g2(wo.dot(n), wi.dot(n), alpha) / ggx_g1(wo.dot(n), alpha);
                assert!((g - w).abs() < 1e-5);
                checked += 1;
            }
        }
    }
    assert!(checked > 15_000);
    // Below the surface everything is 0.
    let (n, wo) = (Vec3::Z, Vec3::new(0.6, 0.0, 0.8));
    let below = Vec3::new(0.6, 0.0, -0.8);
    assert_eq!(eval_ggx_reflect(wo, n, below, 0.3), 0.0);
    assert_eq!(sample_ggx_reflect_pdf(wo, n, below, 0.3), 0.0);
    assert_eq!(sample_ggx_reflect_weight(wo, n, below, 0.3), 0.0);
    assert!(sample_ggx_reflect(below, n, 0.3, [0.5, 0.5]).is_none());
}

#[test]
fn ggx_white_furnace() {
    // Albedo of the lobe = E[weight] (None counts 0). It must be <= 1, equal the quadrature of `eval`
    // alone (independent of the sampler), and at normal incidence stay below 1 - alpha^2/(1 + alpha^2),
    // the mass reflected below the horizon. For alpha = 0.3 that bound is 0.917 and the albedo is
    // ~0.88; albedo > 0.9 holds for roughness 0.3, i.e. alpha = 0.09.
    let n = Vec3::new(0.1, 0.2, 1.0).normalize();
    for (alpha, cos_o) in [(0.3f32, 1.0), (0.3, 0.9), (0.09, 1.0), (0.09, 0.9), (0.1, 0.5), (0.8, 0.6)] {
        let wo = wo_at(n, cos_o);
        let mut r = rng(10);
        let samples = 100_000;
        let (mut sum, mut sum2) = (0.0f64, 0.0f64);
        for _ in 0..samples {
            if let Some(wi) = sample_ggx_reflect(wo, n, alpha, [uf(&mut r), uf(&mut r)]) {
                let w = sample_ggx_reflect_weight(wo, n, wi, alpha) as f64;
                assert!((0.0..=1.0).contains(&w));
                sum += w;
                sum2 += w * w;
            }
        }
        let mean = sum / samples as f64;
        let sigma = ((sum2 / samples as f64 - mean * mean) / samples as f64).sqrt();
        assert!(mean <= 1.0 && mean > 0.3, "alpha {alpha} cos {cos_o}: albedo {mean}");
        let mirror = reflect(wo, n).as_dvec3();
        let quad = integrate_sphere(mirror, 2.0 * alpha as f64, 2000, 256, |w| eval_ggx_reflect(wo, n, v3(w), alpha) as f64);
        assert!((mean - quad).abs() < 4.0 * sigma + 1e-4, "alpha {alpha} cos {cos_o}: MC {mean} quad {quad}");
        let a2 = (alpha as f64).powi(2);
        if cos_o == 1.0 {
            assert!(mean < 1.0 - a2 / (1.0 + a2), "alpha {alpha}: {mean}");
        }
        if alpha == 0.09 {
            assert!(mean > 0.9, "alpha {alpha} cos {cos_o}: albedo {mean}");
        }
    }
}

#[test]
fn ggx_sampling_converges_to_mirror() {
    // Normal incidence: the half-vector angle is exactly atan(alpha sqrt(u0 / (1 - u0))).
    for alpha in [1e-4f32, 1e-2, 0.3] {
        for k in 0..50 {
            let u0 = k as f32 / 50.0;
            let want = 2.0 * (alpha as f64 * (u0 as f64 / (1.0 - u0 as f64)).sqrt()).atan();
            let sampled = sample_ggx_reflect(Vec3::Z, Vec3::Z, alpha, [u0, 0.37]);
            assert_eq!(sampled.is_none(), want >= FRAC_PI_2, "alpha {alpha} u0 {u0}");
            let Some(wi) = sampled else { continue };
            let got = (wi.z as f64).clamp(-1.0, 1.0).acos();
            let got = if got < 1e-3 { (wi.x as f64).hypot(wi.y as f64).asin() } else { got };
            assert!((got - want).abs() < 2e-5 + 1e-4 * want, "alpha {alpha} u0 {u0}: {got} vs {want}");
        }
    }
    let mut r = rng(11);
    for _ in 0..20_000 {
        let n = uniform_sphere(&mut r);
        let mut wo = uniform_sphere(&mut r);
        if wo.dot(n) < 0.05 {
            continue;
        }
        wo = if wo.dot(n) < 0.0 { -wo } else { wo };
        let u = [uf(&mut r) * 0.99, uf(&mut r)];
        for alpha in [0.0f32, 1e-4] {
            let wi = sample_ggx_reflect(wo, n, alpha, u).expect("a near-mirror lobe stays above");
            let m = reflect(wo, n);
            let angle = wi.cross(m).length().asin();
            assert!(angle < 1e-2, "alpha {alpha}: {angle} rad off the mirror");
            let (e, p, w) =
                (eval_ggx_reflect(wo, n, wi, alpha), sample_ggx_reflect_pdf(wo, n, wi, alpha), sample_ggx_reflect_weight(wo, n, wi, alpha));
            assert!(e.is_finite() && p.is_finite() && w.is_finite() && w > 0.9);
            let pm = sample_ggx_reflect_pdf(wo, n, m, alpha);
            assert!(pm.is_finite() && pm > 0.0);
        }
    }
}
