//! The light buffer (Haines & Greenberg 1986, "The Light Buffer: A Shadow-Testing Accelerator", IEEE
//! CG&A 6(9)): a direction cube around a light whose cells list the primitives that can lie between
//! the light and a point seen from the light through that cell. A shadow ray from `o` towards the light
//! then needs one cell lookup (the direction of `o` from the light's centre) and tests that cell's
//! primitives only, nearest to the light first, instead of a BVH traversal. Unlike traversal it does not
//! care whether neighbouring shadow rays are coherent: shading points scattered by diffuse bounces
//! pay the same as neighbouring camera hits.
//!
//! ## Why the lists are complete (the argument the tests check)
//! Each primitive is bounded by a sphere `(c, r)` (padded, below). A shadow segment runs from `o` to a
//! point `y` of the light, `|y - C| <= R` (`R = 0` for a point light, plus the rounding allowance
//! below). If it passes through a point `x` of the bound, `x = (1 - s) y + s o`, so `o - C` has the
//! direction of `(x - C) + w` with `|w| <= R`: the angle between `o - C` and `x - C` is at most
//! `asin(R / |x - C|)`, and `x - C` is within `asin(r / |c - C|)` of the axis `c - C`. So the direction
//! of `o` from `C` lies in the cone around `c - C` of half-angle `asin(r / D) + asin(R / (D - r))`
//! (`D = |c - C|`), and the primitive is listed in every cell that cone meets (each cell is tested by its
//! bounding cone, itself padded). Primitives whose bound reaches within `2 R` of the centre, or whose
//! cone is wider than [`WIDE_CONE`], are on the `always` list instead, tested for every ray.
//!
//! Within a cell the entries are sorted by a lower bound of their distance from the centre: a segment
//! of length `L` from `o` reaches no point farther than `L` (plus rounding) from the centre, so a query
//! stops at the first entry beyond it.
//!
//! ## Rounding
//! The f32 ray `o + t d`, `d = fl(C - o)`, strays from the exact segment by at most `|d - (C - o)| <=
//! 2^-24 sqrt(3) |o - C|`; the build treats that as a light of radius `2^-20` of the longest ray it
//! answers ([`LightBuffer::cells_x8`] refuses longer ones, which the caller traces through the BVH).
//! Bounds are widened by `1e-5` of their radius and `1e-6` of their distance (the kernels' grazing
//! tolerances are a few ulps), cones by `1e-5` radians (the f32 cell lookup is within ~1e-7 of the
//! exact direction, and a direction on a face edge may go to either face: both edges' cells list it).

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::simd::{f32x8, u32x8, Vec3x8, LANES};

/// Cones wider than this (half-angle, radians) go to the `always` list (a prim that covers a large
/// part of the sky of the light would be listed in thousands of cells).
pub const WIDE_CONE: f64 = std::f64::consts::FRAC_PI_4;

/// Angular padding of every cone, radians.
const CONE_PAD: f64 = 1e-5;

/// The longest ray a buffer answers, relative to the farthest point of its prims from the light.
const MAX_LEN: f64 = 256.0;

/// Largest and smallest cells per face side.
const MAX_SIDE: u32 = 512;
const MIN_SIDE: u32 = 4;

/// A cell index that no ray gets (its direction cannot be answered: see [`LightBuffer::cells_x8`]).
pub const NO_CELL: u32 = u32::MAX;

/// A primitive's bounding sphere, as the light buffer sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bound {
    pub center: DVec3,
    pub radius: f64,
}

impl Bound {
    /// The bounding sphere of a box (centre and half diagonal).
    pub fn of_box(min: Vec3, max: Vec3) -> Self {
        let (lo, hi) = (min.as_dvec3(), max.as_dvec3());
        Bound { center: (lo + hi) * 0.5, radius: (hi - lo).length() * 0.5 }
    }
}

/// A light buffer: a cube of `6 n^2` direction cells around the light's centre (see the module doc).
/// Queries take the direction from the ray (`-d` of a ray aimed at the centre), so the centre itself
/// is not kept.
///
/// Cell `(face, iu, iv)` is `(face * n + iv) * n + iu`; face `2 k + s` looks along axis `k` (`s = 1`:
/// negative), its `u` and `v` axes the other two in increasing order (x face: y, z; y face: x, z; z face:
/// x, y); `u = q_u / |q_k|` in `[-1, 1]` splits into `n` equal cells.
#[derive(Clone, Debug, Default)]
pub struct LightBuffer {
    n: u32,
    /// Entries of cell `c`: `start[c]..start[c + 1]`.
    start: Vec<u32>,
    /// Per entry: a lower bound of the squared distance from the centre to the primitive's bound
    /// (ascending within a cell), and the primitive id given to [`LightBuffer::build`] (side by side:
    /// one slice, one bounds check and one cache line per step of a query).
    entries: Vec<(f32, u32)>,
    /// Primitives tested for every ray.
    always: Vec<u32>,
    /// Squared length of the longest ray the buffer answers.
    max_len2: f32,
}

