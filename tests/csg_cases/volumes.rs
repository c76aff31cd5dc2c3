//! Volumes by integrating the interval lengths (`intervals_f64`) of stratified parallel rays, against
//! closed forms.

use super::*;
use glam::{Affine3A, DVec3, Quat, Vec3};
use std::f64::consts::PI;
use strata::csg::*;

// ---------------------------------------------------------------------------------------------------------
// Volumes by integrating interval lengths of parallel rays (intervals_f64)
// ---------------------------------------------------------------------------------------------------------

/// Volume of a solid: `n × n` stratified jittered parallel rays along `dir` over the projection of its
/// bounds; each ray contributes its total inside length times the cell area (intervals by `intervals_f64`).
fn ray_volume(csg: &Csg, solid: u32, dir: DVec3, n: usize, seed: u64) -> f64 {
    let mut iv = Vec::new();
    ray_volume_by(csg, solid, dir, n, seed, |o, d| {
        intervals_f64(csg, solid, o, d, &mut iv);
        measure(&iv)
    })
}

/// The same integral with each ray's inside length from `length(o, d)`.
fn ray_volume_by(csg: &Csg, solid: u32, dir: DVec3, n: usize, seed: u64, mut length: impl FnMut(DVec3, DVec3) -> f64) -> f64 {
    let (lo, hi) = csg.bounds(solid);
    let (lo, hi) = (lo.as_dvec3(), hi.as_dvec3());
    let w = dir.normalize();
    let u = w.any_orthonormal_vector();
    let v = w.cross(u);
    let (mut umin, mut umax, mut vmin, mut vmax, mut wmin) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN, f64::MAX);
    for i in 0..8 {
        let c =
            DVec3::new(if i & 1 == 0 { lo.x } else { hi.x }, if i & 2 == 0 { lo.y } else { hi.y }, if i & 4 == 0 { lo.z } else { hi.z });
        (umin, umax) = (umin.min(c.dot(u)), umax.max(c.dot(u)));
        (vmin, vmax) = (vmin.min(c.dot(v)), vmax.max(c.dot(v)));
        wmin = wmin.min(c.dot(w));
    }
    let (du, dv) = ((umax - umin) / n as f64, (vmax - vmin) / n as f64);
    let mut r = R::new(seed);
    let mut sum = 0.0;
    for i in 0..n {
        for j in 0..n {
            let a = umin + (i as f64 + r.f()) * du;
            let b = vmin + (j as f64 + r.f()) * dv;
            sum += length(u * a + v * b + w * (wmin - 1.0), w);
        }
    }
    sum * du * dv
}

/// The same volume through the renderer's path: intervals walked with `first_hit` (f32, 8-lane
/// kernels, the merge, and for solids of many leaves the culled programs of `csg::cull`), each ray's
/// list also held to the f64 reference's within `2e-3` in length.
fn ray_volume_fast(csg: &Csg, solid: u32, dir: DVec3, n: usize, seed: u64) -> f64 {
    let (mut arena, mut iv) = (CsgArena::new(), Vec::new());
    ray_volume_by(csg, solid, dir, n, seed, |o, w| {
        let (o32, w32) = (o.as_vec3(), w.as_vec3());
        let fast = fast_intervals(csg, solid, o32, w32, &mut arena).expect("unpaired boundaries");
        intervals_f64(csg, solid, o32.as_dvec3(), w32.as_dvec3(), &mut iv);
        assert!(sym_diff(&fast, &iv) <= 2e-3, "o={o32} d={w32}: fast {fast:?} vs reference {iv:?}");
        measure(&fast)
    })
}

/// A plate with a 16 x 16 grid of through holes whose caps are flush with its faces (257 leaves: the
/// solid has a cull program), placed by a rotation: by the renderer's path and by the f64 reference,
/// against the closed form.
#[test]
fn volume_plate_with_many_holes() {
    let g = placement();
    let (k, r, half) = (16usize, 0.075f64, 0.1f64);
    let plate = leaf(Shape::Box, g * Affine3A::from_scale(Vec3::new(2.0, half as f32, 2.0)));
    let s = 4.0 / k as f32;
    let holes = (0..k * k).map(|i| {
        let c = Vec3::new(-2.0 + s * ((i % k) as f32 + 0.5), 0.0, -2.0 + s * ((i / k) as f32 + 0.5));
        leaf(Shape::Cylinder, g * Affine3A::from_scale_rotation_translation(Vec3::new(r as f32, half as f32, r as f32), Quat::IDENTITY, c))
    });
    let tree = node(Op::Difference, std::iter::once(plate).chain(holes).collect());
    let want = 16.0 * 2.0 * half - (k * k) as f64 * PI * r * r * 2.0 * half;
    let mut csg = Csg::new();
    let id = csg.add_solid(&tree).unwrap();
    let fast = ray_volume_fast(&csg, id, DVec3::new(0.31, -0.52, 0.79), 320, 9);
    let rel = (fast - want).abs() / want;
    println!("volume plate (fast): {fast:.6} vs {want:.6} (rel {rel:.2e})");
    assert!(rel < 5e-3, "plate with holes, renderer's path: {fast} vs {want} (rel {rel})");
    check_volume("plate with holes", tree, want, 10);
}

