//! Pixel-area integral: the image of a straight emissive edge equals, pixel by pixel, the filter-weighted
//! coverage of the pixel, computed here by quadrature of each filter's formula (written out
//! independently of `sample::filter`).

use super::*;
use strata::sample::Filter;

const W: u32 = 20;
const DEPTH: f64 = 5.0;

/// The filters' definitions (unnormalised weights; the quadrature normalises).
fn weight(filter: Filter, dx: f64, dy: f64) -> f64 {
    match filter {
        Filter::Box => (dx.abs() <= 0.5 && dy.abs() <= 0.5) as u8 as f64,
        Filter::Tent => (1.0 - dx.abs()).max(0.0) * (1.0 - dy.abs()).max(0.0),
        Filter::Gaussian => {
            let r2 = dx * dx + dy * dy;
            if r2 <= 1.5 * 1.5 {
                (-r2 / (2.0 * 0.5 * 0.5)).exp()
            } else {
                0.0
            }
        }
    }
}

/// `sum w(q) covered(c + q) / sum w(q)` by the midpoint rule on a 240 x 240 grid over the support.
fn filtered_coverage(filter: Filter, cx: f64, cy: f64, covered: &impl Fn(f64, f64) -> bool) -> f64 {
    let r = filter.radius() as f64;
    let k = 240;
    let (mut num, mut den) = (0.0, 0.0);
    for i in 0..k {
        let dy = -r + 2.0 * r * (i as f64 + 0.5) / k as f64;
        for j in 0..k {
            let dx = -r + 2.0 * r * (j as f64 + 0.5) / k as f64;
            let w = weight(filter, dx, dy);
            den += w;
            if w > 0.0 && covered(cx + dx, cy + dy) {
                num += w;
            }
        }
    }
    num / den
}

#[test]
fn edge_image_is_the_filter_weighted_pixel_coverage() {
    let cam = PinholeF64::new(DVec3::ZERO, DVec3::NEG_Z, DVec3::Y, 20.0, W, W);
    // An emissive half-plane (a huge quad) at depth 5 whose edge crosses the view at 20 degrees from
    // the vertical, facing the camera.
    let a = 20f64.to_radians();
    let e = DVec3::new(a.sin(), a.cos(), 0.0);
    let side = DVec3::new(a.cos(), -a.sin(), 0.0);
    let p0 = DVec3::new(0.013, 0.0, -DEPTH);
    let (mut u, mut v) = (side * 100.0, e * 100.0);
    if u.cross(v).z < 0.0 {
        std::mem::swap(&mut u, &mut v);
    }
    let origin = p0 - e * 50.0;
    let s = scene(&format!(
        r#"
[image]
width = {W}
height = {W}
[camera]
position = [0.0, 0.0, 0.0]
look_at = [0.0, 0.0, -1.0]
fov = 20.0
[materials.glow]
type = "emissive"
radiance = [1.0, 1.0, 1.0]
[[shapes]]
type = "quad"
origin = {}
u = {}
v = {}
material = "glow"
"#,
        v3(origin),
        v3(u),
        v3(v)
    ));
    // The edge in image coordinates: a plane parallel to the image projects by a uniform scale.
    let pix = cam.pixel_size_at(DEPTH);
    let to_img = |p: DVec3| (p.x / pix + W as f64 / 2.0, -p.y / pix + W as f64 / 2.0);
    let (ax, ay) = to_img(p0);
    let (bx, by) = to_img(p0 + e);
    let (sx, sy) = to_img(p0 + side);
    let cross = |x: f64, y: f64| (bx - ax) * (y - ay) - (by - ay) * (x - ax);
    let inside_sign = cross(sx, sy).signum();
    let covered = move |x: f64, y: f64| cross(x, y) * inside_sign > 0.0;

    let n = 1024u32;
    for filter in Filter::ALL {
        let mut p = profile(n, "random", 1, "random");
        p.set("filter", filter.name()).unwrap();
        let (img, _) = render_image(&s, &p, 17);
        let (mut worst_z, mut partial, mut sum_err) = (0.0f64, 0, 0.0);
        for y in 0..W {
            for x in 0..W {
                let f = filtered_coverage(filter, x as f64 + 0.5, y as f64 + 0.5, &covered);
                let got = img[(y * W + x) as usize].x as f64;
                if f > 1e-9 && f < 1.0 - 1e-9 {
                    partial += 1;
                    sum_err += got - f;
                }
                // Each sample is 0 or 1 (radiance 1): binomial standard error; a floor keeps pixels
                // with coverage 0 or 1 exact (they must be).
                let sigma = (f * (1.0 - f) / n as f64).sqrt().max(1e-6);
                worst_z = worst_z.max((got - f).abs() / sigma);
            }
        }
        eprintln!(
            "edge, {filter} filter: {partial} partly covered pixels, mean error {:.2e}, worst |z| {worst_z:.2}",
            sum_err / partial as f64
        );
        assert!(partial >= 20, "the edge must cross many pixels");
        assert!(worst_z < 5.0, "{filter}: a pixel is {worst_z:.1} standard errors off its filtered coverage");
    }
}