impl LightBuffer {
    /// Build for a light of centre `center` whose samples lie within `light_radius` of it (0 for a
    /// point light), over `prims` (id, bound). `side`: cells per face side, or `None` to choose from the
    /// bounds (so that a typical primitive covers a few cells). `None` when there is nothing to list.
    pub fn build(center: Vec3, light_radius: f32, prims: &[(u32, Bound)], side: Option<u32>) -> Option<Self> {
        Self::build_within(center, light_radius, prims, side, usize::MAX, f64::INFINITY, usize::MAX)
    }

    /// [`LightBuffer::build`], given up (`None`) where it would not pay, as early as that is known, so
    /// that such a buffer costs neither its memory nor most of its time:
    /// - an `always` list longer than `max_always`: known before any cell is listed;
    /// - more entries than `max_entries`, or than `max_mean` per cell of the cube: the cells' lists are
    ///   counted while they are made, and making stops there (a lattice of long beams around a light:
    ///   10^5 cells per beam);
    /// - more than `max_mean` entries per non-empty cell ([`LightBuffer::mean_list`]): known once the
    ///   lists are counted, before they are sorted (160,000 overlapping spheres under one light: 104 per
    ///   listed cell, and the sorts were two thirds of the build).
    ///
    /// Whether it is given up does not depend on the thread count.
    pub fn build_within(
        center: Vec3,
        light_radius: f32,
        prims: &[(u32, Bound)],
        side: Option<u32>,
        max_entries: usize,
        max_mean: f64,
        max_always: usize,
    ) -> Option<Self> {
        if prims.is_empty() || !center.is_finite() || !(light_radius >= 0.0) {
            return None;
        }
        let c0 = center.as_dvec3();
        // The longest ray answered: 256x the scene's reach from the light (shading points lie on the
        // primitives, or on unbounded planes; points farther out are refused at query time and traced
        // through the BVH). Its rounding allowance is then 2^-12 of that reach. The reach is the 99th
        // percentile of the prims' farthest points, not the farthest: one huge prim (a ground sphere of
        // radius 1e8) would otherwise widen the allowance until every prim went on the `always` list.
        let mut far: Vec<f64> = prims.iter().map(|(_, b)| (b.center - c0).length() + b.radius).collect();
        let k = (far.len() - 1) * 99 / 100;
        let reach = *far.select_nth_unstable_by(k, f64::total_cmp).1;
        if !reach.is_finite() {
            return None;
        }
        let max_len = MAX_LEN * reach.max(f64::MIN_POSITIVE);
        let r_eff = light_radius as f64 + max_len * (1.0 / (1u64 << 20) as f64);
        // Cones: (id, axis, half-angle, near distance) or `always`.
        let mut always = Vec::new();
        let mut cones = Vec::with_capacity(prims.len());
        for &(id, b) in prims {
            let v = b.center - c0;
            let dist = v.length();
            let r = b.radius * (1.0 + 1e-5) + 1e-6 * (dist + c0.abs().max_element());
            let rho = dist - r;
            if !(rho > 2.0 * r_eff) || !b.radius.is_finite() {
                always.push(id);
                continue;
            }
            let alpha = (r / dist).min(1.0).asin() + (r_eff / rho).min(1.0).asin() + CONE_PAD;
            if alpha >= WIDE_CONE {
                always.push(id);
                continue;
            }
            cones.push((id, v / dist, alpha, (rho - r_eff).max(0.0)));
        }
        if always.len() > max_always {
            return None;
        }
        let n = side.unwrap_or_else(|| choose_side(&cones)).clamp(MIN_SIDE, MAX_SIDE);
        let cells = 6 * (n as usize) * (n as usize);
        // (cell, near^2, id) for every cell a cone meets, cones in parallel chunks (concatenated in
        // order, so the result does not depend on the thread count).
        let table = FaceCells::new(n);
        let cap = max_entries.min((max_mean * cells as f64).min(usize::MAX as f64) as usize);
        let made = std::sync::atomic::AtomicUsize::new(0);
        let over = || made.load(std::sync::atomic::Ordering::Relaxed) > cap;
        let chunks: Vec<Vec<(u32, f32, u32)>> = cones
            .par_chunks(4096)
            .map(|chunk| {
                let mut out = Vec::new();
                for &(id, axis, alpha, near) in chunk {
                    if over() {
                        break;
                    }
                    let before = out.len();
                    let near2 = round_down((near * near) as f32, near * near);
                    table.for_each_cell(axis, alpha, |cell| out.push((cell, near2, id)));
                    made.fetch_add(out.len() - before, std::sync::atomic::Ordering::Relaxed);
                }
                out
            })
            .collect();
        // (The total is the same whatever the chunks' order: over the cap, some chunk saw it so.)
        let total = made.into_inner();
        if total > cap {
            return None;
        }
        // Counting sort by cell, then each cell's entries by distance (and id: a total order).
        let mut start = vec![0u32; cells + 1];
        for e in chunks.iter().flatten() {
            start[e.0 as usize + 1] += 1;
        }
        // (The mean as `mean_list` gives it, from the same two counts.)
        let listed = start[1..].iter().filter(|&&k| k > 0).count();
        if total as f64 / listed.max(1) as f64 > max_mean {
            return None;
        }
        for c in 0..cells {
            start[c + 1] += start[c];
        }
        let mut entries = vec![(0.0f32, 0u32); total];
        let mut fill = start.clone();
        for &(cell, near2, id) in chunks.iter().flatten() {
            entries[fill[cell as usize] as usize] = (near2, id);
            fill[cell as usize] += 1;
        }
        for c in 0..cells {
            entries[start[c] as usize..start[c + 1] as usize].sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        }
        Some(LightBuffer { n, start, entries, always, max_len2: (max_len * max_len) as f32 })
    }

