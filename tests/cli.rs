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

/// A `--resume` film that is not there is told before the scene is read (a trial waited a second for a
/// large scene's setup first), naming the flag: the same with a scene that does not exist either.
#[test]
fn missing_resume_film_fails_before_the_scene_is_read() {
    let film = tmp("not-there.film");
    for scene in ["scenes/showcase.toml", "/nonexistent-dir/scene.toml"] {
        let out =
            strata().args(["render", scene, "--resume", film.to_str().unwrap(), "-o", tmp("r.png").to_str().unwrap()]).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert!(err.starts_with(&format!("error: --resume {}: ", film.display())), "{scene}: {err}");
    }
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

/// Errors that state a limit state it as it is: the bound of --checkpoint-every (it said "a positive
/// number of seconds" of 1e9 s), and the samples of a render against 2^38 as exact integers (`2.749e11
/// samples; the limit is 2.749e11` looked like no excess).
#[test]
fn limits_are_stated_exactly() {
    let o = tmp("limits.png");
    let run = |extra: &[&str]| {
        let out = strata().args(["render", "scenes/shapes/sphere.toml", "-o", o.to_str().unwrap()]).args(extra).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{extra:?}");
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let film = tmp("limits.film");
    let err = run(&["--film", film.to_str().unwrap(), "--checkpoint-every", "1000000000"]);
    assert!(err.contains("--checkpoint-every 1000000000: expected a number of seconds above 0 and below 1000000000"), "{err}");
    let err = run(&["--size", "4096x4096", "--spp", "16385"]);
    assert!(
        err.contains("4096 x 4096 pixels x 16385 samples = 274894684160 samples; the limit per render is 2^38 = 274877906944"),
        "{err}"
    );
    // With --size, told before the scene is read (a trial waited 1.5 s for a 16 MB scene's parse): the
    // same message for a scene that is not there.
    let out = strata()
        .args(["render", "/nonexistent-dir/big.toml", "-o", o.to_str().unwrap(), "--size", "4096x4096", "--spp", "16385"])
        .output()
        .unwrap();
    let early = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.code() == Some(2) && early.contains("the limit per render is 2^38"), "{early}");
    assert!(!o.exists() && !film.exists());
}

/// A negative count reaches the flag's own parser, which names it (clap had read `-1` as an unknown
/// flag and suggested `-- -1`).
#[test]
fn negative_counts_are_named_as_bad_values() {
    for (cmd, flag) in [("render", "--threads"), ("render", "--spp"), ("render", "--seed"), ("study", "--threads"), ("study", "--seeds")] {
        let out = strata().args([cmd, "scenes/shapes/sphere.toml", flag, "-1"]).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{cmd} {flag}: {err}");
        assert!(err.contains(&format!("invalid value '-1' for '{flag}")) && !err.contains("tip:"), "{cmd} {flag}: {err}");
    }
    // Each number flag's message says what is wrong and the flag's real range: clap's own said "-1 is not
    // in 0..=4294967295" of --tile (1..=1024) and --max-depth (0..=1024), "invalid digit found in
    // string" of --seed -1 and 1.5, and --tile 0 was told without the value.
    for (cmd, flag, value, says) in [
        ("render", "--tile", "-1", "tile side in pixels: `-1` is negative (a whole number in 1..=1024)"),
        ("render", "--tile", "0", "tile side in pixels: `0` is not in 1..=1024"),
        ("render", "--max-depth", "-1", "bounces: `-1` is negative (a whole number in 0..=1024)"),
        ("render", "--max-depth", "1025", "bounces: `1025` is not in 0..=1024"),
        ("render", "--seed", "-1", "seed: `-1` is negative (a whole number in 0..=18446744073709551615)"),
        ("render", "--seed", "1.5", "seed: `1.5` is not a whole number"),
        ("render", "--seed", "18446744073709551616", "seed: `18446744073709551616` is too large (at most 18446744073709551615)"),
        ("render", "--threads", "1025", "threads: `1025` is not in 0..=1024"),
        ("study", "--threads", "x", "threads: `x` is not a number (a whole number in 0..=1024)"),
        ("study", "--seeds", "0", "seeds: `0` is not in 1..=1000"),
    ] {
        let out = strata().args([cmd, "scenes/shapes/sphere.toml", flag, value]).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{cmd} {flag} {value}: {err}");
        assert!(err.contains(&format!("invalid value '{value}' for '{flag}")) && err.contains(says), "{cmd} {flag} {value}: {err}");
    }
    // Text flags reach their own parsers, which name the flag.
    for (cmd, flag, value) in [("study", "--spp", "-1"), ("render", "--size", "-3x4"), ("study", "--size", "-3x4")] {
        let out = strata().args([cmd, "scenes/shapes/sphere.toml", flag, value]).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{cmd} {flag}: {err}");
        assert!(err.contains(flag.trim_start_matches('-')) && !err.contains("tip:"), "{cmd} {flag} {value}: {err}");
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
    for k in ["width", "height", "spp", "seconds", "setup_seconds", "rays", "rays_per_second", "nonfinite_samples", "lost_media"] {
        assert!(v.get(k).is_some(), "missing {k}");
    }
    assert_eq!(v["width"], 320);
    assert_eq!(v["spp"], 2);
    assert_eq!(v["nonfinite_samples"], 0);
    assert_eq!(v["lost_media"], 0);
    assert!(v["setup_seconds"].as_f64().unwrap() > 0.0);
    assert!(stdout.contains("setup: ") && stdout.contains("(read, parse, BVH, film)"), "{stdout}");
    assert!(v["output_seconds"].as_f64().unwrap() > 0.0 && stdout.contains("s after the render: the image)"), "{stdout}");
    assert_eq!(v["rays"]["camera"], 320 * 240 * 2);
    assert!(v["rays"]["shadow"].as_u64().unwrap() > 0);
}

/// More threads than the machine has hardware threads: a warning (stage times per thread then count
/// waiting), and the same image as one thread.
#[test]
fn more_threads_than_cores_is_warned_and_changes_no_pixel() {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let scene = tiny_scene("scenes/shapes/sphere.toml", 40, 30);
    let run = |threads: usize| {
        let png = tmp(&format!("threads-{threads}.png"));
        let out = strata()
            .args(["render", scene.to_str().unwrap(), "-o", png.to_str().unwrap(), "--spp", "2", "--threads", &threads.to_string()])
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        (String::from_utf8_lossy(&out.stderr).into_owned(), std::fs::read(&png).unwrap())
    };
    let (one_err, one) = run(1);
    assert!(!one_err.contains("hardware threads"), "{one_err}");
    if cores < 1024 {
        let (err, many) = run(cores + 1);
        assert!(err.contains(&format!("warning: --threads {} on {cores} hardware threads", cores + 1)), "{err}");
        assert!(many == one, "the image depends on the thread count");
    }
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
        // (A film named as an image is refused as such, before the clash.)
        (vec!["-o".into(), s(&tmp("clash.exr")), "--film".into(), twice.clone()], "a film is not an image"),
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
    let out = strata().args(["render", "scenes/shapes/sphere.toml", "-o", &png, "--set", "spp=2", "--set", " spp=3"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--set spp=2 and --set  spp=3 both set spp"), "{err}");
    let out = strata().args(["render", "scenes/shapes/sphere.toml", "--spp", "1", "-o", &png, "--set", "name=mine"]).output().unwrap();
    assert_eq!(out.status.code(), Some(0));
    assert!(String::from_utf8_lossy(&out.stdout).contains("profile mine"), "{}", String::from_utf8_lossy(&out.stdout));
}

/// A copy of a shipped scene at `w` x `h` pixels (for cheap renders of its features).
fn tiny_scene(path: &str, w: u32, h: u32) -> PathBuf {
    let text: String = std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| match l {
            l if l.starts_with("width =") => format!("width = {w}\n"),
            l if l.starts_with("height =") => format!("height = {h}\n"),
            l => format!("{l}\n"),
        })
        .collect();
    let out = tmp(&format!("tiny-{}", path.replace('/', "-")));
    std::fs::write(&out, text).unwrap();
    out
}

/// `preview.toml` with some lines replaced (`key = ...` lines by their key), and the 1-based line of
/// each replaced key.
fn profile_with(name: &str, fields: &[(&str, &str)]) -> (PathBuf, Vec<usize>) {
    let text = std::fs::read_to_string("profiles/preview.toml").unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let mut at = Vec::new();
    for (k, v) in fields {
        let i = lines.iter().position(|l| l.split('=').next().unwrap().trim() == *k).unwrap_or_else(|| panic!("no {k} in preview"));
        lines[i] = format!("{k} = {v}");
        at.push(i + 1);
    }
    let path = tmp(name);
    std::fs::write(&path, lines.join("\n") + "\n").unwrap();
    (path, at)
}

/// Split branching with a throughput cut-off of 0 spawns 2^depth rays per camera sample (a 160 x 100
/// render at depth 64 took 24 GB and was killed): it is refused before rendering, at the file's line,
/// or as the command line's when an override made the combination, with a message that says what to
/// use instead. Roulette with cut-off 0 stays valid.
#[test]
fn split_branching_with_zero_cutoff_is_refused() {
    let png = tmp("cut0.png");
    let p = png.to_str().unwrap();
    let render = |extra: &[&str]| {
        let mut a = vec!["render", "scenes/shapes/sphere.toml", "--spp", "1", "-o", p];
        a.extend(extra);
        let out = strata().args(&a).output().unwrap();
        (out.status.code(), String::from_utf8_lossy(&out.stderr).into_owned())
    };
    let advice = |err: &str| err.contains("2^max_depth") && err.contains("cutoff > 0") && err.contains("branching = \"roulette\"");

    let (split0, at) = profile_with("split0.toml", &[("branching", "\"split\""), ("throughput_cutoff", "0")]);
    let (code, err) = render(&["--profile", split0.to_str().unwrap()]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains(&format!("split0.toml:{}:", at[1])) && err.contains("field `throughput_cutoff`"), "{err}");
    assert!(advice(&err), "{err}");
    assert!(!png.exists());
    // The same by --set, from a split profile; the message is the command line's.
    let (code, err) = render(&["--profile", "final", "--set", "throughput_cutoff=0"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.starts_with("error: command line: throughput_cutoff: ") && advice(&err), "{err}");
    // A roulette file with cut-off 0 is valid; `--set branching=split` makes it invalid, and the error
    // names the override and the file's line of the cut-off.
    let (roulette0, at) = profile_with("roulette0.toml", &[("branching", "\"roulette\""), ("throughput_cutoff", "0")]);
    let (code, err) = render(&["--profile", roulette0.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{err}");
    let (code, err) = render(&["--profile", roulette0.to_str().unwrap(), "--set", "branching=split"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.starts_with("error: command line: branching: ") && err.contains(&format!("roulette0.toml:{}", at[1])), "{err}");
    // ... and an override fixes the split file.
    let (code, err) = render(&["--profile", split0.to_str().unwrap(), "--set", "branching=roulette"]);
    assert_eq!(code, Some(0), "{err}");
    let (code, err) = render(&["--profile", split0.to_str().unwrap(), "--set", "throughput_cutoff=1e-3"]);
    assert_eq!(code, Some(0), "{err}");
}

/// The summary's `sampling:` line and `--stats-json` name the filter and the strategy of every integral
/// the scene samples, as profile files spell them, and no other: lens only with a lens, time only with
/// motion, glossy only with glossy materials, diffuse only with diffuse_depth > 0.
#[test]
fn summary_and_json_name_the_strategies_the_scene_uses() {
    let sets = [
        "pixel_strategy=sobol",
        "light_strategy=grid",
        "lens_strategy=random",
        "time_strategy=center",
        "glossy_strategy=random",
        "diffuse_strategy=grid",
        "filter=gaussian",
    ];
    type Case<'a> = (&'a str, &'a [&'a str], &'a [(&'a str, &'a str)]);
    let cases: [Case; 4] = [
        ("scenes/shapes/sphere.toml", &[], &[("pixel", "sobol"), ("light", "grid")]),
        ("scenes/dof.toml", &[], &[("pixel", "sobol"), ("light", "grid"), ("lens", "random"), ("glossy", "random")]),
        ("scenes/motion.toml", &[], &[("pixel", "sobol"), ("light", "grid"), ("time", "center")]),
        (
            "scenes/glossy.toml",
            &["--set", "diffuse_depth=1"],
            &[("pixel", "sobol"), ("light", "grid"), ("glossy", "random"), ("diffuse", "grid")],
        ),
    ];
    for (scene, extra, want) in cases {
        let tiny = tiny_scene(scene, 8, 4);
        let json = tmp("strategies.json");
        let mut c = strata();
        c.args(["render", tiny.to_str().unwrap(), "--spp", "1", "-o", tmp("strategies.png").to_str().unwrap()]);
        c.args(["--stats-json", json.to_str().unwrap()]).args(extra);
        for s in sets {
            c.args(["--set", s]);
        }
        let out = c.output().unwrap();
        assert_eq!(out.status.code(), Some(0), "{scene}: {}", String::from_utf8_lossy(&out.stderr));
        let stdout = String::from_utf8_lossy(&out.stdout);
        let line = stdout.lines().find(|l| l.trim_start().starts_with("sampling:")).unwrap_or_else(|| panic!("{stdout}"));
        let listed = want.iter().map(|(k, v)| format!("{k} {v}")).collect::<Vec<_>>().join(", ");
        assert!(line.ends_with(&format!("filter gaussian; strategies: {listed}")), "{scene}: {line}");
        let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        assert_eq!(v["filter"], "gaussian", "{scene}");
        let got: Vec<(String, String)> =
            v["strategies"].as_object().unwrap().iter().map(|(k, s)| (k.clone(), s.as_str().unwrap().to_string())).collect();
        let want: Vec<(String, String)> = want.iter().map(|(k, s)| (k.to_string(), s.to_string())).collect();
        // (serde_json sorts object keys; compare as sets.)
        let (mut got, mut want) = (got, want);
        got.sort();
        want.sort();
        assert_eq!(got, want, "{scene}");
        assert_eq!(v["work_units"]["done"], v["work_units"]["total"], "{scene}");
        assert_eq!(v["completed"], true, "{scene}");
    }
}

/// A single strategy refines the general one whichever order they are given in, by `--strategy` or by
/// `--set strategy=`: all four spellings render the same image, byte for byte, with pixel random and
/// light grid.
#[test]
fn single_strategy_refines_the_general_one_in_either_order() {
    let orders: [&[&str]; 4] = [
        &["--set", "pixel_strategy=random", "--strategy", "grid"],
        &["--strategy", "grid", "--set", "pixel_strategy=random"],
        &["--set", "pixel_strategy=random", "--set", "strategy=grid"],
        &["--set", "strategy=grid", "--set", "pixel_strategy=random"],
    ];
    let mut images = Vec::new();
    for (i, args) in orders.iter().enumerate() {
        let (png, json) = (tmp(&format!("order{i}.png")), tmp(&format!("order{i}.json")));
        let out = strata()
            .args(["render", "scenes/shapes/sphere.toml", "--spp", "4", "-o", png.to_str().unwrap()])
            .args(["--stats-json", json.to_str().unwrap(), "-q"])
            .args(*args)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(0), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
        let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        assert_eq!((v["strategies"]["pixel"].as_str(), v["strategies"]["light"].as_str()), (Some("random"), Some("grid")), "{args:?}");
        images.push(std::fs::read(&png).unwrap());
    }
    assert!(images.iter().all(|i| *i == images[0]), "the four orders rendered different images");
}

/// Names of strategies, filters and branching policies are exact and lowercase, in files and flags
/// alike; a wrong name is an error that lists the accepted ones (`centre` stays accepted).
#[test]
fn names_are_lowercase_in_files_and_flags_alike() {
    let png = tmp("case.png");
    let p = png.to_str().unwrap();
    let (upper, at) = profile_with("upper.toml", &[("light_strategy", "\"GRID\"")]);
    let refused: [(Vec<&str>, &str); 5] = [
        (
            vec!["--set", "light_strategy=GRID"],
            "command line: light_strategy: unknown strategy `GRID` (one of center, grid, random, jittered, sobol)",
        ),
        (
            vec!["--strategy", "Jittered"],
            "command line: strategy: unknown strategy `Jittered` (one of center, grid, random, jittered, sobol)",
        ),
        (vec!["--set", "filter=TENT"], "command line: filter: expected box, tent or gaussian, got `TENT`"),
        (vec!["--set", "branching=Split"], "command line: branching: expected split or roulette, got `Split`"),
        (vec!["--profile", upper.to_str().unwrap()], "`GRID`, expected one of `center`, `centre`, `grid`, `random`, `jittered`, `sobol`"),
    ];
    for (args, want) in refused {
        let out = strata().args(["render", "scenes/shapes/sphere.toml", "--spp", "1", "-o", p]).args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err}");
    }
    let out = strata()
        .args(["render", "scenes/shapes/sphere.toml", "--spp", "1", "-o", p, "--profile", upper.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&out.stderr).contains(&format!("upper.toml:{}:", at[0])));
    let out = strata()
        .args(["render", "scenes/shapes/sphere.toml", "--spp", "1", "-o", p, "--set", "light_strategy=grid", "--set", "filter=tent"])
        .args(["--set", "pixel_strategy=centre", "--set", "branching=split"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
}

/// `--profile DIR` says that it is a directory (not that there is no such file).
#[test]
fn a_directory_as_profile_is_named_a_directory() {
    let dir = tmp("profdir");
    std::fs::create_dir_all(&dir).unwrap();
    let out = strata()
        .args([
            "render",
            "scenes/shapes/sphere.toml",
            "--spp",
            "1",
            "-o",
            tmp("dir.png").to_str().unwrap(),
            "--profile",
            dir.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains(&format!("`{}` is a directory, not a profile file", dir.display())), "{err}");
}

/// A render whose work units take about half a second each on one thread (64 x 64 pixels, one unit per
/// sample at tile 64; every pixel sees two area lights through an occluder, so all 2 x 4096 shadow
/// rays per sample are traced), started with stderr piped; returns the child and its stderr lines.
#[cfg(unix)]
fn slow_render(name: &str, extra: &[&str]) -> (std::process::Child, std::io::Lines<std::io::BufReader<std::process::ChildStderr>>) {
    slow_render_in(name, std::path::Path::new(env!("CARGO_MANIFEST_DIR")), 10, extra)
}

/// [`slow_render`] of `spp` work units, run in the directory `cwd`.
#[cfg(unix)]
fn slow_render_in(
    name: &str,
    cwd: &std::path::Path,
    spp: u32,
    extra: &[&str],
) -> (std::process::Child, std::io::Lines<std::io::BufReader<std::process::ChildStderr>>) {
    use std::io::BufRead;
    let light =
        |x: f32| format!("[[lights]]\ntype = \"quad\"\norigin = [{x}, 3, -1]\nu = [2, 0, 0]\nv = [0, 0, 2]\nradiance = [1, 1, 1]\n");
    let scene = tmp(&format!("{name}.toml"));
    let text = "[image]\nwidth = 64\nheight = 64\n[camera]\nposition = [0, 1, 0]\nlook_at = [0, 0, 0.01]\nfov = 40\n\
                [materials.m]\ntype = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\n\
                [[shapes]]\ntype = \"plane\"\npoint = [0, 0, 0]\nnormal = [0, 1, 0]\nmaterial = \"m\"\n\
                [[shapes]]\ntype = \"quad\"\norigin = [-5, 2, -5]\nu = [10, 0, 0]\nv = [0, 0, 10]\nmaterial = \"m\"\n"
        .to_string()
        + &light(-2.0)
        + &light(0.0);
    std::fs::write(&scene, text).unwrap();
    let mut child = strata()
        .current_dir(cwd)
        .args(["render", scene.to_str().unwrap(), "--spp", &spp.to_string(), "--tile", "64", "--threads", "1", "--light-samples", "4096"])
        .args(extra)
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let lines = std::io::BufReader::new(child.stderr.take().unwrap()).lines();
    (child, lines)
}

#[cfg(unix)]
fn sigint(child: &std::process::Child) {
    let status = Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert!(status.success());
}

/// Read stderr lines up to the first containing `what` (all lines read so far are returned).
#[cfg(unix)]
fn read_until(lines: &mut impl Iterator<Item = std::io::Result<String>>, what: &str) -> String {
    let mut seen = String::new();
    for l in lines {
        let l = l.unwrap();
        seen += &l;
        seen += "\n";
        if l.contains(what) {
            return seen;
        }
    }
    panic!("stderr ended before a line with `{what}`:\n{seen}");
}

/// Ctrl-C once: one line says what happens, the units in flight finish, the image and the film of what
/// was done are written, the summary says how much was done (and the JSON agrees), exit 130.
/// The signal is sent after the first unit's progress line (so the handler is installed); the render
/// has 9 more units of ~0.5 s, so it cannot have finished.
#[cfg(unix)]
#[test]
fn interrupt_writes_what_was_done_and_says_so() {
    use std::io::Read;
    let (png, film, json) = (tmp("int1.png"), tmp("int1.film"), tmp("int1.json"));
    let (mut child, mut lines) = slow_render("int1", &["-o", png.to_str().unwrap(), "--stats-json", json.to_str().unwrap()]);
    read_until(&mut lines, "work units");
    sigint(&child);
    let notice = read_until(&mut lines, "interrupted: finishing the work units in flight");
    assert!(
        notice.contains(&format!("then writing {} and the film {} (a second Ctrl-C or signal quits", png.display(), film.display())),
        "{notice}"
    );
    let rest: String = lines.map(|l| l.unwrap() + "\n").collect();
    let status = child.wait().unwrap();
    let mut stdout = String::new();
    child.stdout.take().unwrap().read_to_string(&mut stdout).unwrap();
    assert_eq!(status.code(), Some(130), "{rest}");
    assert!(rest.contains("interrupted: wrote the") && rest.contains("--resume"), "{rest}");
    assert!(png.exists() && film.exists());
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(v["completed"], false);
    let done = v["work_units"]["done"].as_u64().unwrap();
    assert_eq!(v["work_units"]["total"], 10);
    assert!((1..10).contains(&done), "{done}");
    assert!(stdout.contains(&format!("  interrupted: {done} of 10 work units of samples 0..10 of 10")), "{stdout}");
    assert!(!stdout.contains("  samples 0..10 of 10"), "{stdout}");
}

/// An image that cannot be written after the render (its directory removed meanwhile) still leaves the
/// render in the film and the statistics asked for, says how to make the image from the film, and
/// exits 1. (Interrupted, so that the test is quick: the film is then incomplete, `--allow-gaps`.)
#[cfg(unix)]
#[test]
fn an_image_that_cannot_be_written_leaves_the_film_and_stats() {
    let gone = tmp("gone");
    std::fs::create_dir_all(&gone).unwrap();
    let (film, json) = (tmp("kept.film"), tmp("kept.json"));
    let png = gone.join("x.png");
    let args = ["-o", png.to_str().unwrap(), "--film", film.to_str().unwrap(), "--stats-json", json.to_str().unwrap()];
    let (mut child, mut lines) = slow_render("gone", &args);
    read_until(&mut lines, "work units");
    std::fs::remove_dir_all(&gone).unwrap();
    sigint(&child);
    let rest: String = lines.map(|l| l.unwrap() + "\n").collect();
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(1), "{rest}");
    assert!(
        rest.contains(&format!("the render is kept in the film {}", film.display())) && rest.contains("--allow-gaps -o IMAGE"),
        "{rest}"
    );
    assert!(film.exists() && json.exists() && !png.exists(), "{rest}");
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert!(v["work_units"]["done"].as_u64().unwrap() >= 1, "{v}");
    // The film gives the image.
    let out = tmp("from_kept.png");
    let m = strata().args(["merge", film.to_str().unwrap(), "--allow-gaps", "-o", out.to_str().unwrap()]).output().unwrap();
    assert!(m.status.success() && out.exists(), "{}", String::from_utf8_lossy(&m.stderr));
    // Its summary gives the partial film's share of work units (it read `samples 0..N of spp N`).
    let (said, done) = (String::from_utf8_lossy(&m.stdout), v["work_units"]["done"].as_u64().unwrap());
    assert!(said.contains(&format!(" ({done} of {} work units)", v["work_units"]["total"])), "{said}");
    // A film being resumed keeps any name (older versions wrote `.exr` films): refused here only as a
    // film of another render.
    let renamed = tmp("kept_as.exr");
    std::fs::copy(&film, &renamed).unwrap();
    let o = strata()
        .args(["render", "scenes/showcase.toml", "--resume", renamed.to_str().unwrap(), "-o", tmp("r.png").to_str().unwrap()])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.code() == Some(2) && err.contains("cannot resume") && !err.contains("not an image"), "{err}");
    // A new film is not named as an image.
    for cmd in
        [&["render", "scenes/showcase.toml", "--film", "f.png"][..], &["merge", film.to_str().unwrap(), "-o", "x.png", "--film", "f.EXR"]]
    {
        let o = strata().args(cmd).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.code() == Some(2) && err.contains("a film is not an image"), "{cmd:?}: {err}");
    }
}

/// A render that completes but whose image cannot be written (its directory removed while it renders),
/// without --film: the film is still written, where an interrupt writes it (beside the image: gone too)
/// or else in the working directory, the error says where and how to make the image from it, and
/// --stats-json is written (the render was lost: no film anywhere). And a film that cannot be written
/// (its directory removed) while the image can: the film goes to the working directory and --stats-json
/// is still written (with a full disk it was not), exit 1. (The directory is removed after the first of
/// the render's 2 work units, ~0.5 s each.)
#[cfg(unix)]
#[test]
fn a_failed_write_keeps_the_render_in_a_film_and_writes_the_stats() {
    let cwd = tmp("fallback-cwd");
    std::fs::create_dir_all(&cwd).unwrap();
    let cwd = std::fs::canonicalize(&cwd).unwrap();
    for image_fails in [true, false] {
        let gone = tmp(&format!("gone-{image_fails}"));
        std::fs::create_dir_all(&gone).unwrap();
        let json = tmp(&format!("fallback-{image_fails}.json"));
        let (png, film) = if image_fails { (gone.join("x.png"), None) } else { (tmp("fallback.png"), Some(gone.join("y.film"))) };
        let mut args = vec!["-o", png.to_str().unwrap(), "--stats-json", json.to_str().unwrap()];
        if let Some(f) = &film {
            args.extend(["--film", f.to_str().unwrap()]);
        }
        let (mut child, mut lines) = slow_render_in(&format!("fallback-{image_fails}"), &cwd, 2, &args);
        read_until(&mut lines, "work units");
        std::fs::remove_dir_all(&gone).unwrap();
        let rest: String = lines.map(|l| l.unwrap() + "\n").collect();
        let status = child.wait().unwrap();
        assert_eq!(status.code(), Some(1), "{rest}");
        let kept = cwd.join(if image_fails { "x.film" } else { "y.film" });
        assert!(rest.contains(&format!("the film was written to {} instead", kept.display())), "{rest}");
        assert!(rest.contains(&format!("--stats-json {} was written", json.display())), "{rest}");
        let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        assert_eq!((v["completed"].as_bool(), v["work_units"]["done"].as_u64()), (Some(true), Some(2)), "{v}");
        assert_eq!(png.exists(), !image_fails, "{rest}");
        if image_fails {
            // Complete: the film gives the whole image, no --allow-gaps needed.
            let how = format!("the render is kept in the film {}: `strata merge {} -o IMAGE`", kept.display(), kept.display());
            assert!(rest.contains(&how), "{rest}");
            let out = tmp("from_fallback.png");
            let m = strata().args(["merge", kept.to_str().unwrap(), "-o", out.to_str().unwrap()]).output().unwrap();
            assert!(m.status.success() && out.exists(), "{}", String::from_utf8_lossy(&m.stderr));
        }
        assert!(kept.exists(), "{rest}");
    }
}

/// Ctrl-C while the scene is being read (200,000 spheres: ~1 s of parsing and BVH here) quits at once
/// with a message, exit 130, writing nothing. (A signal that lands before the process has installed its
/// handler, or after setup on a very fast machine, is retried with another delay.)
#[cfg(unix)]
#[test]
fn interrupt_during_setup_says_nothing_was_written() {
    use std::fmt::Write as _;
    let scene = tmp("setup_int.toml");
    let mut text = String::from(
        "[image]\nwidth = 16\nheight = 16\n[camera]\nposition = [0, 0, 50]\nlook_at = [0, 0, 0]\nfov = 40\n\
         [materials.m]\ntype = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\n",
    );
    // (Compact lines: a scene file may hold 16 MiB.)
    for i in 0..200_000i32 {
        let (x, y, z) = (i % 100 - 50, (i / 100) % 100 - 50, i / 10_000 - 10);
        write!(text, "[[shapes]]\ntype=\"sphere\"\ncenter=[{x},{y},{z}]\nradius=0.1\nmaterial=\"m\"\n").unwrap();
    }
    std::fs::write(&scene, text).unwrap();
    let png = tmp("setup_int.png");
    for delay_ms in [400u64, 150, 800, 50] {
        let child = strata()
            .args(["render", scene.to_str().unwrap(), "-o", png.to_str().unwrap(), "--spp", "1"])
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        std::thread::sleep(std::time::Duration::from_millis(delay_ms));
        sigint(&child);
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        if out.status.code() == Some(130) && err.contains("interrupted while setting up the render") {
            assert!(err.contains("nothing was written") && !png.exists(), "{err}");
            return;
        }
        eprintln!("delay {delay_ms} ms: status {:?}, stderr {err}: retried", out.status);
        let _ = std::fs::remove_file(&png);
    }
    panic!("no interrupt landed during setup");
}

/// Ctrl-C twice: the second, while the unit in flight (~0.5 s) finishes, quits at once and says that
/// nothing was written; nothing is. (The second signal follows the first's notice by 150 ms.)
#[cfg(unix)]
#[test]
fn second_interrupt_quits_at_once_and_says_nothing_was_written() {
    let png = tmp("int2.png");
    let (mut child, mut lines) = slow_render("int2", &["-o", png.to_str().unwrap()]);
    read_until(&mut lines, "work units");
    // (Into the next unit, which takes ~0.5 s: a signal between the progress line and the worker's
    // taking of its next unit stops the render before any unit is in flight, and it writes at once,
    // before the second signal. Seen once on a loaded machine.)
    std::thread::sleep(std::time::Duration::from_millis(100));
    sigint(&child);
    read_until(&mut lines, "interrupted: finishing the work units in flight");
    // (Past the debounce, under which a second signal is the first one delivered twice.)
    std::thread::sleep(std::time::Duration::from_millis(150));
    sigint(&child);
    let rest: String = lines.map(|l| l.unwrap() + "\n").collect();
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(130), "{rest}");
    assert!(rest.contains("interrupted again: quit at once; nothing was written"), "{rest}");
    assert!(!png.exists() && !tmp("int2.film").exists(), "{rest}");
}

/// One interrupt delivered twice at once (GNU `timeout -s INT` signals the process, then its group) is
/// one Ctrl-C: the render stops and writes what was done.
#[cfg(unix)]
#[test]
fn an_interrupt_delivered_twice_at_once_is_one() {
    let (png, film) = (tmp("int3.png"), tmp("int3.film"));
    let (mut child, mut lines) = slow_render("int3", &["-o", png.to_str().unwrap()]);
    read_until(&mut lines, "work units");
    sigint(&child);
    sigint(&child);
    let rest: String = lines.map(|l| l.unwrap() + "\n").collect();
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(130), "{rest}");
    assert!(!rest.contains("interrupted again") && rest.contains("interrupted: wrote the"), "{rest}");
    assert!(png.exists() && film.exists(), "{rest}");
}

/// Samples that can only repeat each other are warned about, and the warning is true: `--spp 4` with
/// every integral at `center` (a scene without glass or diffuse bounces) renders the image `--spp 1` does,
/// byte for byte; 4 light samples at the light's centre render what 1 does. Jittered samples: no warning.
#[test]
fn identical_samples_are_warned_about() {
    let scene = tmp("center.toml");
    std::fs::write(
        &scene,
        "[image]\nwidth = 12\nheight = 8\n[camera]\nposition = [0, 1, 5]\nlook_at = [0, 0, 0]\nfov = 40\n\
         [materials.m]\ntype = \"lambert\"\nalbedo = [0.6, 0.5, 0.4]\n\
         [[shapes]]\ntype = \"plane\"\npoint = [0, -1, 0]\nnormal = [0, 1, 0]\nmaterial = \"m\"\n\
         [[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"m\"\n\
         [[lights]]\ntype = \"quad\"\norigin = [-1, 3, -1]\nu = [2, 0, 0]\nv = [0, 0, 2]\nradiance = [5, 5, 5]\n",
    )
    .unwrap();
    let render = |name: &str, args: &[&str]| {
        let out_path = tmp(name);
        let o = strata().args(["render", scene.to_str().unwrap(), "-q", "-o", out_path.to_str().unwrap()]).args(args).output().unwrap();
        assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
        // (The pixels' bits: the files' headers record the spp and light samples each was rendered with.)
        let px: Vec<u32> = image::open(&out_path).unwrap().into_rgb32f().into_raw().iter().map(|x| x.to_bits()).collect();
        (String::from_utf8_lossy(&o.stderr).into_owned(), px)
    };
    let (w4, img4) = render("c4.exr", &["--spp", "4", "--strategy", "center"]);
    let (w1, img1) = render("c1.exr", &["--spp", "1", "--strategy", "center"]);
    assert!(w4.contains("warning: spp 4") && w4.contains("--spp 1 renders the same image"), "{w4}");
    assert!(!w1.contains("warning"), "{w1}");
    assert_eq!(img4, img1, "the warning's claim");
    let (wl, imgl) = render("l4.exr", &["--spp", "1", "--strategy", "center", "--light-samples", "4"]);
    assert!(wl.contains("warning: light_samples 4"), "{wl}");
    assert_eq!(imgl, img1, "the warning's claim");
    let (wj, _) = render("j4.exr", &["--spp", "4", "--strategy", "jittered", "--light-samples", "4"]);
    assert!(!wj.contains("warning"), "{wj}");
    // One grid light sample is the light's centre for every camera sample: the image of `center` light
    // samples, whatever the spp (jittered pixels here).
    let px = ["--set", "pixel_strategy=jittered"];
    let (wg, img_g) = render("g16.exr", &[&["--spp", "16", "--set", "light_strategy=grid", "--light-samples", "1"][..], &px].concat());
    let (_, img_c) = render("gc16.exr", &[&["--spp", "16", "--set", "light_strategy=center", "--light-samples", "1"][..], &px].concat());
    assert!(wg.contains("light_strategy `grid` with 1 light sample"), "{wg}");
    assert_eq!(img_g, img_c, "the warning's claim");
    // Grids of counts without near-square factors are strips: warned (2 = 1 x 2, 3 = 1 x 3, 7 = 1 x 7,
    // 22 = 2 x 11; a trial saw a lens grid of 3 take a slit's image without a word); 9, 12, 6 not.
    for (n, strips) in [("2", true), ("3", true), ("7", true), ("22", true), ("9", false), ("12", false), ("6", false)] {
        let (w, _) = render("gs.exr", &["--spp", n, "--strategy", "grid"]);
        assert_eq!(w.contains(&format!("pixel grid of {n} samples is")), strips, "spp {n}: {w}");
        let (w, _) = render("gl.exr", &["--spp", "1", "--strategy", "grid", "--light-samples", n]);
        assert_eq!(w.contains(&format!("light grid of {n} samples is")), strips, "light samples {n}: {w}");
        // Jittered sets of such counts take n equal-area strata in rows (`jitter_rows`): no strips.
        let (w, _) = render("js.exr", &["--spp", n, "--strategy", "jittered", "--light-samples", n]);
        assert!(!w.contains("strips"), "jittered {n}: {w}");
    }
}

/// A zero-length shutter in a scene with motion is warned about (every time sample is one instant; the
/// image at that instant is checked in tests/distribution), the default `[0, 0]` (no `shutter` given)
/// and one sample per pixel included; an open shutter is not. The warning names `camera.shutter` at its
/// line, or at the `[camera]` header where the file gives none (a user trial's had no file or line).
#[test]
fn a_zero_length_shutter_with_motion_is_warned_about() {
    let scene = tmp("shutter.toml");
    for (shutter, spp, warned) in
        [("shutter = [0.5, 0.5]", "4", true), ("", "4", true), ("shutter = [0.5, 0.5]", "1", true), ("shutter = [0.0, 1.0]", "4", false)]
    {
        std::fs::write(
            &scene,
            format!(
                "[image]\nwidth = 8\nheight = 6\n[camera]\nposition = [0, 1, 5]\nlook_at = [0, 0, 0]\nfov = 40\n{shutter}\n\
                 [materials.m]\ntype = \"lambert\"\nalbedo = [0.6, 0.5, 0.4]\n\
                 [[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"m\"\nmotion = [1, 0, 0]\n\
                 [[lights]]\ntype = \"point\"\nposition = [0, 4, 4]\nintensity = [9, 9, 9]\n"
            ),
        )
        .unwrap();
        let out = tmp("shutter.png");
        let o = strata().args(["render", scene.to_str().unwrap(), "-q", "--spp", spp, "-o", out.to_str().unwrap()]).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(0), "{err}");
        assert_eq!(err.contains("has zero length") && err.contains("no motion blur"), warned, "{shutter}: {err}");
        let line = if shutter.is_empty() { 4 } else { 8 };
        let at = format!("warning: {}:{line}:", scene.display());
        assert_eq!(err.lines().any(|l| l.starts_with(&at) && l.contains("field `camera.shutter`: shutter")), warned, "{shutter}: {err}");
    }
    // A shutter 1 long at 1e6, where f32 times are 0.0625 apart: 16 instants, motion blur in 16 steps (a
    // user trial); at 1e3 (6e-5 apart: 16,384 instants) nothing to say.
    for (shutter, warned) in [("shutter = [1e6, 1000001.0]", true), ("shutter = [1e3, 1001.0]", false)] {
        std::fs::write(
            &scene,
            format!(
                "[image]\nwidth = 8\nheight = 6\n[camera]\nposition = [0, 1, 5]\nlook_at = [0, 0, 0]\nfov = 40\n{shutter}\n\
                 [materials.m]\ntype = \"lambert\"\nalbedo = [0.6, 0.5, 0.4]\n\
                 [[shapes]]\ntype = \"sphere\"\ncenter = [-1e6, 0, 0]\nradius = 1\nmaterial = \"m\"\nmotion = [1, 0, 0]\n"
            ),
        )
        .unwrap();
        let out = tmp("shutter.png");
        for (time, sampled) in [("time_strategy=jittered", true), ("time_strategy=center", false)] {
            let o = strata()
                .args(["render", scene.to_str().unwrap(), "-q", "--spp", "4", "--set", time, "-o", out.to_str().unwrap()])
                .output()
                .unwrap();
            let err = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(0), "{err}");
            // (Not where time is held at one instant: no blur to come out in steps.)
            let said = err.contains("f32 times there are 0.0625 apart, so it holds only 17 distinct instants");
            assert_eq!(err.contains(&format!("warning: {}:8:11: field `camera.shutter`: shutter", scene.display())), said, "{err}");
            assert_eq!(said, warned && sampled, "{shutter} {time}: {err}");
        }
    }
}

/// `--size WxH` renders the scene at another size (the image and the summary say so), a film records it
/// (a resume at the scene's own size is refused, naming the sizes), and bad sizes are input errors.
#[test]
fn size_renders_at_another_size() {
    let (png, film) = (tmp("sized.png"), tmp("sized.film"));
    let o = strata()
        .args([
            "render",
            "scenes/shapes/sphere.toml",
            "--size",
            "40x30",
            "--spp",
            "1",
            "-o",
            png.to_str().unwrap(),
            "--film",
            film.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stdout).contains("40x30"));
    assert_eq!(image::open(&png).unwrap().into_rgb8().dimensions(), (40, 30));
    let o = strata()
        .args(["render", "scenes/shapes/sphere.toml", "--spp", "1", "-o", png.to_str().unwrap(), "--resume", film.to_str().unwrap()])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("image size: film 40x30, this render 320x240"), "{err}");
    for bad in ["40", "0x30", "40x16385", "8192x8192", "ax3"] {
        let o = strata().args(["render", "scenes/shapes/sphere.toml", "--size", bad, "-o", png.to_str().unwrap()]).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{bad}: {err}");
        assert!(err.contains(&format!("--size {bad}: ")), "{bad}: {err}");
    }
}

