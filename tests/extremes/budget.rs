//! The sample and bounce budgets at their extremes: 1 and 4096 samples per pixel against an analytic
//! image; max depth 0 and 1000 in a hall of mirrors whose bounce count is known for every pixel.

use super::support::*;
use glam::DVec3;
use std::f64::consts::PI;

// ------------------------------------------------------------------------------------------------
// Samples per pixel

/// Form factor from a point to a parallel rectangle `[0, a] x [0, b]` at height `h` whose corner is
/// straight above it (Howell's catalogue, C-11); signed for the corner decomposition.
fn corner_ff(a: f64, b: f64, h: f64) -> f64 {
    let (x, y) = (a.abs() / h, b.abs() / h);
    let f = (x / (1.0 + x * x).sqrt() * (y / (1.0 + x * x).sqrt()).atan() + y / (1.0 + y * y).sqrt() * (x / (1.0 + y * y).sqrt()).atan())
        / (2.0 * PI);
    f * a.signum() * b.signum()
}

/// Radiance of a lambert floor (albedo 0.5) at `p` under the quad light [-1, 1] x [-1, 1] at height 3
/// (radiance 2, facing down): rho L F.
fn floor_radiance(p: DVec3) -> f64 {
    let (x0, x1, z0, z1, h) = (-1.0 - p.x, 1.0 - p.x, -1.0 - p.z, 1.0 - p.z, 3.0);
    let f = corner_ff(x1, z1, h) - corner_ff(x0, z1, h) - corner_ff(x1, z0, h) + corner_ff(x0, z0, h);
    0.5 * 2.0 * f
}

const LIT_FLOOR: &str = "[image]\nwidth = 8\nheight = 6\n[camera]\nposition = [0, 2, 4]\nlook_at = [0, 0, 0]\nfov = 40\n\
    [materials.m]\ntype = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\n\
    [[shapes]]\ntype = \"plane\"\npoint = [0, 0, 0]\nnormal = [0, 1, 0]\nmaterial = \"m\"\n\
    [[lights]]\ntype = \"quad\"\norigin = [-1, 3, -1]\nu = [2, 0, 0]\nv = [0, 0, 2]\nradiance = [2, 2, 2]\n";

/// The pixel's true value: the floor radiance averaged over the pixel (box filter), 32 x 32 midpoints.
fn pixel_truth(scene: &strata::scene::Scene, x: u32, y: u32) -> f64 {
    let mut sum = 0.0;
    for i in 0..32 {
        for j in 0..32 {
            let (o, d) = scene.camera.ray(x as f32 + (i as f32 + 0.5) / 32.0, y as f32 + (j as f32 + 0.5) / 32.0, [0.0, 0.0]);
            let (o, d) = (o.as_dvec3(), d.as_dvec3());
            sum += floor_radiance(o + d * (-o.y / d.y));
        }
    }
    sum / 1024.0
}

/// 4096 samples per pixel (one light sample each) on an 8 x 6 image: every pixel within 5 standard
/// errors (the film's own variance estimate) of the analytic pixel value, plus 2e-4 of it for the
/// midpoint rule (measured: largest deviation 1.9 standard errors). 1 sample per pixel: the 48
/// single-sample pixels scatter around the truth; their mean error must be within 5 standard errors of
/// zero. Both: every sample counted, none non-finite (checked by render).
#[test]
fn one_and_4096_samples_per_pixel() {
    let scene = parse(LIT_FLOOR);
    let truth: Vec<f64> = (0..48).map(|i| pixel_truth(&scene, i % 8, i / 8)).collect();

    let img = render_scene(&scene, profile(&[("spp", "4096"), ("light_samples", "1"), ("light_strategy", "random")]));
    let mut worst_z = 0.0f64;
    for (i, &e) in truth.iter().enumerate() {
        let (v, se) = (img.px[i].x as f64, (img.var[i].x as f64).sqrt());
        let z = (v - e).abs() / (se + 2e-4 * e / 5.0);
        worst_z = worst_z.max(z);
    }
    eprintln!("4096 spp: worst deviation {worst_z:.2} standard errors; {} samples", img.stats.rays.camera);
    assert_eq!(img.stats.rays.camera, 48 * 4096);
    assert!(worst_z < 5.0, "{worst_z}");

    let img = render_scene(&scene, profile(&[("spp", "1"), ("light_samples", "1"), ("light_strategy", "random")]));
    let errs: Vec<f64> = truth.iter().enumerate().map(|(i, &e)| img.px[i].x as f64 - e).collect();
    let mean = errs.iter().sum::<f64>() / 48.0;
    let sd = (errs.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / 47.0).sqrt();
    eprintln!("1 spp: mean error {mean:.4}, per-pixel sd {sd:.4}");
    assert!(sd > 0.0 && mean.abs() < 5.0 * sd / 48f64.sqrt(), "{mean} {sd}");
}

