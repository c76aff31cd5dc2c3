//! Disks: centre, normal, radius (boundary included).

use super::{finish_x8, valid_f64};
use crate::simd::{f32x8, Ray8, Vec3x8};
use glam::{DVec3, Vec3};

/// A disk. `normal` need not be unit length for the kernel ([`Disk::new`] normalises it, and
/// the shading normal is the stored one).
#[derive(Clone, Copy, Debug)]
pub struct Disk {
    pub center: Vec3,
    pub normal: Vec3,
    pub radius: f32,
}

impl Disk {
    /// A disk with unit normal `normalize(normal)`.
    pub fn new(center: Vec3, normal: Vec3, radius: f32) -> Disk {
        Disk { center, normal: normal.normalize_or_zero(), radius }
    }
}

/// Ray/disk: the plane hit `t = -(n.w) / (n.d)` with `w = o - center`, then
/// `|w + t d|^2 <= r^2` (textbook; Haines, "Essential Ray Tracing Algorithms", 1989). The offset
/// from the centre is formed by FMA from `w` (small near the disk) instead of subtracting two
/// large hit coordinates. Parallel rays miss.
#[inline]
pub fn intersect_disk_x8(k: &Disk, ray: &Ray8) -> f32x8 {
    let w = ray.o - Vec3x8::splat(k.center);
    let d = ray.d;
    let t = -w.dot3(k.normal) / d.dot3(k.normal);
    let pc = d.mul_add(t, w);
    let inside = pc.dot(pc).simd_le(f32x8::splat(k.radius * k.radius));
    finish_x8(t, inside, ray)
}

/// f64 twin of [`intersect_disk_x8`] (textbook: plane, then distance to the centre).
pub fn intersect_disk_f64(center: DVec3, normal: DVec3, radius: f64, o: DVec3, d: DVec3, tmax: f64) -> f64 {
    if !valid_f64(o, d, tmax) {
        return f64::INFINITY;
    }
    let den = normal.dot(d);
    if den == 0.0 {
        return f64::INFINITY;
    }
    let t = normal.dot(center - o) / den;
    let p = o + t * d;
    if (p - center).length_squared() <= radius * radius && t > 0.0 && t < tmax {
        t
    } else {
        f64::INFINITY
    }
}
