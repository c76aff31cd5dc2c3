//! Scenes: the TOML format (`format`), validation and compilation into flat arrays (`compile`), and the
//! quality profiles (`profile`). Kernels never see parser types: they see [`Scene`].

pub mod compile;
pub mod error;
pub mod format;
pub mod glass_neighbours;
pub mod leaf_spheres;
pub mod profile;
pub mod sections;

pub use compile::{load_scene, load_scene_sized, parse_scene, parse_scene_sized, MAX_CSG_LEAVES};
pub use error::InputError;
pub use profile::{Branching, LightSelection, Profile, MAX_DEPTH, MAX_LIGHT_SAMPLES, MAX_SPP};

use crate::accel::{Aabb, Bvh, WideBvh};
use crate::camera::Camera;
use crate::csg::Csg;
use crate::geometry::{Disk, Ellipsoid, OBox, Plane, Quad};
use crate::optics::Ior;
use crate::simd::{f32x8, Vec3x8};
use glam::Vec3;

/// Shift of the checker cells, in cells (see [`Texture::eval`]).
pub const CHECKER_SHIFT: f32 = 1.0 / 1024.0;

/// Surface reflectance that may vary over the surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Texture {
    Constant(Vec3),
    /// A 3D checkerboard of cells of size `scale` (world units), alternating `a` and `b`.
    Checker {
        a: Vec3,
        b: Vec3,
        scale: f32,
    },
}

impl Texture {
    #[inline]
    pub fn eval(&self, p: Vec3) -> Vec3 {
        match *self {
            Texture::Constant(c) => c,
            Texture::Checker { a, b, scale } => {
                // Cells are shifted by 1/1024 of a cell: the common surfaces (a floor at y = 0, a wall at a
                // multiple of the cell size) lie exactly on a cell boundary, where the parity would flip with
                // the sign of the hit point's rounding error (noise that depends on the ray's origin).
                let q = (p / scale + Vec3::splat(CHECKER_SHIFT)).floor();
                if checker_parity(q) == 0 {
                    a
                } else {
                    b
                }
            }
        }
    }
}

impl Texture {
    /// The texture as checker parameters `(a, b, scale)` for [`checker_eval_x8`]: a constant is a
    /// checker whose two colours are equal.
    #[inline(always)]
    pub fn checker_params(&self) -> (Vec3, Vec3, f32) {
        match *self {
            Texture::Constant(c) => (c, c, 1.0),
            Texture::Checker { a, b, scale } => (a, b, scale),
        }
    }
}

/// Eight lanes of [`Texture::eval`] from [`Texture::checker_params`] per lane (`a`, `b`, `scale`) at
/// points `p`: the same operations (so the same cells and the same colours) as the scalar.
#[inline(always)]
pub fn checker_eval_x8(a: Vec3x8, b: Vec3x8, scale: f32x8, p: Vec3x8) -> Vec3x8 {
    let shift = f32x8::splat(CHECKER_SHIFT);
    let q = Vec3x8::new((p.x / scale + shift).floor(), (p.y / scale + shift).floor(), (p.z / scale + shift).floor());
    let (half, two) = (f32x8::splat(0.5), f32x8::splat(2.0));
    let par = |v: f32x8| v - (v * half).floor() * two;
    let s = par(q.x) + par(q.y) + par(q.z);
    let odd = s.simd_eq(f32x8::ONE) | s.simd_eq(f32x8::splat(3.0));
    Vec3x8::select(odd, b, a)
}

/// Parity (0 or 1) of `q.x + q.y + q.z` for integer-valued `q`, in float operations, exact for every
/// finite float: each component's parity is `q - 2 floor(q / 2)` (exact: halving, flooring and
/// doubling an integer-valued float lose nothing), and the sum of three parities is odd when it is 1
/// or 3. Equal to `(q.x as i64 + q.y as i64 + q.z as i64).rem_euclid(2)` wherever that does not
/// saturate (`|q| < 2^63`), without the three float-to-integer conversions.
#[inline(always)]
pub fn checker_parity(q: Vec3) -> u32 {
    let par = q - (q * 0.5).floor() * 2.0;
    let s = par.x + par.y + par.z;
    (s == 1.0 || s == 3.0) as u32
}

