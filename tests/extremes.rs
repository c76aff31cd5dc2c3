//! The extremes matrix (issue 7): every case renders a small image with fixed seeds, asserts its
//! expectation against a reference no one can tune (the same scene at unit scale, an analytic mask,
//! an energy bound) and zero non-finite samples (checked for every render in `support::render_scene`).
//! The measured numbers are in the README's section "Numerical robustness". `EXTREMES_DUMP=dir` writes
//! the compared images.
//!
//! - `scale`: scene scale 1e-4 .. 1e5, translation far from the origin
//! - `acne`: ground spheres of radius 1e4 and 1e5, a plane seen from 1e5 away
//! - `tangent`: silhouettes, rays in planes, exact tangency, grazing planes and mirrors
//! - `csg`: coincident and nearly coincident faces, the smallest gap resolved
//! - `optics`: glass of index 1, 1.0001, 4; furnaces; touching media
//! - `lights`: zero, tiny and huge lights
//! - `budget`: 1 and 4096 samples per pixel; max depth 0 and 1000
//! - `distant`: thin walls (a CSG shell, boxes) seen from 1e2 .. 1e4 away

#[path = "extremes/support.rs"]
mod support;

#[path = "extremes/scale.rs"]
mod scale;

#[path = "extremes/acne.rs"]
mod acne;

#[path = "extremes/tangent.rs"]
mod tangent;

#[path = "extremes/csg.rs"]
mod csg;

#[path = "extremes/optics.rs"]
mod optics;

#[path = "extremes/lights.rs"]
mod lights;

#[path = "extremes/budget.rs"]
mod budget;

#[path = "extremes/distant.rs"]
mod distant;
