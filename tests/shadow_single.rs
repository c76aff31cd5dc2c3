//! Shadow rays one at a time through the wide BVH (`shadow::occlusion_single`, taken for the scattered
//! shading points of incoherent bounces) against the packet-group traversal it replaces
//! (`occlusion_group`): the same occluded lanes, bit for bit, on random scenes of spheres (static and
//! moving, leaves of more than 8 with one centroid), boxes, quads, disks and a floor plane, at scales
//! 1e-3 to 1e4, for rays from the open, from shapes' surfaces and from the floor, active and not.

use glam::Vec3;
use rand_core::Rng;
use std::path::Path;
use strata::accel::{Bvh8Stack, GROUP};
use strata::csg::CsgArena;
use strata::geometry::offset_ray_origin;
use strata::scene::{parse_scene, Profile, Scene};
use strata::simd::{f32x8, Ray8, Vec3x8};
use strata::wavefront::shadow::{occlusion_group, occlusion_single};

#[path = "common/rand.rs"]
mod common_rand;
use common_rand::Rand as R;

/// A random opaque scene at scale `k` with `n` shapes (`motion`: a shutter and some moving spheres).
fn scene(r: &mut R, k: f32, n: usize, motion: bool) -> Scene {
    let v = |p: Vec3| format!("[{:e}, {:e}, {:e}]", p.x * k, p.y * k, p.z * k);
    let mut t = format!(
        "[image]\nwidth = 8\nheight = 8\n[camera]\nposition = {}\nlook_at = [0, 0, 0]\nfov = 40\n{}\
         [materials.m]\ntype = \"lambert\"\nalbedo = [0.6, 0.6, 0.6]\n\
         [[lights]]\ntype = \"point\"\nposition = {}\nintensity = [1, 1, 1]\n\
         [[shapes]]\ntype = \"plane\"\npoint = {}\nnormal = [0, 1, 0]\nmaterial = \"m\"\n",
        v(Vec3::new(0.0, 3.0, 12.0)),
        if motion { "shutter = [0.0, 1.0]\n" } else { "" },
        v(Vec3::new(1.0, 9.0, -0.5)),
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
const CLUSTER: Vec3 = Vec3::ZERO;

/// A ray origin: in the open, on the floor, or on top of a shape's box (moved off along +y).
fn origin(r: &mut R, scene: &Scene, k: f32) -> Vec3 {
    match r.0.next_u32() % 3 {
        0 => Vec3::new(r.range(-7.0, 7.0), r.range(0.0, 5.0), r.range(-7.0, 7.0)) * k,
        1 => offset_ray_origin(Vec3::new(r.range(-8.0, 8.0), -0.01, r.range(-8.0, 8.0)) * k, Vec3::Y),
        _ => {
            let b = scene.bounds[1 + (r.0.next_u32() as usize) % (scene.bounds.len() - 1)];
            offset_ray_origin(Vec3::new(r.range(b.min.x, b.max.x), b.max.y, r.range(b.min.z, b.max.z)), Vec3::Y)
        }
    }
}

/// `GROUP` packets of rays from scattered origins to random targets (mostly above, like a light),
/// some lanes inactive (`tmax` -1), with times in motion scenes.
fn packets(r: &mut R, scene: &Scene, k: f32, motion: bool) -> (Vec<Ray8>, Vec<Option<f32x8>>) {
    let mut rays = Vec::new();
    let mut times = Vec::new();
    for _ in 0..GROUP {
        let lanes: [(Vec3, Vec3, f32); 8] = std::array::from_fn(|_| {
            let o = origin(r, scene, k);
            // A quarter of the rays pass through the cluster of one centroid (half way to the target).
            let target = if r.0.next_u32().is_multiple_of(4) {
                2.0 * (CLUSTER + r.vec(-0.5, 0.5)) * k - o
            } else {
                Vec3::new(r.range(-6.0, 6.0), r.range(-1.0, 10.0), r.range(-6.0, 6.0)) * k
            };
            let tmax = match r.0.next_u32() % 8 {
                0 => -1.0,
                1 => 1.0,
                _ => 1.0 - 1e-4,
            };
            (o, target - o, tmax)
        });
        let row = |f: &dyn Fn(&(Vec3, Vec3, f32)) -> f32| f32x8::from(lanes.map(|x| f(&x)));
        let o = Vec3x8::new(row(&|x| x.0.x), row(&|x| x.0.y), row(&|x| x.0.z));
        let d = Vec3x8::new(row(&|x| x.1.x), row(&|x| x.1.y), row(&|x| x.1.z));
        rays.push(Ray8::new(o, d, row(&|x| x.2)));
        times.push(motion.then(|| f32x8::from(std::array::from_fn::<f32, 8, _>(|_| r.f()))));
    }
    (rays, times)
}

#[test]
fn one_ray_at_a_time_occludes_the_lanes_the_group_traversal_does() {
    let mut r = R::new(0x0051_491e);
    let profile = Profile::builtin("final");
    let mut arena = CsgArena::new();
    let mut stack = Bvh8Stack::default();
    let (mut lanes, mut occluded) = (0u32, 0u32);
    for case in 0..24 {
        let k = [1e-3f32, 1.0, 37.0, 1e4][case % 4];
        let motion = case % 3 == 2;
        let n = [20, 150, 600][case % 3];
        let scene = scene(&mut r, k, n, motion);
        assert!(scene.leaf_spheres.window.iter().any(|&w| w != 0), "the scene has static spheres in its leaves");
        let largest = scene.bvh.nodes.iter().filter(|n| n.is_leaf()).map(|n| n.count()).max();
        assert!(largest > Some(8), "case {case}: a leaf of more than 8 prims (largest {largest:?})");
        for _ in 0..6 {
            let (rays, times) = packets(&mut r, &scene, k, motion);
            let single = occlusion_single(&scene, &profile, &rays, &times, &mut arena, &mut stack);
            let (group, _) = occlusion_group(&scene, &profile, &mut rays.clone(), &times, &mut arena, false);
            for j in 0..GROUP {
                let (a, b) = (single[j].to_bitmask(), group[j].to_bitmask());
                assert_eq!(a, b, "case {case} (scale {k}, {n} shapes, motion {motion}), packet {j}: one at a time {a:08b}, group {b:08b}");
                lanes += rays[j].tmax.simd_gt(f32x8::ZERO).to_bitmask().count_ones();
                occluded += a.count_ones();
            }
        }
    }
    // Both outcomes occur often (the comparison is not of all-clear or all-blocked packets).
    assert!(occluded > lanes / 10 && occluded < lanes * 9 / 10, "{occluded} of {lanes} active lanes occluded");
}
