//! The command line as a user meets it: exit codes, messages, outputs.

use std::path::PathBuf;
use std::process::Command;

fn strata() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_strata"));
    c.current_dir(env!("CARGO_MANIFEST_DIR"));
    c
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("strata-cli-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

#[test]
fn bad_scene_exits_2_naming_line_and_field() {
    let scene = tmp("bad.toml");
    std::fs::write(&scene, "[image]\nwidth = 8\nheight = 8\n[camera]\nposition = [0,0,5]\nlook_at = [0,0,0]\nfov = 40\n[materials.x]\ntype = \"mirror\"\n[[shapes]]\ntype = \"sphere\"\ncenter = [0,0,0]\nradius = -2\nmaterial = \"x\"\n").unwrap();
    let out = strata().args(["render", scene.to_str().unwrap(), "-o", tmp("bad.png").to_str().unwrap()]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.toml:13:"), "{err}");
    assert!(err.contains("shapes[0].radius"), "{err}");
    assert!(!tmp("bad.png").exists());
}

#[test]
fn missing_output_directory_fails_before_rendering() {
    let out = strata().args(["render", "scenes/showcase.toml", "-o", "/nonexistent-dir/x.png"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("does not exist"));
}

#[test]
fn bad_flags_are_input_errors() {
    let o = tmp("x.png");
    for args in
        [vec!["--spp", "0"], vec!["--strategy", "magic"], vec!["--set", "spp"], vec!["--set", "colour=3"], vec!["--profile", "nope"]]
    {
        let mut a = vec!["render", "scenes/shapes/sphere.toml", "-o", o.to_str().unwrap()];
        a.extend(args.iter().copied());
        let out = strata().args(&a).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
    }
}

#[test]
fn render_writes_image_and_stats_json() {
    let png = tmp("sphere.png");
    let json = tmp("sphere.json");
    let out = strata()
        .args(["render", "scenes/shapes/sphere.toml", "-o", png.to_str().unwrap(), "--spp", "2", "--stats-json", json.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("rays/s"), "{stdout}");
    let img = image::open(&png).unwrap().into_rgb8();
    assert_eq!(img.dimensions(), (320, 240));
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    for k in ["width", "height", "spp", "seconds", "rays", "rays_per_second", "nonfinite_samples"] {
        assert!(v.get(k).is_some(), "missing {k}");
    }
    assert_eq!(v["width"], 320);
    assert_eq!(v["spp"], 2);
    assert_eq!(v["nonfinite_samples"], 0);
    assert_eq!(v["rays"]["camera"], 320 * 240 * 2);
    assert!(v["rays"]["shadow"].as_u64().unwrap() > 0);
}

/// A render whose samples overflow the film (a point light of intensity 1e30: every lit sample is
/// beyond 2^31) says so on stderr even with --quiet, and counts them in the JSON; the same scene with
/// intensity 1 says nothing.
#[test]
fn discarded_samples_are_never_silent() {
    let scene = |intensity: &str| {
        format!(
            "[image]\nwidth = 8\nheight = 8\n[camera]\nposition = [0,1,5]\nlook_at = [0,0,0]\nfov = 40\n\
             [materials.m]\ntype = \"lambert\"\nalbedo = [0.5,0.5,0.5]\n\
             [[shapes]]\ntype = \"plane\"\npoint = [0,0,0]\nnormal = [0,1,0]\nmaterial = \"m\"\n\
             [[lights]]\ntype = \"point\"\nposition = [0,2,0]\nintensity = [{intensity},1,1]\n"
        )
    };
    for (intensity, discarded) in [("1e30", true), ("1", false)] {
        let path = tmp(&format!("overflow-{intensity}.toml"));
        std::fs::write(&path, scene(intensity)).unwrap();
        let json = tmp(&format!("overflow-{intensity}.json"));
        let out = strata()
            .args(["render", path.to_str().unwrap(), "-q", "--spp", "2", "-o", tmp("overflow.png").to_str().unwrap()])
            .args(["--stats-json", json.to_str().unwrap()])
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let err = String::from_utf8_lossy(&out.stderr);
        let stats: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        let n = stats["nonfinite_samples"].as_u64().unwrap();
        assert_eq!(n > 0, discarded, "intensity {intensity}: {n} discarded");
        assert_eq!(err.contains(&format!("warning: {n} samples were discarded")), discarded, "intensity {intensity}: stderr {err}");
    }
}
