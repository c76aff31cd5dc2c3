//! Shadow rays one at a time through the wide BVH (`shadow::occlusion_single`, taken for the scattered
//! shading points of incoherent bounces) against the packet-group traversal it replaces
//! (`occlusion_group`): the same occluded lanes, bit for bit, on random scenes of spheres (static and
//! moving, leaves of more than 8 with one centroid), boxes, quads, disks and a floor plane, at scales
//! 1e-3 to 1e4, for rays from the open, from shapes' surfaces and from the floor, active and not.

use glam::Vec3;
use rand_core::Rng;
use strata::accel::{WideStack, GROUP};
use strata::csg::CsgArena;
use strata::scene::{Profile, Scene};
use strata::simd::{f32x8, Ray8, Vec3x8};
use strata::wavefront::shadow::{occlusion_group, occlusion_single};

#[path = "common/rand.rs"]
mod common_rand;
use common_rand::Rand as R;
#[path = "common/shadow_scene.rs"]
mod shadow_scene;
use shadow_scene::{origin, scene, CLUSTER};

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
    let mut stack = WideStack::default();
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
