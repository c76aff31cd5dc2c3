//! Leaf solids: one canonical shape in object space, placed in the world by an affine transform.
//!
//! # Canonical forms (object space)
//!
//! The axis of every shape of revolution is **+z**; all solids are closed sets (`<=`). Object-space bounds:
//! `[-1, 1]^3` for the sphere, box and cylinder, `[-r, r]^2 × [-1, 1]` with `r = max(r0, r1)` for the cone,
//! `[-(major + minor), major + minor]^2 × [-minor, minor]` for the torus.
//!
//! | shape | solid (object space) |
//! | --- | --- |
//! | `Sphere` | `x² + y² + z² <= 1` (unit sphere at the origin) |
//! | `Box` | `|x|, |y|, |z| <= 1` (the cube `[-1, 1]^3`) |
//! | `Cylinder` | `x² + y² <= 1` and `|z| <= 1` (radius 1, caps at `z = ±1`) |
//! | `Cone { r0, r1 }` | `|z| <= 1` and `sqrt(x² + y²) <= r0 + (r1 - r0) (z + 1) / 2`: radius `r0` on the cap `z = -1`, `r1` on the cap `z = +1` (a frustum; one radius may be 0: a cone with its apex on that cap) |
//! | `Torus { major, minor }` | `(sqrt(x² + y²) - major)² + z² <= minor²`: ring in the xy-plane around the z axis, `0 < minor <= major` |
//! | `HalfSpace` | `z <= 0` (outward normal +z; unbounded) |
//!
//! [`Leaf::new`] sanitises the parameters so that no finite input panics: cone radii are made
//! non-negative, the torus gets `major = max(|major|, 1e-6)` and `minor = min(|minor|, major)` (a spindle
//! torus, `minor > major`, is not supported: its quartic has roots on the inner "lemon" surface, which is not
//! a boundary of the solid). Use [`Leaf::half_space`] to place a half-space `n . p <= d` directly.
//!
//! The transform is any invertible affine map (rotation, translation, non-uniform scale, shear). Rays are
//! taken to object space by the inverse transform *without* renormalising the direction, so the ray
//! parameter `t` is the same in both spaces. World normals use the inverse transpose of the linear part.

use crate::simd::{f32x8, Vec3x8};
use glam::{Affine3A, DAffine3, DVec3, Mat3A, Quat, Vec3, Vec3A};

/// A canonical shape (see the module docs for the exact sets).
#[derive(Clone, Copy, Debug)]
pub enum Shape {
    Sphere,
    Box,
    Cylinder,
    Cone { r0: f32, r1: f32 },
    Torus { major: f32, minor: f32 },
    HalfSpace,
}

/// A placed canonical shape. Build it with [`Leaf::new`]: the cached inverse and normal matrix are only
/// filled in there, so change `shape` or `object_to_world` by building a new leaf.
#[derive(Clone, Copy, Debug)]
pub struct Leaf {
    pub shape: Shape,
    pub object_to_world: Affine3A,
    world_to_object: Affine3A,
    /// Inverse transpose of the linear part: takes object-space normals to world space.
    normal_to_world: Mat3A,
    pub material: u32,
}

impl Leaf {
    /// A leaf. `object_to_world` must be invertible (a singular one gives NaN crossings, never a panic).
    pub fn new(shape: Shape, object_to_world: Affine3A, material: u32) -> Leaf {
        let shape = sanitize(shape);
        let world_to_object = object_to_world.inverse();
        Leaf { shape, object_to_world, world_to_object, normal_to_world: world_to_object.matrix3.transpose(), material }
    }

    /// The half-space `n . p <= d` (world space, `n` need not be unit; a zero `n` gives a leaf that never
    /// produces valid crossings).
    pub fn half_space(n: Vec3, d: f32, material: u32) -> Leaf {
        let len = n.length();
        let unit = n / len;
        let rot = Quat::from_rotation_arc(Vec3::Z, unit);
        Leaf::new(Shape::HalfSpace, Affine3A::from_rotation_translation(rot, unit * (d / len)), material)
    }

    /// World-to-object transform (cached inverse).
    #[inline]
    pub fn world_to_object(&self) -> &Affine3A {
        &self.world_to_object
    }

    /// World-to-object transform inverted in f64 from the exact f32 `object_to_world` (for references).
    pub fn world_to_object_f64(&self) -> DAffine3 {
        self.object_to_world.as_daffine3().inverse()
    }

