//! Spheres (static and moving): the stable f32x8 kernel, its f64 textbook twin, normals and
//! hit-point refinement.
//!
//! Notation: ray `o + t d`, centre `c`, radius `r`, `f = o - c`. With the half-b form
//! `a t^2 + 2 b t + c0 = 0`: `a = d.d`, `b = f.d`, `c0 = f.f - r^2`.

use super::{finish_x8, nearest_f64, two_diff_x8, two_sum, valid_f64, MISS};
use crate::simd::{f32x8, Lanes, Ray8, Vec3x8};
use glam::{DVec3, Vec3};

/// Tangent rule for spheres and ellipsoids, in units of `r^2`: a computed `r^2 - |l|^2` in
/// `[-GRAZE r^2, 0)` (`l` = perpendicular from the centre to the ray line) is within the rounding
/// error of the kernel (about `4 eps r^2`), so it is clamped to 0 and the ray HITS at the double
/// root (the tangent point). Below `-GRAZE r^2` it misses. So a ray that is tangent in exact
/// arithmetic consistently hits, with finite `t`; a ray that clears the sphere by more than about
/// `4 eps r` (relative gap `GRAZE / 2`) consistently misses.
pub const GRAZE: f32 = 8.0 * f32::EPSILON;

/// Static sphere, nearest hit in `(0, tmax)`.
///
/// Haines, Guenther & Akenine-Moeller, "Precision Improvements for Ray/Sphere Intersection",
/// Ray Tracing Gems ch. 7 (2019): the discriminant from the perpendicular `l = f - (f.d/d.d) d`
/// (`b^2 - a c0 = a (r^2 - |l|^2)`, no cancellation of two huge squares for a small distant
/// sphere) and the roots `c0 / q`, `q / a` with `q = -(b + sign(b) sqrt(b^2 - a c0))` (no
/// cancellation in `-b +- sqrt`). On top of the paper, `f` is split exactly into `s + e` (TwoSum)
/// and `c0 = |f|^2 - r^2` is evaluated with exact FMA products and TwoSum (Ogita, Rump & Oishi,
/// "Accurate Sum and Dot Product", 2005): the near root `c0 / q` of a ray starting just above a
/// huge sphere (ground sphere, radius 1e4) inherits the relative error of `c0`, which in plain
/// f32 is `~eps r / h` for an origin at height `h`; compensated it is `~eps`. The tail `e` also
/// goes into `l`, so a sphere seen from `1e5` radii away keeps its silhouette to `~1e-5 r`.
/// Measured (tests): `t` within ~2e-6 relative of the f64 twin in general position, within 2e-5
/// for rays grazing a radius-1e4 sphere from just above it (the `eps r^2` rounding of `|l|^2`).
/// Cost: the compensation roughly doubles the lane flops (~50 extra; 2 divisions + 1 sqrt as before).
///
/// Origin on the surface: the compensated `c0` decides on which side the f32 origin lies. From
/// outside (or exactly on it) an outgoing ray misses and an incoming ray reports the far root
/// (the chord); from a hair inside, an outgoing ray reports its short exit (`t ~ |c0| / (2 |b|)`,
/// up to `~sqrt(r |c0|) / |d|` for grazing directions). Spawn with `offset_ray_origin`.
#[inline]
pub fn intersect_sphere_x8(center: Vec3, radius: f32, ray: &Ray8) -> f32x8 {
    sphere_x8(Vec3x8::splat(center), radius, ray)
}

/// Moving sphere: centre `center0 + velocity * time` (per lane, one FMA), then exactly the static
/// kernel (same citation). `time` is the ray's time sample.
#[inline]
pub fn intersect_sphere_moving_x8(center0: Vec3, velocity: Vec3, radius: f32, ray: &Ray8, time: f32x8) -> f32x8 {
    let c = Vec3x8::splat(velocity).mul_add(time, Vec3x8::splat(center0));
    sphere_x8(c, radius, ray)
}

