//! Constructive Solid Geometry by interval merging (S. D. Roth, "Ray Casting for Modeling Solids", 1982).
//!
//! A solid is a tree of boolean operations ([`CsgTree`], n-ary: union, intersection, difference = first
//! child minus all the others) over leaves ([`Leaf`]: a canonical shape placed by an affine transform with
//! non-uniform scale; canonical forms in `solid.rs`). [`Csg::add_solid`] compiles the tree to a postfix
//! program (`program.rs`). Along a ray every leaf reports *all* its crossings as inside intervals
//! (`interval_x8.rs`, torus in `quartic.rs`), and the program combines the interval lists pairwise in time
//! linear in the number of crossings (`merge.rs`). [`first_hit`] / [`first_hit_x8`] return the first
//! boundary after `tmin`; [`intervals_f64`] is the f64 reference for the whole list (`reference.rs`).
//! Packets skip the merge on lanes whose crossings are all farther apart than the coincidence tolerance:
//! there the boundaries are the crossings where the program's value flips, found 8 lanes at once
//! (`fast_x8.rs`), the same results bit for bit. A solid of more than 8 leaves also has a cull program
//! (`cull.rs`: its tree balanced, each operand with its bounds): a packet computes the crossings of the
//! leaves its rays can meet and runs a program over those alone, the same results bit for bit as the
//! whole balanced program.
//!
//! # Conventions a caller must know
//!
//! - `t` is the parameter of `o + t d` with `d` as given (not normalised); it is the same in world and
//!   object space. Hits are strictly inside `(tmin, tmax)`.
//! - A hit names the leaf whose surface it is ([`CsgHit::leaf`], a global id for [`Csg::leaf`]). The
//!   solid's outward normal there is `leaf.normal(p)`, negated when [`CsgHit::flip`] (a surface of a
//!   subtracted solid): [`Csg::hit_normal`]. [`CsgHit::entering`] says whether the ray enters the solid.
//!   The leaf's `material` is the natural material of the hit (for a flipped surface, the subtracting
//!   leaf's; a renderer may prefer the first child's).
//! - Rays starting inside the solid get the exit as first boundary (`entering = false`).
//! - Trees deeper than [`MAX_DEPTH`] = 64 nested nodes, nodes without children and unbounded solids
//!   (a half-space outside any intersection, or as the first child of a difference that is not itself
//!   intersected) are rejected with [`CsgError`].
//! - Bounds ([`Csg::bounds`]): union = union of the children's, intersection = their overlap (half-spaces
//!   clip exactly), difference = the first child's. An empty solid has `min = +inf, max = -inf`.
//! - [`CsgArena`]: one per thread; grows to the largest solid seen (for a solid with a cull program, the
//!   most leaves a packet meets), then rarely allocates.
//!
//! # Coincident surfaces (the one rule, details in `merge.rs`)
//!
//! Crossings whose parameters differ by at most `tol(t) = 1e-5 * (max(L, |o|) / |d| + |t|)` (in world
//! units `1e-5 * (max(L, |o|) + |t d|)`, `L` = [`Csg::scale`] of the solid) are one event: they are applied together and a boundary is
//! reported only where the combined inside/outside state changes. So `A - A` is empty, `A ∪ A = A ∩ A = A`,
//! and a hole whose cap is flush with a face is a clean opening (the ray sees the hole's bottom or passes
//! through; never the face inside the hole). Two faces closer than `tol` are one face. Measured by the test
//! `smallest_resolved_gap` (two slabs seen from above, `first_hit` and `intervals_f64` alike): the smallest
//! gap still resolved as two faces is **8.2e-5 world units** for a ray whose origin is 4 units away (the
//! formula gives 8.0e-5), and 1.02e-3 for an origin 50 units away (formula 1.0e-3); i.e. about
//! `1e-5 × (max(L, |o|) + distance)`.
//!
//! `Csg::bounds`, `Csg::leaf` and `Csg::inside` index by id and panic on an id that `add_solid` (or the
//! hit) did not return; `first_hit`, `first_hit_x8` and `intervals_f64` return nothing for an unknown solid.

pub(crate) mod cull;
pub(crate) mod fast_x8;
pub mod hit;
pub mod interval_x8;
pub mod merge;
pub mod program;
pub mod quartic;
pub mod reference;
pub mod solid;

pub use hit::{crossings_x8, first_hit, first_hit_x8, lanes_may_cross_x8, CsgHit};
pub use merge::{CsgArena, COINCIDENT_EPS};
pub use program::{Csg, CsgError, CsgTree, Op, MAX_DEPTH};
pub use reference::intervals_f64;
pub use solid::{Leaf, Shape};
