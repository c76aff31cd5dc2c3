//! Validation and compilation of a parsed scene file into a flat [`Scene`].
//!
//! Every check names the field (`shapes[2].children[0].radius`) and its line and column.

use super::error::{a_or_an, read_text, InputError, Source};
use super::format::{CameraDef, Field, LightDef, MaterialDef, Nums, SceneFile, ShapeDef, TransformDef, S, V3};
use super::{
    CameraMedium, Dielectric, Features, Light, Material, MaterialKind, Prim, Scene, Shape, Texture, MAX_IMAGE_SIDE, MAX_PIXELS, MAX_PRIMS,
    NOT_A_LIGHT,
};
use crate::accel::{build_bvh, Aabb, Bound, BuildOptions, Collapse, LightBuffer, WideBvh, WIDE_MIN_NODES};
use crate::camera::Camera;
use crate::csg::{self, Csg, CsgTree, Op};
use crate::film::MAX_SAMPLE_VALUE;
use crate::geometry::{Disk, Ellipsoid, OBox, Plane, Quad};
use crate::optics::{sigma_from_transmittance, Ior};
use glam::{Affine3A, EulerRot, Mat3, Quat, Vec3};
use std::collections::{BTreeMap, BTreeSet};
use std::fmt::{self, Display};
use std::ops::Range;
use std::path::Path;

type R<T> = Result<T, InputError>;

/// Largest magnitude of a dielectric's `priority`.
pub const MAX_PRIORITY: i64 = 1_000_000;

/// Deepest CSG nesting (and chain of named-solid references) accepted.
pub const MAX_CSG_DEPTH: usize = 64;

/// The most CSG leaves a scene may hold, counted as its `use`s expand, before any is built: a trial's
/// seven levels of named solids, each a union of ten uses of the one before, made 10^7 leaves and
/// aborted out of memory (a 3 GB allocation) after 25 s. Measured, one thread (AMD EPYC, 2 cores): one
/// solid of 10^6 sphere leaves (a 100^3 grid of uses of uses, or 10^6 overlapping ones) sets up in
/// 5.0-5.1 s with 0.8 GB at its peak and renders 32 x 24 in 0.04-0.3 s; 2 x 10^6 took 8.0 s and 1.6 GB,
/// 10^5 0.8 s.
pub const MAX_CSG_LEAVES: u64 = 1_000_000;
/// Rays per side of the grid on each axis with which a CSG solid is probed for volume (an empty one is
/// warned about): `3 n^2` rays at most, one for most solids.
const EMPTY_PROBE_GRID: u32 = 24;

/// Largest coordinate or length a scene may hold, before and after its transforms: the sphere kernel
/// takes squares of differences of coordinates, which overflow f32 a little beyond (a ground sphere of
/// radius 1e16 loses a third of its hits). Fidelity is measured to 1e5 ("Numerical robustness").
pub const MAX_MAGNITUDE: f32 = 1e15;
/// Largest rotation angle in degrees (1000 turns).
const MAX_DEGREES: f32 = 360_000.0;
const BEYOND: &str = "beyond that the kernels' f32 squares overflow";

/// Read, parse, validate and compile a scene file.
pub fn load_scene(path: &Path) -> R<Scene> {
    load_scene_sized(path, None)
}

/// [`load_scene`] at `size` (width, height) instead of the file's `[image]` size, when given (the
/// CLI's `--size`; the caller checks its limits). The camera keeps its `fov`: a new aspect ratio shows
/// more or less of the scene across, as in the file.
pub fn load_scene_sized(path: &Path, size: Option<(u32, u32)>) -> R<Scene> {
    let text = read_text(path)?;
    parse_scene_sized(path, &text, size)
}

/// Parse, validate and compile scene text; `path` is used in error messages.
pub fn parse_scene(path: &Path, text: &str) -> R<Scene> {
    parse_scene_sized(path, text, None)
}

/// [`parse_scene`] at `size` instead of the file's image size, when given.
pub fn parse_scene_sized(path: &Path, text: &str, size: Option<(u32, u32)>) -> R<Scene> {
    let src = Source { path, text };
    let file: SceneFile = super::sections::read_scene_file(text).map_err(|e| src.from_toml(&e))?;
    let mut c = Compiler {
        src: &src,
        file: &file,
        material_ids: BTreeMap::new(),
        materials: Vec::new(),
        prims: Vec::new(),
        csg: Csg::new(),
        lights: Vec::new(),
        used_solids: BTreeSet::new(),
        lenient_material: false,
        size,
        unbounded_by: None,
        warnings: Vec::new(),
        counted: Vec::new(),
        checkers: Default::default(),
        prim_at: Vec::new(),
        leaf_counts: BTreeMap::new(),
        lone_differences: BTreeSet::new(),
        thin_probe_budget: THIN_PROBE_BUDGET,
        empty_probe_budget: EMPTY_PROBE_BUDGET,
        leaf_sites: Vec::new(),
        material_from: None,
    };
    c.compile(hash_text(text))
}

fn hash_text(text: &str) -> u64 {
    // FNV-1a: stable across runs and platforms (std's hasher is not).
    crate::sample::hash::fnv1a(text.bytes())
}

struct Compiler<'a> {
    src: &'a Source<'a>,
    file: &'a SceneFile,
    material_ids: BTreeMap<String, u32>,
    materials: Vec<Material>,
    prims: Vec<Prim>,
    csg: Csg,
    lights: Vec<Light>,
    /// Named solids some shape uses (the others are checked on their own, after the shapes).
    used_solids: BTreeSet<String>,
    /// While checking an unused solid: a leaf may lack a material (a use would give it one).
    lenient_material: bool,
    /// The image size to use instead of the file's (`--size`).
    size: Option<(u32, u32)>,
    /// Set by each `csg_tree` call: for an unbounded subtree, the child that makes it so (its span, field
    /// and what it is); `None` for a bounded one. Names the culprit when a top-level solid is unbounded.
    unbounded_by: Option<(Range<usize>, String, String)>,
    /// What the scene says that is valid but likely not meant (`Scene::warnings`).
    warnings: Vec<String>,
    /// Warnings given per shape, by kind (`warn_each`): how many, and where the first not shown was.
    counted: Vec<(WarnKind, usize, Option<Site>)>,
    /// Checker textures' scales and where they were given, checked against the scene's extent at the end.
    checkers: std::cell::RefCell<Vec<(Range<usize>, String, f32)>>,
    /// Where each prim was given (its definition's span and field), by prim id: for warnings that name a prim.
    prim_at: Vec<(Range<usize>, PrimField)>,
    /// Per named solid, the CSG leaves its definition expands to (`csg_leaves`); `None` while counting it.
    leaf_counts: BTreeMap<String, Option<u64>>,
    /// Where differences of one operand were warned of (a named solid's, once for all its uses).
    lone_differences: BTreeSet<usize>,
    /// What is left of [`THIN_PROBE_BUDGET`] and [`EMPTY_PROBE_BUDGET`].
    thin_probe_budget: u64,
    empty_probe_budget: u64,
    /// The leaves `csg_tree` made since the last top-level solid began: each one's material, where that
    /// material was given (span and field: the leaf's own, an enclosing node's or a `use`'s) and the
    /// leaf's world bounds (`None`: a half-space): to name the leaves of a glass solid of several glasses.
    leaf_sites: Vec<LeafSite>,
    /// While `csg_tree` descends: where the material in force was given (span and field).
    material_from: Option<(Range<usize>, String)>,
}

/// Where a shape was given: its definition's span and field.
type Site = (Range<usize>, String);

/// A field's path, made into text only when an error or a warning names it: 160,000 spheres' paths
/// formatted eagerly (`shapes[i].center`, twice per field) were ~50 ms of their setup in a profile.
#[derive(Clone, Copy)]
struct Sub<P>(P, &'static str);

impl<P: Display> Display for Sub<P> {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "{}.{}", self.0, self.1)
    }
}

/// `shapes[i]`, as a [`Sub`] is made.
#[derive(Clone, Copy)]
struct Item(&'static str, usize);

impl Display for Item {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "{}[{}]", self.0, self.1)
    }
}

/// The field a prim was given under: a top-level shape's by its index (see [`Sub`]).
#[derive(Clone)]
enum PrimField {
    Shape(usize),
    Path(String),
}

impl Display for PrimField {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        match self {
            PrimField::Shape(i) => Item("shapes", *i).fmt(f),
            PrimField::Path(p) => f.write_str(p),
        }
    }
}

/// A leaf of the solid being built (see `Compiler::leaf_sites`).
struct LeafSite {
    material: u32,
    span: Range<usize>,
    field: String,
    bounds: Option<(Vec3, Vec3)>,
}

