//! Shadow rays through dielectrics: the transmittance of the straight segment from a shading point to a
//! light sample, for the lanes whose any-hit test met only dielectrics that do not block.
//!
//! One traversal of the segment collects every surface it crosses (a CSG solid's boundaries from its merged
//! interval list, a convex prim's entry and exit from one interval, a flat prim's one hit: no re-spawned
//! segments, so no offset points and one traversal instead of one per surface); sorted along the segment,
//! the crossings are replayed with the same which-side rule as camera paths
//! ([`medium::cross`]): Beer-Lambert absorption of the medium the ray is in along each piece, and at each
//! surface:
//! * a null crossing (an outranked medium's surface, index-matched media, a dielectric of index 1 in air):
//!   nothing, exactly as for a camera ray, which goes on undeflected;
//! * a thin sheet: its transmission `1 - R` (both faces, inter-reflections summed), undeflected too;
//! * a real interface: physically the light there is refracted, so the shadow ray is blocked (the light
//!   that arrives is a caustic); under the profile's non-physical `transmissive_shadows` it passes,
//!   attenuated by the Fresnel transmission `1 - F` at the ray's angle taken on the rarer side of the
//!   interface ([`straight_eta`]): the straight ray stands for the refracted one, whose crossings of a
//!   slab or a ball pair an outer angle with its refracted inner one, and by reciprocity each transmits
//!   `1 - F` of the outer angle; at its own inner angle the straight ray would be totally reflected
//!   past the critical angle (a slab's shadow went black beyond 42 degrees, a user trial).
//!
//! The media around the shading point are those of the ray that reached it (its stack, which the request
//! carries in scenes with dielectrics): the segment starts inside them, absorbed along its length even
//! where it crosses no surface, and a surface it crosses is weighed between the media on its two sides
//! (an air bubble in glass is a real interface). Where that stack is empty the media around the start
//! are also inferred from the crossings: a medium whose first crossing on the segment is an exit
//! contains the start. Indices are the nominal ones (shadow rays carry no wavelength). A segment with
//! more than [`MAX_CROSSINGS`] surfaces counts as blocked.

use super::intersect::{in_prim_frame, prim_t_at_x8};
use super::medium;
use super::queues::{MediumStack, RayItem, NONE};
use super::shade::surface_hit;
use crate::accel::{intersect_aabb_x8, PacketRay};
use crate::csg::{crossings_x8, CsgArena};
use crate::geometry::{ellipsoid_interval_x8, obox_interval_x8, sphere_interval_x8};
use crate::optics::{beer_lambert, fresnel_dielectric, fresnel_dielectric_x8, fresnel_schlick};
use crate::scene::{Material, Prim, Profile, Scene, Shape};
use crate::simd::{f32x8, for_each_group, lane_bits, mask_from_bits, Ray8, Vec3x8, LANES};
use glam::{Mat3, Vec3};

/// Surfaces recorded per shadow ray; a ray that crosses more is taken as blocked.
pub const MAX_CROSSINGS: usize = 16;

/// One surface crossed by a shadow ray.
#[derive(Clone, Copy, Debug, Default)]
struct Event {
    /// Distance from the segment's start.
    s: f32,
    material: u32,
    entering: bool,
    /// |cos| of the angle between the segment and the surface normal.
    cos: f32,
    /// The Fresnel transmission `1 - F` at `cos` between the material and air ([`air_eta`]).
    tf: f32,
}

/// Whether some dielectric lets shadow rays through under this profile (else the walk is never needed).
pub fn any_passable(scene: &Scene, profile: &Profile) -> bool {
    scene.features.dielectric
        && scene.materials.iter().any(|m| matches!(m, Material::Dielectric(d) if profile.transmissive_shadows || d.passable))
}

/// Whether a dielectric (or any material) lets shadow rays walk through it under this profile.
#[inline(always)]
pub fn passes(scene: &Scene, profile: &Profile, material: u32) -> bool {
    match &scene.materials[material as usize] {
        Material::Dielectric(d) => profile.transmissive_shadows || d.passable,
        _ => false,
    }
}

/// One boundary met by a segment, before its surface geometry is known.
#[derive(Clone, Copy, Debug, Default)]
struct Raw {
    t: f32,
    prim: u32,
    leaf: u32,
    flip: bool,
    /// Whether the segment enters ([`SIDE_ENTRY`]) or leaves ([`SIDE_EXIT`]) the solid here, where the
    /// interval it came from says so (convex prims, CSG solids); [`SIDE_NORMAL`] for flat prims, whose
    /// normal decides.
    side: u8,
}

const SIDE_NORMAL: u8 = 0;
const SIDE_EXIT: u8 = 1;
const SIDE_ENTRY: u8 = 2;

/// Scratch of the walk, reused by every call (per lane: the boundaries found and, as replay events in the
/// same order, what their surfaces are; only the first `count` entries are ever read).
pub struct Walk {
    raw: [[Raw; MAX_CROSSINGS]; LANES],
    geo: [[Event; MAX_CROSSINGS]; LANES],
    count: [usize; LANES],
    /// Lanes with more boundaries than fit.
    full: u32,
    /// Whether sphere entry-exit pairs take the 8-lane replay (always, but in the test that holds it to
    /// the per-lane one).
    sphere_pairs: bool,
}

impl Walk {
    pub fn new() -> Box<Walk> {
        Box::new(Walk {
            raw: [[Raw::default(); MAX_CROSSINGS]; LANES],
            geo: [[Event::default(); MAX_CROSSINGS]; LANES],
            count: [0; LANES],
            full: 0,
            sphere_pairs: true,
        })
    }

    /// Record a boundary of lane `l` (past [`MAX_CROSSINGS`] the lane is full: blocked).
    #[inline(always)]
    fn push(&mut self, l: usize, r: Raw) {
        let k = self.count[l];
        if k == MAX_CROSSINGS {
            self.full |= 1 << l;
            return;
        }
        self.raw[l][k] = r;
        self.count[l] = k + 1;
    }
}

