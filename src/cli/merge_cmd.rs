//! `strata merge`: sum the films of sample ranges into one image (and film), exactly; `--status` lists
//! which ranges are present and which are missing.
//!
//! Every check runs before anything is written, so a refused merge leaves existing outputs untouched.

use super::Failure;
use crate::film::file::{check_film_writable, other_builds_warning, read_film_header, verify_film, write_film, FilmHeader, FilmReader};
use crate::film::output::{check_writable, write_image_with, Provenance};
use crate::film::Film;
use crate::render::unit_count;
use clap::Args;
use std::fmt::Write as _;
use std::io::Write as _;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};
use std::sync::Arc;

#[derive(Args, Debug, Clone)]
pub struct MergeArgs {
    /// Film files written by `strata render --film` (any order).
    #[arg(required = true, value_name = "FILM")]
    pub films: Vec<PathBuf>,
    /// Output image: .png (sRGB 8-bit) or .exr (linear float).
    #[arg(short, long, required_unless_present = "status")]
    pub output: Option<PathBuf>,
    /// Also write the merged film (possible when the ranges are complete and contiguous).
    #[arg(long, value_name = "MERGED")]
    pub film: Option<PathBuf>,
    /// Merge even when the ranges leave gaps (between films, or before the first or after the last: not
    /// all of 0..spp) or films are incomplete: the image then has fewer samples. A film is written only
    /// of complete films of one contiguous range (the film of that range).
    #[arg(long)]
    pub allow_gaps: bool,
    /// List the sample ranges present and missing and each film's completeness; write nothing.
    #[arg(long, conflicts_with_all = ["output", "film", "allow_gaps"])]
    pub status: bool,
}

