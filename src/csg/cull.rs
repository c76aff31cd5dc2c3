//! Solids of many leaves: a bounding hierarchy inside the solid, so that a packet computes the
//! crossings of the leaves it can meet and merges a program of those alone.
//!
//! A plate with 1,000 holes is one solid: a box minus a union of 1,000 cylinders. Evaluated as written,
//! every packet that reaches the plate's bounds computes 1,001 leaf crossings and every lane merges
//! 2,000 instructions, while its rays meet two or three leaves: time linear in the leaves (0.7 s for a
//! 320 x 200 image of a 32 x 32 plate at 4 samples, against 0.017 s for 2 x 2 holes).
//!
//! So a solid of more than [`CULL_LEAVES`] leaves also gets a *cull program*, compiled once:
//!
//! - The tree is made binary and balanced, its operands in the order written: an n-ary union or
//!   intersection is split in halves recursively; a difference `a - b - c ...` becomes
//!   `a - (b ∪ c ∪ ...)`, the union balanced (the same set, and the same `FLIP` parity for every leaf:
//!   each subtracted leaf passes through one difference's right operand either way). The order is kept
//!   so that the face two overlapping operands share stays the first one's (a spatial sort handed it to
//!   another: session 33's user trial).
//! - In postfix order, every union operand and subtracted operand whose leaves' hull (the union of
//!   their world boxes) is finite is preceded by a [`CullInstr::Span`]: the hull, widened (see
//!   [`margin`]), and the length of its instructions.
//!
//! Per packet, [`compact_x8`] walks the cull program: an operand whose widened bounds no active lane's
//! segment `(lo_cut, hi_cut)` meets is skipped whole, a leaf is computed (`leaf_x8`) and dropped when no
//! active lane has an interval reaching into the segment, and each operator with an absent operand folds
//! as the merge folds an empty list (`x ∪ ∅ = x`, `x - ∅ = x`, `∅ - x = x ∩ ∅ = ∅`). What is left is an
//! ordinary postfix program over the leaves that remain, renumbered `0..m` (their crossings in
//! `cross[0..m]`, their solid-leaf indices in `map`), which the pre-test, the 8-lane boundary path (now
//! open to it when `m <= 32`) and the merge run unchanged.
//!
//! **Exact.** Every lane's merge over the compacted program equals its merge over the whole balanced
//! program, bit for bit: a leaf left out has no interval that the merge would keep in that lane. The
//! merge drops the intervals that end before `lo_cut = tmin - 2 tol(tmin)` or start after
//! `hi_cut = tmax + 2 tol(tmax)`; [`compact_x8`] uses the cuts of `3 tol`, and boxes widened far
//! beyond the kernels' rounding, so the lanes it drops are a subset of the ones the merge would. A span
//! bounds all of its operand's *leaves*, not the operand's set: an intersection's merged list can hold
//! an interval where the overlap of its operands' boxes is empty (crossings within the tolerance are one
//! event), but every event is a copy of a leaf crossing. An operand none of whose leaves remains is an
//! empty list for the merge, and the merge's shortcuts for empty operands return exactly what the fold
//! gives. The test `culled_solids_merge_as_whole_programs` holds the two to each other on random solids
//! of up to 300 leaves (and on the review's case of an intersection of empty box overlap). This holds
//! for rays that start near the solid (the renderer re-bases the others); from a far origin, crossings
//! carry the origin's rounding, beyond the margin.
//!
//! The balanced program may group crossings that coincide (within the tolerance) differently from the
//! tree as written, as any regrouping of the operands may: a pixel or two at seams of coincident
//! surfaces can change, within the coincidence rule's own tolerance; `tests/csg_cases/volumes.rs` holds
//! a plate of many holes to its closed-form volume.

use super::program::{union, Bound, Instr, Op};
use super::solid::Leaf;
use super::CsgTree;
use crate::simd::{f32x8, Ray8};
use glam::Vec3;

/// Solids with more leaves than this get a cull program. Smaller ones are evaluated as written (their
/// `FLIP` bits made once). Measured (paired rounds, `bench` profile, the shipped scenes' images
/// identical at every threshold): with 4, peer (a)'s `csg_merge` was 8% slower (its small solids' packets meet most of
/// their leaves, and pay the spans); with 8 or 16 it was even, `scenes/csg.toml` 3% faster (its die of 23
/// leaves), and a plate of 16 holes 2.5x faster in `csg_merge`.
pub(crate) const CULL_LEAVES: usize = 8;

/// One instruction of a cull program.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum CullInstr {
    Leaf(u32),
    Op(Op),
    /// The next `len` instructions are one operand, inside the box `lo..hi` (widened).
    Span {
        lo: Vec3,
        hi: Vec3,
        len: u32,
    },
}

/// A binary operand: a leaf (solid-leaf index) or an operator, with the hull of its leaves' world
/// bounds (infinite if a leaf is a half-space).
struct Node {
    kind: Kind,
    hull: Bound,
}

