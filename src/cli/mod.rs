//! Command-line interface. Exit codes: 0 success, 1 a failure while running (e.g. writing output),
//! 2 bad input (scene, profile, flags), 130 interrupted by SIGINT or SIGTERM (the accumulated image and its
//! film are still written).

pub mod merge_cmd;
pub mod render_cmd;
pub mod study_cmd;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

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

/// Apply `--set KEY=VALUE` flags (after `before`, overrides of the command's own flags) to `profile`,
/// validated together after the last ([`crate::scene::Profile::set_all`]).
pub fn apply_sets(profile: &mut crate::scene::Profile, before: &[(&str, String)], sets: &[String]) -> Result<(), Failure> {
    let mut pairs: Vec<(&str, &str)> = before.iter().map(|(k, v)| (*k, v.as_str())).collect();
    for s in sets {
        pairs.push(s.split_once('=').ok_or_else(|| Failure::input(format!("--set {s}: expected KEY=VALUE")))?);
    }
    profile.set_all(pairs).map_err(|e| Failure::input(format!("command line: {e}")))
}

pub fn main() -> ExitCode {
    let cli = Cli::parse();
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
