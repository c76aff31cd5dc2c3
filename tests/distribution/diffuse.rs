//! Diffuse interreflection (`diffuse_depth > 0`): a furnace with a closed form. Inside a Lambert sphere of
//! radius R and albedo rho, lit by a small sphere light of radius r and radiance Le at its centre, every
//! bounce spreads its flux uniformly over the enclosure (any patch of a sphere's inside irradiates the
//! whole sphere evenly), so the wall radiance is the geometric series
//! `rho / pi * (Phi / A) * (1 + rho' + rho'^2 + ...) = rho Le (r / R)^2 / (1 - rho')`, where
//! `rho' = rho (1 - (r / R)^2)`: each bounce loses the fraction `(r / R)^2` of its flux (the light's
//! projected solid angle over pi, seen from the wall) to the light sphere, which does not reflect.

use super::*;

#[test]
fn furnace_sphere_radiance_is_the_interreflection_series() {
    let albedo = DVec3::new(0.5, 0.8, 0.9);
    let (big, small, le) = (1.0, 0.01, 10_000.0);
    let s = scene(&format!(
        r#"
[image]
width = 24
height = 24
[camera]
position = [0.0, 0.0, 0.4]
look_at = [0.3, 0.2, 1.0]
fov = 60.0
[materials.wall]
type = "lambert"
albedo = {}
[[shapes]]
type = "sphere"
center = [0.0, 0.0, 0.0]
radius = {big}
material = "wall"
[[lights]]
type = "sphere"
center = [0.0, 0.0, 0.0]
radius = {small}
radiance = [{le}, {le}, {le}]
"#,
        v3(albedo)
    ));
    let k = (small / big) * (small / big);
    let expected = albedo * (le * k) / (DVec3::ONE - albedo * (1.0 - k));
    let mut p = profile(256, "jittered", 1, "jittered");
    p.set("max_depth", "400").unwrap();
    p.set("diffuse_depth", "400").unwrap();
    let (img, stats) = render_image(&s, &p, 5);
    let mean = img.iter().map(|v| v.as_dvec3()).sum::<DVec3>() / img.len() as f64;
    let rel = (mean - expected) / expected;
    eprintln!(
        "furnace: image mean {mean:.4}, series {expected:.4}, rel. error {rel:.5}; {:.1} secondary rays per sample",
        stats.rays.secondary as f64 / stats.rays.camera as f64
    );
    assert!(rel.abs().max_element() < 0.01, "interreflection off the series: {rel:?}");
    // Direct light only is the first term of the series.
    let mut d = p.clone();
    d.set("diffuse_depth", "0").unwrap();
    let (img, _) = render_image(&s, &d, 5);
    let mean = img.iter().map(|v| v.as_dvec3()).sum::<DVec3>() / img.len() as f64;
    let first = albedo * (le * (small / big) * (small / big));
    eprintln!("furnace, direct only: image mean {mean:.4}, first term {first:.4}");
    assert!(((mean - first) / first).abs().max_element() < 0.01);
}
