//! Roth's interval merge (S. D. Roth, "Ray Casting for Modeling Solids", CGIP 18, 1982) and its scratch
//! arena.
//!
//! A solid's inside along a ray is a sorted list of events `t0 < t1 < ...` alternating entry / exit (even
//! index = entry). Each leaf contributes its intervals; every operator of the postfix program pops two
//! lists and pushes their combination, computed by one sweep over both lists (time linear in the number of
//! events). Each event carries the global id of the leaf whose surface it is, and a `FLIP` bit toggled each
//! time the event passes through the right operand of a difference: there the solid's outward normal is
//! the leaf's inward one.
//!
//! # Coincident crossings (the one rule)
//!
//! Crossings closer than a tolerance are **one event**: the sweep takes the earliest pending crossing
//! `t0` of either operand, applies together every crossing of both operands with
//! `t <= t0 + tol(t0)`, and emits a boundary only if the combined inside/outside state differs from the
//! state before the group. With `o`, `d` the world ray (`d` need not be unit):
//!
//! ```text
//! tol(t) = COINCIDENT_EPS * (max(L, |o|) / |d| + |t|)        COINCIDENT_EPS = 1e-5
//! ```
//!
//! i.e. in world units, `1e-5 * (max(L, |o|) + |t d|)`: relative to the magnitude of the coordinates the
//! f32 crossings were computed from: the ray's (`|o|`, `|t d|`) and the solid's own, `L` = the largest
//! |coordinate| of the solid's bounds and of its leaves' placements. So the rule is the same at every
//! scene scale (an absolute floor would swallow a solid smaller than it: 1e-5 is 10% of a 1e-4 solid). The
//! boundary emitted for a group is the first crossing of the group, from the operand whose own state
//! changed the same way as the result's (`a` preferred), so its leaf (and flip) is a surface that really
//! bounds the result there.
//!
//! Consequences: `A - A` is empty; `A ∪ A = A ∩ A = A`; a hole whose cap is flush with a face leaves a clean
//! opening (no face is reported inside the hole); two faces closer than the tolerance are one face (and a
//! slab thinner than it vanishes when combined with another operand). Events of a single leaf list that
//! reaches the top of the program unmerged are not regrouped.

use super::program::{Instr, Op};
use super::CsgHit;
use crate::simd::f32x8;

/// Relative tolerance of the coincident-crossing rule (see the module docs).
pub const COINCIDENT_EPS: f32 = 1e-5;

/// Set on an event's tag when the surface belongs to a subtracted solid.
pub(crate) const FLIP: u32 = 1 << 31;

/// One crossing: parameter and tag (global leaf id, `FLIP` bit).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Ev {
    pub t: f32,
    pub tag: u32,
}

/// Per-ray part of the tolerance, `COINCIDENT_EPS * max(L, |o|) / |d|`, in units of `t` (`L`: the
/// solid's scale, [`super::Csg::scale`]).
#[inline]
pub fn tol_base(o_len: f32, d_len: f32, solid_scale: f32) -> f32 {
    COINCIDENT_EPS * o_len.max(solid_scale) / d_len
}

/// The tolerance `tol(t)` (`|t|` is capped so that `±inf` gives a finite tolerance, never NaN).
#[inline(always)]
pub(crate) fn tol_at(t: f32, base: f32) -> f32 {
    base + COINCIDENT_EPS * t.abs().min(1e30)
}

/// [`tol_at`] in 8 lanes (the same operations: the same values).
#[inline(always)]
pub(crate) fn tol_at_x8(t: f32x8, base: f32x8) -> f32x8 {
    base + f32x8::splat(COINCIDENT_EPS) * t.abs().min(f32x8::splat(1e30))
}

/// An upper bound of `tol_at(t, base)` over 8 lanes for every `|t| <= big`, widened by 1% against
/// rounding: the longest group the merge can form among crossings no larger than `big`.
#[inline(always)]
pub(crate) fn tol_bound_x8(big: f32x8, base: f32x8) -> f32x8 {
    (base + f32x8::splat(COINCIDENT_EPS) * big.min(f32x8::splat(1e30))) * f32x8::splat(1.01)
}

/// Last parameter of the group that starts at `t0`.
#[inline(always)]
pub(crate) fn group_end(t0: f32, base: f32) -> f32 {
    t0 + tol_at(t0, base)
}

