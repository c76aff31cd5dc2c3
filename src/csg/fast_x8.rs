//! The first boundary of a solid for 8 lanes at once, by point classification at the leaf crossings,
//! for lanes where that provably equals Roth's merge (`merge.rs`); the other lanes take the merge.
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
//! So the answer is the nearest crossing in `(tmin, tmax)` where the state flips. `tests` holds this to
//! `eval_lane` bit for bit on random programs and crossing tables built to coincide, and
//! `tests/csg.rs` renders through both paths.

use super::merge::COINCIDENT_EPS;
use super::program::{Instr, Op};
use crate::simd::{f32x8, u32x8};

/// Leaves a program may have for the 8-lane path (its `FLIP` parities are bits of a `u32`; the
/// pairwise comparison grows with the square of the crossings).
pub(crate) const FAST_LEAVES: usize = 16;

/// Entries of the mask stack: deeper programs take the merge.
const STACK: usize = 16;

/// What [`first_boundary_x8`] decided, per lane (bit `l` = lane `l`).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct FastHits {
    /// Lanes decided here: each has its first boundary in `t`, `leaf`, `tag_flip`, `entering`, or none.
    pub decided: u32,
    /// Decided lanes that have a boundary in `(tmin, tmax)`.
    pub found: u32,
    pub t: [f32; 8],
    /// The leaf's index within the solid (add the solid's `leaf_start` for its global id).
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

