//! Which opaque surfaces a glass surface may lie on: per prim with a dielectric surface, the prims with
//! an opaque surface whose bounds touch its own (and every opaque unbounded plane). The intersect and
//! CSG stages use the lists to let a glass face that coincides with an opaque face give way to it
//! (`wavefront::intersect::glass_gives_way`): a glass resting on a table top or a floor.
//!
//! The lists are candidates only; the rule itself compares the two surfaces' hits on each ray. A list
//! holds every prim whose bounds come within `margin` of the glass prim's bounds, where `margin` covers
//! the rule's tolerance for every ray of the scene (see [`GlassNeighbours::build`]).

use glam::Vec3;

use super::{MaterialKind, Prim, Shape};
use crate::accel::{build_bvh, Aabb, BuildOptions, Bvh};
use crate::csg::{Csg, COINCIDENT_EPS};
use crate::geometry::OFFSET_ULPS;

/// Glass prims from which the neighbours are found in a tree of the opaque prims alone, built for the
/// purpose: the scene's tree walks every glass prim near each glass prim too, and a heap of glass
/// overlapping itself made that quadratic (a trial's 100,000 coincident glass boxes: 53 s of setup, 97%
/// in this walk). Below it the scene's tree is queried (no second build).
pub const OWN_TREE_GLASS: usize = 64;

/// Per prim, the opaque prims a dielectric surface of it may lie on (compressed rows; empty in a scene
/// where no glass surface can touch an opaque one).
#[derive(Clone, Debug, Default)]
pub struct GlassNeighbours {
    /// `start[p]..start[p + 1]` indexes `list` (length prims + 1, or 0 when no prim has a neighbour).
    start: Vec<u32>,
    list: Vec<u32>,
}

impl GlassNeighbours {
    /// True when no glass surface of the scene can lie on an opaque one (the rule is skipped).
    #[inline(always)]
    pub fn is_empty(&self) -> bool {
        self.list.is_empty()
    }

    /// The opaque prims that prim `pid`'s dielectric surfaces may lie on (planes first, then bounded
    /// prims by id).
    #[inline(always)]
    pub fn of(&self, pid: u32) -> &[u32] {
        match self.start.get(pid as usize..pid as usize + 2) {
            Some(&[a, b]) => &self.list[a as usize..b as usize],
            _ => &[],
        }
    }

