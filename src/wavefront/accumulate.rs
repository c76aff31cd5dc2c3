//! Stage 6: add each camera path's radiance to its pixel. The film's fixed-point sums make the order of
//! additions irrelevant (see `film`); non-finite samples are discarded and counted.

use super::queues::PathTable;
use crate::film::{quantize_x8, valid_sample, Film, Pixel};

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
        let lanes = |v: &[f32]| std::array::from_fn::<f32, 8, _>(|l| v[base + l.min(m - 1)]);
        let (r, g, b) = (lanes(&paths.lr), lanes(&paths.lg), lanes(&paths.lb));
        let q = [quantize_x8(&r), quantize_x8(&g), quantize_x8(&b)];
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
