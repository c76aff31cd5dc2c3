//! Rendering beyond one process: film files, checkpoints, resume, sample ranges and their merge.
//!
//! The ground truth is always an uninterrupted one-process render of the same scene, seed and profile:
//! every path below must reproduce it bit for bit (film sums, film file bytes, EXR bytes).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;
use std::time::Duration;
use strata::film::file::{decode, encode, profile_record, FilmHeader};
use strata::film::Film;
use strata::render::{render_into, render_resumable, work_units, Checkpoint, RenderJob};
use strata::scene::{parse_scene, Profile, Scene};
use strata::wavefront::Settings;

const W: u32 = 48;
const H: u32 = 30;
const SPP: u32 = 6;
/// Small tiles: many work units, so interruptions land in the middle of a render.
const TILE: u32 = 4;

fn scene_text() -> String {
    std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/showcase.toml"))
        .unwrap()
        .replace("width = 640", &format!("width = {W}"))
        .replace("height = 400", &format!("height = {H}"))
}

fn profile() -> Profile {
    let mut p = Profile::builtin("final");
    p.spp = SPP;
    p.light_samples = 2;
    p
}

fn scene() -> Scene {
    parse_scene(Path::new("showcase.toml"), &scene_text()).unwrap()
}

fn job(scene: &Scene) -> RenderJob<'_> {
    let mut j = RenderJob::new(scene, Settings { profile: profile(), seed: 7 });
    j.threads = 2;
    j.tile = TILE;
    j
}

/// Samples a film must hold if it holds exactly the flagged units.
fn samples_of_units(scene: &Scene, completed: &[bool]) -> u64 {
    let units = work_units(scene.width, scene.height, TILE, 0..SPP);
    units.iter().zip(completed).filter(|(_, &c)| c).map(|(u, _)| u.tile.pixel_count() as u64 * u.samples.len() as u64).sum()
}

#[test]
fn resume_after_cancel_and_from_checkpoints_is_bit_identical() {
    let scene = scene();
    let (full, stats) = render_into(&job(&scene), Film::new(W, H));
    assert!(stats.completed && stats.nonfinite_samples == 0);
    let n = work_units(W, H, TILE, 0..SPP).len();
    assert!(n >= 60, "{n} units: too few to interrupt in the middle");

    // Checkpoints as often as they can be taken: each snapshot must hold exactly the units it flags.
    // Interrupt: the cancel flag goes up after 20 units and 4 checkpoints (in-flight units still
    // finish). How many units pass between two snapshots depends on scheduling (the render's checkpoint
    // thread copies the film between units and writes it while the workers go on; the next copy waits
    // for that write), so the test waits for the snapshots it checks instead of hoping for them: until
    // there are 4, each unit's progress call gives that thread a millisecond (these units take ~0.1 ms:
    // the 96 of them could all finish before it was scheduled). On a loaded machine every unit can still
    // finish before the flag goes up: such a run interrupted nothing and is made again, up to 5 times.
    let mut attempt = 0;
    let (snaps, part, completed, st) = loop {
        attempt += 1;
        let snaps: Mutex<Vec<(Film, Vec<bool>)>> = Mutex::new(Vec::new());
        let keep = |f: &Film, c: &[bool]| snaps.lock().unwrap().push((f.clone(), c.to_vec()));
        let cancel = AtomicBool::new(false);
        let stop = |d: usize, _: usize| {
            let taken = snaps.lock().unwrap().len();
            if d >= 20 && taken >= 4 {
                cancel.store(true, Ordering::Relaxed);
            } else if taken < 4 {
                std::thread::sleep(Duration::from_millis(1));
            }
        };
        let mut j = job(&scene);
        j.cancel = Some(&cancel);
        j.progress = Some(&stop);
        j.checkpoint = Some(Checkpoint { every: Duration::ZERO, write: &keep, failed: None, ended: None });
        let (part, completed, st) = render_resumable(&j, Film::new(W, H), vec![false; n]);
        if !st.completed || attempt == 5 {
            break (snaps.into_inner().unwrap(), part, completed, st);
        }
    };
    let done = completed.iter().filter(|&&c| c).count();
    assert!(!st.completed && (20..n).contains(&done), "{done} of {n} units done ({attempt} attempts)");
    assert_eq!(part.total_samples(), samples_of_units(&scene, &completed));
    assert!(part != full);

    // Through the file format, then resume.
    let header = FilmHeader {
        width: W,
        height: H,
        spp: SPP,
        samples: 0..SPP,
        tile: TILE,
        scene_hash: scene.hash,
        seed: 7,
        profile: profile_record(&profile()),
        completed,
        build: 0x5eed,
    };
    let back = decode(&encode(&header, &part)).unwrap();
    assert_eq!(back.header, header);
    let (resumed, flags, st) = render_resumable(&job(&scene), back.film, back.header.completed);
    assert!(st.completed && flags.iter().all(|&c| c));
    assert!(resumed == full, "resumed render differs from the uninterrupted one");

    assert!(snaps.len() >= 4, "only {} checkpoints", snaps.len());
    for (k, (f, c)) in snaps.iter().enumerate() {
        assert_eq!(f.total_samples(), samples_of_units(&scene, c), "checkpoint {k} is inconsistent");
    }
    for (f, c) in snaps.iter().step_by((snaps.len() / 4).max(1)) {
        let (r, _, _) = render_resumable(&job(&scene), f.clone(), c.clone());
        assert!(r == full, "resume from a checkpoint differs from the uninterrupted render");
    }
}

// ---- command line ----

fn strata() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_strata"));
    c.current_dir(env!("CARGO_MANIFEST_DIR"));
    c
}

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("strata-farm-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn write_scene(d: &Path) -> PathBuf {
    let p = d.join("scene.toml");
    std::fs::write(&p, scene_text()).unwrap();
    p
}

