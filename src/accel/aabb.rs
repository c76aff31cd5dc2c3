//! Axis-aligned boxes and the ray-box slab test (Kay & Kajiya 1986), 8 lanes and a scalar f64 twin.

use glam::{DVec3, Vec3};

use crate::simd::{f32x8, Ray8, Vec3x8};

/// An axis-aligned box. `EMPTY` (min = +inf, max = -inf) is the identity of `union` and `grow`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Default for Aabb {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb { min: Vec3::INFINITY, max: Vec3::NEG_INFINITY };

    #[inline]
    pub fn new(min: Vec3, max: Vec3) -> Self {
        Self { min, max }
    }

    #[inline]
    pub fn from_point(p: Vec3) -> Self {
        Self { min: p, max: p }
    }

    #[inline]
    pub fn union(self, o: Self) -> Self {
        Self { min: self.min.min(o.min), max: self.max.max(o.max) }
    }

    #[inline]
    pub fn grow(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    /// Midpoint; `0.5 * min + 0.5 * max` so that it cannot overflow for finite boxes.
    #[inline]
    pub fn centroid(&self) -> Vec3 {
        self.min * 0.5 + self.max * 0.5
    }

    #[inline]
    pub fn extent(&self) -> Vec3 {
        self.max - self.min
    }

    /// Surface area; 0 for an empty box.
    #[inline]
    pub fn surface_area(&self) -> f32 {
        if self.is_empty() {
            return 0.0;
        }
        let e = self.extent();
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }

    /// Half the perimeter (sum of the extents); 0 for an empty box. The SAH uses it in place of the
    /// area for a node whose area is 0 (all its boxes on one line).
    #[inline]
    pub fn half_perimeter(&self) -> f32 {
        if self.is_empty() {
            return 0.0;
        }
        let e = self.extent();
        e.x + e.y + e.z
    }

    /// True when min > max on some axis (or a coordinate is NaN).
    #[inline]
    pub fn is_empty(&self) -> bool {
        !(self.min.cmple(self.max).all())
    }

    /// The box widened outward by 2^-21 of each coordinate's magnitude (about 4 ulps) plus the smallest
    /// normal float: covers the rounding of corners computed from a few f32 operations. Empty boxes
    /// stay empty.
    #[inline]
    pub fn widened_ulps(&self) -> Self {
        if self.is_empty() {
            return *self;
        }
        let e = |v: Vec3| v.abs() * (1.0 / (1u32 << 21) as f32) + Vec3::splat(f32::MIN_POSITIVE);
        Self { min: self.min - e(self.min), max: self.max + e(self.max) }
    }

    /// True when `o` lies inside `self` (boundaries included). An empty `o` is inside every box.
    #[inline]
    pub fn contains(&self, o: &Aabb) -> bool {
        o.is_empty() || (self.min.cmple(o.min).all() && o.max.cmple(self.max).all())
    }
}

/// Largest `|1/d|` the packet slab test uses: `2^60`. Zero direction components (`inv_d = +-inf`)
/// are clamped to it, a power of two so that `o * inv_d` stays exact. Such an axis (ray parallel to
/// the slab) gets the absolute padding `s = ABS_PAD * max(|o_a|, 1)` in space (`s * 2^60` in `t`), so
/// a parallel lane passes when `min - s <= o_a <= max + s` (the boundary itself included whatever the
/// sign of the zero) and fails farther outside (up to `2^-60 * tfar`; a direction that is zero on
/// every axis is a point, which passes exactly when it is inside the padded box and `tmax` allows).
/// Components with `0 < |d| < 2^-60` are treated as `2^-60` (approximation, documented limit).
pub const INV_D_CLAMP: f32 = (1u64 << 60) as f32;

/// Relative padding of a slab distance: `2^-21` (8 ulp), against the roundings of `inv_d = 1/d`,
/// of the folded FMA and of the precomputed products (each at most `2^-24` relative).
const REL_PAD: f32 = 1.0 / (1u32 << 21) as f32;
/// Absolute padding, in units of `|o * inv_d|`: `2^-21`, against the cancellation error of the
/// folded form (`o * inv_d` is rounded before `min * inv_d` is subtracted from it).
const ABS_PAD: f32 = 1.0 / (1u32 << 21) as f32;

/// The per-packet constants of the slab test, computed once per traversal.
///
/// The slab distance `t = (b - o) * inv_d` is folded into `t = b * inv + c` with `c = -o * inv`,
/// so each plane costs one FMA per node (Williams et al. 2005 precompute `inv_d`; folding the origin
/// is what Embree's non-robust kernel does). Folding loses precision when `|o * inv|` is large
/// compared with `t`; as in Ize 2013 ("Robust BVH Ray Traversal", JCGT 2(2)) the test is made
/// conservative, but the padding is folded into the constants, so it costs nothing per node: the
/// plane that is *near* on a lane (box min when `inv >= 0`, box max otherwise) gets
/// `inv * (1 - REL_PAD)` and `c - e`, the far plane `inv * (1 + REL_PAD)` and `c + e`, with
/// `e = ABS_PAD * |o * inv|`. Clamped (parallel) axes keep `inv = +-2^60` unscaled and get
/// `e = ABS_PAD * max(|o * inv|, 2^60)` (see [`INV_D_CLAMP`]).
#[derive(Clone, Copy, Debug)]
pub struct PacketRay {
    /// `inv_d` scaled for the box's min plane, and the folded origin term of that plane.
    pub inv_lo: Vec3x8,
    pub c_lo: Vec3x8,
    /// The same for the box's max plane.
    pub inv_hi: Vec3x8,
    pub c_hi: Vec3x8,
}

