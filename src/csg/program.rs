//! CSG trees compiled to postfix programs, world bounds of solids, and point classification.
//!
//! An n-ary node compiles as a left fold: `c1 c2 OP c3 OP ...`, so `Difference` is
//! `((c1 - c2) - c3) ...` = `c1` minus all the others, and a one-child node is its child. The leaves of one
//! solid are stored contiguously in [`Csg`]; a `Leaf(k)` instruction names the solid's `k`-th leaf.
//!
//! Depth: a leaf has depth 0 and a node one more than its deepest child; trees deeper than [`MAX_DEPTH`]
//! are rejected. With the left fold the evaluation stack of a program never holds more than
//! `depth + 1 <= MAX_DEPTH + 1` interval lists.

use super::cull::{cull_program, CullInstr, CULL_LEAVES};
use super::solid::Leaf;
use glam::Vec3;

/// Deepest accepted tree (number of nested operator nodes on the longest root-to-leaf path).
pub const MAX_DEPTH: usize = 64;

/// A boolean operation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Op {
    Union,
    Intersection,
    /// First child minus all the others.
    Difference,
}

impl Op {
    /// The operation on inside/outside states.
    #[inline(always)]
    pub fn apply(self, a: bool, b: bool) -> bool {
        match self {
            Op::Union => a | b,
            Op::Intersection => a & b,
            Op::Difference => a & !b,
        }
    }
}

/// A CSG tree. Nodes are n-ary.
#[derive(Clone, Debug)]
pub enum CsgTree {
    Leaf(Leaf),
    Node { op: Op, children: Vec<CsgTree> },
}

/// Why a tree was rejected by [`Csg::add_solid`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CsgError {
    /// A node without children.
    EmptyNode,
    /// More than `limit` ([`MAX_DEPTH`]) nested nodes.
    TooDeep { limit: usize },
    /// The solid's bounds are infinite (e.g. a union with a bare half-space): CSG solids must be bounded.
    Unbounded,
}

impl std::fmt::Display for CsgError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            CsgError::EmptyNode => write!(f, "CSG node without children"),
            CsgError::TooDeep { limit } => write!(f, "CSG tree deeper than {limit} nested nodes"),
            CsgError::Unbounded => write!(
                f,
                "CSG solid is unbounded: a half-space must be intersected with a bounded solid or subtracted from one (it cannot be a union operand, nor the solid a difference subtracts from)"
            ),
        }
    }
}

impl std::error::Error for CsgError {}

/// One postfix instruction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Instr {
    /// Push the crossings of the solid's `k`-th leaf.
    Leaf(u32),
    /// Pop two lists, push their combination.
    Op(Op),
}

/// A compiled solid: ranges into [`Csg`]'s arrays.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Solid {
    pub leaf_start: u32,
    pub leaf_count: u32,
    pub instr_start: u32,
    pub instr_count: u32,
    pub bounds: (Vec3, Vec3),
    /// Magnitude of the solid's coordinates: the largest |coordinate| of its bounds and of its leaves'
    /// placements. The floor of the coincidence tolerance (`merge.rs`), so that it scales with the solid.
    pub scale: f32,
    /// Per leaf, bit `k`: its surfaces bound the solid flipped (`fast_x8::flip_bits`); `None` when the
    /// program is beyond the 8-lane boundary path (every lane then takes the merge).
    pub flips: Option<u32>,
    /// Solids of more than [`super::cull::CULL_LEAVES`] leaves: their cull program, a range of
    /// [`Csg`]'s `culls` (`cull.rs`).
    pub cull: Option<(u32, u32)>,
}

/// All leaves of all solids in one array, and one postfix program per solid.
#[derive(Clone, Debug, Default)]
pub struct Csg {
    pub(crate) leaves: Vec<Leaf>,
    pub(crate) instrs: Vec<Instr>,
    pub(crate) solids: Vec<Solid>,
    pub(crate) culls: Vec<CullInstr>,
}

impl Csg {
    pub fn new() -> Csg {
        Csg::default()
    }

    /// Compile a tree; returns the solid's id. Errors: a node without children, a tree deeper than
    /// [`MAX_DEPTH`], or infinite bounds. On error nothing is added.
    pub fn add_solid(&mut self, tree: &CsgTree) -> Result<u32, CsgError> {
        check(tree, 0)?;
        let leaf_start = self.leaves.len();
        let instr_start = self.instrs.len();
        let bound = compile(tree, leaf_start, &mut self.leaves, &mut self.instrs);
        let bounds = match bound {
            Bound::Finite(lo, hi) => (lo, hi),
            Bound::Infinite(_) => {
                self.leaves.truncate(leaf_start);
                self.instrs.truncate(instr_start);
                return Err(CsgError::Unbounded);
            }
        };
        let placed = self.leaves[leaf_start..].iter().map(|l| l.object_to_world.translation.abs().max_element());
        let scale = placed.fold(bounds.0.abs().max(bounds.1.abs()).max_element(), f32::max);
        // An empty solid has infinite bounds; it has no crossings either, so any finite floor will do.
        let scale = if scale.is_finite() { scale } else { 0.0 };
        let leaf_count = self.leaves.len() - leaf_start;
        let cull = (leaf_count > CULL_LEAVES).then(|| {
            let start = self.culls.len();
            self.culls.extend(cull_program(tree, &self.leaves[leaf_start..], scale));
            (start as u32, (self.culls.len() - start) as u32)
        });
        self.solids.push(Solid {
            leaf_start: leaf_start as u32,
            leaf_count: leaf_count as u32,
            instr_start: instr_start as u32,
            instr_count: (self.instrs.len() - instr_start) as u32,
            bounds,
            scale,
            flips: super::fast_x8::flip_bits(&self.instrs[instr_start..]),
            cull,
        });
        Ok(self.solids.len() as u32 - 1)
    }