// ------------------------------------------------------------------------------------------------
// Depth

/// Half the gap between the two mirrors, their length along +x and half-height in z.
const W: f64 = 0.05;
const LEN: f64 = 40.0;
const HALF_Z: f64 = 5.0;

/// Two parallel mirror quads y = +-W, x in [0, LEN], z in [-HALF_Z, HALF_Z]; the camera at the origin
/// looks down the hall (+x, up = +z); the background is 1.
fn hall(tint: f64, infinite: bool) -> String {
    let walls = if infinite {
        format!("[[shapes]]\ntype = \"plane\"\npoint = [0, {w}, 0]\nnormal = [0, 1, 0]\nmaterial = \"mirror\"\n[[shapes]]\ntype = \"plane\"\npoint = [0, -{w}, 0]\nnormal = [0, 1, 0]\nmaterial = \"mirror\"\n", w = num(W))
    } else {
        let q = |y: f64| {
            format!(
                "[[shapes]]\ntype = \"quad\"\norigin = {}\nu = {}\nv = {}\nmaterial = \"mirror\"\n",
                vec3([0.0, y, -HALF_Z]),
                vec3([LEN, 0.0, 0.0]),
                vec3([0.0, 0.0, 2.0 * HALF_Z])
            )
        };
        q(W) + &q(-W)
    };
    format!(
        "[image]\nwidth = 48\nheight = 8\nbackground = [1, 1, 1]\n[camera]\nposition = [0, 0, 0]\nlook_at = [1, 0, 0]\nup = [0, 0, 1]\nfov = 30\n\
         [materials.mirror]\ntype = \"mirror\"\ntint = {}\n{walls}",
        vec3([tint; 3])
    )
}

/// Mirror bounces of the ray (o, d) before it leaves the hall (unfolded: the walls are at y = +-W (2k
/// + 1)), and how far (in units of the gap) the exit point is from the nearest wall crossing.
fn bounces(o: DVec3, d: DVec3) -> (u32, f64) {
    let t_exit = (LEN / d.x).min(if d.z == 0.0 { f64::INFINITY } else { HALF_Z / d.z.abs() });
    let s = ((o.y + d.y.abs() * t_exit) / W + 1.0) / 2.0;
    (s.floor() as u32, (s - s.round()).abs())
}

/// Depth 1000, tint 0.99: every pixel is exactly 0.99^k (the throughput is multiplied by the tint at
/// each bounce and nothing else) for a whole k; k is the analytic bounce count N (up to ~880 here) plus
/// a drift: each bounce spawns the ray 256 ULPs of |p| inside the gap, which in the unfolded picture
/// moves it on by that much, so over N bounces at x up to LEN the ray gains at most
/// N * 256 ulp(LEN) / (2 W) extra wall crossings (~9 at N = 880). Checked: N <= k <= N + that bound + 1
/// (measured below), pixels whose exit is within 2% of a gap from a wall skipped. Tint 1: every pixel
/// exactly 1. Depth 0: mirrors spawn nothing, so a pixel is 1 if its ray meets no mirror, else 0.
#[test]
fn hall_of_mirrors_depth_1000_and_0() {
    let ulp_len = 2f64.powi((LEN as f32).log2().floor() as i32 - 23);
    let p = |depth: &str| profile(&[("spp", "1"), ("pixel_strategy", "center"), ("max_depth", depth), ("throughput_cutoff", "0")]);
    let scene = parse(&hall(0.99, false));
    let img = render_scene(&scene, p("1000"));
    let (mut checked, mut max_n, mut max_drift) = (0, 0, 0);
    for y in 0..img.height {
        for x in 0..img.width {
            let (o, d) = scene.camera.ray(x as f32 + 0.5, y as f32 + 0.5, [0.0, 0.0]);
            let (n, frac) = bounces(o.as_dvec3(), d.as_dvec3());
            let v = img.at(x, y).x as f64;
            let k = v.ln() / 0.99f64.ln();
            assert!((k - k.round()).abs() < 1e-3 * k.max(1.0), "pixel {x},{y}: {v} is not a power of the tint");
            let k = k.round() as u32;
            if frac < 0.02 {
                continue;
            }
            let drift_bound = (n as f64 * 256.0 * ulp_len / (2.0 * W)).ceil() as u32 + 1;
            assert!(k >= n && k <= n + drift_bound, "pixel {x},{y}: {k} bounces, analytic {n} (+{drift_bound})");
            checked += 1;
            max_n = max_n.max(n);
            max_drift = max_drift.max(k - n);
        }
    }
    eprintln!("hall of mirrors, depth 1000: {checked} pixels checked, up to {max_n} bounces, drift up to {max_drift}");
    assert!(checked > 300 && max_n > 500);

    let perfect = render(&hall(1.0, false), p("1000"));
    assert!(perfect.px.iter().all(|v| v.x == 1.0), "tint 1: every path escapes with throughput 1");

    let img = render_scene(&scene, p("0"));
    for y in 0..img.height {
        for x in 0..img.width {
            let (o, d) = scene.camera.ray(x as f32 + 0.5, y as f32 + 0.5, [0.0, 0.0]);
            let (n, _) = bounces(o.as_dvec3(), d.as_dvec3());
            assert_eq!(img.at(x, y).x, if n == 0 { 1.0 } else { 0.0 }, "depth 0, pixel {x},{y}");
        }
    }
}

