//! Single rays through glass, traced by the renderer's stages: the centre of a sphere, a ball lens's focal
//! length, and the transmittance of an absorbing slab.

use super::*;
use strata::geometry::OFFSET_ULPS;

const CAMERA: &str = "[image]\nwidth = 8\nheight = 8\n[camera]\nposition = [0, 0, 9]\nlook_at = [0, 0, 0]\nfov = 30\n";

fn ball(center: Vec3, radius: f32, ior: f32) -> Scene {
    scene(&format!(
        "{CAMERA}[materials.glass]\ntype = \"dielectric\"\nior = {ior}\n\
         [[shapes]]\ntype = \"sphere\"\ncenter = [{}, {}, {}]\nradius = {radius}\nmaterial = \"glass\"\n",
        center.x, center.y, center.z
    ))
}

/// Distance from point `c` to the line `o + s d`.
fn line_distance(o: DVec3, d: DVec3, c: DVec3) -> f64 {
    let d = d.normalize();
    let w = c - o;
    (w - d * w.dot(d)).length()
}

#[test]
fn ray_through_the_centre_leaves_undeflected() {
    let c = Vec3::new(0.3, -0.2, 0.1);
    for (radius, ior) in [(1.0f32, 1.5f32), (0.25, 2.4), (3.0, 1.33)] {
        let s = ball(c, radius, ior);
        let dirs = [Vec3::NEG_Z, Vec3::new(1.0, 2.0, -3.0), Vec3::new(-0.3, -1.0, 0.2), Vec3::new(0.0, 0.0, 1.0)];
        let start: Vec<RayItem> = dirs.iter().map(|&d| ray(c - d.normalize() * 5.0, d)).collect();
        let exits = trace_transmitted(&s, &start);
        assert_eq!(exits.len(), start.len());
        for (e, r) in exits.iter().zip(&start) {
            let angle = v64(e.d).normalize().cross(v64(r.d)).length();
            let off = line_distance(v64(e.o), v64(e.d), v64(c));
            eprintln!("centre ray r={radius} n={ior} d={:?}: angle {angle:.1e} rad, line off the centre by {off:.1e}", r.d);
            assert!(e.depth == 2, "two refractions, got {}", e.depth);
            // f32 hit points carry ~eps |p| of error, which tilts the normal by ~eps |p| / r; refraction
            // passes a few times that on. 1e-5 rad is ~80 eps.
            assert!(angle < 1e-5, "deflected by {angle} rad");
            assert!(off < 1e-5 * radius as f64, "exit line misses the centre by {off}");
        }
    }
}

/// f64 reference: where a ray parallel to the axis at height h crosses the axis after a ball lens
/// (distance from the centre), by exact Snell refraction at both surfaces.
fn axis_crossing_f64(radius: f64, n: f64, h: f64) -> f64 {
    let (o, d) = (DVec3::new(h, 0.0, 3.0 * radius), DVec3::NEG_Z);
    let (p, d) = trace_concentric(&[radius], |r, _| if r < radius { n } else { 1.0 }, o, d).unwrap();
    let s = -p.x / d.x;
    -(p.z + s * d.z)
}

/// Paraxial rays through a ball lens of radius R and index n cross the axis at the effective focal length
/// n R / (2 (n - 1)) from the centre. The renderer's exit rays, for heights down to 1% of R, agree with an
/// f64 Snell trace (which includes spherical aberration) to 0.2%, and their h -> 0 limit (a fit
/// f(h) = f0 + a h^2) with the paraxial formula to 0.5%.
#[test]
fn ball_lens_focuses_at_the_effective_focal_length() {
    for (radius, n) in [(1.0f32, 1.5f32), (2.0, 1.8), (0.5, 1.33)] {
        let s = ball(Vec3::ZERO, radius, n);
        let heights: Vec<f32> = [0.01f32, 0.02, 0.03, 0.05, 0.07, 0.1].iter().map(|h| h * radius).collect();
        let start: Vec<RayItem> = heights.iter().map(|&h| ray(Vec3::new(h, 0.0, 3.0 * radius), Vec3::NEG_Z)).collect();
        let exits = trace_transmitted(&s, &start);
        assert_eq!(exits.len(), heights.len());
        let efl = n as f64 * radius as f64 / (2.0 * (n as f64 - 1.0));
        // Least squares of f = f0 + a h^2.
        let (mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0);
        for (e, &h) in exits.iter().zip(&heights) {
            let (o, d) = (v64(e.o), v64(e.d));
            let f = -(o.z + (-o.x / d.x) * d.z);
            let reference = axis_crossing_f64(radius as f64, n as f64, h as f64);
            eprintln!("ball lens R={radius} n={n} h={h}: crosses at {f:.5}, f64 trace {reference:.5}, paraxial {efl:.5}");
            assert!((f / reference - 1.0).abs() < 2e-3, "h = {h}: {f} vs f64 trace {reference}");
            let x = (h as f64).powi(2);
            (sx, sy, sxx, sxy) = (sx + x, sy + f, sxx + x * x, sxy + x * f);
        }
        let m = heights.len() as f64;
        let a = (m * sxy - sx * sy) / (m * sxx - sx * sx);
        let f0 = (sy - a * sx) / m;
        eprintln!(
            "ball lens R={radius} n={n}: fitted paraxial focus {f0:.5}, n R / (2 (n - 1)) = {efl:.5} ({:+.3}%)",
            100.0 * (f0 / efl - 1.0)
        );
        assert!((f0 / efl - 1.0).abs() < 5e-3, "paraxial focus {f0} vs {efl}");
        let f_small = axis_crossing_f64(radius as f64, n as f64, 0.01 * radius as f64);
        assert!((f_small / efl - 1.0).abs() < 5e-3, "reference itself off: {f_small} vs {efl}");
    }
}

