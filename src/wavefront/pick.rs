//! Light selection (the profile's `light_selection`). With `all` (the default) every shading point samples
//! every light, and the shadow stage's cost grows with the number of lights. The other modes pick one
//! light per shading point with probability `P(l)` and divide its contribution by `P(l)`: unbiased, one
//! light's `light_samples` per point whatever the number of lights, and more noise where a point's light
//! comes from several lights.
//!
//! - `uniform`: `P(l) = 1 / L`.
//! - `power`: `P(l)` proportional to the light's emitted power `Phi` (mean over channels), mixed with
//!   5% uniform over the lights that emit ([`POWER_FLOOR`]).
//! - `local`: proportional to `Phi / max(d^2, r^2)` at the shading point, with `d` the distance to the
//!   light's centre and `r` its bounding radius, times bounds of the light's cosine (one-sided lights)
//!   and of a Lambert point's own ([`LightPick::pick_x8`]), and 0 where the point lies behind a
//!   one-sided (quad or disk) light or the light's bounding sphere below its horizon: where it gives
//!   the point nothing. A point weighs every light: O(L) arithmetic per point (8 points
//!   per vector), no traversal.
//! - `tree`: down a tree of the lights with bounds of `local`'s importance per node (`light_tree.rs`):
//!   O(log L) per point.
//!
//! `local` and `tree` spread [`POWER_FLOOR`] of their picks evenly over the lights that emit, as
//! `power` does (defensive sampling): their importances know no visibility, and where a bright light
//! is blocked the dim ones it outshines still get at least `POWER_FLOOR / L` (`FLOOR_VALUES`).
//!
//! The pick's random number is one more dimension (`dims::LIGHT_PICK`), stratified across a pixel's
//! camera samples (index = camera sample) like the light samples: with 16 spp and 4 equal lights
//! `power` gives each light 4 of a pixel's 16 picks (`local` and `tree` stratify all but the floor's
//! picks, which take a second, random number: `dims::LIGHT_PICK_FINE`). Glossy points' MIS weights
//! count the light strategy's density as `P(l)` x `light_samples` x the light's own density
//! ([`LightPick::prob`] in the shade stage).

use super::light_tree::{LightBounds, LightTree, GRID};
use crate::sample::Strategy;
use crate::scene::{Light, LightSelection, Profile, Scene};
use crate::simd::{f32x8, Vec3x8, LANES};
use glam::Vec3;
use std::sync::Arc;

/// A lane's pick when no light can give its point anything (every importance 0).
pub const NO_LIGHT: u32 = u32::MAX;

/// The share of `power` picks spread evenly over the lights that emit (see [`LightPick::new`]).
pub const POWER_FLOOR: f64 = 0.05;

/// `local` and `tree`: the pick's grid values (of the 2^24) that go to a uniform pick over the lights
/// that emit, [`POWER_FLOOR`] of them (as `power`'s floor), so that no light that emits has a
/// probability below `POWER_FLOOR / L`, whatever the bounds say: a sun 1e12 times as bright as the
/// lamps of a roofed floor left the lamps about 4e-7 each (the floor black at any affordable spp), and
/// the importances know no visibility.
const FLOOR_VALUES: u32 = (POWER_FLOOR * GRID as f64 + 0.5) as u32;

/// Smallest squared distance in `local` and `tree` importances (keeps them finite: at most 1e30 per
/// light).
pub(super) const D2_FLOOR: f32 = 1e-30;

/// Smallest cosine factor of a point in front of a one-sided light, and the tolerance of the receiver's
/// horizon test (`local`; `tree`'s emitter and receiver bounds alike): a light that may give a point
/// something keeps a chance.
pub(super) const COS_FLOOR: f32 = 1e-3;

/// The selection of one scene and mode (O(L) to make: made once per render, [`LightPick::cached`]).
pub struct LightPick {
    mode: LightSelection,
    /// Per light: its power, scaled so that the largest is 1 (`uniform`: all 1).
    phi: Vec<f32>,
    /// Per light (`local`): bounding-sphere centre, squared radius (at least [`D2_FLOOR`]), and the
    /// emitting side's normal (zero: emits all round) with a tolerance on the side test.
    centre: Vec<Vec3>,
    radius: Vec<f32>,
    r2: Vec<f32>,
    normal: Vec<Vec3>,
    one_sided: Vec<bool>,
    side_tol: Vec<f32>,
    /// Per light its probability, and the running sum (the last exactly 1): the picks of `uniform` and
    /// `power`, and the uniform floor of `local` and `tree` (uniform over the lights that emit).
    prob: Vec<f32>,
    cdf: Vec<f32>,
    /// `local` and `tree`: the grid values of the floor ([`FLOOR_VALUES`]), and per light its
    /// probability by the floor (`prob` x the floor's share).
    floor: u32,
    floor_prob: Vec<f32>,
    /// `tree`: the lights' tree.
    tree: Option<LightTree>,
}