/// The two roots of the sphere kernel and the lanes that hit (None: no lane does).
#[inline(always)]
fn sphere_roots_x8(c: Vec3x8, radius: f32, ray: &Ray8) -> Option<(f32x8, f32x8, f32x8)> {
    let k = SphereConsts::of(radius);
    sphere_roots_lanes_x8(c, f32x8::splat(k.r2), f32x8::splat(k.r2_lo), f32x8::splat(k.graze), ray)
}

/// A sphere's radius terms as the kernel uses them: `r^2 = r2 + r2_lo` exactly, and the tangent
/// rule's bound `-GRAZE r2` (one place computes them, so that spheres in lanes take the same bits).
#[derive(Clone, Copy, Debug)]
pub struct SphereConsts {
    pub r2: f32,
    pub r2_lo: f32,
    pub graze: f32,
}

impl SphereConsts {
    #[inline(always)]
    pub fn of(radius: f32) -> Self {
        let r2 = radius * radius;
        SphereConsts { r2, r2_lo: radius.mul_add(radius, -r2), graze: -GRAZE * r2 }
    }
}

/// [`sphere_roots_x8`] with a radius per lane (`r2`, `r2_lo`, `graze` of [`SphereConsts`]): lanes may
/// be different spheres. Every operation is lane-wise, so a lane's result is the one-sphere kernel's.
#[inline(always)]
fn sphere_roots_lanes_x8(c: Vec3x8, r2v: f32x8, r2_lo: f32x8, graze: f32x8, ray: &Ray8) -> Option<(f32x8, f32x8, f32x8)> {
    let d = ray.d;
    // f = o - c = s + e exactly; s alone carries the rounding error eps |f| that would otherwise
    // dominate c0 near a large sphere.
    let (sx, ex) = two_diff_x8(ray.o.x, c.x);
    let (sy, ey) = two_diff_x8(ray.o.y, c.y);
    let (sz, ez) = two_diff_x8(ray.o.z, c.z);
    let s = Vec3x8::new(sx, sy, sz);
    let e = Vec3x8::new(ex, ey, ez);

    let a = d.dot(d);
    let inv_a = f32x8::ONE / a;
    let b = s.dot(d);
    // l = f - (b/a) d: the FMA makes each product exact, so l is accurate to eps |l| plus a
    // component along d (the error of b/a) that adds only its square to |l|^2.
    let k = b * inv_a;
    let l = Vec3x8::new(k.mul_neg_add(d.x, sx) + ex, k.mul_neg_add(d.y, sy) + ey, k.mul_neg_add(d.z, sz) + ez);
    // disc = r^2 - |l|^2 = (b^2 - a c0) / a.
    let disc = l.x.mul_neg_add(l.x, l.y.mul_neg_add(l.y, l.z.mul_neg_add(l.z, r2v)));
    let hit = disc.simd_ge(graze);
    if !hit.any() {
        // Every lane passes outside the sphere (the usual case for a packet at a sphere's silhouette
        // or a box corner): the accurate constant term and the roots are not needed.
        return None;
    }
    let c0 = dist2_minus_r2_x8(s, e, r2v, r2_lo);
    let (near, far) = roots_x8(a, inv_a, b, disc, c0);
    Some((near, far, hit))
}

/// Up to 8 static spheres (one per lane: centre `c`, radius terms of [`SphereConsts`]) against one
/// ray held in every lane of `ray`: per lane, the nearest hit in `(0, tmax)` or MISS, bit for bit what
/// [`intersect_sphere_x8`] gives that ray against that sphere.
#[inline(always)]
pub fn spheres_lanes_x8(c: Vec3x8, r2: f32x8, r2_lo: f32x8, graze: f32x8, ray: &Ray8) -> f32x8 {
    match sphere_roots_lanes_x8(c, r2, r2_lo, graze, ray) {
        Some((near, far, hit)) => finish_x8(nearest_x8(near, far), hit, ray),
        None => f32x8::splat(MISS),
    }
}

#[inline(always)]
fn sphere_x8(c: Vec3x8, radius: f32, ray: &Ray8) -> f32x8 {
    match sphere_roots_x8(c, radius, ray) {
        Some((near, far, hit)) => finish_x8(nearest_x8(near, far), hit, ray),
        None => f32x8::splat(MISS),
    }
}

