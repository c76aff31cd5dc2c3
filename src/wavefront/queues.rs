//! Structure-of-arrays work queues. One plain struct per kind of work item; every field is its own
//! `Vec`, lengths padded to the lane width so kernels never branch on a tail (padding lanes carry
//! `tmax = -1`, which no kernel hits). Queues are cleared, never freed: a wavefront reuses them for the
//! next tile, so after warm-up nothing allocates.

use crate::accel::WideStack;
use crate::simd::{pad_to_lanes, LANES};
use glam::Vec3;

/// Ray flag: the ray left a specular or glossy surface (emission it finds counts).
pub const FLAG_SPECULAR: u8 = 1;
/// Ray flag: the ray left a diffuse surface by a bounce (emission of sampled lights does not count).
pub const FLAG_DIFFUSE: u8 = 2;
/// Ray flag: the ray is a glossy lobe sample (with [`FLAG_SPECULAR`]); the emission of a sampled light
/// it finds is weighted against next-event estimation by multiple importance sampling, from its `pdf`.
pub const FLAG_GLOSSY: u8 = 4;

/// The media a ray is inside, innermost last: up to 4 material ids + 1 (0 = empty slot) in a `u64`.
/// Glass inside water inside glass is three entries; a fifth nested medium is dropped (documented limit).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MediumStack(pub u64);

impl MediumStack {
    pub const DEPTH: usize = 4;
    /// Whether the ray is in no medium (air).
    #[inline(always)]
    pub fn is_empty(self) -> bool {
        self.0 == 0
    }
    /// Innermost medium's material id, if any.
    #[inline]
    pub fn top(self) -> Option<u32> {
        (0..Self::DEPTH).rev().map(|i| ((self.0 >> (16 * i)) & 0xffff) as u32).find(|&v| v != 0).map(|v| v - 1)
    }
    /// Material ids, outermost (entered first) to innermost.
    #[inline]
    pub fn iter(self) -> impl Iterator<Item = u32> {
        (0..Self::DEPTH).map(move |i| ((self.0 >> (16 * i)) & 0xffff) as u32).filter(|&v| v != 0).map(|v| v - 1)
    }
    #[inline]
    pub fn contains(self, m: u32) -> bool {
        (0..Self::DEPTH).any(|i| ((self.0 >> (16 * i)) & 0xffff) as u32 == m + 1)
    }
    /// Whether every slot is taken (a further `push` is dropped).
    #[inline]
    pub fn is_full(self) -> bool {
        self.0 >> (16 * (Self::DEPTH - 1)) != 0
    }
    /// Enter medium `m` (no-op when full).
    #[inline]
    pub fn push(self, m: u32) -> Self {
        for i in 0..Self::DEPTH {
            if (self.0 >> (16 * i)) & 0xffff == 0 {
                return MediumStack(self.0 | ((m as u64 + 1) << (16 * i)));
            }
        }
        self
    }
    /// Leave medium `m`: remove its innermost entry, closing the gap.
    #[inline]
    pub fn remove(self, m: u32) -> Self {
        let mut slots = [0u64; Self::DEPTH];
        for (i, s) in slots.iter_mut().enumerate() {
            *s = (self.0 >> (16 * i)) & 0xffff;
        }
        if let Some(k) = (0..Self::DEPTH).rev().find(|&i| slots[i] == m as u64 + 1) {
            let mut out = 0u64;
            let mut j = 0;
            for (i, &s) in slots.iter().enumerate() {
                if i != k && s != 0 {
                    out |= s << (16 * j);
                    j += 1;
                }
            }
            return MediumStack(out);
        }
        self
    }
}