/// Transmittance of the segments `o + t d`, `t` in `(0, tmax)`, of the lanes set in `lanes`; other lanes
/// get 0. `time` is each lane's shutter time (moving prims). Also returns the number of rays traced (one
/// per lane: the segment is traversed once).
///
/// One traversal collects every surface the segment crosses: a CSG solid's boundaries from its merged
/// interval list, a convex prim's (sphere, ellipsoid, box) entry and exit from one interval, a flat
/// prim's one hit. Their sides come from the intervals (a flat prim's from its normal), their angles from
/// the normals ([`events`]: a sphere's from the point, a box's from the face of its slab, others' as the
/// shading stage's `surface_hit` finds them); sorted along the segment
/// (entries before exits, then prim and leaf at equal distance, whatever the traversal order), they are
/// replayed. `start`: per lane, the media the segment starts inside (the stack of the ray that reached
/// the shading point): a lane whose stack is not empty starts in it, absorbed along the segment even
/// where it crosses no surface, its crossings replayed from that stack; one whose stack is empty takes
/// the media around its start from the crossings (see the module doc).
#[allow(clippy::too_many_arguments)]
pub fn transmittance_x8(
    scene: &Scene,
    profile: &Profile,
    o: &[[f32; LANES]; 3],
    d: &[[f32; LANES]; 3],
    tmax: &[f32; LANES],
    time: &[f32; LANES],
    start: &[MediumStack; LANES],
    lanes: u32,
    arena: &mut CsgArena,
    walk: &mut Walk,
) -> ([Vec3; LANES], u64) {
    let dir: [Vec3; LANES] = std::array::from_fn(|l| Vec3::new(d[0][l], d[1][l], d[2][l]));
    let tm = f32x8::from(std::array::from_fn::<f32, LANES, _>(|l| if lanes & (1 << l) != 0 { tmax[l] } else { -1.0 }));
    let ray = Ray8::new(Vec3x8::from_rows(o), Vec3x8::from_rows(d), tm);
    let time8 = scene.features.motion.then(|| f32x8::from(*time));
    let cr = walk;
    cr.count = [0; LANES];
    cr.full = 0;
    collect(scene, &ray, time8, arena, cr);

    let mut tr = [Vec3::ZERO; LANES];
    // Lanes that enter and leave one sphere of a one-medium dielectric (the usual walk) in 8 lanes.
    let inside = lane_bits(|l| !start[l].is_empty());
    let pairs = if cr.sphere_pairs { sphere_pair_lanes(scene, profile, cr, lanes & !cr.full & !inside) } else { 0 };
    if pairs != 0 {
        sphere_pairs_x8(scene, profile, cr, &ray, time, pairs, &mut tr);
    }
    let rest = lanes & !pairs;
    events(scene, cr, &ray, time, rest & !cr.full);

    let mut bits = rest & !cr.full;
    while bits != 0 {
        let l = bits.trailing_zeros() as usize;
        bits &= bits - 1;
        tr[l] = lane_transmittance(scene, profile, cr, l, (dir[l] * tmax[l]).length(), start[l]);
    }
    (tr, lanes.count_ones() as u64)
}

/// What the replay needs of every boundary's surface (its side, material, angle and Fresnel
/// transmission against air) for the lanes `lanes`, the `k`-th boundaries of all lanes at once. A CSG
/// leaf's normal is found as the shading stage's `surface_hit` finds it (the point projected onto the
/// leaf, the normal there), bit for bit: in 8 lanes per distinct leaf ([`Leaf::refine_x8`],
/// [`Leaf::normal_x8`]). (Taking the normal at the unprojected point instead changed a light sample's
/// transmittance by percents where the point fell past a box's or cylinder's edge onto the neighbouring
/// face: a user trial.) Lane by lane: a sphere's normal straight from the point on the segment, a box's
/// from its face's axis, other shapes' through `surface_hit`.
///
/// [`Leaf::refine_x8`]: crate::csg::Leaf::refine_x8
/// [`Leaf::normal_x8`]: crate::csg::Leaf::normal_x8
fn events(scene: &Scene, cr: &mut Walk, ray: &Ray8, time: &[f32; LANES], lanes: u32) {
    let (o, d) = (ray.o, ray.d);
    // `length` and `normalize_or_zero` as glam rounds them.
    let (len, unit) = (d.dot_unfused(d).sqrt(), d.normalize_or(Vec3x8::splat(Vec3::ZERO)));
    let (len_l, time8) = (len.to_array(), f32x8::from(*time));
    let mut deepest = 0;
    let mut bits = lanes;
    while bits != 0 {
        deepest = deepest.max(cr.count[bits.trailing_zeros() as usize]);
        bits &= bits - 1;
    }
    for k in 0..deepest {
        let at = lanes & lane_bits(|l| cr.count[l] > k);
        let t = f32x8::from(std::array::from_fn::<f32, LANES, _>(|l| if at & (1 << l) != 0 { cr.raw[l][k].t } else { 0.0 }));
        let csg = lane_bits(|l| at & (1 << l) != 0 && matches!(scene.prims[cr.raw[l][k].prim as usize].shape, Shape::Csg { .. }));
        let (mut cos, mut eta) = (f32x8::ZERO, f32x8::ONE);
        let mut material = [0u32; LANES];
        let mut wide = 0;
        for_each_group(
            csg,
            |l| (cr.raw[l][k].leaf, cr.raw[l][k].prim),
            |first, same| {
                let r0 = cr.raw[first][k];
                let (leaf, prim) = (scene.csg.leaf(r0.leaf), &scene.prims[r0.prim as usize]);
                // As `surface_hit` finds it: the point projected onto the leaf in its frame at the ray's
                // time (where defined), the normal there.
                let (naive, shift) = (o + d.scale(t), Vec3x8::splat(prim.motion).scale(time8));
                let (q, _, ok) = leaf.refine_x8(naive - shift);
                let n = leaf.normal_x8(Vec3x8::select(ok, q + shift, naive) - shift);
                let keep = mask_from_bits(same);
                cos = keep.select(unit.dot_unfused(n), cos);
                eta = keep.select(f32x8::splat(air_eta(scene, leaf.material)), eta);
                for l in (0..LANES).filter(|&l| same & (1 << l) != 0) {
                    material[l] = leaf.material;
                }
                wide |= same;
            },
        );
        // The rest lane by lane.
        let (mut cos_l, mut eta_l) = (cos.to_array(), eta.to_array());
        let mut narrow = at & !wide;
        while narrow != 0 {
            let l = narrow.trailing_zeros() as usize;
            narrow &= narrow - 1;
            let r = cr.raw[l][k];
            let prim = &scene.prims[r.prim as usize];
            let (o, d) = (o.lane(l), d.lane(l));
            let (n, m) = match prim.shape {
                Shape::Sphere { center, .. } => ((o + d * r.t - (center + prim.motion * time[l])).normalize_or_zero(), prim.material),
                // The face's normal direction in world space (the row of the world-to-object map for its
                // axis); only |cos| is used, the side comes from the interval.
                Shape::Box(b) => (Mat3::from(b.world_to_object.matrix3).row(r.leaf as usize).normalize_or_zero(), prim.material),
                _ => {
                    let ray = RayItem { o, d, time: time[l], ..RayItem::default() };
                    let h = surface_hit(scene, &ray, r.t, r.prim, r.leaf, r.flip);
                    (h.n, h.material)
                }
            };
            (cos_l[l], eta_l[l], material[l]) = (unit.lane(l).dot(n), air_eta(scene, m), m);
        }
        // Each crossing's Fresnel transmission against air, for the one-medium replay.
        let tf = (f32x8::ONE - fresnel_dielectric_x8(f32x8::from(cos_l).abs(), f32x8::from(eta_l))).to_array();
        let mut bits = at;
        while bits != 0 {
            let l = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let r = &cr.raw[l][k];
            let entering = if r.side == SIDE_NORMAL { cos_l[l] < 0.0 } else { r.side == SIDE_ENTRY };
            cr.geo[l][k] = Event { s: r.t * len_l[l], material: material[l], entering, cos: cos_l[l].abs(), tf: tf[l] };
        }
    }
}