    /// World bounds of a solid: union of the children for a union, overlap for an intersection, the first
    /// child's for a difference; half-spaces only clip (exactly) inside intersections. An empty solid (e.g.
    /// disjoint intersection) has `min = +inf`, `max = -inf`.
    pub fn bounds(&self, solid: u32) -> (Vec3, Vec3) {
        self.solids[solid as usize].bounds
    }

    /// The solid's scale `L`: the largest |coordinate| of its bounds and of its leaves' placements (the
    /// floor of the coincidence tolerance, see `merge.rs`).
    pub fn scale(&self, solid: u32) -> f32 {
        self.solids[solid as usize].scale
    }

    /// A leaf by its global id (the id in [`super::CsgHit::leaf`]).
    pub fn leaf(&self, id: u32) -> &Leaf {
        &self.leaves[id as usize]
    }

    pub fn solid_count(&self) -> usize {
        self.solids.len()
    }

    pub fn leaf_count(&self) -> usize {
        self.leaves.len()
    }

    /// Global ids of a solid's leaves.
    pub fn solid_leaves(&self, solid: u32) -> std::ops::Range<u32> {
        let s = &self.solids[solid as usize];
        s.leaf_start..s.leaf_start + s.leaf_count
    }

    /// Point classification of a world point (closed leaves, combined exactly, no tolerance).
    pub fn inside(&self, solid: u32, p: Vec3) -> bool {
        let s = &self.solids[solid as usize];
        let leaves = &self.leaves[s.leaf_start as usize..];
        eval_bool(self.program(s), |k| leaves[k as usize].inside(p))
    }

    /// Outward unit normal of the solid at a hit point `p` of `hit` (the leaf's normal, negated if flipped).
    pub fn hit_normal(&self, hit: &super::CsgHit, p: Vec3) -> Vec3 {
        let n = self.leaf(hit.leaf).normal(p);
        if hit.flip {
            -n
        } else {
            n
        }
    }

    #[inline]
    pub(crate) fn program(&self, s: &Solid) -> &[Instr] {
        &self.instrs[s.instr_start as usize..(s.instr_start + s.instr_count) as usize]
    }

    /// A solid's cull program (`cull.rs`), if it has one.
    #[inline]
    pub(crate) fn cull_program(&self, s: &Solid) -> Option<&[CullInstr]> {
        s.cull.map(|(start, len)| &self.culls[start as usize..(start + len) as usize])
    }
}

/// Crossing distances for the merge's tests: values that coincide exactly, within the merge's tolerance
/// (`1 + 2e-6`, `2 - 1e-6`) and just beyond it (`1 + 3e-5`), and huge, infinite and NaN ones.
#[cfg(test)]
pub(crate) const TEST_CROSSINGS: [f32; 14] =
    [-3.0, -1e-6, 0.0, 0.5, 1.0, 1.0 + 2e-6, 1.0 + 3e-5, 2.0, 2.0 - 1e-6, 4.0, 1e31, f32::INFINITY, f32::NEG_INFINITY, f32::NAN];

/// A random postfix program over leaves `0..n` (in order) for tests: an operator (any of the three)
/// whenever two lists wait and `coin` says so, or the leaves ran out; nested both ways.
#[cfg(test)]
pub(crate) fn random_postfix(n: usize, coin: &mut dyn FnMut() -> f32) -> Vec<Instr> {
    let mut prog = Vec::new();
    let (mut pushed, mut depth) = (0, 0);
    while pushed < n || depth > 1 {
        if pushed < n && (depth < 2 || coin() < 0.5) {
            prog.push(Instr::Leaf(pushed as u32));
            pushed += 1;
            depth += 1;
        } else {
            prog.push(Instr::Op([Op::Union, Op::Intersection, Op::Difference][(coin() * 3.0) as usize % 3]));
            depth -= 1;
        }
    }
    prog
}