/// Append `n` (<= [`LANES`]) copies of `x`: all 8 stored (a fixed-size copy, inlined stores), then the
/// length cut to `n` more. A partial packet's `n` elements alone were a call to memset per column;
/// storing 8 and truncating (a length write: `T` is `Copy`) measured 2% faster on peer (b) and the
/// showcase (session 50, `benches/ab.py`: shade 0.94-0.97x, generate 0.94-0.96x, images identical).
#[inline(always)]
fn fill<T: Copy>(v: &mut Vec<T>, x: T, n: usize) {
    let len = v.len();
    v.extend_from_slice(&[x; LANES]);
    v.truncate(len + n);
}

/// Append the first `n` (<= [`LANES`]) of the 8 values `s`: all 8 copied, then the length cut (as
/// [`fill`]; a partial packet was a call to memcpy per column).
#[inline(always)]
fn put<T: Copy>(v: &mut Vec<T>, s: &[T; LANES], n: usize) {
    let len = v.len();
    v.extend_from_slice(s);
    v.truncate(len + n);
}

/// One ray, array-of-structs form: for building queues and for tests.
#[derive(Clone, Copy, Debug, Default)]
pub struct RayItem {
    pub o: Vec3,
    pub d: Vec3,
    pub tmax: f32,
    pub time: f32,
    pub lambda: f32,
    pub throughput: Vec3,
    /// Index of the camera path (in the wavefront's [`PathTable`]) this ray belongs to.
    pub path: u32,
    /// Which branch of the path tree (0 for the main path): keys decorrelated random numbers.
    pub branch: u32,
    pub depth: u16,
    pub diffuse: u16,
    pub flags: u8,
    pub media: MediumStack,
    /// Solid-angle density its direction was sampled with ([`FLAG_GLOSSY`] rays; kept only by queues
    /// that carry it).
    pub pdf: f32,
    /// Distance from the glossy point its direction was sampled at to its origin (0, or what it has
    /// crossed unbent since: a light it finds is that much farther than from `o`; with `pdf`).
    pub travel: f32,
}

/// Up to 8 new rays (all with `tmax = inf`) as lane arrays, for [`RayQueue::push_rows`].
#[derive(Clone, Copy, Default)]
pub struct RayRows {
    pub o: [[f32; LANES]; 3],
    pub d: [[f32; LANES]; 3],
    pub time: [f32; LANES],
    pub lambda: [f32; LANES],
    pub throughput: [[f32; LANES]; 3],
    pub path: [u32; LANES],
    pub branch: [u32; LANES],
    pub depth: [u16; LANES],
    pub diffuse: [u16; LANES],
    pub flags: [u8; LANES],
    pub media: [MediumStack; LANES],
    pub pdf: [f32; LANES],
    pub travel: [f32; LANES],
}

impl RayRows {
    /// Lane `l` as one ray (`tmax = inf`, as [`RayQueue::push_rows`] stores it).
    #[inline(always)]
    pub fn item(&self, l: usize) -> RayItem {
        RayItem {
            o: Vec3::new(self.o[0][l], self.o[1][l], self.o[2][l]),
            d: Vec3::new(self.d[0][l], self.d[1][l], self.d[2][l]),
            tmax: f32::INFINITY,
            time: self.time[l],
            lambda: self.lambda[l],
            throughput: Vec3::new(self.throughput[0][l], self.throughput[1][l], self.throughput[2][l]),
            path: self.path[l],
            branch: self.branch[l],
            depth: self.depth[l],
            diffuse: self.diffuse[l],
            flags: self.flags[l],
            media: self.media[l],
            pdf: self.pdf[l],
            travel: self.travel[l],
        }
    }
}

