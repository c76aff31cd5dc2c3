//! Reading a scene file of many shapes section by section. `toml::from_str` builds the whole document
//! as spanned tables before serde sees it: some 3.3 KB per five-line `[[shapes]]` table (a 15 MB file of
//! 160,000 spheres peaked at 550 MB and took 0.5 s to parse, most of it the kernel zeroing fresh pages).
//! Here each run of `[[shapes]]` sections is parsed in pieces of about 256 KiB, in parallel, their spans
//! moved to where the section lies in the file, and the rest of the file (every shape section blanked
//! to spaces, so its spans are the file's) is parsed once: the same [`SceneFile`] as the whole-document
//! parse (for those 160,000 spheres 0.22 s at a 420 MB peak on 2 threads, 0.42 s one piece after
//! another at 324 MB; the setup 1.1 -> 0.82 s), which `tests` checks on every shipped scene. The rest
//! is parsed once more, as a plain table, only where it could hold a `shapes` key. Anything
//! unusual (a multi-line string, a `shapes.*` table after another table, a `shapes` key outside the
//! sections, even `shapes = []`, any error) falls back to the whole-document parse, which then gives
//! its own error messages.

use super::error::table_header;
use super::format::{SceneFile, ShapeDef, TransformDef, S};
use rayon::prelude::*;
use serde::Deserialize;
use std::ops::Range;

/// Files below this size are parsed whole (the sections would save nothing measurable).
pub const SECTIONED_MIN_BYTES: usize = 1 << 20;

/// The scene file `text` as serde reads it: section by section for large files (see the module doc),
/// else (or where that declines) as one document.
pub fn read_scene_file(text: &str) -> Result<SceneFile, toml::de::Error> {
    if text.len() >= SECTIONED_MIN_BYTES {
        if let Some(file) = sectioned(text) {
            return Ok(file);
        }
    }
    toml::from_str(text)
}

/// A run of `[[shapes]]` sections as a document of its own.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Shapes {
    shapes: Vec<S<ShapeDef>>,
}

/// Bytes of shape sections per piece (each piece's tables are freed once it is read).
const JOB_BYTES: usize = 256 << 10;

/// The section-by-section read of `text`, or `None` where it declines (see the module doc).
pub fn sectioned(text: &str) -> Option<SceneFile> {
    if text.contains("\"\"\"") || text.contains("'''") {
        return None;
    }
    // The byte ranges of runs of shape sections: from a `[[shapes]]` header to the next header that is
    // neither another `[[shapes]]` nor a `shapes.*` table of the section.
    let mut runs: Vec<Range<usize>> = Vec::new();
    let mut open: Option<usize> = None;
    let mut at = 0;
    for line in text.split_inclusive('\n') {
        if let Some((list, name)) = table_header(line) {
            let shape = name == "shapes" && list;
            let sub = name.starts_with("shapes.");
            if sub && open.is_none() {
                return None;
            }
            if !shape && !sub {
                if let Some(start) = open.take() {
                    runs.push(start..at);
                }
            } else if shape && open.is_none() {
                open = Some(at);
            }
        }
        at += line.len();
    }
    if let Some(start) = open {
        runs.push(start..text.len());
    }
    if runs.is_empty() {
        return None;
    }
    // The rest of the file, shape sections blanked (the same length: the same spans). Their line breaks
    // too: each run is then one stretch of whitespace for the lexer (a run starts at a line start, and
    // the header after it may follow whitespace).
    let mut rest = text.as_bytes().to_vec();
    for r in &runs {
        rest[r.clone()].fill(b' ');
    }
    let rest = String::from_utf8(rest).ok()?;
    // Pieces of about JOB_BYTES: whole sections of one run.
    let mut jobs: Vec<Range<usize>> = Vec::new();
    for r in &runs {
        let mut start = r.start;
        while start < r.end {
            let end = if r.end - start <= JOB_BYTES { r.end } else { next_section(text, start + JOB_BYTES, r.end) };
            jobs.push(start..end);
            start = end;
        }
    }
    // (A `shapes` key of the rest, even `shapes = []`, conflicts with the sections: the whole-document
    // parse says so. Only a rest that spells `shapes`, or has an escape that could, is parsed for it:
    // a second parse of a rest of 100,000 lights made the sections slower than the whole document.)
    if (rest.contains("shapes") || rest.contains('\\')) && toml::from_str::<toml::Table>(&rest).ok()?.contains_key("shapes") {
        return None;
    }
    let mut file = toml::from_str::<SceneFile>(&rest).ok()?;
    // The pieces in parallel (on rayon's global pool, as the light buffers' build: the setup's
    // threads), then moved into one list in order, each freed as it goes.
    let parts: Vec<Vec<S<ShapeDef>>> = jobs
        .par_iter()
        .map(|j| toml::from_str::<Shapes>(&text[j.clone()]).ok().map(|p| p.shapes.into_iter().map(|d| d.shift(j.start)).collect()))
        .collect::<Option<_>>()?;
    file.shapes.reserve_exact(parts.iter().map(Vec::len).sum());
    for part in parts {
        file.shapes.extend(part);
    }
    Some(file)
}

