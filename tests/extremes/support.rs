//! Shared helpers of the extremes matrix: scene text with a similarity transform applied by hand,
//! small deterministic renders that always check the non-finite counter, and image comparisons.

use glam::Vec3;
use std::path::Path;
use strata::film::Film;
use strata::render::{render_into, RenderJob, RenderStats};
use strata::scene::{parse_scene, Profile, Scene};
use strata::wavefront::Settings;

pub const SEED: u64 = 7;

/// A rendered image (linear RGB, row-major) and the render's statistics.
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub px: Vec<Vec3>,
    /// Variance of each pixel's mean, from the film's sums of squares.
    pub var: Vec<Vec3>,
    pub stats: RenderStats,
}

impl Image {
    pub fn at(&self, x: u32, y: u32) -> Vec3 {
        self.px[(y * self.width + x) as usize]
    }
    pub fn mean(&self) -> Vec3 {
        self.px.iter().copied().sum::<Vec3>() / self.px.len() as f32
    }
    pub fn max(&self) -> f32 {
        self.px.iter().map(|p| p.max_element()).fold(0.0, f32::max)
    }
}

/// A profile: the preview profile with `key=value` overrides.
pub fn profile(sets: &[(&str, &str)]) -> Profile {
    let mut p = Profile::builtin("preview");
    // Raise the depth first so that a diffuse_depth override is valid.
    for (k, v) in sets.iter().filter(|(k, _)| *k == "max_depth").chain(sets.iter().filter(|(k, _)| *k != "max_depth")) {
        p.set(k, v).unwrap_or_else(|e| panic!("profile override {k}={v}: {e}"));
    }
    p
}

pub fn parse(text: &str) -> Scene {
    parse_scene(Path::new("extremes.toml"), text).unwrap_or_else(|e| panic!("scene does not parse: {e}\n{text}"))
}

/// Render a compiled scene on 2 threads. Every render of the matrix goes through here: zero
/// non-finite samples, every pixel finite and non-negative, every sample accounted for.
pub fn render_scene(scene: &Scene, profile: Profile) -> Image {
    let spp = profile.spp;
    let mut job = RenderJob::new(scene, Settings { profile, seed: SEED });
    job.threads = 2;
    let (film, stats) = render_into(&job, Film::new(scene.width, scene.height));
    assert!(stats.completed);
    assert_eq!(stats.nonfinite_samples, 0, "non-finite samples discarded");
    assert_eq!(film.total_samples(), scene.width as u64 * scene.height as u64 * spp as u64);
    let px = film.to_rgb();
    let var = film.pixels().map(|p| p.variance_of_mean()).collect();
    for (i, p) in px.iter().enumerate() {
        assert!(p.is_finite() && p.min_element() >= 0.0, "pixel {i} = {p}");
    }
    Image { width: scene.width, height: scene.height, px, var, stats }
}

pub fn render(text: &str, profile: Profile) -> Image {
    render_scene(&parse(text), profile)
}

/// Differences between two images of the same size.
#[derive(Debug, Clone, Copy)]
pub struct Diff {
    /// Mean over pixels of the largest channel difference, relative to the mean of `a`.
    pub mean_rel: f64,
    /// Largest channel difference of any pixel, absolute.
    pub max_abs: f32,
    /// Pixels whose largest channel difference exceeds `tol` (as passed to [`diff`]).
    pub over: usize,
}

pub fn diff(a: &Image, b: &Image, tol: f32) -> Diff {
    assert_eq!((a.width, a.height), (b.width, b.height));
    let (mut sum, mut max_abs, mut over) = (0.0f64, 0.0f32, 0);
    for (p, q) in a.px.iter().zip(&b.px) {
        let d = (*p - *q).abs().max_element();
        sum += d as f64;
        max_abs = max_abs.max(d);
        over += (d > tol) as usize;
    }
    let scale = a.mean().max_element().max(1e-30) as f64;
    Diff { mean_rel: sum / a.px.len() as f64 / scale, max_abs, over }
}

/// Writes scene coordinates under `x -> t + s x` (points), `x -> s x` (vectors, lengths).
#[derive(Clone, Copy, Debug)]
pub struct Xf {
    pub s: f64,
    pub t: [f64; 3],
}

impl Xf {
    pub const ID: Xf = Xf { s: 1.0, t: [0.0; 3] };
    pub fn scale(s: f64) -> Xf {
        Xf { s, t: [0.0; 3] }
    }
    pub fn point(&self, p: [f64; 3]) -> String {
        vec3([self.t[0] + self.s * p[0], self.t[1] + self.s * p[1], self.t[2] + self.s * p[2]])
    }
    pub fn vector(&self, v: [f64; 3]) -> String {
        vec3([self.s * v[0], self.s * v[1], self.s * v[2]])
    }
    pub fn len(&self, x: f64) -> String {
        num(self.s * x)
    }
}

/// A TOML float that parses back to the f64 (and so rounds once to f32 in the loader).
pub fn num(x: f64) -> String {
    format!("{x:e}")
}

pub fn vec3(v: [f64; 3]) -> String {
    format!("[{}, {}, {}]", num(v[0]), num(v[1]), num(v[2]))
}

/// Debugging aid: `EXTREMES_DUMP=dir` writes every compared pair as `name.png`.
pub fn dump(name: &str, imgs: &[&Image]) {
    let Ok(dir) = std::env::var("EXTREMES_DUMP") else { return };
    let (w, h) = (imgs[0].width, imgs[0].height);
    let k = 8;
    let mut px = vec![Vec3::ZERO; (w * k * imgs.len() as u32 * h * k) as usize];
    let ww = w * k * imgs.len() as u32;
    for (i, im) in imgs.iter().enumerate() {
        for y in 0..h * k {
            for x in 0..w * k {
                px[(y * ww + i as u32 * w * k + x) as usize] = im.at(x / k, y / k);
            }
        }
    }
    strata::film::output::write_image(&Path::new(&dir).join(format!("{name}.png")), ww, h * k, &px).unwrap();
}

/// Debugging aid: an ASCII map of where two images differ by more than `tol`.
pub fn diff_map(a: &Image, b: &Image, tol: f32) -> String {
    let mut s = String::new();
    for y in 0..a.height {
        for x in 0..a.width {
            let d = (a.at(x, y) - b.at(x, y)).abs().max_element();
            s.push(if d > 10.0 * tol {
                '#'
            } else if d > tol {
                '+'
            } else {
                '.'
            });
        }
        s.push('\n');
    }
    s
}
