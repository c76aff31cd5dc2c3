//! Same seed, same image: for any thread count, tile size, and split of the sample range.

use std::path::Path;
use strata::film::Film;
use strata::render::{render_into, RenderJob};
use strata::scene::{parse_scene, LightSelection, Profile};
use strata::wavefront::Settings;

fn scene_text() -> String {
    std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/showcase.toml"))
        .unwrap()
        .replace("width = 640", "width = 48")
        .replace("height = 400", "height = 30")
}

fn profile() -> Profile {
    let mut p = Profile::builtin("final");
    p.spp = 6;
    p.light_samples = 2;
    p
}

fn render(threads: usize, tile: u32, samples: std::ops::Range<u32>) -> Film {
    let scene = parse_scene(Path::new("showcase.toml"), &scene_text()).unwrap();
    let mut job = RenderJob::new(&scene, Settings { profile: profile(), seed: 7 });
    job.threads = threads;
    job.tile = tile;
    job.samples = samples;
    let (film, stats) = render_into(&job, Film::new(scene.width, scene.height));
    assert_eq!(stats.nonfinite_samples, 0);
    film
}

#[test]
fn threads_and_tiles_do_not_change_the_image() {
    let a = render(1, 16, 0..6);
    let b = render(2, 16, 0..6);
    let c = render(2, 5, 0..6);
    assert!(a.total_samples() == 48 * 30 * 6);
    assert!(a == b, "1 vs 2 threads differ");
    assert!(a == c, "tile 16 vs tile 5 differ");
    // The rendered image is not trivially constant.
    let rgb = a.to_rgb();
    let lum: Vec<f32> = rgb.iter().map(|c| c.x + c.y + c.z).collect();
    let (mn, mx) = lum.iter().fold((f32::MAX, f32::MIN), |(a, b), &x| (a.min(x), b.max(x)));
    assert!(mx > 4.0 * mn.max(1e-3), "image looks flat: min {mn} max {mx}");
}

