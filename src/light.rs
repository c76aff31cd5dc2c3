//! Sampling the lights seen from a shading point (next-event estimation), in the area measure:
//! the estimate of the irradiance from an area light is `Le cos_l / d^2 / pdf_area`, times the receiver's
//! cosine, which the caller applies.

use crate::geometry::{offset_distance, offset_distance_x8, offset_ray_origin, offset_ray_origin_scaled_x8};
use crate::sample::warp::{sin_cos_turns, sin_cos_turns_x8};
use crate::sample::{sample_disk_concentric, sample_disk_concentric_x8};
use crate::scene::Light;
use crate::simd::{f32x8, Vec3x8};
use glam::Vec3;

/// One light sample seen from a point.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// The point on the light (offset off its surface towards the receiver).
    pub target: Vec3,
    /// Unit direction from the receiver to the light.
    pub wi: Vec3,
    /// Radiance x geometry / pdf, without the receiver's cosine (for a point light, I / d^2).
    pub weight: Vec3,
}

/// Sample `light` from the receiver point `p` with a uniform 2D point `u`.
#[inline]
pub fn sample_light(light: &Light, p: Vec3, u: [f32; 2]) -> Option<LightSample> {
    match *light {
        Light::Point { position, intensity } => {
            let v = position - p;
            let d2 = v.length_squared();
            (d2 > 0.0).then(|| LightSample { target: position, wi: v / d2.sqrt(), weight: intensity / d2 })
        }
        Light::Quad { quad, radiance } => {
            let y = quad.origin + quad.u * u[0] + quad.v * u[1];
            area_sample(p, y, quad.normal(), quad.area(), radiance)
        }
        Light::Disk { disk, radiance } => {
            let [a, b] = sample_disk_concentric(u);
            let (t, s) = crate::optics::onb(disk.normal);
            let y = disk.center + (t * a + s * b) * disk.radius;
            area_sample(p, y, disk.normal, std::f32::consts::PI * disk.radius * disk.radius, radiance)
        }
        Light::Sphere { center, radius, radiance } => {
            // Uniform over the cone of directions the sphere subtends (pbrt's sphere sampling).
            let v = center - p;
            let d2 = v.length_squared();
            let r2 = radius * radius;
            if d2 <= r2 * 1.000_001 {
                return None;
            }
            let dist = d2.sqrt();
            let axis = v / dist;
            let sin2_max = r2 / d2;
            let cos_max = (1.0 - sin2_max).max(0.0).sqrt();
            // 1 - cos_max without cancellation: for a light 1e3 times smaller than its distance it is
            // 5e-7, below the f32 resolution of 1 - cos_max (the light came out 2x too bright; at 1e-4
            // black; at 1e-6 68x too bright).
            let one_minus_cos = sin2_max / (1.0 + cos_max);
            if !(one_minus_cos > 0.0) {
                return None; // the light subtends no representable solid angle
            }
            let w = u[0] * one_minus_cos; // 1 - cos_t
            let cos_t = 1.0 - w;
            let sin_t = (w * (2.0 - w)).max(0.0).sqrt();
            let (sin_phi, cos_phi) = sin_cos_turns(u[1]);
            let (t, s) = crate::optics::onb(axis);
            let wi = (t * (sin_t * cos_phi) + s * (sin_t * sin_phi) + axis * cos_t).normalize();
            // Distance to the near side of the sphere along wi, as (|v|^2 - r^2) / (b + sqrt(disc)): the
            // root b - sqrt(disc) loses all its digits when disc = r^2 - |v - wi b|^2 is rounding noise
            // (a light much smaller than its distance).
            let b = v.dot(wi);
            let disc = (r2 - (v - wi * b).length_squared()).max(0.0);
            let th = (d2 - r2) / (b + disc.sqrt());
            let y = p + wi * th;
            let pdf = 1.0 / (2.0 * std::f32::consts::PI * one_minus_cos);
            // The target is moved back along the ray towards the receiver, so that the shadow segment
            // stops short of the sphere (where the ray first meets it) without leaving the sampled
            // direction. (Moved along the sphere's normal at y, as it was, a sample near the silhouette
            // went sideways by the offset, which at 5e3 from the origin is 0.125: a light of radius
            // 5e-4 there cast the soft shadow of one 250 times larger; and below the f32 spacing of its
            // centre's coordinates `y - center` is zero, the normal NaN, and every such shadow ray
            // passed: speckled shadows. Both user trials.) y was computed from the receiver's position:
            // its error is ULPs of |p| as well.
            // (At most half way back to the receiver: one nearer the sphere than the offset would
            // otherwise get a target behind it.)
            let back = offset_distance(y.abs().max_element().max(p.abs().max_element())).min(0.5 * th);
            Some(LightSample { target: (-wi).mul_add(Vec3::splat(back), y), wi, weight: radiance / pdf })
        }
    }
}