    /// World-space axis-aligned bounds, `None` for the half-space.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let m = self.object_to_world.matrix3;
        let c = Vec3::from(self.object_to_world.translation);
        let half = match self.shape {
            Shape::HalfSpace => return None,
            // Exact bounds of an ellipsoid: the extent along world axis i is the length of row i.
            Shape::Sphere => {
                let r = m.transpose();
                Vec3::new(r.x_axis.length(), r.y_axis.length(), r.z_axis.length())
            }
            _ => {
                let h = object_half_extent(self.shape);
                let a = m.transpose();
                Vec3::new(Vec3::from(a.x_axis.abs()).dot(h), Vec3::from(a.y_axis.abs()).dot(h), Vec3::from(a.z_axis.abs()).dot(h))
            }
        };
        Some((c - half, c + half))
    }

    /// The leaf's thickness in world units, measured in its own frame: the smallest distance between two
    /// parallel planes that enclose it (its width), over the directions that can give it: the world
    /// normals of the canonical shape's axis planes (a box's faces, a cylinder's or cone's caps and the two
    /// directions across its axis) and the direction its transform squeezes most. Exact for boxes (the
    /// distance between opposite faces, however the box is rotated or sheared) and spheres (twice the
    /// ellipsoid's smallest semi-axis); for cylinders, cones and tori the smaller of the cap-to-cap height
    /// and the width across the axis. `None` for a half-space. (The world-axis bounds overstate a rotated
    /// leaf's thickness: a fin 1e-4 thick turned 30 degrees has bounds 0.5 thick.)
    pub fn thickness(&self) -> Option<f64> {
        if matches!(self.shape, Shape::HalfSpace) {
            return None;
        }
        let m = self.object_to_world.as_daffine3().matrix3;
        let inv_t = m.inverse().transpose();
        let shape = self.shape;
        // Width along world direction n: h(M^T n) + h(-M^T n), h the canonical support function.
        let width = |n: DVec3| {
            let n = n.normalize_or_zero();
            let u = m.transpose() * n;
            support(shape, u) + support(shape, -u)
        };
        let mut best = f64::INFINITY;
        for i in 0..3 {
            let mut e = DVec3::ZERO;
            e[i] = 1.0;
            let n = inv_t * e;
            best = best.min(width(n));
            // The direction M squeezes most (smallest singular value): inverse iteration on (M M^T)^-1 =
            // M^-T M^-1, started from each axis plane's normal.
            let mut x = n.normalize_or_zero();
            for _ in 0..24 {
                x = (inv_t * (inv_t.transpose() * x)).normalize_or_zero();
            }
            best = best.min(width(x));
        }
        Some(best).filter(|w| w.is_finite())
    }

    /// Outward unit normal in world space at a world point `p` on (or near) the surface.
    ///
    /// Near an edge of a box, cylinder or cone the face closest to `p` (in object space) wins.
    pub fn normal(&self, p: Vec3) -> Vec3 {
        let q = self.world_to_object.transform_point3(p);
        let n = self.normal_to_world * Vec3A::from(object_normal(self.shape, q));
        Vec3::from(n).normalize_or(Vec3::Z)
    }

    /// [`Leaf::normal`] at 8 world points, rounded as it rounds them (the same operations lane by lane).
    #[inline]
    pub fn normal_x8(&self, p: Vec3x8) -> Vec3x8 {
        let q = affine_x8(&self.world_to_object, p);
        let zero = f32x8::ZERO;
        let on = match self.shape {
            Shape::Sphere => q,
            Shape::Box => {
                let (x, y, z) = box_axis_x8(q);
                Vec3x8::new(signum_x8(q.x) & x, signum_x8(q.y) & y, signum_x8(q.z) & z)
            }
            Shape::Cylinder => {
                let rho = (q.x * q.x + q.y * q.y).sqrt();
                let cap = cylinder_on_cap_x8(q, rho);
                Vec3x8::new(cap.select(zero, q.x / rho), cap.select(zero, q.y / rho), cap.select(signum_x8(q.z), zero))
            }
            Shape::Cone { r0, r1 } => {
                let (m, k) = cone_line(r0, r1);
                let rho = (q.x * q.x + q.y * q.y).sqrt();
                let (_, cap) = cone_side_x8(q, rho, m, k);
                Vec3x8::new(cap.select(zero, q.x / rho), cap.select(zero, q.y / rho), cap.select(signum_x8(q.z), f32x8::splat(-m)))
            }
            Shape::Torus { major, .. } => {
                let rho = (q.x * q.x + q.y * q.y).sqrt();
                let axis = rho.simd_eq(zero);
                let s = f32x8::ONE - f32x8::splat(major) / rho;
                Vec3x8::new(axis.select(zero, q.x * s), axis.select(zero, q.y * s), axis.select(signum_x8(q.z), q.z))
            }
            Shape::HalfSpace => Vec3x8::splat(Vec3::Z),
        };
        mat3_x8(&self.normal_to_world, on).normalize_or(Vec3x8::splat(Vec3::Z))
    }

    /// [`Leaf::refine`] of 8 world points, rounded as it rounds them (the same operations lane by
    /// lane): the points, their error magnitudes, and the lanes where the scalar gives `Some`
    /// (elsewhere both are unspecified).
    #[inline]
    pub fn refine_x8(&self, p: Vec3x8) -> (Vec3x8, f32x8, f32x8) {
        let q = affine_x8(&self.world_to_object, p);
        let (zero, one) = (f32x8::ZERO, f32x8::ONE);
        // `if v < 0 { -1 } else { 1 }`, the projection's side (a -0 goes to +1, unlike `signum`).
        let side = |v: f32x8| v.simd_lt(zero).select(-one, one);
        let all = zero.simd_eq(zero);
        // `normalize_or_zero` (its reciprocal length), and where it is not the zero vector.
        let unit = |v: Vec3x8| {
            let rcp = one / v.dot_unfused(v).sqrt();
            (v.scale(rcp), rcp.is_finite() & rcp.simd_gt(zero))
        };
        let (on, defined) = match self.shape {
            Shape::Sphere => unit(q),
            Shape::Box => {
                let (x, y, z) = box_axis_x8(q);
                (Vec3x8::new(x.select(side(q.x), q.x), y.select(side(q.y), q.y), z.select(side(q.z), q.z)), all)
            }
            Shape::Cylinder => {
                let rho = (q.x * q.x + q.y * q.y).sqrt();
                let cap = cylinder_on_cap_x8(q, rho);
                (Vec3x8::new(cap.select(q.x, q.x / rho), cap.select(q.y, q.y / rho), cap.select(side(q.z), q.z)), all)
            }
            Shape::Cone { r0, r1 } => {
                let (m, k) = cone_line(r0, r1);
                let rho = (q.x * q.x + q.y * q.y).sqrt();
                let len = f32x8::splat(m.mul_add(m, 1.0).sqrt());
                let (s, cap) = cone_side_x8(q, rho, m, k);
                // Along the side's normal (1, -m) / len in the (rho, z) half-plane.
                let (rho2, z2) = (rho - s / len, q.z + s * f32x8::splat(m) / len);
                let f = rho2 / rho;
                (Vec3x8::new(cap.select(q.x, q.x * f), cap.select(q.y, q.y * f), cap.select(side(q.z), z2)), all)
            }
            Shape::Torus { major, minor } => {
                // The nearest point of the tube's centre circle, then the tube's surface along the way to q.
                let rho = (q.x * q.x + q.y * q.y).sqrt();
                let f = f32x8::splat(major) / rho;
                let c = Vec3x8::new(q.x * f, q.y * f, zero);
                let (v, ok) = unit(q - c);
                (c + v.scale(f32x8::splat(minor)), ok & !rho.simd_eq(zero))
            }
            Shape::HalfSpace => (Vec3x8::new(q.x, q.y, zero), all),
        };
        let w = mat3_x8(&self.object_to_world.matrix3, on);
        let t = Vec3x8::splat(Vec3::from(self.object_to_world.translation));
        let out = w + t;
        let finite = out.x.is_finite() & out.y.is_finite() & out.z.is_finite();
        (out, t.max_abs_element().max(w.max_abs_element()), defined & finite)
    }

    /// A world point `p` on (or within rounding of) this leaf's surface, moved onto it in object space
    /// ([`project_object`]) and back, with the magnitude whose ULPs bound the result's error: the
    /// placement's translation and the leaf's extent in world space, not the ray origin's `|o|` that
    /// `p = o + t d` carries (see `geometry::refine`). `None` where the projection is undefined (a
    /// torus point on its axis) or not finite.
    #[inline]
    pub fn refine(&self, p: Vec3) -> Option<(Vec3, f32)> {
        let q = project_object(self.shape, self.world_to_object.transform_point3(p))?;
        let w = Vec3::from(self.object_to_world.matrix3 * Vec3A::from(q));
        let t = Vec3::from(self.object_to_world.translation);
        let out = w + t;
        out.is_finite().then(|| (out, t.abs().max_element().max(w.abs().max_element())))
    }

    /// Point classification (closed set) of a world point.
    pub fn inside(&self, p: Vec3) -> bool {
        inside_object(self.shape, self.world_to_object.transform_point3(p))
    }

    /// The world plane `(n, d)` with the solid `n . p <= d`, for a half-space leaf.
    pub fn plane(&self) -> Option<(Vec3, f32)> {
        match self.shape {
            Shape::HalfSpace => {
                let n = Vec3::from(self.normal_to_world.z_axis);
                Some((n, n.dot(Vec3::from(self.object_to_world.translation))))
            }
            _ => None,
        }
    }
}

