//! `study.csv`: one row per render (every strategy, sample count and seed).

use super::run::RunResult;
use crate::film::output::write_atomic;
use std::fmt::Write as _;
use std::path::Path;

/// The column names, in order.
pub const COLUMNS: [&str; 12] =
    ["strategy", "spp", "seed", "seconds", "rays", "mse", "relmse", "efficiency", "camera_spp", "light_samples", "mean_ratio", "mean_z"];

/// The CSV text (header and one line per run; floats in shortest round-trip form, `inf` for an
/// infinite efficiency).
pub fn to_csv(runs: &[RunResult]) -> String {
    let mut s = COLUMNS.join(",");
    s.push('\n');
    for r in runs {
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{},{},{}",
            r.strategy,
            r.n,
            r.seed,
            r.seconds,
            r.rays,
            r.mse,
            r.relmse,
            r.efficiency,
            r.camera_spp,
            r.light_samples,
            r.mean_ratio,
            r.mean_z
        );
    }
    s
}

/// Write `study.csv` atomically.
pub fn write(path: &Path, runs: &[RunResult]) -> Result<(), String> {
    let text = to_csv(runs);
    write_atomic(path, |tmp| std::fs::write(tmp, text).map_err(|e| format!("{}: {e}", path.display())))
}
