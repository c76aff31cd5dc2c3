//! Geometry kernels against their f64 twins on seeded random rays (this file), edge and precision
//! cases (`kernels/edge.rs`), spawn offsets and normals (`kernels/spawn.rs`).

use glam::{Affine3A, DVec3, Mat3, Quat, Vec3};
use rand_core::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use strata::geometry::*;
use strata::simd::{f32x8, Ray8, Vec3x8, LANES};

// The edge-case and spawn/normal tests live in submodules of this test crate (a directory that
// cargo does not pick up as separate test targets).
#[path = "kernels/edge.rs"]
mod edge;
#[path = "kernels/spawn.rs"]
mod spawn;

// ---------------------------------------------------------------------------------------------
// Helpers

struct R(Xoshiro256PlusPlus);

impl R {
    fn new(seed: u64) -> R {
        R(Xoshiro256PlusPlus::seed_from_u64(seed))
    }
    fn u(&mut self) -> f64 {
        (self.0.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
    fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.u()
    }
    fn f(&mut self, a: f32, b: f32) -> f32 {
        self.range(a as f64, b as f64) as f32
    }
    fn log_range(&mut self, a: f64, b: f64) -> f64 {
        (a.ln() + (b.ln() - a.ln()) * self.u()).exp()
    }
    fn chance(&mut self, p: f64) -> bool {
        self.u() < p
    }
    fn unit64(&mut self) -> DVec3 {
        let z = self.range(-1.0, 1.0);
        let phi = self.range(0.0, std::f64::consts::TAU);
        let s = (1.0 - z * z).sqrt();
        DVec3::new(s * phi.cos(), s * phi.sin(), z)
    }
    fn unit(&mut self) -> Vec3 {
        self.unit64().as_vec3()
    }
    fn cube(&mut self, h: f32) -> Vec3 {
        Vec3::new(self.f(-h, h), self.f(-h, h), self.f(-h, h))
    }
    fn ball(&mut self, r: f32) -> Vec3 {
        self.unit() * (r * (self.u() as f32).cbrt())
    }
    fn quat(&mut self) -> Quat {
        Quat::from_axis_angle(self.unit(), self.f(0.0, std::f32::consts::TAU))
    }
    /// A general (sheared, non-uniformly scaled) linear map with singular values in [lo, hi].
    fn linear(&mut self, lo: f32, hi: f32) -> Mat3 {
        let s = Vec3::new(self.f(lo, hi), self.f(lo, hi), self.f(lo, hi));
        Mat3::from_quat(self.quat()) * Mat3::from_diagonal(s) * Mat3::from_quat(self.quat())
    }
}

#[derive(Clone, Copy, Debug)]
struct Case {
    o: Vec3,
    d: Vec3,
    tmax: f32,
}

fn pack(c: &[Case; LANES]) -> Ray8 {
    let v = |f: &dyn Fn(&Case) -> f32| f32x8::from(std::array::from_fn::<f32, LANES, _>(|i| f(&c[i])));
    let o = Vec3x8::new(v(&|c| c.o.x), v(&|c| c.o.y), v(&|c| c.o.z));
    let d = Vec3x8::new(v(&|c| c.d.x), v(&|c| c.d.y), v(&|c| c.d.z));
    Ray8::new(o, d, v(&|c| c.tmax))
}

/// One ray in all 8 lanes.
fn one(o: Vec3, d: Vec3, tmax: f32) -> Ray8 {
    pack(&[Case { o, d, tmax }; LANES])
}

/// The common value of all lanes (they must agree bit for bit).
fn first(v: f32x8) -> f32 {
    let a = v.to_array();
    assert!(a.iter().all(|x| x.to_bits() == a[0].to_bits()), "lanes disagree: {a:?}");
    a[0]
}

fn dv(v: Vec3) -> DVec3 {
    v.as_dvec3()
}

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * b.abs().max(1e-30)
}

