//! Distribution ray tracing against ground truth: each integral (pixel area, light area, reflected
//! direction, lens, time) rendered through the whole pipeline and compared with a closed form computed
//! here in f64 (filter-weighted edge coverage, Lambert's polygon irradiance, the thin-lens circle of
//! confusion, the exposure fraction of a moving sphere) or with a limit (glossy -> mirror), at small
//! sizes and fixed seeds.

use glam::{DVec3, Vec3};
use std::path::Path;
use strata::render::{render, RenderStats};
use strata::scene::{parse_scene, Profile, Scene};
use strata::wavefront::Settings;

#[path = "distribution/diffuse.rs"]
mod diffuse;
#[path = "distribution/glossy.rs"]
mod glossy;
#[path = "distribution/irradiance.rs"]
mod irradiance;
#[path = "distribution/lens_time.rs"]
mod lens_time;
#[path = "distribution/light_selection.rs"]
mod light_selection;
#[path = "distribution/pixel.rs"]
mod pixel;
#[path = "distribution/scenes.rs"]
mod scenes;

// ---------------------------------------------------------------------------------------------
// helpers shared by the sub-modules

/// A profile for tests: `spp` camera samples with `pixel` strategy, `ls` light samples with `light`
/// strategy, every other integral jittered, direct light only.
pub fn profile(spp: u32, pixel: &str, ls: u32, light: &str) -> Profile {
    let text = format!("spp = {spp}\npixel_strategy = \"{pixel}\"\nlight_samples = {ls}\nlight_strategy = \"{light}\"\nmax_depth = 4\n");
    Profile::parse(Path::new("test-profile.toml"), &text).unwrap()
}

pub fn scene(text: &str) -> Scene {
    parse_scene(Path::new("test-scene.toml"), text).unwrap_or_else(|e| panic!("{e}"))
}

/// Render and return the linear image (row-major) and the statistics; fails on any non-finite sample.
pub fn render_image(scene: &Scene, profile: &Profile, seed: u64) -> (Vec<Vec3>, RenderStats) {
    let (film, stats) = render(scene, Settings { profile: profile.clone(), seed }, 0);
    assert_eq!(stats.nonfinite_samples, 0, "non-finite samples");
    (film.to_rgb(), stats)
}

/// The documented camera convention, written out independently in f64: vertical field of view, pixel
/// (x, y) from the top-left, centre at (x + 0.5, y + 0.5); returns origin and unit direction of the
/// pinhole ray through image point (px, py).
pub struct PinholeF64 {
    pub pos: DVec3,
    pub forward: DVec3,
    pub right: DVec3,
    pub up: DVec3,
    pub half_w: f64,
    pub half_h: f64,
    pub width: f64,
    pub height: f64,
}

impl PinholeF64 {
    pub fn new(pos: DVec3, look_at: DVec3, up: DVec3, fov_deg: f64, width: u32, height: u32) -> PinholeF64 {
        let forward = (look_at - pos).normalize();
        let right = forward.cross(up).normalize();
        let up = right.cross(forward);
        let half_h = (fov_deg.to_radians() / 2.0).tan();
        let half_w = half_h * width as f64 / height as f64;
        PinholeF64 { pos, forward, right, up, half_w, half_h, width: width as f64, height: height as f64 }
    }

    pub fn dir(&self, px: f64, py: f64) -> DVec3 {
        let sx = (2.0 * px / self.width - 1.0) * self.half_w;
        let sy = (1.0 - 2.0 * py / self.height) * self.half_h;
        (self.forward + self.right * sx + self.up * sy).normalize()
    }

    /// Size of one pixel on the plane at distance `depth` along the view axis.
    pub fn pixel_size_at(&self, depth: f64) -> f64 {
        2.0 * self.half_h * depth / self.height
    }
}

pub fn v3(v: DVec3) -> String {
    format!("[{}, {}, {}]", v.x, v.y, v.z)
}

/// Mean squared error between two images (all channels).
pub fn mse(a: &[Vec3], b: &[Vec3]) -> f64 {
    assert_eq!(a.len(), b.len());
    let s: f64 = a.iter().zip(b).map(|(x, y)| (*x - *y).as_dvec3().length_squared()).sum();
    s / (3 * a.len()) as f64
}