fn sanitize(shape: Shape) -> Shape {
    match shape {
        Shape::Cone { r0, r1 } => Shape::Cone { r0: r0.abs(), r1: r1.abs() },
        Shape::Torus { major, minor } => {
            let major = major.abs().max(1e-6);
            Shape::Torus { major, minor: minor.abs().min(major) }
        }
        s => s,
    }
}

/// The canonical shape's support function `max over q in the shape of q . u` (object space).
fn support(shape: Shape, u: DVec3) -> f64 {
    let rho = (u.x * u.x + u.y * u.y).sqrt();
    match shape {
        Shape::Sphere => u.length(),
        Shape::Box => u.x.abs() + u.y.abs() + u.z.abs(),
        Shape::Cylinder => rho + u.z.abs(),
        // The frustum is the hull of its two cap discs: radius r0 at z = -1, r1 at z = +1.
        Shape::Cone { r0, r1 } => (r0 as f64 * rho - u.z).max(r1 as f64 * rho + u.z),
        Shape::Torus { major, minor } => major as f64 * rho + minor as f64 * u.length(),
        Shape::HalfSpace => f64::INFINITY,
    }
}

/// Half extents of the object-space bounding box (centred at the origin).
fn object_half_extent(shape: Shape) -> Vec3 {
    match shape {
        Shape::Sphere | Shape::Box | Shape::Cylinder => Vec3::ONE,
        Shape::Cone { r0, r1 } => {
            let r = r0.max(r1);
            Vec3::new(r, r, 1.0)
        }
        Shape::Torus { major, minor } => Vec3::new(major + minor, major + minor, minor),
        Shape::HalfSpace => Vec3::INFINITY,
    }
}

