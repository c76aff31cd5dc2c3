//! Tests of the warps of `strata::sample`: filter importance sampling and the concentric lens disk,
//! against analytic distributions. Fixed seeds; statistical bounds are ~5 standard deviations (or
//! chi-square at dof + 5 sqrt(2 dof)).

use rand_core::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use strata::sample::*;

const SEED: u64 = 0x5eed;

fn chi_square(counts: &[u64], expected: &[f64]) -> f64 {
    counts.iter().zip(expected).map(|(&c, &e)| (c as f64 - e).powi(2) / e).sum()
}

/// Chi-square acceptance bound for `dof` degrees of freedom: mean + 5 standard deviations.
fn chi_bound(dof: usize) -> f64 {
    dof as f64 + 5.0 * (2.0 * dof as f64).sqrt()
}

/// Independent uniforms from xoshiro (not from the sampler under test), on the same 2^-24 grid.
fn uniforms(seed: u64, count: usize) -> Vec<[f32; 2]> {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut u = || (rng.next_u32() >> 8) as f32 / 16_777_216.0;
    (0..count).map(|_| [u(), u()]).collect()
}

// ---------------------------------------------------------------------------------------------------
// Filters

#[test]
fn filter_offsets_have_zero_mean_and_stay_in_support() {
    let us = uniforms(21, 400_000);
    for f in Filter::ALL {
        let (mut sx, mut sy, mut sxx) = (0.0f64, 0.0f64, 0.0f64);
        for &u in &us {
            let [dx, dy] = sample_filter(f, u);
            assert!(dx.abs() <= f.radius() && dy.abs() <= f.radius(), "{f:?} {u:?}");
            if f == Filter::Box {
                assert!((-0.5..0.5).contains(&dx) && (-0.5..0.5).contains(&dy));
            }
            (sx, sy, sxx) = (sx + dx as f64, sy + dy as f64, sxx + (dx as f64).powi(2));
        }
        let m = us.len() as f64;
        let sd = (sxx / m / m).sqrt();
        assert!((sx / m).abs() < 5.0 * sd && (sy / m).abs() < 5.0 * sd, "{f:?} mean");
    }
}

#[test]
fn box_is_uniform() {
    let us = uniforms(20, 100_000);
    let bins = 10;
    let mut h = vec![0u64; bins * bins];
    for &u in &us {
        let [dx, dy] = sample_filter(Filter::Box, u);
        let (i, j) = (((dx + 0.5) * bins as f32) as usize, ((dy + 0.5) * bins as f32) as usize);
        h[j.min(bins - 1) * bins + i.min(bins - 1)] += 1;
    }
    let e = us.len() as f64 / (bins * bins) as f64;
    let chi = chi_square(&h, &vec![e; bins * bins]);
    assert!(chi < chi_bound(bins * bins - 1), "chi2 {chi}");
}

#[test]
fn tent_histogram_matches_tent_pdf() {
    let us = uniforms(22, 200_000);
    let bins = 40;
    let cdf = |x: f64| {
        if x < 0.0 {
            0.5 * (1.0 + x).powi(2)
        } else {
            1.0 - 0.5 * (1.0 - x).powi(2)
        }
    };
    for axis in 0..2 {
        let mut h = vec![0u64; bins];
        for &u in &us {
            let d = sample_filter(Filter::Tent, u)[axis] as f64;
            h[(((d + 1.0) / 2.0 * bins as f64) as usize).min(bins - 1)] += 1;
        }
        let e: Vec<f64> = (0..bins)
            .map(|k| {
                let a = -1.0 + 2.0 * k as f64 / bins as f64;
                let b = -1.0 + 2.0 * (k + 1) as f64 / bins as f64;
                (cdf(b) - cdf(a)) * us.len() as f64
            })
            .collect();
        let chi = chi_square(&h, &e);
        assert!(chi < chi_bound(bins - 1), "axis {axis}: chi2 {chi}");
    }
}

#[test]
fn gaussian_variance_and_radial_distribution() {
    let us = uniforms(23, 400_000);
    // Radially truncated 2D Gaussian, sigma^2 = 1/4, R = 3 sigma: E[r^2] = 2 s^2 - R^2 e^(-R^2/2s^2) /
    // (1 - e^(-R^2/2s^2)), and the per-axis variance is half of it (0.23736).
    let (s2, r2max) = (0.25f64, 2.25f64);
    let t = (-r2max / (2.0 * s2)).exp();
    let var_axis = 0.5 * (2.0 * s2 - r2max * t / (1.0 - t));
    let bins = 30;
    let mut h = vec![0u64; bins];
    let (mut sxx, mut syy, mut x4) = (0.0f64, 0.0f64, 0.0f64);
    for &u in &us {
        let [dx, dy] = sample_filter(Filter::Gaussian, u);
        let (dx, dy) = (dx as f64, dy as f64);
        sxx += dx * dx;
        syy += dy * dy;
        x4 += dx.powi(4);
        let r2 = dx * dx + dy * dy;
        h[((r2 / r2max * bins as f64) as usize).min(bins - 1)] += 1;
    }
    let m = us.len() as f64;
    let sd = ((x4 / m - var_axis * var_axis) / m).sqrt();
    assert!((sxx / m - var_axis).abs() < 5.0 * sd, "var x {} vs {var_axis}", sxx / m);
    assert!((syy / m - var_axis).abs() < 5.0 * sd, "var y {} vs {var_axis}", syy / m);
    assert!((var_axis - 0.2374).abs() < 1e-3);
    // r^2 is a truncated exponential: P(r^2 < q) = (1 - e^(-q / 2 s^2)) / (1 - t).
    let cdf = |q: f64| (1.0 - (-q / (2.0 * s2)).exp()) / (1.0 - t);
    let e: Vec<f64> = (0..bins).map(|k| (cdf(r2max * (k + 1) as f64 / bins as f64) - cdf(r2max * k as f64 / bins as f64)) * m).collect();
    let chi = chi_square(&h, &e);
    assert!(chi < chi_bound(bins - 1), "radial chi2 {chi}");
}