// ---------------------------------------------------------------------------------------------
// Random comparison harness: 8 rays per packet against one random primitive.

struct Shape<S> {
    s: S,
    center: Vec3,
    size: f32,
}

#[derive(Default)]
struct Stats {
    rays: usize,
    hits: usize,
    ambiguous: usize,
    bad: usize,
    max_rel: f64,
}

/// Origins near the shape (cube of 3 sizes) or far (10..100 sizes); 60% aimed at `target`;
/// direction lengths 0.1..10; 25% finite tmax.
fn gen_case<S>(rng: &mut R, sh: &Shape<S>, target: Vec3) -> Case {
    let o = if rng.chance(0.5) { sh.center + rng.cube(3.0 * sh.size) } else { sh.center + rng.unit() * sh.size * rng.f(10.0, 100.0) };
    let dir = if rng.chance(0.6) { (target - o).normalize() } else { rng.unit() };
    let d = dir * rng.log_range(0.1, 10.0) as f32;
    let tmax = if rng.chance(0.25) { (target - o).length() / d.length() * rng.f(0.3, 2.0) } else { f32::INFINITY };
    Case { o, d, tmax }
}

/// Runs `packets` packets; per lane, the x8 result must equal the f64 twin (same hit/miss, `t`
/// within 1e-4 relative plus `1e-6 L / |d|`, `L = |o - center| + size`) unless `amb` says the
/// f64 ray is within the 1e-4 relative band of a silhouette/edge, near `t = 0`, or near `tmax`.
#[allow(clippy::too_many_arguments)]
fn run_random<S>(
    name: &str,
    seed: u64,
    packets: usize,
    gen_shape: impl Fn(&mut R) -> Shape<S>,
    target: impl Fn(&S, &mut R) -> Vec3,
    k32: impl Fn(&S, &Ray8) -> f32x8,
    k64: impl Fn(&S, usize, DVec3, DVec3, f64) -> f64,
    amb: impl Fn(&S, usize, &Case, f64) -> bool,
) -> Stats {
    let mut rng = R::new(seed);
    let mut st = Stats::default();
    for _ in 0..packets {
        let sh = gen_shape(&mut rng);
        let cases: [Case; LANES] = std::array::from_fn(|_| {
            let t = target(&sh.s, &mut rng);
            gen_case(&mut rng, &sh, t)
        });
        let t32 = k32(&sh.s, &pack(&cases)).to_array();
        for (i, c) in cases.iter().enumerate() {
            st.rays += 1;
            let (o, d) = (dv(c.o), dv(c.d));
            let t64 = k64(&sh.s, i, o, d, c.tmax as f64);
            let t_inf = k64(&sh.s, i, o, d, f64::INFINITY);
            let l = (c.o - sh.center).length() as f64 + sh.size as f64;
            let abs_tol = 1e-6 * l / d.length();
            assert!(!t32[i].is_nan(), "{name}: NaN for {c:?}");
            st.hits += t64.is_finite() as usize;
            let near_tmax = t_inf.is_finite() && (t_inf - c.tmax as f64).abs() <= 1e-4 * t_inf + abs_tol;
            if near_tmax || amb(&sh.s, i, c, l) {
                st.ambiguous += 1;
                continue;
            }
            let ok = match (t32[i].is_finite(), t64.is_finite()) {
                (true, true) => {
                    let err = (t32[i] as f64 - t64).abs();
                    st.max_rel = st.max_rel.max(err / t64);
                    err <= 1e-4 * t64 + abs_tol
                }
                (false, false) => t32[i] == MISS,
                _ => false,
            };
            if !ok {
                st.bad += 1;
                if st.bad <= 5 {
                    eprintln!("{name}: mismatch {c:?}: x8 {} f64 {t64}", t32[i]);
                }
            }
        }
    }
    eprintln!("{name}: {} rays, {} hits, {} ambiguous, {} bad, max rel err {:.2e}", st.rays, st.hits, st.ambiguous, st.bad, st.max_rel);
    assert_eq!(st.bad, 0, "{name}: mismatches");
    assert!((st.ambiguous as f64) < 0.005 * st.rays as f64, "{name}: too many ambiguous");
    let frac = st.hits as f64 / st.rays as f64;
    assert!((0.25..0.8).contains(&frac), "{name}: hit fraction {frac}");
    st
}

