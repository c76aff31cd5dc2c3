//! The prism scene shows the spectrum. The check: look squarely at the screen of `scenes/prism.toml`, average
//! each image column over the band of dispersed light, and follow the hue along it. Snell's law at the two
//! prism faces (f64, the faces are vertical and the beam horizontal, so it is exact in 2D) says which way the
//! shorter wavelengths are deviated more; the lens keeps the side (the chief ray goes straight through its
//! centre), and the camera projection says which image side that is. Along the band the hue must run
//! monotonically from red (near 0 deg) through green (120) to blue (over 200) in that direction: in
//! five bins of equal light along the band, each hue above the one before, and over columns (summed three
//! at a time) a rank correlation of hue with position above 0.85.

use super::*;
use strata::optics::{wavelength_to_rgb, Ior};

const SCENE: &str = include_str!("../../scenes/prism.toml");

/// Hue angle in degrees (HSV), in [0, 360); hues just below red (magenta) wrap to negative values so that
/// violet (which has a red component) is not confused with red: the range is [-60, 300).
fn hue(c: DVec3) -> f64 {
    let (mx, mn) = (c.max_element(), c.min_element());
    if mx <= mn {
        return f64::NAN;
    }
    let d = mx - mn;
    let h = if mx == c.x {
        60.0 * ((c.y - c.z) / d)
    } else if mx == c.y {
        60.0 * ((c.z - c.x) / d + 2.0)
    } else {
        60.0 * ((c.x - c.y) / d + 4.0)
    };
    if h >= 300.0 {
        h - 360.0
    } else if h < -60.0 {
        h + 360.0
    } else {
        h
    }
}

/// Deviation (rad) of a horizontal ray by the prism of the scene (apex 60 deg), entering face 2 and leaving
/// face 0 (normals from the scene file), by f64 Snell.
fn deviation(n: f64) -> f64 {
    let d0 = DVec3::X;
    let n_in = DVec3::new(-0.64278761, 0.0, 0.76604444);
    let n_out = DVec3::new(0.98480775, 0.0, 0.17364818);
    let d1 = refract64(d0, n_in, 1.0, n).unwrap();
    let d2 = refract64(d1, n_out, n, 1.0).unwrap();
    d2.z.atan2(d2.x).abs()
}

