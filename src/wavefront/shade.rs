//! Stage 4: shading. Hits are partitioned by material kind (a stable counting sort of hit indices), then
//! each kind runs its own loop: Lambert surfaces emit next-event requests (and diffuse bounces when the
//! profile asks for them); mirrors, glossy and dielectric surfaces spawn the next bounce's rays; emitters
//! and escaped rays add radiance to their path.

use super::dims;
use super::medium;
use super::pick::LightPick;
use super::queues::{
    HitQueue, MediumStack, NeeQueue, NeeRows, PathTable, RayItem, RayQueue, RayRows, FLAG_DIFFUSE, FLAG_GLOSSY, FLAG_SPECULAR, NONE,
};
use crate::geometry::{
    ellipsoid_hits_x8, normal_ellipsoid, normal_obox, normal_sphere, obox_hits_x8, offset_ray_origin_scaled, offset_ray_origin_scaled_x8,
    refine_ellipsoid_point, refine_flat_point, refine_flat_point_x8, refine_obox_point, refine_sphere_point, refine_sphere_point_x8,
};
use crate::light::{power_heuristic, sample_pdf, samples_for};
use crate::optics::{
    beer_lambert, fresnel_dielectric, fresnel_refract_x8, fresnel_schlick, reflect, reflect_x8, refract, sample_ggx_reflect_pdf_x8,
    sample_ggx_reflect_weight_x8, sample_ggx_reflect_x8, sample_hemisphere_cos_x8,
};
use crate::sample::{hash_combine, random_f32, stream_key, Sampler2d, Strategy};
use crate::scene::{checker_eval_x8, Branching, Dielectric, Material, MaterialKind, Profile, Scene, Shape, Texture, NOT_A_LIGHT};
use crate::simd::{consecutive8, f32x8, for_each_group, gather8, lane_bits, mask_from_bits, u32x8, Vec3x8, LANES};
use glam::Vec3;
use std::f32::consts::FRAC_1_PI;

/// Bucket of rays that hit nothing.
const MISS_BUCKET: usize = MaterialKind::COUNT;

/// Everything shading needs about one hit, computed once.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceHit {
    /// Hit point (refined where the shape allows).
    pub p: Vec3,
    /// Outward geometric normal of the surface (of the CSG result, for CSG hits).
    pub n: Vec3,
    /// `n` turned to face the incoming ray.
    pub n_facing: Vec3,
    /// The ray arrives on the outside of the surface.
    pub front: bool,
    pub material: u32,
    /// The magnitude whose ULPs bound the error of `p` (beyond `p`'s own): the ray origin's for a point
    /// computed as `o + t d`; for a point re-projected onto its surface, the surface's placement's (0 for
    /// a still sphere, which is re-projected exactly) and a moving prim's shift at the ray's time.
    pub error_scale: f32,
}

impl SurfaceHit {
    /// Origin of a ray leaving the surface towards `side` (`n_facing` or `-n_facing`).
    #[inline]
    pub fn spawn(&self, side: Vec3) -> Vec3 {
        offset_ray_origin_scaled(self.p, side, self.error_scale)
    }
}

/// Geometry at the nearest hit of ray `r`.
#[inline(always)]
pub fn surface_hit(scene: &Scene, r: &RayItem, t: f32, prim_id: u32, leaf: u32, flip: bool) -> SurfaceHit {
    let prim = &scene.prims[prim_id as usize];
    let shift = prim.motion * r.time;
    let mut p = r.o + r.d * t;
    let mut material = prim.material;
    // `o + t d` is accurate to ULPs of `|o|`: every shape's point is re-projected onto its surface (in
    // the prim's frame at the ray's time), after which its error is ULPs of the surface's own placement
    // (see `geometry::refine`); where a projection is undefined the point keeps `|o|`.
    let mut error_scale = r.o.abs().max_element();
    let refined = |q: Option<(Vec3, f32)>, p: &mut Vec3, error_scale: &mut f32| {
        if let Some((q, s)) = q {
            *p = q + shift;
            *error_scale = s.max(shift.abs().max_element());
        }
    };
    let n = match &prim.shape {
        Shape::Sphere { center, radius } => {
            let c = *center + shift;
            p = refine_sphere_point(c, *radius, p);
            // Exact for a still sphere; a moving one's frame at the ray's time is rounded to ULPs of the
            // shift, as the other shapes' (with 0, a ray entering a moving glass ball near the world
            // origin was spawned inside the kernel's error, met the same surface again and again, and
            // filled its medium stack: a user trial).
            error_scale = shift.abs().max_element();
            normal_sphere(c, p)
        }
        Shape::Ellipsoid(e) => {
            refined(refine_ellipsoid_point(e, p - shift), &mut p, &mut error_scale);
            normal_ellipsoid(e, p - shift)
        }
        Shape::Plane(_) | Shape::Quad(_) | Shape::Disk(_) => {
            let g = &scene.prim_geo[prim_id as usize];
            refined(Some((refine_flat_point(p - shift, g.v, g.w), g.w_scale)), &mut p, &mut error_scale);
            g.v
        }
        Shape::Box(b) => {
            refined(refine_obox_point(b, p - shift), &mut p, &mut error_scale);
            normal_obox(b, p - shift)
        }
        Shape::Csg { .. } => {
            debug_assert!(leaf != NONE);
            let l = scene.csg.leaf(leaf);
            material = l.material;
            refined(l.refine(p - shift), &mut p, &mut error_scale);
            let n = l.normal(p - shift);
            if flip {
                -n
            } else {
                n
            }
        }
    };
    let front = r.d.dot(n) < 0.0;
    SurfaceHit { p, n, n_facing: if front { n } else { -n }, front, material, error_scale }
}

/// [`surface_hit`]'s geometry of 8 sphere hits, the same operations lane by lane: the point `naive` =
/// o + t d re-projected onto the sphere (centres `sc`, radii `sr`) in f64, the normalised radial normal
/// (zero where it cannot be normalised), and whether the ray (direction `d`) arrives on the outside.
#[inline(always)]
fn sphere_hits_x8(naive: Vec3x8, d: Vec3x8, sc: &[[f32; LANES]; 3], sr: &[f32; LANES]) -> (Vec3x8, Vec3x8, f32x8) {
    let ps = Vec3x8::from_rows(&refine_sphere_point_x8(sc, sr, &naive.rows()));
    let rel = ps - Vec3x8::from_rows(sc);
    let rcp = f32x8::ONE / rel.dot_unfused(rel).sqrt();
    let ok = rcp.is_finite() & rcp.simd_gt(f32x8::ZERO);
    let n = Vec3x8::select(ok, rel.scale(rcp), Vec3x8::splat(Vec3::ZERO));
    (ps, n, d.dot_unfused(n).simd_lt(f32x8::ZERO))
}

/// [`surface_hit`]'s point and error magnitude of 8 flat hits (planes `n . x = w` at time 0, moved by
/// `shift`; `scale` the planes' error magnitudes), the same operations lane by lane.
#[inline(always)]
fn flat_hits_x8(naive: Vec3x8, n: Vec3x8, shift: Vec3x8, w: f32x8, scale: f32x8) -> (Vec3x8, f32x8) {
    let p = refine_flat_point_x8(naive - shift, n, w) + shift;
    (p, scale.max(shift.x.abs().max(shift.y.abs()).max(shift.z.abs())))
}

/// [`surface_hit`]'s geometry of up to 8 hits as lane rows (lanes past those given are unspecified).
#[derive(Clone, Copy)]
struct HitRows {
    p: Vec3x8,
    n_facing: Vec3x8,
    error_scale: f32x8,
    /// Lanes whose ray arrives on the outside.
    front: u32,
    material: [u32; LANES],
    /// Sphere lanes, and among them the static spheres' (their centre does not move with time).
    sph: u32,
    still: u32,
    /// All 8 lanes hit one sphere or flat prim.
    uniform: bool,
}

/// Hits' point, outward normal and error magnitude (`hit`) into the lanes `same` of a chunk's rows
/// (`rows`: point, facing normal, error magnitude), the normal turned to face the ray (direction `d`)
/// as `surface_hit` turns it, and their sides into `front`.
#[inline(always)]
fn rows_into(
    same: u32,
    hit: (Vec3x8, Vec3x8, f32x8),
    rows: (Vec3x8, Vec3x8, f32x8),
    front: &mut u32,
    d: Vec3x8,
) -> (Vec3x8, Vec3x8, f32x8) {
    let (p, n, scale) = hit;
    let ahead = d.dot_unfused(n).simd_lt(f32x8::ZERO);
    let mask = mask_from_bits(same);
    *front |= ahead.to_bitmask() & same;
    let facing = Vec3x8::select(ahead, n, Vec3x8::new(-n.x, -n.y, -n.z));
    (Vec3x8::select(mask, p, rows.0), Vec3x8::select(mask, facing, rows.1), mask.select(scale, rows.2))
}