/// Materials, by kind. Shading partitions hits by [`Material::kind`] and runs one loop per kind.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Material {
    Lambert {
        albedo: Texture,
    },
    Mirror {
        tint: Vec3,
    },
    /// GGX microfacet reflection, tinted; `alpha` = roughness^2.
    Glossy {
        tint: Vec3,
        alpha: f32,
    },
    Dielectric(Dielectric),
    Emissive {
        radiance: Vec3,
    },
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dielectric {
    pub ior: Ior,
    /// Absorption coefficient per unit distance (Beer-Lambert), per channel.
    pub sigma_a: Vec3,
    /// A thin sheet (window pane): reflects and transmits without bending.
    pub thin: bool,
    /// Schlick's approximation instead of the exact Fresnel equations.
    pub schlick: bool,
    /// Interface priority (Schmidt & Budge 2002): where media overlap, the one with the higher priority
    /// is the medium there; the surfaces of outranked media inside it are null crossings.
    pub priority: i32,
    /// A shadow ray may cross this material's surfaces without being deflected somewhere in the scene
    /// (a thin sheet, an index matching air or another medium, or an outranked medium): physical shadow
    /// rays then walk through it instead of stopping at it. Derived by `compile`.
    pub passable: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum MaterialKind {
    Lambert = 0,
    Mirror = 1,
    Glossy = 2,
    Dielectric = 3,
    Emissive = 4,
}

impl MaterialKind {
    pub const COUNT: usize = 5;
}

impl Material {
    pub fn kind(&self) -> MaterialKind {
        match self {
            Material::Lambert { .. } => MaterialKind::Lambert,
            Material::Mirror { .. } => MaterialKind::Mirror,
            Material::Glossy { .. } => MaterialKind::Glossy,
            Material::Dielectric(_) => MaterialKind::Dielectric,
            Material::Emissive { .. } => MaterialKind::Emissive,
        }
    }
}

/// Geometry of one primitive, in world space (or placed by an affine that the kernel applies).
#[derive(Clone, Copy, Debug)]
pub enum Shape {
    Sphere {
        center: Vec3,
        radius: f32,
    },
    Ellipsoid(Ellipsoid),
    Plane(Plane),
    Quad(Quad),
    Disk(Disk),
    Box(OBox),
    /// A CSG solid: the intersect stage only tests its bounds; `csg_merge` finds the surface.
    Csg {
        solid: u32,
    },
}

#[derive(Clone, Copy, Debug)]
pub struct Prim {
    pub shape: Shape,
    pub material: u32,
    /// World-space velocity over the shutter (zero for static prims): the prim sits at `shape + motion * time`.
    pub motion: Vec3,
    /// Emission of this prim is also sampled as a light (next-event estimation): paths that reach it by a
    /// diffuse bounce must not count it again.
    pub is_light: bool,
}

/// What Lambert shading reads of a prim, 32 bytes (the [`Prim`] is 176: two cache lines per hit, read
/// at random): a sphere's centre and radius, or a flat prim's (plane, quad, disk) outward normal with
/// `r = -1`, or `r = NaN` for every other shape (shaded from the whole prim); its motion and material.
#[repr(C, align(32))]
#[derive(Clone, Copy, Debug)]
pub struct PrimGeo {
    pub v: Vec3,
    pub r: f32,
    pub motion: Vec3,
    pub material: u32,
    /// Flat prims: the plane `v . x = w` (at time 0), and the magnitude whose ULPs bound a point projected
    /// onto it (its defining point's largest coordinate; see [`crate::geometry::refine_flat_point`]).
    pub w: f32,
    pub w_scale: f32,
}

impl PrimGeo {
    pub fn of(p: &Prim) -> PrimGeo {
        let (v, r, (w, w_scale)) = match &p.shape {
            Shape::Sphere { center, radius } => (*center, *radius, (0.0, 0.0)),
            Shape::Plane(pl) => (pl.normal, -1.0, (pl.offset, pl.offset.abs())),
            Shape::Quad(q) => (q.normal(), -1.0, flat_plane(q.normal(), q.origin)),
            Shape::Disk(d) => (d.normal, -1.0, flat_plane(d.normal, d.center)),
            _ => (Vec3::ZERO, f32::NAN, (0.0, 0.0)),
        };
        PrimGeo { v, r, motion: p.motion, material: p.material, w, w_scale }
    }
}

/// The plane offset `n . point` and the magnitude of a projected point's error for a flat prim
/// through `point` with unit normal `n`.
fn flat_plane(n: Vec3, point: Vec3) -> (f32, f32) {
    let w = n.dot(point);
    (w, point.abs().max_element().max(w.abs()))
}

/// Light sources sampled by the shadow stage.
#[derive(Clone, Copy, Debug)]
pub enum Light {
    /// Intensity in W/sr per channel.
    Point { position: Vec3, intensity: Vec3 },
    /// One-sided parallelogram emitting `radiance` towards `quad.normal()`.
    Quad { quad: Quad, radiance: Vec3 },
    /// One-sided disk emitting towards its normal.
    Disk { disk: Disk, radiance: Vec3 },
    /// A sphere emitting outwards.
    Sphere { center: Vec3, radius: f32, radiance: Vec3 },
}

impl Light {
    /// A point light: one position, so its one sample needs no random numbers (all others are area
    /// lights, sampled over their surface).
    #[inline]
    pub fn is_point(&self) -> bool {
        matches!(self, Light::Point { .. })
    }
}

/// Which stages and kernels this scene needs. The pipeline skips what is absent.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Features {
    pub csg: bool,
    pub dielectric: bool,
    pub dispersion: bool,
    pub glossy: bool,
    pub mirror: bool,
    pub point_lights: bool,
    pub area_lights: bool,
    pub motion: bool,
    pub lens: bool,
    pub planes: bool,
}

