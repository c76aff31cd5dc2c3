//! Light-cone culling of shadow rays: before a request's shadow rays towards a light are traced, one
//! test decides, for 8 shading points at once, which of them see the whole light through empty space.
//! Their rays are then all unoccluded (nothing to walk through either) and are credited untraced.
//!
//! Every shadow ray of a shading point towards a light is a segment `o + t d`, `t` in `(0, tmax)`,
//! `tmax <= 1`, `d = target - o`, with its target in the light's box `B` (its sample points moved off
//! the surface by a few ULPs; the box is widened well past that). So the segments lie in the cone of
//! rays from `o` whose direction `d` lies in the box `B - o` (per axis an interval: the box of
//! directions, as the group traversal's interval test bounds a group's inverse directions). A box the
//! cone misses is missed by every segment: per axis, the smallest distance at which any direction of
//! the interval can enter the slab and the largest at which it can leave it bound every ray's own
//! entry and exit (a direction interval that contains 0 still bounds the entry when the origin is
//! outside the slab: only the directions towards it enter). The test walks the binary BVH with 8 such
//! cones (one per lane, each lane's verdict its own: it does not depend on which shading points share
//! the chunk, so images do not depend on tiles) and tests the boxes of the prims in the leaves it
//! reaches. Unbounded prims: a plane is missed when the origin's side (the plane kernel's own
//! numerator, bit for bit) and the light box's corners are on opposite sides of the ray's travel;
//! any other unbounded prim keeps every lane traced.
//!
//! The light's own prim (a quad or disk is geometry too) is skipped for origins clearly in front of it:
//! a segment from there to a target just in front of the light never reaches the light's plane before
//! `t = 1`, far from the `1 - 1e-4` at which shadow rays end.
//!
//! Conservative by construction, with margins far above f32 rounding: boxes widened by `1e-5` of the
//! scene's scale, the direction box by `1e-5` of the scale, and a lane culled only when its entry
//! bound exceeds its exit bound by `1e-4` (in units of the segment, `t` in `[0, 1]`). A lane the test
//! declares clear has, for every sample, exactly the result the traversal would give: unoccluded,
//! untouched (`tests/shadow_cone.rs` holds it to the traversal over random scenes and scales).
//!
//! The same walk also reports the lanes whose cones meet exactly one prim's box (and that prim): their
//! rays can meet no other surface, so the shadow stage tests them against that prim alone.

use crate::accel::MAX_DEPTH;
use crate::scene::{Light, Scene, Shape};
use crate::simd::{f32x8, Vec3x8, LANES};
use glam::Vec3;

/// Relative widening of boxes and of the direction box (of the scale of the scene, light and origins).
const PAD: f32 = 1e-5;
/// Absolute slack of the verdict, in units of the segment (`t` runs over `[0, 1]`).
const SLACK: f32 = 1e-4;
/// The light's own prim is skipped for origins farther than this fraction of the scale in front of it
/// (there the light plane's distance is computed to ~1e-5 of itself, far inside `1 - SHADOW_END`).
const IN_FRONT: f32 = 0.05;
/// Widening of the light's box, relative to the scale: targets are 256 ULPs off the light.
const LIGHT_PAD: f32 = 1e-3;

/// What the cone test needs of one light: its widened target box, and for a quad or disk its own prim
/// and plane.
#[derive(Clone, Copy, Debug)]
pub struct LightCone {
    lo: Vec3,
    hi: Vec3,
    /// Scale of the scene, the light and the margin (max |coordinate| of the scene's and light's boxes).
    scale: f32,
    /// The light's own prim and its plane (unit normal towards the lit side, a point on it).
    own: Option<(u32, Vec3, Vec3)>,
}

impl LightCone {
    /// The cone data of `light` in `scene`, or `None` where the test does not apply (sphere lights,
    /// scenes with motion, a light whose prim is not found, non-finite bounds).
    pub fn new(scene: &Scene, light: &Light) -> Option<Self> {
        Self::new_near(scene, light, usize::MAX)
    }

