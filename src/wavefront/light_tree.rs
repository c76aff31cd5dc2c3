//! `light_selection = "tree"`: a light picked by descending a tree of the lights, O(log L) per shading
//! point where `local` weighs every light (a BVH light sampler, after Conty Estevez & Kulla 2018 and
//! pbrt-v4's `BVHLightSampler`, written here for 8-wide nodes).
//!
//! Each node holds up to 8 children, each with bounds of what lies under it: a bounding sphere (centre,
//! radius), the sum of the lights' powers `Phi`, and a cone of the emitting sides' normals (axis and
//! half-angle `theta_o`; all directions where a light under it emits all round: points, spheres). At a
//! shading point `p` (with the receiver's normal `n` for Lambert points) a child's importance is
//!
//! `Phi x e x r / max(d^2, radius^2)`
//!
//! with `d` the distance from `p` to the sphere's centre, `theta_b` the half-angle the sphere subtends at
//! `p`, `theta_w` the angle between the cone's axis and the direction from the centre to `p`,
//! `e = cos(max(0, theta_w - theta_o - theta_b))` (a bound of any light's cosine towards `p`; 0 where it is
//! below `-COS_FLOOR`: no light under the child faces `p`), and for Lambert points
//! `r = cos(max(0, theta_i - theta_b)) + COS_FLOOR` with `theta_i` the angle between `n` and the direction
//! to the centre (0 where the whole sphere lies below the horizon). Inside a child's sphere both bounds
//! are 1. The 8 children's importances are one 8-lane evaluation.
//!
//! **Exact probabilities.** The pick's number `u` lies on the grid of 2^24 values (the samplers'
//! resolution). A node splits its range of grid values among its children in proportion to their
//! importances (each child of positive importance keeps at least one value while the range has room),
//! and the pick follows `u` down. A light's probability is the width of the range it ends in over 2^24:
//! exactly the share of the numbers that pick it, so `1 / P` weighs what the picks do.
//! [`LightTree::prob`] follows a light's path from the root with the same operations: bit for bit the
//! pick's.
//!
//! **Zooms.** A path's range narrows level by level, by the bounds' importances rather than the lights'
//! (bright quads facing away from a point inside their bounding spheres take both cosine bounds as 1).
//! Once a range had fewer values than children of importance, the later children would get none:
//! probability 0 for lights that do light the point, a bias (a review's dim lamps beside such quads
//! lost half of a point's light at a power ratio of 1e8). So a range narrower than 2^12 values is first
//! widened by 12 fresh random bits (the pick's second number, `fine`): the value `a` of a range `w` wide
//! becomes `a x 2^12 + f` of a range `w x 2^12` wide, again uniform, and the probabilities below carry a
//! factor 2^-12. Two zooms take the resolution from 2^-24 to 2^-48: a child is left out only where its
//! path's probability is below about 2^-45.
//!
//! **Build.** Top down: a node's lights are split in two, repeatedly (the group of most lights first),
//! until it has 8 groups or single lights; each split is the one along an axis, lights ordered by centre,
//! that minimises the sum over both sides of `Phi x (surface area + diagonal^2 / 20) x M(theta_o)` (the
//! surface-area-orientation heuristic of pbrt-v4, `M` the measure of the directions the cone's lights
//! emit into). Past depth 32 the splits are at the median (each halves a group at least), so that no tree of fewer
//! than 2^32 lights is deeper than 64 levels. The lights are sorted along each axis once, and each split
//! partitions the three orders stably, so that no group is sorted again (O(n log n) sorting in all).

use super::pick::{COS_FLOOR, D2_FLOOR};
use crate::simd::{f32x8, Vec3x8};
use glam::{DVec3, Vec3};

/// The pick's numbers: multiples of 2^-24 in [0, 1).
pub const GRID: u32 = 1 << 24;

/// A range narrower than this many values is widened by [`ZOOM_BITS`] fresh random bits before the next
/// split (see the module docs), at most [`MAX_ZOOMS`] times along a path.
const ZOOM_BELOW: u32 = 1 << 12;
const ZOOM_BITS: u32 = 12;
const MAX_ZOOMS: usize = 2;

/// A light's range width over this: its probability after 0, 1 or 2 zooms (powers of two, exact in f32).
const ZOOM_SCALE: [f32; MAX_ZOOMS + 1] = [1.0 / GRID as f32, 1.0 / GRID as f32 / 4096.0, 1.0 / GRID as f32 / 16_777_216.0];

/// A child slot that holds a light (its index in the low bits) rather than a node.
const LIGHT: u32 = 1 << 31;
const EMPTY: u32 = u32::MAX;

/// The tree's deepest path (the build splits at the median past half of it).
const MAX_DEPTH: usize = 64;

/// One light as the tree sees it: bounding-sphere centre and radius, the emitting side's unit normal
/// (zero: emits all round), and its power (scaled; 0: never picked, not in the tree).
#[derive(Clone, Copy, Debug)]
pub struct LightBounds {
    pub centre: Vec3,
    pub radius: f32,
    pub normal: Vec3,
    pub phi: f32,
}

/// 8 children's bounds, one lane each (empty slots: power 0).
#[derive(Clone, Copy)]
struct Node {
    cx: f32x8,
    cy: f32x8,
    cz: f32x8,
    r: f32x8,
    r2: f32x8,
    inv_r2: f32x8,
    phi: f32x8,
    wx: f32x8,
    wy: f32x8,
    wz: f32x8,
    cos_o: f32x8,
    sin_o: f32x8,
    child: [u32; 8],
}