/// The program on 8 lanes of leaf states, twice in one pass: the solid's state with leaf `k` in state
/// `own.0` and with it in state `own.1`, every other leaf `j` in state `inside[j]` (all-ones lanes
/// inside).
#[inline(always)]
fn eval2_x8(prog: &[Instr], inside: &[f32x8], k: usize, own: (f32x8, f32x8)) -> (f32x8, f32x8) {
    let mut st = [(f32x8::ZERO, f32x8::ZERO); STACK];
    let mut sp = 0usize;
    for ins in prog {
        match *ins {
            Instr::Leaf(j) => {
                let s = inside[j as usize];
                st[sp] = if j as usize == k { own } else { (s, s) };
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

/// The first boundary in `(tmin, tmax)` of the lanes `lanes`, for the lanes where point classification
/// provably gives the merge's answer (see the module doc). `cross[k]`: leaf `k`'s crossing table
/// (`[a0, b0, a1, b1]` over 8 lanes, NaN for an absent interval); `base`: each lane's tolerance base
/// (`tol_base`); `flips`: [`flip_bits`] of `prog`. The program must have passed [`flip_bits`].
pub(crate) fn first_boundary_x8(
    prog: &[Instr],
    flips: u32,
    cross: &[[[f32; 8]; 4]],
    tmin: f32x8,
    tmax: f32x8,
    base: f32x8,
    lanes: u32,
) -> FastHits {
    let n = cross.len();
    debug_assert!(n <= FAST_LEAVES);
    let nan = f32x8::NAN;
    // Intervals present in some lane (a convex leaf's second never is: its crossings are skipped).
    let mut present = [[false; 2]; FAST_LEAVES];
    let mut valid = [[f32x8::ZERO; 2]; FAST_LEAVES];
    // Largest finite |crossing| of the present intervals: the tolerance bound T.
    let mut big = f32x8::ZERO;
    let inf = f32x8::splat(f32::INFINITY);
    for k in 0..n {
        for iv in 0..2 {
            let (a, b) = (f32x8::from(cross[k][2 * iv]), f32x8::from(cross[k][2 * iv + 1]));
            let ok = a.simd_lt(b);
            valid[k][iv] = ok;
            present[k][iv] = ok.any();
            for v in [a, b] {
                let finite = v.abs().simd_lt(inf);
                big = big.max((ok & finite).select(v.abs(), f32x8::ZERO));
            }
        }
    }
    let t_big = (base + f32x8::splat(COINCIDENT_EPS) * big.min(f32x8::splat(1e30))) * f32x8::splat(1.01);
    let two_t = t_big + t_big;
    let (lo, hi) = (tmin - two_t, tmax + two_t);
    // The crossings that could matter, NaN elsewhere (so that no comparison with them holds).
    let mut near = [nan; 4 * FAST_LEAVES];
    let mut m = 0;
    for k in 0..n {
        for iv in 0..2 {
            if !present[k][iv] {
                continue;
            }
            for e in 0..2 {
                let c = f32x8::from(cross[k][2 * iv + e]);
                let keep = valid[k][iv] & c.simd_gt(lo) & c.simd_lt(hi);
                near[m] = keep.select(c, nan);
                m += 1;
            }
        }
    }
    // Lanes with two of them within 2 T: the merge's groups there may hold several crossings.
    let mut close = f32x8::ZERO;
    for i in 0..m {
        for j in i + 1..m {
            close |= (near[i] - near[j]).abs().simd_le(two_t);
        }
    }
    // A leaf's two intervals out of order (the kernels never give them, but the merge takes a lone
    // leaf's list as it comes): left to the merge too.
    for k in 0..n {
        if present[k][0] && present[k][1] {
            close |= valid[k][0] & valid[k][1] & !f32x8::from(cross[k][1]).simd_lt(f32x8::from(cross[k][2]));
        }
    }
    let decided = lanes & !close.to_bitmask();
    let mut out = FastHits { decided, ..FastHits::default() };
    if decided == 0 {
        return out;
    }
    // Each crossing in (tmin, tmax): the solid's state just before and just after it.
    let active = crate::simd::mask_from_bits(decided);
    let mut best = inf;
    let mut leaf = u32x8::splat(0);
    let mut entering = f32x8::ZERO;
    let mut inside = [f32x8::ZERO; FAST_LEAVES];
    for k in 0..n {
        for iv in 0..2 {
            if !present[k][iv] {
                continue;
            }
            for e in 0..2 {
                let c = f32x8::from(cross[k][2 * iv + e]);
                let cand = active & valid[k][iv] & c.simd_gt(tmin) & c.simd_lt(tmax) & c.simd_lt(best);
                if !cand.any() {
                    continue;
                }
                // Other leaves have no crossing at `c` in the lanes decided here: one state for both
                // sides. Leaf `k`'s own intervals: closed at the entry for "after", at the exit for
                // "before" (NaN ends compare false: outside).
                for j in 0..n {
                    if j == k {
                        continue;
                    }
                    let mut s = f32x8::ZERO;
                    for jv in 0..2 {
                        if present[j][jv] {
                            s |= c.simd_gt(f32x8::from(cross[j][2 * jv])) & c.simd_lt(f32x8::from(cross[j][2 * jv + 1]));
                        }
                    }
                    inside[j] = s;
                }
                let (mut after, mut before) = (f32x8::ZERO, f32x8::ZERO);
                for jv in 0..2 {
                    if present[k][jv] {
                        let (a, b) = (f32x8::from(cross[k][2 * jv]), f32x8::from(cross[k][2 * jv + 1]));
                        after |= c.simd_ge(a) & c.simd_lt(b);
                        before |= c.simd_gt(a) & c.simd_le(b);
                    }
                }
                let (ra, rb) = eval2_x8(prog, &inside[..n], k, (after, before));
                let hit = cand & (ra ^ rb);
                if hit.any() {
                    best = hit.select(c, best);
                    leaf = bytemuck::cast::<f32x8, u32x8>(hit).select(u32x8::splat(k as u32), leaf);
                    entering = hit.select(ra, entering);
                }
            }
        }
    }
    let found = best.simd_lt(inf).to_bitmask() & decided;
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::csg::merge::{eval_lane, CsgArena, LaneJob};

    /// Wherever the 8-lane path decides a lane, its answer is `eval_lane`'s bit for bit (distance, leaf,
    /// flip, entering, or no boundary): random postfix programs of 1 to 9 leaves and every operator,
    /// over crossings drawn from a small set of values (so that crossings coincide exactly and within
    /// the tolerance, and the path must leave those lanes to the merge) mixed with spread ones, with
    /// absent, infinite and NaN intervals and second intervals. It must also decide most lanes whose
    /// crossings are spread, and leave lanes with coinciding crossings to the merge.
    #[test]
    fn decided_lanes_equal_the_merge() {
        let mut f = crate::sample::hash::test_uniforms(0x0fa5_7c56);
        let values = [-3.0f32, 0.0, 0.5, 1.0, 1.0 + 2e-6, 1.0 + 3e-5, 2.0, 2.0 - 1e-6, 4.0, f32::INFINITY, f32::NEG_INFINITY, f32::NAN];
        let mut arena = CsgArena::new();
        let (mut decided, mut left, mut found, mut spread_left, mut spread_all) = (0usize, 0usize, 0usize, 0usize, 0usize);
        for case in 0..30000 {
            let n = 1 + case % 9;
            let mut prog = Vec::new();
            let (mut pushed, mut depth) = (0, 0);
            while pushed < n || depth > 1 {
                if pushed < n && (depth < 2 || f() < 0.5) {
                    prog.push(Instr::Leaf(pushed as u32));
                    pushed += 1;
                    depth += 1;
                } else {
                    prog.push(Instr::Op([Op::Union, Op::Intersection, Op::Difference][(f() * 3.0) as usize % 3]));
                    depth -= 1;
                }
            }
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
            }
            let tmin: [f32; 8] = std::array::from_fn(|_| if f() < 0.5 { 0.0 } else { pick(&mut f).clamp(-5.0, 5.0) });
            let tmax: [f32; 8] = std::array::from_fn(|l| if f() < 0.3 { f32::INFINITY } else { tmin[l].max(-5.0) + 0.1 + 6.0 * f() });
            let base: [f32; 8] = std::array::from_fn(|_| [1e-5f32, 1e-3, 0.0][(f() * 3.0) as usize % 3]);
            let lanes = (0..8).filter(|&l| tmax[l] > tmin[l]).fold(0u32, |m, l| m | 1 << l);
            let got = first_boundary_x8(&prog, flips, &cross, f32x8::from(tmin), f32x8::from(tmax), f32x8::from(base), lanes);
            assert_eq!(got.decided & !lanes, 0);
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
                let job = LaneJob { prog: &prog, leaf_start: 0, lane: l, tmin: tmin[l], tmax: tmax[l], base: base[l] };
                let want = eval_lane(&job, &mut arena);
                let have = (got.found & (1 << l) != 0)
                    .then(|| (got.t[l].to_bits(), got.leaf[l], got.flip & (1 << l) != 0, got.entering & (1 << l) != 0));
                let want = want.map(|h| (h.t.to_bits(), h.leaf, h.flip, h.entering));
                assert_eq!(have, want, "case {case} lane {l}: {prog:?} tmin {} tmax {} base {}", tmin[l], tmax[l], base[l]);
                found += want.is_some() as usize;
            }
        }
        assert!(decided > 60_000 && found > 20_000 && left > 20_000, "{decided} decided ({found} with a boundary), {left} left");
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
        assert_eq!(flip_bits(&[L(16)]), None);
    }
}
