//! Shadow rays through dielectrics: the transmittance of the straight segment from a shading point to a
//! light sample, for the lanes whose any-hit test met only dielectrics that do not block.
//!
//! The segment is walked surface by surface (closest hit, then on from just past it) and every crossing is
//! recorded; then the crossings are replayed with the same which-side rule as camera paths
//! ([`medium::cross`]): Beer-Lambert absorption of the medium the ray is in along each piece, and at each
//! surface:
//! * a null crossing (an outranked medium's surface, index-matched media, a dielectric of index 1 in air):
//!   nothing, exactly as for a camera ray, which goes on undeflected;
//! * a thin sheet: its transmission `1 - R` (both faces, inter-reflections summed), undeflected too;
//! * a real interface: physically the light there is refracted, so the shadow ray is blocked (the light
//!   that arrives is a caustic); under the profile's non-physical `transmissive_shadows` it passes,
//!   attenuated by the Fresnel transmission `1 - F` at the ray's angle (0 under total internal reflection).
//!
//! The medium around the shading point is inferred from the crossings: a medium whose first crossing on the
//! segment is an exit contains the start. (A shading point inside a medium whose light is in the same medium,
//! with no surface between, is not attenuated: no crossing tells.) Indices are the nominal ones (shadow rays
//! carry no wavelength). A segment with more than [`MAX_CROSSINGS`] surfaces counts as blocked.

use super::intersect::{in_prim_frame, prim_t_at_x8, prim_t_x8};
use super::medium;
use super::queues::{MediumStack, NONE};
use super::shade::{surface_hits_x8, HitRay};
use crate::accel::{intersect_aabb_x8, PacketRay};
use crate::csg::{first_hit_x8, CsgArena};
use crate::optics::{beer_lambert, fresnel_dielectric, fresnel_schlick};
use crate::scene::{Material, Profile, Scene, Shape};
use crate::simd::{f32x8, Ray8, Vec3x8, LANES};
use glam::Vec3;

/// Surfaces recorded per shadow ray; a ray that crosses more is taken as blocked.
pub const MAX_CROSSINGS: usize = 16;

/// One surface crossed by a shadow ray.
#[derive(Clone, Copy, Debug, Default)]
struct Event {
    /// Distance from the segment's start.
    s: f32,
    material: u32,
    entering: bool,
    /// |cos| of the angle between the segment and the surface normal.
    cos: f32,
}

/// Whether some dielectric lets shadow rays through under this profile (else the walk is never needed).
pub fn any_passable(scene: &Scene, profile: &Profile) -> bool {
    scene.features.dielectric
        && scene.materials.iter().any(|m| matches!(m, Material::Dielectric(d) if profile.transmissive_shadows || d.passable))
}

/// Whether a dielectric (or any material) lets shadow rays walk through it under this profile.
#[inline(always)]
pub fn passes(scene: &Scene, profile: &Profile, material: u32) -> bool {
    match &scene.materials[material as usize] {
        Material::Dielectric(d) => profile.transmissive_shadows || d.passable,
        _ => false,
    }
}

/// Transmittance of the segments `o + t d`, `t` in `(0, tmax)`, of the lanes set in `lanes`; other lanes
/// get 0. `time` is each lane's shutter time (moving prims). Also returns the number of ray segments
/// traced (one per lane per surface crossed, plus the last).
#[allow(clippy::too_many_arguments)]
pub fn transmittance_x8(
    scene: &Scene,
    profile: &Profile,
    o: &[[f32; LANES]; 3],
    d: &[[f32; LANES]; 3],
    tmax: &[f32; LANES],
    time: &[f32; LANES],
    lanes: u32,
    arena: &mut CsgArena,
) -> ([Vec3; LANES], u64) {
    let start: [Vec3; LANES] = std::array::from_fn(|l| Vec3::new(o[0][l], o[1][l], o[2][l]));
    let end: [Vec3; LANES] = std::array::from_fn(|l| start[l] + Vec3::new(d[0][l], d[1][l], d[2][l]) * tmax[l]);
    let mut cur = start;
    let mut events = [[Event::default(); MAX_CROSSINGS]; LANES];
    let mut count = [0usize; LANES];
    let mut blocked = 0u32;
    let mut active = lanes;
    let time8 = scene.features.motion.then(|| f32x8::from(*time));
    let mut traced = 0u64;
    while active != 0 {
        traced += active.count_ones() as u64;
        // The rest of each active segment: from the current point to the end, t in (0, 1).
        let seg: [Vec3; LANES] = std::array::from_fn(|l| end[l] - cur[l]);
        let lane_f = |f: &dyn Fn(usize) -> f32| f32x8::from(std::array::from_fn::<f32, LANES, _>(f));
        let mut ray = Ray8::new(
            Vec3x8::new(lane_f(&|l| cur[l].x), lane_f(&|l| cur[l].y), lane_f(&|l| cur[l].z)),
            Vec3x8::new(lane_f(&|l| seg[l].x), lane_f(&|l| seg[l].y), lane_f(&|l| seg[l].z)),
            lane_f(&|l| if active & (1 << l) != 0 { 1.0 } else { -1.0 }),
        );
        let hit = closest_x8(scene, &mut ray, time8, arena);
        let t = ray.tmax.to_array();
        // The lanes that met a surface, and its geometry (spheres in 8 lanes).
        for (l, h) in hit.iter().enumerate() {
            if h.0 == NONE {
                active &= !(1 << l);
            }
        }
        let geometry = surface_hits_x8(scene, active, |l| {
            let (prim, leaf, flip) = hit[l];
            HitRay { o: cur[l], d: seg[l], time: time[l], t: t[l], prim, leaf, flip }
        });
        let mut bits = active;
        while bits != 0 {
            let l = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let h = geometry[l];
            if !passes(scene, profile, h.material) || count[l] == MAX_CROSSINGS {
                blocked |= 1 << l;
                active &= !(1 << l);
                continue;
            }
            events[l][count[l]] = Event {
                s: (h.p - start[l]).length(),
                material: h.material,
                entering: h.front,
                cos: seg[l].normalize_or_zero().dot(h.n).abs(),
            };
            count[l] += 1;
            cur[l] = h.spawn(-h.n_facing);
        }
    }
    let tr = std::array::from_fn(|l| {
        if lanes & (1 << l) == 0 || blocked & (1 << l) != 0 {
            return Vec3::ZERO;
        }
        replay(scene, profile, &events[l][..count[l]], (end[l] - start[l]).length())
    });
    (tr, traced)
}

