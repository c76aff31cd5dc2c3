//! Wavelength-dependent index of refraction and the wavelength sampler of spectral (dispersive) paths.
//!
//! Dispersion model: Cauchy's equation `n(lambda) = A + B / lambda^2` (lambda in µm), which is
//! accurate to ~1e-3 across the visible range for optical glasses. Glass catalogues quote instead the
//! index at the helium d line and the Abbe number `Vd = (nd - 1) / (nF - nC)` (Fraunhofer F and C
//! hydrogen lines); [`Ior::Abbe`] converts that pair to the unique Cauchy pair that reproduces both:
//!
//! ```text
//! B = (nd - 1) / (Vd (1/lF^2 - 1/lC^2)),      A = nd - B / ld^2
//! ```
//!
//! Wavelength sampling: a truncated `sech^2` density centred on 538 nm, the shape proposed by
//! Radziszewski, Boryczko & Alda 2009 ("An improved technique for full spectral rendering", JWSCG) as
//! a close fit to the sum of the CIE colour matching functions, renormalised to
//! `[LAMBDA_MIN, LAMBDA_MAX]`. It is inverted in closed form through `tanh`/`atanh`, and keeps the
//! estimator `wavelength_to_rgb(l) / pdf(l)` much flatter than a uniform density would.

use crate::simd::f32x8;

/// Shortest sampled wavelength (nm).
pub const LAMBDA_MIN: f32 = 380.0;
/// Longest sampled wavelength (nm).
pub const LAMBDA_MAX: f32 = 720.0;
/// Helium d line (nm): where catalogues quote `nd`; [`Ior::nominal`] evaluates here.
pub const LAMBDA_D: f32 = 587.5618;
/// Hydrogen F line (nm).
pub const LAMBDA_F: f32 = 486.1327;
/// Hydrogen C line (nm).
pub const LAMBDA_C: f32 = 656.2725;

/// Index of refraction of a dielectric as a function of wavelength.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Ior {
    /// Non-dispersive index.
    Constant(f32),
    /// Cauchy's equation `a + b_um2 / lambda_um^2`.
    Cauchy { a: f32, b_um2: f32 },
    /// Catalogue pair: index `nd` at the d line and Abbe number `vd`. `vd <= 0`, infinite or NaN means
    /// no dispersion (treated as `Constant(nd)`).
    Abbe { nd: f32, vd: f32 },
}

impl Ior {
    /// The Cauchy pair `(A, B)` (B in µm²) equivalent to this index; `B = 0` when non-dispersive.
    #[inline]
    pub fn cauchy(&self) -> (f32, f32) {
        let (a, b) = self.cauchy_f64();
        (a as f32, b as f32)
    }

    /// f64 twin of [`Ior::cauchy`]: the Abbe conversion differences two close numbers, so tests that
    /// recover `Vd` from `nF - nC` need it.
    #[inline]
    pub fn cauchy_f64(&self) -> (f64, f64) {
        match *self {
            Ior::Constant(n) => (n as f64, 0.0),
            Ior::Cauchy { a, b_um2 } => (a as f64, b_um2 as f64),
            Ior::Abbe { nd, vd } => {
                let (nd, vd) = (nd as f64, vd as f64);
                if !(vd > 0.0 && vd.is_finite()) {
                    return (nd, 0.0);
                }
                let inv2 = |l_nm: f32| {
                    let l = l_nm as f64 * 1e-3;
                    1.0 / (l * l)
                };
                let b = (nd - 1.0) / (vd * (inv2(LAMBDA_F) - inv2(LAMBDA_C)));
                (nd - b * inv2(LAMBDA_D), b)
            }
        }
    }

    /// Index at `lambda_nm` (clamped to at least 1 nm so the result stays finite).
    #[inline]
    pub fn at(&self, lambda_nm: f32) -> f32 {
        match *self {
            Ior::Constant(n) => n,
            Ior::Cauchy { a, b_um2 } => {
                let l = lambda_nm.max(1.0) * 1e-3;
                a + b_um2 / (l * l)
            }
            Ior::Abbe { .. } => {
                let (a, b) = self.cauchy();
                let l = lambda_nm.max(1.0) * 1e-3;
                a + b / (l * l)
            }
        }
    }

    /// f64 twin of [`Ior::at`].
    #[inline]
    pub fn at_f64(&self, lambda_nm: f64) -> f64 {
        let (a, b) = self.cauchy_f64();
        let l = lambda_nm.max(1.0) * 1e-3;
        a + b / (l * l)
    }

    /// Whether the index varies with wavelength (the renderer then needs a per-path wavelength).
    #[inline]
    pub fn is_dispersive(&self) -> bool {
        self.cauchy_f64().1 != 0.0
    }

    /// Index at the d line (587.56 nm), the value to use for non-spectral paths.
    #[inline]
    pub fn nominal(&self) -> f32 {
        match *self {
            Ior::Constant(n) => n,
            Ior::Abbe { nd, .. } => nd,
            // Out of line: inlined, the compiler computes its division for every index and selects
            // (a stall in the shadow stage's walk through glass, which asks for indices per crossing).
            Ior::Cauchy { .. } => self.cauchy_nominal(),
        }
    }

    #[cold]
    #[inline(never)]
    fn cauchy_nominal(&self) -> f32 {
        self.at(LAMBDA_D)
    }
}

