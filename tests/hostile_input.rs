//! Hostile input (issue 7): the scene and profile loaders are fed seeded mutations of valid files
//! (truncations, bit flips, hostile values, wrong and unknown keys, duplicated and deleted lines,
//! non-UTF-8 bytes) and hand-made extremes (deep CSG nesting, cycles of named solids, huge images and
//! sample counts, huge files). The loader must never panic, never hang (each case runs in a worker with
//! a time bound), and answer every bad file with an error whose text names the file and the line (and
//! the field, when the line is a `key = value`). A file it accepts must render without a panic. The
//! protective limits are errors, not out-of-memory crashes; the CLI refuses an unusable output path
//! before rendering and never leaves a partial file (`hostile_input/cli.rs`).

#[path = "hostile_input/cli.rs"]
mod cli;
#[path = "hostile_input/mutate.rs"]
mod mutate;

use mutate::{mutate, Rng, HOSTILE_VALUES};
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::{Duration, Instant};
use strata::film::Film;
use strata::render::{render_into, RenderJob, WorkUnits};
use strata::scene::{load_scene, InputError, Profile};
use strata::wavefront::Settings;

/// A valid scene that uses every table, type and optional field of the format.
pub const BASE: &str = r#"# every feature of the format
[image]
width = 24
height = 16
background = [0.05, 0.05, 0.08]

[camera]
position = [0, 1.5, 6]
look_at = [0, 0.5, 0]
up = [0, 1, 0]
fov = 40
aperture = 0.02
focus_distance = 6
shutter = [0, 1]

[materials.floor]
type = "lambert"
checker = { a = [0.7, 0.7, 0.7], b = [0.2, 0.2, 0.2], scale = 0.5 }
[materials.red]
type = "lambert"
albedo = [0.8, 0.2, 0.1]
[materials.mirror]
type = "mirror"
tint = [0.9, 0.9, 0.9]
[materials.gold]
type = "glossy"
tint = [1, 0.8, 0.3]
roughness = 0.3
[materials.glass]
type = "dielectric"
ior = 1.5
absorption = [0.1, 0.05, 0.0]
[materials.prism]
type = "dielectric"
cauchy = [1.5, 0.004]
transmittance = [0.9, 0.95, 0.9]
transmittance_distance = 2
[materials.pane]
type = "dielectric"
abbe = [1.52, 59]
thin = true
fresnel = "schlick"
[materials.glow]
type = "emissive"
radiance = [2, 2, 2]

[solids.peg]
type = "cylinder"
center = [0, 0, 0]
radius = 0.2
height = 1
material = "gold"

[[shapes]]
type = "plane"
point = [0, 0, 0]
normal = [0, 1, 0]
material = "floor"

[[shapes]]
type = "sphere"
center = [-1.5, 0.5, 0]
radius = 0.5
material = "glass"
transform = { scale = [1, 1.5, 1], rotate = [0, 30, 0], translate = [0, 0.2, 0] }

[[shapes]]
type = "sphere"
center = [1.5, 0.4, 0.5]
radius = 0.4
material = "mirror"
motion = [0.2, 0, 0]

[[shapes]]
type = "box"
min = [-0.4, 0, -1.4]
max = [0.4, 0.8, -0.6]
material = "red"
transform = { rotate = [0, 20, 0] }

[[shapes]]
type = "quad"
origin = [-2, 0, -2]
u = [1, 0, 0]
v = [0, 1, 0]
material = "pane"

[[shapes]]
type = "disk"
center = [2, 0.01, -1]
normal = [0, 1, 0]
radius = 0.5
material = "prism"

[[shapes]]
type = "cone"
center = [0.8, 0.5, 1]
radius = 0.3
radius_top = 0.1
height = 1
material = "gold"

[[shapes]]
type = "torus"
center = [-0.8, 0.2, 1.2]
major_radius = 0.4
minor_radius = 0.1
material = "red"

[[shapes]]
type = "csg"
op = "difference"
material = "red"
children = [
  { type = "box", min = [-0.5, 0, -0.5], max = [0.5, 1, 0.5], transform = { translate = [2.5, 0, 1] } },
  { type = "csg", op = "intersection", children = [
    { type = "sphere", center = [2.5, 1, 1], radius = 0.4 },
    { type = "halfspace", point = [2.5, 1, 1], normal = [0, -1, 0] },
  ] },
  { use = "peg", transform = { translate = [2.5, 0.5, 1] } },
]