    /// Cells per face side.
    pub fn side(&self) -> u32 {
        self.n
    }

    /// Primitives tested for every ray.
    #[inline(always)]
    pub fn always(&self) -> &[u32] {
        &self.always
    }

    /// Entries of cell `c` (not [`NO_CELL`]): the lower bound of each primitive's squared distance
    /// from the centre (ascending), and its id.
    #[inline(always)]
    pub fn cell(&self, c: u32) -> &[(f32, u32)] {
        let (a, b) = (self.start[c as usize] as usize, self.start[c as usize + 1] as usize);
        &self.entries[a..b]
    }

    /// Entries over all cells (what the scene's buffer budget counts).
    pub fn entry_count(&self) -> usize {
        self.entries.len()
    }

    /// Mean entries per non-empty cell: the prims a ray whose cell lists any tests, at most (the
    /// distance cut stops most lists early).
    pub fn mean_list(&self) -> f64 {
        let lists = self.start.windows(2).filter(|w| w[1] > w[0]).count();
        self.entries.len() as f64 / lists.max(1) as f64
    }

    /// The cell of each lane's direction `q = o - center` from the centre, or [`NO_CELL`] where the
    /// buffer cannot answer: `q` zero or not finite, or longer than the longest ray the build allowed
    /// for (the caller traces those lanes through the BVH).
    #[inline(always)]
    pub fn cells_x8(&self, q: Vec3x8) -> [u32; LANES] {
        self.cells_v8(q).to_array()
    }

    /// [`LightBuffer::cells_x8`] as a vector.
    #[inline(always)]
    pub fn cells_v8(&self, q: Vec3x8) -> u32x8 {
        let (ax, ay, az) = (q.x.abs(), q.y.abs(), q.z.abs());
        let xm = ax.simd_ge(ay) & ax.simd_ge(az);
        let ym = !xm & ay.simd_ge(az);
        let major = xm.select(ax, ym.select(ay, az));
        let signed = xm.select(q.x, ym.select(q.y, q.z));
        let nu = xm.select(q.y, q.x);
        let nv = (xm | ym).select(q.z, q.y);
        let len2 = q.dot(q);
        let ok = major.simd_gt(f32x8::ZERO) & len2.simd_le(f32x8::splat(self.max_len2));
        let inv = f32x8::ONE / major;
        let half = f32x8::splat(self.n as f32 * 0.5);
        let top = f32x8::splat(self.n as f32 - 1.0);
        // |num| <= major, so num / major is in [-1, 1] and the cell in [0, n]; (lanes that are not `ok`
        // may be NaN here: they are replaced below). Integers below 6 * 512^2 < 2^24 are exact in f32.
        let idx = |num: f32x8| ((num * inv + f32x8::ONE) * half).floor().fast_min(top).fast_max(f32x8::ZERO);
        let (iu, iv) = (idx(nu), idx(nv));
        let axis = xm.select(f32x8::ZERO, ym.select(f32x8::ONE, f32x8::splat(2.0)));
        let face = axis * f32x8::splat(2.0) + (signed.simd_lt(f32x8::ZERO) & f32x8::ONE);
        let n = f32x8::splat(self.n as f32);
        let cell = ok.select((face * n + iv) * n + iu, f32x8::splat(-1.0)).fast_trunc_int();
        bytemuck::cast(cell)
    }
}

