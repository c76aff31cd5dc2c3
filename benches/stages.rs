//! Rays per second of each pipeline stage on 2 threads. Every benchmark validates its result against the
//! scalar f64 path before it times anything.

mod support;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use rayon::prelude::*;
use std::hint::black_box;
use strata::scene::{Profile, Scene};
use strata::wavefront::intersect::{intersect, prim_t_f64};
use strata::wavefront::queues::NONE;
use strata::wavefront::shadow::occluded_x8;
use strata::wavefront::{CsgCandidates, HitQueue, RayQueue};

/// Nearest hit of one ray by the scalar f64 path (BVH f64 traversal + f64 kernels + planes).
fn scalar_hit(scene: &Scene, q: &RayQueue, i: usize) -> (f64, u32) {
    let r = q.get(i);
    let (o, d) = (r.o.as_dvec3(), r.d.as_dvec3());
    let mut best = (f64::INFINITY, NONE);
    if let Some((t, bi)) = scene.bvh.traverse_closest_f64(o, d, f64::INFINITY, |bi, o, d, tmax| {
        prim_t_f64(&scene.prims[scene.bounded[bi as usize] as usize], o, d, tmax)
    }) {
        best = (t, scene.bounded[bi as usize]);
    }
    for &pid in &scene.unbounded {
        let t = prim_t_f64(&scene.prims[pid as usize], o, d, best.0);
        if t < best.0 {
            best = (t, pid);
        }
    }
    best
}

/// Checksum of hit distances by the SIMD stage and by the scalar path; they must agree.
fn validate_intersect(scene: &Scene, qs: &[RayQueue]) {
    let (mut simd_sum, mut scalar_sum, mut mismatches, mut n) = (0.0f64, 0.0f64, 0usize, 0usize);
    let (mut hits, mut cands) = (HitQueue::default(), CsgCandidates::default());
    for q in qs.iter().step_by(7) {
        intersect(scene, q, &mut hits, &mut cands);
        for i in 0..q.len() {
            let (t, p) = scalar_hit(scene, q, i);
            n += 1;
            if hits.prim[i] != NONE {
                simd_sum += hits.t[i] as f64;
            }
            if p != NONE {
                scalar_sum += t;
            }
            let same = hits.prim[i] == p && (p == NONE || (hits.t[i] as f64 - t).abs() <= 1e-4 * t.max(1.0));
            mismatches += (!same) as usize;
        }
    }
    println!("intersect validation: {n} rays, checksum simd {simd_sum:.3} scalar {scalar_sum:.3}, {mismatches} mismatches");
    assert!(mismatches as f64 <= 1e-4 * n as f64, "SIMD and scalar paths disagree on {mismatches} of {n} rays");
    assert!(((simd_sum - scalar_sum) / scalar_sum).abs() < 1e-5);
}

fn bench_intersect(c: &mut Criterion) {
    let pool = support::pool();
    {
        let (name, spp) = ("bench_spheres.toml", 1);
        let scene = support::scene(name);
        let qs = support::camera_queues(&scene, spp);
        validate_intersect(&scene, &qs);
        let mut g = c.benchmark_group("intersect");
        g.throughput(Throughput::Elements(support::ray_count(&qs)));
        g.sample_size(20);
        g.bench_function(format!("camera/{name}"), |b| {
            b.iter(|| {
                pool.install(|| {
                    qs.par_iter().for_each_init(
                        || (HitQueue::default(), CsgCandidates::default()),
                        |(h, cands), q| {
                            intersect(&scene, q, h, cands);
                            black_box(&h.t);
                        },
                    )
                })
            })
        });
        g.finish();
    }
}

/// Shadow rays from every camera hit to the scene's first light, packed 8 at a time.
fn shadow_packets(scene: &Scene, qs: &[RayQueue]) -> Vec<strata::simd::Ray8> {
    use strata::simd::{f32x8, Ray8, Vec3x8};
    let light = match scene.lights[0] {
        strata::scene::Light::Point { position, .. } => position,
        _ => panic!("bench scene needs a point light first"),
    };
    let (mut hits, mut cands) = (HitQueue::default(), CsgCandidates::default());
    let mut lanes = Vec::new();
    for q in qs {
        intersect(scene, q, &mut hits, &mut cands);
        for i in 0..q.len() {
            if hits.prim[i] != NONE {
                let r = q.get(i);
                let p = r.o + r.d * hits.t[i];
                let n = (light - p).normalize();
                let o = p + n * 1e-3;
                lanes.push((o, light - o));
            }
        }
    }
    lanes
        .chunks(8)
        .map(|c| {
            let mut a = [[0.0f32; 8]; 6];
            let mut tmax = [-1.0f32; 8];
            for (l, (o, d)) in c.iter().enumerate() {
                for k in 0..3 {
                    a[k][l] = o[k];
                    a[3 + k][l] = d[k];
                }
                tmax[l] = 1.0;
            }
            let v = |k: usize| f32x8::from(a[k]);
            Ray8::new(Vec3x8::new(v(0), v(1), v(2)), Vec3x8::new(v(3), v(4), v(5)), f32x8::from(tmax))
        })
        .collect()
}

fn bench_shadow(c: &mut Criterion) {
    let pool = support::pool();
    let scene = support::scene("bench_spheres.toml");
    let qs = support::camera_queues(&scene, 1);
    let packets = shadow_packets(&scene, &qs);
    let profile = Profile::builtin("bench");
    // Validate any-hit against the scalar closest-hit path on a subset.
    let mut arena = strata::csg::CsgArena::new();
    let mut checked = 0;
    for p in packets.iter().step_by(53) {
        let occ = occluded_x8(&scene, &profile, p, None, &mut arena).to_bitmask();
        for l in 0..8 {
            if p.tmax.to_array()[l] < 0.0 {
                continue;
            }
            let (o, d) = (p.o.lane(l).as_dvec3(), p.d.lane(l).as_dvec3());
            let mut t = scene
                .bvh
                .traverse_closest_f64(o, d, 1.0, |bi, o, d, tm| prim_t_f64(&scene.prims[scene.bounded[bi as usize] as usize], o, d, tm))
                .map_or(f64::INFINITY, |h| h.0);
            for &pid in &scene.unbounded {
                t = t.min(prim_t_f64(&scene.prims[pid as usize], o, d, 1.0));
            }
            let scalar = t < 1.0 && t > 1e-6;
            assert_eq!(scalar, occ & (1 << l) != 0, "any-hit disagrees with the scalar path");
            checked += 1;
        }
    }
    println!("shadow validation: {checked} rays agree");
    let n = packets.iter().map(|p| p.tmax.to_array().iter().filter(|&&t| t > 0.0).count() as u64).sum();
    let mut g = c.benchmark_group("shadow");
    g.throughput(Throughput::Elements(n));
    g.sample_size(20);
    g.bench_function("any_hit/bench_spheres.toml", |b| {
        b.iter(|| {
            pool.install(|| {
                packets.par_chunks(512).for_each_init(strata::csg::CsgArena::new, |arena, ps| {
                    for p in ps {
                        black_box(occluded_x8(&scene, &profile, p, None, arena));
                    }
                })
            })
        })
    });
    g.finish();
}

criterion_group!(benches, bench_intersect, bench_shadow);
criterion_main!(benches);
