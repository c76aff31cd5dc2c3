//! Which side is which: the medium a ray travels in, and what happens when it crosses a dielectric surface.
//!
//! Every ray carries a [`MediumStack`]: the dielectric media it is inside, in the order it entered them.
//! The medium the ray is *in* is the entry with the highest interface priority; among equal priorities the
//! one entered last (Schmidt & Budge 2002, "Simple Nested Dielectrics in Ray Traced Images", JGT 7(2)).
//! With all priorities equal (the default) this is the plain stack: the innermost medium.
//!
//! Crossing the surface of medium `m` (entering when the ray meets its outside, leaving otherwise) updates
//! the stack (push / remove `m`) and compares the medium before with the medium after:
//! * they differ: a **real interface** between their indices (air = 1 when the stack is empty);
//! * they are the same: a **null crossing**, the surface of an outranked medium inside a higher-priority
//!   one (the liquid's surface inside the wall of its glass), or of a second object of the same material.
//!   The ray goes on unchanged: no reflection, no bending, no bounce counted.
//!
//! Real interfaces with equal indices on both sides (an index-matched pair, a dielectric of index 1 in
//! air) reflect nothing and do not bend; shading treats them as null crossings too.
//!
//! A fifth nested medium does not fit the stack: its entry is lost (counted as [`Crossing::lost`]) and
//! both its surfaces are null crossings for that ray, which stays in the medium it was in. A ray that
//! leaves a medium it never entered on a stack with room (the camera inside a medium it does not start
//! in: an aperture or shutter across a surface) is taken to have been
//! inside it. Camera rays start with the media around the camera (`Scene::camera_media`).

use super::queues::MediumStack;
use crate::optics::beer_lambert;
use crate::scene::{Dielectric, Material, Scene};
use glam::Vec3;

/// The dielectric of material `m` (None for other kinds).
#[inline]
pub fn dielectric(scene: &Scene, m: u32) -> Option<&Dielectric> {
    match &scene.materials[m as usize] {
        Material::Dielectric(d) => Some(d),
        _ => None,
    }
}

#[inline]
fn priority(scene: &Scene, m: u32) -> i32 {
    dielectric(scene, m).map_or(i32::MIN, |d| d.priority)
}

/// Beer-Lambert transmittance over `dist` in the current medium of `stack` (1 in air or a clear
/// medium): a ray's segment inside it, or the whole of a shadow segment that starts there and crosses
/// no surface.
#[inline]
pub fn absorption(scene: &Scene, stack: MediumStack, dist: f32) -> Vec3 {
    match current(scene, stack).and_then(|m| dielectric(scene, m)) {
        Some(d) if d.sigma_a != Vec3::ZERO => beer_lambert(d.sigma_a, dist),
        _ => Vec3::ONE,
    }
}

/// The medium a ray with this stack is in: highest priority, the last entered among equals.
#[inline]
pub fn current(scene: &Scene, stack: MediumStack) -> Option<u32> {
    // At most one entry (slot 0; the usual case: air, or inside one object): it is the medium, whatever
    // its priority.
    if stack.0 >> 16 == 0 {
        return (stack.0 != 0).then(|| (stack.0 & 0xffff) as u32 - 1);
    }
    let mut best: Option<(u32, i32)> = None;
    for m in stack.iter() {
        let p = priority(scene, m);
        // Entries run outermost to innermost: `>=` lets a later entry win a tie.
        if best.is_none_or(|(_, bp)| p >= bp) {
            best = Some((m, p));
        }
    }
    best.map(|(m, _)| m)
}

/// The outcome of crossing one dielectric surface.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Crossing {
    /// Medium on the incident side (None = air).
    pub before: Option<u32>,
    /// Medium on the far side.
    pub after: Option<u32>,
    /// The stack of a ray that goes through.
    pub stack: MediumStack,
    /// Entering a medium the full stack could not keep (a fifth nested one): it is not on `stack`, so
    /// the ray takes the medium it was in for this one (counted, and warned of after the render).
    pub lost: bool,
}

impl Crossing {
    /// The surface separates two different media (else it is a null crossing).
    #[inline]
    pub fn is_real(&self) -> bool {
        self.before != self.after
    }
}