/// Mean radiant power over the channels (W), from the light's geometry.
fn power(light: &Light) -> f64 {
    use std::f64::consts::PI;
    let mean = |c: Vec3| (c.x as f64 + c.y as f64 + c.z as f64) / 3.0;
    match *light {
        Light::Point { intensity, .. } => 4.0 * PI * mean(intensity),
        Light::Quad { quad, radiance } => PI * quad.area() as f64 * mean(radiance),
        Light::Disk { disk, radiance } => PI * PI * (disk.radius as f64).powi(2) * mean(radiance),
        Light::Sphere { radius, radiance, .. } => PI * 4.0 * PI * (radius as f64).powi(2) * mean(radiance),
    }
}

/// Bounding-sphere centre and radius, and the emitting side's unit normal (zero if it emits all round).
fn bounds(light: &Light) -> (Vec3, f32, Vec3) {
    match *light {
        Light::Point { position, .. } => (position, 0.0, Vec3::ZERO),
        Light::Quad { quad, .. } => {
            let c = quad.origin + (quad.u + quad.v) * 0.5;
            let r = 0.5 * (quad.u + quad.v).length().max((quad.u - quad.v).length());
            (c, r, quad.normal())
        }
        Light::Disk { disk, .. } => (disk.center, disk.radius, disk.normal),
        Light::Sphere { center, radius, .. } => (center, radius, Vec3::ZERO),
    }
}

/// The scene (address, file hash, number of lights) and mode a cached selection was made for.
type CacheKey = (usize, u64, usize, LightSelection);

thread_local! {
    /// The thread's selection and what it was made for: the stages ask once per wavefront. A render
    /// makes it once, before its clock, and installs it in each of its workers
    /// ([`LightPick::install`]); a thread that calls the stages itself makes its own on first use.
    static CACHE: std::cell::RefCell<Option<(CacheKey, Option<Arc<LightPick>>)>> = const { std::cell::RefCell::new(None) };
}

impl LightPick {
    fn key(scene: &Scene, profile: &Profile) -> CacheKey {
        (scene as *const Scene as usize, scene.hash, scene.lights.len(), profile.light_selection)
    }

    /// The thread's selection for `scene` and `profile` ([`LightPick::new`]; `None` for `all`): the
    /// installed one, or made on first use and kept while the scene and mode stay the same. (The key is
    /// the scene's address, file hash and number of lights: a thread that renders a scene, edits its
    /// lights in place and renders again must not call the stages itself; the renderer's workers are
    /// new threads per render, each given the selection made for that render.)
    pub fn cached(scene: &Scene, profile: &Profile) -> Option<Arc<LightPick>> {
        if profile.light_selection == LightSelection::All {
            return None;
        }
        let key = Self::key(scene, profile);
        CACHE.with_borrow_mut(|c| match c {
            Some((k, pick)) if *k == key => pick.clone(),
            _ => {
                let pick = LightPick::new(scene, profile).map(Arc::new);
                *c = Some((key, pick.clone()));
                pick
            }
        })
    }

    /// Make `pick` (made by [`LightPick::new`] for `scene` and `profile`) this thread's selection for
    /// them: a render makes one and shares it among its workers.
    pub fn install(scene: &Scene, profile: &Profile, pick: Option<Arc<LightPick>>) {
        CACHE.set(Some((Self::key(scene, profile), pick)));
    }