#[inline]
fn area_sample(p: Vec3, y: Vec3, n_light: Vec3, area: f32, radiance: Vec3) -> Option<LightSample> {
    let v = y - p;
    let d2 = v.length_squared();
    if d2.is_nan() || d2 <= 0.0 {
        return None;
    }
    let wi = v / d2.sqrt();
    let cos_l = -wi.dot(n_light);
    if cos_l <= 0.0 {
        return None; // one-sided emitters: the receiver is behind the light
    }
    // The receiver is on the emitting side (`n_light` points to it): the target moves off the light
    // towards it, so the shadow segment never has to cross the light's own surface. (Offsetting to the
    // back made grazing shadow rays cross the light plane before `SHADOW_END`: walls beside a ceiling
    // light came out black near the ceiling.)
    Some(LightSample { target: offset_ray_origin(y, n_light), wi, weight: radiance * (cos_l * area / d2) })
}

/// Solid-angle density, seen from `p`, of one sample of an area light at its point `y` (`y` unused for
/// a sphere, sampled uniformly over the cone it subtends): `d^2 / (cos_l A)` for quads and disks.
/// 0 where [`sample_light`] draws nothing (behind a one-sided light, inside a sphere) and for point
/// lights (a delta: no direction finds them). The weight of multiple importance sampling between a
/// glossy lobe and next-event estimation needs it on both sides.
pub fn sample_pdf(light: &Light, p: Vec3, y: Vec3) -> f32 {
    let flat = |n: Vec3, area: f32| {
        let v = y - p;
        let d2 = v.length_squared();
        let cos_l = -v.dot(n) / d2.sqrt();
        if cos_l > 0.0 && area > 0.0 {
            d2 / (cos_l * area)
        } else {
            0.0
        }
    };
    match *light {
        Light::Point { .. } => 0.0,
        Light::Quad { quad, .. } => flat(quad.normal(), quad.area()),
        Light::Disk { disk, .. } => flat(disk.normal, std::f32::consts::PI * disk.radius * disk.radius),
        Light::Sphere { center, radius, .. } => {
            // As `sample_light` forms `1 - cos_max`.
            let d2 = (center - p).length_squared();
            let r2 = radius * radius;
            if d2 <= r2 * 1.000_001 {
                return 0.0;
            }
            let sin2_max = r2 / d2;
            let one_minus_cos = sin2_max / (1.0 + (1.0 - sin2_max).max(0.0).sqrt());
            if one_minus_cos > 0.0 {
                1.0 / (std::f32::consts::TAU * one_minus_cos)
            } else {
                0.0
            }
        }
    }
}

/// Power-heuristic weight (Veach 1997) of a sample drawn with density `p` among `n` such samples, against
/// one sample of the other strategy with density `q` at the same direction: `(n p)^2 / ((n p)^2 + q^2)`,
/// formed from the ratio (no overflow for a sharp lobe); 1 where `q` is 0.
#[inline]
pub fn power_heuristic(n: f32, p: f32, q: f32) -> f32 {
    if !(q > 0.0) {
        return 1.0;
    }
    let r = q / (n * p);
    1.0 / r.mul_add(r, 1.0)
}

/// [`sample_pdf`] in 8 lanes (one light, eight points `p` and light points `y`), the same operations
/// (bit-identical lane by lane).
#[inline(always)]
pub fn sample_pdf_x8(light: &Light, p: Vec3x8, y: Vec3x8) -> f32x8 {
    let zero = f32x8::ZERO;
    let flat = |n: Vec3, area: f32| {
        if !(area > 0.0) {
            return zero;
        }
        let v = y - p;
        let d2 = v.dot_unfused(v);
        let cos_l = -v.dot_unfused(Vec3x8::splat(n)) / d2.sqrt();
        cos_l.simd_gt(zero).select(d2 / (cos_l * f32x8::splat(area)), zero)
    };
    match *light {
        Light::Point { .. } => zero,
        Light::Quad { quad, .. } => flat(quad.normal(), quad.area()),
        Light::Disk { disk, .. } => flat(disk.normal, std::f32::consts::PI * disk.radius * disk.radius),
        Light::Sphere { center, radius, .. } => {
            let v = Vec3x8::splat(center) - p;
            let d2 = v.dot_unfused(v);
            let r2 = f32x8::splat(radius * radius);
            let sin2_max = r2 / d2;
            let one_minus_cos = sin2_max / (f32x8::ONE + (f32x8::ONE - sin2_max).max(zero).sqrt());
            let pdf = f32x8::ONE / (f32x8::splat(std::f32::consts::TAU) * one_minus_cos);
            (d2.simd_gt(r2 * f32x8::splat(1.000_001)) & one_minus_cos.simd_gt(zero)).select(pdf, zero)
        }
    }
}

