//! Error metrics of an image against a reference, and the convergence slope of a series.
//!
//! All sums are in f64 over every pixel and every channel (the reference is f64 so that an analytic
//! reference loses nothing).

use glam::{DVec3, Vec3};

/// The `0.01` in relMSE: keeps the metric finite on black reference pixels (pbrt, Mitsuba and the
/// denoising literature use the same constant).
pub const RELMSE_EPSILON: f64 = 0.01;

/// Mean squared error over pixels and channels: `mean((x - ref)^2)`.
pub fn mse(image: &[Vec3], reference: &[DVec3]) -> f64 {
    assert_eq!(image.len(), reference.len(), "image and reference sizes differ");
    let sum: f64 = image.iter().zip(reference).map(|(x, r)| (x.as_dvec3() - *r).length_squared()).sum();
    sum / (3 * image.len().max(1)) as f64
}

/// Relative MSE per channel: `mean((x - ref)^2 / (ref^2 + 0.01))`.
pub fn relmse(image: &[Vec3], reference: &[DVec3]) -> f64 {
    assert_eq!(image.len(), reference.len(), "image and reference sizes differ");
    let sum: f64 = image
        .iter()
        .zip(reference)
        .map(|(x, r)| {
            let d = x.as_dvec3() - *r;
            let w = *r * *r + DVec3::splat(RELMSE_EPSILON);
            (d * d / w).element_sum()
        })
        .sum();
    sum / (3 * image.len().max(1)) as f64
}

/// The image's mean against the reference's: their ratio (means over pixels and channels; NaN for a
/// black reference) and a z-score of their difference, `(mean(x) - mean(ref)) / se`, with `se` the
/// standard error of that difference estimated from the spread of the pixels' errors (each pixel's error
/// averaged over its channels, which share paths). A render's pixels are independent streams, so with no
/// bias in the render or the reference `z` is about standard normal; a bias the size of the noise of a
/// few pixels gives a large `z` over a whole image, where the MSE hardly moves (or drops: a black
/// image of a dim, noisy region). `se` is at least [`FLOAT_RESOLUTION`] of the reference's mean (f32
/// renders). `z` is 0 for identical images, `offset / (FLOAT_RESOLUTION x mean)` for a uniform offset
/// without noise (infinite against a black reference), NaN for differing images of one pixel (nothing
/// to estimate the noise from).
pub fn mean_check(image: &[Vec3], reference: &[DVec3]) -> (f64, f64) {
    mean_check_f64(&image.iter().map(|x| x.as_dvec3()).collect::<Vec<_>>(), reference)
}

/// The smallest relative difference of means [`mean_check`] can call a bias: two f32 roundings
/// (`2 x 2^-23`, 2.4e-7) of the reference's mean, the standard error's floor.
pub const FLOAT_RESOLUTION: f64 = 2.0 * f32::EPSILON as f64;

/// [`mean_check`] of an image in f64 (the study's mean of a row's seeds: its pixels' errors hold the
/// runs' noise over the seeds and the reference's once, so that its `z` stays standard normal however
/// many seeds share the reference).
pub fn mean_check_f64(image: &[DVec3], reference: &[DVec3]) -> (f64, f64) {
    assert_eq!(image.len(), reference.len(), "image and reference sizes differ");
    let n = image.len() as f64;
    let (mut sx, mut sr) = (0.0f64, 0.0f64);
    for (x, r) in image.iter().zip(reference) {
        sx += x.element_sum();
        sr += r.element_sum();
    }
    let ratio = if sr > 0.0 { sx / sr } else { f64::NAN };
    // Per-pixel errors (channel means): their mean and, in a second pass, their spread.
    let e = |(x, r): (&DVec3, &DVec3)| (*x - *r).element_sum() / 3.0;
    let mean = image.iter().zip(reference).map(e).sum::<f64>() / n;
    if image.len() < 2 {
        // One pixel has no spread to tell its noise from a bias by (0 read as "no bias": a user trial).
        return (ratio, if mean == 0.0 { 0.0 } else { f64::NAN });
    }
    let var = image.iter().zip(reference).map(|p| (e(p) - mean).powi(2)).sum::<f64>() / (n - 1.0);
    // The renderer computes in f32: a difference within a few f32 roundings of the reference's mean is
    // no bias one can tell, however small the noise (a user trial: sobol at 1,024 spp against the
    // analytic reference, mean/ref 0.99999997, read as z = -7.3 with the pixels' errors near the f32
    // floor). So the standard error is at least `FLOAT_RESOLUTION` of the reference's mean.
    let floor = FLOAT_RESOLUTION * (sr / (3.0 * n)).abs();
    let se = (var / n + floor * floor).sqrt();
    let z = if mean == 0.0 { 0.0 } else { mean / se };
    (ratio, z)
}

/// Efficiency `1 / (MSE x seconds)`: the inverse of the work needed for a given error (higher is better).
/// Infinite for a zero error.
pub fn efficiency(mse: f64, seconds: f64) -> f64 {
    1.0 / (mse * seconds)
}

/// A straight line `ln y = slope ln x + intercept`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LogLogFit {
    pub slope: f64,
    pub intercept: f64,
}

/// Least-squares fit of `ln y` against `ln x`. Points with a non-positive or non-finite coordinate are
/// skipped (a zero error has no logarithm); None if fewer than two distinct `x` remain.
pub fn fit_loglog(points: &[(f64, f64)]) -> Option<LogLogFit> {
    let pts: Vec<(f64, f64)> =
        points.iter().filter(|(x, y)| x.is_finite() && y.is_finite() && *x > 0.0 && *y > 0.0).map(|(x, y)| (x.ln(), y.ln())).collect();
    let n = pts.len() as f64;
    if pts.len() < 2 {
        return None;
    }
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    if sxx <= 0.0 {
        return None;
    }
    let slope = sxy / sxx;
    Some(LogLogFit { slope, intercept: my - slope * mx })
}
