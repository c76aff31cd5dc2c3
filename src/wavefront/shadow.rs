//! Stage 5: next-event estimation. Each request (a shading point) is expanded into light samples with the
//! profile's light strategy; the shadow rays are packed in batches of 16 packets of 8 (consecutive samples
//! of one point, and neighbouring points, are coherent) and traced together with any-hit group traversal;
//! unoccluded samples add their contribution to the path. Before a sample's rays join a batch, the chunk
//! loop decides what it can without one: the light-cone test (`cone.rs`) for lights with many samples,
//! and, for point lights in scenes that have one, the light's light buffer
//! ([`occlusion_light_buffer_x16`], `accel/light_buffer.rs`).
//! Smooth dielectrics block direct light (the light they pass is a caustic), except where they do not
//! deflect it (null crossings, index-matched media, thin sheets), or everywhere under the profile's opt-in,
//! non-physical transmissive shadows: lanes whose any-hit test met only such dielectrics are then walked
//! through them for their transmittance (`transmit.rs`).

use super::cone::LightCone;
use super::dims;
use super::intersect::{in_prim_frame, prim_t_at_x8, prim_t_x8};
use super::pick::LightPick;
use super::queues::{MediumStack, NeeQueue, PathTable};
use super::transmit::{any_passable, pair_sphere, passes, single_sphere_x8, transmittance_x8, SingleSpheres, Walk};
use crate::accel::{intersect_aabb_x8, PacketRay};
use crate::accel::{LightBuffer, WideStack, GROUP, NO_CELL};
use crate::csg::{first_hit_x8, lanes_may_cross_x8, CsgArena};
use crate::geometry::{
    occludes_plane, occludes_sphere, occludes_sphere_consts, occludes_sphere_x8, occludes_spheres_lanes, SpherePacket, SpherePacketOf,
};
use crate::light::{light_points_x8, power_heuristic_x8, sample_light_x8, sample_pdf_x8, samples_for};
use crate::optics::{eval_ggx_reflect_x8, sample_ggx_reflect_pdf_x8};
use crate::sample::hash::{random_bits, RUN_MAX};
use crate::sample::{hash_combine, sample_1d_keyed, stream_key, Sampler2d, Strategy};
use crate::scene::{Light, Profile, Scene, Shape, NOT_A_LIGHT};
use crate::simd::{
    chunk8, f32x16, f32x8, for_each_group, gather8, i32x16, lane_bits, load8, mask_from_bits, store8, u32x16, u32x8, Lanes, Ray8, Vec3x8,
    LANES,
};
use glam::Vec3;

/// Shadow rays stop this fraction short of an area light's sample point (the light is geometry too).
const SHADOW_END: f32 = 1.0 - 1e-4;

/// Lights whose sample-stream keys the shadow stage keeps per pixel.
const KEY_CACHE: usize = 8;

/// Rays per batch: one traversal group of [`GROUP`] packets.
const BATCH: usize = GROUP * LANES;

/// Shadow rays waiting to be traced, in packet-sized rows: lane `k` is packet `k / 8`, lane `k % 8`.
struct Batch {
    o: [[f32; BATCH]; 3],
    d: [[f32; BATCH]; 3],
    tmax: [f32; BATCH],
    time: [f32; BATCH],
    contrib: [[f32; BATCH]; 3],
    /// Index of the request (in the NEE queue) each ray serves.
    req: [u32; BATCH],
    /// Per packet: the first of the 8 consecutive requests its lanes serve when it was appended whole
    /// (lane `l` = request `whole + l`), else [`NOT_WHOLE`].
    whole: [u32; GROUP],
    len: usize,
    /// Scratch of the walks through glass (made on the first walk).
    walk: Option<Box<Walk>>,
}

/// Eight shadow rays (one per request of a chunk) before they join a batch.
struct Rays8 {
    o: Vec3x8,
    d: Vec3x8,
    tmax: f32,
    time: f32x8,
    contrib: Vec3x8,
    /// Request index per lane: `base + lane`.
    req: u32x8,
}

/// [`Batch::whole`] of a packet appended lane by lane.
const NOT_WHOLE: u32 = u32::MAX;

impl Batch {
    fn new() -> Box<Batch> {
        Box::new(Batch {
            o: [[0.0; BATCH]; 3],
            d: [[1.0; BATCH]; 3],
            tmax: [-1.0; BATCH],
            time: [0.0; BATCH],
            contrib: [[0.0; BATCH]; 3],
            req: [0; BATCH],
            whole: [NOT_WHOLE; GROUP],
            len: 0,
            walk: None,
        })
    }

    /// Append the lanes of `r` set in `lanes`: whole vectors when all 8 are set and the batch is at a
    /// packet boundary, else lane by lane. The caller flushes first if fewer than 8 slots are free.
    #[inline(always)]
    fn append(&mut self, r: &Rays8, lanes: u32) {
        let k = self.len;
        debug_assert!(k + LANES <= BATCH);
        let vs = [r.o.x, r.o.y, r.o.z, r.d.x, r.d.y, r.d.z, r.time, r.contrib.x, r.contrib.y, r.contrib.z];
        if lanes == 0xff && k.is_multiple_of(LANES) {
            for a in 0..3 {
                store8(&mut self.o[a], k, vs[a]);
                store8(&mut self.d[a], k, vs[3 + a]);
                store8(&mut self.contrib[a], k, vs[7 + a]);
            }
            store8(&mut self.time, k, r.time);
            self.tmax[k..k + LANES].fill(r.tmax);
            let req = r.req.to_array();
            self.req[k..k + LANES].copy_from_slice(&req);
            self.whole[k / LANES] = req[0];
            self.len += LANES;
            return;
        }
        let a = vs.map(|v| v.to_array());
        let req = r.req.to_array();
        let mut bits = lanes;
        let mut k = k;
        // The (at most two) packets these lanes land in are not whole.
        self.whole[k / LANES] = NOT_WHOLE;
        self.whole[(k + lanes.count_ones() as usize - 1) / LANES] = NOT_WHOLE;
        while bits != 0 {
            let l = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            for c in 0..3 {
                self.o[c][k] = a[c][l];
                self.d[c][k] = a[3 + c][l];
                self.contrib[c][k] = a[7 + c][l];
            }
            self.time[k] = a[6][l];
            self.tmax[k] = r.tmax;
            self.req[k] = req[l];
            k += 1;
        }
        self.len = k;
    }

    /// Packet `j` into `ray` (lanes past `len` carry `tmax = -1`).
    #[inline(always)]
    fn load_packet(&self, j: usize, ray: &mut Ray8) {
        ray.load_into([&self.o[0], &self.o[1], &self.o[2]], [&self.d[0], &self.d[1], &self.d[2]], &self.tmax, j * LANES);
    }
}

/// The largest stratified set of a pixel's light samples (`spp x light_samples`, one set across the
/// pixel's camera samples, for jittered and Sobol light samples); past it each camera sample's light
/// samples are a set of their own (the samplers' sets hold at most 2^24 samples).
pub const LIGHT_SET_MAX: u64 = 1 << 24;

/// Key of light `li`'s sample stream for request `i`: shared by a pixel's samples (`across`), or the
/// sample's own.
#[inline(always)]
fn light_key(seed: u64, nee: &NeeQueue, across: bool, i: usize, li: usize) -> u64 {
    let stream = hash_combine(nee.key[i], li as u64);
    if across {
        stream_key(seed, stream, dims::LIGHT)
    } else {
        stream_key(seed, hash_combine(stream, nee.sample[i] as u64), dims::LIGHT)
    }
}

/// The stream keys of the first [`KEY_CACHE`] lights for the last request they were computed for.
struct LightKeys {
    keys: [u64; KEY_CACHE],
    /// Across samples, the request key they belong to (a pixel's requests share it).
    cached: Option<u64>,
}

impl LightKeys {
    /// Make `keys` those of request `i` (unless they already are). Point lights draw no sample: no key.
    #[inline(always)]
    fn refresh(&mut self, scene: &Scene, seed: u64, nee: &NeeQueue, across: bool, i: usize) {
        if !across || self.cached != Some(nee.key[i]) {
            self.cached = Some(nee.key[i]);
            for (li, k) in self.keys.iter_mut().enumerate().take(scene.lights.len()) {
                if !scene.lights[li].is_point() {
                    *k = light_key(seed, nee, across, i, li);
                }
            }
        }
    }
}

/// Light samples per request from which a light's shadow rays are first put to the light-cone test
/// (`cone.rs`), which costs about one packet's traversal per 8 requests. In a scene of few prims most
/// cones clear or meet one prim: from 4 samples (one thread, shadow stage: the showcase under `final`
/// 1.35 -> 1.17 s, cornell 0.101 -> 0.079; at 2 samples no gain). Among many prims few do: from 16
/// (1,000 spheres under a quad light: 4 samples +23%, 8 +5%, 16 -6%, 32 -12%).
fn cone_min_samples(scene: &Scene) -> u32 {
    if scene.bounded.len() <= 64 {
        4
    } else {
        16
    }
}

/// Shadow rays traced and shadow rays the light-cone test found clear (credited untraced).
pub fn shadow(scene: &Scene, profile: &Profile, seed: u64, nee: &NeeQueue, paths: &mut PathTable, arena: &mut CsgArena) -> (u64, u64) {
    shadow_with(scene, profile, seed, nee, paths, arena, None)
}