/// Rays in flight (camera rays, or the secondary rays of one bounce).
#[derive(Default)]
pub struct RayQueue {
    pub ox: Vec<f32>,
    pub oy: Vec<f32>,
    pub oz: Vec<f32>,
    pub dx: Vec<f32>,
    pub dy: Vec<f32>,
    pub dz: Vec<f32>,
    pub tmax: Vec<f32>,
    /// Shutter time; filled only for scenes with motion (else empty: no time per ray).
    pub time: Vec<f32>,
    /// Wavelength in nm; filled only for scenes with a dispersive material.
    pub lambda: Vec<f32>,
    pub tr: Vec<f32>,
    pub tg: Vec<f32>,
    pub tb: Vec<f32>,
    pub path: Vec<u32>,
    pub branch: Vec<u32>,
    pub depth: Vec<u16>,
    pub diffuse: Vec<u16>,
    pub flags: Vec<u8>,
    pub media: Vec<MediumStack>,
    /// Sampling density of glossy lobe rays; filled only for scenes with glossy materials and area
    /// lights (multiple importance sampling).
    pub pdf: Vec<f32>,
    pub travel: Vec<f32>,
    len: usize,
    /// Whether `time` / `lambda` / `pdf` are carried.
    pub with_time: bool,
    pub with_lambda: bool,
    pub with_pdf: bool,
    /// How many image pixels the queue's rays serve (set by the pipeline per work unit; 0: unknown).
    /// The intersect stage sorts incoherent queues by finer direction cells when they hold many rays
    /// per pixel.
    pub pixels: u32,
}

impl RayQueue {
    pub fn new(with_time: bool, with_lambda: bool) -> Self {
        RayQueue { with_time, with_lambda, ..Default::default() }
    }
    /// The same queue carrying (or not) the lobe rays' sampling density.
    pub fn with_pdf(self, with_pdf: bool) -> Self {
        RayQueue { with_pdf, ..self }
    }
    #[inline]
    pub fn len(&self) -> usize {
        self.len
    }
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
    /// Length rounded up to the lane width (valid after [`RayQueue::pad`]).
    #[inline]
    pub fn padded_len(&self) -> usize {
        pad_to_lanes(self.len)
    }

    pub fn clear(&mut self) {
        macro_rules! clr { ($($f:ident),*) => { $( self.$f.clear(); )* }; }
        clr!(ox, oy, oz, dx, dy, dz, tmax, time, lambda, tr, tg, tb, path, branch, depth, diffuse, flags, media, pdf, travel);
        self.len = 0;
    }

    #[inline(always)]
    pub fn push(&mut self, r: &RayItem) {
        // Padding from a previous `pad` is dropped first so pushes stay contiguous.
        if self.ox.len() != self.len {
            self.truncate_to_len();
        }
        self.ox.push(r.o.x);
        self.oy.push(r.o.y);
        self.oz.push(r.o.z);
        self.dx.push(r.d.x);
        self.dy.push(r.d.y);
        self.dz.push(r.d.z);
        self.tmax.push(r.tmax);
        if self.with_time {
            self.time.push(r.time);
        }
        if self.with_lambda {
            self.lambda.push(r.lambda);
        }
        self.tr.push(r.throughput.x);
        self.tg.push(r.throughput.y);
        self.tb.push(r.throughput.z);
        self.path.push(r.path);
        self.branch.push(r.branch);
        self.depth.push(r.depth);
        self.diffuse.push(r.diffuse);
        self.flags.push(r.flags);
        self.media.push(r.media);
        if self.with_pdf {
            self.pdf.push(r.pdf);
            self.travel.push(r.travel);
        }
        self.len += 1;
    }