/// A quad lit by a point light straight above its centre, the whole scene at scale `s`: the centre
/// pixel's radiance is albedo / pi x I / h^2 = 0.5 / pi at every scale (I = 16 s^2, h = 4 s). The quad's
/// checks and basis squared the cross product in f32: at sides of 8e9 it overflowed and the quad was
/// refused as "parallel" (a user trial), at 8e-12 it underflowed into an inaccurate normal and basis.
#[test]
fn quads_of_huge_and_tiny_sides_render_their_irradiance() {
    for s in [1e-12f64, 1.0, 1e9, 1e12] {
        let scene = tmp(&format!("quad_scale_{s:e}.toml"));
        let v = |x: f64| format!("{:e}", x * s);
        std::fs::write(
            &scene,
            format!(
                "[image]\nwidth = 15\nheight = 15\n[camera]\nposition = [0, {h}, {z}]\nlook_at = [0, 0, 0]\nfov = 40\n\
                 [materials.l]\ntype = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\n\
                 [[shapes]]\ntype = \"quad\"\norigin = [{m}, 0, {m}]\nu = [0, 0, {e}]\nv = [{e}, 0, 0]\nmaterial = \"l\"\n\
                 [[lights]]\ntype = \"point\"\nposition = [0, {h}, 0]\nintensity = [{i}, {i}, {i}]\n",
                h = v(4.0),
                z = v(12.0),
                m = v(-4.0),
                e = v(8.0),
                i = format!("{:e}", 16.0 * s * s)
            ),
        )
        .unwrap();
        let out = tmp(&format!("quad_scale_{s:e}.exr"));
        let o = strata()
            .args(["render", scene.to_str().unwrap(), "-q", "--spp", "1", "--strategy", "center", "-o", out.to_str().unwrap()])
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(0), "scale {s:e}: {}", String::from_utf8_lossy(&o.stderr));
        let img = image::open(&out).unwrap().into_rgb32f();
        let centre = img.get_pixel(7, 7)[0] as f64;
        let expect = 0.5 / std::f64::consts::PI;
        assert!((centre / expect - 1.0).abs() < 1e-3, "scale {s:e}: centre {centre}, expected {expect}");
    }
}

