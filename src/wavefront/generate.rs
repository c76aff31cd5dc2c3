//! Stage 1: camera rays for (pixels of a tile) x (a range of sample indices).
//!
//! Every sample is a pure function of (seed, pixel, sample index, dimension): pixel-area offset (through
//! the pixel filter), lens position, shutter time and wavelength each have their own dimension and
//! strategy. Lens, time and wavelength are drawn only when the scene needs them.

use super::dims;
use super::queues::{PathTable, RayQueue, RayRows};
use crate::optics::{sample_wavelength_pdf_x8, sample_wavelength_x8, wavelength_to_rgb_x8, LAMBDA_D};
use crate::sample::hash::RUN_MAX;
use crate::sample::{
    sample_1d_keyed_x8, sample_disk_concentric_x8, sample_filter, sample_filter_x8, stream_key, Filter, Sampler2d, Strategy,
};
use crate::scene::{Profile, Scene};
use crate::simd::{f32x8, LANES};
use std::ops::Range;

/// A rectangle of pixels, [x0, x1) x [y0, y1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tile {
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
}

impl Tile {
    pub fn pixel_count(&self) -> u32 {
        (self.x1 - self.x0) * (self.y1 - self.y0)
    }

    /// The tile's pixels in 8x8 blocks (row by row), each block in Morton (Z) order: 8 consecutive
    /// pixels form a 4x2 block and 64 an 8x8 block, so the 8-ray packets and the traversal groups (four
    /// blocks) of camera rays are compact in the image (row order made a group a 64x1 strip). Cells of a block
    /// outside the tile are skipped, so the cost is at most 64 per block whatever the tile's shape.
    pub fn pixels_z_order(&self) -> impl Iterator<Item = (u32, u32)> {
        let (w, h) = (self.x1 - self.x0, self.y1 - self.y0);
        let (x0, y0) = (self.x0, self.y0);
        (0..h.div_ceil(8)).flat_map(move |by| {
            (0..w.div_ceil(8)).flat_map(move |bx| {
                (0..64u64).filter_map(move |code| {
                    let (x, y) = (bx * 8 + compact_bits(code), by * 8 + compact_bits(code >> 1));
                    (x < w && y < h).then_some((x0 + x, y0 + y))
                })
            })
        })
    }
}

/// The even bits of `v` packed into the low half (inverse of bit interleaving).
fn compact_bits(v: u64) -> u32 {
    let mut x = v & 0x5555_5555_5555_5555;
    x = (x | (x >> 1)) & 0x3333_3333_3333_3333;
    x = (x | (x >> 2)) & 0x0f0f_0f0f_0f0f_0f0f;
    x = (x | (x >> 4)) & 0x00ff_00ff_00ff_00ff;
    x = (x | (x >> 8)) & 0x0000_ffff_0000_ffff;
    x = (x | (x >> 16)) & 0x0000_0000_ffff_ffff;
    x as u32
}

