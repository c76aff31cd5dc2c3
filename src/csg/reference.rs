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
    intervals_f64_within(csg, solid, o, d, out, &mut { u64::MAX });
}

/// [`intervals_f64`], taking its leaf tests and program instructions from `budget`: `false` (and the
/// intervals found by then) where it runs out. The whole program runs at each group of crossings, so a
/// ray through n leaves costs ~n^2 (one of 8,000 leaves took 0.7 ms a ray).
fn intervals_f64_within(csg: &Csg, solid: u32, o: DVec3, d: DVec3, out: &mut Vec<(f64, f64)>, budget: &mut u64) -> bool {
    out.clear();
    let Some(s) = csg.solids.get(solid as usize) else {
        return true;
    };
    if !(d.length_squared() > 0.0 && d.is_finite() && o.is_finite()) {
        return true;
    }
    let leaves = &csg.leaves[s.leaf_start as usize..(s.leaf_start + s.leaf_count) as usize];
    let prog = csg.program(s);
    if *budget < leaves.len() as u64 {
        return false;
    }
    *budget -= leaves.len() as u64;
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
    let (mut inside, mut entry) = (false, 0.0);
    let mut i = 0;
    while i < evs.len() {
        if *budget < prog.len() as u64 {
            return false;
        }
        *budget -= prog.len() as u64;
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
    true
}

/// Where in its cell each probe ray passes: not the centre (a user trial's plate of 24 x 24 touching
/// holes, probed at cell centres by a 24 x 24 grid, had every ray pass through hole centres and rows of
/// holes, and was warned of as empty); a fraction (2 - golden ratio) that regular layouts rarely share.
const OFFSET: f64 = 0.381_966_011_250_105;

/// The probes' ray directions: the world axes turned by a fixed rotation of no round angle (about 12, 19
/// and 26 degrees about x, y and z), so that no ray lies in a face a user is likely to give (an axis plane,
/// or one turned by a round number of degrees). Axis-parallel rays lay in the face two intersected boxes
/// turned 30 degrees share (the exact diagonal of their bounds) and found it inside by rounding: a trial's
/// solid of no volume was not said to look empty.
pub fn probe_directions() -> [DVec3; 3] {
    let r = glam::DQuat::from_euler(glam::EulerRot::ZYX, 0.4527, 0.3371, 0.2113);
    [r * DVec3::X, r * DVec3::Y, r * DVec3::Z]
}

/// The `3 n^2` probe rays through bounds `(lo, hi)`: for each of the [`probe_directions`] (the one nearest
/// world axis `a`), an `n x n` grid of cells across the bounds' two other axes, one ray per cell at
/// [`OFFSET`] within it, through the bounds' mid-plane across `a` (the intervals cover all `t`).
pub fn probe_rays(lo: DVec3, hi: DVec3, n: u32) -> impl Iterator<Item = (DVec3, DVec3)> {
    let ext = hi - lo;
    let dirs = probe_directions();
    (0..3).flat_map(move |axis| {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        (0..n * n).map(move |c| {
            let (i, j) = (c / n, c % n);
            let mut o = (lo + hi) * 0.5;
            o[u] = lo[u] + ext[u] * (i as f64 + OFFSET) / n as f64;
            o[v] = lo[v] + ext[v] * (j as f64 + OFFSET) / n as f64;
            (o, dirs[axis])
        })
    })
}

/// Whether any of the `3 n^2` [`probe_rays`] through the solid's bounds finds an inside interval longer
/// than `1e-6` of the bounds' largest extent and than the solid's coincidence tolerance (crossings closer
/// than that are one for the render, so such an interval renders as nothing: a trial's intersection of two
/// boxes sharing a face was said to look empty at some scales and not at others, by the rounding of their
/// faces). `false` means the solid is very likely empty (a hole larger than its part, `A - A`), or thinner
/// than the grid's spacing everywhere. Solids with unbounded or empty bounds are reported as not empty (the
/// bounds already decide those). Most solids answer at their first ray. The rays take their leaf tests and
/// program instructions from `budget`; where it runs out before they find volume, `None`: not known.
pub fn probe_finds_volume(csg: &Csg, solid: u32, n: u32, budget: &mut u64) -> Option<bool> {
    let (lo, hi) = csg.bounds(solid);
    let (lo, hi) = (lo.as_dvec3(), hi.as_dvec3());
    if !(lo.is_finite() && hi.is_finite() && lo.cmple(hi).all()) {
        return Some(true);
    }
    let ext = hi - lo;
    let min_len = (1e-6 * ext.max_element()).max(super::merge::COINCIDENT_EPS as f64 * csg.scale(solid) as f64);
    let mut out = Vec::new();
    for (o, d) in probe_rays(lo, hi, n) {
        let whole = intervals_f64_within(csg, solid, o, d, &mut out, budget);
        // (`d` is a unit vector: lengths in `t` are world lengths.)
        if out.iter().any(|&(a, b)| b - a > min_len) {
            return Some(true);
        }
        if !whole {
            return None;
        }
    }
    Some(false)
}

/// A thin part of a CSG solid found by [`thinnest_part`]: its thickness (world units) and a point in it.
#[derive(Clone, Copy, Debug)]
pub struct ThinPart {
    pub thickness: f64,
    pub at: DVec3,
}

/// Walks rays through one solid, in f64, with crossings closer than `fine` (world units) taken as one:
/// the inside intervals of every operation node of its program (each `Op` instruction's result), with the
/// leaves whose crossings bound them, and whether the whole solid changes state there too.
struct NodeWalker<'a> {
    leaves: &'a [super::solid::Leaf],
    prog: &'a [super::program::Instr],
    /// Per instruction, the range of the solid's leaves under it.
    under: Vec<(u32, u32)>,
    /// Per leaf, its world bounds (`None`: a half-space, met by every ray) and its f64 world-to-object map.
    bounds: Vec<Option<(DVec3, DVec3)>>,
    w2o: Vec<glam::DAffine3>,
    fine: f64,
    evs: Vec<(f64, u32)>,
    state: Vec<bool>,
    node: Vec<bool>,
    /// Per instruction, where its current inside interval began: whether the solid changed state there, and the crossing.
    entry: Vec<(bool, usize)>,
    changed: Vec<usize>,
    stack: Vec<bool>,
    /// Leaf tests and program instructions the walks took so far, and how many they may take: a walk
    /// stops where `work` reaches `budget`.
    work: u64,
    budget: u64,
}