/// Cross the surface of medium `m`, entering it when `entering` (the ray meets the surface's outside).
#[inline]
pub fn cross(scene: &Scene, stack: MediumStack, m: u32, entering: bool) -> Crossing {
    if entering {
        let after = stack.push(m);
        Crossing { before: current(scene, stack), after: current(scene, after), stack: after, lost: stack.is_full() }
    } else {
        let before = if stack.contains(m) || stack.is_full() {
            // (Not on a full stack: a fifth medium whose entry was lost, and whose surface was a null
            // crossing on the way in; on the way out too, so the ray stays in the medium it was in.)
            current(scene, stack)
        } else {
            let inside = stack.push(m);
            if inside.contains(m) {
                current(scene, inside)
            } else {
                Some(m)
            }
        };
        let after = stack.remove(m);
        Crossing { before, after: current(scene, after), stack: after, lost: false }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::parse_scene;
    use std::path::Path;

    /// Materials 0..: air-bubble (prio 2), glass (prio 3), ice (prio 2), water (prio 1) (BTreeMap order).
    fn scene() -> Scene {
        let text = "[image]\nwidth = 2\nheight = 2\n[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\nfov = 30\n\
            [materials.a_bubble]\ntype = \"dielectric\"\nior = 1.0\npriority = 2\n\
            [materials.b_glass]\ntype = \"dielectric\"\nior = 1.5\npriority = 3\n\
            [materials.c_ice]\ntype = \"dielectric\"\nior = 1.31\npriority = 2\n\
            [materials.d_water]\ntype = \"dielectric\"\nior = 1.33\npriority = 1\n";
        parse_scene(Path::new("m.toml"), text).unwrap()
    }
    const BUBBLE: u32 = 0;
    const GLASS: u32 = 1;
    const ICE: u32 = 2;
    const WATER: u32 = 3;

    /// `current` (with its one-entry shortcut) equals the rule of the module doc computed directly: the
    /// entry of highest priority, the innermost among equals; on every stack of up to 4 entries drawn
    /// from the four media (repeats included).
    #[test]
    fn current_equals_the_priority_rule() {
        let s = scene();
        let ids = [BUBBLE, GLASS, ICE, WATER];
        let prio = |m: u32| dielectric(&s, m).map(|d| d.priority).unwrap();
        let mut checked = 0;
        for depth in 0..=MediumStack::DEPTH as u32 {
            for code in 0..4usize.pow(depth) {
                let entries: Vec<u32> = (0..depth).map(|k| ids[code / 4usize.pow(k) % 4]).collect();
                let stack = entries.iter().fold(MediumStack::default(), |st, &m| st.push(m));
                // Outermost first: among the highest priority, the last entered.
                let top = entries.iter().map(|&m| prio(m)).max();
                let want = entries.iter().copied().rev().find(|&m| Some(prio(m)) == top);
                assert_eq!(current(&s, stack), want, "stack {entries:?}");
                checked += 1;
            }
        }
        assert_eq!(checked, 1 + 4 + 16 + 64 + 256);
    }

    #[test]
    fn current_is_highest_priority_then_last_entered() {
        let s = scene();
        let e = MediumStack::default();
        assert_eq!(current(&s, e), None);
        assert_eq!(current(&s, e.push(WATER).push(GLASS)), Some(GLASS));
        assert_eq!(current(&s, e.push(GLASS).push(WATER)), Some(GLASS));
        // Equal priorities: the last entered.
        assert_eq!(current(&s, e.push(ICE).push(BUBBLE)), Some(BUBBLE));
        assert_eq!(current(&s, e.push(BUBBLE).push(ICE)), Some(ICE));
    }

    #[test]
    fn crossings_real_and_null() {
        let s = scene();
        let e = MediumStack::default();
        // Air into glass: real.
        let c = cross(&s, e, GLASS, true);
        assert_eq!((c.before, c.after, c.is_real()), (None, Some(GLASS), true));
        // Inside the glass wall, meeting the water's surface: null, but the water is now on the stack.
        let c2 = cross(&s, c.stack, WATER, true);
        assert_eq!((c2.before, c2.after, c2.is_real()), (Some(GLASS), Some(GLASS), false));
        // Leaving the glass into the water: real, glass -> water.
        let c3 = cross(&s, c2.stack, GLASS, false);
        assert_eq!((c3.before, c3.after, c3.is_real()), (Some(GLASS), Some(WATER), true));
        // Into a bubble in the water and out again.
        let c4 = cross(&s, c3.stack, BUBBLE, true);
        assert_eq!((c4.before, c4.after), (Some(WATER), Some(BUBBLE)));
        let c5 = cross(&s, c4.stack, BUBBLE, false);
        assert_eq!((c5.before, c5.after, c5.stack), (Some(BUBBLE), Some(WATER), c3.stack));
        // Leaving a medium the ray never entered: taken as inside it.
        let c6 = cross(&s, e, ICE, false);
        assert_eq!((c6.before, c6.after, c6.stack), (Some(ICE), None, e));
        // A second object of the same material overlapping the first: its surfaces are null crossings.
        let c7 = cross(&s, e.push(GLASS), GLASS, true);
        assert!(!c7.is_real());
        let c8 = cross(&s, c7.stack, GLASS, false);
        assert!(!c8.is_real() && c8.stack == e.push(GLASS));
    }

    /// Leaving a medium whose entry was lost (never on the stack) while inside a higher-priority one: the
    /// ray is taken to have been inside the lost medium too (README, "Which side is which"), so on the
    /// stack {glass} the water's surface is outranked by the glass on both sides: a null crossing, glass to
    /// glass, and the stack is unchanged. With a lower-priority (or no) medium around it, the lost medium
    /// itself is the medium before.
    #[test]
    fn leaving_a_lost_medium_inside_a_higher_priority_one_is_null() {
        let s = scene();
        let e = MediumStack::default();
        let c = cross(&s, e.push(GLASS), WATER, false);
        assert_eq!((c.before, c.after, c.is_real()), (Some(GLASS), Some(GLASS), false), "{c:?}");
        assert_eq!(c.stack, e.push(GLASS));
        // Same with glass outermost under a lower-priority medium entered later.
        let c = cross(&s, e.push(GLASS).push(BUBBLE), ICE, false);
        assert_eq!((c.before, c.after, c.is_real()), (Some(GLASS), Some(GLASS), false), "{c:?}");
        // The lost medium outranks what is on the stack: it was the medium, the crossing is real.
        let c = cross(&s, e.push(WATER), GLASS, false);
        assert_eq!((c.before, c.after, c.is_real()), (Some(GLASS), Some(WATER), true), "{c:?}");
    }
}
