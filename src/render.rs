//! The render driver: splits the image into work units (tiles x sample batches), runs them on a rayon
//! pool with one reusable [`Wavefront`] per worker, reports progress, honours cancellation, and sums the
//! counters into a [`RenderStats`].
//!
//! Work units are taken from a shared counter, sample batch by sample batch over the whole image, so a
//! render stopped early has (nearly) the same number of samples in every pixel; within a batch tiles
//! are taken column by column ([`WorkUnits::taken`]), so the units two workers accumulate at the same time
//! are vertical neighbours, whose rows lie far apart in the film. Neither the order nor the number of
//! threads changes the image: every random number is a function of (seed, pixel, sample, dimension) and
//! the film adds in exact fixed point.
//!
//! A render can start from a film that already holds some units ([`render_resumable`]: resume) and can
//! hand out consistent snapshots while it runs ([`Checkpoint`]): a snapshot holds exactly the units it
//! marks complete, so resuming from it never counts a unit twice or misses one.

use crate::film::Film;
use crate::scene::Scene;
use crate::wavefront::generate::Tile;
use crate::wavefront::{render_unit, Counters, Settings, StageTimes, Wavefront, WorkUnit};
use serde::Serialize;
use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Mutex, RwLock};
use std::time::{Duration, Instant};

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
    /// Crossings into a fifth nested medium, which a ray's medium stack (4 deep) could not keep.
    pub lost_media: u64,
    pub csg_candidates: u64,
    /// CPU seconds per stage, summed over threads.
    pub stage_seconds: StageTimes,
    pub completed: bool,
    pub features: crate::scene::Features,
    /// Seconds spent making the light selection (`light_selection` other than `all`: the power table,
    /// the light tree) before the render's clock started: setup, not in `seconds`.
    pub selection_seconds: f64,
    /// A pass of some work unit outgrew its ray limit (`RenderJob::max_rays_per_path`): the render stopped, that
    /// unit not done ([`overflow_message`] says why). (Not in `--stats-json`: such a render is an error.)
    #[serde(skip)]
    pub overflow: bool,
}

/// The error of a render that stopped because a pass outgrew its ray limit (`RenderJob::max_rays_per_path`).
pub fn overflow_message(job: &RenderJob) -> String {
    let p = &job.settings.profile;
    format!(
        "the rays of one bounce of a work unit passed {} per camera path: with branching = \"split\", \
         throughput_cutoff = {:e} and max_depth = {} let the ray tree grow without bound; raise throughput_cutoff \
         (at 1e-3 a glass ray tree holds about 1,000 rays per path at one bounce at most), lower max_depth, or use branching = \"roulette\"",
        job.max_rays_per_path,
        p.throughput_cutoff,
        p.max_depth
    )
}

#[derive(Clone, Copy, Debug, Serialize)]
pub struct RayCounts {
    pub camera: u64,
    pub secondary: u64,
    /// Shadow rays traced.
    pub shadow: u64,
    /// Shadow rays whose light samples the light-cone test found clear: credited without tracing, not
    /// counted in `shadow` or `total` (nor in rays/s).
    pub shadow_cleared: u64,
    /// Rays traced: camera + secondary + shadow.
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
    /// Called after each finished work unit with (done, total); `done` counts units resumed from the film.
    pub progress: Option<&'a (dyn Fn(usize, usize) + Sync)>,
    /// Periodic consistent snapshots of the film.
    pub checkpoint: Option<Checkpoint<'a>>,
    /// Most rays one pass of a work unit may hold per camera path of the unit (default
    /// [`crate::wavefront::MAX_RAYS_PER_PATH`]); past it the render stops (`RenderStats::overflow`).
    pub max_rays_per_path: usize,
}

/// Every `every` (and once a unit has finished since the last), a thread of the render's own copies the
/// film while the workers pause between units, then calls `write(film, completed)` with the copy and
/// one flag per work unit ([`work_units`] order), while the workers go on: the film holds exactly the
/// flagged units. One copy at a time, into memory taken once (the film's size again) and kept for the
/// next: the next is taken `every` after this one, or when `write` returns if that is later. Where
/// that memory cannot be had, `failed` is told and the checkpoint skipped. When the workers stop,
/// `ended` (if given) is set before the render waits for a `write` in progress: the render's own film
/// supersedes it, and `write` may give up.
#[derive(Clone, Copy)]
pub struct Checkpoint<'a> {
    pub every: Duration,
    pub write: &'a (dyn Fn(&Film, &[bool]) + Sync),
    pub failed: Option<&'a (dyn Fn(String) + Sync)>,
    pub ended: Option<&'a AtomicBool>,
}

