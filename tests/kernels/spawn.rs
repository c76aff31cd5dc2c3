//! Spawn offsets (no self-intersection at any scale) and surface normals.

use super::*;

// Spawn offsets

const SCALES: [f32; 5] = [1e-4, 1e-2, 1.0, 1e2, 1e5];

/// A centre 1e4..3e4 radii from the origin, at most ~1e5 (a sphere smaller than the f32 grid at
/// its position is not a surface any more).
fn far_center(rng: &mut R, s: f32) -> Vec3 {
    rng.unit() * (1e4 * s).min(1e5).max(s) * rng.f(1.0, 3.0)
}

/// Outward direction with d.n > 0 (a fifth of them grazing, d.n in 1e-6..1e-3).
fn outward(rng: &mut R, n: Vec3) -> Vec3 {
    if rng.chance(0.2) {
        let t = rng.unit();
        let t = (t - n * t.dot(n)).normalize();
        (t + n * rng.log_range(1e-6, 1e-3) as f32).normalize()
    } else {
        let d = rng.unit();
        if d.dot(n) < 0.0 {
            -d
        } else {
            d
        }
    }
}

fn check_offset(p: Vec3, q: Vec3) {
    let moved = (q - p).length();
    assert!(moved > 0.0 && moved <= 3.1e-5 * p.length(), "offset {moved} for |p| {}", p.length());
}

#[test]
fn offset_sphere_no_self_intersection() {
    let mut rng = R::new(16);
    let (mut rays, mut self_hits, mut inward_short) = (0, 0, 0);
    for &s in &SCALES {
        for far in [false, true] {
            let c = if far { far_center(&mut rng, s) } else { rng.cube(0.5 * s) };
            for _ in 0..10_000 / LANES {
                // Half the points are generated on the sphere, half come from kernel hits from
                // 50 radii away, refined onto the sphere.
                let cases: [Case; LANES] = std::array::from_fn(|i| {
                    let mut p = c + rng.unit() * s;
                    if i % 2 == 1 {
                        let o = c + rng.unit() * 50.0 * s;
                        let d = c + rng.ball(0.9 * s) - o;
                        let t = first(intersect_sphere_x8(c, s, &one(o, d, f32::INFINITY)));
                        p = refine_sphere_point(c, s, d.mul_add(Vec3::splat(t), o));
                    }
                    let n = normal_sphere(c, p);
                    let q = offset_ray_origin(p, n);
                    check_offset(p, q);
                    Case { o: q, d: outward(&mut rng, n), tmax: f32::INFINITY }
                });
                let t = intersect_sphere_x8(c, s, &pack(&cases)).to_array();
                rays += LANES;
                self_hits += t.iter().filter(|t| **t != MISS).count();
                // Inward (refraction): offset to the inside, at least 0.2 off the surface plane;
                // the hit must be the far side (chord >= 0.4 r), never a self-hit near 0.
                let inward: [Case; LANES] = std::array::from_fn(|i| {
                    let n = normal_sphere(c, cases[i].o);
                    let p = c + n * s;
                    let mut d = outward(&mut rng, n);
                    if d.dot(n) < 0.2 {
                        d = (d + n * 0.5).normalize();
                    }
                    Case { o: offset_ray_origin(p, -n), d: -d, tmax: f32::INFINITY }
                });
                for t in intersect_sphere_x8(c, s, &pack(&inward)).to_array() {
                    inward_short += (t.is_nan() || t < 0.3 * s) as usize;
                }
            }
        }
    }
    eprintln!("offset sphere: {rays} outward rays, {self_hits} self-intersections, {inward_short} short inward");
    assert!(rays >= 100_000);
    assert_eq!(self_hits, 0);
    assert_eq!(inward_short, 0);
}

#[test]
fn offset_box_no_self_intersection() {
    let mut rng = R::new(17);
    let (mut rays, mut self_hits) = (0, 0);
    for &s in &SCALES {
        for far in [false, true] {
            for _ in 0..10_000 / LANES {
                let t = if far { far_center(&mut rng, s) } else { rng.cube(0.5 * s) };
                let o2w = Affine3A::from_mat3_translation(rng.linear(0.3, 3.0) * s, t);
                let b = OBox::new(o2w, Vec3::new(rng.f(0.2, 2.0), rng.f(0.2, 2.0), rng.f(0.2, 2.0)));
                let cases: [Case; LANES] = std::array::from_fn(|_| {
                    let axis = (rng.u() * 3.0) as usize;
                    let mut p = rng.cube(1.0) * b.half;
                    p[axis] = if rng.chance(0.5) { b.half[axis] } else { -b.half[axis] };
                    let p = o2w.transform_point3(p);
                    let n = normal_obox(&b, p);
                    let q = offset_ray_origin(p, n);
                    check_offset(p, q);
                    Case { o: q, d: outward(&mut rng, n), tmax: f32::INFINITY }
                });
                let t = intersect_obox_x8(&b, &pack(&cases)).to_array();
                rays += LANES;
                self_hits += t.iter().filter(|t| **t != MISS).count();
            }
        }
    }
    eprintln!("offset box: {rays} outward rays, {self_hits} self-intersections");
    assert!(rays >= 100_000);
    assert_eq!(self_hits, 0);
}

