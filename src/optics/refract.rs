//! Mirror reflection and Snell refraction of unit directions (see the conventions in `mod.rs`:
//! `wo` points away from the surface, `n` is on `wo`'s side, `eta = n_incident / n_transmitted`).

use glam::Vec3;

use super::fresnel::{clamp01, cos_t_sq};

/// Mirror `wo` about `n`: the reflected direction, pointing away from the surface.
#[inline]
pub fn reflect(wo: Vec3, n: Vec3) -> Vec3 {
    (2.0 * wo.dot(n)) * n - wo
}

/// Refracted direction (pointing away from the surface, on the far side), or `None` under total
/// internal reflection — exactly when [`super::fresnel_dielectric`] returns 1 because
/// `cos_t^2 <= 0` (both use [`super::cos_t_sq`]).
///
/// `t = -eta wo + (eta cos_i - cos_t) n` (Snell's law in vector form: the tangential component is
/// scaled by `eta`, the normal component fixed by `|t| = 1`). The result is renormalised.
/// `eta == 1` (index-matched interface) returns `-wo` exactly.
#[inline]
pub fn refract(wo: Vec3, n: Vec3, eta: f32) -> Option<Vec3> {
    if eta == 1.0 {
        return Some(-wo);
    }
    let c = clamp01(wo.dot(n));
    let ct2 = cos_t_sq(c, eta);
    if !(ct2 > 0.0) {
        return None;
    }
    let t = eta.mul_add(c, -ct2.sqrt()) * n - eta * wo;
    Some(t.normalize_or(-n))
}