/// The `eta` at which a crossing between material `m` (a dielectric) and air is weighed by the one-medium
/// replay ([`straight_eta`] of its index against 1, either way); 1 for other materials (unused).
#[inline(always)]
fn air_eta(scene: &Scene, m: u32) -> f32 {
    match medium::dielectric(scene, m) {
        Some(d) => {
            let n = d.ior.nominal();
            straight_eta(n, 1.0)
        }
        None => 1.0,
    }
}

/// The lanes (among `lanes`) whose crossings are exactly a sphere's entry and exit (in that order) and
/// whose sphere is of a dielectric that [`replay_one_medium`] replays (passable, not thin) with the exact
/// Fresnel equations: [`sphere_pairs_x8`] gives their transmittance.
#[inline]
fn sphere_pair_lanes(scene: &Scene, profile: &Profile, cr: &Walk, lanes: u32) -> u32 {
    let mut out = 0;
    let mut bits = lanes;
    while bits != 0 {
        let l = bits.trailing_zeros() as usize;
        bits &= bits - 1;
        let (r0, r1) = (&cr.raw[l][0], &cr.raw[l][1]);
        if cr.count[l] != 2 || r0.prim != r1.prim || r0.side != SIDE_ENTRY || r1.side != SIDE_EXIT || !(r0.t <= r1.t) {
            continue;
        }
        if paired_sphere(scene, profile, &scene.prims[r0.prim as usize]) {
            out |= 1 << l;
        }
    }
    out
}

/// Transmittance of the `pairs` lanes ([`sphere_pair_lanes`]) into `tr`, in 8 lanes: bit for bit what the
/// per-lane path gives them (the same unfused point, normal and cosine as [`events`] gives a sphere's crossing, the
/// exact Fresnel reflectance in 8 lanes, and [`replay_one_medium`]'s products in its order; absorption,
/// whose `exp` has no 8-lane twin, lane by lane).
fn sphere_pairs_x8(scene: &Scene, profile: &Profile, cr: &Walk, ray: &Ray8, time: &[f32; LANES], pairs: u32, tr: &mut [Vec3; LANES]) {
    // Other lanes: any pair lane's sphere.
    let l0 = pairs.trailing_zeros() as usize;
    let lane_of = |l: usize| if pairs & (1 << l) != 0 { l } else { l0 };
    let prims = std::array::from_fn(|l| cr.raw[lane_of(l)][0].prim);
    let t = [std::array::from_fn(|l| cr.raw[lane_of(l)][0].t), std::array::from_fn(|l| cr.raw[lane_of(l)][1].t)];
    pair_transmittance_x8(scene, profile, &prims, t, ray, time, pairs, tr);
}

/// Spheres of a dielectric that shadow rays walk through, one per lane ([`paired_sphere`]), with what
/// the transmittance of their entry-exit pairs needs ([`SingleSpheres::pairs_x8`]). For the lanes whose
/// light-cone verdict is one glass sphere each ([`pair_sphere`]) it is made once per chunk of shading
/// points, for all their light samples ([`single_sphere_x8`]); the walk makes one per packet.
pub struct SingleSpheres {
    /// The distinct spheres and their lanes (for [`single_sphere_x8`]).
    groups: [(u32, u32); LANES],
    n_groups: usize,
    /// Per lane (lanes outside those given: the first one's): the sphere's centre at the lane's time
    /// (`centre + motion * time`, unfused as `Vec3` computes it) and its medium's index.
    c: Vec3x8,
    ior: f32x8,
    /// Lanes whose sphere absorbs (their transmittance has a per-lane `exp`), and lanes whose sphere
    /// stops shadow rays (of index other than 1, passable but not under `transmissive_shadows`).
    absorbs: u32,
    blocks: u32,
    sigma_a: [Vec3; LANES],
}

impl SingleSpheres {
    /// The static spheres `prims[l]` of lanes `lanes` (each a [`pair_sphere`]).
    pub fn new(scene: &Scene, profile: &Profile, prims: &[u32; LANES], lanes: u32) -> SingleSpheres {
        let mut out = SingleSpheres::at(scene, profile, prims, lanes, &[0.0; LANES]);
        for_each_group(
            lanes,
            |l| prims[l],
            |first, same| {
                out.groups[out.n_groups] = (prims[first], same);
                out.n_groups += 1;
            },
        );
        out
    }

    /// The spheres `prims[l]` of lanes `lanes` (each a [`paired_sphere`]) at the lanes' times `time`.
    fn at(scene: &Scene, profile: &Profile, prims: &[u32; LANES], lanes: u32, time: &[f32; LANES]) -> SingleSpheres {
        let mut out = SingleSpheres {
            groups: [(0, 0); LANES],
            n_groups: 0,
            c: Vec3x8::splat(Vec3::ZERO),
            ior: f32x8::ONE,
            absorbs: 0,
            blocks: 0,
            sigma_a: [Vec3::ZERO; LANES],
        };
        if lanes == 0 {
            return out;
        }
        let l0 = lanes.trailing_zeros() as usize;
        let (mut rows, mut ior) = ([[0.0f32; LANES]; 6], [1.0f32; LANES]);
        for l in 0..LANES {
            let pid = if lanes & (1 << l) != 0 { prims[l] } else { prims[l0] };
            let prim = &scene.prims[pid as usize];
            let Shape::Sphere { center, .. } = prim.shape else { unreachable!("the callers checked the shape") };
            let d = medium::dielectric(scene, prim.material).expect("the callers checked the material");
            for a in 0..3 {
                (rows[a][l], rows[3 + a][l]) = (center[a], prim.motion[a]);
            }
            ior[l] = d.ior.nominal();
            out.sigma_a[l] = d.sigma_a;
            out.absorbs |= ((d.sigma_a != Vec3::ZERO) as u32) << l;
            out.blocks |= ((ior[l] != 1.0 && !profile.transmissive_shadows) as u32) << l;
        }
        let (f, tm) = (|a: &[f32; LANES]| f32x8::from(*a), f32x8::from(*time));
        out.c = Vec3x8::new(f(&rows[0]) + f(&rows[3]) * tm, f(&rows[1]) + f(&rows[4]) * tm, f(&rows[2]) + f(&rows[5]) * tm);
        out.ior = f32x8::from(ior);
        out
    }