/// Cone radius as `m z + k` (see the canonical form).
#[inline]
pub(crate) fn cone_line(r0: f32, r1: f32) -> (f32, f32) {
    (0.5 * (r1 - r0), 0.5 * (r0 + r1))
}

/// The axis of the unit box's face nearest `q` (the largest `|q_i|`).
#[inline(always)]
fn box_axis(q: Vec3) -> usize {
    let a = q.abs();
    if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    }
}

/// Whether `q` (`rho` its distance from the axis) is taken to be on the unit cylinder's cap rather than
/// its side: nearer the cap's plane, or on the axis.
#[inline(always)]
fn cylinder_on_cap(q: Vec3, rho: f32) -> bool {
    (1.0 - q.z.abs()).abs() < (rho - 1.0).abs() || rho == 0.0
}

/// [`cylinder_on_cap`] in 8 lanes.
#[inline(always)]
fn cylinder_on_cap_x8(q: Vec3x8, rho: f32x8) -> f32x8 {
    let one = f32x8::ONE;
    (one - q.z.abs()).abs().simd_lt((rho - one).abs()) | rho.simd_eq(f32x8::ZERO)
}

/// [`box_axis`] in 8 lanes, as three lane masks (x, y, z).
#[inline(always)]
fn box_axis_x8(q: Vec3x8) -> (f32x8, f32x8, f32x8) {
    let (ax, ay, az) = (q.x.abs(), q.y.abs(), q.z.abs());
    let x = ax.simd_ge(ay) & ax.simd_ge(az);
    let y = !x & ay.simd_ge(az);
    (x, y, !(x | y))
}

/// `f32::signum` in 8 lanes (NaN stays NaN).
#[inline(always)]
fn signum_x8(v: f32x8) -> f32x8 {
    v.simd_eq(v).select((v & f32x8::splat(-0.0)) | f32x8::ONE, v)
}

/// `Mat3A * Vec3A` in 8 lanes, as glam rounds it: `(x v.x + y v.y) + z v.z`, no FMA.
#[inline(always)]
fn mat3_x8(m: &Mat3A, v: Vec3x8) -> Vec3x8 {
    let col = |c: Vec3A| Vec3x8::splat(Vec3::from(c));
    col(m.x_axis).scale(v.x) + col(m.y_axis).scale(v.y) + col(m.z_axis).scale(v.z)
}