/// [`power_heuristic`] in 8 lanes (bit-identical lane by lane).
#[inline(always)]
pub fn power_heuristic_x8(n: f32, p: f32x8, q: f32x8) -> f32x8 {
    let r = q / (f32x8::splat(n) * p);
    q.simd_gt(f32x8::ZERO).select(f32x8::ONE / r.mul_add(r, f32x8::ONE), f32x8::ONE)
}

/// How many samples a light gets per shading point (delta lights need one).
#[inline]
pub fn samples_for(light: &Light, area_samples: u32) -> u32 {
    match light {
        Light::Point { .. } => 1,
        _ => area_samples,
    }
}

/// Eight light samples seen from eight points: [`LightSample`] per lane, and the lanes that have one.
#[derive(Clone, Copy, Debug)]
pub struct LightSample8 {
    pub target: Vec3x8,
    pub wi: Vec3x8,
    pub weight: Vec3x8,
    /// All-ones on lanes with a sample (where [`sample_light`] returns `Some`).
    pub valid: f32x8,
}

/// Eight lanes of [`sample_light`]: receiver points `p`, uniform points `u = [u0s, u1s]`. Point and
/// quad lights are bit-identical to the scalar function (same operations, no FMA where it has none);
/// disk lights agree to ~1e-6 (wide's `sin_cos` in the concentric map); sphere lights are bit-identical
/// too (their angle's sine and cosine by [`sin_cos_turns`] in both).
#[inline]
pub fn sample_light_x8(light: &Light, p: Vec3x8, u: [f32x8; 2]) -> LightSample8 {
    let zero = f32x8::ZERO;
    match *light {
        Light::Point { position, intensity } => {
            let v = Vec3x8::splat(position) - p;
            let d2 = v.dot_unfused(v);
            let s = d2.sqrt();
            let wi = Vec3x8::new(v.x / s, v.y / s, v.z / s);
            let weight = Vec3x8::new(f32x8::splat(intensity.x) / d2, f32x8::splat(intensity.y) / d2, f32x8::splat(intensity.z) / d2);
            LightSample8 { target: Vec3x8::splat(position), wi, weight, valid: d2.simd_gt(zero) }
        }
        Light::Quad { .. } | Light::Disk { .. } => {
            let (y, target) = light_points_x8(light, u).expect("an area light");
            sample_light_at_x8(light, p, y, target)
        }
        Light::Sphere { center, radius, radiance } => sample_sphere_x8(center, radius, radiance, p, u),
    }
}

/// Eight lanes of [`sample_light`]'s sphere, the same operations in the same order (bit-identical lane
/// by lane where the scalar gives a sample).
#[inline(always)]
fn sample_sphere_x8(center: Vec3, radius: f32, radiance: Vec3, p: Vec3x8, u: [f32x8; 2]) -> LightSample8 {
    let (zero, one) = (f32x8::ZERO, f32x8::ONE);
    let v = Vec3x8::splat(center) - p;
    let d2 = v.dot_unfused(v);
    let r2 = f32x8::splat(radius * radius);
    let outside = !d2.simd_le(r2 * f32x8::splat(1.000_001));
    let dist = d2.sqrt();
    let axis = Vec3x8::new(v.x / dist, v.y / dist, v.z / dist);
    let sin2_max = r2 / d2;
    let cos_max = (one - sin2_max).max(zero).sqrt();
    let one_minus_cos = sin2_max / (one + cos_max);
    let w = u[0] * one_minus_cos;
    let cos_t = one - w;
    let sin_t = (w * (f32x8::splat(2.0) - w)).max(zero).sqrt();
    let (sin_phi, cos_phi) = sin_cos_turns_x8(u[1]);
    let (t, s) = crate::optics::onb_x8(axis);
    let wi = (t.scale(sin_t * cos_phi) + s.scale(sin_t * sin_phi) + axis.scale(cos_t)).normalize();
    let b = v.dot_unfused(wi);
    let off = v - wi.scale(b);
    let disc = (r2 - off.dot_unfused(off)).max(zero);
    let th = (d2 - r2) / (b + disc.sqrt());
    let y = p + wi.scale(th);
    let pdf = one / (f32x8::splat(2.0 * std::f32::consts::PI) * one_minus_cos);
    let back = offset_distance_x8(y.max_abs_element().max(p.max_abs_element())).min(f32x8::splat(0.5) * th);
    let target = Vec3x8::new(-wi.x, -wi.y, -wi.z).mul_add(back, y);
    let weight = Vec3x8::new(f32x8::splat(radiance.x) / pdf, f32x8::splat(radiance.y) / pdf, f32x8::splat(radiance.z) / pdf);
    LightSample8 { target, wi, weight, valid: outside & one_minus_cos.simd_gt(zero) }
}