[[shapes]]
type = "group"
material = "gold"
children = [
  { type = "box", min = [-2.8, 0, 1], max = [-2.2, 0.6, 1.6] },
  { type = "sphere", center = [-2.5, 0.6, 1.3], radius = 0.2, hole = true },
]

[[shapes]]
use = "peg"
transform = { translate = [0, 0.5, 2] }

[[lights]]
type = "point"
position = [2, 5, 3]
intensity = [20, 20, 20]

[[lights]]
type = "quad"
origin = [-1, 3.5, -1]
u = [2, 0, 0]
v = [0, 0, 2]
radiance = [3, 3, 3]

[[lights]]
type = "disk"
center = [0, 3, 2]
normal = [0, -1, 0]
radius = 0.3
radiance = [2, 2, 2]

[[lights]]
type = "sphere"
center = [-2, 2.5, 1]
radius = 0.2
radiance = [4, 4, 4]
"#;

fn tmp_dir() -> PathBuf {
    let d = std::env::temp_dir().join(format!("strata-hostile-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// What the loader made of one file.
#[derive(Debug)]
enum Outcome {
    /// Accepted (and, if small enough, rendered without a panic).
    Accepted,
    Rejected(InputError),
    Panicked(String),
}

/// Scenes the fuzzer renders when it accepts them: small enough to take milliseconds.
const RENDER_PIXELS: u64 = 64 * 64;

/// Load `bytes` from a file (as `strata render` does) in a worker thread: a panic is caught, a hang
/// past the bound fails the test. An accepted scene of at most `RENDER_PIXELS` is rendered with one
/// sample per pixel, also inside the worker.
fn run_bounded(path: &Path, bytes: &[u8]) -> Outcome {
    std::fs::write(path, bytes).unwrap();
    let p = path.to_path_buf();
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let r = std::panic::catch_unwind(|| match load_scene(&p) {
            Ok(scene) => {
                if scene.width as u64 * scene.height as u64 <= RENDER_PIXELS {
                    let mut profile = Profile::builtin("preview");
                    profile.set("spp", "1").unwrap();
                    let mut job = RenderJob::new(&scene, Settings { profile, seed: 1 });
                    job.threads = 1;
                    render_into(&job, Film::new(scene.width, scene.height));
                }
                Outcome::Accepted
            }
            Err(e) => Outcome::Rejected(e),
        });
        let _ = tx.send(r.unwrap_or_else(|p| {
            Outcome::Panicked(p.downcast_ref::<String>().cloned().or(p.downcast_ref::<&str>().map(|s| s.to_string())).unwrap_or_default())
        }));
    });
    // Generous: a case takes milliseconds; this only catches a hang.
    rx.recv_timeout(Duration::from_secs(30)).unwrap_or_else(|_| panic!("{}: no answer within 30 s (hang)", path.display()))
}

/// The error must read `file:line:col: [field `f`: ]message` with a line inside the file (or just past
/// its end, for a truncated file), and name a field whenever that line is a `key = value`.
fn check_error(e: &InputError, path: &Path, bytes: &[u8], what: &str) {
    let shown = e.to_string();
    let text = String::from_utf8_lossy(bytes);
    let lines = text.split('\n').count();
    let ctx = || format!("{what}: {shown}\n--- file ---\n{}", text.chars().take(3000).collect::<String>());
    if e.line == 0 {
        // Not a position in the file: the file as a whole (too large to read).
        assert!(shown.starts_with(&format!("{}: ", path.display())) && e.message.starts_with("file is"), "{}", ctx());
        return;
    }
    assert!(shown.starts_with(&format!("{}:{}:{}: ", path.display(), e.line, e.column)), "{}", ctx());
    assert!(e.line >= 1 && e.line <= lines + 1, "line {} of {lines}: {}", e.line, ctx());
    let line = text.split('\n').nth(e.line - 1).unwrap_or("");
    let key = line.trim_start().split('=').next().unwrap_or("").trim();
    let key_value = line.contains('=') && !key.is_empty() && key.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-');
    if key_value && !e.message.starts_with("file is") {
        assert!(!e.field.is_empty(), "no field named for a key = value line `{line}`: {}", ctx());
        assert!(shown.contains(&format!("field `{}`", e.field)), "{}", ctx());
    }
}

/// The seeds: the feature scene above, every shipped scene.
fn seeds() -> Vec<(String, String)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut v = vec![("base".to_string(), BASE.to_string())];
    for dir in ["scenes", "scenes/shapes"] {
        let mut files: Vec<_> = std::fs::read_dir(root.join(dir)).unwrap().map(|e| e.unwrap().path()).collect();
        files.sort();
        for f in files.into_iter().filter(|f| f.extension().is_some_and(|e| e == "toml")) {
            let text = std::fs::read_to_string(&f).unwrap();
            // The 1000-sphere bench scene is long; its first ~200 lines (up to a whole shape) carry every
            // table it has.
            let text = if text.len() > 20_000 {
                let head: Vec<&str> = text.lines().take(200).collect();
                let cut = head.iter().rposition(|l| *l == "[[shapes]]").unwrap();
                head[..cut].join("\n")
            } else {
                text
            };
            v.push((f.file_name().unwrap().to_string_lossy().into_owned(), text));
        }
    }
    v
}

