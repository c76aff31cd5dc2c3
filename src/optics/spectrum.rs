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

use super::dispersion::{LAMBDA_MAX, LAMBDA_MIN};

/// One lobe of the Wyman-Sloan-Shirley fit: a Gaussian with different widths left and right of `mu`.
#[inline(always)]
fn lobe(lambda: f32, mu: f32, sigma_left: f32, sigma_right: f32) -> f32 {
    let s = if lambda < mu { sigma_left } else { sigma_right };
    let t = (lambda - mu) / s;
    (-0.5 * t * t).exp()
}

/// CIE 1931 2° colour matching functions `(x̄, ȳ, z̄)` at `lambda` nm (multi-lobe fit of Wyman, Sloan
/// & Shirley 2013; parameters are those of the paper).
#[inline]
pub fn cie_xyz_fit(lambda: f32) -> Vec3 {
    let l = lambda;
    let x = 1.056 * lobe(l, 599.8, 37.9, 31.0) + 0.362 * lobe(l, 442.0, 16.0, 26.7) - 0.065 * lobe(l, 501.1, 20.4, 26.2);
    let y = 0.821 * lobe(l, 568.8, 46.9, 40.5) + 0.286 * lobe(l, 530.9, 16.3, 31.1);
    let z = 1.217 * lobe(l, 437.0, 11.8, 36.0) + 0.681 * lobe(l, 459.0, 26.0, 13.8);
    Vec3::new(x, y, z)
}

/// CIE XYZ -> linear sRGB (D65 white), IEC 61966-2-1 matrix. Out-of-gamut colours give negative
/// channels (not clamped here).
#[inline]
pub fn xyz_to_linear_srgb(xyz: Vec3) -> Vec3 {
    Vec3::new(
        3.240_454_2 * xyz.x - 1.537_138_5 * xyz.y - 0.498_531_4 * xyz.z,
        -0.969_266 * xyz.x + 1.876_010_8 * xyz.y + 0.041_556 * xyz.z,
        0.055_643_4 * xyz.x - 0.204_025_9 * xyz.y + 1.057_225_2 * xyz.z,
    )
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
