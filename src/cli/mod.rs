//! Command-line interface. Exit codes: 0 success, 1 a failure while running (e.g. writing output),
//! 2 bad input (scene, profile, flags), 130 interrupted by SIGINT or SIGTERM (the accumulated image and its
//! film are still written; a second signal while the work units in flight finish quits at once, writing
//! nothing, and says so).

pub mod merge_cmd;
pub mod render_cmd;
pub mod study_cmd;

use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

#[derive(Parser, Debug)]
#[command(name = "strata", version, about = "A data-oriented SIMD wavefront ray tracer for the CPU")]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Render a scene to PNG or EXR.
    Render(render_cmd::RenderArgs),
    /// Measure error, time and efficiency of sampling strategies against a reference (CSV, plot, sheet).
    Study(study_cmd::StudyArgs),
    /// Sum the films of sample ranges into one image (and film), exactly; --status lists the ranges.
    Merge(merge_cmd::MergeArgs),
}

/// A clap parser of a count flag of `what`, quoting its limit `max` ([`crate::scene::profile::parse_count`]:
/// 0 and the limit itself are left to the profile's validation, which says why).
pub fn count_parser(what: &'static str, max: u32) -> impl Fn(&str) -> Result<u32, String> + Clone + Send + Sync + 'static {
    move |v: &str| crate::scene::profile::parse_count(v, max).map_err(|e| format!("{what}: {e}"))
}

/// A clap value parser for a whole number in `lo..=hi` (`what` names it in errors), in the words of
/// [`count_parser`] for negative, fractional and non-numeric values and with the value in a range error
/// (clap's own said "-1 is not in 0..=4294967295" of a flag limited to 1..=1024, and "invalid digit found
/// in string" of `--seed -1`).
pub fn range_parser<T: TryFrom<u64> + Clone + Send + Sync + 'static>(
    what: &'static str,
    lo: u64,
    hi: u64,
) -> impl Fn(&str) -> Result<T, String> + Clone + Send + Sync + 'static {
    move |v: &str| {
        let t = v.trim();
        let n = t.parse::<u64>().map_err(|_| match t.parse::<f64>() {
            Ok(x) if !x.is_finite() => format!("{what}: `{v}` is not a whole number in {lo}..={hi}"),
            Ok(x) if x < 0.0 => format!("{what}: `{v}` is negative (a whole number in {lo}..={hi})"),
            Ok(x) if x.fract() != 0.0 => format!("{what}: `{v}` is not a whole number (in {lo}..={hi})"),
            Ok(_) if t.bytes().all(|b| b.is_ascii_digit()) => format!("{what}: `{v}` is too large (at most {hi})"),
            Ok(x) if x > hi as f64 => format!("{what}: `{v}` is too large (at most {hi})"),
            Ok(x) => format!("{what}: `{v}`: write it in digits (`{}`)", x as u64),
            Err(_) => format!("{what}: `{v}` is not a number (a whole number in {lo}..={hi})"),
        })?;
        if !(lo..=hi).contains(&n) {
            return Err(format!("{what}: `{v}` is not in {lo}..={hi}"));
        }
        T::try_from(n).map_err(|_| format!("{what}: `{v}` is too large (at most {hi})"))
    }
}

/// The most worker threads `--threads` takes.
pub const MAX_THREADS: u64 = 1024;

/// An error with its exit code.
pub struct Failure {
    pub code: u8,
    pub message: String,
}

impl Failure {
    pub fn input(m: impl std::fmt::Display) -> Self {
        Failure { code: 2, message: m.to_string() }
    }
    pub fn runtime(m: impl std::fmt::Display) -> Self {
        Failure { code: 1, message: m.to_string() }
    }
}