impl Compiler<'_> {
    fn err(&self, span: Range<usize>, field: impl Display, msg: impl Into<String>) -> InputError {
        self.src.error(span, field.to_string(), msg)
    }

    /// A warning (`Scene::warnings`), located as an error would be.
    fn warn(&mut self, span: Range<usize>, field: impl Display, msg: impl Into<String>) {
        let w = self.err(span, field, msg).to_string();
        self.warnings.push(w);
    }

    /// A warning that any number of shapes may earn: the first [`SHOWN_PER_KIND`] of its kind in full
    /// (`msg` is only made for those), the others counted and told in one line at the end, at the first
    /// not shown (20,000 generated solids that look empty printed 20,000 warnings).
    fn warn_each(&mut self, kind: WarnKind, span: Range<usize>, field: impl Display + Copy, msg: impl FnOnce() -> String) {
        let at = match self.counted.iter().position(|c| c.0 == kind) {
            Some(at) => at,
            None => {
                self.counted.push((kind, 0, None));
                self.counted.len() - 1
            }
        };
        let c = &mut self.counted[at];
        c.1 += 1;
        if c.1 > SHOWN_PER_KIND {
            c.2.get_or_insert_with(|| (span, field.to_string()));
            return;
        }
        self.warn(span, field, msg());
    }

    /// How many shapes earned each kind of [`Compiler::warn_each`] warning beyond those shown.
    fn tell_counted(&mut self) {
        for (kind, n, at) in std::mem::take(&mut self.counted) {
            if let Some((span, field)) = at {
                self.warn(span, field, format!("and {} more shapes from here on: {}", n - SHOWN_PER_KIND, kind.says(n)));
            }
        }
    }

    /// Whether `kind` has been earned `n` times or more.
    fn counted_at_least(&self, kind: WarnKind, n: usize) -> bool {
        self.counted.iter().any(|c| c.0 == kind && c.1 >= n)
    }

    /// Three finite numbers (colours, intensities).
    fn finite3(&self, v: &V3, field: impl Display + Copy) -> R<Vec3> {
        let a = v.get_ref().0;
        if a.iter().any(|x| !x.is_finite()) {
            return Err(self.err(
                v.span(),
                field,
                "components must be finite numbers (not NaN or inf, and within f32 range: |x| < 3.4e38)",
            ));
        }
        Ok(Vec3::from_array(a))
    }

    /// A point or vector of the scene's space: finite and within [`MAX_MAGNITUDE`].
    fn vec3(&self, v: &V3, field: impl Display + Copy) -> R<Vec3> {
        let a = self.finite3(v, field)?.to_array();
        if a.iter().any(|x| x.abs() > MAX_MAGNITUDE) {
            return Err(self.err(v.span(), field, format!("components must be within +-{MAX_MAGNITUDE:e} ({BEYOND})")));
        }
        Ok(Vec3::from_array(a))
    }

    fn color(&self, v: &V3, field: impl Display + Copy, max: Option<f32>) -> R<Vec3> {
        let c = self.finite3(v, field)?;
        if c.min_element() < 0.0 {
            return Err(self.err(v.span(), field, "colour components must not be negative"));
        }
        if let Some(m) = max {
            if c.max_element() > m {
                return Err(self.err(v.span(), field, format!("components must be at most {m} (energy conservation)")));
            }
        }
        Ok(c)
    }

    /// The background's radiance: a colour below the film's range in every component. Every camera ray
    /// that escapes makes a sample of that value, and the film discards samples at or beyond
    /// [`MAX_SAMPLE_VALUE`] (its fixed-point sums would overflow), so such a background could only ever
    /// be lost. (Emitters are not held to it: a tiny area light needs a huge radiance for its power, and
    /// a camera ray almost never sees it; a render that discards samples says so.)
    fn background(&self, v: &V3, field: impl Display + Copy) -> R<Vec3> {
        let c = self.color(v, field, None)?;
        if !(c.max_element() < MAX_SAMPLE_VALUE) {
            return Err(self.err(
                v.span(),
                field,
                format!(
                    "background components must be below {MAX_SAMPLE_VALUE:.0} (2^31, the film's range: every sample that sees it would be discarded), got {:e}{}; scale every radiance and intensity of the scene down by one factor",
                    c.max_element(),
                    if c.max_element() == MAX_SAMPLE_VALUE { " (the value as f32: the largest accepted is 2147483520)" } else { "" }
                ),
            ));
        }
        Ok(c)
    }

    fn positive(&self, v: &S<f32>, field: impl Display + Copy) -> R<f32> {
        let x = *v.get_ref();
        if !(x.is_finite() && x > 0.0) {
            return Err(self.err(v.span(), field, format!("must be a finite number > 0, got {}", self.as_read(v))));
        }
        if x > MAX_MAGNITUDE {
            return Err(self.err(v.span(), field, format!("must be at most {MAX_MAGNITUDE:e} ({BEYOND}), got {x:e}")));
        }
        Ok(x)
    }

    /// A number as it was read, for a message: `0`, or where the file's digits are not zero but round
    /// to 0 in f32 (`1e-50`), those digits and that they underflow (`got 0` for `1e-50` read as a lie).
    fn as_read(&self, v: &S<f32>) -> String {
        let x = *v.get_ref();
        let written = self.src.text.get(v.span()).unwrap_or("").trim();
        match written.replace('_', "").parse::<f64>() {
            Ok(w) if x == 0.0 && w != 0.0 => {
                format!("{written}, which underflows f32 to {x} (the smallest positive f32 is about 1.4e-45)")
            }
            _ => format!("{x}"),
        }
    }

    fn req<'b, T, F: Field<T>>(&self, v: &'b Option<F>, table: Range<usize>, field: impl Display + Copy) -> R<&'b S<T>> {
        v.as_ref().map(|f| f.spanned()).ok_or_else(|| self.err(table, field, "missing required field"))
    }

    fn compile(&mut self, hash: u64) -> R<Scene> {
        let file = self.file;
        let img = file.image.get_ref();
        let check_side = |s: &S<i64>, name: &str| -> R<u32> {
            let v = *s.get_ref();
            if !(1..=MAX_IMAGE_SIDE).contains(&v) {
                return Err(self.err(s.span(), format!("image.{name}"), format!("must be in 1..={MAX_IMAGE_SIDE}, got {v}")));
            }
            Ok(v as u32)
        };
        let (width, height) = (check_side(&img.width, "width")?, check_side(&img.height, "height")?);
        let (width, height) = self.size.unwrap_or((width, height));
        if width as u64 * height as u64 > MAX_PIXELS {
            return Err(self.err(
                img.height.span(),
                "image.height",
                format!(
                    "{width} x {height} = {} pixels; the limit is {MAX_PIXELS} (the film takes {} bytes per pixel)",
                    width as u64 * height as u64,
                    crate::film::FILM_BYTES_PER_PIXEL
                ),
            ));
        }
        let background = match &img.background {
            Some(b) => self.background(b, "image.background")?,
            None => Vec3::ZERO,
        };
        let mut camera = self.camera(&file.camera, width, height)?;
        let pixel = 2.0 * camera.half_h * camera.focus_distance / height as f32;
        // The camera's position is rounded as the lens points are (below): focus points `position + d f` to
        // ULPs of its coordinates. Where those are a fraction of a pixel at the focus distance, the plane in
        // focus is blurred (warned of, at the focus distance, where the position rounds more coarsely than
        // the aperture); where the focus distance is below the rounding of the lens points themselves, the
        // focus point is lost in it and every camera ray's direction is rounding's (a user trial's
        // focus_distance of 1e-30 rendered black, warned of as an aperture 3.9e23 pixels wide).
        let (at, focus_field) = match &file.camera.get_ref().focus_distance {
            Some(f) => (f.span(), "camera.focus_distance"),
            None => (file.camera.get_ref().look_at.span(), "camera.look_at"),
        };
        let reach = camera.position.abs().max_element();
        let lens_step = (reach + camera.lens_radius) * f32::EPSILON;
        let position_blur = reach * f32::EPSILON / pixel;
        let default = if focus_field == "camera.look_at" { " (the default focus distance: the distance to look_at)" } else { "" };
        if camera.lens_radius > 0.0 && !(camera.focus_distance > lens_step) {
            return Err(self.err(
                at,
                focus_field,
                format!(
                    "a focus distance of {:e}{default} is too small for f32 at this camera: its lens points (position {}, aperture \
                     {:e}) are rounded to ~{lens_step:.1e}, which loses the point in focus, so every camera ray's direction would be \
                     rounding's; focus farther than ~{:.1e} (a quarter of a pixel there is the rounding), or move the camera nearer \
                     the origin",
                    camera.focus_distance,
                    plain_vec(camera.position),
                    camera.lens_radius,
                    4.0 * lens_step * height as f32 / (2.0 * camera.half_h)
                ),
            ));
        }
        if camera.lens_radius > 0.0 && position_blur > 0.25 && reach >= camera.lens_radius {
            self.warn(
                at,
                focus_field,
                format!(
                    "a focus distance of {:e}{default} is too small for f32 at the camera's position {}: points there are rounded to \
                     ~{:.1e}, {position_blur:.2} of a pixel at the focus distance, so the plane in focus is blurred by that much \
                     (focus farther than ~{:.1e}, or move the camera nearer the origin)",
                    camera.focus_distance,
                    plain_vec(camera.position),
                    reach * f32::EPSILON,
                    4.0 * reach * f32::EPSILON * height as f32 / (2.0 * camera.half_h)
                ),
            );
        }
        if let Some(a) = file.camera.get_ref().aperture.as_ref().filter(|_| !(position_blur > 0.25 && reach >= camera.lens_radius)) {
            // Lens points are rounded to ULPs of the aperture: past a fraction of a pixel at the focus
            // distance, the plane in focus is no longer sharp (a user trial: an edge pixel 0.39 off at an
            // aperture of 1e6, focused at 10). (Not said where the position rounds as coarsely: that is
            // the focus distance's warning.)
            let blur = camera.lens_radius * f32::EPSILON / pixel;
            if blur > 0.25 {
                self.warn(
                    a.span(),
                    "camera.aperture",
                    format!(
                        "an aperture of {:e} rounds its lens points to ~{:.1e}, {blur:.2} of a pixel at the focus distance: the \
                         plane in focus is blurred by that much (a smaller aperture, or a scene in larger units)",
                        camera.lens_radius,
                        camera.lens_radius * f32::EPSILON
                    ),
                );
            }
        }
        if let Some(f) = &file.camera.get_ref().focus_distance {
            // (Valid, but the image is the one without it: most likely an aperture left out.)
            if camera.lens_radius == 0.0 {
                self.warn(
                    f.span(),
                    "camera.focus_distance",
                    "focus_distance has no effect without an aperture > 0 (a pinhole camera is in focus everywhere): give \
                     camera.aperture for depth of field",
                );
            }
        }

        for (name, def) in &file.materials {
            let m = self.material(def, &format!("materials.{name}"))?;
            self.material_ids.insert(name.clone(), self.materials.len() as u32);
            self.materials.push(m);
        }
        for (i, def) in file.shapes.iter().enumerate() {
            self.top_shape(def, i)?;
            if self.prims.len() > MAX_PRIMS {
                return Err(self.err(def.span(), format!("shapes[{i}]"), format!("more than {MAX_PRIMS} primitives")));
            }
        }
        // Named solids no shape uses are checked as a use would check them (a missing material
        // excepted: a use may give it).
        for (name, def) in &file.solids {
            if !self.used_solids.contains(name) {
                self.solid_definition(name, def)?;
                let leaves = self.csg_leaves(def, 1);
                if leaves > MAX_CSG_LEAVES {
                    return Err(self.err(def.span(), format!("solids.{name}"), too_many_leaves(leaves, 0)));
                }
                self.lenient_material = true;
                self.material_from = None;
                self.leaf_sites.clear();
                let field = format!("solids.{name}");
                let tree = self.csg_tree(def, &field, Affine3A::IDENTITY, None, 1, &mut vec![name.clone()]);
                self.lenient_material = false;
                self.placed_alone(&tree?, def, &field)?;
            }
        }
        for (i, def) in file.lights.iter().enumerate() {
            self.light(def, &format!("lights[{i}]"))?;
        }

        // A checker's cells must be resolvable where it is seen: beyond 2^23 cells from the origin an f32
        // coordinate over the scale is an even integer everywhere, and the pattern is its colour `a`.
        let extent = self
            .prims
            .iter()
            .filter_map(|p| prim_bounds(&p.shape, &self.csg))
            .map(|b| b.min.abs().max(b.max.abs()).max_element())
            .fold(camera.position.abs().max_element(), f32::max);
        for (at, field, scale) in self.checkers.take() {
            if extent / scale > (1u32 << 23) as f32 {
                let w = format!(
                    "a checker of scale {scale:e} in a scene reaching {extent:e} from the origin: beyond 2^23 cells from the \
                     origin an f32 coordinate resolves no cell, and the pattern shows its colour `a` alone there"
                );
                self.warn(at, field, w);
            }
        }
        let shutter = camera.shutter;
        let mut bounds = Vec::with_capacity(self.prims.len());
        let (mut bounded, mut unbounded) = (Vec::new(), Vec::new());
        for (i, p) in self.prims.iter().enumerate() {
            match prim_bounds(&p.shape, &self.csg) {
                Some(b) => {
                    let b = if p.motion == Vec3::ZERO {
                        b
                    } else {
                        let b0 = Aabb::new(b.min + p.motion * shutter[0], b.max + p.motion * shutter[0]);
                        let b1 = Aabb::new(b.min + p.motion * shutter[1], b.max + p.motion * shutter[1]);
                        b0.union(b1)
                    };
                    bounds.push(b);
                    bounded.push(i as u32);
                }
                None => {
                    bounds.push(Aabb::EMPTY);
                    unbounded.push(i as u32);
                }
            }
        }
        let bvh_bounds: Vec<Aabb> = bounded.iter().map(|&i| bounds[i as usize]).collect();
        let bvh = build_bvh(&bvh_bounds, &BuildOptions::default());
        // Camera rays take the wide tree at every size; incoherent rays only from `WIDE_MIN_NODES`. The
        // collapse is linear in the node count, a few percent of the binary build.
        let wide_bvh = WideBvh::from_bvh(&bvh, Collapse::Sah);
        let wide_incoherent = bvh.nodes.len() >= WIDE_MIN_NODES;
        let leaf_spheres = super::leaf_spheres::LeafSpheres::new(&bvh, &bounded, &self.prims);
        let prim_geo = self.prims.iter().map(super::PrimGeo::of).collect();
        let light_buffers = light_buffers(&self.lights, &self.prims, &bounds, &bounded);

        let mut features = Features {
            csg: self.prims.iter().any(|p| matches!(p.shape, Shape::Csg { .. })),
            // (A shutter of no length at a time other than 0 still places moving prims at that time.)
            motion: self.prims.iter().any(|p| p.motion != Vec3::ZERO) && (shutter[1] > shutter[0] || shutter[0] != 0.0),
            lens: camera.lens_radius > 0.0,
            planes: !unbounded.is_empty(),
            point_lights: self.lights.iter().any(Light::is_point),
            area_lights: self.lights.iter().any(|l| !l.is_point()),
            ..Features::default()
        };
        // Only materials that some surface uses count.
        let mut used = vec![false; self.materials.len()];
        for p in &self.prims {
            used[p.material as usize] = true;
        }
        for l in 0..self.csg.leaf_count() {
            used[self.csg.leaf(l as u32).material as usize] = true;
        }
        mark_passable(&mut self.materials, &used);
        for (m, _) in self.materials.iter().zip(&used).filter(|(_, u)| **u) {
            match m {
                Material::Dielectric(d) => {
                    features.dielectric = true;
                    features.dispersion |= d.ior.is_dispersive();
                }
                Material::Glossy { .. } => features.glossy = true,
                Material::Mirror { .. } => features.mirror = true,
                _ => {}
            }
        }
        let prim_kind: Vec<MaterialKind> = self.prims.iter().map(|p| self.materials[p.material as usize].kind()).collect();
        // Each area light pushed one prim, in the lights' order.
        let mut area_lights = (0..self.lights.len() as u32).filter(|&l| !self.lights[l as usize].is_point());
        let light_of_prim: Vec<u32> =
            self.prims.iter().map(|p| if p.is_light { area_lights.next().unwrap_or(NOT_A_LIGHT) } else { NOT_A_LIGHT }).collect();
        let leaf_kind: Vec<MaterialKind> =
            (0..self.csg.leaf_count()).map(|l| self.materials[self.csg.leaf(l as u32).material as usize].kind()).collect();
        let glass_neighbours = if features.dielectric {
            // The largest coordinate a ray's origin or hit can have (bounded prims, the camera and its lens).
            let extent = bvh_bounds
                .iter()
                .fold(camera.position.abs().max_element() + camera.lens_radius, |e, b| e.max(b.min.abs().max(b.max.abs()).max_element()));
            super::glass_neighbours::GlassNeighbours::build(
                &self.prims,
                &self.csg,
                &prim_kind,
                &leaf_kind,
                &bounds,
                &bounded,
                &unbounded,
                &bvh,
                extent,
                super::glass_neighbours::OWN_TREE_GLASS,
            )
        } else {
            Default::default()
        };
        let camera_media = if features.dielectric { self.camera_media(&mut camera, &file.camera) } else { Vec::new() };
        if features.dielectric {
            let spheres = self.coincident_glass_spheres();
            self.coincident_glass_surfaces(&spheres);
        }
        self.coincident_emitters();
        self.enclosed_lights(&bvh, &bounded, shutter);
        self.tell_counted();
        let cam = file.camera.get_ref();
        let sites = vec![
            self.err(cam.shutter.as_ref().map_or(file.camera.span(), |s| s.span()), "camera.shutter", ""),
            self.err(img.background.as_ref().map_or(file.image.span(), |b| b.span()), "image.background", ""),
        ];
        Ok(Scene {
            sites,
            camera_media,
            width,
            height,
            background,
            camera,
            materials: std::mem::take(&mut self.materials),
            prims: std::mem::take(&mut self.prims),
            bounds,
            bvh,
            wide_bvh,
            wide_incoherent,
            prim_geo,
            leaf_spheres,
            light_buffers,
            bounded,
            unbounded,
            csg: std::mem::replace(&mut self.csg, Csg::new()),
            lights: std::mem::take(&mut self.lights),
            features,
            prim_kind,
            leaf_kind,
            glass_neighbours,
            warnings: std::mem::take(&mut self.warnings),
            hash,
            light_of_prim,
        })
    }

    /// Warn of separate solids whose glass sphere surfaces coincide: a glass sphere that fills a
    /// spherical hole of another glass solid exactly, or two equal glass spheres. A ray meets the two
    /// surfaces in an order that rounding decides pixel by pixel, so the media it enters and leaves (and
    /// its refraction) speckle. Sphere prims and CSG sphere leaves placed by a uniform scale (and a
    /// rotation) are compared by the exact bits of their centre and radius, as the file gives them; a
    /// pair that only rounds apart under different transforms is not caught. At the later shape of each
    /// pair, once per shape.
    fn coincident_glass_spheres(&mut self) -> Vec<(usize, usize)> {
        debug_assert_eq!(self.prim_at.len(), self.prims.len());
        if self.prim_at.len() != self.prims.len() {
            return Vec::new();
        }
        let glass = |m: u32| self.is_medium(m);
        let mut first: std::collections::HashMap<[u32; 4], usize> = std::collections::HashMap::new();
        let mut pairs: Vec<(usize, usize)> = Vec::new();
        let mut spheres: Vec<(Vec3, f32)> = Vec::new();
        for (i, p) in self.prims.iter().enumerate() {
            if p.motion != Vec3::ZERO {
                continue;
            }
            spheres.clear();
            match p.shape {
                Shape::Sphere { center, radius } if glass(p.material) => spheres.push((center, radius)),
                Shape::Csg { solid } => {
                    for k in self.csg.solid_leaves(solid) {
                        let leaf = self.csg.leaf(k);
                        if !matches!(leaf.shape, csg::solid::Shape::Sphere) || !glass(leaf.material) {
                            continue;
                        }
                        if let Some(r) = similarity_scale(&leaf.object_to_world) {
                            spheres.push((Vec3::from(leaf.object_to_world.translation), r));
                        }
                    }
                }
                _ => {}
            }
            for &(c, r) in &spheres {
                let key = [c.x.to_bits(), c.y.to_bits(), c.z.to_bits(), r.to_bits()];
                match first.get(&key) {
                    // (Prims come in order: one pair per prim is a look at the last.)
                    Some(&j) if j != i && pairs.last().is_none_or(|&(a, _)| a != i) => pairs.push((i, j)),
                    Some(_) => {}
                    None => {
                        first.insert(key, i);
                    }
                }
            }
        }
        self.warn_pairs(
            &pairs,
            |other| {
                format!(
                    "a glass sphere surface of this shape coincides with one of `{other}`: a ray meets the two in an order that \
                     rounding decides pixel by pixel, so the media it enters and leaves speckle; make the inner medium slightly \
                     larger than the space it fills and give the container the higher `priority` (README, \"How to model a glass \
                     of water\")"
                )
            },
            |more| format!("and {more} more shapes from here on have glass sphere surfaces that coincide with another's"),
        );
        pairs
    }

    /// Warn of separate glass shapes whose surfaces meet within the spawn offset anywhere, not only equal
    /// spheres: water whose cylinder fills a cup's cylindrical hole exactly, a box of liquid fitted to
    /// a cuvette, one glass block resting on another. A ray that crosses both surfaces at one point is
    /// spawned past the second, so it never enters (or leaves) that medium: a trial's water exactly
    /// filling its cup vanished without a word. Found by probing: for each pair of glass shapes (a
    /// sphere, ellipsoid or box of a non-thin dielectric, or a CSG solid with such a leaf; static)
    /// whose bounds touch, 3 x 6^2 axis rays across the overlap of their bounds, the f64 crossings of
    /// both compared (closer than the spawn offset, 256 ULPs of the point; a CSG solid's by its leaves
    /// near the overlap, whether or not they bound it there); pairs of balls analytically
    /// ([`balls_nearly_tangent`]: the probes miss the small cap of two nearly tangent balls). Shapes the
    /// sphere check warned of (`spheres`) are not warned of twice; the probes stop after 2^22 leaf tests (about 0.05 s).
    fn coincident_glass_surfaces(&mut self, spheres: &[(usize, usize)]) {
        use crate::csg::reference::leaf_f64;
        use glam::DVec3;
        if self.prim_at.len() != self.prims.len() {
            return;
        }
        let glass = |m: u32| self.is_medium(m);
        // Each item's surfaces as leaves (`leaves[range]`): a plain shape's one canonical leaf, a CSG
        // solid's glass leaves (whether or not they bound it everywhere: its boundary by the boolean
        // program would cost a program evaluation per crossing; an opaque leaf meeting glass is the
        // intersect stage's opaque-neighbour rule's, as for plain opaque shapes).
        let mut leaves: Vec<csg::Leaf> = Vec::new();
        // (prim, its leaves, bounds lo, hi, a plain sphere)
        let mut items: Vec<(usize, Range<usize>, DVec3, DVec3, bool)> = Vec::new();
        for (i, p) in self.prims.iter().enumerate() {
            if p.motion != Vec3::ZERO {
                continue;
            }
            let start = leaves.len();
            let leaf = |shape: csg::Shape, m: Affine3A| csg::Leaf::new(shape, m, p.material);
            let (bounds, sphere) = match p.shape {
                Shape::Sphere { .. } | Shape::Ellipsoid(_) | Shape::Box(_) if !glass(p.material) => continue,
                Shape::Sphere { center, radius } => {
                    leaves.push(leaf(
                        csg::Shape::Sphere,
                        Affine3A::from_scale_rotation_translation(Vec3::splat(radius), Quat::IDENTITY, center),
                    ));
                    (leaves[start].bounds(), true)
                }
                Shape::Ellipsoid(e) => {
                    leaves.push(leaf(csg::Shape::Sphere, Affine3A::from_mat3_translation(e.to_world, e.center)));
                    (leaves[start].bounds(), false)
                }
                Shape::Box(b) => {
                    leaves.push(leaf(csg::Shape::Box, Affine3A::from_mat3_translation(b.to_world * Mat3::from_diagonal(b.half), b.center)));
                    (leaves[start].bounds(), false)
                }
                Shape::Csg { solid } => {
                    leaves.extend(self.csg.solid_leaves(solid).map(|k| *self.csg.leaf(k)).filter(|l| glass(l.material)));
                    (Some(self.csg.bounds(solid)), false)
                }
                _ => continue,
            };
            let (lo, hi) = bounds.map_or((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi)| (lo.as_dvec3(), hi.as_dvec3()));
            if leaves.len() > start && lo.is_finite() && hi.is_finite() && lo.cmple(hi).all() {
                items.push((i, start..leaves.len(), lo, hi, sphere));
            } else {
                leaves.truncate(start);
            }
        }
        // An item's leaves whose bounds meet the box `lo..hi`.
        let near = |range: &Range<usize>, lo: DVec3, hi: DVec3, out: &mut Vec<csg::Leaf>| {
            out.clear();
            out.extend(
                leaves[range.clone()]
                    .iter()
                    .filter(|l| l.bounds().is_none_or(|(a, b)| a.as_dvec3().cmple(hi).all() && b.as_dvec3().cmpge(lo).all())),
            );
        };
        let crossings = |leaves: &[csg::Leaf], o: DVec3, d: DVec3, out: &mut Vec<f64>| {
            out.clear();
            out.extend(leaves.iter().flat_map(|l| leaf_f64(l, o, d)).filter(|t| t.is_finite()));
        };
        const N: usize = 6;
        // Leaf crossings computed at most (about 0.2 s), where many glass shapes touch.
        const BUDGET: usize = 1 << 22;
        let (mut spent, mut pairs) = (0usize, Vec::new());
        let (mut a, mut b, mut la, mut lb) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        // Bounds closer than this may hold surfaces within the spawn offset: 1e-4 of the largest item
        // or 256 ULPs of the farthest coordinate (the same for every pair).
        let far = items.iter().map(|it| it.2.abs().max(it.3.abs()).max_element()).fold(0.0f64, f64::max);
        let ext = items.iter().map(|it| (it.3 - it.2).max_element()).fold(0.0f64, f64::max);
        let slack = (1e-4 * ext).max(512.0 * far * f32::EPSILON as f64);
        // The pairs whose bounds come within `2 slack` of each other: from a tree of the items' bounds,
        // each widened by `slack` (and outwards past its f32 rounding), so that the work follows the pairs that
        // are near, not the items' count squared (3,000 panes in a column along z used up a budget that
        // counted every pair overlapping along x, and a touching pair elsewhere went unseen).
        // (`widened_ulps`: 2^-21 of each coordinate, more than the f32 rounding of the f64 corners.)
        let boxes: Vec<Aabb> =
            items.iter().map(|it| Aabb::new((it.2 - slack).as_vec3(), (it.3 + slack).as_vec3()).widened_ulps()).collect();
        let tree = build_bvh(&boxes, &BuildOptions::default());
        let (mut stack, mut near_items) = (Vec::new(), Vec::new());
        // The item at which the budget ran out, if it did.
        let mut cut = None;
        // The coincident spheres' first ids, looked up per tangent pair (a scan of them per pair made 10^5
        // glass spheres at one centre take 259 s: the budget counts pairs, not the scan).
        let coincident: std::collections::HashSet<usize> = spheres.iter().map(|s| s.0).collect();
        'outer: for x in 0..items.len() {
            near_items.clear();
            tree.for_each_in_box(boxes[x].min, boxes[x].max, &mut stack, |y| {
                if y as usize > x {
                    near_items.push(y as usize);
                }
            });
            near_items.sort_unstable();
            for &y in &near_items {
                let ((i, ref p, lo1, hi1, s1), (j, ref q, lo2, hi2, s2)) = (&items[x], &items[y]);
                // (Every pair looked at counts too: a heap of glass in one place is near pairs only.)
                spent += 1;
                if spent > BUDGET {
                    cut = Some(*i);
                    break 'outer;
                }
                if *s1 && *s2 {
                    // Two balls: analytic (the probes' rays miss the small cap where two nearly tangent
                    // balls come within the offset: a trial's liquid ball poking 3e-5 out of its glass
                    // ball took the glass's absorption away from the rays through that cap).
                    if balls_nearly_tangent(&self.prims[*i].shape, &self.prims[*j].shape) {
                        let pair = ((*i).max(*j), (*i).min(*j));
                        if !coincident.contains(&pair.0) {
                            pairs.push(pair);
                        }
                    }
                    continue;
                }
                let (lo, hi) = (lo1.max(*lo2) - slack, hi1.min(*hi2) + slack);
                if !lo.cmple(hi).all() {
                    continue;
                }
                near(p, lo, hi, &mut la);
                near(q, lo, hi, &mut lb);
                let mid = (lo1.min(*lo2) + hi1.max(*hi2)) * 0.5;
                let mut hit = false;
                'rays: for axis in 0..3 {
                    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                    let mut d = DVec3::ZERO;
                    d[axis] = 1.0;
                    for m in 0..N * N {
                        // (The crossings computed count, ray by ray: a pair that touches stops early.)
                        spent += la.len() + lb.len();
                        if spent > BUDGET {
                            cut = Some(*i);
                            break 'outer;
                        }
                        let mut o = mid;
                        o[u] = lo[u] + (hi[u] - lo[u]) * ((m % N) as f64 + 0.381_966) / N as f64;
                        o[v] = lo[v] + (hi[v] - lo[v]) * ((m / N) as f64 + 0.381_966) / N as f64;
                        crossings(&la, o, d, &mut a);
                        crossings(&lb, o, d, &mut b);
                        for &ta in &a {
                            let at = (o + d * ta).abs().max_element();
                            let tol = 256.0 * at.max(1e-30) * f32::EPSILON as f64;
                            if b.iter().any(|&tb| (ta - tb).abs() <= tol) {
                                hit = true;
                                break 'rays;
                            }
                        }
                    }
                }
                let pair = ((*i).max(*j), (*i).min(*j));
                if hit && !spheres.iter().any(|s| s.0 == pair.0) {
                    pairs.push(pair);
                }
            }
        }
        pairs.sort_unstable();
        pairs.dedup_by_key(|p| p.0);
        self.warn_pairs(
            &pairs,
            |other| {
                format!(
                    "a glass surface of this shape meets one of `{other}` (closer than the spawn offset): a ray crosses the two \
                     at one point and is spawned past the second, so it misses that medium's entry or exit (a medium filling \
                     a hole exactly vanishes or speckles); make the inner medium slightly larger than the space it fills and \
                     give the container the higher `priority` (README, \"How to model a glass of water\")"
                )
            },
            |more| format!("and {more} more shapes from here on have glass surfaces that meet another's"),
        );
        if let Some(at) = cut {
            let (span, field) = self.prim_at[at].clone();
            self.warn(
                span,
                field,
                format!(
                    "the check for glass surfaces that meet stopped here, at its budget of {BUDGET} (leaf crossings and pairs \
                     looked at): the \
                     glass shapes from this one on were not all checked against their neighbours, so there may be more \
                     than the warnings above say"
                ),
            );
        }
    }

    /// Warnings of coinciding pairs of prims `(later, earlier)`: at the later one, naming the earlier
    /// (`says`), at most 8, then a count (`more`) at the ninth: a scene of thousands of equal shapes is
    /// one mistake.
    fn warn_pairs(&mut self, pairs: &[(usize, usize)], says: impl Fn(&PrimField) -> String, more: impl Fn(usize) -> String) {
        const SHOWN: usize = SHOWN_PER_KIND;
        for &(i, j) in pairs.iter().take(SHOWN) {
            let ((span, field), other) = (self.prim_at[i].clone(), self.prim_at[j].1.clone());
            self.warn(span, field, says(&other));
        }
        if pairs.len() > SHOWN {
            let (span, field) = self.prim_at[pairs[SHOWN].0].clone();
            self.warn(span, field, more(pairs.len() - SHOWN));
        }
    }

    /// Warn of lights inside a closed solid that keeps their light in (a user who puts a point light at
    /// the centre of an opaque sphere, a lamp's bulb, gets no light from it and, with other lights in
    /// the scene, no other sign of it): a light whose every test point (a point light's position; a
    /// sphere light's centre and 14 points of its surface; a quad's corners and centre; a disk's centre
    /// and 8 points of its rim) lies strictly inside one solid (sphere, ellipsoid, box or CSG solid;
    /// one that moves, for the whole shutter) that is opaque (for a CSG solid: every leaf), or, for a point light, inside a glass solid
    /// whose surfaces shadow rays cannot cross (glass blocks direct light: what it passes is a caustic,
    /// which next-event estimation does not find, and no bounce ray can meet a point). At the light,
    /// naming the solid; the candidates come from the BVH (solids whose bounds hold the first point).
    /// Past a budget of work (BVH nodes, inside tests counted in CSG leaves) the check stops quietly.
    fn enclosed_lights(&mut self, bvh: &crate::accel::Bvh, bounded: &[u32], shutter: [f32; 2]) {
        if self.prim_at.len() != self.prims.len() || bvh.is_empty() {
            return;
        }
        // (A hint, not a rule: past a budget of work the check stops quietly, so that thousands of lamps
        // inside the bounds of a solid of a million leaves cost no more than a second.)
        const ENCLOSED_BUDGET: u64 = 1 << 26;
        let (file, mut work) = (self.file, 0u64);
        let mut found: Vec<(usize, usize, bool)> = Vec::new();
        for (i, light) in self.lights.iter().enumerate() {
            let points: Vec<Vec3> = match light {
                Light::Point { position, .. } => vec![*position],
                Light::Sphere { center, radius, .. } => {
                    let mut v = vec![*center];
                    for d in [Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, -Vec3::Y, -Vec3::Z] {
                        v.push(*center + d * *radius);
                    }
                    for k in 0..8 {
                        let d = Vec3::new(
                            if k & 1 == 0 { 1.0 } else { -1.0 },
                            if k & 2 == 0 { 1.0 } else { -1.0 },
                            if k & 4 == 0 { 1.0 } else { -1.0 },
                        );
                        v.push(*center + d.normalize() * *radius);
                    }
                    v
                }
                Light::Quad { quad, .. } => {
                    let (o, u, v) = (quad.origin, quad.u, quad.v);
                    vec![o + 0.5 * (u + v), o, o + u, o + v, o + u + v]
                }
                Light::Disk { disk, .. } => {
                    let (a, b) = disk.normal.any_orthonormal_pair();
                    let mut v = vec![disk.center];
                    for k in 0..8 {
                        let phi = k as f32 * std::f32::consts::FRAC_PI_4;
                        v.push(disk.center + (a * phi.cos() + b * phi.sin()) * disk.radius);
                    }
                    v
                }
            };
            if !points.iter().all(|x| x.is_finite()) {
                continue;
            }
            if work > ENCLOSED_BUDGET {
                break;
            }
            let x = points[0];
            // The solids whose bounds hold `x` (a point query of the BVH).
            let mut stack = vec![0usize];
            let mut holder: Option<(usize, bool)> = None;
            while let Some(n) = stack.pop() {
                let node = &bvh.nodes[n];
                work += 1;
                if !(Vec3::from(node.min).cmple(x).all() && x.cmple(Vec3::from(node.max)).all()) {
                    continue;
                }
                if !node.is_leaf() {
                    let l = node.left_first as usize;
                    stack.extend([l, l + 1]);
                    continue;
                }
                let (first, count) = (node.left_first as usize, node.count() as usize);
                for &slot in &bvh.indices[first..first + count] {
                    let k = bounded[slot as usize] as usize;
                    let p = &self.prims[k];
                    if p.is_light {
                        continue;
                    }
                    let opaque = |m: u32| !matches!(self.materials[m as usize], Material::Dielectric(_) | Material::Emissive { .. });
                    let keeps = match p.shape {
                        Shape::Csg { solid } => {
                            // (Its leaves' materials, then each point's inside test: work in its leaves.)
                            let (mut leaves, mut all) = (0u64, true);
                            for l in self.csg.solid_leaves(solid) {
                                leaves += 1;
                                all &= opaque(self.csg.leaf(l).material);
                            }
                            work += leaves * (1 + points.len() as u64);
                            all.then_some(true)
                        }
                        Shape::Sphere { .. } | Shape::Ellipsoid(_) | Shape::Box(_) => match &self.materials[p.material as usize] {
                            Material::Dielectric(d) => (light.is_point() && !d.thin && !d.passable).then_some(false),
                            Material::Emissive { .. } => None,
                            _ => Some(true),
                        },
                        _ => None,
                    };
                    let Some(opaque) = keeps else { continue };
                    work += points.len() as u64;
                    // (A moving solid keeps the light in when it holds each point for the whole shutter; the
                    // BVH's bounds are swept over the shutter.)
                    let holds = |x: Vec3| {
                        if p.motion == Vec3::ZERO {
                            self.solid_contains(p, x, shutter[0])
                        } else {
                            self.times_inside(p, x, shutter).iter().any(|&(a, b)| a <= shutter[0] && b >= shutter[1])
                        }
                    };
                    if points.iter().all(|&x| holds(x)) && holder.is_none_or(|(_, o)| opaque && !o) {
                        holder = Some((k, opaque));
                    }
                }
            }
            if let Some((k, opaque)) = holder {
                found.push((i, k, opaque));
            }
        }
        for (n, &(i, k, opaque)) in found.iter().enumerate() {
            let span = file.lights[i].span();
            let field = format!("lights[{i}]");
            if n == SHOWN_PER_KIND {
                self.warn(
                    span,
                    field,
                    format!("and {} more lights from here on lie inside a solid that keeps their light in", found.len() - n),
                );
                break;
            }
            let solid = &self.prim_at[k].1;
            let msg = if opaque {
                let seen = if self.lights[i].is_point() { "" } else { ", and it is hidden from everything outside" };
                format!(
                    "this light lies inside `{solid}`, a closed opaque solid: none of its light reaches outside that solid{seen}; \
                     move it out, or make the solid a glass or smaller"
                )
            } else {
                format!(
                    "this point light lies inside `{solid}`, a glass solid: glass blocks a point light's direct light (what it \
                     passes is a caustic, which next-event estimation does not find, and no ray can meet a point), so it lights \
                     nothing outside the glass; set `transmissive_shadows = true` in the profile (shadows through glass, not \
                     bent), or use a small sphere light, which bounce rays through the glass can find"
                )
            };
            self.warn(span, field, msg);
        }
    }

    /// Warn of area lights whose surfaces coincide (two equal disks in one place, a quad given twice,
    /// from any corner): a ray meets only one of the two surfaces, so a camera ray sees one light's
    /// radiance, not their sum (a user trial's doubled quad: 0.60 of the summed light's image), and
    /// next-event estimation samples both while a reflected ray finds one, so the reflection's weights
    /// (multiple importance sampling) no longer sum to one (glossy floors 1-12% dark). Compared by the
    /// exact shape, as the file gives it. At the later light of each pair ([`Self::warn_pairs`]).
    fn coincident_emitters(&mut self) {
        if self.prim_at.len() != self.prims.len() {
            return;
        }
        let mut first: std::collections::HashMap<[u64; 14], usize> = std::collections::HashMap::new();
        let mut pairs: Vec<(usize, usize)> = Vec::new();
        // (The bits of f32 numbers, -0.0 as 0.0, into `key` from `at`.)
        let put = |key: &mut [u64; 14], at: usize, xs: &[f32]| {
            for (k, x) in xs.iter().enumerate() {
                key[at + k] = (x + 0.0).to_bits() as u64;
            }
        };
        for (i, p) in self.prims.iter().enumerate().filter(|(_, p)| p.is_light) {
            // (Each shape by the bits of what it is made of, its kind in the last word; a quad by its
            // corners, in f64 where their sums are exact, and its emitting side, so that one given from
            // another corner with the same numbers is the same.)
            let mut key = [0u64; 14];
            match p.shape {
                Shape::Quad(q) => {
                    let (o, u, v) = (q.origin.as_dvec3(), q.u.as_dvec3(), q.v.as_dvec3());
                    // (`+ 0.0`: -0.0 and 0.0 alike.)
                    let mut c = [o, o + u, o + v, o + u + v].map(|c| (c + 0.0).to_array().map(f64::to_bits));
                    c.sort_unstable();
                    let [a, b, d, _] = c.map(|c| glam::DVec3::from_array(c.map(f64::from_bits)));
                    key[..12].copy_from_slice(c.as_flattened());
                    key[12] = (u.cross(v).dot((b - a).cross(d - a)) > 0.0) as u64;
                    key[13] = 1;
                }
                Shape::Disk(d) => {
                    put(&mut key, 0, &[d.center.x, d.center.y, d.center.z, d.normal.x, d.normal.y, d.normal.z, d.radius]);
                    key[13] = 2;
                }
                Shape::Sphere { center, radius } => {
                    put(&mut key, 0, &[center.x, center.y, center.z, radius]);
                    key[13] = 3;
                }
                // (Area lights are the three above.)
                _ => continue,
            }
            match first.entry(key) {
                std::collections::hash_map::Entry::Occupied(e) => pairs.push((i, *e.get())),
                std::collections::hash_map::Entry::Vacant(e) => {
                    e.insert(i);
                }
            }
        }
        self.warn_pairs(
            &pairs,
            |other| {
                format!(
                    "this light's surface coincides with `{other}`'s: a ray meets only one of the two, so seen directly the \
                     surface shows one light's radiance, not their sum, and its reflections come out wrong too (12% dark on a \
                     glossy floor in a trial); make them one light with the summed radiance"
                )
            },
            |more| format!("and {more} more lights from here on coincide with another light"),
        );
    }

    /// The media the camera starts in ([`Scene::camera_media`]): every solid prim (sphere, ellipsoid, box,
    /// CSG solid with a glass: its one medium) of a non-thin dielectric that contains the camera's
    /// position, outermost (largest bounds) first, each with the shutter times at which it holds the
    /// camera (a moving ball of glass that passes over the camera holds it for part of the shutter, and
    /// each camera ray starts in it or not by its own time; a user trial's absorbing ball that did so
    /// was invisible while the media were taken at shutter open and close alone). Warns where that
    /// cannot hold for every camera ray: a lens aperture that crosses a medium's surface, more media
    /// than a ray's stack keeps.
    ///
    /// A camera exactly on a medium's surface (a camera at the water line of a box of water whose top is
    /// at its height) is moved off it first, by a spawn offset of the solid's scale along the view
    /// direction (or, where the view runs along the surface, along up or right), with a note: on the
    /// surface, the strict inside test put it outside while the camera rays heading into the solid missed
    /// the surface they start on, so they never entered it (a user trial: no absorption, no refraction).
    fn camera_media(&mut self, camera: &mut Camera, def: &S<CameraDef>) -> Vec<CameraMedium> {
        self.camera_off_surfaces(camera, def);
        let pos = camera.position;
        let shutter = camera.shutter;
        // The aperture's rim, where it crosses the surface the lens centre is inside of.
        let rim: Vec<Vec3> = if camera.lens_radius > 0.0 {
            [camera.right, -camera.right, camera.up, -camera.up].iter().map(|&a| pos + a * camera.lens_radius).collect()
        } else {
            Vec::new()
        };
        let mut found: Vec<(f32, CameraMedium)> = Vec::new();
        let mut notes: Vec<String> = Vec::new();
        for p in &self.prims {
            if self.medium_of(p, pos).is_none() {
                continue;
            }
            let during = self.times_inside(p, pos, shutter);
            let at_open = self.solid_contains(p, pos, shutter[0]);
            // (A medium that moves past the camera crosses the lens on its way, whatever it does at open.)
            let passes = !rim.is_empty() && during.iter().any(|&(from, to)| from > shutter[0] || to < shutter[1]);
            if passes || rim.iter().any(|&x| self.solid_contains(p, x, shutter[0]) != at_open) {
                let m = self.medium_of(p, pos).unwrap_or(0);
                notes.push(format!(
                    "the lens aperture crosses the surface of a `{}` solid: camera rays take the media at the lens centre",
                    self.material_name(m)
                ));
            }
            // (The bounds of the solid itself, not swept over the shutter as the BVH's are.)
            let area = prim_bounds(&p.shape, &self.csg).map_or(f32::INFINITY, |b| b.surface_area());
            for (from, to) in during {
                // The medium of a CSG solid is the glass around the camera at that time, if several.
                let Some(material) = self.medium_of(p, pos - p.motion * (0.5 * (from + to)).clamp(shutter[0], shutter[1])) else {
                    continue;
                };
                // (Open-ended at the shutter's ends, so that a time at either end is held.)
                let during = [if from <= shutter[0] { f32::NEG_INFINITY } else { from }, if to >= shutter[1] { f32::INFINITY } else { to }];
                found.push((area, CameraMedium { material, during }));
            }
        }
        // Outermost first: a solid inside another has the smaller bounds.
        found.sort_by(|a, b| b.0.total_cmp(&a.0));
        let found: Vec<CameraMedium> = found.into_iter().map(|(_, m)| m).collect();
        // The most media around the camera at once: at shutter open, or where one of them begins to hold it.
        let depth = crate::wavefront::queues::MediumStack::DEPTH;
        let most = std::iter::once(shutter[0])
            .chain(found.iter().map(|m| m.during[0]))
            .map(|t| found.iter().filter(|m| m.holds_at(t)).count())
            .max()
            .unwrap_or(0);
        if most > depth {
            notes
                .push(format!("the camera is inside {most} nested media; a ray keeps {depth}: camera rays start in the {depth} innermost"));
        }
        for n in notes {
            self.warn(def.get_ref().position.span(), "camera.position", n);
        }
        found
    }

    /// The shutter times within `shutter` at which the solid prim `p` holds `x` strictly inside, as
    /// intervals (several for a CSG ring that passes over `x`): relative to the solid, `x` moves along the
    /// segment `x - motion t`, which is met as a ray is, in f64 (a CSG solid's by the reference interval
    /// merge, `csg::reference::intervals_f64`).
    fn times_inside(&self, p: &Prim, x: Vec3, shutter: [f32; 2]) -> Vec<(f32, f32)> {
        use glam::DVec3;
        let (t0, t1) = (shutter[0] as f64, shutter[1] as f64);
        let o = x.as_dvec3() - p.motion.as_dvec3() * t0;
        let d = -p.motion.as_dvec3() * (t1 - t0);
        if d == DVec3::ZERO {
            return if self.solid_contains(p, x, shutter[0]) { vec![(shutter[0], shutter[1])] } else { Vec::new() };
        }
        // `o + s d` in the frame of an affine map.
        let object = |m: &Affine3A| {
            let l = Mat3::from(m.matrix3).as_dmat3();
            (l * o + m.translation.as_dvec3(), l * d)
        };
        // Where `|o + s d| < r` (strictly between the roots of the quadratic).
        let ball = |o: DVec3, d: DVec3, r: f64| {
            let (a, b, c) = (d.length_squared(), o.dot(d), o.length_squared() - r * r);
            let disc = b * b - a * c;
            (disc > 0.0).then(|| ((-b - disc.sqrt()) / a, (-b + disc.sqrt()) / a))
        };
        let mut iv: Vec<(f64, f64)> = Vec::new();
        match &p.shape {
            Shape::Sphere { center, radius } => iv.extend(ball(o - center.as_dvec3(), d, *radius as f64)),
            Shape::Ellipsoid(e) => {
                let (o, d) = object(&e.world_to_object);
                iv.extend(ball(o, d, 1.0));
            }
            Shape::Box(b) => {
                let (o, d) = object(&b.world_to_object);
                let h = b.half.as_dvec3();
                // The slabs the segment moves across; along an axis it does not move along, inside that
                // slab (strictly, as `solid_contains`: a point on a face is outside) or never. (Not by
                // 0/0 = NaN through min and max: glam's keep or drop a NaN by the axis.)
                let (mut near, mut far) = (f64::NEG_INFINITY, f64::INFINITY);
                for i in 0..3 {
                    if d[i] == 0.0 {
                        if !(o[i].abs() < h[i]) {
                            far = f64::NEG_INFINITY;
                        }
                    } else {
                        let (a, b) = ((-h[i] - o[i]) / d[i], (h[i] - o[i]) / d[i]);
                        (near, far) = (near.max(a.min(b)), far.min(a.max(b)));
                    }
                }
                if near < far {
                    iv.push((near, far));
                }
            }
            Shape::Csg { solid } => crate::csg::reference::intervals_f64(&self.csg, *solid, o, d, &mut iv),
            _ => {}
        }
        iv.into_iter()
            .filter_map(|(a, b)| {
                let (a, b) = (a.max(0.0), b.min(1.0));
                (a < b).then_some(((t0 + a * (t1 - t0)) as f32, (t0 + b * (t1 - t0)) as f32))
            })
            .collect()
    }

    /// Whether material `m` is a medium rays enter (a dielectric, not a thin sheet).
    fn is_medium(&self, m: u32) -> bool {
        matches!(&self.materials[m as usize], Material::Dielectric(d) if !d.thin)
    }

    /// The medium a solid prim is (a non-thin dielectric sphere, ellipsoid or box; a CSG solid's one glass,
    /// where glasses apart in one solid give the one around `pos`, if any): None for anything else.
    fn medium_of(&self, p: &Prim, pos: Vec3) -> Option<u32> {
        let medium = |m: u32| self.is_medium(m);
        match p.shape {
            // A solid's medium is its one glass (`one_medium`); opaque leaves are surfaces in or on it.
            Shape::Csg { solid } => {
                let leaves = || self.csg.solid_leaves(solid).map(|k| self.csg.leaf(k)).filter(|l| medium(l.material));
                leaves().find(|l| l.inside(pos)).or_else(|| leaves().next()).map(|l| l.material)
            }
            Shape::Sphere { .. } | Shape::Ellipsoid(_) | Shape::Box(_) if medium(p.material) => Some(p.material),
            _ => None,
        }
    }

    /// Whether the solid prim `p` holds `x` strictly inside at shutter time `t`.
    fn solid_contains(&self, p: &Prim, x: Vec3, t: f32) -> bool {
        let x = x - p.motion * t;
        match &p.shape {
            Shape::Sphere { center, radius } => (x.as_dvec3() - center.as_dvec3()).length_squared() < (*radius as f64).powi(2),
            Shape::Ellipsoid(e) => e.world_to_object.transform_point3(x).length_squared() < 1.0,
            Shape::Box(b) => b.world_to_object.transform_point3(x).abs().cmplt(b.half).all(),
            Shape::Csg { solid } => self.csg.inside(*solid, x),
            _ => false,
        }
    }

    /// Move a camera that lies on the surface of a medium (a non-thin dielectric sphere, ellipsoid, box or
    /// CSG solid) off it: see [`Compiler::camera_media`].
    fn camera_off_surfaces(&mut self, camera: &mut Camera, def: &S<CameraDef>) {
        for k in 0..self.prims.len() {
            let p = &self.prims[k];
            let Some(material) = self.medium_of(p, camera.position) else { continue };
            let inside = |x: Vec3| self.solid_contains(p, x, camera.shutter[0]);
            let Some(b) = prim_bounds(&p.shape, &self.csg) else { continue };
            let pos = camera.position;
            let reach = b.min.abs().max(b.max.abs()).max_element();
            // On the surface: a point a few ULPs either side of the camera along some axis of the view is
            // on the other side of it (a camera 1e-6 above water 10 wide is not: its rays meet the surface
            // at t = 1e-6, and it keeps its place).
            let probe = (4.0 * f32::EPSILON * pos.abs().max_element()).max(reach * f32::EPSILON / 2.0);
            let here = inside(pos);
            let off = |x: Vec3, a: Vec3| inside(x) == here && inside(x + a * probe) == here && inside(x - a * probe) == here;
            let Some(a) = [camera.forward, camera.up, camera.right].into_iter().find(|&a| !off(pos, a)) else { continue };
            // A spawn offset off it (two across an edge), on the side the inside test puts the camera.
            let step = crate::geometry::offset_distance(reach.max(pos.abs().max_element()));
            let Some(to) = [a * step, -a * step, a * 2.0 * step, -a * 2.0 * step].into_iter().map(|m| pos + m).find(|&x| off(x, a)) else {
                continue;
            };
            let side = if inside(to) { "inside it" } else { "outside it" };
            let name = self.material_name(material);
            camera.position = to;
            self.warn(
                def.get_ref().position.span(),
                "camera.position",
                format!(
                    "the camera lies on the surface of a `{name}` solid: moved {:.1e} off it (to [{}, {}, {}]) so that \
                     every camera ray starts on one side, {side}; camera rays that start on a surface miss it",
                    (to - pos).length(),
                    to.x,
                    to.y,
                    to.z,
                ),
            );
        }
    }

    fn camera(&self, def: &S<CameraDef>, width: u32, height: u32) -> R<Camera> {
        let c = def.get_ref();
        let position = self.vec3(&c.position, "camera.position")?;
        let look_at = self.vec3(&c.look_at, "camera.look_at")?;
        let up = match &c.up {
            Some(u) => self.vec3(u, "camera.up")?,
            None => Vec3::Y,
        };
        let forward = look_at - position;
        // (Both within MAX_MAGNITUDE: their distance is finite.)
        if forward.length_squared() <= f32::MIN_POSITIVE {
            // (Points that differ by so little that the square of their distance is below f32's normal
            // range give no direction either: said as such, not as equal points.)
            let msg = if look_at == position {
                "must differ from camera.position".to_string()
            } else {
                format!(
                    "is too close to camera.position to give a viewing direction (they are {:e} apart; at least {:.1e} is needed)",
                    forward.as_dvec3().length() as f32,
                    f32::MIN_POSITIVE.sqrt()
                )
            };
            return Err(self.err(c.look_at.span(), "camera.look_at", msg));
        }
        let up_span = c.up.as_ref().map_or(def.span(), |u| u.span());
        if up.length_squared() <= f32::MIN_POSITIVE {
            return Err(self.err(up_span, "camera.up", too_short(up, f32::MIN_POSITIVE.sqrt())));
        }
        if forward.normalize().cross(up.normalize()).length() < 1e-6 {
            if c.up.is_none() {
                // No `up` in the file: the view itself is what to change (or give an `up`).
                return Err(self.err(
                    c.look_at.span(),
                    "camera.look_at",
                    "the camera looks straight up or down (look_at - position is parallel to the default up [0, 1, 0]): \
                     give camera.up, or move position or look_at",
                ));
            }
            return Err(self.err(up_span, "camera.up", "must not be parallel to the viewing direction (look_at - position)"));
        }
        let fov = *c.fov.get_ref();
        if !(fov.is_finite() && fov > 0.0 && fov < 180.0) {
            return Err(self.err(c.fov.span(), "camera.fov", format!("must be in (0, 180) degrees, got {fov}")));
        }
        let aperture = match &c.aperture {
            Some(a) => {
                let x = *a.get_ref();
                if !(x.is_finite() && x >= 0.0) {
                    return Err(self.err(a.span(), "camera.aperture", format!("must be a finite number >= 0, got {x}")));
                }
                if x > MAX_MAGNITUDE {
                    return Err(self.err(a.span(), "camera.aperture", format!("must be at most {MAX_MAGNITUDE:e} ({BEYOND}), got {x:e}")));
                }
                x
            }
            None => 0.0,
        };
        let focus = match &c.focus_distance {
            Some(f) => self.positive(f, "camera.focus_distance")?,
            None => forward.length(),
        };
        let shutter = match &c.shutter {
            Some(s) => {
                let [a, b] = s.get_ref().0;
                if !(a.is_finite() && b.is_finite()) {
                    return Err(self.err(
                        s.span(),
                        "camera.shutter",
                        format!("must be two finite times, got [{a}, {b}] (a value beyond f32's range, about 3.4e38, reads as infinite)"),
                    ));
                }
                if a > b {
                    return Err(self.err(s.span(), "camera.shutter", "must be [open, close] with open <= close"));
                }
                [a, b]
            }
            None => [0.0, 0.0],
        };
        Ok(Camera::new(position, look_at, up, fov, aperture, focus, shutter, width, height))
    }

    fn material(&self, def: &S<MaterialDef>, field: &str) -> R<Material> {
        let m = def.get_ref();
        let kind = m.kind.get_ref().as_str();
        let f = |name: &str| format!("{field}.{name}");
        let present: Vec<(&str, Range<usize>)> = [
            ("albedo", m.albedo.as_ref().map(|x| x.span())),
            ("checker", m.checker.as_ref().map(|x| x.span())),
            ("tint", m.tint.as_ref().map(|x| x.span())),
            ("radiance", m.radiance.as_ref().map(|x| x.span())),
            ("roughness", m.roughness.as_ref().map(|x| x.span())),
            ("ior", m.ior.as_ref().map(|x| x.span())),
            ("cauchy", m.cauchy.as_ref().map(|x| x.span())),
            ("abbe", m.abbe.as_ref().map(|x| x.span())),
            ("absorption", m.absorption.as_ref().map(|x| x.span())),
            ("transmittance", m.transmittance.as_ref().map(|x| x.span())),
            ("transmittance_distance", m.transmittance_distance.as_ref().map(|x| x.span())),
            ("thin", m.thin.as_ref().map(|x| x.span())),
            ("fresnel", m.fresnel.as_ref().map(|x| x.span())),
            ("priority", m.priority.as_ref().map(|x| x.span())),
        ]
        .into_iter()
        .filter_map(|(n, s)| s.map(|s| (n, s)))
        .collect();
        let allowed: &[&str] = match kind {
            "lambert" => &["albedo", "checker"],
            "mirror" => &["tint"],
            "glossy" => &["tint", "roughness"],
            "dielectric" => {
                &["ior", "cauchy", "abbe", "absorption", "transmittance", "transmittance_distance", "thin", "fresnel", "priority"]
            }
            "emissive" => &["radiance"],
            _ => {
                return Err(self.err(
                    m.kind.span(),
                    f("type"),
                    format!("unknown material type `{kind}` (lambert, mirror, glossy, dielectric, emissive)"),
                ))
            }
        };
        for (name, span) in &present {
            if !allowed.contains(name) {
                return Err(self.err(
                    span.clone(),
                    f(name),
                    format!("does not apply to {} `{kind}` material (allowed: {})", a_or_an(kind), allowed.join(", ")),
                ));
            }
        }
        let tint = |s: &Self| -> R<Vec3> { m.tint.as_ref().map_or(Ok(Vec3::ONE), |t| s.color(t, &f("tint"), Some(1.0))) };
        Ok(match kind {
            "lambert" => {
                let albedo = match (&m.albedo, &m.checker) {
                    (Some(a), None) => Texture::Constant(self.color(a, &f("albedo"), Some(1.0))?),
                    (None, Some(c)) => {
                        let cd = c.get_ref();
                        let scale = match &cd.scale {
                            Some(s) => self.positive(s, &f("checker.scale"))?,
                            None => 1.0,
                        };
                        let at = cd.scale.as_ref().map_or(c.span(), |s| s.span());
                        self.checkers.borrow_mut().push((at, f("checker.scale"), scale));
                        Texture::Checker {
                            a: self.color(&cd.a, &f("checker.a"), Some(1.0))?,
                            b: self.color(&cd.b, &f("checker.b"), Some(1.0))?,
                            scale,
                        }
                    }
                    (Some(_), Some(c)) => return Err(self.err(c.span(), f("checker"), "give either albedo or checker, not both")),
                    (None, None) => return Err(self.err(def.span(), f("albedo"), "missing required field (or give `checker`)")),
                };
                Material::Lambert { albedo }
            }
            "mirror" => Material::Mirror { tint: tint(self)? },
            "glossy" => {
                let r = self.req(&m.roughness, def.span(), &f("roughness"))?;
                let x = *r.get_ref();
                if !(x.is_finite() && (0.0..=1.0).contains(&x)) {
                    return Err(self.err(r.span(), f("roughness"), format!("must be in [0, 1], got {x}")));
                }
                Material::Glossy { tint: tint(self)?, alpha: x * x }
            }
            "dielectric" => {
                let ior = match (&m.ior, &m.cauchy, &m.abbe) {
                    (Some(n), None, None) => {
                        let x = *n.get_ref();
                        if !(x.is_finite() && (1.0..=10.0).contains(&x)) {
                            return Err(self.err(n.span(), f("ior"), format!("must be in [1, 10], got {x}")));
                        }
                        Ior::Constant(x)
                    }
                    (None, Some(c), None) => {
                        let [a, b] = c.get_ref().0;
                        if !(a.is_finite() && b.is_finite() && (1.0..=10.0).contains(&a) && (0.0..1.0).contains(&b)) {
                            return Err(self.err(
                                c.span(),
                                f("cauchy"),
                                "must be [A, B] with A in [1, 10] and B in [0, 1) (B in square micrometres)",
                            ));
                        }
                        Ior::Cauchy { a, b_um2: b }
                    }
                    (None, None, Some(c)) => {
                        let [nd, vd] = c.get_ref().0;
                        if !(nd.is_finite() && vd.is_finite() && nd > 1.0 && nd <= 10.0 && vd >= 5.0) {
                            return Err(self.err(c.span(), f("abbe"), "must be [nd, Vd] with nd in (1, 10] and Abbe number Vd >= 5"));
                        }
                        Ior::Abbe { nd, vd }
                    }
                    (None, None, None) => Ior::Constant(1.5),
                    _ => return Err(self.err(def.span(), f("ior"), "give only one of ior, cauchy, abbe")),
                };
                let sigma_a = match (&m.absorption, &m.transmittance) {
                    (Some(a), None) => self.color(a, &f("absorption"), None)?,
                    (None, Some(t)) => {
                        let c = self.color(t, &f("transmittance"), Some(1.0))?;
                        if c.min_element() <= 0.0 {
                            return Err(self.err(t.span(), f("transmittance"), "components must be in (0, 1]"));
                        }
                        let d = match &m.transmittance_distance {
                            Some(d) => self.positive(d, &f("transmittance_distance"))?,
                            None => 1.0,
                        };
                        sigma_from_transmittance(c, d)
                    }
                    (None, None) => Vec3::ZERO,
                    (Some(_), Some(t)) => {
                        return Err(self.err(t.span(), f("transmittance"), "give either absorption or transmittance, not both"))
                    }
                };
                if m.transmittance.is_none() {
                    if let Some(d) = &m.transmittance_distance {
                        return Err(self.err(d.span(), f("transmittance_distance"), "only applies together with `transmittance`"));
                    }
                }
                let schlick = match &m.fresnel {
                    None => false,
                    Some(s) => match s.get_ref().as_str() {
                        "exact" => false,
                        "schlick" => true,
                        other => return Err(self.err(s.span(), f("fresnel"), format!("expected `exact` or `schlick`, got `{other}`"))),
                    },
                };
                let priority = match &m.priority {
                    None => 0,
                    Some(p) => {
                        let x = *p.get_ref();
                        if !(-MAX_PRIORITY..=MAX_PRIORITY).contains(&x) {
                            return Err(self.err(
                                p.span(),
                                f("priority"),
                                format!("must be an integer in -{MAX_PRIORITY}..={MAX_PRIORITY}, got {x}"),
                            ));
                        }
                        x as i32
                    }
                };
                let thin = m.thin.as_ref().is_some_and(|t| *t.get_ref());
                if thin {
                    if let Some(p) = &m.priority {
                        return Err(self.err(p.span(), f("priority"), "a thin sheet is not a medium: priority does not apply"));
                    }
                    // A sheet of no thickness absorbs nothing along a path through it.
                    for (name, v) in [
                        ("absorption", m.absorption.as_ref().map(|x| x.span())),
                        ("transmittance", m.transmittance.as_ref().map(|x| x.span())),
                    ] {
                        if let Some(span) = v {
                            return Err(self.err(
                                span,
                                f(name),
                                format!("a thin sheet has no thickness to absorb along: {name} does not apply"),
                            ));
                        }
                    }
                }
                Material::Dielectric(Dielectric { ior, sigma_a, thin, schlick, priority, passable: false })
            }
            "emissive" => {
                let r = self.req(&m.radiance, def.span(), &f("radiance"))?;
                Material::Emissive { radiance: self.color(r, &f("radiance"), None)? }
            }
            _ => unreachable!(),
        })
    }

    fn material_ref(&self, m: &S<String>, field: impl Display + Copy) -> R<u32> {
        self.material_ids.get(m.get_ref()).copied().ok_or_else(|| {
            let known: Vec<&str> = self.material_ids.keys().map(|s| s.as_str()).collect();
            self.err(
                m.span(),
                field,
                format!(
                    "no material named `{}` (defined: {})",
                    m.get_ref(),
                    if known.is_empty() { "none".to_string() } else { known.join(", ") }
                ),
            )
        })
    }

    fn transform(&self, t: &Option<Box<S<TransformDef>>>, field: impl Display + Copy) -> R<Affine3A> {
        let Some(t) = t else { return Ok(Affine3A::IDENTITY) };
        let td = t.get_ref();
        let scale = match &td.scale {
            Some(s) => {
                let v = self.vec3(s, &format!("{field}.transform.scale"))?;
                if v.abs().min_element() < 1e-12 || v.abs().max_element() > 1e12 {
                    return Err(self.err(
                        s.span(),
                        format!("{field}.transform.scale"),
                        "scale components must be non-zero and within 1e-12..1e12",
                    ));
                }
                v
            }
            None => Vec3::ONE,
        };
        let rot = match &td.rotate {
            Some(r) => {
                let f = format!("{field}.transform.rotate");
                let d = self.finite3(r, &f)?;
                if d.abs().max_element() > MAX_DEGREES {
                    return Err(self.err(
                        r.span(),
                        f,
                        format!("angles (degrees) must be within +-{MAX_DEGREES} (1000 turns; beyond, an f32 angle resolves no better than 0.03 degrees)"),
                    ));
                }
                Quat::from_euler(EulerRot::ZYX, d.z.to_radians(), d.y.to_radians(), d.x.to_radians())
            }
            None => Quat::IDENTITY,
        };
        let tr = match &td.translate {
            Some(v) => self.vec3(v, &format!("{field}.transform.translate"))?,
            None => Vec3::ZERO,
        };
        Ok(Affine3A::from_scale_rotation_translation(scale, rot, tr))
    }

    /// A placed shape (after its transforms) within [`MAX_MAGNITUDE`] of the origin: its box, or a
    /// plane's distance; and, moving by `motion` (it sits at `shape + motion * t`), at every time of the
    /// camera's shutter (checked before the shapes): the farthest it gets is at the shutter's open or
    /// close, the motion being linear.
    fn within_range(&self, shape: &Shape, motion: Vec3, def: &S<ShapeDef>, field: impl Display + Copy) -> R<()> {
        let bounds = prim_bounds(shape, &self.csg).filter(|b| !b.is_empty());
        let reach = match (shape, bounds) {
            (Shape::Plane(p), _) => p.offset.abs(),
            (_, Some(b)) => b.min.abs().max(b.max.abs()).max_element(),
            _ => 0.0,
        };
        if reach > MAX_MAGNITUDE {
            return Err(self.err(
                def.span(),
                field,
                format!("placed, it reaches {reach:e} from the origin; the limit is {MAX_MAGNITUDE:e} ({BEYOND})"),
            ));
        }
        let (Some(b), Some(m)) = (bounds, def.get_ref().motion.as_ref()) else { return Ok(()) };
        if motion == Vec3::ZERO {
            return Ok(());
        }
        // (In f64: a shutter time of 1e30 times a motion of 1e15 overflows f32.)
        let shutter = self.file.camera.get_ref().shutter.as_ref().map_or([0.0, 0.0], |s| s.get_ref().0);
        let at = |t: f32| {
            let d = motion.as_dvec3() * t as f64;
            (b.min.as_dvec3() + d).abs().max((b.max.as_dvec3() + d).abs()).max_element()
        };
        let (t, far) = shutter.into_iter().map(|t| (t, at(t))).fold((0.0, 0.0), |a, b| if b.1 > a.1 { b } else { a });
        if far > MAX_MAGNITUDE as f64 {
            let end = if t == shutter[1] { "close" } else { "open" };
            return Err(self.err(
                m.span(),
                Sub(field, "motion"),
                format!(
                    "moving by this motion, it reaches {far:.2e} from the origin at time {} (camera.shutter's {end}; a moving \
                     shape is at its given place at time 0); the limit is {MAX_MAGNITUDE:e} ({BEYOND}): give a slower \
                     motion or a shorter shutter",
                    plain_number(t)
                ),
            ));
        }
        Ok(())
    }

    /// Warn of a moving shape shifted so far during the shutter (`motion` x t) that the spawn offset of
    /// its hits, which grows with the shift (rays meet it in its own frame at time 0, and the shift's
    /// rounding enters the hit point: README, "Known limits"), passes 1% of its size and 4 times the
    /// offset of its place alone at that time (a user trial, session 50: a glass ball of radius 0.5
    /// under a shutter of [1000, 1001] was off by up to 0.105 at its rim; a ball moving 1e5 over [0, 1]
    /// had lit pixels black, its shadow rays starting under the floor). At the shape's `motion`.
    fn far_shift(&mut self, shape: &Shape, motion: Vec3, def: &S<ShapeDef>, field: impl Display + Copy) {
        let Some(m) = def.get_ref().motion.as_ref() else { return };
        let Some(b) = prim_bounds(shape, &self.csg).filter(|b| !b.is_empty()) else { return };
        if motion == Vec3::ZERO {
            return;
        }
        let shutter = self.file.camera.get_ref().shutter.as_ref().map_or([0.0, 0.0], |s| s.get_ref().0);
        let (t, shift) =
            shutter.into_iter().map(|t| (t, (motion * t).abs().max_element())).fold((0.0, 0.0), |a, b| if b.1 > a.1 { b } else { a });
        // (Where it is at that time: the offset of its place alone, which no shutter choice changes.)
        let place = (b.min + motion * t).abs().max((b.max + motion * t).abs()).max_element();
        // Its size: the smallest extent of its box that is not flat (a quad's or disk's in-plane size).
        let e = b.max - b.min;
        let size = [e.x, e.y, e.z].into_iter().filter(|&x| x > 0.0).fold(f32::INFINITY, f32::min);
        let (off, own) = (crate::geometry::offset_distance(shift), crate::geometry::offset_distance(place));
        if !(size.is_finite() && off > 0.01 * size && off > 4.0 * own) {
            return;
        }
        let msg = format!(
            "moving by this motion, it is shifted by up to {shift:.3e} (at time {}, camera.shutter's {}): rays meet a moving \
             shape in its own frame at time 0, and the shift's rounding sets its spawn offset, {off:.1e}, {:.0}% of its size \
             {size:.2e}: its edges, refraction and shadows lose that precision (a trial: a glass ball's rim off by up to \
             0.1 at a shift of 1e3); give shutters near time 0 (a moving shape is at its given place at time 0), or a \
             slower motion",
            plain_number(t),
            if t == shutter[1] { "close" } else { "open" },
            100.0 * off / size
        );
        self.warn_each(WarnKind::FarShift, m.span(), Sub(field, "motion"), || msg);
    }

    /// Warn of a glass box or ball (a medium rays enter) thinner than a few spawn offsets where it lies: a
    /// ray entering it starts `offset_distance` (256 ULPs of the hit point's largest coordinate) inside,
    /// so through a thinner one it starts past the far face, never sees it, and counts as inside the glass
    /// for the rest of its path (a 2 mm pane at x = 200 rendered black, a user trial). CSG leaves have
    /// their own, stricter warning (in [`Self::top_shape`]: a leaf thinner than 10 coincidence tolerances).
    fn thin_glass(&mut self, shape: &Shape, material: u32, def: &S<ShapeDef>, field: impl Display + Copy) {
        if !self.is_medium(material) {
            return;
        }
        let (thickness, what) = match shape {
            Shape::Sphere { radius, .. } => (2.0 * radius, "ball"),
            // The distance between opposite faces: `2 half_i / |row i|` of the world-to-object matrix.
            Shape::Box(b) => {
                let m = Mat3::from(b.world_to_object.matrix3).transpose();
                let t = (0..3).map(|i| 2.0 * b.half[i] / m.col(i).length()).fold(f32::INFINITY, f32::min);
                (t, "box")
            }
            _ => return,
        };
        let Some(bounds) = prim_bounds(shape, &self.csg) else { return };
        let reach = bounds.min.abs().max(bounds.max.abs()).max_element();
        let offset = crate::geometry::offset_distance(reach);
        if thickness < 4.0 * offset {
            self.warn_each(WarnKind::ThinGlass, def.span(), field, || {
                format!(
                    "this glass {what} is only {thickness:.2e} thick but reaches {reach:.2e} from the origin, where a ray that \
                     enters it starts {offset:.2e} inside (256 ULPs of its coordinates): rays can pass its far face unseen \
                     and then count as inside the glass for the rest of their path (dark or black pixels); make it thicker \
                     than {:.1e} or move the scene nearer the origin",
                    4.0 * offset
                )
            });
        }
    }

    /// What a named solid's definition may not hold, whether or not it is used: `hole` (a hole is a
    /// place in a group, marked where the solid is used).
    fn solid_definition(&self, name: &str, def: &S<ShapeDef>) -> R<()> {
        match def.get_ref().hole.as_ref().filter(|h| *h.get_ref()) {
            Some(h) => Err(self.err(
                h.span(),
                format!("solids.{name}.hole"),
                format!("a named solid is not a hole by itself: mark the group child that uses it, `{{ use = \"{name}\", hole = true }}`"),
            )),
            None => Ok(()),
        }
    }

    fn check_fields(&self, def: &S<ShapeDef>, field: impl Display + Copy, kind: &str, allowed: &[&str]) -> R<()> {
        match def.get_ref().misfit(allowed) {
            Some((name, span)) => {
                let a = a_or_an(kind);
                // (A `use` places a solid: its own geometry is the definition's; a trial read `allowed:
                // motion, hole` as the whole list.)
                let allowed = if kind == "use" {
                    "material, transform, motion (at the top level), hole (in a group's children)".to_string()
                } else {
                    allowed.join(", ")
                };
                Err(self.err(span, Sub(field, name), format!("does not apply to {a} `{kind}` (allowed: {allowed})")))
            }
            None => Ok(()),
        }
    }

    /// A shape at the top level of `shapes`: a primitive, or a CSG solid.
    fn top_shape(&mut self, def: &S<ShapeDef>, i: usize) -> R<()> {
        let s = def.get_ref();
        let at = Item("shapes", i);
        let t = self.transform(&s.transform, at)?;
        let motion = match &s.motion {
            Some(m) => self.vec3(m, Sub(at, "motion"))?,
            None => Vec3::ZERO,
        };
        // (`hole = false` is harmless anywhere, and accepted: a trial's was refused at the top level.)
        if let Some(h) = s.hole.as_ref().filter(|h| *h.get_ref()) {
            return Err(self.err(h.span(), Sub(at, "hole"), "only children of a `group` can be holes (`hole = true`)"));
        }
        let kind = match (&s.kind, &s.use_solid) {
            (Some(k), None) => k.get_ref().as_str(),
            (None, Some(_)) => "use",
            (Some(k), Some(_)) => return Err(self.err(k.span(), Sub(at, "type"), "give either `type` or `use`, not both")),
            (None, None) => return Err(self.err(def.span(), Sub(at, "type"), "missing required field (or `use`)")),
        };
        let simple = matches!(kind, "sphere" | "plane" | "box" | "quad" | "disk");
        if simple {
            let mat_field = Sub(at, "material");
            let material = self.material_ref(self.req(&s.material, def.span(), mat_field)?, mat_field)?;
            let shape = self.simple_shape(def, at, kind, t)?;
            if matches!(shape, Shape::Plane(_)) && motion != Vec3::ZERO {
                return Err(self.err(s.motion.as_ref().unwrap().span(), Sub(at, "motion"), "an infinite plane cannot move"));
            }
            self.within_range(&shape, motion, def, at)?;
            self.far_shift(&shape, motion, def, at);
            self.thin_glass(&shape, material, def, at);
            self.prims.push(Prim { shape, material, motion, is_light: false });
            self.prim_at.push((def.span(), PrimField::Shape(i)));
            return Ok(());
        }
        let field = &at.to_string();
        let material = match &s.material {
            Some(m) => Some(self.material_ref(m, &format!("{field}.material"))?),
            None => None,
        };
        // Everything else is a CSG solid (a single cylinder, cone or torus is a one-leaf solid).
        let leaves = self.csg_leaves(def, 0);
        let before = self.csg.leaf_count() as u64;
        if leaves.saturating_add(before) > MAX_CSG_LEAVES {
            let (span, at) = match &s.use_solid {
                Some(u) => (u.span(), format!("{field}.use")),
                None => (def.span(), field.clone()),
            };
            return Err(self.err(span, at, too_many_leaves(leaves, before)));
        }
        let mut stack = Vec::new();
        self.leaf_sites.clear();
        self.material_from = s.material.as_ref().map(|m| (m.span(), format!("{field}.material")));
        let tree = self.csg_tree(def, field, Affine3A::IDENTITY, material, 0, &mut stack)?;
        let _ = t; // the transform was applied inside csg_tree (it reads the def's own transform)
        let solid = self.add_solid(&tree, def, field)?;
        let (lo, hi) = self.csg.bounds(solid);
        if !lo.cmple(hi).all() {
            // An empty solid (e.g. a disjoint intersection) contributes nothing.
            self.warn_each(WarnKind::EmptySolid, def.span(), field, || {
                "this CSG solid is empty (an intersection of solids that do not overlap?): it is left out".to_string()
            });
            return Ok(());
        }
        self.one_medium(field)?;
        // The coincidence tolerance is relative to the solid's scale L (its farthest coordinate): a leaf
        // far from the rest (a part at 1e5 in a union with one at the origin) widens it for every leaf.
        let scale = self.csg.scale(solid);
        let tol = crate::csg::merge::COINCIDENT_EPS * scale;
        // (A solid that looks empty costs the probe all its rays, ~0.4 ms: past `MAX_EMPTY_PROBED` of them
        // the rest are not probed, and the count says so.)
        // (Bounds no thicker than the tolerance hold nothing the render keeps, whatever a probe's rays find
        // there: an intersection of two boxes that share a face has bounds of ~0 thickness, and rays
        // lying in the face found it inside or not by the rounding of the faces, so it was said to look
        // empty at some scales and not at others.)
        let flat = (hi - lo).min_element() <= tol;
        // (A probe that runs out of the scene's `EMPTY_PROBE_BUDGET` before it finds volume says nothing.)
        let looks_empty = !self.counted_at_least(WarnKind::LooksEmpty, MAX_EMPTY_PROBED)
            && (flat
                || crate::csg::reference::probe_finds_volume(&self.csg, solid, EMPTY_PROBE_GRID, &mut self.empty_probe_budget)
                    == Some(false));
        if looks_empty {
            // Kept (the probe can miss a solid thinner than its spacing), but most likely a mistake; or its
            // walls are thinner than the tolerance (a thin shell far from the origin), which merges them
            // away for the probe's rays as for the render's.
            let rays = 3 * EMPTY_PROBE_GRID * EMPTY_PROBE_GRID;
            self.warn_each(WarnKind::LooksEmpty, def.span(), field, || {
                format!(
                    "this CSG solid looks empty: {rays} probe rays across its bounds found no stretch inside it longer \
                         than its coincidence tolerance, {tol:.2e} (1e-5 of its farthest coordinate {scale:.2e}), and shorter \
                         ones render as nothing (is a hole as large as its part? or are its walls thinner than that \
                         tolerance? such walls merge away where rays cross them, in part or whole, though the camera may \
                         still see some: move the scene nearer the origin); it is kept"
                )
            });
        }
        // Each leaf's thickness in its own frame (`Leaf::thickness`): the world-axis bounds of a fin turned
        // 30 degrees are 0.5 thick, and a trial's fin 1e-4 thick at 100 was warned of only unturned.
        let thinnest = self.csg.solid_leaves(solid).filter_map(|k| self.csg.leaf(k).thickness()).fold(f64::INFINITY, f64::min);
        if thinnest < 10.0 * tol as f64 {
            // (A leaf thinner than an f32 step where it lies: a trial's leaf of 2e-9 at y = 0.5 was said to be
            // `0e0` thick by its bounds.)
            let step = f64::from(scale) * f64::from(f32::EPSILON);
            let thick =
                if thinnest > step { format!("only {thinnest:.4e} thick") } else { "thinner than f32 resolves where it lies".into() };
            self.warn_each(WarnKind::LostDetail, def.span(), field, || {
                format!(
                    "this CSG solid reaches {scale:e} from the origin, so surfaces closer than its coincidence tolerance \
                         ({tol:e}, 1e-5 of that) merge, and one of its leaves is {thick}: its detail may be lost \
                         (far-apart parts in one solid: make them separate solids; a solid far from the origin: move the \
                         scene nearer it)"
                )
            });
        }
        // Parts the operations make thinner than the tolerance (a hole's wall against the far face of its
        // part, a floor, a skin; each leaf thick) merge away as well: a trial's cup with walls 1e-4 thick on
        // a base, 20 from the origin, lost three walls and its floor without a word. Probed where no leaf
        // was warned of, in solids that do not look empty, while the scene's budget lasts.
        else if !looks_empty && self.thin_probe_budget > 0 {
            let (lo, hi) = (lo.as_dvec3(), hi.as_dvec3());
            let diag = (hi - lo).length();
            let reach = f64::from(crate::csg::merge::COINCIDENT_EPS) * (f64::from(scale) + diag);
            let fine = 0.05 * f64::from(tol);
            let found =
                crate::csg::reference::thinnest_part(&self.csg, solid, THIN_PROBE_GRID, 2.0 * reach, fine, &mut self.thin_probe_budget);
            if let Some(part) = found {
                let (t, p) = (part.thickness, part.at);
                self.warn_each(WarnKind::LostDetail, def.span(), field, || {
                    format!(
                        "this CSG solid has a part only {t:.2e} thick near ({:.4}, {:.4}, {:.4}) (a wall its operations leave: \
                         between a hole and a face, a floor, a skin), less than twice the coincidence tolerance its rays can use \
                         ({reach:.2e}: 1e-5 of its farthest coordinate, {scale:.2e}, plus its bounds' diagonal, {diag:.2e}): faces \
                         closer than the tolerance merge, so such a wall vanishes where rays cross it squarely (make it thicker, \
                         or move the scene nearer the origin); it is kept",
                        p.x, p.y, p.z
                    )
                });
            }
        }
        let shape = Shape::Csg { solid };
        self.within_range(&shape, motion, def, field)?;
        self.far_shift(&shape, motion, def, field);
        self.prims.push(Prim { shape, material: material.unwrap_or(0), motion, is_light: false });
        self.prim_at.push((def.span(), PrimField::Path(field.to_string())));
        Ok(())
    }

    /// Compile a solid's tree (just built by `csg_tree`, which set `unbounded_by`) into `csg`; an
    /// unbounded one is an error at the child that makes it so.
    fn add_solid(&mut self, tree: &CsgTree, def: &S<ShapeDef>, field: &str) -> R<u32> {
        self.csg.add_solid(tree).map_err(|e| match (e, self.unbounded_by.take()) {
            (csg::program::CsgError::Unbounded, Some((span, at, what))) => self.err(
                span,
                at,
                format!(
                    "{what} makes the CSG solid `{field}` unbounded: a half-space must be intersected with a bounded solid \
                     or subtracted from one (it cannot be a union operand, nor the solid a difference subtracts from)"
                ),
            ),
            _ => self.err(def.span(), field, format!("{e}")),
        })
    }

    /// An unused named solid's tree held to what placing it (`[[shapes]]` with `use`) would hold it to
    /// wherever it is placed: one medium where its parts meet, within [`MAX_MAGNITUDE`] of the origin.
    /// Compiled on its own, and left out of the scene. (Until a user trial these were checked only once
    /// used: two glasses that meet, a sphere reaching 1.1e15 were silent unused.) An unbounded solid is
    /// no error here: it is a fine operand of an intersection or the part a difference subtracts (a
    /// named half-space is meant for that), so an unused one is left alone.
    fn placed_alone(&mut self, tree: &CsgTree, def: &S<ShapeDef>, field: &str) -> R<()> {
        let scene = std::mem::take(&mut self.csg);
        let checked = match self.csg.add_solid(tree) {
            Err(csg::program::CsgError::Unbounded) => {
                self.unbounded_by = None;
                Ok(())
            }
            Err(e) => Err(self.err(def.span(), field, format!("{e}"))),
            Ok(solid) => {
                let (lo, hi) = self.csg.bounds(solid);
                if !lo.cmple(hi).all() {
                    Ok(())
                } else {
                    self.one_medium(field).and_then(|()| self.within_range(&Shape::Csg { solid }, Vec3::ZERO, def, field))
                }
            }
        };
        self.csg = scene;
        checked.map_err(|mut e| {
            e.message += &format!(" (no shape uses `{field}`: it is checked as if placed on its own)");
            e
        })
    }

    /// The name a material was defined under (`#id` for one made by a light).
    fn material_name(&self, m: u32) -> String {
        self.material_ids.iter().find(|(_, &id)| id == m).map_or_else(|| format!("#{m}"), |(n, _)| n.clone())
    }

    /// A CSG solid is one medium where its parts meet: a ray that enters through the surface of one
    /// glass and leaves through that of another would keep the first as its medium (and leave a medium
    /// it never entered), so its image would be wrong with no sign of it. Two leaves of the solid just
    /// made (`leaf_sites`) of different dielectrics, one of them not thin, whose bounds overlap (or one
    /// of them a half-space) are an error; leaves apart (beads of two glasses in one union) are not, nor
    /// are opaque leaves (a painted hole in glass: surfaces inside or on it).
    fn one_medium(&self, field: &str) -> R<()> {
        let dielectric = |m: u32| match &self.materials[m as usize] {
            Material::Dielectric(d) => Some(!d.thin),
            _ => None,
        };
        let overlap = |a: &LeafSite, b: &LeafSite| match (a.bounds, b.bounds) {
            (Some((alo, ahi)), Some((blo, bhi))) => alo.cmple(bhi).all() && blo.cmple(ahi).all(),
            _ => true,
        };
        let sites = &self.leaf_sites;
        // (Each leaf is compared with those before it: with one glass there is nothing to find, and a
        // solid of 125,000 leaves of one glass spent 5.8 s of its setup here.)
        let mut glasses = sites.iter().filter(|l| dielectric(l.material).is_some()).map(|l| l.material);
        let Some(glass) = glasses.next() else { return Ok(()) };
        if glasses.all(|m| m == glass) {
            return Ok(());
        }
        for (j, other) in sites.iter().enumerate() {
            let Some(other_solid) = dielectric(other.material) else { continue };
            let clash = sites[..j].iter().find(|first| {
                first.material != other.material
                    && dielectric(first.material).is_some_and(|solid| solid || other_solid)
                    && overlap(first, other)
            });
            let Some(first) = clash else { continue };
            let (a, b) = (self.material_name(first.material), self.material_name(other.material));
            return Err(self.err(
                other.span.clone(),
                other.field.clone(),
                format!(
                    "the CSG solid `{field}` joins the glasses `{a}` (given at {}) and `{b}` (here) where its parts meet, but a \
                     solid is one medium: a ray entering through one and leaving through the other would stay inside the \
                     first. Give the solid one material (a `material` on the solid overrides its children's), or make \
                     separate solids ranked by `priority`",
                    first.field
                ),
            ));
        }
        Ok(())
    }

    fn simple_shape(&self, def: &S<ShapeDef>, field: impl Display + Copy, kind: &str, t: Affine3A) -> R<Shape> {
        let s = def.get_ref();
        let sp = def.span();
        let f = |n: &'static str| Sub(field, n);
        Ok(match kind {
            "sphere" => {
                self.check_fields(def, field, kind, &["center", "radius", "motion"])?;
                let c = self.vec3(self.req(&s.center, sp.clone(), f("center"))?, f("center"))?;
                let r = self.positive(self.req(&s.radius, sp.clone(), f("radius"))?, f("radius"))?;
                match similarity_scale(&t) {
                    Some(k) => Shape::Sphere { center: t.transform_point3(c), radius: r * k },
                    None => {
                        Shape::Ellipsoid(Ellipsoid::new(t * Affine3A::from_scale_rotation_translation(Vec3::splat(r), Quat::IDENTITY, c)))
                    }
                }
            }
            "plane" => {
                self.check_fields(def, field, kind, &["point", "normal"])?;
                let p = self.vec3(self.req(&s.point, sp.clone(), f("point"))?, f("point"))?;
                let nd = self.req(&s.normal, sp.clone(), f("normal"))?;
                let n = self.unit(nd, f("normal"))?;
                let n = normal_matrix(&t).mul_vec3(n).normalize();
                let p = t.transform_point3(p);
                Shape::Plane(Plane { normal: n, offset: n.dot(p) })
            }
            "box" => {
                self.check_fields(def, field, kind, &["min", "max", "motion"])?;
                let (lo, hi) = self.min_max(def, field)?;
                let half = (hi - lo) * 0.5;
                let center = (hi + lo) * 0.5;
                Shape::Box(OBox::new(t * Affine3A::from_translation(center), half))
            }
            "quad" => {
                self.check_fields(def, field, kind, &["origin", "u", "v", "motion"])?;
                let (o, u, v) = self.parallelogram(def.span(), &s.origin, &s.u, &s.v, field)?;
                Shape::Quad(Quad::new(t.transform_point3(o), t.transform_vector3(u), t.transform_vector3(v)))
            }
            "disk" => {
                self.check_fields(def, field, kind, &["center", "normal", "radius", "motion"])?;
                let c = self.vec3(self.req(&s.center, sp.clone(), f("center"))?, f("center"))?;
                let n = self.unit(self.req(&s.normal, sp.clone(), f("normal"))?, f("normal"))?;
                let r = self.positive(self.req(&s.radius, sp.clone(), f("radius"))?, f("radius"))?;
                let k = similarity_scale(&t).ok_or_else(|| {
                    self.err(s.transform.as_ref().map_or(sp.clone(), |x| x.span()), f("transform"), "a disk needs a uniform scale")
                })?;
                Shape::Disk(Disk { center: t.transform_point3(c), normal: normal_matrix(&t).mul_vec3(n).normalize(), radius: r * k })
            }
            _ => unreachable!(),
        })
    }

    fn unit(&self, v: &V3, field: impl Display + Copy) -> R<Vec3> {
        let n = self.vec3(v, field)?;
        if n.length_squared() < 1e-20 {
            return Err(self.err(v.span(), field, too_short(n, 1e-10)));
        }
        Ok(n.normalize())
    }

    fn min_max(&self, def: &S<ShapeDef>, field: impl Display + Copy) -> R<(Vec3, Vec3)> {
        let s = def.get_ref();
        let lo_d = self.req(&s.min, def.span(), Sub(field, "min"))?;
        let hi_d = self.req(&s.max, def.span(), Sub(field, "max"))?;
        let lo = self.vec3(lo_d, Sub(field, "min"))?;
        let hi = self.vec3(hi_d, Sub(field, "max"))?;
        if !(hi.cmpgt(lo).all()) {
            return Err(self.err(hi_d.span(), format!("{field}.max"), "every component of max must exceed min"));
        }
        Ok((lo, hi))
    }

    fn parallelogram<F: Field<Nums<3>>>(
        &self,
        span: Range<usize>,
        o: &Option<F>,
        u: &Option<F>,
        v: &Option<F>,
        field: impl Display + Copy,
    ) -> R<(Vec3, Vec3, Vec3)> {
        let f = |n: &'static str| Sub(field, n);
        let o = self.vec3(self.req(o, span.clone(), f("origin"))?, f("origin"))?;
        let ud = self.req(u, span.clone(), f("u"))?;
        let u = self.vec3(ud, f("u"))?;
        let vd = self.req(v, span.clone(), f("v"))?;
        let v = self.vec3(vd, f("v"))?;
        for (x, d, n) in [(u, ud, "u"), (v, vd, "v")] {
            if x == Vec3::ZERO {
                return Err(self.err(d.span(), f(n), "must be non-zero (an edge of the parallelogram)"));
            }
        }
        // (In f64: the squares of the cross product's length are fourth powers of the sides, which
        // overflow or underflow f32 for sides past 1e9 or below 1e-10.)
        let (u64_, v64) = (u.as_dvec3(), v.as_dvec3());
        if u64_.cross(v64).length_squared() <= 1e-30 * u64_.length_squared() * v64.length_squared() || u.cross(v) == Vec3::ZERO {
            return Err(self.err(vd.span(), f("v"), "u and v must not be parallel (or so short that their cross product vanishes)"));
        }
        Ok((o, u, v))
    }

    /// Set `unbounded_by` for a node of `op` whose children's culprits (`None`: bounded) are `culprits`.
    /// The rule is `Csg::add_solid`'s bounds, on the children's flags (a child is unbounded exactly when
    /// it has a culprit): a union is bounded when all its operands are, a difference when its first is,
    /// an intersection when any is (a half-space only clips a finite box).
    fn node_culprit(&mut self, op: Op, mut culprits: Vec<Option<(Range<usize>, String, String)>>, span: Range<usize>, field: &str) {
        self.unbounded_by = match op {
            Op::Union => culprits.into_iter().flatten().next(),
            Op::Difference => culprits.swap_remove(0),
            Op::Intersection if culprits.iter().any(Option::is_none) => None,
            Op::Intersection => Some((span, field.to_string(), "this intersection of unbounded solids only".to_string())),
        };
    }

    /// How many CSG leaves `def` makes once its `use`s expand, counted before any is built (each named
    /// solid once, in `leaf_counts`; saturating: ten levels of ten uses each are 10^10). `depth` is
    /// `csg_tree`'s: a cycle, a missing solid or nesting past [`MAX_CSG_DEPTH`] counts 0 there, since
    /// `csg_tree` stops with its error where it meets them, before it builds the leaves past them.
    fn csg_leaves(&mut self, def: &S<ShapeDef>, depth: usize) -> u64 {
        if depth > MAX_CSG_DEPTH {
            return 0;
        }
        let s = def.get_ref();
        if let Some(u) = &s.use_solid {
            let name = u.get_ref();
            if let Some(n) = self.leaf_counts.get(name) {
                return n.unwrap_or(0);
            }
            let Some(target) = self.file.solids.get(name) else { return 0 };
            self.leaf_counts.insert(name.clone(), None);
            let n = self.csg_leaves(target, depth + 1);
            self.leaf_counts.insert(name.clone(), Some(n));
            return n;
        }
        match (s.kind.as_ref().map(|k| k.get_ref().as_str()), &s.children) {
            (Some("csg" | "group"), Some(c)) => c.get_ref().iter().fold(0, |n: u64, c| n.saturating_add(self.csg_leaves(c, depth + 1))),
            _ => 1,
        }
    }

    /// Build a CSG tree; `parent` is the parent's transform, `material` the inherited override. Sets
    /// `unbounded_by` for the subtree: a bare half-space names itself, a node the child that makes it
    /// unbounded (`node_culprit`), a `use` what its definition's tree set; `None` when bounded.
    fn csg_tree(
        &mut self,
        def: &S<ShapeDef>,
        field: &str,
        parent: Affine3A,
        material: Option<u32>,
        depth: usize,
        uses: &mut Vec<String>,
    ) -> R<CsgTree> {
        self.unbounded_by = None;
        if depth > MAX_CSG_DEPTH {
            return Err(self.err(def.span(), field, format!("CSG nesting deeper than {MAX_CSG_DEPTH}")));
        }
        let s = def.get_ref();
        let t = parent * self.transform(&s.transform, field)?;
        let f = |n: &str| format!("{field}.{n}");
        if depth > 0 {
            if let Some(m) = &s.motion {
                // (A named solid's own definition is reached at depth 1 and up, under its own name.)
                let msg = match uses.last().filter(|n| field.strip_prefix("solids.") == Some(n.as_str())) {
                    Some(name) => format!(
                        "a named solid's definition takes no motion: give it where the solid is placed at the top level, \
                         `[[shapes]]` with `use = \"{name}\"` and `motion = [...]`"
                    ),
                    None => "motion applies to a whole top-level shape, not a CSG child".to_string(),
                };
                return Err(self.err(m.span(), f("motion"), msg));
            }
        }
        // Outermost material wins: a node's material overrides its descendants. Every material name
        // written must still name a material, overridden or not (a misspelt name is an error wherever
        // it is written, not only where it would be used).
        let saved_from = self.material_from.clone();
        let own = match &s.material {
            Some(m) => Some(self.material_ref(m, &f("material"))?),
            None => None,
        };
        let material = match (material, own, &s.material) {
            (Some(m), _, _) => Some(m),
            (None, Some(m), Some(d)) => {
                self.material_from = Some((d.span(), f("material")));
                Some(m)
            }
            _ => None,
        };
        if let Some(u) = &s.use_solid {
            let name = u.get_ref();
            let Some(target) = self.file.solids.get(name) else {
                let known: Vec<&str> = self.file.solids.keys().map(|k| k.as_str()).collect();
                return Err(self.err(
                    u.span(),
                    f("use"),
                    format!("no solid named `{name}` (defined: {})", if known.is_empty() { "none".into() } else { known.join(", ") }),
                ));
            };
            if uses.contains(name) {
                return Err(self.err(
                    u.span(),
                    f("use"),
                    format!("solid `{name}` refers to itself (cycle: {} -> {name})", uses.join(" -> ")),
                ));
            }
            // (`motion` reaches here only at the top level, where `top_shape` applies it to the
            // placed solid: a CSG child's motion was refused above; `hole`, only in a group's
            // children, where the group reads it.)
            self.check_fields(def, field, "use", &["motion", "hole"])?;
            self.solid_definition(name, target)?;
            self.used_solids.insert(name.clone());
            uses.push(name.clone());
            let r = self.csg_tree(target, &format!("solids.{name}"), t, material, depth + 1, uses);
            uses.pop();
            self.material_from = saved_from;
            // An error inside the definition is located there; say which use reached it (a solid used
            // twice may fail through one use only, e.g. the one without a material).
            return r.map_err(|mut e| {
                if !e.message.contains("(reached through") {
                    let at = self.err(u.span(), f("use"), "");
                    e.message += &format!(" (reached through `use = \"{name}\"` at {}, line {})", f("use"), at.line);
                }
                e
            });
        }
        let kind_s = self.req(&s.kind, def.span(), &f("type"))?;
        let kind = kind_s.get_ref().as_str();
        let mat = |c: &Self| -> R<u32> {
            material.or(c.lenient_material.then_some(0)).ok_or_else(|| {
                c.err(
                    def.span(),
                    f("material"),
                    "missing required field (a CSG leaf needs a material of its own or from an enclosing node)",
                )
            })
        };
        let sp = def.span();
        let leaf = |shape: csg::Shape, place: Affine3A, m: u32| CsgTree::Leaf(csg::Leaf::new(shape, t * place, m));
        let tree = match kind {
            "sphere" => {
                self.check_fields(def, field, kind, &["center", "radius", "motion", "hole"])?;
                let c = self.vec3(self.req(&s.center, sp.clone(), &f("center"))?, &f("center"))?;
                let r = self.positive(self.req(&s.radius, sp.clone(), &f("radius"))?, &f("radius"))?;
                leaf(csg::Shape::Sphere, Affine3A::from_scale_rotation_translation(Vec3::splat(r), Quat::IDENTITY, c), mat(self)?)
            }
            "box" => {
                self.check_fields(def, field, kind, &["min", "max", "motion", "hole"])?;
                let (lo, hi) = self.min_max(def, field)?;
                leaf(csg::Shape::Box, Affine3A::from_scale_rotation_translation((hi - lo) * 0.5, Quat::IDENTITY, (hi + lo) * 0.5), mat(self)?)
            }
            "cylinder" | "cone" => {
                let allowed: &[&str] = if kind == "cone" { &["center", "radius", "radius_top", "height", "motion", "hole"] } else { &["center", "radius", "height", "motion", "hole"] };
                self.check_fields(def, field, kind, allowed)?;
                let c = match &s.center {
                    Some(c) => self.vec3(c, &f("center"))?,
                    None => Vec3::ZERO,
                };
                let h = self.positive(self.req(&s.height, sp.clone(), &f("height"))?, &f("height"))?;
                let (shape, r) = if kind == "cone" {
                    // Either radius may be 0 (the apex on that cap), not both.
                    let r_d = self.req(&s.radius, sp.clone(), &f("radius"))?;
                    let rt_d = self.req(&s.radius_top, sp.clone(), &f("radius_top"))?;
                    for (v, name) in [(r_d, "radius"), (rt_d, "radius_top")] {
                        let x = *v.get_ref();
                        if !(x.is_finite() && x >= 0.0) {
                            return Err(self.err(v.span(), f(name), format!("must be a finite number >= 0, got {x}")));
                        }
                        if x > MAX_MAGNITUDE {
                            return Err(self.err(v.span(), f(name), format!("must be at most {MAX_MAGNITUDE:e} ({BEYOND}), got {x:e}")));
                        }
                    }
                    let (r, rt) = (*r_d.get_ref(), *rt_d.get_ref());
                    if r.max(rt) == 0.0 {
                        return Err(self.err(r_d.span(), f("radius"), "radius and radius_top are both 0: one must be > 0"));
                    }
                    csg_cone(r, rt)
                } else {
                    (csg::Shape::Cylinder, self.positive(self.req(&s.radius, sp.clone(), &f("radius"))?, &f("radius"))?)
                };
                // Canonical cylinder/cone: see csg::solid; centre `c` is the middle of the axis (along +y).
                leaf(shape, csg_axis_placement(c, r, h), mat(self)?)
            }
            "torus" => {
                self.check_fields(def, field, kind, &["center", "major_radius", "minor_radius", "motion", "hole"])?;
                let c = match &s.center {
                    Some(c) => self.vec3(c, &f("center"))?,
                    None => Vec3::ZERO,
                };
                let big = self.positive(self.req(&s.major_radius, sp.clone(), &f("major_radius"))?, &f("major_radius"))?;
                let small = self.positive(self.req(&s.minor_radius, sp.clone(), &f("minor_radius"))?, &f("minor_radius"))?;
                if small >= big {
                    return Err(self.err(s.minor_radius.as_ref().unwrap().span(), f("minor_radius"), "must be smaller than major_radius (spindle tori are not supported)"));
                }
                leaf(csg_torus(1.0, small / big), csg_torus_placement(c, big), mat(self)?)
            }
            "halfspace" => {
                if depth == 0 {
                    return Err(self.err(kind_s.span(), f("type"), "a half-space is unbounded: use it inside an intersection or difference (or use a `plane` shape)"));
                }
                self.check_fields(def, field, kind, &["point", "normal", "hole"])?;
                let p = self.vec3(self.req(&s.point, sp.clone(), &f("point"))?, &f("point"))?;
                let n = self.unit(self.req(&s.normal, sp.clone(), &f("normal"))?, &f("normal"))?;
                let m = mat(self)?;
                self.unbounded_by = Some((sp.clone(), field.to_string(), "this half-space".to_string()));
                leaf(csg::Shape::HalfSpace, csg_halfspace_placement(p, n), m)
            }
            "csg" | "group" => {
                self.check_fields(def, field, kind, &["op", "children", "motion", "hole"])?;
                let children = match &s.children {
                    None => return Err(self.err(sp.clone(), f("children"), "missing required field (a non-empty list of solids)")),
                    // (A trial's `children = []` was called missing.)
                    Some(c) if c.get_ref().is_empty() => {
                        return Err(self.err(c.span(), f("children"), format!("is empty: a `{kind}` needs at least one solid in `children`")))
                    }
                    Some(c) => c.get_ref(),
                };
                if kind == "group" {
                    if let Some(op) = &s.op {
                        return Err(self.err(op.span(), f("op"), "a `group` has no op: it is the union of its children minus those marked `hole = true`"));
                    }
                    let (mut solids, mut holes, mut culprits) = (Vec::new(), Vec::new(), Vec::new());
                    for (i, c) in children.iter().enumerate() {
                        let sub = self.csg_tree(c, &format!("{field}.children[{i}]"), t, material, depth + 1, uses)?;
                        if c.get_ref().hole.as_ref().is_some_and(|h| *h.get_ref()) {
                            holes.push(sub);
                        } else {
                            solids.push(sub);
                            culprits.push(self.unbounded_by.take());
                        }
                    }
                    if solids.is_empty() {
                        return Err(self.err(sp, f("children"), "a group needs at least one child that is not a hole"));
                    }
                    // (Holes are subtracted: only the solids' union can make the group unbounded.)
                    self.node_culprit(Op::Union, culprits, sp.clone(), field);
                    let body = CsgTree::Node { op: Op::Union, children: solids };
                    if holes.is_empty() {
                        body
                    } else {
                        CsgTree::Node { op: Op::Difference, children: vec![body, CsgTree::Node { op: Op::Union, children: holes }] }
                    }
                } else {
                    let op_d = self.req(&s.op, sp.clone(), &f("op"))?;
                    let op = match op_d.get_ref().as_str() {
                        "union" => Op::Union,
                        "intersection" => Op::Intersection,
                        "difference" => Op::Difference,
                        other => return Err(self.err(op_d.span(), f("op"), format!("expected union, intersection or difference, got `{other}`"))),
                    };
                    let (mut kids, mut culprits) = (Vec::with_capacity(children.len()), Vec::with_capacity(children.len()));
                    for (i, c) in children.iter().enumerate() {
                        if let Some(h) = c.get_ref().hole.as_ref().filter(|h| *h.get_ref()) {
                            return Err(self.err(
                                h.span(),
                                format!("{field}.children[{i}].hole"),
                                "`hole = true` only applies to children of a `group` (a `csg` subtracts by `op = \"difference\"`)",
                            ));
                        }
                        kids.push(self.csg_tree(c, &format!("{field}.children[{i}]"), t, material, depth + 1, uses)?);
                        culprits.push(self.unbounded_by.take());
                    }
                    self.node_culprit(op, culprits, sp.clone(), field);
                    if op == Op::Difference && kids.len() == 1 && self.lone_differences.insert(op_d.span().start) {
                        // (Valid, A - nothing = A, but most likely a hole left out: a user trial.)
                        self.warn_each(WarnKind::LoneDifference, op_d.span(), Sub(field, "op"), || {
                            "a difference of one operand subtracts nothing: the solid is that operand (is a hole \
                             missing from `children`?)"
                                .to_string()
                        });
                    }
                    CsgTree::Node { op, children: kids }
                }
            }
            "plane" | "quad" | "disk" => {
                return Err(self.err(kind_s.span(), f("type"), format!("a `{kind}` is not a closed solid; CSG takes sphere, box, cylinder, cone, torus, halfspace, csg, group")));
            }
            other => {
                return Err(self.err(
                    kind_s.span(),
                    f("type"),
                    format!("unknown shape type `{other}` (sphere, plane, box, quad, disk, cylinder, cone, torus, csg, group; halfspace inside CSG)"),
                ))
            }
        };
        // (Not a leaf of an unused solid that has no material: the 0 it was given stands for a use's.)
        if let (CsgTree::Leaf(l), Some(_)) = (&tree, material) {
            let (span, field) = self.material_from.clone().unwrap_or((sp, f("material")));
            self.leaf_sites.push(LeafSite { material: l.material, span, field, bounds: l.bounds() });
        }
        self.material_from = saved_from;
        Ok(tree)
    }

    /// Warn of a light that gives none (valid, and sampled at every shading point all the same: a user
    /// trial's lights of intensity and radiance [0, 0, 0] were silent).
    fn dark_light(&mut self, power: Vec3, span: Range<usize>, field: &str, what: &'static str) {
        if power == Vec3::ZERO {
            let area = if what == "radiance" { " (its surface is still seen, black, and casts shadows)" } else { "" };
            self.warn_each(WarnKind::DarkLight, span, Sub(field, what), || {
                format!("a light of {what} [0, 0, 0] gives no light{area}: give it a {what} > 0, or remove it")
            });
        }
    }

    fn light(&mut self, def: &S<LightDef>, field: &str) -> R<()> {
        let l = def.get_ref();
        let sp = def.span();
        let f = |n: &str| format!("{field}.{n}");
        let kind = l.kind.get_ref().as_str();
        let present: Vec<(&str, Range<usize>)> = [
            ("position", l.position.as_ref().map(|x| x.span())),
            ("intensity", l.intensity.as_ref().map(|x| x.span())),
            ("origin", l.origin.as_ref().map(|x| x.span())),
            ("u", l.u.as_ref().map(|x| x.span())),
            ("v", l.v.as_ref().map(|x| x.span())),
            ("center", l.center.as_ref().map(|x| x.span())),
            ("normal", l.normal.as_ref().map(|x| x.span())),
            ("radius", l.radius.as_ref().map(|x| x.span())),
            ("radiance", l.radiance.as_ref().map(|x| x.span())),
        ]
        .into_iter()
        .filter_map(|(n, s)| s.map(|s| (n, s)))
        .collect();
        let allowed: &[&str] = match kind {
            "point" => &["position", "intensity"],
            "quad" => &["origin", "u", "v", "radiance"],
            "disk" => &["center", "normal", "radius", "radiance"],
            "sphere" => &["center", "radius", "radiance"],
            other => return Err(self.err(l.kind.span(), f("type"), format!("unknown light type `{other}` (point, quad, disk, sphere)"))),
        };
        for (name, span) in &present {
            if !allowed.contains(name) {
                return Err(self.err(
                    span.clone(),
                    f(name),
                    format!("does not apply to {} `{kind}` light (allowed: {})", a_or_an(kind), allowed.join(", ")),
                ));
            }
        }
        if kind == "point" {
            let position = self.vec3(self.req(&l.position, sp.clone(), &f("position"))?, &f("position"))?;
            let given = self.req(&l.intensity, sp.clone(), &f("intensity"))?;
            let intensity = self.color(given, &f("intensity"), None)?;
            self.dark_light(intensity, given.span(), field, "intensity");
            self.lights.push(Light::Point { position, intensity });
            return Ok(());
        }
        let given = self.req(&l.radiance, sp.clone(), &f("radiance"))?;
        let radiance = self.color(given, &f("radiance"), None)?;
        self.dark_light(radiance, given.span(), field, "radiance");
        let material = self.materials.len() as u32;
        self.materials.push(Material::Emissive { radiance });
        let (light, shape) = match kind {
            "quad" => {
                let (o, u, v) = self.parallelogram(sp.clone(), &l.origin, &l.u, &l.v, field)?;
                let q = Quad::new(o, u, v);
                (Light::Quad { quad: q, radiance }, Shape::Quad(q))
            }
            "disk" => {
                let c = self.vec3(self.req(&l.center, sp.clone(), &f("center"))?, &f("center"))?;
                let n = self.unit(self.req(&l.normal, sp.clone(), &f("normal"))?, &f("normal"))?;
                let r = self.positive(self.req(&l.radius, sp.clone(), &f("radius"))?, &f("radius"))?;
                let d = Disk { center: c, normal: n, radius: r };
                (Light::Disk { disk: d, radiance }, Shape::Disk(d))
            }
            "sphere" => {
                let c = self.vec3(self.req(&l.center, sp.clone(), &f("center"))?, &f("center"))?;
                let r = self.positive(self.req(&l.radius, sp.clone(), &f("radius"))?, &f("radius"))?;
                (Light::Sphere { center: c, radius: r, radiance }, Shape::Sphere { center: c, radius: r })
            }
            _ => unreachable!(),
        };
        self.lights.push(light);
        self.prims.push(Prim { shape, material, motion: Vec3::ZERO, is_light: true });
        self.prim_at.push((def.span(), PrimField::Path(field.to_string())));
        Ok(())
    }
}