    /// Append the first `n` (<= 8) rays of `rows` (as `n` calls of [`RayQueue::push`] would, one copy
    /// per field; `time` and `lambda` kept only when the queue carries them).
    #[inline(always)]
    pub fn push_rows(&mut self, n: usize, rows: &RayRows) {
        debug_assert!(n <= LANES);
        if self.ox.len() != self.len {
            self.truncate_to_len();
        }
        for (v, x) in [&mut self.ox, &mut self.oy, &mut self.oz].into_iter().zip(&rows.o) {
            put(v, x, n);
        }
        for (v, x) in [&mut self.dx, &mut self.dy, &mut self.dz].into_iter().zip(&rows.d) {
            put(v, x, n);
        }
        fill(&mut self.tmax, f32::INFINITY, n);
        if self.with_time {
            put(&mut self.time, &rows.time, n);
        }
        if self.with_lambda {
            put(&mut self.lambda, &rows.lambda, n);
        }
        for (t, x) in [&mut self.tr, &mut self.tg, &mut self.tb].into_iter().zip(&rows.throughput) {
            put(t, x, n);
        }
        put(&mut self.path, &rows.path, n);
        put(&mut self.branch, &rows.branch, n);
        put(&mut self.depth, &rows.depth, n);
        put(&mut self.diffuse, &rows.diffuse, n);
        put(&mut self.flags, &rows.flags, n);
        put(&mut self.media, &rows.media, n);
        if self.with_pdf {
            put(&mut self.pdf, &rows.pdf, n);
            put(&mut self.travel, &rows.travel, n);
        }
        self.len += n;
    }

    fn truncate_to_len(&mut self) {
        let n = self.len;
        macro_rules! tr { ($($f:ident),*) => { $( self.$f.truncate(n); )* }; }
        tr!(ox, oy, oz, dx, dy, dz, tmax, tr, tg, tb, path, branch, depth, diffuse, flags, media);
        if self.with_time {
            self.time.truncate(n);
        }
        if self.with_lambda {
            self.lambda.truncate(n);
        }
        if self.with_pdf {
            self.pdf.truncate(n);
            self.travel.truncate(n);
        }
    }

    /// Pad the lane fields to a multiple of the lane width with inert rays (tmax = -1).
    pub fn pad(&mut self) {
        let n = self.padded_len();
        for v in [&mut self.ox, &mut self.oy, &mut self.oz, &mut self.dx, &mut self.dy, &mut self.dz] {
            v.resize(n, 0.0);
        }
        self.dx.iter_mut().skip(self.len).for_each(|d| *d = 1.0);
        self.tmax.resize(n, -1.0);
        if self.with_time {
            self.time.resize(n, 0.0);
        }
    }

    /// The ray at index `i` (tests, debugging and scalar stages).
    #[inline(always)]
    pub fn get(&self, i: usize) -> RayItem {
        RayItem {
            o: Vec3::new(self.ox[i], self.oy[i], self.oz[i]),
            d: Vec3::new(self.dx[i], self.dy[i], self.dz[i]),
            tmax: self.tmax[i],
            time: if self.with_time { self.time[i] } else { 0.0 },
            lambda: if self.with_lambda { self.lambda[i] } else { 0.0 },
            throughput: Vec3::new(self.tr[i], self.tg[i], self.tb[i]),
            path: self.path[i],
            branch: self.branch[i],
            depth: self.depth[i],
            diffuse: self.diffuse[i],
            flags: self.flags[i],
            media: self.media[i],
            pdf: if self.with_pdf { self.pdf[i] } else { 0.0 },
            travel: if self.with_pdf { self.travel[i] } else { 0.0 },
        }
    }
}

/// Sentinel for "no primitive" / "no CSG leaf".
pub const NONE: u32 = u32::MAX;

/// Nearest hits of a ray queue, index-aligned with it.
#[derive(Default)]
pub struct HitQueue {
    pub t: Vec<f32>,
    /// Primitive id, or [`NONE`] for a miss.
    pub prim: Vec<u32>,
    /// For CSG hits: the leaf whose surface was hit; else [`NONE`].
    pub leaf: Vec<u32>,
    /// For CSG hits: the leaf's normal is reversed (surface of a subtracted solid).
    pub flip: Vec<bool>,
    /// Scratch of the intersect stage: ray indices partitioned by direction octant.
    pub order: Vec<u32>,
    /// Scratch of the intersect stage: the wide BVH's traversal stack (the shadow stage's too).
    pub wide_stack: WideStack,
    /// Set by the intersect stage: the rays' directions were incoherent (it sorted them by octant), so
    /// the hit points are scattered (diffuse and glossy bounces), not a tile's coherent surface.
    pub scattered: bool,
}

