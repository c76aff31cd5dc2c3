//! How Strata scales on this machine (issue 8, item 5): rays/s at 1 and 2 threads, render time against
//! the number of primitives (1e2 .. 1e6 spheres), the resolution, the leaves of one CSG solid and the
//! number of lights (per light selection). Prints markdown tables
//! (docs/scaling.md holds a measured copy).
//!
//! ```text
//! cargo run --release --example scaling [-- --reps 2 --spp 16 --max-prims 1000000 --only threads|prims|resolution|leaves|lights]
//! ```
//!
//! Every number is a [`RenderStats`] of one render with the `bench` profile (fixed counts, no adaptive
//! behaviour): the same `seconds` (wall time of the render, scene loading excluded) and rays that
//! `strata render --profile bench --stats-json` reports. Each configuration is rendered `--reps` times and
//! the fastest run is kept, because the machine is shared and other load only ever slows a run down.
//! Beside wall-clock rates the tables give rays per worker-second: the render summary's stage seconds
//! (each worker's time inside the stages, summed over workers), which leave out the idle time of a
//! thread waiting for work and are exact to the microsecond (the process's CPU clock in
//! `/proc/self/stat` ticks at 10 ms, a tenth of a 0.1 s render). Neither clock can see a host that
//! takes a virtual CPU away: then only runs side by side in time compare, which is why the thread
//! table alternates its 1- and 2-thread renders.
//!
//! Sphere scenes come from `scenes/tools/gen_bench_spheres.py N` (python3), parsed from memory with
//! `parse_scene`: a million spheres is ~95 MB of TOML, over the 16 MiB limit of scene *files*, so no
//! file is written. The generator keeps its 40 x 40 area, so density grows with N.

use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};
use std::time::Instant;
use strata::render::{render, RenderStats};
use strata::scene::{parse_scene, LightSelection, Profile, Scene};
use strata::wavefront::Settings;

struct Opts {
    reps: usize,
    spp: Option<u32>,
    max_prims: u64,
    /// Tables to print: threads, prims, resolution, leaves (default all).
    only: Option<String>,
}

impl Opts {
    fn wants(&self, table: &str) -> bool {
        self.only.as_deref().is_none_or(|o| o == table)
    }
}

