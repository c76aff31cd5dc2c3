//! Sampling the lights seen from a shading point (next-event estimation), in the area measure:
//! the estimate of the irradiance from an area light is `Le cos_l / d^2 / pdf_area`, times the receiver's
//! cosine, which the caller applies.

use crate::geometry::{offset_ray_origin, offset_ray_origin_scaled};
use crate::sample::sample_disk_concentric;
use crate::scene::Light;
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
            let phi = 2.0 * std::f32::consts::PI * u[1];
            let (t, s) = crate::optics::onb(axis);
            let wi = (t * (sin_t * phi.cos()) + s * (sin_t * phi.sin()) + axis * cos_t).normalize();
            // Distance to the near side of the sphere along wi, as (|v|^2 - r^2) / (b + sqrt(disc)): the
            // root b - sqrt(disc) loses all its digits when disc = r^2 - |v - wi b|^2 is rounding noise
            // (a light much smaller than its distance).
            let b = v.dot(wi);
            let disc = (r2 - (v - wi * b).length_squared()).max(0.0);
            let th = (d2 - r2) / (b + disc.sqrt());
            let y = p + wi * th;
            let n = (y - center).normalize();
            let pdf = 1.0 / (2.0 * std::f32::consts::PI * one_minus_cos);
            // y was computed from the receiver's position: its error is ULPs of |p| as well.
            Some(LightSample { target: offset_ray_origin_scaled(y, n, p.abs().max_element()), wi, weight: radiance / pdf })
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

/// How many samples a light gets per shading point (delta lights need one).
#[inline]
pub fn samples_for(light: &Light, area_samples: u32) -> u32 {
    match light {
        Light::Point { .. } => 1,
        _ => area_samples,
    }
}