/// [`shadow`]; `scattered` (a traversal stack): the shading points are scattered (hits of incoherent
/// bounces), so that packets of their shadow rays share few nodes: scenes whose shadow rays walk
/// through nothing then trace them one at a time ([`occlusion_single`]; in trees of at least
/// `WIDE_MIN_NODES` nodes without CSG). Same result either way. Glossy points' requests (in
/// `nee.glossy`, scenes with glossy materials) are taken after the Lambert ones, with their lobes.
pub fn shadow_with(
    scene: &Scene,
    profile: &Profile,
    seed: u64,
    nee: &NeeQueue,
    paths: &mut PathTable,
    arena: &mut CsgArena,
    mut scattered: Option<&mut WideStack>,
) -> (u64, u64) {
    let Some(pick) = LightPick::cached(scene, profile) else {
        let (mut traced, mut cleared) =
            shadow_queue::<false, false>(scene, profile, seed, nee, paths, arena, scattered.as_deref_mut(), None);
        if let Some(g) = nee.glossy.as_deref().filter(|g| !g.is_empty()) {
            let (t, c) = shadow_queue::<true, false>(scene, profile, seed, g, paths, arena, scattered, None);
            (traced, cleared) = (traced + t, cleared + c);
        }
        return (traced, cleared);
    };
    // One light per request: each queue is copied in the order of the lights picked (a chunk's lanes
    // then share their light, whose samples are computed for 8 lanes at once), weights divided by the
    // picks' probabilities. A request is credited by its one light, so the order of requests changes
    // no request's sum.
    let mut sorted = PICKED.take().unwrap_or_default();
    let (mut traced, mut cleared) = (0, 0);
    let queues = [Some(nee), nee.glossy.as_deref()];
    for (k, q) in queues.into_iter().enumerate() {
        let Some(q) = q.filter(|q| !q.is_empty()) else { continue };
        sorted.sort(&pick, profile, seed, q);
        let picks = Some((&sorted.light[..], &sorted.prob[..]));
        let (t, c) = if k == 0 {
            shadow_queue::<false, true>(scene, profile, seed, &sorted.queue, paths, arena, scattered.as_deref_mut(), picks)
        } else {
            shadow_queue::<true, true>(scene, profile, seed, &sorted.queue, paths, arena, scattered.as_deref_mut(), picks)
        };
        (traced, cleared) = (traced + t, cleared + c);
    }
    PICKED.set(Some(sorted));
    (traced, cleared)
}

/// A NEE queue's requests sorted by the light each picked (see [`shadow_with`]), with their picks.
#[derive(Default)]
struct Picked {
    queue: NeeQueue,
    /// Per sorted request: its light (ascending) and the probability it was picked with.
    light: Vec<u32>,
    prob: Vec<f32>,
    /// Scratch: per request of the source queue its light and probability, the importances of `local`
    /// picks, and the sort's order.
    src_light: Vec<u32>,
    src_prob: Vec<f32>,
    scratch: Vec<f32x8>,
    order: Vec<u32>,
    counts: Vec<u32>,
}

impl Picked {
    /// Pick a light for each request of `q` (its random number: [`LightPick::strategy`], key of the
    /// request's stream and `dims::LIGHT_PICK`, index its camera sample among `spp`, so a pixel's picks
    /// are stratified; and 24 random bits of `dims::LIGHT_PICK_FINE` for the floor and the zooms), and
    /// copy `q` sorted by light (stably), leaving out requests no light reaches, their weights divided
    /// by the probabilities.
    fn sort(&mut self, pick: &LightPick, profile: &Profile, seed: u64, q: &NeeQueue) {
        let n = q.len();
        let strategy = LightPick::strategy(profile);
        self.src_light.clear();
        self.src_prob.clear();
        let mut memo = (0u64, 0u64, 0u64);
        let mut base = 0;
        while base < n {
            let m = (n - base).min(LANES);
            // (Glossy points pick at their offset origin, bit for bit the lobe ray's, where its MIS
            // weight asks the probability again.)
            let p = if q.alpha.is_empty() {
                Vec3x8::new(chunk8(&q.px, base, m), chunk8(&q.py, base, m), chunk8(&q.pz, base, m))
            } else {
                Vec3x8::new(chunk8(&q.ox, base, m), chunk8(&q.oy, base, m), chunk8(&q.oz, base, m))
            };
            let (mut u, mut fine) = ([0.0f32; LANES], [0u32; LANES]);
            for l in 0..m {
                let i = base + l;
                // (A pixel's requests are consecutive: their stream keys are made once.)
                if memo.0 != q.key[i] || base + l == 0 {
                    memo = (q.key[i], stream_key(seed, q.key[i], dims::LIGHT_PICK), stream_key(seed, q.key[i], dims::LIGHT_PICK_FINE));
                }
                u[l] = sample_1d_keyed(strategy, memo.1, q.sample[i], profile.spp);
                fine[l] = random_bits(memo.2, q.sample[i]) as u32;
            }
            // (Lambert points' picks weigh their horizon: glossy points' must be found again by the MIS
            // weights of their lobe rays, which know no normal.)
            let normals = (q.alpha.is_empty()).then(|| Vec3x8::new(chunk8(&q.nx, base, m), chunk8(&q.ny, base, m), chunk8(&q.nz, base, m)));
            let (light, prob) = pick.pick_x8(p, normals, f32x8::from(u), fine, &mut self.scratch);
            self.src_light.extend_from_slice(&light[..m]);
            self.src_prob.extend_from_slice(&prob[..m]);
            base += m;
        }
        // Counting sort by light (NO_LIGHT requests last, then dropped).
        let nl = pick.lights();
        self.counts.clear();
        self.counts.resize(nl + 1, 0);
        for &l in &self.src_light {
            self.counts[(l as usize).min(nl)] += 1;
        }
        let mut start = 0;
        for c in self.counts.iter_mut() {
            (*c, start) = (start, start + *c);
        }
        self.order.clear();
        self.order.resize(n, 0);
        for (i, &l) in self.src_light.iter().enumerate() {
            let slot = &mut self.counts[(l as usize).min(nl)];
            self.order[*slot as usize] = i as u32;
            *slot += 1;
        }
        let kept = self.counts[nl - 1] as usize;
        self.order.truncate(kept);
        self.queue.copy_from(q, &self.order);
        self.light.clear();
        self.prob.clear();
        for k in 0..kept {
            let i = self.order[k] as usize;
            let inv = 1.0 / self.src_prob[i];
            self.queue.wr[k] *= inv;
            self.queue.wg[k] *= inv;
            self.queue.wb[k] *= inv;
            self.light.push(self.src_light[i]);
            self.prob.push(self.src_prob[i]);
        }
    }
}

