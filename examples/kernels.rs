//! Strata's ray kernels against Embree's (through Mitsuba 3's `llvm_ad_rgb` variant) on the same rays:
//! this program makes four ray sets of a scene (peer scene (b) by default), writes them to files,
//! traces each with the traversal the renderer uses for such rays, and prints rays per second;
//! `benches/peers/kernels.py` traces the same files with Mitsuba's `ray_intersect_preliminary` and
//! `ray_test` (Embree) and prints both side by side, after checking that both find the same hits.
//!
//! ```sh
//! cargo run --release --example kernels -- --out target/kernels       # Strata, writes the rays
//! python3 benches/peers/kernels.py target/kernels                     # Mitsuba on the same rays
//! ```
//!
//! The sets, from the camera rays of every 4th 16 x 16 tile at 16 samples per pixel (the renderer's
//! work units at 16 spp and more), in the renderer's queue order:
//! - `camera`: those camera rays (closest hit: wide-BVH groups);
//! - `bounce`: a cosine-distributed diffuse bounce from each camera hit, started off the surface as
//!   shading starts it (closest hit: direction-sorted packets through the wide BVH);
//! - `shadow`: from each camera hit towards a uniform point of the first light (a quad), ending 1e-4
//!   short of it, where the point and the light face each other (any hit: groups of packets, as the shadow stage traces rays of camera hits; the
//!   light-cone test, which clears many of them untraced in renders, is not used);
//! - `shadow_scattered`: the same from each bounce's hit (any hit: one ray at a time, as the shadow
//!   stage traces rays of scattered shading points).
//!
//! Files: `<set>.bin`, 7 little-endian f32 per ray (origin, direction, tmax; `t` is in units of the
//! direction's length), and `strata.json` with per set the ray count, hit count, sum of hit distances
//! and the best rate. Timing: best of `--reps` passes over the set on `--threads` threads (2).

#[path = "../benches/support.rs"]
mod support;

use glam::Vec3;
use rand_core::{Rng, SeedableRng};
use rayon::prelude::*;
use std::hint::black_box;
use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;
use strata::accel::{WideStack, GROUP};
use strata::csg::CsgArena;
use strata::scene::{load_scene, Light, Profile, Scene};
use strata::simd::{f32x8, Ray8, Vec3x8};
use strata::wavefront::intersect::intersect;
use strata::wavefront::queues::{RayItem, NONE};
use strata::wavefront::shadow::{occlusion_group, occlusion_single};
use strata::wavefront::{CsgCandidates, HitQueue, RayQueue};

const SHADOW_END: f32 = 1.0 - 1e-4;

struct Args {
    scene: PathBuf,
    out: PathBuf,
    threads: usize,
    reps: usize,
}

fn args() -> Args {
    let mut a = Args { scene: "benches/peers/scenes/spheres_area.toml".into(), out: "target/kernels".into(), threads: 2, reps: 7 };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().unwrap_or_else(|| fail(&format!("{flag} needs a value")));
        match flag.as_str() {
            "--scene" => a.scene = value().into(),
            "--out" => a.out = value().into(),
            "--threads" => a.threads = value().parse().unwrap_or_else(|_| fail("--threads takes a number")),
            "--reps" => a.reps = value().parse().unwrap_or_else(|_| fail("--reps takes a number")),
            _ => fail(&format!("unknown flag {flag} (--scene, --out, --threads, --reps)")),
        }
    }
    a
}

fn fail(msg: &str) -> ! {
    eprintln!("kernels: {msg}");
    std::process::exit(2)
}

/// Camera rays of every 4th 16 x 16 tile at 16 spp (the benchmarks' queues: one tile per queue).
fn camera_queues(scene: &Scene) -> Vec<RayQueue> {
    support::camera_queues(scene, 16).into_iter().skip(3).step_by(4).collect()
}

/// Per queue, the hit point and facing surface normal of each ray that hits a sphere, plane or quad.
fn hit_points(scene: &Scene, qs: &[RayQueue]) -> Vec<Vec<(Vec3, Vec3)>> {
    let (mut hits, mut cands) = (HitQueue::default(), CsgCandidates::default());
    qs.iter()
        .map(|q| {
            intersect(scene, q, &mut hits, &mut cands);
            (0..q.len())
                .filter(|&i| hits.prim[i] != NONE)
                .filter_map(|i| {
                    let r = q.get(i);
                    let p = r.o + r.d * hits.t[i];
                    support::facing_normal(scene, hits.prim[i], p, r.d).map(|n| (p, n))
                })
                .collect()
        })
        .collect()
}

