//! Shared, seeded inputs for the benchmarks: scenes from `scenes/`, camera-ray queues, thread pools.
#![allow(dead_code)]

use std::path::PathBuf;
use strata::scene::{load_scene, Profile, Scene};
use strata::wavefront::generate::{generate, Tile};
use strata::wavefront::{PathTable, RayQueue};

/// Benchmarks run on 2 threads (the target machine's cores).
pub const THREADS: usize = 2;
/// Rays per wavefront queue (the renderer's size).
pub const CHUNK: u32 = 4096;

pub fn scene(name: &str) -> Scene {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes").join(name);
    load_scene(&p).unwrap_or_else(|e| panic!("{e}"))
}

pub fn pool() -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(THREADS).build().unwrap()
}

/// Camera rays of the whole image at `spp` samples, cut into padded wavefront-sized queues
/// (one tile of 64x64 pixels per queue at 1 spp).
pub fn camera_queues(scene: &Scene, spp: u32) -> Vec<RayQueue> {
    let mut profile = Profile::builtin("bench");
    profile.spp = spp;
    let mut out = Vec::new();
    let side = ((CHUNK / spp) as f32).sqrt().max(1.0) as u32;
    for y0 in (0..scene.height).step_by(side as usize) {
        for x0 in (0..scene.width).step_by(side as usize) {
            let tile = Tile { x0, y0, x1: (x0 + side).min(scene.width), y1: (y0 + side).min(scene.height) };
            let mut q = RayQueue::new(scene.features.motion, scene.features.dispersion);
            let mut paths = PathTable::default();
            generate(scene, &profile, 1, tile, 0..spp, &mut paths, &mut q);
            q.pad();
            // (As the pipeline tells the intersect stage.)
            q.pixels = tile.pixel_count();
            out.push(q);
        }
    }
    out
}

pub fn ray_count(qs: &[RayQueue]) -> u64 {
    qs.iter().map(|q| q.len() as u64).sum()
}

/// The image cut into `side` x `side` tiles (the renderer's default tile is 16).
pub fn tiles(scene: &Scene, side: u32) -> Vec<Tile> {
    let mut out = Vec::new();
    for y0 in (0..scene.height).step_by(side as usize) {
        for x0 in (0..scene.width).step_by(side as usize) {
            out.push(Tile { x0, y0, x1: (x0 + side).min(scene.width), y1: (y0 + side).min(scene.height) });
        }
    }
    out
}

/// The surface normal at `p` on `prim` (a sphere, plane or quad), facing against the ray direction `d`;
/// `None` for other shapes.
pub fn facing_normal(scene: &Scene, prim: u32, p: glam::Vec3, d: glam::Vec3) -> Option<glam::Vec3> {
    use strata::scene::Shape;
    let n = match scene.prims[prim as usize].shape {
        Shape::Sphere { center, .. } => (p - center).normalize(),
        Shape::Plane(pl) => pl.normal,
        Shape::Quad(q) => q.unit_normal,
        _ => return None,
    };
    Some(if n.dot(d) > 0.0 { -n } else { n })
}

/// A cosine-distributed diffuse bounce about `n` from two uniforms (the first picks the radius), as
/// path tracing takes them.
pub fn cosine_about(n: glam::Vec3, u1: f32, u2: f32) -> glam::Vec3 {
    let (a, b) = n.any_orthonormal_pair();
    let (rad, phi) = (u1.sqrt(), std::f32::consts::TAU * u2);
    let z = (1.0 - rad * rad).max(0.0).sqrt();
    a * (rad * phi.cos()) + b * (rad * phi.sin()) + n * z
}
