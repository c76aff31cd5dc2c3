//! The boundaries of a solid for 8 lanes at once (the first, or all in order), by point classification
//! at the leaf crossings, for lanes where that provably equals Roth's merge (`merge.rs`); the other
//! lanes take the merge.
//!
//! The merge sweeps each lane's sorted crossings one group at a time (crossings within the tolerance
//! `tol(t)` of a group's first are one event), which is a data-dependent loop per lane: about 650-1,000
//! instructions per lane on the CSG scenes here (callgrind). When no two crossings of a lane that could
//! matter lie within `2 T` of each other (`T`: the largest tolerance the merge can use for that lane,
//! `tol_at` at its largest finite crossing, widened by 1% against rounding), every group the merge forms
//! near `(tmin, tmax)` is a single crossing, and the merge's result there is fixed by inside/outside
//! states alone:
//!
//! - Between two groups the merge's state of every node of the program is the point state (the parity of
//!   the crossings passed), so the solid's state just before and just after a lone crossing `c` are
//!   `R(c-)` and `R(c+)`, the program evaluated on the leaves' closed/open interval tests at `c`.
//! - The merged list has an event at a lone crossing `c` exactly when `R(c-) != R(c+)`; the event is `c`
//!   itself, with its leaf (only that leaf's state moves there, so every operator on the way up
//!   attributes the boundary to it) and a `FLIP` bit that is the parity of the differences whose
//!   right operand holds the leaf; it enters the solid when `R(c+)` is inside.
//! - Which crossings could matter: a group that starts before `tmin - T` ends before `tmin` (each
//!   group is at most `T` long), so it yields no event in `(tmin, tmax)` and leaves point states behind
//!   it; a group that starts at or after `tmax` yields no event before `tmax`. So only crossings in
//!   `(tmin - 2 T, tmax + 2 T)` are compared, pairwise: a lane where two of them (of any leaves, or the
//!   two ends of one interval) are within `2 T` is left to the merge. Infinite crossings (half-spaces)
//!   are never within a finite distance of a finite one and never inside `(tmin, tmax)`: they are
//!   classified, not compared.
//!
//! So the first boundary is the nearest crossing in `(tmin, tmax)` where the state flips, and the list
//! of all is every such crossing in order. `tests` holds both to `eval_lane` and `for_each_boundary` bit
//! for bit on random programs and crossing tables built to coincide; `tests/csg.rs` renders solids whose
//! rays take either path (coincident faces go to the merge).

use super::merge::{tol_bound_x8, Ev};
use super::program::{Instr, Op};
use crate::simd::{f32x8, u32x8};

/// Leaves a program may have for the 8-lane path (its `FLIP` parities are bits of a `u32`, its present
/// intervals of a `u64`).
pub(crate) const FAST_LEAVES: usize = 32;

/// Entries of the mask stack: deeper programs take the merge (n-ary operators compile left-deep, so a
/// stack deeper than 2 needs nesting on the right). Kept small: it is zeroed at every evaluation (the
/// path's scratch is its cost: per-leaf arrays sized for 32 leaves instead of 16 had cost peer (a) 56
/// instructions per ray, 527 against 471, before the present intervals became bits).
const STACK: usize = 8;

/// What [`first_boundary_x8`] decided, per lane (bit `l` = lane `l`).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct FastHits {
    /// Lanes decided here: each has its first boundary in `t`, `leaf`, `flip`, `entering`, or none.
    pub decided: u32,
    /// Decided lanes that have a boundary in `(tmin, tmax)`.
    pub found: u32,
    pub t: [f32; 8],
    /// The leaf's index within the program (for the solid's own program, its index within the solid).
    pub leaf: [u32; 8],
    pub flip: u32,
    pub entering: u32,
}