pub fn run(a: MergeArgs) -> Result<u8, Failure> {
    if a.status {
        return status(&a.films);
    }
    let out = a.output.clone().expect("clap requires -o without --status");
    check_writable(&out).map_err(Failure::input)?;
    if let Some(f) = &a.film {
        crate::film::file::check_film_name(f).map_err(Failure::input)?;
        check_film_writable(f).map_err(Failure::input)?;
    }
    let mut outputs: Vec<(&str, &Path)> = vec![("-o", &out)];
    if let Some(f) = &a.film {
        outputs.push(("--film", f));
    }
    let inputs: Vec<(&str, &Path)> = a.films.iter().map(|f| ("an input film", f.as_path())).collect();
    super::check_distinct_files(&outputs, &inputs, &[])?;
    // The headers first (a few KB each): every check of the films against each other is made before a
    // pixel is read; the pixels are then read one film at a time into the running sum.
    let mut films = Vec::new();
    for p in &a.films {
        films.push((p.clone(), read_film_header(p).map_err(Failure::input)?));
    }
    check_same_render(&films).map_err(Failure::input)?;
    films.sort_by_key(|(_, h)| (h.samples.start, h.samples.end));
    check_overlaps(&films).map_err(Failure::input)?;

    let mut problems = Vec::new();
    for (p, h) in &films {
        if !h.is_complete() {
            problems.push(format!(
                "{} is incomplete ({} of {} work units of samples {}); finish it with `strata render ... --resume {}`",
                p.display(),
                h.units_done(),
                h.completed.len(),
                range_text(&h.samples),
                p.display()
            ));
        }
    }
    for w in films.windows(2) {
        let (pa, a_) = (&w[0].0, &w[0].1.samples);
        let (pb, b_) = (&w[1].0, &w[1].1.samples);
        if a_.end < b_.start {
            problems.push(format!(
                "gap: samples {}..{} are in no film (between {} {} and {} {})",
                a_.end,
                b_.start,
                pa.display(),
                range_text(a_),
                pb.display(),
                range_text(b_)
            ));
        }
    }
    // Samples before the first film or after the last: the image would not be the whole render, which
    // the merge of a split's parts is taken for (a split missing its last part merged `samples 0..192 of
    // spp 256` without a word). Refused as a gap between films is; `--allow-gaps` merges such a range
    // alone, and (its films complete and contiguous) into a film of that range, which merges later with
    // the rest.
    let (first_film, last_film) = (&films[0], &films[films.len() - 1]);
    let spp = first_film.1.spp;
    let mut outside = Vec::new();
    let (start, end) = (first_film.1.samples.start, last_film.1.samples.end);
    if start > 0 {
        outside.push(format!(
            "missing: samples 0..{start} of spp {spp} are in no film (before {} {})",
            first_film.0.display(),
            range_text(&first_film.1.samples)
        ));
    }
    if end < spp {
        outside.push(format!(
            "missing: samples {end}..{spp} of spp {spp} are in no film (after {} {})",
            last_film.0.display(),
            range_text(&last_film.1.samples)
        ));
    }
    if !outside.is_empty() && !a.allow_gaps {
        let all: Vec<&String> = problems.iter().chain(&outside).collect();
        let alone = if problems.is_empty() {
            format!(
                "; --allow-gaps merges samples {start}..{end} alone, into an image{} that is not the full render",
                if a.film.is_some() { " and a film of that range" } else { "" }
            )
        } else {
            String::new()
        };
        return Err(Failure::input(format!(
            "cannot merge: {}: the image would not be the full render (give every part's film, or use --allow-gaps to merge anyway{alone})",
            all.iter().map(|p| p.as_str()).collect::<Vec<_>>().join("; ")
        )));
    }
    if !problems.is_empty() {
        if !a.allow_gaps {
            return Err(Failure::input(format!("cannot merge: {} (use --allow-gaps to merge anyway)", problems.join("; "))));
        }
        if a.film.is_some() {
            return Err(Failure::input(format!(
                "cannot write a merged film: {}; a film records one complete, contiguous range",
                problems.join("; ")
            )));
        }
    }

    let first = &films[0].1;
    // Films of several builds merge (their samples are exact either way), with a warning; the merged film
    // records a build only where all of them share it.
    let builds: Vec<(String, u64)> = films.iter().map(|(p, h)| (p.display().to_string(), h.build)).collect();
    let (name0, build0) = builds.iter().find(|b| b.1 != 0).cloned().unwrap_or_default();
    let warning = other_builds_warning(&builds, build0, &name0);
    // Films of unknown build (0: version 1, or already of several builds) are not taken as the others'
    // build: the merged film records none (a user trial found it claiming theirs).
    let unknown: Vec<&str> = builds.iter().filter(|b| b.1 == 0).map(|b| b.0.as_str()).collect();
    let build = if warning.is_some() || !unknown.is_empty() { 0 } else { build0 };
    if let Some(w) = warning {
        errln!("{w}");
    }
    if build0 != 0 && !unknown.is_empty() {
        errln!(
            "note: {} {} no build (from before builds were recorded, or of several builds' samples): the merged film records \
             none either (build 0, unknown)",
            unknown.join(", "),
            if unknown.len() == 1 { "records" } else { "record" }
        );
    }
    let range = first.samples.start..films.iter().map(|(_, h)| h.samples.end).max().unwrap();
    // One film in memory, the sum (its memory taken fallibly: an error, not an abort, where it runs
    // out); each film's pixels are added as they are read, and its checksum checked at its end.
    let mut merged = Film::try_new(first.width, first.height).map_err(|e| {
        let names: Vec<String> = films.iter().map(|(p, _)| p.display().to_string()).collect();
        Failure::runtime(format!("cannot merge {}: the merged film: {e}", names.join(", ")))
    })?;
    for (p, h) in &films {
        let reader = FilmReader::open(p).map_err(Failure::input)?;
        if reader.header() != h {
            return Err(Failure::input(format!("{}: the film changed while the merge read it: merge again", p.display())));
        }
        reader.merge_into(&mut merged).map_err(|e| Failure::input(format!("{}: {e}", p.display())))?;
    }
    // (With --allow-gaps the range is the span the films cover, marked incomplete.)
    let provenance = Provenance { samples: range.clone(), complete: problems.is_empty(), ..Provenance::of(first) };
    // (The merged film's header first: a film --film would replace is refused before anything is written.)
    let film_out = match &a.film {
        Some(fp) => {
            let completed = vec![true; unit_count(first.width, first.height, first.tile, range.clone())];
            let h = FilmHeader { samples: range.clone(), completed, build, ..first.clone() };
            let advice = format!("finish it with `strata render ... --resume {}`", fp.display());
            if let Some(w) = super::render_cmd::check_film_replaced(fp, "--film", &h, &advice, false)? {
                errln!("warning: {w}");
            }
            Some((fp, h))
        }
        None => None,
    };
    // From here on a signal no longer quits at once (it said "nothing was written" after the image was):
    // the output being written is finished, and the merge stops after it, saying what was written.
    let film_path = film_out.as_ref().map(|(fp, _)| fp.to_path_buf());
    let writing = Arc::new(Writing::new(&out, film_path.as_deref()));
    {
        let w = writing.clone();
        super::on_signal(move || {
            if let Some(m) = w.signal() {
                errln!("{m}");
            }
            if w.quitting() {
                std::process::exit(130);
            }
        });
    }
    if !writing.begin(IMAGE) {
        // A signal has just quit (its handler ends the process).
        loop {
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
    }
    write_image_with(&out, merged.width, merged.height, &merged.to_rgb(), Some(&provenance)).map_err(Failure::runtime)?;
    if let Some((fp, h)) = film_out {
        if writing.stopped() {
            errln!("{}", writing.stopped_message(false));
            return Ok(130);
        }
        writing.begin(FILM);
        write_film(fp, &h, &merged).map_err(Failure::runtime)?;
    }
    writing.begin(DONE);
    if writing.stopped() {
        errln!("{}", writing.stopped_message(true));
        return Ok(130);
    }
    // (A partial film's range with its share of work units: `samples 0..1024` of one interrupted film
    // read as the whole render, the warning below aside.)
    let ranges: Vec<String> = films
        .iter()
        .map(|(_, h)| {
            let part = if h.is_complete() { String::new() } else { format!(" ({} of {} work units)", h.units_done(), h.completed.len()) };
            format!("{}{part}", range_text(&h.samples))
        })
        .collect();
    outln!(
        "merged {} films: samples {} of spp {} ({} samples in all); wrote {}{}",
        films.len(),
        if problems.is_empty() { range_text(&range) } else { ranges.join(", ") },
        first.spp,
        merged.total_samples(),
        out.display(),
        a.film.as_ref().map(|f| format!(" and {}", f.display())).unwrap_or_default()
    );
    for p in &problems {
        errln!("warning: {p}");
    }
    for p in &outside {
        errln!("warning: {p}: the image holds samples {start}..{end} of {spp} only, not the full render");
    }
    Ok(0)
}

/// Stages of a merge towards signals ([`Writing`]).
const CHECKING: u8 = 0;
const IMAGE: u8 = 1;
const FILM: u8 = 2;
const DONE: u8 = 3;
const QUIT: u8 = 4;

/// What a signal does to a merge: while the films are read and checked, nothing has been written, and
/// the merge quits at once saying so; once it writes (the image, then the merged film), the output being
/// written is finished (its temporary file renamed into place) and the merge stops after it, exit 130,
/// saying which outputs were written and which not. Once everything is written a signal changes nothing.
struct Writing {
    stage: AtomicU8,
    stopped: AtomicBool,
    out: String,
    film: Option<String>,
}

impl Writing {
    fn new(out: &Path, film: Option<&Path>) -> Writing {
        let film = film.map(|f| f.display().to_string());
        Writing { stage: AtomicU8::new(CHECKING), stopped: AtomicBool::new(false), out: out.display().to_string(), film }
    }

    /// Enter `stage`; false where a signal has quit first (before anything was written).
    fn begin(&self, stage: u8) -> bool {
        let mut now = self.stage.load(Ordering::SeqCst);
        loop {
            if now == QUIT {
                return false;
            }
            match self.stage.compare_exchange(now, stage, Ordering::SeqCst, Ordering::SeqCst) {
                Ok(_) => return true,
                Err(s) => now = s,
            }
        }
    }

    /// A signal arrived: what to say (the first time), and the stage moves to QUIT before any write.
    fn signal(&self) -> Option<String> {
        if self.stage.compare_exchange(CHECKING, QUIT, Ordering::SeqCst, Ordering::SeqCst).is_ok() {
            return Some("interrupted: nothing was written".into());
        }
        let stage = self.stage.load(Ordering::SeqCst);
        if stage == DONE || stage == QUIT || self.stopped.swap(true, Ordering::SeqCst) {
            return None;
        }
        Some(match (stage, &self.film) {
            (IMAGE, Some(f)) => format!("interrupted: finishing {}, then stopping (the merged film {f} will not be written)", self.out),
            (IMAGE, None) => format!("interrupted: finishing {}, please wait", self.out),
            (_, f) => {
                format!("interrupted: finishing the merged film {} ({} is written), please wait", f.as_deref().unwrap_or("?"), self.out)
            }
        })
    }

    fn quitting(&self) -> bool {
        self.stage.load(Ordering::SeqCst) == QUIT
    }

    fn stopped(&self) -> bool {
        self.stopped.load(Ordering::SeqCst)
    }

    /// The last line of a merge stopped by a signal, after the image (`all`: after the film too).
    fn stopped_message(&self, all: bool) -> String {
        match (&self.film, all) {
            (Some(f), false) => {
                format!("interrupted: wrote {} (the merged image, complete); the merged film {f} was not written", self.out)
            }
            (Some(f), true) => format!("interrupted: wrote {} and {f}: the merge is complete", self.out),
            (None, _) => format!("interrupted: wrote {}: the merge is complete", self.out),
        }
    }
}

fn range_text(r: &Range<u32>) -> String {
    format!("{}..{}", r.start, r.end)
}

/// All films must come from one render: size, scene, seed, spp, profile.
fn check_same_render(films: &[(PathBuf, FilmHeader)]) -> Result<(), String> {
    let (p0, h0) = &films[0];
    for (p, h) in &films[1..] {
        let d = h0.identity_differences(h, (&p0.display().to_string(), &p.display().to_string()));
        if !d.is_empty() {
            return Err(format!("cannot merge: {} and {} are from different renders: {}", p0.display(), p.display(), d.join("; ")));
        }
    }
    Ok(())
}

/// Films sorted by range start; any two that share a sample index are an error naming both.
fn check_overlaps(films: &[(PathBuf, FilmHeader)]) -> Result<(), String> {
    for (i, (pa, a)) in films.iter().enumerate() {
        for (pb, b) in &films[i + 1..] {
            let (ra, rb) = (&a.samples, &b.samples);
            if rb.start < ra.end {
                return Err(format!(
                    "cannot merge: overlap: {} {} and {} {} share samples {}..{}",
                    pa.display(),
                    range_text(ra),
                    pb.display(),
                    range_text(rb),
                    rb.start,
                    ra.end.min(rb.end)
                ));
            }
        }
    }
    Ok(())
}

/// Sample ranges of 0..spp covered by no film.
fn missing_ranges(spp: u32, present: &[Range<u32>]) -> Vec<Range<u32>> {
    let mut sorted = present.to_vec();
    sorted.sort_by_key(|r| r.start);
    let mut missing = Vec::new();
    let mut at = 0;
    for r in sorted {
        if r.start > at {
            missing.push(at..r.start);
        }
        at = at.max(r.end);
    }
    if at < spp {
        missing.push(at..spp);
    }
    missing
}

/// `strata merge --status`: one line per film, then the ranges present, partial and missing (in no film),
/// and those held by partial films alone.
fn status(paths: &[PathBuf]) -> Result<u8, Failure> {
    // Printed at once at the end, ignoring a closed pipe (`strata merge --status ... | head`).
    let mut out = String::new();
    macro_rules! say {
        ($($t:tt)*) => {{
            let _ = writeln!(out, $($t)*);
        }};
    }
    let mut ok: Vec<(PathBuf, FilmHeader)> = Vec::new();
    let mut failed = false;
    let width = paths.iter().map(|p| p.display().to_string().len()).max().unwrap_or(0);
    for p in paths {
        // (Every check, the checksum's too, one film at a time, its pixels not kept.)
        match verify_film(p) {
            Err(e) => {
                failed = true;
                say!("{:width$}  unreadable: {e}", p.display());
            }
            Ok(h) => {
                if let Some((p0, h0)) = ok.first() {
                    let d = h0.identity_differences(&h, (&p0.display().to_string(), &p.display().to_string()));
                    if !d.is_empty() {
                        failed = true;
                        say!("{:width$}  from a different render than {}: {}", p.display(), p0.display(), d.join("; "));
                        continue;
                    }
                }
                let pct = 100.0 * h.units_done() as f64 / h.completed.len().max(1) as f64;
                let state = if h.is_complete() { "complete".to_string() } else { format!("partial {pct:.1}%") };
                say!(
                    "{:width$}  samples {:>11}  {state} ({} of {} work units)",
                    p.display(),
                    range_text(&h.samples),
                    h.units_done(),
                    h.completed.len()
                );
                ok.push((p.clone(), h));
            }
        }
    }
    if let Some((_, h0)) = ok.first() {
        let spp = h0.spp;
        say!("render: {}x{}, scene {:016x}, seed {}, spp {spp}", h0.width, h0.height, h0.scene_hash, h0.seed);
        let complete: Vec<Range<u32>> = ok.iter().filter(|(_, h)| h.is_complete()).map(|(_, h)| h.samples.clone()).collect();
        let partial: Vec<&(PathBuf, FilmHeader)> = ok.iter().filter(|(_, h)| !h.is_complete()).collect();
        let all: Vec<Range<u32>> = ok.iter().map(|(_, h)| h.samples.clone()).collect();
        let list =
            |rs: &[Range<u32>]| if rs.is_empty() { "none".to_string() } else { rs.iter().map(range_text).collect::<Vec<_>>().join(", ") };
        let mut sorted = complete.clone();
        sorted.sort_by_key(|r| r.start);
        say!("present (complete): {}", list(&sorted));
        if !partial.is_empty() {
            let v: Vec<String> = partial.iter().map(|(p, h)| format!("{} ({})", range_text(&h.samples), p.display())).collect();
            say!("partial: {}", v.join(", "));
        }
        let missing = missing_ranges(spp, &all);
        say!("missing: {}", list(&missing));
        // Samples some partial film holds but no complete one: not missing, not done either.
        let only_partial = missing_ranges(spp, &[&complete[..], &missing[..]].concat());
        if !only_partial.is_empty() {
            say!("only in partial films: {} (resume them to complete)", list(&only_partial));
        }
        // Samples covered by complete films, each counted once where films overlap.
        let done = spp - missing_ranges(spp, &complete).iter().map(|r| r.len() as u32).sum::<u32>();
        let overlaps = overlap_lines(&ok);
        for o in &overlaps {
            say!("overlap: {o}");
        }
        say!("complete samples: {done} of {spp}{}", if done == spp && overlaps.is_empty() { " (ready to merge)" } else { "" });
    }
    let _ = std::io::stdout().write_all(out.as_bytes());
    Ok(if failed { 2 } else { 0 })
}

fn overlap_lines(films: &[(PathBuf, FilmHeader)]) -> Vec<String> {
    let mut v = Vec::new();
    for (i, (pa, a)) in films.iter().enumerate() {
        for (pb, b) in &films[i + 1..] {
            if a.samples.start < b.samples.end && b.samples.start < a.samples.end {
                v.push(format!("{} {} and {} {}", pa.display(), range_text(&a.samples), pb.display(), range_text(&b.samples)));
            }
        }
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A signal while the films are checked quits, nothing written; one while the image is written lets
    /// it finish and stops before the film, and the last line names the image as written (a user trial:
    /// "interrupted: nothing was written" after the image, and once the film, had been written).
    #[test]
    fn an_interrupted_merge_says_what_it_wrote() {
        let w = Writing::new(Path::new("m.exr"), Some(Path::new("m.film")));
        assert_eq!(w.signal().as_deref(), Some("interrupted: nothing was written"));
        assert!(w.quitting() && !w.begin(IMAGE));

        let w = Writing::new(Path::new("m.exr"), Some(Path::new("m.film")));
        assert!(w.begin(IMAGE));
        let m = w.signal().unwrap();
        assert!(!w.quitting() && w.stopped(), "{m}");
        assert!(m.contains("finishing m.exr") && m.contains("m.film will not be written") && !m.contains("nothing"), "{m}");
        assert_eq!(w.signal(), None, "said twice");
        assert_eq!(
            w.stopped_message(false),
            "interrupted: wrote m.exr (the merged image, complete); the merged film m.film was not written"
        );

        let w = Writing::new(Path::new("m.exr"), Some(Path::new("m.film")));
        assert!(w.begin(IMAGE) && w.begin(FILM));
        let m = w.signal().unwrap();
        assert!(m.contains("finishing the merged film m.film (m.exr is written)"), "{m}");
        assert!(w.begin(DONE) && w.stopped());
        assert_eq!(w.stopped_message(true), "interrupted: wrote m.exr and m.film: the merge is complete");

        // Once all is written, a signal changes nothing.
        let w = Writing::new(Path::new("m.exr"), None);
        assert!(w.begin(IMAGE) && w.begin(DONE));
        assert_eq!(w.signal(), None);
        assert!(!w.stopped() && !w.quitting());
    }

    #[test]
    fn missing_ranges_are_the_complement() {
        assert_eq!(missing_ranges(10, &[2..4, 6..8]), vec![0..2, 4..6, 8..10]);
        assert_eq!(missing_ranges(10, &[0..5, 3..10]), vec![]);
        assert_eq!(missing_ranges(4, &[]), vec![0..4]);
    }
}
