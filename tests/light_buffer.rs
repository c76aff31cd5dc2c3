//! Shadow rays towards a point light answered from its light buffer (`accel/light_buffer.rs`,
//! `shadow::occlusion_light_buffer`) against the BVH group traversal (`occlusion_group`): the same
//! occluded lanes, bit for bit, on random scenes of static and moving spheres, boxes, quads, disks and
//! a floor plane at scales 1e-3 to 1e4, for origins in the open, on shapes and on the floor, including
//! origins far out on the floor that the buffer refuses; and whole renders with and without the
//! buffers give identical films (to the rounding of a path's sum where another light's samples are
//! added in a different order).

use glam::Vec3;
use rand_core::Rng;
use std::path::Path;
use strata::accel::GROUP;
use strata::csg::CsgArena;
use strata::film::Film;
use strata::render::{render_into, RenderJob};
use strata::scene::{parse_scene, Profile};
use strata::simd::{f32x8, Ray8, Vec3x8};
use strata::wavefront::queues::NONE;
use strata::wavefront::shadow::{occlusion_group, occlusion_light_buffer, occlusion_light_buffer_x16};
use strata::wavefront::Settings;

#[path = "common/rand.rs"]
mod common_rand;
use common_rand::Rand as R;
#[path = "common/shadow_scene.rs"]
mod shadow_scene;
use shadow_scene::{light, origin, scene};

#[test]
fn the_light_buffer_occludes_the_lanes_the_traversal_does() {
    let mut r = R::new(0x11b0_ffe5);
    let profile = Profile::builtin("final");
    let mut arena = CsgArena::new();
    let (mut lanes, mut occluded, mut refused, mut second_half) = (0u32, 0u32, 0u32, [0u32; 2]);
    for case in 0..24 {
        let k = [1e-3f32, 1.0, 37.0, 1e4][case % 4];
        let motion = case % 3 == 2;
        let n = [20, 150, 600][case % 3];
        let scene = scene(&mut r, k, n, motion);
        let lb = scene.light_buffers[0].as_ref().expect("a point light over bounded prims has a buffer");
        let target = light(k);
        for _ in 0..8 {
            let mut rays = Vec::new();
            let mut times = Vec::new();
            for _ in 0..GROUP {
                let lane: [(Vec3, f32); 8] = std::array::from_fn(|_| {
                    let o = match r.0.next_u32() % 16 {
                        // Far out on the floor: longer than the buffer answers.
                        0 => strata::geometry::offset_ray_origin(Vec3::new(r.range(1e4, 2e4), -0.01, r.range(-1e4, 1e4)) * k, Vec3::Y),
                        _ => origin(&mut r, &scene, k),
                    };
                    (o, if r.0.next_u32().is_multiple_of(8) { -1.0 } else { 1.0 })
                });
                let row = |f: &dyn Fn(&(Vec3, f32)) -> f32| f32x8::from(lane.map(|x| f(&x)));
                let o = Vec3x8::new(row(&|x| x.0.x), row(&|x| x.0.y), row(&|x| x.0.z));
                // As the shadow stage makes them: d = light - o, tmax = 1 (point lights).
                rays.push(Ray8::new(o, Vec3x8::splat(target) - o, row(&|x| x.1)));
                times.push(motion.then(|| f32x8::from(std::array::from_fn::<f32, 8, _>(|_| r.f()))));
            }
            let (group, _) = occlusion_group(&scene, &profile, &mut rays.clone(), &times, &mut arena, false);
            for j in 0..GROUP {
                let active = rays[j].tmax.simd_gt(f32x8::ZERO).to_bitmask();
                let (occ, answered) = occlusion_light_buffer(&scene, &profile, lb, &rays[j], active, &[NONE; 8], times[j], &mut arena);
                assert_eq!(answered & !active, 0, "only active lanes are answered");
                let want = group[j].to_bitmask() & answered;
                assert_eq!(
                    occ, want,
                    "case {case} (scale {k}, {n} shapes, motion {motion}), packet {j}: buffer {occ:08b}, traversal {want:08b}"
                );
                lanes += answered.count_ones();
                occluded += occ.count_ones();
                refused += (active & !answered).count_ones();
            }
            // Two packets as 16 lanes (as the shadow stage asks): each half the traversal's verdict
            // (the packet pairs of this loop: packet j with j + 1, and with itself).
            for (a, b) in (0..GROUP).map(|j| (j, (j + (j % 2 == 0) as usize) % GROUP)) {
                let bits = |j: usize| rays[j].tmax.simd_gt(f32x8::ZERO).to_bitmask();
                let active = bits(a) | bits(b) << 8;
                let time = times[a].map(|t| [t, times[b].unwrap()]);
                let (occ, answered) =
                    occlusion_light_buffer_x16(&scene, &profile, lb, &[rays[a], rays[b]], active, &[NONE; 16], time, &mut arena);
                assert_eq!(answered & !active, 0, "only active lanes are answered");
                let want = (group[a].to_bitmask() | group[b].to_bitmask() << 8) & answered;
                assert_eq!(occ, want, "case {case}, packets {a} and {b}: buffer {occ:016b}, traversal {want:016b}");
                second_half[0] += (answered >> 8).count_ones();
                second_half[1] += (occ >> 8).count_ones();
            }
        }
    }
    // The pairs' second packets were answered and occluded too (not only passed through).
    assert!(second_half[1] > second_half[0] / 10 && second_half[1] < second_half[0] * 9 / 10, "{second_half:?}");
    assert!(occluded > lanes / 10 && occluded < lanes * 9 / 10, "{occluded} of {lanes} answered lanes occluded");
    // Some far floor points are refused (and traced by the traversal), most lanes are answered.
    assert!(refused > 0 && refused < lanes / 10, "{refused} refused, {lanes} answered");
}