/// [`surface_hit`] of hits `idx` of a queue (`m` lanes), for rays `o + t d` (lane rows) at `times`
/// hitting `prims`, bit for bit: spheres and flat prims (planes, quads, disks: the common cases) in 8
/// lanes with the same operations, boxes, ellipsoids and CSG hits in 8 lanes per distinct prim or leaf
/// (`obox_hits_x8`, `ellipsoid_hits_x8`, `Leaf::refine_x8`, `Leaf::normal_x8`).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn hit_rows_x8(
    scene: &Scene,
    hits: &HitQueue,
    idx: &[u32],
    o: Vec3x8,
    d: Vec3x8,
    t: &[f32; LANES],
    times: &[f32; LANES],
    prims: &[u32; LANES],
) -> HitRows {
    // o + t d, as `surface_hit` computes it (unfused).
    let naive = o + d.scale(f32x8::from(*t));
    let flip = |ahead: f32x8, n: Vec3x8| Vec3x8::select(ahead, n, Vec3x8::new(-n.x, -n.y, -n.z));
    // Eight hits on one sphere or flat prim (the usual chunk: coherent rays, sorted by material):
    // the prim's record once, as vectors (lane-by-lane stores would stall the vector loads after them).
    let g = &scene.prim_geo[prims[0] as usize];
    let uniform = idx.len() == LANES && u32x8::from(*prims).simd_eq(u32x8::splat(prims[0])).all() && (g.r > 0.0 || g.r == -1.0);
    if uniform {
        let (all, material) = (u32::MAX >> (32 - LANES), [g.material; LANES]);
        if g.r > 0.0 {
            // The centre at each ray's time, as the lane loop below computes it.
            let shift = Vec3x8::splat(g.motion).scale(f32x8::from(*times));
            let sc = (Vec3x8::splat(g.v) + shift).rows();
            let (p, n, ahead) = sphere_hits_x8(naive, d, &sc, &[g.r; LANES]);
            let still = if g.motion == Vec3::ZERO { all } else { 0 };
            let front = ahead.to_bitmask();
            let error_scale = shift.max_abs_element();
            return HitRows { p, n_facing: flip(ahead, n), error_scale, front, material, sph: all, still, uniform };
        }
        let n = Vec3x8::splat(g.v);
        let ahead = d.dot_unfused(n).simd_lt(f32x8::ZERO);
        let shift = Vec3x8::splat(g.motion).scale(f32x8::from(*times));
        let (p, error_scale) = flat_hits_x8(naive, n, shift, f32x8::splat(g.w), f32x8::splat(g.w_scale));
        return HitRows { p, n_facing: flip(ahead, n), error_scale, front: ahead.to_bitmask(), material, sph: 0, still: 0, uniform };
    }
    let mut nf = [[0.0f32; LANES]; 3];
    let mut material = [0u32; LANES];
    let (mut sph, mut still, mut pla, mut front) = (0u32, 0u32, 0u32, 0u32);
    let mut sc = [[0.0f32; LANES]; 3];
    let mut sr = [1.0f32; LANES];
    // Sphere lanes' error magnitudes: their shifts' (see `surface_hit`).
    let mut ss = [0.0f32; LANES];
    // Flat lanes' planes and motion shifts.
    let (mut fw, mut fs, mut fshift) = ([0.0f32; LANES], [0.0f32; LANES], [[0.0f32; LANES]; 3]);
    // CSG lanes taken in 8 lanes: their leaves, and those whose leaf is subtracted (normal flipped).
    let (mut csg, mut flipped, mut leaf_of) = (0u32, 0u32, [0u32; LANES]);
    // Box and ellipsoid lanes (after the loop, per distinct prim).
    let mut solids = 0u32;
    for (l, &i) in idx.iter().enumerate() {
        let g = &scene.prim_geo[prims[l] as usize];
        if g.r > 0.0 {
            sph |= 1 << l;
            still |= ((g.motion == Vec3::ZERO) as u32) << l;
            let shift = g.motion * times[l];
            let c = g.v + shift;
            for k in 0..3 {
                sc[k][l] = c[k];
            }
            ss[l] = shift.abs().max_element();
            sr[l] = g.r;
            material[l] = g.material;
        } else if g.r == -1.0 {
            // Flat prims: their outward normal here.
            pla |= 1 << l;
            for (row, c) in nf.iter_mut().zip(g.v.to_array()) {
                row[l] = c;
            }
            let shift = g.motion * times[l];
            for (row, c) in fshift.iter_mut().zip(shift.to_array()) {
                row[l] = c;
            }
            (fw[l], fs[l]) = (g.w, g.w_scale);
            material[l] = g.material;
        } else if matches!(scene.prims[prims[l] as usize].shape, Shape::Box(_) | Shape::Ellipsoid(_)) {
            // (Ellipsoids: spheres under a non-uniform scale.)
            solids |= 1 << l;
        } else {
            // CSG leaves (every other shape is taken above): after the loop, per distinct leaf.
            debug_assert!(matches!(scene.prims[prims[l] as usize].shape, Shape::Csg { .. }));
            csg |= 1 << l;
            leaf_of[l] = hits.leaf[i as usize];
            flipped |= (hits.flip[i as usize] as u32) << l;
        }
    }
    // (Every lane's point and error magnitude are set by its kind's pass below.)
    let (mut pv, mut nv, mut sv) = (Vec3x8::splat(Vec3::ZERO), Vec3x8::from_rows(&nf), f32x8::ZERO);
    if pla != 0 {
        // The point o + t d projected onto the plane, and the normal turned to face the ray.
        let (fp, fscale) = flat_hits_x8(naive, nv, Vec3x8::from_rows(&fshift), f32x8::from(fw), f32x8::from(fs));
        (pv, nv, sv) = rows_into(pla, (fp, nv, fscale), (pv, nv, sv), &mut front, d);
    }
    for_each_group(
        solids,
        |l| prims[l],
        |first, same| {
            // `surface_hit` of the hits on one box or ellipsoid: the point moved onto it in its frame at the
            // ray's time (or left where that is undefined), the normal there.
            let prim = &scene.prims[prims[first] as usize];
            let shift = Vec3x8::splat(prim.motion).scale(f32x8::from(*times));
            let point = |q: Vec3x8, ok: f32x8| Vec3x8::select(ok, q + shift, naive);
            let at = |q, ok| point(q, ok) - shift;
            let (q, s, ok, n) = match &prim.shape {
                Shape::Box(b) => obox_hits_x8(b, naive - shift, at),
                Shape::Ellipsoid(e) => ellipsoid_hits_x8(e, naive - shift, at),
                _ => unreachable!("a box or ellipsoid lane"),
            };
            let scale = ok.select(s.max(shift.max_abs_element()), o.max_abs_element());
            (pv, nv, sv) = rows_into(same, (point(q, ok), n, scale), (pv, nv, sv), &mut front, d);
            for l in (0..LANES).filter(|&l| same & (1 << l) != 0) {
                material[l] = prim.material;
            }
        },
    );
    for_each_group(
        csg,
        |l| (prims[l], leaf_of[l]),
        |first, same| {
            // `surface_hit` of the hits on one leaf: the point refined in the leaf's frame at the ray's time
            // (or left where that is undefined, with the error magnitude of the origin), the leaf's normal
            // there, flipped for a subtracted leaf.
            let (prim, leaf) = (&scene.prims[prims[first] as usize], scene.csg.leaf(leaf_of[first]));
            let shift = Vec3x8::splat(prim.motion).scale(f32x8::from(*times));
            let (q, s, ok) = leaf.refine_x8(naive - shift);
            let p = Vec3x8::select(ok, q + shift, naive);
            let scale = ok.select(s.max(shift.max_abs_element()), o.max_abs_element());
            let n = leaf.normal_x8(p - shift);
            let n = Vec3x8::select(mask_from_bits(flipped), Vec3x8::new(-n.x, -n.y, -n.z), n);
            (pv, nv, sv) = rows_into(same, (p, n, scale), (pv, nv, sv), &mut front, d);
            for l in (0..LANES).filter(|&l| same & (1 << l) != 0) {
                material[l] = leaf.material;
            }
        },
    );
    if sph != 0 {
        let (ps, n, ahead) = sphere_hits_x8(naive, d, &sc, &sr);
        let mask = mask_from_bits(sph);
        pv = Vec3x8::select(mask, ps, pv);
        nv = Vec3x8::select(mask, flip(ahead, n), nv);
        sv = mask.select(f32x8::from(ss), sv);
        front |= ahead.to_bitmask() & sph;
    }
    HitRows { p: pv, n_facing: nv, error_scale: sv, front, material, sph, still, uniform }
}

/// Random-number stream of one path branch: stratified dimensions index it by sample.
#[inline]
pub fn branch_stream(pixel: u32, branch: u32) -> u64 {
    hash_combine(pixel as u64, branch as u64)
}

/// Stream shared by the shading points of one pixel, branch and depth across the pixel's samples: light
/// samples are stratified over all of them (index = sample x light_samples + j).
#[inline]
pub fn point_key(pixel: u32, branch: u32, depth: u16) -> u64 {
    hash_combine(branch_stream(pixel, branch), depth as u64)
}

#[inline]
fn child_branch(branch: u32, depth: u16, which: u32) -> u32 {
    (hash_combine(hash_combine(branch as u64, depth as u64), which as u64) >> 32) as u32 | 1
}

/// Index of refraction of a dielectric material at the ray's wavelength (air = 1 for no material).
#[inline]
fn ior_of(scene: &Scene, m: Option<u32>, lambda: f32, dispersive: bool) -> f32 {
    match m.map(|m| &scene.materials[m as usize]) {
        Some(Material::Dielectric(d)) => {
            if dispersive {
                d.ior.at(lambda)
            } else {
                d.ior.nominal()
            }
        }
        _ => 1.0,
    }
}

pub struct ShadeOut<'a> {
    pub paths: &'a mut PathTable,
    pub next: &'a mut RayQueue,
    pub nee: &'a mut NeeQueue,
}

/// Shade every hit of `rays`; returns the number of crossings into a medium that a ray's full medium
/// stack could not keep (a fifth nested medium: its absorption and index are lost for that ray).
#[allow(clippy::too_many_arguments)]
pub fn shade(scene: &Scene, profile: &Profile, seed: u64, rays: &RayQueue, hits: &HitQueue, order: &mut Vec<u32>, out: ShadeOut) -> u64 {
    let n = rays.len();
    // The light selection, made when a glossy lobe ray first finds a light.
    let pick = std::cell::OnceCell::new();
    // Stable counting sort of ray indices by material kind (misses last).
    let mut counts = [0usize; MaterialKind::COUNT + 2];
    let bucket = |i: usize| -> usize {
        match (hits.prim[i], hits.leaf[i]) {
            (NONE, _) => MISS_BUCKET,
            (p, NONE) => scene.prim_kind[p as usize] as usize,
            (_, leaf) => scene.leaf_kind[leaf as usize] as usize,
        }
    };
    // `order` holds each ray's bucket in its first half (computed once) and the partition in its second
    // (one slot more: see below).
    order.clear();
    order.resize(2 * n + 1, 0);
    // Four sets of counters, taken in turn: one set would make each hit's increment wait for the last
    // (most hits have the same kind).
    let mut count4 = [[0usize; MaterialKind::COUNT + 2]; 4];
    for (i, slot) in order[..n].iter_mut().enumerate() {
        let b = bucket(i);
        *slot = b as u32;
        count4[i & 3][b + 1] += 1;
    }
    for k in 1..counts.len() {
        counts[k] = counts[k - 1] + count4[0][k] + count4[1][k] + count4[2][k] + count4[3][k];
    }
    let (buckets, sorted) = order.split_at_mut(n);
    // One pass over the queue per kind present, without a branch per ray: every index is written at
    // the kind's next free slot, which only the kind's rays take (a foreign index left there is
    // overwritten by the kind's next ray or, past the kind's block, by the next kind's pass; the spare
    // slot takes the last kind's). Session 23 replaced a scan run by run (each run of one kind as one
    // block): bounce queues alternate hits and misses at random, so their runs are short; peer scene
    // (b)'s shade stage at 16 spp, one thread, 0.2357 -> 0.2135 CPU s together with the skipped misses
    // of a black background, and camera queues (long runs, several kinds: showcase, glass) within the
    // runs' spread.
    for b in 0..counts.len() - 1 {
        let (start, end) = (counts[b], counts[b + 1]);
        if start == end {
            continue;
        }
        let mut at = start;
        for (i, &k) in buckets.iter().enumerate() {
            sorted[at] = i as u32;
            at += (k == b as u32) as usize;
        }
        debug_assert_eq!(at, end);
    }
    let order = &sorted[..n];

    let ctx = Ctx::new(scene, profile, seed);
    let ShadeOut { paths, next, nee } = out;
    // The point key of the last Lambert hit: a pixel's samples are usually consecutive and share it.
    let mut last_point = KeyMemo::default();
    for b in 0..=MaterialKind::COUNT {
        if b == MaterialKind::Lambert as usize {
            for chunk in order[counts[b]..counts[b + 1]].chunks(LANES) {
                ctx.lambert_x8(rays, hits, chunk, paths, nee, next, &mut last_point);
            }
            continue;
        }
        if b == MISS_BUCKET {
            // Escaped rays: only their path, throughput and (rarely) medium are needed; nothing to add
            // under a black background.
            if scene.background == Vec3::ZERO {
                continue;
            }
            for &i in &order[counts[b]..counts[b + 1]] {
                let i = i as usize;
                let mut thr = Vec3::new(rays.tr[i], rays.tg[i], rays.tb[i]);
                if rays.media[i] != MediumStack::default() {
                    let mut r = rays.get(i);
                    absorb(scene, &mut r, hits.t[i]);
                    thr = r.throughput;
                }
                paths.add(rays.path[i], thr * scene.background);
            }
            continue;
        }
        if b == MaterialKind::Mirror as usize || b == MaterialKind::Dielectric as usize {
            for chunk in order[counts[b]..counts[b + 1]].chunks(LANES) {
                ctx.specular_x8(rays, hits, chunk, paths, next);
            }
            continue;
        }
        if b == MaterialKind::Glossy as usize {
            for chunk in order[counts[b]..counts[b + 1]].chunks(LANES) {
                ctx.glossy_x8(rays, hits, chunk, paths, nee, next);
            }
            continue;
        }
        // Emitters: which side each of 8 hits arrives on (`hit_rows_x8`), then each hit's radiance.
        for chunk in order[counts[b]..counts[b + 1]].chunks(LANES) {
            let at = |l: usize| chunk[l.min(chunk.len() - 1)] as usize;
            let lanes = |v: &[f32]| std::array::from_fn(|l| v[at(l)]);
            let (o, d) = (
                Vec3x8::from_rows(&[lanes(&rays.ox), lanes(&rays.oy), lanes(&rays.oz)]),
                Vec3x8::from_rows(&[lanes(&rays.dx), lanes(&rays.dy), lanes(&rays.dz)]),
            );
            let times = if rays.with_time { lanes(&rays.time) } else { [0.0; LANES] };
            let prims = std::array::from_fn(|l| hits.prim[at(l)]);
            let geo = hit_rows_x8(scene, hits, chunk, o, d, &lanes(&hits.t), &times, &prims);
            for (l, &i) in chunk.iter().enumerate() {
                let i = i as usize;
                let mut r = rays.get(i);
                absorb(scene, &mut r, hits.t[i]);
                match &scene.materials[geo.material[l] as usize] {
                    Material::Emissive { radiance } => {
                        let prim = &scene.prims[hits.prim[i] as usize];
                        // Sampled lights were already counted by next-event estimation at a diffuse vertex;
                        // at a glossy one, in part: the lobe ray's share is its MIS weight.
                        if geo.front & (1 << l) != 0 && !(prim.is_light && r.flags & FLAG_DIFFUSE != 0) {
                            if prim.is_light && r.flags & FLAG_GLOSSY != 0 && rays.with_pdf {
                                let pick = pick.get_or_init(|| LightPick::cached(scene, profile));
                                // (A `center` lobe's ray: its light is the light samples' alone, nothing
                                // added here.)
                                if profile.glossy_strategy != Strategy::Center {
                                    let w = lobe_light_weight(scene, profile, pick.as_deref(), hits.prim[i], &r, hits.t[i]);
                                    paths.add(r.path, r.throughput * *radiance * w);
                                }
                            } else {
                                paths.add(r.path, r.throughput * *radiance);
                            }
                        }
                    }
                    // Shaded 8 at a time by `Ctx::lambert_x8`, `Ctx::specular_x8` and `Ctx::glossy_x8`.
                    Material::Lambert { .. } | Material::Mirror { .. } | Material::Dielectric(_) | Material::Glossy { .. } => {
                        unreachable!("Lambert, mirror, dielectric and glossy hits are shaded 8 at a time")
                    }
                }
            }
        }
    }
    ctx.lost_media.get()
}

