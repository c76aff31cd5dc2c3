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

/// GGX reflection `f(wo, wi) cos(wi)` (no Fresnel, tint 1), written out here in f64 from Walter et al.
/// 2007 and Heitz 2014: `D(h) G2(wo, wi) / (4 cos_o)` with the height-correlated Smith `G2`.
fn ggx_f_cos(wo: DVec3, n: DVec3, wi: DVec3, alpha: f64) -> f64 {
    let (co, ci) = (wo.dot(n), wi.dot(n));
    if co <= 0.0 || ci <= 0.0 {
        return 0.0;
    }
    let h = (wo + wi).normalize();
    let ch = h.dot(n);
    let a2 = alpha * alpha;
    let k = ch * ch * (a2 - 1.0) + 1.0;
    let d = a2 / (std::f64::consts::PI * k * k);
    let lambda = |c: f64| ((1.0 + a2 * (1.0 - c * c) / (c * c)).sqrt() - 1.0) / 2.0;
    let g2 = 1.0 / (1.0 + lambda(co) + lambda(ci));
    d * g2 / (4.0 * co)
}

/// A glossy floor (y = 0, tint 1) seen from `camera` under `light` (a `[[lights]]` table), nothing else.
fn glossy_floor(roughness: f64, light: &str, w: u32, h: u32) -> Scene {
    scene(&format!(
        "[image]\nwidth = {w}\nheight = {h}\n[camera]\nposition = [0.0, 1.0, 3.0]\nlook_at = [0.0, 0.0, -1.0]\nfov = 40.0\n\
         [materials.floor]\ntype = \"glossy\"\nroughness = {roughness}\n\
         [[shapes]]\ntype = \"plane\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 1.0, 0.0]\nmaterial = \"floor\"\n{light}"
    ))
}

/// The floor point and the direction back to the camera seen through pixel `(x, y)`'s centre.
fn floor_point(cam: &PinholeF64, x: usize, y: usize) -> Option<(DVec3, DVec3)> {
    let d = cam.dir(x as f64 + 0.5, y as f64 + 0.5);
    let t = -cam.pos.y / d.y;
    (t > 0.0).then(|| (cam.pos + d * t, -d))
}

/// A point light on a glossy floor: every pixel (one sample through its centre) is the GGX lobe times
/// `I / d^2`, evaluated here in f64. Before glossy surfaces took next-event estimation this image was
/// black (a point light is found by no reflected ray).
#[test]
fn a_point_light_on_a_glossy_floor_gives_the_ggx_highlight() {
    let (w, h) = (40, 30);
    let pos = DVec3::new(0.0, 1.0, -1.0);
    for roughness in [0.2, 0.5, 0.9] {
        let s = glossy_floor(
            roughness,
            &format!("[[lights]]\ntype = \"point\"\nposition = {}\nintensity = [10.0, 10.0, 10.0]\n", v3(pos)),
            w,
            h,
        );
        let (img, _) = render_image(&s, &profile(1, "center", 1, "center"), 3);
        let cam = PinholeF64::new(DVec3::new(0.0, 1.0, 3.0), DVec3::new(0.0, 0.0, -1.0), DVec3::Y, 40.0, w, h);
        let alpha = roughness * roughness;
        let (mut worst, mut peak) = (0.0f64, 0.0f64);
        for y in 0..h as usize {
            for x in 0..w as usize {
                let want = floor_point(&cam, x, y).map_or(0.0, |(p, wo)| {
                    let v = pos - p;
                    10.0 * ggx_f_cos(wo, DVec3::Y, v.normalize(), alpha) / v.length_squared()
                });
                let got = img[y * w as usize + x].x as f64;
                peak = peak.max(want);
                worst = worst.max((got - want).abs() / want.max(1e-3));
            }
        }
        eprintln!("roughness {roughness}: peak radiance {peak:.3}, largest relative error {worst:.2e}");
        assert!(peak > 0.1, "a visible highlight ({peak})");
        assert!(worst < 2e-3, "roughness {roughness}: a pixel off the GGX lobe by {worst:.2e}");
    }
}