const PACKETS: usize = 100_000 / LANES + 1;

/// Sphere ambiguity: line distance within 1e-4 r of r, or a root within 1e-5 L of t = 0.
fn sphere_amb(c: DVec3, r: f64, o: DVec3, d: DVec3, l: f64) -> bool {
    let f = o - c;
    let a = d.length_squared();
    let cr = f.cross(d).length_squared();
    if ((cr / a).sqrt() - r).abs() <= 1e-4 * r {
        return true;
    }
    let disc = a * r * r - cr;
    disc >= 0.0 && {
        let b = f.dot(d);
        let near0 = |t: f64| (t * d.length()).abs() <= 1e-5 * l;
        near0((-b - disc.sqrt()) / a) || near0((-b + disc.sqrt()) / a)
    }
}

/// Planar ambiguity: grazing (|cos| < 1e-3) or origin within 1e-5 L of the plane.
fn planar_amb(n: DVec3, p0: DVec3, o: DVec3, d: DVec3, l: f64) -> bool {
    let n = n.normalize();
    (n.dot(d) / d.length()).abs() < 1e-3 || n.dot(o - p0).abs() <= 1e-5 * l
}

// ---------------------------------------------------------------------------------------------
// Random rays against every kernel

#[test]
fn random_sphere() {
    run_random(
        "sphere",
        1,
        PACKETS,
        |r| {
            let c = r.cube(10.0);
            let rad = r.log_range(0.05, 5.0) as f32;
            Shape { s: (c, rad), center: c, size: rad }
        },
        |&(c, rad), r| c + r.ball(1.2 * rad),
        |&(c, rad), ray| intersect_sphere_x8(c, rad, ray),
        |&(c, rad), _, o, d, tmax| intersect_sphere_f64(dv(c), rad as f64, o, d, tmax),
        |&(c, rad), _, k, l| sphere_amb(dv(c), rad as f64, dv(k.o), dv(k.d), l),
    );
}

#[test]
fn random_sphere_moving() {
    run_random(
        "moving sphere",
        2,
        PACKETS,
        |r| {
            let c0 = r.cube(10.0);
            let v = r.unit() * r.f(0.0, 3.0);
            let rad = r.log_range(0.05, 5.0) as f32;
            let times: [f32; LANES] = std::array::from_fn(|_| r.f(0.0, 1.0));
            // The shape's centre for ray generation: mid-time.
            Shape { s: (c0, v, rad, times), center: c0 + v * 0.5, size: rad + v.length() }
        },
        |&(c0, v, rad, _), r| c0 + v * r.f(0.0, 1.0) + r.ball(1.2 * rad),
        |&(c0, v, rad, times), ray| intersect_sphere_moving_x8(c0, v, rad, ray, f32x8::from(times)),
        |&(c0, v, rad, times), i, o, d, tmax| intersect_sphere_f64(dv(c0) + dv(v) * times[i] as f64, rad as f64, o, d, tmax),
        |&(c0, v, rad, times), i, k, l| sphere_amb(dv(c0) + dv(v) * times[i] as f64, rad as f64, dv(k.o), dv(k.d), l),
    );
}