#[test]
fn seeds_are_valid() {
    let dir = tmp_dir();
    for (name, text) in seeds() {
        let path = dir.join(format!("seed-{name}"));
        match run_bounded(&path, text.as_bytes()) {
            Outcome::Accepted => {}
            o => panic!("seed {name}: {o:?}"),
        }
    }
}

/// 400 seeded mutations of each seed (the base scene and every `.toml` of `scenes/` and `scenes/shapes/`:
/// 23 seeds, 9,200 files, when this was written).
#[test]
fn mutated_scenes_never_panic_and_errors_are_located() {
    let dir = tmp_dir();
    let t0 = Instant::now();
    let (mut accepted, mut rejected) = (0, 0);
    let mut slowest = Duration::ZERO;
    for (k, (name, text)) in seeds().into_iter().enumerate() {
        let mut rng = Rng(0x5eed_0000 + k as u64);
        for i in 0..400 {
            let (bytes, what) = mutate(&mut rng, &text);
            let path = dir.join(format!("mutant-{name}-{i}.toml"));
            let t = Instant::now();
            match run_bounded(&path, &bytes) {
                Outcome::Accepted => accepted += 1,
                Outcome::Rejected(e) => {
                    check_error(&e, &path, &bytes, &format!("{name} #{i} ({what})"));
                    rejected += 1;
                }
                Outcome::Panicked(m) => panic!("{name} #{i} ({what}) panicked: {m}\n{}", String::from_utf8_lossy(&bytes)),
            }
            slowest = slowest.max(t.elapsed());
            let _ = std::fs::remove_file(&path);
        }
    }
    eprintln!("mutants: {accepted} accepted (and rendered when small), {rejected} rejected; slowest {slowest:?}; total {:?}", t0.elapsed());
    assert!(rejected > 1000 && accepted > 100);
}

/// Every `key = value` line of the feature scene, with every hostile value in turn.
#[test]
fn every_field_with_every_hostile_value() {
    let dir = tmp_dir();
    let lines: Vec<&str> = BASE.lines().collect();
    let (mut accepted, mut rejected) = (0, 0);
    for (i, line) in lines.iter().enumerate() {
        let Some((key, _)) = line.split_once(" = ") else { continue };
        for v in HOSTILE_VALUES {
            let mut l = lines.clone();
            let new = format!("{key} = {v}");
            l[i] = &new;
            let bytes = l.join("\n").into_bytes();
            let path = dir.join(format!("value-{i}.toml"));
            match run_bounded(&path, &bytes) {
                Outcome::Accepted => accepted += 1,
                Outcome::Rejected(e) => {
                    check_error(&e, &path, &bytes, &format!("line {}: {new}", i + 1));
                    rejected += 1;
                }
                Outcome::Panicked(m) => panic!("line {}: `{new}` panicked: {m}", i + 1),
            }
        }
    }
    eprintln!("hostile values: {accepted} accepted, {rejected} rejected");
}

