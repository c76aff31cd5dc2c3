//! Infinite two-sided planes `normal . p = offset`.

use super::{finish_t_x8, valid_f64};
use crate::simd::{f32x8, Lanes, Ray8};
use glam::{DVec3, Vec3};

/// The plane of points `p` with `normal . p = offset`. `normal` need not be unit length (the
/// kernel divides it out).
#[derive(Clone, Copy, Debug)]
pub struct Plane {
    pub normal: Vec3,
    pub offset: f32,
}

/// Ray/plane: `t = (offset - n.o) / (n.d)`, one division (textbook; Haines, "Essential Ray
/// Tracing Algorithms", in Glassner (ed.), An Introduction to Ray Tracing, 1989, ch. 2).
/// The numerator is one FMA chain starting from `offset`, so an origin close to the plane keeps
/// the relative accuracy of its distance. A parallel ray (`n.d = 0`) gives `t = +-inf` or NaN
/// (origin in the plane: 0/0) and misses; an origin in the plane gives `t = 0` and misses.
#[inline]
pub fn intersect_plane_x8(p: &Plane, ray: &Ray8) -> f32x8 {
    finish_t_x8(plane_t([ray.o.x, ray.o.y, ray.o.z], [ray.d.x, ray.d.y, ray.d.z], p), ray)
}

/// Any-hit twin of [`intersect_plane_x8`] at any lane width (rays by axis; `finite` the rays'
/// [`ray_finite`](super::ray_finite) mask): the lanes where `intersect_plane_x8(..) < tmax`, from
/// the same [`plane_t`] (`MISS` is +inf, which no `tmax` of a shadow ray exceeds).
#[inline(always)]
pub fn occludes_plane<F: Lanes>(o: [F; 3], d: [F; 3], tmax: F, p: &Plane, finite: F) -> F {
    let t = plane_t(o, d, p);
    finite & t.gt(F::splat(0.0)) & t.lt(tmax)
}

/// The distance `(offset - n.o) / (n.d)` of both plane kernels, at any lane width.
#[inline(always)]
fn plane_t<F: Lanes>(o: [F; 3], d: [F; 3], p: &Plane) -> F {
    let (nx, ny, nz) = (F::splat(p.normal.x), F::splat(p.normal.y), F::splat(p.normal.z));
    let num = nx.mul_neg_add(o[0], ny.mul_neg_add(o[1], nz.mul_neg_add(o[2], F::splat(p.offset))));
    let den = d[0].mul_add(nx, d[1].mul_add(ny, d[2] * nz));
    num / den
}

/// f64 twin of [`intersect_plane_x8`] (textbook form, branches on the parallel case).
pub fn intersect_plane_f64(normal: DVec3, offset: f64, o: DVec3, d: DVec3, tmax: f64) -> f64 {
    if !valid_f64(o, d, tmax) {
        return f64::INFINITY;
    }
    let den = normal.dot(d);
    if den == 0.0 {
        return f64::INFINITY;
    }
    let t = (offset - normal.dot(o)) / den;
    if t > 0.0 && t < tmax {
        t
    } else {
        f64::INFINITY
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::ray_finite;
    use crate::simd::Vec3x8;

    /// The any-hit kernel's lanes are exactly `intersect_plane_x8(..) < tmax`, and agree with the f64
    /// twin away from rounding ties, on seeded rays at scales 1e-4 to 1e4, parallel rays, origins in
    /// the plane and inactive lanes; and a segment crossing `y = 0` at half its length is occluded
    /// with `tmax = 1` and not with `tmax = 0.4`.
    #[test]
    fn occludes_plane_is_the_closest_hit_kernel_below_tmax() {
        let mut f = crate::sample::hash::test_uniforms(0x91a4e);
        let (mut occluded, mut clear) = (0, 0);
        for round in 0..4000 {
            let scale = [1e-4f32, 1.0, 1e4][round % 3];
            let n = Vec3::new(f() - 0.5, f() - 0.5, f() - 0.5);
            let p = Plane { normal: n, offset: (f() - 0.5) * scale };
            let lane = |f: &mut dyn FnMut() -> f32| f32x8::from(std::array::from_fn(|_| (f() - 0.5) * 2.0 * scale));
            let o = Vec3x8::new(lane(&mut f), lane(&mut f), lane(&mut f));
            let mut d = Vec3x8::new(lane(&mut f), lane(&mut f), lane(&mut f));
            if round % 7 == 0 {
                // Parallel to the plane in lane 0: d . n = 0 exactly along a perpendicular of n.
                let t = n.any_orthonormal_vector();
                let mut dx = d.x.to_array();
                let (mut dy, mut dz) = (d.y.to_array(), d.z.to_array());
                (dx[0], dy[0], dz[0]) = (t.x, t.y, t.z);
                d = Vec3x8::new(f32x8::from(dx), f32x8::from(dy), f32x8::from(dz));
            }
            let tmax = f32x8::from(std::array::from_fn(|l| if l == 7 { -1.0 } else { f() * 2.0 }));
            let ray = Ray8::new(o, d, tmax);
            let (oa, da) = ([o.x, o.y, o.z], [d.x, d.y, d.z]);
            let any = occludes_plane(oa, da, tmax, &p, ray_finite(oa, da)).to_bitmask();
            let closest = intersect_plane_x8(&p, &ray).simd_lt(tmax).to_bitmask();
            assert_eq!(any, closest, "round {round}");
            let (ox, oy, oz, dx, dy, dz, tm) =
                (o.x.to_array(), o.y.to_array(), o.z.to_array(), d.x.to_array(), d.y.to_array(), d.z.to_array(), tmax.to_array());
            for l in 0..8 {
                let (od, dd) = (DVec3::new(ox[l] as f64, oy[l] as f64, oz[l] as f64), DVec3::new(dx[l] as f64, dy[l] as f64, dz[l] as f64));
                let t = intersect_plane_f64(n.as_dvec3(), p.offset as f64, od, dd, tm[l] as f64);
                // Away from the ends of the segment the f64 verdict is the f32 one.
                let margin = 1e-3 * tm[l].abs() as f64;
                if t.is_finite() && t > margin && t < tm[l] as f64 - margin {
                    assert!(any & (1 << l) != 0, "round {round} lane {l}: f64 t = {t}");
                    occluded += 1;
                } else if t.is_infinite() && tm[l] > 0.0 {
                    // f64 misses the segment; f32 may only disagree at its ends.
                    let tf = (p.offset as f64 - n.as_dvec3().dot(od)) / n.as_dvec3().dot(dd);
                    if !(tf.abs() < margin || (tf - tm[l] as f64).abs() < margin) {
                        assert!(any & (1 << l) == 0, "round {round} lane {l}");
                        clear += 1;
                    }
                }
            }
            assert_eq!(any >> 7, 0, "an inactive lane (tmax = -1) is never occluded");
        }
        assert!(occluded > 2000 && clear > 2000, "both verdicts exercised: {occluded} occluded, {clear} clear");
        // A known case: from (0, 1, 0) to (0, -1, 0) the plane y = 0 is met at t = 0.5.
        let p = Plane { normal: Vec3::Y, offset: 0.0 };
        let s = f32x8::splat;
        let (o, d) = ([s(0.0), s(1.0), s(0.0)], [s(0.0), s(-2.0), s(0.0)]);
        let fin = ray_finite(o, d);
        assert_eq!(occludes_plane(o, d, s(1.0), &p, fin).to_bitmask(), 0xff);
        assert_eq!(occludes_plane(o, d, s(0.4), &p, fin).to_bitmask(), 0);
    }
}