/// `Affine3A::transform_point3` in 8 lanes, as glam rounds it.
#[inline(always)]
fn affine_x8(a: &Affine3A, p: Vec3x8) -> Vec3x8 {
    mat3_x8(&a.matrix3, p) + Vec3x8::splat(Vec3::from(a.translation))
}

/// The signed distance of `q` from the cone's slanted side `rho = m z + k` in the (rho, z) half-plane,
/// and whether `q` is taken to be on a cap instead (nearer the cap's plane, or on the axis).
#[inline(always)]
fn cone_side(q: Vec3, rho: f32, m: f32, k: f32) -> (f32, bool) {
    let s = (rho - m.mul_add(q.z, k)) / m.mul_add(m, 1.0).sqrt();
    (s, (1.0 - q.z.abs()).abs() < s.abs() || rho == 0.0)
}

/// [`cone_side`] in 8 lanes.
#[inline(always)]
fn cone_side_x8(q: Vec3x8, rho: f32x8, m: f32, k: f32) -> (f32x8, f32x8) {
    let s = (rho - f32x8::splat(m).mul_add(q.z, f32x8::splat(k))) / f32x8::splat(m.mul_add(m, 1.0).sqrt());
    (s, (f32x8::ONE - q.z.abs()).abs().simd_lt(s.abs()) | rho.simd_eq(f32x8::ZERO))
}

/// Object-space outward normal (not normalised) at an object-space point `q`.
pub fn object_normal(shape: Shape, q: Vec3) -> Vec3 {
    match shape {
        Shape::Sphere => q,
        Shape::Box => {
            let mut n = Vec3::ZERO;
            let i = box_axis(q);
            n[i] = q[i].signum();
            n
        }
        Shape::Cylinder => {
            let rho = (q.x * q.x + q.y * q.y).sqrt();
            if cylinder_on_cap(q, rho) {
                Vec3::new(0.0, 0.0, q.z.signum())
            } else {
                Vec3::new(q.x / rho, q.y / rho, 0.0)
            }
        }
        Shape::Cone { r0, r1 } => {
            let (m, k) = cone_line(r0, r1);
            let rho = (q.x * q.x + q.y * q.y).sqrt();
            if cone_side(q, rho, m, k).1 {
                Vec3::new(0.0, 0.0, q.z.signum())
            } else {
                // Gradient of rho - (m z + k).
                Vec3::new(q.x / rho, q.y / rho, -m)
            }
        }
        Shape::Torus { major, .. } => {
            let rho = (q.x * q.x + q.y * q.y).sqrt();
            if rho == 0.0 {
                return Vec3::new(0.0, 0.0, q.z.signum());
            }
            let s = 1.0 - major / rho;
            Vec3::new(q.x * s, q.y * s, q.z)
        }
        Shape::HalfSpace => Vec3::Z,
    }
}

/// The object-space point `q` moved onto the canonical surface along its normal, on the part
/// [`object_normal`] picks (a box's face, a cylinder's or cone's cap or side): so a hit point's normal and
/// its projection agree. `None` where no projection is defined (a sphere's centre, a torus point on its
/// axis, a zero-length offset from the tube's circle).
pub fn project_object(shape: Shape, q: Vec3) -> Option<Vec3> {
    let cap = |q: Vec3| Vec3::new(q.x, q.y, if q.z < 0.0 { -1.0 } else { 1.0 });
    match shape {
        Shape::Sphere => Some(q.normalize_or_zero()).filter(|v| *v != Vec3::ZERO),
        Shape::Box => {
            let mut out = q;
            let i = box_axis(q);
            out[i] = if q[i] < 0.0 { -1.0 } else { 1.0 };
            Some(out)
        }
        Shape::Cylinder => {
            let rho = (q.x * q.x + q.y * q.y).sqrt();
            if cylinder_on_cap(q, rho) {
                Some(cap(q))
            } else {
                Some(Vec3::new(q.x / rho, q.y / rho, q.z))
            }
        }
        Shape::Cone { r0, r1 } => {
            let (m, k) = cone_line(r0, r1);
            let rho = (q.x * q.x + q.y * q.y).sqrt();
            let len = m.mul_add(m, 1.0).sqrt();
            let (s, on_cap) = cone_side(q, rho, m, k);
            if on_cap {
                Some(cap(q))
            } else {
                // Along the side's normal (1, -m) / len in the (rho, z) half-plane.
                let (rho2, z2) = (rho - s / len, q.z + s * m / len);
                Some(Vec3::new(q.x * (rho2 / rho), q.y * (rho2 / rho), z2))
            }
        }
        Shape::Torus { major, minor } => {
            let rho = (q.x * q.x + q.y * q.y).sqrt();
            if rho == 0.0 {
                return None;
            }
            let c = Vec3::new(q.x * (major / rho), q.y * (major / rho), 0.0);
            let v = (q - c).normalize_or_zero();
            (v != Vec3::ZERO).then(|| c + v * minor)
        }
        Shape::HalfSpace => Some(Vec3::new(q.x, q.y, 0.0)),
    }
}

