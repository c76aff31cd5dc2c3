//! The light-cone test (`wavefront/cone.rs`) against the any-hit traversal it stands in for: every lane
//! it declares clear has, for every target on the light, a shadow ray that the traversal finds neither
//! occluded nor touching a surface to walk through. Random scenes (spheres, boxes, CSG, glass the rays
//! walk through, a floor plane) under quad, disk and point lights, at scales 1e-3 to 1e4, with origins
//! in the open, on the floor and on the shapes' surfaces (moved off as the shading stage does).

use glam::Vec3;
use rand_core::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use std::path::Path;
use strata::csg::CsgArena;
use strata::geometry::offset_ray_origin;
use strata::scene::{parse_scene, Light, Profile, Scene};
use strata::simd::{f32x8, Ray8, Vec3x8, LANES};
use strata::wavefront::cone::{LightCone, Verdict};
use strata::wavefront::shadow::occlusion_x8;

struct R(Xoshiro256PlusPlus);

impl R {
    fn f(&mut self) -> f32 {
        (self.0.next_u32() >> 8) as f32 / (1u32 << 24) as f32
    }
    fn range(&mut self, a: f32, b: f32) -> f32 {
        a + (b - a) * self.f()
    }
}

/// A random scene at scale `k`: a floor, spheres and boxes of diffuse, glass and absorbing glass
/// material, a CSG part, and one light of kind `light`.
fn scene(r: &mut R, k: f32, light: usize) -> String {
    let v = |x: f32, y: f32, z: f32| format!("[{}, {}, {}]", x * k, y * k, z * k);
    let mut t = format!(
        "[image]\nwidth = 8\nheight = 8\n[camera]\nposition = {}\nlook_at = {}\nfov = 40\n\
         [materials.m]\ntype = \"lambert\"\nalbedo = [0.6, 0.6, 0.6]\n\
         [materials.g]\ntype = \"dielectric\"\nior = 1.5\n\
         [materials.a]\ntype = \"dielectric\"\nior = 1.5\nabsorption = [0.3, 0.1, 0.05]\n\
         [[shapes]]\ntype = \"plane\"\npoint = {}\nnormal = [0, 1, 0]\nmaterial = \"m\"\n",
        v(0.0, 3.0, 9.0),
        v(0.0, 0.0, 0.0),
        v(0.0, -0.001, 0.0)
    );
    for i in 0..6 {
        let (x, z) = (r.range(-4.0, 4.0), r.range(-4.0, 4.0));
        let s = r.range(0.2, 0.9);
        // Clear glass, and absorbing glass of the same index (so that both are passable: shadow rays
        // may meet index-matched interfaces, and walk even without `transmissive_shadows`).
        let m = match i {
            0 | 3 => "g",
            2 => "a",
            _ => "m",
        };
        t += &if i % 2 == 0 {
            format!("[[shapes]]\ntype = \"sphere\"\ncenter = {}\nradius = {}\nmaterial = \"{m}\"\n", v(x, s, z), s * k)
        } else {
            format!("[[shapes]]\ntype = \"box\"\nmin = {}\nmax = {}\nmaterial = \"{m}\"\n", v(x - s, 0.0, z - s), v(x + s, 2.0 * s, z + s))
        };
    }
    let (x, z) = (r.range(-3.0, 3.0), r.range(-3.0, 3.0));
    t += &format!(
        "[[shapes]]\ntype = \"csg\"\nop = \"difference\"\nmaterial = \"m\"\nchildren = [\n\
         {{ type = \"box\", min = {}, max = {} }},\n{{ type = \"sphere\", center = {}, radius = {} }},\n]\n",
        v(x - 0.7, 0.0, z - 0.7),
        v(x + 0.7, 1.4, z + 0.7),
        v(x, 1.4, z),
        0.6 * k
    );
    let h = r.range(3.0, 6.0);
    t += &match light {
        0 => format!(
            "[[lights]]\ntype = \"quad\"\norigin = {}\nu = {}\nv = {}\nradiance = [5, 5, 5]\n",
            v(-1.5, h, -1.0),
            v(3.0, 0.0, 0.0),
            v(0.0, 0.0, 2.0)
        ),
        1 => format!(
            "[[lights]]\ntype = \"disk\"\ncenter = {}\nnormal = [0.2, -1, 0.1]\nradius = {}\nradiance = [5, 5, 5]\n",
            v(0.5, h, 0.0),
            k
        ),
        _ => format!("[[lights]]\ntype = \"point\"\nposition = {}\nintensity = [5, 5, 5]\n", v(1.0, h, -0.5)),
    };
    t
}

