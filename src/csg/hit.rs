//! Boundaries of a solid along rays: leaf crossings by the 8-lane kernels (one call per leaf per
//! packet), then the boundaries 8 lanes at once where point classification gives the merge's result
//! (`fast_x8.rs`), and Roth's merge per lane elsewhere (`merge.rs`).

use super::fast_x8::{first_boundary_x8, for_each_boundary_x8, Query};
use super::interval_x8::leaf_x8;
use super::merge::{eval_lane, for_each_boundary, lanes_with_boundaries_x8, tol_base, CsgArena, LaneJob, COINCIDENT_EPS};
use super::program::{Csg, Instr, Solid};
use crate::simd::{f32x8, Ray8, Vec3x8};
use glam::Vec3;

/// A boundary of a CSG solid along a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CsgHit {
    pub t: f32,
    /// Global leaf id ([`Csg::leaf`]) whose surface this is.
    pub leaf: u32,
    /// The surface belongs to a subtracted solid: the outward normal of the result is `-leaf.normal`.
    pub flip: bool,
    /// The ray enters the solid here (else it leaves).
    pub entering: bool,
}

/// Fill the arena's crossing table for the solid's leaves and a world-space packet.
fn fill_crossings(csg: &Csg, s: &Solid, o: &Vec3x8, d: &Vec3x8, arena: &mut CsgArena) {
    let n = s.leaf_count as usize;
    if arena.cross.len() < n {
        arena.cross.resize(n, [[0.0; 8]; 4]);
    }
    let leaves = &csg.leaves[s.leaf_start as usize..s.leaf_start as usize + n];
    for (slot, leaf) in arena.cross.iter_mut().zip(leaves) {
        let c = leaf_x8(leaf, o, d);
        *slot = [c[0].to_array(), c[1].to_array(), c[2].to_array(), c[3].to_array()];
    }
}

/// The crossing table of a packet ([`fill_crossings`]) and each lane's coincidence tolerance base.
#[inline(always)]
fn prepare_x8(csg: &Csg, s: &Solid, ray: &Ray8, arena: &mut CsgArena) -> [f32; 8] {
    fill_crossings(csg, s, &ray.o, &ray.d, arena);
    let eps = f32x8::splat(COINCIDENT_EPS);
    (eps * ray.o.dot(ray.o).sqrt().max(f32x8::splat(s.scale)) / ray.d.dot(ray.d).sqrt()).to_array()
}

/// First boundary of the solid along `o + t d` with `tmin < t < tmax` (`d` not necessarily unit); handles
/// an origin inside the solid (the first boundary is then an exit). Uses the same 8-lane kernels as
/// [`first_hit_x8`] (the ray in every lane), so both agree bit for bit. An unknown solid id gives `None`.
pub fn first_hit(csg: &Csg, solid: u32, o: Vec3, d: Vec3, tmin: f32, tmax: f32, arena: &mut CsgArena) -> Option<CsgHit> {
    let s = csg.solids.get(solid as usize)?;
    // Also rejects NaN bounds.
    if tmax.partial_cmp(&tmin) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    fill_crossings(csg, s, &Vec3x8::splat(o), &Vec3x8::splat(d), arena);
    let base = tol_base(o.length(), d.length(), s.scale);
    eval_lane(&LaneJob { prog: csg.program(s), leaf_start: s.leaf_start, lane: 0, tmin, tmax, base }, arena)
}

/// 8 rays against one solid: leaf crossings by the 8-lane kernels (one call per leaf per packet), then the
/// merge per active lane. Inactive lanes (`tmax <= tmin`) get `None`.
///
/// Lanes whose crossings near `(tmin, tmax)` are all farther apart than the coincidence tolerance are
/// answered 8 at a time by point classification at the crossings (`fast_x8.rs`, equal to the merge bit
/// for bit there); the others take the merge lane by lane.
pub fn first_hit_x8(csg: &Csg, solid: u32, ray: &Ray8, tmin: f32x8, arena: &mut CsgArena, out: &mut [Option<CsgHit>; 8]) {
    *out = [None; 8];
    let Some((s, base, mask)) = prepare_lanes_x8(csg, solid, ray, tmin, arena) else {
        return;
    };
    let prog = csg.program(s);
    let mut rest = mask;
    if let (Some(flips), true) = (s.flips, mask != 0) {
        let cross = &arena.cross[..s.leaf_count as usize];
        let fast = first_boundary_x8(&Query { prog, flips, cross, tmin, tmax: ray.tmax, base: f32x8::from(base), lanes: mask });
        let mut found = fast.found;
        while found != 0 {
            let l = found.trailing_zeros() as usize;
            found &= found - 1;
            let bit = 1 << l;
            out[l] = Some(CsgHit {
                t: fast.t[l],
                leaf: s.leaf_start + fast.leaf[l],
                flip: fast.flip & bit != 0,
                entering: fast.entering & bit != 0,
            });
        }
        rest &= !fast.decided;
    }
    each_lane(s, prog, &base, tmin, ray.tmax, rest, arena, |job, arena| out[job.lane] = eval_lane(job, arena));
}

