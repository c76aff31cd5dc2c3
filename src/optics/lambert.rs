//! Orthonormal bases and the cosine-weighted (Lambertian) hemisphere.

use crate::sample::sample_disk_concentric_x8;
use crate::sample::warp::concentric_polar;
use crate::simd::{f32x8, u32x8, Vec3x8};
use glam::Vec3;
use std::f32::consts::FRAC_1_PI;

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
/// Malley's method: a uniform point on the unit disk (the concentric map, `sample_disk_concentric`,
/// which keeps the stratification of jittered `u` and sends the square's centre, the `center`
/// strategy, to the normal) lifted to the hemisphere.
#[inline]
pub fn sample_hemisphere_cos(n: Vec3, u: [f32; 2]) -> Vec3 {
    // (The height from the map's radius r, exact, rather than from x and y, whose sine and cosine
    // round: near the rim that would amplify it. The 8-lane twin takes r^2 as max(a^2, b^2).)
    let (r, phi) = concentric_polar(u);
    let (s, c) = phi.sin_cos();
    let z = (1.0 - r * r).max(0.0).sqrt();
    let (t, b) = onb(n);
    to_world(Vec3::new(r * c, r * s, z), t, b, n)
}

/// Density over solid angle of [`sample_hemisphere_cos`]: `max(0, dot(n, wi)) / pi`.
#[inline]
pub fn sample_hemisphere_cos_pdf(n: Vec3, wi: Vec3) -> f32 {
    n.dot(wi).max(0.0) * FRAC_1_PI
}

/// Eight lanes of [`sample_hemisphere_cos`] (normals `n`, points `u = [u0s, u1s]`): the same map and
/// basis; agrees with the scalar to ~1e-6 (wide's `sin_cos` polynomial vs libm).
#[inline]
pub fn sample_hemisphere_cos_x8(n: Vec3x8, u: [f32x8; 2]) -> Vec3x8 {
    let [x, y] = sample_disk_concentric_x8(u);
    let two = f32x8::splat(2.0);
    let (a, b) = (two * u[0] - f32x8::ONE, two * u[1] - f32x8::ONE);
    let z = (f32x8::ONE - (a * a).max(b * b)).max(f32x8::ZERO).sqrt();
    let (t, bt) = onb_x8(n);
    t.scale(x) + bt.scale(y) + n.scale(z)
}

/// [`onb`] lane by lane, the same operations (sign = copysign(1, n.z)).
#[inline(always)]
pub fn onb_x8(n: Vec3x8) -> (Vec3x8, Vec3x8) {
    let one = f32x8::ONE;
    let sign = bytemuck::cast::<u32x8, f32x8>(
        (bytemuck::cast::<f32x8, u32x8>(n.z) & u32x8::splat(0x8000_0000)) | bytemuck::cast::<f32x8, u32x8>(one),
    );
    let a = -one / (sign + n.z);
    let b = n.x * n.y * a;
    (Vec3x8::new(one + sign * n.x * n.x * a, sign * b, -sign * n.x), Vec3x8::new(b, sign + n.y * n.y * a, -n.y))
}

#[cfg(test)]
mod x8_tests {
    use super::*;
    use crate::simd::LANES;

    /// [`sample_hemisphere_cos_x8`] against the scalar map for normals all over the sphere (both signs
    /// of `n.z`, the poles, `-0.0`) and points over the whole square, edges included.
    #[test]
    fn hemisphere_x8_matches_scalar() {
        let mut next = crate::sample::hash::test_uniforms(0x1234_5678_9abc_def1);
        for round in 0..4000 {
            let ns: [Vec3; LANES] = std::array::from_fn(|l| match (round + l) % 97 {
                0 => Vec3::Z,
                1 => -Vec3::Z,
                2 => Vec3::new(0.0, 1.0, -0.0),
                _ => Vec3::new(next() * 2.0 - 1.0, next() * 2.0 - 1.0, next() * 2.0 - 1.0).normalize_or(Vec3::X),
            });
            let us: [[f32; 2]; LANES] =
                std::array::from_fn(|l| if round % 50 == 0 { [(l % 2) as f32 * 0.99999994, 0.0] } else { [next(), next()] });
            let nv = Vec3x8::new(f32x8::from(ns.map(|n| n.x)), f32x8::from(ns.map(|n| n.y)), f32x8::from(ns.map(|n| n.z)));
            let got = sample_hemisphere_cos_x8(nv, [f32x8::from(us.map(|u| u[0])), f32x8::from(us.map(|u| u[1]))]);
            for l in 0..LANES {
                let want = sample_hemisphere_cos(ns[l], us[l]);
                let g = got.lane(l);
                assert!((g - want).abs().max_element() < 2e-6, "n {} u {:?}: {g} vs {want}", ns[l], us[l]);
                assert!(g.dot(ns[l]) >= -1e-6, "below the surface");
            }
        }
    }
}