/// Per leaf `k` of a postfix program, bit `k`: set when the leaf lies in the right operand of an odd
/// number of differences (its surfaces bound the result with their normals flipped). `None` for a
/// program beyond [`FAST_LEAVES`] leaves or [`STACK`] entries, or a malformed one.
pub(crate) fn flip_bits(prog: &[Instr]) -> Option<u32> {
    let mut st = [0u32; STACK];
    let (mut sp, mut flips) = (0usize, 0u32);
    for ins in prog {
        match *ins {
            Instr::Leaf(k) => {
                if k as usize >= FAST_LEAVES || sp == STACK {
                    return None;
                }
                st[sp] = 1 << k;
                sp += 1;
            }
            Instr::Op(op) => {
                if sp < 2 {
                    return None;
                }
                sp -= 1;
                if op == Op::Difference {
                    flips ^= st[sp];
                }
                st[sp - 1] |= st[sp];
            }
        }
    }
    (sp == 1).then_some(flips)
}

/// The program on 8 lanes of leaf states, twice in one pass: `leaf(j)` gives leaf `j`'s two states
/// (all-ones lanes inside), and the result is the solid's in each.
#[inline(always)]
fn eval2_x8(prog: &[Instr], mut leaf: impl FnMut(usize) -> (f32x8, f32x8)) -> (f32x8, f32x8) {
    let mut st = [(f32x8::ZERO, f32x8::ZERO); STACK];
    let mut sp = 0usize;
    for ins in prog {
        match *ins {
            Instr::Leaf(j) => {
                st[sp] = leaf(j as usize);
                sp += 1;
            }
            Instr::Op(op) => {
                sp -= 1;
                let ((a0, a1), (b0, b1)) = (st[sp - 1], st[sp]);
                st[sp - 1] = match op {
                    Op::Union => (a0 | b0, a1 | b1),
                    Op::Intersection => (a0 & b0, a1 & b1),
                    Op::Difference => (a0 & !b0, a1 & !b1),
                };
            }
        }
    }
    st[0]
}

/// A packet's query: the solid's program and [`flip_bits`], each leaf `k`'s crossing table `cross[k]`
/// (`[a0, b0, a1, b1]` over 8 lanes, NaN for an absent interval), the lanes' `(tmin, tmax)` and
/// tolerance bases (`tol_base`), and the lanes asked. The program must have passed [`flip_bits`].
#[derive(Clone, Copy)]
pub(crate) struct Query<'a> {
    pub prog: &'a [Instr],
    pub flips: u32,
    pub cross: &'a [[[f32; 8]; 4]],
    pub tmin: f32x8,
    pub tmax: f32x8,
    pub base: f32x8,
    pub lanes: u32,
}

/// What every query of a packet shares: which intervals are present, and the lanes decided here.
struct Prepared {
    /// Bit `2 k + iv`: interval `iv` of leaf `k` is present in some lane (a convex leaf's second never
    /// is; in a solid of many leaves a packet usually meets few).
    present: u64,
    /// Lanes among the asked ones whose crossings that could matter are all farther than `2 T` apart.
    decided: u32,
}

/// Crossings of present intervals a packet may have for the 8-lane path (more: every lane takes the
/// merge). The pairwise comparison holds them in an array zeroed per packet, so it is kept small.
const MAX_CROSSINGS: usize = 32;

/// Per lane: interval `iv` of a leaf's crossing table is not empty (`a < b`; NaN ends: empty).
#[inline(always)]
fn valid(ck: &[[f32; 8]; 4], iv: usize) -> f32x8 {
    f32x8::from(ck[2 * iv]).simd_lt(f32x8::from(ck[2 * iv + 1]))
}