    /// The lists of a scene's prims. `kind` and `leaf_kind`: material kinds of the prims and the CSG
    /// leaves; `bounds`: each prim's bounds (empty for unbounded prims, whose ids are `unbounded`);
    /// `bvh` over the bounded prims (`bounded[index]` = prim id); `extent`: the largest absolute
    /// coordinate a ray origin or hit of the scene can have among its bounded prims and camera.
    ///
    /// The rule's tolerance along a ray is `COINCIDENT_EPS (|o|_inf + t |d|)`: with origin and hit
    /// within `extent`, at most `COINCIDENT_EPS (extent + 2 sqrt(3) extent)`; its reach across a
    /// surface twice the spawn offset, `2 OFFSET_ULPS ulp(extent)`. Bounds within 8 times their sum
    /// (and 2^-20 of the prim's own size) of each other are neighbours. From `own_tree` glass prims on
    /// ([`OWN_TREE_GLASS`]), a tree of the opaque prims alone is queried; the lists are the same.
    #[allow(clippy::too_many_arguments)]
    pub fn build(
        prims: &[Prim],
        csg: &Csg,
        kind: &[MaterialKind],
        leaf_kind: &[MaterialKind],
        bounds: &[Aabb],
        bounded: &[u32],
        unbounded: &[u32],
        bvh: &Bvh,
        extent: f32,
        own_tree: usize,
    ) -> Self {
        // Whether a prim has a dielectric surface, and whether it has an opaque one.
        let surfaces = |p: usize| -> (bool, bool) {
            match prims[p].shape {
                Shape::Csg { solid } => csg.solid_leaves(solid).fold((false, false), |(g, o), l| {
                    let glass = leaf_kind[l as usize] == MaterialKind::Dielectric;
                    (g || glass, o || !glass)
                }),
                _ => {
                    let glass = kind[p] == MaterialKind::Dielectric;
                    (glass, !glass)
                }
            }
        };
        let glass: Vec<usize> = (0..prims.len()).filter(|&p| surfaces(p).0).collect();
        if glass.is_empty() {
            return Self::default();
        }
        let planes: Vec<u32> =
            unbounded.iter().copied().filter(|&p| matches!(prims[p as usize].shape, Shape::Plane(_)) && surfaces(p as usize).1).collect();
        let margin = 8.0 * (COINCIDENT_EPS * (1.0 + 2.0 * 3f32.sqrt()) + OFFSET_ULPS * f32::EPSILON) * extent;
        // The tree queried (`ids[k]`: the prim of its entry `k`): the scene's, or one of the prims with an
        // opaque surface alone where glass is plentiful (see `OWN_TREE_GLASS`).
        let opaque_tree = (glass.len() >= own_tree).then(|| {
            let ids: Vec<u32> = bounded.iter().copied().filter(|&q| surfaces(q as usize).1).collect();
            let boxes: Vec<Aabb> = ids.iter().map(|&q| bounds[q as usize]).collect();
            (build_bvh(&boxes, &BuildOptions::default()), ids)
        });
        let (tree, ids) = opaque_tree.as_ref().map_or((bvh, bounded), |(t, ids)| (t, ids.as_slice()));
        let mut start = vec![0u32; prims.len() + 1];
        let mut list = Vec::new();
        let mut stack = Vec::new();
        let mut found = Vec::new();
        let mut next = 0;
        for &g in &glass {
            // (Prims before `g` have empty rows.)
            start[next..=g].fill(list.len() as u32);
            list.extend_from_slice(&planes);
            let b = bounds[g];
            if b.min.x <= b.max.x && !tree.is_empty() {
                let pad = Vec3::splat(margin) + (b.max - b.min) * 2f32.powi(-20);
                let (lo, hi) = (b.min - pad, b.max + pad);
                found.clear();
                tree.for_each_in_box(lo, hi, &mut stack, |k| {
                    let q = ids[k as usize];
                    let qb = bounds[q as usize];
                    if q as usize != g && !(qb.min.cmpgt(hi).any() || qb.max.cmplt(lo).any()) && surfaces(q as usize).1 {
                        found.push(q);
                    }
                });
                found.sort_unstable();
                list.extend_from_slice(&found);
            }
            next = g + 1;
        }
        start[next..].fill(list.len() as u32);
        if list.is_empty() {
            return Self::default();
        }
        Self { start, list }
    }
}

#[cfg(test)]
mod tests {
    use super::GlassNeighbours;
    use crate::scene::{parse_scene, Scene};

    fn scene(shapes: &str) -> Scene {
        let text = format!(
            "[image]\nwidth = 4\nheight = 4\n[camera]\nposition = [0, 3, 9]\nlook_at = [0, 0, 0]\nfov = 40\n\
             [materials.f]\ntype = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\n[materials.g]\ntype = \"dielectric\"\nior = 1.5\n{shapes}"
        );
        parse_scene(std::path::Path::new("n.toml"), &text).unwrap()
    }

