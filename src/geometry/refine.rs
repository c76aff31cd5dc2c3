//! Hit points re-projected onto their surface, so that their error is ULPs of the surface's own
//! coordinates and not of the ray's origin.
//!
//! A hit point computed as `o + t d` is only accurate to ULPs of `max(|o|, |p|)`: seen from a camera
//! 1e3 away, 256 ULPs of `|o|` (the spawn offset that covers that error) is 0.016, more than the wall
//! of a 0.01-thick shell, and a ray spawned through one wall skips the other. Each function here moves
//! the point onto its surface along the surface's normal and returns the magnitude whose ULPs bound the
//! result's error (the surface's own placement: its plane offset, centre, or the size of its frame);
//! the caller spawns with [`super::offset_ray_origin_scaled`] at that magnitude. Spheres have their own
//! (f64) re-projection, [`super::refine_sphere_point`].
//!
//! The displacement is along the normal only: the point stays where the ray met the surface to within
//! the ray's own rounding (ULPs of `|o|` sideways), which no image can see.

use super::{Ellipsoid, OBox};
use crate::simd::{f32x8, Vec3x8};
use glam::Vec3;

/// `p` moved along the unit normal `n` onto the plane `n . x = w`: `p - n (n . p - w)`. Its error is a
/// few ULPs of `max(|p|, |w|)` (and of the plane's defining point, which the caller's magnitude holds).
#[inline(always)]
pub fn refine_flat_point(p: Vec3, n: Vec3, w: f32) -> Vec3 {
    p - n * (n.dot(p) - w)
}

/// [`refine_flat_point`] in 8 lanes, the same operations (bit-identical lane by lane).
#[inline(always)]
pub fn refine_flat_point_x8(p: Vec3x8, n: Vec3x8, w: f32x8) -> Vec3x8 {
    p - n.scale(n.dot_unfused(p) - w)
}

/// The largest absolute coordinate of `v`.
#[inline(always)]
fn mag(v: Vec3) -> f32 {
    v.abs().max_element()
}

/// A hit point `p` on the oriented box `b`, moved onto the face [`super::normal_obox`] picks (its
/// coordinate set to the face's), and the magnitude of its error: the centre's and the box's extent in
/// world space. `None` for a non-finite result (a degenerate box).
#[inline]
pub fn refine_obox_point(b: &OBox, p: Vec3) -> Option<(Vec3, f32)> {
    let (mut q, i) = super::obox::obox_face(b, p);
    q[i] = if q[i] < 0.0 { -b.half[i] } else { b.half[i] };
    let w = b.to_world * q;
    let out = b.center + w;
    out.is_finite().then(|| (out, mag(b.center).max(mag(w))))
}

/// A hit point `p` on the ellipsoid `e`, moved radially onto the unit sphere of its object frame and back,
/// and the magnitude of its error (the centre's and the semi-axes' in world space). `None` for a
/// non-finite result (a degenerate ellipsoid, or `p` at its centre).
#[inline]
pub fn refine_ellipsoid_point(e: &Ellipsoid, p: Vec3) -> Option<(Vec3, f32)> {
    let q = (glam::Mat3::from(e.world_to_object.matrix3) * (p - e.center)).normalize_or_zero();
    if q == Vec3::ZERO {
        return None;
    }
    let w = e.to_world * q;
    let out = e.center + w;
    out.is_finite().then(|| (out, mag(e.center).max(mag(w))))
}