/// `strata render SCENE --profile final --spp 6 --light-samples 2 --seed 7 --tile 4 -q ARGS`; a flag
/// given in ARGS replaces the default one.
fn render(scene: &Path, args: &[&str]) -> Output {
    let mut a = vec!["render", s(scene), "-q"];
    for (k, v) in [("--profile", "final"), ("--spp", "6"), ("--light-samples", "2"), ("--seed", "7"), ("--tile", "4")] {
        if !args.contains(&k) {
            a.extend([k, v]);
        }
    }
    a.extend_from_slice(args);
    strata().args(&a).output().unwrap()
}

fn ok(o: Output) -> Output {
    assert!(o.status.success(), "exit {:?}: {}", o.status.code(), String::from_utf8_lossy(&o.stderr));
    o
}

fn bytes(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// Exit 2 with a message containing every `needle`.
fn refused(o: &Output, needles: &[&str]) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    for n in needles {
        assert!(err.contains(n), "expected `{n}` in: {err}");
    }
}

/// A render refuses to replace a complete film of itself (`--film`, also beside `--resume`): a finished
/// command run again and stopped with Ctrl-C replaced the complete film, and the image, with a partial
/// one. The film is left as it was; `merge --film` still replaces one (a merge gives the same film).
#[test]
fn cli_a_complete_film_of_the_same_render_is_not_replaced() {
    let d = dir("complete");
    let sc = write_scene(&d);
    let p = |n: &str| d.join(n);
    ok(render(&sc, &["-o", s(&p("a.exr")), "--film", s(&p("a.film"))]));
    let (film, image) = (bytes(&p("a.film")), bytes(&p("a.exr")));
    let o = render(&sc, &["-o", s(&p("a.exr")), "--film", s(&p("a.film"))]);
    let needle = format!("{}: a complete film of this same render is there, which --film would replace", p("a.film").display());
    refused(&o, &[&needle, &format!("strata merge {} -o IMAGE", p("a.film").display())]);
    ok(render(&sc, &["-o", s(&p("b.exr")), "--film", s(&p("b.film")), "--samples", "0..3"]));
    refused(&render(&sc, &["-o", s(&p("a.exr")), "--resume", s(&p("b.film")), "--film", s(&p("a.film"))]), &[&needle]);
    assert!(bytes(&p("a.film")) == film && bytes(&p("a.exr")) == image);
    // Another render's complete film is still replaced, with a warning.
    let o = ok(render(&sc, &["-o", s(&p("a.exr")), "--film", s(&p("a.film")), "--seed", "8"]));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--film replaces a complete film of another render"));
    ok(strata().args(["merge", s(&p("a.film")), "-o", s(&p("m.exr")), "--film", s(&p("m.film"))]).output().unwrap());
    ok(strata().args(["merge", s(&p("a.film")), "-o", s(&p("m.exr")), "--film", s(&p("m.film"))]).output().unwrap());
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn cli_merge_of_ranges_is_bit_identical_to_one_render() {
    let d = dir("merge");
    let sc = write_scene(&d);
    let p = |n: &str| d.join(n);
    ok(render(&sc, &["-o", s(&p("full.exr")), "--film", s(&p("full.film")), "--threads", "2"]));
    ok(render(&sc, &["-o", s(&p("a.exr")), "--film", s(&p("a.film")), "--samples", "0..1", "--threads", "1"]));
    ok(render(&sc, &["-o", s(&p("b.exr")), "--film", s(&p("b.film")), "--samples", "1..4", "--threads", "2"]));
    ok(render(&sc, &["-o", s(&p("c.exr")), "--film", s(&p("c.film")), "--samples", "4..6"]));
    // Given out of order on purpose.
    let o = ok(strata()
        .args(["merge", s(&p("c.film")), s(&p("a.film")), s(&p("b.film")), "-o", s(&p("m.exr")), "--film", s(&p("m.film"))])
        .output()
        .unwrap());
    assert!(String::from_utf8_lossy(&o.stdout).contains("samples 0..6"));
    assert!(bytes(&p("m.exr")) == bytes(&p("full.exr")), "merged EXR differs from the one-process EXR");
    assert!(bytes(&p("m.film")) == bytes(&p("full.film")), "merged film differs from the one-process film");
    assert!(bytes(&p("a.exr")) != bytes(&p("full.exr")));

    let st = ok(strata().args(["merge", "--status", s(&p("a.film")), s(&p("c.film"))]).output().unwrap());
    let out = String::from_utf8_lossy(&st.stdout);
    assert!(out.contains("present (complete): 0..1, 4..6") && out.contains("missing: 1..4"), "{out}");
    assert!(out.contains("complete samples: 3 of 6"), "{out}");
    // Overlapping films: each sample counted once (0..4 and 1..6 cover 6 of 6), the overlap named.
    ok(render(&sc, &["-o", s(&p("d.exr")), "--film", s(&p("d.film")), "--samples", "0..4"]));
    ok(render(&sc, &["-o", s(&p("e.exr")), "--film", s(&p("e.film")), "--samples", "1..6"]));
    let st = ok(strata().args(["merge", "--status", s(&p("d.film")), s(&p("e.film"))]).output().unwrap());
    let out = String::from_utf8_lossy(&st.stdout);
    assert!(out.contains("complete samples: 6 of 6") && !out.contains("ready to merge") && out.contains("overlap:"), "{out}");
    let _ = std::fs::remove_dir_all(&d);
}

/// Write at `path` the partial film (30 or so of its work units) of `render(scene, ...)`'s render, made by
/// a cancelled library render (deterministic, unlike a signal); returns its header.
fn write_partial_film(sc: &Path, path: &Path) -> FilmHeader {
    let scene = parse_scene(sc, &scene_text()).unwrap();
    let cancel = AtomicBool::new(false);
    let stop = |done: usize, _: usize| {
        if done >= 30 {
            cancel.store(true, Ordering::Relaxed);
        }
    };
    let mut j = job(&scene);
    j.cancel = Some(&cancel);
    j.progress = Some(&stop);
    let n = work_units(W, H, TILE, 0..SPP).len();
    let (film, completed, st) = render_resumable(&j, Film::new(W, H), vec![false; n]);
    assert!(!st.completed);
    let header = FilmHeader {
        width: W,
        height: H,
        spp: SPP,
        samples: 0..SPP,
        tile: TILE,
        scene_hash: scene.hash,
        seed: 7,
        profile: profile_record(&profile()),
        completed,
        // (Unknown: this test's own executable is not the strata the commands below run.)
        build: 0,
    };
    strata::film::file::write_film(path, &header, &film).unwrap();
    header
}

/// Running an interrupted command again finds the partial film its interrupt wrote under a numbered
/// name (`g.2.film`, where `g.film` was taken): refused, naming it and `--resume` (it was not: the
/// rerun started from 0, and an interrupt of it wrote `g.3.film`).
#[test]
fn cli_rerun_finds_the_partial_film_under_its_numbered_name() {
    let d = dir("numbered");
    let sc = write_scene(&d);
    let p = |n: &str| d.join(n);
    std::fs::write(p("g.film"), b"someone else's file").unwrap();
    write_partial_film(&sc, &p("g.2.film"));
    let film = bytes(&p("g.2.film"));
    let o = render(&sc, &["-o", s(&p("g.exr"))]);
    let name = p("g.2.film").display().to_string();
    refused(&o, &[&format!("{name}: a partial film of this same render"), &format!("continue it with --resume {name}")]);
    assert!(!p("g.exr").exists() && !p("g.3.film").exists());
    // Two of them: the one holding more work is offered, the other named.
    std::fs::write(p("g.7.film"), &film).unwrap();
    let mut less = decode(&film).unwrap();
    let first = less.header.completed.iter().position(|&c| c).unwrap();
    less.header.completed[first] = false;
    strata::film::file::write_film(&p("g.2.film"), &less.header, &Film::new(W, H)).unwrap();
    let o = render(&sc, &["-o", s(&p("g.exr"))]);
    let seven = p("g.7.film").display().to_string();
    refused(&o, &[&format!("--resume {seven}"), &format!("more partial films of this render: {name}")]);
    assert!(bytes(&p("g.7.film")) == film && bytes(&p("g.film")) == b"someone else's file");
    let _ = std::fs::remove_dir_all(&d);
}

/// No command replaces a partial film of its own render: `--resume A --film B` and `merge ... --film B`
/// refuse a partial B (they replaced it without a word), naming how to continue it; nothing is written.
#[test]
fn cli_film_never_replaces_a_partial_film_of_its_render() {
    let d = dir("partial-b");
    let sc = write_scene(&d);
    let p = |n: &str| d.join(n);
    write_partial_film(&sc, &p("a.film"));
    std::fs::copy(p("a.film"), p("b.film")).unwrap();
    let b = bytes(&p("b.film"));
    let name = p("b.film").display().to_string();
    let o = render(&sc, &["-o", s(&p("r.exr")), "--resume", s(&p("a.film")), "--film", s(&p("b.film"))]);
    refused(
        &o,
        &[&format!("{name}: a partial film of this same render"), "which --film would replace", &format!("--resume {name} instead")],
    );
    ok(render(&sc, &["-o", s(&p("x.exr")), "--film", s(&p("x.film")), "--samples", "0..3"]));
    ok(render(&sc, &["-o", s(&p("y.exr")), "--film", s(&p("y.film")), "--samples", "3..6"]));
    let o = strata().args(["merge", s(&p("x.film")), s(&p("y.film")), "-o", s(&p("m.exr")), "--film", s(&p("b.film"))]).output().unwrap();
    refused(&o, &[&format!("{name}: a partial film of this same render"), &format!("--resume {name}`")]);
    assert!(bytes(&p("b.film")) == b && !p("r.exr").exists() && !p("m.exr").exists());
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn cli_resume_of_an_interrupted_render_is_bit_identical() {
    let d = dir("resume");
    let sc = write_scene(&d);
    let p = |n: &str| d.join(n);
    ok(render(&sc, &["-o", s(&p("full.exr")), "--film", s(&p("full.film"))]));

    // A partial film made by a cancelled library render (deterministic, unlike a signal).
    let mut header = write_partial_film(&sc, &p("part.film"));
    // Stamped as the strata binary stamps it (a film of unknown build resumes into one of unknown build,
    // which would differ from full.film in its build field alone).
    header.build = decode(&bytes(&p("full.film"))).unwrap().header.build;
    let partial = decode(&bytes(&p("part.film"))).unwrap();
    strata::film::file::write_film(&p("part.film"), &header, &partial.film).unwrap();
    // Its samples are neither missing nor complete, and the status says which.
    let st = ok(strata().args(["merge", "--status", s(&p("part.film"))]).output().unwrap());
    let out = String::from_utf8_lossy(&st.stdout);
    assert!(out.contains("missing: none") && out.contains("only in partial films: 0..6"), "{out}");
    assert!(out.contains("complete samples: 0 of 6"), "{out}");

    // Refusals first: each names what differs, exits 2 and writes nothing.
    let other = d.join("other.toml");
    std::fs::write(&other, scene_text().replace("background = [0.05, 0.06, 0.09]", "background = [0.05, 0.06, 0.1]")).unwrap();
    let no = p("no.exr");
    let part = p("part.film");
    let resume = ["-o", s(&no), "--resume", s(&part)];
    refused(&render(&other, &resume), &["part.film", "cannot resume", "scene"]);
    refused(&render(&sc, &[&resume[..], &["--seed", "8"]].concat()), &["seed: film 7, this render 8"]);
    refused(&render(&sc, &[&resume[..], &["--set", "max_depth=5"]].concat()), &["profile", "max_depth film 8, this render 5"]);
    refused(&render(&sc, &[&resume[..], &["--samples", "0..3"]].concat()), &["sample range: film 0..6, this render 0..3"]);
    refused(&render(&sc, &[&resume[..], &["--tile", "8"]].concat()), &["tile: film 4, this render 8"]);
    // Nor does --film replace it from another render (a trial lost 6% of a `final` render so): refused,
    // naming what differs.
    refused(&render(&other, &["-o", s(&no), "--film", s(&part)]), &["part.film", "a partial film of another render", "scene"]);
    refused(&render(&sc, &["-o", s(&no), "--film", s(&part), "--samples", "0..3"]), &["a partial film of another render", "sample range"]);
    assert!(!no.exists());
    assert!(decode(&bytes(&p("part.film"))).unwrap().header == header, "a refused resume touched the film");

    ok(render(&sc, &["-o", s(&p("resumed.exr")), "--resume", s(&p("part.film"))]));
    assert!(bytes(&p("resumed.exr")) == bytes(&p("full.exr")), "resumed EXR differs");
    // The resumed film was brought up to date in place and is now the complete film.
    assert!(bytes(&p("part.film")) == bytes(&p("full.film")), "resumed film differs");
    // A complete film of another render is replaced where --film names it, with a warning.
    let o = ok(render(&other, &["-o", s(&no), "--film", s(&part)]));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("part.film: --film replaces a complete film of another render (scene"), "{err}");
    assert!(bytes(&p("part.film")) != bytes(&p("full.film")));
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn cli_ctrl_c_writes_a_film_that_resumes_exactly() {
    let d = dir("sigint");
    let sc = d.join("big.toml");
    // ~0.8 s of work on one thread (session 12): long enough to be interrupted after the first
    // checkpoint (at 64 spp it had become 0.2 s, and a render that finished before the signal
    // arrived failed the test now and then).
    std::fs::write(&sc, scene_text().replace(&format!("width = {W}"), "width = 160").replace(&format!("height = {H}"), "height = 100"))
        .unwrap();
    let p = |n: &str| d.join(n);
    let args = |out: &Path| {
        let mut a: Vec<String> =
            ["render", s(&sc), "--profile", "final", "--spp", "256", "--threads", "1", "--seed", "3", "-q", "-o", s(out)]
                .iter()
                .map(|x| x.to_string())
                .collect();
        a.extend(["--film", s(&p("run.film")), "--checkpoint-every", "0.05"].iter().map(|x| x.to_string()));
        a
    };
    let mut child = strata().args(args(&p("int.exr"))).spawn().unwrap();
    // Wait for the first checkpoint: the render is under way.
    let t0 = std::time::Instant::now();
    while !p("run.film").exists() {
        assert!(t0.elapsed() < Duration::from_secs(30), "no checkpoint written");
        std::thread::sleep(Duration::from_millis(10));
    }
    let kill = Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert!(kill.success());
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(130), "the render was not interrupted (finished too early?)");
    let saved = decode(&bytes(&p("run.film"))).unwrap();
    assert!(!saved.header.is_complete() && saved.header.units_done() > 0);

    let mut resume = args(&p("resumed.exr"));
    resume.extend(["--resume".to_string(), s(&p("run.film")).to_string()]);
    assert!(strata().args(&resume).status().unwrap().success());

    let mut plain: Vec<String> = args(&p("plain.exr"));
    plain.truncate(plain.len() - 4);
    plain.extend(["--film".to_string(), s(&p("plain.film")).to_string()]);
    assert!(strata().args(&plain).status().unwrap().success());
    assert!(bytes(&p("resumed.exr")) == bytes(&p("plain.exr")), "resumed EXR differs from the uninterrupted one");
    assert!(bytes(&p("run.film")) == bytes(&p("plain.film")), "resumed film differs from the uninterrupted one");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn cli_merge_refuses_mismatched_films_and_writes_nothing() {
    let d = dir("refuse");
    let sc = write_scene(&d);
    let p = |n: &str| d.join(n);
    let other = d.join("other.toml");
    std::fs::write(&other, scene_text().replace("fov = 38.0", "fov = 39.0")).unwrap();
    ok(render(&sc, &["-o", s(&p("a.exr")), "--film", s(&p("a.film")), "--samples", "0..2"]));
    ok(render(&sc, &["-o", s(&p("b.exr")), "--film", s(&p("b.film")), "--samples", "2..6"]));
    ok(render(&sc, &["-o", s(&p("c.exr")), "--film", s(&p("c.film")), "--samples", "3..6"]));
    ok(render(&sc, &["-o", s(&p("e.exr")), "--film", s(&p("e.film")), "--samples", "4..6"]));
    ok(render(&other, &["-o", s(&p("x.exr")), "--film", s(&p("scene.film")), "--samples", "2..6"]));
    ok(render(&sc, &["-o", s(&p("x.exr")), "--film", s(&p("seed.film")), "--samples", "2..6", "--seed", "8"]));
    ok(render(&sc, &["-o", s(&p("x.exr")), "--film", s(&p("prof.film")), "--samples", "2..6", "--light-samples", "3"]));
    let good = bytes(&p("b.film"));
    let mut flipped = good.clone();
    flipped[good.len() / 2] ^= 0x04;
    std::fs::write(p("flipped.film"), flipped).unwrap();
    std::fs::write(p("short.film"), &good[..good.len() - 100]).unwrap();

    // An existing output must survive a refused merge untouched; a new one must not appear.
    std::fs::write(p("keep.exr"), b"previous image").unwrap();
    std::fs::write(p("keep.film"), b"previous film").unwrap();
    let cases: [(&str, &[&str]); 7] = [
        ("scene.film", &["a.film", "scene.film", "different renders", "scene:"]),
        ("seed.film", &["different renders", "seed: ", "7", "8"]),
        ("prof.film", &["different renders", "profile: light_samples", "2", "3"]),
        ("c.film", &["overlap", "b.film 2..6", "c.film 3..6", "share samples 3..6"]),
        ("e.film", &["gap: samples 2..4 are in no film", "a.film 0..2", "e.film 4..6"]),
        ("flipped.film", &["flipped.film", "checksum"]),
        ("short.film", &["short.film", "truncated"]),
    ];
    for (second, needles) in cases {
        let mut films = vec![s(&p("a.film")).to_string(), s(&p(second)).to_string()];
        if second == "c.film" {
            films.insert(1, s(&p("b.film")).to_string());
        }
        for (out, film) in [("new.exr", "new.film"), ("keep.exr", "keep.film")] {
            let o = strata().arg("merge").args(&films).args(["-o", s(&p(out)), "--film", s(&p(film))]).output().unwrap();
            refused(&o, needles);
        }
        assert!(!p("new.exr").exists() && !p("new.film").exists(), "{second}: a refused merge wrote output");
        assert_eq!(bytes(&p("keep.exr")), b"previous image", "{second}: a refused merge overwrote the image");
        assert_eq!(bytes(&p("keep.film")), b"previous film", "{second}: a refused merge overwrote the film");
    }
    // --allow-gaps merges a gap into an image, but never into a film (it records one contiguous range).
    ok(strata().args(["merge", s(&p("a.film")), s(&p("e.film")), "-o", s(&p("gaps.exr")), "--allow-gaps"]).output().unwrap());
    refused(
        &strata()
            .args(["merge", s(&p("a.film")), s(&p("e.film")), "-o", s(&p("g.exr")), "--allow-gaps", "--film", s(&p("g.film"))])
            .output()
            .unwrap(),
        &["cannot write a merged film"],
    );
    // A missing first or last range is refused as a gap between films is (a 4-part split missing its
    // last part merged `samples 0..192 of spp 256`, exit 0): the image would not be the full render.
    for (film, needles) in [
        ("a.film", ["missing: samples 2..6 of spp 6 are in no film (after", "a.film 0..2)"]),
        ("b.film", ["missing: samples 0..2 of spp 6 are in no film (before", "b.film 2..6)"]),
    ] {
        let o = strata().args(["merge", s(&p(film)), "-o", s(&p("new.exr")), "--film", s(&p("new.film"))]).output().unwrap();
        refused(&o, &[needles[0], needles[1], "not be the full render", "use --allow-gaps to merge anyway;"]);
        assert!(!p("new.exr").exists() && !p("new.film").exists(), "{film}: a refused merge wrote output");
    }
    // --allow-gaps merges such a range alone, with a warning, and (complete and contiguous) into the film
    // of that range: here b.film's own bytes.
    let o =
        ok(strata().args(["merge", s(&p("b.film")), "--allow-gaps", "-o", s(&p("b2.exr")), "--film", s(&p("b2.film"))]).output().unwrap());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("warning: missing: samples 0..2 of spp 6") && err.contains("not the full render"), "{err}");
    assert!(bytes(&p("b2.film")) == good, "the film of b.film's range alone differs from b.film");
    // --status on a damaged film names it and exits 2.
    let st = strata().args(["merge", "--status", s(&p("a.film")), s(&p("short.film"))]).output().unwrap();
    assert_eq!(st.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&st.stdout).contains("short.film  unreadable"));
    let _ = std::fs::remove_dir_all(&d);
}