#[test]
fn filter_pdfs_integrate_to_one_and_match_samples() {
    // Midpoint quadrature over [-2, 2]^2 in f64 of the f32 pdf.
    let k = 800;
    let hstep = 4.0 / k as f64;
    for f in Filter::ALL {
        let mut total = 0.0;
        for j in 0..k {
            for i in 0..k {
                let p = [(-2.0 + (i as f64 + 0.5) * hstep) as f32, (-2.0 + (j as f64 + 0.5) * hstep) as f32];
                total += sample_filter_pdf(f, p) as f64 * hstep * hstep;
            }
        }
        // The gaussian's disk edge is resolved to O(h) by the quadrature.
        assert!((total - 1.0).abs() < 2e-3, "{f:?}: {total}");
    }
    // Gaussian samples in the cell [0.2, 0.4)^2 vs the pdf integrated over it.
    let us = uniforms(24, 400_000);
    let inside =
        us.iter().map(|&u| sample_filter(Filter::Gaussian, u)).filter(|d| (0.2..0.4).contains(&d[0]) && (0.2..0.4).contains(&d[1])).count()
            as f64;
    let mut mass = 0.0;
    for j in 0..100 {
        for i in 0..100 {
            let p = [0.2 + 0.002 * (i as f32 + 0.5), 0.2 + 0.002 * (j as f32 + 0.5)];
            mass += sample_filter_pdf(Filter::Gaussian, p) as f64 * 4e-6;
        }
    }
    let e = mass * us.len() as f64;
    assert!((inside - e).abs() < 5.0 * e.sqrt(), "{inside} vs {e}");
}

// ---------------------------------------------------------------------------------------------------
// Concentric disk

#[test]
fn concentric_disk_is_uniform() {
    let us = uniforms(31, 400_000);
    let (rings, sectors) = (10usize, 16usize);
    let mut hr = vec![0u64; rings];
    let mut hs = vec![0u64; sectors];
    for &u in &us {
        let [x, y] = sample_disk_concentric(u);
        let r2 = x * x + y * y;
        assert!(r2 <= 1.0 + 1e-6, "{u:?} -> r^2 {r2}");
        // Ring k covers r in [k/10, (k+1)/10): area fraction (2k + 1) / 100.
        hr[((r2.sqrt() * rings as f32) as usize).min(rings - 1)] += 1;
        let a = (y.atan2(x) as f64 + std::f64::consts::PI) / std::f64::consts::TAU;
        hs[((a * sectors as f64) as usize).min(sectors - 1)] += 1;
    }
    let m = us.len() as f64;
    let er: Vec<f64> = (0..rings).map(|k| (2 * k + 1) as f64 / (rings * rings) as f64 * m).collect();
    let chi = chi_square(&hr, &er);
    assert!(chi < chi_bound(rings - 1), "rings chi2 {chi}");
    let chi = chi_square(&hs, &vec![m / sectors as f64; sectors]);
    assert!(chi < chi_bound(sectors - 1), "sectors chi2 {chi}");
    assert_eq!(sample_disk_concentric_pdf([0.3, 0.3]), std::f32::consts::FRAC_1_PI);
    assert_eq!(sample_disk_concentric_pdf([0.9, 0.9]), 0.0);
}

#[test]
fn concentric_disk_keeps_stratification() {
    // The map is measure-preserving, so jittered lens samples stay stratified on the disk: the
    // estimate of E[r^2] = 1/2 from 64 jittered points has an RMS error far below the independent
    // sqrt(1/12 / 64) = 0.036 (a smooth integrand: ~0.013 expected).
    let n = 64;
    let streams = 400;
    let mut se = 0.0f64;
    for stream in 0..streams {
        let mean: f64 = (0..n)
            .map(|i| {
                let u = sample_2d(Strategy::Jittered, SEED, stream, 1, i, n);
                let [x, y] = sample_disk_concentric(u);
                (x * x + y * y) as f64
            })
            .sum::<f64>()
            / n as f64;
        se += (mean - 0.5).powi(2);
    }
    let rms = (se / streams as f64).sqrt();
    let iid = (1.0 / 12.0 / n as f64).sqrt();
    assert!(rms < 0.5 * iid, "rms {rms} vs independent {iid}");
}
