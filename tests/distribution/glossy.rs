//! Reflected-direction integral: a GGX glossy floor converges to the mirror image as roughness -> 0.
//! (The lobe's pdf and its chi-square test are in tests/physics.)

use super::*;
use strata::optics::GGX_ALPHA_MIN;

/// A reflective floor seen at a slant, reflecting emissive stripes and a sphere lit by a point light.
fn floor_scene(floor: &str) -> Scene {
    scene(&format!(
        r#"
[image]
width = 48
height = 48
[camera]
position = [0.0, 1.0, 3.0]
look_at = [0.0, 0.0, -0.5]
fov = 45.0
[materials.floor]
{floor}
[materials.white]
type = "lambert"
albedo = [0.8, 0.8, 0.8]
[materials.red]
type = "emissive"
radiance = [2.0, 0.2, 0.2]
[materials.blue]
type = "emissive"
radiance = [0.2, 0.4, 2.0]
[[shapes]]
type = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 1.0, 0.0]
material = "floor"
[[shapes]]
type = "sphere"
center = [0.3, 0.4, -0.8]
radius = 0.4
material = "white"
[[shapes]]
type = "quad"
origin = [-1.6, 0.0, -2.5]
u = [0.4, 0.0, 0.0]
v = [0.0, 1.5, 0.0]
material = "red"
[[shapes]]
type = "quad"
origin = [-0.6, 0.0, -2.5]
u = [0.4, 0.0, 0.0]
v = [0.0, 1.5, 0.0]
material = "blue"
[[shapes]]
type = "quad"
origin = [0.9, 0.0, -2.5]
u = [0.3, 0.0, 0.0]
v = [0.0, 1.5, 0.0]
material = "red"
[[lights]]
type = "point"
position = [1.5, 2.5, 1.0]
intensity = [3.0, 3.0, 3.0]
"#
    ))
}

#[test]
fn glossy_converges_to_mirror_as_roughness_vanishes() {
    let p = profile(16, "jittered", 1, "jittered");
    let (mirror, _) = render_image(&floor_scene("type = \"mirror\""), &p, 21);
    let roughness = [0.2f32, 0.05, 0.01, 0.001];
    let mut errs = Vec::new();
    for r in roughness {
        let (img, _) = render_image(&floor_scene(&format!("type = \"glossy\"\nroughness = {r}")), &p, 21);
        let e = mse(&img, &mirror);
        eprintln!("glossy roughness {r}: alpha {:.1e}, MSE vs mirror {e:.3e}", (r * r).max(GGX_ALPHA_MIN));
        errs.push(e);
    }
    let scale = mse(&mirror, &vec![Vec3::ZERO; mirror.len()]);
    for (i, w) in errs.windows(2).enumerate() {
        let (a0, a1) = ((roughness[i] * roughness[i]).max(GGX_ALPHA_MIN), (roughness[i + 1] * roughness[i + 1]).max(GGX_ALPHA_MIN));
        if a1 < a0 {
            assert!(w[1] < w[0], "MSE does not decrease from roughness {} to {}: {errs:?}", roughness[i], roughness[i + 1]);
        } else {
            // Both roughnesses clamp to the same alpha (GGX_ALPHA_MIN): the same lobe, the same image.
            assert_eq!(w[1], w[0], "equal alphas must render identically");
        }
    }
    assert!(errs[0] > 1e-3 * scale, "roughness 0.2 should differ visibly from the mirror ({:.2e})", errs[0]);
    // The narrowest lobe (1e-4 rad) renders as the mirror except where a sample lands across an edge of
    // an emitter (then one of 16 samples differs): at most 1% of the pixels differ by more than 0.1%.
    let (img, _) = render_image(&floor_scene("type = \"glossy\"\nroughness = 0.001"), &p, 21);
    let differ = img.iter().zip(&mirror).filter(|(a, b)| (**a - **b).abs().max_element() > 1e-3 * (b.max_element() + 0.01)).count();
    eprintln!("roughness 0.001: {differ} of {} pixels differ from the mirror by more than 0.1%", img.len());
    assert!(differ * 100 <= img.len(), "{differ} pixels differ from the mirror");
}