    /// [`LightCone::new`] with the light's prim looked for at `guess` first (the shadow stage's tables,
    /// from `Scene::light_of_prim`: a search of every prim per light is O(L x P)).
    pub fn new_near(scene: &Scene, light: &Light, guess: usize) -> Option<Self> {
        if scene.features.motion {
            return None;
        }
        let find = |is: &dyn Fn(&Shape) -> bool| match scene.prims.get(guess) {
            Some(p) if p.is_light && is(&p.shape) => Some(guess),
            _ => scene.prims.iter().rposition(|p| p.is_light && is(&p.shape)),
        };
        // Lights are compiled after the shapes: their prims are the last ones (searched from the end).
        let (lo, hi, own) = match *light {
            Light::Point { position, .. } => (position, position, None),
            Light::Quad { quad, .. } => {
                let corners = [quad.origin, quad.origin + quad.u, quad.origin + quad.v, quad.origin + quad.u + quad.v];
                let lo = corners.iter().fold(Vec3::splat(f32::INFINITY), |a, &c| a.min(c));
                let hi = corners.iter().fold(Vec3::splat(f32::NEG_INFINITY), |a, &c| a.max(c));
                let pid = find(&|s| matches!(*s, Shape::Quad(q) if q.origin == quad.origin && q.u == quad.u && q.v == quad.v))?;
                (lo, hi, Some((pid as u32, quad.normal().normalize(), quad.origin)))
            }
            Light::Disk { disk, .. } => {
                let r = Vec3::splat(disk.radius);
                let pid = find(
                    &|s| matches!(*s, Shape::Disk(k) if k.center == disk.center && k.normal == disk.normal && k.radius == disk.radius),
                )?;
                (disk.center - r, disk.center + r, Some((pid as u32, disk.normal.normalize(), disk.center)))
            }
            Light::Sphere { .. } => return None,
        };
        // The root's box holds every bounded prim's.
        let mut scale = lo.abs().max(hi.abs()).max_element();
        if let Some(root) = scene.bvh.nodes.first() {
            scale = scale.max(Vec3::from_array(root.min).abs().max(Vec3::from_array(root.max).abs()).max_element());
        }
        if !scale.is_finite() || own.is_some_and(|(_, n, _)| !n.is_finite()) {
            return None;
        }
        let m = Vec3::splat(LIGHT_PAD * scale + f32::MIN_POSITIVE);
        Some(LightCone { lo: lo - m, hi: hi + m, scale, own })
    }

    /// The lanes (bits, among `lanes`) whose shadow rays from origin `o` towards this light's targets
    /// meet no prim's box and no unbounded prim (every such ray is unoccluded and crosses nothing), and
    /// the lanes whose cones meet exactly one bounded prim's box (and no unbounded prim), with that prim:
    /// their shadow rays can cross no other surface.
    pub fn verdict(&self, scene: &Scene, o: Vec3x8, lanes: u32) -> Verdict {
        let none = Verdict { clear: 0, single: 0, prim: [0; LANES] };
        let splat = f32x8::splat;
        let ao = o.x.abs().max(o.y.abs()).max(o.z.abs());
        let s = ao + splat(self.scale);
        let pad = s * splat(PAD);
        // Direction box per lane, widened; and its inverses (infinite where an end is 0).
        let (dlo, dhi) = (Vec3x8::splat(self.lo) - o - Vec3x8::new(pad, pad, pad), Vec3x8::splat(self.hi) - o + Vec3x8::new(pad, pad, pad));
        // A NaN or infinite origin fails `|o| < inf` (the light box is finite): never cleared.
        let finite = ao.simd_lt(f32x8::splat(f32::INFINITY)).to_bitmask();
        let mut clear = lanes & finite;
        if clear == 0 {
            return none;
        }
        for &pid in &scene.unbounded {
            clear &= self.plane_clear(scene, pid, o, s);
            if clear == 0 {
                return none;
            }
        }
        let cone = Cone::new(o, dlo, dhi, pad);
        // The light's own prim is skipped by lanes clearly in front of it.
        let skip_own = match self.own {
            Some((pid, n, p)) => {
                let h = Vec3x8::splat(n).dot_unfused(o - Vec3x8::splat(p));
                Some((pid, h.simd_gt(s * splat(IN_FRONT)).to_bitmask()))
            }
            None => None,
        };
        let bvh = &scene.bvh;
        if bvh.nodes.is_empty() {
            return Verdict { clear, ..none };
        }
        // Lanes that met exactly one prim's box so far, and which (a lane that meets a second one leaves
        // both `clear` and `one`).
        let (mut one, mut prim) = (0u32, [0u32; LANES]);
        // Lanes still clear or single whose cones reach a node; a leaf's prims' boxes decide.
        let mut stack = [(0u32, 0u32); MAX_DEPTH];
        let mut sp = 0;
        let (mut node, mut live) = (0usize, clear);
        loop {
            let n = &bvh.nodes[node];
            live &= (clear | one) & cone.reaches(Vec3::from_array(n.min), Vec3::from_array(n.max));
            if live != 0 {
                let count = n.count() as usize;
                if count == 0 {
                    stack[sp] = (n.left_first + 1, live);
                    sp += 1;
                    node = n.left_first as usize;
                    continue;
                }
                let first = n.left_first as usize;
                for &bi in &bvh.indices[first..first + count] {
                    let pid = scene.bounded[bi as usize];
                    // A one-prim leaf's box is its prim's (taking it as met is conservative anyway).
                    let b = &scene.bounds[pid as usize];
                    let mut hit = if count == 1 { live } else { cone.reaches(b.min, b.max) & live };
                    if let Some((own, front)) = skip_own {
                        if own == pid {
                            hit &= !front;
                        }
                    }
                    // A lane's first prim makes it single; a second one, neither.
                    let mut first = hit & clear;
                    one = (one & !hit) | first;
                    clear &= !hit;
                    while first != 0 {
                        prim[first.trailing_zeros() as usize] = pid;
                        first &= first - 1;
                    }
                }
                if clear | one == 0 {
                    return none;
                }
            }
            if sp == 0 {
                return Verdict { clear, single: one, prim };
            }
            sp -= 1;
            (node, live) = (stack[sp].0 as usize, stack[sp].1);
        }
    }