/// The terms of the sphere kernel that depend on the packet only (`a = d.d`, `1 / a`, and the
/// finite-ray mask of `finish_x8`), for any-hit tests of many spheres against one packet
/// ([`occludes_sphere_x8`]); `F` the lane type (8 lanes, or 16 for two packets at once).
#[derive(Clone, Copy, Debug)]
pub struct SpherePacketOf<F> {
    a: F,
    inv_a: F,
    finite: F,
}

/// [`SpherePacketOf`] of one 8-lane packet.
pub type SpherePacket = SpherePacketOf<f32x8>;

impl SpherePacket {
    #[inline(always)]
    pub fn new(ray: &Ray8) -> Self {
        SpherePacketOf::of([ray.o.x, ray.o.y, ray.o.z], [ray.d.x, ray.d.y, ray.d.z])
    }

    /// Lane `l`'s terms in all 8 lanes: the terms of lane `l`'s ray splatted (the operations are
    /// lane-wise, so the bits are the same).
    #[inline(always)]
    pub fn lane(&self, l: usize) -> Self {
        let at = |v: f32x8| f32x8::splat(v.to_array()[l]);
        SpherePacket { a: at(self.a), inv_a: at(self.inv_a), finite: at(self.finite) }
    }
}

impl<F: Lanes> SpherePacketOf<F> {
    /// From the rays' origins and directions by axis (the same operations as [`SpherePacket::new`]).
    #[inline(always)]
    pub fn of(o: [F; 3], d: [F; 3]) -> Self {
        let a = d[0].mul_add(d[0], d[1].mul_add(d[1], d[2] * d[2]));
        SpherePacketOf { a, inv_a: F::splat(1.0) / a, finite: super::ray_finite(o, d) }
    }

    /// The rays' finite mask ([`ray_finite`](super::ray_finite)), which every kernel's tail takes.
    #[inline(always)]
    pub fn finite(&self) -> F {
        self.finite
    }
}

/// Any-hit twin of the sphere kernel: the lanes whose nearest hit lies in `(0, tmax)`, exactly
/// `intersect_sphere_x8(center, radius, ray).simd_lt(ray.tmax)` (the same operations in the same
/// order; `pk` from [`SpherePacket::new`] of this `ray`), at less cost: the packet's terms come from
/// `pk`, and the square root and both divisions are skipped when every lane that meets the sphere's
/// line starts outside it (`c0 >= 0`) and moves away from its centre (`b > 0`): then `q <= -b < 0`,
/// so `c0 / q <= 0` and `q / a < 0`, and no root is positive (the usual case of a shadow ray leaving
/// the sphere it starts on, and of spheres behind it).
#[inline(always)]
pub fn occludes_sphere_x8(center: Vec3, radius: f32, ray: &Ray8, pk: &SpherePacket) -> f32x8 {
    occludes_sphere([ray.o.x, ray.o.y, ray.o.z], [ray.d.x, ray.d.y, ray.d.z], ray.tmax, center, radius, pk)
}

/// [`occludes_sphere_x8`] at any lane width (rays by axis: origins `o`, directions `d`, `tmax`; `pk`
/// of these rays). Lane-wise operations only, so each lane's verdict is the 8-lane twin's.
#[inline(always)]
pub fn occludes_sphere<F: Lanes>(o: [F; 3], d: [F; 3], tmax: F, center: Vec3, radius: f32, pk: &SpherePacketOf<F>) -> F {
    occludes_sphere_consts(o, d, tmax, center, SphereConsts::of(radius), pk)
}

/// [`occludes_sphere`] from the radius terms of [`SphereConsts`] (as kept per leaf slot in
/// `scene::LeafSpheres`): the same operations, hence the same lanes.
#[inline(always)]
pub fn occludes_sphere_consts<F: Lanes>(o: [F; 3], d: [F; 3], tmax: F, center: Vec3, k: SphereConsts, pk: &SpherePacketOf<F>) -> F {
    let c = [F::splat(center.x), F::splat(center.y), F::splat(center.z)];
    occludes_spheres_lanes(o, d, tmax, c, [F::splat(k.r2), F::splat(k.r2_lo), F::splat(k.graze)], pk)
}