/// A light buffer per point light over the bounded prims (static spheres by their own sphere, the
/// others by the sphere around their box, swept over the shutter for moving prims), in scenes without
/// CSG solids: a solid's bounding sphere is loose and each candidate costs an 8-lane interval merge,
/// where the traversal's leaf boxes reject most packets first (bench_csg's shadow stage took 16-30%
/// longer through the buffer, csg.toml 8%).
pub fn light_buffers(lights: &[Light], prims: &[Prim], bounds: &[Aabb], bounded: &[u32]) -> Vec<Option<LightBuffer>> {
    light_buffers_within(lights, prims, bounds, bounded, LIGHT_BUFFER_ENTRIES)
}

/// [`light_buffers`] within `budget` entries in all: a buffer that would exceed what is left of it is
/// given up while it is made, and none is built once the budget is spent (those lights' shadow rays are
/// traced through the BVH); so are
/// lights past the first [`MAX_LIGHT_BUFFERS`] point lights, whose buffers would cost more to build
/// than they save (1,000 point lights over 1e4 spheres: 15 s to build, the render as fast without),
/// and a buffer whose `always` list is longer than [`MAX_ALWAYS`] or whose cells list more than
/// [`MAX_MEAN_LIST`] prims on average (each of its rays would test all of those: one huge prim around
/// the light, or a light above a lattice of long thin beams, whose cones are wide).
fn light_buffers_within(lights: &[Light], prims: &[Prim], bounds: &[Aabb], bounded: &[u32], budget: usize) -> Vec<Option<LightBuffer>> {
    if prims.iter().any(|p| matches!(p.shape, Shape::Csg { .. })) {
        return vec![None; lights.len()];
    }
    let spheres: Vec<(u32, Bound)> = bounded
        .iter()
        .map(|&pid| {
            let p = &prims[pid as usize];
            let bound = match p.shape {
                Shape::Sphere { center, radius } if p.motion == Vec3::ZERO => Bound { center: center.as_dvec3(), radius: radius as f64 },
                _ => Bound::of_box(bounds[pid as usize].min, bounds[pid as usize].max),
            };
            (pid, bound)
        })
        .collect();
    let (mut budget, mut built) = (budget, 0);
    lights
        .iter()
        .map(|l| match *l {
            Light::Point { position, .. } if budget > 0 && built < MAX_LIGHT_BUFFERS => {
                built += 1;
                // (Given up as soon as it would pass the budget, the mean list or the `always` list: `None`.)
                let lb = LightBuffer::build_within(position, 0.0, &spheres, None, budget, MAX_MEAN_LIST, MAX_ALWAYS)?;
                budget -= lb.entry_count();
                Some(lb)
            }
            _ => None,
        })
        .collect()
}