/// The checks of the module doc for the lanes `lanes`: `Prepared::decided` are the lanes whose answer
/// point classification gives.
#[inline(always)]
fn prepare(q: &Query) -> Prepared {
    let Query { cross, tmin, tmax, base, lanes, .. } = *q;
    debug_assert!(cross.len() <= FAST_LEAVES);
    let (nan, inf) = (f32x8::NAN, f32x8::splat(f32::INFINITY));
    let mut p = Prepared { present: 0, decided: 0 };
    // Largest finite |crossing| of the present intervals: the tolerance bound T.
    let mut big = f32x8::ZERO;
    for (k, ck) in cross.iter().enumerate() {
        for iv in 0..2 {
            let ok = valid(ck, iv);
            if !ok.any() {
                continue;
            }
            p.present |= 1 << (2 * k + iv);
            for v in [f32x8::from(ck[2 * iv]), f32x8::from(ck[2 * iv + 1])] {
                let finite = v.abs().simd_lt(inf);
                big = big.max((ok & finite).select(v.abs(), f32x8::ZERO));
            }
        }
    }
    if 2 * p.present.count_ones() as usize > MAX_CROSSINGS {
        return p;
    }
    let t_big = tol_bound_x8(big, base);
    let two_t = t_big + t_big;
    let (lo, hi) = (tmin - two_t, tmax + two_t);
    // The crossings that could matter, NaN elsewhere (so that no comparison with them holds), each
    // compared with those before it: lanes with two within 2 T may have groups of several crossings.
    let mut near = [nan; MAX_CROSSINGS];
    let (mut close, mut m) = (f32x8::ZERO, 0);
    for_present_crossings(cross, &p, |_, c, ok| {
        let c = (ok & c.simd_gt(lo) & c.simd_lt(hi)).select(c, nan);
        for &o in &near[..m] {
            close |= (c - o).abs().simd_le(two_t);
        }
        near[m] = c;
        m += 1;
    });
    for (k, ck) in cross.iter().enumerate() {
        // A leaf's two intervals out of order (the kernels never give them, but the merge takes a lone
        // leaf's list as it comes): left to the merge too.
        if (p.present >> (2 * k)) & 3 == 3 {
            close |= valid(ck, 0) & valid(ck, 1) & !f32x8::from(ck[1]).simd_lt(f32x8::from(ck[2]));
        }
    }
    p.decided = lanes & !close.to_bitmask();
    p
}

/// At crossing `c` of leaf `k` (lanes decided by [`prepare`]): the solid's state just after and just
/// before it. Other leaves have no crossing at `c` in those lanes: one state serves both sides; leaf
/// `k`'s own intervals are closed at the entry for "after", at the exit for "before" (NaN ends compare
/// false: outside).
#[inline(always)]
fn states_at(prog: &[Instr], cross: &[[[f32; 8]; 4]], p: &Prepared, k: usize, c: f32x8) -> (f32x8, f32x8) {
    eval2_x8(prog, |j| {
        let (ck, (mut after, mut before)) = (&cross[j], (f32x8::ZERO, f32x8::ZERO));
        for jv in 0..2 {
            if (p.present >> (2 * j + jv)) & 1 == 0 {
                continue;
            }
            let (a, b) = (f32x8::from(ck[2 * jv]), f32x8::from(ck[2 * jv + 1]));
            if j == k {
                after |= c.simd_ge(a) & c.simd_lt(b);
                before |= c.simd_gt(a) & c.simd_le(b);
            } else {
                let s = c.simd_gt(a) & c.simd_lt(b);
                (after, before) = (after | s, before | s);
            }
        }
        (after, before)
    })
}

/// For each crossing `c` of leaf `k` in `(tmin, min(tmax, below(state)))` in a lane [`prepare`] decided,
/// where the solid's state flips: `f(state, k, c, lanes, after)` (`lanes`: the lanes where it does,
/// `after`: the state just after `c`, all-ones lanes inside).
#[inline(always)]
fn each_flip<S>(
    q: &Query,
    p: &Prepared,
    state: &mut S,
    below: impl Fn(&S) -> f32x8,
    mut f: impl FnMut(&mut S, usize, f32x8, f32x8, f32x8),
) {
    let Query { prog, cross, tmin, tmax, .. } = *q;
    let active = crate::simd::mask_from_bits(p.decided);
    for_present_crossings(cross, p, |k, c, ok| {
        let cand = active & ok & c.simd_gt(tmin) & c.simd_lt(tmax) & c.simd_lt(below(state));
        if !cand.any() {
            return;
        }
        let (ra, rb) = states_at(prog, cross, p, k, c);
        let hit = cand & (ra ^ rb);
        if hit.any() {
            f(state, k, c, hit, ra);
        }
    });
}

