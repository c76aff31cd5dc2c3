//! Scalar optics of the shading stage: Fresnel and Snell at dielectric interfaces, Beer-Lambert
//! absorption inside media, dispersion (wavelength-dependent index) with spectral-to-RGB weights, the
//! cosine-weighted Lambertian lobe, and a GGX microfacet reflection lobe for glossy surfaces.
//!
//! # Conventions (every function in this module)
//!
//! * Directions are unit `Vec3`s. `wo` (towards the viewer / previous vertex) and `wi` (towards the
//!   next vertex / the light) both point **away** from the surface point.
//! * `n` is the unit shading normal on the side of the incident ray: `dot(wo, n) >= 0`. The caller
//!   flips the geometric normal when a ray hits a surface from behind (i.e. when leaving a medium).
//! * `eta = n_incident / n_transmitted` (the index on `wo`'s side over the index on the far side).
//!   Entering glass from air: `eta = 1 / 1.5`; leaving it: `eta = 1.5`.
//! * `cos_i` arguments are `dot(wo, n)` and are clamped to `[0, 1]`.
//! * Angles are in radians, wavelengths in nanometres (`Ior::Cauchy::b_um2` is in µm²).
//! * Functions returning a direction that may not exist return `Option` (`None` = total internal
//!   reflection, or a sampled direction below the surface). No function panics or returns NaN/Inf on
//!   finite inputs, and none allocates.
//! * Sampling functions take uniform numbers `u` in `[0, 1)` and have a `_pdf` twin returning the
//!   density over the same measure (solid angle for directions, nm⁻¹ for wavelengths).
//!
//! # Files
//!
//! * `fresnel.rs`: exact unpolarised dielectric Fresnel (f32 and f64), Schlick, critical angle.
//! * `refract.rs`: mirror reflection and Snell refraction.
//! * `absorption.rs`: Beer-Lambert transmittance and its inverse (colour at a distance -> sigma_a).
//! * `dispersion.rs`: `Ior` (constant / Cauchy / Abbe number) and the wavelength sampler.
//! * `spectrum.rs`: CIE 1931 fit -> linear sRGB weights of a single wavelength sample.
//! * `lambert.rs`: orthonormal basis and cosine-weighted hemisphere sampling.
//! * `microfacet.rs`: GGX distribution, Smith height-correlated masking, visible-normal sampling.

// `!(x > 0.0)` is used on purpose: it also rejects NaN (a degenerate direction yields 0 / None, not a
// NaN that would poison a pixel); and `x.max(a).min(b)` maps NaN to `a` where `clamp` keeps it.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::manual_clamp)]

mod absorption;
mod dispersion;
mod fresnel;
mod lambert;
mod microfacet;
mod refract;
mod spectrum;

pub use absorption::{beer_lambert, sigma_from_transmittance};
pub use dispersion::{
    sample_wavelength, sample_wavelength_pdf, sample_wavelength_pdf_x8, sample_wavelength_x8, Ior, LAMBDA_C, LAMBDA_D, LAMBDA_F,
    LAMBDA_MAX, LAMBDA_MIN,
};
pub use fresnel::{cos_t_sq, critical_angle, fresnel_dielectric, fresnel_dielectric_f64, fresnel_schlick};
pub use lambert::{onb, onb_x8, sample_hemisphere_cos, sample_hemisphere_cos_pdf, sample_hemisphere_cos_x8, to_local, to_world};
pub use microfacet::{
    eval_ggx_reflect, eval_ggx_reflect_x8, ggx_d, ggx_g1, ggx_g2, sample_ggx_reflect, sample_ggx_reflect_pdf, sample_ggx_reflect_pdf_x8,
    sample_ggx_reflect_weight, sample_ggx_reflect_weight_x8, sample_ggx_reflect_x8, GGX_ALPHA_MIN,
};
pub use refract::{fresnel_dielectric_x8, fresnel_refract_x8, reflect, reflect_x8, refract};
pub use spectrum::{cie_xyz_fit, wavelength_to_rgb, wavelength_to_rgb_x8, xyz_to_linear_srgb};
