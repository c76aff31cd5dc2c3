//! Stage 6: add each camera path's radiance to its pixel. The film's fixed-point sums make the order of
//! additions irrelevant (see `film`); non-finite samples are discarded and counted.

use super::queues::PathTable;
use crate::film::{quantize_x8, valid_sample, valid_x8, Film, Pixel};

/// Returns the number of samples discarded as non-finite.
pub fn accumulate(paths: &PathTable, film: &mut Film) -> u64 {
    let mut bad = 0;
    // A pixel's samples are consecutive paths: they are summed into a local pixel and merged into the
    // film once per run (exact: the sums are integers, so the grouping changes nothing). Samples are
    // quantized 8 at a time (`quantize_x8`, equal to the scalar `quantize` that `Pixel::add` uses).
    let mut run = Pixel::default();
    let mut at = None;
    let n = paths.len();
    for base in (0..n).step_by(8) {
        let m = (n - base).min(8);
        // A whole chunk is one block copy (lane by lane stores would stall the vector loads after them).
        let lanes = |v: &[f32]| -> [f32; 8] {
            match v.get(base..base + 8) {
                Some(s) => s.try_into().unwrap(),
                None => std::array::from_fn(|l| v[base + l.min(m - 1)]),
            }
        };
        let (r, g, b) = (lanes(&paths.lr), lanes(&paths.lg), lanes(&paths.lb));
        let q = [quantize_x8(&r), quantize_x8(&g), quantize_x8(&b)];
        // Eight valid samples of one pixel (the usual case from 8 samples per pixel on): summed per
        // channel in registers, then added to the run once.
        let px8 = &paths.pixel[base..base + m];
        if m == 8 && px8.iter().all(|&p| p == px8[0]) && valid_x8(&r, &g, &b) == 0xff {
            if at != Some(px8[0]) {
                if let Some(a) = at {
                    film.pixels[a as usize].merge(&run);
                }
                (run, at) = (Pixel::default(), Some(px8[0]));
            }
            run.add_quantized_x8(&q);
            continue;
        }
        for l in 0..m {
            let px = paths.pixel[base + l];
            if at != Some(px) {
                if let Some(a) = at {
                    film.pixels[a as usize].merge(&run);
                }
                (run, at) = (Pixel::default(), Some(px));
            }
            if valid_sample([r[l], g[l], b[l]]) {
                run.add_quantized([q[0][l], q[1][l], q[2][l]]);
            } else {
                bad += 1;
            }
        }
    }
    if let Some(a) = at {
        film.pixels[a as usize].merge(&run);
    }
    bad
}