/// A cone of directions (f64, at build): unit axis and the cosine of its half-angle (-1: all).
#[derive(Clone, Copy, Debug)]
struct Cone {
    w: DVec3,
    cos: f64,
}

const ALL_DIRECTIONS: Cone = Cone { w: DVec3::Z, cos: -1.0 };

impl Cone {
    /// The smallest cone about both (pbrt-v4's `Union` of direction cones).
    fn union(a: Cone, b: Cone) -> Cone {
        use std::f64::consts::PI;
        if a.cos <= -1.0 || b.cos <= -1.0 {
            return ALL_DIRECTIONS;
        }
        let (ta, tb) = (a.cos.clamp(-1.0, 1.0).acos(), b.cos.clamp(-1.0, 1.0).acos());
        let td = a.w.angle_between(b.w);
        if (td + tb).min(PI) <= ta {
            return a;
        }
        if (td + ta).min(PI) <= tb {
            return b;
        }
        let to = (ta + td + tb) / 2.0;
        let k = a.w.cross(b.w);
        if to >= PI || k.length_squared() < 1e-24 {
            return ALL_DIRECTIONS;
        }
        // a's axis turned by (to - ta) towards b's, about their common normal.
        let k = k.normalize();
        let tr = to - ta;
        let w = a.w * tr.cos() + k.cross(a.w) * tr.sin();
        Cone { w: w.normalize(), cos: to.cos() }
    }

    /// The measure of the directions the cone's Lambert emitters send light into (pbrt-v4's `M_Omega`
    /// with an emission half-angle of pi / 2).
    fn measure(self) -> f64 {
        use std::f64::consts::{FRAC_PI_2, PI};
        let to = self.cos.clamp(-1.0, 1.0).acos();
        let tw = (to + FRAC_PI_2).min(PI);
        let so = to.sin();
        2.0 * PI * (1.0 - self.cos) + FRAC_PI_2 * (2.0 * tw * so - (to - 2.0 * tw).cos() - 2.0 * to * so + self.cos)
    }
}

/// What lies under a child: bounds in f64 while building.
#[derive(Clone, Copy, Debug)]
struct Agg {
    lo: DVec3,
    hi: DVec3,
    phi: f64,
    cone: Option<Cone>,
}

impl Agg {
    const EMPTY: Agg = Agg { lo: DVec3::INFINITY, hi: DVec3::NEG_INFINITY, phi: 0.0, cone: None };

    fn of(l: &LightBounds) -> Agg {
        let (c, r) = (l.centre.as_dvec3(), l.radius as f64);
        let cone = if l.normal == Vec3::ZERO { ALL_DIRECTIONS } else { Cone { w: l.normal.as_dvec3().normalize(), cos: 1.0 } };
        Agg { lo: c - r, hi: c + r, phi: l.phi as f64, cone: Some(cone) }
    }

    fn add(self, o: Agg) -> Agg {
        let cone = match (self.cone, o.cone) {
            (Some(a), Some(b)) => Some(Cone::union(a, b)),
            (a, b) => a.or(b),
        };
        Agg { lo: self.lo.min(o.lo), hi: self.hi.max(o.hi), phi: self.phi + o.phi, cone }
    }

    /// The split heuristic's cost of this side.
    fn cost(&self) -> f64 {
        // (An empty side, no cone: nothing.)
        let Some(cone) = self.cone else {
            return 0.0;
        };
        let e = (self.hi - self.lo).max(DVec3::ZERO);
        let area = 2.0 * (e.x * e.y + e.y * e.z + e.z * e.x);
        self.phi * (area + 0.05 * e.length_squared()) * cone.measure()
    }
}

/// One child's bounds, as its lane of a [`Node`] holds them.
#[derive(Clone, Copy)]
struct Slot {
    centre: Vec3,
    r: f32,
    phi: f32,
    w: Vec3,
    cos_o: f32,
    sin_o: f32,
}

impl Slot {
    /// An empty slot: no power, so importance 0 (and finite terms wherever the point is).
    const EMPTY: Slot = Slot { centre: Vec3::ZERO, r: 1.0, phi: 0.0, w: Vec3::ZERO, cos_o: -1.0, sin_o: 0.0 };

    /// The bounds of a group of lights: the sphere about their spheres (centre at their bounds' middle,
    /// radius the farthest reach of a light's sphere from it, rounded up for f32), their summed power,
    /// and the cone of their normals, widened by 1e-4 rad for the f32 arithmetic.
    fn of(lights: &[LightBounds], group: &[u32]) -> Slot {
        let agg = group.iter().fold(Agg::EMPTY, |a, &i| a.add(Agg::of(&lights[i as usize])));
        // (The reach measured from the f32 centre that is stored.)
        let c = ((agg.lo + agg.hi) * 0.5).as_vec3().as_dvec3();
        let reach = group.iter().map(|&i| {
            let l = &lights[i as usize];
            (l.centre.as_dvec3() - c).length() + l.radius as f64
        });
        let r = reach.fold(0.0f64, f64::max);
        // (Padded past the f32 rounding of the lights' own centres: half an ulp per axis, sqrt(3) / 2 x
        // 2^-23 x |c|.)
        let r = r * (1.0 + 1e-6) + 2.5e-7 * c.abs().max_element();
        let cone = agg.cone.unwrap_or(ALL_DIRECTIONS);
        let (cos_o, sin_o) = if cone.cos <= -1.0 {
            (-1.0, 0.0)
        } else {
            let to = (cone.cos.clamp(-1.0, 1.0).acos() + 1e-4).min(std::f64::consts::PI);
            (to.cos() as f32, to.sin() as f32)
        };
        Slot { centre: c.as_vec3(), r: r as f32, phi: agg.phi as f32, w: cone.w.as_vec3(), cos_o, sin_o }
    }
}