/// Centre (nm) and inverse width (1/nm) of the `sech^2` sampling density.
const SAMPLE_CENTER: f32 = 538.0;
const SAMPLE_K: f32 = 0.0072;
/// `tanh(SAMPLE_K (LAMBDA_MIN - SAMPLE_CENTER))` and the same at `LAMBDA_MAX` (checked by a test:
/// `tanh` is not a `const fn`).
const TANH_MIN: f32 = -0.813_604_4;
const TANH_MAX: f32 = 0.864_376_6;

/// Wavelength (nm) in `[LAMBDA_MIN, LAMBDA_MAX]` from a uniform `u` in `[0, 1)`, distributed with
/// density [`sample_wavelength_pdf`] (a truncated `sech^2` around 538 nm, see the module doc).
#[inline]
pub fn sample_wavelength(u: f32) -> f32 {
    let t = (TANH_MAX - TANH_MIN).mul_add(u, TANH_MIN);
    (SAMPLE_CENTER + t.atanh() / SAMPLE_K).clamp(LAMBDA_MIN, LAMBDA_MAX)
}

/// Eight lanes of [`sample_wavelength`] (the camera rays of dispersive scenes are made 8 at a time):
/// the same map, `atanh t` as `ln((1 + t) / (1 - t)) / 2` with `wide`'s vector logarithm instead of
/// libm's scalar `atanhf` (within 2e-4 nm of the exact map, tested against it in f64).
#[inline]
pub fn sample_wavelength_x8(u: f32x8) -> f32x8 {
    let t = f32x8::splat(TANH_MAX - TANH_MIN).mul_add(u, f32x8::splat(TANH_MIN));
    let a = ((f32x8::ONE + t) / (f32x8::ONE - t)).ln() * f32x8::splat(0.5 / SAMPLE_K);
    (f32x8::splat(SAMPLE_CENTER) + a).fast_max(f32x8::splat(LAMBDA_MIN)).fast_min(f32x8::splat(LAMBDA_MAX))
}

/// Eight lanes of [`sample_wavelength_pdf`] (`wide`'s vector `cosh`; within 2e-6 of the exact density,
/// relatively); 0 outside `[LAMBDA_MIN, LAMBDA_MAX]`.
#[inline]
pub fn sample_wavelength_pdf_x8(lambda: f32x8) -> f32x8 {
    let inside = lambda.simd_ge(f32x8::splat(LAMBDA_MIN)) & lambda.simd_le(f32x8::splat(LAMBDA_MAX));
    let ch = (f32x8::splat(SAMPLE_K) * (lambda - f32x8::splat(SAMPLE_CENTER))).cosh();
    inside.select(f32x8::splat(SAMPLE_K) / (f32x8::splat(TANH_MAX - TANH_MIN) * ch * ch), f32x8::ZERO)
}

/// Density (per nm) of [`sample_wavelength`]; 0 outside `[LAMBDA_MIN, LAMBDA_MAX]`.
#[inline]
pub fn sample_wavelength_pdf(lambda: f32) -> f32 {
    if !(LAMBDA_MIN..=LAMBDA_MAX).contains(&lambda) {
        return 0.0;
    }
    let ch = (SAMPLE_K * (lambda - SAMPLE_CENTER)).cosh();
    SAMPLE_K / ((TANH_MAX - TANH_MIN) * ch * ch)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 8-lane sampler and density against the exact map and density in f64, over a fine grid of
    /// `u` with both ends (the scalar pair is checked against each other in `tests/physics.rs`).
    #[test]
    fn wavelength_sampler_x8_follows_the_exact_map() {
        let (t0, t1, k, c) = (TANH_MIN as f64, TANH_MAX as f64, SAMPLE_K as f64, SAMPLE_CENTER as f64);
        let exact = |u: f64| (c + (t0 + (t1 - t0) * u).atanh() / k).clamp(LAMBDA_MIN as f64, LAMBDA_MAX as f64);
        let density = |l: f64| k / ((t1 - t0) * (k * (l - c)).cosh().powi(2));
        let n = 1 << 16;
        let (mut worst_l, mut worst_p) = (0.0f64, 0.0f64);
        for block in 0..=n / 8 {
            let u: [f32; 8] = std::array::from_fn(|l| ((block * 8 + l) as f32 / n as f32).min(1.0 - f32::EPSILON / 2.0));
            let (w, p) = (
                sample_wavelength_x8(f32x8::from(u)).to_array(),
                sample_wavelength_pdf_x8(sample_wavelength_x8(f32x8::from(u))).to_array(),
            );
            for l in 0..8 {
                worst_l = worst_l.max((w[l] as f64 - exact(u[l] as f64)).abs());
                worst_p = worst_p.max((p[l] as f64 / density(w[l] as f64) - 1.0).abs());
            }
        }
        assert!(worst_l < 2e-4 && worst_p < 2e-6, "wavelength off by {worst_l} nm, density by {worst_p} (relative)");
        // Outside the range the density is 0, as the scalar's.
        let out = sample_wavelength_pdf_x8(f32x8::from([379.9, 720.1, -1.0, 1e9, 380.0, 720.0, 500.0, f32::INFINITY])).to_array();
        assert_eq!(out.map(|p| p > 0.0), [false, false, false, false, true, true, true, false]);
    }
}
