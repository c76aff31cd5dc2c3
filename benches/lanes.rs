//! 8 lanes or 16? The renderer's two hottest kernels, the slab test (`intersect_aabb_x8`) and the sphere
//! kernel (`intersect_sphere_x8`), beside 16-lane twins written here with `wide::f32x16` (one zmm register
//! with AVX-512; Zen 4 executes a 512-bit operation as two 256-bit halves). The twins use the same
//! formulation and constants, so before anything is timed every ray is checked against every box and
//! sphere: masks, `tnear` and sphere `t` must be bit-identical lane for lane.
//!
//! Timed: ray-primitive tests per second, on one thread and on a rayon pool of 2, over 65,536 seeded rays
//! (incoherent, coherent bundles, axis-parallel) x 256 boxes or 256 spheres.
//!
//! `cargo bench --bench lanes -- --quick --noplot`
//!
//! Measured (EPYC Zen 4, 2.6 GHz, 2 cores, `--quick`), tests/s, 8 lanes -> 16 lanes (ratio 16/8):
//! slab 1 thread 3.26 G -> 3.58 G (1.10x), 2 threads 6.43 G -> 6.96 G (1.08x);
//! sphere 1 thread 0.565 G -> 0.871 G (1.54x), 2 threads 1.06-1.11 G -> 1.68-1.70 G (1.53-1.58x).
//! Disassembly: the 16-lane loops are zmm only, the 8-lane loops ymm only.

mod support;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use glam::Vec3;
use rand_core::{Rng, SeedableRng};
use rayon::prelude::*;
use std::hint::black_box;
use strata::accel::{intersect_aabb_x8, Aabb, PacketRay, INV_D_CLAMP};
use strata::geometry::{intersect_sphere_x8, GRAZE, MISS};
use strata::simd::{f32x8, Ray8, Vec3x8};
use wide::f32x16;

const RAYS: usize = 65_536;
const PRIMS: usize = 256;
/// Rays per rayon task on 2 threads (the same for both widths).
const TASK_RAYS: usize = 2048;

// ---------------------------------------------------------------------------------------------------
// 16-lane twins. Constants and operation order copied from src/accel/aabb.rs and src/geometry/.

/// `REL_PAD` and `ABS_PAD` of src/accel/aabb.rs (private there): `2^-21`.
const REL_PAD: f32 = 1.0 / (1u32 << 21) as f32;
const ABS_PAD: f32 = 1.0 / (1u32 << 21) as f32;

#[derive(Clone, Copy, Debug)]
struct Vec3x16 {
    x: f32x16,
    y: f32x16,
    z: f32x16,
}

impl Vec3x16 {
    #[inline(always)]
    fn new(x: f32x16, y: f32x16, z: f32x16) -> Self {
        Self { x, y, z }
    }
    #[inline(always)]
    fn splat(v: Vec3) -> Self {
        Self { x: f32x16::splat(v.x), y: f32x16::splat(v.y), z: f32x16::splat(v.z) }
    }
    #[inline(always)]
    fn dot(self, o: Self) -> f32x16 {
        self.x.mul_add(o.x, self.y.mul_add(o.y, self.z * o.z))
    }
}

/// Twin of `Ray8`.
#[derive(Clone, Copy, Debug)]
struct Ray16 {
    o: Vec3x16,
    d: Vec3x16,
    inv_d: Vec3x16,
    tmax: f32x16,
}

impl Ray16 {
    #[inline(always)]
    fn new(o: Vec3x16, d: Vec3x16, tmax: f32x16) -> Self {
        let one = f32x16::ONE;
        Self { o, d, inv_d: Vec3x16::new(one / d.x, one / d.y, one / d.z), tmax }
    }
}

/// Twin of `PacketRay`.
#[derive(Clone, Copy, Debug)]
struct PacketRay16 {
    inv_lo: Vec3x16,
    c_lo: Vec3x16,
    inv_hi: Vec3x16,
    c_hi: Vec3x16,
}