/// The tree (see the module docs). Node 0 is the root.
pub struct LightTree {
    nodes: Vec<Node>,
    /// Per node: its parent and the slot it fills there (the root: `EMPTY`).
    parent: Vec<(u32, u8)>,
    /// Per light: the node and slot that hold it (`EMPTY` for lights of no power).
    leaf: Vec<(u32, u8)>,
}

/// A node's range of `w` grid values split among its children: child `k` gets the values from the end
/// of child `k - 1`'s (0 for the first) to lane `k` of the result, whose last lane is `w`. Each child of
/// positive importance gets one value, and the rest of the range is shared in proportion to the
/// importances; a child of no importance gets none. (Where the range has fewer values than children of
/// importance, at the bottom of a deep path of vanishing probabilities, the first ones get one each.)
/// `None` where no child has any importance. In f32 lanes, exact integers below 2^24: the running sums
/// are one tree of additions in every lane, zeros for the children past the lane's, so that they never
/// decrease from lane to lane (addition rounds monotonically), and neither do the ends.
#[inline(always)]
fn split(imp: f32x8, w: u32) -> Option<f32x8> {
    let zero = f32x8::ZERO;
    let pos = imp.simd_gt(zero);
    let (x, ones) = (pos.select(imp, zero).to_array(), pos.select(f32x8::ONE, zero).to_array());
    let lane = f32x8::from([0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]);
    // Lane k: the sum over children 0..=k.
    let running = |a: [f32; 8]| {
        let t = |j: usize| lane.simd_ge(f32x8::splat(j as f32)).select(f32x8::splat(a[j]), zero);
        ((t(0) + t(1)) + (t(2) + t(3))) + ((t(4) + t(5)) + (t(6) + t(7)))
    };
    let (prefix, count) = (running(x), running(ones));
    let (total, c) = (prefix.to_array()[7], count.to_array()[7]);
    if !(total > 0.0) {
        return None;
    }
    let wf = w as f32;
    let ends = if wf >= c {
        let spare = wf - c;
        // (The ratio in f64, clamped: a total below 2^24 / f32::MAX would make it infinite, and the
        // lanes before the first child of importance 0 x inf.)
        let scale = (spare as f64 / total as f64).min(f32::MAX as f64) as f32;
        let share = (prefix * f32x8::splat(scale) + f32x8::splat(0.5)).floor().min(f32x8::splat(spare));
        count + share
    } else {
        count.min(f32x8::splat(wf))
    };
    // (From the last child of importance on: the range's end, whatever the rounding.)
    Some(count.simd_eq(f32x8::splat(c)).select(f32x8::splat(wf), ends))
}

impl LightTree {
    /// The tree over `lights` (those of positive power).
    pub fn build(lights: &[LightBounds]) -> LightTree {
        let items: Vec<u32> = (0..lights.len() as u32).filter(|&i| lights[i as usize].phi > 0.0).collect();
        let mut tree = LightTree { nodes: Vec::new(), parent: Vec::new(), leaf: vec![(EMPTY, 0); lights.len()] };
        let mut left = vec![false; lights.len()];
        tree.node(lights, Group::new(lights, items), 0, (EMPTY, 0), &mut left);
        tree
    }

    /// Builds the node over `items` (its index returned).
    /// (`left`: scratch flags per light for [`split_group`], all false between calls.)
    fn node(&mut self, lights: &[LightBounds], items: Group, depth: usize, parent: (u32, u8), left: &mut [bool]) -> u32 {
        let me = self.nodes.len() as u32;
        let none = f32x8::ZERO;
        self.nodes.push(Node {
            cx: none,
            cy: none,
            cz: none,
            r: none,
            r2: none,
            inv_r2: none,
            phi: none,
            wx: none,
            wy: none,
            wz: none,
            cos_o: none,
            sin_o: none,
            child: [EMPTY; 8],
        });
        self.parent.push(parent);
        // Split the group of most lights until there are 8 groups or single lights.
        let mut groups = vec![items];
        while groups.len() < 8 {
            let Some((g, _)) = groups.iter().enumerate().filter(|(_, g)| g.len() > 1).max_by_key(|(i, g)| (g.len(), usize::MAX - i)) else {
                break;
            };
            let group = std::mem::take(&mut groups[g]);
            let (a, b) = split_group(lights, group, depth >= MAX_DEPTH / 2, left);
            groups[g] = a;
            groups.insert(g + 1, b);
        }
        let mut slot = [Slot::EMPTY; 8];
        let mut child = [EMPTY; 8];
        for (k, group) in groups.into_iter().enumerate() {
            if group.len() == 0 {
                continue;
            }
            slot[k] = Slot::of(lights, group.items());
            child[k] = if group.len() == 1 {
                let l = group.items()[0];
                self.leaf[l as usize] = (me, k as u8);
                LIGHT | l
            } else {
                self.node(lights, group, depth + 1, (me, k as u8), left)
            };
        }
        let lane = |f: &dyn Fn(&Slot) -> f32| f32x8::from(std::array::from_fn::<f32, 8, _>(|k| f(&slot[k])));
        self.nodes[me as usize] = Node {
            cx: lane(&|s| s.centre.x),
            cy: lane(&|s| s.centre.y),
            cz: lane(&|s| s.centre.z),
            r: lane(&|s| s.r),
            r2: lane(&|s| (s.r * s.r).max(D2_FLOOR)),
            inv_r2: lane(&|s| 1.0 / (s.r * s.r).max(D2_FLOOR)),
            phi: lane(&|s| s.phi),
            wx: lane(&|s| s.w.x),
            wy: lane(&|s| s.w.y),
            wz: lane(&|s| s.w.z),
            cos_o: lane(&|s| s.cos_o),
            sin_o: lane(&|s| s.sin_o),
            child,
        };
        me
    }