/// [`Scene::light_of_prim`] of a prim that is no light's surface.
pub const NOT_A_LIGHT: u32 = u32::MAX;

/// A medium the camera is inside ([`Scene::camera_media`]): its material and the shutter times at which
/// it holds the camera, `[from, to)`, or [`CameraMedium::ALWAYS`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraMedium {
    pub material: u32,
    pub during: [f32; 2],
}

impl CameraMedium {
    /// A medium that holds the camera through the whole shutter (it does not move past the camera).
    pub const ALWAYS: [f32; 2] = [f32::NEG_INFINITY, f32::INFINITY];

    /// Whether it holds the camera at shutter time `t`.
    #[inline]
    pub fn holds_at(&self, t: f32) -> bool {
        self.during[0] <= t && t < self.during[1]
    }
}

/// A compiled scene: flat arrays, a BVH over the bounded primitives, and the features it uses.
pub struct Scene {
    pub width: u32,
    pub height: u32,
    pub background: Vec3,
    pub camera: Camera,
    pub materials: Vec<Material>,
    pub prims: Vec<Prim>,
    /// World bounds of each prim (swept over the shutter for moving prims); empty for planes.
    pub bounds: Vec<Aabb>,
    /// The BVH indexes `bounded` (prim ids); unbounded prims (planes) are tested against every packet.
    pub bvh: Bvh,
    /// The same tree collapsed to `accel::WIDTH` (16 or 8) children per node (`wavefront::intersect`): camera rays traverse it
    /// in groups of packets, incoherent rays as single packets when `wide_incoherent`.
    pub wide_bvh: WideBvh,
    /// Whether incoherent queues take `wide_bvh`: `bvh` has at least `accel::WIDE_MIN_NODES` nodes (below,
    /// groups through the binary tree are faster for them).
    pub wide_incoherent: bool,
    /// Per prim, what Lambert shading reads of it ([`PrimGeo`]).
    pub prim_geo: Vec<PrimGeo>,
    /// The leaves' static spheres as lanes, per slot of `bvh.indices` (single-ray shadow tests).
    pub leaf_spheres: leaf_spheres::LeafSpheres,
    /// Per light: its light buffer over the bounded prims (point lights only; the shadow stage answers
    /// their shadow rays from it where they walk through nothing).
    pub light_buffers: Vec<Option<crate::accel::LightBuffer>>,
    pub bounded: Vec<u32>,
    pub unbounded: Vec<u32>,
    pub csg: Csg,
    pub lights: Vec<Light>,
    pub features: Features,
    /// The kind of each prim's material (for a CSG prim, of its `material` field; its hits take their
    /// leaf's, `leaf_kind`): the shading stage sorts hits by it without following two indices.
    pub prim_kind: Vec<MaterialKind>,
    /// The kind of each CSG leaf's material (global leaf ids).
    pub leaf_kind: Vec<MaterialKind>,
    /// Per prim with a dielectric surface, the opaque prims (unbounded planes included) that its glass
    /// faces may lie on and give way to (`wavefront::intersect::glass_gives_way`); empty in a scene
    /// where no glass can touch an opaque surface.
    pub glass_neighbours: glass_neighbours::GlassNeighbours,
    /// The media the camera is inside (the non-thin dielectric solids that contain its position at some
    /// time of the shutter), outermost first: camera rays start with those that hold it at their time on
    /// their medium stack ([`Scene::camera_media_at`]). Empty for a camera in air (nearly always).
    pub camera_media: Vec<CameraMedium>,
    /// Valid input that is likely not what was meant (an empty CSG solid), each naming its file, line
    /// and field; the CLI prints them as warnings.
    pub warnings: Vec<String>,
    /// A stable hash of the scene file text (films from different scenes are never merged).
    pub hash: u64,
    /// Per prim, the light it is the surface of (area lights), else [`NOT_A_LIGHT`].
    pub light_of_prim: Vec<u32>,
    /// Where the fields that the render's own warnings name were given (`camera.shutter`,
    /// `image.background`; where the file leaves one out, its table's header), each an `InputError` with
    /// no message yet: see [`Scene::located`].
    pub sites: Vec<InputError>,
}