/// A scene with many spheres, a floor plane, a point light (which takes the buffer) and optionally a
/// quad light (which does not), rendered with direct lighting and with diffuse bounces (scattered
/// shading points).
fn render(buffers: bool, diffuse_depth: u32, quad: bool) -> Film {
    let mut text = String::from(
        "[image]\nwidth = 40\nheight = 30\n[camera]\nposition = [0, 4, 12]\nlook_at = [0, 0.5, 0]\nfov = 45\n\
         [materials.m]\ntype = \"lambert\"\nalbedo = [0.7, 0.6, 0.5]\n\
         [[lights]]\ntype = \"point\"\nposition = [3, 8, 2]\nintensity = [60, 60, 60]\n\
         [[shapes]]\ntype = \"plane\"\npoint = [0, 0, 0]\nnormal = [0, 1, 0]\nmaterial = \"m\"\n",
    );
    if quad {
        text += "[[lights]]\ntype = \"quad\"\norigin = [-2, 6, -1]\nu = [1, 0, 0]\nv = [0, 0, 1]\nradiance = [5, 5, 5]\n";
    }
    let mut r = R::new(7);
    for _ in 0..120 {
        let c = Vec3::new(r.range(-5.0, 5.0), r.range(0.2, 2.0), r.range(-5.0, 3.0));
        text += &format!(
            "[[shapes]]\ntype = \"sphere\"\ncenter = [{}, {}, {}]\nradius = {}\nmaterial = \"m\"\n",
            c.x,
            c.y,
            c.z,
            r.range(0.1, 0.5)
        );
    }
    let mut scene = parse_scene(Path::new("buffer.toml"), &text).unwrap();
    assert!(scene.light_buffers[0].is_some() && scene.light_buffers.iter().skip(1).all(Option::is_none));
    if !buffers {
        scene.light_buffers = vec![None; scene.lights.len()];
    }
    let mut profile = Profile::builtin("final");
    profile.spp = 4;
    profile.light_samples = 2;
    profile.diffuse_depth = diffuse_depth;
    let job = RenderJob::new(&scene, Settings { profile, seed: 3 });
    let (film, stats) = render_into(&job, Film::new(scene.width, scene.height));
    assert_eq!(stats.nonfinite_samples, 0);
    film
}

#[test]
fn renders_with_and_without_the_buffer_are_identical() {
    for depth in [0, 3] {
        let (a, b) = (render(true, depth, false), render(false, depth, false));
        assert!(a == b, "diffuse depth {depth}: the light buffer changed the image");
        // With a second light, the shadow stage adds a path's point-light and quad-light sums in
        // another order (the buffer's verdicts are credited apart from the batch's): rounding only.
        let (a, b) = (render(true, depth, true).to_rgb(), render(false, depth, true).to_rgb());
        let worst =
            a.iter().zip(&b).map(|(x, y)| ((*x - *y).abs() / (x.abs() + y.abs() + Vec3::splat(1e-6))).max_element()).fold(0.0, f32::max);
        assert!(worst < 1e-5, "diffuse depth {depth}, two lights: pixels differ by up to {worst} relative");
    }
}

