//! Robust spawn points: move a hit point off its surface by a few ULPs of its magnitude.

use crate::simd::{f32x8, u32x8, Vec3x8};
use glam::Vec3;

/// Offset in units of the ULP of the largest coordinate of `p` (Waechter & Binder use 256).
pub const OFFSET_ULPS: f32 = 256.0;

/// Below this magnitude the ULP would be subnormal; keeps the offset a normal float.
const MIN_SCALE: f32 = 1.0e-30;

/// Move `p` off the surface towards the side `n` (unit) points to, by `OFFSET_ULPS` ULPs of
/// `max_i |p_i|`, along `n`.
///
/// After Waechter & Binder, "A Fast and Robust Method for Avoiding Self-Intersection", Ray
/// Tracing Gems ch. 6 (2019): a computed hit point is off the true surface by a few ULPs of its
/// coordinates, so an offset of a fixed number of ULPs works at any distance from the origin.
/// Two deliberate differences from the paper: (1) the ULP is that of the LARGEST coordinate,
/// applied to every component along `n`: a component near zero is still as uncertain as the
/// largest one, which is why the paper switches to a fixed `1/65536` offset below `|p_i| < 1/32`;
/// that fixed offset assumes a unit-scale scene (it is 15% of a `1e-4`-sized object), while the
/// largest coordinate scales with the scene. (2) It moves along `n` in float arithmetic instead
/// of adding integer ULPs per component, so the offset is a true normal displacement:
/// `n . (p' - p) >= (OFFSET_ULPS - 2) ulp(max |p_i|)` for unit `n`.
///
/// The offset is at most `OFFSET_ULPS * 2^-23 ~ 3e-5` of `|p|`. It covers the error of a hit
/// point that is itself a few ULPs accurate; a point computed as `o + t d` from a distant origin
/// is only accurate to ULPs of `|o| + |t d|` and should be re-projected first (e.g.
/// [`super::refine_sphere_point`]). Non-finite `p` or `n` propagate.
#[inline]
pub fn offset_ray_origin(p: Vec3, n: Vec3) -> Vec3 {
    offset_ray_origin_scaled(p, n, 0.0)
}

/// [`offset_ray_origin`] for a point whose error is ULPs of a larger magnitude than its own: the
/// offset is `OFFSET_ULPS` ULPs of `max(max_i |p_i|, magnitude)`. A hit point computed as `o + t d`
/// is accurate to ULPs of `max(|o|, |p|)` (`|t d| <= |o| + |p|`); seen from a camera 1e3 away, a
/// plane near the origin has hit points off the plane by far more than 256 ULPs of the point itself.
#[inline]
pub fn offset_ray_origin_scaled(p: Vec3, n: Vec3, magnitude: f32) -> Vec3 {
    n.mul_add(Vec3::splat(offset_distance(p.abs().max_element().max(magnitude))), p)
}

/// The distance [`offset_ray_origin_scaled`] moves a point whose largest coordinate (or error scale) is
/// `m`: `OFFSET_ULPS` ULPs of `m` (between 2^-24 and 2^-23 x `OFFSET_ULPS` x `m`).
#[inline]
pub fn offset_distance(m: f32) -> f32 {
    OFFSET_ULPS * ulp_at(m.abs().max(MIN_SCALE))
}

/// The f32 spacing at magnitude `m >= f32::MIN_POSITIVE`: `2^(exponent of m) * 2^-23` (the exponent
/// bits kept alone), between 2^-24 and 2^-23 x `m`.
#[inline]
pub fn ulp_at(m: f32) -> f32 {
    f32::from_bits(m.to_bits() & 0x7f80_0000) * f32::EPSILON
}
/// Eight lanes of [`offset_distance`], bit-identical to it for finite inputs.
#[inline(always)]
pub fn offset_distance_x8(m: f32x8) -> f32x8 {
    let m = m.abs().max(f32x8::splat(MIN_SCALE));
    let exp = bytemuck::cast::<f32x8, u32x8>(m) & u32x8::splat(0x7f80_0000);
    f32x8::splat(OFFSET_ULPS) * (bytemuck::cast::<u32x8, f32x8>(exp) * f32x8::splat(f32::EPSILON))
}

/// Eight lanes of [`offset_ray_origin_scaled`], bit-identical to it for finite inputs (same
/// exponent masking, same fused multiply-add per component).
#[inline(always)]
pub fn offset_ray_origin_scaled_x8(p: Vec3x8, n: Vec3x8, magnitude: f32x8) -> Vec3x8 {
    n.mul_add(offset_distance_x8(p.x.abs().max(p.y.abs()).max(p.z.abs()).max(magnitude)), p)
}