/// One inside interval of an operation node along a walked ray: `(t0, t1)`, the crossings (indices into
/// the walk's sorted events) of leaves under the node at its ends, and whether the solid changes state at
/// either end (the interval shows: it is not inside another operand of a union, say).
#[derive(Clone, Copy, Debug)]
struct NodeSpan {
    instr: usize,
    t0: f64,
    t1: f64,
    leaf0: u32,
    leaf1: u32,
    shows: bool,
}

impl<'a> NodeWalker<'a> {
    fn new(csg: &'a Csg, solid: u32, fine: f64) -> Option<Self> {
        use super::program::Instr;
        let s = csg.solids.get(solid as usize)?;
        let leaves = &csg.leaves[s.leaf_start as usize..(s.leaf_start + s.leaf_count) as usize];
        let prog = csg.program(s);
        let mut under = Vec::with_capacity(prog.len());
        let mut stack: Vec<(u32, u32)> = Vec::new();
        for ins in prog {
            let r = match *ins {
                Instr::Leaf(k) => (k, k + 1),
                Instr::Op(_) => {
                    let b = stack.pop()?;
                    let a = stack.pop()?;
                    (a.0.min(b.0), a.1.max(b.1))
                }
            };
            stack.push(r);
            under.push(r);
        }
        let bounds = leaves.iter().map(|l| l.bounds().map(|(lo, hi)| (lo.as_dvec3(), hi.as_dvec3()))).collect();
        Some(NodeWalker {
            leaves,
            prog,
            under,
            bounds,
            w2o: leaves.iter().map(|l| l.world_to_object_f64()).collect(),
            fine,
            evs: Vec::new(),
            state: vec![false; leaves.len()],
            node: vec![false; prog.len()],
            entry: vec![(false, 0); prog.len()],
            changed: Vec::new(),
            stack: Vec::new(),
            work: 0,
            budget: u64::MAX,
        })
    }

