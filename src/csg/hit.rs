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

/// The crossing table of a packet ([`fill_crossings`]) and each lane's coincidence tolerance base: from
/// the origin's length, or for lanes re-based next to the solid (`rebased`, see [`rebase_x8`]) its
/// largest coordinate (there about the solid's own scale, the same for every ray that enters the solid
/// through one face: the tolerance then does not vary across the pixels that see one face).
#[inline(always)]
fn prepare_x8(csg: &Csg, s: &Solid, ray: &Ray8, rebased: f32x8, arena: &mut CsgArena) -> [f32; 8] {
    fill_crossings(csg, s, &ray.o, &ray.d, arena);
    let eps = f32x8::splat(COINCIDENT_EPS);
    let o_inf = ray.o.x.abs().max(ray.o.y.abs()).max(ray.o.z.abs());
    let mag = rebased.select(o_inf, ray.o.dot(ray.o).sqrt());
    (eps * mag.max(f32x8::splat(s.scale)) / ray.d.dot(ray.d).sqrt()).to_array()
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
    // Re-based as the 8-lane path re-bases (lane 0 of the same computation).
    let (ray, tmin8, shift) = rebase_x8(s, &Ray8::new(Vec3x8::splat(o), Vec3x8::splat(d), f32x8::splat(tmax)), f32x8::splat(tmin));
    let (o2, shift) = (ray.o.lane(0), shift.to_array()[0]);
    fill_crossings(csg, s, &ray.o, &ray.d, arena);
    let base = tol_base(if shift > 0.0 { o2.abs().max_element() } else { o2.length() }, d.length(), s.scale);
    let (tmin, tmax) = (tmin8.to_array()[0], ray.tmax.to_array()[0]);
    eval_lane(&LaneJob { prog: csg.program(s), leaf_start: s.leaf_start, lane: 0, tmin, tmax, base }, arena).map(|h| unshift(h, shift))
}

/// A crossing of a re-based ray ([`rebase_x8`]) at the original ray's parameter.
#[inline(always)]
fn unshift(h: CsgHit, shift: f32) -> CsgHit {
    CsgHit { t: h.t + shift, ..h }
}

/// Rays that start well outside the solid's bounds moved along themselves to just outside them (by the
/// parameter `shift`, per lane; 0 elsewhere), with `tmin` and `tmax` moved alike: the solid's crossings
/// and the coincidence tolerance (`merge.rs`) are then computed from an origin at the solid's own scale,
/// not from a camera far away. From an origin at distance `D`, crossings are only accurate to ULPs of
/// `D` and the tolerance is `1e-5 D`: a wall 0.01 thick seen from 1e3 away was one event and vanished.
/// The moved origin keeps a margin of 1% of the bounds' diagonal (and 1e-6 of the origin's magnitude,
/// against the rounding of the entry) outside the bounds, so it is outside the solid as the original
/// was; the origin's rounding moves the ray sideways by ULPs of `|o|`, which no image resolves.
#[inline(always)]
fn rebase_x8(s: &Solid, ray: &Ray8, tmin: f32x8) -> (Ray8, f32x8, f32x8) {
    let (lo, hi) = s.bounds;
    let zero = f32x8::ZERO;
    let slab = |o: f32x8, inv: f32x8, a: f32, b: f32| {
        let (ta, tb) = ((f32x8::splat(a) - o) * inv, (f32x8::splat(b) - o) * inv);
        ta.min(tb)
    };
    // (A NaN on an axis (0 x inf) gives NaN or leaves that axis out: an entry no later than the true one,
    // or no shift at all.)
    let entry =
        slab(ray.o.x, ray.inv_d.x, lo.x, hi.x).max(slab(ray.o.y, ray.inv_d.y, lo.y, hi.y)).max(slab(ray.o.z, ray.inv_d.z, lo.z, hi.z));
    let o_inf = ray.o.x.abs().max(ray.o.y.abs()).max(ray.o.z.abs());
    let margin = (f32x8::splat(0.01 * (hi - lo).length()) + f32x8::splat(1e-6) * o_inf) / ray.d.dot_unfused(ray.d).sqrt();
    let t0 = entry - margin;
    let shift = (t0.simd_gt(zero) & t0.is_finite()).select(t0, zero);
    if shift.simd_gt(zero).to_bitmask() == 0 {
        return (*ray, tmin, zero);
    }
    let moved = Ray8 { o: ray.d.mul_add(shift, ray.o), d: ray.d, inv_d: ray.inv_d, tmax: ray.tmax - shift };
    // A caller that asks again from the boundary it was given (`tmin` = its `t' + shift`, rounded) must
    // not get it back: `tmin - shift` can round below `t'`, by at most an ULP of `tmin`; two ULPs more
    // exclude it (crossings that close to `tmin` are one point in the caller's parameter anyway).
    let bump = f32x8::splat(2.0 * f32::EPSILON) * tmin.abs();
    let tmin = shift.simd_gt(zero).select(tmin - shift + bump, tmin);
    (moved, tmin, shift)
}