/// Camera rays (and their paths) for samples `samples` of every pixel of `tile`, pixels in Z order, a
/// pixel's samples consecutive. Positions, lens points and directions are made 8 rays at a time (the
/// sampler, the box filter, the lens disk and `Camera::rays_x8` in 8 lanes), and so are shutter times
/// and wavelengths with their weights, only for scenes that have them (`sample_1d_keyed_x8`, the
/// `_x8` spectral functions: the scalar ones per lane cost a dispersive scene half its render).
pub fn generate(scene: &Scene, profile: &Profile, seed: u64, tile: Tile, samples: Range<u32>, paths: &mut PathTable, rays: &mut RayQueue) {
    let f = &scene.features;
    let cam = &scene.camera;
    let spp = profile.spp;
    let area = Sampler2d::new(profile.pixel_strategy, spp);
    let lens_set = Sampler2d::new(profile.lens_strategy, spp);
    // Per lane: pixel centre, the pixel's stream keys and the sample index; rays are made 8 at a time.
    // Lanes are written one by one into one of two buffers while the other, full, waits: a buffer is
    // read (as vectors) one packet after it was filled, when its scalar stores have long reached the
    // cache (read at once, each vector load would wait for the stores it overlaps).
    let mut bufs = [Lanes::default(); 2];
    let runs = area.runs() || (f.lens && lens_set.runs());
    let mut run = [[[f32x8::ZERO; 2]; RUN_MAX]; 2];
    let mut cur = 0;
    let mut pending = false;
    let mut k = 0;
    let mut next_path = paths.len() as u32;
    // The media the camera is inside (none, nearly always); by each ray's time where one moves past it.
    let media = scene.camera_media_at(cam.shutter[0]);
    let media_move = f.motion && scene.camera_media_move();
    // Whether the wavelength integral has one sample point: then it is held at the nominal index.
    let nominal = profile.wavelength_strategy == Strategy::Center || (profile.wavelength_strategy == Strategy::Grid && spp == 1);
    // Rays (and their path ids, from `next_path` on) for the first `k` lanes of `b`; `one`: its lanes are
    // one pixel's samples (one key per dimension, in lane 0).
    // `made`: the packet's pixel and lens samples, where they were made beforehand (`Sampler2d::sample_x8_run`).
    let emit = |k: usize, b: &Lanes, one: bool, made: Option<[[f32x8; 2]; 2]>, next_path: &mut u32, rays: &mut RayQueue| {
        let (keys, index, first) = (&b.keys, &b.index, *next_path);
        *next_path += k as u32;
        let sample = |set: &Sampler2d, keys: &[u64; LANES]| {
            if one {
                set.sample_x8_one_key(keys[0], index, true)
            } else {
                set.sample_x8(keys, index, true)
            }
        };
        let off = filter_offsets(profile.filter, made.map_or_else(|| sample(&area, &keys[0]), |m| m[0]));
        let lens =
            if f.lens { sample_disk_concentric_x8(made.map_or_else(|| sample(&lens_set, &keys[1]), |m| m[1])) } else { [f32x8::ZERO; 2] };
        let (o, d) = cam.rays_x8(f32x8::from(b.cx) + off[0], f32x8::from(b.cy) + off[1], lens);
        // New paths: branch, depth, bounce counts and flags start empty (zero); media, the camera's.
        let mut rows = RayRows {
            o: o.rows(),
            d: d.rows(),
            throughput: [[1.0; LANES]; 3],
            path: std::array::from_fn(|l| first + l as u32),
            media: [media; LANES],
            ..RayRows::default()
        };
        if f.motion {
            rows.time = sample_1d_keyed_x8(profile.time_strategy, &keys[2], index, spp, one).map(|u| cam.time(u));
            if media_move {
                for l in 0..k {
                    rows.media[l] = scene.camera_media_at(rows.time[l]);
                }
            }
        }
        if f.dispersion && nominal {
            // One point for the spectrum (`center`, a grid of one): the d line, weight 1 (the path RGB,
            // every dielectric at its nominal index): the image without dispersion. The midpoint of the
            // wavelength density, 541 nm, rendered the whole scene green (weight (0, 3.05, 0)).
            rows.lambda = [LAMBDA_D; LANES];
        } else if f.dispersion {
            // Its own strategy: with the pixel's, `center` pixels rendered one wavelength only. The
            // wavelengths and their weights (`rgb / pdf`) in 8 lanes (lanes past `k` are not pushed).
            let u = sample_1d_keyed_x8(profile.wavelength_strategy, &keys[3], index, spp, one);
            let w = sample_wavelength_x8(f32x8::from(u));
            let (rgb, pdf) = (wavelength_to_rgb_x8(w), sample_wavelength_pdf_x8(w));
            rows.lambda = w.to_array();
            for (row, c) in rows.throughput.iter_mut().zip(rgb) {
                *row = (c / pdf).to_array();
            }
        }
        rays.push_rows(k, &rows);
    };
    // Across pixels: where each pixel's samples of the unit are whole packets, and at most `RUN_MAX` (a
    // unit of the default tile holds 16 samples of each of its pixels), the strata of 8 pixels' samples
    // are walked at once, a lane per pixel (`Sampler2d::strata_runs`): a pixel's own run of 2 packets is
    // too short to keep the walk busy: `walked[m][lane]`, then turned to `strata[set][lane][m]` (the pixels
    // `ahead[..n_ahead]`), so that each packet's strata are one row.
    let len = samples.len();
    let across = runs && len.is_multiple_of(LANES) && len <= RUN_MAX;
    let mut strata = [[[0u32; RUN_MAX]; LANES]; 2];
    let mut walked = [[0u32; LANES]; RUN_MAX];
    let mut zs = tile.pixels_z_order();
    let mut ahead = [(0u32, 0u32); LANES];
    let (mut n_ahead, mut at) = (0usize, 0usize);
    loop {
        if at == n_ahead {
            (n_ahead, at) = (0, 0);
            while n_ahead < LANES {
                let Some(p) = zs.next() else { break };
                ahead[n_ahead] = p;
                n_ahead += 1;
            }
            if n_ahead == 0 {
                break;
            }
            if across {
                let key = |l: usize, dim: u32| {
                    stream_key(seed, (ahead[l.min(n_ahead - 1)].1 * scene.width + ahead[l.min(n_ahead - 1)].0) as u64, dim)
                };
                let count = std::array::from_fn(|l| if l < n_ahead { len as u32 } else { 0 });
                let base = [samples.start; LANES];
                for (set, dim, used) in [(&area, dims::PIXEL, true), (&lens_set, dims::LENS, f.lens)] {
                    if used && set.runs() {
                        let keys = std::array::from_fn(|l| key(l, dim));
                        set.strata_runs(&keys, &base, 1, &count, &mut walked);
                        let to = &mut strata[(dim == dims::LENS) as usize];
                        for (m, row) in walked.iter().enumerate().take(len) {
                            for l in 0..LANES {
                                to[l][m] = row[l];
                            }
                        }
                    }
                }
            }
        }
        let ((x, y), lane) = (ahead[at], at);
        at += 1;
        let pixel = y * scene.width + x;
        let stream = pixel as u64;
        // The pixel's stream keys, once per pixel (the 1D ones only where the scene uses them).
        let pk = [
            stream_key(seed, stream, dims::PIXEL),
            if f.lens { stream_key(seed, stream, dims::LENS) } else { 0 },
            if f.motion { stream_key(seed, stream, dims::TIME) } else { 0 },
            if f.dispersion && !nominal { stream_key(seed, stream, dims::WAVELENGTH) } else { 0 },
        ];
        paths.push_ids(pixel, samples.clone());
        // Whole packets of this pixel's samples (from 8 samples per pixel on) are filled as vectors:
        // the same lanes as below, without lane-by-lane stores that stall the vector loads after them.
        let mut first = samples.start;
        if k == 0 && samples.end - first >= LANES as u32 && pending {
            // (In order: the waiting packet's rays come first.)
            emit(LANES, &bufs[cur ^ 1], false, None, &mut next_path, rays);
            pending = false;
        }
        // (Sets whose permutation walks cycles: the samples of up to `RUN_MAX` whole packets made at
        // once, each lane walking its packets' samples one after another.)
        let (mut run_at, mut run_len) = (0, 0);
        while k == 0 && samples.end - first >= LANES as u32 {
            let whole = Lanes {
                cx: [x as f32 + 0.5; LANES],
                cy: [y as f32 + 0.5; LANES],
                keys: pk.map(|key| [key; LANES]),
                index: std::array::from_fn(|l| first + l as u32),
            };
            if across {
                // Packet `p` of this pixel: its lane's strata `8 p .. 8 p + 8`.
                let p = ((first - samples.start) / LANES as u32) as usize;
                let made = |set: &Sampler2d, which: usize, key: &[u64; LANES]| {
                    if set.runs() {
                        let s = strata[which][lane][p * LANES..][..LANES].try_into().expect("8 strata");
                        set.sample_x8_in_strata(key, &whole.index, s)
                    } else {
                        set.sample_x8_one_key(key[0], &whole.index, true)
                    }
                };
                let lens = if f.lens { made(&lens_set, 1, &whole.keys[1]) } else { [f32x8::ZERO; 2] };
                emit(LANES, &whole, true, Some([made(&area, 0, &whole.keys[0]), lens]), &mut next_path, rays);
            } else if runs {
                if run_at == run_len {
                    let count = (((samples.end - first) / LANES as u32) as usize).min(RUN_MAX);
                    area.sample_x8_run(&whole.keys[0], &whole.index, LANES as u32, count, true, &mut run[0]);
                    if f.lens {
                        lens_set.sample_x8_run(&whole.keys[1], &whole.index, LANES as u32, count, true, &mut run[1]);
                    }
                    (run_at, run_len) = (0, count);
                }
                run_at += 1;
                emit(LANES, &whole, true, Some([run[0][run_at - 1], run[1][run_at - 1]]), &mut next_path, rays);
            } else {
                emit(LANES, &whole, true, None, &mut next_path, rays);
            }
            first += LANES as u32;
        }
        for s in first..samples.end {
            let b = &mut bufs[cur];
            (b.cx[k], b.cy[k], b.index[k]) = (x as f32 + 0.5, y as f32 + 0.5, s);
            // (The keys of dimensions the scene does not use stay unread.)
            b.keys[0][k] = pk[0];
            if f.lens || f.motion || f.dispersion {
                for (lane_keys, key) in b.keys.iter_mut().zip(pk).skip(1) {
                    lane_keys[k] = key;
                }
            }
            k += 1;
            if k == LANES {
                if pending {
                    emit(LANES, &bufs[cur ^ 1], false, None, &mut next_path, rays);
                }
                (pending, cur, k) = (true, cur ^ 1, 0);
            }
        }
    }
    if pending {
        emit(LANES, &bufs[cur ^ 1], false, None, &mut next_path, rays);
    }
    if k > 0 {
        emit(k, &bufs[cur], false, None, &mut next_path, rays);
    }
    paths.zero_radiance();
}