/// Point lights that get a light buffer (the first ones declared).
pub const MAX_LIGHT_BUFFERS: usize = 32;

/// The longest `always` list a light buffer may have (beyond it the BVH answers that light's rays).
pub const MAX_ALWAYS: usize = 16;

/// The most entries a light buffer's non-empty cells may hold on average (`bench_spheres`: 1.3).
pub const MAX_MEAN_LIST: f64 = 32.0;

/// Warnings of one kind shown in full before the rest are counted ([`Compiler::warn_each`], and
/// [`Compiler::warn_pairs`] for pairs).
const SHOWN_PER_KIND: usize = 8;

/// Rays per side of the grid on each axis with which a CSG solid is probed for thin parts (`3 n^2` rays).
const THIN_PROBE_GRID: u32 = 8;

/// Leaf tests and program instructions the thin-part probes of one scene may take in all, 0.05-0.3 s
/// (bench_csg's 208 solids take 172,000 of them, 20 ms); the probe stops where it runs out. (It was
/// charged an estimate, leaves x rays, which left out that the program runs at each group of crossings:
/// a solid of 10^5 overlapping spheres took 21 s.)
const THIN_PROBE_BUDGET: u64 = 1 << 22;

/// Solids found to look empty after which the others are not probed (the probe of one costs ~0.4 ms).
const MAX_EMPTY_PROBED: usize = 64;