#[test]
fn offset_is_needed() {
    // Without the offset, rounded points on a sphere re-hit it: the test above is not vacuous.
    let mut rng = R::new(18);
    let mut self_hits = 0;
    for _ in 0..10_000 {
        let (c, s) = (rng.cube(10.0), rng.log_range(0.1, 10.0) as f32);
        let p = c + rng.unit() * s;
        let d = outward(&mut rng, normal_sphere(c, p));
        self_hits += (first(intersect_sphere_x8(c, s, &one(p, d, f32::INFINITY))) != MISS) as usize;
    }
    eprintln!("no offset: {self_hits} of 10000 outward rays self-intersect");
    assert!(self_hits > 100);
}

// ---------------------------------------------------------------------------------------------
// Normals

fn grad(f: impl Fn(DVec3) -> f64, p: DVec3, h: f64) -> DVec3 {
    let e = |i: usize| DVec3::from_array(std::array::from_fn(|j| if i == j { h } else { 0.0 }));
    DVec3::new(f(p + e(0)) - f(p - e(0)), f(p + e(1)) - f(p - e(1)), f(p + e(2)) - f(p - e(2))) / (2.0 * h)
}

#[test]
fn normals_unit_outward_and_gradient() {
    let mut rng = R::new(19);
    for _ in 0..2000 {
        // Ellipsoid: gradient of |M (p - c)|^2.
        let o2w = Affine3A::from_mat3_translation(rng.linear(0.2, 5.0), rng.cube(10.0));
        let e = Ellipsoid::new(o2w);
        let p = o2w.transform_point3(rng.unit());
        let n = normal_ellipsoid(&e, p);
        let w = e.world_to_object_f64();
        let g = grad(|x| w.transform_point3(x).length_squared(), dv(p), 1e-5).normalize();
        assert!((n.length() - 1.0).abs() < 1e-5 && n.dot(p - e.center) > 0.0);
        assert!((dv(n) - g).length() < 1e-3, "ellipsoid {n} vs {g}");

        // Box: gradient of max_i |p'_i| / h_i on a face (away from edges).
        let b = OBox::new(o2w, Vec3::new(rng.f(0.2, 2.0), rng.f(0.2, 2.0), rng.f(0.2, 2.0)));
        let axis = (rng.u() * 3.0) as usize;
        let mut q = rng.cube(0.9) * b.half;
        q[axis] = if rng.chance(0.5) { b.half[axis] } else { -b.half[axis] };
        let p = o2w.transform_point3(q);
        let n = normal_obox(&b, p);
        let wb = b.world_to_object_f64();
        let h = dv(b.half);
        let g = grad(|x| (wb.transform_point3(x) / h).abs().max_element(), dv(p), 1e-6 * h.min_element()).normalize();
        assert!((n.length() - 1.0).abs() < 1e-5 && n.dot(p - b.center) > 0.0);
        assert!((dv(n) - g).length() < 1e-3, "box {n} vs {g}");

        // Sphere.
        let (c, r) = (rng.cube(10.0), rng.f(0.1, 5.0));
        let u = rng.unit();
        let n = normal_sphere(c, c + u * r);
        assert!((n.length() - 1.0).abs() < 1e-6 && (n - u).length() < 1e-5);
        let pr = refine_sphere_point(c, r, c + u * r * 1.01);
        assert!(((pr - c).length() - r).abs() < 1e-5 * (r + c.length()));

        // Quad: unit normal orthogonal to u, v; area; dual basis.
        let (u, v) = (rng.unit() * rng.f(0.2, 3.0), rng.unit() * rng.f(0.2, 3.0));
        if u.normalize().dot(v.normalize()).abs() < 0.95 {
            let q = Quad::new(rng.cube(5.0), u, v);
            let n = q.normal();
            assert!((n.length() - 1.0).abs() < 1e-6 && n.dot(u).abs() < 1e-5 * u.length() && n.dot(v).abs() < 1e-5 * v.length());
            assert!(n.dot(u.cross(v)) > 0.0 && close(q.area() as f64, u.cross(v).length() as f64, 1e-6));
            for (x, y, want) in [(q.dual_u, u, 1.0), (q.dual_u, v, 0.0), (q.dual_v, v, 1.0), (q.dual_v, u, 0.0)] {
                assert!((x.dot(y) - want).abs() < 1e-5);
            }
        }
    }
}