    /// The profile's selection for this scene; `None` when every light is sampled at every point (`all`,
    /// or a scene of at most one light, where a pick would change nothing but the cost).
    pub fn new(scene: &Scene, profile: &Profile) -> Option<LightPick> {
        let mode = profile.light_selection;
        if mode == LightSelection::All || scene.lights.len() <= 1 {
            return None;
        }
        // (A light of no power gives nothing: never picked, in `uniform` too.)
        let raw: Vec<f64> = scene
            .lights
            .iter()
            .map(|l| match power(l) {
                p if p > 0.0 && mode == LightSelection::Uniform => 1.0,
                p => p.max(0.0),
            })
            .collect();
        let top = raw.iter().cloned().fold(0.0f64, f64::max);
        let phi: Vec<f32> = raw.iter().map(|&p| if top > 0.0 { (p / top) as f32 } else { 0.0 }).collect();
        let (mut centre, mut radius, mut r2, mut normal, mut one_sided, mut side_tol) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for light in &scene.lights {
            let (c, r, n) = bounds(light);
            centre.push(c);
            radius.push(r);
            r2.push((r * r).max(D2_FLOOR));
            normal.push(n);
            one_sided.push(n != Vec3::ZERO);
            // Conservative: a point on the far side within 1e-4 of the light's size (plus 1e-6 of its
            // distance from the origin: the rounding of its plane) keeps its chance.
            side_tol.push(1e-4 * r + 1e-6 * c.abs().max_element());
        }
        // `power`: a share POWER_FLOOR of the picks spread evenly over the lights that emit, so that no
        // light that gives anything has a probability below POWER_FLOOR / L (a sun 1e13 times a lamp's
        // power left the lamps no slot in the table: never picked, 22% of a room's light lost).
        let emitting = phi.iter().filter(|&&p| p > 0.0).count();
        let total: f64 = phi.iter().map(|&p| p as f64).sum();
        let share = |p: f32| -> f64 {
            match mode {
                _ if p <= 0.0 || total <= 0.0 => 0.0,
                LightSelection::Power => (1.0 - POWER_FLOOR) * p as f64 / total + POWER_FLOOR / emitting as f64,
                LightSelection::Local | LightSelection::Tree => 1.0 / emitting as f64,
                _ => p as f64 / total,
            }
        };
        // The table on the grid of the pick's numbers (multiples of 2^-24, the resolution of a number in
        // [0, 1) from the samplers): each light's probability is then exactly the chance that a number
        // lands in its slot, the last slot with any width ends at 1, and a light whose slot rounds to no
        // width (below 2^-24: more than about 800,000 lights) has probability 0, consistently.
        const GRID_F: f64 = GRID as f64;
        let mut cdf = Vec::with_capacity(phi.len());
        let mut run = 0.0f64;
        for &p in &phi {
            run += share(p);
            cdf.push(((run * GRID_F).round().min(GRID_F) / GRID_F) as f32);
        }
        if let Some(last) = phi.iter().rposition(|&p| p > 0.0) {
            cdf[last..].fill(1.0);
        }
        let prob: Vec<f32> = (0..cdf.len()).map(|i| if i == 0 { cdf[0] } else { cdf[i] - cdf[i - 1] }).collect();
        let tree = (mode == LightSelection::Tree).then(|| {
            let bounds: Vec<LightBounds> =
                (0..phi.len()).map(|i| LightBounds { centre: centre[i], radius: radius[i], normal: normal[i], phi: phi[i] }).collect();
            LightTree::build(&bounds)
        });
        let floor = if matches!(mode, LightSelection::Local | LightSelection::Tree) { FLOOR_VALUES } else { 0 };
        let floor_prob = prob.iter().map(|&p| p * (floor as f32 / GRID as f32)).collect();
        Some(LightPick { mode, phi, centre, radius, r2, normal, one_sided, side_tol, prob, cdf, floor, floor_prob, tree })
    }

    /// Number of lights.
    pub fn lights(&self) -> usize {
        self.phi.len()
    }

    /// The strategy of the pick's random number: the light samples' own where they are random or Sobol,
    /// else jittered (a grid or a centre would pick the same light at every point of a pixel: bias).
    pub fn strategy(profile: &Profile) -> Strategy {
        match profile.light_strategy {
            Strategy::Random => Strategy::Random,
            Strategy::Sobol => Strategy::Sobol,
            _ => Strategy::Jittered,
        }
    }

    /// `local`: light `li`'s importance at `p` (see [`LightPick::pick_x8`]; without a receiver normal).
    #[inline(always)]
    fn importance(&self, li: usize, p: Vec3) -> f32 {
        let v = p - self.centre[li];
        let d2 = v.dot(v).max(self.r2[li]);
        let (dn, r) = (self.normal[li].dot(v), self.radius[li]);
        if self.one_sided[li] {
            let cos = (dn / d2.sqrt() + r / d2.sqrt()).clamp(COS_FLOOR, 1.0);
            if dn > -self.side_tol[li] {
                self.phi[li] * cos / d2
            } else {
                0.0
            }
        } else {
            self.phi[li] / d2
        }
    }

    /// The probability that a point at `p` picks light `li` (the MIS weights of glossy lobe rays that
    /// find a light need it). The same operations as [`LightPick::pick_x8`]: bit for bit its lanes'.
    pub fn prob(&self, p: Vec3, li: usize) -> f32 {
        match self.mode {
            LightSelection::Local => {
                let mut total = 0.0f32;
                for l in 0..self.phi.len() {
                    total += self.importance(l, p);
                }
                self.local_prob(li, self.importance(li, p), total)
            }
            LightSelection::Tree => self.tree_prob(p, None, li).unwrap_or(0.0),
            _ => self.prob[li],
        }
    }

    /// `local`: the probability of light `li`, of importance `i` among importances summing to `total`
    /// at the point, floor included (the one expression of [`LightPick::prob`] and the lanes).
    #[inline(always)]
    fn local_prob(&self, li: usize, i: f32, total: f32) -> f32 {
        if total > 0.0 {
            self.floor_prob[li] + self.beside_floor() * (i / total)
        } else {
            self.floor_prob[li]
        }
    }

    /// `local` and `tree`: the share of the picks that are not the floor's.
    #[inline(always)]
    fn beside_floor(&self) -> f32 {
        (GRID - self.floor) as f32 / GRID as f32
    }

    /// `tree`: the probability that a point at `p` with receiver normal `n` (Lambert points; `None`:
    /// glossy points, as [`LightPick::prob`]) picks light `li`, the floor's share and the tree's.
    pub fn tree_prob(&self, p: Vec3, n: Option<Vec3>, li: usize) -> Option<f32> {
        self.tree_share(p, n, li).map(|t| self.floor_prob[li] + t)
    }