    /// A glass block on a table, beside a sphere that touches it and far from another; a glass sphere
    /// inside a CSG solid of a glass and an opaque part; a scene without glass.
    #[test]
    fn lists_hold_the_opaque_prims_that_touch_the_glass() {
        let s = scene(
            "[[shapes]]\ntype = \"plane\"\npoint = [0, -3, 0]\nnormal = [0, 1, 0]\nmaterial = \"f\"\n\
             [[shapes]]\ntype = \"box\"\nmin = [-1, 0, -1]\nmax = [1, 1, 1]\nmaterial = \"g\"\n\
             [[shapes]]\ntype = \"box\"\nmin = [-2, -1, -2]\nmax = [2, 0, 2]\nmaterial = \"f\"\n\
             [[shapes]]\ntype = \"sphere\"\ncenter = [1.5, 0.5, 0]\nradius = 0.5\nmaterial = \"f\"\n\
             [[shapes]]\ntype = \"sphere\"\ncenter = [1.5, 2.5, 0]\nradius = 0.5\nmaterial = \"f\"\n\
             [[shapes]]\ntype = \"sphere\"\ncenter = [5, 0.5, 0]\nradius = 0.5\nmaterial = \"g\"\n\
             [[shapes]]\ntype = \"csg\"\nop = \"union\"\nmaterial = \"g\"\nchildren = [ { type = \"sphere\", center = [9, 0, 0], radius = 1 }, \
             { type = \"box\", min = [9.5, -0.2, -0.2], max = [10.5, 0.2, 0.2], material = \"f\" } ]\n",
        );
        let n = &s.glass_neighbours;
        // Prims in file order: 0 plane, 1 glass box, 2 table, 3 touching sphere, 4 sphere 1.5 above, 5
        // glass sphere alone, 6 a CSG solid of a glass sphere and an opaque box (its own leaves are the
        // CSG rule's business, not a neighbour's).
        assert_eq!(n.of(1), &[0, 2, 3], "the glass block");
        assert_eq!(n.of(5), &[0], "a glass sphere that touches no bounded prim");
        assert_eq!(n.of(6), &[0], "a CSG solid with a glass leaf");
        for opaque in [0, 2, 3, 4] {
            assert!(n.of(opaque).is_empty(), "prim {opaque} has no glass surface");
        }
        let none = scene(
            "[[shapes]]\ntype = \"plane\"\npoint = [0, 0, 0]\nnormal = [0, 1, 0]\nmaterial = \"f\"\n\
             [[shapes]]\ntype = \"box\"\nmin = [-1, 0, -1]\nmax = [1, 1, 1]\nmaterial = \"f\"\n",
        );
        assert!(none.glass_neighbours.is_empty(), "no glass: the pass is skipped");
        let apart = scene(
            "[[shapes]]\ntype = \"box\"\nmin = [-1, 0, -1]\nmax = [1, 1, 1]\nmaterial = \"g\"\n\
             [[shapes]]\ntype = \"box\"\nmin = [-1, -1, -1]\nmax = [1, -0.01, 1]\nmaterial = \"f\"\n",
        );
        assert!(apart.glass_neighbours.is_empty(), "glass 0.01 above the table: no neighbour");
    }

    /// The opaque prims' own tree gives the lists the scene's tree gives: a heap of 120 glass spheres and
    /// boxes, some coincident, among opaque spheres, boxes and a CSG solid, on a table and a plane.
    #[test]
    fn the_opaque_tree_gives_the_scene_trees_lists() {
        let mut shapes = String::from(
            "[[shapes]]\ntype = \"plane\"\npoint = [0, -3, 0]\nnormal = [0, 1, 0]\nmaterial = \"f\"\n\
             [[shapes]]\ntype = \"box\"\nmin = [-9, -1, -9]\nmax = [9, 0, 9]\nmaterial = \"f\"\n\
             [[shapes]]\ntype = \"csg\"\nop = \"union\"\nmaterial = \"g\"\nchildren = [ { type = \"sphere\", center = [3, 1, 0], radius = 1 }, \
             { type = \"box\", min = [3.5, 0.8, -0.2], max = [4.5, 1.2, 0.2], material = \"f\" } ]\n",
        );
        for i in 0..160 {
            let (x, z) = ((i * 37 % 17) as f32 - 8.0, (i * 11 % 13) as f32 - 6.0);
            let (m, r) = (if i % 4 == 3 { "f" } else { "g" }, 0.3 + (i % 5) as f32 * 0.2);
            if i % 2 == 0 {
                shapes += &format!("[[shapes]]\ntype = \"sphere\"\ncenter = [{x}, {r}, {z}]\nradius = {r}\nmaterial = \"{m}\"\n");
            } else {
                shapes +=
                    &format!("[[shapes]]\ntype = \"box\"\nmin = [{x}, 0, {z}]\nmax = [{}, {r}, {}]\nmaterial = \"{m}\"\n", x + r, z + r);
            }
        }
        let s = scene(&shapes);
        let build = |own| {
            GlassNeighbours::build(&s.prims, &s.csg, &s.prim_kind, &s.leaf_kind, &s.bounds, &s.bounded, &s.unbounded, &s.bvh, 10.0, own)
        };
        let (scene_tree, own_tree) = (build(usize::MAX), build(0));
        assert!(scene_tree.list.len() > 200, "a test of few neighbours: {}", scene_tree.list.len());
        assert_eq!((&scene_tree.start, &scene_tree.list), (&own_tree.start, &own_tree.list));
    }
}