/// The requests of one queue (see [`shadow_with`]): Lambert ones, or (`LOBES`) glossy ones, with lobe
/// columns (a separate instance: the Lambert one compiles without the glossy code); each request's
/// light and its probability where (`PICK`) requests picked one, sorted by it (again an instance of
/// its own: the renders of every light compile without the picks).
#[allow(clippy::too_many_arguments)]
fn shadow_queue<const LOBES: bool, const PICK: bool>(
    scene: &Scene,
    profile: &Profile,
    seed: u64,
    nee: &NeeQueue,
    paths: &mut PathTable,
    arena: &mut CsgArena,
    scattered: Option<&mut WideStack>,
    picks: Option<(&[u32], &[f32])>,
) -> (u64, u64) {
    debug_assert_eq!(PICK, picks.is_some());
    let picks = if PICK { picks } else { None };
    // One batch per light in scenes of a few lights: a batch mixing lights in different directions has
    // directions of both signs on two or three axes, and its group is then traced packet by packet
    // (GroupBounds); a third of the showcase's were. A batch is flushed only after every lower light's
    // (`flush_upto`), so each request's contributions are still credited in light order, then sample
    // order, whatever the batches: the same sums as one batch.
    let nb = if scene.lights.len() <= MAX_LIGHT_BATCHES { scene.lights.len().max(1) } else { 1 };
    // The thread's batches from its last call (empty after their last flush; 6.5 KB each, not made
    // again per call).
    let mut batches = BATCHES.take();
    while batches.len() < nb {
        batches.push(Batch::new());
    }
    let mut traced = 0u64;
    let mut cleared = 0u64;
    // Jittered and Sobol light samples form one stratified set over all of a pixel's camera samples
    // (index = sample x light_samples + j, strata permuted per stream, as a padded sampler does): with
    // 1 light sample and 64 pixel samples the light is still covered by 64 strata. Grid keeps its meaning
    // (each shading point sees the light as the same grid of point lights); random needs no set.
    let (spp, nl) = (profile.spp as u64, profile.light_samples as u64);
    let across = matches!(profile.light_strategy, Strategy::Jittered | Strategy::Sobol) && spp * nl <= LIGHT_SET_MAX;
    let area = Sampler2d::new(profile.light_strategy, if across { (spp * nl) as u32 } else { profile.light_samples });
    let tables = LightTables::get(scene, profile, across, &area);
    let LightTables { grid, grid_points, flat_light, .. } = &*tables;
    let walk = any_passable(scene, profile);
    // Only where it pays (measured): trees large enough that incoherent rays take the wide one in the
    // intersect stage too (in small trees groups share the top levels), and no CSG solids (a lone ray
    // would pay a whole 8-lane interval merge).
    let mut single = scattered.filter(|_| !walk && scene.wide_incoherent && !scene.features.csg && !scene.wide_bvh.is_empty());
    let cones = &tables.cones;
    // Point lights' light buffers, where shadow rays walk through nothing.
    let buffer = |li: usize| scene.light_buffers.get(li).and_then(|b| b.as_ref()).filter(|_| !walk);
    let light_key = |i: usize, li: usize| light_key(seed, nee, across, i, li);
    let mut keys = LightKeys { keys: [0; KEY_CACHE], cached: None };
    let keyed = tables.keyed;
    // Requests are taken 8 at a time: one lane each, every light sample of the chunk computed as one
    // 8-lane light sample. Each request sums its unoccluded contributions by light, then sample, from
    // zero (`Credit`), and the sums go to the paths in request order at the end: a path's radiance
    // then does not depend on which requests share a chunk or a batch (that depends on the tile).
    let buffers = tables.buffers && !walk;
    debug_assert_eq!(nee.alpha.len(), if LOBES { nee.len() } else { 0 }, "lobe columns for every request or none");
    debug_assert!(nee.alpha.iter().all(|&a| a != 0.0), "a queue with lobes holds glossy requests only");
    let mut credit = Credit::new(nee.len(), tables.any_cone, buffers);
    // The requests' media, where some point lies inside one (else none: the queue's points are all in
    // air, as in scenes without dielectrics, and nothing below looks them up).
    let media: &[MediumStack] = if nee.media.iter().any(|m| !m.is_empty()) { &nee.media } else { &[] };
    // Per light (when any has a buffer, and requests did not pick theirs), the packet of an even chunk
    // waiting for its pair.
    let mut held: Vec<Option<BufferJob>> = if buffers && picks.is_none() { vec![None; scene.lights.len()] } else { Vec::new() };
    let mut chunk = 0usize;
    // (The light samples of a run, `sample_x8_run`: made once here, not zeroed per chunk and light.)
    let mut run = [[f32x8::ZERO; 2]; RUN_MAX];
    let mut base = 0;
    while base < nee.len() {
        let m = (nee.len() - base).min(LANES);
        let live = (1u32 << m) - 1;
        // Lanes past `m` repeat the last request (masked off by `live`).
        let p = Vec3x8::new(chunk8(&nee.px, base, m), chunk8(&nee.py, base, m), chunk8(&nee.pz, base, m));
        let n = Vec3x8::new(chunk8(&nee.nx, base, m), chunk8(&nee.ny, base, m), chunk8(&nee.nz, base, m));
        let w = Vec3x8::new(chunk8(&nee.wr, base, m), chunk8(&nee.wg, base, m), chunk8(&nee.wb, base, m));
        // Light samples are taken at the shading point; only the shadow ray starts off the surface.
        let o = Vec3x8::new(chunk8(&nee.ox, base, m), chunk8(&nee.oy, base, m), chunk8(&nee.oz, base, m));
        let time = chunk8(&nee.time, base, m);
        // Requests sorted by the light they picked (`picks`): the chunk's lights, each lane's, and the
        // probabilities of their picks.
        let picked = picks.map(|(light, prob)| (gather8(light, m == LANES, base, |l| base + l.min(m - 1)), chunk8(prob, base, m)));
        // (Plain loops rather than `array::from_fn` in this loop: see `simd::chunk8`.)
        let mut req = [0u32; LANES];
        for (l, r) in req.iter_mut().enumerate() {
            *r = (base + l.min(m - 1)) as u32;
        }
        let req = u32x8::from(req);
        // Requests whose points lie inside media (their shadow rays are absorbed on the way, and
        // cross the media's surfaces from inside): traced in batches (then absorbed, or walked where
        // they met surfaces), never answered untraced.
        let inside = if media.is_empty() { 0 } else { lane_bits(|l| l < m && !media[base + l].is_empty()) };
        // Light-stream keys per lane. Across samples a light's stream is shared by the pixel's samples,
        // whose requests are usually consecutive: the keys of the first KEY_CACHE lights are computed
        // once per run of them.
        let mut lane_keys = [[0u64; LANES]; KEY_CACHE];
        // Usually the whole chunk is one pixel's samples (one key per light, splat below); lanes written
        // one by one would stall the vector loads of the keys.
        // (Requests that picked their light need only that light's keys, made below.)
        let one_pixel = keyed && across && picks.is_none() && nee.key[base..base + m].iter().all(|&k| k == nee.key[base]);
        if one_pixel {
            keys.refresh(scene, seed, nee, across, base);
        } else if keyed && picks.is_none() {
            for l in 0..m {
                keys.refresh(scene, seed, nee, across, base + l);
                for (lane_key, &k) in lane_keys.iter_mut().zip(&keys.keys).take(scene.lights.len()) {
                    lane_key[l] = k;
                }
            }
        }
        // Every light, or the chunk's picked ones (ascending: each once).
        let mut chosen = [0usize; LANES];
        let mut n_chosen = 0;
        if let Some((lanes, _)) = &picked {
            for &li in lanes.iter().take(m) {
                if n_chosen == 0 || chosen[n_chosen - 1] != li as usize {
                    chosen[n_chosen] = li as usize;
                    n_chosen += 1;
                }
            }
        }
        let every = if picked.is_some() { 0..0 } else { 0..scene.lights.len() };
        for li in every.chain(chosen[..n_chosen].iter().copied()) {
            let light = &scene.lights[li];
            // The lanes that sample this light (all, unless requests picked theirs), and the picks'
            // probabilities (for the MIS weights of glossy requests).
            let (live, pick_prob) = match &picked {
                None => (live, None),
                Some((light, prob)) => (live & lane_bits(|l| light[l] == li as u32), Some(*prob)),
            };
            if live == 0 {
                continue;
            }
            // A queue of glossy requests: their light samples are weighted by `glossy_samples`, which reads
            // their lobes.
            let glossy = if LOBES { live } else { 0 };
            let ns = samples_for(light, profile.light_samples);
            let point = light.is_point();
            let keys_li: [u64; LANES] = if point {
                [0; LANES]
            } else if one_pixel && li < KEY_CACHE {
                [keys.keys[li]; LANES]
            } else if li < KEY_CACHE && picks.is_none() {
                lane_keys[li]
            } else {
                // (Across samples, lanes of one pixel's requests share the key: made once per run.)
                let mut k = [0u64; LANES];
                for l in 0..m {
                    let i = base + l;
                    k[l] = if across && l > 0 && nee.key[i] == nee.key[i - 1] { k[l - 1] } else { light_key(i, li) };
                }
                k
            };
            let end = if point { 1.0 } else { SHADOW_END };
            let ns_lanes = f32x8::splat(ns as f32);
            // Lanes whose every shadow ray towards this light is clear: credited untraced. Lanes whose rays
            // can meet only one glass sphere they walk through (`glass`), or one opaque prim (`opaque`):
            // tested against that prim (`prim_of`) alone.
            let verdict = cones[li].as_ref().map(|c| c.verdict(scene, o, live));
            let clear = verdict.map_or(0, |v| v.clear) & !inside;
            let (glass, opaque, prim_of) = match verdict {
                Some(v) if v.single != 0 => {
                    let single = |l: usize| v.single & (1 << l) != 0;
                    (
                        lane_bits(|l| single(l) && walk && pair_sphere(scene, profile, v.prim[l])) & !inside,
                        lane_bits(|l| single(l) && opaque_prim(scene, profile, v.prim[l])) & !inside,
                        v.prim,
                    )
                }
                _ => (0, 0, [0; LANES]),
            };
            let spheres = (glass != 0).then(|| SingleSpheres::new(scene, profile, &prim_of, glass));
            let samples = gather8(&nee.sample, m == LANES, base, |l| base + l.min(m - 1));
            // The cleared lanes' contributions of this light, summed over its samples in registers.
            let mut cleared_sum = Vec3x8::splat(Vec3::ZERO);
            // Across: sample index = camera sample x ns + j of the pixel's set. Else all ns samples
            // serve this one shading point: strata need no permutation.
            let permuted = across && !point;
            // Sets whose permutation walks cycles: the samples of up to `RUN_MAX` consecutive j at once
            // (`run`, from `run_j` on), each lane walking its j one after another.
            let mut run_j = u32::MAX;
            for j in 0..ns {
                let index = if permuted { samples.map(|s| s * ns + j) } else { [j; LANES] };
                // A point light's one sample is the centre of its (unused) sample square.
                // A quad or disk light's point `y` (and target): the contribution w L A cos_l cos / (d^2 ns)
                // with both cosines from the unnormalised direction (no square root, two divisions).
                let area_point = |y: Vec3x8, target: Vec3x8| {
                    let (nl, la) = flat_light[li];
                    let v = y - p;
                    let d2 = v.dot_unfused(v);
                    let (cl, cr) = (-Vec3x8::splat(nl).dot_unfused(v), n.dot_unfused(v));
                    let c = (w * Vec3x8::splat(la)).scale(cl * cr / d2 / d2);
                    let zero = f32x8::ZERO;
                    (target, c, d2.simd_gt(zero) & cl.simd_gt(zero) & cr.simd_gt(zero) & c.x.max(c.y).max(c.z).simd_gt(zero), y)
                };
                // (`y`: a point along the sample's direction from `p`, for glossy requests' lobes.)
                let (target, c, lit, y) = match grid_points[li].get(j as usize) {
                    Some(&(y, target)) => area_point(y, target),
                    None => {
                        let u = match (point, grid.get(j as usize)) {
                            (true, _) => [f32x8::splat(0.5); 2],
                            (false, Some(&u)) => u,
                            (false, None) if area.runs() => {
                                if !(run_j..run_j.saturating_add(RUN_MAX as u32)).contains(&j) {
                                    let count = ((ns - j) as usize).min(RUN_MAX);
                                    area.sample_x8_run(&keys_li, &index, 1, count, permuted, &mut run);
                                    run_j = j;
                                }
                                run[(j - run_j) as usize]
                            }
                            // (One pixel's requests: one key, its constants worked out once.)
                            (false, None) if one_pixel && li < KEY_CACHE => area.sample_x8_one_key_call(keys_li[0], &index, permuted),
                            (false, None) => area.sample_x8_call(&keys_li, &index, permuted),
                        };
                        match (light_points_x8(light, u), light) {
                            (Some((y, target)), _) => area_point(y, target),
                            (None, &Light::Point { position, intensity }) => {
                                // w I cos / d^2 with the cosine from the unnormalised direction: one
                                // square root and one division (the light's one sample: no 1 / ns).
                                let v = Vec3x8::splat(position) - p;
                                let d2 = v.dot_unfused(v);
                                let cr = n.dot_unfused(v);
                                let c = (w * Vec3x8::splat(intensity)).scale(cr / (d2 * d2.sqrt()));
                                let zero = f32x8::ZERO;
                                let lit = d2.simd_gt(zero) & cr.simd_gt(zero) & c.x.max(c.y).max(c.z).simd_gt(zero);
                                (Vec3x8::splat(position), c, lit, Vec3x8::splat(position))
                            }
                            (None, _) => {
                                // Sphere lights.
                                let ls = sample_light_x8(light, p, u);
                                let cos = n.dot_unfused(ls.wi);
                                let c = (w * ls.weight).scale(cos / ns_lanes);
                                let lit = ls.valid & cos.simd_gt(f32x8::ZERO) & c.x.max(c.y).max(c.z).simd_gt(f32x8::ZERO);
                                (ls.target, c, lit, p + ls.wi)
                            }
                        }
                    }
                };
                let (c, lit) = match glossy & lit.to_bitmask() {
                    0 => (c, lit),
                    _ => glossy_samples(light, ns, pick_prob, nee, base, m, p, n, y, c, lit),
                };
                let lanes = lit.to_bitmask() & live;
                if lanes & clear != 0 {
                    let keep = mask_from_bits(lanes & clear);
                    cleared_sum = cleared_sum + Vec3x8::masked(c, keep);
                    cleared += (lanes & clear).count_ones() as u64;
                }
                let mut lanes = lanes & !clear;
                if let Some(spheres) = spheres.as_ref().filter(|_| lanes & glass != 0) {
                    let d = target - o;
                    let tmax = mask_from_bits(lanes & glass).select(f32x8::splat(end), f32x8::splat(-1.0));
                    // Rays crossing the sphere once (not `done`) go on to the batch.
                    let (done, t) = single_sphere_x8(scene, spheres, &Ray8::new(o, d, tmax), lanes & glass);
                    if done != 0 {
                        let keep = mask_from_bits(done);
                        cleared_sum = cleared_sum + Vec3x8::new((c.x * t.x) & keep, (c.y * t.y) & keep, (c.z * t.z) & keep);
                        traced += done.count_ones() as u64;
                        lanes &= !done;
                    }
                }
                if let Some(lb) = buffer(li) {
                    // Answered from the light's buffer; where AVX-512 makes 16 lanes cost what 8 do,
                    // two chunks' packets at once: an even chunk's packet waits for the next chunk's
                    // (`BufferJob`).
                    let job = (lanes & !inside != 0).then_some(BufferJob { base, lanes: lanes & !inside, c });
                    lanes &= inside;
                    // (Requests that picked their light are sorted by it: no pairs across lights.)
                    if PAIR_PACKETS && picked.is_none() && chunk.is_multiple_of(2) {
                        held[li] = job;
                    } else {
                        let first = held.get_mut(li).and_then(Option::take);
                        traced += resolve_buffered(scene, profile, lb, li, nee, first.as_ref(), job.as_ref(), &mut credit, arena);
                    }
                }
                for_each_group(
                    lanes & opaque,
                    |l| prim_of[l],
                    |first, same| {
                        let pid = prim_of[first];
                        let tmax = mask_from_bits(same).select(f32x8::splat(end), f32x8::splat(-1.0));
                        let mut touched = 0;
                        let occ = prim_occlusion(scene, profile, pid, &Ray8::new(o, target - o, tmax), None, arena, walk, &mut touched);
                        debug_assert_eq!(touched, 0, "an opaque prim lets no ray through");
                        let keep = mask_from_bits(same & !occ.to_bitmask());
                        cleared_sum = cleared_sum + Vec3x8::masked(c, keep);
                        traced += same.count_ones() as u64;
                        lanes &= !same;
                    },
                );
                if lanes == 0 {
                    continue;
                }
                // (A request that picked one light is credited by one batch: no order to keep between
                // batches, and a full batch goes alone.)
                let bi = li.min(nb - 1);
                let lo = if picked.is_some() { bi } else { 0 };
                if batches[bi].len + LANES > BATCH {
                    traced += flush_upto(scene, profile, &mut batches[lo..=bi], &mut credit, media, arena, walk, single.as_deref_mut());
                }
                batches[bi].append(&Rays8 { o, d: target - o, tmax: end, time, contrib: c, req }, lanes);
                if batches[bi].len == BATCH {
                    traced += flush_upto(scene, profile, &mut batches[lo..=bi], &mut credit, media, arena, walk, single.as_deref_mut());
                }
            }
            if clear | glass | opaque != 0 {
                credit.add_clear(base, cleared_sum);
            }
        }
        base += m;
        chunk += 1;
    }
    for (li, job) in held.iter_mut().enumerate() {
        if let Some(lb) = buffer(li) {
            traced += resolve_buffered(scene, profile, lb, li, nee, job.take().as_ref(), None, &mut credit, arena);
        }
    }
    traced += flush_upto(scene, profile, &mut batches[..nb], &mut credit, media, arena, walk, single);
    BATCHES.set(batches);
    credit.to_paths(nee, paths);
    (traced, cleared)
}