#[inline(always)]
fn fold_axis_x16(o: f32x16, inv_d: f32x16) -> (f32x16, f32x16, f32x16, f32x16) {
    let lim = f32x16::splat(INV_D_CLAMP);
    let inv = inv_d.fast_max(-lim).fast_min(lim);
    let parallel = inv.abs().simd_ge(lim);
    let pos = inv.simd_ge(f32x16::ZERO);
    let (down, up) = (f32x16::splat(1.0 - REL_PAD), f32x16::splat(1.0 + REL_PAD));
    let one = f32x16::ONE;
    let s_lo = parallel.select(one, pos.select(down, up));
    let s_hi = parallel.select(one, pos.select(up, down));
    let e = (o * inv).abs().fast_max(parallel.select(lim, f32x16::ZERO)) * f32x16::splat(ABS_PAD);
    let (inv_lo, inv_hi) = (inv * s_lo, inv * s_hi);
    let c_lo = -(o * inv_lo) + pos.select(-e, e);
    let c_hi = -(o * inv_hi) + pos.select(e, -e);
    (inv_lo, c_lo, inv_hi, c_hi)
}

impl PacketRay16 {
    fn new(ray: &Ray16) -> Self {
        let (xl, xcl, xh, xch) = fold_axis_x16(ray.o.x, ray.inv_d.x);
        let (yl, ycl, yh, ych) = fold_axis_x16(ray.o.y, ray.inv_d.y);
        let (zl, zcl, zh, zch) = fold_axis_x16(ray.o.z, ray.inv_d.z);
        Self {
            inv_lo: Vec3x16::new(xl, yl, zl),
            c_lo: Vec3x16::new(xcl, ycl, zcl),
            inv_hi: Vec3x16::new(xh, yh, zh),
            c_hi: Vec3x16::new(xch, ych, zch),
        }
    }
}

/// Twin of `intersect_aabb_x8`: 6 FMA, 3 min, 3 max, 2 max, 2 min, 1 compare per box.
#[inline(always)]
fn intersect_aabb_x16(min: Vec3, max: Vec3, r: &PacketRay16, tmax: f32x16) -> (f32x16, f32x16) {
    let x0 = f32x16::splat(min.x).mul_add(r.inv_lo.x, r.c_lo.x);
    let x1 = f32x16::splat(max.x).mul_add(r.inv_hi.x, r.c_hi.x);
    let y0 = f32x16::splat(min.y).mul_add(r.inv_lo.y, r.c_lo.y);
    let y1 = f32x16::splat(max.y).mul_add(r.inv_hi.y, r.c_hi.y);
    let z0 = f32x16::splat(min.z).mul_add(r.inv_lo.z, r.c_lo.z);
    let z1 = f32x16::splat(max.z).mul_add(r.inv_hi.z, r.c_hi.z);
    let tnear = x0.fast_min(x1).fast_max(y0.fast_min(y1)).fast_max(z0.fast_min(z1).fast_max(f32x16::ZERO));
    let tfar = x0.fast_max(x1).fast_min(y0.fast_max(y1)).fast_min(z0.fast_max(z1).fast_min(tmax));
    (tnear, tnear.simd_le(tfar))
}

#[inline(always)]
fn two_sum_x16(a: f32x16, b: f32x16) -> (f32x16, f32x16) {
    let s = a + b;
    let bb = s - a;
    let e = (a - (s - bb)) + (b - bb);
    (s, e)
}

#[inline(always)]
fn dist2_minus_r2_x16(s: Vec3x16, e: Vec3x16, r2: f32x16, r2_lo: f32x16) -> f32x16 {
    let (px, py, pz) = (s.x * s.x, s.y * s.y, s.z * s.z);
    let pi = s.x.mul_sub(s.x, px) + s.y.mul_sub(s.y, py) + s.z.mul_sub(s.z, pz);
    let (u, eu) = two_sum_x16(px, py);
    let (w, ew) = two_sum_x16(u, pz);
    let two = f32x16::splat(2.0);
    let cross = e.x.mul_add(s.x.mul_add(two, e.x), e.y.mul_add(s.y.mul_add(two, e.y), e.z * s.z.mul_add(two, e.z)));
    (w - r2) + (((eu + ew) + pi) + (cross - r2_lo))
}

#[inline(always)]
fn nearest_root_x16(a: f32x16, inv_a: f32x16, b: f32x16, disc: f32x16, c0: f32x16) -> f32x16 {
    let h = (disc.max(f32x16::ZERO) * a).sqrt();
    let sign_b = b & f32x16::splat(-0.0);
    let q = -(b + (h | sign_b));
    let t0 = c0 / q;
    let t1 = q * inv_a;
    let near = t0.min(t1);
    let far = t0.max(t1);
    near.simd_gt(f32x16::ZERO).select(near, far)
}

#[inline(always)]
fn ray_finite_x16(ray: &Ray16) -> f32x16 {
    let (o, d, z) = (ray.o, ray.d, f32x16::ZERO);
    let s = o.x.mul_add(z, o.y.mul_add(z, o.z.mul_add(z, d.x.mul_add(z, d.y.mul_add(z, d.z * z)))));
    s.simd_eq(z)
}