impl<'a> RenderJob<'a> {
    pub fn new(scene: &'a Scene, settings: Settings) -> Self {
        let spp = settings.profile.spp;
        RenderJob {
            scene,
            settings,
            threads: 0,
            samples: 0..spp,
            tile: TILE,
            cancel: None,
            progress: None,
            checkpoint: None,
            max_rays_per_path: crate::wavefront::MAX_RAYS_PER_PATH,
        }
    }
}

/// Samples per work unit for a tile side.
fn batch_size(tile: u32) -> u32 {
    (WAVEFRONT_PATHS / (tile * tile)).max(1)
}

/// Most samples (pixels x samples per pixel) one render may take: 2^38 = 2.7e11 (1920 x 1080 at
/// 131072 spp, 7680 x 4320 at 8192 spp; about 8 hours at 10M samples/s). What it protects is memory,
/// not time: a render keeps one completion flag per work unit of ~4096 samples (for checkpoints and
/// resume), 2 bytes each, 134 MB at this limit; the largest image at the largest spp would need 17 GB.
pub const MAX_RENDER_SAMPLES: u64 = 1 << 38;

/// Refuse a render of more than [`MAX_RENDER_SAMPLES`] samples (an input error, before anything is
/// allocated).
pub fn check_render_size(width: u32, height: u32, samples: &Range<u32>) -> Result<(), String> {
    let n = width as u64 * height as u64 * samples.len() as u64;
    if n > MAX_RENDER_SAMPLES {
        return Err(format!(
            "{width} x {height} pixels x {} samples = {n} samples; the limit per render is 2^38 = {MAX_RENDER_SAMPLES} \
             (render sample ranges separately and merge them)",
            samples.len()
        ));
    }
    Ok(())
}

/// The work units of a render, indexed sample batch by sample batch, tiles in row order within a batch
/// (the index of completion flags and film files); they are taken in [`WorkUnits::taken`] order.
/// Computed from their index, never stored: a list takes 24 bytes per unit.
#[derive(Clone, Debug)]
pub struct WorkUnits {
    width: u32,
    height: u32,
    tile: u32,
    samples: Range<u32>,
    batch: u32,
    tiles_x: usize,
    tiles: usize,
    len: usize,
}

impl WorkUnits {
    pub fn new(width: u32, height: u32, tile: u32, samples: Range<u32>) -> WorkUnits {
        let tile = tile.max(1);
        let batch = batch_size(tile);
        let tiles_x = width.div_ceil(tile) as usize;
        let tiles = tiles_x * height.div_ceil(tile) as usize;
        let len = tiles * samples.len().div_ceil(batch as usize);
        WorkUnits { width, height, tile, samples, batch, tiles_x, tiles, len }
    }

    pub fn len(&self) -> usize {
        self.len
    }

