//! Pixel reconstruction filters by importance sampling: a film sample's offset from the pixel centre is
//! drawn from the normalised filter, so every sample carries weight 1 and the pixel value is a plain
//! average (no filter-weight division, no negative lobes). Only non-negative filters can be sampled this
//! way, which is why there is no Mitchell or Lanczos here.
//!
//! - box: uniform on the square `[-0.5, 0.5]^2`.
//! - tent: separable `(1 - |x|)(1 - |y|)` on `[-1, 1]^2`, each axis by its exact inverse CDF.
//! - gaussian: isotropic `exp(-r^2 / (2 sigma^2))` with `sigma = 0.5`, truncated to the *disk* of radius
//!   1.5 (= 3 sigma, 98.9% of the mass). Radial truncation keeps the filter rotationally symmetric and
//!   gives an exact closed-form inverse CDF in polar coordinates (the Box-Muller radius, rescaled to the
//!   truncated mass), so no `erfinv` approximation is needed.

use std::f32::consts::PI;
use wide::f32x8;

/// A pixel reconstruction filter.
#[derive(Clone, Copy, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Filter {
    /// Uniform over the pixel, radius 0.5.
    Box,
    /// Separable triangle, radius 1.
    Tent,
    /// Isotropic Gaussian, sigma 0.5, truncated to the disk of radius 1.5.
    Gaussian,
}

/// Standard deviation of [`Filter::Gaussian`], in pixels.
pub const GAUSSIAN_SIGMA: f32 = 0.5;
/// Truncation radius of [`Filter::Gaussian`], in pixels (3 sigma).
pub const GAUSSIAN_RADIUS: f32 = 1.5;
/// Mass of the untruncated 2D Gaussian inside the truncation disk: `1 - exp(-R^2 / (2 sigma^2))`
/// = `1 - exp(-4.5)`.
const GAUSSIAN_MASS: f32 = 0.988_891;

impl Filter {
    /// Every filter.
    pub const ALL: [Filter; 3] = [Filter::Box, Filter::Tent, Filter::Gaussian];

    /// The lowercase name (same as serde).
    pub fn name(self) -> &'static str {
        match self {
            Filter::Box => "box",
            Filter::Tent => "tent",
            Filter::Gaussian => "gaussian",
        }
    }

    /// Parse a name, ignoring ASCII case.
    pub fn parse(s: &str) -> Option<Filter> {
        Filter::ALL.into_iter().find(|f| f.name().eq_ignore_ascii_case(s))
    }

    /// Support radius in pixels: every offset satisfies `|dx|, |dy| <= radius`.
    pub fn radius(self) -> f32 {
        match self {
            Filter::Box => 0.5,
            Filter::Tent => 1.0,
            Filter::Gaussian => GAUSSIAN_RADIUS,
        }
    }
}

impl std::fmt::Display for Filter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Inverse CDF of the unit tent `1 - |x|` on `[-1, 1]`: maps `[0, 1)` onto `[-1, 1)`.
#[inline(always)]
fn sample_tent(u: f32) -> f32 {
    let t = 2.0 * u - 1.0;
    (1.0 - (1.0 - t.abs()).max(0.0).sqrt()).copysign(t)
}

/// Map `u` in `[0, 1)^2` to an offset `(dx, dy)` from the pixel centre, in pixels, distributed as the
/// normalised filter (so each sample has weight 1). A stratified `u` stays stratified: every map here is
/// a measure-preserving bijection (per axis for box and tent, polar for gaussian).
#[inline]
pub fn sample_filter(filter: Filter, u: [f32; 2]) -> [f32; 2] {
    match filter {
        Filter::Box => [u[0] - 0.5, u[1] - 0.5],
        Filter::Tent => [sample_tent(u[0]), sample_tent(u[1])],
        Filter::Gaussian => {
            // P(r < s) = (1 - exp(-s^2 / 2 sigma^2)) / MASS: invert for s, angle uniform.
            let r2 = -2.0 * GAUSSIAN_SIGMA * GAUSSIAN_SIGMA * (-u[0] * GAUSSIAN_MASS).ln_1p();
            let r = r2.max(0.0).sqrt().min(GAUSSIAN_RADIUS);
            let (s, c) = (2.0 * PI * u[1]).sin_cos();
            [r * c, r * s]
        }
    }
}

/// Eight lanes of [`sample_tent`].
#[inline(always)]
fn sample_tent_x8(u: f32x8) -> f32x8 {
    let t = u.mul_add(f32x8::splat(2.0), -f32x8::ONE);
    let m = f32x8::ONE - (f32x8::ONE - t.abs()).max(f32x8::ZERO).sqrt();
    t.simd_lt(f32x8::ZERO).select(-m, m)
}

