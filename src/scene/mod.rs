//! Scenes: the TOML format (`format`), validation and compilation into flat arrays (`compile`), and the
//! quality profiles (`profile`). Kernels never see parser types: they see [`Scene`].

pub mod compile;
pub mod error;
pub mod format;
pub mod profile;

pub use compile::{load_scene, parse_scene};
pub use error::InputError;
pub use profile::{Branching, Profile};

use crate::accel::{Aabb, Bvh, Bvh8};
use crate::camera::Camera;
use crate::csg::Csg;
use crate::geometry::{Disk, Ellipsoid, OBox, Plane, Quad};
use crate::optics::Ior;
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
                // i64 parity: cells far from the origin stay exact.
                let s = q.x as i64 + q.y as i64 + q.z as i64;
                if s.rem_euclid(2) == 0 {
                    a
                } else {
                    b
                }
            }
        }
    }
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
    /// The same tree collapsed to 8 children per node, for incoherent rays (`wavefront::intersect`);
    /// empty when `bvh` has fewer than `accel::WIDE_MIN_NODES` nodes (groups are faster there).
    pub bvh8: Bvh8,
    pub bounded: Vec<u32>,
    pub unbounded: Vec<u32>,
    pub csg: Csg,
    pub lights: Vec<Light>,
    pub features: Features,
    /// A stable hash of the scene file text (films from different scenes are never merged).
    pub hash: u64,
}

/// Limits that protect the machine; exceeding one is an input error.
pub const MAX_IMAGE_SIDE: i64 = 16384;
/// Largest image, in pixels (2^25: 8192 x 4096; 8K UHD fits). The film keeps `size_of::<film::Pixel>()`
/// = 112 bytes per pixel (exact fixed-point sums and sums of squares), 3.75 GB at this limit; a 16384 x
/// 16384 film would take 30 GB.
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
