//! Ray–torus crossings: the quartic is solved by bracketing its real roots between its critical points,
//! then polishing each root with safeguarded Newton steps. 8-lane kernel plus an f64 twin that takes the
//! same steps.
//!
//! Closed-form quartic solvers (Ferrari, Descartes) lose most of f32's digits near tangency and for distant
//! origins (e.g. Herbison-Evans, "Solving Quartics and Cubics for Graphics", Graphics Gems V, 1995), so:
//!
//! 1. **Frame.** Object space is scaled by `1 / (major + minor)` (bounding sphere of radius 1), the direction
//!    is made unit (`u`), and the origin is moved to `c`, the point of the line closest to the torus centre:
//!    `p(s) = c + s u` with `t = (ts + s) / |d|`. Every crossing has `|s| <= 1` and `|c| >= 1` is a miss.
//!    The quartic's coefficients are then O(1): a distant origin no longer cancels (the rounding of `c`
//!    itself is the only error it brings, as for every other shape).
//! 2. **Brackets.** `f(s) = (|p|² + R² - r²)² - 4 R² (x² + y²)` is monic in `s`; its critical points are the
//!    roots of the cubic `f'(s) / 4`, found in closed form (trigonometric form for three real roots,
//!    Cardano in the cancellation-free form `w = cbrt(-q/2 - sign(q) sqrt(disc))`, `y = w - p / (3w)`,
//!    otherwise). A monic quartic has at most a min, a max and a min, and is monotone between them, so
//!    each of `[-S, m1]`, `[m1, M]`, `[M, m2]`, `[m2, S]` (`S` slightly above 1) holds at most one root.
//! 3. **Signs.** `f = G · ((rho + R)² + z² - r²)` with `G(s) = (rho - R)² + z² - r²` and `rho = sqrt(x² + y²)`;
//!    the second factor is positive when `r < R`, so `G` has the roots and signs of `f`, and it is evaluated
//!    without `f`'s cancellation on thin tori. A negative value at the max forces both mins negative (their
//!    values cannot exceed it), which keeps the bracket signs consistent under rounding.
//! 4. **Roots.** In every bracket whose ends differ in sign: Newton on `G` starting at the midpoint, falling
//!    back to bisection when the step leaves the bracket or does not halve (Press et al., Numerical Recipes,
//!    "rtsafe"), until the step is below `TOL_X8` (`TOL_F64`) in normalised units. This is the root polish.
//!
//! Inside intervals: `[x1, x2]` when `G(m1) < 0`, `[x3, x4]` when `G(m2) < 0`, or the single `[x1, x4]`
//! when `G(M) < 0` (the ray stays inside the tube from its first to its last crossing).

use super::interval_x8::Cross8;
use crate::simd::{f32x8, Vec3x8};
use glam::DVec3;

/// Newton/bisection stops when the step (in units of `major + minor`) is below this (f32 kernel).
pub const TOL_X8: f32 = 3e-7;
/// Same for the f64 twin.
pub const TOL_F64: f64 = 1e-13;
const MAX_IT_X8: usize = 32;
const MAX_IT_F64: usize = 80;
/// Bracket ends `±S`: just outside the unit bounding sphere, where `G > 0`.
const S: f32 = 1.001;
const SQRT3: f32 = 1.732_050_8;

#[inline(always)]
fn g_x8(c: &Vec3x8, u: &Vec3x8, s: f32x8, major: f32x8, minor2: f32x8) -> (f32x8, f32x8) {
    let p = u.mul_add(s, *c);
    let rho = p.x.mul_add(p.x, p.y * p.y).sqrt();
    let dr = rho - major;
    let g = dr.mul_add(dr, p.z.mul_add(p.z, -minor2));
    let drho = p.x.mul_add(u.x, p.y * u.y) / rho;
    let dg = dr.mul_add(drho, p.z * u.z) * f32x8::splat(2.0);
    (g, dg)
}

