//! Linear-sRGB weight of a single-wavelength sample, for spectral (dispersive) paths.
//!
//! Pipeline: CIE 1931 2° colour matching functions from the analytic multi-lobe piecewise-Gaussian
//! fit of Wyman, Sloan & Shirley 2013 ("Simple Analytic Approximations to the CIE XYZ Color Matching
//! Functions", JCGT 2(2)), within ~0.015 of the tabulated CMFs, then the IEC 61966-2-1 XYZ -> linear
//! sRGB (D65) matrix, then:
//!
//! * **negative lobes clamped to 0.** Monochromatic light lies outside the sRGB gamut, so the exact
//!   weights have negative channels; a renderer that averages them is unbiased in colour but produces
//!   negative radiance in low-sample pixels and breaks luminance-based heuristics (Russian roulette,
//!   firefly clamps). Clamping desaturates pure spectral colours slightly, nothing else.
//! * **per-channel normalisation** so that `∫ w(l) dl = (1, 1, 1)` over `[LAMBDA_MIN, LAMBDA_MAX]`.
//!   Hence for any sampling density `p`, `E[w(l) / p(l)] = (1, 1, 1)`: a flat (equal-energy) spectrum
//!   renders exactly white and a non-dispersive path gives the same result as an RGB path. This is an
//!   RGB-space white balance from illuminant E to the sRGB white.

use glam::Vec3;

use crate::simd::f32x8;

use super::dispersion::{LAMBDA_MAX, LAMBDA_MIN};

/// One lobe of the Wyman-Sloan-Shirley fit: a Gaussian with different widths left and right of `mu`.
#[inline(always)]
fn lobe(lambda: f32, mu: f32, sigma_left: f32, sigma_right: f32) -> f32 {
    let s = if lambda < mu { sigma_left } else { sigma_right };
    let t = (lambda - mu) / s;
    (-0.5 * t * t).exp()
}

/// The fit's lobes of `x̄`, `ȳ` and `z̄`: `[weight, mu, sigma_left, sigma_right]` (Wyman, Sloan & Shirley
/// 2013; parameters are those of the paper). One table for the scalar fit, its 8-lane twin and the
/// tests' f64 reference.
const FIT_X: [[f32; 4]; 3] = [[1.056, 599.8, 37.9, 31.0], [0.362, 442.0, 16.0, 26.7], [-0.065, 501.1, 20.4, 26.2]];
const FIT_Y: [[f32; 4]; 2] = [[0.821, 568.8, 46.9, 40.5], [0.286, 530.9, 16.3, 31.1]];
const FIT_Z: [[f32; 4]; 2] = [[1.217, 437.0, 11.8, 36.0], [0.681, 459.0, 26.0, 13.8]];

/// CIE XYZ -> linear sRGB (D65 white), IEC 61966-2-1 matrix, by rows.
const XYZ_TO_SRGB: [[f32; 3]; 3] =
    [[3.240_454_2, -1.537_138_5, -0.498_531_4], [-0.969_266, 1.876_010_8, 0.041_556], [0.055_643_4, -0.204_025_9, 1.057_225_2]];

/// CIE 1931 2° colour matching functions `(x̄, ȳ, z̄)` at `lambda` nm (multi-lobe fit of Wyman, Sloan
/// & Shirley 2013: [`FIT_X`], [`FIT_Y`], [`FIT_Z`]).
#[inline]
pub fn cie_xyz_fit(lambda: f32) -> Vec3 {
    let sum = |fit: &[[f32; 4]]| fit.iter().fold(0.0, |a, &[w, mu, sl, sr]| a + w * lobe(lambda, mu, sl, sr));
    Vec3::new(sum(&FIT_X), sum(&FIT_Y), sum(&FIT_Z))
}

/// CIE XYZ -> linear sRGB (D65 white), IEC 61966-2-1 matrix. Out-of-gamut colours give negative
/// channels (not clamped here).
#[inline]
pub fn xyz_to_linear_srgb(xyz: Vec3) -> Vec3 {
    let row = |m: [f32; 3]| m[0] * xyz.x + m[1] * xyz.y + m[2] * xyz.z;
    Vec3::new(row(XYZ_TO_SRGB[0]), row(XYZ_TO_SRGB[1]), row(XYZ_TO_SRGB[2]))
}

/// `1 / ∫ max(0, M xyz(l)) dl` over `[LAMBDA_MIN, LAMBDA_MAX]` per channel (f64 midpoint quadrature,
/// 340 000 steps; a test recomputes it).
const RGB_NORM: Vec3 = Vec3::new(0.005_676_191, 0.008_667_388, 0.009_147_586);