impl HitQueue {
    /// `n` entries whose `t` and `prim` the caller writes, every one of them, or fills with
    /// [`HitQueue::fill_misses`] (their old values are left in place, new ones are misses); the CSG
    /// fields are reset (no leaf, not flipped).
    pub fn reset_for_overwrite(&mut self, n: usize) {
        self.t.truncate(n);
        self.t.resize(n, f32::INFINITY);
        self.prim.truncate(n);
        self.prim.resize(n, NONE);
        self.reset_csg(n);
    }

    /// Every entry's `t` and `prim` a miss.
    pub fn fill_misses(&mut self) {
        self.t.fill(f32::INFINITY);
        self.prim.fill(NONE);
    }

    fn reset_csg(&mut self, n: usize) {
        self.leaf.clear();
        self.leaf.resize(n, NONE);
        self.flip.clear();
        self.flip.resize(n, false);
    }
}

/// Rays whose packet reached the bounds of a CSG solid: (ray index, prim id) pairs for `csg_merge`.
#[derive(Default)]
pub struct CsgCandidates {
    pub ray: Vec<u32>,
    pub prim: Vec<u32>,
    /// Scratch: (prim << 32 | ray), grouped by solid so that rays of one solid form packets.
    pub sorted: Vec<u64>,
    /// Scratch: the counting sort's slot per solid.
    pub counts: Vec<u32>,
}

impl CsgCandidates {
    pub fn clear(&mut self) {
        self.ray.clear();
        self.prim.clear();
        self.sorted.clear();
        self.counts.clear();
    }
    pub fn len(&self) -> usize {
        self.ray.len()
    }
    pub fn is_empty(&self) -> bool {
        self.ray.is_empty()
    }
}

/// Direct-light requests from shading points (next-event estimation); the shadow stage turns each into
/// light samples and traces them as any-hit packets. (A new column goes into [`NeeQueue::clear`]'s and
/// [`NeeQueue::copy_from`]'s lists too: the light selection's sorted copy would lack it.)
#[derive(Default)]
pub struct NeeQueue {
    /// The shading point (on the surface): light samples are taken from here.
    pub px: Vec<f32>,
    pub py: Vec<f32>,
    pub pz: Vec<f32>,
    /// Origin of the shadow rays: the shading point moved off the surface on the lit side.
    pub ox: Vec<f32>,
    pub oy: Vec<f32>,
    pub oz: Vec<f32>,
    /// Shading normal on the side of the incoming ray.
    pub nx: Vec<f32>,
    pub ny: Vec<f32>,
    pub nz: Vec<f32>,
    /// throughput x BRDF (albedo / pi).
    pub wr: Vec<f32>,
    pub wg: Vec<f32>,
    pub wb: Vec<f32>,
    pub path: Vec<u32>,
    /// Random-number stream of this shading point.
    pub key: Vec<u64>,
    /// The camera sample index of the path (light samples are stratified across a pixel's samples).
    pub sample: Vec<u32>,
    pub time: Vec<f32>,
    /// A static sphere the point lies on, seen from outside (its shadow rays leave it outward and
    /// cannot meet it again: it is convex), else [`NONE`].
    pub own: Vec<u32>,
    /// The media around each shading point (its incoming ray's stack: its shadow rays start inside
    /// them), in scenes with dielectrics; empty elsewhere (every point is in air) and where requests
    /// were pushed one by one ([`NeeQueue::push`]).
    pub media: Vec<MediumStack>,
    /// In the queue of glossy points ([`NeeQueue::glossy`], filled by [`NeeQueue::push_lobes`]; empty
    /// elsewhere): the direction back along the incoming ray (unit) and the GGX `alpha` (its `w` is
    /// throughput x tint: the shadow stage evaluates the lobe per light sample), never 0; `alpha < 0`
    /// when no lobe ray leaves the point (depth limit) or its lobe ray is not sampled (the `center`
    /// strategy's fixed direction), so its light samples need no MIS weight.
    pub wox: Vec<f32>,
    pub woy: Vec<f32>,
    pub woz: Vec<f32>,
    pub alpha: Vec<f32>,
    /// The requests of glossy points, apart (made on the first): Lambert requests carry no lobe
    /// columns and take the shadow stage's Lambert path unchanged.
    pub glossy: Option<Box<NeeQueue>>,
}