fn check_volume(name: &str, tree: CsgTree, want: f64, seed: u64) {
    let mut csg = Csg::new();
    let s = csg.add_solid(&tree).unwrap();
    let got = ray_volume(&csg, s, DVec3::new(0.31, -0.52, 0.79), 448, seed);
    let rel = (got - want).abs() / want;
    println!("volume {name}: {got:.6} vs {want:.6} (rel {rel:.2e})");
    assert!(rel < 5e-3, "volume {name}: {got} vs {want} (rel {rel})");
}

#[test]
fn volume_sphere_sphere_lens() {
    let (r1, r2, d) = (1.0f64, 0.8f64, 1.2f64);
    let g = placement();
    let a = leaf(Shape::Sphere, g);
    let b = leaf(Shape::Sphere, g * Affine3A::from_scale_rotation_translation(Vec3::splat(0.8), Quat::IDENTITY, Vec3::new(1.2, 0.0, 0.0)));
    let want =
        PI * (r1 + r2 - d).powi(2) * (d * d + 2.0 * d * r2 - 3.0 * r2 * r2 + 2.0 * d * r1 + 6.0 * r1 * r2 - 3.0 * r1 * r1) / (12.0 * d);
    check_volume("lens", node(Op::Intersection, vec![a, b]), want, 1);
}

#[test]
fn volume_box_minus_cylinder() {
    let g = placement();
    let bx = leaf(Shape::Box, g * Affine3A::from_scale(Vec3::new(1.0, 0.8, 0.6)));
    let cyl = leaf(Shape::Cylinder, g * Affine3A::from_scale(Vec3::new(0.5, 0.5, 2.0)));
    let want = 8.0 * 0.8 * 0.6 - PI * 0.25 * 1.2;
    check_volume("box - cylinder", node(Op::Difference, vec![bx, cyl]), want, 2);
}

#[test]
fn volume_cube_intersect_sphere() {
    // Radius 1.3 < sqrt 2: the sphere minus six disjoint caps of height 0.3.
    let g = placement();
    let (rho, h) = (1.3f64, 0.3f64);
    let want = 4.0 / 3.0 * PI * rho.powi(3) - 6.0 * PI * h * h * (3.0 * rho - h) / 3.0;
    let sphere = leaf(Shape::Sphere, g * Affine3A::from_scale(Vec3::splat(1.3)));
    check_volume("cube ∩ sphere(1.3)", node(Op::Intersection, vec![leaf(Shape::Box, g), sphere]), want, 3);
    // Radius 1.6 (sqrt 2 < 1.6 < sqrt 3): only the corners are rounded. Reference: the z-extent over
    // (x, y) is 2 min(1, sqrt(rho² - x² - y²)); its y-integral is closed form, the x-integral is composite
    // Simpson split at the kinks x = ±sqrt(rho² - 2).
    let rho = 1.6f64;
    let inner = |x: f64| {
        let s2 = rho * rho - x * x;
        let y1 = (s2 - 1.0).sqrt();
        if y1 >= 1.0 {
            return 4.0;
        }
        let s = s2.sqrt();
        let f = |y: f64| 0.5 * (y * (s2 - y * y).sqrt() + s2 * (y / s).asin());
        4.0 * y1 + 4.0 * (f(1.0) - f(y1))
    };
    let simpson = |a: f64, b: f64| {
        let n = 20_000;
        let h = (b - a) / n as f64;
        let mut acc = inner(a) + inner(b);
        for i in 1..n {
            acc += inner(a + h * i as f64) * if i % 2 == 1 { 4.0 } else { 2.0 };
        }
        acc * h / 3.0
    };
    let k = (rho * rho - 2.0).sqrt();
    let want = simpson(-1.0, -k) + simpson(-k, k) + simpson(k, 1.0);
    assert!(want < 8.0 && want > 7.0);
    let sphere = leaf(Shape::Sphere, g * Affine3A::from_scale(Vec3::splat(1.6)));
    check_volume("cube ∩ sphere(1.6)", node(Op::Intersection, vec![leaf(Shape::Box, g), sphere]), want, 4);
}

#[test]
fn volume_torus() {
    let g = placement() * Affine3A::from_scale(Vec3::splat(1.3));
    let want = 2.0 * PI * PI * 1.0 * 0.3f64.powi(2) * 1.3f64.powi(3);
    check_volume("torus", leaf(Shape::Torus { major: 1.0, minor: 0.3 }, g), want, 5);
}

#[test]
fn volume_cone_frustum() {
    let g = placement() * Affine3A::from_scale(Vec3::new(1.2, 0.7, 0.9));
    let (r0, r1) = (0.4f64, 1.0f64);
    let want = PI * 2.0 * (r0 * r0 + r0 * r1 + r1 * r1) / 3.0 * 1.2 * 0.7 * 0.9;
    check_volume("cone frustum", leaf(Shape::Cone { r0: 0.4, r1: 1.0 }, g), want, 6);
    let want = PI * 2.0 / 3.0 * 1.2 * 0.7 * 0.9;
    check_volume("cone", leaf(Shape::Cone { r0: 1.0, r1: 0.0 }, g), want, 7);
}

#[test]
fn volume_scaled_sphere() {
    let g = placement() * Affine3A::from_scale(Vec3::new(1.5, 0.7, 0.4));
    check_volume("ellipsoid", leaf(Shape::Sphere, g), 4.0 / 3.0 * PI * 1.5 * 0.7 * 0.4, 8);
}