#[test]
fn exr_files_are_byte_identical_across_thread_counts() {
    let dir = std::env::temp_dir().join(format!("strata-det-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut bytes = Vec::new();
    for threads in [1, 2] {
        let f = render(threads, 16, 0..6);
        let p = dir.join(format!("t{threads}.exr"));
        strata::film::output::write_image(&p, f.width, f.height, &f.to_rgb()).unwrap();
        bytes.push(std::fs::read(&p).unwrap());
    }
    assert_eq!(bytes[0], bytes[1]);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn sample_ranges_merge_exactly() {
    let full = render(2, 16, 0..6);
    let mut a = render(1, 16, 0..2);
    let b = render(2, 7, 2..6);
    assert!(a != full);
    a.merge(&b);
    assert!(a == full, "merge of 0..2 and 2..6 differs from 0..6");
}

// ------------------------------------------------ hits do not depend on which rays share a packet

use glam::Vec3;
use strata::wavefront::intersect::intersect;
use strata::wavefront::{CsgCandidates, HitQueue, RayItem, RayQueue};

/// Two overlapping coplanar quads in different BVH leaves (spheres spread them apart), seen head on:
/// every ray through the overlap meets both at the same distance.
fn coplanar_scene() -> strata::scene::Scene {
    let mut t = String::from(
        "[image]\nwidth = 16\nheight = 16\n[camera]\nposition = [0.0, 0.0, 0.0]\nlook_at = [0.0, 0.0, -1.0]\nfov = 40.0\n\
         [[lights]]\ntype = \"point\"\nposition = [0.0, 0.0, 0.0]\nintensity = [10.0, 10.0, 10.0]\n\
         [materials.red]\ntype = \"lambert\"\nalbedo = [0.7, 0.1, 0.1]\n[materials.blue]\ntype = \"lambert\"\nalbedo = [0.1, 0.1, 0.7]\n\
         [[shapes]]\ntype = \"quad\"\norigin = [-0.5, -1.0, -5.0]\nu = [1.0, 0.0, 0.0]\nv = [0.0, 12.0, 0.0]\nmaterial = \"red\"\n\
         [[shapes]]\ntype = \"quad\"\norigin = [-1.0, -0.5, -5.0]\nu = [12.0, 0.0, 0.0]\nv = [0.0, 1.0, 0.0]\nmaterial = \"blue\"\n",
    );
    for k in 3..10 {
        for (x, y, m) in [(0, k, "red"), (k, 0, "blue")] {
            t += &format!("[[shapes]]\ntype = \"sphere\"\ncenter = [{x}.0, {y}.0, -5.5]\nradius = 0.2\nmaterial = \"{m}\"\n");
        }
    }
    parse_scene(Path::new("coplanar.toml"), &t).unwrap_or_else(|e| panic!("{e}"))
}

/// Nearest hits of rays from `origins[i]` along `dirs[i]` through the intersect stage.
fn hits_of(scene: &strata::scene::Scene, rays: &[(Vec3, Vec3)]) -> Vec<(f32, u32)> {
    let mut q = RayQueue::new(false, false);
    for (i, &(o, d)) in rays.iter().enumerate() {
        q.push(&RayItem { o, d, tmax: f32::INFINITY, path: i as u32, ..RayItem::default() });
    }
    q.pad();
    let (mut hits, mut cands) = (HitQueue::default(), CsgCandidates::default());
    intersect(scene, &q, &mut hits, &mut cands);
    (0..rays.len()).map(|i| (hits.t[i], hits.prim[i])).collect()
}

#[test]
fn equal_distances_go_to_the_lower_id_whatever_the_packet() {
    // The packet's other rays change the traversal order (which quad's leaf is visited first); a tie
    // must still go to quad 0. Before the fix the ray alone hit quad 0 and with these mates quad 1.
    let scene = coplanar_scene();
    let r = (Vec3::ZERO, Vec3::new(0.001, 0.0, -1.0));
    let alone = hits_of(&scene, &[r]);
    assert_eq!(alone[0].1, 0, "the overlap belongs to the lower id");
    for mate in [Vec3::new(-0.05, 0.0, -1.0), Vec3::new(0.05, 0.0, -1.0), Vec3::new(0.0, 0.05, -1.0)] {
        let mut rays = vec![r];
        rays.extend(std::iter::repeat_n((Vec3::ZERO, mate), 63));
        assert_eq!(hits_of(&scene, &rays)[0], alone[0], "mates along {mate:?}");
        let mut rays: Vec<_> = std::iter::repeat_n((Vec3::ZERO, mate), 63).collect();
        rays.push(r);
        assert_eq!(hits_of(&scene, &rays)[63], alone[0], "mates along {mate:?}, ray last");
    }
    // And the image (every pixel's first hit is in the overlap's plane) is the same for any tile size.
    let mut p = Profile::builtin("final");
    p.spp = 1;
    let render = |tile: u32| {
        let mut job = RenderJob::new(&scene, Settings { profile: p.clone(), seed: 7 });
        job.threads = 1;
        job.tile = tile;
        job.samples = 0..1;
        render_into(&job, Film::new(scene.width, scene.height)).0.to_rgb()
    };
    let a = render(16);
    for tile in [6, 5, 3] {
        assert!(a == render(tile), "tile 16 and tile {tile} differ");
    }
}

#[test]
fn a_group_never_drops_a_hit_its_packet_finds_alone() {
    // A sphere 1e4 from the origin; its box corner is rounded, and a ray grazing just outside the
    // rounded box still hits the sphere. Alone it is found; behind packets that miss, the group's
    // interval test must not cull the node either.
    let text = "[image]\nwidth = 16\nheight = 16\n[camera]\nposition = [0.0, 0.0, 0.0]\nlook_at = [0.0, 0.0, -1.0]\nfov = 40.0\n\
                [materials.red]\ntype = \"lambert\"\nalbedo = [0.7, 0.1, 0.1]\n\
                [[shapes]]\ntype = \"sphere\"\ncenter = [10000.0, 0.0, 0.0]\nradius = 0.3\nmaterial = \"red\"\n";
    let scene = parse_scene(Path::new("far.toml"), text).unwrap_or_else(|e| panic!("{e}"));
    let d = Vec3::new(-1.66e-4, 1.0, 1e-7);
    let graze = (Vec3::new(10_000.301, -5.0, 0.0), d);
    let alone = hits_of(&scene, &[graze]);
    assert_eq!(alone[0].1, 0, "the grazing ray hits the sphere");
    for k in [8, 16, 56] {
        let mut rays: Vec<_> = (0..k).map(|_| (Vec3::new(10_000.301, -5.0, 5.0), d)).collect();
        rays.push(graze);
        assert_eq!(hits_of(&scene, &rays)[k], alone[0], "behind {k} missing rays");
    }
}

#[test]
fn pinhole_camera_rays_made_eight_at_a_time_equal_the_scalar_camera_bit_for_bit() {
    use strata::sample::{sample_filter, stream_key, Sampler2d};
    use strata::wavefront::generate::{generate, Tile};
    use strata::wavefront::{dims, PathTable};
    let scene = parse_scene(Path::new("s.toml"), &scene_text()).unwrap();
    assert!(!scene.features.lens && !scene.features.motion && !scene.features.dispersion);
    for (spp, samples, filter) in [(4, 0..4, "box"), (5, 1..4, "tent"), (9, 0..9, "gaussian")] {
        let mut profile = profile();
        profile.spp = spp;
        profile.filter = match filter {
            "box" => strata::sample::Filter::Box,
            "tent" => strata::sample::Filter::Tent,
            _ => strata::sample::Filter::Gaussian,
        };
        // An edge-sized tile and a full one; odd counts leave a partial last packet.
        for tile in [Tile { x0: 3, y0: 2, x1: 16, y1: 9 }, Tile { x0: 0, y0: 0, x1: 16, y1: 16 }] {
            let (mut paths, mut q) = (PathTable::default(), RayQueue::new(false, false));
            generate(&scene, &profile, 11, tile, samples.clone(), &mut paths, &mut q);
            assert_eq!(q.len() as u32, tile.pixel_count() * samples.len() as u32);
            let area = Sampler2d::new(profile.pixel_strategy, spp);
            for i in 0..q.len() {
                let r = q.get(i);
                let (pixel, s) = (paths.pixel[r.path as usize], paths.sample[r.path as usize]);
                let off = sample_filter(profile.filter, area.sample(stream_key(11, pixel as u64, dims::PIXEL), s));
                let (x, y) = ((pixel % scene.width) as f32, (pixel / scene.width) as f32);
                let (o, d) = scene.camera.ray(x + 0.5 + off[0], y + 0.5 + off[1], [0.0, 0.0]);
                assert_eq!(
                    (r.o.to_array().map(f32::to_bits), r.d.to_array().map(f32::to_bits)),
                    (o.to_array().map(f32::to_bits), d.to_array().map(f32::to_bits)),
                    "ray {i}"
                );
                assert_eq!((r.path as usize, r.tmax, r.throughput, r.depth), (i, f32::INFINITY, glam::Vec3::ONE, 0));
            }
        }
    }
}

/// Cameras with a lens and a shutter make their rays 8 at a time too: every ray equals the scalar
/// camera's (`Camera::ray` at the scalar pixel and lens samples, `Camera::time` at the scalar time
/// sample): times bit for bit, origins and directions to float rounding (the 8-lane concentric disk map
/// uses wide's `sin_cos`); paths in order; partial packets at the ends of tiles.
#[test]
fn lens_and_motion_camera_rays_made_eight_at_a_time_equal_the_scalar_camera() {
    use strata::sample::{sample_1d_keyed, sample_disk_concentric, sample_filter, stream_key, Sampler2d};
    use strata::wavefront::generate::{generate, Tile};
    use strata::wavefront::{dims, PathTable};
    let text = scene_text().replacen("fov = 38.0", "fov = 38.0\naperture = 0.2\nfocus_distance = 6.0\nshutter = [0.25, 0.75]", 1)
        + "\n[[shapes]]\ntype = \"sphere\"\ncenter = [3.0, 0.3, 2.0]\nradius = 0.3\nmaterial = \"red\"\nmotion = [0.5, 0.0, 0.0]\n";
    let scene = parse_scene(Path::new("s.toml"), &text).unwrap_or_else(|e| panic!("{e}"));
    assert!(scene.features.lens && scene.features.motion && scene.camera.lens_radius > 0.0);
    let mut profile = profile();
    profile.spp = 5;
    let (mut paths, mut q) = (PathTable::default(), RayQueue::new(true, false));
    let tile = Tile { x0: 3, y0: 2, x1: 16, y1: 9 };
    generate(&scene, &profile, 11, tile, 1..4, &mut paths, &mut q);
    assert_eq!(q.len() as u32, tile.pixel_count() * 3);
    let area = Sampler2d::new(profile.pixel_strategy, 5);
    let lens = Sampler2d::new(profile.lens_strategy, 5);
    let mut spread = 0.0f32;
    for i in 0..q.len() {
        let r = q.get(i);
        let (pixel, s) = (paths.pixel[r.path as usize], paths.sample[r.path as usize]);
        let key = |dim| stream_key(11, pixel as u64, dim);
        let off = sample_filter(profile.filter, area.sample(key(dims::PIXEL), s));
        let l = sample_disk_concentric(lens.sample(key(dims::LENS), s));
        let (x, y) = ((pixel % scene.width) as f32, (pixel / scene.width) as f32);
        let (o, d) = scene.camera.ray(x + 0.5 + off[0], y + 0.5 + off[1], l);
        let t = scene.camera.time(sample_1d_keyed(profile.time_strategy, key(dims::TIME), s, 5));
        assert_eq!(r.time.to_bits(), t.to_bits(), "ray {i}: time");
        let err = (r.o - o).abs().max_element().max((r.d - d).abs().max_element());
        spread = spread.max((r.o - scene.camera.position).length());
        assert!(err < 1e-5, "ray {i}: {:?} vs {:?}", (r.o, r.d), (o, d));
        assert_eq!((r.path as usize, r.tmax, r.throughput, r.depth), (i, f32::INFINITY, glam::Vec3::ONE, 0));
    }
    // The lens is in effect: origins spread over the aperture (a lens sample lost on the way would
    // leave them at the camera's position, and the comparison above would fail on it).
    assert!(spread > 0.05, "origins spread by {spread} only");
}

/// Under split branching one path has several shading points per bounce (the reflected and the
/// refracted branch of a glass hit): their light samples must reach the path's sum in the same order
/// whatever tile the path is in, since a float sum's rounding depends on order. Glass ball over a
/// checker floor, 4 light samples, tiles of 16, 8, 5 and 3 pixels, and a split of the sample range.
#[test]
fn several_shading_points_per_path_sum_the_same_way_in_any_tile() {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/glass.toml"))
        .unwrap()
        .replace("width = 480", "width = 60")
        .replace("height = 320", "height = 40");
    let scene = parse_scene(Path::new("glass.toml"), &text).unwrap();
    let mut profile = Profile::builtin("final");
    profile.spp = 3;
    profile.light_samples = 4;
    profile.branching = strata::scene::Branching::Split;
    let run = |threads: usize, tile: u32, samples: std::ops::Range<u32>| {
        let mut job = RenderJob::new(&scene, Settings { profile: profile.clone(), seed: 5 });
        (job.threads, job.tile, job.samples) = (threads, tile, samples);
        let (film, stats) = render_into(&job, Film::new(scene.width, scene.height));
        assert_eq!(stats.nonfinite_samples, 0);
        film
    };
    let reference = run(1, 16, 0..3);
    for (threads, tile) in [(2, 16), (2, 8), (1, 5), (2, 3)] {
        assert!(run(threads, tile, 0..3) == reference, "{threads} threads, tile {tile}: the image differs");
    }
    let mut merged = run(1, 8, 0..1);
    merged.merge(&run(2, 5, 1..3));
    assert!(merged == reference, "sample ranges 0..1 + 1..3 differ from 0..3");
}

/// Light-stream keys are the same whether a chunk of shading points is one pixel's (one key per light,
/// splat: the shadow stage's fast path) or spans pixels (keys lane by lane): with 12 samples per pixel
/// the 8-request chunks of the full range are one pixel's or split across two, and a range starting at
/// sample 5 shifts every boundary, so a request's keys come from the other path. Twelve lights mix point,
/// quad, disk and sphere lights, area lights sitting past the first eight (the key cache).
#[test]
fn light_keys_do_not_depend_on_how_requests_share_a_chunk() {
    let mut text = String::from(
        "[image]\nwidth = 20\nheight = 14\n[camera]\nposition = [0, 3, 7]\nlook_at = [0, 0.5, 0]\nfov = 40\n\
         [materials.m]\ntype = \"lambert\"\nalbedo = [0.6, 0.6, 0.6]\n\
         [[shapes]]\ntype = \"plane\"\npoint = [0, 0, 0]\nnormal = [0, 1, 0]\nmaterial = \"m\"\n\
         [[shapes]]\ntype = \"sphere\"\ncenter = [0, 0.7, 0]\nradius = 0.7\nmaterial = \"m\"\n",
    );
    for i in 0..12 {
        let x = i as f32 - 5.5;
        text += &match i % 4 {
            0 => format!("[[lights]]\ntype = \"point\"\nposition = [{x}, 4, 1]\nintensity = [2, 2, 2]\n"),
            1 => format!("[[lights]]\ntype = \"quad\"\norigin = [{x}, 4, -1]\nu = [0.5, 0, 0]\nv = [0, 0, 0.5]\nradiance = [3, 3, 3]\n"),
            2 => format!("[[lights]]\ntype = \"disk\"\ncenter = [{x}, 4.5, 0]\nnormal = [0, -1, 0]\nradius = 0.3\nradiance = [3, 3, 3]\n"),
            _ => format!("[[lights]]\ntype = \"sphere\"\ncenter = [{x}, 5, 2]\nradius = 0.2\nradiance = [3, 3, 3]\n"),
        };
    }
    let scene = parse_scene(Path::new("lights.toml"), &text).unwrap();
    assert_eq!(scene.lights.len(), 12);
    // Every light selection: picked lights sort a queue's requests by light, which must not depend on
    // the tile either.
    for mode in LightSelection::ALL {
        let mut profile = Profile::builtin("final");
        (profile.spp, profile.light_samples, profile.light_selection) = (12, 2, mode);
        let run = |threads: usize, tile: u32, samples: std::ops::Range<u32>| {
            let mut job = RenderJob::new(&scene, Settings { profile: profile.clone(), seed: 3 });
            (job.threads, job.tile, job.samples) = (threads, tile, samples);
            render_into(&job, Film::new(scene.width, scene.height)).0
        };
        let reference = run(1, 16, 0..12);
        let mut split = run(2, 5, 0..5);
        split.merge(&run(1, 7, 5..12));
        assert!(split == reference, "{}: sample ranges 0..5 + 5..12 differ from 0..12", mode.name());
        assert!(run(2, 3, 0..12) == reference, "{}: tile 3 differs", mode.name());
        let lum: Vec<f32> = reference.to_rgb().iter().map(|c| c.x + c.y + c.z).collect();
        assert!(lum.iter().all(|&l| l.is_finite()) && lum.iter().any(|&l| l > 0.0), "{}: the image is black", mode.name());
    }
}

/// With 16 light samples the shadow stage's light-cone test credits the shading points that see a
/// light through empty space untraced, the others are traced: a request's lights can go either way
/// (the quad light cleared, the point light traced, or the reverse). Its verdict is each point's own,
/// so the image must not depend on which points share a chunk: tiles 16, 5 and 3, one and two threads,
/// and a split sample range give the same image; and the test did clear some rays.
#[test]
fn light_cone_test_does_not_depend_on_tiles() {
    let text = scene_text();
    let scene = parse_scene(Path::new("showcase.toml"), &text).unwrap();
    let mut profile = profile();
    (profile.spp, profile.light_samples) = (3, 16);
    let run = |threads: usize, tile: u32, samples: std::ops::Range<u32>| {
        let mut job = RenderJob::new(&scene, Settings { profile: profile.clone(), seed: 11 });
        (job.threads, job.tile, job.samples) = (threads, tile, samples);
        render_into(&job, Film::new(scene.width, scene.height))
    };
    let (reference, stats) = run(1, 16, 0..3);
    assert!(stats.rays.shadow_cleared > 0 && stats.rays.shadow > 0, "cleared {} traced {}", stats.rays.shadow_cleared, stats.rays.shadow);
    for (threads, tile) in [(2, 16), (1, 5), (2, 3)] {
        assert!(run(threads, tile, 0..3).0 == reference, "{threads} threads, tile {tile}: the image differs");
    }
    let mut merged = run(2, 5, 0..1).0;
    merged.merge(&run(1, 3, 1..3).0);
    assert!(merged == reference, "sample ranges 0..1 + 1..3 differ from 0..3");
}