/// Twin of `intersect_sphere_x8` (compensated Haines et al. 2019 kernel, same operation order).
#[inline(always)]
fn intersect_sphere_x16(center: Vec3, radius: f32, ray: &Ray16) -> f32x16 {
    let c = Vec3x16::splat(center);
    let d = ray.d;
    let (sx, ex) = two_sum_x16(ray.o.x, -c.x);
    let (sy, ey) = two_sum_x16(ray.o.y, -c.y);
    let (sz, ez) = two_sum_x16(ray.o.z, -c.z);
    let s = Vec3x16::new(sx, sy, sz);
    let e = Vec3x16::new(ex, ey, ez);
    let a = d.dot(d);
    let inv_a = f32x16::ONE / a;
    let b = s.dot(d);
    let k = b * inv_a;
    let l = Vec3x16::new(k.mul_neg_add(d.x, sx) + ex, k.mul_neg_add(d.y, sy) + ey, k.mul_neg_add(d.z, sz) + ez);
    let r2 = radius * radius;
    let r2_lo = radius.mul_add(radius, -r2);
    let r2v = f32x16::splat(r2);
    let disc = l.x.mul_neg_add(l.x, l.y.mul_neg_add(l.y, l.z.mul_neg_add(l.z, r2v)));
    let hit = disc.simd_ge(f32x16::splat(-GRAZE * r2));
    let c0 = dist2_minus_r2_x16(s, e, r2v, f32x16::splat(r2_lo));
    let t = nearest_root_x16(a, inv_a, b, disc, c0);
    let ok = hit & ray_finite_x16(ray) & t.simd_gt(f32x16::ZERO) & t.simd_lt(ray.tmax);
    ok.select(t, f32x16::splat(MISS))
}

// ---------------------------------------------------------------------------------------------------
// Seeded inputs.

struct Rays {
    o: Vec<Vec3>,
    d: Vec<Vec3>,
    tmax: Vec<f32>,
}

struct Uniform(rand_xoshiro::Xoshiro256PlusPlus);

impl Uniform {
    /// Uniform in `[0, 1)` with 24 random bits.
    fn u(&mut self) -> f32 {
        (self.0.next_u32() >> 8) as f32 / (1u32 << 24) as f32
    }
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.u()
    }
    fn in_box(&mut self, h: f32) -> Vec3 {
        Vec3::new(self.range(-h, h), self.range(-h, h), self.range(-h, h))
    }
    fn dir(&mut self) -> Vec3 {
        let (z, phi) = (2.0 * self.u() - 1.0, std::f32::consts::TAU * self.u());
        let s = (1.0 - z * z).max(0.0).sqrt();
        Vec3::new(s * phi.cos(), s * phi.sin(), z)
    }
}

/// 256 boxes in `[-8, 8]^3` (1 in 16 flat on one axis) and 256 spheres (radius 0.1..2, plus a radius-1e4
/// ground sphere and a radius-1e3 sphere far away).
fn scene(rng: &mut Uniform) -> (Vec<Aabb>, Vec<(Vec3, f32)>) {
    let boxes = (0..PRIMS)
        .map(|i| {
            let c = rng.in_box(8.0);
            let mut h = Vec3::new(rng.range(0.05, 1.5), rng.range(0.05, 1.5), rng.range(0.05, 1.5));
            if i % 16 == 5 {
                h[i / 16 % 3] = 0.0;
            }
            Aabb::new(c - h, c + h)
        })
        .collect();
    let mut spheres: Vec<(Vec3, f32)> = (0..PRIMS).map(|_| (rng.in_box(8.0), rng.range(0.1, 2.0))).collect();
    spheres[17] = (Vec3::new(0.0, -1.0e4 - 12.0, 0.0), 1.0e4);
    spheres[99] = (Vec3::new(3.0e3, 50.0, -2.0e3), 1.0e3);
    (boxes, spheres)
}