/// Linear-sRGB weight of one wavelength sample (nm): the Monte Carlo average of
/// `wavelength_to_rgb(l) / sample_wavelength_pdf(l)` over `l ~ sample_wavelength` is exactly
/// `(1, 1, 1)` for a flat spectrum. Negative lobes clamped; 0 outside `[LAMBDA_MIN, LAMBDA_MAX]`.
/// See the module doc.
#[inline]
pub fn wavelength_to_rgb(lambda: f32) -> Vec3 {
    if !(LAMBDA_MIN..=LAMBDA_MAX).contains(&lambda) {
        return Vec3::ZERO;
    }
    xyz_to_linear_srgb(cie_xyz_fit(lambda)).max(Vec3::ZERO) * RGB_NORM
}

/// One lobe of [`cie_xyz_fit`] in 8 lanes (`wide`'s vector `exp`; the widths' reciprocals multiply).
#[inline(always)]
fn lobe_x8(lambda: f32x8, mu: f32, sigma_left: f32, sigma_right: f32) -> f32x8 {
    let left = lambda.simd_lt(f32x8::splat(mu));
    let t = (lambda - f32x8::splat(mu)) * left.select(f32x8::splat(1.0 / sigma_left), f32x8::splat(1.0 / sigma_right));
    (f32x8::splat(-0.5) * t * t).exp()
}

/// Eight lanes of [`wavelength_to_rgb`] (the camera rays of dispersive scenes are made 8 at a time),
/// as rows `[r, g, b]`: the same fit, matrix, clamp and normalisation with vector `exp` (within 2e-6 of
/// the peak weight of the exact function, tested against it in f64); 0 outside `[LAMBDA_MIN, LAMBDA_MAX]`.
#[inline]
pub fn wavelength_to_rgb_x8(lambda: f32x8) -> [f32x8; 3] {
    let s = f32x8::splat;
    let sum = |fit: &[[f32; 4]]| fit.iter().fold(f32x8::ZERO, |a, &[w, mu, sl, sr]| a + s(w) * lobe_x8(lambda, mu, sl, sr));
    let (x, y, z) = (sum(&FIT_X), sum(&FIT_Y), sum(&FIT_Z));
    let inside = lambda.simd_ge(s(LAMBDA_MIN)) & lambda.simd_le(s(LAMBDA_MAX));
    let row =
        |m: [f32; 3], norm: f32| inside.select((s(m[0]) * x + s(m[1]) * y + s(m[2]) * z).fast_max(f32x8::ZERO) * s(norm), f32x8::ZERO);
    [row(XYZ_TO_SRGB[0], RGB_NORM.x), row(XYZ_TO_SRGB[1], RGB_NORM.y), row(XYZ_TO_SRGB[2], RGB_NORM.z)]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Wyman-Sloan-Shirley fit, matrix, clamp and normalisation in f64 (the same parameters).
    fn rgb_f64(l: f64) -> [f64; 3] {
        let sum = |fit: &[[f32; 4]]| {
            fit.iter()
                .map(|p| {
                    let [w, mu, sl, sr] = p.map(|v| v as f64);
                    let t = (l - mu) / if l < mu { sl } else { sr };
                    w * (-0.5 * t * t).exp()
                })
                .sum::<f64>()
        };
        let xyz = [sum(&FIT_X), sum(&FIT_Y), sum(&FIT_Z)];
        let norm = [RGB_NORM.x as f64, RGB_NORM.y as f64, RGB_NORM.z as f64];
        std::array::from_fn(|c| (0..3).map(|k| XYZ_TO_SRGB[c][k] as f64 * xyz[k]).sum::<f64>().max(0.0) * norm[c])
    }

    /// [`wavelength_to_rgb_x8`] against the f64 fit every 1/64 nm over the range and past its ends
    /// (0 outside), and the scalar [`wavelength_to_rgb`] against the same, within 2e-6 of the peak.
    #[test]
    fn wavelength_to_rgb_x8_follows_the_fit() {
        let peak = (0..3400).map(|i| rgb_f64(380.0 + i as f64 * 0.1).into_iter().fold(0.0, f64::max)).fold(0.0, f64::max);
        let (mut worst_x8, mut worst_scalar) = (0.0f64, 0.0f64);
        for block in 0..(360 * 64 / 8) {
            let l: [f32; 8] = std::array::from_fn(|k| 370.0 + (block * 8 + k) as f32 / 64.0);
            let v = wavelength_to_rgb_x8(f32x8::from(l)).map(|c| c.to_array());
            for (k, &lk) in l.iter().enumerate() {
                let r = if (LAMBDA_MIN..=LAMBDA_MAX).contains(&lk) { rgb_f64(lk as f64) } else { [0.0; 3] };
                let s = wavelength_to_rgb(lk);
                for c in 0..3 {
                    worst_x8 = worst_x8.max((v[c][k] as f64 - r[c]).abs());
                    worst_scalar = worst_scalar.max((s[c] as f64 - r[c]).abs());
                    if r[c] == 0.0 {
                        assert_eq!(v[c][k], 0.0, "{lk} nm, channel {c}");
                    }
                }
            }
        }
        assert!(worst_x8 < 2e-6 * peak && worst_scalar < 2e-6 * peak, "off by {worst_x8} (x8), {worst_scalar} (scalar); peak {peak}");
    }
}