/// `a op b` for the two lists on top of the stack `evs` (`a = evs[sa..sb]`, `b = evs[sb..]`), left in
/// place as `evs[sa..]`. Both lists alternate entry/exit starting with an entry. An empty operand or
/// disjoint spans (farther apart than the tolerance) need no sweep, and mostly no copy: the result is
/// one operand, already where it belongs, or nothing; only the general sweep goes through `tmp`.
#[inline(always)]
pub(crate) fn combine_top(evs: &mut Vec<Ev>, sa: usize, sb: usize, op: Op, base: f32, tmp: &mut Vec<Ev>) {
    let (a_empty, b_empty) = (sa == sb, sb == evs.len());
    // Empty operands.
    match op {
        // b (at sb == sa) is the result.
        Op::Union if a_empty => return,
        // a is the result.
        Op::Union | Op::Difference if b_empty => return evs.truncate(sb),
        Op::Intersection | Op::Difference if a_empty => return evs.truncate(sa),
        Op::Intersection if b_empty => return evs.truncate(sa),
        _ => {}
    }
    let (a_first, a_last) = (evs[sa].t, evs[sb - 1].t);
    let (b_first, b_last) = (evs[sb].t, evs[evs.len() - 1].t);
    let a_before = group_end(a_last, base) < b_first;
    let b_before = group_end(b_last, base) < a_first;
    if a_before || b_before {
        match op {
            Op::Intersection => evs.truncate(sa),
            Op::Difference => evs.truncate(sb),
            // a then b: as they are.
            Op::Union if a_before => {}
            // b then a.
            Op::Union => evs[sa..].rotate_left(sb - sa),
        }
        return;
    }
    let flip_b = if op == Op::Difference { FLIP } else { 0 };
    tmp.clear();
    sweep(&evs[sa..sb], &evs[sb..], op, flip_b, base, tmp);
    evs.truncate(sa);
    evs.extend_from_slice(tmp);
}

/// The general sweep with grouping of coincident crossings.
fn sweep(a: &[Ev], b: &[Ev], op: Op, flip_b: u32, base: f32, out: &mut Vec<Ev>) {
    let is_diff = op == Op::Difference;
    let (mut i, mut j) = (0, 0);
    let (mut in_a, mut in_b, mut in_r) = (false, false, false);
    while i < a.len() || j < b.len() {
        let ta = a.get(i).map_or(f32::INFINITY, |e| e.t);
        let tb = b.get(j).map_or(f32::INFINITY, |e| e.t);
        let end = group_end(ta.min(tb), base);
        let (i0, j0) = (i, j);
        while i < a.len() && a[i].t <= end {
            i += 1;
        }
        while j < b.len() && b[j].t <= end {
            j += 1;
        }
        if i == i0 && j == j0 {
            // Only a NaN (a NaN crossing, or -inf plus an infinite tolerance) takes nothing: the first
            // pending crossing then goes alone, so the sweep always ends. Finite and infinite crossings
            // always take at least the first (`t0 <= t0 + tol`), and never come here.
            if i < a.len() && !(tb < ta) {
                i += 1;
            } else {
                j += 1;
            }
        }
        let na = in_a ^ ((i - i0) & 1 == 1);
        let nb = in_b ^ ((j - j0) & 1 == 1);
        let nr = op.apply(na, nb);
        if nr != in_r {
            // Attribute the boundary to an operand that moved the same way as the result.
            let a_ok = na != in_a && na == nr;
            let b_ok = nb != in_b && (nb ^ is_diff) == nr;
            // (One of the two always holds; the fallback only keeps the index inside the group.)
            let e = if a_ok || (!b_ok && i > i0) { a[i0] } else { Ev { t: b[j0].t, tag: b[j0].tag ^ flip_b } };
            out.push(e);
            in_r = nr;
        }
        in_a = na;
        in_b = nb;
    }
}