/// The MIS weight (power heuristic) of glossy lobe ray `r` that found light `prim` at `t`: its own density
/// (`r.pdf`, one sample) against the light's `light_samples` samples, seen from the glossy point the ray
/// left (`r.travel` back from `r.o`: it may have crossed surfaces unbent since), x the probability that
/// the point picks this light (`pick`, where the profile picks one light per point).
fn lobe_light_weight(scene: &Scene, profile: &Profile, pick: Option<&LightPick>, prim: u32, r: &RayItem, t: f32) -> f32 {
    match scene.light_of_prim.get(prim as usize).copied().filter(|&l| l != NOT_A_LIGHT) {
        Some(li) => {
            let li = li as usize;
            let light = &scene.lights[li];
            // Seen from the glossy point: `travel` back along the (unbent) direction from the origin.
            let ns = samples_for(light, profile.light_samples) as f32;
            let p = r.o - r.d.normalize() * r.travel;
            let pdf = sample_pdf(light, p, r.o + r.d * t);
            let pdf = pick.map_or(pdf, |pick| pdf * pick.prob(p, li));
            power_heuristic(1.0, r.pdf, ns * pdf)
        }
        None => 1.0,
    }
}

/// Beer-Lambert absorption along the segment just travelled inside a medium (of length `t |d|`).
#[inline(always)]
fn absorb(scene: &Scene, r: &mut RayItem, t: f32) {
    r.throughput *= medium::absorption(scene, r.media, t * r.d.length());
}

/// [`absorb`] for lane `l` of a chunk (ray `i`, in a medium of `stack`, `t` along it), into the lane's
/// throughput rows `thr`: only the ray's direction is read (not the whole ray), and the rows are left
/// alone where the medium is clear (transmittance 1, as in every glass without absorption).
#[inline(always)]
fn absorb_lane(scene: &Scene, rays: &RayQueue, i: usize, stack: MediumStack, t: f32, thr: &mut [[f32; LANES]; 3], l: usize) {
    let d = Vec3::new(rays.dx[i], rays.dy[i], rays.dz[i]);
    let k = medium::absorption(scene, stack, t * d.length());
    if k != Vec3::ONE {
        for (row, c) in thr.iter_mut().zip(k.to_array()) {
            row[l] *= c;
        }
    }
}

/// Beer-Lambert over the stretch a child ray skips at its spawn: its origin `o` is off the surface point
/// `p` by the spawn offset (256 ULPs of the coordinates), into the medium it travels in (`media`), and
/// [`absorb`] counts its segment from `o`. Without this, each segment inside an absorbing medium was
/// short by the offset along the ray: a trial's 2 mm glass cube 1.7 from the origin let through 6.3%
/// too much (`(o - p) . d / |d|`, about 6e-5 of 2e-3 per segment). 1 outside absorbing media.
#[inline(always)]
fn spawn_absorption(scene: &Scene, media: MediumStack, p: Vec3, o: Vec3, d: Vec3) -> Vec3 {
    if media == MediumStack::default() {
        return Vec3::ONE;
    }
    match medium::current(scene, media).map(|m| &scene.materials[m as usize]) {
        Some(Material::Dielectric(x)) if x.sigma_a != Vec3::ZERO => {
            let lead = ((o - p).dot(d) / d.length()).max(0.0);
            let k = x.sigma_a.max(Vec3::ZERO) * lead;
            // (The stretch is some 1e-5 of the coordinates: `e^-k` by its series, whose next term,
            // k^3 / 6, is below f32's resolution there, saving three `exp` per child.)
            if k.max_element() < 1e-4 {
                Vec3::ONE - k + k * k * 0.5
            } else {
                beer_lambert(x.sigma_a, lead)
            }
        }
        _ => Vec3::ONE,
    }
}

/// The last key computed for a (pixel, branch, depth): a pixel's samples are consecutive in the queues,
/// so their hits usually ask for the same stream key one after another.
#[derive(Default)]
struct KeyMemo(Option<((u32, u32, u16), u64)>);

impl KeyMemo {
    #[inline(always)]
    fn get(&mut self, id: (u32, u32, u16), make: impl FnOnce() -> u64) -> u64 {
        match self.0 {
            Some((last, key)) if last == id => key,
            _ => {
                let key = make();
                self.0 = Some((id, key));
                key
            }
        }
    }
}

/// A child ray inheriting the parent's bookkeeping, one bounce deeper.
#[inline]
fn next_of(r: &RayItem) -> RayItem {
    RayItem { tmax: f32::INFINITY, depth: r.depth + 1, ..*r }
}

struct Ctx<'a> {
    scene: &'a Scene,
    profile: &'a Profile,
    seed: u64,
    /// The diffuse-bounce and glossy-lobe samplers (the profile's strategies over the pixel's samples).
    diffuse: Sampler2d,
    glossy: Sampler2d,
    /// Crossings into a medium the ray's stack was too full to keep ([`medium::Crossing::lost`]).
    lost_media: std::cell::Cell<u64>,
}

impl<'a> Ctx<'a> {
    fn new(scene: &'a Scene, profile: &'a Profile, seed: u64) -> Self {
        let sampler = |s| Sampler2d::new(s, profile.spp);
        Ctx {
            scene,
            profile,
            seed,
            diffuse: sampler(profile.diffuse_strategy),
            glossy: sampler(profile.glossy_strategy),
            lost_media: Default::default(),
        }
    }