    /// The transmittance of the entry-exit pairs `t` (entry, exit) of the lanes `pairs` along `ray`, as
    /// the per-lane replay ([`replay_one_medium`]) gives it, bit for bit: the two crossings' Fresnel
    /// transmissions ([`pair_fresnel_x8`]) and, for absorbing spheres, Beer-Lambert between them (lane by
    /// lane: `exp` has no 8-lane twin), in its order; 0 in the lanes whose sphere blocks. Other lanes:
    /// unspecified.
    fn pairs_x8(&self, t: [f32x8; 2], ray: &Ray8, pairs: u32) -> Vec3x8 {
        let (f0, f1, s0, s1) = pair_fresnel_x8(self.c, self.ior, t, ray);
        let f = f0 * f1;
        let mut tr = Vec3x8::masked(Vec3x8::new(f, f, f), !mask_from_bits(self.blocks));
        let mut absorbing = pairs & self.absorbs & !self.blocks;
        if absorbing != 0 {
            let mut rows = tr.rows();
            let (f0, f1, s0, s1) = (f0.to_array(), f1.to_array(), s0.to_array(), s1.to_array());
            while absorbing != 0 {
                let l = absorbing.trailing_zeros() as usize;
                absorbing &= absorbing - 1;
                let v = Vec3::ONE * f0[l] * beer_lambert(self.sigma_a[l], s1[l] - s0[l]) * f1[l];
                (rows[0][l], rows[1][l], rows[2][l]) = (v.x, v.y, v.z);
            }
            tr = Vec3x8::from_rows(&rows);
        }
        tr
    }
}

/// Shadow rays that can meet no surface but one sphere (the light-cone test's verdict) of a dielectric
/// they walk through ([`pair_sphere`], gathered in `spheres`): per lane of `lanes` (a subset of those the
/// spheres were made for), the transmittance of the ray, exactly as the traversal and the walk would
/// give it (1 where it misses the sphere; the pair's, as `sphere_pairs_x8` gives it, where it enters and
/// leaves it within the segment). Lanes that cross the sphere once (a segment starting or ending inside
/// it) are left out of the returned mask: they are traced.
pub fn single_sphere_x8(scene: &Scene, spheres: &SingleSpheres, ray: &Ray8, lanes: u32) -> (u32, Vec3x8) {
    let (mut pairs, mut done) = (0u32, 0u32);
    let nan = f32x8::splat(f32::NAN);
    let (mut t0, mut t1) = (nan, nan);
    let active = ray.tmax.simd_gt(f32x8::ZERO).to_bitmask();
    for &(pid, group) in &spheres.groups[..spheres.n_groups] {
        let same = group & lanes;
        if same == 0 {
            continue;
        }
        let Shape::Sphere { center, radius } = scene.prims[pid as usize].shape else { continue };
        // As the walk collects a sphere's crossings (`collect`).
        let (near, far) = sphere_interval_x8(center, radius, ray);
        let inside = |t: f32x8| (t.simd_gt(f32x8::ZERO) & t.simd_lt(ray.tmax)).to_bitmask() & active;
        let (nb, fb) = (inside(near), inside(far));
        pairs |= same & nb & fb;
        done |= same & !(nb | fb);
        let keep = mask_from_bits(same);
        (t0, t1) = (keep.select(near, t0), keep.select(far, t1));
    }
    let one = Vec3x8::splat(Vec3::ONE);
    if pairs == 0 {
        return (done, one);
    }
    // Lanes outside the pairs take a pair lane's crossings (their results are not used).
    let first = pairs.trailing_zeros() as usize;
    let is_pair = mask_from_bits(pairs);
    let t = [t0, t1].map(|t| is_pair.select(t, f32x8::splat(t.to_array()[first])));
    (pairs | done, Vec3x8::select(is_pair, spheres.pairs_x8(t, ray, pairs), one))
}

/// Whether prim `pid` is a static sphere whose crossings [`single_sphere_x8`] replays.
pub fn pair_sphere(scene: &Scene, profile: &Profile, pid: u32) -> bool {
    let prim = &scene.prims[pid as usize];
    prim.motion == Vec3::ZERO && paired_sphere(scene, profile, prim)
}

/// Whether a prim's entry-exit pairs are replayed by [`pair_transmittance_x8`]: a sphere of a dielectric
/// that shadow rays walk through, neither thin nor Schlick.
fn paired_sphere(scene: &Scene, profile: &Profile, prim: &Prim) -> bool {
    matches!(prim.shape, Shape::Sphere { .. })
        && passes(scene, profile, prim.material)
        && medium::dielectric(scene, prim.material).is_some_and(|d| !d.thin && !d.schlick)
}

/// The transmittance of entry-exit pairs `t` of spheres `prims` (every lane a valid sphere; the `pairs`
/// lanes are written), in 8 lanes (see [`sphere_pairs_x8`]).
#[allow(clippy::too_many_arguments)]
fn pair_transmittance_x8(
    scene: &Scene,
    profile: &Profile,
    prims: &[u32; LANES],
    t: [[f32; LANES]; 2],
    ray: &Ray8,
    time: &[f32; LANES],
    pairs: u32,
    tr: &mut [Vec3; LANES],
) {
    let spheres = SingleSpheres::at(scene, profile, prims, u32::MAX >> (32 - LANES), time);
    let v = spheres.pairs_x8(t.map(f32x8::from), ray, pairs);
    for l in (0..LANES).filter(|&l| pairs & (1 << l) != 0) {
        tr[l] = v.lane(l);
    }
}

/// The two crossings `t` (entry, exit) of spheres centred at `c` of index `n`, as the per-lane walk
/// weighs them: each one's Fresnel transmission `1 - F` and distance along the segment (`f0`, `f1`,
/// `s0`, `s1`).
#[inline(always)]
fn pair_fresnel_x8(c: Vec3x8, n: f32x8, t: [f32x8; 2], ray: &Ray8) -> (f32x8, f32x8, f32x8, f32x8) {
    let one = f32x8::ONE;
    let (o, d) = (ray.o, ray.d);
    // `normalize_or_zero` as glam rounds it.
    let normalize = |v: Vec3x8| v.normalize_or(Vec3x8::splat(Vec3::ZERO));
    let len = d.dot_unfused(d).sqrt();
    let unit = normalize(d);
    // Each crossing's distance along the segment and |cos| to its normal.
    let crossing = |t: f32x8| {
        let p = o + d.scale(t);
        let n = normalize(p - c);
        (t * len, unit.dot_unfused(n).abs())
    };
    let ((s0, cos0), (s1, cos1)) = (crossing(t[0]), crossing(t[1]));
    // Entering (n1, n2) = (1, n), leaving (n, 1): both weighed from the air side, eta = 1 / n
    // (`straight_eta`; glass of index below 1 too: its rarer side is inside); no Fresnel factor where
    // n1 == n2.
    let matched = n.simd_eq(one);
    let eta = n.simd_gt(one).select(one / n, n);
    let f0 = matched.select(one, one - fresnel_dielectric_x8(cos0, eta));
    let f1 = matched.select(one, one - fresnel_dielectric_x8(cos1, eta));
    (f0, f1, s0, s1)
}

