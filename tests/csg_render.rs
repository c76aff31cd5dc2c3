//! CSG through the whole renderer: scene file -> intersect -> csg_merge -> shade -> film. Each expectation is
//! analytic (pixel classes from the geometry and the camera projection in f64, the thick-lens focal length)
//! or exact (a solid minus itself is empty, a stage that must not run has no candidates and no time).

#[path = "csg_render/flat.rs"]
mod flat;
#[path = "csg_render/lens.rs"]
mod lens;

use std::path::Path;
use strata::render::render;
use strata::scene::{load_scene, parse_scene, Profile, Scene};
use strata::wavefront::Settings;

/// One sample per pixel through the pixel centre, no bounces: with emissive materials and no lights each
/// pixel is exactly the radiance of the surface its centre ray sees.
pub fn flat_profile() -> Profile {
    let mut p = Profile::builtin("preview");
    p.spp = 1;
    p.pixel_strategy = strata::sample::Strategy::Center;
    p.filter = strata::sample::Filter::Box;
    p.max_depth = 0;
    p
}

pub fn scene_from(name: &str, text: &str) -> Scene {
    parse_scene(Path::new(name), text).unwrap_or_else(|e| panic!("{e}"))
}

/// (d) The merge stage runs only for CSG scenes: a scene without CSG records no candidate and spends no
/// time in the stage; the same scene with one CSG solid added does both.
#[test]
fn scene_without_csg_skips_the_merge_stage() {
    let plain = r#"
[image]
width = 48
height = 32
[camera]
position = [0.0, 1.0, 4.0]
look_at = [0.0, 0.5, 0.0]
fov = 40.0
[materials.white]
type = "lambert"
albedo = [0.7, 0.7, 0.7]
[[shapes]]
type = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 1.0, 0.0]
material = "white"
[[shapes]]
type = "sphere"
center = [0.0, 0.5, 0.0]
radius = 0.5
material = "white"
[[lights]]
type = "point"
position = [2.0, 3.0, 2.0]
intensity = [10.0, 10.0, 10.0]
"#;
    let with_csg =
        format!("{plain}\n[[shapes]]\ntype = \"cylinder\"\ncenter = [1.0, 0.3, 0.0]\nradius = 0.3\nheight = 0.6\nmaterial = \"white\"\n");
    let settings = Settings { profile: Profile::builtin("preview"), seed: 3 };
    let a = scene_from("plain.toml", plain);
    assert!(!a.features.csg);
    let (_, sa) = render(&a, settings.clone(), 2);
    let b = scene_from("with_csg.toml", &with_csg);
    assert!(b.features.csg);
    let (_, sb) = render(&b, settings, 2);
    println!(
        "no CSG: candidates {}, csg_merge {:.6} s; with CSG: candidates {}, csg_merge {:.6} s",
        sa.csg_candidates, sa.stage_seconds.csg_merge, sb.csg_candidates, sb.stage_seconds.csg_merge
    );
    assert_eq!(sa.csg_candidates, 0);
    assert_eq!(sa.stage_seconds.csg_merge, 0.0);
    assert!(sb.csg_candidates > 0);
    assert!(sb.stage_seconds.csg_merge > 0.0);
}

/// (e) Every shipped scene with CSG renders (at a quarter of its resolution, 2 spp) with no non-finite
/// sample, and its camera rays reach the merge stage.
#[test]
fn shipped_csg_scenes_render_finite() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut names: Vec<_> =
        std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().path()).filter(|p| p.extension().is_some_and(|e| e == "toml")).collect();
    names.sort();
    let mut rendered = Vec::new();
    for path in names {
        let mut scene = load_scene(&path).unwrap_or_else(|e| panic!("{e}"));
        if !scene.features.csg {
            continue;
        }
        // Same aspect ratio (the camera keeps its field of view), a sixteenth of the pixels.
        scene.width = (scene.width / 4).max(1);
        scene.height = (scene.height / 4).max(1);
        scene.camera.width = scene.width;
        scene.camera.height = scene.height;
        let mut profile = Profile::builtin("preview");
        profile.spp = 2;
        let (film, stats) = render(&scene, Settings { profile, seed: 5 }, 2);
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        println!(
            "{name}: {} rays, {} CSG candidates, {} non-finite samples",
            stats.rays.total, stats.csg_candidates, stats.nonfinite_samples
        );
        assert_eq!(stats.nonfinite_samples, 0, "{name}");
        assert_eq!(film.total_samples(), scene.width as u64 * scene.height as u64 * 2, "{name}");
        assert!(stats.csg_candidates > 0, "{name}");
        rendered.push(name);
    }
    for required in ["csg.toml", "csg_glass.toml", "bench_csg.toml"] {
        assert!(rendered.iter().any(|n| n == required), "{required} missing from the CSG scenes ({rendered:?})");
    }
}