    /// Up to 8 Lambert hits (`idx`, ray indices): the geometry of each hit (shape dispatch) and its
    /// albedo lane by lane, then the next-event request's weight and shadow-ray origin as 8-lane
    /// arithmetic, appended to the request queue as rows; diffuse bounces, when the profile asks for
    /// them, lane by lane. Same requests and rays, in the same order, as shading the hits one by one.
    #[allow(clippy::too_many_arguments)]
    // Out of line (one call per 8 hits): keeps it a separate entry in profiles.
    #[inline(never)]
    fn lambert_x8(
        &self,
        rays: &RayQueue,
        hits: &HitQueue,
        idx: &[u32],
        paths: &mut PathTable,
        nee: &mut NeeQueue,
        next: &mut RayQueue,
        last_point: &mut KeyMemo,
    ) {
        let (scene, profile) = (self.scene, self.profile);
        let m = idx.len();
        // Ray fields as lane arrays, straight from the queue: one vector load per field when the chunk
        // is a run of consecutive rays (the usual case: a queue whose hits are mostly Lambert), else one
        // load per lane. Lanes past `m` repeat the chunk's last ray.
        let i0 = idx[0] as usize;
        let run = m == LANES && idx[LANES - 1] as usize == i0 + LANES - 1;
        let at = |l: usize| idx[l.min(m - 1)] as usize;
        let ro = [gather8(&rays.ox, run, i0, at), gather8(&rays.oy, run, i0, at), gather8(&rays.oz, run, i0, at)];
        let rd = [gather8(&rays.dx, run, i0, at), gather8(&rays.dy, run, i0, at), gather8(&rays.dz, run, i0, at)];
        let mut thr = [gather8(&rays.tr, run, i0, at), gather8(&rays.tg, run, i0, at), gather8(&rays.tb, run, i0, at)];
        let rt = gather8(&hits.t, run, i0, at);
        let times = if rays.with_time { gather8(&rays.time, run, i0, at) } else { [0.0; LANES] };
        let path = gather8(&rays.path, run, i0, at);
        let branch = gather8(&rays.branch, run, i0, at);
        let depth = gather8(&rays.depth, run, i0, at);
        let media = gather8(&rays.media, run, i0, at);
        let prims = gather8(&hits.prim, run, i0, at);

        let geo = hit_rows_x8(scene, hits, idx, Vec3x8::from_rows(&ro), Vec3x8::from_rows(&rd), &rt, &times, &prims);
        let mut tex_a = [[0.0f32; LANES]; 3];
        let mut tex_b = [[0.0f32; LANES]; 3];
        let mut tex_scale = [1.0f32; LANES];
        let mut shift = [[0.0f32; LANES]; 3];
        // Each lane's pixel and sample index: one load each when the paths are consecutive (camera
        // hits in queue order).
        let consecutive = m == LANES && consecutive8(&path);
        let (p0, at_path) = (path[0] as usize, |l: usize| path[l] as usize);
        let (pixels, samples) = (gather8(&paths.pixel, consecutive, p0, at_path), gather8(&paths.sample, consecutive, p0, at_path));
        // The point keys: one when the chunk is one pixel's samples at one vertex (from 8 samples per
        // pixel on, the usual case), else each lane's (consecutive lanes usually share it).
        let one = |l: usize| (pixels[l], branch[l], depth[l]);
        let keys = if (1..LANES).all(|l| one(l) == one(0)) {
            [last_point.get(one(0), || point_key(pixels[0], branch[0], depth[0])); LANES]
        } else {
            // (A plain loop: `array::from_fn` here was an out-of-line call per lane.)
            let mut k = [0u64; LANES];
            for l in 0..LANES {
                k[l] = last_point.get(one(l), || point_key(pixels[l], branch[l], depth[l]));
            }
            k
        };
        // Lanes with a checker texture (the others take their constant colour). The time shift is kept
        // even without motion: `motion * 0` can be -0, and a centre plus -0 is what `surface_hit`
        // computes.
        let mut checker = 0u32;
        let albedo_of = |l: usize| {
            let Material::Lambert { albedo } = &scene.materials[geo.material[l] as usize] else {
                unreachable!("lambert_x8 is given Lambert hits only")
            };
            *albedo
        };
        if geo.uniform {
            // One prim, one texture: its constants as vectors.
            match albedo_of(0) {
                Texture::Constant(a) => tex_a = Vec3x8::splat(a).rows(),
                Texture::Checker { a, b, scale } => {
                    checker = (1 << m) - 1;
                    (tex_a, tex_b, tex_scale) = (Vec3x8::splat(a).rows(), Vec3x8::splat(b).rows(), [scale; LANES]);
                    shift = Vec3x8::splat(scene.prim_geo[prims[0] as usize].motion).scale(f32x8::from(times)).rows();
                }
            }
        } else {
            for l in 0..m {
                match albedo_of(l) {
                    Texture::Constant(a) => {
                        for c in 0..3 {
                            tex_a[c][l] = a[c];
                        }
                    }
                    // The second colour, scale and frame shift only for checker lanes (the others take
                    // their constant below).
                    Texture::Checker { a, b, scale } => {
                        checker |= 1 << l;
                        let sh = scene.prim_geo[prims[l] as usize].motion * times[l];
                        for c in 0..3 {
                            (tex_a[c][l], tex_b[c][l], shift[c][l]) = (a[c], b[c], sh[c]);
                        }
                        tex_scale[l] = scale;
                    }
                }
            }
        }
        for (l, &i) in idx.iter().enumerate() {
            if media[l] != MediumStack::default() {
                absorb_lane(scene, rays, i as usize, media[l], rt[l], &mut thr, l);
            }
        }
        let v = |a: &[f32; LANES]| f32x8::from(*a);
        let v3 = Vec3x8::from_rows;
        // Shadow rays from outside a static sphere cannot meet it again.
        let outside = mask_from_bits(geo.sph & geo.still & geo.front);
        let own = ((u32x8::from(prims) & bytemuck::cast::<f32x8, u32x8>(outside))
            | (u32x8::splat(NONE) & !bytemuck::cast::<f32x8, u32x8>(outside)))
        .to_array();
        let (pv, nv) = (geo.p, geo.n_facing);
        // Albedo (checker or constant) and the path weight, 8 lanes. Texture lookups happen in the
        // primitive's frame at the ray's time.
        let albedo = if checker == 0 {
            v3(&tex_a)
        } else {
            let eval = checker_eval_x8(v3(&tex_a), v3(&tex_b), v(&tex_scale), pv - v3(&shift));
            Vec3x8::select(mask_from_bits(checker), eval, v3(&tex_a))
        };
        let wv = v3(&thr) * albedo;
        let w = wv.rows();
        // The light is sampled from the hit point itself: the spawn offset is only there to keep the
        // shadow ray off this surface, it must not move the shading point.
        let off = offset_ray_origin_scaled_x8(pv, nv, geo.error_scale);
        let (ox, oy, oz) = (off.x.to_array(), off.y.to_array(), off.z.to_array());
        if !scene.lights.is_empty() {
            let inv_pi = f32x8::splat(FRAC_1_PI);
            let wr = [v(&w[0]) * inv_pi, v(&w[1]) * inv_pi, v(&w[2]) * inv_pi].map(|x| x.to_array());
            nee.push_rows(
                m,
                NeeRows {
                    p: &pv.rows(),
                    o: [&ox, &oy, &oz],
                    n: &nv.rows(),
                    w: &wr,
                    path: &path,
                    key: &keys,
                    sample: &samples,
                    time: &times,
                    own: &own,
                    media: scene.features.dielectric.then_some(&media),
                },
            );
        }
        if profile.diffuse_depth == 0 {
            return;
        }
        // Diffuse bounces: the lanes below both depth limits.
        let diffuse = gather8(&rays.diffuse, run, i0, at);
        let mut go = 0u32;
        for l in 0..m {
            if (diffuse[l] as u32) < profile.diffuse_depth && (depth[l] as u32) < profile.max_depth {
                go |= 1 << l;
            }
        }
        if go == 0 {
            return;
        }
        // Its own strategy: borrowing the pixel strategy made `center` pixels bounce every path in the
        // one direction (0.5, 0.5) maps to, a biased estimate. The stream of (pixel, branch, depth) is
        // shared by a pixel's consecutive samples: its key is computed once per run.
        let mut dkeys = [0u64; LANES];
        let mut memo = KeyMemo::default();
        for l in 0..m {
            let stream = || stream_key(self.seed, branch_stream(pixels[l], branch[l]), dims::DIFFUSE + depth[l] as u32);
            dkeys[l] = memo.get((pixels[l], branch[l], depth[l]), stream);
        }
        let u = self.diffuse.sample_x8(&dkeys, &samples, true);
        let wi = sample_hemisphere_cos_x8(nv, u);
        let (wx, wy, wz) = (wi.x.to_array(), wi.y.to_array(), wi.z.to_array());
        // Russian roulette, as `spawn` plays it: continuation probabilities per lane, then (only when
        // some lane needs one) the roulette numbers of all 8 lanes in one branch-free loop of 64-bit
        // hashes, which the compiler vectorises (`vpmullq`; lane by lane for the lanes that play measured
        // a tie, unlike the glass chunks' Fresnel coins).
        let cutoff = profile.throughput_cutoff;
        let mut q = [1.0f32; LANES];
        let (mut alive, mut play) = (0u32, 0u32);
        for l in 0..m {
            let mx = w[0][l].max(w[1][l]).max(w[2][l]);
            if go & (1 << l) == 0 || mx.is_nan() || mx <= 0.0 {
                continue;
            }
            alive |= 1 << l;
            // The child's diffuse count is diffuse + 1: bounces after the first play with min(m, 0.95).
            q[l] = if diffuse[l] >= 1 { mx.min(0.95) } else { (mx / cutoff).min(1.0) };
            play |= ((q[l] < 1.0) as u32) << l;
        }
        let mut roll = [0.0f32; LANES];
        if play != 0 {
            let seed = self.seed;
            for l in 0..LANES {
                let key = hash_combine(branch_stream(pixels[l], branch[l]), samples[l] as u64);
                roll[l] = random_f32(seed, key, dims::ROULETTE + (depth[l] as u32 + 1) * 4, 0);
            }
        }
        // The surviving children, compacted into rows: what `next_of` and the bounce give each. Which
        // lanes the roulette ends, and the survivors' weights (w / q: exactly w where q = 1), for all 8
        // lanes at once, without a branch per lane (the roulette's coin is a branch no predictor
        // learns).
        let mut dead = 0u32;
        for l in 0..LANES {
            dead |= ((((play >> l) & 1 == 1) & (roll[l] >= q[l])) as u32) << l;
        }
        let survive = alive & !dead;
        let qv = f32x8::from(q);
        let thr = [(v(&w[0]) / qv).to_array(), (v(&w[1]) / qv).to_array(), (v(&w[2]) / qv).to_array()];
        let lambda = if rays.with_lambda { gather8(&rays.lambda, run, i0, at) } else { [0.0; LANES] };
        let mut rows = RayRows::default();
        let k = survive.count_ones() as usize;
        if survive & (survive + 1) == 0 {
            // The survivors are the chunk's first lanes (every lane, usually, before the roulette
            // plays): the rows are the lane arrays themselves. (The compaction loop below gives the
            // same rows here too; taking the arrays whole measured 2-3% of peer scene (b)'s shade
            // stage faster, one thread, `benches/ab.py`.)
            rows.throughput = thr;
            (rows.o, rows.d) = ([ox, oy, oz], [wx, wy, wz]);
            (rows.time, rows.lambda, rows.path, rows.branch) = (times, lambda, path, branch);
            // (Every lane's, survivor or not: wrapping, since only survivors', below both limits, are kept.)
            for l in 0..LANES {
                (rows.depth[l], rows.diffuse[l], rows.flags[l]) = (depth[l].wrapping_add(1), diffuse[l].wrapping_add(1), FLAG_DIFFUSE);
            }
            rows.media = media;
        } else {
            // Every lane written at the next free row, which only survivors take.
            let mut r = 0;
            for l in 0..LANES {
                (rows.throughput[0][r], rows.throughput[1][r], rows.throughput[2][r]) = (thr[0][l], thr[1][l], thr[2][l]);
                (rows.o[0][r], rows.o[1][r], rows.o[2][r]) = (ox[l], oy[l], oz[l]);
                (rows.d[0][r], rows.d[1][r], rows.d[2][r]) = (wx[l], wy[l], wz[l]);
                (rows.time[r], rows.lambda[r], rows.path[r], rows.branch[r]) = (times[l], lambda[l], path[l], branch[l]);
                let (d1, f1) = (depth[l].wrapping_add(1), diffuse[l].wrapping_add(1));
                (rows.depth[r], rows.diffuse[r], rows.flags[r], rows.media[r]) = (d1, f1, FLAG_DIFFUSE, media[l]);
                r += ((survive >> l) & 1) as usize;
            }
        }
        next.push_rows(k, &rows);
    }

