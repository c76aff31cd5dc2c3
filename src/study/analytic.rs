//! The analytic reference: a Lambert plane of constant albedo lit by one quad light, nothing else.
//!
//! The irradiance at a point `x` (unit normal `n`) from a polygon of uniform radiance `L` is Lambert's
//! closed form (Lambert 1760; Baum, Rushmeier & Winget 1989, eq. 7):
//!
//! ```text
//! E(x) = L/2 * sum over edges (v_i, v_i+1) of  angle(v_i - x, v_i+1 - x) * n . unit((v_i - x) x (v_i+1 - x))
//! ```
//!
//! (the polygon's projected solid angle times `L`), valid when the whole polygon is above `x`'s tangent
//! plane. The outgoing radiance is `albedo / pi * E`. A pixel's expected value is that radiance averaged
//! over the pixel footprint under the profile's filter (or taken at the pixel centre when the pixel
//! integral is held at `center`), integrated by Gauss-Legendre quadrature in f64: 8 x 8 nodes over the
//! box pixel, 8 x 8 per quadrant for the tent (its kink is on the quadrant edges), 16 radial x 32
//! angular nodes for the truncated Gaussian. The radiance is analytic (smooth) over the visible region,
//! which the form check guarantees, so these rules are exact to ~1e-12 relative.

use crate::sample::filter::{Filter, GAUSSIAN_RADIUS, GAUSSIAN_SIGMA};
use crate::scene::{Light, Material, Profile, Scene, Shape, Texture};
use glam::DVec3;
use std::f64::consts::PI;

/// Nodes and weights of the `n`-point Gauss-Legendre rule on `[-1, 1]`, by Newton's method on the
/// Legendre polynomial (three-term recurrence), from the Tricomi initial guesses.
pub fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0f64, x);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            let pn = if n == 0 { 1.0 } else { p1 };
            let pn1 = if n == 0 { 0.0 } else { p0 };
            dp = n as f64 * (x * pn - pn1) / (x * x - 1.0);
            let dx = pn / dp;
            x -= dx;
            if dx.abs() < 1e-16 {
                break;
            }
        }
        out.push((x, 2.0 / ((1.0 - x * x) * dp * dp)));
    }
    out
}

/// Irradiance at `x` (unit normal `n`) from a polygon of unit radiance: its projected solid angle.
/// The winding does not matter (the absolute value is taken); every vertex must be above `x`'s tangent
/// plane. The angle is `atan2(|a x b|, a . b)`, accurate for small and near-straight angles alike.
pub fn polygon_irradiance(x: DVec3, n: DVec3, verts: &[DVec3]) -> f64 {
    let mut sum = 0.0;
    for (i, v) in verts.iter().enumerate() {
        let a = *v - x;
        let b = verts[(i + 1) % verts.len()] - x;
        let c = a.cross(b);
        let len = c.length();
        if len > 0.0 {
            sum += len.atan2(a.dot(b)) * n.dot(c / len);
        }
    }
    0.5 * sum.abs()
}

/// How a pixel's expected value relates to the radiance over the image plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Footprint {
    /// The pixel integral is held at the centre sample.
    Centre,
    /// The pixel integral is sampled: the filter-weighted average over the footprint.
    Filter(Filter),
}

/// A scene of the analytic form, in f64.
#[derive(Clone, Debug)]
pub struct QuadIrradiance {
    cam_pos: DVec3,
    forward: DVec3,
    right: DVec3,
    up: DVec3,
    half_w: f64,
    half_h: f64,
    width: u32,
    height: u32,
    /// Plane `normal . p = offset`, normal turned towards the camera.
    normal: DVec3,
    offset: f64,
    albedo: DVec3,
    corners: [DVec3; 4],
    /// The light's emitting side.
    light_normal: DVec3,
    radiance: DVec3,
    /// The light integral is held at one `center` sample: the quad acts as a point at its centre.
    light_at_centre: bool,
}