/// 65,536 rays in blocks of 16: half incoherent (origin in `[-12, 12]^3`, uniform direction scaled by
/// 0.5..2, so not unit length), 3/8 coherent bundles (shared origin, aimed at a box centre, spread
/// 0.02), 1/8 parallel to one or two axes (zero components of both signs, the origin's matching
/// coordinates on a box face). `tmax`: +inf mostly, finite 1..30 for 1 ray in 4, -1 (dead lane) 1 in 64.
fn rays(rng: &mut Uniform, boxes: &[Aabb]) -> Rays {
    let mut r = Rays { o: Vec::with_capacity(RAYS), d: Vec::with_capacity(RAYS), tmax: Vec::with_capacity(RAYS) };
    for block in 0..RAYS / 16 {
        let kind = block % 8;
        let (p, target) = (rng.in_box(12.0), boxes[rng.0.next_u32() as usize % boxes.len()].centroid());
        for _ in 0..16 {
            let (o, d) = match kind {
                0..=3 => (rng.in_box(12.0), rng.dir() * rng.range(0.5, 2.0)),
                4..=6 => (p + rng.in_box(0.01), ((target - p).normalize() + rng.in_box(0.02)).normalize()),
                _ => {
                    let b = boxes[rng.0.next_u32() as usize % boxes.len()];
                    let (mut o, mut d) = (rng.in_box(12.0), rng.dir());
                    let axes = 1 + (rng.0.next_u32() % 2) as usize;
                    let first = (rng.0.next_u32() % 3) as usize;
                    for k in 0..axes {
                        let a = (first + k) % 3;
                        d[a] = if rng.u() < 0.5 { 0.0 } else { -0.0 };
                        o[a] = if rng.u() < 0.5 { b.min[a] } else { b.max[a] };
                    }
                    (o, d)
                }
            };
            let x = rng.u();
            let tmax = if x < 1.0 / 64.0 {
                -1.0
            } else if x < 0.25 {
                rng.range(1.0, 30.0)
            } else {
                f32::INFINITY
            };
            r.o.push(o);
            r.d.push(d);
            r.tmax.push(tmax);
        }
    }
    r
}

fn lanes<const N: usize>(v: &[Vec3], f: impl Fn(Vec3) -> f32) -> [f32; N] {
    std::array::from_fn(|i| f(v[i]))
}

fn ray8(r: &Rays, i: usize) -> Ray8 {
    let v = |s: &[Vec3]| Vec3x8::new(lanes(s, |p| p.x).into(), lanes(s, |p| p.y).into(), lanes(s, |p| p.z).into());
    let t: [f32; 8] = r.tmax[i..i + 8].try_into().unwrap();
    Ray8::new(v(&r.o[i..i + 8]), v(&r.d[i..i + 8]), t.into())
}

fn ray16(r: &Rays, i: usize) -> Ray16 {
    let v = |s: &[Vec3]| Vec3x16::new(lanes(s, |p| p.x).into(), lanes(s, |p| p.y).into(), lanes(s, |p| p.z).into());
    let t: [f32; 16] = r.tmax[i..i + 16].try_into().unwrap();
    Ray16::new(v(&r.o[i..i + 16]), v(&r.d[i..i + 16]), t.into())
}

/// Everything one width needs: packets for the sphere kernel, precomputed slab constants and `tmax`.
struct Packets8 {
    rays: Vec<Ray8>,
    slab: Vec<(PacketRay, f32x8)>,
}

struct Packets16 {
    rays: Vec<Ray16>,
    slab: Vec<(PacketRay16, f32x16)>,
}

fn packets8(r: &Rays) -> Packets8 {
    let rays: Vec<Ray8> = (0..RAYS).step_by(8).map(|i| ray8(r, i)).collect();
    let slab = rays.iter().map(|p| (PacketRay::new(p), p.tmax)).collect();
    Packets8 { rays, slab }
}

fn packets16(r: &Rays) -> Packets16 {
    let rays: Vec<Ray16> = (0..RAYS).step_by(16).map(|i| ray16(r, i)).collect();
    let slab = rays.iter().map(|p| (PacketRay16::new(p), p.tmax)).collect();
    Packets16 { rays, slab }
}

// ---------------------------------------------------------------------------------------------------
// Validation: the 16-lane twins against the renderer's 8-lane kernels, bit for bit.

fn bits16(v: f32x16) -> [u32; 16] {
    v.to_array().map(f32::to_bits)
}

/// The two 8-lane halves side by side, as 16 lanes of bits.
fn bits8x2(a: f32x8, b: f32x8) -> [u32; 16] {
    let (a, b) = (a.to_array(), b.to_array());
    std::array::from_fn(|i| if i < 8 { a[i] } else { b[i - 8] }.to_bits())
}

fn vec_bits16(v: &Vec3x16) -> [[u32; 16]; 3] {
    [bits16(v.x), bits16(v.y), bits16(v.z)]
}