/// Leaf tests and program instructions the probes for solids that look empty may take in one scene
/// (~0.1 s; 64 empty solids of three leaves take 2.6 M, bench_csg's 208 solids 47,000); a probe that
/// runs out says nothing (a solid of 8,000 leaves that looks empty was probed in 1.1 s, and is no longer).
const EMPTY_PROBE_BUDGET: u64 = 1 << 24;

/// The kinds of warning that any number of shapes may earn ([`Compiler::warn_each`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum WarnKind {
    ThinGlass,
    EmptySolid,
    LooksEmpty,
    LostDetail,
    LoneDifference,
    DarkLight,
    FarShift,
}

impl WarnKind {
    /// The kind in a few words, for the count of those not shown (`n` of them in all).
    fn says(self, n: usize) -> String {
        match self {
            WarnKind::ThinGlass => "glass balls or boxes thinner than four spawn offsets where they lie, as above".into(),
            WarnKind::EmptySolid => "empty CSG solids, left out, as above".into(),
            WarnKind::LooksEmpty if n >= MAX_EMPTY_PROBED => format!(
                "CSG solids that look empty, as above (the probe stops after {MAX_EMPTY_PROBED} such solids: the \
                 solids after the last of them were not probed, and more may look empty)"
            ),
            WarnKind::LooksEmpty => "CSG solids that look empty, as above".into(),
            WarnKind::LostDetail => "CSG solids whose detail may be lost to their coincidence tolerance, as above".into(),
            WarnKind::LoneDifference => "differences of one operand, as above".into(),
            WarnKind::DarkLight => "lights that give no light, as above".into(),
            WarnKind::FarShift => "moving shapes shifted far enough to lose precision, as above".into(),
        }
    }
}