fn parse_args() -> Result<Opts, String> {
    let mut o = Opts { reps: 2, spp: None, max_prims: 1_000_000, only: None };
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut i = 0;
    while i < args.len() {
        if args[i] == "--help" || args[i] == "-h" {
            return Err(String::new());
        }
        let val = args.get(i + 1).ok_or_else(|| format!("{} needs a value", args[i]))?;
        let num = |v: &str| v.parse::<u64>().map_err(|_| format!("{}: `{v}` is not a number", args[i]));
        match args[i].as_str() {
            "--reps" => o.reps = num(val)?.max(1) as usize,
            "--spp" => o.spp = Some(num(val)? as u32),
            "--max-prims" => o.max_prims = num(val)?,
            "--only" if ["threads", "prims", "resolution", "leaves", "lights"].contains(&val.as_str()) => o.only = Some(val.clone()),
            other => {
                return Err(format!(
                    "bad option `{other} {val}` (--reps N, --spp N, --max-prims N, --only threads|prims|resolution|leaves|lights)"
                ))
            }
        }
        i += 2;
    }
    Ok(o)
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn profile(o: &Opts) -> Profile {
    let mut p = Profile::builtin("bench");
    if let Some(s) = o.spp {
        p.spp = s;
    }
    p
}

/// One render's statistics.
struct Run {
    stats: RenderStats,
}

impl Run {
    /// Seconds the workers spent inside the stages, summed over workers (the render summary's stage
    /// seconds; see the module doc).
    fn worker_seconds(&self) -> f64 {
        let t = &self.stats.stage_seconds;
        t.generate + t.intersect + t.csg_merge + t.shade + t.shadow + t.accumulate
    }

    /// Rays per worker-second, in millions.
    fn per_worker(&self) -> String {
        m(self.stats.rays.total as f64 / self.worker_seconds())
    }
}

fn once(scene: &Scene, o: &Opts, threads: usize) -> Run {
    let settings = Settings { profile: profile(o), seed: 1 };
    Run { stats: render(scene, settings, threads).1 }
}

/// The fastest of some renders of one configuration (all of them give the same image and ray counts).
fn fastest(runs: impl IntoIterator<Item = Run>) -> Run {
    runs.into_iter().min_by(|a, b| a.stats.seconds.total_cmp(&b.stats.seconds)).expect("reps >= 1")
}

/// The fastest of `reps` renders.
fn best(scene: &Scene, o: &Opts, threads: usize) -> Run {
    fastest((0..o.reps).map(|_| once(scene, o, threads)))
}

/// `gen_bench_spheres.py n` (with `--same-density`: radii scaled so that the spheres fill the same
/// fraction of the layer as 1,000 do).
fn gen_spheres(n: u64, same_density: bool) -> Result<String, String> {
    let n = n.to_string();
    let args: &[&str] = if same_density { &[&n, "--same-density"] } else { &[&n] };
    generated("gen_bench_spheres.py", args)
}

/// The scene text `scenes/tools/SCRIPT ARGS` writes.
fn generated(script: &str, args: &[&str]) -> Result<String, String> {
    let script = root().join("scenes/tools").join(script);
    let out =
        Command::new("python3").arg(&script).args(args).output().map_err(|e| format!("cannot run python3 {}: {e}", script.display()))?;
    if !out.status.success() {
        return Err(format!("{} failed: {}", script.display(), String::from_utf8_lossy(&out.stderr)));
    }
    String::from_utf8(out.stdout).map_err(|e| e.to_string())
}

fn load(name: &str, text: &str) -> Result<(Scene, f64), String> {
    let t0 = Instant::now();
    let scene = parse_scene(Path::new(name), text).map_err(|e| e.to_string())?;
    Ok((scene, t0.elapsed().as_secs_f64()))
}

fn read_scene(file: &str) -> Result<String, String> {
    let p = root().join("scenes").join(file);
    std::fs::read_to_string(&p).map_err(|e| format!("{}: {e}", p.display()))
}

/// `text` with the `[image]` size replaced (the generated and shipped scenes write one `width =` and
/// one `height =` line).
fn with_resolution(text: &str, w: u32, h: u32) -> String {
    text.lines()
        .map(|l| {
            if l.starts_with("width = ") {
                format!("width = {w}")
            } else if l.starts_with("height = ") {
                format!("height = {h}")
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n")
}

fn m(x: f64) -> String {
    format!("{:.2}", x / 1e6)
}

fn machine() {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| s.lines().find(|l| l.starts_with("model name")).map(|l| l.split(':').nth(1).unwrap_or("").trim().to_string()))
        .unwrap_or_else(|| "unknown".into());
    let commit = Command::new("git")
        .args(["rev-parse", "--short", "HEAD"])
        .current_dir(root())
        .output()
        .ok()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_default();
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!(
        "commit {commit}, cpu {cpu}, {} hardware threads, load average {}",
        std::thread::available_parallelism().map(|n| n.get()).unwrap_or(0),
        load.split_whitespace().take(3).collect::<Vec<_>>().join(" ")
    );
}

fn run(o: &Opts) -> Result<(), String> {
    machine();
    let p = profile(o);
    println!("profile bench: {} spp, max depth {}, best of {} runs\n", p.spp, p.max_depth, o.reps);

    if o.wants("threads") {
        threads(o)?;
    }
    if o.wants("prims") {
        prims(o)?;
    }
    if o.wants("resolution") {
        resolution(o)?;
    }
    if o.wants("leaves") {
        leaves(o)?;
    }
    if o.wants("lights") {
        lights(o)?;
    }
    Ok(())
}

fn threads(o: &Opts) -> Result<(), String> {
    println!("## Threads\n");
    println!(
        "1- and 2-thread renders alternate (rep by rep), so that both see the same phases of a shared machine; \
         the speed-up is the best 1-thread time over the best 2-thread time, and in brackets the median and \
         range of the {} per-rep ratios.\n",
        o.reps
    );
    println!(
        "| scene | rays (M) | 1 thread: s | M rays/s | M rays / worker s | 2 threads: s | M rays/s | M rays / worker s | \
         speed-up | second thread adds |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for file in ["bench_spheres.toml", "showcase.toml"] {
        let (scene, _) = load(file, &read_scene(file)?)?;
        let (ones, twos): (Vec<Run>, Vec<Run>) = (0..o.reps).map(|_| (once(&scene, o, 1), once(&scene, o, 2))).unzip();
        let mut ratios: Vec<f64> = ones.iter().zip(&twos).map(|(a, b)| a.stats.seconds / b.stats.seconds).collect();
        ratios.sort_by(f64::total_cmp);
        let (one, two) = (fastest(ones), fastest(twos));
        let s = one.stats.seconds / two.stats.seconds;
        // (Of an even count, the mean of the middle two: with 2 reps, `ratios[1]` was the larger.)
        let n = ratios.len();
        let median = if n % 2 == 1 { ratios[n / 2] } else { (ratios[n / 2 - 1] + ratios[n / 2]) / 2.0 };
        println!(
            "| {file} | {} | {:.3} | {} | {} | {:.3} | {} | {} | {s:.2}x ({median:.2}x, {:.2}-{:.2}) | {:.0}% ({:.0}%) |",
            m(two.stats.rays.total as f64),
            one.stats.seconds,
            m(one.stats.rays_per_second),
            one.per_worker(),
            two.stats.seconds,
            m(two.stats.rays_per_second),
            two.per_worker(),
            ratios[0],
            ratios[ratios.len() - 1],
            (s - 1.0) * 100.0,
            (median - 1.0) * 100.0
        );
    }

    Ok(())
}

fn prims(o: &Opts) -> Result<(), String> {
    for same_density in [false, true] {
        prims_table(o, same_density)?;
    }
    Ok(())
}

/// One primitive-count table: the bench_spheres layout with its radii (overlap grows with N) or with
/// radii scaled to the same volume fraction (`same_density`).
fn prims_table(o: &Opts, same_density: bool) -> Result<(), String> {
    if same_density {
        println!(
            "\n## Primitive count, same density (radii x (1000 / N)^(1/3): the spheres fill the layer as 1,000 do; 640x480, 2 threads)\n"
        );
    } else {
        println!("\n## Primitive count (bench_spheres layout, radii kept: overlap grows with N; 640x480, 2 threads)\n");
    }
    println!(
        "| spheres | TOML MB | parse + BVH s | render s | rays (M) | M rays/s | M rays / worker s | worker s per ray / same at 1e2 \
         | ns per ray: intersect, shade, shadow, rest |"
    );
    println!("|---:|---:|---:|---:|---:|---:|---:|---:|---|");
    let mut base = None;
    let mut n = 100u64;
    while n <= o.max_prims {
        let text = gen_spheres(n, same_density)?;
        let (scene, load_s) = load(&format!("<gen_bench_spheres.py {n}>"), &text)?;
        let r = best(&scene, o, 2);
        let st = &r.stats;
        // Per ray: the ray count changes a little with N (shadow rays follow the visible surfaces).
        let cost = r.worker_seconds() / st.rays.total as f64;
        let b = *base.get_or_insert(cost);
        // Where the time per ray goes (worker ns per traced ray; the rest is generation and accumulation).
        let t = &st.stage_seconds;
        let ns = |x: f64| x * 1e9 / st.rays.total as f64;
        let rest = t.generate + t.csg_merge + t.accumulate;
        println!(
            "| {n} | {:.1} | {load_s:.2} | {:.3} | {} | {} | {} | {:.2} | {:.1}, {:.1}, {:.1}, {:.1} |",
            text.len() as f64 / 1e6,
            st.seconds,
            m(st.rays.total as f64),
            m(st.rays_per_second),
            r.per_worker(),
            cost / b,
            ns(t.intersect),
            ns(t.shade),
            ns(t.shadow),
            ns(rest)
        );
        n *= 10;
    }

    Ok(())
}

fn resolution(o: &Opts) -> Result<(), String> {
    println!("\n## Resolution (bench_spheres.toml, 2 threads)\n");
    println!("| resolution | pixels (M) | render s | rays (M) | M rays/s | M rays / worker s | worker s per M pixels |");
    println!("|---|---:|---:|---:|---:|---:|---:|");
    let text = read_scene("bench_spheres.toml")?;
    for (w, h) in [(160, 120), (320, 240), (640, 480), (1280, 960), (2560, 1920)] {
        let (scene, _) = load("bench_spheres.toml", &with_resolution(&text, w, h))?;
        let r = best(&scene, o, 2);
        let st = &r.stats;
        let px = (w * h) as f64;
        println!(
            "| {w}x{h} | {:.3} | {:.3} | {} | {} | {} | {:.3} |",
            px / 1e6,
            st.seconds,
            m(st.rays.total as f64),
            m(st.rays_per_second),
            r.per_worker(),
            r.worker_seconds() / (px / 1e6)
        );
    }
    Ok(())
}

/// One CSG solid of more and more leaves: `gen_perforated.py n`, a plate with n x n holes (the same
/// picture, finer holes). Per ray and per CSG candidate: with the solid's cull program (`csg::cull`) the
/// time grows with the depth of its hierarchy, not with its leaves.
fn leaves(o: &Opts) -> Result<(), String> {
    println!("\n## Leaves of one CSG solid (scenes/tools/gen_perforated.py N: a plate minus N x N holes; 640x400, 2 threads)\n");
    println!("| holes | leaves | parse s | render s | rays (M) | M rays/s | CSG candidates (M) | csg_merge ns per candidate | shadow ns per shadow ray |");
    println!("|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for n in [2u64, 4, 8, 16, 32, 64] {
        let text = generated("gen_perforated.py", &[&n.to_string()])?;
        let (scene, load_s) = load(&format!("<gen_perforated.py {n}>"), &text)?;
        let r = best(&scene, o, 2);
        let st = &r.stats;
        let t = &st.stage_seconds;
        println!(
            "| {} | {} | {load_s:.3} | {:.3} | {} | {} | {} | {:.1} | {:.1} |",
            n * n,
            n * n + 1,
            st.seconds,
            m(st.rays.total as f64),
            m(st.rays_per_second),
            m(st.csg_candidates as f64),
            t.csg_merge * 1e9 / st.csg_candidates.max(1) as f64,
            t.shadow * 1e9 / st.rays.shadow.max(1) as f64
        );
    }
    Ok(())
}

/// Time against the number of lights, for each light selection (`scenes/tools/gen_many_lights.py N`:
/// N x N lamps over a square, up to 65,536; `all` only up to 256 lamps, 19 s there, `local` up to 1,024).
fn lights(o: &Opts) -> Result<(), String> {
    println!("\n## Lights (scenes/tools/gen_many_lights.py N: N x N lamps; 640x400, 2 threads): render s, shadow stage thread s\n");
    println!("| lamps | all | power | local | tree | shadow stage ns per shadow ray: local, tree |");
    println!("|---:|---:|---:|---:|---:|---:|");
    for n in [1u64, 2, 4, 8, 16, 32, 64, 128, 256] {
        let text = generated("gen_many_lights.py", &[&n.to_string()])?;
        let (scene, _) = load(&format!("<gen_many_lights.py {n}>"), &text)?;
        let mut cells = Vec::new();
        let mut per_point = Vec::new();
        for sel in [LightSelection::All, LightSelection::Power, LightSelection::Local, LightSelection::Tree] {
            // (`all` takes 19 s at 256 lamps, `local` 12 s at 4,096.)
            if (sel == LightSelection::All && n > 16) || (sel == LightSelection::Local && n > 32) {
                cells.push("-".to_string());
                if sel == LightSelection::Local {
                    per_point.push("-".to_string());
                }
                continue;
            }
            let mut p = profile(o);
            p.light_selection = sel;
            let st = fastest((0..o.reps).map(|_| Run { stats: render(&scene, Settings { profile: p.clone(), seed: 1 }, 2).1 })).stats;
            cells.push(format!("{:.3} ({:.3})", st.seconds, st.stage_seconds.shadow));
            if matches!(sel, LightSelection::Local | LightSelection::Tree) {
                // (Rays traced or cleared by the light-cone test: one per lit shading point here.)
                let rays = (st.rays.shadow + st.rays.shadow_cleared).max(1) as f64;
                per_point.push(format!("{:.0}", st.stage_seconds.shadow * 1e9 / rays));
            }
        }
        println!("| {} | {} | {} |", n * n, cells.join(" | "), per_point.join(", "));
    }
    Ok(())
}

fn main() -> ExitCode {
    match parse_args().and_then(|o| run(&o)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if e.is_empty() => {
            println!(
                "usage: cargo run --release --example scaling [-- OPTIONS]\n\
                 Markdown tables of how Strata scales on this machine (bench profile, best of --reps runs):\n\
                 threads (1 against 2, alternating), prims (1e2 .. --max-prims spheres, twice: radii kept and\n\
                 the same density), resolution, leaves (of one CSG solid) and lights (per light selection).\n\
                 options:\n  --reps N        runs per configuration, the fastest kept (default 2)\n\
                 \x20 --spp N         samples per pixel (default: the bench profile's 16)\n\
                 \x20 --max-prims N   largest sphere count of the prims tables (default 1000000)\n\
                 \x20 --only TABLE    threads, prims, resolution, leaves or lights (default: all five)"
            );
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("scaling: {e}");
            ExitCode::from(2)
        }
    }
}
