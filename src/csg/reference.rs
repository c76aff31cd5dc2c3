//! f64 references: the scalar twin of every leaf kernel (same steps as `interval_x8.rs` / `quartic.rs`, in
//! f64, on the ray taken to object space by the f64 inverse of the exact f32 transform), and
//! [`intervals_f64`], all intervals of a solid along a ray.
//!
//! `intervals_f64` does not use Roth's pairwise merge: it sorts the crossings of all leaves, groups them
//! with the same coincidence rule (`merge.rs`, same `COINCIDENT_EPS`, in f64), and classifies each group by
//! evaluating the program on the leaves' inside/outside states. An independent algorithm for the same
//! result, so the tests hold the fast path against it. It allocates and is meant for tests and tools.

use super::merge::COINCIDENT_EPS;
use super::program::{eval_bool, Csg};
use super::quartic::torus_f64;
use super::solid::{cone_line, Leaf, Shape};
use glam::{DVec3, Vec3};

/// Crossings of one leaf, world-space ray, f64: `[a0, b0, a1, b1]`, NaN for absent intervals.
pub fn leaf_f64(leaf: &Leaf, o: DVec3, d: DVec3) -> [f64; 4] {
    let w2o = leaf.world_to_object_f64();
    let (o, d) = (w2o.transform_point3(o), w2o.transform_vector3(d));
    leaf_object_f64(leaf.shape, o, d)
}

/// Crossings of a canonical shape for an object-space ray, f64.
pub fn leaf_object_f64(shape: Shape, o: DVec3, d: DVec3) -> [f64; 4] {
    let (a, b) = match shape {
        Shape::Sphere => sphere_f64(o, d),
        Shape::Box => box_f64(o, d),
        Shape::Cylinder => cylinder_f64(o, d),
        Shape::Cone { r0, r1 } => cone_f64(o, d, r0, r1),
        Shape::HalfSpace => half_space_f64(o, d),
        Shape::Torus { major, minor } => return torus_f64(o, d, major as f64, minor as f64),
    };
    [a, b, f64::NAN, f64::NAN]
}

fn quadratic_f64(a: f64, b: f64, c: f64, disc: f64) -> (f64, f64) {
    let sq = disc.max(0.0).sqrt();
    let q = -(b + sq.copysign(b));
    let (r1, r2) = (q / a, c / q);
    let (lo, hi) = (r1.min(r2), r1.max(r2));
    if disc > 0.0 && lo < hi {
        (lo, hi)
    } else {
        (f64::NAN, f64::NAN)
    }
}

/// Twin of `sphere_x8`.
pub fn sphere_f64(o: DVec3, d: DVec3) -> (f64, f64) {
    let a = d.dot(d);
    let b = o.dot(d);
    let c = o.dot(o) - 1.0;
    let f = o - d * (b / a);
    quadratic_f64(a, b, c, a * (1.0 - f.dot(f)))
}

fn slab_f64(o: f64, d: f64) -> (f64, f64) {
    let inv = 1.0 / d;
    let (t1, t2) = ((-1.0 - o) * inv, (1.0 - o) * inv);
    (t1.min(t2), t1.max(t2))
}

/// Twin of `box_x8`.
pub fn box_f64(o: DVec3, d: DVec3) -> (f64, f64) {
    let (x0, x1) = slab_f64(o.x, d.x);
    let (y0, y1) = slab_f64(o.y, d.y);
    let (z0, z1) = slab_f64(o.z, d.z);
    let (enter, exit) = (x0.max(y0).max(z0), x1.min(y1).min(z1));
    if enter < exit {
        (enter, exit)
    } else {
        (f64::NAN, f64::NAN)
    }
}

/// Twin of `cylinder_x8`.
pub fn cylinder_f64(o: DVec3, d: DVec3) -> (f64, f64) {
    let a = d.x * d.x + d.y * d.y;
    let b = o.x * d.x + o.y * d.y;
    let c = o.x * o.x + o.y * o.y - 1.0;
    let (l0, l1) = if a == 0.0 {
        if c <= 0.0 {
            (f64::NEG_INFINITY, f64::INFINITY)
        } else {
            return (f64::NAN, f64::NAN);
        }
    } else {
        let s = -(b / a);
        let (fx, fy) = (o.x + d.x * s, o.y + d.y * s);
        quadratic_f64(a, b, c, a * (1.0 - (fx * fx + fy * fy)))
    };
    let (z0, z1) = slab_f64(o.z, d.z);
    let (enter, exit) = (l0.max(z0), l1.min(z1));
    if l0 <= l1 && enter < exit {
        (enter, exit)
    } else {
        (f64::NAN, f64::NAN)
    }
}