/// The points of a quad or disk light that [`sample_light_x8`] samples for the uniform points `u`, and
/// their shadow-ray targets (offset off the light towards its emitting side); `None` for other lights.
/// They depend on `u` only: a grid's points are the same for every receiver (the shadow stage computes
/// them once and calls [`sample_light_at_x8`]).
#[inline]
pub fn light_points_x8(light: &Light, u: [f32x8; 2]) -> Option<(Vec3x8, Vec3x8)> {
    let (y, n) = match *light {
        Light::Quad { quad, .. } => {
            let y = Vec3x8::splat(quad.u).scale(u[0]) + Vec3x8::splat(quad.origin);
            (y + Vec3x8::splat(quad.v).scale(u[1]), quad.normal())
        }
        Light::Disk { disk, .. } => {
            let [a, b] = sample_disk_concentric_x8(u);
            let (t, s) = crate::optics::onb(disk.normal);
            let r = f32x8::splat(disk.radius);
            let off = Vec3x8::splat(t).scale(a) + Vec3x8::splat(s).scale(b);
            (Vec3x8::splat(disk.center) + off.scale(r), disk.normal)
        }
        _ => return None,
    };
    Some((y, offset_ray_origin_scaled_x8(y, Vec3x8::splat(n), f32x8::ZERO)))
}

/// [`sample_light_x8`] of a quad or disk light from its points `y` and targets ([`light_points_x8`]).
#[inline(always)]
pub fn sample_light_at_x8(light: &Light, p: Vec3x8, y: Vec3x8, target: Vec3x8) -> LightSample8 {
    match *light {
        Light::Quad { quad, radiance } => area_sample_x8(p, y, target, quad.normal(), quad.area(), radiance),
        Light::Disk { disk, radiance } => {
            area_sample_x8(p, y, target, disk.normal, std::f32::consts::PI * disk.radius * disk.radius, radiance)
        }
        _ => unreachable!("an area light with points"),
    }
}

