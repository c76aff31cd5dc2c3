//! Lane types shared by every SIMD kernel.
//!
//! glam has no structure-of-arrays vectors (`Vec3A` is one SSE register), so a packet of 8 vectors is
//! three `f32x8`: `Vec3x8`. The lane width is one constant (`LANES`); kernels are written against the
//! `F32s` alias and carry the `_x8` suffix.
//!
//! `wide` picks its backend at compile time from the target features (see `.cargo/config.toml`):
//! with AVX2+FMA an `f32x8` is one ymm register and `mul_add` is one `vfmadd`.

use glam::Vec3;
pub use wide::{f32x16, f32x8, i32x16, i32x8, u32x16, u32x8};

/// The float-lane operations a kernel written once for both widths uses (`f32x8`, and `f32x16` where
/// a stage pairs packets): generic kernels take the same operations in the same order at either width,
/// so a lane's result does not depend on the width it was computed at.
pub trait Lanes:
    Copy
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<Output = Self>
    + std::ops::Div<Output = Self>
    + std::ops::Neg<Output = Self>
    + std::ops::BitAnd<Output = Self>
    + std::ops::BitOr<Output = Self>
    + std::ops::Not<Output = Self>
{
    fn splat(x: f32) -> Self;
    fn mul_add(self, m: Self, a: Self) -> Self;
    fn mul_sub(self, m: Self, a: Self) -> Self;
    fn mul_neg_add(self, m: Self, a: Self) -> Self;
    fn sqrt(self) -> Self;
    fn min(self, o: Self) -> Self;
    fn max(self, o: Self) -> Self;
    fn ge(self, o: Self) -> Self;
    fn gt(self, o: Self) -> Self;
    fn lt(self, o: Self) -> Self;
    fn eq(self, o: Self) -> Self;
    /// `self` a mask: `a` where set, else `b`.
    fn select(self, a: Self, b: Self) -> Self;
    fn any(self) -> bool;
    fn bits(self) -> u32;
}

macro_rules! impl_lanes {
    ($t:ty) => {
        impl Lanes for $t {
            #[inline(always)]
            fn splat(x: f32) -> Self {
                <$t>::splat(x)
            }
            #[inline(always)]
            fn mul_add(self, m: Self, a: Self) -> Self {
                <$t>::mul_add(self, m, a)
            }
            #[inline(always)]
            fn mul_sub(self, m: Self, a: Self) -> Self {
                <$t>::mul_sub(self, m, a)
            }
            #[inline(always)]
            fn mul_neg_add(self, m: Self, a: Self) -> Self {
                <$t>::mul_neg_add(self, m, a)
            }
            #[inline(always)]
            fn sqrt(self) -> Self {
                <$t>::sqrt(self)
            }
            #[inline(always)]
            fn min(self, o: Self) -> Self {
                <$t>::min(self, o)
            }
            #[inline(always)]
            fn max(self, o: Self) -> Self {
                <$t>::max(self, o)
            }
            #[inline(always)]
            fn ge(self, o: Self) -> Self {
                self.simd_ge(o)
            }
            #[inline(always)]
            fn gt(self, o: Self) -> Self {
                self.simd_gt(o)
            }
            #[inline(always)]
            fn lt(self, o: Self) -> Self {
                self.simd_lt(o)
            }
            #[inline(always)]
            fn eq(self, o: Self) -> Self {
                self.simd_eq(o)
            }
            #[inline(always)]
            fn select(self, a: Self, b: Self) -> Self {
                <$t>::select(self, a, b)
            }
            #[inline(always)]
            fn any(self) -> bool {
                <$t>::any(self)
            }
            #[inline(always)]
            fn bits(self) -> u32 {
                <$t>::to_bitmask(self)
            }
        }
    };
}
impl_lanes!(f32x8);
impl_lanes!(f32x16);

/// Lanes per packet.
pub const LANES: usize = 8;
/// The lane type of every kernel.
pub type F32s = f32x8;