    /// The index of the unit taken `k`-th: sample batch by sample batch, and within a batch tiles column
    /// by column. Two workers accumulate the units they take one after the other at the same time: taken
    /// in row order those were horizontally adjacent tiles, whose rows meet in the film every image row
    /// (the prefetcher of one core reached into the lines the other was writing), and on two threads
    /// the showcase's accumulate took 0.010-0.012 CPU s at 4 spp (0.027-0.035 in the machine's slow
    /// phase); column by column 0.008-0.010 (0.020-0.022), one thread 0.007-0.008. A bijection of each
    /// batch's indices.
    pub fn taken(&self, k: usize) -> usize {
        let (b, p) = (k / self.tiles, k % self.tiles);
        let rows = self.tiles / self.tiles_x;
        b * self.tiles + (p % rows) * self.tiles_x + p / rows
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The samples each tile holds (indexed as [`WorkUnits::tile_of`] gives) by the units flagged in
    /// `completed` (one flag per unit): the samples every pixel of the tile holds.
    pub fn tile_samples(&self, completed: &[bool]) -> Vec<u64> {
        let mut per = vec![0u64; self.tiles];
        for (i, _) in completed.iter().enumerate().filter(|(_, &c)| c) {
            per[i % self.tiles] += self.get(i).samples.len() as u64;
        }
        per
    }

    /// The index of the tile of pixel column `x` (within a batch, units are their tiles in row order),
    /// less the row's part: [`WorkUnits::row_of`] adds it.
    pub fn column_of(&self, x: u32) -> usize {
        (x / self.tile) as usize
    }

    /// The index of the first tile of pixel row `y` (see [`WorkUnits::column_of`]).
    pub fn row_of(&self, y: u32) -> usize {
        (y / self.tile) as usize * self.tiles_x
    }

    /// Unit `i` (< `len()`).
    pub fn get(&self, i: usize) -> WorkUnit {
        let (b, k) = (i / self.tiles, i % self.tiles);
        let s = self.samples.start + b as u32 * self.batch;
        let (x0, y0) = ((k % self.tiles_x) as u32 * self.tile, (k / self.tiles_x) as u32 * self.tile);
        let tile = Tile { x0, y0, x1: (x0 + self.tile).min(self.width), y1: (y0 + self.tile).min(self.height) };
        WorkUnit { tile, samples: s..s.saturating_add(self.batch).min(self.samples.end) }
    }
}

/// `work_units(..).len()` without building the list.
pub fn unit_count(width: u32, height: u32, tile: u32, samples: Range<u32>) -> usize {
    WorkUnits::new(width, height, tile, samples).len()
}

/// The work units of a render as a list (small renders and tests; the renderer uses [`WorkUnits`]).
pub fn work_units(width: u32, height: u32, tile: u32, samples: Range<u32>) -> Vec<WorkUnit> {
    let units = WorkUnits::new(width, height, tile, samples);
    (0..units.len()).map(|i| units.get(i)).collect()
}

/// Render into `film` (which may already hold other samples). Returns the statistics of this call.
pub fn render_into(job: &RenderJob, film: Film) -> (Film, RenderStats) {
    let n = unit_count(job.scene.width, job.scene.height, job.tile, job.samples.clone());
    let (film, _, stats) = render_resumable(job, film, vec![false; n]);
    (film, stats)
}

/// Render the work units not flagged in `completed` (one flag per unit of [`work_units`]) into `film`,
/// which holds exactly the flagged ones. Returns the film, the flags after this call (all set unless
/// cancelled) and the statistics of this call.
pub fn render_resumable(job: &RenderJob, film: Film, completed: Vec<bool>) -> (Film, Vec<bool>, RenderStats) {
    let scene = job.scene;
    let units = WorkUnits::new(scene.width, scene.height, job.tile, job.samples.clone());
    assert_eq!(completed.len(), units.len(), "one completion flag per work unit");
    let resumed = completed.iter().filter(|&&c| c).count();
    let flags: Vec<AtomicBool> = completed.iter().map(|&c| AtomicBool::new(c)).collect();
    let threads = if job.threads == 0 { rayon::current_num_threads() } else { job.threads };
    let film = Mutex::new(film);
    // Workers hold `gate` for reading while a unit goes into the film and gets its flag; a snapshot
    // takes it for writing, so it never sees a unit accumulated but not flagged (or the reverse).
    // `pause` keeps workers from starting units while a snapshot waits, whatever the lock's fairness.
    let gate = RwLock::new(());
    let pause = AtomicBool::new(false);
    // Set when the workers have stopped: the checkpoint thread takes no further copy.
    let finished = (Mutex::new(false), std::sync::Condvar::new());
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let overflow = AtomicBool::new(false);
    let totals = Mutex::new((Counters::default(), StageTimes::default()));
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool");
    // The light selection is made once for all the workers, before the clock (setup, like the BVH).
    let picking = Instant::now();
    let pick = crate::wavefront::pick::LightPick::new(scene, &job.settings.profile).map(std::sync::Arc::new);
    let selection_seconds = picking.elapsed().as_secs_f64();
    // The clock starts after the pool exists: thread start-up is not render time.
    let t0 = Instant::now();
    let stopping = || job.cancel.is_some_and(|c| c.load(Ordering::Relaxed)) || overflow.load(Ordering::Relaxed);
    // Checkpoints: a copy of the film taken between units (the workers paused only for the copy, into
    // memory taken beforehand: a new film's pages cost more than the copy, 1.9 s against 0.04 s at
    // 3840 x 2160 here), written by this thread while the workers go on.
    let checkpoints = |cp: Checkpoint| {
        let mut due = Instant::now() + cp.every;
        let mut done_at_last = usize::MAX;
        let mut kept: Option<Film> = None;
        loop {
            // Until due (or the render ends), then until a unit has finished since the last copy.
            let mut end = finished.0.lock().unwrap_or_else(|e| e.into_inner());
            loop {
                let now = Instant::now();
                let fresh = done.load(Ordering::Relaxed) != done_at_last;
                if *end || (now >= due && fresh) {
                    break;
                }
                // (Workers tell of each unit finished under the lock: no wake-up is lost.)
                let wait = if now >= due { Duration::from_millis(100) } else { due - now };
                end = finished.1.wait_timeout(end, wait).unwrap_or_else(|e| e.into_inner()).0;
            }
            if *end {
                return;
            }
            drop(end);
            if stopping() {
                return;
            }
            let snapshot = match kept.take().map_or_else(|| Film::try_new(scene.width, scene.height), Ok) {
                Ok(f) => kept.insert(f),
                Err(e) => {
                    if let Some(failed) = cp.failed {
                        failed(e);
                    }
                    due = Instant::now() + cp.every;
                    continue;
                }
            };
            pause.store(true, Ordering::Release);
            let taken = {
                let _all = gate.write().unwrap_or_else(|e| e.into_inner());
                // (Nothing to keep where the render has ended meanwhile: its film is written next.)
                let ended = stopping() || resumed + done.load(Ordering::Relaxed) == units.len();
                done_at_last = done.load(Ordering::Relaxed);
                (!ended).then(|| {
                    snapshot.copy_from(&film.lock().unwrap_or_else(|e| e.into_inner()));
                    (Instant::now(), flags.iter().map(|f| f.load(Ordering::Relaxed)).collect::<Vec<bool>>())
                })
            };
            pause.store(false, Ordering::Release);
            let Some((taken, snapshot_flags)) = taken else { return };
            (cp.write)(snapshot, &snapshot_flags);
            due = taken + cp.every;
        }
    };
    let seconds = std::thread::scope(|sc| {
        let writer = job.checkpoint.map(|cp| sc.spawn(move || checkpoints(cp)));
        pool.broadcast(|_| {
            // (The pool's threads are new for each render: nothing of another render's scene is cached in
            // them, in this thread-local or the shadow stage's.)
            crate::wavefront::pick::LightPick::install(scene, &job.settings.profile, pick.clone());
            let mut wf = Wavefront::new(&scene.features);
            loop {
                if stopping() {
                    break;
                }
                let k = next.fetch_add(1, Ordering::Relaxed);
                if k >= units.len() {
                    break;
                }
                let i = units.taken(k);
                // Units are taken once each: a flag already set here came with the film.
                if flags[i].load(Ordering::Relaxed) {
                    continue;
                }
                while pause.load(Ordering::Acquire) {
                    std::thread::sleep(Duration::from_micros(200));
                }
                {
                    let _unit = gate.read().unwrap_or_else(|e| e.into_inner());
                    if !render_unit(scene, &job.settings, &units.get(i), &mut wf, &film, job.max_rays_per_path) {
                        overflow.store(true, Ordering::Relaxed);
                        break;
                    }
                    flags[i].store(true, Ordering::Relaxed);
                }
                let d = done.fetch_add(1, Ordering::Relaxed) + 1;
                if job.checkpoint.is_some() {
                    let _end = finished.0.lock().unwrap_or_else(|e| e.into_inner());
                    finished.1.notify_all();
                }
                if let Some(p) = job.progress {
                    p(resumed + d, units.len());
                }
            }
            let mut t = totals.lock().unwrap();
            t.0.add(&wf.counters);
            t.1.add(&wf.times);
        });
        // (The render's time ends here; a checkpoint being written is finished before the film is returned.)
        let seconds = t0.elapsed().as_secs_f64();
        if let Some(ended) = job.checkpoint.and_then(|c| c.ended) {
            ended.store(true, Ordering::SeqCst);
        }
        *finished.0.lock().unwrap_or_else(|e| e.into_inner()) = true;
        finished.1.notify_all();
        if let Some(w) = writer {
            w.join().expect("the checkpoint thread");
        }
        seconds
    });
    let (c, times) = totals.into_inner().unwrap();
    let film = film.into_inner().unwrap();
    let completed: Vec<bool> = flags.into_iter().map(|f| f.into_inner()).collect();
    let rays = RayCounts {
        camera: c.camera_rays,
        secondary: c.secondary_rays,
        shadow: c.shadow_rays,
        shadow_cleared: c.shadow_cleared,
        total: c.total_rays(),
    };
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
        lost_media: c.lost_media,
        csg_candidates: c.csg_candidates,
        stage_seconds: times,
        completed: completed.iter().all(|&c| c),
        features: scene.features,
        selection_seconds,
        overflow: overflow.into_inner(),
    };
    (film, completed, stats)
}

/// Render a whole image with default options.
pub fn render(scene: &Scene, settings: Settings, threads: usize) -> (Film, RenderStats) {
    let mut job = RenderJob::new(scene, settings);
    job.threads = threads;
    render_into(&job, Film::new(scene.width, scene.height))
}