/// Eight lanes of [`sample_filter`] (`u = [u0s, u1s]`, one filter for all lanes). Agrees with the
/// scalar twin to ~1e-6 (wide's `ln_1p` and `sin_cos` polynomials vs libm).
#[inline]
pub fn sample_filter_x8(filter: Filter, u: [f32x8; 2]) -> [f32x8; 2] {
    match filter {
        Filter::Box => [u[0] - f32x8::HALF, u[1] - f32x8::HALF],
        Filter::Tent => [sample_tent_x8(u[0]), sample_tent_x8(u[1])],
        Filter::Gaussian => {
            let k = f32x8::splat(-2.0 * GAUSSIAN_SIGMA * GAUSSIAN_SIGMA);
            let r2 = k * (-u[0] * f32x8::splat(GAUSSIAN_MASS)).ln_1p();
            let r = r2.max(f32x8::ZERO).sqrt().min(f32x8::splat(GAUSSIAN_RADIUS));
            let (s, c) = (f32x8::splat(2.0 * PI) * u[1]).sin_cos();
            [r * c, r * s]
        }
    }
}

/// Density (per pixel^2) of the offsets [`sample_filter`] produces; 0 outside the support.
#[inline]
pub fn sample_filter_pdf(filter: Filter, d: [f32; 2]) -> f32 {
    let [x, y] = [d[0].abs(), d[1].abs()];
    match filter {
        Filter::Box => {
            if x <= 0.5 && y <= 0.5 {
                1.0
            } else {
                0.0
            }
        }
        Filter::Tent => (1.0 - x).max(0.0) * (1.0 - y).max(0.0),
        Filter::Gaussian => {
            let r2 = x * x + y * y;
            if r2 <= GAUSSIAN_RADIUS * GAUSSIAN_RADIUS {
                let two_s2 = 2.0 * GAUSSIAN_SIGMA * GAUSSIAN_SIGMA;
                (-r2 / two_s2).exp() / (PI * two_s2 * GAUSSIAN_MASS)
            } else {
                0.0
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_core::{Rng, SeedableRng};
    use rand_xoshiro::Xoshiro256PlusPlus;

    #[test]
    fn x8_matches_scalar() {
        let hi = 1.0 - f32::EPSILON / 2.0;
        let mut us: Vec<[f32; 2]> =
            vec![[0.0, 0.0], [hi, hi], [0.5, 0.5], [0.0, hi], [hi, 0.0], [0.25, 0.75], [1e-7, 0.5], [0.5 + 1e-7, 0.5 - 1e-7]];
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(6);
        while us.len() < 4096 {
            us.push([(rng.next_u32() >> 8) as f32 / 16_777_216.0, (rng.next_u32() >> 8) as f32 / 16_777_216.0]);
        }
        for f in Filter::ALL {
            for chunk in us.chunks(8) {
                let lane = |k: usize| f32x8::from(std::array::from_fn::<f32, 8, _>(|i| chunk[i][k]));
                let [x, y] = sample_filter_x8(f, [lane(0), lane(1)]);
                let (x, y) = (x.to_array(), y.to_array());
                for i in 0..8 {
                    let d = sample_filter(f, chunk[i]);
                    assert!(
                        (x[i] - d[0]).abs() < 2e-6 && (y[i] - d[1]).abs() < 2e-6,
                        "{f:?} {:?}: x8 ({}, {}) scalar {d:?}",
                        chunk[i],
                        x[i],
                        y[i]
                    );
                    assert!(x[i].abs() <= f.radius() && y[i].abs() <= f.radius());
                }
            }
        }
    }

    #[test]
    fn gaussian_mass_constant() {
        let exact = 1.0 - (-4.5f64).exp();
        assert!((GAUSSIAN_MASS as f64 - exact).abs() < 1e-7);
        let s = GAUSSIAN_SIGMA as f64;
        let r = GAUSSIAN_RADIUS as f64;
        assert!((1.0 - (-r * r / (2.0 * s * s)).exp() - exact).abs() < 1e-12);
    }

    #[test]
    fn edge_inputs() {
        assert_eq!(sample_filter(Filter::Tent, [0.0, 0.5]), [-1.0, 0.0]);
        let hi = 1.0 - f32::EPSILON / 2.0;
        for f in Filter::ALL {
            for u in [[0.0, 0.0], [hi, hi], [0.5, 0.5], [0.0, hi]] {
                let d = sample_filter(f, u);
                assert!(d[0].is_finite() && d[1].is_finite(), "{f:?} {u:?}");
                assert!(d[0].abs() <= f.radius() && d[1].abs() <= f.radius(), "{f:?} {u:?} {d:?}");
            }
        }
        // u = 0 is the centre for the gaussian (r = 0).
        assert_eq!(sample_filter(Filter::Gaussian, [0.0, 0.3]), [0.0, 0.0]);
    }

    #[test]
    fn names_round_trip() {
        for f in Filter::ALL {
            assert_eq!(Filter::parse(f.name()), Some(f));
            assert_eq!(f.to_string(), f.name());
        }
        assert_eq!(Filter::parse("mitchell"), None);
    }
}
