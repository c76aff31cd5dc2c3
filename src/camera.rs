//! Pinhole and thin-lens cameras with a shutter interval.

use crate::simd::{f32x8, Vec3x8};
use glam::Vec3;

#[derive(Clone, Copy, Debug)]
pub struct Camera {
    pub position: Vec3,
    /// Unit vectors of the camera frame.
    pub forward: Vec3,
    pub right: Vec3,
    pub up: Vec3,
    /// Half extents of the image plane at distance 1.
    pub half_w: f32,
    pub half_h: f32,
    /// Lens radius; 0 is a pinhole.
    pub lens_radius: f32,
    pub focus_distance: f32,
    pub shutter: [f32; 2],
    pub width: u32,
    pub height: u32,
}

impl Camera {
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        position: Vec3,
        look_at: Vec3,
        up: Vec3,
        fov_deg: f32,
        lens_radius: f32,
        focus_distance: f32,
        shutter: [f32; 2],
        width: u32,
        height: u32,
    ) -> Camera {
        let forward = (look_at - position).normalize();
        let right = forward.cross(up).normalize();
        let up = right.cross(forward);
        let half_h = (fov_deg.to_radians() * 0.5).tan();
        let half_w = half_h * width as f32 / height as f32;
        Camera { position, forward, right, up, half_w, half_h, lens_radius, focus_distance, shutter, width, height }
    }

    /// Direction (not normalised; its forward component is 1) through the image point (x, y) in pixels,
    /// x to the right and y downwards from the top-left corner.
    #[inline]
    pub fn pinhole_dir(&self, x: f32, y: f32) -> Vec3 {
        let sx = (2.0 * x / self.width as f32 - 1.0) * self.half_w;
        let sy = (1.0 - 2.0 * y / self.height as f32) * self.half_h;
        self.forward + self.right * sx + self.up * sy
    }

    /// Unit directions of 8 pinhole rays through image points (x, y): [`Camera::pinhole_dir`] and
    /// `normalize` lane by lane, the same operations in the same order (no fused multiply-adds), so the
    /// bits equal those of [`Camera::ray`].
    #[inline]
    pub fn pinhole_dirs_x8(&self, x: f32x8, y: f32x8) -> Vec3x8 {
        let (two, one) = (f32x8::splat(2.0), f32x8::ONE);
        let sx = (two * x / f32x8::splat(self.width as f32) - one) * f32x8::splat(self.half_w);
        let sy = (one - two * y / f32x8::splat(self.height as f32)) * f32x8::splat(self.half_h);
        let (f, r, u) = (self.forward, self.right, self.up);
        let s = |a: f32| f32x8::splat(a);
        let d = Vec3x8::new(s(f.x) + s(r.x) * sx + s(u.x) * sy, s(f.y) + s(r.y) * sx + s(u.y) * sy, s(f.z) + s(r.z) * sx + s(u.z) * sy);
        let inv_len = one / (d.x * d.x + d.y * d.y + d.z * d.z).sqrt();
        d.scale(inv_len)
    }

    /// A camera ray through image point (x, y); `lens` is a point on the unit disk (ignored for a pinhole).
    /// Returns origin and unit direction.
    #[inline]
    pub fn ray(&self, x: f32, y: f32, lens: [f32; 2]) -> (Vec3, Vec3) {
        let d = self.pinhole_dir(x, y);
        if self.lens_radius <= 0.0 {
            return (self.position, d.normalize());
        }
        // Thin lens: every ray through the lens meets the pinhole ray on the plane of focus.
        let focus = self.position + d * self.focus_distance;
        let o = self.position + (self.right * lens[0] + self.up * lens[1]) * self.lens_radius;
        (o, (focus - o).normalize())
    }

    /// Image position (pixels) of a world point, or None behind the camera.
    pub fn project(&self, p: Vec3) -> Option<(f32, f32)> {
        let v = p - self.position;
        let z = v.dot(self.forward);
        if z <= 0.0 {
            return None;
        }
        let sx = v.dot(self.right) / z / self.half_w;
        let sy = v.dot(self.up) / z / self.half_h;
        Some(((sx + 1.0) * 0.5 * self.width as f32, (1.0 - sy) * 0.5 * self.height as f32))
    }

    /// The shutter time for a 1D sample u in [0, 1).
    #[inline]
    pub fn time(&self, u: f32) -> f32 {
        self.shutter[0] + (self.shutter[1] - self.shutter[0]) * u
    }
}