/// One axis of [`PacketRay::new`]: `(inv_lo, c_lo, inv_hi, c_hi)`.
#[inline(always)]
fn fold_axis(o: f32x8, inv_d: f32x8) -> (f32x8, f32x8, f32x8, f32x8) {
    let lim = f32x8::splat(INV_D_CLAMP);
    // fast_max/fast_min: inv_d is never NaN for a finite, valid ray (1/0 is +-inf, clamped here).
    let inv = inv_d.fast_max(-lim).fast_min(lim);
    let parallel = inv.abs().simd_ge(lim);
    let pos = inv.simd_ge(f32x8::ZERO);
    let (down, up) = (f32x8::splat(1.0 - REL_PAD), f32x8::splat(1.0 + REL_PAD));
    let one = f32x8::ONE;
    let s_lo = parallel.select(one, pos.select(down, up));
    let s_hi = parallel.select(one, pos.select(up, down));
    let e = (o * inv).abs().fast_max(parallel.select(lim, f32x8::ZERO)) * f32x8::splat(ABS_PAD);
    let (inv_lo, inv_hi) = (inv * s_lo, inv * s_hi);
    let c_lo = -(o * inv_lo) + pos.select(-e, e);
    let c_hi = -(o * inv_hi) + pos.select(e, -e);
    (inv_lo, c_lo, inv_hi, c_hi)
}

impl PacketRay {
    /// Precompute from a packet (uses `ray.o` and `ray.inv_d`, which must be `1 / d` correctly
    /// rounded, as `Ray8::new` computes it).
    #[inline]
    pub fn new(ray: &Ray8) -> Self {
        let (xl, xcl, xh, xch) = fold_axis(ray.o.x, ray.inv_d.x);
        let (yl, ycl, yh, ych) = fold_axis(ray.o.y, ray.inv_d.y);
        let (zl, zcl, zh, zch) = fold_axis(ray.o.z, ray.inv_d.z);
        Self {
            inv_lo: Vec3x8::new(xl, yl, zl),
            c_lo: Vec3x8::new(xcl, ycl, zcl),
            inv_hi: Vec3x8::new(xh, yh, zh),
            c_hi: Vec3x8::new(xch, ych, zch),
        }
    }
}

/// Slab test of one box against 8 rays: `(tnear, mask)` where `tnear = max(0, slab entries)` (a
/// lower bound of the true entry) and `mask` holds the lanes whose `[tnear, tfar]` overlaps
/// `[0, tmax]`. Conservative: a lane whose exact interval overlaps is never rejected; a lane may pass
/// when it misses the box by less than the padding (see [`PacketRay`]). Lanes with `tmax < 0` never
/// pass. No NaN can arise: all constants are finite (for `|o| < 2^68` and finite boxes).
///
/// Cost per box: 6 FMA, 3 min, 3 max, 2 max, 2 min, 1 compare.
#[inline(always)]
pub fn intersect_aabb_x8(min: Vec3, max: Vec3, r: &PacketRay, tmax: f32x8) -> (f32x8, f32x8) {
    let x0 = f32x8::splat(min.x).mul_add(r.inv_lo.x, r.c_lo.x);
    let x1 = f32x8::splat(max.x).mul_add(r.inv_hi.x, r.c_hi.x);
    let y0 = f32x8::splat(min.y).mul_add(r.inv_lo.y, r.c_lo.y);
    let y1 = f32x8::splat(max.y).mul_add(r.inv_hi.y, r.c_hi.y);
    let z0 = f32x8::splat(min.z).mul_add(r.inv_lo.z, r.c_lo.z);
    let z1 = f32x8::splat(max.z).mul_add(r.inv_hi.z, r.c_hi.z);
    // The padded min-plane and max-plane distances keep their order (the padding only widens the
    // interval), so min/max sort each slab into (near, far) per lane.
    let tnear = x0.fast_min(x1).fast_max(y0.fast_min(y1)).fast_max(z0.fast_min(z1).fast_max(f32x8::ZERO));
    let tfar = x0.fast_max(x1).fast_min(y0.fast_max(y1)).fast_min(z0.fast_max(z1).fast_min(tmax));
    (tnear, tnear.simd_le(tfar))
}

/// Scalar f64 slab interval of the whole line `o + t d` with the box: `(tnear, tfar)`, empty when
/// `tnear > tfar`. An axis with `d == 0` contributes `(-inf, inf)` when `min <= o <= max` and an
/// empty interval otherwise (no `0 * inf`). Distances are `(b - o) / d`, each correctly rounded.
pub fn slab_interval_f64(min: Vec3, max: Vec3, o: DVec3, d: DVec3) -> (f64, f64) {
    let (mut tn, mut tf) = (f64::NEG_INFINITY, f64::INFINITY);
    for a in 0..3 {
        let (lo, hi, oa, da) = (min[a] as f64, max[a] as f64, o[a], d[a]);
        if da == 0.0 {
            if oa < lo || oa > hi {
                return (f64::INFINITY, f64::NEG_INFINITY);
            }
            continue;
        }
        let (t0, t1) = ((lo - oa) / da, (hi - oa) / da);
        tn = tn.max(t0.min(t1));
        tf = tf.min(t0.max(t1));
    }
    (tn, tf)
}

/// Scalar f64 twin of [`intersect_aabb_x8`] (exact up to one rounding per distance, not padded):
/// `Some(tnear)` with `tnear = max(0, entry)` when the slab interval overlaps `[0, tmax]`.
pub fn intersect_aabb_f64(min: Vec3, max: Vec3, o: DVec3, d: DVec3, tmax: f64) -> Option<f64> {
    let (tn, tf) = slab_interval_f64(min, max, o, d);
    let (tn, tf) = (tn.max(0.0), tf.min(tmax));
    (tn <= tf).then_some(tn)
}