/// Points on the light (random, its corners and edges) and the ray's end fraction.
fn targets(r: &mut R, light: &Light) -> (Vec<Vec3>, f32) {
    let mut out = Vec::new();
    match *light {
        Light::Quad { quad, .. } => {
            for (a, b) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0), (0.5, 0.0), (0.0, 0.5)] {
                out.push(quad.origin + quad.u * a + quad.v * b);
            }
            for _ in 0..58 {
                let (a, b) = (r.f(), r.f());
                out.push(quad.origin + quad.u * a + quad.v * b);
            }
            (out.into_iter().map(|y| offset_ray_origin(y, quad.normal())).collect(), 1.0 - 1e-4)
        }
        Light::Disk { disk, .. } => {
            let (t, s) = strata::optics::onb(disk.normal);
            for i in 0..64 {
                let a = i as f32 / 64.0 * std::f32::consts::TAU;
                let rr = if i % 4 == 0 { 1.0 } else { r.f().sqrt() };
                out.push(disk.center + (t * a.cos() + s * a.sin()) * disk.radius * rr);
            }
            (out.into_iter().map(|y| offset_ray_origin(y, disk.normal)).collect(), 1.0 - 1e-4)
        }
        Light::Point { position, .. } => (vec![position], 1.0),
        Light::Sphere { .. } => unreachable!(),
    }
}

/// Origins: in the open, on the floor, on a shape's top (moved off the surface along +y).
fn origin(r: &mut R, scene: &Scene, k: f32) -> Vec3 {
    match r.0.next_u32() % 3 {
        0 => Vec3::new(r.range(-6.0, 6.0), r.range(0.0, 3.0), r.range(-6.0, 6.0)) * k,
        1 => offset_ray_origin(Vec3::new(r.range(-8.0, 8.0), -0.001, r.range(-8.0, 8.0)) * k, Vec3::Y),
        _ => {
            let b = scene.bounds[(r.0.next_u32() as usize) % scene.bounds.len()];
            let p = Vec3::new(r.range(b.min.x, b.max.x), b.max.y, r.range(b.min.z, b.max.z));
            offset_ray_origin(p, Vec3::Y)
        }
    }
}

/// One random chunk: its scene (case `case`, scale `k`), light, 8 origins (also as rows) and the cone
/// test's verdict on them.
struct Chunk<'a> {
    case: usize,
    k: f32,
    scene: &'a Scene,
    light: Light,
    os: [Vec3; LANES],
    o: Vec3x8,
    v: Verdict,
}

/// `per_case` random chunks in each of `cases` random scenes (cycling through the scales and the three
/// light kinds), handed to `f` with the random source.
fn chunks(seed: u64, cases: usize, per_case: usize, mut f: impl FnMut(&Chunk, &mut R)) {
    let mut r = R(Xoshiro256PlusPlus::seed_from_u64(seed));
    for case in 0..cases {
        let k = [1e-3f32, 1.0, 37.0, 1e4][case % 4];
        let text = scene(&mut r, k, case % 3);
        let scene = parse_scene(Path::new("cone.toml"), &text).unwrap();
        let light = scene.lights[0];
        let cone = LightCone::new(&scene, &light).expect("the test applies to quad, disk and point lights");
        // The shadow stage's tables look for the light's prim at a guess first: any guess (the
        // right prim, another, or past the end) gives the same cone.
        let guess = [scene.prims.len() - 1, 0, scene.prims.len(), usize::MAX][case % 4];
        let near = LightCone::new_near(&scene, &light, guess).expect("as `new`");
        for _ in 0..per_case {
            let os: [Vec3; LANES] = std::array::from_fn(|_| origin(&mut r, &scene, k));
            let o = Vec3x8::from_rows(&std::array::from_fn(|a| std::array::from_fn(|l| os[l][a])));
            let v = cone.verdict(&scene, o, 0xff);
            let w = near.verdict(&scene, o, 0xff);
            assert_eq!((v.clear, v.single, v.prim), (w.clear, w.single, w.prim), "case {case}: guess {guess}");
            f(&Chunk { case, k, scene: &scene, light, os, o, v }, &mut r);
        }
    }
}

/// A shadow ray from `o` to each of `ts` (lanes past the end repeat the first targets).
fn rays_to(o: Vec3, ts: &[Vec3], end: f32) -> impl Iterator<Item = Ray8> + '_ {
    ts.chunks(LANES).map(move |c| {
        let d = Vec3x8::from_rows(&std::array::from_fn(|a| std::array::from_fn(|i| c[i % c.len()][a] - o[a])));
        Ray8::new(Vec3x8::splat(o), d, f32x8::splat(end))
    })
}

