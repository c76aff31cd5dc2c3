//! The pipeline driver: the only place that knows the order of the stages. It reads like the diagram:
//!
//! ```text
//! generate -> loop { intersect -> csg_merge -> shade -> shadow } -> accumulate
//! ```

use super::accumulate::accumulate;
use super::csg_merge::csg_merge;
use super::generate::{generate, Tile};
use super::intersect::intersect;
use super::shade::{shade, ShadeOut};
use super::shadow::shadow_with;
use super::Wavefront;
use crate::film::Film;
use crate::scene::{Profile, Scene};
use std::ops::Range;
use std::sync::Mutex;
use std::time::Instant;

/// What a render needs besides the scene.
#[derive(Clone, Debug)]
pub struct Settings {
    pub profile: Profile,
    pub seed: u64,
}

/// One piece of work: a tile of pixels and a range of sample indices.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct WorkUnit {
    pub tile: Tile,
    pub samples: Range<u32>,
}

macro_rules! timed {
    ($acc:expr, $e:expr) => {{
        let t0 = Instant::now();
        let r = $e;
        $acc += t0.elapsed().as_secs_f64();
        r
    }};
}

/// Most rays one pass of a work unit may hold per camera path of the unit (`branching = "split"` lets
/// the ray tree grow until `throughput_cutoff` and `max_depth` stop it; a tiny cutoff lets it grow past
/// any memory): a unit of 4,096 paths may hold 2^24 rays, about 1.5 GB of queues. With a cutoff `c`, a
/// glass ray tree's rays at one bounce share the path's throughput (R + T = 1), so there are at most
/// about `1 / c` of them (more where roulette or dispersion weighs a path above 1): a cutoff of 1e-3
/// stays far below the limit.
pub const MAX_RAYS_PER_PATH: usize = 4096;

/// Render one work unit with the worker's wavefront and add it to the film. False (and nothing added)
/// where a pass outgrew `max_rays_per_path` ([`MAX_RAYS_PER_PATH`] by default) times the unit's camera paths.
#[must_use]
pub fn render_unit(
    scene: &Scene,
    settings: &Settings,
    unit: &WorkUnit,
    wf: &mut Wavefront,
    film: &Mutex<Film>,
    max_rays_per_path: usize,
) -> bool {
    let (profile, seed) = (&settings.profile, settings.seed);
    let Wavefront { rays, hits, csg, csg_arena, nee, paths, order, counters, times } = wf;
    paths.clear();
    rays[0].clear();
    timed!(times.generate, generate(scene, profile, seed, unit.tile, unit.samples.clone(), paths, &mut rays[0]));
    counters.camera_rays += rays[0].len() as u64;
    counters.samples += paths.len() as u64;

    // Bounces are counted per ray (`RayItem::depth`, checked by shade); null crossings of dielectric surfaces
    // are not bounces, so a path may need more passes than max_depth + 1. The cap is only a safety net.
    for depth in 0..max_passes(profile) {
        let [a, b] = &mut *rays;
        let (cur, next) = if depth & 1 == 0 { (a, b) } else { (b, a) };
        if cur.is_empty() {
            break;
        }
        cur.pad();
        cur.pixels = unit.tile.pixel_count();
        next.clear();
        nee.clear();
        timed!(times.intersect, intersect(scene, cur, hits, csg));
        if scene.features.csg {
            counters.csg_candidates += csg.len() as u64;
            timed!(times.csg_merge, csg_merge(scene, cur, csg, hits, csg_arena));
        }
        counters.lost_media += timed!(times.shade, shade(scene, profile, seed, cur, hits, order, ShadeOut { paths, next, nee }));
        // Shading points scattered by incoherent bounces: their shadow rays share few BVH nodes.
        let scattered = hits.scattered.then_some(&mut hits.wide_stack);
        let (traced, cleared) = timed!(times.shadow, shadow_with(scene, profile, seed, nee, paths, csg_arena, scattered));
        counters.shadow_rays += traced;
        counters.shadow_cleared += cleared;
        counters.secondary_rays += next.len() as u64;
        if next.len() > max_rays_per_path.saturating_mul(paths.len()) {
            rays[0].clear();
            rays[1].clear();
            return false;
        }
    }
    rays[0].clear();
    rays[1].clear();

    let mut film = film.lock().unwrap_or_else(|e| e.into_inner());
    counters.nonfinite_samples += timed!(times.accumulate, accumulate(paths, &mut film));
    true
}

/// Most passes of the bounce loop: max_depth + 1 bounces plus room for null crossings.
pub fn max_passes(profile: &Profile) -> usize {
    4 * (profile.max_depth as usize + 1)
}