/// What lets the buffer skip a lane's own sphere: for every shading point the pipeline records on a
/// static sphere seen from outside (`NeeQueue::own`), the shadow ray from its offset origin towards a
/// lit light position meets that sphere nowhere, by the kernel itself. Spheres at scales 1e-4 to 1e5,
/// some a thousand times their scene's size from the origin (the offset then spans many radii of a
/// small sphere), lights anywhere on the lit side, grazing ones included.
#[test]
fn own_spheres_never_occlude_their_shadow_rays() {
    use strata::geometry::intersect_sphere_x8;
    use strata::scene::Shape;
    use strata::wavefront::generate::{generate, Tile};
    use strata::wavefront::intersect::intersect;
    use strata::wavefront::shade::{shade, ShadeOut};
    use strata::wavefront::{CsgCandidates, HitQueue, NeeQueue, PathTable, RayQueue};
    let mut r = R::new(0x0e11_5e1f);
    let (mut checked, mut grazing) = (0u64, 0u64);
    for case in 0..12 {
        let k = [1e-4f32, 1.0, 1e3, 1e5][case % 4];
        let far = if case % 3 == 2 { 1e3 * k } else { 0.0 };
        let v = |p: Vec3| format!("[{:e}, {:e}, {:e}]", p.x * k + far, p.y * k, p.z * k);
        let mut text = format!(
            "[image]\nwidth = 24\nheight = 24\n[camera]\nposition = {}\nlook_at = {}\nfov = 50\n\
             [materials.m]\ntype = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\n\
             [[lights]]\ntype = \"point\"\nposition = {}\nintensity = [1, 1, 1]\n",
            v(Vec3::new(0.0, 2.0, 9.0)),
            v(Vec3::ZERO),
            v(Vec3::new(2.0, 6.0, 1.0))
        );
        for _ in 0..40 {
            let c = Vec3::new(r.range(-3.0, 3.0), r.range(-2.0, 2.0), r.range(-3.0, 2.0));
            text += &format!("[[shapes]]\ntype = \"sphere\"\ncenter = {}\nradius = {:e}\nmaterial = \"m\"\n", v(c), r.range(0.05, 0.8) * k);
        }
        let scene = parse_scene(Path::new("own.toml"), &text).unwrap();
        let profile = Profile::builtin("bench");
        let (mut paths, mut q) = (PathTable::default(), RayQueue::new(false, false));
        generate(&scene, &profile, 1, Tile { x0: 0, y0: 0, x1: 24, y1: 24 }, 0..4, &mut paths, &mut q);
        q.pad();
        let (mut hits, mut cands) = (HitQueue::default(), CsgCandidates::default());
        intersect(&scene, &q, &mut hits, &mut cands);
        let (mut next, mut nee, mut order) = (RayQueue::new(false, false), NeeQueue::default(), Vec::new());
        shade(&scene, &profile, 1, &q, &hits, &mut order, ShadeOut { paths: &mut paths, next: &mut next, nee: &mut nee });
        for i in 0..nee.len() {
            let own = nee.own[i];
            if own == NONE {
                continue;
            }
            let Shape::Sphere { center, radius } = scene.prims[own as usize].shape else { panic!("own is a sphere") };
            let (p, o, n) = (
                Vec3::new(nee.px[i], nee.py[i], nee.pz[i]),
                Vec3::new(nee.ox[i], nee.oy[i], nee.oz[i]),
                Vec3::new(nee.nx[i], nee.ny[i], nee.nz[i]),
            );
            // Lights on the lit side as the shadow stage decides it (n . (y - p) > 0), down to grazing.
            for j in 0..16 {
                let t = n.any_orthonormal_vector();
                let up = [1.0, 0.3, 1e-2, 1e-4][j % 4];
                let y = p + (n * up + t * r.range(-1.0, 1.0) + n.cross(t) * r.range(-1.0, 1.0)) * (r.range(0.5, 20.0) * k);
                if n.dot(y - p) <= 0.0 {
                    continue;
                }
                let ray = Ray8::new(Vec3x8::splat(o), Vec3x8::splat(y - o), f32x8::splat(1.0));
                let t_hit = intersect_sphere_x8(center, radius, &ray).to_array()[0];
                assert!(
                    t_hit.is_nan() || t_hit >= 1.0,
                    "case {case}: the shadow ray from {o} (on sphere {own}) to {y} meets its own sphere at t = {t_hit}"
                );
                checked += 1;
                grazing += (up < 1e-3) as u64;
            }
        }
    }
    assert!(checked > 20_000 && grazing > 2_000, "{checked} rays checked ({grazing} grazing)");
}