/// Unknown keys in every table are refused, naming the key and its line.
#[test]
fn unknown_keys_in_every_table() {
    let dir = tmp_dir();
    let lines: Vec<&str> = BASE.lines().collect();
    let mut tables = 0;
    for (i, line) in lines.iter().enumerate() {
        if !line.starts_with('[') {
            continue;
        }
        let mut l: Vec<String> = lines.iter().map(|s| s.to_string()).collect();
        l.insert(i + 1, "colour = 3".into());
        let bytes = l.join("\n").into_bytes();
        let path = dir.join(format!("unknown-{i}.toml"));
        match run_bounded(&path, &bytes) {
            Outcome::Rejected(e) => {
                check_error(&e, &path, &bytes, line);
                assert_eq!((e.line, e.field.as_str()), (i + 2, "colour"), "{e}");
                tables += 1;
            }
            o => panic!("unknown key under {line}: {o:?}"),
        }
    }
    assert!(tables > 20);
}

/// A byte that is not UTF-8 on any line: the error names that line.
#[test]
fn non_utf8_bytes_name_their_line() {
    let dir = tmp_dir();
    let lines: Vec<&str> = BASE.lines().collect();
    for i in (0..lines.len()).step_by(7) {
        let mut bytes = Vec::new();
        for (k, l) in lines.iter().enumerate() {
            bytes.extend_from_slice(l.as_bytes());
            if k == i {
                bytes.extend_from_slice(b" \xff\xfe");
            }
            bytes.push(b'\n');
        }
        let path = dir.join(format!("latin1-{i}.toml"));
        match run_bounded(&path, &bytes) {
            Outcome::Rejected(e) => {
                assert_eq!(e.line, i + 1, "{e}");
                assert!(e.to_string().starts_with(&format!("{}:{}:", path.display(), i + 1)) && e.message.contains("UTF-8"), "{e}");
            }
            o => panic!("{o:?}"),
        }
    }
}

/// A scene with one shape and `extra` TOML appended.
fn one_shape(extra: &str) -> String {
    format!(
        "[image]\nwidth = 16\nheight = 12\n[camera]\nposition = [0, 1, 6]\nlook_at = [0, 0, 0]\nfov = 40\n\
         [materials.m]\ntype = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\n[[lights]]\ntype = \"point\"\nposition = [0, 5, 5]\nintensity = [9, 9, 9]\n{extra}"
    )
}

fn expect_error(text: &str, what: &str) -> InputError {
    // Tests run in parallel: one file per case.
    static CASE: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let path = tmp_dir().join(format!("case-{}.toml", CASE.fetch_add(1, std::sync::atomic::Ordering::Relaxed)));
    let outcome = run_bounded(&path, text.as_bytes());
    let _ = std::fs::remove_file(&path);
    match outcome {
        Outcome::Rejected(e) => {
            check_error(&e, &path, text.as_bytes(), what);
            e
        }
        o => panic!("{what}: {o:?}"),
    }
}

/// Nesting 1000 CSG levels deep, written inline and as a chain of named solids: an error with its
/// line, no stack overflow. A chain within the documented depth (64) renders.
#[test]
fn deep_csg_nesting_is_an_error() {
    let leaf = "{ type = \"sphere\", center = [0, 0, 0], radius = 1 }";
    let mut inline = leaf.to_string();
    for _ in 0..1000 {
        inline = format!("{{ type = \"csg\", op = \"union\", children = [{inline}] }}");
    }
    let e = expect_error(
        &one_shape(&format!("[[shapes]]\ntype = \"csg\"\nop = \"union\"\nmaterial = \"m\"\nchildren = [{inline}]\n")),
        "inline nesting",
    );
    eprintln!("1000 inline levels: {e}");

    let chain = |n: usize| {
        let mut s = String::from("[[shapes]]\nuse = \"s0\"\nmaterial = \"m\"\n");
        for i in 0..n {
            s += &format!("[solids.s{i}]\ntype = \"csg\"\nop = \"union\"\nchildren = [{{ use = \"s{}\" }}]\n", i + 1);
        }
        s + &format!("[solids.s{n}]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\n")
    };
    let e = expect_error(&one_shape(&chain(1000)), "chain of 1000 named solids");
    eprintln!("chain of 1000: {e}");
    assert!(e.message.contains("deeper than") && !e.field.is_empty(), "{e}");
    let path = tmp_dir().join("chain30.toml");
    assert!(matches!(run_bounded(&path, one_shape(&chain(30)).as_bytes()), Outcome::Accepted));
}

