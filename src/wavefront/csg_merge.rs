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
    group_by_solid(cands);
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

/// `cands.sorted`: the candidates as `prim << 32 | ray`, those of one solid together so that they form
/// packets. Where the solids' ids span at most as many slots as there are candidates (a scene's few
/// solids), a counting sort by solid that keeps the order the intersect stage found them in (its
/// packets' order: as coherent as the rays' own); else a sort of the keys (solid, then ray). Either
/// way a ray's hit does not depend on which rays share its packet.
fn group_by_solid(cands: &mut CsgCandidates) {
    let CsgCandidates { ray, prim, sorted, counts } = cands;
    sorted.clear();
    let key = |r: u32, p: u32| ((p as u64) << 32) | r as u64;
    let (lo, hi) = prim.iter().fold((u32::MAX, 0), |(lo, hi), &p| (lo.min(p), hi.max(p)));
    let span = (hi - lo) as usize + 1;
    if span == 1 {
        sorted.extend(ray.iter().map(|&r| key(r, lo)));
    } else if span <= prim.len() {
        counts.clear();
        counts.resize(span + 1, 0);
        for &p in prim.iter() {
            counts[(p - lo) as usize + 1] += 1;
        }
        for i in 1..=span {
            counts[i] += counts[i - 1];
        }
        sorted.resize(prim.len(), 0);
        for (&r, &p) in ray.iter().zip(prim.iter()) {
            let at = &mut counts[(p - lo) as usize];
            sorted[*at as usize] = key(r, p);
            *at += 1;
        }
    } else {
        sorted.extend(ray.iter().zip(prim.iter()).map(|(&r, &p)| key(r, p)));
        sorted.sort_unstable();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every candidate once, each solid's together, in all three ways of grouping (one solid, the
    /// counting sort, the sort of keys), and the counting sort keeping each solid's candidates in the
    /// order they came.
    #[test]
    fn group_by_solid_keeps_every_candidate_and_groups_solids() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = |m: u32| {
            state = crate::sample::mix64(state.wrapping_add(1));
            (state % m as u64) as u32
        };
        for (n, solids, base) in [(1usize, 1, 7), (50, 1, 3), (300, 5, 100), (40, 30, 0), (20, 1000, 9), (500, 2, u32::MAX - 2)] {
            let mut c = CsgCandidates::default();
            for i in 0..n {
                c.ray.push(next(4096) + i as u32);
                c.prim.push(base + next(solids));
            }
            group_by_solid(&mut c);
            let mut want: Vec<u64> = c.ray.iter().zip(&c.prim).map(|(&r, &p)| ((p as u64) << 32) | r as u64).collect();
            let mut got = c.sorted.clone();
            assert_eq!(got.len(), want.len());
            // Each solid's run is contiguous (a solid seen again after another's run would fail).
            let mut seen = std::collections::HashSet::new();
            for w in got.windows(2) {
                if w[0] >> 32 != w[1] >> 32 {
                    assert!(seen.insert(w[0] >> 32), "solid {} in two runs", w[0] >> 32);
                }
            }
            if (solids as usize) <= n {
                // The counting sort: within a solid, the order of arrival.
                for p in c.prim.iter().collect::<std::collections::BTreeSet<_>>() {
                    let arrived: Vec<u64> = want.iter().copied().filter(|k| (k >> 32) as u32 == *p).collect();
                    let run: Vec<u64> = got.iter().copied().filter(|k| (k >> 32) as u32 == *p).collect();
                    assert_eq!(run, arrived, "solid {p}");
                }
            }
            got.sort_unstable();
            want.sort_unstable();
            assert_eq!(got, want, "{n} candidates of {solids} solids");
        }
    }
}
