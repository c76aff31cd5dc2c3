//! Beer-Lambert absorption inside a homogeneous medium.
//!
//! Transmittance over a path of length `d` through a medium with absorption coefficient `sigma_a`
//! (per unit scene length, per RGB channel) is `T = exp(-sigma_a d)`.

use glam::Vec3;

/// Per-channel transmittance `exp(-sigma_a * distance)`.
///
/// Safe at the edges: `sigma_a <= 0` (clear channel) gives 1 for any distance, including infinity
/// (where the naive product `0 * inf` is NaN); `distance = inf` with `sigma_a > 0` gives 0; a negative
/// distance is treated as 0. Negative `sigma_a` (unphysical gain) is treated as 0.
#[inline]
pub fn beer_lambert(sigma_a: Vec3, distance: f32) -> Vec3 {
    let d = distance.max(0.0);
    let ch = |s: f32| if s > 0.0 { (-s * d).exp() } else { 1.0 };
    Vec3::new(ch(sigma_a.x), ch(sigma_a.y), ch(sigma_a.z))
}

/// Absorption coefficient that makes white light take colour `color` after travelling `at_distance`:
/// `sigma_a = -ln(color) / at_distance`, so `beer_lambert(sigma_from_transmittance(c, d), d) == c`.
///
/// `color` is meant to lie in `(0, 1]`; channels are clamped to `[f32::MIN_POSITIVE, 1]` (a black
/// channel becomes a very large but finite coefficient). `at_distance <= 0` is clamped to `1e-30`;
/// the result is always finite and `>= 0` (exactly 0 for a channel equal to 1).
#[inline]
pub fn sigma_from_transmittance(color: Vec3, at_distance: f32) -> Vec3 {
    let inv_d = 1.0 / at_distance.max(1e-30);
    let ch = |c: f32| (0.0 - c.max(f32::MIN_POSITIVE).min(1.0).ln()) * inv_d;
    let s = Vec3::new(ch(color.x), ch(color.y), ch(color.z));
    // -ln(MIN_POSITIVE) / 1e-30 overflows to inf; keep it finite.
    s.min(Vec3::splat(f32::MAX))
}
