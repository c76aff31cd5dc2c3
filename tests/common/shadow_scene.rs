//! A random opaque scene of spheres (static and moving, a leaf of more than 8 prims with one
//! centroid), boxes, quads, disks and a floor plane under a point light, and ray origins in it: the
//! shadow-ray tests of `shadow_single.rs` and `light_buffer.rs` share them.

use glam::Vec3;
use rand_core::Rng;
use std::path::Path;
use strata::geometry::offset_ray_origin;
use strata::scene::{parse_scene, Scene};

use super::common_rand::Rand as R;

/// A random opaque scene at scale `k` with `n` shapes (`motion`: a shutter and some moving spheres).
pub fn scene(r: &mut R, k: f32, n: usize, motion: bool) -> Scene {
    let v = |p: Vec3| format!("[{:e}, {:e}, {:e}]", p.x * k, p.y * k, p.z * k);
    let mut t = format!(
        "[image]\nwidth = 8\nheight = 8\n[camera]\nposition = {}\nlook_at = [0, 0, 0]\nfov = 40\n{}\
         [materials.m]\ntype = \"lambert\"\nalbedo = [0.6, 0.6, 0.6]\n\
         [[lights]]\ntype = \"point\"\nposition = {}\nintensity = [1, 1, 1]\n\
         [[shapes]]\ntype = \"plane\"\npoint = {}\nnormal = [0, 1, 0]\nmaterial = \"m\"\n",
        v(Vec3::new(0.0, 3.0, 12.0)),
        if motion { "shutter = [0.0, 1.0]\n" } else { "" },
        v(light(1.0)),
        v(Vec3::new(0.0, -0.01, 0.0)),
    );
    // Four spheres and twelve disks of one centre (one leaf of more than 8 prims: their centroids
    // cannot be split); the disks face different ways, so each blocks rays the others let through.
    let c = CLUSTER;
    for i in 0..16 {
        t += &if i < 4 {
            format!("[[shapes]]\ntype = \"sphere\"\ncenter = {}\nradius = {:e}\nmaterial = \"m\"\n", v(c), (0.05 + 0.04 * i as f32) * k)
        } else {
            let n = r.vec(-1.0, 1.0) + Vec3::new(0.0, 0.0, 1e-3);
            format!(
                "[[shapes]]\ntype = \"disk\"\ncenter = {}\nnormal = [{}, {}, {}]\nradius = {:e}\nmaterial = \"m\"\n",
                v(c),
                n.x,
                n.y,
                n.z,
                r.range(0.3, 1.2) * k
            )
        };
    }
    for i in 0..n {
        let (p, s) = (Vec3::new(r.range(-6.0, 6.0), r.range(0.0, 4.0), r.range(-6.0, 6.0)), r.range(0.05, 0.8));
        t += &match i % 8 {
            0..=4 => {
                let mv = if motion && i % 3 == 0 { format!("motion = {}\n", v(r.vec(-0.5, 0.5))) } else { String::new() };
                format!("[[shapes]]\ntype = \"sphere\"\ncenter = {}\nradius = {:e}\nmaterial = \"m\"\n{mv}", v(p), s * k)
            }
            5 => format!("[[shapes]]\ntype = \"box\"\nmin = {}\nmax = {}\nmaterial = \"m\"\n", v(p - s), v(p + s)),
            6 => format!(
                "[[shapes]]\ntype = \"quad\"\norigin = {}\nu = {}\nv = {}\nmaterial = \"m\"\n",
                v(p),
                v(Vec3::new(s, 0.0, 0.1)),
                v(Vec3::new(0.0, s, s))
            ),
            _ => {
                format!("[[shapes]]\ntype = \"disk\"\ncenter = {}\nnormal = [0.3, 1, 0.2]\nradius = {:e}\nmaterial = \"m\"\n", v(p), s * k)
            }
        };
    }
    parse_scene(Path::new("single.toml"), &t).unwrap()
}

/// The centre of the scene's cluster of 16 prims: the origin, so that every one of their boxes is
/// `-h..h` and their centroids are 0 exactly at every scale.
pub const CLUSTER: Vec3 = Vec3::ZERO;

/// A ray origin: in the open, on the floor, or on top of a shape's box (moved off along +y).
pub fn origin(r: &mut R, scene: &Scene, k: f32) -> Vec3 {
    match r.0.next_u32() % 3 {
        0 => Vec3::new(r.range(-7.0, 7.0), r.range(0.0, 5.0), r.range(-7.0, 7.0)) * k,
        1 => offset_ray_origin(Vec3::new(r.range(-8.0, 8.0), -0.01, r.range(-8.0, 8.0)) * k, Vec3::Y),
        _ => {
            let b = scene.bounds[1 + (r.0.next_u32() as usize) % (scene.bounds.len() - 1)];
            offset_ray_origin(Vec3::new(r.range(b.min.x, b.max.x), b.max.y, r.range(b.min.z, b.max.z)), Vec3::Y)
        }
    }
}

/// The position of the scene's point light.
pub fn light(k: f32) -> Vec3 {
    Vec3::new(1.0, 9.0, -0.5) * k
}