/// Past 64 lights, `light_selection = all` (the default) is noted with the shadow rays it sends per
/// point (a trial's 10,000 lamps took 10.9 s with it against 0.05 s with `tree`, without a word); not
/// with another selection, nor with few lights.
#[test]
fn many_lights_under_all_are_noted() {
    let o = tmp("many.png");
    let run = |scene: &str, extra: &[&str]| {
        let out = strata()
            .args(["render", scene, "-q", "--size", "16x10", "--spp", "1", "-o", o.to_str().unwrap()])
            .args(extra)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    // scenes/many_lights.toml: 64 point lights and 192 area lights (4 samples each with --light-samples 4).
    let err = run("scenes/many_lights.toml", &["--light-samples", "4"]);
    assert!(err.contains("note: light_selection `all` (the default) with 256 lights: every shading point sends 832 shadow rays"), "{err}");
    assert!(!run("scenes/many_lights.toml", &["--set", "light_selection=tree"]).contains("note:"));
    assert!(!run("scenes/showcase.toml", &[]).contains("note:"));
}

/// A shutter of no length away from time 0 places moving shapes at its one instant: the time integral
/// is not sampled, so the summary lists no time strategy, and `--spp 4` with every integral at `center`
/// is warned of as identical samples (a motion trial found neither), and renders what `--spp 1` does.
#[test]
fn a_shutter_of_no_length_samples_no_time() {
    let scene = tmp("instant.toml");
    std::fs::write(
        &scene,
        "[image]\nwidth = 12\nheight = 8\n[camera]\nposition = [0, 1, 5]\nlook_at = [0, 0, 0]\nfov = 40\nshutter = [0.5, 0.5]\n\
         [materials.m]\ntype = \"lambert\"\nalbedo = [0.6, 0.5, 0.4]\n\
         [[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"m\"\nmotion = [1, 0, 0]\n\
         [[lights]]\ntype = \"point\"\nposition = [0, 3, 3]\nintensity = [5, 5, 5]\n",
    )
    .unwrap();
    let render = |name: &str, spp: &str| {
        let out_path = tmp(name);
        let o = strata()
            .args(["render", scene.to_str().unwrap(), "-o", out_path.to_str().unwrap(), "--spp", spp, "--strategy", "center"])
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
        let px: Vec<u32> = image::open(&out_path).unwrap().into_rgb32f().into_raw().iter().map(|x| x.to_bits()).collect();
        (String::from_utf8_lossy(&o.stderr).into_owned(), String::from_utf8_lossy(&o.stdout).into_owned(), px)
    };
    let (w4, out4, img4) = render("i4.exr", "4");
    let (_, _, img1) = render("i1.exr", "1");
    assert!(w4.contains("warning: spp 4") && w4.contains("shutter [0.5, 0.5] has zero length"), "{w4}");
    assert!(out4.contains("strategies: pixel center") && !out4.contains("time center"), "{out4}");
    assert_eq!(img4, img1, "the warning's claim");
}
