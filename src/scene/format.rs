//! The scene file format, as serde reads it. Every field is `Spanned` so that validation errors can name
//! the line and column; every table denies unknown keys. Shapes and lights are flat tables with a `type`
//! and optional fields: `compile` checks per type which fields are required and which do not apply (a
//! flat table keeps spans exact, which serde's internally tagged enums do not).

use serde::Deserialize;
use std::collections::BTreeMap;
use toml::Spanned;

pub type S<T> = Spanned<T>;
pub type V3 = S<Nums<3>>;

/// Exactly `N` numbers. serde's `[f32; N]` reads the first `N` elements of a longer array and silently
/// drops the rest (`center = [0, 0, 0, 5]` was accepted as the origin).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Nums<const N: usize>(pub [f32; N]);

impl<'de, const N: usize> Deserialize<'de> for Nums<N> {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V<const N: usize>;
        impl<'de, const N: usize> serde::de::Visitor<'de> for V<N> {
            type Value = Nums<N>;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                write!(f, "an array of {N} numbers")
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<Nums<N>, A::Error> {
                let mut out = [0.0f32; N];
                for (i, slot) in out.iter_mut().enumerate() {
                    *slot = seq.next_element()?.ok_or_else(|| serde::de::Error::invalid_length(i, &self))?;
                }
                let mut len = N;
                while seq.next_element::<serde::de::IgnoredAny>()?.is_some() {
                    len += 1;
                }
                if len > N {
                    return Err(serde::de::Error::invalid_length(len, &self));
                }
                Ok(Nums(out))
            }
        }
        d.deserialize_seq(V::<N>)
    }
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    pub image: S<ImageDef>,
    pub camera: S<CameraDef>,
    #[serde(default)]
    pub materials: BTreeMap<String, S<MaterialDef>>,
    /// Named solids, reusable by `use = "name"` in shapes and CSG children.
    #[serde(default)]
    pub solids: BTreeMap<String, S<ShapeDef>>,
    #[serde(default)]
    pub shapes: Vec<S<ShapeDef>>,
    #[serde(default)]
    pub lights: Vec<S<LightDef>>,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
pub struct ImageDef {
    pub width: S<i64>,
    pub height: S<i64>,
    pub background: Option<V3>,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
pub struct CameraDef {
    pub position: V3,
    pub look_at: V3,
    pub up: Option<V3>,
    /// Vertical field of view in degrees.
    pub fov: S<f32>,
    /// Lens radius (world units); 0 or absent is a pinhole.
    pub aperture: Option<S<f32>>,
    pub focus_distance: Option<S<f32>>,
    /// Shutter open and close times; objects move by `motion * t`.
    pub shutter: Option<S<Nums<2>>>,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
pub struct CheckerDef {
    pub a: V3,
    pub b: V3,
    pub scale: Option<S<f32>>,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
pub struct MaterialDef {
    #[serde(rename = "type")]
    pub kind: S<String>,
    pub albedo: Option<V3>,
    pub checker: Option<S<CheckerDef>>,
    pub tint: Option<V3>,
    pub radiance: Option<V3>,
    pub roughness: Option<S<f32>>,
    pub ior: Option<S<f32>>,
    pub cauchy: Option<S<Nums<2>>>,
    pub abbe: Option<S<Nums<2>>>,
    pub absorption: Option<V3>,
    pub transmittance: Option<V3>,
    pub transmittance_distance: Option<S<f32>>,
    pub thin: Option<S<bool>>,
    pub fresnel: Option<S<String>>,
    /// Interface priority of a dielectric medium (Schmidt & Budge 2002): where media overlap, the
    /// higher priority owns the overlap.
    pub priority: Option<S<i64>>,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
pub struct TransformDef {
    pub scale: Option<V3>,
    /// Degrees about x, then y, then z.
    pub rotate: Option<V3>,
    pub translate: Option<V3>,
}

/// One shape table. The fields most shapes leave out are boxed: a large scene holds every `ShapeDef` at
/// once until it is compiled, and 160,000 spheres' definitions took 140 MB of its 395 MB peak at 880
/// bytes each (now 288: `type`, `material`, `center` and `radius` inline, 8 bytes for each other field).
#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
pub struct ShapeDef {
    #[serde(rename = "type")]
    pub kind: Option<S<String>>,
    #[serde(rename = "use")]
    pub use_solid: Option<Box<S<String>>>,
    pub material: Option<S<String>>,
    pub center: Option<V3>,
    pub radius: Option<S<f32>>,
    pub point: Option<Box<V3>>,
    pub normal: Option<Box<V3>>,
    pub min: Option<Box<V3>>,
    pub max: Option<Box<V3>>,
    pub origin: Option<Box<V3>>,
    pub u: Option<Box<V3>>,
    pub v: Option<Box<V3>>,
    pub height: Option<Box<S<f32>>>,
    pub radius_top: Option<Box<S<f32>>>,
    pub major_radius: Option<Box<S<f32>>>,
    pub minor_radius: Option<Box<S<f32>>>,
    pub motion: Option<Box<V3>>,
    pub transform: Option<Box<S<TransformDef>>>,
    pub op: Option<Box<S<String>>>,
    pub children: Option<Box<S<Vec<S<ShapeDef>>>>>,
    pub hole: Option<Box<S<bool>>>,
}

/// A field's value as it is held, inline (`S<T>`) or boxed (`Box<S<T>>`).
pub trait Field<T> {
    fn spanned(&self) -> &S<T>;
}

impl<T> Field<T> for S<T> {
    fn spanned(&self) -> &S<T> {
        self
    }
}

impl<T> Field<T> for Box<S<T>> {
    fn spanned(&self) -> &S<T> {
        self
    }
}

impl ShapeDef {
    /// The first optional geometric field that is set and not in `allowed`, by name and span (for "does
    /// not apply" errors; no allocation, as it runs for every shape).
    pub fn misfit(&self, allowed: &[&str]) -> Option<(&'static str, std::ops::Range<usize>)> {
        macro_rules! check {
            ($($f:ident),*) => { $( if let Some(x) = &self.$f { if !allowed.contains(&stringify!($f)) { return Some((stringify!($f), x.span())); } } )* };
        }
        check!(center, radius, point, normal, min, max, origin, u, v, height, radius_top, major_radius, minor_radius, motion, op);
        // (`hole = false` is harmless on any shape: only `hole = true` is checked.)
        if let Some(x) = self.hole.as_ref().filter(|h| *h.get_ref()) {
            if !allowed.contains(&"hole") {
                return Some(("hole", x.span()));
            }
        }
        check!(children);
        None
    }
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
pub struct LightDef {
    #[serde(rename = "type")]
    pub kind: S<String>,
    pub position: Option<V3>,
    pub intensity: Option<V3>,
    pub origin: Option<V3>,
    pub u: Option<V3>,
    pub v: Option<V3>,
    pub center: Option<V3>,
    pub normal: Option<V3>,
    pub radius: Option<S<f32>>,
    pub radiance: Option<V3>,
}

#[cfg(test)]
mod tests {
    /// A large scene holds every shape's definition at once until it is compiled (see [`ShapeDef`]):
    /// a field added inline instead of boxed makes every shape larger.
    #[test]
    fn shape_definitions_stay_small() {
        let n = std::mem::size_of::<super::ShapeDef>();
        assert!(n <= 288, "ShapeDef is {n} bytes");
    }
}