/// Round `n` up to a multiple of [`LANES`].
#[inline]
pub const fn pad_to_lanes(n: usize) -> usize {
    n.div_ceil(LANES) * LANES
}

/// Load 8 consecutive `f32` from `s[i..i + 8]`.
#[inline(always)]
pub fn load8(s: &[f32], i: usize) -> f32x8 {
    let a: [f32; 8] = s[i..i + 8].try_into().unwrap();
    f32x8::from(a)
}

/// Store 8 lanes into `s[i..i + 8]`.
#[inline(always)]
pub fn store8(s: &mut [f32], i: usize, v: f32x8) {
    s[i..i + 8].copy_from_slice(&v.to_array());
}

/// Eight lanes of a queue field: `v[first..first + 8]` as one load when `run` (the lanes are 8
/// consecutive elements), else `v[at(l)]` lane by lane.
#[inline(always)]
pub fn gather8<T: Copy>(v: &[T], run: bool, first: usize, at: impl Fn(usize) -> usize) -> [T; LANES] {
    if run {
        v[first..first + LANES].try_into().unwrap()
    } else {
        // (A plain loop, not `array::from_fn`: under some codegen-unit partitions `from_fn` stayed an
        // out-of-line call per use, 17 of them in the Lambert shading of 8 hits: shade 8% slower.)
        let mut out = [v[at(0)]; LANES];
        for (l, x) in out.iter_mut().enumerate().skip(1) {
            *x = v[at(l)];
        }
        out
    }
}

/// Lanes of entries `base..base + m` of a queue field (`1 <= m <= 8`; lanes past `m` repeat the last):
/// one load for a whole chunk. A function, not a closure in the caller: a closure of this in the shadow
/// stage's chunk loop was left out of line when an unrelated change moved the codegen-unit partition,
/// and the stage ran 25% slower (session 27).
#[inline(always)]
pub fn chunk8(v: &[f32], base: usize, m: usize) -> f32x8 {
    f32x8::from(gather8(v, m == LANES, base, |l| base + l.min(m - 1)))
}

/// Whether `v` is 8 consecutive values `v[0], v[0] + 1, ..` (ids that [`gather8`] can load as a run;
/// ids may repeat, so the ends alone do not tell).
#[inline(always)]
pub fn consecutive8(v: &[u32; LANES]) -> bool {
    let step = u32x8::from([0, 1, 2, 3, 4, 5, 6, 7]);
    u32x8::from(*v).simd_eq(u32x8::splat(v[0]) + step).all()
}

/// Three `f32x8`: 8 vectors in structure-of-arrays form (96 bytes, 32-byte aligned).
#[derive(Clone, Copy, Debug)]
pub struct Vec3x8 {
    pub x: f32x8,
    pub y: f32x8,
    pub z: f32x8,
}

