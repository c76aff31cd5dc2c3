//! Stage 6: add each camera path's radiance to its pixel. The film's fixed-point sums make the order of
//! additions irrelevant (see `film`); non-finite samples are discarded and counted.

use super::queues::PathTable;
use crate::film::{Film, Pixel};
use glam::Vec3;

/// Returns the number of samples discarded as non-finite.
pub fn accumulate(paths: &PathTable, film: &mut Film) -> u64 {
    let mut bad = 0;
    // A pixel's samples are consecutive paths: they are summed into a local pixel and merged into the
    // film once per run (exact: the sums are integers, so the grouping changes nothing).
    let mut run = Pixel::default();
    let mut at = None;
    for i in 0..paths.len() {
        let px = paths.pixel[i];
        if at != Some(px) {
            if let Some(a) = at {
                film.pixels[a as usize].merge(&run);
            }
            (run, at) = (Pixel::default(), Some(px));
        }
        if !run.add(Vec3::new(paths.lr[i], paths.lg[i], paths.lb[i])) {
            bad += 1;
        }
    }
    if let Some(a) = at {
        film.pixels[a as usize].merge(&run);
    }
    bad
}