    /// The spans of every operation node along `o + t d` (`d` unit), to `visit`; none where no two
    /// crossings of different leaves are closer than `near` (and farther apart than `fine`).
    fn walk(&mut self, o: DVec3, d: DVec3, near: f64, mut visit: impl FnMut(&Self, NodeSpan)) {
        use super::program::Instr;
        self.evs.clear();
        self.work += self.leaves.len() as u64;
        for (k, leaf) in self.leaves.iter().enumerate() {
            if let Some((lo, hi)) = self.bounds[k] {
                // (Widened: the bounds are f32, the crossings f64.)
                let pad = 1e-6 * (hi - lo).max_element().max(lo.abs().max_element()).max(hi.abs().max_element());
                let (t1, t2) = ((lo - pad - o) / d, (hi + pad - o) / d);
                let (near, far) = (t1.min(t2).max_element(), t1.max(t2).min_element());
                if !(near <= far) {
                    continue;
                }
            }
            let w2o = &self.w2o[k];
            let c = leaf_object_f64(leaf.shape, w2o.transform_point3(o), w2o.transform_vector3(d));
            for iv in 0..2 {
                if c[2 * iv] < c[2 * iv + 1] {
                    self.evs.push((c[2 * iv], k as u32));
                    self.evs.push((c[2 * iv + 1], k as u32));
                }
            }
        }
        self.evs.sort_by(|x, y| x.0.total_cmp(&y.0));
        // (Only a ray with crossings of two leaves closer than `near` can hold a span that short.)
        if !self.evs.windows(2).any(|w| w[0].1 != w[1].1 && w[1].0 - w[0].0 > self.fine && w[1].0 - w[0].0 < near) {
            return;
        }
        self.state.iter_mut().for_each(|s| *s = false);
        self.node.iter_mut().for_each(|s| *s = false);
        let root = self.prog.len() - 1;
        let mut i = 0;
        while i < self.evs.len() {
            let (g0, t0) = (i, self.evs[i].0);
            while i < self.evs.len() && self.evs[i].0 <= t0 + self.fine {
                let k = self.evs[i].1 as usize;
                self.state[k] = !self.state[k];
                i += 1;
            }
            let group = g0..i;
            // (The whole program runs at each group of crossings: a ray through n leaves costs ~n^2, and
            // one solid of 1e5 overlapping leaves took 21 s of its setup here before this was counted.)
            if self.work >= self.budget {
                return;
            }
            self.work += self.prog.len() as u64;
            self.stack.clear();
            let mut changed = std::mem::take(&mut self.changed);
            changed.clear();
            for (j, ins) in self.prog.iter().enumerate() {
                let v = match *ins {
                    Instr::Leaf(k) => self.state[k as usize],
                    Instr::Op(op) => {
                        let b = self.stack.pop().unwrap_or(false);
                        let a = self.stack.pop().unwrap_or(false);
                        op.apply(a, b)
                    }
                };
                self.stack.push(v);
                if matches!(ins, Instr::Op(_)) && v != self.node[j] {
                    changed.push(j);
                }
            }
            let root_changed = changed.last() == Some(&root);
            for &j in &changed {
                self.node[j] = !self.node[j];
                // The crossing of a leaf under node `j` in this group.
                let (a, b) = self.under[j];
                let Some(e) = group.clone().find(|&e| (a..b).contains(&self.evs[e].1)) else { continue };
                if self.node[j] {
                    self.entry[j] = (root_changed, e);
                } else {
                    let (shown, e0) = self.entry[j];
                    let span = NodeSpan {
                        instr: j,
                        t0: self.evs[e0].0,
                        t1: self.evs[e].0,
                        leaf0: self.evs[e0].1,
                        leaf1: self.evs[e].1,
                        shows: shown || root_changed,
                    };
                    visit(self, span);
                }
            }
            self.changed = changed;
        }
    }

    /// The outward normal (world, unit) of leaf `k` at world point `p`, oriented against `d` when
    /// `entering`, along it otherwise.
    fn normal(&self, k: u32, p: DVec3, d: DVec3, entering: bool) -> DVec3 {
        let leaf = &self.leaves[k as usize];
        let w2o = &self.w2o[k as usize];
        let q = w2o.transform_point3(p);
        let n = (w2o.matrix3.transpose() * super::solid::object_normal(leaf.shape, q.as_vec3()).as_dvec3()).normalize_or_zero();
        if (n.dot(d) < 0.0) == entering {
            n
        } else {
            -n
        }
    }
}