fn vec_bits8x2(a: &Vec3x8, b: &Vec3x8) -> [[u32; 16]; 3] {
    [bits8x2(a.x, b.x), bits8x2(a.y, b.y), bits8x2(a.z, b.z)]
}

fn validate(p8: &Packets8, p16: &Packets16, boxes: &[Aabb], spheres: &[(Vec3, f32)]) {
    let (mut box_hits, mut sphere_hits, mut tests) = (0u64, 0u64, 0u64);
    for (k, (r16, (s16, t16))) in p16.rays.iter().zip(&p16.slab).enumerate() {
        let (ra, rb) = (&p8.rays[2 * k], &p8.rays[2 * k + 1]);
        let ((sa, ta), (sb, tb)) = (&p8.slab[2 * k], &p8.slab[2 * k + 1]);
        // The precomputed constants first: the same fold on 16 lanes must give the same bits.
        assert_eq!(vec_bits16(&r16.inv_d), vec_bits8x2(&ra.inv_d, &rb.inv_d), "inv_d, packet {k}");
        for (name, a, b, c) in [
            ("inv_lo", &s16.inv_lo, &sa.inv_lo, &sb.inv_lo),
            ("c_lo", &s16.c_lo, &sa.c_lo, &sb.c_lo),
            ("inv_hi", &s16.inv_hi, &sa.inv_hi, &sb.inv_hi),
            ("c_hi", &s16.c_hi, &sa.c_hi, &sb.c_hi),
        ] {
            assert_eq!(vec_bits16(a), vec_bits8x2(b, c), "{name}, packet {k}");
        }
        assert_eq!(bits16(*t16), bits8x2(*ta, *tb));
        for (j, bx) in boxes.iter().enumerate() {
            let (tn16, m16) = intersect_aabb_x16(bx.min, bx.max, s16, *t16);
            let (tna, ma) = intersect_aabb_x8(bx.min, bx.max, sa, *ta);
            let (tnb, mb) = intersect_aabb_x8(bx.min, bx.max, sb, *tb);
            let m8 = ma.to_bitmask() | (mb.to_bitmask() << 8);
            assert_eq!(m16.to_bitmask(), m8, "slab hit mask, packet {k}, box {j}");
            assert_eq!(bits16(tn16), bits8x2(tna, tnb), "slab tnear, packet {k}, box {j}");
            box_hits += m8.count_ones() as u64;
        }
        for (j, &(c, rad)) in spheres.iter().enumerate() {
            let t16 = intersect_sphere_x16(c, rad, r16);
            let (ta, tb) = (intersect_sphere_x8(c, rad, ra), intersect_sphere_x8(c, rad, rb));
            assert_eq!(bits16(t16), bits8x2(ta, tb), "sphere t, packet {k}, sphere {j}");
            sphere_hits += t16.simd_lt(f32x16::splat(MISS)).to_bitmask().count_ones() as u64;
        }
        tests += 16 * boxes.len() as u64;
    }
    let (fb, fs) = (box_hits as f64 / tests as f64, sphere_hits as f64 / tests as f64);
    println!(
        "lanes validation: {tests} ray-box and {tests} ray-sphere tests, 16 lanes == 8 lanes bit for bit \
         (slab constants, tnear, masks, sphere t); hit rates: boxes {:.2}%, spheres {:.2}%",
        100.0 * fb,
        100.0 * fs
    );
    // Both outcomes must be exercised, or "identical" says little.
    assert!(fb > 0.005 && fb < 0.995 && fs > 0.005 && fs < 0.995);
}

// ---------------------------------------------------------------------------------------------------
// Timed loops: every packet against every primitive; hit counts and a sum of distances are kept so
// that no test can be skipped. Not inlined, so that each width is its own symbol in the disassembly.

#[inline(never)]
fn slab_run_x8(packets: &[(PacketRay, f32x8)], boxes: &[Aabb]) -> (u64, f32) {
    let (mut hits, mut acc) = (0u64, f32x8::ZERO);
    for (pr, tmax) in packets {
        for b in boxes {
            let (tn, m) = intersect_aabb_x8(b.min, b.max, pr, *tmax);
            hits += m.to_bitmask().count_ones() as u64;
            acc += m & tn;
        }
    }
    (hits, acc.reduce_add())
}