/// Cycles in `use`: a solid using itself, two using each other, a cycle of 100.
#[test]
fn cycles_of_named_solids_are_errors() {
    let cyc = |n: usize| {
        let mut s = String::from("[[shapes]]\nuse = \"c0\"\nmaterial = \"m\"\n");
        for i in 0..n {
            s += &format!("[solids.c{i}]\ntype = \"csg\"\nop = \"union\"\nchildren = [{{ use = \"c{}\" }}]\n", (i + 1) % n);
        }
        s
    };
    for n in [1, 2, 100] {
        let e = expect_error(&one_shape(&cyc(n)), &format!("cycle of {n}"));
        eprintln!("cycle of {n}: {e}");
        assert!(e.message.contains("cycle") || e.message.contains("deeper than"), "{e}");
    }
}

/// Image size and sample count limits are located errors (a film of 16384 x 16384 would take 30 GB).
#[test]
fn huge_images_and_sample_counts_are_errors() {
    let sized = |w: u64, h: u64| one_shape("").replace("width = 16\nheight = 12", &format!("width = {w}\nheight = {h}"));
    for (w, h, field) in [
        (16384, 16384, "image.height"),
        (16385, 1, "image.width"),
        (1, 1 << 40, "image.height"),
        (0, 12, "image.width"),
        (-5i64 as u64, 12, ""),
    ] {
        let text = sized(w, h);
        let t = Instant::now();
        let e = expect_error(&text, &format!("{w} x {h}"));
        eprintln!("{w} x {h}: {e}");
        if !field.is_empty() {
            assert_eq!(e.field, field);
        }
        assert!(t.elapsed() < Duration::from_secs(5));
    }
    // At the limit: accepted (the loader allocates no film).
    let path = tmp_dir().join("big.toml");
    assert!(matches!(run_bounded(&path, sized(8192, 4096).as_bytes()), Outcome::Accepted));

    let base = "spp = 4\npixel_strategy = \"jittered\"\nlight_samples = 1\nlight_strategy = \"jittered\"\nmax_depth = 4\n";
    assert!(Profile::parse(Path::new("p.toml"), &base.replace("spp = 4", "spp = 1048576")).is_ok());
    assert!(Profile::parse(Path::new("p.toml"), &(base.to_string() + "throughput_cutoff = 0\nbranching = \"roulette\"\n")).is_ok());
    for (from, to, field) in [
        ("spp = 4", "spp = 1048577", "spp"),
        ("spp = 4", "spp = 0", "spp"),
        ("spp = 4", "spp = 99999999999", "spp"),
        ("spp = 4", "spp = -1", "spp"),
        ("light_samples = 1", "light_samples = 4097", "light_samples"),
        ("max_depth = 4", "max_depth = 1025", "max_depth"),
        ("max_depth = 4", "max_depth = 4\nthroughput_cutoff = nan", "throughput_cutoff"),
        // Split branching (the default) with no cut-off: 2^max_depth rays per camera sample.
        ("max_depth = 4", "max_depth = 4\nthroughput_cutoff = 0", "throughput_cutoff"),
        ("max_depth = 4", "max_depth = 4\nthroughput_cutoff = 0.0\nbranching = \"split\"", "throughput_cutoff"),
    ] {
        let text = base.replace(from, to);
        let e = Profile::parse(Path::new("p.toml"), &text).expect_err(to);
        eprintln!("profile `{to}`: {e}");
        let line = text.lines().position(|l| l.starts_with(field)).unwrap() + 1;
        assert_eq!((e.field.as_str(), e.line), (field, line), "{e}");
        assert!(e.to_string().starts_with(&format!("p.toml:{line}:")), "{e}");
    }
}