/// [`occludes_sphere_consts`] with a sphere per lane (centres `c` by axis; `k` = the lanes' `r2`,
/// `r2_lo` and `graze` of [`SphereConsts`]): lane-wise operations only, so a lane's verdict is the
/// one-sphere twin's for that sphere, hence `spheres_lanes_x8(..) < tmax` of the closest-hit kernel
/// (the any-hit leaf test of one ray against a leaf's spheres in lanes: the ray splatted, `pk` of it).
#[inline(always)]
pub fn occludes_spheres_lanes<F: Lanes>(o: [F; 3], d: [F; 3], tmax: F, c: [F; 3], k: [F; 3], pk: &SpherePacketOf<F>) -> F {
    let none = F::splat(0.0);
    let [r2, r2_lo, graze] = k;
    let (sx, ex) = two_sum(o[0], -c[0]);
    let (sy, ey) = two_sum(o[1], -c[1]);
    let (sz, ez) = two_sum(o[2], -c[2]);
    let b = sx.mul_add(d[0], sy.mul_add(d[1], sz * d[2]));
    let kk = b * pk.inv_a;
    let l = [kk.mul_neg_add(d[0], sx) + ex, kk.mul_neg_add(d[1], sy) + ey, kk.mul_neg_add(d[2], sz) + ez];
    let disc = l[0].mul_neg_add(l[0], l[1].mul_neg_add(l[1], l[2].mul_neg_add(l[2], r2)));
    let hit = disc.ge(graze) & pk.finite & tmax.gt(none);
    if !hit.any() {
        return none;
    }
    let c0 = dist2_minus_r2([sx, sy, sz], [ex, ey, ez], r2, r2_lo);
    let away = b.gt(none) & c0.ge(none);
    if !(hit & !away).any() {
        return none;
    }
    let (near, far) = roots(pk.a, pk.inv_a, b, disc, c0);
    let t = near.gt(none).select(near, far);
    hit & t.gt(none) & t.lt(tmax)
}

/// Both crossings of the sphere's surface along the packet, `(entry, exit)` by distance (any sign;
/// NaN where a lane misses), with the same arithmetic as [`intersect_sphere_x8`] (whose hit is the
/// nearest positive one of them, within `(0, tmax)`).
#[inline]
pub fn sphere_interval_x8(center: Vec3, radius: f32, ray: &Ray8) -> (f32x8, f32x8) {
    match sphere_roots_x8(Vec3x8::splat(center), radius, ray) {
        Some((near, far, hit)) => (hit.select(near, f32x8::splat(f32::NAN)), hit.select(far, f32x8::splat(f32::NAN))),
        None => (f32x8::splat(f32::NAN), f32x8::splat(f32::NAN)),
    }
}

/// `|s + e|^2 - (r2 + r2_lo)` to about `eps` relative even when it cancels: squares split exactly
/// by FMA (TwoProduct), their sum by TwoSum; the leading subtraction `w - r2` is then exact by
/// Sterbenz's lemma whenever it cancels (`r2/2 <= w <= 2 r2`), and everything else is tiny.
#[inline(always)]
fn dist2_minus_r2_x8(s: Vec3x8, e: Vec3x8, r2: f32x8, r2_lo: f32x8) -> f32x8 {
    dist2_minus_r2([s.x, s.y, s.z], [e.x, e.y, e.z], r2, r2_lo)
}

/// [`dist2_minus_r2_x8`] at any lane width (`s`, `e` by axis).
#[inline(always)]
fn dist2_minus_r2<F: Lanes>(s: [F; 3], e: [F; 3], r2: F, r2_lo: F) -> F {
    let (px, py, pz) = (s[0] * s[0], s[1] * s[1], s[2] * s[2]);
    let pi = s[0].mul_sub(s[0], px) + s[1].mul_sub(s[1], py) + s[2].mul_sub(s[2], pz);
    let (u, eu) = two_sum(px, py);
    let (w, ew) = two_sum(u, pz);
    let two = F::splat(2.0);
    // (s + e)^2 - s^2 = e (2 s + e), per component.
    let cross = e[0].mul_add(s[0].mul_add(two, e[0]), e[1].mul_add(s[1].mul_add(two, e[1]), e[2] * s[2].mul_add(two, e[2])));
    (w - r2) + (((eu + ew) + pi) + (cross - r2_lo))
}