/// A quad light over a glossy floor: light samples (next-event estimation) and the lobe rays that find
/// the light are combined by multiple importance sampling; the image must be the lobe integrated over
/// the light (f64 midpoint quadrature over the quad) whatever the light-sample count, and with no lobe
/// ray at all (`max_depth = 0`: next-event estimation alone, weight 1). Counting the light twice (both
/// weights 1) would double the highlight; a wrong weight biases it.
#[test]
fn an_area_light_on_a_glossy_floor_is_the_lobe_integrated_over_the_light() {
    let (w, h) = (24, 18);
    let (origin, u, v, radiance) = (DVec3::new(-0.5, 1.5, -1.5), DVec3::new(1.0, 0.0, 0.0), DVec3::new(0.0, 0.0, 1.0), 4.0);
    let light = format!(
        "[[lights]]\ntype = \"quad\"\norigin = {}\nu = {}\nv = {}\nradiance = [{radiance}, {radiance}, {radiance}]\n",
        v3(origin),
        v3(u),
        v3(v)
    );
    let roughness = 0.3;
    let alpha = roughness * roughness;
    let s = glossy_floor(roughness, &light, w, h);
    // The same under a slab of index 1 between floor and light (shadow rays and lobe rays cross it
    // unbent): the lobe ray's weight must be taken from the glossy point, not from where it left the
    // slab (that made the highlight 12% too bright in a review).
    let slab = "[materials.air]\ntype = \"dielectric\"\nior = 1.0\n\
                [[shapes]]\ntype = \"box\"\nmin = [-4.0, 0.6, -5.0]\nmax = [4.0, 0.9, 3.5]\nmaterial = \"air\"\n";
    let slabbed = glossy_floor(roughness, &format!("{light}{slab}"), w, h);
    let cam = PinholeF64::new(DVec3::new(0.0, 1.0, 3.0), DVec3::new(0.0, 0.0, -1.0), DVec3::Y, 40.0, w, h);
    let nl = u.cross(v).normalize();
    let k = 200;
    let truth: Vec<f64> = (0..(w * h) as usize)
        .map(|i| {
            let Some((p, wo)) = floor_point(&cam, i % w as usize, i / w as usize) else { return 0.0 };
            let mut sum = 0.0;
            for a in 0..k {
                for b in 0..k {
                    let y = origin + u * ((a as f64 + 0.5) / k as f64) + v * ((b as f64 + 0.5) / k as f64);
                    let d = y - p;
                    let d2 = d.length_squared();
                    let wi = d / d2.sqrt();
                    let cos_l = -wi.dot(nl);
                    if cos_l > 0.0 {
                        sum += ggx_f_cos(wo, DVec3::Y, wi, alpha) * cos_l / d2;
                    }
                }
            }
            radiance * sum * u.cross(v).length() / (k * k) as f64
        })
        .collect();
    let total: f64 = truth.iter().sum();
    // (The last case holds the lobe at `center`, as `strata study` does when glossy is not studied: its
    // one fixed direction samples no density, so the light samples count in full and the lobe ray's find
    // not at all; weighed by MIS as if drawn from the lobe, the image was 6% dark at 1 light sample.)
    for (ls, depth, s, lobe) in
        [(1, 1, &s, "jittered"), (16, 1, &s, "jittered"), (16, 0, &s, "jittered"), (4, 4, &slabbed, "jittered"), (1, 1, &s, "center")]
    {
        let text = format!(
            "spp = 256\npixel_strategy = \"center\"\nlight_samples = {ls}\nlight_strategy = \"jittered\"\nmax_depth = {depth}\nglossy_strategy = \"{lobe}\"\n"
        );
        let p = Profile::parse(Path::new("test-profile.toml"), &text).unwrap();
        let (img, _) = render_image(s, &p, 5);
        let got: f64 = img.iter().map(|c| c.x as f64).sum();
        let rel_rms =
            (img.iter().zip(&truth).map(|(c, t)| (c.x as f64 - t).powi(2)).sum::<f64>() / truth.iter().map(|t| t * t).sum::<f64>()).sqrt();
        eprintln!("light samples {ls}, max depth {depth}, lobe {lobe}: image sum {got:.4} against {total:.4}, relative RMS {rel_rms:.2e}");
        assert!((got / total - 1.0).abs() < 0.01, "light samples {ls}, depth {depth}, lobe {lobe}: sum {got} against {total}");
        assert!(rel_rms < 0.03, "light samples {ls}, depth {depth}, lobe {lobe}: relative RMS {rel_rms}");
    }
}