impl NeeQueue {
    pub fn clear(&mut self) {
        macro_rules! clr { ($($f:ident),*) => { $( self.$f.clear(); )* }; }
        clr!(px, py, pz, ox, oy, oz, nx, ny, nz, wr, wg, wb, path, key, sample, time, own, media, wox, woy, woz, alpha);
        if let Some(g) = &mut self.glossy {
            g.clear();
        }
    }
    pub fn len(&self) -> usize {
        self.px.len()
    }
    pub fn is_empty(&self) -> bool {
        self.px.is_empty()
    }
    /// Make this queue `src`'s requests `order` (lobe columns too, where `src` has them; not its glossy
    /// queue).
    pub fn copy_from(&mut self, src: &NeeQueue, order: &[u32]) {
        macro_rules! copy { ($($f:ident),*) => { $(
            self.$f.clear();
            if !src.$f.is_empty() {
                self.$f.extend(order.iter().map(|&i| src.$f[i as usize]));
            }
        )* }; }
        copy!(px, py, pz, ox, oy, oz, nx, ny, nz, wr, wg, wb, path, key, sample, time, own, media, wox, woy, woz, alpha);
    }
    #[inline]
    #[allow(clippy::too_many_arguments)]
    pub fn push(&mut self, p: Vec3, o: Vec3, n: Vec3, w: Vec3, path: u32, key: u64, sample: u32, time: f32, own: u32) {
        self.px.push(p.x);
        self.py.push(p.y);
        self.pz.push(p.z);
        self.ox.push(o.x);
        self.oy.push(o.y);
        self.oz.push(o.z);
        self.nx.push(n.x);
        self.ny.push(n.y);
        self.nz.push(n.z);
        self.wr.push(w.x);
        self.wg.push(w.y);
        self.wb.push(w.z);
        self.path.push(path);
        self.key.push(key);
        self.sample.push(sample);
        self.time.push(time);
        self.own.push(own);
    }
}

/// Up to 8 next-event requests as lane arrays (see [`NeeQueue::push_rows`]).
pub struct NeeRows<'a> {
    pub p: &'a [[f32; LANES]; 3],
    pub o: [&'a [f32; LANES]; 3],
    pub n: &'a [[f32; LANES]; 3],
    pub w: &'a [[f32; LANES]; 3],
    pub path: &'a [u32; LANES],
    pub key: &'a [u64; LANES],
    pub sample: &'a [u32; LANES],
    pub time: &'a [f32; LANES],
    pub own: &'a [u32; LANES],
    /// The media around the points, where the scene has dielectrics (see [`NeeQueue::media`]).
    pub media: Option<&'a [MediumStack; LANES]>,
}

impl NeeQueue {
    /// Append the first `m` lanes of `r` (as `m` calls of [`NeeQueue::push`] would, one copy per field).
    #[inline(always)]
    pub fn push_rows(&mut self, m: usize, r: NeeRows) {
        for c in 0..3 {
            put([&mut self.px, &mut self.py, &mut self.pz][c], &r.p[c], m);
            put([&mut self.ox, &mut self.oy, &mut self.oz][c], r.o[c], m);
            put([&mut self.nx, &mut self.ny, &mut self.nz][c], &r.n[c], m);
            put([&mut self.wr, &mut self.wg, &mut self.wb][c], &r.w[c], m);
        }
        put(&mut self.path, r.path, m);
        put(&mut self.key, r.key, m);
        put(&mut self.sample, r.sample, m);
        put(&mut self.time, r.time, m);
        put(&mut self.own, r.own, m);
        if let Some(media) = r.media {
            put(&mut self.media, media, m);
        }
    }

