//! The CLI with unusable output paths: refused before rendering (exit code 2, the code of every check
//! that runs before the render; a failure after it is 1), and nothing partial left behind.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn strata(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_strata")).current_dir(env!("CARGO_MANIFEST_DIR")).args(args).output().unwrap()
}

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("strata-hostile-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn entries(d: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(d).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}

const SCENE: &str = "scenes/shapes/sphere.toml";

/// A directory that refuses new files even to root (/proc), and a read-only directory when the
/// permission bits are enforced (not for root).
fn unwritable_dirs(tag: &str) -> Vec<PathBuf> {
    let mut v = Vec::new();
    if Path::new("/proc/self").is_dir() {
        v.push(PathBuf::from("/proc"));
    }
    let ro = dir(&format!("readonly-{tag}"));
    let mut perm = std::fs::metadata(&ro).unwrap().permissions();
    std::os::unix::fs::PermissionsExt::set_mode(&mut perm, 0o555);
    std::fs::set_permissions(&ro, perm).unwrap();
    if std::fs::write(ro.join("probe"), b"").is_err() {
        v.push(ro);
    } else {
        let _ = std::fs::remove_file(ro.join("probe"));
    }
    assert!(!v.is_empty(), "no unwritable directory to test with");
    v
}

#[test]
fn output_paths_that_cannot_be_written_are_refused_before_rendering() {
    let d = dir("out");
    let is_dir = d.join("taken.png");
    std::fs::create_dir(&is_dir).unwrap();
    let mut cases: Vec<(PathBuf, &str)> = vec![
        (d.join("missing/x.png"), "does not exist"),
        (is_dir.clone(), "is a directory"),
        (d.join("x.bmp"), ".png or .exr"),
        (d.join("noext"), ".png or .exr"),
        // A trailing `/` or `/.` names a directory: refused before the render, not failed after it.
        (PathBuf::from(format!("{}/", d.join("x.png").display())), "names a directory, not a file"),
        (PathBuf::from(format!("{}/.", d.join("x.png").display())), "names a directory, not a file"),
        (PathBuf::from(SCENE).join("x.png"), "is a file, not a directory"),
    ];
    for u in unwritable_dirs("out") {
        cases.push((u.join("x.png"), "cannot write here"));
    }
    for (out, msg) in cases {
        let o = strata(&["render", SCENE, "-o", out.to_str().unwrap(), "--spp", "1", "--quiet"]);
        let err = String::from_utf8_lossy(&o.stderr);
        eprintln!("-o {}: {}", out.display(), err.trim());
        assert_eq!(o.status.code(), Some(2), "-o {}: {err}", out.display());
        assert!(err.contains(msg), "-o {}: {err}", out.display());
    }
    // Nothing was created next to the outputs (no image, no temporary file), the directory is untouched.
    assert_eq!(entries(&d), vec!["taken.png".to_string()]);
    assert!(entries(&is_dir).is_empty());
}

#[test]
fn stats_json_paths_are_checked_before_rendering() {
    let d = dir("stats");
    let png = d.join("img.png");
    std::fs::create_dir(d.join("taken.json")).unwrap();
    let mut bad = vec![d.join("missing/s.json"), d.join("taken.json")];
    bad.extend(unwritable_dirs("stats").into_iter().map(|u| u.join("s.json")));
    for j in bad {
        let o = strata(&["render", SCENE, "-o", png.to_str().unwrap(), "--spp", "1", "--quiet", "--stats-json", j.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "--stats-json {}: {err}", j.display());
        // Refused before rendering: the image was not written either.
        assert!(!png.exists(), "--stats-json {}: the render ran", j.display());
    }
}

/// A refused render leaves an existing image alone.
#[test]
fn refused_render_keeps_the_previous_image() {
    let d = dir("keep");
    let out = d.join("old.png");
    std::fs::write(&out, b"previous image").unwrap();
    let scene = d.join("bad.toml");
    std::fs::write(&scene, "[image]\nwidth = 16384\nheight = 16384\n[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\nfov = 40\n")
        .unwrap();
    let o = strata(&["render", scene.to_str().unwrap(), "-o", out.to_str().unwrap(), "--quiet"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("bad.toml:3:") && err.contains("image.height") && err.contains("pixels"), "{err}");
    assert_eq!(std::fs::read(&out).unwrap(), b"previous image");
    assert_eq!(entries(&d), vec!["bad.toml".to_string(), "old.png".to_string()]);
}

/// Writes that fail keep no partial file: into a path that is a directory, into an unwritable
/// directory, and a write that fails inside the encoder while an older image is in place.
#[test]
fn failing_writes_leave_no_partial_file() {
    use glam::Vec3;
    use strata::film::output::write_image;
    let d = dir("write");
    let px = vec![Vec3::splat(0.5); 16 * 8];
    std::fs::create_dir(d.join("taken.png")).unwrap();
    assert!(write_image(&d.join("taken.png"), 16, 8, &px).is_err());
    assert!(entries(&d.join("taken.png")).is_empty());
    for u in unwritable_dirs("write") {
        assert!(write_image(&u.join("strata-x.png"), 16, 8, &px).is_err());
        assert!(!u.join("strata-x.png").exists());
    }
    // The encoder refuses the buffer (too short for 16 x 9): the old file stays as it was.
    std::fs::write(d.join("old.exr"), b"older image").unwrap();
    assert!(write_image(&d.join("old.exr"), 16, 9, &px).is_err());
    assert_eq!(std::fs::read(d.join("old.exr")).unwrap(), b"older image");
    assert_eq!(entries(&d), vec!["old.exr".to_string(), "taken.png".to_string()]);
    // And a good write replaces it whole.
    write_image(&d.join("old.exr"), 16, 8, &px).unwrap();
    assert_eq!(entries(&d), vec!["old.exr".to_string(), "taken.png".to_string()]);
}

/// Ctrl-C during a long render: exit code 130, the samples accumulated so far are written (the image,
/// and the film beside it for --resume), no temporary file left.
#[test]
fn interrupted_render_writes_what_it_has() {
    let d = dir("sigint");
    let out = d.join("partial.png");
    let mut child = Command::new(env!("CARGO_BIN_EXE_strata"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["render", SCENE, "-o", out.to_str().unwrap(), "--spp", "1048576", "--quiet", "--threads", "1"])
        .spawn()
        .unwrap();
    // Loading takes milliseconds; after 2 s the render (hours at this sample count) is under way.
    std::thread::sleep(std::time::Duration::from_secs(2));
    let killed = Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert!(killed.success());
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(130));
    let img = image::open(&out).unwrap().into_rgb8();
    assert_eq!(img.dimensions(), (320, 240));
    assert!(img.pixels().any(|p| p[0] > 0), "the partial image has content");
    assert_eq!(entries(&d), vec!["partial.film".to_string(), "partial.png".to_string()]);
    // The same command again (no --resume) would throw that film's work away: refused, film untouched.
    let film = std::fs::read(d.join("partial.film")).unwrap();
    let again = Command::new(env!("CARGO_BIN_EXE_strata"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["render", SCENE, "-o", out.to_str().unwrap(), "--spp", "1048576", "--quiet", "--threads", "1"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&again.stderr);
    assert_eq!(again.status.code(), Some(2), "{err}");
    assert!(err.contains("a partial film of this same render") && err.contains("--resume"), "{err}");
    assert_eq!(std::fs::read(d.join("partial.film")).unwrap(), film);
    // Another render (another seed) interrupted with the same -o: its film goes beside, not over it.
    let mut other = Command::new(env!("CARGO_BIN_EXE_strata"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["render", SCENE, "-o", out.to_str().unwrap(), "--spp", "1048576", "--quiet", "--threads", "1", "--seed", "2"])
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_secs(2));
    assert!(Command::new("kill").args(["-INT", &other.id().to_string()]).status().unwrap().success());
    assert_eq!(other.wait().unwrap().code(), Some(130));
    assert_eq!(std::fs::read(d.join("partial.film")).unwrap(), film, "an interrupt replaced another render's film");
    assert_eq!(entries(&d), vec!["partial.2.film".to_string(), "partial.film".to_string(), "partial.png".to_string()]);
}