/// `center` holds a bounce at the lobe's central direction: a rough glossy floor's `center` lobe ray
/// leaves in the mirror direction at any incidence (head-on and at 45 degrees), and a Lambert floor's
/// `center` diffuse bounce along the normal; each finds an emitter hung in that direction (not a
/// `[[lights]]` light: only the bounce can find it). The visible-normal map sent the sample square's
/// centre to a radius of 0.71 (polar map): the lobe 2 atan(alpha) = 52 degrees off the mirror head-on,
/// the bounce 45 degrees off the normal, and both images were black; a concentric map fixed head-on
/// only (the visible normals lean towards the viewer: 25 degrees off at 45 degrees of incidence).
#[test]
fn center_bounces_leave_along_the_lobes_centre() {
    // (camera position, emitter quad origin, u, v, floor material, profile lines, pixel value wanted)
    let glossy = "type = \"glossy\"\nroughness = 0.7";
    let head_on = ("[0.0, 2.0, 0.0]", "[-0.5, 4.0, -0.5]", "[1.0, 0.0, 0.0]", "[0.0, 0.0, 1.0]");
    // At 45 degrees: the emitter about the mirror image of the ray, facing the floor's centre.
    let oblique = ("[0.0, 2.0, 2.0]", "[-0.5, 1.646, -2.354]", "[1.0, 0.0, 0.0]", "[0.0, 0.707, 0.707]");
    for (at, material, profile_extra, low, high) in [
        (head_on, glossy, "glossy_strategy = \"center\"\n", 0.98, 1.0001),
        (oblique, glossy, "glossy_strategy = \"center\"\n", 0.5, 1.0001),
        (head_on, "type = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]", "diffuse_strategy = \"center\"\ndiffuse_depth = 1\n", 0.49, 0.5005),
    ] {
        let (cam, origin, u, v) = at;
        let s = scene(&format!(
            "[image]\nwidth = 8\nheight = 8\n[camera]\nposition = {cam}\nlook_at = [0.0, 0.0, 0.0]\nup = [0.0, 0.0, -1.0]\nfov = 5.0\n\
             [materials.floor]\n{material}\n[materials.glow]\ntype = \"emissive\"\nradiance = [1.0, 1.0, 1.0]\n\
             [[shapes]]\ntype = \"plane\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 1.0, 0.0]\nmaterial = \"floor\"\n\
             [[shapes]]\ntype = \"quad\"\norigin = {origin}\nu = {u}\nv = {v}\nmaterial = \"glow\"\n"
        ));
        let text =
            format!("spp = 1\npixel_strategy = \"center\"\nlight_samples = 1\nlight_strategy = \"center\"\nmax_depth = 2\n{profile_extra}");
        let p = Profile::parse(Path::new("test-profile.toml"), &text).unwrap();
        let (img, _) = render_image(&s, &p, 1);
        for (i, c) in img.iter().enumerate() {
            assert!(c.x as f64 > low && (c.x as f64) < high, "{material} seen from {cam}: pixel {i} is {c}");
        }
    }
}