    /// Depth of the deepest light (the root's children: 1).
    pub fn depth(&self) -> usize {
        self.leaf.iter().filter(|l| l.0 != EMPTY).map(|&(n, _)| self.path(n).1).max().unwrap_or(0)
    }

    /// Nodes from `node` up to the root (the first entry `node`'s own parent link), and how many.
    fn path(&self, node: u32) -> ([(u32, u8); MAX_DEPTH], usize) {
        let mut path = [(0u32, 0u8); MAX_DEPTH];
        let (mut n, mut depth) = (node, 1);
        while self.parent[n as usize].0 != EMPTY {
            path[depth - 1] = self.parent[n as usize];
            n = self.parent[n as usize].0;
            depth += 1;
        }
        (path, depth)
    }

    /// The 8 children's importances at `p` (see the module docs), with the receiver's normal `n` for
    /// Lambert points.
    #[inline(always)]
    fn importance(&self, node: u32, p: Vec3, n: Option<Vec3>) -> f32x8 {
        let b = &self.nodes[node as usize];
        let (zero, one) = (f32x8::ZERO, f32x8::ONE);
        let floor = f32x8::splat(COS_FLOOR);
        // (The square roots depend on `l2` and the dot products only, so that they run side by side.)
        let v = Vec3x8::splat(p) - Vec3x8::new(b.cx, b.cy, b.cz);
        let l2 = v.dot_unfused(v);
        let inside = l2.simd_le(b.r2);
        let inv = one / l2.sqrt();
        let inv_d2 = (inv * inv).min(b.inv_r2);
        // The half-angle the sphere subtends.
        let sin_b = (b.r * inv).min(one);
        let cos_b = (l2 - b.r2).max(zero).sqrt() * inv;
        // The angle between the cone's axis and the direction to `p`, less the cone's half-angle.
        let wv = Vec3x8::new(b.wx, b.wy, b.wz).dot_unfused(v);
        let cos_w = (wv * inv).min(one).max(-one);
        let sin_w = (l2 - wv * wv).max(zero).sqrt() * inv;
        let in_cone = cos_w.simd_ge(b.cos_o);
        let cos_x = in_cone.select(one, cos_w * b.cos_o + sin_w * b.sin_o);
        let sin_x = in_cone.select(zero, (sin_w * b.cos_o - cos_w * b.sin_o).max(zero));
        // Less the sphere's half-angle.
        let cos_e = cos_x.simd_ge(cos_b).select(one, cos_x * cos_b + sin_x * sin_b);
        let e = cos_e.simd_lt(-floor).select(zero, cos_e.max(floor).min(one));
        let mut imp = b.phi * inside.select(one, e) * inv_d2;
        if let Some(n) = n {
            // The angle between the normal and the direction to the centre, less the sphere's.
            let nv = Vec3x8::splat(n).dot_unfused(v);
            let cos_i = (-nv * inv).min(one).max(-one);
            let sin_i = (l2 - nv * nv).max(zero).sqrt() * inv;
            let cos_r = cos_i.simd_ge(cos_b).select(one, cos_i * cos_b + sin_i * sin_b);
            let rcv = cos_r.simd_lt(-floor).select(zero, (cos_r + floor).min(one).max(f32x8::splat(1e-6)));
            imp *= inside.select(one, rcv);
        }
        imp
    }

    /// One step down from `node`, whose children have importances `imp`, for the grid value `at` of a
    /// range `w` wide: the child, `at` within its range, and the range's width; `None` where no child
    /// has any importance.
    #[inline(always)]
    fn step(&self, node: u32, imp: f32x8, at: u32, w: u32) -> Option<(u32, u32, u32)> {
        let ends = split(imp, w)?;
        // The child whose range holds `at`: the number of ends at or below it (`at < w`, the last).
        let k = ends.simd_le(f32x8::splat(at as f32)).to_bitmask().count_ones() as usize;
        let ends = ends.to_array();
        let start = if k == 0 { 0 } else { ends[k - 1] as u32 };
        Some((self.nodes[node as usize].child[k], at - start, ends[k] as u32 - start))
    }

    /// The light picked at `p` (normal `n` for Lambert points) by the number `u` in [0, 1) and the 24
    /// random bits `fine` (the zooms' numbers, low bits first), and its probability; `None` where no
    /// light can give `p` anything.
    pub fn pick(&self, p: Vec3, n: Option<Vec3>, u: f32, fine: u32) -> Option<(u32, f32)> {
        let mut out = [None; 8];
        let at = ((u * GRID as f32) as u32).min(GRID - 1);
        self.pick_x8(&[p; 8], n.map(|n| [n; 8]).as_ref(), &[at; 8], GRID, &[fine; 8], &mut out);
        out[0]
    }