enum Kind {
    Leaf(u32),
    Op(Op, Box<Node>, Box<Node>),
}

/// The cull program of a solid whose leaves are `leaves` (in the order `compile` numbers them: depth
/// first, children in order) and whose coordinates reach `scale`.
pub(crate) fn cull_program(tree: &CsgTree, leaves: &[Leaf], scale: f32) -> Vec<CullInstr> {
    let mut next = 0u32;
    let root = binary(tree, leaves, &mut next);
    debug_assert_eq!(next as usize, leaves.len());
    let mut out = Vec::new();
    emit(&root, false, scale, &mut out);
    out
}

/// The tree as a balanced binary one (leaves numbered as `compile` numbers them; operands kept in the
/// order written).
fn binary(tree: &CsgTree, leaves: &[Leaf], next: &mut u32) -> Node {
    match tree {
        CsgTree::Leaf(_) => {
            let k = *next;
            *next += 1;
            let hull = leaves[k as usize].bounds().map_or(Bound::Infinite(None), |(lo, hi)| Bound::Finite(lo, hi));
            Node { kind: Kind::Leaf(k), hull }
        }
        CsgTree::Node { op, children } => {
            let mut kids: Vec<Node> = children.iter().map(|c| binary(c, leaves, next)).collect();
            match op {
                Op::Difference if kids.len() > 1 => {
                    let rest = balance(Op::Union, kids.split_off(1));
                    let first = kids.pop().expect("a difference has a first operand");
                    let hull = union(first.hull, rest.hull);
                    Node { kind: Kind::Op(Op::Difference, Box::new(first), Box::new(rest)), hull }
                }
                _ => balance(*op, kids),
            }
        }
    }
}

/// `op` over `kids` as a balanced binary tree, split in halves in the order written. (Not sorted in
/// space: where operands share a face, the one written first owns it, and a reordered union would hand
/// the face to another: a user trial saw the top of two overlapping boxes change colour once the solid
/// passed 8 leaves. Parts are usually written in the order they are laid out, so halves stay compact.)
fn balance(op: Op, mut kids: Vec<Node>) -> Node {
    if kids.len() == 1 {
        return kids.pop().expect("one operand");
    }
    let right = kids.split_off(kids.len() / 2);
    let (a, b) = (balance(op, kids), balance(op, right));
    let hull = union(a.hull, b.hull);
    Node { kind: Kind::Op(op, Box::new(a), Box::new(b)), hull }
}

/// How far a span's box is widened: far beyond the rounding of any crossing computed inside the solid
/// (f32 crossings are accurate to a few ULPs of the coordinates, `1e-7 x scale`, for rays that start
/// near the solid, as the renderer's re-based rays do), so that a ray that misses the widened box has no
/// crossing of the operand's leaves.
fn margin(scale: f32, lo: Vec3, hi: Vec3) -> f32 {
    1e-4 * scale.max((hi - lo).max_element())
}

/// The node in postfix order, preceded by a span (its leaves' hull) when `span` and the hull is finite.
/// Spans go on union operands and on the subtracted operand of a difference only: an intersection's
/// operands and a difference's first operand are met wherever their parent is (their hulls contain the
/// parent's region of events), and their tests were measured to cost 25-30% of `csg_merge` for nothing.
fn emit(node: &Node, span: bool, scale: f32, out: &mut Vec<CullInstr>) {
    let start = out.len();
    let span = match node.hull {
        Bound::Finite(lo, hi) if span && lo.is_finite() && hi.is_finite() && lo.cmple(hi).all() => {
            let m = Vec3::splat(margin(scale, lo, hi));
            out.push(CullInstr::Span { lo: lo - m, hi: hi + m, len: 0 });
            true
        }
        _ => false,
    };
    match &node.kind {
        Kind::Leaf(k) => out.push(CullInstr::Leaf(*k)),
        Kind::Op(op, a, b) => {
            emit(a, *op == Op::Union, scale, out);
            emit(b, *op != Op::Intersection, scale, out);
            out.push(CullInstr::Op(*op));
        }
    }
    if span {
        let n = (out.len() - start - 1) as u32;
        if let CullInstr::Span { len, .. } = &mut out[start] {
            *len = n;
        }
    }
}

/// The cull program without its spans: the balanced program as a plain postfix one (leaf indices of
/// the solid), which the compacted programs are exact restrictions of (the tests' reference).
#[cfg(test)]
pub(crate) fn plain(cull: &[CullInstr]) -> Vec<Instr> {
    cull.iter()
        .filter_map(|c| match *c {
            CullInstr::Leaf(k) => Some(Instr::Leaf(k)),
            CullInstr::Op(op) => Some(Instr::Op(op)),
            CullInstr::Span { .. } => None,
        })
        .collect()
}

/// One operand on the compaction stack: whether it is absent (an empty list for every active lane), and
/// where its instructions and leaves began in the output.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Entry {
    empty: bool,
    prog: u32,
    leaves: u32,
}