/// Reusable scratch for the merge: the stack of interval lists, one temporary list, and the crossings of
/// the current packet. Vectors only grow (to the largest solid and list seen); no allocation per ray after
/// warm-up.
#[derive(Clone, Debug, Default)]
pub struct CsgArena {
    pub(crate) evs: Vec<Ev>,
    pub(crate) tmp: Vec<Ev>,
    pub(crate) starts: Vec<usize>,
    /// Per leaf of the solid (or of a packet's compacted program): `[a0, b0, a1, b1]`, each over the 8
    /// lanes.
    pub(crate) cross: Vec<[[f32; 8]; 4]>,
    /// The packet's compacted program, for solids with a cull program (`cull.rs`).
    pub(crate) compact: super::cull::Compacted,
}

impl CsgArena {
    pub fn new() -> Self {
        Self::default()
    }

    /// Total capacity (elements over all buffers): stops changing once warmed up.
    pub fn capacity(&self) -> usize {
        self.evs.capacity() + self.tmp.capacity() + self.starts.capacity() + self.cross.capacity() + self.compact.capacity()
    }
}

/// One lane's merge: the solid's program and leaf ids, the lane's `(tmin, tmax)` (the caller has checked
/// `tmin < tmax`) and its coincidence tolerance base.
pub(crate) struct LaneJob<'a> {
    pub(crate) prog: &'a [Instr],
    pub(crate) lane: usize,
    pub(crate) tmin: f32,
    pub(crate) tmax: f32,
    pub(crate) base: f32,
}

/// Run a solid's program on one lane of the crossings table; first boundary in `(tmin, tmax)`.
///
/// Intervals that end before `tmin` or start after `tmax` by more than twice the tolerance cannot change
/// the state in `(tmin, tmax)` and are skipped.
pub(crate) fn eval_lane(job: &LaneJob, arena: &mut CsgArena) -> Option<CsgHit> {
    let mut first = None;
    boundaries(job, arena, |h| {
        first = Some(h);
        true
    });
    first
}

/// Every boundary in `(tmin, tmax)` of one lane, in order along the ray (as [`eval_lane`] finds the first).
pub(crate) fn for_each_boundary(job: &LaneJob, arena: &mut CsgArena, mut visit: impl FnMut(CsgHit)) {
    boundaries(job, arena, |h| {
        visit(h);
        false
    });
}

/// The merge, then the boundaries in `(tmin, tmax)` in order until `visit` returns true.
#[inline(always)]
fn boundaries(job: &LaneJob, arena: &mut CsgArena, mut visit: impl FnMut(CsgHit) -> bool) {
    if !merge_lane(job, arena) {
        return;
    }
    for (i, e) in arena.evs.iter().enumerate() {
        if e.t >= job.tmax {
            break;
        }
        if e.t > job.tmin && visit(boundary(i, e)) {
            return;
        }
    }
}

/// The boundary at position `i` of a merged list (even positions enter the solid).
#[inline(always)]
fn boundary(i: usize, e: &Ev) -> CsgHit {
    CsgHit { t: e.t, leaf: e.tag & !FLIP, flip: e.tag & FLIP != 0, entering: i.is_multiple_of(2) }
}

/// Stack entries of [`lanes_with_boundaries_x8`]: deeper programs take the merge on every lane.
const HULL_STACK: usize = 8;