    /// `tree`: the tree's share of [`LightPick::tree_prob`] (0 where the tree never picks `li` at `p`).
    pub fn tree_share(&self, p: Vec3, n: Option<Vec3>, li: usize) -> Option<f32> {
        self.tree.as_ref().map(|t| t.prob(p, n, li, GRID - self.floor))
    }

    /// The light of a floor pick by the random bits `fine` (their low 24): uniform over the lights that
    /// emit, by `cdf`.
    #[inline(always)]
    fn floor_pick(&self, fine: u32) -> Option<u32> {
        let u = (fine & (GRID - 1)) as f32 / GRID as f32;
        let i = self.cdf.partition_point(|&c| c <= u).min(self.cdf.len() - 1);
        (self.prob[i] > 0.0).then_some(i as u32)
    }

    /// Picks for 8 points `p` with uniform numbers `u` in [0, 1) (and 24 random bits `fine` per lane:
    /// the floor's pick of `local` and `tree` where `u` falls in the floor, else `tree`'s zooms): per
    /// lane the light (or [`NO_LIGHT`])
    /// and its probability. `scratch` holds the lanes' importances (`local`). With the points' normals
    /// `n` (Lambert points), a `local` importance also has the receiver's cosine bound towards the
    /// light's bounding sphere, 0 when the sphere lies below the point's horizon; without (glossy points,
    /// whose lobe rays' MIS weights need the probability again, from [`LightPick::prob`]), it has none.
    ///
    /// `local` importance of light `l` at `p`: `Phi / max(d^2, r^2)`, x for a one-sided light (quad,
    /// disk) with normal `m` the bound `min(1, (m.(p - c) + r) / d)` of its cosine (at least
    /// [`COS_FLOOR`]), or 0 when `p` lies behind its plane; x the receiver's `min(1, (n.(c - p) + r) / d)`
    /// where it is given (0 when negative).
    pub fn pick_x8(
        &self,
        p: Vec3x8,
        n: Option<Vec3x8>,
        u: f32x8,
        fine: [u32; LANES],
        scratch: &mut Vec<f32x8>,
    ) -> ([u32; LANES], [f32; LANES]) {
        let mut light = [NO_LIGHT; LANES];
        let mut prob = [0.0f32; LANES];
        // `local` and `tree`: the grid values below `floor` pick uniformly (with `fine`); the others,
        // less `floor`, are the tree's root range (or `local`'s numbers, scaled to [0, 1)).
        let at = u.to_array().map(|u| ((u * GRID as f32) as u32).min(GRID - 1));
        let floored = (0..LANES).filter(|&l| at[l] < self.floor).fold(0u32, |m, l| m | 1 << l);
        if let Some(tree) = &self.tree {
            let ps: [Vec3; LANES] = std::array::from_fn(|l| p.lane(l));
            let ns: Option<[Vec3; LANES]> = n.map(|n| std::array::from_fn(|l| n.lane(l)));
            let mut out = [None; LANES];
            let root = GRID - self.floor;
            tree.pick_x8(&ps, ns.as_ref(), &at.map(|a| a.wrapping_sub(self.floor)), root, &fine, &mut out);
            for l in 0..LANES {
                let picked = if floored & (1 << l) != 0 {
                    self.floor_pick(fine[l]).map(|li| (li, tree.prob(ps[l], ns.map(|n| n[l]), li as usize, root)))
                } else {
                    out[l]
                };
                if let Some((li, share)) = picked {
                    (light[l], prob[l]) = (li, self.floor_prob[li as usize] + share);
                }
            }
            return (light, prob);
        }
        if self.mode != LightSelection::Local {
            let u = u.to_array();
            for l in 0..LANES {
                let i = self.cdf.partition_point(|&c| c <= u[l]).min(self.cdf.len() - 1);
                if self.prob[i] > 0.0 {
                    (light[l], prob[l]) = (i as u32, self.prob[i]);
                }
            }
            return (light, prob);
        }
        scratch.clear();
        let (zero, one) = (f32x8::ZERO, f32x8::ONE);
        let mut total = zero;
        match n {
            // Glossy points: the operations of the scalar `importance`, bit for bit.
            None => {
                for li in 0..self.phi.len() {
                    let v = p - Vec3x8::splat(self.centre[li]);
                    let d2 = v.dot_unfused(v).max(f32x8::splat(self.r2[li]));
                    let i = if self.one_sided[li] {
                        let r = f32x8::splat(self.radius[li]);
                        let dn = Vec3x8::splat(self.normal[li]).dot_unfused(v);
                        let d = d2.sqrt();
                        let cos = (dn / d + r / d).min(one).max(f32x8::splat(COS_FLOOR));
                        dn.simd_gt(f32x8::splat(-self.side_tol[li])).select(f32x8::splat(self.phi[li]) * cos / d2, zero)
                    } else {
                        f32x8::splat(self.phi[li]) / d2
                    };
                    scratch.push(i);
                    total += i;
                }
            }
            // Lambert points: one division for the light's 1 / d. (Not the hardware's estimate of
            // 1 / sqrt, 15% faster here: its bits differ between CPU vendors, and films rendered on
            // several machines must merge into the one image.)
            Some(n) => {
                for li in 0..self.phi.len() {
                    let v = p - Vec3x8::splat(self.centre[li]);
                    let d2 = v.dot_unfused(v).max(f32x8::splat(self.r2[li]));
                    let d = d2.sqrt();
                    let inv_d = one / d;
                    let r = f32x8::splat(self.radius[li]);
                    // Towards the light: -v. Below the horizon by more than COS_FLOOR x d: 0.
                    let up = r - n.dot_unfused(v);
                    let mut c = up
                        .simd_gt(f32x8::splat(-COS_FLOOR) * d)
                        .select((up * inv_d + f32x8::splat(COS_FLOOR)).min(one).max(f32x8::splat(1e-6)), zero);
                    if self.one_sided[li] {
                        let dn = Vec3x8::splat(self.normal[li]).dot_unfused(v);
                        let cos = ((dn + r) * inv_d).min(one).max(f32x8::splat(COS_FLOOR));
                        c = dn.simd_gt(f32x8::splat(-self.side_tol[li])).select(c * cos, zero);
                    }
                    let i = f32x8::splat(self.phi[li]) * c * (inv_d * inv_d);
                    scratch.push(i);
                    total += i;
                }
            }
        }
        // The first light whose running sum passes u x total (u: the number past the floor, scaled to
        // [0, 1)); past the end by rounding, the last light with any importance.
        let beside = (GRID - self.floor) as f32;
        let u = f32x8::from(at.map(|a| a.saturating_sub(self.floor) as f32 / beside));
        let target = u * total;
        let mut run = zero;
        let (mut sel, mut last) = (f32x8::splat(-1.0), f32x8::splat(-1.0));
        let (mut sel_imp, mut last_imp) = (zero, zero);
        let mut found = zero.simd_gt(zero);
        for (li, &imp) in scratch.iter().enumerate() {
            if found.all() {
                break;
            }
            run += imp;
            let k = f32x8::splat(li as f32);
            let pos = imp.simd_gt(zero);
            let now = run.simd_gt(target) & pos & !found;
            sel = now.select(k, sel);
            sel_imp = now.select(imp, sel_imp);
            found |= now;
            last = pos.select(k, last);
            last_imp = pos.select(imp, last_imp);
        }
        let sel = found.select(sel, last).to_array();
        let sel_imp = found.select(sel_imp, last_imp).to_array();
        let totals = total.to_array();
        for l in 0..LANES {
            // (The same operations as `prob`.)
            if floored & (1 << l) != 0 {
                if let Some(li) = self.floor_pick(fine[l]) {
                    (light[l], prob[l]) = (li, self.local_prob(li as usize, scratch[li as usize].to_array()[l], totals[l]));
                }
            } else if sel[l] >= 0.0 && totals[l] > 0.0 {
                let li = sel[l] as usize;
                (light[l], prob[l]) = (li as u32, self.local_prob(li, sel_imp[l], totals[l]));
            }
        }
        (light, prob)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sample::random_f32_keyed;
    use crate::scene::parse_scene;
    use std::path::Path;

    /// Lights of every kind, strengths and sizes: quads (one facing up), disks, points, spheres, and
    /// one quad of zero radiance.
    fn lights_scene() -> Scene {
        let text = r#"
[image]
width = 8
height = 8
[camera]
position = [0, 2, 9]
look_at = [0, 0, 0]
fov = 40
[materials.m]
type = "lambert"
albedo = [0.5, 0.5, 0.5]
[[shapes]]
type = "sphere"
center = [0, 0, 0]
radius = 1
material = "m"
[[lights]]
type = "quad"
origin = [-2, 3, -1]
u = [1, 0, 0]
v = [0, 0, 1]
radiance = [4, 4, 4]
[[lights]]
type = "quad"
origin = [1, 2, 2]
v = [0.5, 0, 0]
u = [0, 0, 0.3]
radiance = [9, 1, 1]
[[lights]]
type = "quad"
origin = [3, 0, -3]
u = [0, 2, 0]
v = [0, 0, 2]
radiance = [0, 0, 0]
[[lights]]
type = "disk"
center = [0, 4, 0]
normal = [0, -1, 0.2]
radius = 0.7
radiance = [2, 2, 3]
[[lights]]
type = "disk"
center = [-3, 1, 2]
normal = [1, 0, 0]
radius = 0.2
radiance = [20, 20, 20]
[[lights]]
type = "point"
position = [2, 5, 1]
intensity = [10, 10, 10]
[[lights]]
type = "point"
position = [-1, -2, -4]
intensity = [1, 3, 1]
[[lights]]
type = "sphere"
center = [0, 1.5, -3]
radius = 0.4
radiance = [3, 3, 3]
[[lights]]
type = "sphere"
center = [4, 4, 4]
radius = 1.5
radiance = [0.5, 0.5, 0.5]
"#;
        parse_scene(Path::new("lights.toml"), text).unwrap()
    }

    fn profile(mode: LightSelection) -> Profile {
        let mut p = Profile::builtin("preview");
        p.light_selection = mode;
        p
    }

    fn rnd(k: &mut u32) -> f32 {
        *k += 1;
        random_f32_keyed(0x5eed, *k)
    }

    /// Points in and around the lights, some on their planes, behind them and inside the spheres.
    fn points(k: &mut u32) -> Vec<Vec3x8> {
        (0..64)
            .map(|_| {
                let xyz: [[f32; LANES]; 3] = std::array::from_fn(|_| std::array::from_fn(|_| rnd(k) * 12.0 - 6.0));
                Vec3x8::from_rows(&xyz)
            })
            .collect()
    }

    fn unit(k: &mut u32) -> Vec3 {
        loop {
            let v = Vec3::new(rnd(k) * 2.0 - 1.0, rnd(k) * 2.0 - 1.0, rnd(k) * 2.0 - 1.0);
            if v.length_squared() > 0.01 && v.length_squared() <= 1.0 {
                return v.normalize();
            }
        }
    }

    #[test]
    fn each_area_light_is_found_from_its_prim() {
        use crate::scene::{Shape, NOT_A_LIGHT};
        let scene = lights_scene();
        assert_eq!(scene.light_of_prim.len(), scene.prims.len());
        let mut found = vec![0; scene.lights.len()];
        for (prim, &li) in scene.prims.iter().zip(&scene.light_of_prim) {
            assert_eq!(prim.is_light, li != NOT_A_LIGHT);
            if li == NOT_A_LIGHT {
                continue;
            }
            found[li as usize] += 1;
            let same = match (scene.lights[li as usize], prim.shape) {
                (Light::Quad { quad, .. }, Shape::Quad(q)) => (quad.origin, quad.u, quad.v) == (q.origin, q.u, q.v),
                (Light::Disk { disk, .. }, Shape::Disk(k)) => (disk.center, disk.normal, disk.radius) == (k.center, k.normal, k.radius),
                (Light::Sphere { center, radius, .. }, Shape::Sphere { center: c, radius: r }) => (center, radius) == (c, r),
                _ => false,
            };
            assert!(same, "light {li}'s prim");
        }
        for (li, light) in scene.lights.iter().enumerate() {
            assert_eq!(found[li], if light.is_point() { 0 } else { 1 }, "light {li}");
        }
        assert!(found.iter().filter(|&&f| f == 0).count() >= 2 && found.iter().sum::<i32>() >= 5);
    }

    #[test]
    fn a_thread_keeps_its_selection_and_takes_an_installed_one() {
        let scene = lights_scene();
        assert!(LightPick::cached(&scene, &profile(LightSelection::All)).is_none());
        for mode in [LightSelection::Uniform, LightSelection::Power, LightSelection::Local, LightSelection::Tree] {
            let a = LightPick::cached(&scene, &profile(mode)).expect("several lights");
            assert_eq!(a.mode, mode);
            // Kept: the same selection on the next call. Another thread makes its own, unless given one.
            assert!(Arc::ptr_eq(&a, &LightPick::cached(&scene, &profile(mode)).unwrap()));
            std::thread::scope(|s| {
                s.spawn(|| assert!(!Arc::ptr_eq(&a, &LightPick::cached(&scene, &profile(mode)).unwrap())));
                s.spawn(|| {
                    LightPick::install(&scene, &profile(mode), Some(a.clone()));
                    assert!(Arc::ptr_eq(&a, &LightPick::cached(&scene, &profile(mode)).unwrap()));
                });
            });
        }
    }

    #[test]
    fn probabilities_sum_to_one_and_lanes_match_the_scalar() {
        let scene = lights_scene();
        assert!(LightPick::new(&scene, &profile(LightSelection::All)).is_none(), "`all` picks nothing");
        let mut k = 0;
        let mut scratch = Vec::new();
        for mode in [LightSelection::Uniform, LightSelection::Power, LightSelection::Local, LightSelection::Tree] {
            let pick = LightPick::new(&scene, &profile(mode)).unwrap();
            let mut lost = 0;
            for p in points(&mut k) {
                let u = f32x8::from(std::array::from_fn::<f32, LANES, _>(|_| rnd(&mut k)));
                let (light, prob) = pick.pick_x8(p, None, u, [0; LANES], &mut scratch);
                for l in 0..LANES {
                    let pl = p.lane(l);
                    let sum: f64 = (0..pick.lights()).map(|li| pick.prob(pl, li) as f64).sum();
                    // (`tree`: below 1 where a node's bound has importance and all its children's
                    // none; those numbers pick no light.)
                    // `local` and `tree`: every light that emits keeps the floor's share.
                    if matches!(mode, LightSelection::Local | LightSelection::Tree) {
                        for li in (0..pick.lights()).filter(|&li| li != 2) {
                            assert!(pick.prob(pl, li) >= POWER_FLOOR as f32 / 8.0 * 0.999, "{mode:?}: light {li} at {pl}");
                        }
                    }
                    if mode == LightSelection::Tree {
                        assert!(sum <= 1.0 + 1e-6 && sum > 0.5, "{mode:?} at {pl}: probabilities sum to {sum}");
                        if light[l] == NO_LIGHT {
                            lost += 1;
                            continue;
                        }
                    } else {
                        assert!((sum - 1.0).abs() < 1e-5, "{mode:?} at {pl}: probabilities sum to {sum}");
                    }
                    assert!(light[l] != NO_LIGHT, "{mode:?}: some light reaches every point");
                    assert_eq!(prob[l].to_bits(), pick.prob(pl, light[l] as usize).to_bits(), "{mode:?}: lane and scalar differ");
                    assert!(prob[l] > 0.0);
                }
            }
            assert!(lost < 64 * LANES / 10, "{mode:?}: {lost} picks of no light");
            // The light of zero radiance is never picked.
            assert_eq!(pick.prob(Vec3::ZERO, 2), 0.0, "{mode:?}");
        }
        let uniform = LightPick::new(&scene, &profile(LightSelection::Uniform)).unwrap();
        assert!((0..9).all(|li| li == 2 || (uniform.prob(Vec3::ONE, li) - 1.0 / 8.0).abs() < 1e-6));
    }

    /// For a fixed point, the picks of many stratified numbers land on each light in proportion to its
    /// probability (within 1.5 / n: the numbers are evenly spread), with and without normals.
    #[test]
    fn picks_follow_their_probabilities() {
        let scene = lights_scene();
        let mut k = 7;
        let mut scratch = Vec::new();
        for mode in [LightSelection::Power, LightSelection::Local, LightSelection::Tree] {
            let pick = LightPick::new(&scene, &profile(mode)).unwrap();
            for _ in 0..6 {
                let p = Vec3::new(rnd(&mut k) * 4.0 - 2.0, rnd(&mut k) * 2.0, rnd(&mut k) * 4.0 - 2.0);
                let normal = unit(&mut k);
                for with_n in [false, true] {
                    let n = with_n.then_some(Vec3x8::splat(normal));
                    let count = 4096usize;
                    let mut hits = vec![0usize; pick.lights()];
                    let mut probs = vec![0.0f32; pick.lights()];
                    // The numbers below the floor's share pick uniformly by `fine`: stratified over
                    // those numbers too.
                    let floored = (0..count).filter(|&c| ((c as f64 + 0.5) / count as f64) < FLOOR_VALUES as f64 / GRID as f64).count();
                    let fine = |c: usize| ((c as f64 + 0.5) / floored as f64 * GRID as f64) as u32 & (GRID - 1);
                    for c in (0..count).step_by(LANES) {
                        let u = f32x8::from(std::array::from_fn::<f32, LANES, _>(|l| ((c + l) as f32 + 0.5) / count as f32));
                        let (light, prob) = pick.pick_x8(Vec3x8::splat(p), n, u, std::array::from_fn(|l| fine(c + l)), &mut scratch);
                        for l in 0..LANES {
                            if light[l] != NO_LIGHT {
                                hits[light[l] as usize] += 1;
                                probs[light[l] as usize] = prob[l];
                            }
                        }
                    }
                    let local = mode == LightSelection::Local;
                    let total: f32 = if local { (0..pick.lights()).map(|li| scratch[li].to_array()[0]).sum() } else { 1.0 };
                    for li in 0..pick.lights() {
                        let expect = match pick.tree_prob(p, with_n.then_some(normal), li) {
                            Some(prob) => prob,
                            None if local => pick.local_prob(li, scratch[li].to_array()[0], total),
                            None => pick.prob(p, li),
                        };
                        let seen = hits[li] as f32 / count as f32;
                        // (Within one pick of the floor's strata and 1.5 of the others'.)
                        assert!(
                            (seen - expect).abs() <= 2.5 / count as f32,
                            "{mode:?} light {li} at {p}: picked {seen}, probability {expect}"
                        );
                        if hits[li] > 0 {
                            assert!((probs[li] - expect).abs() <= 1e-6 * expect.max(1e-30) + 1e-9, "{mode:?}: reported probability");
                        }
                    }
                }
            }
        }
    }

    /// `power` under a sun 1e13 times as strong as its lamps: every light that emits keeps at least
    /// POWER_FLOOR / L, and each light's probability is exactly the share of the pick's 2^24 possible
    /// numbers that land on it (counted), so that 1 / P weighs what the picks do.
    #[test]
    fn power_picks_keep_every_light_and_their_probabilities_are_exact() {
        // (The lamps first: their slots lie below 0.5, where f32 steps are finer than the numbers'.)
        let mut text = String::from("[image]\nwidth = 4\nheight = 4\n[camera]\nposition = [0, 1, 5]\nlook_at = [0, 0, 0]\nfov = 40\n");
        for i in 0..6 {
            text += &format!("[[lights]]\ntype = \"point\"\nposition = [{i}, 2, 0]\nintensity = [0.{i}, 0.1, 0.1]\n");
        }
        text += "[[lights]]\ntype = \"quad\"\norigin = [-1e6, 1e6, -1e6]\nu = [2e6, 0, 0]\nv = [0, 0, 2e6]\nradiance = [30, 30, 30]\n";
        text += "[[lights]]\ntype = \"point\"\nposition = [0, 3, 0]\nintensity = [0, 0, 0]\n";
        let scene = parse_scene(Path::new("sun.toml"), &text).unwrap();
        let pick = LightPick::new(&scene, &profile(LightSelection::Power)).unwrap();
        let l = pick.lights();
        // 5% of the picks over the 7 lights that emit.
        for li in 0..l - 1 {
            assert!(pick.prob(Vec3::ZERO, li) >= 0.05 / 7.0 * 0.999, "light {li}: {}", pick.prob(Vec3::ZERO, li));
        }
        assert_eq!(pick.prob(Vec3::ZERO, l - 1), 0.0, "a light of no power");
        let mut hits = vec![0u64; l];
        let mut scratch = Vec::new();
        let grid = 1u32 << 24;
        for k in (0..grid).step_by(LANES) {
            let u = f32x8::from(std::array::from_fn::<f32, LANES, _>(|j| (k + j as u32) as f32 / grid as f32));
            let (light, _) = pick.pick_x8(Vec3x8::splat(Vec3::ZERO), None, u, [0; LANES], &mut scratch);
            for li in light {
                hits[li as usize] += 1;
            }
        }
        for (li, &h) in hits.iter().enumerate() {
            assert_eq!(h as f64 / grid as f64, pick.prob(Vec3::ZERO, li) as f64, "light {li}: realized against reported");
        }
    }

    /// A light a point never picks (importance 0) gives it nothing: no point of the light lies both in
    /// front of the light's emitting side and above the receiver's horizon.
    #[test]
    fn a_light_never_picked_gives_the_point_nothing() {
        let scene = lights_scene();
        for mode in [LightSelection::Local, LightSelection::Tree] {
            never_picked_gives_nothing(&scene, &LightPick::new(&scene, &profile(mode)).unwrap());
        }
    }

    fn never_picked_gives_nothing(scene: &Scene, pick: &LightPick) {
        let mut k = 99;
        let mut scratch = Vec::new();
        let mut zeros = 0;
        for p in points(&mut k) {
            let normals: [[f32; LANES]; 3] = {
                let ns: [Vec3; LANES] = std::array::from_fn(|_| unit(&mut k));
                std::array::from_fn(|a| std::array::from_fn(|l| ns[l][a]))
            };
            let n = Vec3x8::from_rows(&normals);
            pick.pick_x8(p, Some(n), f32x8::splat(0.5), [0; LANES], &mut scratch);
            for (li, light) in scene.lights.iter().enumerate() {
                for l in 0..LANES {
                    let never = match pick.tree_share(p.lane(l), Some(n.lane(l)), li) {
                        Some(prob) => prob == 0.0,
                        None => scratch[li].to_array()[l] <= 0.0,
                    };
                    if !never {
                        continue;
                    }
                    zeros += 1;
                    let (pl, nl) = (p.lane(l), n.lane(l));
                    for s in 0..256 {
                        let (a, b) = (((s % 16) as f32 + 0.5) / 16.0, ((s / 16) as f32 + 0.5) / 16.0);
                        let (y, emits) = match *light {
                            Light::Quad { quad, radiance } => {
                                let y = quad.origin + quad.u * a + quad.v * b;
                                (y, radiance != Vec3::ZERO && quad.normal().dot(pl - y) > 0.0)
                            }
                            Light::Disk { disk, .. } => {
                                let (t, w) = crate::optics::onb(disk.normal);
                                let r = disk.radius * a.sqrt();
                                let phi = b * std::f32::consts::TAU;
                                let y = disk.center + (t * phi.cos() + w * phi.sin()) * r;
                                (y, disk.normal.dot(pl - y) > 0.0)
                            }
                            Light::Point { position, .. } => (position, true),
                            Light::Sphere { center, radius, .. } => {
                                let z = 2.0 * a - 1.0;
                                let phi = b * std::f32::consts::TAU;
                                let s = (1.0 - z * z).sqrt();
                                let m = Vec3::new(s * phi.cos(), s * phi.sin(), z);
                                let y = center + m * radius;
                                (y, m.dot(pl - y) > 0.0)
                            }
                        };
                        assert!(
                            !(emits && nl.dot(y - pl) > 1e-4 * (y - pl).length()),
                            "light {li} reaches {pl} (normal {nl}) at {y} but is never picked"
                        );
                    }
                }
            }
        }
        assert!(zeros > 500, "the points and normals leave some lights out ({zeros} lane-lights)");
    }
}