/// Transmittance of lane `l`'s segment (of length `len`) from its collected crossings: 0 at a surface that
/// stops shadow rays or past [`MAX_CROSSINGS`], else the replay of the crossings sorted along the segment.
#[inline]
fn lane_transmittance(scene: &Scene, profile: &Profile, cr: &Walk, l: usize, len: f32, start: MediumStack) -> Vec3 {
    let (raw, geo) = (&cr.raw[l], &cr.geo[l]);
    let mut events = [Event::default(); MAX_CROSSINGS];
    let mut order = [(0.0f32, 0u32, 0u32, 0u32); MAX_CROSSINGS];
    let mut n = 0;
    for k in 0..cr.count[l] {
        let (r, g) = (&raw[k], &geo[k]);
        if !passes(scene, profile, g.material) || n == MAX_CROSSINGS {
            return Vec3::ZERO;
        }
        // Insertion by (t, entries before exits, prim, leaf): the order does not depend on the
        // traversal's, and where one solid ends exactly where another begins (glued faces) the ray is in
        // both for an instant, so an index-matched pair is a null crossing, not two interfaces.
        let key = (r.t, !g.entering as u32, r.prim, r.leaf);
        let e = *g;
        let mut i = n;
        while i > 0 && later(order[i - 1], key) {
            order[i] = order[i - 1];
            events[i] = events[i - 1];
            i -= 1;
        }
        order[i] = key;
        events[i] = e;
        n += 1;
    }
    replay(scene, profile, &events[..n], len, start)
}

/// Whether boundary key `a` sorts after `b` (by distance, then exits after entries, prim, leaf).
#[inline(always)]
fn later(a: (f32, u32, u32, u32), b: (f32, u32, u32, u32)) -> bool {
    a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)).then(a.3.cmp(&b.3)).is_gt()
}

/// Every boundary of the packet's segments (lanes with `tmax > 0`) into `cr`.
fn collect(scene: &Scene, ray: &Ray8, time: Option<f32x8>, arena: &mut CsgArena, cr: &mut Walk) {
    let active = ray.tmax.simd_gt(f32x8::ZERO).to_bitmask();
    let (zero, tmax) = (f32x8::ZERO, ray.tmax);
    let prim_hits = |pid: u32, cr: &mut Walk| {
        let prim = &scene.prims[pid as usize];
        // A convex prim's entry and exit from one interval (so a segment that clips an edge gets both or
        // neither); a flat prim's one hit.
        let local = in_prim_frame(ray, prim.motion, time);
        // A box's crossings carry their face's axis (in `leaf`), which the point cannot tell at an edge.
        let no_axis = [NONE; LANES];
        let ((near, far), side_near, (ax_near, ax_far)) = match &prim.shape {
            Shape::Sphere { center, radius } => (sphere_interval_x8(*center, *radius, &local), SIDE_ENTRY, (no_axis, no_axis)),
            Shape::Ellipsoid(e) => (ellipsoid_interval_x8(e, &local), SIDE_ENTRY, (no_axis, no_axis)),
            Shape::Box(b) => {
                let (n, f, an, af) = obox_interval_x8(b, &local);
                ((n, f), SIDE_ENTRY, (an, af))
            }
            _ => ((prim_t_at_x8(prim, ray, time), f32x8::splat(f32::NAN)), SIDE_NORMAL, (no_axis, no_axis)),
        };
        let inside = |t: f32x8| (t.simd_gt(zero) & t.simd_lt(tmax)).to_bitmask() & active;
        let (nb, fb) = (inside(near), inside(far));
        let (tn, tf) = (near.to_array(), far.to_array());
        let mut lanes = nb | fb;
        while lanes != 0 {
            let l = lanes.trailing_zeros() as usize;
            lanes &= lanes - 1;
            if nb & (1 << l) != 0 {
                cr.push(l, Raw { t: tn[l], prim: pid, leaf: ax_near[l], flip: false, side: side_near });
            }
            if fb & (1 << l) != 0 {
                cr.push(l, Raw { t: tf[l], prim: pid, leaf: ax_far[l], flip: false, side: SIDE_EXIT });
            }
        }
    };
    for &pid in &scene.unbounded {
        prim_hits(pid, cr);
    }
    scene.bvh.traverse_any_x8(ray, |slot, r| {
        let pid = scene.leaf_spheres.prim[slot as usize];
        let prim = &scene.prims[pid as usize];
        if let Shape::Csg { solid } = prim.shape {
            let b = &scene.bounds[pid as usize];
            let (_, mask) = intersect_aabb_x8(b.min, b.max, &PacketRay::new(r), r.tmax);
            if mask.to_bitmask() != 0 {
                let local = in_prim_frame(r, prim.motion, time);
                let masked = Ray8 { tmax: mask.select(r.tmax, f32x8::splat(-1.0)), ..local };
                crossings_x8(&scene.csg, solid, &masked, f32x8::ZERO, arena, |l, h| {
                    cr.push(
                        l,
                        Raw { t: h.t, prim: pid, leaf: h.leaf, flip: h.flip, side: if h.entering { SIDE_ENTRY } else { SIDE_EXIT } },
                    );
                });
            }
        } else {
            prim_hits(pid, cr);
        }
        f32x8::ZERO
    });
}

/// The `eta` (`n1 / n2` of the side the light arrives from) at which a straight shadow ray's crossing
/// from index `n1` into `n2` is weighed under `transmissive_shadows`: from the rarer side at the ray's
/// angle, so never totally reflected (see the module doc).
#[inline(always)]
fn straight_eta(n1: f32, n2: f32) -> f32 {
    if n1 > n2 {
        n2 / n1
    } else {
        n1 / n2
    }
}