/// Transmittance of one segment of length `len` from its recorded crossings (see the module doc).
fn replay(scene: &Scene, profile: &Profile, events: &[Event], len: f32) -> Vec3 {
    // Media around the start: those whose first crossing leaves them, outermost (left last) first.
    let mut starts: [(f32, u32); MAX_CROSSINGS] = [(0.0, 0); MAX_CROSSINGS];
    let mut n_starts = 0;
    for (i, e) in events.iter().enumerate() {
        let first = events[..i].iter().all(|p| p.material != e.material);
        if first && !e.entering && !medium::dielectric(scene, e.material).is_some_and(|d| d.thin) {
            starts[n_starts] = (e.s, e.material);
            n_starts += 1;
        }
    }
    starts[..n_starts].sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut stack = MediumStack::default();
    for &(_, m) in &starts[..n_starts] {
        stack = stack.push(m);
    }

    let ior = |m: Option<u32>| m.and_then(|m| medium::dielectric(scene, m)).map_or(1.0, |d| d.ior.nominal());
    let absorb = |stack: MediumStack, dist: f32| match medium::current(scene, stack).and_then(|m| medium::dielectric(scene, m)) {
        Some(d) if d.sigma_a != Vec3::ZERO => beer_lambert(d.sigma_a, dist),
        _ => Vec3::ONE,
    };
    let mut tr = Vec3::ONE;
    let mut s_prev = 0.0;
    for e in events {
        tr *= absorb(stack, e.s - s_prev);
        s_prev = e.s;
        let Some(d) = medium::dielectric(scene, e.material) else { return Vec3::ZERO };
        let fres = |cos: f32, eta: f32| if d.schlick { fresnel_schlick(cos, eta) } else { fresnel_dielectric(cos, eta) };
        if d.thin {
            let (n1, n2) = (ior(medium::current(scene, stack)), d.ior.nominal());
            if n1 != n2 {
                let r1 = fres(e.cos, n1 / n2);
                tr *= if r1 < 1.0 { 1.0 - 2.0 * r1 / (1.0 + r1) } else { 0.0 };
            }
            continue;
        }
        let c = medium::cross(scene, stack, e.material, e.entering);
        let (n1, n2) = (ior(c.before), ior(c.after));
        if c.is_real() && n1 != n2 {
            if !profile.transmissive_shadows {
                return Vec3::ZERO;
            }
            tr *= 1.0 - fres(e.cos, n1 / n2);
        }
        stack = c.stack;
    }
    tr * absorb(stack, len - s_prev)
}

/// Closest hit of 8 segments (any material): per lane (prim, CSG leaf, CSG flip), prim = NONE on a miss;
/// `ray.tmax` is lowered to the hit distances.
fn closest_x8(scene: &Scene, ray: &mut Ray8, time: Option<f32x8>, arena: &mut CsgArena) -> [(u32, u32, bool); LANES] {
    let mut best = [(NONE, NONE, false); LANES];
    let record = |ray: &mut Ray8, best: &mut [(u32, u32, bool); LANES], t: [f32; LANES], hit: [(u32, u32, bool); LANES]| {
        let mut tm = ray.tmax.to_array();
        for l in 0..LANES {
            if t[l] < tm[l] {
                tm[l] = t[l];
                best[l] = hit[l];
            }
        }
        ray.tmax = f32x8::from(tm);
    };
    scene.bvh.traverse_closest_x8(ray, |bi, ray| {
        let pid = scene.bounded[bi as usize];
        let prim = &scene.prims[pid as usize];
        if let Shape::Csg { solid } = prim.shape {
            let local = in_prim_frame(ray, prim.motion, time);
            let b = &scene.bounds[pid as usize];
            let (_, mask) = intersect_aabb_x8(b.min, b.max, &PacketRay::new(ray), ray.tmax);
            if mask.to_bitmask() == 0 {
                return;
            }
            let masked = Ray8 { tmax: mask.select(ray.tmax, f32x8::splat(-1.0)), ..local };
            let mut out = [None; LANES];
            first_hit_x8(&scene.csg, solid, &masked, f32x8::ZERO, arena, &mut out);
            let t = std::array::from_fn(|l| out[l].map_or(f32::INFINITY, |h| h.t));
            let hit = std::array::from_fn(|l| out[l].map_or((NONE, NONE, false), |h| (pid, h.leaf, h.flip)));
            record(ray, &mut best, t, hit);
        } else {
            let t = prim_t_at_x8(prim, ray, time).to_array();
            record(ray, &mut best, t, [(pid, NONE, false); LANES]);
        }
    });
    for &pid in &scene.unbounded {
        let t = prim_t_x8(&scene.prims[pid as usize], ray).to_array();
        record(ray, &mut best, t, [(pid, NONE, false); LANES]);
    }
    best
}