/// One light sample's contributions `c` (as a Lambert point's, from `w` = throughput x tint) for the
/// glossy requests of the chunk at request `base` (`m` of them; `p`, `n` their points and normals):
/// `c` x `f(wo, wi)` / `cos` with `f` the GGX lobe ([`eval_ggx_reflect_x8`], which holds the cosine),
/// x the power-heuristic weight against the point's one lobe ray for area lights (the light's `ns`
/// samples against it; none for point lights, which no lobe ray finds, or where no lobe ray leaves:
/// `alpha < 0`, see [`NeeQueue::wox`]). `y` is a point along the sample's direction (the light point).
/// Lanes whose lobe gives nothing are no longer lit (no shadow ray). All 8 lanes at once, each lane's
/// bits those of the scalar functions (`eval_ggx_reflect`, `sample_pdf`, `power_heuristic`,
/// `sample_ggx_reflect_pdf`), as their x8 twins' tests check.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn glossy_samples(
    light: &Light,
    ns: u32,
    pick_prob: Option<f32x8>,
    nee: &NeeQueue,
    base: usize,
    m: usize,
    p: Vec3x8,
    n: Vec3x8,
    y: Vec3x8,
    c: Vec3x8,
    lit: f32x8,
) -> (Vec3x8, f32x8) {
    let zero = f32x8::ZERO;
    let wo = Vec3x8::new(chunk8(&nee.wox, base, m), chunk8(&nee.woy, base, m), chunk8(&nee.woz, base, m));
    let a = chunk8(&nee.alpha, base, m);
    let alpha = a.abs();
    let wi = (y - p).normalize_or(Vec3x8::splat(Vec3::ZERO));
    let cos = n.dot_unfused(wi);
    let mut k = cos.simd_gt(zero).select(eval_ggx_reflect_x8(wo, n, wi, alpha) / cos, zero);
    if !light.is_point() {
        // The light strategy's density: ns samples of the light's own, x the pick's probability.
        let pdf = sample_pdf_x8(light, p, y);
        let pdf = pick_prob.map_or(pdf, |q| pdf * q);
        let mis = power_heuristic_x8(ns as f32, pdf, sample_ggx_reflect_pdf_x8(wo, n, wi, alpha));
        k = a.simd_gt(zero).select(k * mis, k);
    }
    let ok = k.simd_gt(zero) & k.is_finite();
    (Vec3x8::masked(c.scale(k), ok), lit & ok)
}

/// Per request of the NEE queue, the sum of its unoccluded shadow rays' contributions (channels apart:
/// a whole packet's 8 consecutive requests are one vector). The samples decided in the chunk loop
/// (cleared by the light-cone test, or tested against their single prim) are summed apart from the
/// traced ones: which samples are which depends only on the request's own geometry, but the traced
/// ones arrive later, at a flush whose timing depends on the batch, so one sum would take the two
/// kinds in an order that depends on the tile.
struct Credit {
    c: [Vec<f32>; 3],
    clear: [Vec<f32>; 3],
    /// Sums of the contributions answered from light buffers (by light, from zero).
    buffered: [Vec<f32>; 3],
}

impl Credit {
    /// For `n` requests; `cone`: whether any light takes the light-cone test (else no clear sums);
    /// `buffers`: whether any light has a light buffer.
    fn new(n: usize, cone: bool, buffers: bool) -> Self {
        // Padded to whole packets: a whole packet's vector never reaches past the end.
        let len = n.next_multiple_of(LANES);
        let z = |on: bool| {
            let len = if on { len } else { 0 };
            [vec![0.0; len], vec![0.0; len], vec![0.0; len]]
        };
        Credit { c: z(true), clear: z(cone), buffered: z(buffers) }
    }

    /// Add the contributions `c` of a chunk's lanes `lit` answered from a light buffer.
    #[inline(always)]
    fn add_buffered(&mut self, base: usize, c: Vec3x8, lit: u32) {
        let c = Vec3x8::masked(c, mask_from_bits(lit));
        for (acc, v) in self.buffered.iter_mut().zip([c.x, c.y, c.z]) {
            let sum = load8(acc, base) + v;
            store8(acc, base, sum);
        }
    }

    /// Add the sums `c` of a chunk's contributions cleared by the light-cone test (lane `l` = request
    /// `base + l`; 0 in lanes without any).
    #[inline(always)]
    fn add_clear(&mut self, base: usize, c: Vec3x8) {
        for (acc, v) in self.clear.iter_mut().zip([c.x, c.y, c.z]) {
            let sum = load8(acc, base) + v;
            store8(acc, base, sum);
        }
    }