#[test]
fn random_plane() {
    run_random(
        "plane",
        3,
        PACKETS,
        |r| {
            let p0 = r.cube(5.0);
            let n = r.unit() * r.f(0.5, 2.0);
            Shape { s: (Plane { normal: n, offset: n.dot(p0) }, p0), center: p0, size: 5.0 }
        },
        |&(p, p0), r| {
            let t = r.unit();
            p0 + (t - p.normal.normalize() * t.dot(p.normal.normalize())) * r.f(0.0, 5.0)
        },
        |(p, _), ray| intersect_plane_x8(p, ray),
        |(p, _), _, o, d, tmax| intersect_plane_f64(dv(p.normal), p.offset as f64, o, d, tmax),
        |(p, _), _, k, l| {
            let n = dv(p.normal);
            // A point of the f32 plane in f64: offset n / |n|^2.
            planar_amb(n, n * (p.offset as f64 / n.length_squared()), dv(k.o), dv(k.d), l)
        },
    );
}

#[test]
fn random_quad() {
    run_random(
        "quad",
        4,
        PACKETS,
        |r| loop {
            let (org, u, v) = (r.cube(5.0), r.unit() * r.log_range(0.2, 5.0) as f32, r.unit() * r.log_range(0.2, 5.0) as f32);
            if u.normalize().dot(v.normalize()).abs() < 0.95 {
                let q = Quad::new(org, u, v);
                break Shape { s: q, center: org + 0.5 * (u + v), size: 0.5 * (u.length() + v.length()) };
            }
        },
        |q, r| q.origin + q.u * r.f(-0.1, 1.1) + q.v * r.f(-0.1, 1.1),
        intersect_quad_x8,
        |q, _, o, d, tmax| intersect_quad_f64(dv(q.origin), dv(q.u), dv(q.v), o, d, tmax),
        |q, _, k, l| {
            let (org, u, v, o, d) = (dv(q.origin), dv(q.u), dv(q.v), dv(k.o), dv(k.d));
            let n = u.cross(v);
            if planar_amb(n, org, o, d, l) {
                return true;
            }
            // In-plane coordinates of the unbounded plane hit, from the f64 dual basis.
            let p = o + d * (n.dot(org - o) / n.dot(d)) - org;
            let (a, b) = (p.dot(v.cross(n)) / n.length_squared(), p.dot(n.cross(u)) / n.length_squared());
            // World distance from the hit point to each edge line within 1e-4 size + 2e-6 L (the
            // in-plane coordinates of a hit from distance L carry an error ~eps L).
            let band = 1e-4 * (l - (k.o - (q.origin + 0.5 * (q.u + q.v))).length() as f64) + 2e-6 * l;
            let area = n.length();
            let (ba, bb) = (band * v.length() / area, band * u.length() / area);
            let near_edge = |x: f64, bx: f64, y: f64, by: f64| (x.abs() <= bx || (x - 1.0).abs() <= bx) && (-by..=1.0 + by).contains(&y);
            near_edge(a, ba, b, bb) || near_edge(b, bb, a, ba)
        },
    );
}

#[test]
fn random_disk() {
    run_random(
        "disk",
        5,
        PACKETS,
        |r| {
            let k = Disk::new(r.cube(5.0), r.unit(), r.log_range(0.1, 5.0) as f32);
            Shape { s: k, center: k.center, size: k.radius }
        },
        |k, r| {
            let t = r.unit();
            let t = (t - k.normal * t.dot(k.normal)).normalize();
            k.center + t * k.radius * r.f(0.0, 1.3)
        },
        intersect_disk_x8,
        |k, _, o, d, tmax| intersect_disk_f64(dv(k.center), dv(k.normal), k.radius as f64, o, d, tmax),
        |k, _, c, l| {
            let (ctr, n, o, d, r) = (dv(k.center), dv(k.normal), dv(c.o), dv(c.d), k.radius as f64);
            if planar_amb(n, ctr, o, d, l) {
                return true;
            }
            let p = o + d * (n.dot(ctr - o) / n.dot(d));
            ((p - ctr).length() - r).abs() <= 1e-4 * r
        },
    );
}