#[test]
fn prism_spreads_white_light_into_an_ordered_spectrum() {
    let flint = Ior::Cauchy { a: 1.52, b_um2: 0.03 };
    let (dev_blue, dev_red) = (deviation(flint.at_f64(450.0)), deviation(flint.at_f64(650.0)));
    assert!(dev_blue > dev_red, "Snell: blue is deviated more ({dev_blue} vs {dev_red})");

    // The screen (from the scene file): centre on the lens axis, tangent t across it.
    let axis = DVec3::new(0.6630185, 0.0, -0.74860301);
    let t = DVec3::new(0.74860301, 0.0, 0.6630185);
    let centre = DVec3::new(0.79239615, 0.5, -0.55715343) + axis * 2.25;
    // More deviation turns the beam towards -t (d/d(delta) of (cos, 0, -sin) is -t at the axis).
    let blue_side = -t;
    let look = centre - t * 0.1;
    let eye = look - axis * 1.0;
    let forward = (look - eye).normalize();
    let right = forward.cross(DVec3::Y).normalize();
    let blue_to_the_right = blue_side.dot(right) > 0.0;

    // Square view of the screen, the room light off.
    let (w, h) = (64u32, 16u32);
    let swaps = [
        ("width = 320".to_string(), format!("width = {w}")),
        ("height = 200".to_string(), format!("height = {h}")),
        ("position = [2.0, 3.3, 2.6]".to_string(), format!("position = [{}, {}, {}]", eye.x, eye.y, eye.z)),
        ("look_at = [0.5, 0.35, -0.9]".to_string(), format!("look_at = [{}, {}, {}]", look.x, look.y, look.z)),
        ("fov = 48.0".to_string(), "fov = 12.0".to_string()),
        ("radiance = [0.35, 0.35, 0.35]".to_string(), "radiance = [0.0, 0.0, 0.0]".to_string()),
    ];
    let mut text = SCENE.to_string();
    for (from, to) in &swaps {
        assert_eq!(text.matches(from.as_str()).count(), 1, "scenes/prism.toml changed: `{from}`");
        text = text.replace(from.as_str(), to);
    }
    let s = scene(&text);
    assert!(s.features.dispersion);
    let mut profile = Profile::builtin("caustic");
    profile.spp = 2048;
    let film = images::render(&s, profile, 21);
    let rgb = film.to_rgb();
    let cols: Vec<DVec3> =
        (0..w as usize).map(|x| (0..h as usize).map(|y| rgb[y * w as usize + x].as_dvec3()).sum::<DVec3>() / h as f64).collect();
    let lum: Vec<f64> = cols.iter().map(|c| c.x + c.y + c.z).collect();
    let peak = lum.iter().cloned().fold(0.0, f64::max);
    let band: Vec<usize> = (0..w as usize).filter(|&x| lum[x] > 0.08 * peak).collect();
    let (first, last) = (*band.first().unwrap(), *band.last().unwrap());
    // Columns of the band, red end first.
    let mut xs: Vec<usize> = (first..=last).collect();
    if !blue_to_the_right {
        xs.reverse();
    }
    // Bins of equal light (luminance quantiles): the dim, wide blue tail is one bin, not three noisy ones.
    let bins = 5;
    let total: f64 = xs.iter().map(|&x| lum[x]).sum();
    let mut groups = vec![DVec3::ZERO; bins];
    let mut acc = 0.0;
    for &x in &xs {
        let b = (((acc + 0.5 * lum[x]) / total) * bins as f64).floor().min(bins as f64 - 1.0) as usize;
        groups[b] += cols[x];
        acc += lum[x];
    }
    let hues: Vec<f64> = groups.iter().map(|&c| hue(c)).collect();
    // Rank correlation of hue with position along the band (noise may swap neighbours, not the trend), on
    // columns summed three at a time.
    let col_hues: Vec<f64> = xs.windows(3).map(|x| hue(cols[x[0]] + cols[x[1]] + cols[x[2]])).collect();
    let rho = spearman(&col_hues);
    eprintln!("hues of 3 columns, red end first: {:.0?}", col_hues);
    eprintln!("band: columns {first}..={last} of {w}; blue expected to the {}", if blue_to_the_right { "right" } else { "left" });
    eprintln!("hue in 5 bins of equal light, red end first: {:.0?}; rank correlation with position {rho:.3}", hues);
    // The renderer's own colours of pure wavelengths, for scale.
    eprintln!(
        "hues of 650, 590, 550, 500, 450 nm: {:.0?}",
        [650.0, 590.0, 550.0, 500.0, 450.0].map(|l| hue(wavelength_to_rgb(l).as_dvec3()))
    );
    assert!(last - first + 1 >= 8, "the spectrum should spread over several columns");
    for k in 1..bins {
        assert!(hues[k] > hues[k - 1], "hue must increase from red to blue: {hues:?}");
    }
    assert!(rho > 0.85, "hue should grow along the band (rank correlation {rho})");
    assert!(hues[0] < 60.0, "red end: {hues:?}");
    assert!(hues[bins - 1] > 200.0, "blue end: {hues:?}");
}

/// Spearman rank correlation of `v` with its index.
fn spearman(v: &[f64]) -> f64 {
    let n = v.len();
    let mut idx: Vec<usize> = (0..n).collect();
    idx.sort_by(|&a, &b| v[a].total_cmp(&v[b]));
    let mut rank = vec![0.0; n];
    for (r, &i) in idx.iter().enumerate() {
        rank[i] = r as f64;
    }
    let d2: f64 = rank.iter().enumerate().map(|(i, r)| (i as f64 - r).powi(2)).sum();
    1.0 - 6.0 * d2 / (n as f64 * (n as f64 * n as f64 - 1.0))
}