#[test]
fn lanes_the_cone_test_clears_are_clear_for_every_target() {
    let mut profile = Profile::builtin("bench");
    profile.transmissive_shadows = true; // glass is walked through: a touched lane would show
    let mut arena = CsgArena::new();
    let (mut cleared, mut lanes_tested) = (0usize, 0usize);
    chunks(0xc0_7e5, 120, 6, |ch, r| {
        lanes_tested += LANES;
        let (ts, end) = targets(r, &ch.light);
        for l in (0..LANES).filter(|&l| ch.v.clear & (1 << l) != 0) {
            cleared += 1;
            for ray in rays_to(ch.os[l], &ts, end) {
                let (occ, touched) = occlusion_x8(ch.scene, &profile, &ray, None, &mut arena, true);
                assert!(
                    occ.to_bitmask() == 0 && touched == 0,
                    "case {} (scale {}): lane {l} from {:?} cleared, but a ray is occluded or touches glass",
                    ch.case,
                    ch.k,
                    ch.os[l]
                );
            }
        }
    });
    // Neither vacuous nor trivial: the test clears a share of the lanes and keeps the rest.
    assert!(cleared > lanes_tested / 10 && cleared < lanes_tested * 9 / 10, "{cleared} of {lanes_tested} lanes cleared");
}

/// Lanes whose origin sits right on the floor plane's far side, or under the light's plane, or whose
/// rays graze the floor, are never cleared wrongly; a lane with a NaN origin is never cleared.
#[test]
fn degenerate_origins_are_not_cleared() {
    let mut r = R(Xoshiro256PlusPlus::seed_from_u64(7));
    let text = scene(&mut r, 1.0, 0);
    let scene = parse_scene(Path::new("cone.toml"), &text).unwrap();
    let cone = LightCone::new(&scene, &scene.lights[0]).unwrap();
    let os = [
        Vec3::new(20.0, -0.001, 20.0), // exactly on the floor (the kernel's t = 0: fine either way)
        Vec3::new(20.0, -0.5, 20.0),   // below the floor: every ray crosses it
        Vec3::new(0.0, 7.0, 0.0),      // above the light (behind it): its own prim is in the way
        Vec3::new(f32::NAN, 1.0, 1.0), // NaN
        Vec3::new(1e3, 1e-3, 0.0),     // far along the floor, rays grazing it
        Vec3::new(0.0, 1e-2, 1e3),
        Vec3::new(20.0, 0.5, 20.0), // in the open, far from the shapes: clear
        Vec3::new(-20.0, 0.5, -20.0),
    ];
    let o = Vec3x8::from_rows(&std::array::from_fn(|a| std::array::from_fn(|l| os[l][a])));
    let clear = cone.verdict(&scene, o, 0xff).clear;
    assert_eq!(clear & 0b0000_1110, 0, "lanes below the floor, above the light or NaN cleared: {clear:08b}");
    assert_eq!(clear & 0b1100_0000, 0b1100_0000, "open lanes not cleared: {clear:08b}");
}

