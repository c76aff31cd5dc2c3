//! The render driver: splits the image into work units (tiles x sample batches), runs them on a rayon
//! pool with one reusable [`Wavefront`] per worker, reports progress, honours cancellation, and sums the
//! counters into a [`RenderStats`].
//!
//! Work units are taken in order from a shared counter, sample batch by sample batch over the whole image,
//! so a render stopped early has (nearly) the same number of samples in every pixel. Neither the order nor
//! the number of threads changes the image: every random number is a function of (seed, pixel, sample,
//! dimension) and the film adds in exact fixed point.

use crate::film::Film;
use crate::scene::Scene;
use crate::wavefront::generate::Tile;
use crate::wavefront::{render_unit, Counters, Settings, StageTimes, Wavefront, WorkUnit};
use serde::Serialize;
use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

/// Tile side in pixels.
pub const TILE: u32 = 16;
/// Camera paths per wavefront: a tile's pixels x a batch of samples stays around this size, so that the
/// queues stay in L2.
pub const WAVEFRONT_PATHS: u32 = 4096;

#[derive(Clone, Debug, Serialize)]
pub struct RenderStats {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub samples: [u32; 2],
    pub threads: usize,
    pub seed: u64,
    pub seconds: f64,
    pub rays: RayCounts,
    pub rays_per_second: f64,
    pub nonfinite_samples: u64,
    pub csg_candidates: u64,
    /// CPU seconds per stage, summed over threads.
    pub stage_seconds: StageTimes,
    pub completed: bool,
    pub features: crate::scene::Features,
}

#[derive(Clone, Copy, Debug, Serialize)]
pub struct RayCounts {
    pub camera: u64,
    pub secondary: u64,
    pub shadow: u64,
    pub total: u64,
}

/// Options of one render call.
pub struct RenderJob<'a> {
    pub scene: &'a Scene,
    pub settings: Settings,
    pub threads: usize,
    /// Sample indices to render (default: 0..spp).
    pub samples: Range<u32>,
    pub tile: u32,
    pub cancel: Option<&'a AtomicBool>,
    /// Called after each finished work unit with (done, total).
    pub progress: Option<&'a (dyn Fn(usize, usize) + Sync)>,
}

impl<'a> RenderJob<'a> {
    pub fn new(scene: &'a Scene, settings: Settings) -> Self {
        let spp = settings.profile.spp;
        RenderJob { scene, settings, threads: 0, samples: 0..spp, tile: TILE, cancel: None, progress: None }
    }
}

/// The work units of a render, in the order they are taken.
pub fn work_units(width: u32, height: u32, tile: u32, samples: Range<u32>) -> Vec<WorkUnit> {
    let tile = tile.max(1);
    let batch = (WAVEFRONT_PATHS / (tile * tile)).max(1);
    let mut units = Vec::new();
    let mut s = samples.start;
    while s < samples.end {
        let e = (s + batch).min(samples.end);
        for y0 in (0..height).step_by(tile as usize) {
            for x0 in (0..width).step_by(tile as usize) {
                let t = Tile { x0, y0, x1: (x0 + tile).min(width), y1: (y0 + tile).min(height) };
                units.push(WorkUnit { tile: t, samples: s..e });
            }
        }
        s = e;
    }
    units
}

/// Render into `film` (which may already hold other samples). Returns the statistics of this call.
pub fn render_into(job: &RenderJob, film: Film) -> (Film, RenderStats) {
    let scene = job.scene;
    let units = work_units(scene.width, scene.height, job.tile, job.samples.clone());
    let threads = if job.threads == 0 { rayon::current_num_threads() } else { job.threads };
    let film = Mutex::new(film);
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let totals = Mutex::new((Counters::default(), StageTimes::default()));
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool");
    // The clock starts after the pool exists: thread start-up is not render time.
    let t0 = Instant::now();
    pool.broadcast(|_| {
        let mut wf = Wavefront::new(&scene.features);
        loop {
            if job.cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                break;
            }
            let i = next.fetch_add(1, Ordering::Relaxed);
            if i >= units.len() {
                break;
            }
            render_unit(scene, &job.settings, &units[i], &mut wf, &film);
            let d = done.fetch_add(1, Ordering::Relaxed) + 1;
            if let Some(p) = job.progress {
                p(d, units.len());
            }
        }
        let mut t = totals.lock().unwrap();
        t.0.add(&wf.counters);
        t.1.add(&wf.times);
    });
    let seconds = t0.elapsed().as_secs_f64();
    let (c, times) = totals.into_inner().unwrap();
    let film = film.into_inner().unwrap();
    let rays = RayCounts { camera: c.camera_rays, secondary: c.secondary_rays, shadow: c.shadow_rays, total: c.total_rays() };
    let stats = RenderStats {
        width: scene.width,
        height: scene.height,
        spp: job.settings.profile.spp,
        samples: [job.samples.start, job.samples.end],
        threads,
        seed: job.settings.seed,
        seconds,
        rays,
        rays_per_second: rays.total as f64 / seconds.max(1e-9),
        nonfinite_samples: c.nonfinite_samples,
        csg_candidates: c.csg_candidates,
        stage_seconds: times,
        completed: done.load(Ordering::Relaxed) == units.len(),
        features: scene.features,
    };
    (film, stats)
}

/// Render a whole image with default options.
pub fn render(scene: &Scene, settings: Settings, threads: usize) -> (Film, RenderStats) {
    let mut job = RenderJob::new(scene, settings);
    job.threads = threads;
    render_into(&job, Film::new(scene.width, scene.height))
}