impl Vec3x8 {
    #[inline(always)]
    pub fn new(x: f32x8, y: f32x8, z: f32x8) -> Self {
        Self { x, y, z }
    }
    #[inline(always)]
    pub fn splat(v: Vec3) -> Self {
        Self { x: f32x8::splat(v.x), y: f32x8::splat(v.y), z: f32x8::splat(v.z) }
    }
    /// From lane rows (`rows[k][l]` = component `k` of lane `l`).
    #[inline(always)]
    pub fn from_rows(rows: &[[f32; LANES]; 3]) -> Self {
        Self { x: f32x8::from(rows[0]), y: f32x8::from(rows[1]), z: f32x8::from(rows[2]) }
    }
    /// As lane rows (the inverse of [`Vec3x8::from_rows`]).
    #[inline(always)]
    pub fn rows(self) -> [[f32; LANES]; 3] {
        [self.x.to_array(), self.y.to_array(), self.z.to_array()]
    }
    #[inline(always)]
    pub fn load(xs: &[f32], ys: &[f32], zs: &[f32], i: usize) -> Self {
        Self { x: load8(xs, i), y: load8(ys, i), z: load8(zs, i) }
    }
    #[inline(always)]
    pub fn dot(self, o: Self) -> f32x8 {
        self.x.mul_add(o.x, self.y.mul_add(o.y, self.z * o.z))
    }
    #[inline(always)]
    pub fn dot3(self, o: Vec3) -> f32x8 {
        self.x.mul_add(f32x8::splat(o.x), self.y.mul_add(f32x8::splat(o.y), self.z * f32x8::splat(o.z)))
    }
    /// The dot product rounded exactly as glam's `Vec3::dot` (`(x x' + y y') + z z'`, no FMA): kernels
    /// that must agree bit for bit with a scalar glam twin use it.
    #[inline(always)]
    pub fn dot_unfused(self, o: Self) -> f32x8 {
        self.x * o.x + self.y * o.y + self.z * o.z
    }
    /// `mask ? a : b`, lane-wise.
    #[inline(always)]
    pub fn select(mask: f32x8, a: Self, b: Self) -> Self {
        Self { x: mask.select(a.x, b.x), y: mask.select(a.y, b.y), z: mask.select(a.z, b.z) }
    }
    /// `self / |self|` as glam's `normalize` rounds it (times the reciprocal of the length).
    #[inline(always)]
    pub fn normalize(self) -> Self {
        self.scale(f32x8::ONE / self.dot_unfused(self).sqrt())
    }
    /// glam's `normalize_or`, lane-wise: `fallback` where the reciprocal length is not finite and positive.
    #[inline(always)]
    pub fn normalize_or(self, fallback: Self) -> Self {
        let rcp = f32x8::ONE / self.dot_unfused(self).sqrt();
        Self::select(rcp.is_finite() & rcp.simd_gt(f32x8::ZERO), self.scale(rcp), fallback)
    }
    #[inline(always)]
    pub fn cross(self, o: Self) -> Self {
        Self { x: self.y * o.z - self.z * o.y, y: self.z * o.x - self.x * o.z, z: self.x * o.y - self.y * o.x }
    }
    #[inline(always)]
    pub fn scale(self, s: f32x8) -> Self {
        Self { x: self.x * s, y: self.y * s, z: self.z * s }
    }
    /// `v` in the lanes of `mask`, +0 elsewhere (as a sum's term: the unmasked lanes add nothing).
    #[inline(always)]
    pub fn masked(v: Self, mask: f32x8) -> Self {
        Self { x: v.x & mask, y: v.y & mask, z: v.z & mask }
    }
    /// `self * s + o`, lane-wise, fused.
    #[inline(always)]
    pub fn mul_add(self, s: f32x8, o: Self) -> Self {
        Self { x: self.x.mul_add(s, o.x), y: self.y.mul_add(s, o.y), z: self.z.mul_add(s, o.z) }
    }
    /// The largest `|component|` per lane, as glam's `v.abs().max_element()` rounds it (NaN aside).
    #[inline(always)]
    pub fn max_abs_element(self) -> f32x8 {
        self.x.abs().max(self.y.abs().max(self.z.abs()))
    }
    #[inline(always)]
    pub fn lane(&self, i: usize) -> Vec3 {
        Vec3::new(self.x.to_array()[i], self.y.to_array()[i], self.z.to_array()[i])
    }
}

impl std::ops::Add for Vec3x8 {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Self { x: self.x + o.x, y: self.y + o.y, z: self.z + o.z }
    }
}

/// Lane-wise, component-wise product (colour times colour).
impl std::ops::Mul for Vec3x8 {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        Self { x: self.x * o.x, y: self.y * o.y, z: self.z * o.z }
    }
}

impl std::ops::Sub for Vec3x8 {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Self { x: self.x - o.x, y: self.y - o.y, z: self.z - o.z }
    }
}

/// A packet of 8 rays. Lanes that carry no ray have `tmax = -1` (never hit anything).
///
/// `inv_d` is `1 / d` with IEEE infinities for zero components (slab tests rely on them).
#[derive(Clone, Copy, Debug)]
pub struct Ray8 {
    pub o: Vec3x8,
    pub d: Vec3x8,
    pub inv_d: Vec3x8,
    pub tmax: f32x8,
}