/// Both roots of `a t^2 + 2 b t + c0 = 0` as (smaller, larger), given `disc = (b^2 - a c0) / a`
/// (clamped at 0 here; the caller's mask decides hit or miss): `c0 / q` and `q / a` with
/// `q = -(b + sign(b) sqrt(b^2 - a c0))` (Haines et al. 2019, after Press et al., Numerical Recipes
/// 5.6). [`nearest_x8`] then takes the nearest in `t > 0` (or a value that fails `t > 0` or is +inf,
/// which `finish_x8` turns into MISS).
#[inline(always)]
pub(super) fn roots_x8(a: f32x8, inv_a: f32x8, b: f32x8, disc: f32x8, c0: f32x8) -> (f32x8, f32x8) {
    roots(a, inv_a, b, disc, c0)
}

/// [`roots_x8`] at any lane width.
#[inline(always)]
fn roots<F: Lanes>(a: F, inv_a: F, b: F, disc: F, c0: F) -> (F, F) {
    let h = (disc.max(F::splat(0.0)) * a).sqrt();
    let sign_b = b & F::splat(-0.0);
    let q = -(b + (h | sign_b)); // h >= 0, so `h | sign(b)` is copysign(h, b)
    let t0 = c0 / q;
    let t1 = q * inv_a;
    // min/max skip a NaN operand (t0 = 0/0 only when b = h = c0 = 0: origin at a tangent point;
    // then t1 = 0 and the lane misses).
    (t0.min(t1), t0.max(t1))
}

/// The nearest positive of two roots (else the larger, which then fails the range test).
#[inline(always)]
pub(super) fn nearest_x8(near: f32x8, far: f32x8) -> f32x8 {
    near.simd_gt(f32x8::ZERO).select(near, far)
}

/// f64 twin of [`intersect_sphere_x8`], textbook form: `t = (-b -+ sqrt(b^2 - 4ac)) / 2a`
/// (e.g. Glassner (ed.), "An Introduction to Ray Tracing", 1989, ch. 2 (Haines)).
/// A negative discriminant misses; `INFINITY` on a miss.
pub fn intersect_sphere_f64(center: DVec3, radius: f64, o: DVec3, d: DVec3, tmax: f64) -> f64 {
    if !valid_f64(o, d, tmax) {
        return f64::INFINITY;
    }
    let f = o - center;
    let a = d.dot(d);
    let b = 2.0 * f.dot(d);
    let c = f.dot(f) - radius * radius;
    let disc = b * b - 4.0 * a * c;
    if disc.is_nan() || disc < 0.0 || a == 0.0 {
        return f64::INFINITY;
    }
    let sq = disc.sqrt();
    nearest_f64((-b - sq) / (2.0 * a), (-b + sq) / (2.0 * a), tmax)
}

/// Outward unit normal of the sphere at `p` (zero if `p == center`).
#[inline]
pub fn normal_sphere(center: Vec3, p: Vec3) -> Vec3 {
    (p - center).normalize_or_zero()
}

/// Re-project a computed hit point onto the sphere, along the radial direction: `p - n (|p - c| - r)`
/// with `n = (p - c) / |p - c|`. A hit point `o + t d` carries an error of about
/// `eps (|o| + |t d|)`, which for a distant origin is far more than the ULPs of `p` that
/// [`super::offset_ray_origin`] covers. The radial residual `|p - c| - r` is formed in f64 (`p - c` of
/// two f32 is exact there), so the refined point is the true sphere point rounded to f32: off the
/// surface by half an ULP of its own coordinates, whatever `|c|` and `r` are. (The textbook
/// `c + r n` is only accurate to ULPs of `|c| + r`: under a ground sphere of radius 1e4, 2000 times
/// the ULP of a hit point near the origin, which the spawn offset does not cover: acne.)
/// `p == center` is returned unchanged.
#[inline]
pub fn refine_sphere_point(center: Vec3, radius: f32, p: Vec3) -> Vec3 {
    let f = p.as_dvec3() - center.as_dvec3();
    let len = f.length();
    if !(len > 0.0) {
        return p;
    }
    let q = p.as_dvec3() - f * ((len - radius as f64) / len);
    if !q.is_finite() {
        return p;
    }
    q.as_vec3()
}

