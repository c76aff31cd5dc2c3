//! Stage 6: add each camera path's radiance to its pixel. The film's fixed-point sums make the order of
//! additions irrelevant (see `film`); non-finite samples are discarded and counted.

use super::queues::PathTable;
use crate::film::{quantize_x8, small_x8, square_fixed_x8, valid_x8, Film, Pixel};
use crate::simd::chunk8;

/// Make `px` the pixel of the run, merging the previous run into the film.
#[inline(always)]
fn switch(px: u32, run: &mut Pixel, at: &mut Option<u32>, film: &mut Film) {
    if *at != Some(px) {
        if let Some(a) = *at {
            film.merge_pixel(a as usize, run);
        }
        (*run, *at) = (Pixel::default(), Some(px));
    }
}

/// Returns the number of samples discarded as non-finite.
pub fn accumulate(paths: &PathTable, film: &mut Film) -> u64 {
    let mut bad = 0;
    // A pixel's samples are consecutive paths: they are summed into a local pixel and merged into the
    // film once per run (exact: the sums are integers, so the grouping changes nothing). Samples are
    // quantized 8 at a time (`quantize_x8`, equal to the scalar `quantize` that `Pixel::add` uses), and
    // their validity decided 8 at a time (`valid_x8`, the comparison of `valid_sample`).
    let mut run = Pixel::default();
    let mut at = None;
    let n = paths.len();
    for base in (0..n).step_by(8) {
        let m = (n - base).min(8);
        // The cells are spread over a film larger than L2: ask for the one two chunks ahead now.
        if let Some(&ahead) = paths.pixel.get(base + 16) {
            film.prefetch(ahead as usize);
        }
        // A whole chunk is one block copy (lane by lane stores would stall the vector loads after them).
        // (Lanes past `m` repeat the last sample.)
        let (r, g, b) =
            (chunk8(&paths.lr, base, m).to_array(), chunk8(&paths.lg, base, m).to_array(), chunk8(&paths.lb, base, m).to_array());
        let q = [quantize_x8(&r), quantize_x8(&g), quantize_x8(&b)];
        let valid = valid_x8(&r, &g, &b);
        // Samples below SMALL_SAMPLE_VALUE (nearly all) have their squared terms computed 8 at a time
        // in 64-bit lanes for the whole-chunk path below (computed here, ahead of the branch: measured
        // faster); lane by lane, `add_quantized`'s one widening multiply per channel is as cheap.
        let small = small_x8(&r, &g, &b);
        let sq = [square_fixed_x8(&q[0]), square_fixed_x8(&q[1]), square_fixed_x8(&q[2])];
        let px8 = &paths.pixel[base..base + m];
        // Eight valid samples of one pixel (the usual case from 8 samples per pixel on): summed per
        // channel in registers, then added to the run once.
        if m == 8 && valid == 0xff && px8.iter().all(|&p| p == px8[0]) {
            switch(px8[0], &mut run, &mut at, film);
            if small == 0xff {
                run.add_small_x8(&q, &sq);
            } else {
                run.add_quantized_x8(&q);
            }
            continue;
        }
        for (l, &px) in px8.iter().enumerate() {
            switch(px, &mut run, &mut at, film);
            if valid >> l & 1 != 0 {
                run.add_quantized([q[0][l], q[1][l], q[2][l]]);
            } else {
                bad += 1;
            }
        }
    }
    if let Some(a) = at {
        film.merge_pixel(a as usize, &run);
    }
    bad
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// The stage gives the film what `Pixel::add` gives sample by sample, and counts the samples it
    /// discards: runs of 1 to 24 samples per pixel (whole 8-sample chunks of one pixel, chunks spanning
    /// pixels, a short tail), with non-finite and out-of-range samples among valid ones.
    #[test]
    fn equals_pixel_add_sample_by_sample() {
        let mut next = crate::sample::hash::test_uniforms(0xacc);
        for round in 0..40 {
            let mut paths = PathTable::default();
            let (w, h) = (16u32, 12u32);
            let mut pixel = 0;
            while pixel < w * h && paths.len() < 600 {
                let n = 1 + (next() * [8.0, 24.0][round % 2]) as u32;
                paths.push_pixel(pixel, 0..n);
                pixel += 1 + (next() * 2.0) as u32;
            }
            for i in 0..paths.len() {
                let v = |u: f32| match (u * 100.0) as u32 {
                    0 => f32::NAN,
                    1 => f32::INFINITY,
                    2 => -3e9,
                    // Valid but beyond the 64-bit path (SMALL_SAMPLE_VALUE), either sign.
                    3 => 1.0e6,
                    4 => -2.0e9,
                    5 => 8192.0,
                    _ => (u - 0.2) * 5.0,
                };
                (paths.lr[i], paths.lg[i], paths.lb[i]) = (v(next()), v(next()), v(next()));
            }
            let mut film = Film::new(w, h);
            let bad = accumulate(&paths, &mut film);
            // Sample by sample into 128-bit pixels (the film moves pixels whose sums outgrow 64 bits,
            // as the 1e6 and -2e9 samples make them, to its side table: same values).
            let mut want = vec![Pixel::default(); (w * h) as usize];
            let mut want_bad = 0;
            for i in 0..paths.len() {
                let c = Vec3::new(paths.lr[i], paths.lg[i], paths.lb[i]);
                want_bad += !want[paths.pixel[i] as usize].add(c) as u64;
            }
            assert_eq!(bad, want_bad, "round {round}");
            assert!(film.pixels().eq(want.iter().copied()), "round {round}: films differ");
            let kept: u64 = want.iter().map(|p| p.count).sum();
            assert!(want_bad > 0 && kept > 200, "round {round}: {want_bad} bad, {kept} kept");
            let wide = |p: &Pixel| p.sum.iter().chain(&p.sum_sq).any(|s| i64::try_from(*s).is_err());
            assert!(want.iter().any(wide), "round {round}: no pixel outgrew the film's 64-bit cells");
            // The film's means and count from its cells (64-bit or moved to the side table) are the
            // 128-bit pixels' own.
            let bits = |v: Vec3| v.to_array().map(f32::to_bits);
            let rgb = film.to_rgb();
            assert!(want.iter().zip(&rgb).all(|(p, &m)| bits(p.mean()) == bits(m)), "round {round}: means differ");
            assert_eq!(film.total_samples(), kept, "round {round}");
        }
    }
}
