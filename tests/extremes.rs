//! The extremes matrix (issue 7): every case renders a small image with fixed seeds, asserts its
//! expectation against a reference no one can tune (the same scene at unit scale, an analytic mask,
//! an energy bound) and zero non-finite samples (checked for every render in `support::render_scene`).

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