/// The lanes of a packet whose merge may have a boundary in `(tmin, tmax)`: a conservative test in 8
/// lanes on the crossing table, before the merge per lane, which the other lanes skip.
///
/// Every event of a merged list is a copy of a leaf crossing (the sweep emits a crossing of the group
/// it closes; the shortcuts keep or drop whole lists), so each node's events lie in an interval `[L, H]`
/// computed bottom-up: a leaf's from its non-empty intervals; a union's `[min L, max H]`; an
/// intersection's `[max L - tol, min H + tol]` (the result changes only inside both operands, up to the
/// group that contains the change: its first crossing may precede the operand's own by the tolerance,
/// and the emitted crossing may follow the group's start by as much); a difference's `[L_a - tol, H_a +
/// tol]` (only where `a` is inside); `L > H` means no event. `tol` is the largest group tolerance the
/// operator can use, `tol_at` at the largest crossing of the leaves pushed so far, widened by 1% against
/// rounding. A lane whose interval misses `(tmin, tmax)` has no boundary there: the merge would find none.
#[inline]
pub(crate) fn lanes_with_boundaries_x8(prog: &[Instr], cross: &[[[f32; 8]; 4]], tmin: f32x8, tmax: f32x8, base: f32x8) -> u32 {
    let (inf, ninf) = (f32x8::splat(f32::INFINITY), f32x8::splat(f32::NEG_INFINITY));
    // Largest |crossing| of the non-empty intervals of the leaves pushed so far: an operator's groups are
    // made of its operands' crossings, all from leaves already pushed.
    let mut big = f32x8::ZERO;
    let mut st = [(inf, ninf); HULL_STACK];
    let mut sp = 0;
    for ins in prog {
        match *ins {
            Instr::Leaf(k) => {
                if sp == HULL_STACK {
                    return u32::MAX;
                }
                let c = &cross[k as usize];
                let (mut lo, mut hi) = (inf, ninf);
                for iv in 0..2 {
                    let (t0, t1) = (f32x8::from(c[2 * iv]), f32x8::from(c[2 * iv + 1]));
                    let ok = t0.simd_lt(t1);
                    lo = lo.min(ok.select(t0, inf));
                    hi = hi.max(ok.select(t1, ninf));
                    big = big.max(ok.select(t0.abs().max(t1.abs()), f32x8::ZERO));
                }
                st[sp] = (lo, hi);
                sp += 1;
            }
            Instr::Op(op) => {
                if sp < 2 {
                    return u32::MAX;
                }
                sp -= 1;
                let ((la, ha), (lb, hb)) = (st[sp - 1], st[sp]);
                let tol = tol_bound_x8(big, base);
                let (lo, hi) = match op {
                    Op::Union => (la.min(lb), ha.max(hb)),
                    Op::Intersection => (la.max(lb) - tol, ha.min(hb) + tol),
                    Op::Difference => (la - tol, ha + tol),
                };
                // Canonical empty, so that a union with it keeps the other operand's interval.
                let empty = lo.simd_gt(hi);
                st[sp - 1] = (empty.select(inf, lo), empty.select(ninf, hi));
            }
        }
    }
    if sp != 1 {
        return u32::MAX;
    }
    let (lo, hi) = st[0];
    // Some event may lie in (tmin, tmax): lo < tmax and hi > tmin (false for the empty interval).
    (lo.simd_lt(tmax) & hi.simd_gt(tmin)).to_bitmask()
}