/// Torus `(sqrt(x² + y²) - major)² + z² <= minor²` (object space), 8 lanes. See the module docs.
pub fn torus_x8(o: Vec3x8, d: Vec3x8, major: f32, minor: f32) -> Cross8 {
    let nan = f32x8::NAN;
    let inv_scale = f32x8::splat(1.0 / (major + minor));
    let rr = f32x8::splat(major / (major + minor));
    let r = f32x8::splat(minor / (major + minor));
    let (o, d) = (o.scale(inv_scale), d.scale(inv_scale));
    let len2 = d.dot(d);
    let inv_len = f32x8::ONE / len2.sqrt();
    let u = d.scale(inv_len);
    let ts = -o.dot(u);
    let c = u.mul_add(ts, o);
    let cc = c.dot(c);
    let live = cc.simd_lt(f32x8::ONE) & len2.simd_gt(f32x8::ZERO) & len2.simd_lt(f32x8::INFINITY);
    if !live.any() {
        return [nan; 4];
    }

    // Critical points: roots of s³ + 3b s² + a1 s + a0, depressed by s = y - b.
    let b = c.dot(u);
    let rr2 = rr * rr;
    let r2 = r * r;
    let p0 = cc + (rr2 - r2);
    let e = u.x.mul_add(u.x, u.y * u.y);
    let g = c.x.mul_add(u.x, c.y * u.y);
    let two = f32x8::splat(2.0);
    let a1 = (two * b).mul_add(b, p0) - two * rr2 * e;
    let a0 = b.mul_add(p0, -(two * rr2 * g));
    let pp = a1 - f32x8::splat(3.0) * b * b;
    let qq = (two * b * b).mul_add(b, -(b * a1)) + a0;
    let hq = qq * f32x8::HALF;
    let p3 = pp * f32x8::splat(1.0 / 3.0);
    let disc = hq.mul_add(hq, p3 * p3 * p3);
    // Three real roots (trigonometric form).
    let m = (-p3).max(f32x8::ZERO).sqrt();
    let cos_phi = (-hq / (m * m * m)).max(-f32x8::ONE).min(f32x8::ONE);
    let (sn, cs) = (cos_phi.acos() * f32x8::splat(1.0 / 3.0)).sin_cos();
    let y_hi = two * m * cs;
    let y_mid = m * f32x8::splat(SQRT3).mul_add(sn, -cs);
    let y_lo = -m * f32x8::splat(SQRT3).mul_add(sn, cs);
    // One real root (Cardano, stable form).
    let w = (-hq - disc.max(f32x8::ZERO).sqrt().flip_signs(qq)).cbrt();
    let y_one = w.simd_eq(f32x8::ZERO).select(f32x8::ZERO, w - pp / (f32x8::splat(3.0) * w));
    let three = disc.simd_lt(f32x8::ZERO);
    let (lim_lo, lim_hi) = (f32x8::splat(-S), f32x8::splat(S));
    let crit = |y: f32x8| (three.select(y, y_one) - b).max(lim_lo).min(lim_hi);
    let ends = [lim_lo, crit(y_lo), crit(y_mid), crit(y_hi), lim_hi];

    let neg = |s: f32x8| g_x8(&c, &u, s, rr, r2).0.simd_lt(f32x8::ZERO);
    let n2 = neg(ends[2]);
    let n1 = neg(ends[1]) | n2;
    let n3 = neg(ends[3]) | n2;
    // Brackets with a sign change; G is positive at the lower end of brackets 0 and 2, negative at 1, 3.
    let need = [n1 & live, n1 & !n2 & live, n3 & !n2 & live, n3 & live];
    let x = solve_brackets_x8(&c, &u, rr, r2, &ends, &need);

    let t = |s: f32x8| (s + ts) * inv_len;
    let first = n1 & live;
    let second = n3 & !n2 & live;
    let b0 = n2.select(t(x[3]), t(x[1]));
    [first.select(t(x[0]), nan), first.select(b0, nan), second.select(t(x[2]), nan), second.select(t(x[3]), nan)]
}

/// Safeguarded Newton ("rtsafe") in the four brackets at once; brackets 0 and 2 start positive.
fn solve_brackets_x8(c: &Vec3x8, u: &Vec3x8, major: f32x8, minor2: f32x8, ends: &[f32x8; 5], need: &[f32x8; 4]) -> [f32x8; 4] {
    let half = f32x8::HALF;
    let mut lo = [ends[0], ends[1], ends[2], ends[3]];
    let mut hi = [ends[1], ends[2], ends[3], ends[4]];
    let mut x = [f32x8::ZERO; 4];
    let mut dx_old = [f32x8::ZERO; 4];
    let mut dx = [f32x8::ZERO; 4];
    for k in 0..4 {
        x[k] = half * (lo[k] + hi[k]);
        dx_old[k] = hi[k] - lo[k];
        dx[k] = dx_old[k];
    }
    let tol = f32x8::splat(TOL_X8);
    let mut done = [!need[0], !need[1], !need[2], !need[3]];
    for _ in 0..MAX_IT_X8 {
        for k in 0..4 {
            if done[k].all() {
                continue;
            }
            let (g, dg) = g_x8(c, u, x[k], major, minor2);
            // Make the function positive at `lo` so one rule updates every bracket.
            let g = if k % 2 == 0 { g } else { -g };
            let dg = if k % 2 == 0 { dg } else { -dg };
            let pos = g.simd_gt(f32x8::ZERO);
            lo[k] = pos.select(x[k], lo[k]);
            hi[k] = pos.select(hi[k], x[k]);
            let newton = x[k] - g / dg;
            let inside = newton.simd_ge(lo[k]) & newton.simd_le(hi[k]);
            let slow = (g + g).abs().simd_gt((dx_old[k] * dg).abs());
            let bisect = !inside | slow;
            dx_old[k] = dx[k];
            let xn = bisect.select(half * (lo[k] + hi[k]), newton);
            dx[k] = xn - x[k];
            // Converged lanes are frozen: a further sub-ulp Newton step would land on the bracket end and
            // be taken for an escape.
            x[k] = done[k].select(x[k], xn);
            done[k] |= dx[k].abs().simd_lt(tol);
        }
        if done.iter().all(|m| m.all()) {
            break;
        }
    }
    x
}