impl Scene {
    /// The medium stack a camera ray of shutter time `t` starts with: the innermost
    /// [`MediumStack::DEPTH`](crate::wavefront::queues::MediumStack::DEPTH) of the media that hold the camera at `t`, outermost first.
    pub fn camera_media_at(&self, t: f32) -> crate::wavefront::queues::MediumStack {
        let holds = |m: &&CameraMedium| m.holds_at(t);
        let n = self.camera_media.iter().filter(holds).count();
        let skip = n.saturating_sub(crate::wavefront::queues::MediumStack::DEPTH);
        self.camera_media.iter().filter(holds).skip(skip).fold(Default::default(), |s, m| s.push(m.material))
    }

    /// Whether the scene has moving shapes but a shutter of zero length (the default `[0, 0]` too, for
    /// which `features.motion` is off): every time sample is one instant.
    pub fn motion_at_one_instant(&self) -> bool {
        let [t0, t1] = self.camera.shutter;
        !(t1 > t0) && self.prims.iter().any(|p| p.motion != Vec3::ZERO)
    }

    /// A warning about `field` (one of [`Scene::sites`]), located as an error there would be:
    /// `file:line:col: field `camera.shutter`: message` (a user trial's zero-length shutter was warned of
    /// with no file or line); the bare message for a field not recorded.
    pub fn located(&self, field: &str, message: String) -> String {
        match self.sites.iter().find(|e| e.field == field) {
            Some(site) => InputError { message, ..site.clone() }.to_string(),
            None => message,
        }
    }

    /// Whether some medium holds the camera for part of the shutter only, so that camera rays' media
    /// depend on their time.
    pub fn camera_media_move(&self) -> bool {
        self.camera_media.iter().any(|m| m.during != CameraMedium::ALWAYS)
    }

    /// Whether anything in the scene gives light: a light, an emissive material or a background that
    /// is not black (what [`crate::film::warn_dim`] needs to tell a dim image from an unlit one).
    pub fn has_light(&self) -> bool {
        !self.lights.is_empty()
            || self.background != Vec3::ZERO
            || self.materials.iter().any(|m| matches!(m, Material::Emissive { radiance } if *radiance != Vec3::ZERO))
    }
}