/// Mutated profiles: same properties as scenes.
#[test]
fn mutated_profiles_never_panic() {
    let dir = tmp_dir();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("profiles");
    for name in ["preview", "final", "reference", "bench"] {
        let text = std::fs::read_to_string(root.join(format!("{name}.toml"))).unwrap();
        let mut rng = Rng(0xface + name.len() as u64);
        for i in 0..300 {
            let (bytes, what) = mutate(&mut rng, &text);
            let path = dir.join(format!("profile-{name}-{i}.toml"));
            std::fs::write(&path, &bytes).unwrap();
            let p = path.clone();
            let r = std::panic::catch_unwind(move || Profile::load(p.to_str().unwrap()));
            match r {
                Ok(Ok(_)) => {}
                Ok(Err(e)) => check_error(&e, &path, &bytes, &format!("profile {name} #{i} ({what})")),
                Err(_) => panic!("profile {name} #{i} ({what}) panicked:\n{}", String::from_utf8_lossy(&bytes)),
            }
            let _ = std::fs::remove_file(&path);
        }
    }
}

/// A file over the 16 MiB limit is refused without being read whole.
#[test]
fn huge_files_are_refused() {
    let mut text = one_shape("");
    while text.len() <= 17 << 20 {
        text += "# padding padding padding padding padding padding padding padding padding padding\n";
    }
    let e = expect_error(&text, "17 MiB file");
    assert!(e.message.contains("limit"), "{e}");
}

/// The renderer never lists its work units: the largest accepted render (2^25 pixels, 2^20 samples
/// per pixel: 8.6e9 units) costs nothing to describe; units cover every (pixel, sample) exactly once.
#[test]
fn work_units_cover_each_pixel_sample_once_at_any_size() {
    let big = WorkUnits::new(8192, 4096, 16, 0..1 << 20);
    assert_eq!(big.len(), (8192 / 16) * (4096 / 16) * ((1 << 20) / 16));
    let last = big.get(big.len() - 1);
    assert_eq!((last.tile.x1, last.tile.y1, last.samples.end), (8192, 4096, 1 << 20));
    for (w, h, tile, samples) in [(37, 23, 16, 0..70), (5, 3, 7, 3..4), (64, 1, 1, 10..4200)] {
        let units = WorkUnits::new(w, h, tile, samples.clone());
        let mut seen = vec![0u32; (w * h) as usize * samples.end as usize];
        for i in 0..units.len() {
            let u = units.get(i);
            for y in u.tile.y0..u.tile.y1 {
                for x in u.tile.x0..u.tile.x1 {
                    for s in u.samples.clone() {
                        seen[((y * w + x) * samples.end + s) as usize] += 1;
                    }
                }
            }
        }
        for (k, &c) in seen.iter().enumerate() {
            let s = k as u32 % samples.end;
            assert_eq!(c, samples.contains(&s) as u32, "{w}x{h} tile {tile}: entry {k}");
        }
    }
}

/// Units are taken batch by batch, each batch's tiles column by column: `taken` is a bijection that
/// keeps every unit in its batch, and two units taken one after the other inside a tile column are
/// vertical neighbours (what two workers accumulate at the same time shares no film row).
#[test]
fn units_are_taken_column_by_column_within_a_batch() {
    for (w, h, tile, samples) in [(37, 23, 16, 0..70), (5, 3, 7, 3..4), (64, 1, 1, 10..4200), (640, 400, 16, 0..4), (48, 80, 16, 0..40)] {
        let units = WorkUnits::new(w, h, tile, samples.clone());
        let (tiles_x, tiles_y) = (w.div_ceil(tile) as usize, h.div_ceil(tile) as usize);
        let tiles = tiles_x * tiles_y;
        let mut hit = vec![false; units.len()];
        for k in 0..units.len() {
            let i = units.taken(k);
            assert!(i < units.len() && !hit[i], "{w}x{h} tile {tile}: unit {i} taken twice");
            hit[i] = true;
            assert_eq!(i / tiles, k / tiles, "{w}x{h}: a unit left its sample batch");
            if k + 1 < units.len() && (k + 1) % tiles != 0 && (k + 1) % tiles % tiles_y != 0 {
                let (a, b) = (units.get(i).tile, units.get(units.taken(k + 1)).tile);
                assert_eq!((b.x0, b.y0), (a.x0, a.y1), "{w}x{h} tile {tile}: takes {k} and {} are not vertical neighbours", k + 1);
            }
        }
        assert!(hit.iter().all(|&h| h));
    }
}