/// Exact unpolarised Fresnel reflectance in f64 (textbook form, written independently of src/optics).
fn fresnel64(cos_i: f64, n1: f64, n2: f64) -> f64 {
    let sin_t = n1 / n2 * (1.0 - cos_i * cos_i).sqrt();
    if sin_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin_t * sin_t).sqrt();
    let rs = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t);
    let rp = (n1 * cos_t - n2 * cos_i) / (n1 * cos_t + n2 * cos_i);
    0.5 * (rs * rs + rp * rp)
}

/// A slab of thickness d and absorption sigma: the ray that goes straight through carries
/// T(in) exp(-sigma L) T(out), with L = d / cos(theta_t) and T = 1 - Fresnel.
#[test]
fn slab_transmittance_is_beer_lambert_times_two_fresnel_transmissions() {
    let (n, thick, sigma) = (1.5f64, 0.7f64, DVec3::new(0.3, 1.1, 2.5));
    let s = scene(&format!(
        "{CAMERA}[materials.tinted]\ntype = \"dielectric\"\nior = {n}\nabsorption = [{}, {}, {}]\n\
         [[shapes]]\ntype = \"box\"\nmin = [-5, -5, 0]\nmax = [5, 5, {thick}]\nmaterial = \"tinted\"\n",
        sigma.x, sigma.y, sigma.z
    ));
    let angles_deg = [0.0f64, 20.0, 45.0, 70.0];
    let start: Vec<RayItem> = angles_deg
        .iter()
        .map(|a| {
            let a = a.to_radians();
            ray(Vec3::new(0.1, 0.2, 2.0), Vec3::new(a.sin() as f32, 0.0, -a.cos() as f32))
        })
        .collect();
    let exits = trace_transmitted(&s, &start);
    assert_eq!(exits.len(), start.len());
    for (e, a) in exits.iter().zip(angles_deg) {
        let ci = a.to_radians().cos();
        let st = a.to_radians().sin() / n;
        let ct = (1.0 - st * st).sqrt();
        let t_in = 1.0 - fresnel64(ci, 1.0, n);
        let t_out = 1.0 - fresnel64(ct, n, 1.0);
        let beer = (-sigma * (thick / ct)).exp();
        let expect = beer * t_in * t_out;
        let got = v64(e.throughput);
        let rel = ((got - expect) / expect).abs();
        eprintln!("slab at {a} deg: throughput {got:.6?}, expected {expect:.6?} (rel err {:.1e})", rel.max_element());
        // The spawn offset (OFFSET_ULPS ulps of the largest coordinate of the entry point or of the ray
        // origin it was computed from, along the normal) starts the inside segment past the entry
        // surface: the segment is short by up to that over cos theta_t, which raises exp(-sigma L) by
        // sigma times it (plus f32 rounding elsewhere).
        let i = exits.iter().position(|x| x.path == e.path).unwrap();
        let (o, d) = (v64(start[i].o), v64(start[i].d).normalize());
        let entry = o + d * ((thick - o.z) / d.z);
        let delta = OFFSET_ULPS as f64 * f32::EPSILON as f64 * entry.abs().max_element().max(o.abs().max_element()) / ct;
        let tol = sigma * delta * 1.2 + DVec3::splat(1e-5);
        assert!(rel.cmplt(tol).all(), "{got:?} vs {expect:?} (tolerance {tol:?})");
        // Parallel faces: it leaves parallel to how it came in.
        assert!(v64(e.d).normalize().cross(d).length() < 1e-6, "exit {:?} vs entry {d:?}", e.d);
    }
}