impl Ray8 {
    #[inline(always)]
    pub fn new(o: Vec3x8, d: Vec3x8, tmax: f32x8) -> Self {
        let one = f32x8::ONE;
        Self { o, d, inv_d: Vec3x8::new(one / d.x, one / d.y, one / d.z), tmax }
    }

    /// Overwrite `self` with rays `i..i + 8` of SoA rows (`o` and `d` per axis, `tmax`), as
    /// [`Ray8::new`] makes them. Field by field on purpose: building a `Ray8` temporary and copying it
    /// into an array compiled to 64-byte moves that reload two 32-byte stores at once, a
    /// store-forwarding stall per packet (17% of the camera intersect stage, a third of the shadow
    /// stage's `flush`, in `perf annotate`).
    #[inline(always)]
    pub fn load_into(&mut self, o: [&[f32]; 3], d: [&[f32]; 3], tmax: &[f32], i: usize) {
        let (dx, dy, dz) = (load8(d[0], i), load8(d[1], i), load8(d[2], i));
        (self.o.x, self.o.y, self.o.z) = (load8(o[0], i), load8(o[1], i), load8(o[2], i));
        (self.d.x, self.d.y, self.d.z) = (dx, dy, dz);
        (self.inv_d.x, self.inv_d.y, self.inv_d.z) = (f32x8::ONE / dx, f32x8::ONE / dy, f32x8::ONE / dz);
        self.tmax = load8(tmax, i);
    }
}

/// Lane mask helpers: `wide` masks are all-ones / all-zeros lanes of the float type.
/// The mask set in the lanes whose bit is set in `bits` (the inverse of `to_bitmask`).
#[inline(always)]
pub fn mask_from_bits(bits: u32) -> f32x8 {
    let lane = i32x8::from([1, 2, 4, 8, 16, 32, 64, 128]);
    bytemuck::cast((i32x8::splat(bits as i32) & lane).simd_eq(lane))
}

/// The lanes `l` (as bits) for which `f(l)` holds.
#[inline(always)]
pub fn lane_bits(f: impl Fn(usize) -> bool) -> u32 {
    (0..LANES).filter(|&l| f(l)).fold(0, |m, l| m | (1 << l))
}

/// The lanes of `mask` grouped by `key` (evaluated for every lane, in `mask` or not): `f(first, lanes)`
/// once per distinct key, with its first lane and all the lanes of `mask` that share it, in the order
/// of the first lanes.
#[inline(always)]
pub fn for_each_group<K: PartialEq>(mask: u32, key: impl Fn(usize) -> K, mut f: impl FnMut(usize, u32)) {
    let mut todo = mask;
    while todo != 0 {
        let first = todo.trailing_zeros() as usize;
        let k = key(first);
        let same = todo & lane_bits(|l| key(l) == k);
        todo &= !same;
        f(first, same);
    }
}

/// Whether any lane of mask `m` is set.
#[inline(always)]
pub fn any(m: f32x8) -> bool {
    m.any()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every 8-bit pattern survives bits -> mask -> bits, and `lane_bits` of its bit test gives it back.
    #[test]
    fn lane_masks_and_bits_round_trip() {
        for b in 0u32..256 {
            assert_eq!(mask_from_bits(b).to_bitmask(), b);
            assert_eq!(lane_bits(|l| (b >> l) & 1 == 1), b);
        }
    }

    #[test]
    fn vec3x8_matches_glam() {
        let a = Vec3::new(1.0, -2.0, 3.5);
        let b = Vec3::new(-0.25, 4.0, 2.0);
        let (pa, pb) = (Vec3x8::splat(a), Vec3x8::splat(b));
        for i in 0..LANES {
            assert_eq!(pa.dot(pb).to_array()[i], a.dot(b));
            assert_eq!(pa.cross(pb).lane(i), a.cross(b));
        }
        assert_eq!(pad_to_lanes(0), 0);
        assert_eq!(pad_to_lanes(9), 16);
    }
}
