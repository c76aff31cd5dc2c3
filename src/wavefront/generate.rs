//! Stage 1: camera rays for (pixels of a tile) x (a range of sample indices).
//!
//! Every sample is a pure function of (seed, pixel, sample index, dimension): pixel-area offset (through
//! the pixel filter), lens position, shutter time and wavelength each have their own dimension and
//! strategy. Lens, time and wavelength are drawn only when the scene needs them.

use super::dims;
use super::queues::{MediumStack, PathTable, RayItem, RayQueue};
use crate::optics::{sample_wavelength, sample_wavelength_pdf, wavelength_to_rgb};
use crate::sample::{sample_1d, sample_disk_concentric, sample_filter, stream_key, Sampler2d};
use crate::scene::{Profile, Scene};
use glam::Vec3;
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
}

pub fn generate(scene: &Scene, profile: &Profile, seed: u64, tile: Tile, samples: Range<u32>, paths: &mut PathTable, rays: &mut RayQueue) {
    let cam = &scene.camera;
    let f = &scene.features;
    let spp = profile.spp;
    let area = Sampler2d::new(profile.pixel_strategy, spp);
    let lens_set = Sampler2d::new(profile.lens_strategy, spp);
    for y in tile.y0..tile.y1 {
        for x in tile.x0..tile.x1 {
            let pixel = y * scene.width + x;
            let stream = pixel as u64;
            let (area_key, lens_key) = (stream_key(seed, stream, dims::PIXEL), stream_key(seed, stream, dims::LENS));
            for s in samples.clone() {
                let off = sample_filter(profile.filter, area.sample(area_key, s));
                let lens = if f.lens { sample_disk_concentric(lens_set.sample(lens_key, s)) } else { [0.0, 0.0] };
                let (o, d) = cam.ray(x as f32 + 0.5 + off[0], y as f32 + 0.5 + off[1], lens);
                let time = if f.motion { cam.time(sample_1d(profile.time_strategy, seed, stream, dims::TIME, s, spp)) } else { 0.0 };
                let (lambda, throughput) = if f.dispersion {
                    // Its own strategy: with the pixel's, `center` pixels rendered one wavelength only.
                    let l = sample_wavelength(sample_1d(profile.wavelength_strategy, seed, stream, dims::WAVELENGTH, s, spp));
                    (l, wavelength_to_rgb(l) / sample_wavelength_pdf(l))
                } else {
                    (0.0, Vec3::ONE)
                };
                let path = paths.push(pixel, s);
                rays.push(&RayItem {
                    o,
                    d,
                    tmax: f32::INFINITY,
                    time,
                    lambda,
                    throughput,
                    path,
                    branch: 0,
                    depth: 0,
                    diffuse: 0,
                    flags: 0,
                    media: MediumStack::default(),
                });
            }
        }
    }
}