    /// Add packet `j` of the batch: `keep` = its lanes that pass (unoccluded), `through` the walked
    /// ones among them with their transmittance `tr`.
    #[inline(always)]
    fn add_packet(&mut self, pk: &Batch, j: usize, keep: u32, through: u32, tr: &[Vec3; LANES]) {
        let q0 = j * LANES;
        let base = pk.whole[j];
        if base != NOT_WHOLE {
            // Lanes = requests base..base + 8: one vector per channel, occluded lanes adding exactly 0.
            let keep_f = mask_from_bits(keep);
            let b = base as usize;
            for (a, acc) in self.c.iter_mut().enumerate() {
                let mut v = load8(&pk.contrib[a], q0);
                if through != 0 {
                    v *= f32x8::from(std::array::from_fn(|l| if through & (1 << l) != 0 { tr[l][a] } else { 1.0 }));
                }
                let sum = load8(acc, b) + (v & keep_f);
                store8(acc, b, sum);
            }
            return;
        }
        let mut bits = keep;
        while bits != 0 {
            let l = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let q = q0 + l;
            let r = pk.req[q] as usize;
            let t = if through & (1 << l) != 0 { tr[l] } else { Vec3::ONE };
            for (a, acc) in self.c.iter_mut().enumerate() {
                acc[r] += pk.contrib[a][q] * t[a];
            }
        }
    }

    /// Each request's sum to its path, in request order.
    fn to_paths(&self, nee: &NeeQueue, paths: &mut PathTable) {
        for sums in [&self.c, &self.clear, &self.buffered] {
            if !sums[0].is_empty() {
                add_to_paths(sums, &nee.path, paths);
            }
        }
    }
}

/// `paths[path[i]] += sums[i]` for every request `i`, in request order; 8 at a time where 8
/// consecutive requests serve 8 consecutive paths (the usual case: camera paths in order), which adds
/// the same values to the same paths.
fn add_to_paths(sums: &[Vec<f32>; 3], path: &[u32], paths: &mut PathTable) {
    let steps = u32x8::from([0, 1, 2, 3, 4, 5, 6, 7]);
    let mut i = 0;
    while i < path.len() {
        let p = path[i];
        if i + LANES <= path.len() && u32x8::from(gather8(path, true, i, |l| l)) == u32x8::splat(p) + steps {
            let q = p as usize;
            for (acc, sum) in [&mut paths.lr, &mut paths.lg, &mut paths.lb].into_iter().zip(sums) {
                let v = load8(acc, q) + load8(sum, i);
                store8(acc, q, v);
            }
            i += LANES;
        } else {
            paths.add(p, Vec3::new(sums[0][i], sums[1][i], sums[2][i]));
            i += 1;
        }
    }
}

/// A chunk's shadow rays towards a point light with a light buffer, waiting to be answered with the
/// next chunk's ([`resolve_buffered`]): the rays are rebuilt from the requests then.
#[derive(Clone, Copy)]
struct BufferJob {
    /// The chunk's first request.
    base: usize,
    /// The lanes with a shadow ray.
    lanes: u32,
    /// The lanes' contributions if unoccluded.
    c: Vec3x8,
}

/// Answer up to two chunks' shadow rays towards point light `li` from its buffer `lb` (two as 16 lanes,
/// [`occlusion_light_buffer_x16`]; one as 8); lanes it refuses are traced through the BVH as one
/// packet. The unoccluded lanes' contributions go to their requests' buffered sums. Where packets are
/// paired ([`PAIR_PACKETS`]), even chunks wait for the odd chunk after them and every light's jobs are
/// answered in light order at that chunk, so each request's buffered sum adds its lights in light
/// order, whichever chunks were paired (and unpaired, each chunk's at its light's turn). Rays traced.
#[allow(clippy::too_many_arguments)]
fn resolve_buffered(
    scene: &Scene,
    profile: &Profile,
    lb: &LightBuffer,
    li: usize,
    nee: &NeeQueue,
    a: Option<&BufferJob>,
    b: Option<&BufferJob>,
    credit: &mut Credit,
    arena: &mut CsgArena,
) -> u64 {
    let jobs = match (a, b) {
        (Some(a), b) => [Some(a), b],
        (None, b) => [b, None],
    };
    if jobs[0].is_none() {
        return 0;
    }
    let Light::Point { position, .. } = scene.lights[li] else { unreachable!("light buffers are built for point lights") };
    let motion = scene.features.motion;
    // A job's rays as the chunk loop makes them: from the spawn points to the light, tmax 1.
    let rays_of = |j: &BufferJob| {
        let (base, m) = (j.base, (nee.len() - j.base).min(LANES));
        let o = Vec3x8::new(chunk8(&nee.ox, base, m), chunk8(&nee.oy, base, m), chunk8(&nee.oz, base, m));
        let tmax = mask_from_bits(j.lanes).select(f32x8::ONE, f32x8::splat(-1.0));
        let own = gather8(&nee.own, m == LANES, base, |l| base + l.min(m - 1));
        (Ray8::new(o, Vec3x8::splat(position) - o, tmax), own, motion.then(|| chunk8(&nee.time, base, m)))
    };
    let mut rays = [Ray8::new(Vec3x8::splat(Vec3::ZERO), Vec3x8::splat(Vec3::ONE), f32x8::splat(-1.0)); 2];
    let mut own = [super::queues::NONE; 2 * LANES];
    let mut times = [None; 2];
    let mut lanes = 0;
    for (h, j) in jobs.iter().enumerate() {
        if let Some(j) = j {
            let (r, o, t) = rays_of(j);
            (rays[h], times[h]) = (r, t);
            own[LANES * h..LANES * (h + 1)].copy_from_slice(&o);
            lanes |= j.lanes << (LANES * h);
        }
    }
    let time = times[0].map(|t| [t, times[1].unwrap_or(t)]);
    let (mut occ, answered) = if jobs[1].is_some() {
        occlusion_light_buffer_x16(scene, profile, lb, &rays, lanes, &own, time, arena)
    } else {
        query_light_buffer::<f32x8>(scene, profile, lb, &rays[..1], lanes, &own[..LANES], time, arena)
    };
    for (h, j) in jobs.iter().enumerate() {
        let Some(j) = j else { continue };
        occ |= occlusion_refused(scene, profile, &rays[h], (lanes & !answered) >> (LANES * h) & 0xff, times[h], arena) << (LANES * h);
        credit.add_buffered(j.base, j.c, (lanes & !occ) >> (LANES * h) & 0xff);
    }
    lanes.count_ones() as u64
}

/// The occluded lanes among `refused`, lanes of `ray` a light buffer did not answer, by the group
/// traversal (one packet; none when `refused` is empty).
pub fn occlusion_refused(scene: &Scene, profile: &Profile, ray: &Ray8, refused: u32, time: Option<f32x8>, arena: &mut CsgArena) -> u32 {
    if refused == 0 {
        return 0;
    }
    let mut r = [Ray8 { tmax: mask_from_bits(refused).select(ray.tmax, f32x8::splat(-1.0)), ..*ray }];
    occlusion_group(scene, profile, &mut r, &[time], arena, false).0[0].to_bitmask()
}

/// The scene (its address, its prims' and light buffers' addresses, its number of lights; its file
/// hash) and the profile's light sampling (samples, strategy, spp) that [`LightTables`] were made for.
type TablesKey = ([usize; 4], u64, (u32, Strategy, u32));

/// Per light, what the shadow stage works out once per scene and light sampling rather than per call
/// (a call per wavefront: at 90,000 lamps, remaking these per call took more time than the picked
/// lights' shadow rays, and each quad light's cone searched every prim for the light's own).
struct LightTables {
    /// What they were made for ([`TablesKey`]).
    key: TablesKey,
    /// A grid's sample `j` in the light square: the same for every shading point (no key, no
    /// permutation), so made once (grid strategy, unless across samples).
    grid: Vec<[f32x8; 2]>,
    /// Per area light, its points and shadow-ray targets of those samples.
    grid_points: Vec<Vec<(Vec3x8, Vec3x8)>>,
    /// Per quad or disk light: its unit normal and radiance x area / samples.
    flat_light: Vec<(Vec3, Vec3)>,
    /// Per light, its light-cone data where its samples are many enough ([`cone_min_samples`]).
    cones: Vec<Option<LightCone>>,
    any_cone: bool,
    /// Whether any light has a light buffer (used where shadow rays walk through nothing).
    buffers: bool,
    /// Whether any light draws samples (needs stream keys).
    keyed: bool,
}

impl LightTables {
    /// The thread's tables for `scene` and `profile`'s light sampling, made again when the key changes.
    /// (A render's workers are new threads: each render makes its own. A thread that calls the stages
    /// itself must not edit a scene's lights in place between calls: the key would not see it.)
    fn get(scene: &Scene, profile: &Profile, across: bool, area: &Sampler2d) -> std::rc::Rc<LightTables> {
        let key = (
            [scene as *const Scene as usize, scene.prims.as_ptr() as usize, scene.light_buffers.as_ptr() as usize, scene.lights.len()],
            scene.hash,
            (profile.light_samples, profile.light_strategy, profile.spp),
        );
        TABLES.with_borrow_mut(|t| match t {
            Some(t) if t.key == key => t.clone(),
            _ => {
                let made = std::rc::Rc::new(LightTables::new(key, scene, profile, across, area));
                *t = Some(made.clone());
                made
            }
        })
    }