/// One cosine-distributed bounce per hit point, in queues of the same pixels.
fn bounce_queues(points: &[Vec<(Vec3, Vec3)>], pixels: &[u32], u: &mut impl FnMut() -> f32) -> Vec<RayQueue> {
    points
        .iter()
        .zip(pixels)
        .map(|(pts, &px)| {
            let mut q = RayQueue::new(false, false);
            for &(p, n) in pts {
                let (u1, u2) = (u(), u());
                let d = support::cosine_about(n, u1, u2);
                q.push(&RayItem { o: strata::geometry::offset_ray_origin(p, n), d, tmax: f32::INFINITY, ..Default::default() });
            }
            q.pad();
            q.pixels = px;
            q
        })
        .collect()
}

/// Shadow rays from each hit point towards a uniform point of the quad light, as 8-ray packets (the
/// last one padded with inactive lanes), in hit order.
fn shadow_packets(points: &[Vec<(Vec3, Vec3)>], light: &strata::geometry::Quad, u: &mut impl FnMut() -> f32) -> Vec<Ray8> {
    // (Only points that face the light point and that the light faces: the shadow stage traces no
    // other ray.)
    let lanes: Vec<(Vec3, Vec3)> = points
        .iter()
        .flatten()
        .filter_map(|&(p, n)| {
            let y = light.origin + light.u * u() + light.v * u();
            let o = strata::geometry::offset_ray_origin(p, n);
            (n.dot(y - p) > 0.0 && light.unit_normal.dot(p - y) > 0.0).then_some((o, y - o))
        })
        .collect();
    lanes
        .chunks(8)
        .map(|c| {
            let mut a = [[0.0f32; 8]; 6];
            let mut tmax = [-1.0f32; 8];
            for (l, (o, d)) in c.iter().enumerate() {
                for k in 0..3 {
                    (a[k][l], a[3 + k][l]) = (o[k], d[k]);
                }
                tmax[l] = SHADOW_END;
            }
            let v = |k: usize| f32x8::from(a[k]);
            Ray8::new(Vec3x8::new(v(0), v(1), v(2)), Vec3x8::new(v(3), v(4), v(5)), f32x8::from(tmax))
        })
        .collect()
}

fn write_queues(path: &PathBuf, qs: &[RayQueue]) -> u64 {
    let mut buf = Vec::new();
    let mut n = 0;
    for q in qs {
        for i in 0..q.len() {
            let r = q.get(i);
            for v in [r.o.x, r.o.y, r.o.z, r.d.x, r.d.y, r.d.z, r.tmax] {
                buf.extend_from_slice(&v.to_le_bytes());
            }
            n += 1;
        }
    }
    std::fs::write(path, buf).unwrap_or_else(|e| fail(&format!("{}: {e}", path.display())));
    n
}

fn write_packets(path: &PathBuf, ps: &[Ray8]) -> u64 {
    let mut buf = Vec::new();
    let mut n = 0;
    for p in ps {
        let (o, d, t) = (p.o.rows(), p.d.rows(), p.tmax.to_array());
        for l in 0..8 {
            if t[l] < 0.0 {
                continue;
            }
            for v in [o[0][l], o[1][l], o[2][l], d[0][l], d[1][l], d[2][l], t[l]] {
                buf.extend_from_slice(&v.to_le_bytes());
            }
            n += 1;
        }
    }
    std::fs::write(path, buf).unwrap_or_else(|e| fail(&format!("{}: {e}", path.display())));
    n
}