/// [`replay`] of the usual case, bit for bit: every crossing is a surface of one (not thin) dielectric, in
/// and out by turns (the start inside it when the first crossing leaves it). None otherwise. The medium
/// stack then only says whether the ray is inside, and every crossing is a real interface between the
/// medium and air.
#[inline(always)]
fn replay_one_medium(scene: &Scene, profile: &Profile, events: &[Event], len: f32) -> Option<Vec3> {
    let first = events.first()?;
    let m = first.material;
    let d = medium::dielectric(scene, m).filter(|d| !d.thin)?;
    if events.iter().enumerate().any(|(i, e)| e.material != m || e.entering != (first.entering == (i % 2 == 0))) {
        return None;
    }
    let n = d.ior.nominal();
    let absorbs = d.sigma_a != Vec3::ZERO;
    let mut inside = !first.entering;
    let mut tr = Vec3::ONE;
    let mut s_prev = 0.0;
    for e in events {
        if inside && absorbs {
            tr *= beer_lambert(d.sigma_a, e.s - s_prev);
        }
        s_prev = e.s;
        let (n1, n2) = if inside { (n, 1.0) } else { (1.0, n) };
        if n1 != n2 {
            if !profile.transmissive_shadows {
                return Some(Vec3::ZERO);
            }
            // (`e.tf` is `1 - fresnel_dielectric` at this eta, `straight_eta(n, 1)`.)
            tr *= if d.schlick { 1.0 - fresnel_schlick(e.cos, straight_eta(n1, n2)) } else { e.tf };
        }
        inside = !inside;
    }
    if inside && absorbs {
        tr *= beer_lambert(d.sigma_a, len - s_prev);
    }
    Some(tr)
}

/// Transmittance of one segment of length `len` from its recorded crossings (see the module doc), from
/// the media `start` where the segment's start is known to be inside some.
fn replay(scene: &Scene, profile: &Profile, events: &[Event], len: f32, start: MediumStack) -> Vec3 {
    if !start.is_empty() {
        return replay_stack(scene, profile, events, len, start);
    }
    match replay_one_medium(scene, profile, events, len) {
        Some(tr) => tr,
        None => replay_media(scene, profile, events, len),
    }
}

/// [`replay`] in general: a medium stack, nested media and their priorities, thin sheets.
fn replay_media(scene: &Scene, profile: &Profile, events: &[Event], len: f32) -> Vec3 {
    // Media around the start: those whose first crossing leaves them, outermost (left last) first.
    let mut starts: [(f32, u32); MAX_CROSSINGS] = [(0.0, 0); MAX_CROSSINGS];
    let mut n_starts = 0;
    for (i, e) in events.iter().enumerate() {
        let first = events[..i].iter().all(|p| p.material != e.material);
        if first && !e.entering && !medium::dielectric(scene, e.material).is_some_and(|d| d.thin) {
            starts[n_starts] = (e.s, e.material);
            n_starts += 1;
        }
    }
    starts[..n_starts].sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut stack = MediumStack::default();
    for &(_, m) in &starts[..n_starts] {
        stack = stack.push(m);
    }
    replay_stack(scene, profile, events, len, stack)
}