    fn new(key: TablesKey, scene: &Scene, profile: &Profile, across: bool, area: &Sampler2d) -> Self {
        let grid: Vec<[f32x8; 2]> = if profile.light_strategy == Strategy::Grid && !across {
            (0..profile.light_samples).map(|j| area.sample_x8_call(&[0; LANES], &[j; LANES], false)).collect()
        } else {
            Vec::new()
        };
        let grid_points = scene.lights.iter().map(|light| grid.iter().map_while(|&u| light_points_x8(light, u)).collect()).collect();
        let flat_light = scene
            .lights
            .iter()
            .map(|light| match *light {
                Light::Quad { quad, radiance } => {
                    (quad.normal(), radiance * (quad.area() / samples_for(light, profile.light_samples) as f32))
                }
                Light::Disk { disk, radiance } => (
                    disk.normal,
                    radiance * (std::f32::consts::PI * disk.radius * disk.radius / samples_for(light, profile.light_samples) as f32),
                ),
                _ => (Vec3::ZERO, Vec3::ZERO),
            })
            .collect();
        // Each area light's prim, from the scene's map of prims to lights (the cone checks it).
        let mut prim_of = vec![usize::MAX; scene.lights.len()];
        for (pid, &li) in scene.light_of_prim.iter().enumerate().filter(|(_, &li)| li != NOT_A_LIGHT) {
            prim_of[li as usize] = pid;
        }
        let cones: Vec<Option<LightCone>> = scene
            .lights
            .iter()
            .zip(&prim_of)
            .map(|(light, &pid)| {
                (samples_for(light, profile.light_samples) >= cone_min_samples(scene))
                    .then(|| LightCone::new_near(scene, light, pid))
                    .flatten()
            })
            .collect();
        LightTables {
            key,
            grid,
            grid_points,
            flat_light,
            any_cone: cones.iter().any(Option::is_some),
            cones,
            buffers: scene.light_buffers.iter().any(Option::is_some),
            keyed: scene.lights.iter().any(|l| !l.is_point()),
        }
    }
}

thread_local! {
    /// Each thread's light tables for its last scene and light sampling ([`LightTables::get`]).
    static TABLES: std::cell::RefCell<Option<std::rc::Rc<LightTables>>> = const { std::cell::RefCell::new(None) };
    /// Each thread's shadow batches, kept between calls of [`shadow_with`].
    static BATCHES: std::cell::Cell<Vec<Box<Batch>>> = const { std::cell::Cell::new(Vec::new()) };
    /// Each thread's sorted copies of its NEE queues where requests pick their light.
    static PICKED: std::cell::Cell<Option<Box<Picked>>> = const { std::cell::Cell::new(None) };
}

/// Lights up to which the shadow stage keeps one batch per light (more share one batch).
const MAX_LIGHT_BATCHES: usize = 4;

/// [`flush`] every non-empty batch of `batches`, in order (a light's batch after every lower light's).
#[allow(clippy::too_many_arguments)]
fn flush_upto(
    scene: &Scene,
    profile: &Profile,
    batches: &mut [Box<Batch>],
    credit: &mut Credit,
    media: &[MediumStack],
    arena: &mut CsgArena,
    walk: bool,
    mut single: Option<&mut WideStack>,
) -> u64 {
    let mut traced = 0;
    for pk in batches.iter_mut().filter(|b| b.len > 0) {
        traced += flush(scene, profile, pk, credit, media, arena, walk, single.as_deref_mut());
    }
    traced
}

/// Trace the batch's shadow rays (any hit, as one traversal group, or one ray at a time when `single`
/// holds a stack: [`occlusion_single`]) and credit the unoccluded ones, times their transmittance where
/// they met dielectrics they walk through or start inside media (`media`, by request: [`NeeQueue::media`]).
/// Returns rays traced (walk segments included).
#[allow(clippy::too_many_arguments)]
fn flush(
    scene: &Scene,
    profile: &Profile,
    pk: &mut Batch,
    credit: &mut Credit,
    media: &[MediumStack],
    arena: &mut CsgArena,
    walk: bool,
    single: Option<&mut WideStack>,
) -> u64 {
    let n = pk.len;
    pk.tmax[n..].fill(-1.0);
    let k = n.div_ceil(LANES);
    let motion = scene.features.motion;
    let mut rays = [Ray8::new(Vec3x8::splat(Vec3::ZERO), Vec3x8::splat(Vec3::ONE), f32x8::splat(-1.0)); GROUP];
    let mut times = [None; GROUP];
    for j in 0..k {
        pk.load_packet(j, &mut rays[j]);
        if motion {
            times[j] = Some(load8(&pk.time, j * LANES));
        }
    }
    let (occluded, touched) = if let Some(stack) = single {
        (occlusion_single(scene, profile, &rays[..k], &times, arena, stack), [0; GROUP])
    } else {
        occlusion_group(scene, profile, &mut rays[..k], &times, arena, walk)
    };
    let mut walked = 0;
    for j in 0..k {
        let lanes = (n - j * LANES).min(LANES);
        let r = j * LANES..j * LANES + LANES;
        let bits = occluded[j].to_bitmask();
        // The media each lane starts in (none, unless some request of the queue lies inside one).
        let mut start = [MediumStack::default(); LANES];
        if !media.is_empty() {
            for (l, s) in start.iter_mut().enumerate().take(lanes) {
                *s = media[pk.req[j * LANES + l] as usize];
            }
        }
        let live = !bits & ((1u32 << lanes) - 1);
        // Lanes that met surfaces they walk through are walked; lanes inside media that met none (the
        // traversal found nothing on them) are only absorbed by their medium along the segment.
        let through = touched[j] & live;
        let absorbed = live & !touched[j] & lane_bits(|l| !start[l].is_empty());
        let arr = |a: &[f32; BATCH]| <[f32; LANES]>::try_from(&a[r.clone()]).unwrap();
        let mut tr = if through != 0 {
            let (o, d) = ([0, 1, 2].map(|a| arr(&pk.o[a])), [0, 1, 2].map(|a| arr(&pk.d[a])));
            let (tr, w) = transmittance_x8(
                scene,
                profile,
                &o,
                &d,
                &arr(&pk.tmax),
                &arr(&pk.time),
                &start,
                through,
                arena,
                pk.walk.get_or_insert_with(Walk::new),
            );
            walked += w;
            tr
        } else {
            [Vec3::ONE; LANES]
        };
        let mut bits_in = absorbed;
        while bits_in != 0 {
            let l = bits_in.trailing_zeros() as usize;
            bits_in &= bits_in - 1;
            let q = j * LANES + l;
            let len = (Vec3::new(pk.d[0][q], pk.d[1][q], pk.d[2][q]) * pk.tmax[q]).length();
            tr[l] = super::medium::absorption(scene, start[l], len);
        }
        // Unoccluded lanes credit their requests (times their transmittance where walked or absorbed).
        credit.add_packet(pk, j, live, through | absorbed, &tr);
    }
    pk.len = 0;
    n as u64 + walked
}

/// Whether every surface of a prim stops shadow rays (a CSG solid: every leaf's).
fn opaque_prim(scene: &Scene, profile: &Profile, pid: u32) -> bool {
    let prim = &scene.prims[pid as usize];
    match prim.shape {
        Shape::Csg { solid } => scene.csg.solid_leaves(solid).all(|l| blocks(scene, profile, scene.csg.leaf(l).material)),
        _ => blocks(scene, profile, prim.material),
    }
}

/// Whether a primitive stops shadow rays (else the shadow ray walks through it: `transmit.rs`).
#[inline(always)]
fn blocks(scene: &Scene, profile: &Profile, material: u32) -> bool {
    !passes(scene, profile, material)
}

/// Any-hit occlusion of 8 shadow rays over (0, tmax). Returns the occluded lanes as a mask.
pub fn occluded_x8(scene: &Scene, profile: &Profile, ray: &Ray8, time: Option<f32x8>, arena: &mut CsgArena) -> f32x8 {
    occlusion_x8(scene, profile, ray, time, arena, any_passable(scene, profile)).0
}

/// [`occluded_x8`], and as bits the lanes that met a dielectric shadow rays walk through (whose
/// transmittance is then needed). `walk`: [`any_passable`] of this scene and profile.
pub fn occlusion_x8(scene: &Scene, profile: &Profile, ray: &Ray8, time: Option<f32x8>, arena: &mut CsgArena, walk: bool) -> (f32x8, u32) {
    let (occ, touched) = occlusion_group(scene, profile, &mut [*ray], &[time], arena, walk);
    (occ[0], touched[0])
}

/// Any-hit occlusion of up to [`GROUP`] packets of shadow rays, traversed together: per packet, the
/// occluded mask and the walk-through bits of [`occlusion_x8`]. The packets' `tmax` are clobbered.
pub fn occlusion_group(
    scene: &Scene,
    profile: &Profile,
    rays: &mut [Ray8],
    times: &[Option<f32x8>],
    arena: &mut CsgArena,
    walk: bool,
) -> ([f32x8; GROUP], [u32; GROUP]) {
    let zero = f32x8::ZERO;
    let none = zero.simd_gt(f32x8::ONE); // all false
    let mut touched = [0u32; GROUP];
    let mut occ = [none; GROUP];
    let k = rays.len();
    for j in 0..k {
        for &pid in &scene.unbounded {
            let prim = &scene.prims[pid as usize];
            let hit = prim_t_x8(prim, &rays[j]).simd_lt(rays[j].tmax);
            if blocks(scene, profile, prim.material) {
                occ[j] |= hit;
            } else {
                touched[j] |= hit.to_bitmask();
            }
        }
        // Lanes the planes already occlude take no part in the traversal.
        rays[j].tmax = occ[j].select(f32x8::splat(-1.0), rays[j].tmax);
    }
    let mut pk = [SpherePacket::new(&rays[0]); GROUP];
    for j in 1..k {
        pk[j] = SpherePacket::new(&rays[j]);
    }
    // Where no surface lets shadow rays through, a static sphere's terms come from the slot-ordered
    // `LeafSpheres` lanes, read in leaf order (no lookups of `indices`, `bounded` and its record: cache
    // misses in scenes larger than the caches); any other prim by its id.
    let ls = &scene.leaf_spheres;
    let from_bvh = scene.bvh.traverse_any_group(rays, |slot, j, ray| {
        let at = slot as usize;
        if !walk && ls.window[at] & 1 != 0 {
            let (c, consts) = ls.sphere(at);
            return occludes_sphere_consts([ray.o.x, ray.o.y, ray.o.z], [ray.d.x, ray.d.y, ray.d.z], ray.tmax, c, consts, &pk[j]);
        }
        prim_occlusion_with(scene, profile, ls.prim[at], ray, Some(&pk[j]), times[j], arena, walk, &mut touched[j])
    });
    for j in 0..k {
        occ[j] |= from_bvh[j];
    }
    (occ, touched)
}

