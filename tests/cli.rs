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
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        // Flags are located on the command line, not at a made-up position in a file.
        assert!(err.starts_with("error: command line: ") || err.starts_with("error: --set "), "{args:?}: {err}");
        assert!(!err.contains(":0:0"), "{args:?}: {err}");
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

/// A closed stdout or stderr (`strata render ... | head -1`, `strata study ... 2>&1 | head -1`) does
/// not end a command with a panic: the render still writes its image and exits 0, the study its CSV.
/// (Rust ignores SIGPIPE, so each write to a closed pipe fails; `println!` would panic on it.)
#[test]
fn closed_pipes_do_not_panic() {
    use std::process::Stdio;
    let scene_text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/soft_shadows.toml"))
        .unwrap()
        .replace("width = 160", "width = 20")
        .replace("height = 120", "height = 14");
    let scene = tmp("pipes.toml");
    std::fs::write(&scene, scene_text).unwrap();
    let s = scene.to_str().unwrap().to_string();
    for closed in ["stdout", "stderr"] {
        let png = tmp(&format!("pipes-{closed}.png"));
        let study = tmp(&format!("pipes-study-{closed}"));
        let commands = [
            vec!["render".to_string(), s.clone(), "-o".into(), png.to_str().unwrap().into(), "--spp".into(), "2".into()],
            ["study", &s, "--spp", "1,2", "--seeds", "1", "--reference-spp", "8", "--out", study.to_str().unwrap()]
                .map(String::from)
                .to_vec(),
        ];
        for args in commands {
            let mut c = strata();
            c.args(&args).stdin(Stdio::null());
            // The closed end: a pipe whose reader is dropped before the command writes; the other
            // stream is kept to look for a panic message.
            if closed == "stdout" {
                c.stdout(Stdio::piped()).stderr(Stdio::piped());
            } else {
                c.stderr(Stdio::piped()).stdout(Stdio::piped());
            }
            let mut child = c.spawn().unwrap();
            let mut kept: Box<dyn std::io::Read> = if closed == "stdout" {
                drop(child.stdout.take());
                Box::new(child.stderr.take().unwrap())
            } else {
                drop(child.stderr.take());
                Box::new(child.stdout.take().unwrap())
            };
            let mut text = String::new();
            kept.read_to_string(&mut text).unwrap();
            let status = child.wait().unwrap();
            assert!(!text.contains("panicked"), "{} with {closed} closed: {text}", args[0]);
            assert_eq!(status.code(), Some(0), "{} with {closed} closed: {text}", args[0]);
        }
        assert!(png.exists(), "the render with {closed} closed wrote no image");
        assert!(study.join("study.csv").exists(), "the study with {closed} closed wrote no CSV");
    }
}