/// `f(leaf, crossing, valid)` for the crossings of the intervals present in some lane, leaf by leaf
/// (`valid`: the lanes where the crossing's interval is not empty). Internal iteration: a `flat_map` iterator
/// here was an out-of-line call per crossing, +15 instructions per ray on peer (a).
#[inline(always)]
fn for_present_crossings(cross: &[[[f32; 8]; 4]], p: &Prepared, mut f: impl FnMut(usize, f32x8, f32x8)) {
    let mut bits = p.present;
    while bits != 0 {
        let b = bits.trailing_zeros() as usize;
        bits &= bits - 1;
        let (k, iv) = (b / 2, b % 2);
        let (ck, ok) = (&cross[k], valid(&cross[k], iv));
        f(k, f32x8::from(ck[2 * iv]), ok);
        f(k, f32x8::from(ck[2 * iv + 1]), ok);
    }
}

/// The first boundary in `(tmin, tmax)` of the lanes `lanes`, for the lanes where point classification
/// provably gives the merge's answer (see the module doc).
pub(crate) fn first_boundary_x8(q: &Query) -> FastHits {
    let flips = q.flips;
    let p = prepare(q);
    let mut out = FastHits { decided: p.decided, ..FastHits::default() };
    if p.decided == 0 {
        return out;
    }
    // The nearest crossing in (tmin, tmax) where the state flips (crossings past the nearest flip so
    // far are not classified).
    let inf = f32x8::splat(f32::INFINITY);
    let mut near = (inf, u32x8::splat(0), f32x8::ZERO);
    each_flip(
        q,
        &p,
        &mut near,
        |n| n.0,
        |(best, leaf, entering), k, c, hit, ra| {
            *best = hit.select(c, *best);
            *leaf = bytemuck::cast::<f32x8, u32x8>(hit).select(u32x8::splat(k as u32), *leaf);
            *entering = hit.select(ra, *entering);
        },
    );
    let (best, leaf, entering) = near;
    let found = best.simd_lt(inf).to_bitmask() & p.decided;
    out.found = found;
    out.t = best.to_array();
    out.leaf = leaf.to_array();
    out.entering = entering.to_bitmask() & found;
    for l in 0..8 {
        if found & (1 << l) != 0 && flips & (1 << out.leaf[l]) != 0 {
            out.flip |= 1 << l;
        }
    }
    out
}