/// [`occlusion_group`] for scenes whose shadow rays walk through nothing (`!any_passable`), one ray at
/// a time through the wide BVH (`WideBvh::occluded_lanes`): incoherent packets (shading points scattered
/// by bounces) share few nodes and leaves, so a packet's leaf tests would mostly test lanes that never
/// reach the leaf. A leaf's static spheres meet the ray in one 8-lane call (spheres in lanes, the
/// any-hit twin [`occludes_spheres_lanes`]: the verdict of the packet kernel per ray and sphere), its other prims
/// the packet test with the ray in every lane. The same occluded lanes as [`occlusion_group`].
pub fn occlusion_single(
    scene: &Scene,
    profile: &Profile,
    rays: &[Ray8],
    times: &[Option<f32x8>],
    arena: &mut CsgArena,
    stack: &mut WideStack,
) -> [f32x8; GROUP] {
    let none = f32x8::ZERO.simd_gt(f32x8::ONE); // all false
    let mut occ = [none; GROUP];
    let ls = &scene.leaf_spheres;
    let idx = &scene.wide_bvh.indices;
    for (j, ray) in rays.iter().enumerate() {
        let mut touched = 0;
        for &pid in &scene.unbounded {
            occ[j] |= prim_occlusion(scene, profile, pid, ray, times[j], arena, false, &mut touched);
        }
        let lanes = !occ[j].to_bitmask() & ray.tmax.simd_gt(f32x8::ZERO).to_bitmask();
        let (o, d, tm) = (ray.o, ray.d, ray.tmax.to_array());
        let time = times[j].map(|t| t.to_array());
        // The sphere twin's packet terms of each lane's ray in all 8 lanes: lane l of `pk`, splatted.
        let pk = SpherePacket::new(ray);
        let bits = scene.wide_bvh.occluded_lanes_hybrid(ray, lanes, stack, |l, first, count| {
            // The lane's ray in all 8 lanes (its inverse direction as the packet computed it).
            let one = &Ray8 {
                o: Vec3x8::splat(o.lane(l)),
                d: Vec3x8::splat(d.lane(l)),
                inv_d: Vec3x8::splat(ray.inv_d.lane(l)),
                tmax: f32x8::splat(tm[l]),
            };
            // Leaves of more than 8 prims (identical centroids) in chunks of 8 slots.
            let end = first + count;
            let mut first = first;
            while first < end {
                let n = (end - first).min(LANES);
                let sph = ls.sphere_bits(first, n);
                if sph != 0 {
                    let c = [load8(&ls.cx, first), load8(&ls.cy, first), load8(&ls.cz, first)];
                    let k = [load8(&ls.r2, first), load8(&ls.r2_lo, first), load8(&ls.graze, first)];
                    let (ov, dv) = ([one.o.x, one.o.y, one.o.z], [one.d.x, one.d.y, one.d.z]);
                    if occludes_spheres_lanes(ov, dv, one.tmax, c, k, &pk.lane(l)).to_bitmask() & sph != 0 {
                        return true;
                    }
                }
                let mut rest = !sph & ((1u32 << n) - 1);
                while rest != 0 {
                    let k = rest.trailing_zeros() as usize;
                    rest &= rest - 1;
                    let pid = scene.bounded[idx[first + k] as usize];
                    let t1 = time.map(|t| f32x8::splat(t[l]));
                    if prim_occlusion(scene, profile, pid, one, t1, arena, false, &mut touched).to_bitmask() & 1 != 0 {
                        return true;
                    }
                }
                first += n;
            }
            false
        });
        debug_assert_eq!(touched, 0, "no surface lets shadow rays through");
        occ[j] |= mask_from_bits(bits);
    }
    occ
}

/// Any-hit occlusion of the lanes `lanes` of `ray`, shadow rays towards the centre of light buffer
/// `lb` (`ray.d` = centre - `ray.o`, `tmax` their end), in scenes whose shadow rays walk through
/// nothing: `(occluded, answered)`. Planes first, then the buffer's `always` list, then each lane's
/// cell, nearest entries first and only those within the ray's reach. Lanes sharing a cell take its
/// list together; every prim is tested with all lanes still pending (the leaf test of the traversal,
/// [`prim_occlusion`]), so a lane is occluded exactly when the traversal would find it occluded: the
/// cell lists hold every prim a lane's ray can meet (`accel/light_buffer.rs`). Lanes the buffer refuses
/// (see [`LightBuffer::cells_x8`]) are not answered; the caller traces them.
///
/// `own[l]`: a static sphere lane `l`'s ray leaves outward from a point on or outside it
/// ([`NONE`](super::queues::NONE) for none), which it therefore cannot meet (spheres are convex): not tested for that lane. (The
/// kernel agrees: `tests/light_buffer.rs` holds it to a miss for such rays at scales 1e-4 to 1e5.)
#[allow(clippy::too_many_arguments)]
pub fn occlusion_light_buffer(
    scene: &Scene,
    profile: &Profile,
    lb: &LightBuffer,
    ray: &Ray8,
    lanes: u32,
    own: &[u32; LANES],
    time: Option<f32x8>,
    arena: &mut CsgArena,
) -> (u32, u32) {
    query_light_buffer::<f32x8>(scene, profile, lb, std::slice::from_ref(ray), lanes, own, time.map(|t| [t; 2]), arena)
}

/// [`occlusion_light_buffer`] of two packets at once, as 16 lanes (lane `8 h + l` = lane `l` of
/// `rays[h]`; `lanes`, `own`, the results likewise): cells looked up, lists walked and spheres tested
/// for all 16 lanes together (`f32x16`: one AVX-512 register, so on such targets a pair costs about
/// what one packet does); other prims by packet. Each lane's verdict is the one-packet query's.
#[allow(clippy::too_many_arguments)]
pub fn occlusion_light_buffer_x16(
    scene: &Scene,
    profile: &Profile,
    lb: &LightBuffer,
    rays: &[Ray8; 2],
    lanes: u32,
    own: &[u32; 2 * LANES],
    time: Option<[f32x8; 2]>,
    arena: &mut CsgArena,
) -> (u32, u32) {
    query_light_buffer::<f32x16>(scene, profile, lb, rays, lanes, own, time, arena)
}

/// Whether the shadow stage pairs packets for the light buffer: where `f32x16` is one register. (On
/// AVX2 a pair costs two packets' work, and pairing scattered packets measured 3% slower.) Public for
/// the criterion row that times what the stage does.
pub const PAIR_PACKETS: bool = cfg!(target_feature = "avx512f");

/// A lane type of the light-buffer query: one packet of 8 rays (`f32x8`) or two (`f32x16`), with
/// the integer lanes (`U`) of its cells and own spheres.
trait PacketLanes: Lanes {
    /// Packets per vector.
    const PACKETS: usize;
    type U: Copy;
    /// The vector of the packets' lanes `p` (`PACKETS` of them), packet `h` in lanes `8 h..8 h + 8`.
    fn cat(p: &[f32x8]) -> Self;
    /// Packet `h`'s lanes.
    fn half(self, h: usize) -> f32x8;
    /// The mask set in the lanes whose bit is set in `bits`.
    fn from_bits(bits: u32) -> Self;
    /// The integer vector of the packets' lanes `p`.
    fn cat_u(p: &[u32x8]) -> Self::U;
    /// The integer vector of `v[..8 * PACKETS]`.
    fn load_u(v: &[u32]) -> Self::U;
    /// The lanes of `u` equal to `c`, as bits.
    fn eq_bits(u: Self::U, c: u32) -> u32;
}

impl PacketLanes for f32x8 {
    const PACKETS: usize = 1;
    type U = u32x8;
    #[inline(always)]
    fn cat(p: &[f32x8]) -> Self {
        p[0]
    }
    #[inline(always)]
    fn half(self, _: usize) -> f32x8 {
        self
    }
    #[inline(always)]
    fn from_bits(bits: u32) -> Self {
        mask_from_bits(bits)
    }
    #[inline(always)]
    fn cat_u(p: &[u32x8]) -> u32x8 {
        p[0]
    }
    #[inline(always)]
    fn load_u(v: &[u32]) -> u32x8 {
        u32x8::from(<[u32; 8]>::try_from(&v[..8]).unwrap())
    }
    #[inline(always)]
    fn eq_bits(u: u32x8, c: u32) -> u32 {
        u.simd_eq(u32x8::splat(c)).to_bitmask()
    }
}

impl PacketLanes for f32x16 {
    const PACKETS: usize = 2;
    type U = u32x16;
    // (Vectors of two packets are built in registers: two 8-lane stores read back as one vector
    // would stall.)
    #[inline(always)]
    fn cat(p: &[f32x8]) -> Self {
        bytemuck::cast([p[0], p[1]])
    }
    #[inline(always)]
    fn half(self, h: usize) -> f32x8 {
        bytemuck::cast::<f32x16, [f32x8; 2]>(self)[h]
    }
    #[inline(always)]
    fn from_bits(bits: u32) -> Self {
        let lane = i32x16::from(std::array::from_fn::<i32, 16, _>(|l| 1 << l));
        bytemuck::cast((i32x16::splat(bits as i32) & lane).simd_eq(lane))
    }
    #[inline(always)]
    fn cat_u(p: &[u32x8]) -> u32x16 {
        bytemuck::cast([p[0], p[1]])
    }
    #[inline(always)]
    fn load_u(v: &[u32]) -> u32x16 {
        u32x16::from(<[u32; 16]>::try_from(&v[..16]).unwrap())
    }
    #[inline(always)]
    fn eq_bits(u: u32x16, c: u32) -> u32 {
        u.simd_eq(u32x16::splat(c)).to_bitmask()
    }
}

