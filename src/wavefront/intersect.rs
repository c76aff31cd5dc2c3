//! Stage 2: nearest hits of a ray queue, 8 rays per packet: BVH packet traversal with the SIMD primitive
//! kernels at the leaves, then the unbounded planes. CSG solids are not solved here: a packet that reaches
//! a solid's bounds records (ray, solid) candidates for `csg_merge`.

use super::queues::{CsgCandidates, HitQueue, RayQueue, NONE};
use crate::accel::{intersect_aabb_x8, PacketRay};
use crate::geometry::{
    intersect_disk_f64, intersect_disk_x8, intersect_ellipsoid_f64, intersect_ellipsoid_x8, intersect_obox_f64, intersect_obox_x8,
    intersect_plane_f64, intersect_plane_x8, intersect_quad_f64, intersect_quad_x8, intersect_sphere_f64, intersect_sphere_x8, MISS,
};
use crate::scene::{Prim, Scene, Shape};
use crate::simd::{f32x8, load8, Ray8, Vec3x8, LANES};
use glam::{DVec3, Vec3};

/// Distance to a (non-CSG) primitive for 8 rays; MISS where there is none.
#[inline(always)]
pub fn prim_t_x8(prim: &Prim, ray: &Ray8) -> f32x8 {
    match &prim.shape {
        Shape::Sphere { center, radius } => intersect_sphere_x8(*center, *radius, ray),
        Shape::Ellipsoid(e) => intersect_ellipsoid_x8(e, ray),
        Shape::Plane(p) => intersect_plane_x8(p, ray),
        Shape::Quad(q) => intersect_quad_x8(q, ray),
        Shape::Disk(d) => intersect_disk_x8(d, ray),
        Shape::Box(b) => intersect_obox_x8(b, ray),
        Shape::Csg { .. } => f32x8::splat(MISS),
    }
}

/// Scalar f64 twin of [`prim_t_x8`] (the reference path of tests and benchmark validation).
pub fn prim_t_f64(prim: &Prim, o: DVec3, d: DVec3, tmax: f64) -> f64 {
    match &prim.shape {
        Shape::Sphere { center, radius } => intersect_sphere_f64(center.as_dvec3(), *radius as f64, o, d, tmax),
        Shape::Ellipsoid(e) => intersect_ellipsoid_f64(e.world_to_object_f64(), o, d, tmax),
        Shape::Plane(p) => intersect_plane_f64(p.normal.as_dvec3(), p.offset as f64, o, d, tmax),
        Shape::Quad(q) => intersect_quad_f64(q.origin.as_dvec3(), q.u.as_dvec3(), q.v.as_dvec3(), o, d, tmax),
        Shape::Disk(k) => intersect_disk_f64(k.center.as_dvec3(), k.normal.as_dvec3(), k.radius as f64, o, d, tmax),
        Shape::Box(b) => intersect_obox_f64(b.world_to_object_f64(), b.half.as_dvec3(), o, d, tmax),
        Shape::Csg { .. } => f64::INFINITY,
    }
}

/// The packet in the frame of a moving primitive: origin moved by -motion * time (translation motion).
#[inline(always)]
pub fn in_prim_frame(ray: &Ray8, motion: Vec3, time: Option<f32x8>) -> Ray8 {
    match time {
        Some(t) if motion != Vec3::ZERO => Ray8 { o: Vec3x8::splat(-motion).mul_add(t, ray.o), ..*ray },
        _ => *ray,
    }
}

/// [`prim_t_x8`] at the packet's shutter times: only moving prims pay for a packet in their own frame
/// (static prims test the packet in place, no copy).
#[inline(always)]
pub fn prim_t_at_x8(prim: &Prim, ray: &Ray8, time: Option<f32x8>) -> f32x8 {
    match time {
        Some(_) if prim.motion != Vec3::ZERO => prim_t_x8(prim, &in_prim_frame(ray, prim.motion, time)),
        _ => prim_t_x8(prim, ray),
    }
}

/// Load packet `i` (rays i..i+8) of a padded queue.
#[inline(always)]
pub fn load_packet(rays: &RayQueue, i: usize) -> (Ray8, Option<f32x8>) {
    let o = Vec3x8::load(&rays.ox, &rays.oy, &rays.oz, i);
    let d = Vec3x8::load(&rays.dx, &rays.dy, &rays.dz, i);
    let time = rays.with_time.then(|| load8(&rays.time, i));
    (Ray8::new(o, d, load8(&rays.tmax, i)), time)
}

/// Record hits of `t` on the lanes where it is nearer than the current best. Equal distances go to the
/// lower primitive id, so the result does not depend on traversal order (packet composition).
#[inline(always)]
fn record(ray: &mut Ray8, ids: &mut [u32; LANES], t: f32x8, prim: u32) {
    let le = t.simd_le(ray.tmax);
    let mut bits = le.to_bitmask();
    if bits == 0 {
        return;
    }
    let (ta, tm) = (t.to_array(), ray.tmax.to_array());
    let mut new_tmax = tm;
    while bits != 0 {
        let l = bits.trailing_zeros() as usize;
        bits &= bits - 1;
        if ta[l] < tm[l] || (ta[l] != MISS && prim < ids[l]) {
            new_tmax[l] = ta[l];
            ids[l] = prim;
        }
    }
    ray.tmax = f32x8::from(new_tmax);
}

pub fn intersect(scene: &Scene, rays: &RayQueue, hits: &mut HitQueue, cands: &mut CsgCandidates) {
    let n = rays.padded_len();
    hits.reset(n);
    cands.clear();
    for base in (0..n).step_by(LANES) {
        let (mut ray, time) = load_packet(rays, base);
        let mut ids = [NONE; LANES];
        scene.bvh.traverse_closest_x8(&mut ray, |bi, ray| {
            let pid = scene.bounded[bi as usize];
            let prim = &scene.prims[pid as usize];
            if let Shape::Csg { .. } = prim.shape {
                let b = &scene.bounds[pid as usize];
                // The swept bounds already cover the motion: test the world-space packet.
                let (_, mask) = intersect_aabb_x8(b.min, b.max, &PacketRay::new(ray), ray.tmax);
                let mut bits = mask.to_bitmask();
                while bits != 0 {
                    let l = bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    cands.ray.push((base + l) as u32);
                    cands.prim.push(pid);
                }
                return;
            }
            record(ray, &mut ids, prim_t_at_x8(prim, ray, time), pid);
        });
        for &pid in &scene.unbounded {
            let t = prim_t_x8(&scene.prims[pid as usize], &ray);
            record(&mut ray, &mut ids, t, pid);
        }
        let ta = ray.tmax.to_array();
        for l in 0..LANES {
            if ids[l] != NONE {
                hits.t[base + l] = ta[l];
                hits.prim[base + l] = ids[l];
            }
        }
    }
}