/// The replay of [`replay_media`] from the media `stack` around the segment's start.
fn replay_stack(scene: &Scene, profile: &Profile, events: &[Event], len: f32, stack: MediumStack) -> Vec3 {
    let mut stack = stack;
    let ior = |m: Option<u32>| m.and_then(|m| medium::dielectric(scene, m)).map_or(1.0, |d| d.ior.nominal());
    let absorb = |stack: MediumStack, dist: f32| medium::absorption(scene, stack, dist);
    let mut tr = Vec3::ONE;
    let mut s_prev = 0.0;
    for e in events {
        tr *= absorb(stack, e.s - s_prev);
        s_prev = e.s;
        let Some(d) = medium::dielectric(scene, e.material) else { return Vec3::ZERO };
        let fres = |cos: f32, eta: f32| if d.schlick { fresnel_schlick(cos, eta) } else { fresnel_dielectric(cos, eta) };
        if d.thin {
            let (n1, n2) = (ior(medium::current(scene, stack)), d.ior.nominal());
            if n1 != n2 {
                let r1 = fres(e.cos, n1 / n2);
                tr *= if r1 < 1.0 { 1.0 - 2.0 * r1 / (1.0 + r1) } else { 0.0 };
            }
            continue;
        }
        let c = medium::cross(scene, stack, e.material, e.entering);
        let (n1, n2) = (ior(c.before), ior(c.after));
        if c.is_real() && n1 != n2 {
            if !profile.transmissive_shadows {
                return Vec3::ZERO;
            }
            tr *= 1.0 - fres(e.cos, straight_eta(n1, n2));
        }
        stack = c.stack;
    }
    tr * absorb(stack, len - s_prev)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::parse_scene;

    /// `events` gives every crossing what the per-lane walk gave it, bit for bit: the distance, side and
    /// material, the cosine from the normal the shading stage's `surface_hit` finds (the point projected
    /// onto the leaf) or, for spheres and boxes, from the point and the slab's face, and the Fresnel
    /// transmission against air. Glass CSG solids of every leaf shape, rotated, scaled and moving, and a
    /// glass sphere, box and ellipsoid; segments from random points, half of them aimed through a point
    /// on an edge of a CSG box or cylinder leaf, where the face is decided by rounding. (Normals taken at
    /// the unprojected point there picked the neighbouring face: a user trial.)
    #[test]
    fn events_equal_the_per_lane_crossings() {
        let text = "[image]\nwidth = 4\nheight = 4\n[camera]\nposition = [0, 0, 9]\nlook_at = [0, 0, 0]\nfov = 40\nshutter = [0, 1]\n\
                    [materials.glass]\ntype = \"dielectric\"\nior = 1.5\n\
                    [materials.tinted]\ntype = \"dielectric\"\nior = 1.33\nabsorption = [0.5, 0.1, 0.0]\n\
                    [[shapes]]\ntype = \"csg\"\nop = \"difference\"\nmaterial = \"glass\"\n\
                    transform = { rotate = [30, 45, 0], scale = [0.9, 1.2, 0.8], translate = [-1.5, 0.5, 0] }\nchildren = [\n\
                      { type = \"box\", min = [-0.8, -0.8, -0.8], max = [0.8, 0.8, 0.8] },\n\
                      { type = \"sphere\", center = [0, 0, 0], radius = 0.6 },\n\
                      { type = \"cylinder\", radius = 0.3, height = 3.0 },\n]\n\
                    [[shapes]]\ntype = \"csg\"\nop = \"difference\"\nmaterial = \"tinted\"\nmotion = [0.4, 0.2, 0]\n\
                    transform = { rotate = [0, 20, 70], translate = [1.5, 0.5, 0] }\nchildren = [\n\
                      { type = \"csg\", op = \"union\", children = [\n\
                        { type = \"cone\", radius = 0.7, radius_top = 0.2, height = 1.2 },\n\
                        { type = \"torus\", major_radius = 0.6, minor_radius = 0.2 },\n] },\n\
                      { type = \"box\", min = [-0.2, -1, -1], max = [0.2, 1, 1] },\n\
                      { type = \"halfspace\", point = [0, 0.5, 0], normal = [0.2, 1, 0.1] },\n]\n\
                    [[shapes]]\ntype = \"sphere\"\ncenter = [0, -2, 0]\nradius = 0.7\nmaterial = \"glass\"\n\
                    [[shapes]]\ntype = \"box\"\nmin = [-2.5, -2.5, -0.5]\nmax = [-1.5, -1.5, 0.5]\nmaterial = \"glass\"\n\
                    transform = { rotate = [10, 0, 25] }\n\
                    [[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"tinted\"\n\
                    transform = { scale = [0.8, 0.4, 0.6], rotate = [0, 30, 0], translate = [2, -2, 0] }\n";
        let scene = parse_scene(std::path::Path::new("events.toml"), text).unwrap();
        // The CSG box and cylinder leaves, whose edges the aimed segments pass through.
        let edged: Vec<u32> = (0..scene.csg.leaf_count() as u32)
            .filter(|&i| matches!(scene.csg.leaf(i).shape, crate::csg::Shape::Box | crate::csg::Shape::Cylinder))
            .collect();
        assert_eq!(edged.len(), 3);
        let mut f = crate::sample::hash::test_uniforms(0xe7e7_5eed);
        let mut arena = CsgArena::new();
        let mut walk = Walk::new();
        walk.sphere_pairs = false;
        let profile = Profile::builtin("bench");
        let (mut crossings, mut csg) = (0usize, 0usize);
        for case in 0..8000 {
            let (mut o, mut d) = ([[0.0f32; LANES]; 3], [[0.0f32; LANES]; 3]);
            let (mut tmax, mut time) = ([0.0f32; LANES], [0.0f32; LANES]);
            for l in 0..LANES {
                let start = Vec3::new(f() - 0.5, f() - 0.5, f() - 0.5) * 8.0;
                let through = if (case + l) % 2 == 0 {
                    // A point on an edge of a box leaf (two coordinates at +-1) or on a cylinder's rim.
                    let leaf = scene.csg.leaf(edged[(f() * edged.len() as f32) as usize % edged.len()]);
                    let sign = |x: f32| if x < 0.5 { -1.0 } else { 1.0 };
                    let q = match leaf.shape {
                        crate::csg::Shape::Box => {
                            let mut q = Vec3::splat(f() * 2.0 - 1.0);
                            let axis = (f() * 3.0) as usize % 3;
                            q[axis] = sign(f());
                            q[(axis + 1) % 3] = sign(f());
                            q
                        }
                        _ => {
                            let a = f() * std::f32::consts::TAU;
                            Vec3::new(a.cos(), a.sin(), sign(f()))
                        }
                    };
                    leaf.object_to_world.transform_point3(q)
                } else {
                    Vec3::new(f() - 0.5, f() - 0.5, f() - 0.5) * 8.0
                };
                // (Past the aimed point: the segment crosses the edge, not ends on it.)
                let dir = (through - start) * 1.5;
                for a in 0..3 {
                    (o[a][l], d[a][l]) = (start[a], dir[a]);
                }
                (tmax[l], time[l]) = (1.0, if case % 3 == 0 { 0.0 } else { f() });
            }
            let lanes = (f() * 256.0) as u32 | 1;
            transmittance_x8(&scene, &profile, &o, &d, &tmax, &time, &[MediumStack::default(); LANES], lanes, &mut arena, &mut walk);
            for l in (0..LANES).filter(|&l| lanes & !walk.full & (1 << l) != 0) {
                let (o, d) = (Vec3::new(o[0][l], o[1][l], o[2][l]), Vec3::new(d[0][l], d[1][l], d[2][l]));
                let (len, unit) = (d.length(), d.normalize_or_zero());
                for k in 0..walk.count[l] {
                    let r = walk.raw[l][k];
                    let prim = &scene.prims[r.prim as usize];
                    let (n, material) = match prim.shape {
                        Shape::Sphere { center, .. } => {
                            ((o + d * r.t - (center + prim.motion * time[l])).normalize_or_zero(), prim.material)
                        }
                        Shape::Box(b) => (Mat3::from(b.world_to_object.matrix3).row(r.leaf as usize).normalize_or_zero(), prim.material),
                        _ => {
                            let h =
                                surface_hit(&scene, &RayItem { o, d, time: time[l], ..RayItem::default() }, r.t, r.prim, r.leaf, r.flip);
                            (h.n, h.material)
                        }
                    };
                    let cos = unit.dot(n);
                    let entering = if r.side == SIDE_NORMAL { cos < 0.0 } else { r.side == SIDE_ENTRY };
                    let tf = 1.0 - fresnel_dielectric(cos.abs(), air_eta(&scene, material));
                    let want = [(r.t * len).to_bits(), material, entering as u32, cos.abs().to_bits(), tf.to_bits()];
                    let e = walk.geo[l][k];
                    let got = [e.s.to_bits(), e.material, e.entering as u32, e.cos.to_bits(), e.tf.to_bits()];
                    assert_eq!(got, want, "case {case} lane {l} crossing {k} of prim {} leaf {}", r.prim, r.leaf);
                    crossings += 1;
                    csg += matches!(prim.shape, Shape::Csg { .. }) as usize;
                }
            }
        }
        assert!(crossings > 20_000 && csg > 16_000, "{crossings} crossings, {csg} of CSG leaves");
    }

    /// The 8-lane replay of sphere entry-exit pairs equals the per-lane one bit for bit: random segments
    /// (through, into, out of and past spheres of clear, absorbing, index-1 and Schlick dielectrics, a
    /// moving one, a glass CSG solid and an opaque box beside them) from random points, physical and
    /// transmissive shadows.
    #[test]
    fn sphere_pairs_x8_equal_the_per_lane_replay() {
        let text = "[image]\nwidth = 4\nheight = 4\n[camera]\nposition = [0, 0, 9]\nlook_at = [0, 0, 0]\nfov = 40\nshutter = [0, 1]\n\
                    [materials.glass]\ntype = \"dielectric\"\nior = 1.5\n\
                    [materials.tinted]\ntype = \"dielectric\"\nior = 1.33\nabsorption = [0.5, 0.1, 0.0]\n\
                    [materials.air]\ntype = \"dielectric\"\nior = 1.0\n\
                    [materials.schlick]\ntype = \"dielectric\"\nior = 1.5\nfresnel = \"schlick\"\n\
                    [materials.red]\ntype = \"lambert\"\nalbedo = [0.8, 0.1, 0.1]\n\
                    [[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"glass\"\n\
                    [[shapes]]\ntype = \"sphere\"\ncenter = [2.5, 0, 0]\nradius = 0.8\nmaterial = \"tinted\"\n\
                    [[shapes]]\ntype = \"sphere\"\ncenter = [-2.5, 0, 0]\nradius = 0.8\nmaterial = \"air\"\n\
                    [[shapes]]\ntype = \"sphere\"\ncenter = [0, 2.5, 0]\nradius = 0.7\nmaterial = \"schlick\"\n\
                    [[shapes]]\ntype = \"sphere\"\ncenter = [0, -2.5, 0]\nradius = 0.7\nmotion = [0.5, 0, 0]\nmaterial = \"glass\"\n\
                    [[shapes]]\ntype = \"box\"\nmin = [2, 2, -0.5]\nmax = [3, 3, 0.5]\nmaterial = \"red\"\n\
                    [[shapes]]\ntype = \"csg\"\nop = \"difference\"\nmaterial = \"glass\"\nchildren = [\n\
                      { type = \"box\", min = [-3, -3, -0.5], max = [-2, -2, 0.5] },\n\
                      { type = \"sphere\", center = [-2.5, -2.5, 0.5], radius = 0.4 },\n]\n";
        let scene = parse_scene(std::path::Path::new("pairs.toml"), text).unwrap();
        let mut f = crate::sample::hash::test_uniforms(0x9a1b_5eed);
        let mut arena = CsgArena::new();
        let (mut fast, mut slow) = (Walk::new(), Walk::new());
        slow.sphere_pairs = false;
        let mut paired = 0;
        for case in 0..6000 {
            let mut profile = Profile::builtin("bench");
            profile.transmissive_shadows = case % 4 != 0;
            let (mut o, mut d) = ([[0.0f32; LANES]; 3], [[0.0f32; LANES]; 3]);
            let mut tmax = [0.0f32; LANES];
            let mut time = [0.0f32; LANES];
            for l in 0..LANES {
                // From a random point to a random point, both in the spheres' region (segments that end
                // inside a sphere, start inside one, graze one or pass between them).
                for a in 0..3 {
                    o[a][l] = (f() - 0.5) * 8.0;
                    d[a][l] = (f() - 0.5) * 8.0 - o[a][l];
                }
                tmax[l] = if case % 3 == 0 { 1.0 } else { 0.2 + f() };
                time[l] = f();
            }
            let lanes = (f() * 256.0) as u32 | 1;
            let (a, _) =
                transmittance_x8(&scene, &profile, &o, &d, &tmax, &time, &[MediumStack::default(); LANES], lanes, &mut arena, &mut fast);
            let (b, _) =
                transmittance_x8(&scene, &profile, &o, &d, &tmax, &time, &[MediumStack::default(); LANES], lanes, &mut arena, &mut slow);
            let bits = |v: &[Vec3; LANES]| v.map(|t| t.to_array().map(f32::to_bits));
            assert_eq!(bits(&a), bits(&b), "case {case}");
            paired += sphere_pair_lanes(&scene, &profile, &fast, lanes & !fast.full).count_ones() as usize;
        }
        assert!(paired > 2500, "{paired} lanes took the 8-lane replay");
    }
    use rand_core::{Rng, SeedableRng};
    use rand_xoshiro::Xoshiro256PlusPlus;

    /// The one-medium replay is the general one, bit for bit, wherever it applies (alternating crossings
    /// of one dielectric: exact or Schlick Fresnel, absorbing or not, from outside or inside, physical or
    /// transmissive shadows), and declines every other sequence.
    #[test]
    fn one_medium_replay_equals_the_general_one() {
        let text = "[image]\nwidth = 4\nheight = 4\n[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\nfov = 40\n\
                    [materials.glass]\ntype = \"dielectric\"\nior = 1.5\nabsorption = [0.3, 0.1, 0.0]\n\
                    [materials.clear]\ntype = \"dielectric\"\nior = 1.33\nfresnel = \"schlick\"\n\
                    [materials.pane]\ntype = \"dielectric\"\nior = 1.5\nthin = true\n\
                    [[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"glass\"\n\
                    [[shapes]]\ntype = \"sphere\"\ncenter = [3, 0, 0]\nradius = 1\nmaterial = \"clear\"\n\
                    [[shapes]]\ntype = \"quad\"\norigin = [-5, 2, -5]\nu = [10, 0, 0]\nv = [0, 0, 10]\nmaterial = \"pane\"\n";
        let scene = parse_scene(std::path::Path::new("replay.toml"), text).unwrap();
        let id = |name: &str| {
            scene
                .materials
                .iter()
                .position(|m| {
                    matches!(m, Material::Dielectric(d) if match name {
                        "glass" => !d.thin && !d.schlick,
                        "clear" => d.schlick,
                        _ => d.thin,
                    })
                })
                .unwrap() as u32
        };
        let (glass, clear, pane) = (id("glass"), id("clear"), id("pane"));
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(3);
        let mut unit = || (rng.next_u32() >> 8) as f32 / (1u32 << 24) as f32;
        let (mut fast, mut declined) = (0, 0);
        for case in 0..20000 {
            let mut profile = Profile::builtin("bench");
            profile.transmissive_shadows = case % 3 != 0;
            let n = 1 + case % 6;
            let m = if case % 2 == 0 { glass } else { clear };
            let from_inside = case % 4 >= 2;
            let mut s = 0.0;
            let mut events: Vec<Event> = (0..n)
                .map(|i| {
                    s += 0.01 + 2.0 * unit();
                    Event { s, material: m, entering: (i % 2 == 0) != from_inside, cos: unit(), tf: 0.0 }
                })
                .collect();
            // Every fifth sequence is not one medium's: another medium, a thin pane, or out of turn.
            if case % 5 == 4 {
                let k = case % n;
                match (case / 5) % 3 {
                    0 => events[k].material = if m == glass { clear } else { glass },
                    1 => events[k].material = pane,
                    _ => events[k].entering = !events[k].entering,
                }
            }
            for e in &mut events {
                e.tf = 1.0 - fresnel_dielectric(e.cos, air_eta(&scene, e.material));
            }
            let len = s + unit();
            let general = replay_media(&scene, &profile, &events, len);
            match replay_one_medium(&scene, &profile, &events, len) {
                Some(t) => {
                    assert_eq!(t.to_array().map(f32::to_bits), general.to_array().map(f32::to_bits), "case {case}: {events:?}");
                    fast += 1;
                }
                None => {
                    assert_eq!(case % 5, 4, "case {case}: a one-medium sequence declined: {events:?}");
                    declined += 1;
                }
            }
        }
        assert_eq!((fast, declined), (16000, 4000));
    }
}