impl QuadIrradiance {
    /// Check that `scene` (rendered with `profile`) is of the analytic form and extract it; the error
    /// says what is missing.
    pub fn from_scene(scene: &Scene, profile: &Profile) -> Result<QuadIrradiance, String> {
        let why = |m: String| format!("--reference analytic needs a Lambert plane lit by one quad light and nothing else: {m}");
        let (quad, radiance) = match scene.lights.as_slice() {
            [Light::Quad { quad, radiance }] => (*quad, *radiance),
            [_] => return Err(why("the light is not a quad light".into())),
            l => return Err(why(format!("found {} lights", l.len()))),
        };
        let others: Vec<_> = scene.prims.iter().filter(|p| !p.is_light).collect();
        let [plane_prim] = others.as_slice() else {
            return Err(why(format!("found {} shapes besides the light", others.len())));
        };
        let Shape::Plane(plane) = plane_prim.shape else {
            return Err(why("the shape is not a plane".into()));
        };
        let albedo = match scene.materials[plane_prim.material as usize] {
            Material::Lambert { albedo: Texture::Constant(a) } => a.as_dvec3(),
            Material::Lambert { .. } => return Err(why("the plane's albedo is not constant".into())),
            _ => return Err(why("the plane's material is not lambert".into())),
        };
        let cam = &scene.camera;
        if cam.lens_radius > 0.0 {
            return Err(why("the camera has an aperture (the form assumes a pinhole)".into()));
        }
        if profile.diffuse_depth > 0 && scene.background != glam::Vec3::ZERO {
            return Err(why("diffuse bounces would gather the non-black background".into()));
        }
        let n_len = plane.normal.as_dvec3().length();
        let mut normal = plane.normal.as_dvec3() / n_len;
        let mut offset = plane.offset as f64 / n_len;
        let cam_pos = cam.position.as_dvec3();
        let side = normal.dot(cam_pos) - offset;
        if side == 0.0 {
            return Err(why("the camera lies in the plane".into()));
        }
        if side < 0.0 {
            normal = -normal;
            offset = -offset;
        }
        let (o, u, v) = (quad.origin.as_dvec3(), quad.u.as_dvec3(), quad.v.as_dvec3());
        let corners = [o, o + u, o + u + v, o + v];
        if corners.iter().any(|c| normal.dot(*c) - offset <= 0.0) {
            return Err(why("the light is not entirely on the camera's side of the plane".into()));
        }
        let form = QuadIrradiance {
            cam_pos,
            forward: cam.forward.as_dvec3(),
            right: cam.right.as_dvec3(),
            up: cam.up.as_dvec3(),
            half_w: cam.half_w as f64,
            half_h: cam.half_h as f64,
            width: cam.width,
            height: cam.height,
            normal,
            offset,
            albedo,
            corners,
            light_normal: u.cross(v).normalize(),
            radiance: radiance.as_dvec3(),
            light_at_centre: false,
        };
        // The region the filter can reach: the image grown by the filter radius.
        let r = profile.filter.radius() as f64;
        let (w, h) = (cam.width as f64, cam.height as f64);
        let rect = [(-r, -r), (w + r, -r), (w + r, h + r), (-r, h + r)];
        let dirs = rect.map(|(x, y)| form.direction(x, y));
        for d in dirs {
            let denom = d.dot(normal);
            if denom >= 0.0 {
                return Err(why("the horizon is in view (some camera rays miss the plane)".into()));
            }
            let p = cam_pos + d * ((offset - normal.dot(cam_pos)) / denom);
            if (p - corners[0]).dot(form.light_normal) <= 0.0 {
                return Err(why("part of the visible plane is behind the one-sided light".into()));
            }
        }
        if !form.light_outside_frustum(&dirs) {
            return Err(why("the light may be visible to the camera".into()));
        }
        Ok(form)
    }

    /// The light is invisible if all its corners are behind the camera or outside one side of the frustum
    /// (a separating plane through the eye). Conservative: a light this cannot prove invisible is refused.
    fn light_outside_frustum(&self, dirs: &[DVec3; 4]) -> bool {
        let rel = self.corners.map(|c| c - self.cam_pos);
        if rel.iter().all(|c| c.dot(self.forward) <= 0.0) {
            return true;
        }
        (0..4).any(|i| {
            // Inward normal of the side plane through dirs[i], dirs[i+1] (the rectangle winds clockwise
            // on screen); orient it by the frustum's central direction.
            let mut m = dirs[i].cross(dirs[(i + 1) % 4]);
            if m.dot(self.forward) < 0.0 {
                m = -m;
            }
            rel.iter().all(|c| c.dot(m) <= 0.0)
        })
    }

    /// Hold the light integral at its centre sample (the renderer's `center` light strategy): the
    /// irradiance is then `L A cos_x cos_l / d^2` from the quad's centre.
    pub fn with_light_at_centre(mut self, yes: bool) -> QuadIrradiance {
        self.light_at_centre = yes;
        self
    }