    /// [`LightTree::pick`] for 8 points, level by level (the lanes' chains of dependent arithmetic
    /// overlap), with the numbers as grid values `at` in a root range of `root` values (the tree's share
    /// of the 2^24: [`LightPick`](super::pick::LightPick) keeps the rest for its uniform floor; lanes
    /// with `at >= root` pick nothing here). The probabilities are of the 2^24 values. Returns each
    /// lane's number of zooms.
    pub fn pick_x8(
        &self,
        p: &[Vec3; 8],
        n: Option<&[Vec3; 8]>,
        at: &[u32; 8],
        root: u32,
        fine: &[u32; 8],
        out: &mut [Option<(u32, f32)>; 8],
    ) -> [usize; 8] {
        *out = [None; 8];
        let mut zooms = [0usize; 8];
        if self.nodes.is_empty() {
            return zooms;
        }
        assert!(root <= GRID, "a root range within the 2^24 grid (exact f32 splits)");
        let mut at = *at;
        let (mut node, mut w) = ([0u32; 8], [root; 8]);
        let mut live = (0..8).filter(|&l| at[l] < root).fold(0u32, |m, l| m | 1 << l);
        let mut imp = [f32x8::ZERO; 8];
        // (Each phase a loop over the lanes, so that the lanes' chains of dependent arithmetic overlap.)
        let lanes = |mut left: u32| {
            std::iter::from_fn(move || {
                (left != 0).then(|| {
                    let l = left.trailing_zeros() as usize;
                    left &= left - 1;
                    l
                })
            })
        };
        for _ in 0..MAX_DEPTH {
            for l in lanes(live) {
                imp[l] = self.importance(node[l], p[l], n.map(|n| n[l]));
            }
            for l in lanes(live) {
                if w[l] < ZOOM_BELOW && zooms[l] < MAX_ZOOMS {
                    let f = (fine[l] >> (ZOOM_BITS as usize * zooms[l])) & (ZOOM_BELOW - 1);
                    (at[l], w[l]) = ((at[l] << ZOOM_BITS) | f, w[l] << ZOOM_BITS);
                    zooms[l] += 1;
                }
                match self.step(node[l], imp[l], at[l], w[l]) {
                    Some((c, _, width)) if c & LIGHT != 0 => {
                        out[l] = Some((c & !LIGHT, width as f32 * ZOOM_SCALE[zooms[l]]));
                        live &= !(1 << l);
                    }
                    Some((c, a, width)) => (node[l], at[l], w[l]) = (c, a, width),
                    None => live &= !(1 << l),
                }
            }
            if live == 0 {
                break;
            }
        }
        zooms
    }

    /// The probability that a point at `p` (normal `n` as given to [`LightTree::pick`]) picks `light`
    /// from a root range of `root` values (as [`LightTree::pick_x8`]): the pick's operations along the
    /// light's path, bit for bit.
    pub fn prob(&self, p: Vec3, n: Option<Vec3>, light: usize, root: u32) -> f32 {
        let Some(&(node, slot)) = self.leaf.get(light).filter(|l| l.0 != EMPTY) else {
            return 0.0;
        };
        let (path, depth) = self.path(node);
        // From the root down: path[depth - 2] .. path[0], then the light's own slot.
        assert!(root <= GRID, "a root range within the 2^24 grid (exact f32 splits)");
        let (mut w, mut zooms) = (root, 0);
        for i in (0..depth).rev() {
            let (at, k) = if i == 0 { (node, slot) } else { path[i - 1] };
            if w < ZOOM_BELOW && zooms < MAX_ZOOMS {
                (w, zooms) = (w << ZOOM_BITS, zooms + 1);
            }
            let Some(ends) = split(self.importance(at, p, n), w) else {
                return 0.0;
            };
            let ends = ends.to_array();
            let k = k as usize;
            w = ends[k] as u32 - if k == 0 { 0 } else { ends[k - 1] as u32 };
            if w == 0 {
                return 0.0;
            }
        }
        w as f32 * ZOOM_SCALE[zooms]
    }
}

/// A group of lights while building: its lights in order of centre along each axis (ties by index),
/// so that a split sweeps them without sorting, and the axis of the split that made it, whose order
/// its bounds are gathered in (the root's group, which no split made, is always split unless it holds
/// one light or none).
#[derive(Default)]
struct Group {
    by: [Vec<u32>; 3],
    last: usize,
}

impl Group {
    fn new(lights: &[LightBounds], items: Vec<u32>) -> Group {
        let order = |a: usize| {
            let mut v = items.clone();
            v.sort_by(|&x, &y| centre(lights, x, a).total_cmp(&centre(lights, y, a)).then(x.cmp(&y)));
            v
        };
        Group { by: [order(0), order(1), order(2)], last: 0 }
    }

    fn len(&self) -> usize {
        self.by[0].len()
    }

    /// The lights in the order of the split that made the group.
    fn items(&self) -> &[u32] {
        &self.by[self.last]
    }
}

fn centre(lights: &[LightBounds], i: u32, a: usize) -> f64 {
    lights[i as usize].centre[a] as f64
}