/// Entries (8 bytes each) all of a scene's light buffers may hold together: 128 MiB (a buffer's build
/// takes 12 bytes per entry more while it runs).
pub const LIGHT_BUFFER_ENTRIES: usize = 16 << 20;

/// Derive [`Dielectric::passable`]: which dielectrics a shadow ray may cross without deflection somewhere
/// in this scene. Conservative (may say yes for a surface that is never a null crossing; the shadow stage
/// then walks the ray and finds out), never no for one that can be: a thin sheet; a constant index equal
/// to air's or to another used medium's (an index-matched interface); a priority below the highest among
/// the used media (its surfaces inside a higher-priority medium are null crossings).
fn mark_passable(materials: &mut [Material], used: &[bool]) {
    let media: Vec<&Dielectric> = materials
        .iter()
        .zip(used)
        .filter_map(|(m, &u)| match m {
            Material::Dielectric(d) if u && !d.thin => Some(d),
            _ => None,
        })
        .collect();
    let top = media.iter().map(|d| d.priority).max().unwrap_or(0);
    let constant = |d: &Dielectric| (!d.ior.is_dispersive()).then(|| d.ior.nominal());
    let indices: Vec<Option<f32>> = media.iter().map(|d| constant(d)).collect();
    let flags: Vec<bool> = materials
        .iter()
        .map(|m| match m {
            Material::Dielectric(d) => {
                let n = constant(d);
                let matched = n.is_some_and(|n| n == 1.0 || indices.iter().filter(|&&o| o == Some(n)).count() > 1);
                d.thin || matched || d.priority < top
            }
            _ => false,
        })
        .collect();
    for (m, f) in materials.iter_mut().zip(flags) {
        if let Material::Dielectric(d) = m {
            d.passable = f;
        }
    }
}