/// f64 twin of `g_x8`.
#[inline]
fn g_f64(c: DVec3, u: DVec3, s: f64, major: f64, minor2: f64) -> (f64, f64) {
    let p = c + u * s;
    let rho = (p.x * p.x + p.y * p.y).sqrt();
    let dr = rho - major;
    let g = dr * dr + p.z * p.z - minor2;
    let drho = (p.x * u.x + p.y * u.y) / rho;
    (g, 2.0 * (dr * drho + p.z * u.z))
}

/// f64 twin of [`torus_x8`]: same frame, brackets, signs and root polish.
pub fn torus_f64(o: DVec3, d: DVec3, major: f64, minor: f64) -> [f64; 4] {
    let nan = f64::NAN;
    let inv_scale = 1.0 / (major + minor);
    let (rr, r) = (major * inv_scale, minor * inv_scale);
    let (o, d) = (o * inv_scale, d * inv_scale);
    let len2 = d.length_squared();
    let inv_len = 1.0 / len2.sqrt();
    let u = d * inv_len;
    let ts = -o.dot(u);
    let c = o + u * ts;
    let cc = c.length_squared();
    if !(cc < 1.0 && len2 > 0.0 && len2 < f64::INFINITY) {
        return [nan; 4];
    }
    let b = c.dot(u);
    let (rr2, r2) = (rr * rr, r * r);
    let p0 = cc + (rr2 - r2);
    let e = u.x * u.x + u.y * u.y;
    let g = c.x * u.x + c.y * u.y;
    let a1 = 2.0 * b * b + p0 - 2.0 * rr2 * e;
    let a0 = b * p0 - 2.0 * rr2 * g;
    let pp = a1 - 3.0 * b * b;
    let qq = 2.0 * b * b * b - b * a1 + a0;
    let (hq, p3) = (0.5 * qq, pp / 3.0);
    let disc = hq * hq + p3 * p3 * p3;
    let ys = if disc < 0.0 {
        let m = (-p3).max(0.0).sqrt();
        let th = (-hq / (m * m * m)).clamp(-1.0, 1.0).acos() / 3.0;
        let (sn, cs) = th.sin_cos();
        let sq3 = 3f64.sqrt();
        [-m * (sq3 * sn + cs), m * (sq3 * sn - cs), 2.0 * m * cs]
    } else {
        let w = (-hq - disc.sqrt().copysign(qq)).cbrt();
        let y = if w == 0.0 { 0.0 } else { w - pp / (3.0 * w) };
        [y; 3]
    };
    let lim = S as f64;
    let crit = |y: f64| (y - b).clamp(-lim, lim);
    let ends = [-lim, crit(ys[0]), crit(ys[1]), crit(ys[2]), lim];
    let neg = |s: f64| g_f64(c, u, s, rr, r2).0 < 0.0;
    let n2 = neg(ends[2]);
    let n1 = neg(ends[1]) || n2;
    let n3 = neg(ends[3]) || n2;
    let need = [n1, n1 && !n2, n3 && !n2, n3];
    let mut x = [nan; 4];
    for k in 0..4 {
        if need[k] {
            x[k] = rtsafe_f64(c, u, rr, r2, ends[k], ends[k + 1], k % 2 == 1);
        }
    }
    let t = |s: f64| (s + ts) * inv_len;
    let (first, second) = (n1, n3 && !n2);
    let b0 = if n2 { t(x[3]) } else { t(x[1]) };
    [
        if first { t(x[0]) } else { nan },
        if first { b0 } else { nan },
        if second { t(x[2]) } else { nan },
        if second { t(x[3]) } else { nan },
    ]
}

/// Safeguarded Newton on `G` in `[lo, hi]`; `neg_lo` says `G(lo) < 0`.
fn rtsafe_f64(c: DVec3, u: DVec3, major: f64, minor2: f64, mut lo: f64, mut hi: f64, neg_lo: bool) -> f64 {
    let sign = if neg_lo { -1.0 } else { 1.0 };
    let mut x = 0.5 * (lo + hi);
    let mut dx_old = hi - lo;
    let mut dx = dx_old;
    for _ in 0..MAX_IT_F64 {
        let (g, dg) = g_f64(c, u, x, major, minor2);
        let (g, dg) = (g * sign, dg * sign);
        if g > 0.0 {
            lo = x;
        } else {
            hi = x;
        }
        let newton = x - g / dg;
        let bisect = !(newton >= lo && newton <= hi) || (2.0 * g).abs() > (dx_old * dg).abs();
        dx_old = dx;
        let xn = if bisect { 0.5 * (lo + hi) } else { newton };
        dx = xn - x;
        x = xn;
        if dx.abs() < TOL_F64 {
            break;
        }
    }
    x
}