/// [`refine_sphere_point`] of 8 points at once (centres `c`, radii `r`, points `p` as lane rows), the
/// same f64 operations in the same order, in two `f64x4` halves: bit-identical to the scalar (tested).
pub fn refine_sphere_point_x8(c: &[[f32; 8]; 3], r: &[f32; 8], p: &[[f32; 8]; 3]) -> [[f32; 8]; 3] {
    use wide::f64x4;
    let mut out = *p;
    for h in 0..2 {
        let d4 = |a: &[f32; 8]| f64x4::from(std::array::from_fn::<f64, 4, _>(|i| a[4 * h + i] as f64));
        let (px, py, pz) = (d4(&p[0]), d4(&p[1]), d4(&p[2]));
        let (fx, fy, fz) = (px - d4(&c[0]), py - d4(&c[1]), pz - d4(&c[2]));
        let len = (fx * fx + fy * fy + fz * fz).sqrt();
        let s = (len - d4(r)) / len;
        let q = [px - fx * s, py - fy * s, pz - fz * s];
        // `!(len > 0)` (a point at the centre, or NaN) and a non-finite result keep the point.
        let ok = (len.simd_gt(f64x4::ZERO) & q[0].is_finite() & q[1].is_finite() & q[2].is_finite()).to_bitmask();
        for (k, qk) in q.iter().enumerate() {
            let qa = qk.to_array();
            for i in 0..4 {
                if ok & (1 << i) != 0 {
                    out[k][4 * h + i] = qa[i] as f32;
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Spheres in lanes against one ray give, lane by lane, the bits of the one-sphere kernel with the
    /// ray in every lane: random rays and spheres at scales 1e-4 to 1e5, origins on and near the
    /// surfaces, grazing rays, rays from inside, and inactive `tmax`.
    #[test]
    fn spheres_in_lanes_match_the_one_sphere_kernel() {
        let mut f = crate::sample::hash::test_uniforms(0x51f3_0e5a_11ce_0001);
        let (mut hits, mut checked, mut occluded) = (0, 0, 0);
        for round in 0..3000 {
            let scale = [1e-4f32, 1.0, 1e3, 1e5][round % 4];
            let v = |f: &mut dyn FnMut() -> f32| Vec3::new(f() - 0.5, f() - 0.5, f() - 0.5);
            let centres: [Vec3; 8] = std::array::from_fn(|_| v(&mut f) * scale * 10.0);
            let radii: [f32; 8] = std::array::from_fn(|_| (0.01 + f()) * scale);
            let mut o = v(&mut f) * scale * 20.0;
            let mut d = v(&mut f).normalize_or(Vec3::X) * (0.1 + f() * 10.0);
            match round % 5 {
                // On the surface of sphere 0, leaving it.
                0 => {
                    let n = v(&mut f).normalize_or(Vec3::Y);
                    o = centres[0] + n * radii[0];
                    d = (n + v(&mut f)).normalize_or(n);
                }
                // Aimed at the silhouette of sphere 1 (grazing).
                1 => {
                    let side = d.any_orthonormal_vector() * radii[1] * (1.0 + (f() - 0.5) * 1e-6);
                    o = centres[1] + side - d * scale * 5.0;
                }
                // Inside sphere 2.
                2 => o = centres[2] + v(&mut f) * radii[2],
                _ => {}
            }
            let tmax = [f32::INFINITY, scale * 30.0, -1.0][round % 3];
            let ray = Ray8::new(Vec3x8::splat(o), Vec3x8::splat(d), f32x8::splat(tmax));
            let k = radii.map(SphereConsts::of);
            let c = Vec3x8::new(f32x8::from(centres.map(|c| c.x)), f32x8::from(centres.map(|c| c.y)), f32x8::from(centres.map(|c| c.z)));
            let lanes =
                spheres_lanes_x8(c, f32x8::from(k.map(|k| k.r2)), f32x8::from(k.map(|k| k.r2_lo)), f32x8::from(k.map(|k| k.graze)), &ray);
            for l in 0..8 {
                let one = intersect_sphere_x8(centres[l], radii[l], &ray).to_array()[0];
                assert_eq!(lanes.to_array()[l].to_bits(), one.to_bits(), "round {round}, sphere {l}");
                hits += (one != MISS) as u32;
                checked += 1;
            }
            // The any-hit twin with spheres in lanes gives the kernel's verdict `t < tmax`, with the
            // packet terms of a packet whose lane 3 is this ray (`SpherePacket::lane`).
            let mut packet = Ray8::new(Vec3x8::splat(v(&mut f)), Vec3x8::splat(v(&mut f) * 1e3), f32x8::splat(1.0));
            for (dst, src) in [(&mut packet.o, ray.o), (&mut packet.d, ray.d)] {
                let (mut x, mut y, mut z) = (dst.x.to_array(), dst.y.to_array(), dst.z.to_array());
                (x[3], y[3], z[3]) = (src.x.to_array()[0], src.y.to_array()[0], src.z.to_array()[0]);
                *dst = Vec3x8::new(f32x8::from(x), f32x8::from(y), f32x8::from(z));
            }
            let pk = SpherePacket::new(&packet).lane(3);
            let terms = [f32x8::from(k.map(|k| k.r2)), f32x8::from(k.map(|k| k.r2_lo)), f32x8::from(k.map(|k| k.graze))];
            let occ =
                occludes_spheres_lanes([ray.o.x, ray.o.y, ray.o.z], [ray.d.x, ray.d.y, ray.d.z], ray.tmax, [c.x, c.y, c.z], terms, &pk);
            assert_eq!(occ.to_bitmask(), lanes.simd_lt(ray.tmax).to_bitmask(), "round {round}: any-hit twin");
            occluded += occ.to_bitmask().count_ones();
        }
        assert_eq!(checked, 24_000);
        assert!(hits > 500, "only {hits} hits");
        assert!(occluded > 300, "only {occluded} occluded lanes");
    }

    /// The any-hit twin gives exactly the kernel's verdict `t < tmax`: random packets at scales 1e-4
    /// to 1e5 with origins on the surface (leaving and entering), just inside and outside it, at the
    /// centre, grazing the silhouette, far away, and lanes with zero, infinite or NaN components and
    /// `tmax` of -1, 0, finite and infinite.
    #[test]
    fn any_hit_twin_gives_the_kernels_verdict() {
        let mut f = crate::sample::hash::test_uniforms(0xa11_0cc1_0de5);
        let (mut occluded, mut checked) = (0, 0);
        for round in 0..4000 {
            let scale = [1e-4f32, 1.0, 1e3, 1e5][round % 4];
            let v = |f: &mut dyn FnMut() -> f32| Vec3::new(f() - 0.5, f() - 0.5, f() - 0.5);
            let centre = v(&mut f) * scale * 10.0;
            let radius = (0.01 + f()) * scale;
            let mut rows = [[0.0f32; 8]; 7];
            for l in 0..8 {
                let n = v(&mut f).normalize_or(Vec3::Y);
                let mut d = v(&mut f).normalize_or(Vec3::X) * (0.1 + f() * 10.0);
                let on = centre + n * radius;
                let mut tmax = [f32::INFINITY, 1.0, scale * 30.0, -1.0, 0.0][(round + l) % 5];
                let o = match (round * 3 + l) % 11 {
                    0 => {
                        d = (n + v(&mut f)).normalize_or(n);
                        on
                    }
                    1 => {
                        d = -(n + v(&mut f)).normalize_or(n);
                        on
                    }
                    2 => centre + n * radius * (1.0 - 1e-6),
                    3 => centre + n * radius * (1.0 + 1e-6),
                    4 => centre,
                    5 => {
                        let side = d.any_orthonormal_vector() * radius * (1.0 + (f() - 0.5) * 1e-6);
                        centre + side - d * 5.0
                    }
                    6 => centre + v(&mut f) * scale * 1e4,
                    7 => {
                        d = Vec3::ZERO;
                        on
                    }
                    8 => {
                        d.x = [f32::INFINITY, f32::NAN][round % 2];
                        on
                    }
                    9 => {
                        tmax = f32::NAN;
                        centre + v(&mut f) * scale * 20.0
                    }
                    _ => centre + v(&mut f) * scale * 20.0,
                };
                for k in 0..3 {
                    (rows[k][l], rows[3 + k][l]) = (o[k], d[k]);
                }
                rows[6][l] = tmax;
            }
            let r = |k: usize| f32x8::from(rows[k]);
            let ray = Ray8::new(Vec3x8::new(r(0), r(1), r(2)), Vec3x8::new(r(3), r(4), r(5)), r(6));
            let want = intersect_sphere_x8(centre, radius, &ray).simd_lt(ray.tmax).to_bitmask();
            let got = occludes_sphere_x8(centre, radius, &ray, &SpherePacket::new(&ray)).to_bitmask();
            assert_eq!(got, want, "round {round}");
            // At 16 lanes (these rays beside the same rays reversed): each half the 8-lane verdict.
            let rev = |k: usize| {
                let mut a = rows[k];
                a.reverse();
                a
            };
            let wide16 = |a: [f32; 8], b: [f32; 8]| -> wide::f32x16 { bytemuck::cast([a, b]) };
            let o16 = [wide16(rows[0], rev(0)), wide16(rows[1], rev(1)), wide16(rows[2], rev(2))];
            let d16 = [wide16(rows[3], rev(3)), wide16(rows[4], rev(4)), wide16(rows[5], rev(5))];
            let t16 = wide16(rows[6], rev(6));
            let got16 = occludes_sphere(o16, d16, t16, centre, radius, &SpherePacketOf::of(o16, d16)).to_bitmask();
            let want_rev = (0..8).fold(0, |m, l| m | ((want >> (7 - l)) & 1) << l);
            assert_eq!(got16, want | want_rev << 8, "round {round}, 16 lanes");
            occluded += want.count_ones();
            checked += 8;
        }
        assert_eq!(checked, 32_000);
        assert!(occluded > 3000, "only {occluded} occluded lanes");
    }

    /// The 8-lane re-projection equals the scalar one bit for bit: random points near spheres at
    /// scales 1e-4 to 1e5, points at the centre, far off the surface, and non-finite inputs.
    #[test]
    fn refine_x8_matches_scalar() {
        let mut f = crate::sample::hash::test_uniforms(0x9e37_79b9_7f4a_7c15);
        let mut checked = 0;
        for round in 0..2000 {
            let scale = [1e-4f32, 1.0, 1e3, 1e5][round % 4];
            let (mut c, mut r, mut p) = ([[0.0f32; 8]; 3], [0.0f32; 8], [[0.0f32; 8]; 3]);
            for l in 0..8 {
                let centre = Vec3::new(f() - 0.5, f() - 0.5, f() - 0.5) * scale * 10.0;
                let radius = (0.01 + f()) * scale;
                let dir = Vec3::new(f() - 0.5, f() - 0.5, f() - 0.5).normalize_or(Vec3::X);
                let mut point = centre + dir * radius * (1.0 + (f() - 0.5) * 1e-3);
                match (round + l) % 17 {
                    0 => point = centre,
                    1 => point = centre + dir * radius * 50.0,
                    2 => point.x = f32::INFINITY,
                    3 => point.y = f32::NAN,
                    _ => {}
                }
                for k in 0..3 {
                    (c[k][l], p[k][l]) = (centre[k], point[k]);
                }
                r[l] = radius;
            }
            let got = refine_sphere_point_x8(&c, &r, &p);
            for l in 0..8 {
                let want = refine_sphere_point(Vec3::new(c[0][l], c[1][l], c[2][l]), r[l], Vec3::new(p[0][l], p[1][l], p[2][l]));
                let g = [got[0][l], got[1][l], got[2][l]];
                assert_eq!(g.map(f32::to_bits), want.to_array().map(f32::to_bits), "round {round} lane {l}");
                checked += 1;
            }
        }
        assert_eq!(checked, 16_000);
    }
}