    /// Up to 8 mirror or dielectric hits (`idx`, ray indices; one kind per chunk): the ray fields as lane
    /// arrays straight from the queue, the hit geometry (spheres in 8 lanes), then lane by lane the
    /// medium bookkeeping (is the surface a real interface, between which indices), then the directions,
    /// reflectance and spawn points of all lanes as 8-lane arithmetic ([`fresnel_refract_x8`],
    /// [`reflect_x8`], [`offset_ray_origin_scaled_x8`], each bit-identical to its scalar twin), and the
    /// one child of each mirror, roulette-branched interface and null crossing as lane rows, selected
    /// in 8 lanes and queued as one block when every lane has its child (the usual case); under split
    /// branching an interface's two children come from two row sets. Thin sheets and Schlick's
    /// approximation take the scalar code per lane. Same rays, in the same order, as shading the hits
    /// one by one.
    // Out of line (one call per 8 hits): keeps it a separate entry in profiles.
    #[inline(never)]
    fn specular_x8(&self, rays: &RayQueue, hits: &HitQueue, idx: &[u32], paths: &PathTable, next: &mut RayQueue) {
        let (scene, profile) = (self.scene, self.profile);
        let m = idx.len();
        // Lanes past `m` repeat the chunk's last ray (their results are discarded).
        let i0 = idx[0] as usize;
        let run = m == LANES && idx[LANES - 1] as usize == i0 + LANES - 1;
        let at = |l: usize| idx[l.min(m - 1)] as usize;
        let org = [gather8(&rays.ox, run, i0, at), gather8(&rays.oy, run, i0, at), gather8(&rays.oz, run, i0, at)];
        let dir = [gather8(&rays.dx, run, i0, at), gather8(&rays.dy, run, i0, at), gather8(&rays.dz, run, i0, at)];
        let times = if rays.with_time { gather8(&rays.time, run, i0, at) } else { [0.0; LANES] };
        let d = Vec3x8::from_rows(&dir);
        let (t, prims) = (gather8(&hits.t, run, i0, at), gather8(&hits.prim, run, i0, at));
        let geo = hit_rows_x8(scene, hits, idx, Vec3x8::from_rows(&org), d, &t, &times, &prims);
        let mut thr = [gather8(&rays.tr, run, i0, at), gather8(&rays.tg, run, i0, at), gather8(&rays.tb, run, i0, at)];
        let path = gather8(&rays.path, run, i0, at);
        let branch = gather8(&rays.branch, run, i0, at);
        let depth = gather8(&rays.depth, run, i0, at);
        let media = gather8(&rays.media, run, i0, at);
        let consecutive = m == LANES && consecutive8(&path);
        let (p0, at_path) = (path[0] as usize, |l: usize| path[l] as usize);
        let (pixel, sample) = (gather8(&paths.pixel, consecutive, p0, at_path), gather8(&paths.sample, consecutive, p0, at_path));
        let lambda = if rays.with_lambda { gather8(&rays.lambda, run, i0, at) } else { [0.0; LANES] };
        let mut eta = [1.0f32; LANES];
        // The media on the far side of the surface (children that cross it).
        let mut stack = media;
        let mut tint = [[1.0f32; LANES]; 3];
        // Lanes by what they do: pass straight through (a null or index-matched crossing), reflect
        // (mirrors), reflect or refract (real interfaces), take the scalar path; lanes in none of
        // them are at the depth limit.
        let (mut pass, mut mirror, mut real, mut scalar) = (0u32, 0u32, 0u32, 0u32);
        let disp = scene.features.dispersion;
        for (l, &i) in idx.iter().enumerate() {
            let (material, bit) = (geo.material[l], 1 << l);
            if media[l] != MediumStack::default() {
                absorb_lane(scene, rays, i as usize, media[l], t[l], &mut thr, l);
            }
            let deeper = (depth[l] as u32) < profile.max_depth;
            match &scene.materials[material as usize] {
                Material::Mirror { tint: k } => {
                    if deeper {
                        mirror |= bit;
                        for (row, c) in tint.iter_mut().zip(k.to_array()) {
                            row[l] = c;
                        }
                    }
                }
                Material::Dielectric(d) if d.thin || d.schlick => scalar |= bit,
                // As `dielectric`: null crossings are not bounces (no depth check for them).
                Material::Dielectric(_) => {
                    let c = medium::cross(scene, media[l], material, geo.front & bit != 0);
                    self.count_lost(c);
                    stack[l] = c.stack;
                    let (n1, n2) = if c.is_real() {
                        (ior_of(scene, c.before, lambda[l], disp), ior_of(scene, c.after, lambda[l], disp))
                    } else {
                        (1.0, 1.0)
                    };
                    if n1 == n2 {
                        pass |= bit;
                    } else if deeper {
                        real |= bit;
                        eta[l] = n1 / n2;
                    }
                }
                _ => unreachable!("specular_x8 is given mirror and dielectric hits only"),
            }
        }
        // All lanes in 8-lane arithmetic.
        let (p, nf, scale) = (geo.p, geo.n_facing, geo.error_scale);
        // -normalize(d), as glam rounds it.
        let rcp = f32x8::ONE / d.dot_unfused(d).sqrt();
        let wo = Vec3x8::new(-(d.x * rcp), -(d.y * rcp), -(d.z * rcp));
        let refl = reflect_x8(wo, nf);
        let (fres, refr, tir) = fresnel_refract_x8(wo, nf, f32x8::from(eta));
        let p_refl = offset_ray_origin_scaled_x8(p, nf, scale);
        let p_trans = offset_ray_origin_scaled_x8(p, Vec3x8::new(-nf.x, -nf.y, -nf.z), scale);
        let (fres_v, fres, tir) = (fres, fres.to_array(), tir.to_bitmask());
        // Real interfaces: one child picked by the Fresnel coin (roulette branching) or both, weighted
        // (split: `real` then holds none of them).
        let (real, split) = if profile.branching == Branching::Roulette { (real, 0) } else { (0, real) };
        // The Fresnel coin of each lane, in one branch-free loop; the transmitted lanes
        // (`interface_children`: a refracted direction exists and the coin passes reflectance).
        let mut trans = 0u32;
        if real != 0 {
            // (Lane by lane, for the lanes that toss one. A branch-free loop over all 8 lanes, which the
            // compiler vectorised with `vpmullq`, made `glass.toml`'s shade stage 1.06x slower: each coin
            // is a chain of 18 dependent 64-bit multiplies, 15 cycles each in a vector against 3 in
            // scalar registers, where the lanes' chains overlap.)
            let mut coin = [0.0f32; LANES];
            let mut bits = real & !tir;
            while bits != 0 {
                let l = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                coin[l] = self.fresnel_coin(pixel[l], branch[l], sample[l], depth[l]);
            }
            trans = real & !tir & lane_bits(|l| coin[l] >= fres[l]);
        }
        // Each lane's (first) child: crossing (transmitted or passed) or reflected; a split lane's
        // reflected child carries the reflectance of its throughput (x 1 elsewhere, and off mirrors: exact).
        let across = trans | pass;
        let child_d = Vec3x8::select(mask_from_bits(trans), refr, Vec3x8::select(mask_from_bits(pass), d, refl));
        let weight = mask_from_bits(split).select(fres_v, f32x8::ONE);
        let thr_v = Vec3x8::from_rows(&thr);
        let flags = gather8(&rays.flags, run, i0, at);
        let mut rows = RayRows {
            o: Vec3x8::select(mask_from_bits(across), p_trans, p_refl).rows(),
            d: child_d.rows(),
            throughput: (thr_v * Vec3x8::from_rows(&tint)).scale(weight).rows(),
            time: times,
            lambda,
            path,
            branch,
            depth: depth.map(|k| k + 1),
            diffuse: gather8(&rays.diffuse, run, i0, at),
            flags: [FLAG_SPECULAR; LANES],
            media,
            // (The parent's: kept with its flags by a passed lane, or a refracted one under transmissive
            // shadows.)
            pdf: if rays.with_pdf { gather8(&rays.pdf, run, i0, at) } else { [0.0; LANES] },
            travel: [0.0; LANES],
        };
        if rays.with_pdf {
            // The distance from the lobe's glossy point (lanes that keep a lobe ray's flags: passed, or
            // refracted under transmissive shadows): what was travelled before, and this segment.
            let (travel, o) = (gather8(&rays.travel, run, i0, at), org);
            for l in 0..LANES {
                let seg = Vec3::new(rows.o[0][l] - o[0][l], rows.o[1][l] - o[1][l], rows.o[2][l] - o[2][l]);
                rows.travel[l] = travel[l] + seg.length();
            }
        }
        // Split lanes' transmitted children.
        let mut second = None;
        if split != 0 {
            let mut t = rows;
            (t.o, t.d, t.throughput) = (p_trans.rows(), refr.rows(), thr_v.scale(f32x8::ONE - fres_v).rows());
            (t.flags, t.media) = (flags.map(|f| self.refracted_flags(f)), stack);
            second = Some(t);
        }
        for (l, &s) in stack.iter().enumerate().take(m) {
            if across & (1 << l) != 0 {
                rows.media[l] = s;
            }
        }
        // The stretch each child's spawn offset skips inside an absorbing medium (`spawn_absorption`).
        if media[..m].iter().chain(&stack[..m]).any(|&s| s != MediumStack::default()) {
            let (px, py, pz) = (p.x.to_array(), p.y.to_array(), p.z.to_array());
            let p_of = |l: usize| Vec3::new(px[l], py[l], pz[l]);
            let at = |r: &[[f32; LANES]; 3], l: usize| Vec3::new(r[0][l], r[1][l], r[2][l]);
            for l in 0..m {
                let k = spawn_absorption(scene, rows.media[l], p_of(l), at(&rows.o, l), at(&rows.d, l));
                for (row, k) in rows.throughput.iter_mut().zip(k.to_array()) {
                    row[l] *= k;
                }
                if let Some(t) = second.as_mut() {
                    let k = spawn_absorption(scene, t.media[l], p_of(l), at(&t.o, l), at(&t.d, l));
                    for (row, k) in t.throughput.iter_mut().zip(k.to_array()) {
                        row[l] *= k;
                    }
                }
            }
        }
        let (mut kept, mut kept2) = (pass, 0u32);
        let roulette = |t: &mut [[f32; LANES]; 3], l: usize, branch: u32, depth: u16, which: u32| {
            let thr = Vec3::new(t[0][l], t[1][l], t[2][l]);
            let q = self.survival(thr, rows.diffuse[l], branch, depth, pixel[l], sample[l], which);
            if let Some(q) = q.filter(|&q| q < 1.0) {
                for row in t.iter_mut() {
                    row[l] /= q;
                }
            }
            q.is_some()
        };
        for l in 0..m {
            let bit = 1 << l;
            if pass & bit != 0 {
                // Not a bounce (`passed`): the parent's depth and flags.
                (rows.depth[l], rows.flags[l]) = (depth[l], flags[l]);
            } else if split & bit != 0 {
                // Both children (`interface_children`), each after `spawn`'s roulette.
                rows.branch[l] = child_branch(branch[l], depth[l], 1);
                if fres[l] > 0.0 && roulette(&mut rows.throughput, l, rows.branch[l], depth[l] + 1, 1) {
                    kept |= bit;
                }
                if let Some(t) = second.as_mut().filter(|_| tir & bit == 0 && fres[l] < 1.0) {
                    if roulette(&mut t.throughput, l, branch[l], depth[l] + 1, 2) {
                        kept2 |= bit;
                    }
                }
            } else if (mirror | real) & bit != 0 {
                // A bounce (`next_of`), then `spawn`'s roulette on the child.
                let which = if mirror & bit != 0 {
                    0
                } else if trans & bit != 0 {
                    rows.flags[l] = self.refracted_flags(flags[l]);
                    2
                } else {
                    1
                };
                if roulette(&mut rows.throughput, l, branch[l], depth[l] + 1, which) {
                    kept |= bit;
                }
            }
        }
        // Every child a prefix of the lanes (usually all of them): one block.
        if scalar | split == 0 && kept & (kept + 1) == 0 {
            next.push_rows(kept.count_ones() as usize, &rows);
            return;
        }
        for (l, &i) in idx.iter().enumerate() {
            let bit = 1 << l;
            if kept & bit != 0 {
                next.push(&rows.item(l));
            } else if scalar & bit != 0 {
                // The ray as shading found it (absorbed throughput).
                let r = RayItem { throughput: Vec3::new(thr[0][l], thr[1][l], thr[2][l]), ..rays.get(i as usize) };
                let Material::Dielectric(d) = &scene.materials[geo.material[l] as usize] else { unreachable!() };
                let i = i as usize;
                let hit = surface_hit(scene, &r, t[l], prims[l], hits.leaf[i], hits.flip[i]);
                self.dielectric(d, &r, &hit, pixel[l], sample[l], next);
            }
            if let Some(t) = second.as_ref().filter(|_| kept2 & bit != 0) {
                next.push(&t.item(l));
            }
        }
    }