/// The start of the first `[[shapes]]` header line after the line holding byte `from` (which may lie
/// inside a character: the search is by bytes), or `end`.
fn next_section(text: &str, from: usize, end: usize) -> usize {
    let line_after = |from: usize| text.as_bytes()[from..end].iter().position(|&b| b == b'\n').map_or(end, |i| from + i + 1);
    let mut at = line_after(from);
    while at < end {
        let line_end = line_after(at);
        if table_header(&text[at..line_end]).is_some_and(|(list, name)| list && name == "shapes") {
            return at;
        }
        at = line_end;
    }
    end
}

/// Moving every span of a value parsed from a slice of the file by the slice's start.
trait Shift {
    fn shift(self, by: usize) -> Self;
}

impl<T: Shift> Shift for S<T> {
    fn shift(self, by: usize) -> Self {
        let span = self.span();
        S::new(span.start + by..span.end + by, self.into_inner().shift(by))
    }
}

impl<T: Shift> Shift for Option<T> {
    fn shift(self, by: usize) -> Self {
        self.map(|v| v.shift(by))
    }
}

impl<T: Shift> Shift for Box<T> {
    fn shift(self, by: usize) -> Self {
        Box::new((*self).shift(by))
    }
}

impl<T: Shift> Shift for Vec<T> {
    fn shift(self, by: usize) -> Self {
        self.into_iter().map(|v| v.shift(by)).collect()
    }
}

macro_rules! unspanned {
    ($($t:ty),*) => {
        $(impl Shift for $t {
            fn shift(self, _: usize) -> Self {
                self
            }
        })*
    };
}
unspanned!(String, f32, bool, super::format::Nums<3>);

impl Shift for TransformDef {
    fn shift(self, by: usize) -> Self {
        TransformDef { scale: self.scale.shift(by), rotate: self.rotate.shift(by), translate: self.translate.shift(by) }
    }
}