/// The scratch of [`compact_x8`] (in the arena).
#[derive(Clone, Debug, Default)]
pub(crate) struct Compacted {
    /// The packet's program over leaves `0..m`.
    pub prog: Vec<Instr>,
    /// Per compacted leaf, its index within the solid.
    pub map: Vec<u32>,
    stack: Vec<Entry>,
}

impl Compacted {
    /// Elements held (for [`super::CsgArena::capacity`]).
    pub(crate) fn capacity(&self) -> usize {
        self.prog.capacity() + self.map.capacity() + self.stack.capacity()
    }
}

/// The packet's compacted program (see the module docs) into `out`, and the crossing table of its
/// leaves into `cross[0..m]` (grown as needed). `lo_cut`, `hi_cut`: per lane, the segment outside which
/// the merge keeps no interval, widened (`+inf`, `-inf` on inactive lanes). An empty program means no
/// lane meets the solid.
pub(crate) fn compact_x8(
    cull: &[CullInstr],
    leaves: &[Leaf],
    ray: &Ray8,
    lo_cut: f32x8,
    hi_cut: f32x8,
    cross: &mut Vec<[[f32; 8]; 4]>,
    out: &mut Compacted,
) {
    let Compacted { prog, map, stack } = out;
    prog.clear();
    map.clear();
    stack.clear();
    let at = |prog: &Vec<Instr>, map: &Vec<u32>, empty| Entry { empty, prog: prog.len() as u32, leaves: map.len() as u32 };
    let mut i = 0;
    while i < cull.len() {
        match cull[i] {
            CullInstr::Span { lo, hi, len } => {
                if !meets_box(ray, lo, hi, lo_cut, hi_cut) {
                    stack.push(at(prog, map, true));
                    i += len as usize;
                }
            }
            CullInstr::Leaf(k) => {
                let c = super::interval_x8::leaf_x8(&leaves[k as usize], &ray.o, &ray.d);
                let mut keep = f32x8::ZERO;
                for iv in 0..2 {
                    let (t0, t1) = (c[2 * iv], c[2 * iv + 1]);
                    keep |= t0.simd_lt(t1) & t1.simd_ge(lo_cut) & t0.simd_le(hi_cut);
                }
                if keep.any() {
                    let m = map.len();
                    if cross.len() <= m {
                        cross.resize(m + 1, [[0.0; 8]; 4]);
                    }
                    cross[m] = [c[0].to_array(), c[1].to_array(), c[2].to_array(), c[3].to_array()];
                    stack.push(at(prog, map, false));
                    map.push(k);
                    prog.push(Instr::Leaf(m as u32));
                } else {
                    stack.push(at(prog, map, true));
                }
            }
            CullInstr::Op(op) => {
                let (Some(b), Some(a)) = (stack.pop(), stack.pop()) else {
                    // (A malformed program: nothing is pushed, and the caller finds no boundary.)
                    prog.clear();
                    map.clear();
                    return;
                };
                let empty = match op {
                    Op::Union => a.empty && b.empty,
                    Op::Intersection => a.empty || b.empty,
                    Op::Difference => a.empty,
                };
                if empty {
                    prog.truncate(a.prog as usize);
                    map.truncate(a.leaves as usize);
                } else if !a.empty && !b.empty {
                    prog.push(Instr::Op(op));
                }
                stack.push(Entry { empty, ..a });
            }
        }
        i += 1;
    }
    if stack.len() != 1 || stack[0].empty {
        prog.clear();
        map.clear();
    }
}

/// Whether some lane's segment `(lo_cut, hi_cut)` of the line meets the box `lo..hi` (slab test). A lane
/// whose slab parameters are NaN (an origin in a slab's plane, parallel to it) counts as meeting it.
#[inline(always)]
fn meets_box(ray: &Ray8, lo: Vec3, hi: Vec3, lo_cut: f32x8, hi_cut: f32x8) -> bool {
    let axis = |o: f32x8, inv: f32x8, a: f32, b: f32| {
        let (t0, t1) = ((f32x8::splat(a) - o) * inv, (f32x8::splat(b) - o) * inv);
        (t0.min(t1), t0.max(t1), t0.simd_ne(t0) | t1.simd_ne(t1))
    };
    let (nx, fx, bx) = axis(ray.o.x, ray.inv_d.x, lo.x, hi.x);
    let (ny, fy, by) = axis(ray.o.y, ray.inv_d.y, lo.y, hi.y);
    let (nz, fz, bz) = axis(ray.o.z, ray.inv_d.z, lo.z, hi.z);
    let (near, far) = (nx.max(ny).max(nz).max(lo_cut), fx.min(fy).min(fz).min(hi_cut));
    // Active lanes have lo_cut <= hi_cut; inactive ones (+inf, -inf) never meet.
    let meets = near.simd_le(far) | ((bx | by | bz) & lo_cut.simd_le(hi_cut));
    meets.any()
}