    /// Up to 8 glossy (GGX) hits: the ray fields as lane arrays, the hit geometry (spheres and flat prims
    /// in 8 lanes), the lobe sample of each lane (the glossy sampler in 8 lanes, keyed per pixel, branch
    /// and depth), the visible-normal sample and its weight in 8 lanes ([`sample_ggx_reflect_x8`],
    /// bit-identical to the scalar one), and the children queued as one block when every lane has one.
    /// Same rays, in the same order, as shading the hits one by one.
    // Out of line (one call per 8 hits): keeps it a separate entry in profiles.
    #[inline(never)]
    fn glossy_x8(&self, rays: &RayQueue, hits: &HitQueue, idx: &[u32], paths: &PathTable, nee: &mut NeeQueue, next: &mut RayQueue) {
        let (scene, profile) = (self.scene, self.profile);
        let m = idx.len();
        // (The same gathers as `specular_x8` and `lambert_x8`, written out in each: folded into one
        // function returning a struct of the lane arrays, the shade stage measured 10-15% slower.)
        // Lanes past `m` repeat the chunk's last ray (their results are discarded).
        let i0 = idx[0] as usize;
        let run = m == LANES && idx[LANES - 1] as usize == i0 + LANES - 1;
        let at = |l: usize| idx[l.min(m - 1)] as usize;
        let org = [gather8(&rays.ox, run, i0, at), gather8(&rays.oy, run, i0, at), gather8(&rays.oz, run, i0, at)];
        let dir = [gather8(&rays.dx, run, i0, at), gather8(&rays.dy, run, i0, at), gather8(&rays.dz, run, i0, at)];
        let times = if rays.with_time { gather8(&rays.time, run, i0, at) } else { [0.0; LANES] };
        let d = Vec3x8::from_rows(&dir);
        let (t, prims) = (gather8(&hits.t, run, i0, at), gather8(&hits.prim, run, i0, at));
        let geo = hit_rows_x8(scene, hits, idx, Vec3x8::from_rows(&org), d, &t, &times, &prims);
        let mut thr = [gather8(&rays.tr, run, i0, at), gather8(&rays.tg, run, i0, at), gather8(&rays.tb, run, i0, at)];
        let path = gather8(&rays.path, run, i0, at);
        let branch = gather8(&rays.branch, run, i0, at);
        let depth = gather8(&rays.depth, run, i0, at);
        let media = gather8(&rays.media, run, i0, at);
        let consecutive = m == LANES && consecutive8(&path);
        let (p0, at_path) = (path[0] as usize, |l: usize| path[l] as usize);
        let (pixel, sample) = (gather8(&paths.pixel, consecutive, p0, at_path), gather8(&paths.sample, consecutive, p0, at_path));
        let mut tint = [[0.0f32; LANES]; 3];
        let mut alpha = [1.0f32; LANES];
        let mut live = 0u32;
        for (l, &i) in idx.iter().enumerate() {
            if media[l] != MediumStack::default() {
                absorb_lane(scene, rays, i as usize, media[l], t[l], &mut thr, l);
            }
            let Material::Glossy { tint: k, alpha: a } = &scene.materials[geo.material[l] as usize] else {
                unreachable!("glossy_x8 is given glossy hits only")
            };
            for (row, c) in tint.iter_mut().zip(k.to_array()) {
                row[l] = c;
            }
            alpha[l] = *a;
            live |= (((depth[l] as u32) < profile.max_depth) as u32) << l;
        }
        // -normalize(d), as glam rounds it.
        let rcp = f32x8::ONE / d.dot_unfused(d).sqrt();
        let wo = Vec3x8::new(-(d.x * rcp), -(d.y * rcp), -(d.z * rcp));
        if !scene.lights.is_empty() {
            // Next-event estimation, as at Lambert points (same point keys): the request carries the
            // throughput x tint and the lobe (`wo`, alpha); the shadow stage evaluates the GGX lobe per
            // light sample, weighted against this point's lobe ray by MIS where one leaves it.
            let mut memo = KeyMemo::default();
            let mut keys = [0u64; LANES];
            for l in 0..LANES {
                keys[l] = memo.get((pixel[l], branch[l], depth[l]), || point_key(pixel[l], branch[l], depth[l]));
            }
            let off = offset_ray_origin_scaled_x8(geo.p, geo.n_facing, geo.error_scale);
            let (ox, oy, oz) = (off.x.to_array(), off.y.to_array(), off.z.to_array());
            let w = (Vec3x8::from_rows(&thr) * Vec3x8::from_rows(&tint)).rows();
            let own = [NONE; LANES];
            let nee = nee.glossy.get_or_insert_with(Default::default);
            nee.push_rows(
                m,
                NeeRows {
                    p: &geo.p.rows(),
                    o: [&ox, &oy, &oz],
                    n: &geo.n_facing.rows(),
                    w: &w,
                    path: &path,
                    key: &keys,
                    sample: &sample,
                    time: &times,
                    own: &own,
                    media: scene.features.dielectric.then_some(&media),
                },
            );
            // (Negative: no lobe ray to share the light with, at the depth limit, or a lobe ray in the
            // fixed direction of the `center` strategy, which samples no density to weigh against:
            // the light samples then count in full, and the lobe ray's finds of sampled lights not at all.)
            let mut lobe = [0.0f32; LANES];
            let random_lobe = profile.glossy_strategy != Strategy::Center;
            for l in 0..LANES {
                let a = alpha[l].max(f32::MIN_POSITIVE);
                lobe[l] = if live & (1 << l) != 0 && random_lobe { a } else { -a };
            }
            nee.push_lobes(m, &wo.rows(), &lobe);
        }
        if live == 0 {
            return;
        }
        // The lobe's stream per (pixel, branch, depth): consecutive lanes usually share it.
        let mut memo = KeyMemo::default();
        let mut keys = [0u64; LANES];
        for l in 0..LANES {
            let stream = || stream_key(self.seed, branch_stream(pixel[l], branch[l]), dims::GLOSSY + depth[l] as u32);
            keys[l] = memo.get((pixel[l], branch[l], depth[l]), stream);
        }
        let u = self.glossy.sample_x8(&keys, &sample, true);
        let (nf, alpha_x8) = (geo.n_facing, f32x8::from(alpha));
        // `center`: the lobe's central direction, the mirror direction (microfacet normal `n`) at any
        // incidence; else the visible-normal sample.
        let (wi, ok) = if profile.glossy_strategy == Strategy::Center {
            let wi = reflect_x8(wo, nf).normalize_or(nf);
            let zero = f32x8::ZERO;
            (wi, wo.dot_unfused(nf).simd_gt(zero) & wi.dot_unfused(nf).simd_gt(zero))
        } else {
            sample_ggx_reflect_x8(wo, nf, alpha_x8, u)
        };
        let weight = sample_ggx_reflect_weight_x8(wo, nf, wi, alpha_x8);
        // The lobe rays' density, for the MIS weight of the sampled light they may find.
        let pdf = if next.with_pdf { sample_ggx_reflect_pdf_x8(wo, nf, wi, alpha_x8).to_array() } else { [0.0f32; LANES] };
        let mut rows = RayRows {
            o: offset_ray_origin_scaled_x8(geo.p, nf, geo.error_scale).rows(),
            d: wi.rows(),
            throughput: (Vec3x8::from_rows(&thr) * Vec3x8::from_rows(&tint)).scale(weight).rows(),
            time: times,
            lambda: if rays.with_lambda { gather8(&rays.lambda, run, i0, at) } else { [0.0; LANES] },
            path,
            branch,
            depth: depth.map(|k| k + 1),
            diffuse: gather8(&rays.diffuse, run, i0, at),
            flags: [FLAG_SPECULAR | FLAG_GLOSSY; LANES],
            media,
            pdf,
            travel: [0.0; LANES],
        };
        // `spawn`'s roulette on each child.
        let mut kept = 0u32;
        let mut todo = live & ok.to_bitmask();
        while todo != 0 {
            let l = todo.trailing_zeros() as usize;
            todo &= todo - 1;
            let c = Vec3::new(rows.throughput[0][l], rows.throughput[1][l], rows.throughput[2][l]);
            if let Some(q) = self.survival(c, rows.diffuse[l], branch[l], rows.depth[l], pixel[l], sample[l], 0) {
                if q < 1.0 {
                    for row in &mut rows.throughput {
                        row[l] /= q;
                    }
                }
                kept |= 1 << l;
            }
        }
        // Every child a prefix of the lanes (usually all of them): one block.
        if kept & (kept + 1) == 0 {
            next.push_rows(kept.count_ones() as usize, &rows);
            return;
        }
        let mut bits = kept;
        while bits != 0 {
            let l = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            next.push(&rows.item(l));
        }
    }

    /// Whether a child of throughput `t` survives the unbiased Russian roulette on low throughput, and
    /// its survival probability (divide the throughput by it when below 1); `which` keys the child kind.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn survival(&self, t: Vec3, diffuse: u16, branch: u32, depth: u16, pixel: u32, sample: u32, which: u32) -> Option<f32> {
        let m = t.max_element();
        if m.is_nan() || m <= 0.0 {
            return None;
        }
        let cutoff = self.profile.throughput_cutoff;
        let q = if diffuse > 1 { m.min(0.95) } else { (m / cutoff).min(1.0) };
        if q < 1.0 {
            let key = hash_combine(branch_stream(pixel, branch), sample as u64);
            if random_f32(self.seed, key, dims::ROULETTE + depth as u32 * 4 + which, 0) >= q {
                return None;
            }
        }
        Some(q)
    }

    /// Queue a child ray, after an unbiased Russian roulette on low throughput.
    #[inline]
    fn spawn(&self, next: &mut RayQueue, mut child: RayItem, pixel: u32, sample: u32, which: u32) {
        if let Some(q) = self.survival(child.throughput, child.diffuse, child.branch, child.depth, pixel, sample, which) {
            if q < 1.0 {
                child.throughput /= q;
            }
            next.push(&child);
        }
    }

    #[inline(always)]
    fn count_lost(&self, c: medium::Crossing) {
        if c.lost {
            self.lost_media.set(self.lost_media.get() + 1);
        }
    }

    /// A smooth dielectric surface: a null crossing passes the ray on unchanged; a real interface reflects
    /// and refracts by the exact Fresnel equations (or Schlick's), between the media that
    /// [`medium::cross`] finds on both sides; a thin sheet reflects and transmits without bending.
    fn dielectric(&self, d: &Dielectric, r: &RayItem, hit: &SurfaceHit, pixel: u32, sample: u32, next: &mut RayQueue) {
        let scene = self.scene;
        let disp = scene.features.dispersion;
        let ior = |m: Option<u32>| ior_of(scene, m, r.lambda, disp);
        let this = hit.material;
        let p_trans = hit.spawn(-hit.n_facing);

        let (n1, n2, stack) = if d.thin {
            (ior(medium::current(scene, r.media)), ior(Some(this)), r.media)
        } else {
            let c = medium::cross(scene, r.media, this, hit.front);
            self.count_lost(c);
            if !c.is_real() {
                next.push(&passed(scene, r, hit.p, p_trans, c.stack));
                return;
            }
            (ior(c.before), ior(c.after), c.stack)
        };
        if n1 == n2 {
            // Index-matched: no reflection, no bending (exactly what Fresnel and Snell give for eta = 1).
            next.push(&passed(scene, r, hit.p, p_trans, stack));
            return;
        }
        if (r.depth as u32) >= self.profile.max_depth {
            return;
        }

        let wo = -r.d.normalize();
        let cos_i = wo.dot(hit.n_facing).clamp(0.0, 1.0);
        let fres = |cos: f32, eta: f32| if d.schlick { fresnel_schlick(cos, eta) } else { fresnel_dielectric(cos, eta) };
        let eta = n1 / n2;
        // Transmitted: (direction, media after, flags).
        let (f, trans): (f32, Option<(Vec3, MediumStack, u8)>) = if d.thin {
            // Both faces, all inter-reflections summed; transmission goes straight through.
            let r1 = fres(cos_i, eta);
            let rr = if r1 < 1.0 { 2.0 * r1 / (1.0 + r1) } else { 1.0 };
            (rr, Some((r.d, stack, r.flags)))
        } else {
            (fres(cos_i, eta), refract(wo, hit.n_facing, eta).map(|dir| (dir, stack, self.refracted_flags(r.flags))))
        };
        let f = if trans.is_none() { 1.0 } else { f };
        let refl = (hit.spawn(hit.n_facing), reflect(wo, hit.n_facing));
        let coin = || self.fresnel_coin(pixel, r.branch, sample, r.depth);
        self.interface_children(
            r,
            hit.p,
            f,
            refl,
            trans.map(|(dir, media, flags)| (p_trans, dir, media, flags)),
            coin,
            pixel,
            sample,
            next,
        );
    }

    /// The flags of a ray refracted through a real interface. Under transmissive shadows the shadow stage
    /// already carried light through the interface to diffuse points: a diffuse path that reaches a light
    /// through it must not count it again, so only then it keeps its own.
    #[inline(always)]
    fn refracted_flags(&self, flags: u8) -> u8 {
        if self.profile.transmissive_shadows {
            flags
        } else {
            FLAG_SPECULAR
        }
    }

    /// The uniform number that picks reflection or transmission at a dielectric under roulette branching.
    #[inline(always)]
    fn fresnel_coin(&self, pixel: u32, branch: u32, sample: u32, depth: u16) -> f32 {
        let key = hash_combine(branch_stream(pixel, branch), sample as u64);
        random_f32(self.seed, key, dims::FRESNEL + depth as u32, 0)
    }

    /// The children of ray `r` at a dielectric interface of reflectance `f`: reflected from `refl` (origin,
    /// direction), transmitted when `trans` (origin, direction, media after, flags) is given; both,
    /// weighted, under split branching, else one picked by `coin()` (drawn only when there is a choice).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn interface_children(
        &self,
        r: &RayItem,
        p: Vec3,
        f: f32,
        refl: (Vec3, Vec3),
        trans: Option<(Vec3, Vec3, MediumStack, u8)>,
        coin: impl FnOnce() -> f32,
        pixel: u32,
        sample: u32,
        next: &mut RayQueue,
    ) {
        // (Each child's throughput x `spawn_absorption` of the stretch its spawn offset skips.)
        let scene = self.scene;
        let reflected = |thr: Vec3| RayItem {
            o: refl.0,
            d: refl.1,
            throughput: thr * spawn_absorption(scene, r.media, p, refl.0, refl.1),
            flags: FLAG_SPECULAR,
            ..next_of(r)
        };
        // (`travel`: for a thin sheet's straight transmission, which keeps a lobe ray's flags.)
        let transmitted = |thr: Vec3, (o, d, media, flags): (Vec3, Vec3, MediumStack, u8)| RayItem {
            o,
            d,
            throughput: thr * spawn_absorption(scene, media, p, o, d),
            flags,
            media,
            travel: r.travel + (o - r.o).length(),
            ..next_of(r)
        };
        match self.profile.branching {
            Branching::Split => {
                if f > 0.0 {
                    let c = RayItem { branch: child_branch(r.branch, r.depth, 1), ..reflected(r.throughput * f) };
                    self.spawn(next, c, pixel, sample, 1);
                }
                if let Some(t) = trans {
                    if f < 1.0 {
                        self.spawn(next, transmitted(r.throughput * (1.0 - f), t), pixel, sample, 2);
                    }
                }
            }
            Branching::Roulette => match trans {
                Some(t) if coin() >= f => self.spawn(next, transmitted(r.throughput, t), pixel, sample, 2),
                _ => self.spawn(next, reflected(r.throughput), pixel, sample, 1),
            },
        }
    }
}

