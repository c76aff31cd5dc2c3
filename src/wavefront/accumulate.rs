//! Stage 6: add each camera path's radiance to its pixel. The film's fixed-point sums make the order of
//! additions irrelevant (see `film`); non-finite samples are discarded and counted.

use super::queues::PathTable;
use crate::film::Film;
use glam::Vec3;

/// Returns the number of samples discarded as non-finite.
pub fn accumulate(paths: &PathTable, film: &mut Film) -> u64 {
    let mut bad = 0;
    for i in 0..paths.len() {
        let v = Vec3::new(paths.lr[i], paths.lg[i], paths.lb[i]);
        if !film.pixels[paths.pixel[i] as usize].add(v) {
            bad += 1;
        }
    }
    bad
}