/// Eight lanes of `area_sample` (bit-identical to it), the target already offset off the light.
#[inline(always)]
fn area_sample_x8(p: Vec3x8, y: Vec3x8, target: Vec3x8, n_light: Vec3, area: f32, radiance: Vec3) -> LightSample8 {
    let v = y - p;
    let d2 = v.dot_unfused(v);
    let s = d2.sqrt();
    let wi = Vec3x8::new(v.x / s, v.y / s, v.z / s);
    let cos_l = -wi.dot_unfused(Vec3x8::splat(n_light));
    // `d2 > 0` is false for NaN too (the scalar's `is_nan() || <= 0`).
    let valid = d2.simd_gt(f32x8::ZERO) & cos_l.simd_gt(f32x8::ZERO);
    let g = cos_l * f32x8::splat(area) / d2;
    LightSample8 { target, wi, weight: Vec3x8::splat(radiance).scale(g), valid }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Disk, Quad};
    use crate::simd::LANES;
    use rand_core::{Rng, SeedableRng};
    use rand_xoshiro::Xoshiro256PlusPlus;

    /// One light of each kind, placed around the origin (receivers of the tests lie within 6 of it).
    fn test_lights() -> [Light; 4] {
        [
            Light::Point { position: Vec3::new(1.0, 4.0, -2.0), intensity: Vec3::new(5.0, 4.0, 3.0) },
            Light::Quad {
                quad: Quad::new(Vec3::new(-1.0, 3.0, -1.0), Vec3::new(2.0, 0.4, 0.0), Vec3::new(0.0, 0.3, 1.5)),
                radiance: Vec3::new(2.0, 3.0, 4.0),
            },
            Light::Disk { disk: Disk::new(Vec3::new(0.5, 2.0, 0.0), Vec3::new(0.0, -1.0, 0.2), 0.7), radiance: Vec3::splat(3.0) },
            Light::Sphere { center: Vec3::new(0.0, 5.0, 1.0), radius: 0.5, radiance: Vec3::splat(7.0) },
        ]
    }

    /// A sphere light's shadow-ray target lies on the sampled direction, short of the sphere: for radii
    /// from 1 down to far below the f32 spacing of the centre's coordinates (where `y - center` is
    /// zero: its normal was NaN, and the shadow rays passed), near the origin and 5e3 from it (where
    /// the offset, 256 ULPs of the coordinates, is 0.125: along the normal it moved silhouette samples
    /// sideways by that, a light 250x its size). Checked in f64: the target's distance from the ray
    /// `p + t wi` within 4 ULPs of the coordinates and 1e-6 of the distance travelled (the f32 rounding
    /// of the points), in front of the receiver, and outside the sphere, nearer than its centre.
    #[test]
    fn sphere_light_targets_stay_on_their_rays() {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(46);
        let mut u01 = || (rng.next_u32() >> 8) as f32 / (1u32 << 24) as f32;
        let mut checked = 0;
        for shift in [Vec3::ZERO, Vec3::new(5e3, 0.0, 0.0)] {
            for radius in [1.0, 1e-3, 5e-4, 1e-6, 1e-9] {
                let center = Vec3::new(-1.0, 3.0, -1.0) + shift;
                let light = Light::Sphere { center, radius, radiance: Vec3::ONE };
                for i in 0..200 {
                    // Receivers across a floor 3 below the light, and every fourth one near its surface
                    // (gaps from 1e-4 to 0.1: nearer than the offset 5e3 from the origin, where the
                    // target must still lie in front of the receiver).
                    let p = if i % 4 == 0 {
                        let gap = 10f32.powf(-4.0 + 3.0 * u01());
                        center + Vec3::new(u01() - 0.5, -1.0, u01() - 0.5).normalize() * (radius + gap)
                    } else {
                        Vec3::new(u01() * 6.0 - 3.0, 0.0, u01() * 6.0 - 3.0) + shift
                    };
                    let Some(s) = sample_light(&light, p, [u01(), u01()]) else { continue };
                    assert!(s.target.is_finite() && s.wi.is_finite(), "radius {radius} at {shift}: {s:?}");
                    let (p64, t64, wi64, c64) = (p.as_dvec3(), s.target.as_dvec3(), s.wi.as_dvec3(), center.as_dvec3());
                    let along = (t64 - p64).dot(wi64);
                    let off = ((t64 - p64) - wi64 * along).length();
                    let ulp = p.abs().max_element().max(1.0) as f64 * f32::EPSILON as f64;
                    assert!(along > 0.0 && off <= 4.0 * ulp + 1e-6 * along, "radius {radius} at {shift}: {off} off the ray of {along}");
                    let to_centre = (c64 - p64).length();
                    assert!(
                        along < to_centre && (t64 - c64).length() >= radius as f64 * (1.0 - 1e-6),
                        "radius {radius} at {shift}: inside"
                    );
                    checked += 1;
                }
            }
        }
        assert!(checked > 1500, "{checked} samples");
    }

    /// [`sample_pdf_x8`] and [`power_heuristic_x8`] against their scalar twins, bit for bit: points
    /// around, behind, on the plane of, inside and far from each light, light points on and off the
    /// light; the power heuristic with zero, tiny and huge densities on either side.
    #[test]
    fn pdf_and_power_heuristic_x8_match_scalar() {
        let lights = test_lights();
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(12);
        let mut f = |s: f32| (rng.next_u32() >> 8) as f32 / 16_777_216.0 * s;
        let (mut positive, mut zero) = (0, 0);
        for light in &lights {
            for round in 0..300 {
                let scale = [1.0, 1e-3, 1e3][round % 3];
                let (mut p, mut y) = ([[0.0f32; LANES]; 3], [[0.0f32; LANES]; 3]);
                for l in 0..LANES {
                    for (pc, yc) in p.iter_mut().zip(&mut y) {
                        pc[l] = (f(2.0) - 1.0) * 6.0 * scale;
                        yc[l] = (f(2.0) - 1.0) * 6.0;
                    }
                }
                // Some light points on the light, and one receiver at the light point (d = 0).
                if let Some((yl, _)) = light_points_x8(light, [f32x8::splat(f(1.0)), f32x8::splat(f(1.0))]) {
                    let r = yl.rows();
                    for c in 0..3 {
                        y[c][1] = r[c][1];
                        (y[c][2], p[c][2]) = (r[c][2], r[c][2]);
                    }
                }
                let (pv, yv) = (Vec3x8::from_rows(&p), Vec3x8::from_rows(&y));
                let got = sample_pdf_x8(light, pv, yv).to_array();
                for (l, g) in got.iter().enumerate() {
                    let want = sample_pdf(light, pv.lane(l), yv.lane(l));
                    assert_eq!(g.to_bits(), want.to_bits(), "{light:?} lane {l}: p {} y {}", pv.lane(l), yv.lane(l));
                    if want > 0.0 {
                        positive += 1;
                    } else {
                        zero += 1;
                    }
                }
            }
        }
        assert!(positive > 3000 && zero > 3000, "{positive} positive, {zero} zero densities");
        let values = [0.0, 1e-30, 1e-6, 0.3, 1.0, 7.5, 1e6, 1e30, f32::INFINITY];
        for n in [1.0, 4.0, 64.0] {
            for (i, &pv) in values.iter().enumerate() {
                let q: [f32; LANES] = std::array::from_fn(|l| values[(i + l) % values.len()]);
                let got = power_heuristic_x8(n, f32x8::splat(pv), f32x8::from(q)).to_array();
                for l in 0..LANES {
                    let want = power_heuristic(n, pv, q[l]);
                    assert_eq!(got[l].to_bits(), want.to_bits(), "n {n} p {pv} q {}", q[l]);
                }
            }
        }
    }

    /// Every lane of [`sample_light_x8`] against [`sample_light`] for receivers around, behind, on the
    /// plane of and far from each light: the same lanes valid, and the same bits (point, quad, sphere) or
    /// agreement to float rounding of the disk map's `sin_cos` (disk).
    #[test]
    fn x8_matches_scalar() {
        let lights = test_lights();
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(11);
        let mut f = |s: f32| (rng.next_u32() >> 8) as f32 / 16_777_216.0 * s;
        for (k, light) in lights.iter().enumerate() {
            let (mut valid_lanes, mut checked) = (0, 0);
            for round in 0..200 {
                let scale = [1.0, 1e-3, 1e3][round % 3];
                let mut p = [[0.0f32; LANES]; 3];
                let mut u = [[0.0f32; LANES]; 2];
                for l in 0..LANES {
                    for c in &mut p {
                        c[l] = (f(2.0) - 1.0) * 6.0 * scale;
                    }
                    u[0][l] = f(1.0);
                    u[1][l] = f(1.0);
                }
                // One receiver exactly at the point light (d2 = 0: no sample).
                if round == 7 {
                    if let Light::Point { position, .. } = light {
                        (p[0][0], p[1][0], p[2][0]) = (position.x, position.y, position.z);
                    }
                }
                let pv = Vec3x8::new(f32x8::from(p[0]), f32x8::from(p[1]), f32x8::from(p[2]));
                let s8 = sample_light_x8(light, pv, [f32x8::from(u[0]), f32x8::from(u[1])]);
                let valid = s8.valid.to_bitmask();
                for l in 0..LANES {
                    let s = sample_light(light, Vec3::new(p[0][l], p[1][l], p[2][l]), [u[0][l], u[1][l]]);
                    assert_eq!(s.is_some(), valid & (1 << l) != 0, "light {k} round {round} lane {l}");
                    let Some(s) = s else { continue };
                    valid_lanes += 1;
                    let got = [s8.target.lane(l), s8.wi.lane(l), s8.weight.lane(l)];
                    for (g, want) in got.iter().zip([s.target, s.wi, s.weight]) {
                        if matches!(light, Light::Disk { .. }) {
                            let tol = 1e-5 * want.abs().max_element().max(1.0) * scale.max(1.0);
                            assert!((*g - want).abs().max_element() <= tol, "light {k}: {g} vs {want}");
                        } else {
                            assert_eq!(g.to_array().map(f32::to_bits), want.to_array().map(f32::to_bits), "light {k}: {g} vs {want}");
                        }
                        checked += 1;
                    }
                }
            }
            assert!(valid_lanes > 200 && checked > 600, "light {k}: only {valid_lanes} valid lanes");
        }
    }
}