/// Ray `r` through a surface unbent at `p`, from `o` with `media`: the same bounce count, branch and flags
/// (what it would have done without the surface; shadow rays see through such crossings too).
#[inline(always)]
fn passed(scene: &Scene, r: &RayItem, p: Vec3, o: Vec3, media: MediumStack) -> RayItem {
    let throughput = r.throughput * spawn_absorption(scene, media, p, o, r.d);
    RayItem { o, media, throughput, tmax: f32::INFINITY, travel: r.travel + (o - r.o).length(), ..*r }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::csg::CsgArena;
    use crate::sample::Strategy;
    use crate::wavefront::csg_merge::csg_merge;
    use crate::wavefront::generate::{generate, Tile};
    use crate::wavefront::intersect::intersect;
    use crate::wavefront::queues::CsgCandidates;

    /// One mirror or dielectric hit shaded by the scalar code (`surface_hit`, then the mirror bounce or
    /// `Ctx::dielectric`): what `shade` did per hit before `specular_x8`.
    fn scalar_specular(ctx: &Ctx, rays: &RayQueue, hits: &HitQueue, i: usize, paths: &PathTable, next: &mut RayQueue) {
        let mut r = rays.get(i);
        absorb(ctx.scene, &mut r, hits.t[i]);
        let hit = surface_hit(ctx.scene, &r, hits.t[i], hits.prim[i], hits.leaf[i], hits.flip[i]);
        let (pixel, sample) = (paths.pixel[r.path as usize], paths.sample[r.path as usize]);
        match &ctx.scene.materials[hit.material as usize] {
            Material::Mirror { tint } => {
                if (r.depth as u32) < ctx.profile.max_depth {
                    let d = reflect(-r.d.normalize(), hit.n_facing);
                    let o = hit.spawn(hit.n_facing);
                    let throughput = r.throughput * *tint * spawn_absorption(ctx.scene, r.media, hit.p, o, d);
                    let child = RayItem { o, d, throughput, flags: FLAG_SPECULAR, ..next_of(&r) };
                    ctx.spawn(next, child, pixel, sample, 0);
                }
            }
            Material::Dielectric(d) => ctx.dielectric(d, &r, &hit, pixel, sample, next),
            m => panic!("not a specular material: {m:?}"),
        }
    }

    /// Every field of every ray of a queue, floats as bits.
    fn bits(q: &RayQueue) -> Vec<String> {
        (0..q.len())
            .map(|i| {
                let r = q.get(i);
                let f = |v: f32| v.to_bits();
                format!(
                    "{:?} {:?} {} {} {} {:?} {} {} {} {} {} {:?}",
                    r.o.to_array().map(f),
                    r.d.to_array().map(f),
                    f(r.tmax),
                    f(r.time),
                    f(r.lambda),
                    r.throughput.to_array().map(f),
                    r.path,
                    r.branch,
                    r.depth,
                    r.diffuse,
                    r.flags,
                    r.media
                )
            })
            .collect()
    }

    /// `specular_x8` pushes the rays the scalar shading pushes, bit for bit and in the same order, on the
    /// mirror and glass hits of five bounces of real scenes: glass in glass with priorities (nested),
    /// absorbing, thin and Schlick media (absorption: those lanes take the scalar path inside a chunk),
    /// dispersion (prism: a wavelength per lane), CSG glass and the showcase's mirror; roulette and split
    /// branching, with and without transmissive shadows, and with roulette on most children; chunks of 1
    /// to 8 hits.
    #[test]
    fn specular_x8_equals_scalar_shading() {
        let mut compared = 0usize;
        for name in ["glass", "nested", "absorption", "prism", "csg_glass", "showcase"] {
            let scene = crate::scene::load_scene(std::path::Path::new(&format!("scenes/{name}.toml"))).unwrap();
            for variant in 0..3 {
                let mut profile = Profile::builtin("bench");
                (profile.spp, profile.max_depth) = (2, 4);
                let split = variant > 0;
                if split {
                    (profile.branching, profile.transmissive_shadows) = (Branching::Split, variant == 1);
                }
                if variant == 2 {
                    // Russian roulette on most children (`spawn`'s stream per child kind), a low depth limit.
                    (profile.throughput_cutoff, profile.max_depth) = (0.5, 2);
                }
                let ctx = Ctx::new(&scene, &profile, 5);
                let (cx, cy) = (scene.width / 2, scene.height / 2);
                let tile = Tile { x0: cx - 60, y0: cy - 50, x1: cx + 60, y1: cy + 50 };
                bounces(&scene, &profile, 5, &[tile], |rays, hits, paths| {
                    let (mut lanes, mut scalar) =
                        (RayQueue::new(rays.with_time, rays.with_lambda), RayQueue::new(rays.with_time, rays.with_lambda));
                    in_chunks(&hits_of(&scene, rays, hits, &[MaterialKind::Mirror, MaterialKind::Dielectric]), |chunk| {
                        ctx.specular_x8(rays, hits, chunk, paths, &mut lanes);
                        for &i in chunk {
                            scalar_specular(&ctx, rays, hits, i as usize, paths, &mut scalar);
                        }
                    });
                    compared += assert_same_rays(&lanes, &scalar, &format!("{name} split={split}"));
                });
            }
        }
        // Enough children for the comparison to mean something.
        assert!(compared > 500_000, "{compared}");
    }

    /// Five bounces of `scene` as the renderer runs them, from the camera rays of `tiles`: `check` sees
    /// each bounce's rays, hits (CSG solved) and paths before `shade` makes the next bounce's rays.
    fn bounces(scene: &Scene, profile: &Profile, seed: u64, tiles: &[Tile], mut check: impl FnMut(&RayQueue, &HitQueue, &mut PathTable)) {
        let (mut paths, mut rays) = (PathTable::default(), RayQueue::new(scene.features.motion, scene.features.dispersion));
        for &tile in tiles {
            generate(scene, profile, seed, tile, 0..profile.spp, &mut paths, &mut rays);
        }
        let (mut hits, mut cands, mut arena, mut order) = (HitQueue::default(), CsgCandidates::default(), CsgArena::new(), Vec::new());
        for _bounce in 0..5 {
            if rays.is_empty() {
                break;
            }
            rays.pad();
            intersect(scene, &rays, &mut hits, &mut cands);
            if scene.features.csg {
                csg_merge(scene, &rays, &mut cands, &mut hits, &mut arena);
            }
            check(&rays, &hits, &mut paths);
            let (mut next, mut nee) = (RayQueue::new(rays.with_time, rays.with_lambda), NeeQueue::default());
            shade(scene, profile, seed, &rays, &hits, &mut order, ShadeOut { paths: &mut paths, next: &mut next, nee: &mut nee });
            rays = next;
        }
    }

    /// The hits of `rays` on materials of the given kinds, in queue order.
    fn hits_of(scene: &Scene, rays: &RayQueue, hits: &HitQueue, kinds: &[MaterialKind]) -> Vec<u32> {
        (0..rays.len())
            .filter(|&i| match (hits.prim[i], hits.leaf[i]) {
                (NONE, _) => false,
                (p, NONE) => kinds.contains(&scene.prim_kind[p as usize]),
                (_, leaf) => kinds.contains(&scene.leaf_kind[leaf as usize]),
            })
            .map(|i| i as u32)
            .collect()
    }

    /// `ids` in chunks of 1 to 8 (a fixed cycle of sizes).
    fn in_chunks(ids: &[u32], mut chunk: impl FnMut(&[u32])) {
        let mut at = 0;
        for size in [8, 3, 8, 8, 1, 5, 8, 2, 7, 6, 4].into_iter().cycle() {
            if at >= ids.len() {
                break;
            }
            chunk(&ids[at..(at + size).min(ids.len())]);
            at += size.min(ids.len() - at);
        }
    }

    /// The two queues hold the same rays, bit for bit and in order; returns how many.
    fn assert_same_rays(a: &RayQueue, b: &RayQueue, what: &str) -> usize {
        let (a, b) = (bits(a), bits(b));
        assert_eq!(a.len(), b.len(), "{what}: child counts differ");
        for (k, (x, y)) in a.iter().zip(&b).enumerate() {
            assert_eq!(x, y, "{what}: child {k} differs");
        }
        a.len()
    }

    /// One glossy hit shaded by the scalar code (`surface_hit`, `sample_2d`, `sample_ggx_reflect` and its
    /// weight, `spawn`): what `shade` did per hit before `glossy_x8`.
    fn scalar_glossy(ctx: &Ctx, rays: &RayQueue, hits: &HitQueue, i: usize, paths: &PathTable, next: &mut RayQueue) {
        use crate::optics::{sample_ggx_reflect, sample_ggx_reflect_weight};
        let mut r = rays.get(i);
        absorb(ctx.scene, &mut r, hits.t[i]);
        let hit = surface_hit(ctx.scene, &r, hits.t[i], hits.prim[i], hits.leaf[i], hits.flip[i]);
        let (pixel, sample) = (paths.pixel[r.path as usize], paths.sample[r.path as usize]);
        let Material::Glossy { tint, alpha } = &ctx.scene.materials[hit.material as usize] else { panic!("not glossy") };
        if (r.depth as u32) < ctx.profile.max_depth {
            let wo = -r.d.normalize();
            let (p, dim) = (ctx.profile, dims::GLOSSY + r.depth as u32);
            let u = crate::sample::sample_2d(p.glossy_strategy, ctx.seed, branch_stream(pixel, r.branch), dim, sample, p.spp);
            let wi = if p.glossy_strategy == Strategy::Center {
                Some(reflect(wo, hit.n_facing).normalize_or(hit.n_facing))
                    .filter(|wi| wo.dot(hit.n_facing) > 0.0 && wi.dot(hit.n_facing) > 0.0)
            } else {
                sample_ggx_reflect(wo, hit.n_facing, *alpha, u)
            };
            if let Some(wi) = wi {
                let wgt = sample_ggx_reflect_weight(wo, hit.n_facing, wi, *alpha);
                let child = RayItem {
                    o: hit.spawn(hit.n_facing),
                    d: wi,
                    throughput: r.throughput * *tint * wgt,
                    flags: FLAG_SPECULAR | FLAG_GLOSSY,
                    ..next_of(&r)
                };
                ctx.spawn(next, child, pixel, sample, 0);
            }
        }
    }

    /// `glossy_x8` pushes the rays the scalar shading pushes, bit for bit and in the same order, on the
    /// glossy hits of five bounces of the glossy scene (several roughnesses) and the showcase: every
    /// lobe strategy, roulette on most children, a low depth limit; chunks of 1 to 8 hits.
    #[test]
    fn glossy_x8_equals_scalar_shading() {
        let mut compared = 0usize;
        for name in ["glossy", "showcase"] {
            let scene = crate::scene::load_scene(std::path::Path::new(&format!("scenes/{name}.toml"))).unwrap();
            for variant in 0..4 {
                let mut profile = Profile::builtin("bench");
                (profile.spp, profile.max_depth) = (4, 4);
                profile.glossy_strategy = [Strategy::Jittered, Strategy::Random, Strategy::Sobol, Strategy::Center][variant];
                if variant == 1 {
                    (profile.throughput_cutoff, profile.max_depth) = (0.5, 2);
                }
                let ctx = Ctx::new(&scene, &profile, 7);
                // A band across the middle of the image.
                let cy = scene.height / 2;
                let band = Tile { x0: 0, y0: cy - 40.min(cy), x1: scene.width, y1: cy + 40 };
                bounces(&scene, &profile, 7, &[band], |rays, hits, paths| {
                    let (mut lanes, mut scalar) =
                        (RayQueue::new(rays.with_time, rays.with_lambda), RayQueue::new(rays.with_time, rays.with_lambda));
                    in_chunks(&hits_of(&scene, rays, hits, &[MaterialKind::Glossy]), |chunk| {
                        ctx.glossy_x8(rays, hits, chunk, paths, &mut NeeQueue::default(), &mut lanes);
                        for &i in chunk {
                            scalar_glossy(&ctx, rays, hits, i as usize, paths, &mut scalar);
                        }
                    });
                    compared += assert_same_rays(&lanes, &scalar, &format!("{name} variant {variant}"));
                });
            }
        }
        assert!(compared > 100_000, "{compared}");
    }

    /// Every field of every request of a NEE queue, floats as bits.
    fn nee_bits(q: &NeeQueue) -> Vec<String> {
        let f = |v: &Vec<f32>, i: usize| v[i].to_bits();
        (0..q.len())
            .map(|i| {
                let rows = [&q.px, &q.py, &q.pz, &q.ox, &q.oy, &q.oz, &q.nx, &q.ny, &q.nz, &q.wr, &q.wg, &q.wb, &q.time];
                format!("{:?} {} {} {} {}", rows.map(|v| f(v, i)), q.path[i], q.key[i], q.sample[i], q.own[i])
            })
            .collect()
    }

    /// `hit_rows_x8` gives each lane what `surface_hit` gives that hit, bit for bit: point, facing normal,
    /// error magnitude, side and material, for chunks of hits of every material in scenes of spheres,
    /// flat prims, boxes, ellipsoids and CSG leaves of every shape (cones and tori counted), some moving, at
    /// camera and bounce depths.
    #[test]
    fn hit_rows_x8_equal_surface_hit() {
        let (mut csg_lanes, mut box_lanes, mut ellipsoid_lanes, mut lanes, mut curved) = (0usize, 0usize, 0usize, 0usize, [0usize; 2]);
        // Moving CSG solids of every leaf shape, some subtracted, one cut by a half-space.
        let moving = "[image]\nwidth = 64\nheight = 48\n[camera]\nposition = [0, 1.5, 6]\nlook_at = [0, 0.5, 0]\nfov = 45\n\
                      shutter = [0, 1]\n[materials.a]\ntype = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\n\
                      [materials.b]\ntype = \"lambert\"\nalbedo = [0.2, 0.6, 0.3]\n\
                      [[shapes]]\ntype = \"plane\"\npoint = [0, 0, 0]\nnormal = [0, 1, 0]\nmaterial = \"a\"\n\
                      [[shapes]]\ntype = \"csg\"\nop = \"difference\"\nmotion = [3.0, 0.2, 0.1]\n\
                      transform = { rotate = [10, 30, 0], scale = [1.2, 0.8, 1], translate = [-2.5, 0.6, 0] }\nchildren = [\n\
                      { type = \"box\", min = [-0.6, -0.6, -0.6], max = [0.6, 0.6, 0.6], material = \"a\" },\n\
                      { type = \"sphere\", center = [0.5, 0.5, 0.5], radius = 0.5, material = \"b\" },\n\
                      { type = \"cylinder\", center = [0, 0, 0], radius = 0.25, height = 2, material = \"b\" },\n]\n\
                      [[shapes]]\ntype = \"csg\"\nop = \"intersection\"\nmotion = [-0.3, 0.0, 0.4]\nchildren = [\n\
                      { type = \"sphere\", center = [1, 0.7, 0], radius = 0.7, material = \"b\" },\n\
                      { type = \"halfspace\", point = [1, 1.0, 0], normal = [0.3, 1, 0.2], material = \"a\" },\n\
                      { type = \"cone\", center = [1, 0.7, 0], radius = 0.8, radius_top = 0.2, height = 1.6, material = \"a\" },\n]\n\
                      [[shapes]]\ntype = \"csg\"\nop = \"difference\"\nmotion = [0.5, 0.3, 0.0]\n\
                      transform = { rotate = [60, 20, 0], scale = [1.3, 1, 0.8], translate = [0.2, 1.6, -0.5] }\nchildren = [\n\
                      { type = \"torus\", major_radius = 0.6, minor_radius = 0.25, material = \"a\" },\n\
                      { type = \"cone\", center = [0.6, 0, 0], radius = 0.2, radius_top = 0.05, height = 0.8, material = \"b\" },\n]\n\
                      [[shapes]]\ntype = \"box\"\nmin = [-0.4, 0, -0.3]\nmax = [0.4, 0.5, 0.3]\nmaterial = \"b\"\nmotion = [2.5, 0, 0.3]\n\
                      transform = { rotate = [0, 40, 15], scale = [1, 1.5, 0.7], translate = [-1, 0, 1.2] }\n\
                      [[shapes]]\ntype = \"sphere\"\ncenter = [1.8, 0.6, 0.5]\nradius = 0.5\nmaterial = \"b\"\nmotion = [-1.5, 0, 0.4]\n\
                      transform = { rotate = [20, 0, 35], scale = [1.6, 0.7, 1.1] }\n\
                      [[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 0.6\nmaterial = \"a\"\n\
                      transform = { scale = [0.6, 1.4, 0.9], translate = [0.3, 0.8, 1.5] }\n\
                      [[lights]]\ntype = \"point\"\nposition = [2, 5, 4]\nintensity = [20, 20, 20]\n";
        let scenes = ["csg", "showcase", "bench_csg", "glass", "motion", "csg_glass", "nested", "cornell", "absorption"]
            .map(|name| (name, crate::scene::load_scene(std::path::Path::new(&format!("scenes/{name}.toml"))).unwrap()))
            .into_iter()
            .chain([("moving", crate::scene::parse_scene(std::path::Path::new("moving.toml"), moving).unwrap())]);
        for (name, scene) in scenes {
            let mut profile = Profile::builtin("bench");
            (profile.spp, profile.max_depth, profile.diffuse_depth) = (2, 4, 2);
            let tiles = [(0.3, 0.5), (0.5, 0.5), (0.7, 0.6), (0.5, 0.8)].map(|(fx, fy)| {
                let (x0, y0) = ((scene.width as f32 * fx) as u32 - 8, (scene.height as f32 * fy) as u32 - 8);
                Tile { x0, y0, x1: x0 + 16, y1: y0 + 16 }
            });
            bounces(&scene, &profile, 5, &tiles, |rays, hits, _| {
                let all = hits_of(
                    &scene,
                    rays,
                    hits,
                    &[MaterialKind::Lambert, MaterialKind::Mirror, MaterialKind::Glossy, MaterialKind::Dielectric],
                );
                for chunk in all.chunks(LANES) {
                    let get =
                        |f: &dyn Fn(usize) -> f32| std::array::from_fn::<f32, LANES, _>(|l| chunk.get(l).map_or(0.0, |&i| f(i as usize)));
                    let o = Vec3x8::from_rows(&[get(&|i| rays.ox[i]), get(&|i| rays.oy[i]), get(&|i| rays.oz[i])]);
                    let d = Vec3x8::from_rows(&[get(&|i| rays.dx[i]), get(&|i| rays.dy[i]), get(&|i| rays.dz[i])]);
                    let t = get(&|i| hits.t[i]);
                    let times = get(&|i| if rays.with_time { rays.time[i] } else { 0.0 });
                    let prims = std::array::from_fn(|l| chunk.get(l).map_or(chunk[0], |&i| i) as usize).map(|i| hits.prim[i]);
                    let geo = hit_rows_x8(&scene, hits, chunk, o, d, &t, &times, &prims);
                    for (l, &i) in chunk.iter().enumerate() {
                        let i = i as usize;
                        let r = RayItem { o: o.lane(l), d: d.lane(l), time: times[l], ..RayItem::default() };
                        let h = surface_hit(&scene, &r, t[l], hits.prim[i], hits.leaf[i], hits.flip[i]);
                        let bits = |v: Vec3| v.to_array().map(f32::to_bits);
                        let at = format!("{name}: hit {i} (prim {}, leaf {})", hits.prim[i], hits.leaf[i]);
                        assert_eq!(bits(geo.p.lane(l)), bits(h.p), "{at}: point");
                        assert_eq!(bits(geo.n_facing.lane(l)), bits(h.n_facing), "{at}: normal");
                        assert_eq!(geo.error_scale.to_array()[l].to_bits(), h.error_scale.to_bits(), "{at}: error magnitude");
                        assert_eq!(geo.front & (1 << l) != 0, h.front, "{at}: side");
                        assert_eq!(geo.material[l], h.material, "{at}: material");
                        lanes += 1;
                        // (CSG hits, which the 8-lane leaf forms take.)
                        csg_lanes += (hits.leaf[i] != NONE) as usize;
                        if hits.leaf[i] != NONE {
                            match scene.csg.leaf(hits.leaf[i]).shape {
                                crate::csg::Shape::Cone { .. } => curved[0] += 1,
                                crate::csg::Shape::Torus { .. } => curved[1] += 1,
                                _ => {}
                            }
                        }
                        box_lanes += matches!(scene.prims[hits.prim[i] as usize].shape, Shape::Box(_)) as usize;
                        ellipsoid_lanes += matches!(scene.prims[hits.prim[i] as usize].shape, Shape::Ellipsoid(_)) as usize;
                    }
                }
            });
        }
        assert!(
            lanes > 20_000 && csg_lanes > 5_000 && box_lanes > 1_000 && ellipsoid_lanes > 300 && curved[0] > 100 && curved[1] > 100,
            "{lanes} hits compared, {csg_lanes} on CSG leaves ({} cones, {} tori), {box_lanes} on boxes, {ellipsoid_lanes} on ellipsoids",
            curved[0],
            curved[1]
        );
    }

    /// `lambert_x8`'s fast paths (whole chunks of one prim, one texture and one point key; pixels and
    /// samples of consecutive paths as one load; runs of consecutive rays) give the requests and
    /// diffuse rays its lane-by-lane path gives (chunks of one hit), bit for bit and in the same order:
    /// five bounces of scenes with checker textures, spheres, boxes, CSG, glass (whose split branching
    /// gives two rays one path, so that path ids repeat within a chunk) and motion, with and without
    /// diffuse bounces.
    #[test]
    fn lambert_x8_chunks_equal_single_hits() {
        let (mut compared, mut uniform) = (0usize, 0usize);
        for name in ["showcase", "bench_spheres", "cornell", "glass", "motion", "csg"] {
            let scene = crate::scene::load_scene(std::path::Path::new(&format!("scenes/{name}.toml"))).unwrap();
            for variant in 0..3 {
                let mut profile = Profile::builtin("bench");
                (profile.spp, profile.max_depth) = ([8, 2, 16][variant], 4);
                if variant == 1 {
                    profile.branching = Branching::Split;
                }
                if variant == 2 {
                    (profile.diffuse_depth, profile.throughput_cutoff) = (2, 0.3);
                }
                let ctx = Ctx::new(&scene, &profile, 9);
                // Tiles of 16 x 16 pixels across the image.
                let tiles = [(0.25, 0.5), (0.5, 0.5), (0.75, 0.5), (0.5, 0.3), (0.5, 0.7), (0.3, 0.8), (0.7, 0.8)].map(|(fx, fy)| {
                    let (x0, y0) = ((scene.width as f32 * fx) as u32 - 8, (scene.height as f32 * fy) as u32 - 8);
                    Tile { x0, y0, x1: x0 + 16, y1: y0 + 16 }
                });
                bounces(&scene, &profile, 9, &tiles, |rays, hits, paths| {
                    // Under split branching, some hits left out too (any increasing subset is valid
                    // input): with the repeated path ids, runs whose ends alone look consecutive.
                    let lambert: Vec<u32> =
                        hits_of(&scene, rays, hits, &[MaterialKind::Lambert]).into_iter().filter(|&i| variant != 1 || i % 5 != 3).collect();
                    let with = || RayQueue::new(rays.with_time, rays.with_lambda);
                    let (mut nee_a, mut nee_b, mut next_a, mut next_b) = (NeeQueue::default(), NeeQueue::default(), with(), with());
                    let (mut memo_a, mut memo_b) = (KeyMemo::default(), KeyMemo::default());
                    for chunk in lambert.chunks(LANES) {
                        let one_prim = chunk.len() == LANES && chunk.iter().all(|&i| hits.prim[i as usize] == hits.prim[chunk[0] as usize]);
                        uniform += one_prim as usize;
                        ctx.lambert_x8(rays, hits, chunk, paths, &mut nee_a, &mut next_a, &mut memo_a);
                        for i in chunk {
                            ctx.lambert_x8(rays, hits, std::slice::from_ref(i), paths, &mut nee_b, &mut next_b, &mut memo_b);
                        }
                    }
                    let (a, b) = (nee_bits(&nee_a), nee_bits(&nee_b));
                    assert_eq!(a.len(), b.len(), "{name} variant {variant}: request counts differ");
                    for (k, (x, y)) in a.iter().zip(&b).enumerate() {
                        assert_eq!(x, y, "{name} variant {variant}: request {k} differs");
                    }
                    compared += a.len() + assert_same_rays(&next_a, &next_b, &format!("{name} variant {variant}: diffuse rays"));
                });
            }
        }
        // Enough requests, and enough whole chunks of one prim, for the comparison to mean something.
        assert!(compared > 200_000 && uniform > 10_000, "{compared} compared, {uniform} uniform chunks");
    }
}