/// Cells per face side from the cones: about one cell per typical cone width (the median half-angle),
/// so that a primitive covers a few cells, within 32 cells per primitive overall. (On bench_spheres'
/// 1,000 spheres the shadow rays of camera hits ran at the same rate from 37 to 100 cells per side,
/// 4% slower at 160 and 9% at 256: the cells stop mattering once a typical list is one or two long.)
fn choose_side(cones: &[(u32, DVec3, f64, f64)]) -> u32 {
    if cones.is_empty() {
        return MIN_SIDE;
    }
    let mut a: Vec<f64> = cones.iter().map(|c| c.2).collect();
    a.sort_unstable_by(f64::total_cmp);
    let median = a[a.len() / 2];
    let by_size = (2.0 / median).ceil();
    let by_count = ((32.0 * cones.len() as f64) / 6.0).sqrt().ceil();
    by_size.min(by_count).clamp(MIN_SIDE as f64, MAX_SIDE as f64) as u32
}

/// `x` (an f32 rounding of `exact`) moved down until it is at most `exact`.
fn round_down(x: f32, exact: f64) -> f32 {
    let mut x = x;
    while x > 0.0 && x as f64 > exact {
        x = x.next_down();
    }
    x.max(0.0)
}

/// The bounding cones of one face's cells (every face has the same ones, axes permuted): per cell
/// `(iu, iv)`, the unit direction of its centre in face coordinates `(u, v, 1) / |(u, v, 1)|` and the
/// cosine and sine of its half-angle (the largest angle to a corner) plus [`CONE_PAD`].
struct FaceCells {
    n: u32,
    cells: Vec<([f64; 3], f64, f64)>,
}

impl FaceCells {
    fn new(n: u32) -> Self {
        let w = 2.0 / n as f64;
        let dir = |u: f64, v: f64| DVec3::new(u, v, 1.0).normalize();
        let mut cells = Vec::with_capacity((n * n) as usize);
        for iv in 0..n {
            for iu in 0..n {
                let (u0, v0) = (-1.0 + w * iu as f64, -1.0 + w * iv as f64);
                let g = dir(u0 + 0.5 * w, v0 + 0.5 * w);
                let corners = [(u0, v0), (u0 + w, v0), (u0, v0 + w), (u0 + w, v0 + w)];
                let beta = corners.iter().map(|&(u, v)| g.dot(dir(u, v)).clamp(-1.0, 1.0).acos()).fold(0.0f64, f64::max) + CONE_PAD;
                cells.push(([g.x, g.y, g.z], beta.cos(), beta.sin()));
            }
        }
        FaceCells { n, cells }
    }

