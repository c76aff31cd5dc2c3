//! Stage 3 (CSG scenes only): rays whose packets reached a CSG solid's bounds are grouped by solid, 8 at a
//! time, and each group is solved by the solid's interval merge (Roth 1982, `csg::first_hit_x8`). A CSG
//! boundary nearer than the ray's current hit replaces it.

use super::intersect::{glass_gives_way, in_prim_frame};
use super::queues::{CsgCandidates, HitQueue, RayQueue};
use crate::csg::{first_hit_x8, CsgArena, CsgHit};
use crate::scene::{Scene, Shape};
use crate::simd::{f32x8, Ray8, Vec3x8, LANES};

pub fn csg_merge(scene: &Scene, rays: &RayQueue, cands: &mut CsgCandidates, hits: &mut HitQueue, arena: &mut CsgArena) {
    csg_merge_candidates(scene, rays, cands, hits, arena);
    // Then glass faces that lie on an opaque surface give way to it (see `glass_gives_way`).
    glass_gives_way(scene, rays, hits, arena);
}

/// The candidates' CSG hits, nearer than the rays' current hits, replace them.
pub(crate) fn csg_merge_candidates(scene: &Scene, rays: &RayQueue, cands: &mut CsgCandidates, hits: &mut HitQueue, arena: &mut CsgArena) {
    if cands.is_empty() {
        return;
    }
    cands.sorted.clear();
    cands.sorted.extend(cands.ray.iter().zip(&cands.prim).map(|(&r, &p)| ((p as u64) << 32) | r as u64));
    cands.sorted.sort_unstable();
    let sorted = &cands.sorted;
    let mut out = [None::<CsgHit>; LANES];
    let mut i = 0;
    while i < sorted.len() {
        let pid = (sorted[i] >> 32) as u32;
        // Up to 8 consecutive candidates of the same solid form one packet.
        let mut idx = [usize::MAX; LANES];
        let mut k = 0;
        while k < LANES && i < sorted.len() && (sorted[i] >> 32) as u32 == pid {
            idx[k] = (sorted[i] & 0xffff_ffff) as usize;
            k += 1;
            i += 1;
        }
        let prim = &scene.prims[pid as usize];
        let Shape::Csg { solid } = prim.shape else { continue };
        let mut o = [[0.0f32; LANES]; 3];
        let mut d = [[1.0f32; LANES]; 3];
        let mut tmax = [-1.0f32; LANES];
        let mut time = [0.0f32; LANES];
        for (l, &r) in idx.iter().enumerate().take(k) {
            o[0][l] = rays.ox[r];
            o[1][l] = rays.oy[r];
            o[2][l] = rays.oz[r];
            d[0][l] = rays.dx[r];
            d[1][l] = rays.dy[r];
            d[2][l] = rays.dz[r];
            tmax[l] = hits.t[r];
            if rays.with_time {
                time[l] = rays.time[r];
            }
        }
        let ray = Ray8::new(
            Vec3x8::new(f32x8::from(o[0]), f32x8::from(o[1]), f32x8::from(o[2])),
            Vec3x8::new(f32x8::from(d[0]), f32x8::from(d[1]), f32x8::from(d[2])),
            f32x8::from(tmax),
        );
        let ray = in_prim_frame(&ray, prim.motion, rays.with_time.then(|| f32x8::from(time)));
        first_hit_x8(&scene.csg, solid, &ray, f32x8::ZERO, arena, &mut out);
        for (l, &r) in idx.iter().enumerate().take(k) {
            if let Some(h) = out[l] {
                // Same tie rule as the intersect stage: nearer wins, equal distance goes to the lower id.
                if h.t < hits.t[r] || (h.t == hits.t[r] && pid < hits.prim[r]) {
                    hits.t[r] = h.t;
                    hits.prim[r] = pid;
                    hits.leaf[r] = h.leaf;
                    hits.flip[r] = h.flip;
                }
            }
        }
    }
}