fn random_obox(r: &mut R) -> (OBox, Affine3A) {
    let o2w = Affine3A::from_mat3_translation(r.linear(0.3, 3.0), r.cube(10.0));
    let half = Vec3::new(r.f(0.2, 2.0), r.f(0.2, 2.0), r.f(0.2, 2.0));
    (OBox::new(o2w, half), o2w)
}

/// Object-space slabs in f64: entry, exit, the slab binding each (3 = none) and `d'`.
fn obox_slabs_f64(b: &OBox, o: Vec3, d: Vec3) -> (f64, f64, usize, usize, DVec3) {
    let w = b.world_to_object_f64();
    let (oo, dd, h) = (w.transform_point3(dv(o)), w.transform_vector3(dv(d)), dv(b.half));
    let (mut tn, mut tf, mut sn, mut sf) = (f64::NEG_INFINITY, f64::INFINITY, 3, 3);
    for i in 0..3 {
        let (t1, t2) = ((-h[i] - oo[i]) / dd[i], (h[i] - oo[i]) / dd[i]);
        if t1.min(t2) > tn {
            (tn, sn) = (t1.min(t2), i);
        }
        if t1.max(t2) < tf {
            (tf, sf) = (t1.max(t2), i);
        }
    }
    (tn, tf, sn, sf, dd)
}

#[test]
fn random_obox_rays() {
    run_random(
        "obox",
        6,
        PACKETS,
        |r| {
            let (b, o2w) = random_obox(r);
            let size = (0..8)
                .map(|i| {
                    let s = Vec3::new([-1.0, 1.0][i & 1], [-1.0, 1.0][(i >> 1) & 1], [-1.0, 1.0][i >> 2]);
                    o2w.transform_vector3(s * b.half).length()
                })
                .fold(0.0, f32::max);
            Shape { s: (b, o2w), center: b.center, size }
        },
        |&(b, o2w), r| o2w.transform_point3(r.cube(1.2) * b.half),
        |(b, _), ray| intersect_obox_x8(b, ray),
        |(b, _), _, o, d, tmax| intersect_obox_f64(b.world_to_object_f64(), dv(b.half), o, d, tmax),
        |(b, _), _, c, l| {
            let (tn, tf, sn, sf, dd) = obox_slabs_f64(b, c.o, c.d);
            let dl = dv(c.d).length();
            let size = l - (c.o - b.center).length() as f64;
            let graze = |s: usize| s < 3 && dd[s].abs() < 1e-3 * dd.length();
            ((tn - tf) * dl).abs() <= 1e-4 * size
                || (tn * dl).abs() <= 1e-5 * l
                || (tf * dl).abs() <= 1e-5 * l
                || graze(if tn > 0.0 { sn } else { sf })
        },
    );
}

#[test]
fn random_ellipsoid() {
    run_random(
        "ellipsoid",
        7,
        PACKETS,
        |r| {
            let m = r.linear(0.3, 3.0);
            let o2w = Affine3A::from_mat3_translation(m, r.cube(10.0));
            let size = m.x_axis.length().max(m.y_axis.length()).max(m.z_axis.length()) * 1.8;
            Shape { s: (Ellipsoid::new(o2w), o2w), center: o2w.translation.into(), size }
        },
        |&(_, o2w), r| o2w.transform_point3(r.ball(1.2)),
        |(e, _), ray| intersect_ellipsoid_x8(e, ray),
        |(e, _), _, o, d, tmax| intersect_ellipsoid_f64(e.world_to_object_f64(), o, d, tmax),
        |(e, _), _, c, l| {
            let w = e.world_to_object_f64();
            let (oo, dd) = (w.transform_point3(dv(c.o)), w.transform_vector3(dv(c.d)));
            // Object-space sphere band; roots near 0 measured in world length.
            let s = dv(c.d).length() / dd.length();
            sphere_amb(DVec3::ZERO, 1.0, oo, dd, l / s)
        },
    );
}