/// 8 rays against one solid: leaf crossings by the 8-lane kernels (one call per leaf per packet), then the
/// merge per active lane. Inactive lanes (`tmax <= tmin`) get `None`.
///
/// Lanes whose crossings near `(tmin, tmax)` are all farther apart than the coincidence tolerance are
/// answered 8 at a time by point classification at the crossings (`fast_x8.rs`, equal to the merge bit
/// for bit there); the others take the merge lane by lane.
pub fn first_hit_x8(csg: &Csg, solid: u32, ray: &Ray8, tmin: f32x8, arena: &mut CsgArena, out: &mut [Option<CsgHit>; 8]) {
    *out = [None; 8];
    let Some((s, base, mask, ray, tmin, shift)) = prepare_lanes_x8(csg, solid, ray, tmin, arena) else {
        return;
    };
    let shift = shift.to_array();
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
                t: fast.t[l] + shift[l],
                leaf: s.leaf_start + fast.leaf[l],
                flip: fast.flip & bit != 0,
                entering: fast.entering & bit != 0,
            });
        }
        rest &= !fast.decided;
    }
    each_lane(s, prog, &base, tmin, ray.tmax, rest, arena, |job, arena| {
        out[job.lane] = eval_lane(job, arena).map(|h| unshift(h, shift[job.lane]))
    });
}

/// Every boundary of the solid along 8 rays within `(tmin, tmax)`, lane by lane in order along the ray:
/// `visit(lane, hit)` (the same leaf kernels and merge as [`first_hit_x8`], whose hit is each lane's first
/// here). Inactive lanes (`tmax <= tmin`) are skipped.
///
/// Lanes decided by point classification (as in [`first_hit_x8`]) are visited first, each in order;
/// the others then take the merge.
pub fn crossings_x8(csg: &Csg, solid: u32, ray: &Ray8, tmin: f32x8, arena: &mut CsgArena, mut visit: impl FnMut(usize, CsgHit)) {
    let Some((s, base, mask, ray, tmin, shift)) = prepare_lanes_x8(csg, solid, ray, tmin, arena) else {
        return;
    };
    let shift = shift.to_array();
    let prog = csg.program(s);
    let mut rest = mask;
    if let (Some(flips), true) = (s.flips, mask != 0) {
        let CsgArena { cross, tmp, .. } = arena;
        let cross = &cross[..s.leaf_count as usize];
        let q = Query { prog, flips, cross, tmin, tmax: ray.tmax, base: f32x8::from(base), lanes: mask };
        rest &= !for_each_boundary_x8(&q, tmp, |l, t, k, flip, entering| {
            visit(l, CsgHit { t: t + shift[l], leaf: s.leaf_start + k, flip, entering })
        });
    }
    each_lane(s, prog, &base, tmin, ray.tmax, rest, arena, |job, arena| {
        for_each_boundary(job, arena, |h| visit(job.lane, unshift(h, shift[job.lane])))
    });
}

/// The active lanes (`tmax > tmin`) whose merge may have a boundary in `(tmin, tmax)`, by the 8-lane
/// pre-test alone (no merge): a superset of the lanes [`first_hit_x8`] gives a hit. For a caller that only
/// needs to know which lanes may cross the solid (the shadow stage, for a solid every surface of which
/// shadow rays walk through: the walk finds the crossings, or none).
pub fn lanes_may_cross_x8(csg: &Csg, solid: u32, ray: &Ray8, tmin: f32x8, arena: &mut CsgArena) -> u32 {
    prepare_lanes_x8(csg, solid, ray, tmin, arena).map_or(0, |(_, _, mask, ..)| mask)
}

/// The solid, the crossing table of a packet and each lane's tolerance base ([`prepare_x8`]) for the rays
/// re-based near the solid ([`rebase_x8`]: the re-based rays, `tmin` and each lane's shift are returned;
/// crossings are in the re-based parameter until the shift is added back), and the active lanes
/// (`tmax > tmin`) whose merge may have a boundary in `(tmin, tmax)` (the 8-lane pre-test: the others skip
/// the merge). `None` for an unknown solid or no active lane.
#[allow(clippy::type_complexity)]
#[inline(always)]
fn prepare_lanes_x8<'a>(
    csg: &'a Csg,
    solid: u32,
    ray: &Ray8,
    tmin: f32x8,
    arena: &mut CsgArena,
) -> Option<(&'a Solid, [f32; 8], u32, Ray8, f32x8, f32x8)> {
    let s = csg.solids.get(solid as usize)?;
    let mask = ray.tmax.simd_gt(tmin).to_bitmask();
    if mask == 0 {
        return None;
    }
    let (ray, tmin, shift) = rebase_x8(s, ray, tmin);
    let base = prepare_x8(csg, s, &ray, shift.simd_gt(f32x8::ZERO), arena);
    let may = lanes_with_boundaries_x8(csg.program(s), &arena.cross[..s.leaf_count as usize], tmin, ray.tmax, f32x8::from(base));
    Some((s, base, mask & may, ray, tmin, shift))
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