    /// Call `f(cell)` for every cell the cone `(axis, alpha)` meets (conservatively: each cell by its
    /// padded bounding cone: the angle between the axes at most `alpha + beta`, compared as cosines).
    fn for_each_cell(&self, axis: DVec3, alpha: f64, mut f: impl FnMut(u32)) {
        let n = self.n;
        let s = alpha.sin();
        let (ca, sa) = (alpha.cos(), s);
        for face in 0..6u32 {
            let k = (face / 2) as usize;
            let sign = if face & 1 == 1 { -1.0 } else { 1.0 };
            let (i, j) = match k {
                0 => (1, 2),
                1 => (0, 2),
                _ => (0, 1),
            };
            // The cone is the set of directions of points in the ball (axis, sin alpha), inside this box.
            let (z0, z1) = (sign * axis[k] - s, sign * axis[k] + s);
            if z1 <= 0.0 {
                continue;
            }
            let range = |lo: f64, hi: f64| -> (f64, f64) {
                if z0 > 0.0 {
                    ((lo / z0).min(lo / z1), (hi / z0).max(hi / z1))
                } else {
                    // Points with z' -> 0+ reach any ratio of the sign of their numerator.
                    (if lo < 0.0 { f64::NEG_INFINITY } else { lo / z1 }, if hi > 0.0 { f64::INFINITY } else { hi / z1 })
                }
            };
            let (ulo, uhi) = range(axis[i] - s, axis[i] + s);
            let (vlo, vhi) = range(axis[j] - s, axis[j] + s);
            let cell_range = |lo: f64, hi: f64| -> Option<(u32, u32)> {
                let (lo, hi) = ((lo - 1e-6).max(-1.0), (hi + 1e-6).min(1.0));
                if lo > hi {
                    return None;
                }
                let at = |x: f64| (((x + 1.0) * 0.5 * n as f64).floor() as i64).clamp(0, n as i64 - 1) as u32;
                Some((at(lo), at(hi)))
            };
            let (Some((iu0, iu1)), Some((iv0, iv1))) = (cell_range(ulo, uhi), cell_range(vlo, vhi)) else {
                continue;
            };
            // The axis in this face's coordinates (u, v, out).
            let a = [axis[i], axis[j], sign * axis[k]];
            for iv in iv0..=iv1 {
                for iu in iu0..=iu1 {
                    let (g, cb, sb) = self.cells[(iv * n + iu) as usize];
                    // cos(angle) >= cos(alpha + beta), with room for the rounding of both sides.
                    if g[0] * a[0] + g[1] * a[1] + g[2] * a[2] >= ca * cb - sa * sb - 1e-12 {
                        f((face * n + iv) * n + iu);
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Distance from `c` to the segment `a..b` (f64).
    fn seg_dist(a: DVec3, b: DVec3, c: DVec3) -> f64 {
        let ab = b - a;
        let t = ((c - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
        (a + ab * t - c).length()
    }

    /// Every sphere that a segment from a random origin to a random point of the light meets (exactly,
    /// in f64) is listed in the origin's cell (or on the `always` list), and the distance cut keeps
    /// it: random scenes at scales 1e-3 to 1e4, point and area lights, spheres near and far, one around
    /// the light. Also counts that the lists are selective (most spheres are not in a given cell).
    #[test]
    fn lists_hold_every_sphere_a_segment_meets() {
        let mut f = crate::sample::hash::test_uniforms(0x11b0_ffe5);
        let (mut met, mut tested, mut listed_total) = (0usize, 0usize, 0usize);
        for round in 0..60 {
            let scale = [1e-3f64, 1.0, 1e4][round % 3];
            let light_r = [0.0, 0.05, 0.5][(round / 3) % 3] * scale;
            let c = DVec3::new(f() as f64 - 0.5, 3.0 + f() as f64, f() as f64 - 0.5) * scale;
            let cf = c.as_vec3();
            let c = cf.as_dvec3();
            let mut spheres: Vec<(u32, Bound)> = (0..200)
                .map(|i| {
                    let p = DVec3::new(f() as f64 * 10.0 - 5.0, f() as f64 * 4.0 - 1.0, f() as f64 * 10.0 - 5.0) * scale;
                    (i, Bound { center: p, radius: (0.02 + 0.3 * f() as f64) * scale })
                })
                .collect();
            if round % 4 == 0 {
                spheres.push((999, Bound { center: c + DVec3::splat(0.01 * scale), radius: 0.1 * scale }));
            }
            let lb = LightBuffer::build(cf, light_r as f32, &spheres, [None, Some(4), Some(97)][round % 3]).unwrap();
            for _ in 0..400 {
                let o = DVec3::new(f() as f64 * 12.0 - 6.0, f() as f64 * 5.0 - 1.5, f() as f64 * 12.0 - 6.0) * scale;
                let of = o.as_vec3();
                let q = of - cf;
                let cell = lb.cells_x8(Vec3x8::splat(q))[0];
                assert_ne!(cell, NO_CELL);
                let entries = lb.cell(cell);
                let len2 = q.length_squared();
                listed_total += entries.len();
                // A point of the light (area lights: uniform in the ball around the centre).
                let y = loop {
                    let w = DVec3::new(f() as f64 * 2.0 - 1.0, f() as f64 * 2.0 - 1.0, f() as f64 * 2.0 - 1.0);
                    if w.length_squared() <= 1.0 {
                        break c + w * light_r;
                    }
                };
                for &(id, b) in &spheres {
                    tested += 1;
                    if seg_dist(of.as_dvec3(), y, b.center) <= b.radius {
                        met += 1;
                        let near2 = entries.iter().find(|e| e.1 == id).map(|e| e.0);
                        let ok = lb.always().contains(&id) || near2.is_some_and(|n2| n2 <= len2 * (1.0 + 4e-6));
                        assert!(ok, "round {round}: sphere {id} {b:?} meets the segment from {o} to {y} but is not listed in cell {cell}");
                    }
                }
            }
        }
        assert!(met > 1000, "{met} sphere-segment meetings");
        // Selective: on average a cell lists far fewer spheres than there are.
        assert!((listed_total as f64) < 0.25 * tested as f64, "{listed_total} listed of {tested}");
    }

    /// Lanes the buffer cannot answer: zero and non-finite directions, and rays longer than the build
    /// allowed for, get NO_CELL; others get a cell inside the cube.
    #[test]
    fn unanswerable_lanes() {
        let lb = LightBuffer::build(Vec3::new(0.0, 5.0, 0.0), 0.0, &[(0, Bound { center: DVec3::ZERO, radius: 1.0 })], None).unwrap();
        let q = Vec3x8::new(
            f32x8::from([0.0, f32::NAN, f32::INFINITY, 1e9, 0.3, -0.3, 0.0, 1.0]),
            f32x8::from([0.0, 0.0, 0.0, 0.0, -5.0, 2.0, -1e-30, 1.0]),
            f32x8::from([0.0, 0.0, 0.0, 0.0, 0.1, 0.0, 0.0, -1.0]),
        );
        let cells = lb.cells_x8(q);
        assert_eq!(&cells[..4], &[NO_CELL; 4]);
        for &c in &cells[4..] {
            assert!(c < 6 * lb.side() * lb.side(), "{cells:?}");
        }
    }

    /// A build given a cap gives up (`None`) exactly when its entries would pass it, whatever the
    /// thread count, and otherwise equals the uncapped build: wide cones (spheres close around the
    /// light) make many entries, and caps just below and at the count decide. So do caps on the mean
    /// list per listed cell and on the `always` list.
    #[test]
    fn a_capped_build_gives_up_past_its_cap() {
        let mut f = crate::sample::hash::test_uniforms(0xcab);
        let mut spheres: Vec<(u32, Bound)> = (0..5000)
            .map(|i| {
                let c = DVec3::new(f() as f64 * 20.0 - 10.0, f() as f64 * 4.0, f() as f64 * 20.0 - 10.0);
                (i, Bound { center: c, radius: 0.05 + f() as f64 * if i % 10 == 0 { 2.0 } else { 0.1 } })
            })
            .collect();
        let light = Vec3::new(0.5, 6.0, -0.5);
        // Two spheres close beside the light, whose cones are wider than `WIDE_CONE`: always tested.
        for (i, dx) in [(5000, 1.5), (5001, -1.6)] {
            spheres.push((i, Bound { center: light.as_dvec3() + DVec3::new(dx, 0.0, 0.0), radius: 1.2 }));
        }
        let full = LightBuffer::build(light, 0.0, &spheres, None).unwrap();
        let n = full.entry_count();
        assert!(n > 10_000, "{n} entries");
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| {
                let build = |entries, mean, always| LightBuffer::build_within(light, 0.0, &spheres, None, entries, mean, always);
                assert!(build(n - 1, f64::INFINITY, usize::MAX).is_none());
                let at = build(n, f64::INFINITY, usize::MAX).unwrap();
                assert_eq!((at.entry_count(), &at.start, &at.always), (n, &full.start, &full.always));
                let cells = 6.0 * (full.side() as f64).powi(2);
                assert!(build(usize::MAX, (n as f64 - 1.0) / cells, usize::MAX).is_none());
                // Per listed cell: given up just below the finished buffer's own mean list, kept at it.
                let mean = full.mean_list();
                assert!(mean > 1.5 * n as f64 / cells, "a third of the cells or more list nothing: {mean} per listed cell");
                assert!(build(usize::MAX, mean * (1.0 - 1e-12), usize::MAX).is_none());
                assert_eq!(build(usize::MAX, mean, usize::MAX).unwrap().entries, full.entries);
                // The `always` list: given up just below its length, kept at it.
                let always = full.always().len();
                assert_eq!(always, 2, "the two spheres beside the light are on the always list");
                assert!(build(usize::MAX, f64::INFINITY, always - 1).is_none());
                assert_eq!(build(usize::MAX, f64::INFINITY, always).unwrap().entries, full.entries);
            });
        }
    }
}
