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
//! A ray that leaves a medium it never entered (its entry was lost: camera inside, or a fifth nested
//! medium that did not fit the stack) is taken to have been inside it.

use super::queues::MediumStack;
use crate::scene::{Dielectric, Material, Scene};

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

/// The medium a ray with this stack is in: highest priority, the last entered among equals.
#[inline]
pub fn current(scene: &Scene, stack: MediumStack) -> Option<u32> {
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
        Crossing { before: current(scene, stack), after: current(scene, after), stack: after }
    } else {
        let before = if stack.contains(m) {
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
        Crossing { before, after: current(scene, after), stack: after }
    }
}