    /// Lanes whose segments cannot cross unbounded prim `pid` (a plane; any other shape: none).
    fn plane_clear(&self, scene: &Scene, pid: u32, o: Vec3x8, s: f32x8) -> u32 {
        let Shape::Plane(p) = scene.prims[pid as usize].shape else {
            return 0;
        };
        let splat = f32x8::splat;
        let (nx, ny, nz) = (splat(p.normal.x), splat(p.normal.y), splat(p.normal.z));
        // The kernel's numerator, bit for bit: its sign says on which side the kernel sees the origin
        // (`t = num / den` hits only where `den = n.d` has the same sign).
        let num = nx.mul_neg_add(o.x, ny.mul_neg_add(o.y, nz.mul_neg_add(o.z, splat(p.offset))));
        // n.d over the direction box: the light box's corners' n.c - n.o, bounded with a margin far
        // above the rounding of the kernel's `den`.
        let (lo, hi) = (self.lo, self.hi);
        let n = p.normal;
        let corner_min = n.x * if n.x >= 0.0 { lo.x } else { hi.x }
            + n.y * if n.y >= 0.0 { lo.y } else { hi.y }
            + n.z * if n.z >= 0.0 { lo.z } else { hi.z };
        let corner_max = n.x * if n.x >= 0.0 { hi.x } else { lo.x }
            + n.y * if n.y >= 0.0 { hi.y } else { lo.y }
            + n.z * if n.z >= 0.0 { hi.z } else { lo.z };
        let no = Vec3x8::splat(n).dot_unfused(o);
        let m = s * splat(1e-4 * n.abs().max_element());
        let den_lo = splat(corner_min) - no - m;
        let den_hi = splat(corner_max) - no + m;
        // num < 0 (origin on the normal's side): the segment meets the plane only where den < 0; so
        // den > 0 for every direction is clear. num > 0: den < 0 everywhere is clear. num = 0: t = 0,
        // which the kernel never reports (a finite den; the margin keeps den away from 0).
        let zero = f32x8::ZERO;
        let away = (num.simd_lt(zero) & den_lo.simd_gt(zero)) | (num.simd_gt(zero) & den_hi.simd_lt(zero));
        away.to_bitmask()
    }
}