/// Limits that protect the machine; exceeding one is an input error.
pub const MAX_IMAGE_SIDE: i64 = 16384;
/// Largest image, in pixels (2^25: 8192 x 4096; 8K UHD fits). The film keeps
/// [`crate::film::FILM_BYTES_PER_PIXEL`] = 64 bytes per pixel (exact fixed-point sums and sums of
/// squares), 2.1 GB at this limit; a 16384 x 16384 film would take 17 GB.
pub const MAX_PIXELS: u64 = 1 << 25;
pub const MAX_PRIMS: usize = 10_000_000;

impl std::fmt::Debug for Scene {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Scene")
            .field("width", &self.width)
            .field("height", &self.height)
            .field("prims", &self.prims.len())
            .field("csg_solids", &self.csg.solid_count())
            .field("lights", &self.lights.len())
            .field("features", &self.features)
            .finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::LANES;

    /// [`checker_eval_x8`] against [`Texture::eval`] lane by lane: checkers of several scales (and a
    /// constant) at points on cell boundaries, near zero and far away; same colour in every lane.
    #[test]
    fn checker_x8_matches_scalar() {
        let texs = [
            Texture::Checker { a: Vec3::new(0.9, 0.1, 0.2), b: Vec3::new(0.1, 0.8, 0.3), scale: 0.5 },
            Texture::Checker { a: Vec3::ONE, b: Vec3::ZERO, scale: 1e-3 },
            Texture::Checker { a: Vec3::splat(0.25), b: Vec3::splat(0.75), scale: 7.0 },
            Texture::Constant(Vec3::new(0.3, 0.4, 0.5)),
        ];
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        let (mut checked, mut odd) = (0, 0);
        for round in 0..2000 {
            let pts: [Vec3; LANES] = std::array::from_fn(|l| {
                let r = next();
                let mag = [1.0f32, 0.5, 1e4, 1e-4][(r % 4) as usize];
                let c = |k: u32| (((r >> (8 + 16 * k)) & 0xffff) as f32 / 32768.0 - 1.0) * mag;
                // Every fourth lane exactly on a cell boundary.
                if l % 4 == 0 {
                    (Vec3::new(c(0), c(1), c(2)) * 4.0).round() * 0.5
                } else {
                    Vec3::new(c(0), c(1), c(2))
                }
            });
            let texs_l: [Texture; LANES] = std::array::from_fn(|l| texs[(round + l) % texs.len()]);
            let params = texs_l.map(|t| t.checker_params());
            let lane3 = |f: &dyn Fn(usize) -> Vec3| {
                let v: [Vec3; LANES] = std::array::from_fn(f);
                Vec3x8::new(f32x8::from(v.map(|u| u.x)), f32x8::from(v.map(|u| u.y)), f32x8::from(v.map(|u| u.z)))
            };
            let got =
                checker_eval_x8(lane3(&|l| params[l].0), lane3(&|l| params[l].1), f32x8::from(params.map(|p| p.2)), lane3(&|l| pts[l]));
            for l in 0..LANES {
                let want = texs_l[l].eval(pts[l]);
                assert_eq!(got.lane(l), want, "{:?} at {}", texs_l[l], pts[l]);
                odd += (want == params[l].1 && params[l].0 != params[l].1) as u32;
                checked += 1;
            }
        }
        assert!(checked == 16_000 && odd > 2000, "both colours must occur: {odd}");
    }

    #[test]
    fn checker_parity_matches_integer_parity() {
        let mut x = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        for k in 0..20_000 {
            // Integers of every magnitude up to 2^62, both signs, and small ones around zero.
            let v = [0; 3].map(|_| {
                let r = next();
                let mag = if k % 2 == 0 { (r % 64) as f32 - 32.0 } else { ((r >> 8) as f32) * 2f32.powi((r % 40) as i32 - 40) };
                (if r & 1 == 0 { mag } else { -mag }).floor()
            });
            let q = Vec3::from_array(v);
            let want = (q.x as i64 + q.y as i64 + q.z as i64).rem_euclid(2) as u32;
            assert_eq!(checker_parity(q), want, "{q}");
        }
    }
}
