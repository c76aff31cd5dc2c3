//! Orthonormal bases and the cosine-weighted (Lambertian) hemisphere.

use glam::Vec3;
use std::f32::consts::{FRAC_1_PI, TAU};

/// Tangent and bitangent `(t, b)` completing the unit `n` to a right-handed orthonormal basis
/// (`t × b = n`), branch-free and continuous except across `n.z = 0`'s sign flip.
///
/// Duff, Burgess, Christensen, Hery, Kensler, Liani & Villemin 2017, "Building an Orthonormal Basis,
/// Revisited" (JCGT 6(1)): fixes the precision loss of Frisvad's basis near `n = (0, 0, -1)` by
/// choosing the sign of `n.z` (with `copysign`, so `-0.0` is handled too).
#[inline]
pub fn onb(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x), Vec3::new(b, sign + n.y * n.y * a, -n.y))
}

/// Coordinates of `v` in the basis `(t, b, n)`.
#[inline]
pub fn to_local(v: Vec3, t: Vec3, b: Vec3, n: Vec3) -> Vec3 {
    Vec3::new(v.dot(t), v.dot(b), v.dot(n))
}

/// World vector of local coordinates `l` in the basis `(t, b, n)`.
#[inline]
pub fn to_world(l: Vec3, t: Vec3, b: Vec3, n: Vec3) -> Vec3 {
    t * l.x + b * l.y + n * l.z
}

/// Cosine-weighted direction in the hemisphere around the unit `n` (density `cos / pi` over solid
/// angle, [`sample_hemisphere_cos_pdf`]), from `u` in `[0, 1)^2`.
///
/// Malley's method: a uniform point on the unit disk (polar map `r = sqrt(u0)`, `phi = 2 pi u1`)
/// lifted to the hemisphere. The polar map suffices here; directions are not stratified across
/// dimensions by the caller.
#[inline]
pub fn sample_hemisphere_cos(n: Vec3, u: [f32; 2]) -> Vec3 {
    let r = u[0].max(0.0).min(1.0).sqrt();
    let (s, c) = (TAU * u[1]).sin_cos();
    let z = (1.0 - u[0]).max(0.0).sqrt();
    let (t, b) = onb(n);
    to_world(Vec3::new(r * c, r * s, z), t, b, n)
}

/// Density over solid angle of [`sample_hemisphere_cos`]: `max(0, dot(n, wi)) / pi`.
#[inline]
pub fn sample_hemisphere_cos_pdf(n: Vec3, wi: Vec3) -> f32 {
    n.dot(wi).max(0.0) * FRAC_1_PI
}