/// One huge prim (a ground sphere of radius 1e6 under 300 small ones) leaves the buffer useful: the
/// longest ray it answers follows the 99th percentile of the prims' reach, not the huge one's, so its
/// rounding allowance stays small and the small spheres keep their cells (before: every prim on the
/// list tested for every ray, 24 us per shadow ray in a user trial). Its verdicts still equal the
/// traversal's, for origins in the open, on the small spheres and on the huge one near and far (far
/// ones refused: longer than the buffer answers).
#[test]
fn a_huge_prim_keeps_the_buffer_useful_and_exact() {
    let mut r = R::new(0x46e_5eed);
    let mut t = String::from(
        "[image]\nwidth = 8\nheight = 8\n[camera]\nposition = [0, 3, 12]\nlook_at = [0, 0, 0]\nfov = 40\n\
         [materials.m]\ntype = \"lambert\"\nalbedo = [0.6, 0.6, 0.6]\n\
         [[lights]]\ntype = \"point\"\nposition = [2, 8, 1]\nintensity = [1, 1, 1]\n\
         [[shapes]]\ntype = \"sphere\"\ncenter = [0, -1e6, 0]\nradius = 1e6\nmaterial = \"m\"\n",
    );
    for _ in 0..300 {
        let (p, s) = (Vec3::new(r.range(-6.0, 6.0), r.range(0.3, 4.0), r.range(-6.0, 6.0)), r.range(0.05, 0.3));
        t += &format!("[[shapes]]\ntype = \"sphere\"\ncenter = [{}, {}, {}]\nradius = {s}\nmaterial = \"m\"\n", p.x, p.y, p.z);
    }
    let scene = parse_scene(Path::new("huge.toml"), &t).unwrap();
    let lb = scene.light_buffers[0].as_ref().expect("the point light keeps its buffer");
    assert!(lb.always().len() <= 1 && lb.mean_list() < 8.0, "always {}, mean list {}", lb.always().len(), lb.mean_list());
    let profile = Profile::builtin("final");
    let mut arena = CsgArena::new();
    let target = Vec3::new(2.0, 8.0, 1.0);
    let on_ground = |x: f32, z: f32| {
        let (x, z) = (x as f64, z as f64);
        let y = (1e12 - x * x - z * z).sqrt() - 1e6;
        strata::geometry::offset_ray_origin(
            Vec3::new(x as f32, y as f32, z as f32),
            Vec3::new(x as f32, (y + 1e6) as f32, z as f32).normalize(),
        )
    };
    let (mut answered_lanes, mut occluded, mut refused) = (0u32, 0u32, 0u32);
    for _ in 0..16 {
        let rays: Vec<Ray8> = (0..GROUP)
            .map(|_| {
                let o: [Vec3; 8] = std::array::from_fn(|_| match r.0.next_u32() % 4 {
                    0 => Vec3::new(r.range(-7.0, 7.0), r.range(0.0, 5.0), r.range(-7.0, 7.0)),
                    1 => on_ground(r.range(-8.0, 8.0), r.range(-8.0, 8.0)),
                    2 => on_ground(r.range(1e3, 9e4), r.range(-1e3, 1e3)),
                    _ => {
                        let b = scene.bounds[1 + (r.0.next_u32() as usize) % (scene.bounds.len() - 1)];
                        strata::geometry::offset_ray_origin(
                            Vec3::new(r.range(b.min.x, b.max.x), b.max.y, r.range(b.min.z, b.max.z)),
                            Vec3::Y,
                        )
                    }
                });
                let o = Vec3x8::new(f32x8::from(o.map(|v| v.x)), f32x8::from(o.map(|v| v.y)), f32x8::from(o.map(|v| v.z)));
                Ray8::new(o, Vec3x8::splat(target) - o, f32x8::ONE)
            })
            .collect();
        let (group, _) = occlusion_group(&scene, &profile, &mut rays.clone(), &[None; GROUP], &mut arena, false);
        for j in 0..GROUP {
            let (occ, answered) = occlusion_light_buffer(&scene, &profile, lb, &rays[j], 0xff, &[NONE; 8], None, &mut arena);
            assert_eq!(occ, group[j].to_bitmask() & answered, "packet {j}");
            answered_lanes += answered.count_ones();
            occluded += occ.count_ones();
            refused += 8 - answered.count_ones();
        }
    }
    assert!(occluded > answered_lanes / 20 && occluded < answered_lanes * 9 / 10, "{occluded} of {answered_lanes} occluded");
    assert!(refused > 0 && refused < answered_lanes / 2, "{refused} refused, {answered_lanes} answered");
}