/// Best of `reps` timed passes of `pass` (seconds).
fn best(reps: usize, mut pass: impl FnMut()) -> f64 {
    pass();
    (0..reps)
        .map(|_| {
            let t = Instant::now();
            pass();
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    let a = args();
    let scene = load_scene(&a.scene).unwrap_or_else(|e| fail(&e.to_string()));
    let Some(Light::Quad { quad: light, .. }) = scene.lights.first() else {
        fail("the scene's first light must be a quad light");
    };
    std::fs::create_dir_all(&a.out).unwrap_or_else(|e| fail(&format!("{}: {e}", a.out.display())));
    let pool = rayon::ThreadPoolBuilder::new().num_threads(a.threads).build().expect("thread pool");
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(22);
    let mut u = move || (rng.next_u32() >> 8) as f32 / (1u32 << 24) as f32;

    let camera = camera_queues(&scene);
    let pixels: Vec<u32> = camera.iter().map(|q| q.pixels).collect();
    let camera_points = hit_points(&scene, &camera);
    let bounce = bounce_queues(&camera_points, &pixels, &mut u);
    let bounce_points = hit_points(&scene, &bounce);
    let shadow = shadow_packets(&camera_points, light, &mut u);
    let scattered = shadow_packets(&bounce_points, light, &mut u);

    let profile = Profile::builtin("bench");
    let closest = |qs: &[RayQueue]| {
        // Hits and sum of t (checks against the peer), then the rate.
        let (mut hits, mut cands) = (HitQueue::default(), CsgCandidates::default());
        let (mut n, mut sum) = (0u64, 0f64);
        for q in qs {
            intersect(&scene, q, &mut hits, &mut cands);
            for i in 0..q.len() {
                if hits.prim[i] != NONE {
                    (n, sum) = (n + 1, sum + hits.t[i] as f64);
                }
            }
        }
        let secs = best(a.reps, || {
            pool.install(|| {
                qs.par_iter().for_each_init(
                    || (HitQueue::default(), CsgCandidates::default()),
                    |(h, c), q| {
                        intersect(&scene, q, h, c);
                        black_box(&h.t);
                    },
                )
            })
        });
        (n, sum, secs)
    };
    let any = |ps: &[Ray8], single: bool| {
        let trace = |g: &[Ray8], arena: &mut CsgArena, stack: &mut WideStack| {
            if single {
                occlusion_single(&scene, &profile, g, &[None; GROUP], arena, stack)
            } else {
                occlusion_group(&scene, &profile, &mut g.to_vec(), &[None; GROUP], arena, false).0
            }
        };
        let (mut arena, mut stack) = (CsgArena::new(), WideStack::default());
        let mut n = 0u64;
        for g in ps.chunks(GROUP) {
            let occ = trace(g, &mut arena, &mut stack);
            for (j, p) in g.iter().enumerate() {
                n += (occ[j].to_bitmask() & p.tmax.simd_ge(f32x8::ZERO).to_bitmask()).count_ones() as u64;
            }
        }
        let secs = best(a.reps, || {
            pool.install(|| {
                ps.par_chunks(512).for_each_init(
                    || (CsgArena::new(), WideStack::default()),
                    |(arena, stack), c| {
                        for g in c.chunks(GROUP) {
                            black_box(trace(g, arena, stack));
                        }
                    },
                )
            })
        });
        (n, 0.0, secs)
    };

    let sets: [(&str, u64, (u64, f64, f64)); 4] = [
        ("camera", write_queues(&a.out.join("camera.bin"), &camera), closest(&camera)),
        ("bounce", write_queues(&a.out.join("bounce.bin"), &bounce), closest(&bounce)),
        ("shadow", write_packets(&a.out.join("shadow.bin"), &shadow), any(&shadow, false)),
        ("shadow_scattered", write_packets(&a.out.join("shadow_scattered.bin"), &scattered), any(&scattered, true)),
    ];
    println!("scene {}, {} threads, best of {}", a.scene.display(), a.threads, a.reps);
    println!("| set | rays | hits | Strata M rays/s |");
    println!("|---|---:|---:|---:|");
    let mut json = String::from("{");
    for (k, (name, rays, (hits, sum, secs))) in sets.iter().enumerate() {
        let rate = *rays as f64 / secs / 1e6;
        println!("| {name} | {rays} | {hits} | {rate:.1} |");
        json += &format!(
            "{}\"{name}\": {{\"rays\": {rays}, \"hits\": {hits}, \"t_sum\": {sum}, \"seconds\": {secs}, \"m_rays_per_s\": {rate}}}",
            if k > 0 { ", " } else { "" }
        );
    }
    json += &format!(", \"threads\": {}}}\n", a.threads);
    let path = a.out.join("strata.json");
    std::fs::File::create(&path)
        .and_then(|mut f| f.write_all(json.as_bytes()))
        .unwrap_or_else(|e| fail(&format!("{}: {e}", path.display())));
    println!("wrote {}/{{camera,bounce,shadow,shadow_scattered}}.bin and strata.json", a.out.display());
}