/// Every boundary in `(tmin, tmax)` of the lanes `lanes` that point classification decides, lane by
/// lane in order along the ray: `visit(lane, t, leaf, flip, entering)` (`leaf` within the solid).
/// Returns the decided lanes; the others are the caller's (the merge's). `scratch` holds the
/// boundaries found before they are sorted.
pub(crate) fn for_each_boundary_x8(q: &Query, scratch: &mut Vec<Ev>, mut visit: impl FnMut(usize, f32, u32, bool, bool)) -> u32 {
    let flips = q.flips;
    let p = prepare(q);
    if p.decided == 0 {
        return 0;
    }
    // Every flip of every lane, tagged (lane << 8 | leaf << 1 | entering), then sorted by lane and
    // distance (distinct within a decided lane).
    scratch.clear();
    let inf = f32x8::splat(f32::INFINITY);
    each_flip(
        q,
        &p,
        scratch,
        |_| inf,
        |scratch, k, c, hit, ra| {
            let (mut bits, ca, ra) = (hit.to_bitmask(), c.to_array(), ra.to_bitmask());
            while bits != 0 {
                let l = bits.trailing_zeros();
                bits &= bits - 1;
                scratch.push(Ev { t: ca[l as usize], tag: l << 8 | (k as u32) << 1 | (ra >> l) & 1 });
            }
        },
    );
    scratch.sort_unstable_by(|a, b| (a.tag >> 8).cmp(&(b.tag >> 8)).then(a.t.total_cmp(&b.t)));
    for e in scratch.iter() {
        let k = (e.tag >> 1) & 0x7f;
        visit((e.tag >> 8) as usize, e.t, k, flips & (1 << k) != 0, e.tag & 1 != 0);
    }
    p.decided
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::csg::merge::{eval_lane, for_each_boundary, CsgArena, LaneJob};
    use crate::csg::program::{random_postfix, TEST_CROSSINGS};

    /// Wherever the 8-lane path decides a lane, its answer is `eval_lane`'s bit for bit (distance, leaf,
    /// flip, entering, or no boundary), and its list of every boundary is `for_each_boundary`'s: random postfix programs of 1 to 9 leaves and every operator,
    /// over crossings drawn from a small set of values (so that crossings coincide exactly and within
    /// the tolerance, and the path must leave those lanes to the merge) mixed with spread ones, with
    /// absent, infinite and NaN intervals and second intervals. It must also decide most lanes whose
    /// crossings are spread, and leave lanes with coinciding crossings to the merge.
    #[test]
    fn decided_lanes_equal_the_merge() {
        let mut f = crate::sample::hash::test_uniforms(0x0fa5_7c56);
        let values = TEST_CROSSINGS;
        let mut arena = CsgArena::new();
        let (mut decided, mut left, mut found, mut spread_left, mut spread_all, mut several, mut decided_many) =
            (0usize, 0usize, 0usize, 0usize, 0usize, 0usize, 0usize);
        for case in 0..30000 {
            // Every tenth case a solid of 10-31 leaves most of which the packet misses (as the pips of a
            // die): leaf ids past 16 in the flip bits and the present-interval bits.
            let many = case % 10 == 9;
            let n = if many { 10 + case % 22 } else { 1 + case % 9 };
            let prog = random_postfix(n, &mut f);
            let Some(flips) = flip_bits(&prog) else { continue };
            // Half the cases draw from the small set (coincidences), half spread values.
            let spread = case % 2 == 0;
            let pick = |f: &mut dyn FnMut() -> f32| {
                if spread {
                    (f() - 0.3) * 10.0
                } else {
                    values[((f() * values.len() as f32) as usize).min(values.len() - 1)]
                }
            };
            let mut cross = vec![[[f32::NAN; 8]; 4]; n];
            for c in cross.iter_mut() {
                let lanes: [[f32; 4]; 8] = std::array::from_fn(|_| {
                    let mut v = [pick(&mut f), pick(&mut f), pick(&mut f), pick(&mut f)];
                    // Mostly sorted (a0 < b0 <= a1 < b1), sometimes not; the second interval often absent.
                    if f() < 0.85 {
                        v.sort_by(|a, b| a.total_cmp(b));
                    }
                    if f() < 0.6 {
                        (v[2], v[3]) = (f32::NAN, f32::NAN);
                    }
                    v
                });
                *c = std::array::from_fn(|i| std::array::from_fn(|l| lanes[l][i]));
                if many && f() < 0.75 {
                    *c = [[f32::NAN; 8]; 4];
                }
            }
            let tmin: [f32; 8] = std::array::from_fn(|_| if f() < 0.5 { 0.0 } else { pick(&mut f).clamp(-5.0, 5.0) });
            let tmax: [f32; 8] = std::array::from_fn(|l| if f() < 0.3 { f32::INFINITY } else { tmin[l].max(-5.0) + 0.1 + 6.0 * f() });
            let base: [f32; 8] = std::array::from_fn(|_| [1e-5f32, 1e-3, 0.0][(f() * 3.0) as usize % 3]);
            let lanes = (0..8).filter(|&l| tmax[l] > tmin[l]).fold(0u32, |m, l| m | 1 << l);
            let (t0, t1, b) = (f32x8::from(tmin), f32x8::from(tmax), f32x8::from(base));
            let q = Query { prog: &prog, flips, cross: &cross, tmin: t0, tmax: t1, base: b, lanes };
            let got = first_boundary_x8(&q);
            assert_eq!(got.decided & !lanes, 0);
            // Every boundary, per lane in the order visited.
            let mut all: [Vec<(u32, u32, bool, bool)>; 8] = Default::default();
            let mut scratch = Vec::new();
            let all_decided =
                for_each_boundary_x8(&q, &mut scratch, |l, t, k, flip, entering| all[l].push((t.to_bits(), k, flip, entering)));
            assert_eq!(all_decided, got.decided);
            // Packets with more crossings than the path holds are the merge's whole.
            let intervals = cross.iter().map(|ck| (0..2).filter(|&iv| valid(ck, iv).any()).count()).sum::<usize>();
            let spread = spread && 2 * intervals <= MAX_CROSSINGS;
            assert!(2 * intervals <= MAX_CROSSINGS || got.decided == 0);
            arena.cross = cross.clone();
            for l in 0..8 {
                if lanes & (1 << l) == 0 {
                    continue;
                }
                spread_all += spread as usize;
                if got.decided & (1 << l) == 0 {
                    left += 1;
                    spread_left += spread as usize;
                    continue;
                }
                decided += 1;
                decided_many += many as usize;
                let job = LaneJob { prog: &prog, lane: l, tmin: tmin[l], tmax: tmax[l], base: base[l] };
                let want = eval_lane(&job, &mut arena);
                let have = (got.found & (1 << l) != 0)
                    .then(|| (got.t[l].to_bits(), got.leaf[l], got.flip & (1 << l) != 0, got.entering & (1 << l) != 0));
                let want = want.map(|h| (h.t.to_bits(), h.leaf, h.flip, h.entering));
                assert_eq!(have, want, "case {case} lane {l}: {prog:?} tmin {} tmax {} base {}", tmin[l], tmax[l], base[l]);
                found += want.is_some() as usize;
                let mut every = Vec::new();
                for_each_boundary(&job, &mut arena, |h| every.push((h.t.to_bits(), h.leaf, h.flip, h.entering)));
                assert_eq!(all[l], every, "case {case} lane {l}: every boundary, {prog:?}");
                several += (every.len() > 1) as usize;
            }
        }
        assert!(
            decided > 60_000 && found > 20_000 && several > 5_000 && left > 20_000 && decided_many > 2_000,
            "{decided} decided ({found} with a boundary, {several} with several, {decided_many} of 10+ leaves), {left} left"
        );
        // Spread crossings rarely come within 2 T (T ~ 1e-3 at most here); the lanes left are mostly
        // those with a leaf's intervals out of order.
        assert!(spread_left * 10 < spread_all, "{spread_left} of {spread_all} spread lanes left to the merge");
    }

    #[test]
    fn flip_bits_follow_right_operands_of_differences() {
        use Instr::{Leaf as L, Op as O};
        // (0 - 1) - (2 - 3): leaf 1 once, leaf 2 once, leaf 3 twice (even).
        let prog = [L(0), L(1), O(Op::Difference), L(2), L(3), O(Op::Difference), O(Op::Difference)];
        assert_eq!(flip_bits(&prog), Some(0b0110));
        assert_eq!(flip_bits(&[L(0), L(1), O(Op::Union)]), Some(0));
        assert_eq!(flip_bits(&[L(0), O(Op::Union)]), None);
        assert_eq!(flip_bits(&[L(31)]), Some(0));
        assert_eq!(flip_bits(&[L(32)]), None);
    }
}