/// The light-buffer query of `F::PACKETS` packets `rays` as one vector of lanes (see
/// [`occlusion_light_buffer`]; `lanes`, `own` and the results by lane, packet `h` in lanes
/// `8 h..8 h + 8`; `time` per packet).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn query_light_buffer<F: PacketLanes>(
    scene: &Scene,
    profile: &Profile,
    lb: &LightBuffer,
    rays: &[Ray8],
    lanes: u32,
    own: &[u32],
    time: Option<[f32x8; 2]>,
    arena: &mut CsgArena,
) -> (u32, u32) {
    let rays = &rays[..F::PACKETS];
    let mut per = [u32x8::ZERO; 2];
    for (h, r) in rays.iter().enumerate() {
        per[h] = lb.cells_v8(Vec3x8::new(-r.d.x, -r.d.y, -r.d.z));
    }
    let cell_v = F::cat_u(&per[..F::PACKETS]);
    let cells: [u32; 2 * LANES] = bytemuck::cast(per);
    let answered = lanes & !F::eq_bits(cell_v, NO_CELL);
    if answered == 0 {
        return (0, 0);
    }
    let o = [by_lane::<F>(rays, |r| r.o.x), by_lane(rays, |r| r.o.y), by_lane(rays, |r| r.o.z)];
    let d = [by_lane::<F>(rays, |r| r.d.x), by_lane(rays, |r| r.d.y), by_lane(rays, |r| r.d.z)];
    let mut q = Query {
        scene,
        profile,
        rays,
        o,
        d,
        tmax: F::from_bits(answered).select(by_lane(rays, |r| r.tmax), F::splat(-1.0)),
        pk: SpherePacketOf::of(o, d),
        time,
        pending: answered,
    };
    for &pid in scene.unbounded.iter().chain(lb.always()) {
        if !q.test(pid, arena) {
            return (answered, answered);
        }
    }
    let own_v = F::load_u(own);
    // Each lane's reach (its squared length, with room for the rounding of the lengths).
    let reach = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) * F::splat(1.0 + 4e-6);
    let mut todo = q.pending;
    while todo != 0 {
        let c = cells[todo.trailing_zeros() as usize];
        let same = todo & F::eq_bits(cell_v, c);
        todo &= !same;
        for &(n2, pid) in lb.cell(c) {
            // The list is by nearest distance: done once it lies beyond every pending lane of the cell.
            let live = q.pending & same;
            if F::splat(n2).gt(reach).bits() & live == live {
                break;
            }
            let mine = F::eq_bits(own_v, pid) & q.pending;
            if mine == 0 {
                if !q.test(pid, arena) {
                    return (answered, answered);
                }
            } else if mine != q.pending {
                // The lanes on this sphere skip it; the others test it.
                let keep = q.tmax;
                q.pending &= !mine;
                q.tmax = F::from_bits(q.pending).select(q.tmax, F::splat(-1.0));
                q.test(pid, arena);
                q.pending |= mine;
                q.tmax = F::from_bits(mine).select(keep, q.tmax);
            }
            if q.pending & same == 0 {
                break;
            }
        }
    }
    (answered & !q.pending, answered)
}

/// One field `f` of the packets `rays` (`F::PACKETS` of them) as one vector.
#[inline(always)]
fn by_lane<F: PacketLanes>(rays: &[Ray8], f: impl Fn(&Ray8) -> f32x8) -> F {
    let mut p = [f32x8::ZERO; 2];
    for (h, r) in rays.iter().enumerate() {
        p[h] = f(r);
    }
    F::cat(&p[..F::PACKETS])
}

/// The state of one [`query_light_buffer`]: the rays by axis, their `tmax` (-1 in lanes no longer
/// pending), the sphere terms, and the pending lanes.
struct Query<'a, F> {
    scene: &'a Scene,
    profile: &'a Profile,
    rays: &'a [Ray8],
    o: [F; 3],
    d: [F; 3],
    tmax: F,
    pk: SpherePacketOf<F>,
    time: Option<[f32x8; 2]>,
    pending: u32,
}

impl<F: PacketLanes> Query<'_, F> {
    /// Prim `pid` against the pending lanes: occluded lanes leave `pending` (and `tmax = -1`). False
    /// when no lane is left. Static spheres in all lanes at once; other prims by packet, as the
    /// traversal's leaf test ([`prim_occlusion`]).
    #[inline(always)]
    fn test(&mut self, pid: u32, arena: &mut CsgArena) -> bool {
        let (scene, profile) = (self.scene, self.profile);
        let g = &scene.prim_geo[pid as usize];
        let fixed = (self.time.is_none() || g.motion == Vec3::ZERO) && blocks(scene, profile, g.material);
        let occ = if g.r > 0.0 && fixed {
            occludes_sphere(self.o, self.d, self.tmax, g.v, g.r, &self.pk).bits()
        } else if let (true, Shape::Plane(p)) = (fixed && g.r < 0.0, &scene.prims[pid as usize].shape) {
            // Unbounded planes (met by every packet): all lanes at once, as spheres.
            occludes_plane(self.o, self.d, self.tmax, p, self.pk.finite()).bits()
        } else {
            other_prim_occlusion(scene, profile, pid, self.rays, self.tmax, self.pending, self.time, arena)
        } & self.pending;
        if occ != 0 {
            self.pending &= !occ;
            self.tmax = F::from_bits(self.pending).select(self.tmax, F::splat(-1.0));
        }
        self.pending != 0
    }
}

/// [`Query::test`] of a prim other than a static sphere or plane, packet by packet as the traversal's
/// leaf test: out of line, so that the query's hot path keeps a small frame.
#[allow(clippy::too_many_arguments)]
#[cold]
#[inline(never)]
fn other_prim_occlusion<F: PacketLanes>(
    scene: &Scene,
    profile: &Profile,
    pid: u32,
    rays: &[Ray8],
    tmax: F,
    pending: u32,
    time: Option<[f32x8; 2]>,
    arena: &mut CsgArena,
) -> u32 {
    let mut occ = 0;
    for (h, ray) in rays.iter().enumerate() {
        if (pending >> (LANES * h)) & 0xff != 0 {
            let r = Ray8 { tmax: tmax.half(h), ..*ray };
            let mut touched = 0;
            let hit = prim_occlusion_with(scene, profile, pid, &r, None, time.map(|t| t[h]), arena, false, &mut touched);
            debug_assert_eq!(touched, 0, "no surface lets shadow rays through");
            occ |= hit.to_bitmask() << (LANES * h);
        }
    }
    occ
}

/// Any-hit test of 8 shadow rays against one prim (the traversal's leaf callback): the occluded lanes,
/// and into `touched` the lanes that met a surface they walk through.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub fn prim_occlusion(
    scene: &Scene,
    profile: &Profile,
    pid: u32,
    ray: &Ray8,
    time: Option<f32x8>,
    arena: &mut CsgArena,
    walk: bool,
    touched: &mut u32,
) -> f32x8 {
    prim_occlusion_with(scene, profile, pid, ray, None, time, arena, walk, touched)
}

/// [`prim_occlusion`]; `pk`: the packet's sphere terms, when the caller tests many prims against it.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn prim_occlusion_with(
    scene: &Scene,
    profile: &Profile,
    pid: u32,
    ray: &Ray8,
    pk: Option<&SpherePacket>,
    time: Option<f32x8>,
    arena: &mut CsgArena,
    walk: bool,
    touched: &mut u32,
) -> f32x8 {
    let zero = f32x8::ZERO;
    let none = zero.simd_gt(f32x8::ONE); // all false
                                         // Static spheres that stop shadow rays (the common case) from their 32-byte record.
    let g = &scene.prim_geo[pid as usize];
    if g.r > 0.0 && (time.is_none() || g.motion == Vec3::ZERO) && blocks(scene, profile, g.material) {
        let pk = pk.copied().unwrap_or_else(|| SpherePacket::new(ray));
        return occludes_sphere_x8(g.v, g.r, ray, &pk);
    }
    let prim = &scene.prims[pid as usize];
    match prim.shape {
        Shape::Csg { solid } => {
            // Lanes that reach the solid's bounds are solved together by the 8-lane interval merge.
            let b = &scene.bounds[pid as usize];
            let (_, mask) = intersect_aabb_x8(b.min, b.max, &PacketRay::new(ray), ray.tmax);
            if mask.to_bitmask() == 0 {
                return none;
            }
            let local = in_prim_frame(ray, prim.motion, time);
            let masked = Ray8 { tmax: mask.select(ray.tmax, f32x8::splat(-1.0)), ..local };
            if walk && scene.csg.solid_leaves(solid).all(|l| passes(scene, profile, scene.csg.leaf(l).material)) {
                // Every surface lets shadow rays through: the solid occludes no lane, and the walk finds
                // the crossings of the lanes that may have some (none at all: transmittance 1 exactly).
                *touched |= lanes_may_cross_x8(&scene.csg, solid, &masked, zero, arena);
                return none;
            }
            let mut out = [None; LANES];
            first_hit_x8(&scene.csg, solid, &masked, zero, arena, &mut out);
            let mut hit = [0.0f32; LANES];
            for (l, h) in out.iter().enumerate() {
                if let Some(h) = h {
                    if blocks(scene, profile, scene.csg.leaf(h.leaf).material) {
                        hit[l] = f32::from_bits(u32::MAX);
                    } else {
                        // A first boundary that lets the ray through: the walk sees the rest of the solid.
                        *touched |= 1 << l;
                    }
                }
            }
            f32x8::from(hit)
        }
        _ => {
            let t = || prim_t_at_x8(prim, ray, time);
            if !blocks(scene, profile, prim.material) {
                if walk {
                    *touched |= t().simd_lt(ray.tmax).to_bitmask();
                }
                return none;
            }
            t().simd_lt(ray.tmax)
        }
    }
}