/// Evaluate a program on inside/outside leaf states.
pub(crate) fn eval_bool(prog: &[Instr], leaf_inside: impl Fn(u32) -> bool) -> bool {
    let mut stack = [false; MAX_DEPTH + 2];
    let mut sp = 0;
    for ins in prog {
        match *ins {
            Instr::Leaf(k) => {
                stack[sp] = leaf_inside(k);
                sp += 1;
            }
            Instr::Op(op) => {
                sp -= 1;
                stack[sp - 1] = op.apply(stack[sp - 1], stack[sp]);
            }
        }
    }
    sp == 1 && stack[0]
}

/// Reject empty nodes and trees deeper than [`MAX_DEPTH`] (stops descending at the limit).
fn check(tree: &CsgTree, depth: usize) -> Result<(), CsgError> {
    match tree {
        CsgTree::Leaf(_) => Ok(()),
        CsgTree::Node { children, .. } => {
            if depth >= MAX_DEPTH {
                return Err(CsgError::TooDeep { limit: MAX_DEPTH });
            }
            if children.is_empty() {
                return Err(CsgError::EmptyNode);
            }
            children.iter().try_for_each(|c| check(c, depth + 1))
        }
    }
}

/// World bound of a subtree: a box (possibly empty), or infinite with the plane of a bare half-space.
#[derive(Clone, Copy, Debug)]
pub(super) enum Bound {
    Finite(Vec3, Vec3),
    Infinite(Option<(Vec3, f32)>),
}

const EMPTY: Bound = Bound::Finite(Vec3::INFINITY, Vec3::NEG_INFINITY);

fn compile(tree: &CsgTree, leaf_start: usize, leaves: &mut Vec<Leaf>, instrs: &mut Vec<Instr>) -> Bound {
    match tree {
        CsgTree::Leaf(leaf) => {
            instrs.push(Instr::Leaf((leaves.len() - leaf_start) as u32));
            leaves.push(*leaf);
            match leaf.bounds() {
                Some((lo, hi)) => Bound::Finite(lo, hi),
                None => Bound::Infinite(leaf.plane()),
            }
        }
        CsgTree::Node { op, children } => {
            let mut bounds = Vec::with_capacity(children.len());
            for (i, c) in children.iter().enumerate() {
                bounds.push(compile(c, leaf_start, leaves, instrs));
                if i > 0 {
                    instrs.push(Instr::Op(*op));
                }
            }
            match op {
                Op::Union => bounds.iter().fold(EMPTY, |a, b| union(a, *b)),
                Op::Intersection => intersect(&bounds),
                Op::Difference => bounds[0],
            }
        }
    }
}

pub(super) fn union(a: Bound, b: Bound) -> Bound {
    match (a, b) {
        (Bound::Finite(a0, a1), Bound::Finite(b0, b1)) => Bound::Finite(a0.min(b0), a1.max(b1)),
        _ => Bound::Infinite(None),
    }
}

/// Intersection of the children's bounds: the overlap of the finite ones, clipped (exactly, see [`clip`])
/// by the plane of every infinite one that has a plane; infinite if no child is finite.
fn intersect(bounds: &[Bound]) -> Bound {
    let mut acc: Option<(Vec3, Vec3)> = None;
    for b in bounds {
        if let Bound::Finite(lo, hi) = *b {
            acc = Some(acc.map_or((lo, hi), |(a0, a1)| (a0.max(lo), a1.min(hi))));
        }
    }
    let Some((mut lo, mut hi)) = acc else {
        return Bound::Infinite(None);
    };
    for b in bounds {
        if let Bound::Infinite(Some((n, d))) = *b {
            match clip(lo, hi, n, d) {
                Bound::Finite(a, c) => (lo, hi) = (a, c),
                inf => return inf,
            }
        }
    }
    normalize(lo, hi)
}

fn normalize(lo: Vec3, hi: Vec3) -> Bound {
    if lo.cmpgt(hi).any() || lo.is_nan() || hi.is_nan() {
        EMPTY
    } else {
        Bound::Finite(lo, hi)
    }
}

/// Bounds of `box ∩ {n . p <= d}`: the corners inside and the edge crossings of the plane.
fn clip(lo: Vec3, hi: Vec3, n: Vec3, d: f32) -> Bound {
    if lo.cmpgt(hi).any() {
        return EMPTY;
    }
    let corner = |i: usize| {
        Vec3::new(if i & 1 == 0 { lo.x } else { hi.x }, if i & 2 == 0 { lo.y } else { hi.y }, if i & 4 == 0 { lo.z } else { hi.z })
    };
    let (mut a, mut b) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    for i in 0..8 {
        let p = corner(i);
        let fp = n.dot(p) - d;
        if fp <= 0.0 {
            a = a.min(p);
            b = b.max(p);
        }
        for bit in [1, 2, 4] {
            if i & bit != 0 {
                continue;
            }
            let q = corner(i | bit);
            let fq = n.dot(q) - d;
            if (fp < 0.0) != (fq < 0.0) {
                let x = p + (q - p) * (fp / (fp - fq));
                let x = x.clamp(lo, hi);
                a = a.min(x);
                b = b.max(x);
            }
        }
    }
    normalize(a, b)
}