/// Twin of `cone_x8` (see there for the two forms of the quadric's inside).
pub fn cone_f64(o: DVec3, d: DVec3, r0: f32, r1: f32) -> (f64, f64) {
    let (m, k) = cone_line(r0, r1);
    let (m, k) = (m as f64, k as f64);
    let ts = -(o.dot(d) / d.dot(d));
    let o = o + d * ts;
    let w = m * o.z + k;
    let mdz = m * d.z;
    let a = d.x * d.x + d.y * d.y - mdz * mdz + 0.0;
    let b = o.x * d.x + o.y * d.y - mdz * w;
    let c = o.x * o.x + o.y * o.y - w * w;
    let disc = b * b - a * c;
    let disc = if disc.abs() <= 4.0 * f64::EPSILON * (b * b + (a * c).abs()) { 0.0 } else { disc };
    let two_rays = a < 0.0;
    let (lo, hi) = if a == 0.0 && b == 0.0 {
        if c <= 0.0 {
            (f64::NEG_INFINITY, f64::INFINITY)
        } else {
            (f64::INFINITY, f64::NEG_INFINITY)
        }
    } else if disc < 0.0 {
        (f64::INFINITY, if two_rays { f64::INFINITY } else { f64::NEG_INFINITY })
    } else {
        let q = -(b + disc.sqrt().copysign(b));
        let (r1, r2) = (q / a, c / q);
        (r1.min(r2), r1.max(r2))
    };
    let (s0, s1) = slab_f64(o.z, d.z);
    let (enter, exit, ok) = if two_rays {
        let (cut_lo, cut_hi) = (s1.min(lo), s0.max(hi));
        let (v1, v2) = (s0 < cut_lo, cut_hi < s1);
        (if v1 { s0 } else { cut_hi }, if v2 { s1 } else { cut_lo }, v1 || v2)
    } else {
        let (e, x) = (s0.max(lo), s1.min(hi));
        (e, x, e < x)
    };
    if ok && s0 < s1 {
        (enter + ts, exit + ts)
    } else {
        (f64::NAN, f64::NAN)
    }
}

/// Twin of `half_space_x8`.
pub fn half_space_f64(o: DVec3, d: DVec3) -> (f64, f64) {
    if d.z == 0.0 {
        return if o.z > 0.0 { (f64::NAN, f64::NAN) } else { (f64::NEG_INFINITY, f64::INFINITY) };
    }
    let t = -(o.z / d.z);
    if d.z < 0.0 {
        (t, f64::INFINITY)
    } else {
        (f64::NEG_INFINITY, t)
    }
}

/// How far along `o + t d` the CSG code re-bases a ray before a solid with bounds `(lo, hi)` (`hit.rs`'s
/// `rebase_x8`, in f64): to 1% of the bounds' diagonal (plus 1e-6 of `|o|_inf`) before the bounds' entry,
/// where that is ahead of the origin; else 0.
pub fn rebase_shift_f64((lo, hi): (Vec3, Vec3), o: DVec3, d: DVec3) -> f64 {
    let (lo, hi) = (lo.as_dvec3(), hi.as_dvec3());
    let slab = |o: f64, d: f64, a: f64, b: f64| ((a - o) / d).min((b - o) / d);
    let entry = slab(o.x, d.x, lo.x, hi.x).max(slab(o.y, d.y, lo.y, hi.y)).max(slab(o.z, d.z, lo.z, hi.z));
    let t0 = entry - (0.01 * (hi - lo).length() + 1e-6 * o.abs().max_element()) / d.length();
    if t0 > 0.0 && t0.is_finite() {
        t0
    } else {
        0.0
    }
}

