//! Warps of the unit square onto other domains (the lens disk).

use std::f32::consts::{FRAC_PI_4, TAU};
use wide::f32x8;

/// Shirley & Chiu 1997, "A Low Distortion Map Between Disk and Square": concentric squares of
/// `[-1, 1]^2` go to concentric circles, so the map is area-preserving (uniform in, uniform out) with
/// low distortion and keeps the stratification of the input (unlike the polar `sqrt(u0), 2 pi u1`).
/// `u` in `[0, 1)^2` maps into the closed unit disk.
#[inline]
pub fn sample_disk_concentric(u: [f32; 2]) -> [f32; 2] {
    let (r, phi) = concentric_polar(u);
    let (s, c) = phi.sin_cos();
    [r * c, r * s]
}

/// The signed radius and angle of [`sample_disk_concentric`]'s point (`(r cos phi, r sin phi)`, `r` in
/// `[-1, 1]`): for samplers that lift a disk point and take the sine and cosine themselves. The centre of
/// the square, `(0.5, 0.5)`, is the disk's centre.
#[inline(always)]
pub fn concentric_polar(u: [f32; 2]) -> (f32, f32) {
    let a = 2.0 * u[0] - 1.0;
    let b = 2.0 * u[1] - 1.0;
    // Pick the dominant axis; at the origin both are 0 and the guard keeps the ratio finite. (Selects,
    // not branches: the dominant axis is a coin toss per sample.)
    let dom = a.abs() > b.abs();
    let (r, other) = if dom { (a, b) } else { (b, a) };
    let ratio = if r != 0.0 { other / r } else { 0.0 };
    let phi = if dom {
        FRAC_PI_4 * ratio
    } else if r != 0.0 {
        2.0 * FRAC_PI_4 - FRAC_PI_4 * ratio
    } else {
        0.0
    };
    (r, phi)
}

/// Eight lanes of [`sample_disk_concentric`] (`u = [u0s, u1s]`); the branches become selects. Agrees
/// with the scalar twin to ~1e-6.
///
/// The angle is `x = (pi / 4) ratio` with `|ratio| <= 1` where `|a| > |b|`, and `pi / 2 - x` elsewhere,
/// whose cosine and sine are `x`'s sine and cosine: so only `x` in `[-pi / 4, pi / 4]` needs its sine and
/// cosine ([`sin_cos_quarter_x8`]), and no lane needs a general `sin_cos`'s range reduction (nor the
/// rounding of `pi / 2 - x`, which the scalar twin has).
#[inline]
pub fn sample_disk_concentric_x8(u: [f32x8; 2]) -> [f32x8; 2] {
    let one = f32x8::ONE;
    let a = u[0].mul_add(f32x8::splat(2.0), -one);
    let b = u[1].mul_add(f32x8::splat(2.0), -one);
    let a_dom = a.abs().simd_gt(b.abs());
    // |a| <= |b| lanes use b as radius; at the origin (a = b = 0) the radius is 0 and the ratio is
    // forced to 0 instead of 0/0.
    let r = a_dom.select(a, b);
    let ratio = a_dom.select(b, a) / r;
    let ratio = r.simd_eq(f32x8::ZERO).select(f32x8::ZERO, ratio);
    let (s, c) = sin_cos_quarter_x8(f32x8::splat(FRAC_PI_4) * ratio);
    [r * a_dom.select(c, s), r * a_dom.select(s, c)]
}

/// Sine and cosine of `x` in `[-pi / 4, pi / 4]`: their Taylor polynomials to degrees 9 and 10, whose
/// truncation errors there (`(pi / 4)^11 / 11!` and `(pi / 4)^12 / 12!`, below 2e-9) are far below an
/// f32 ulp; evaluated by Horner's rule in `x^2` with fused multiply-adds. [`sin_cos_quarter`] is the
/// same arithmetic on one lane (bit for bit: one generic body).
#[inline(always)]
pub fn sin_cos_quarter_x8(x: f32x8) -> (f32x8, f32x8) {
    sin_cos_quarter_in(x)
}