    /// Camera direction (unnormalised) through the raster point (x, y), as the renderer's pinhole.
    fn direction(&self, x: f64, y: f64) -> DVec3 {
        let sx = (2.0 * x / self.width as f64 - 1.0) * self.half_w;
        let sy = (1.0 - 2.0 * y / self.height as f64) * self.half_h;
        self.forward + self.right * sx + self.up * sy
    }

    /// Radiance seen through the raster point (x, y).
    pub fn radiance_at(&self, x: f64, y: f64) -> DVec3 {
        let d = self.direction(x, y);
        let denom = d.dot(self.normal);
        if denom >= 0.0 {
            return DVec3::ZERO;
        }
        let p = self.cam_pos + d * ((self.offset - self.normal.dot(self.cam_pos)) / denom);
        self.radiance_at_point(p)
    }

    /// Outgoing radiance of the plane point `p` (towards the camera side).
    pub fn radiance_at_point(&self, p: DVec3) -> DVec3 {
        if (p - self.corners[0]).dot(self.light_normal) <= 0.0 {
            return DVec3::ZERO;
        }
        let e = if self.light_at_centre {
            let [o, a, _, b] = self.corners;
            let (u, v) = (a - o, b - o);
            let y = o + 0.5 * (u + v);
            let d = y - p;
            let d2 = d.length_squared();
            let wi = d / d2.sqrt();
            let (cos_x, cos_l) = (self.normal.dot(wi).max(0.0), (-wi.dot(self.light_normal)).max(0.0));
            cos_x * cos_l * u.cross(v).length() / d2
        } else {
            polygon_irradiance(p, self.normal, &self.corners)
        };
        self.albedo * self.radiance * (e / PI)
    }

    /// The expected value of pixel (px, py).
    pub fn pixel(&self, px: u32, py: u32, footprint: Footprint) -> DVec3 {
        let (cx, cy) = (px as f64 + 0.5, py as f64 + 0.5);
        let f = |dx: f64, dy: f64| self.radiance_at(cx + dx, cy + dy);
        match footprint {
            Footprint::Centre => f(0.0, 0.0),
            Footprint::Filter(Filter::Box) => {
                let gl = gauss_legendre(8);
                let mut s = DVec3::ZERO;
                for &(xi, wi) in &gl {
                    for &(yj, wj) in &gl {
                        s += f(0.5 * xi, 0.5 * yj) * (wi * wj);
                    }
                }
                s * 0.25
            }
            Footprint::Filter(Filter::Tent) => {
                // Per axis: [0, 1] with weight (1 - t), mirrored; nodes t = (xi + 1) / 2.
                let gl: Vec<(f64, f64)> = gauss_legendre(8).into_iter().map(|(x, w)| (0.5 * (x + 1.0), 0.5 * w)).collect();
                let mut s = DVec3::ZERO;
                for &(tx, wx) in &gl {
                    for &(ty, wy) in &gl {
                        let w = wx * (1.0 - tx) * wy * (1.0 - ty);
                        s += (f(tx, ty) + f(-tx, ty) + f(tx, -ty) + f(-tx, -ty)) * w;
                    }
                }
                s
            }
            Footprint::Filter(Filter::Gaussian) => {
                // Polar: radial Gauss-Legendre on [0, R] with the normalised density, trapezoid in angle
                // (spectrally accurate for a periodic integrand).
                let (rmax, two_s2) = (GAUSSIAN_RADIUS as f64, 2.0 * (GAUSSIAN_SIGMA as f64).powi(2));
                let mass = 1.0 - (-rmax * rmax / two_s2).exp();
                let gl = gauss_legendre(16);
                let na = 32;
                let mut s = DVec3::ZERO;
                for &(xi, wi) in &gl {
                    let r = 0.5 * rmax * (xi + 1.0);
                    let pdf = (-r * r / two_s2).exp() / (PI * two_s2 * mass);
                    let wr = 0.5 * rmax * wi * pdf * r * (2.0 * PI / na as f64);
                    for k in 0..na {
                        let a = 2.0 * PI * (k as f64 + 0.5) / na as f64;
                        s += f(r * a.cos(), r * a.sin()) * wr;
                    }
                }
                s
            }
        }
    }

    /// The whole image, row-major.
    pub fn image(&self, footprint: Footprint) -> Vec<DVec3> {
        (0..self.height).flat_map(|y| (0..self.width).map(move |x| (x, y))).map(|(x, y)| self.pixel(x, y, footprint)).collect()
    }
}