/// A film whose pixel no render gives, its checksum made to match (the reviewer's crafted films:
/// sums of 1.5 2^126 in both films, a count of 2^64 - 1, a count of 0 under sums; each merged exit 0
/// into a wrong image, a mean of -4.95e27, and a film with a valid checksum), is refused by merge, by
/// `merge --status` and by resume, exit 2, naming the film, the pixel and what is wrong, and nothing is
/// written; the films unaltered still merge into the one-process render's film and image, byte for byte.
#[test]
fn cli_films_of_impossible_pixels_are_refused() {
    use strata::film::checksum::xxh64;
    use strata::film::file::{header_bytes, read_film, PIXEL_BYTES};
    let d = dir("pixels");
    let sc = write_scene(&d);
    let p = |n: &str| d.join(n);
    ok(render(&sc, &["-o", s(&p("full.exr")), "--film", s(&p("full.film"))]));
    ok(render(&sc, &["-o", s(&p("a.exr")), "--film", s(&p("a.film")), "--samples", "0..3"]));
    ok(render(&sc, &["-o", s(&p("b.exr")), "--film", s(&p("b.film")), "--samples", "3..6"]));
    // Pixel (x, y) of film `src` changed by `f` (sums r g b, sums of squares r g b, count), written
    // at `dst` with its checksum made to match again (the film module's own xxh64).
    let craft = |src: &str, dst: &str, (x, y): (usize, usize), f: &dyn Fn(&mut [i128; 6], &mut u64)| {
        let b = bytes(&p(src));
        let head = header_bytes(&read_film(&p(src)).unwrap().header).len();
        let at = head + (y * W as usize + x) * PIXEL_BYTES;
        let mut b = b[..b.len() - 8].to_vec();
        let mut v: [i128; 6] = std::array::from_fn(|j| i128::from_le_bytes(b[at + 16 * j..at + 16 * j + 16].try_into().unwrap()));
        let mut count = u64::from_le_bytes(b[at + 96..at + 104].try_into().unwrap());
        assert_eq!(count, 3, "{src} ({x}, {y})");
        f(&mut v, &mut count);
        for (j, v) in v.iter().enumerate() {
            b[at + 16 * j..at + 16 * j + 16].copy_from_slice(&v.to_le_bytes());
        }
        b[at + 96..at + 104].copy_from_slice(&count.to_le_bytes());
        let sum = xxh64(&b);
        b.extend_from_slice(&sum.to_le_bytes());
        std::fs::write(p(dst), b).unwrap();
    };
    craft("a.film", "a_big.film", (0, 0), &|v, _| v[..3].fill(3 << 125));
    craft("b.film", "b_big.film", (0, 0), &|v, _| v[..3].fill(3 << 125));
    craft("a.film", "a_countmax.film", (5, 2), &|_, n| *n = u64::MAX);
    craft("b.film", "b_countmax.film", (5, 2), &|_, n| *n = u64::MAX);
    craft("a.film", "a_count0.film", (47, 29), &|v, n| {
        assert!(v[0] > 0);
        *n = 0
    });
    craft("b.film", "b_count4.film", (10, 20), &|_, n| *n = 4);
    let sum = "beyond what 3 samples can give (|sum| <= 3 x (2^63 - 2^39) = 27670114461296885760)";
    let cases: [(&str, &str, String); 4] = [
        ("a_big.film", "b_big.film", format!("a_big.film: inconsistent pixel (0, 0): red sum 127605887595351923798765477786913079296 (in units of 2^-32) is {sum}")),
        ("a_countmax.film", "b_countmax.film", "a_countmax.film: inconsistent pixel (5, 2): 18446744073709551615 samples, but the film's completed work units hold 3 samples for it".into()),
        ("a_count0.film", "b.film", "a_count0.film: inconsistent pixel (47, 29): red sum".into()),
        ("a.film", "b_count4.film", "b_count4.film: inconsistent pixel (10, 20): 4 samples, but the film's completed work units hold 3 samples for it".into()),
    ];
    for (a, b, want) in &cases {
        let o = strata().args(["merge", s(&p(a)), s(&p(b)), "-o", s(&p("m.exr")), "--film", s(&p("m.film"))]).output().unwrap();
        refused(&o, &[want]);
        assert!(!p("m.exr").exists() && !p("m.film").exists(), "{a} + {b}: a refused merge wrote output");
        let st = strata().args(["merge", "--status", s(&p(a)), s(&p(b))]).output().unwrap();
        assert_eq!(st.status.code(), Some(2));
        let out = String::from_utf8_lossy(&st.stdout);
        let bad = if want.starts_with(a) { a } else { b };
        assert!(out.contains(&format!("{bad}  unreadable: ")) && out.contains("inconsistent pixel ("), "{out}");
    }
    let o = String::from_utf8_lossy(
        &strata().args(["merge", s(&p("a_count0.film")), s(&p("b.film")), "-o", s(&p("m.exr"))]).output().unwrap().stderr,
    )
    .to_string();
    assert!(o.contains("(in units of 2^-32) with no samples (a pixel of no samples sums to 0)"), "{o}");
    // Resume refuses them the same way, and leaves the film as it was.
    for (film, range) in [("a_big.film", "0..3"), ("b_count4.film", "3..6")] {
        let before = bytes(&p(film));
        let o = render(&sc, &["-o", s(&p("r.exr")), "--resume", s(&p(film)), "--samples", range]);
        refused(&o, &[&format!("--resume {}: inconsistent pixel (", p(film).display())]);
        assert!(bytes(&p(film)) == before && !p("r.exr").exists(), "{film}");
    }
    // The films themselves merge into the one-process render, byte for byte.
    ok(strata().args(["merge", s(&p("a.film")), s(&p("b.film")), "-o", s(&p("m.exr")), "--film", s(&p("m.film"))]).output().unwrap());
    assert!(bytes(&p("m.film")) == bytes(&p("full.film")) && bytes(&p("m.exr")) == bytes(&p("full.exr")));
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn local_split_script_matches_one_render() {
    if Command::new("xargs").arg("--version").output().is_err() {
        panic!("xargs is required by scripts/local_split.sh");
    }
    let d = dir("split");
    let sc = write_scene(&d);
    let p = |n: &str| d.join(n);
    ok(render(&sc, &["-o", s(&p("full.exr"))]));
    let o = Command::new("bash")
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("STRATA", env!("CARGO_BIN_EXE_strata"))
        .env("WORKDIR", p("parts"))
        .args(["scripts/local_split.sh", "2", "6", s(&p("split.exr")), s(&sc)])
        .args(["--profile", "final", "--light-samples", "2", "--seed", "7", "--tile", "4"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}\n{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    assert!(bytes(&p("split.exr")) == bytes(&p("full.exr")), "2-process split differs from one render");
    assert!(p("parts/part_0.film").exists() && p("parts/part_1.film").exists());
    // Run again with another PARTS: its part films hold other sample ranges. Refused at once, saying to
    // run it with the PARTS it was started with (strata's own advice, `pass --samples 0..3`, is of no
    // use inside the script).
    let o = Command::new("bash")
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("STRATA", env!("CARGO_BIN_EXE_strata"))
        .env("WORKDIR", p("parts"))
        .args(["scripts/local_split.sh", "3", "6", s(&p("split3.exr")), s(&sc)])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("a split into 2 parts of 6 spp, not 3 of 6") && err.contains("PARTS 2 and SPP 6 as it was started"), "{err}");
    assert!(!err.contains("--samples") && !p("parts/part_2.film").exists(), "{err}");
    // PARALLEL=1 without GNU parallel says so, before anything runs (it said only "some parts failed").
    let bash = std::env::split_paths(&std::env::var_os("PATH").unwrap()).map(|d| d.join("bash")).find(|b| b.is_file()).unwrap();
    let empty = d.join("empty-path");
    std::fs::create_dir_all(&empty).unwrap();
    let o = Command::new(&bash)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("PATH", &empty)
        .env("PARALLEL", "1")
        .args(["scripts/local_split.sh", "2", "6", s(&p("par.exr")), s(&sc)])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("PARALLEL=1 but GNU parallel is not installed"), "{err}");
    let _ = std::fs::remove_dir_all(&d);
}

/// Ctrl-C (a SIGINT to the script's whole process group, as a terminal sends it) while the first of 3
/// parts runs one at a time (`JOBS=1`): that part writes its film, and no other part starts (xargs used
/// to start the next parts after the interrupt and render them to the end). The signal is sent once
/// part 0's log shows its first progress line, with 90% of its work left. The same for a SIGTERM to the
/// script alone (a scheduler's stop, `kill`), which reaches no part: the script used to die of it while
/// xargs went on, part 0 to its end and the others after it.
#[cfg(unix)]
#[test]
fn local_split_interrupt_starts_no_further_part() {
    split_interrupted_by(&["-INT", "--"], true, "split-int");
    split_interrupted_by(&["-TERM"], false, "split-term");
}

/// [`local_split_interrupt_starts_no_further_part`] with `kill ARGS PID` (`-PID`, the process group,
/// where `group`).
#[cfg(unix)]
fn split_interrupted_by(args: &[&str], group: bool, name: &str) {
    use std::os::unix::process::CommandExt;
    let d = dir(name);
    let sc = d.join("slow.toml");
    // Part 0 (samples 0..256 at 160 x 100, 1,120 work units) takes about a second on one thread.
    std::fs::write(&sc, scene_text().replace(&format!("width = {W}"), "width = 160").replace(&format!("height = {H}"), "height = 100"))
        .unwrap();
    let p = |n: &str| d.join(n);
    let child = Command::new("bash")
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("STRATA", env!("CARGO_BIN_EXE_strata"))
        .env("WORKDIR", p("parts"))
        .env("JOBS", "1")
        .env("THREADS", "1")
        .args(["scripts/local_split.sh", "3", "768", s(&p("split.exr")), s(&sc), "--profile", "final", "--seed", "7"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .process_group(0)
        .spawn()
        .unwrap();
    let t0 = std::time::Instant::now();
    while !std::fs::read_to_string(p("parts/part_0.log")).unwrap_or_default().contains("work units") {
        assert!(t0.elapsed() < Duration::from_secs(60), "part 0 shows no progress");
        std::thread::sleep(Duration::from_millis(5));
    }
    let target = if group { format!("-{}", child.id()) } else { child.id().to_string() };
    let kill = Command::new("kill").args(args).arg(&target).status().unwrap();
    assert!(kill.success());
    let o = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
    assert!(err.contains("part 0 (samples 0..256) interrupted: its film is kept"), "{err}");
    for (i, r) in [(1, "256..512"), (2, "512..768")] {
        assert!(err.contains(&format!("part {i} (samples {r}) not started: interrupted")), "{err}");
        assert!(!p(&format!("parts/part_{i}.film")).exists() && !p(&format!("parts/part_{i}.log")).exists(), "{err}");
    }
    assert!(err.contains("interrupted: the parts that ran wrote their films, and no part started after the interrupt"), "{err}");
    let saved = decode(&bytes(&p("parts/part_0.film"))).unwrap();
    assert!(!saved.header.is_complete() && saved.header.units_done() > 0);
    assert!(!p("split.exr").exists());
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn exr_bytes_depend_only_on_the_pixels() {
    // Many 64x64 blocks: exr compresses them in parallel, and the file must not record the finish order.
    let (w, h) = (300u32, 200u32);
    let rgb: Vec<glam::Vec3> = (0..w * h).map(|i| glam::Vec3::new((i % 97) as f32 / 7.0, (i % 13) as f32, (i / w) as f32 * 0.01)).collect();
    let d = dir("exr");
    let mut first = None;
    for k in 0..6 {
        let p = d.join(format!("{k}.exr"));
        strata::film::output::write_image(&p, w, h, &rgb).unwrap();
        let b = bytes(&p);
        match &first {
            None => {
                let (rw, rh, back) = strata::film::output::read_image(&p).unwrap();
                assert!((rw, rh) == (w, h) && back == rgb, "EXR does not read back exactly");
                first = Some(b);
            }
            Some(f) => assert!(*f == b, "write {k} of the same pixels gave different bytes"),
        }
    }
    let _ = std::fs::remove_dir_all(&d);
}

/// Films record the build that rendered them (the executable's hash): a film of another build (here one
/// whose build field is rewritten, as another executable would have written it) merges and resumes with
/// a warning naming it, and the merged film records no build; films of one build merge without a word
/// and keep it (a user trial merged films of two builds that render differently, silently).
#[test]
fn cli_films_of_other_builds_are_warned_of() {
    let d = dir("builds");
    let sc = write_scene(&d);
    let p = |n: &str| d.join(n);
    ok(render(&sc, &["-o", s(&p("a.exr")), "--film", s(&p("a.film")), "--samples", "0..3"]));
    ok(render(&sc, &["-o", s(&p("b.exr")), "--film", s(&p("b.film")), "--samples", "3..6"]));
    let merge = |out: &str, film: &str| {
        ok(strata().args(["merge", s(&p("a.film")), s(&p("b.film")), "-o", s(&p(out)), "--film", s(&p(film))]).output().unwrap())
    };
    let same = merge("m.exr", "m.film");
    assert!(!String::from_utf8_lossy(&same.stderr).contains("another build"), "{}", String::from_utf8_lossy(&same.stderr));
    let build = strata::film::file::read_film(&p("a.film")).unwrap().header.build;
    assert_ne!(build, 0);
    assert_eq!(strata::film::file::read_film(&p("m.film")).unwrap().header.build, build);
    // b.film as another build wrote it.
    let mut b = strata::film::file::read_film(&p("b.film")).unwrap();
    b.header.build ^= 1;
    strata::film::file::write_film(&p("b.film"), &b.header, &b.film).unwrap();
    let mixed = merge("x.exr", "x.film");
    let err = String::from_utf8_lossy(&mixed.stderr);
    assert!(err.contains("b.film was rendered by another build of strata than") && err.contains("a.film"), "{err}");
    assert_eq!(strata::film::file::read_film(&p("x.film")).unwrap().header.build, 0);
    // Resuming it (complete: nothing left to render) says so too.
    let resumed = ok(render(&sc, &["-o", s(&p("r.exr")), "--resume", s(&p("b.film")), "--samples", "3..6"]));
    let err = String::from_utf8_lossy(&resumed.stderr);
    assert!(err.contains("b.film was rendered by another build of strata than this one"), "{err}");
    // The film it writes back holds samples of two builds: it records none.
    assert_eq!(strata::film::file::read_film(&p("b.film")).unwrap().header.build, 0);
    // A film of unknown build (0: version 1, or of several builds) is not taken as this build's: merged
    // with one of this build, or resumed, the film written records none, and a note says why (a user
    // trial found them stamped with this build).
    ok(render(&sc, &["-o", s(&p("c.exr")), "--film", s(&p("c.film")), "--samples", "3..6"]));
    let mut u = strata::film::file::read_film(&p("a.film")).unwrap();
    u.header.build = 0;
    strata::film::file::write_film(&p("u.film"), &u.header, &u.film).unwrap();
    let merged =
        ok(strata().args(["merge", s(&p("u.film")), s(&p("c.film")), "-o", s(&p("uc.exr")), "--film", s(&p("uc.film"))]).output().unwrap());
    let err = String::from_utf8_lossy(&merged.stderr);
    assert!(err.contains("u.film records no build") && !err.contains("another build"), "{err}");
    assert_eq!(strata::film::file::read_film(&p("uc.film")).unwrap().header.build, 0);
    let resumed = ok(render(&sc, &["-o", s(&p("u.exr")), "--resume", s(&p("u.film")), "--samples", "0..3"]));
    let err = String::from_utf8_lossy(&resumed.stderr);
    assert!(err.contains("u.film records no build"), "{err}");
    assert_eq!(strata::film::file::read_film(&p("u.film")).unwrap().header.build, 0);
    // A copy of this build whose file is replaced (as a rebuild replaces it) or deleted while it renders
    // still stamps its film with its own build, which it reads when it writes the film (a user trial:
    // such films were stamped 0, unknown, when the stamp was read from the file at the path).
    #[cfg(target_os = "linux")]
    for delete in [false, true] {
        let exe = p("strata-copy");
        std::fs::copy(env!("CARGO_BIN_EXE_strata"), &exe).unwrap();
        let (film, image) = (p("c.film"), p("c.exr"));
        // (A render refuses to replace a complete film of itself, which the first round leaves.)
        let _ = std::fs::remove_file(&film);
        let mut cmd = Command::new(&exe);
        let args = ["render", s(&sc), "-q", "--spp", "6", "-o", s(&image), "--film", s(&film)];
        cmd.current_dir(env!("CARGO_MANIFEST_DIR")).args(args).stderr(std::process::Stdio::piped());
        // (`spawn` returns once the copy is executing. It can fail with ETXTBSY, 26, while a process
        // another test thread forks still holds the copy's write handle until its exec: retried.)
        let mut tries = 0;
        let child = loop {
            match cmd.spawn() {
                Err(e) if e.raw_os_error() == Some(26) && tries < 100 => {
                    tries += 1;
                    std::thread::sleep(std::time::Duration::from_millis(20));
                }
                r => break r.unwrap(),
            }
        };
        if delete {
            std::fs::remove_file(&exe).unwrap();
        } else {
            std::fs::write(p("other"), b"another build").unwrap();
            std::fs::rename(p("other"), &exe).unwrap();
        }
        ok(child.wait_with_output().unwrap());
        assert_eq!(strata::film::file::read_film(&film).unwrap().header.build, build, "deleted: {delete}");
        let _ = std::fs::remove_file(&exe);
    }
    let _ = std::fs::remove_dir_all(&d);
}

/// Memory for a film being resumed or merged that cannot be had is an error naming the film and the
/// bytes it needs (exit 1), not an abort (a user trial's 8K resume and merge aborted, exit 134, after
/// reading the whole file into memory). The film here is an 8192 x 4096 one (2 GiB in memory) whose
/// header is real and whose pixels are a hole in a sparse file: the header is read first, and the
/// memory is asked for before a pixel is read; the processes run with 1.5 GB of address space.
#[cfg(target_os = "linux")]
#[test]
fn cli_a_film_too_large_for_memory_is_an_error_not_an_abort() {
    use strata::film::file::{header_bytes, PIXEL_BYTES};
    let d = dir("nomem");
    let sc = write_scene(&d);
    let scene = parse_scene(&sc, &scene_text()).unwrap();
    let (w, h) = (8192u32, 4096u32);
    let n = strata::render::unit_count(w, h, TILE, 0..SPP);
    let fake = |path: &Path, complete: bool| {
        let header = FilmHeader {
            width: w,
            height: h,
            spp: SPP,
            samples: 0..SPP,
            tile: TILE,
            scene_hash: scene.hash,
            seed: 7,
            profile: profile_record(&profile()),
            completed: vec![complete; n],
            build: 0,
        };
        let head = header_bytes(&header);
        let f = std::fs::File::create(path).unwrap();
        std::io::Write::write_all(&mut &f, &head).unwrap();
        f.set_len((head.len() + w as usize * h as usize * PIXEL_BYTES + 8) as u64).unwrap();
    };
    let (part, whole) = (d.join("big.film"), d.join("whole.film"));
    fake(&part, false);
    fake(&whole, true);
    let limited = |args: &[&str]| {
        let mut c = Command::new("sh");
        c.current_dir(env!("CARGO_MANIFEST_DIR"));
        c.args(["-c", "ulimit -v 1500000 && exec \"$@\"", "sh", env!("CARGO_BIN_EXE_strata")]).args(args);
        c.output().unwrap()
    };
    let need = (w as u64 * h as u64 * 64).to_string();
    let o = limited(&[
        "render",
        s(&sc),
        "-q",
        "--profile",
        "final",
        "--spp",
        "6",
        "--light-samples",
        "2",
        "--seed",
        "7",
        "--tile",
        "4",
        "--size",
        "8192x4096",
        "-o",
        s(&d.join("big.exr")),
        "--resume",
        s(&part),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "resume: {err}");
    assert!(err.contains(&format!("--resume {}", part.display())) && err.contains(&need) && err.contains("not enough memory"), "{err}");
    let o = limited(&["merge", s(&whole), "-o", s(&d.join("m.exr"))]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "merge: {err}");
    assert!(err.contains(&whole.display().to_string()) && err.contains(&need) && err.contains("not enough memory"), "{err}");
    assert!(!d.join("m.exr").exists() && !d.join("big.exr").exists());
    let _ = std::fs::remove_dir_all(&d);
}