impl Shift for ShapeDef {
    fn shift(self, by: usize) -> Self {
        // (Destructured: a field added to `ShapeDef` fails to compile here until it is shifted too.)
        let ShapeDef {
            kind,
            use_solid,
            material,
            center,
            radius,
            point,
            normal,
            min,
            max,
            origin,
            u,
            v,
            height,
            radius_top,
            major_radius,
            minor_radius,
            motion,
            transform,
            op,
            children,
            hole,
        } = self;
        ShapeDef {
            kind: kind.shift(by),
            use_solid: use_solid.shift(by),
            material: material.shift(by),
            center: center.shift(by),
            radius: radius.shift(by),
            point: point.shift(by),
            normal: normal.shift(by),
            min: min.shift(by),
            max: max.shift(by),
            origin: origin.shift(by),
            u: u.shift(by),
            v: v.shift(by),
            height: height.shift(by),
            radius_top: radius_top.shift(by),
            major_radius: major_radius.shift(by),
            minor_radius: minor_radius.shift(by),
            motion: motion.shift(by),
            transform: transform.shift(by),
            op: op.shift(by),
            children: children.shift(by),
            hole: hole.shift(by),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The section-by-section read gives the whole-document parse's `SceneFile`, spans included (their
    /// `Debug` forms are equal), on every shipped scene and on scenes of many shapes with `shapes.*`
    /// sub-tables, CSG children, comments and other tables between the shapes; and it declines what it
    /// does not handle.
    #[test]
    fn sections_equal_the_whole_document() {
        let mut scenes: Vec<(String, String)> = std::fs::read_dir("scenes")
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .map(|p| (p.display().to_string(), std::fs::read_to_string(&p).unwrap()))
            .collect();
        assert!(scenes.len() >= 10);
        // Many shapes, several jobs: sub-tables, nested CSG, comments, a light and a material between
        // runs of shapes.
        let mut big = String::from("[image]\nwidth = 32\nheight = 24\n[camera]\nposition = [0, 1, 5]\nlook_at = [0, 0, 0]\nfov = 40\n");
        big += "[materials.a]\ntype = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\n";
        for i in 0..6000 {
            match i % 4 {
                0 => big += &format!("[[shapes]] # sphere {i}\ntype = \"sphere\"\ncenter = [{i}, 0, 0]\nradius = 0.5\nmaterial = \"a\"\n"),
                1 => big += &format!(
                    "[[shapes]]\ntype = \"box\"\nmin = [0, 0, 0]\nmax = [1, 1, 1]\nmaterial = \"a\"\n[shapes.transform]\nrotate = [0, {i}, 0]\n"
                ),
                2 => big += &format!(
                    "[[shapes]]\ntype = \"csg\"\nop = \"difference\"\nmaterial = \"a\"\n[[shapes.children]]\ntype = \"sphere\"\ncenter = [0, 0, {i}]\nradius = 1\n\
                     [[shapes.children]]\ntype = \"torus\"\nmajor_radius = 0.5\nminor_radius = 0.1\n"
                ),
                _ => big += &format!("\n[[shapes]]\ntype = \"quad\"\norigin = [0, 0, 0]\nu = [1, 0, 0]\nv = [0, 0, {i}]\nmaterial = \"a\"\n"),
            }
            if i % 1500 == 700 {
                big += &format!(
                    "[[lights]]\ntype = \"point\"\nposition = [0, {i}, 0]\nintensity = [1, 1, 1]\n[materials.m{i}]\ntype = \"mirror\"\n"
                );
            }
        }
        assert!(big.len() > 2 * JOB_BYTES);
        // The same with a multi-byte comment on every shape (a piece's end then falls inside a
        // character: a review's panic), and with CRLF line breaks.
        let wide = big.replace("[[shapes]]\n", "[[shapes]] # 球体 · café\n");
        let crlf = big.replace('\n', "\r\n");
        // Quoted list headers (`[["shapes"]]`, `[[ 'shapes' ]]`), which `table_header` reads as `shapes`.
        let quoted = big
            .replace("[[shapes]] # sphere", "[[\"shapes\"]] # sphere")
            .replace("[[shapes]]\ntype = \"box\"", "[[ 'shapes' ]]\ntype = \"box\"");
        scenes.extend([("big".into(), big), ("multi-byte".into(), wide), ("crlf".into(), crlf), ("quoted".into(), quoted)]);
        let mut compared = 0;
        for (name, text) in &scenes {
            let whole: SceneFile = toml::from_str(text).unwrap();
            let Some(parts) = sectioned(text) else {
                assert!(whole.shapes.is_empty(), "{name}: declined");
                continue;
            };
            assert_eq!(format!("{parts:?}"), format!("{whole:?}"), "{name}");
            compared += whole.shapes.len();
        }
        assert!(compared > 24_000, "{compared} shapes compared");
        // A piece's end inside a character (a review's panic): the next section after that line.
        let two = "[[shapes]] # é\ntype = \"sphere\"\n[[shapes]] # é\nradius = 1\n";
        let inside = two.find('é').unwrap() + 1;
        assert!(!two.is_char_boundary(inside));
        assert_eq!(next_section(two, inside, two.len()), two.rfind("[[shapes]]").unwrap());
        // Declined: a `shapes.*` table after another table, a multi-line string, an inline array of
        // shapes beside the sections, a section that does not parse.
        let head = "[image]\nwidth = 4\nheight = 4\n[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\nfov = 40\n";
        let sphere = "[[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\n";
        for odd in [
            format!("{head}{sphere}[materials.a]\ntype = \"lambert\"\n[shapes.transform]\nscale = [1, 1, 1]\n"),
            format!("{head}{sphere}material = \"\"\"a\"\"\"\n"),
            format!("shapes = [{{ type = \"sphere\" }}]\n{head}{sphere}"),
            format!("shapes = []\n{head}{sphere}"),
            // (`shapes` spelt with escapes: the rest does not contain the word.)
            format!("\"sh\\u0061pes\" = []\n{head}{sphere}"),
            format!("\"\\x73hapes\" = []\n{head}{sphere}"),
            format!("{head}{sphere}radius = 2\n"),
        ] {
            assert!(sectioned(&odd).is_none(), "{odd}");
        }
    }
}