    /// The lobe columns of the `m` requests just pushed (see [`NeeQueue::wox`]).
    #[inline]
    pub fn push_lobes(&mut self, m: usize, wo: &[[f32; LANES]; 3], alpha: &[f32; LANES]) {
        put(&mut self.wox, &wo[0], m);
        put(&mut self.woy, &wo[1], m);
        put(&mut self.woz, &wo[2], m);
        put(&mut self.alpha, alpha, m);
    }
}

/// One entry per camera path of the wavefront: where it lands and what it has gathered.
#[derive(Clone, Default)]
pub struct PathTable {
    pub pixel: Vec<u32>,
    pub sample: Vec<u32>,
    pub lr: Vec<f32>,
    pub lg: Vec<f32>,
    pub lb: Vec<f32>,
}

impl PathTable {
    pub fn clear(&mut self) {
        self.pixel.clear();
        self.sample.clear();
        self.lr.clear();
        self.lg.clear();
        self.lb.clear();
    }
    pub fn len(&self) -> usize {
        self.pixel.len()
    }
    pub fn is_empty(&self) -> bool {
        self.pixel.is_empty()
    }
    #[inline]
    pub fn push(&mut self, pixel: u32, sample: u32) -> u32 {
        self.pixel.push(pixel);
        self.sample.push(sample);
        self.lr.push(0.0);
        self.lg.push(0.0);
        self.lb.push(0.0);
        (self.pixel.len() - 1) as u32
    }
    /// Paths for samples `samples` of one pixel (as one [`PathTable::push`] per sample, in order);
    /// returns the first new path's index.
    #[inline]
    pub fn push_pixel(&mut self, pixel: u32, samples: std::ops::Range<u32>) -> u32 {
        let first = self.pixel.len() as u32;
        self.push_ids(pixel, samples);
        self.zero_radiance();
        first
    }

    /// The pixel and sample index of new paths (their radiance comes with [`PathTable::zero_radiance`]):
    /// [`PathTable::push_pixel`] for many pixels, with one fill of the radiance for all of them.
    #[inline]
    pub fn push_ids(&mut self, pixel: u32, samples: std::ops::Range<u32>) {
        let n = samples.len();
        if n == 4 {
            // (At 4 samples per pixel, fixed-size copies: an extend of 4 is a loop.)
            let s = samples.start;
            self.pixel.extend_from_slice(&[pixel; 4]);
            self.sample.extend_from_slice(&[s, s + 1, s + 2, s + 3]);
        } else {
            self.pixel.extend(std::iter::repeat_n(pixel, n));
            self.sample.extend(samples);
        }
    }

    /// Zero radiance for the paths pushed by [`PathTable::push_ids`] since the last call.
    #[inline]
    pub fn zero_radiance(&mut self) {
        let n = self.pixel.len();
        for v in [&mut self.lr, &mut self.lg, &mut self.lb] {
            v.resize(n, 0.0);
        }
    }
    #[inline]
    pub fn add(&mut self, path: u32, c: Vec3) {
        let i = path as usize;
        self.lr[i] += c.x;
        self.lg[i] += c.y;
        self.lb[i] += c.z;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn medium_stack_nests_and_unwinds() {
        let s = MediumStack::default();
        assert_eq!(s.top(), None);
        let s = s.push(3).push(7).push(3);
        assert_eq!(s.top(), Some(3));
        let s2 = s.remove(7);
        assert_eq!(s2.top(), Some(3));
        assert!(!s2.contains(7));
        let s3 = s2.remove(3).remove(3);
        assert_eq!(s3, MediumStack::default());
        // Full stack ignores a fifth push.
        let full = MediumStack::default().push(1).push(2).push(3).push(4);
        assert_eq!(full.push(9), full);
    }
}
