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

    /// Eight lanes of [`Camera::pinhole_dir`] (same operations, same bits).
    #[inline(always)]
    fn pinhole_dir_x8(&self, x: f32x8, y: f32x8) -> Vec3x8 {
        let (two, one) = (f32x8::splat(2.0), f32x8::ONE);
        let sx = (two * x / f32x8::splat(self.width as f32) - one) * f32x8::splat(self.half_w);
        let sy = (one - two * y / f32x8::splat(self.height as f32)) * f32x8::splat(self.half_h);
        let (f, r, u) = (self.forward, self.right, self.up);
        let s = |a: f32| f32x8::splat(a);
        Vec3x8::new(s(f.x) + s(r.x) * sx + s(u.x) * sy, s(f.y) + s(r.y) * sx + s(u.y) * sy, s(f.z) + s(r.z) * sx + s(u.z) * sy)
    }

    /// Eight lanes of [`Camera::ray`] (`lens = [l0s, l1s]`, points on the unit disk): origins and unit
    /// directions, the same operations in the same order as the scalar, so the same bits.
    #[inline]
    pub fn rays_x8(&self, x: f32x8, y: f32x8, lens: [f32x8; 2]) -> (Vec3x8, Vec3x8) {
        let d = self.pinhole_dir_x8(x, y);
        let pos = Vec3x8::splat(self.position);
        if self.lens_radius <= 0.0 {
            return (pos, d.normalize());
        }
        let focus = pos + d.scale(f32x8::splat(self.focus_distance));
        let off = Vec3x8::splat(self.right).scale(lens[0]) + Vec3x8::splat(self.up).scale(lens[1]);
        let o = pos + off.scale(f32x8::splat(self.lens_radius));
        (o, (focus - o).normalize())
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

#[cfg(test)]
mod tests {
    use super::*;

    /// [`Camera::rays_x8`] against [`Camera::ray`], bit for bit, with and without a lens, over image
    /// points inside and outside the frame and lens points over the disk.
    #[test]
    fn rays_x8_equal_the_scalar_camera() {
        for lens_radius in [0.0, 0.05] {
            let cam = Camera::new(Vec3::new(1.0, 2.0, 3.0), Vec3::new(0.0, 0.5, -1.0), Vec3::Y, 40.0, lens_radius, 4.0, [0.0, 1.0], 64, 48);
            for k in 0..200 {
                let f = |l: usize, m: f32| ((k * 8 + l) as f32 * 0.618_034).fract() * m;
                let (x, y) = (
                    f32x8::from(std::array::from_fn::<f32, 8, _>(|l| f(l, 80.0) - 8.0)),
                    f32x8::from(std::array::from_fn::<f32, 8, _>(|l| f(l + 3, 60.0) - 6.0)),
                );
                let lens = [
                    f32x8::from(std::array::from_fn::<f32, 8, _>(|l| f(l + 5, 2.0) - 1.0)),
                    f32x8::from(std::array::from_fn::<f32, 8, _>(|l| f(l + 7, 1.4) - 0.7)),
                ];
                let (o, d) = cam.rays_x8(x, y, lens);
                for l in 0..8 {
                    let (so, sd) = cam.ray(x.to_array()[l], y.to_array()[l], [lens[0].to_array()[l], lens[1].to_array()[l]]);
                    assert_eq!(o.lane(l).to_array().map(f32::to_bits), so.to_array().map(f32::to_bits));
                    assert_eq!(d.lane(l).to_array().map(f32::to_bits), sd.to_array().map(f32::to_bits));
                }
            }
        }
    }
}