/// A number for a message: as written for ordinary magnitudes (`10`, `0.5`), in exponent form for
/// others (`1e30`, not its 31 digits).
/// The error of a solid of `leaves` CSG leaves in a scene that holds `before` already.
fn too_many_leaves(leaves: u64, before: u64) -> String {
    let n = if leaves == u64::MAX { format!("more than {}", u64::MAX) } else { leaves.to_string() };
    if leaves > MAX_CSG_LEAVES {
        format!("expands to {n} CSG leaves; the limit is {MAX_CSG_LEAVES} in a scene (count each `use` as a copy of its solid)")
    } else {
        format!(
            "expands to {n} CSG leaves, which with the {before} of the shapes before it make more than the limit of \
             {MAX_CSG_LEAVES} in a scene (count each `use` as a copy of its solid)"
        )
    }
}

/// `[x, y, z]` with each number as [`plain_number`] writes it.
fn plain_vec(v: Vec3) -> String {
    format!("[{}, {}, {}]", plain_number(v.x), plain_number(v.y), plain_number(v.z))
}

fn plain_number(x: f32) -> String {
    if x == 0.0 || (1e-3..1e6).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// Why a direction (`normal`, `up`) shorter than `min` is refused: the zero vector, or a vector that is
/// not zero but too short to normalise (`[0, 1e-30, 0]`: its squared length underflows f32).
fn too_short(v: Vec3, min: f32) -> String {
    if v == Vec3::ZERO {
        return "must not be the zero vector".to_string();
    }
    format!(
        "is too short to normalise (length {:e}, below {min:.1e}): give the direction at an ordinary length, e.g. [0, 1, 0]",
        v.as_dvec3().length() as f32
    )
}

/// The uniform scale of a similarity transform (rotation x uniform scale), or None.
pub fn similarity_scale(t: &Affine3A) -> Option<f32> {
    let m = t.matrix3;
    let (a, b, c) = (m.x_axis, m.y_axis, m.z_axis);
    let (la, lb, lc) = (a.length(), b.length(), c.length());
    let tol = 1e-5 * la.max(lb).max(lc);
    let ortho = a.dot(b).abs() <= tol * la.max(lb) && a.dot(c).abs() <= tol * la.max(lc) && b.dot(c).abs() <= tol * lb.max(lc);
    ((la - lb).abs() <= tol && (la - lc).abs() <= tol && ortho).then_some(la)
}

/// Transforms normals: the inverse transpose of the linear part.
pub fn normal_matrix(t: &Affine3A) -> Mat3 {
    Mat3::from(t.matrix3).inverse().transpose()
}

/// World bounds of a primitive (None for unbounded planes), widened outward by a few ulps: the corners
/// are computed in f32 and rounded to nearest, which can cut off a sliver of the surface.
pub fn prim_bounds(shape: &Shape, csg: &Csg) -> Option<Aabb> {
    exact_bounds(shape, csg).map(|b| b.widened_ulps())
}

fn exact_bounds(shape: &Shape, csg: &Csg) -> Option<Aabb> {
    Some(match shape {
        Shape::Sphere { center, radius } => Aabb::new(*center - Vec3::splat(*radius), *center + Vec3::splat(*radius)),
        Shape::Ellipsoid(e) => affine_box_bounds(&e.world_to_object.inverse(), Vec3::ONE),
        Shape::Plane(_) => return None,
        Shape::Quad(q) => {
            let mut b = Aabb::from_point(q.origin);
            b.grow(q.origin + q.u);
            b.grow(q.origin + q.v);
            b.grow(q.origin + q.u + q.v);
            b
        }
        Shape::Disk(d) => {
            let n = d.normal;
            let e = d.radius * (Vec3::ONE - n * n).max(Vec3::ZERO).powf(0.5);
            Aabb::new(d.center - e, d.center + e)
        }
        Shape::Box(b) => affine_box_bounds(&b.world_to_object.inverse(), b.half),
        Shape::Csg { solid } => {
            let (lo, hi) = csg.bounds(*solid);
            Aabb::new(lo, hi)
        }
    })
}

/// Bounds of the box [-half, half] under an affine map.
pub fn affine_box_bounds(t: &Affine3A, half: Vec3) -> Aabb {
    let c = Vec3::from(t.translation);
    let m = t.matrix3;
    let e = Vec3::from(m.x_axis).abs() * half.x + Vec3::from(m.y_axis).abs() * half.y + Vec3::from(m.z_axis).abs() * half.z;
    Aabb::new(c - e, c + e)
}

// Adapters to the canonical CSG shapes (defined in csg::solid).
/// The canonical cone of the scene's radii and the radius it is placed by: the larger, so that the
/// canonical radii lie in [0, 1] whichever end is narrow (scaled by the smaller, an apex-down cone of
/// radius 1e-10 had object coordinates of 1e10, whose squares overflowed f32).
fn csg_cone(r_bottom: f32, r_top: f32) -> (csg::Shape, f32) {
    let r = r_bottom.max(r_top);
    (csg::Shape::Cone { r0: r_bottom / r, r1: r_top / r }, r)
}

/// Canonical cylinders and cones have radius 1 and z in [-1, 1] (axis +z); the scene's axis is +y.
fn csg_axis_placement(center: Vec3, radius: f32, height: f32) -> Affine3A {
    Affine3A::from_scale_rotation_translation(Vec3::new(radius, radius, height * 0.5), Quat::from_rotation_arc(Vec3::Z, Vec3::Y), center)
}

fn csg_torus(major: f32, minor: f32) -> csg::Shape {
    csg::Shape::Torus { major, minor }
}

/// The canonical torus lies in the xy plane around +z; the scene's lies in the xz plane around +y. Placed
/// by a scale of its major radius (the canonical one 1): the canonical form's floor on the major radius
/// (1e-6, absolute) once enlarged a torus of major radius 5e-7 twofold.
fn csg_torus_placement(center: Vec3, major: f32) -> Affine3A {
    Affine3A::from_scale_rotation_translation(Vec3::splat(major), Quat::from_rotation_arc(Vec3::Z, Vec3::Y), center)
}

fn csg_halfspace_placement(point: Vec3, normal: Vec3) -> Affine3A {
    // Canonical half-space: z <= 0 (outward normal +z), rotated so +z becomes `normal`, moved to `point`.
    Affine3A::from_rotation_translation(Quat::from_rotation_arc(Vec3::Z, normal), point)
}

/// Whether two balls (`Shape::Sphere`) have surfaces within the spawn offset of each other: tangent
/// outside or inside within it, or one poking out of the other (or overlapping it) by less than it. The
/// surfaces are nearest along the line of centres, where the gap is `d - (r1 + r2)` (balls apart or
/// overlapping) or `|r1 - r2| - d` (one inside the other, or poking out of it); either within 256 ULPs of
/// the farthest coordinate of the two balls (the spawn offset, taken where it is largest), in f64.
/// Equal balls give `true` too; the caller leaves out the pairs the sphere check
/// (`coincident_glass_spheres`) warned of.
fn balls_nearly_tangent(a: &Shape, b: &Shape) -> bool {
    let (Shape::Sphere { center: c1, radius: r1 }, Shape::Sphere { center: c2, radius: r2 }) = (a, b) else {
        return false;
    };
    let (c1, c2, r1, r2) = (c1.as_dvec3(), c2.as_dvec3(), *r1 as f64, *r2 as f64);
    let d = (c2 - c1).length();
    let far = (c1.abs().max_element() + r1).max(c2.abs().max_element() + r2);
    let tol = 256.0 * far * f32::EPSILON as f64;
    (d - (r1 + r2)).abs() <= tol || ((r1 - r2).abs() - d).abs() <= tol
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Point lights get buffers in order while their entries fit the budget; area lights and scenes
    /// with CSG solids get none.
    #[test]
    fn light_buffers_fit_their_budget() {
        let light = |y: f32| Light::Point { position: Vec3::new(0.0, y, 0.0), intensity: Vec3::ONE };
        let quad = Light::Quad { quad: Quad::new(Vec3::new(-1.0, 5.0, -1.0), Vec3::X, Vec3::Z), radiance: Vec3::ONE };
        let prims: Vec<Prim> = (0..50)
            .map(|i| Prim {
                shape: Shape::Sphere { center: Vec3::new(i as f32 * 0.7 - 17.0, 0.5, (i % 7) as f32 - 3.0), radius: 0.3 },
                material: 0,
                motion: Vec3::ZERO,
                is_light: false,
            })
            .collect();
        let bounds: Vec<Aabb> = prims.iter().map(|p| prim_bounds(&p.shape, &Csg::new()).unwrap()).collect();
        let bounded: Vec<u32> = (0..50).collect();
        let lights = [light(8.0), quad, light(12.0), light(9.0)];
        let all = light_buffers_within(&lights, &prims, &bounds, &bounded, usize::MAX);
        assert!(all[0].is_some() && all[1].is_none() && all[2].is_some() && all[3].is_some());
        let first = all[0].as_ref().unwrap().entry_count();
        assert!(first > 0);
        // Room for the first buffer only: the others are traced through the BVH.
        let some = light_buffers_within(&lights, &prims, &bounds, &bounded, first);
        assert!(some[0].is_some() && some[2].is_none() && some[3].is_none());
        // At most MAX_LIGHT_BUFFERS point lights get one (the first declared).
        let many: Vec<Light> = (0..MAX_LIGHT_BUFFERS + 5).map(|i| light(8.0 + i as f32 * 0.1)).collect();
        let built = light_buffers_within(&many, &prims, &bounds, &bounded, usize::MAX);
        assert!(built[..MAX_LIGHT_BUFFERS].iter().all(Option::is_some) && built[MAX_LIGHT_BUFFERS..].iter().all(Option::is_none));
    }

    /// A light above a lattice of long thin beams (boxes 40 long, 0.04 thick): every beam's bounding
    /// sphere is 20 wide, so its cone covers much of the light's sky and the cells list hundreds of
    /// beams each. No buffer is built (the BVH answers: 13.5 s -> 0.07 s in a user trial's render);
    /// the same number of small boxes keeps one.
    #[test]
    fn beams_that_fill_the_lights_sky_get_no_buffer() {
        let light = [Light::Point { position: Vec3::new(10.0, 40.0, 10.0), intensity: Vec3::ONE }];
        let boxes = |long: f32| -> Vec<Prim> {
            (0..400)
                .map(|i| {
                    let (a, y) = ((i % 20) as f32 * 2.0 - 20.0, 0.5 + 0.05 * (i % 7) as f32);
                    let (lo, hi) = if i % 2 == 0 {
                        (Vec3::new(-long, y, a - 0.02), Vec3::new(long, y + 0.04, a + 0.02))
                    } else {
                        (Vec3::new(a - 0.02, y + 0.5, -long), Vec3::new(a + 0.02, y + 0.54, long))
                    };
                    let b = OBox::new(Affine3A::from_translation((lo + hi) * 0.5), (hi - lo) * 0.5);
                    Prim { shape: Shape::Box(b), material: 0, motion: Vec3::ZERO, is_light: false }
                })
                .collect()
        };
        for (long, kept) in [(20.0, false), (0.02, true)] {
            let prims = boxes(long);
            let bounds: Vec<Aabb> = prims.iter().map(|p| prim_bounds(&p.shape, &Csg::new()).unwrap()).collect();
            let bounded: Vec<u32> = (0..prims.len() as u32).collect();
            let lb = light_buffers_within(&light, &prims, &bounds, &bounded, usize::MAX);
            assert_eq!(lb[0].is_some(), kept, "half length {long}");
        }
    }
}
