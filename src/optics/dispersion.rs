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

/// Density (per nm) of [`sample_wavelength`]; 0 outside `[LAMBDA_MIN, LAMBDA_MAX]`.
#[inline]
pub fn sample_wavelength_pdf(lambda: f32) -> f32 {
    if !(LAMBDA_MIN..=LAMBDA_MAX).contains(&lambda) {
        return 0.0;
    }
    let ch = (SAMPLE_K * (lambda - SAMPLE_CENTER)).cosh();
    SAMPLE_K / ((TANH_MAX - TANH_MIN) * ch * ch)
}