/// The merge of [`eval_lane`]: the solid's interval list for `(tmin, tmax)` left in `arena.evs`. False for
/// a malformed program.
#[inline(always)]
fn merge_lane(job: &LaneJob, arena: &mut CsgArena) -> bool {
    let LaneJob { prog, lane, tmin, tmax, base } = *job;
    let CsgArena { evs, tmp, starts, cross, .. } = arena;
    evs.clear();
    starts.clear();
    // (`cull::compact_x8` drops leaves by these cuts taken at 3 tolerances: keep them the wider.)
    let lo_cut = tmin - 2.0 * tol_at(tmin, base);
    let hi_cut = tmax + 2.0 * tol_at(tmax, base);
    for ins in prog {
        match *ins {
            Instr::Leaf(k) => {
                starts.push(evs.len());
                let c = &cross[k as usize];
                let tag = k;
                for iv in 0..2 {
                    let (t0, t1) = (c[2 * iv][lane], c[2 * iv + 1][lane]);
                    if t0 < t1 && t1 >= lo_cut && t0 <= hi_cut {
                        evs.push(Ev { t: t0, tag });
                        evs.push(Ev { t: t1, tag });
                    }
                }
            }
            Instr::Op(op) => {
                let (Some(sb), Some(sa)) = (starts.pop(), starts.last().copied()) else {
                    return false;
                };
                combine_top(evs, sa, sb, op, base, tmp);
            }
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::csg::program::{random_postfix, TEST_CROSSINGS};

    /// The 8-lane pre-test never drops a lane whose merge has a boundary in `(tmin, tmax)`: random postfix
    /// programs (1 to 7 leaves, every operator, nested both ways) over crossings drawn from a small set of
    /// values (so that crossings coincide, within and across the tolerance), with empty, inverted, infinite
    /// and NaN intervals, against `eval_lane` and `for_each_boundary` on every lane it drops.
    #[test]
    fn pretest_keeps_every_lane_with_a_boundary() {
        let mut f = crate::sample::hash::test_uniforms(0x4a11_b0d5);
        let values = TEST_CROSSINGS;
        let pick = |f: &mut dyn FnMut() -> f32| values[((f() * values.len() as f32) as usize).min(values.len() - 1)];
        let mut arena = CsgArena::new();
        let (mut dropped, mut kept, mut with_boundary) = (0, 0, 0);
        for case in 0..20000 {
            let n = 1 + case % 7;
            let prog = random_postfix(n, &mut f);
            let mut cross = vec![[[0.0f32; 8]; 4]; n];
            for c in cross.iter_mut() {
                for iv in 0..2 {
                    let (lower, upper) = c.split_at_mut(2 * iv + 1);
                    for (x0, x1) in lower[2 * iv].iter_mut().zip(upper[0].iter_mut()) {
                        let (mut t0, mut t1) = (pick(&mut f), pick(&mut f));
                        // Mostly ordered intervals; the second often empty (NaN).
                        if f() < 0.8 && t0 > t1 {
                            (t0, t1) = (t1, t0);
                        }
                        if iv == 1 && f() < 0.4 {
                            (t0, t1) = (f32::NAN, f32::NAN);
                        }
                        (*x0, *x1) = (t0, t1);
                    }
                }
            }
            let tmin: [f32; 8] = std::array::from_fn(|_| if f() < 0.5 { 0.0 } else { pick(&mut f).max(-5.0) });
            let tmax: [f32; 8] = std::array::from_fn(|l| if f() < 0.3 { f32::INFINITY } else { tmin[l] + 0.1 + 3.0 * f() });
            let base: [f32; 8] = std::array::from_fn(|_| [1e-5f32, 1e-3, 0.0][(f() * 3.0) as usize % 3]);
            arena.cross = cross.clone();
            let mask = lanes_with_boundaries_x8(&prog, &cross, f32x8::from(tmin), f32x8::from(tmax), f32x8::from(base));
            for lane in 0..8 {
                if !(tmax[lane] > tmin[lane]) {
                    continue;
                }
                let job = LaneJob { prog: &prog, lane, tmin: tmin[lane], tmax: tmax[lane], base: base[lane] };
                let first = eval_lane(&job, &mut arena);
                let mut all = 0;
                for_each_boundary(&job, &mut arena, |_| all += 1);
                with_boundary += first.is_some() as usize;
                if mask & (1 << lane) == 0 {
                    assert!(first.is_none() && all == 0, "case {case} lane {lane}: dropped a lane with a boundary ({first:?}): {prog:?}");
                    dropped += 1;
                } else {
                    kept += 1;
                }
            }
        }
        assert!(
            dropped > 20_000 && kept > 20_000 && with_boundary > 10_000,
            "{dropped} dropped, {kept} kept, {with_boundary} with a boundary"
        );
    }

    /// The sweep ends on crossings no ray should produce but arithmetic can: a NaN crossing, and -inf
    /// with an infinite tolerance (whose group end is NaN). Each merge runs on its own thread and must
    /// finish within seconds (before the guard it looped forever). Finite inputs never reach the guard:
    /// `tests/csg.rs` holds every merge to the reference.
    #[test]
    fn sweep_ends_on_nan_group_ends() {
        let cases: [(&[f32], &[f32], f32); 4] = [
            (&[f32::NAN, 1.0], &[0.5, 2.0], 1e-5),
            (&[0.0, 1.0], &[f32::NAN, f32::NAN], 1e-5),
            (&[f32::NEG_INFINITY, 1.0], &[0.0, 2.0], f32::INFINITY),
            (&[0.0, 3.0], &[f32::NEG_INFINITY, f32::NEG_INFINITY, 1.0, 2.0], f32::INFINITY),
        ];
        for (a, b, base) in cases {
            for op in [Op::Union, Op::Intersection, Op::Difference] {
                let (a, b) = (a.to_vec(), b.to_vec());
                let (tx, rx) = std::sync::mpsc::channel();
                std::thread::spawn(move || {
                    let mut evs: Vec<Ev> = a.iter().chain(&b).enumerate().map(|(k, &t)| Ev { t, tag: k as u32 }).collect();
                    combine_top(&mut evs, 0, a.len(), op, base, &mut Vec::new());
                    tx.send(evs.len()).unwrap();
                });
                let n = rx.recv_timeout(std::time::Duration::from_secs(20)).expect("the merge did not finish");
                assert!(n <= 6);
            }
        }
    }
}