/// Lanes whose cones meet one glass sphere only: `single_sphere_x8` gives, bit for bit, what the any-hit
/// traversal and the walk through glass give their rays (unoccluded; transmittance 1 where a ray misses
/// the sphere, the pair's Fresnel product, with absorption for the absorbing glass, where it enters and
/// leaves it), for every target on the light, called with all the lanes its spheres were gathered for
/// and with random subsets of them (as the shadow stage calls it, with the lanes a sample lights);
/// rays that cross the sphere once are left to the traversal. Without `transmissive_shadows` the
/// spheres are still walked (index-matched glasses are passable) and their real interfaces block.
#[test]
fn single_sphere_lanes_match_the_traversal_and_the_walk() {
    use strata::wavefront::transmit::{pair_sphere, single_sphere_x8, transmittance_x8, SingleSpheres, Walk};
    for transmissive in [true, false] {
        let mut profile = Profile::builtin("bench");
        profile.transmissive_shadows = transmissive;
        let mut arena = CsgArena::new();
        let mut walk = Walk::new();
        let (mut crossed, mut missed, mut absorbed, mut subsets) = (0usize, 0usize, 0usize, 0usize);
        chunks(0x5_9e7e, 240, 8, |ch, r| {
            let (scene, v, o) = (ch.scene, &ch.v, ch.o);
            assert_eq!(v.clear & v.single, 0);
            let lanes =
                (0..LANES).filter(|&l| v.single & (1 << l) != 0 && pair_sphere(scene, &profile, v.prim[l])).fold(0u32, |m, l| m | 1 << l);
            if lanes == 0 {
                return;
            }
            let (ts, end) = targets(r, &ch.light);
            let spheres = SingleSpheres::new(scene, &profile, &v.prim, lanes);
            for &t in &ts {
                let d = Vec3x8::from_rows(&std::array::from_fn(|a| std::array::from_fn(|l| t[a] - ch.os[l][a])));
                // Every other target with a random subset of the lanes.
                let sub = if r.0.next_u32() % 2 == 0 { lanes } else { lanes & r.0.next_u32() };
                subsets += (sub != lanes) as usize;
                let tmax = f32x8::from(std::array::from_fn(|l| if sub & (1 << l) != 0 { end } else { -1.0 }));
                let ray = Ray8::new(o, d, tmax);
                let (done, tr) = single_sphere_x8(scene, &spheres, &ray, sub);
                assert_eq!(done & !sub, 0, "case {}: lanes outside the call answered", ch.case);
                let tr: [Vec3; LANES] = std::array::from_fn(|l| tr.lane(l));
                let (occ, touched) = occlusion_x8(scene, &profile, &ray, None, &mut arena, true);
                assert_eq!(occ.to_bitmask() & done, 0, "case {}: a single-sphere lane is occluded", ch.case);
                let rows = |v: Vec3x8| [v.x.to_array(), v.y.to_array(), v.z.to_array()];
                let (walked, _) = transmittance_x8(
                    scene,
                    &profile,
                    &rows(o),
                    &rows(d),
                    &tmax.to_array(),
                    &[0.0; LANES],
                    &[strata::wavefront::MediumStack::default(); LANES],
                    touched & done,
                    &mut arena,
                    &mut walk,
                );
                for l in (0..LANES).filter(|&l| done & (1 << l) != 0) {
                    let want = if touched & (1 << l) != 0 { walked[l] } else { Vec3::ONE };
                    assert_eq!(tr[l].to_array().map(f32::to_bits), want.to_array().map(f32::to_bits), "case {} lane {l}", ch.case);
                    if touched & (1 << l) != 0 {
                        crossed += 1;
                        absorbed += (want != Vec3::ZERO && want.x != want.z) as usize;
                        // (Absorbing glass at the largest scales lets nothing through either.)
                        assert!(transmissive || want == Vec3::ZERO, "case {} lane {l}: {want:?} through a real interface", ch.case);
                    } else {
                        missed += 1;
                    }
                }
            }
        });
        eprintln!("transmissive {transmissive}: {crossed} through, {missed} past, {absorbed} absorbed, {subsets} subsets");
        assert!(crossed > 200 && missed > 200 && subsets > 200, "{crossed} rays through a sphere, {missed} past it, {subsets} subsets");
        assert!(!transmissive || absorbed > 50, "{absorbed} rays through absorbing glass");
    }
}

/// Lanes whose cones meet one opaque prim only (a sphere, a box, the CSG part, the light's own quad seen
/// from behind): the any-hit test of that prim alone (`shadow::prim_occlusion`) decides every ray as
/// the traversal of the whole scene does.
#[test]
fn single_opaque_prim_lanes_match_the_traversal() {
    use strata::wavefront::shadow::prim_occlusion;
    let mut profile = Profile::builtin("bench");
    profile.transmissive_shadows = true;
    let mut arena = CsgArena::new();
    let (mut occluded, mut open) = (0usize, 0usize);
    chunks(0x0_9a9e, 240, 8, |ch, r| {
        let (scene, v) = (ch.scene, &ch.v);
        let (ts, end) = targets(r, &ch.light);
        for l in (0..LANES).filter(|&l| v.single & (1 << l) != 0) {
            let pid = v.prim[l];
            let opaque = match scene.prims[pid as usize].shape {
                strata::scene::Shape::Csg { .. } => true, // the test scene's CSG part is diffuse
                _ => !matches!(scene.materials[scene.prims[pid as usize].material as usize], strata::scene::Material::Dielectric(_)),
            };
            if !opaque {
                continue;
            }
            for ray in rays_to(ch.os[l], &ts, end) {
                let mut touched = 0;
                let alone = prim_occlusion(scene, &profile, pid, &ray, None, &mut arena, true, &mut touched).to_bitmask();
                let (all, all_touched) = occlusion_x8(scene, &profile, &ray, None, &mut arena, true);
                assert_eq!((alone, touched), (all.to_bitmask(), all_touched), "case {} lane {l} prim {pid}", ch.case);
                occluded += alone.count_ones() as usize;
                open += (!alone & 0xff).count_ones() as usize;
            }
        }
    });
    assert!(occluded > 500 && open > 500, "{occluded} rays occluded, {open} open");
}