/// Eight lanes of camera samples waiting to become rays: pixel centres, the pixels' stream keys (area,
/// lens, time, wavelength) and the sample indices.
#[derive(Clone, Copy, Default)]
struct Lanes {
    cx: [f32; LANES],
    cy: [f32; LANES],
    keys: [[u64; LANES]; 4],
    index: [u32; LANES],
}

/// Image-plane offsets of 8 pixel samples for `filter`: box and tent in 8 lanes (the same bits as the
/// scalar map: `2u` is exact, so its fused `2u - 1` rounds as the scalar's, and the square root is
/// correctly rounded in both; per lane, the tent cost the `final` profile's generation 40%), the
/// Gaussian per lane (its 8-lane twin's `ln_1p` and `sin_cos` round differently from libm's).
#[inline(always)]
fn filter_offsets(filter: Filter, u: [f32x8; 2]) -> [f32x8; 2] {
    if filter != Filter::Gaussian {
        return sample_filter_x8(filter, u);
    }
    let (u0, u1) = (u[0].to_array(), u[1].to_array());
    let mut o = [[0.0f32; LANES]; 2];
    for l in 0..LANES {
        [o[0][l], o[1][l]] = sample_filter(filter, [u0[l], u1[l]]);
    }
    [f32x8::from(o[0]), f32x8::from(o[1])]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sample::Strategy;

    /// Whole packets of one pixel's samples (filled as vectors) give the rays the lane-by-lane fill
    /// gives: 16 samples per pixel generated at once (two whole packets per pixel), 8..16 (one), and the range 3..13
    /// (one whole packet, then a partial one that spans pixels), against one sample at a time (always
    /// lane by lane), per (pixel, sample), with lens, motion and dispersion: origin, direction, time,
    /// wavelength and throughput.
    #[test]
    fn whole_pixel_packets_equal_lane_by_lane() {
        let text = "[image]\nwidth = 12\nheight = 5\n[camera]\nposition = [0, 1, 5]\nlook_at = [0, 0, 0]\nfov = 40\n\
            aperture = 0.2\nfocus_distance = 5\nshutter = [0, 1]\n\
            [materials.m]\ntype = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\n\
            [materials.g]\ntype = \"dielectric\"\ncauchy = [1.52, 0.03]\n\
            [[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"m\"\nmotion = [1, 0, 0]\n\
            [[shapes]]\ntype = \"sphere\"\ncenter = [2, 0, 0]\nradius = 0.5\nmaterial = \"g\"\n";
        let scene = crate::scene::parse_scene(std::path::Path::new("g.toml"), text).unwrap();
        assert!(scene.features.lens && scene.features.motion && scene.features.dispersion);
        let mut profile = Profile::builtin("preview");
        let tile = Tile { x0: 1, y0: 0, x1: 12, y1: 5 };
        let rays_of = |profile: &Profile, ranges: &[Range<u32>]| {
            let mut out = std::collections::BTreeMap::new();
            for r in ranges {
                let (mut paths, mut q) = (PathTable::default(), RayQueue::new(true, true));
                generate(&scene, profile, 7, tile, r.clone(), &mut paths, &mut q);
                for i in 0..q.len() {
                    let ray = q.get(i);
                    let key = (paths.pixel[ray.path as usize], paths.sample[ray.path as usize]);
                    let bits = [ray.o.to_array(), ray.d.to_array()].concat().iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                    let rest = (ray.time.to_bits(), ray.lambda.to_bits(), ray.throughput.to_array());
                    assert!(out.insert(key, (bits, rest)).is_none());
                }
            }
            out
        };
        // (24 and 100 jittered samples: sets whose permutation walks cycles, 8 pixels' strata at once
        // where a unit's samples are whole packets, 0..16 and 8..16, the 55 pixels 6 groups of 8 and one
        // of 7; with a random lens, the pixel set alone walks.)
        for (spp, lens) in [(16, Strategy::Jittered), (24, Strategy::Jittered), (24, Strategy::Random), (100, Strategy::Jittered)] {
            (profile.spp, profile.pixel_strategy, profile.lens_strategy) = (spp, Strategy::Jittered, lens);
            for range in [0..16, 3..13, 8..16] {
                let whole = rays_of(&profile, std::slice::from_ref(&range));
                let single = rays_of(&profile, &range.clone().map(|s| s..s + 1).collect::<Vec<_>>());
                assert_eq!(whole.len(), 11 * 5 * range.len());
                assert!(whole == single, "{spp} spp, lens {lens:?}, samples {range:?}: whole-packet and lane-by-lane rays differ");
            }
        }
    }

    #[test]
    fn z_order_visits_each_pixel_once_in_blocks() {
        for (w, h) in [(16, 16), (5, 3), (64, 64), (1, 7), (17, 2), (1024, 3), (3, 1000)] {
            let t = Tile { x0: 3, y0: 10, x1: 3 + w, y1: 10 + h };
            let px: Vec<_> = t.pixels_z_order().collect();
            assert_eq!(px.len() as u32, w * h);
            let mut seen = std::collections::HashSet::new();
            for &(x, y) in &px {
                assert!((3..3 + w).contains(&x) && (10..10 + h).contains(&y));
                assert!(seen.insert((x, y)));
            }
        }
        // A full 16x16 tile: every run of 8 is a 4x2 block, every run of 64 an 8x8 block.
        let t = Tile { x0: 0, y0: 0, x1: 16, y1: 16 };
        let px: Vec<_> = t.pixels_z_order().collect();
        for (run, (bw, bh)) in [(8, (4, 2)), (64, (8, 8))] {
            for c in px.chunks(run) {
                let (xs, ys): (Vec<u32>, Vec<u32>) = c.iter().copied().unzip();
                assert_eq!(xs.iter().max().unwrap() - xs.iter().min().unwrap() + 1, bw);
                assert_eq!(ys.iter().max().unwrap() - ys.iter().min().unwrap() + 1, bh);
            }
        }
    }
}