/// Load `--profile NAME|PATH`, apply `before` (overrides from the command's own flags, which may depend
/// on the file's values), then the `--set KEY=VALUE` flags, in order (except that a general `strategy`
/// comes before every single one, which refines it), and check the result as a whole
/// ([`crate::scene::Profile::load_with`]): an override may make a file's combination valid.
pub fn load_profile(
    name: &str,
    before: impl FnOnce(&crate::scene::Profile) -> Vec<(&'static str, String)>,
    sets: &[String],
) -> Result<crate::scene::Profile, Failure> {
    let mut split = Vec::with_capacity(sets.len());
    for s in sets {
        let (k, v) = s.split_once('=').ok_or_else(|| Failure::input(format!("--set {s}: expected KEY=VALUE")))?;
        split.push((k.to_string(), v.to_string()));
    }
    crate::scene::Profile::load_with(name, |p| before(p).into_iter().map(|(k, v)| (k.to_string(), v)).chain(split).collect())
        .map_err(Failure::input)
}

/// A path as the file system names it, so that two spellings of one file compare equal: canonical
/// when the file exists, else its canonical directory joined with its name.
fn file_identity(p: &Path) -> PathBuf {
    if let Ok(c) = std::fs::canonicalize(p) {
        return c;
    }
    let dir = match p.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    match (std::fs::canonicalize(dir), p.file_name()) {
        (Ok(d), Some(name)) => d.join(name),
        _ => p.to_path_buf(),
    }
}

/// Refuse a command whose output files (flag, path) name one file twice, or name one of its input
/// files (what, path): the later write would silently replace the earlier, or the input. `allowed`:
/// (output flag, input) pairs that may name one file (a film written back into the film it resumes).
pub fn check_distinct_files(outputs: &[(&str, &Path)], inputs: &[(&str, &Path)], allowed: &[(&str, &str)]) -> Result<(), Failure> {
    let outs: Vec<(&str, &Path, PathBuf)> = outputs.iter().map(|&(f, p)| (f, p, file_identity(p))).collect();
    for (i, (fa, pa, ia)) in outs.iter().enumerate() {
        if let Some((fb, _, _)) = outs[..i].iter().find(|(_, _, ib)| ib == ia) {
            return Err(Failure::input(format!("{fb} and {fa} both name {}: give each output its own file", pa.display())));
        }
        for &(what, q) in inputs {
            if !allowed.contains(&(fa, what)) && file_identity(q) == *ia {
                return Err(Failure::input(format!("{fa} {} is {what}: writing it would replace that input", pa.display())));
            }
        }
    }
    Ok(())
}

/// What a signal (Ctrl-C, SIGINT, SIGTERM) does now: the command's handler once it has set one
/// ([`on_signal`]). `ctrlc` takes one handler per process, so that one, installed first thing, calls
/// this; until a command sets its own, a signal ends the process with a message and exit 130.
type SignalAction = Box<dyn FnMut() + Send>;
static ON_SIGNAL: std::sync::Mutex<Option<SignalAction>> = std::sync::Mutex::new(None);

/// Make `f` what a signal does from now on (see [`ON_SIGNAL`]).
pub(crate) fn on_signal(f: impl FnMut() + Send + 'static) {
    *ON_SIGNAL.lock().unwrap_or_else(|e| e.into_inner()) = Some(Box::new(f));
}

fn install_signal_dispatch() {
    let _ = ctrlc::set_handler(|| match ON_SIGNAL.lock().unwrap_or_else(|e| e.into_inner()).as_mut() {
        Some(f) => f(),
        None => {
            errln!("interrupted: nothing was written");
            std::process::exit(130);
        }
    });
}

pub fn main() -> ExitCode {
    let cli = Cli::parse();
    install_signal_dispatch();
    let r = match cli.command {
        Command::Render(a) => render_cmd::run(a),
        Command::Study(a) => study_cmd::run(a),
        Command::Merge(a) => merge_cmd::run(a),
    };
    match r {
        Ok(code) => ExitCode::from(code),
        Err(f) => {
            errln!("error: {}", f.message);
            ExitCode::from(f.code)
        }
    }
}

/// A long setup (reading, parsing, checking and building a large scene) shown while it runs: after
/// 1 s, a spinner on a terminal, else a line (then one every 30 s, for job logs). A trial's scene of
/// 4,000 coincident glass spheres left the terminal blank for 5.9 s, and 8K films take seconds to
/// allocate. Stopped when dropped.
pub struct SetupNotice {
    done: Option<std::sync::mpsc::Sender<()>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl SetupNotice {
    pub fn start(what: &str, quiet: bool) -> SetupNotice {
        use std::sync::mpsc::RecvTimeoutError::Timeout;
        use std::time::Duration;
        if quiet {
            return SetupNotice { done: None, thread: None };
        }
        let (tx, rx) = std::sync::mpsc::channel::<()>();
        let what = what.to_string();
        let thread = std::thread::spawn(move || {
            let t0 = Instant::now();
            if rx.recv_timeout(Duration::from_secs(1)) != Err(Timeout) {
                return;
            }
            if std::io::stderr().is_terminal() {
                let s = ProgressBar::new_spinner().with_elapsed(t0.elapsed());
                s.set_style(ProgressStyle::with_template("{spinner} {msg} [{elapsed}]").expect("a valid template"));
                s.set_message(what);
                s.enable_steady_tick(Duration::from_millis(120));
                let _ = rx.recv();
                s.finish_and_clear();
            } else {
                errln!("{what}...");
                while rx.recv_timeout(Duration::from_secs(30)) == Err(Timeout) {
                    errln!("{what}: {:.0} s so far", t0.elapsed().as_secs_f64());
                }
            }
        });
        SetupNotice { done: Some(tx), thread: Some(thread) }
    }
}

impl Drop for SetupNotice {
    fn drop(&mut self) {
        self.done.take();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Progress of a render's work units: a bar on a terminal, else a line per 10% (for job logs).
pub struct Progress {
    pub(crate) bar: Option<ProgressBar>,
    label: String,
    quiet: bool,
    logged_tenths: AtomicUsize,
    start: Instant,
}

impl Progress {
    pub fn new(label: &str, quiet: bool, total: usize, done: usize) -> Progress {
        let bar = (!quiet && std::io::stderr().is_terminal()).then(|| {
            let b = ProgressBar::new(total as u64);
            b.set_style(
                ProgressStyle::with_template("{prefix} {spinner} [{elapsed_precise}] {wide_bar} {pos}/{len} work units (eta {eta})")
                    .unwrap(),
            );
            b.set_prefix(label.to_string());
            b.set_position(done as u64);
            b
        });
        let tenths = (done * 10).checked_div(total).unwrap_or(10);
        Progress { bar, label: label.to_string(), quiet, logged_tenths: AtomicUsize::new(tenths), start: Instant::now() }
    }

    pub fn update(&self, done: usize, total: usize) {
        if let Some(b) = &self.bar {
            b.set_length(total as u64);
            b.set_position(done as u64);
        } else if !self.quiet && total > 0 {
            let tenths = done * 10 / total;
            if self.logged_tenths.fetch_max(tenths, Ordering::Relaxed) < tenths {
                let secs = self.start.elapsed().as_secs_f64();
                errln!("{}: {}% ({done}/{total} work units, {secs:.1} s)", self.label, tenths * 10);
            }
        }
    }

    pub fn println(&self, m: &str) {
        match &self.bar {
            Some(b) => b.suspend(|| errln!("{m}")),
            None => errln!("{m}"),
        }
    }

    pub fn finish(&self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
}