/// Splits `group` in two (see the module docs): at the heuristic's best position, or at the median
/// (`median`, or where no position is better than another). `left`: scratch flags per light, all false
/// between calls.
fn split_group(lights: &[LightBounds], group: Group, median: bool, left: &mut [bool]) -> (Group, Group) {
    let n = group.len();
    let mut best: Option<(f64, usize, usize)> = None;
    if !median {
        for axis in 0..3 {
            let items = &group.by[axis];
            let mut suffix = vec![Agg::EMPTY; n + 1];
            for i in (0..n).rev() {
                suffix[i] = suffix[i + 1].add(Agg::of(&lights[items[i] as usize]));
            }
            let mut prefix = Agg::EMPTY;
            for i in 1..n {
                prefix = prefix.add(Agg::of(&lights[items[i - 1] as usize]));
                let cost = prefix.cost() + suffix[i].cost();
                // Ties within rounding (such as lights that share one point) go to the most even split.
                let off = i.abs_diff(n / 2);
                let tie = |c: f64| (cost - c).abs() <= 1e-9 * c.abs().max(cost.abs());
                if best.is_none_or(|(c, _, at)| (cost < c && !tie(c)) || (tie(c) && off < at.abs_diff(n / 2))) {
                    best = Some((cost, axis, i));
                }
            }
        }
    }
    let (axis, at) = match best {
        Some((_, axis, at)) => (axis, at),
        None => {
            let ext = |a: usize| centre(lights, group.by[a][n - 1], a) - centre(lights, group.by[a][0], a);
            ((0..3).max_by(|&a, &b| ext(a).total_cmp(&ext(b))).unwrap_or(0), n / 2)
        }
    };
    // The first `at` along the axis go left; every order keeps its own (a stable partition).
    for &i in &group.by[axis][..at] {
        left[i as usize] = true;
    }
    let (mut a, mut b) = (Group { last: axis, ..Group::default() }, Group { last: axis, ..Group::default() });
    for k in 0..3 {
        (a.by[k], b.by[k]) = group.by[k].iter().partition(|&&i| left[i as usize]);
    }
    for &i in &group.by[axis][..at] {
        left[i as usize] = false;
    }
    (a, b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sample::random_f32_keyed;

    fn rnd(k: &mut u32) -> f32 {
        *k += 1;
        random_f32_keyed(0x7ee, *k)
    }

    fn unit(k: &mut u32) -> Vec3 {
        loop {
            let v = Vec3::new(rnd(k) * 2.0 - 1.0, rnd(k) * 2.0 - 1.0, rnd(k) * 2.0 - 1.0);
            if v.length_squared() > 0.01 && v.length_squared() <= 1.0 {
                return v.normalize();
            }
        }
    }

    /// `n` lights in a 10-unit box: one-sided (a third), points and spheres, powers over 4 decades, and
    /// every seventh of no power.
    fn lights(n: usize, k: &mut u32) -> Vec<LightBounds> {
        (0..n)
            .map(|i| {
                let centre = Vec3::new(rnd(k), rnd(k), rnd(k)) * 10.0 - 5.0;
                let (radius, normal) = match i % 3 {
                    0 => (0.05 + rnd(k), unit(k)),
                    1 => (0.0, Vec3::ZERO),
                    _ => (0.3 * rnd(k), Vec3::ZERO),
                };
                let phi = if i % 7 == 3 { 0.0 } else { 10f32.powf(-4.0 * rnd(k)) };
                LightBounds { centre, radius, normal, phi }
            })
            .collect()
    }

    #[test]
    fn split_gives_every_child_of_importance_its_share_and_no_other() {
        let mut k = 1;
        for case in 0..2000 {
            let imp: [f32; 8] = std::array::from_fn(|_| {
                let x = rnd(&mut k);
                if x < 0.3 {
                    0.0
                } else {
                    10f32.powf(12.0 * rnd(&mut k) - 6.0)
                }
            });
            let w = [1, 2, 3, 7, 100, GRID][case % 6];
            let Some(ends) = split(f32x8::from(imp), w) else {
                assert!(imp.iter().all(|&x| x <= 0.0), "{imp:?}");
                continue;
            };
            let total: f64 = imp.iter().filter(|&&x| x > 0.0).map(|&x| x as f64).sum();
            let positive = imp.iter().filter(|&&x| x > 0.0).count() as u32;
            let ends: [u32; 9] = std::array::from_fn(|k| if k == 0 { 0 } else { ends.to_array()[k - 1] as u32 });
            assert_eq!(ends[8], w);
            for c in 0..8 {
                let width = ends[c + 1] - ends[c];
                assert!(ends[c + 1] >= ends[c]);
                if imp[c] <= 0.0 {
                    assert_eq!(width, 0, "child {c} of no importance: {imp:?}");
                } else if w >= positive {
                    assert!(width >= 1, "child {c} lost its share: {imp:?} over {w}");
                }
                // One value, and its share of the rest (within the f32 rounding of both ends).
                if imp[c] > 0.0 && w >= positive {
                    let ideal = 1.0 + imp[c] as f64 / total * (w - positive) as f64;
                    let tol = 1.0 + 8.0 * f32::EPSILON as f64 * w as f64;
                    assert!((width as f64 - ideal).abs() <= tol, "child {c}: {width} against {ideal}");
                }
            }
        }
    }

    #[test]
    fn cone_union_holds_both_cones() {
        let mut k = 5;
        for _ in 0..5000 {
            let a = Cone { w: unit(&mut k).as_dvec3(), cos: (rnd(&mut k) * 2.0 - 1.0) as f64 };
            let b = Cone { w: unit(&mut k).as_dvec3(), cos: if rnd(&mut k) < 0.3 { 1.0 } else { (rnd(&mut k) * 2.0 - 1.0) as f64 } };
            let u = Cone::union(a, b);
            for c in [a, b] {
                // Every direction of c lies within u: the angle between axes plus c's half-angle.
                let reach = u.w.angle_between(c.w) + c.cos.acos();
                assert!(u.cos <= -1.0 || reach <= u.cos.acos() + 1e-9, "{c:?} outside {u:?} of {a:?}, {b:?}");
            }
            assert!(u.measure() >= a.measure().max(b.measure()) - 1e-9);
        }
    }

    /// At random points (with and without receiver normals) the probabilities of all lights sum to at
    /// most 1 (exactly 1 where no node's range is lost), lights of no power have 0, and each pick reports its light's probability bit for bit.
    #[test]
    fn probabilities_sum_to_one_and_picks_report_them() {
        let mut k = 11;
        for n in [2, 9, 64, 700] {
            let ls = lights(n, &mut k);
            let tree = LightTree::build(&ls);
            assert!(tree.depth() <= 2 + (n as f64).log2().ceil() as usize, "{n} lights: depth {}", tree.depth());
            for _ in 0..40 {
                let p = Vec3::new(rnd(&mut k), rnd(&mut k), rnd(&mut k)) * 14.0 - 7.0;
                for normal in [None, Some(unit(&mut k))] {
                    // (Below 1 where a node's bound has importance and all its children's none.)
                    let sum: f64 = (0..n).map(|l| tree.prob(p, normal, l, GRID) as f64).sum();
                    assert!(sum <= 1.0, "{n} lights at {p}: {sum}");
                    if normal.is_none() {
                        // Omni-directional lights (a third) face every point.
                        assert!(sum > 0.0);
                    }
                    for l in (0..n).filter(|l| ls[*l].phi == 0.0) {
                        assert_eq!(tree.prob(p, normal, l, GRID), 0.0);
                    }
                    for _ in 0..16 {
                        let u = rnd(&mut k);
                        if let Some((light, prob)) = tree.pick(p, normal, u, 0) {
                            assert_eq!(prob.to_bits(), tree.prob(p, normal, light as usize, GRID).to_bits());
                            assert!(prob > 0.0 && ls[light as usize].phi > 0.0);
                        }
                        // (The numbers that pick nothing are counted in the next test.)
                    }
                }
            }
        }
    }

    /// In a tree of 600 lights (inner nodes 3 deep), a light of probability 0 at a point gives it
    /// nothing: no point of its disk (one-sided lights, the disk of their bounding radius: more than a
    /// quad) or sphere both faces the point and lies above its horizon. Loose group bounds pass this;
    /// a group sphere or cone too small does not.
    #[test]
    fn a_light_of_probability_zero_gives_the_point_nothing() {
        let mut k = 31;
        let ls = lights(600, &mut k);
        let tree = LightTree::build(&ls);
        assert!(tree.depth() >= 4, "depth {}", tree.depth());
        let mut zeros = 0;
        for _ in 0..60 {
            let p = Vec3::new(rnd(&mut k), rnd(&mut k), rnd(&mut k)) * 12.0 - 6.0;
            let n = unit(&mut k);
            for (li, l) in ls.iter().enumerate() {
                if l.phi == 0.0 || tree.prob(p, Some(n), li, GRID) > 0.0 {
                    continue;
                }
                zeros += 1;
                let (t, b) = crate::optics::onb(if l.normal == Vec3::ZERO { Vec3::Z } else { l.normal });
                for s in 0..64 {
                    let (a, c) = (((s % 8) as f32 + 0.5) / 8.0, ((s / 8) as f32 + 0.5) / 8.0);
                    let phi = c * std::f32::consts::TAU;
                    let (y, emits) = if l.normal != Vec3::ZERO {
                        let y = l.centre + (t * phi.cos() + b * phi.sin()) * (l.radius * a.sqrt());
                        (y, l.normal.dot(p - y) > 0.0)
                    } else {
                        let z = 2.0 * a - 1.0;
                        let m = (t * phi.cos() + b * phi.sin()) * (1.0 - z * z).sqrt() + Vec3::Z * z;
                        let y = l.centre + m * l.radius;
                        (y, l.radius == 0.0 || m.dot(p - y) > 0.0)
                    };
                    assert!(
                        !(emits && n.dot(y - p) > 1e-4 * (y - p).length()),
                        "light {li} ({l:?}) reaches {p} (normal {n}) at {y} but has probability 0"
                    );
                }
            }
        }
        assert!(zeros > 1000, "the points and normals leave lights out ({zeros})");
    }

    /// The picks at `p` (normal `n`) over all 2^24 numbers `u` and, where a pick zooms, all the zooms'
    /// random bits, counted per light (and for no light) in units of 2^-48: a pick with no zoom counts
    /// 2^24 units, one zoom 2^12, two 1. Also the numbers `u` that zoomed, and the first zooms' numbers
    /// that zoomed again.
    fn realized(tree: &LightTree, lights: usize, p: Vec3, n: Option<Vec3>, root: u32) -> (Vec<u64>, u64, usize, usize) {
        let (n8, ps) = (n.map(|n| [n; 8]), [p; 8]);
        let mut hits = vec![0u64; lights];
        let mut none = 0u64;
        let mut credit = |o: Option<(u32, f32)>, units: u64| match o {
            Some((light, _)) => hits[light as usize] += units,
            None => none += units,
        };
        let (mut zoomed, mut twice) = (0, 0);
        let (mut out, mut o1, mut o2) = ([None; 8], [None; 8], [None; 8]);
        for i in (0..GRID).step_by(8) {
            let u: [u32; 8] = std::array::from_fn(|l| i + l as u32);
            let z = tree.pick_x8(&ps, n8.as_ref(), &u, root, &[0; 8], &mut out);
            for l in 0..8 {
                if z[l] == 0 {
                    credit(out[l], 1 << 24);
                    continue;
                }
                zoomed += 1;
                for f in (0..ZOOM_BELOW).step_by(8) {
                    let fine: [u32; 8] = std::array::from_fn(|j| f + j as u32);
                    let z1 = tree.pick_x8(&ps, n8.as_ref(), &[u[l]; 8], root, &fine, &mut o1);
                    for j in 0..8 {
                        if z1[j] == 1 {
                            credit(o1[j], 1 << 12);
                            continue;
                        }
                        twice += 1;
                        for g in (0..ZOOM_BELOW).step_by(8) {
                            let fine2 = std::array::from_fn(|q| fine[j] | ((g + q as u32) << ZOOM_BITS));
                            tree.pick_x8(&ps, n8.as_ref(), &[u[l]; 8], root, &fine2, &mut o2);
                            for o in o2 {
                                credit(o, 1);
                            }
                        }
                    }
                }
            }
        }
        (hits, none, zoomed, twice)
    }

    /// Each light's realized share of the picks ([`realized`]) is its reported probability, and the
    /// picks of nothing are the rest. Returns the numbers that zoomed, once and twice.
    fn realized_is_reported(tree: &LightTree, lights: usize, p: Vec3, n: Option<Vec3>, root: u32) -> (Vec<u64>, usize, usize) {
        let (hits, none, zoomed, twice) = realized(tree, lights, p, n, root);
        const UNITS: f64 = (1u64 << 48) as f64;
        let mut sum = 0.0;
        for (l, &h) in hits.iter().enumerate() {
            assert_eq!(h as f64 / UNITS, tree.prob(p, n, l, root) as f64, "light {l} at {p}");
            sum += h as f64 / UNITS;
        }
        assert_eq!(none as f64 / UNITS, 1.0 - sum);
        (hits, zoomed, twice)
    }

    #[test]
    fn realized_probabilities_are_the_reported_ones() {
        let mut k = 21;
        let ls = lights(40, &mut k);
        let tree = LightTree::build(&ls);
        // (The second with the root range `LightPick` gives the tree beside its uniform floor.)
        let cases = [(Vec3::new(0.5, -1.0, 2.0), Some(Vec3::new(0.0, 0.6, 0.8)), GRID), (Vec3::new(7.0, 1.0, -6.0), None, GRID - 838_861)];
        for (p, n, root) in cases {
            let (hits, _, _) = realized_is_reported(&tree, ls.len(), p, n, root);
            assert!(hits.iter().filter(|&&h| h > 0).count() > 10, "{hits:?}");
        }
    }

    /// Clusters of very dim lights beside bright ones: a cluster's range is a few values, fewer than its
    /// groups, and without zooms some of its lights would have probability 0 while lighting the
    /// point (the bias of running out). With them every light keeps a chance, and the realized shares
    /// of all numbers and zoom bits are still the reported probabilities.
    #[test]
    fn zooms_keep_every_dim_light_and_report_their_probabilities() {
        let mut k = 5;
        let mut ls: Vec<LightBounds> = (0..8)
            .map(|_| LightBounds {
                centre: Vec3::new(rnd(&mut k), rnd(&mut k), rnd(&mut k)) * 4.0,
                radius: 0.1,
                normal: Vec3::ZERO,
                phi: 1.0,
            })
            .collect();
        // 30 omni lamps of 1e-7 around (20, 0, 0), and 12 of 1e-14 close together beside them.
        for i in 0..42 {
            let (at, size, phi) = if i < 30 { (Vec3::new(20.0, 0.0, 0.0), 2.0, 1e-7) } else { (Vec3::new(20.0, 4.0, 0.0), 0.2, 1e-14) };
            let centre = at + Vec3::new(rnd(&mut k), rnd(&mut k), rnd(&mut k)) * size;
            ls.push(LightBounds { centre, radius: 0.0, normal: Vec3::ZERO, phi });
        }
        let tree = LightTree::build(&ls);
        let (p, n) = (Vec3::new(10.0, 0.0, 0.0), None);
        let (hits, zoomed, twice) = realized_is_reported(&tree, ls.len(), p, n, GRID);
        assert!(hits.iter().all(|&h| h > 0), "every light lights the point and keeps a chance: {hits:?}");
        assert!(zoomed > 0 && twice > 0, "the case zooms twice ({zoomed}, {twice})");
    }

    #[test]
    fn coincident_and_collinear_lights_build_shallow_trees() {
        let same: Vec<LightBounds> =
            (0..3000).map(|_| LightBounds { centre: Vec3::ONE, radius: 0.0, normal: Vec3::ZERO, phi: 1.0 }).collect();
        let row: Vec<LightBounds> =
            (0..3000).map(|i| LightBounds { centre: Vec3::new(i as f32, 0.0, 0.0), radius: 0.0, normal: Vec3::ZERO, phi: 1.0 }).collect();
        for ls in [same, row] {
            let tree = LightTree::build(&ls);
            assert!(tree.depth() <= 6, "depth {}", tree.depth());
            let p = Vec3::new(3.0, 2.0, 1.0);
            let sum: f64 = (0..ls.len()).map(|l| tree.prob(p, None, l, GRID) as f64).sum();
            assert_eq!(sum, 1.0, "lights that emit all round");
        }
    }
}