/// Point classification in object space (closed sets).
pub fn inside_object(shape: Shape, q: Vec3) -> bool {
    match shape {
        Shape::Sphere => q.length_squared() <= 1.0,
        Shape::Box => q.abs().max_element() <= 1.0,
        Shape::Cylinder => q.x * q.x + q.y * q.y <= 1.0 && q.z.abs() <= 1.0,
        Shape::Cone { r0, r1 } => {
            let (m, k) = cone_line(r0, r1);
            q.z.abs() <= 1.0 && (q.x * q.x + q.y * q.y).sqrt() <= m.mul_add(q.z, k)
        }
        Shape::Torus { major, minor } => {
            let rho = (q.x * q.x + q.y * q.y).sqrt();
            (rho - major) * (rho - major) + q.z * q.z <= minor * minor
        }
        Shape::HalfSpace => q.z <= 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A seeded LCG of floats in `[0, 1)` (24 bits), for the tests' random points and placements.
    fn lcg(mut seed: u64) -> impl FnMut() -> f32 {
        move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((seed >> 40) as f32) / (1u64 << 24) as f32
        }
    }

    /// [`Leaf::thickness`] in the leaf's own frame, under turns the world-axis bounds overstate: a box
    /// 1e-4 thin (turned 30 degrees about y and about a skew axis), an ellipsoid of semi-axes (1, 2e-3, 3),
    /// a cylinder as a disc 1e-3 high and as a needle of radius 2e-3, a cone 5e-4 high, a torus of tube
    /// radius 1e-3; each within 1e-6 relative of its analytic width, and a half-space has none.
    #[test]
    fn thickness_is_measured_in_the_leafs_frame() {
        let turns =
            [Quat::IDENTITY, Quat::from_rotation_y(30f32.to_radians()), Quat::from_axis_angle(Vec3::new(1.0, 2.0, 3.0).normalize(), 0.7)];
        let place = |s: Vec3, q: Quat| Affine3A::from_scale_rotation_translation(s, q, Vec3::new(100.0, -3.0, 7.0));
        for q in turns {
            let cases = [
                (Shape::Box, Vec3::new(5e-5, 0.35, 0.5), 1e-4),
                (Shape::Sphere, Vec3::new(1.0, 2e-3, 3.0), 4e-3),
                (Shape::Cylinder, Vec3::new(0.5, 0.5, 5e-4), 1e-3),
                (Shape::Cylinder, Vec3::new(2e-3, 2e-3, 1.0), 4e-3),
                (Shape::Cone { r0: 1.0, r1: 0.5 }, Vec3::new(0.4, 0.4, 2.5e-4), 5e-4),
                (Shape::Torus { major: 1.0, minor: 1e-3 }, Vec3::splat(0.5), 1e-3),
            ];
            for (shape, s, want) in cases {
                let got = Leaf::new(shape, place(s, q), 0).thickness().unwrap();
                assert!((got / want - 1.0).abs() < 1e-6, "{shape:?} scaled {s} turned {q}: {got} vs {want}");
            }
        }
        assert!(Leaf::half_space(Vec3::Z, 0.0, 0).thickness().is_none());
    }

    /// [`Leaf::normal_x8`] and [`Leaf::refine_x8`] are [`Leaf::normal`] and [`Leaf::refine`] bit for bit
    /// (every leaf shape under rotations, non-uniform scales and translations, at points on, near and off
    /// their surfaces, points within 1e-6 of edges and rims included, points on a torus's axis, and at
    /// non-finite points).
    #[test]
    fn x8_forms_equal_the_scalar_ones() {
        let mut u = lcg(0x0a0e);
        let (mut checked, mut refined) = (0, 0);
        for case in 0..1200 {
            // (Cones narrowing either way, to a point, and tori thin and fat.)
            let cone = Shape::Cone { r0: [0.3, 1.2, 0.0][case % 3], r1: [1.0, 0.4, 0.9][case % 3] };
            let torus = Shape::Torus { major: 1.0, minor: [0.25, 0.6, 1.0][case % 3] };
            let shape = [Shape::Sphere, Shape::Box, Shape::HalfSpace, Shape::Cylinder, cone, torus][case % 6];
            let scale = Vec3::new(0.2 + 3.0 * u(), 0.2 + 3.0 * u(), 0.2 + 3.0 * u());
            let rot = Quat::from_euler(glam::EulerRot::XYZ, 6.0 * u(), 6.0 * u(), 6.0 * u());
            let at = Vec3::new(u(), u(), u()) * 20.0 - 10.0;
            let leaf = Leaf::new(shape, Affine3A::from_scale_rotation_translation(scale, rot, at), 0);
            // Object points on the canonical surface (a box's face or near its edges, a cylinder's side
            // or caps or near their rims), scaled by 0.5..1.5, then placed.
            let q: [Vec3; 8] = std::array::from_fn(|l| {
                let v = Vec3::new(u() * 2.0 - 1.0, u() * 2.0 - 1.0, u() * 2.0 - 1.0);
                let edge = 1.0 - 1e-6 * u();
                let on = match shape {
                    Shape::Box if l % 2 == 0 => v.signum(),
                    Shape::Box => {
                        let mut e = v;
                        e[l % 3] = v[l % 3].signum();
                        e[(l + 1) % 3] = v[(l + 1) % 3].signum() * edge;
                        e
                    }
                    Shape::Cylinder => {
                        let a = u() * std::f32::consts::TAU;
                        match l % 3 {
                            0 => Vec3::new(a.cos(), a.sin(), v.z),
                            1 => Vec3::new(v.x * 0.7, v.y * 0.7, v.z.signum()),
                            _ => Vec3::new(a.cos() * edge, a.sin() * edge, v.z.signum() * edge),
                        }
                    }
                    Shape::Cone { r0, r1 } => {
                        let (a, (m, k)) = (u() * std::f32::consts::TAU, cone_line(r0, r1));
                        let z = match l % 4 {
                            0 | 1 => v.z,
                            2 => v.z.signum() * edge,
                            _ => v.z.signum(),
                        };
                        let rho = m.mul_add(z, k) * if l % 4 == 3 { 0.6 * u() } else { 1.0 };
                        Vec3::new(a.cos() * rho, a.sin() * rho, z)
                    }
                    Shape::Torus { major, minor } => {
                        let (a, b) = (u() * std::f32::consts::TAU, u() * std::f32::consts::TAU);
                        match l % 4 {
                            // On the axis (no projection), and near it.
                            0 => Vec3::new(0.0, 0.0, v.z),
                            1 => Vec3::new(1e-7 * v.x, 1e-7 * v.y, v.z),
                            _ => Vec3::new(a.cos() * (major + minor * b.cos()), a.sin() * (major + minor * b.cos()), minor * b.sin()),
                        }
                    }
                    _ => v.normalize(),
                };
                on * (0.5 + u())
            });
            let mut p: [Vec3; 8] = std::array::from_fn(|l| leaf.object_to_world.transform_point3(q[l]));
            // Every tenth case, non-finite and overflowing points in some lanes.
            if case % 10 == 9 {
                let bad = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 3e38];
                for (l, p) in p.iter_mut().enumerate().take(4) {
                    p[l % 3] = bad[l];
                }
            }
            let rows = Vec3x8::from_rows(&std::array::from_fn(|a| std::array::from_fn(|l| p[l][a])));
            let n = leaf.normal_x8(rows);
            let (r, mag, ok) = leaf.refine_x8(rows);
            let bits = |v: Vec3| v.to_array().map(f32::to_bits);
            for (l, &p) in p.iter().enumerate() {
                assert_eq!(bits(n.lane(l)), bits(leaf.normal(p)), "case {case} lane {l}: normal");
                match leaf.refine(p) {
                    Some((want, m)) => {
                        assert!(ok.to_bitmask() & (1 << l) != 0, "case {case} lane {l}: refinement declined");
                        assert_eq!(bits(r.lane(l)), bits(want), "case {case} lane {l}: refined point");
                        assert_eq!(mag.to_array()[l].to_bits(), m.to_bits(), "case {case} lane {l}: error magnitude");
                        refined += 1;
                    }
                    None => assert_eq!(ok.to_bitmask() & (1 << l), 0, "case {case} lane {l}: refinement given"),
                }
                checked += 1;
            }
        }
        assert_eq!(checked, 9600);
        // (The non-finite lanes, and the torus's on-axis points, have no projection.)
        assert!(refined > 8500 && refined < 9600, "{refined} refined");
        // A sphere's centre and a torus's axis have no projection, in 8 lanes too.
        let ball = Leaf::new(Shape::Sphere, Affine3A::from_translation(Vec3::new(1.0, 2.0, 3.0)), 0);
        let (_, _, ok) = ball.refine_x8(Vec3x8::splat(Vec3::new(1.0, 2.0, 3.0)));
        assert!(ball.refine(Vec3::new(1.0, 2.0, 3.0)).is_none() && ok.to_bitmask() == 0);
        let ring = Leaf::new(Shape::Torus { major: 1.0, minor: 0.3 }, Affine3A::from_translation(Vec3::new(1.0, 2.0, 3.0)), 0);
        let (_, _, ok) = ring.refine_x8(Vec3x8::splat(Vec3::new(1.0, 2.0, 3.5)));
        assert!(ring.refine(Vec3::new(1.0, 2.0, 3.5)).is_none() && ok.to_bitmask() == 0);
    }

    /// [`project_object`] puts points a little off each canonical surface (1e-4 along a random
    /// direction, away from edges) back on it: the surface's own distance function is ~0 there, and the
    /// point moved no farther than it was off. Undefined cases give `None`.
    #[test]
    fn projection_lands_on_each_surface() {
        let mut u = lcg(0x5eed);
        let (m, k) = cone_line(0.3, 0.8);
        // Each shape with its signed distance function (exact near the part the points lie on).
        type Distance = fn(Vec3) -> f32;
        let cases: [(Shape, Distance); 6] = [
            (Shape::Sphere, |q| q.length() - 1.0),
            (Shape::Box, |q| q.abs().max_element() - 1.0),
            (Shape::Cylinder, |q| (q.x * q.x + q.y * q.y).sqrt() - 1.0),
            (Shape::Cone { r0: 0.3, r1: 0.8 }, |q| {
                let (m, k) = cone_line(0.3, 0.8);
                ((q.x * q.x + q.y * q.y).sqrt() - m.mul_add(q.z, k)) / m.mul_add(m, 1.0).sqrt()
            }),
            (Shape::Torus { major: 1.0, minor: 0.25 }, |q| (((q.x * q.x + q.y * q.y).sqrt() - 1.0).powi(2) + q.z * q.z).sqrt() - 0.25),
            (Shape::HalfSpace, |q| q.z),
        ];
        for (shape, dist) in cases {
            for _ in 0..2000 {
                let (a, z) = (u() * std::f32::consts::TAU, u() * 1.4 - 0.7);
                // A surface point away from edges (sides of the cylinder and cone, a box face's middle).
                let on = match shape {
                    Shape::Sphere => Vec3::new(u() - 0.5, u() - 0.5, u() - 0.5).normalize_or(Vec3::X),
                    Shape::Box => Vec3::new(1.0, u() * 1.6 - 0.8, u() * 1.6 - 0.8),
                    Shape::Cylinder => Vec3::new(a.cos(), a.sin(), z),
                    Shape::Cone { .. } => Vec3::new(a.cos(), a.sin(), 0.0) * m.mul_add(z, k) + Vec3::Z * z,
                    Shape::Torus { .. } => {
                        let b = u() * std::f32::consts::TAU;
                        let c = Vec3::new(a.cos(), a.sin(), 0.0);
                        c + (c * b.cos() + Vec3::Z * b.sin()) * 0.25
                    }
                    Shape::HalfSpace => Vec3::new(u() * 4.0 - 2.0, u() * 4.0 - 2.0, 0.0),
                };
                assert!(dist(on).abs() < 2e-6, "{shape:?}: the test's surface point {on} is off by {}", dist(on));
                let off = on + Vec3::new(u() - 0.5, u() - 0.5, u() - 0.5).normalize_or(Vec3::Y) * 1e-4;
                let q = project_object(shape, off).unwrap_or_else(|| panic!("{shape:?} {off}: no projection"));
                assert!(dist(q).abs() < 2e-6, "{shape:?}: {off} projected to {q}, off the surface by {}", dist(q));
                assert!((q - off).length() <= 1.001e-4 + 1e-6, "{shape:?}: {off} moved {} to {q}", (q - off).length());
            }
        }
        assert!(project_object(Shape::Sphere, Vec3::ZERO).is_none());
        assert!(project_object(Shape::Torus { major: 1.0, minor: 0.25 }, Vec3::new(0.0, 0.0, 0.1)).is_none());
    }
}