/// The thinnest part (thinner than `limit`, world units) that the solid's operations make, found by the
/// `3 n^2` [`probe_rays`]: an inside interval of an operation node (a difference, intersection or union
/// of its operands: a wall left between a hole and the far face of its part, a floor, a skin) that
/// shows in the solid (the solid changes state at one of its ends), bounded by faces whose outward
/// normals are opposite within 14 degrees (a wall, not the corner of an edge or a tangent graze), crossed
/// within 78 degrees of its normal, and thinner than `limit` across its faces; then confirmed as a
/// part, not a point: rays along the wall's normal through the point and 1% of the bounds' diagonal
/// beside it four ways (along the wall) cross the node's inside there in less than `limit` each, so a
/// knife edge (a lens's rim), two touching holes and a rounding sliver at an edge are not taken for
/// walls. Crossings within `fine` (world units) of each other are one (faces meant to be flush).
/// Single leaves are not looked at (their thickness is `Leaf::thickness`). `None`: no such part found.
/// The walks take their leaf tests and program instructions from `budget`, and stop where it runs out
/// (with what they found by then).
pub fn thinnest_part(csg: &Csg, solid: u32, n: u32, limit: f64, fine: f64, budget: &mut u64) -> Option<ThinPart> {
    let mut w = NodeWalker::new(csg, solid, fine)?;
    w.budget = *budget;
    let found = thinnest_part_within(&mut w, csg, solid, n, limit);
    *budget = budget.saturating_sub(w.work);
    found
}

fn thinnest_part_within(w: &mut NodeWalker, csg: &Csg, solid: u32, n: u32, limit: f64) -> Option<ThinPart> {
    let (lo, hi) = csg.bounds(solid);
    let (lo, hi) = (lo.as_dvec3(), hi.as_dvec3());
    if !(lo.is_finite() && hi.is_finite() && lo.cmple(hi).all() && limit > w.fine) {
        return None;
    }
    if !w.prog.iter().any(|i| matches!(i, super::program::Instr::Op(_))) {
        return None;
    }
    let side = 0.01 * (hi - lo).length();
    let mut candidates = Vec::new();
    for (o, d) in probe_rays(lo, hi, n) {
        if w.work >= w.budget {
            return None;
        }
        w.walk(o, d, 5.0 * limit, |w, s| {
            let len = s.t1 - s.t0;
            if !s.shows || len * 0.2 >= limit {
                return;
            }
            let (p0, p1) = (o + d * s.t0, o + d * s.t1);
            let (n0, n1) = (w.normal(s.leaf0, p0, d, true), w.normal(s.leaf1, p1, d, false));
            let cos = -n0.dot(d);
            if n0.dot(n1) < -0.97 && cos > 0.2 && len * cos < limit {
                candidates.push((s.instr, (p0 + p1) * 0.5, (n0 - n1).normalize_or_zero()));
            }
        });
    }
    // Confirm: across the wall at the point and beside it, along the wall.
    let mut best: Option<ThinPart> = None;
    for (instr, p, nrm) in candidates {
        let u = nrm.any_orthonormal_vector();
        let v = nrm.cross(u);
        let mut thickness = f64::NAN;
        let mut thin_everywhere = true;
        for (k, off) in [DVec3::ZERO, u, -u, v, -v].into_iter().enumerate() {
            if w.work >= w.budget {
                return best;
            }
            let q = p + off * side;
            // The node's interval nearest `q` along the normal, within `side` of it.
            let mut nearest: Option<(f64, f64)> = None;
            w.walk(q, nrm, f64::INFINITY, |_, s| {
                if s.instr == instr {
                    let dist = if s.t0 > 0.0 {
                        s.t0
                    } else if s.t1 < 0.0 {
                        -s.t1
                    } else {
                        0.0
                    };
                    if dist <= side && nearest.is_none_or(|(d0, _)| dist < d0) {
                        nearest = Some((dist, s.t1 - s.t0));
                    }
                }
            });
            match nearest {
                Some((_, len)) if len < limit => {
                    if k == 0 {
                        thickness = len;
                    }
                }
                _ => {
                    thin_everywhere = false;
                    break;
                }
            }
        }
        if thin_everywhere && best.is_none_or(|b| thickness < b.thickness) {
            best = Some(ThinPart { thickness, at: p });
        }
    }
    best
}