/// Every boundary of the solid along 8 rays within `(tmin, tmax)`, lane by lane in order along the ray:
/// `visit(lane, hit)` (the same leaf kernels and merge as [`first_hit_x8`], whose hit is each lane's first
/// here). Inactive lanes (`tmax <= tmin`) are skipped.
///
/// Lanes decided by point classification (as in [`first_hit_x8`]) are visited first, each in order;
/// the others then take the merge.
pub fn crossings_x8(csg: &Csg, solid: u32, ray: &Ray8, tmin: f32x8, arena: &mut CsgArena, mut visit: impl FnMut(usize, CsgHit)) {
    let Some((s, base, mask)) = prepare_lanes_x8(csg, solid, ray, tmin, arena) else {
        return;
    };
    let prog = csg.program(s);
    let mut rest = mask;
    if let (Some(flips), true) = (s.flips, mask != 0) {
        let CsgArena { cross, tmp, .. } = arena;
        let cross = &cross[..s.leaf_count as usize];
        let q = Query { prog, flips, cross, tmin, tmax: ray.tmax, base: f32x8::from(base), lanes: mask };
        rest &= !for_each_boundary_x8(&q, tmp, |l, t, k, flip, entering| visit(l, CsgHit { t, leaf: s.leaf_start + k, flip, entering }));
    }
    each_lane(s, prog, &base, tmin, ray.tmax, rest, arena, |job, arena| for_each_boundary(job, arena, |h| visit(job.lane, h)));
}

/// The active lanes (`tmax > tmin`) whose merge may have a boundary in `(tmin, tmax)`, by the 8-lane
/// pre-test alone (no merge): a superset of the lanes [`first_hit_x8`] gives a hit. For a caller that only
/// needs to know which lanes may cross the solid (the shadow stage, for a solid every surface of which
/// shadow rays walk through: the walk finds the crossings, or none).
pub fn lanes_may_cross_x8(csg: &Csg, solid: u32, ray: &Ray8, tmin: f32x8, arena: &mut CsgArena) -> u32 {
    prepare_lanes_x8(csg, solid, ray, tmin, arena).map_or(0, |(_, _, mask)| mask)
}

/// The solid, the crossing table of a packet and each lane's tolerance base ([`prepare_x8`]), and the
/// active lanes (`tmax > tmin`) whose merge may have a boundary in `(tmin, tmax)` (the 8-lane pre-test:
/// the others skip the merge). `None` for an unknown solid or no active lane.
#[inline(always)]
fn prepare_lanes_x8<'a>(csg: &'a Csg, solid: u32, ray: &Ray8, tmin: f32x8, arena: &mut CsgArena) -> Option<(&'a Solid, [f32; 8], u32)> {
    let s = csg.solids.get(solid as usize)?;
    let mask = ray.tmax.simd_gt(tmin).to_bitmask();
    if mask == 0 {
        return None;
    }
    let base = prepare_x8(csg, s, ray, arena);
    let may = lanes_with_boundaries_x8(csg.program(s), &arena.cross[..s.leaf_count as usize], tmin, ray.tmax, f32x8::from(base));
    Some((s, base, mask & may))
}

/// `f` with each lane of `lanes` as a merge job (the lanes the 8-lane path left).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn each_lane(
    s: &Solid,
    prog: &[Instr],
    base: &[f32; 8],
    tmin: f32x8,
    tmax: f32x8,
    mut lanes: u32,
    arena: &mut CsgArena,
    mut f: impl FnMut(&LaneJob, &mut CsgArena),
) {
    let (t0, t1) = (tmin.to_array(), tmax.to_array());
    while lanes != 0 {
        let lane = lanes.trailing_zeros() as usize;
        lanes &= lanes - 1;
        f(&LaneJob { prog, leaf_start: s.leaf_start, lane, tmin: t0[lane], tmax: t1[lane], base: base[lane] }, arena);
    }
}