/// All inside intervals `(entry, exit)` of a solid along `o + t d`, all `t` (f64 reference, see the module
/// docs). Coincident crossings are grouped as in `merge.rs`; a group's boundary is reported at its first
/// crossing. An unknown solid id, and a direction that is not a ray's (zero or not finite), give no
/// intervals.
pub fn intervals_f64(csg: &Csg, solid: u32, o: DVec3, d: DVec3, out: &mut Vec<(f64, f64)>) {
    out.clear();
    let Some(s) = csg.solids.get(solid as usize) else {
        return;
    };
    if !(d.length_squared() > 0.0 && d.is_finite() && o.is_finite()) {
        return;
    }
    let leaves = &csg.leaves[s.leaf_start as usize..(s.leaf_start + s.leaf_count) as usize];
    let mut evs: Vec<(f64, usize)> = Vec::with_capacity(4 * leaves.len());
    for (k, leaf) in leaves.iter().enumerate() {
        let c = leaf_f64(leaf, o, d);
        for iv in 0..2 {
            if c[2 * iv] < c[2 * iv + 1] {
                evs.push((c[2 * iv], k));
                evs.push((c[2 * iv + 1], k));
            }
        }
    }
    evs.sort_by(|x, y| x.0.total_cmp(&y.0));
    let eps = COINCIDENT_EPS as f64;
    // The tolerance measured from the origin re-based near the solid, as `hit.rs` re-bases it.
    let shift = rebase_shift_f64(s.bounds, o, d);
    let o2 = o + d * shift;
    let base = eps * if shift > 0.0 { o2.abs().max_element() } else { o2.length() }.max(s.scale as f64) / d.length();
    let mut state = vec![false; leaves.len()];
    let prog = csg.program(s);
    let (mut inside, mut entry) = (false, 0.0);
    let mut i = 0;
    while i < evs.len() {
        let t0 = evs[i].0;
        let end = t0 + (base + eps * (t0 - shift).abs().min(1e300));
        // (At least the group's first crossing, whatever `end` is: the loop always moves on.)
        loop {
            state[evs[i].1] ^= true;
            i += 1;
            if i == evs.len() || !(evs[i].0 <= end) {
                break;
            }
        }
        let now = eval_bool(prog, |k| state[k as usize]);
        if now != inside {
            if now {
                entry = t0;
            } else {
                out.push((entry, t0));
            }
            inside = now;
        }
    }
}

/// Where in its cell each probe ray passes: not the centre (a user trial's plate of 24 x 24 touching
/// holes, probed at cell centres by a 24 x 24 grid, had every ray pass through hole centres and rows of
/// holes, and was warned of as empty); a fraction (2 - golden ratio) that regular layouts rarely share.
const OFFSET: f64 = 0.381_966_011_250_105;

/// Whether any of `3 n^2` axis-parallel rays through the solid's bounds (an `n x n` grid of cells across
/// each pair of axes, each ray at [`OFFSET`] within its cell) finds an inside interval longer than `1e-6` of
/// the bounds' largest extent and than the solid's coincidence tolerance (crossings closer than that are
/// one for the render, so such an interval renders as nothing: a trial's intersection of two boxes sharing
/// a face was said to look empty at some scales and not at others, by the rounding of their faces).
/// `false` means the solid is very likely empty (a hole larger than its part, `A - A`), or thinner than
/// the grid's spacing everywhere. Solids with unbounded or empty bounds are reported as not empty (the
/// bounds already decide those). Most solids answer at their first ray.
pub fn probe_finds_volume(csg: &Csg, solid: u32, n: u32) -> bool {
    let (lo, hi) = csg.bounds(solid);
    let (lo, hi) = (lo.as_dvec3(), hi.as_dvec3());
    if !(lo.is_finite() && hi.is_finite() && lo.cmple(hi).all()) {
        return true;
    }
    let ext = hi - lo;
    let min_len = (1e-6 * ext.max_element()).max(super::merge::COINCIDENT_EPS as f64 * csg.scale(solid) as f64);
    let mut out = Vec::new();
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let mut d = DVec3::ZERO;
        d[axis] = 1.0;
        for i in 0..n {
            for j in 0..n {
                // (On the bounds' mid-plane: the intervals cover all t.)
                let mut o = (lo + hi) * 0.5;
                o[u] = lo[u] + ext[u] * (i as f64 + OFFSET) / n as f64;
                o[v] = lo[v] + ext[v] * (j as f64 + OFFSET) / n as f64;
                intervals_f64(csg, solid, o, d, &mut out);
                if out.iter().any(|&(a, b)| b - a > min_len) {
                    return true;
                }
            }
        }
    }
    false
}