/// Infinite parallel mirrors: no path ever escapes. Depth 1000 must terminate with every pixel black
/// (the rays between the planes) and take exactly 1000 bounces for each camera ray that starts one.
#[test]
fn infinite_hall_terminates_at_max_depth() {
    let p = profile(&[("spp", "1"), ("pixel_strategy", "center"), ("max_depth", "1000"), ("throughput_cutoff", "0")]);
    let img = render(&hall(1.0, true), p);
    assert!(img.px.iter().all(|v| v.x == 0.0));
    // Every camera ray (none is parallel to the planes) bounces 1000 times.
    assert_eq!(img.stats.rays.secondary, 48 * 8 * 1000);
}

// ------------------------------------------------------------------------------------------------
// The ray tree of `branching = "split"`

/// A split ray tree that `throughput_cutoff` does not bound (1e-30 over 40 bounces between two glass
/// slabs) stops the render at the pass limit (`RenderStats::overflow`, no unit done, nothing in the
/// film) instead of growing until memory runs out; the usual cutoff (1e-3) renders the same scene
/// with the same limit, its passes far below it. (A limit of 400 rays per camera path, against the
/// default 4,096, keeps the test small; the CLI's message is `overflow_message`.)
#[test]
fn an_unbounded_split_tree_stops_at_the_pass_limit() {
    let text = "[image]\nwidth = 8\nheight = 6\n[camera]\nposition = [0, 0, 4]\nlook_at = [0, 0, 0]\nfov = 30\n\
        [materials.g]\ntype = \"dielectric\"\nior = 1.5\n\
        [[shapes]]\ntype = \"box\"\nmin = [-2, -2, -0.3]\nmax = [2, 2, -0.1]\nmaterial = \"g\"\n\
        [[shapes]]\ntype = \"box\"\nmin = [-2, -2, 0.1]\nmax = [2, 2, 0.3]\nmaterial = \"g\"\n";
    let scene = parse(text);
    let run = |cutoff: &str| {
        let p = profile(&[("max_depth", "40"), ("branching", "split"), ("throughput_cutoff", cutoff), ("spp", "1")]);
        let mut job = strata::render::RenderJob::new(&scene, strata::wavefront::Settings { profile: p, seed: SEED });
        job.threads = 2;
        job.max_rays_per_path = 400;
        let (film, stats) = strata::render::render_into(&job, strata::film::Film::new(scene.width, scene.height));
        (stats, film.total_samples(), strata::render::overflow_message(&job))
    };
    let (stats, samples, msg) = run("1e-30");
    assert!(stats.overflow && !stats.completed && samples == 0, "{stats:?}");
    assert!(msg.contains("passed 400 per camera path") && msg.contains("throughput_cutoff = 1e-30") && msg.contains("roulette"), "{msg}");
    let (stats, samples, _) = run("1e-3");
    assert!(!stats.overflow && stats.completed && samples == 48, "{stats:?}");
}