/// What [`LightCone::verdict`] found for 8 shading points.
#[derive(Clone, Copy, Debug)]
pub struct Verdict {
    /// Lanes whose shadow rays towards the light meet nothing.
    pub clear: u32,
    /// Lanes whose shadow rays can meet only `prim[l]` (a bounded prim).
    pub single: u32,
    pub prim: [u32; LANES],
}

/// Eight cones, per axis: the origins widened by `pad` either way (for the boxes' far and near
/// planes), the direction intervals' signs and the inverses the bounds multiply by.
struct Cone {
    axes: [ConeAxis; 3],
}

#[derive(Clone, Copy)]
struct ConeAxis {
    /// `o + pad`, `o - pad`: `b0 - (o + pad)` and `b1 - (o - pad)` are the box widened by `pad`.
    op: f32x8,
    om: f32x8,
    /// Every direction positive (`dlo > 0`), every one negative (`dhi < 0`).
    pos: f32x8,
    neg: f32x8,
    /// Entry from below: `1 / dhi` where some direction is positive, else `+inf` (no entry).
    enter_below: f32x8,
    /// Entry from above: `1 / dlo` where some direction is negative, else `-inf` (no entry: the
    /// distance to the box is negative, so the product is `+inf`).
    enter_above: f32x8,
    ilo: f32x8,
    ihi: f32x8,
}

impl Cone {
    fn new(o: Vec3x8, dlo: Vec3x8, dhi: Vec3x8, pad: f32x8) -> Self {
        let (zero, inf, one) = (f32x8::ZERO, f32x8::splat(f32::INFINITY), f32x8::ONE);
        let axis = |o: f32x8, dlo: f32x8, dhi: f32x8| {
            let (ilo, ihi) = (one / dlo, one / dhi);
            ConeAxis {
                op: o + pad,
                om: o - pad,
                pos: dlo.simd_gt(zero),
                neg: dhi.simd_lt(zero),
                enter_below: dhi.simd_gt(zero).select(ihi, inf),
                enter_above: dlo.simd_lt(zero).select(ilo, -inf),
                ilo,
                ihi,
            }
        };
        Cone { axes: [axis(o.x, dlo.x, dhi.x), axis(o.y, dlo.y, dhi.y), axis(o.z, dlo.z, dhi.z)] }
    }

    /// Lanes whose cone may meet the box `[min, max]` (widened) within `t` in `[0, 1]`.
    #[inline(always)]
    fn reaches(&self, min: Vec3, max: Vec3) -> u32 {
        let (tx0, tx1) = self.axes[0].bounds(min.x, max.x);
        let (ty0, ty1) = self.axes[1].bounds(min.y, max.y);
        let (tz0, tz1) = self.axes[2].bounds(min.z, max.z);
        let tn = tx0.fast_max(ty0).fast_max(tz0).fast_max(f32x8::ZERO);
        let tf = tx1.fast_min(ty1).fast_min(tz1).fast_min(f32x8::ONE);
        // Culled only past the slack; an infinite entry bound (no direction enters) culls.
        !(tn.simd_gt(tf + f32x8::splat(SLACK))).to_bitmask() & 0xff
    }
}

impl ConeAxis {
    /// The smallest entry and the largest exit distance over the lane's direction interval `[dlo, dhi]`
    /// on this axis, for the slab `[b0, b1]` widened by `pad`.
    #[inline(always)]
    fn bounds(&self, b0: f32, b1: f32) -> (f32x8, f32x8) {
        let inf = f32x8::splat(f32::INFINITY);
        let (d0, d1) = (f32x8::splat(b0) - self.op, f32x8::splat(b1) - self.om);
        let (below, above) = (d0.simd_gt(f32x8::ZERO), d1.simd_lt(f32x8::ZERO));
        // Entry: from below only directions with d > 0 enter, first at the largest d; from above only
        // d < 0, first at the most negative d; inside, at once.
        let tin = below.select(d0 * self.enter_below, above.select(d1 * self.enter_above, -inf));
        // Exit: with every d > 0 through b1, last at the smallest d; every d < 0 through b0, last at
        // the d nearest 0; directions of both signs (or 0) may stay in the slab for ever.
        let tout = self.pos.select(d1 * self.ilo, self.neg.select(d0 * self.ihi, inf));
        (tin, tout)
    }
}