#[inline(never)]
fn slab_run_x16(packets: &[(PacketRay16, f32x16)], boxes: &[Aabb]) -> (u64, f32) {
    let (mut hits, mut acc) = (0u64, f32x16::ZERO);
    for (pr, tmax) in packets {
        for b in boxes {
            let (tn, m) = intersect_aabb_x16(b.min, b.max, pr, *tmax);
            hits += m.to_bitmask().count_ones() as u64;
            acc += m & tn;
        }
    }
    (hits, acc.reduce_add())
}

#[inline(never)]
fn sphere_run_x8(packets: &[Ray8], spheres: &[(Vec3, f32)]) -> (u64, f32) {
    let (mut hits, mut acc) = (0u64, f32x8::ZERO);
    let miss = f32x8::splat(MISS);
    for r in packets {
        for &(c, rad) in spheres {
            let t = intersect_sphere_x8(c, rad, r);
            let m = t.simd_lt(miss);
            hits += m.to_bitmask().count_ones() as u64;
            acc += m & t;
        }
    }
    (hits, acc.reduce_add())
}

#[inline(never)]
fn sphere_run_x16(packets: &[Ray16], spheres: &[(Vec3, f32)]) -> (u64, f32) {
    let (mut hits, mut acc) = (0u64, f32x16::ZERO);
    let miss = f32x16::splat(MISS);
    for r in packets {
        for &(c, rad) in spheres {
            let t = intersect_sphere_x16(c, rad, r);
            let m = t.simd_lt(miss);
            hits += m.to_bitmask().count_ones() as u64;
            acc += m & t;
        }
    }
    (hits, acc.reduce_add())
}

fn sum(a: (u64, f32), b: (u64, f32)) -> (u64, f32) {
    (a.0 + b.0, a.1 + b.1)
}

fn bench_lanes(c: &mut Criterion) {
    let mut rng = Uniform(rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(16));
    let (boxes, spheres) = scene(&mut rng);
    let rays = rays(&mut rng, &boxes);
    let (p8, p16) = (packets8(&rays), packets16(&rays));
    validate(&p8, &p16, &boxes, &spheres);
    // The timed loops must agree with each other too (same hit counts).
    assert_eq!(slab_run_x8(&p8.slab, &boxes).0, slab_run_x16(&p16.slab, &boxes).0);
    assert_eq!(sphere_run_x8(&p8.rays, &spheres).0, sphere_run_x16(&p16.rays, &spheres).0);

    let tests = (RAYS * PRIMS) as u64;
    {
        let mut g = c.benchmark_group("lanes_1thread");
        g.throughput(Throughput::Elements(tests));
        g.sample_size(20);
        g.bench_function("slab_x8", |b| b.iter(|| slab_run_x8(black_box(&p8.slab), black_box(&boxes))));
        g.bench_function("slab_x16", |b| b.iter(|| slab_run_x16(black_box(&p16.slab), black_box(&boxes))));
        g.bench_function("sphere_x8", |b| b.iter(|| sphere_run_x8(black_box(&p8.rays), black_box(&spheres))));
        g.bench_function("sphere_x16", |b| b.iter(|| sphere_run_x16(black_box(&p16.rays), black_box(&spheres))));
        g.finish();
    }
    let pool = support::pool();
    let zero = || (0u64, 0f32);
    let mut g = c.benchmark_group(format!("lanes_{}threads", support::THREADS));
    g.throughput(Throughput::Elements(tests));
    g.sample_size(20);
    g.bench_function("slab_x8", |b| {
        b.iter(|| {
            pool.install(|| black_box(&p8.slab).par_chunks(TASK_RAYS / 8).map(|s| slab_run_x8(s, black_box(&boxes))).reduce(zero, sum))
        })
    });
    g.bench_function("slab_x16", |b| {
        b.iter(|| {
            pool.install(|| black_box(&p16.slab).par_chunks(TASK_RAYS / 16).map(|s| slab_run_x16(s, black_box(&boxes))).reduce(zero, sum))
        })
    });
    g.bench_function("sphere_x8", |b| {
        b.iter(|| {
            pool.install(|| black_box(&p8.rays).par_chunks(TASK_RAYS / 8).map(|s| sphere_run_x8(s, black_box(&spheres))).reduce(zero, sum))
        })
    });
    g.bench_function("sphere_x16", |b| {
        b.iter(|| {
            pool.install(|| {
                black_box(&p16.rays).par_chunks(TASK_RAYS / 16).map(|s| sphere_run_x16(s, black_box(&spheres))).reduce(zero, sum)
            })
        })
    });
    g.finish();
}

criterion_group!(benches, bench_lanes);
criterion_main!(benches);
