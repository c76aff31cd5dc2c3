//! Strata: a data-oriented SIMD wavefront ray tracer for the CPU.
//!
//! ```text
//! scene.toml + profile.toml
//!       | scene::load_scene   parse + validate (errors carry file:line:col and the field)
//!       v
//!   Scene (compiled, flat)    prims, CSG programs, materials, lights, camera, BVH, Features
//!       v
//!   for each work unit (tile x sample batch; one reusable Wavefront per worker):
//!      generate        camera rays: pixel filter, lens, time, wavelength samples
//!      loop until no rays or max depth:
//!         intersect    BVH packet traversal + 8-lane primitive kernels  -> HitQueue
//!         csg_merge    rays at CSG solids: Roth interval merge           -> HitQueue
//!         shade        per material kind: NEE requests, next-bounce rays
//!         shadow       light samples, any-hit packets, direct light
//!      accumulate      film: exact fixed-point sums per pixel
//!       v
//!   film -> PNG / EXR + summary (rays per kind, rays/s, time per stage)
//! ```

// `!(x > 0.0)` is deliberate throughout: it is also true for NaN, which must take the rejecting branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

// The kernels need a fused multiply-add: `wide`'s `mul_add` without the FMA target feature is a product
// and a sum, two roundings, where the sphere kernel takes an exact product's error term from it and the
// lanes must equal the scalar code's `f32::mul_add` bit for bit (a baseline `x86-64` build, session 50:
// 21 of 512 tests failed, acne on a sphere of radius 1e4, hits reported as misses).
// (Not where rustdoc reads the crate: `cargo test`'s doctests and `cargo doc` run rustdoc, which takes
// `rustdocflags`, not the build's `rustflags`.)
#[cfg(all(target_arch = "x86_64", not(target_feature = "fma"), not(doc), not(doctest)))]
compile_error!(
    "Strata needs FMA (fused multiply-add): build with `-C target-cpu=native` (the default, .cargo/config.toml) on a CPU \
     that has it, or `RUSTFLAGS=\"-C target-cpu=x86-64-v3\"` for a portable binary"
);

/// `println!` that ignores write errors: a closed stdout (`strata render ... | head -3`) must not end
/// a command with a panic (Rust ignores SIGPIPE, so the write fails instead of killing the process).
macro_rules! outln {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($t)*);
    }};
}

/// `eprintln!` that ignores write errors (`strata render ... 2>&1 | head -3`), like [`outln`].
macro_rules! errln {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($t)*);
    }};
}

pub mod accel;
pub mod camera;
pub mod cli;
pub mod csg;
pub mod film;
pub mod geometry;
pub mod light;
pub mod optics;
pub mod render;
pub mod sample;
pub mod scene;
pub mod simd;
pub mod study;
pub mod wavefront;