/// Outputs that name one file twice, or name an input (the scene, the profile, a film being merged),
/// are refused before anything is written, whatever the spelling of the path; the inputs are left
/// as they were. Writing the film back into the film a render resumes stays allowed.
#[test]
fn outputs_never_replace_each_other_or_an_input() {
    let scene = tmp("clash.toml");
    let text = std::fs::read_to_string("scenes/shapes/sphere.toml").unwrap();
    std::fs::write(&scene, &text).unwrap();
    let profile = tmp("clash_profile.toml");
    let profile_text = std::fs::read_to_string("profiles/preview.toml").unwrap();
    std::fs::write(&profile, &profile_text).unwrap();
    let s = |p: &PathBuf| p.to_str().unwrap().to_string();
    let dir = tmp("");
    let twice = format!("{}/./clash.exr", dir.display());
    let refused: [(Vec<String>, &str); 4] = [
        (vec!["-o".into(), s(&tmp("clash.png")), "--stats-json".into(), s(&scene)], "the scene file"),
        (vec!["-o".into(), s(&tmp("clash.exr")), "--film".into(), twice.clone()], "both name"),
        (vec!["-o".into(), s(&tmp("clash.png")), "--profile".into(), s(&profile), "--stats-json".into(), s(&profile)], "the profile file"),
        (vec!["-o".into(), s(&tmp("clash.exr")), "--stats-json".into(), twice], "both name"),
    ];
    for (args, want) in refused {
        let mut a = vec!["render".to_string(), s(&scene), "--spp".into(), "1".into()];
        a.extend(args.iter().cloned());
        let out = strata().args(&a).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err}");
    }
    assert_eq!(std::fs::read_to_string(&scene).unwrap(), text);
    assert_eq!(std::fs::read_to_string(&profile).unwrap(), profile_text);
    assert!(!tmp("clash.exr").exists() && !tmp("clash.png").exists());

    // A film, resumed into itself; then merged over itself (refused).
    let film = tmp("clash.film");
    let run = |a: &[&str]| strata().args(a).output().unwrap();
    let (sc, fl, png) = (s(&scene), s(&film), s(&tmp("clash.png")));
    assert_eq!(run(&["render", &sc, "--spp", "1", "-o", &png, "--film", &fl]).status.code(), Some(0));
    assert_eq!(run(&["render", &sc, "--spp", "1", "-o", &png, "--resume", &fl, "--film", &fl]).status.code(), Some(0));
    let out = run(&["merge", &fl, "-o", &png, "--film", &fl]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("an input film"));
}

/// A profile file's combination is checked after the command line's overrides: an error that no
/// override touches is the file's, at its line; `--set` (or `--max-depth`) can make it valid; an
/// override that breaks it is the command line's. A field given by its own flag and by `--set` is an
/// error. `--set name=...` renames the profile.
#[test]
fn profile_overrides_are_checked_with_the_file() {
    let profile = tmp("deep.toml");
    let text: String = std::fs::read_to_string("profiles/preview.toml")
        .unwrap()
        .lines()
        .map(|l| {
            if l.starts_with("diffuse_depth") {
                "diffuse_depth = 9\n".to_string()
            } else if l.starts_with("max_depth") {
                "max_depth = 4\n".to_string()
            } else {
                format!("{l}\n")
            }
        })
        .collect();
    assert!(text.contains("diffuse_depth = 9"));
    std::fs::write(&profile, &text).unwrap();
    let line = text.lines().position(|l| l.starts_with("diffuse_depth")).unwrap() + 1;
    let (pf, png) = (profile.to_str().unwrap().to_string(), tmp("deep.png").to_str().unwrap().to_string());
    let run = |extra: &[&str]| {
        let mut a = vec!["render", "scenes/shapes/sphere.toml", "--spp", "1", "-o", &png, "--profile", &pf];
        a.extend(extra);
        strata().args(&a).output().unwrap()
    };
    let out = run(&[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains(&format!("deep.toml:{line}:")) && err.contains("diffuse_depth"), "{err}");
    for fix in [&["--set", "max_depth=9"][..], &["--max-depth", "3"], &["--set", "diffuse_depth=1"]] {
        let out = run(fix);
        assert_eq!(out.status.code(), Some(0), "{fix:?}: {}", String::from_utf8_lossy(&out.stderr));
    }
    let out =
        strata().args(["render", "scenes/shapes/sphere.toml", "--spp", "1", "-o", &png, "--set", "diffuse_depth=9"]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.starts_with("error: command line: diffuse_depth"), "{err}");
    let out = strata().args(["render", "scenes/shapes/sphere.toml", "--spp", "1", "-o", &png, "--set", "spp=8"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("--spp and --set spp=8 both set spp"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = strata().args(["render", "scenes/shapes/sphere.toml", "--spp", "1", "-o", &png, "--set", "name=mine"]).output().unwrap();
    assert_eq!(out.status.code(), Some(0));
    assert!(String::from_utf8_lossy(&out.stdout).contains("profile mine"), "{}", String::from_utf8_lossy(&out.stdout));
}