/// One lane of [`sin_cos_quarter_x8`], the same operations (so the same bits).
#[inline(always)]
pub fn sin_cos_quarter(x: f32) -> (f32, f32) {
    sin_cos_quarter_in(x)
}

/// What the quarter-range polynomial needs of a lane type: f32 and f32x8 alike.
trait Fma: Copy + std::ops::Mul<Output = Self> {
    fn k(c: f64) -> Self;
    fn fma(self, m: Self, a: Self) -> Self;
}
impl Fma for f32 {
    #[inline(always)]
    fn k(c: f64) -> Self {
        c as f32
    }
    #[inline(always)]
    fn fma(self, m: Self, a: Self) -> Self {
        self.mul_add(m, a)
    }
}
impl Fma for f32x8 {
    #[inline(always)]
    fn k(c: f64) -> Self {
        f32x8::splat(c as f32)
    }
    #[inline(always)]
    fn fma(self, m: Self, a: Self) -> Self {
        self.mul_add(m, a)
    }
}

/// The Taylor coefficients of `sin x / x - 1` and `cos x - 1` in powers of `x^2`, highest first (from
/// `x^8 / 9!` and `x^10 / 10!` down to `-x^2 / 3!` and `-x^2 / 2`).
const SIN_TAYLOR: [f64; 4] = [1.0 / 362_880.0, -1.0 / 5_040.0, 1.0 / 120.0, -1.0 / 6.0];
const COS_TAYLOR: [f64; 5] = [-1.0 / 3_628_800.0, 1.0 / 40_320.0, -1.0 / 720.0, 1.0 / 24.0, -0.5];

#[inline(always)]
fn sin_cos_quarter_in<T: Fma>(x: T) -> (T, T) {
    let x2 = x * x;
    let sin_p = SIN_TAYLOR[1..].iter().fold(T::k(SIN_TAYLOR[0]), |p, &c| x2.fma(p, T::k(c)));
    let s = (x * x2).fma(sin_p, x);
    let cos_p = COS_TAYLOR[1..].iter().fold(T::k(COS_TAYLOR[0]), |p, &c| x2.fma(p, T::k(c)));
    (s, x2.fma(cos_p, T::k(1.0)))
}

/// `sin(2 pi u)` and `cos(2 pi u)` for `u` in `[0, 1]` (an angle in turns, as samplers give it), without
/// libm: `u` is reduced to the nearest quarter turn `q / 4` exactly (`4u`, its rounding and `u - q / 4`
/// are all exact in f32 there), the remainder's angle lies in `[-pi / 4, pi / 4]` ([`sin_cos_quarter`]),
/// and the quarter turns swap and negate the pair. Within ~2 ulp of the exact values of `2 pi u`
/// (closer than `(2 pi u).sin_cos()`, which first rounds the angle). [`sin_cos_turns_x8`] is the same
/// arithmetic in 8 lanes, bit for bit.
#[inline(always)]
pub fn sin_cos_turns(u: f32) -> (f32, f32) {
    let q = u.mul_add(4.0, 0.5).floor();
    let (s, c) = sin_cos_quarter((u - q * 0.25) * TAU);
    let k = q as i32 & 3;
    let (a, b) = if k & 1 != 0 { (c, s) } else { (s, c) };
    (if k >= 2 { -a } else { a }, if k == 1 || k == 2 { -b } else { b })
}

/// Eight lanes of [`sin_cos_turns`], bit for bit.
#[inline(always)]
pub fn sin_cos_turns_x8(u: f32x8) -> (f32x8, f32x8) {
    let q = u.mul_add(f32x8::splat(4.0), f32x8::splat(0.5)).floor();
    let (s, c) = sin_cos_quarter_x8((u - q * f32x8::splat(0.25)) * f32x8::splat(TAU));
    // q mod 4 (floored: the scalar's two's-complement `& 3`), exact in f32 for |q| < 2^24.
    let four = f32x8::splat(4.0);
    let k = q - four * (q * f32x8::splat(0.25)).floor();
    let (one, two, three) = (f32x8::ONE, f32x8::splat(2.0), f32x8::splat(3.0));
    let odd = k.simd_eq(one) | k.simd_eq(three);
    let (a, b) = (odd.select(c, s), odd.select(s, c));
    let neg_a = k.simd_ge(two);
    let neg_b = k.simd_eq(one) | k.simd_eq(two);
    (neg_a.select(-a, a), neg_b.select(-b, b))
}

