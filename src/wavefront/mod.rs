//! The wavefront: small, cache-resident SoA queues that a worker reuses for tile after tile, and one
//! file per pipeline stage. `pipeline.rs` is the only place that knows the order of the stages.
//!
//! ```text
//! generate -> [ intersect -> csg_merge (CSG scenes only) -> shade -> shadow ] x depth -> accumulate
//! ```

pub mod accumulate;
pub mod cone;
pub mod csg_merge;
pub mod generate;
pub mod intersect;
pub mod light_tree;
pub mod medium;
pub mod pick;
pub mod pipeline;
pub mod queues;
pub mod shade;
pub mod shadow;
pub mod transmit;

pub use pipeline::{render_unit, Settings, WorkUnit, MAX_RAYS_PER_PATH};
pub use queues::{CsgCandidates, HitQueue, MediumStack, NeeQueue, PathTable, RayItem, RayQueue};

use crate::csg::CsgArena;
use crate::scene::Features;
use serde::Serialize;

/// Sample dimensions: which integral a random number belongs to. Bounce-dependent integrals add the depth.
pub mod dims {
    pub const PIXEL: u32 = 0;
    pub const LENS: u32 = 1;
    pub const TIME: u32 = 2;
    pub const WAVELENGTH: u32 = 3;
    pub const GLOSSY: u32 = 0x100;
    pub const DIFFUSE: u32 = 0x200;
    pub const FRESNEL: u32 = 0x300;
    pub const ROULETTE: u32 = 0x400;
    pub const LIGHT: u32 = 0x500;
    pub const LIGHT_PICK: u32 = 0x600;
    /// The light pick's second number: random bits for the uniform floor's pick of `local` and `tree`
    /// (`pick.rs`), or else for `tree`'s zooms (`light_tree.rs`).
    pub const LIGHT_PICK_FINE: u32 = 0x700;
}

/// Counters of one render (or one wavefront), summed over workers.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct Counters {
    pub camera_rays: u64,
    pub secondary_rays: u64,
    pub shadow_rays: u64,
    /// Shadow rays the light-cone test found clear: credited, not traced (not in `shadow_rays`).
    pub shadow_cleared: u64,
    /// Rays that entered the csg_merge stage (ray x solid candidates).
    pub csg_candidates: u64,
    pub nonfinite_samples: u64,
    /// Crossings into a medium beyond the 4 a ray's stack keeps (their absorption and index are lost).
    pub lost_media: u64,
    pub samples: u64,
}

impl Counters {
    pub fn add(&mut self, o: &Counters) {
        self.camera_rays += o.camera_rays;
        self.secondary_rays += o.secondary_rays;
        self.shadow_rays += o.shadow_rays;
        self.shadow_cleared += o.shadow_cleared;
        self.csg_candidates += o.csg_candidates;
        self.nonfinite_samples += o.nonfinite_samples;
        self.lost_media += o.lost_media;
        self.samples += o.samples;
    }
    pub fn total_rays(&self) -> u64 {
        self.camera_rays + self.secondary_rays + self.shadow_rays
    }
}

/// Seconds spent in each stage, summed over workers: each worker's wall clock inside the stage (its CPU
/// time when it has a core of its own; a worker waiting for a core, under load or with more threads than
/// cores, counts the wait too).
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct StageTimes {
    pub generate: f64,
    pub intersect: f64,
    pub csg_merge: f64,
    pub shade: f64,
    pub shadow: f64,
    pub accumulate: f64,
}

impl StageTimes {
    pub fn add(&mut self, o: &StageTimes) {
        self.generate += o.generate;
        self.intersect += o.intersect;
        self.csg_merge += o.csg_merge;
        self.shade += o.shade;
        self.shadow += o.shadow;
        self.accumulate += o.accumulate;
    }
}

/// All queues of one worker. Created once per worker, cleared per tile.
pub struct Wavefront {
    /// Ping-pong ray queues: `rays[depth & 1]` is current, the other receives the next bounce.
    pub rays: [RayQueue; 2],
    pub hits: HitQueue,
    pub csg: CsgCandidates,
    pub csg_arena: CsgArena,
    pub nee: NeeQueue,
    pub paths: PathTable,
    /// Scratch for shading: hit indices partitioned by material kind.
    pub order: Vec<u32>,
    pub counters: Counters,
    pub times: StageTimes,
}

impl Wavefront {
    pub fn new(features: &Features) -> Wavefront {
        // Glossy lobe rays carry their density where they can find a sampled (area) light: MIS.
        let q = || RayQueue::new(features.motion, features.dispersion).with_pdf(features.glossy && features.area_lights);
        Wavefront {
            rays: [q(), q()],
            hits: HitQueue::default(),
            csg: CsgCandidates::default(),
            csg_arena: CsgArena::new(),
            nee: NeeQueue::default(),
            paths: PathTable::default(),
            order: Vec::new(),
            counters: Counters::default(),
            times: StageTimes::default(),
        }
    }
}