/// Density of [`sample_disk_concentric`] with respect to area on the unit disk: `1 / pi`.
#[inline]
pub fn sample_disk_concentric_pdf(p: [f32; 2]) -> f32 {
    if p[0] * p[0] + p[1] * p[1] <= 1.0 {
        std::f32::consts::FRAC_1_PI
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_core::{Rng, SeedableRng};
    use rand_xoshiro::Xoshiro256PlusPlus;

    #[test]
    fn x8_matches_scalar() {
        let hi = 1.0 - f32::EPSILON / 2.0;
        // Edge cases: origin, axes, diagonals (|a| == |b|), corners, then seeded random inputs.
        let mut us: Vec<[f32; 2]> = vec![
            [0.5, 0.5],
            [0.0, 0.5],
            [0.5, 0.0],
            [hi, 0.5],
            [0.5, hi],
            [0.0, 0.0],
            [hi, hi],
            [0.25, 0.25],
            [0.75, 0.25],
            [0.25, 0.75],
            [0.5 + 1e-7, 0.5],
            [0.5, 0.5 - 1e-7],
        ];
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(5);
        while us.len() < 4096 {
            us.push([(rng.next_u32() >> 8) as f32 / 16_777_216.0, (rng.next_u32() >> 8) as f32 / 16_777_216.0]);
        }
        for chunk in us.chunks(8) {
            let lane = |k: usize| f32x8::from(std::array::from_fn::<f32, 8, _>(|i| chunk[i][k]));
            let [x, y] = sample_disk_concentric_x8([lane(0), lane(1)]);
            let (x, y) = (x.to_array(), y.to_array());
            for i in 0..8 {
                let p = sample_disk_concentric(chunk[i]);
                assert!(x[i].is_finite() && y[i].is_finite(), "{:?}", chunk[i]);
                assert!((x[i] - p[0]).abs() < 2e-6 && (y[i] - p[1]).abs() < 2e-6, "{:?}: x8 ({}, {}) scalar {p:?}", chunk[i], x[i], y[i]);
            }
        }
    }

    /// [`sin_cos_quarter_x8`] against f64 `sin` and `cos` over `[-pi / 4, pi / 4]` (every 2^-20, the
    /// ends, zero and subnormals): within 1.5 ulp of the result's magnitude (an f32 rounding of each
    /// term), and the sine odd and the cosine even.
    #[test]
    fn sin_cos_quarter_matches_f64() {
        let end = FRAC_PI_4;
        let mut xs: Vec<f32> = (0..=(1 << 20)).map(|i| i as f32 / (1 << 20) as f32 * end).collect();
        xs.extend([end, f32::MIN_POSITIVE, 1e-40, 1e-20, 0.0]);
        let (mut worst_s, mut worst_c) = (0.0f64, 0.0f64);
        for chunk in xs.chunks(8) {
            let lane = f32x8::from(std::array::from_fn::<f32, 8, _>(|i| chunk.get(i).copied().unwrap_or(0.0)));
            let (s, c) = sin_cos_quarter_x8(lane);
            let (sn, cn) = sin_cos_quarter_x8(-lane);
            for (i, &x) in chunk.iter().enumerate() {
                let (s, c) = (s.to_array()[i], c.to_array()[i]);
                let ulp = |v: f32| (v.abs().max(f32::MIN_POSITIVE).to_bits() + 1) as f64;
                let ulps = |got: f32, want: f64| (got as f64 - want).abs() / (f32::from_bits(ulp(got) as u32) as f64 - got.abs() as f64);
                worst_s = worst_s.max(ulps(s, (x as f64).sin()));
                worst_c = worst_c.max(ulps(c, (x as f64).cos()));
                // (Equal values: the sine of -0 comes out +0.)
                assert!(sn.to_array()[i] == -s && cn.to_array()[i] == c, "x = {x:e}");
            }
        }
        assert!(worst_s <= 1.5 && worst_c <= 1.5, "sin {worst_s} ulp, cos {worst_c} ulp");
    }

    /// [`sin_cos_turns`] against f64 `sin` and `cos` of `2 pi u` (every 2^-20 of `[0, 1]`, each quarter
    /// turn's ends and neighbours, the largest f32 below 1): within 2.5 ulp of the result's magnitude
    /// (or 1e-12 absolutely, the f64 reference's own error where the exact value is 0); and the 8-lane twin
    /// bit for bit.
    #[test]
    fn sin_cos_turns_matches_f64_and_x8() {
        let mut us: Vec<f32> = (0..=(1 << 20)).map(|i| i as f32 / (1 << 20) as f32).collect();
        for k in 0..=8 {
            let e = k as f32 / 8.0;
            us.extend([e, f32::from_bits(e.to_bits().wrapping_add(1)), f32::from_bits(e.to_bits().wrapping_sub(1)).max(0.0)]);
        }
        us.extend([1.0 - f32::EPSILON / 2.0, 1e-30, f32::MIN_POSITIVE]);
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(11);
        us.extend((0..4096).map(|_| (rng.next_u32() >> 8) as f32 / 16_777_216.0));
        let (mut worst_s, mut worst_c) = (0.0f64, 0.0f64);
        for chunk in us.chunks(8) {
            let lane = f32x8::from(std::array::from_fn::<f32, 8, _>(|i| chunk.get(i).copied().unwrap_or(0.0)));
            let (sv, cv) = sin_cos_turns_x8(lane);
            for (i, &u) in chunk.iter().enumerate() {
                let (s, c) = sin_cos_turns(u);
                assert_eq!((sv.to_array()[i].to_bits(), cv.to_array()[i].to_bits()), (s.to_bits(), c.to_bits()), "u = {u:e}");
                let angle = std::f64::consts::TAU * u as f64;
                let err = |got: f32, want: f64| {
                    let ulp = f32::from_bits(got.abs().max(f32::MIN_POSITIVE).to_bits() + 1) as f64 - got.abs() as f64;
                    let e = (got as f64 - want).abs();
                    if e <= 1e-12 {
                        0.0
                    } else {
                        e / ulp
                    }
                };
                worst_s = worst_s.max(err(s, angle.sin()));
                worst_c = worst_c.max(err(c, angle.cos()));
                assert!(s.abs() <= 1.0 && c.abs() <= 1.0, "u = {u:e}: ({s}, {c})");
            }
        }
        assert!(worst_s <= 2.5 && worst_c <= 2.5, "sin {worst_s} ulp, cos {worst_c} ulp");
    }

    #[test]
    fn known_points() {
        assert_eq!(sample_disk_concentric([0.5, 0.5]), [0.0, 0.0]);
        let close = |p: [f32; 2], q: [f32; 2]| (p[0] - q[0]).abs() < 1e-6 && (p[1] - q[1]).abs() < 1e-6;
        // Edge midpoints of the square go to the axis points of the circle.
        assert!(close(sample_disk_concentric([0.0, 0.5]), [-1.0, 0.0]));
        assert!(close(sample_disk_concentric([0.5, 0.0]), [0.0, -1.0]));
        // Corners go to the diagonals.
        let h = std::f32::consts::FRAC_1_SQRT_2;
        assert!(close(sample_disk_concentric([0.0, 0.0]), [-h, -h]));
        // The ring |a| = 0.5 maps to the circle of radius 0.5.
        for k in 0..16 {
            let t = k as f32 / 16.0;
            for u in [[0.75, 0.25 + 0.5 * t], [0.25 + 0.5 * t, 0.25]] {
                let p = sample_disk_concentric(u);
                let r = (p[0] * p[0] + p[1] * p[1]).sqrt();
                assert!((r - 0.5).abs() < 1e-6, "{u:?} -> r {r}");
            }
        }
    }
}
