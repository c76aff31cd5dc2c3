//! Film files: the raw accumulation of a render (or of a sample range of it) with everything needed to
//! resume it or to merge it exactly with other ranges.
//!
//! The pixel sums are the film's own 128-bit fixed-point integers, so a film written and read back is the
//! same film bit for bit, and films of disjoint sample ranges add up to exactly the film of their union.
//!
//! # Layout (version 2; version 1, read too, has no build field)
//!
//! All integers little-endian; no padding.
//!
//! ```text
//! offset    size         field
//! 0         8            magic "STRATAFM"
//! 8         4   u32      format version (2)
//! 12        4   u32      width
//! 16        4   u32      height
//! 20        4   u32      spp: samples per pixel of the whole render (the profile's)
//! 24        4   u32      sample range start (first sample index in this film)
//! 28        4   u32      sample range end (exclusive)
//! 32        4   u32      tile side of the work units
//! 36        4   u32      U: number of work units of the range (tiles x sample batches, in render order)
//! 40        8   u64      scene hash (Scene::hash: FNV-1a of the scene file's text)
//! 48        8   u64      seed
//! 56        8   u64      profile hash: xxh64 of the profile record below
//! 64        4   u32      P: length of the profile record
//! 68        P            profile record: the profile as JSON (fields in declaration order, name omitted)
//! 68+P      8   u64      build: xxh64 of the strata executable that rendered it (0: unknown, or several)
//! 76+P      ceil(U/8)    completed work units: bit (i mod 8) of byte i/8 is unit i; unused bits zero
//! ...       104 x W x H  pixels, row-major, each: sum r g b (3 x i128), sum of squares r g b
//!                        (3 x i128), sample count (u64); sums in units of 2^-32
//! end-8     8   u64      checksum: xxh64 (seed 0) of every preceding byte
//! ```
//!
//! A film is consistent: its pixels hold exactly the samples of the work units marked complete (the
//! render driver snapshots it between units). Reading checks the magic, the version, the size implied by
//! the header, the checksum, the header's own consistency and every pixel's (its count at most the samples
//! of the completed units that cover it, its sums within what that many samples can give:
//! [`Pixel::inconsistency`]), and says which failed. Writing is atomic
//! (temporary file in the same directory, synced, renamed), so a checkpoint interrupted mid-write leaves
//! the previous checkpoint intact.
//!
//! Both stream: a file is never held whole in memory (at 7680 x 4320 it is 3.45 GB, the film 2.1 GB). The
//! header is read and checked first ([`FilmReader`], [`read_film_header`]), so that a film of another
//! render is refused before a pixel is read; the pixels then go straight into one film (or are added to
//! one: a merge), hashed as they are read, and the checksum is checked at the end. Writing encodes a
//! chunk of pixels at a time into a buffered file, hashed as it goes: the same bytes as [`encode`].

use super::checksum::{xxh64, Xxh64};
use super::output::write_atomic;
use super::{Film, Pixel};
use crate::scene::Profile;
use std::io::{Read, Write};
use std::ops::Range;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

pub const MAGIC: [u8; 8] = *b"STRATAFM";
pub const VERSION: u32 = 2;
/// Bytes before the profile record.
pub const FIXED_HEADER: usize = 68;
/// Bytes per pixel record.
pub const PIXEL_BYTES: usize = 6 * 16 + 8;
/// Largest accepted profile record (a real one is a few hundred bytes).
const MAX_PROFILE_RECORD: usize = 1 << 16;

/// Everything in a film file but the pixels.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FilmHeader {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub samples: Range<u32>,
    pub tile: u32,
    pub scene_hash: u64,
    pub seed: u64,
    /// The profile as JSON (see [`profile_record`]).
    pub profile: String,
    /// One flag per work unit of `samples` (in [`crate::render::work_units`] order).
    pub completed: Vec<bool>,
    /// The [`build_id`] of the strata that rendered it: 0 where unknown (a version-1 film) or several
    /// (a film resumed or merged across builds). Not part of its identity: films of other builds merge
    /// and resume, with a warning (their images match neither build's one-process render bit for bit).
    pub build: u64,
}

/// This strata's build: xxh64 of its executable (another build, a pulled change or a local edit, gives
/// another; 10-40 ms for a 46 MB executable, once per process, and only where a film is written or
/// read); 0 where the executable cannot be read. On Linux the running image is read through
/// `/proc/self/exe`, which still opens it after the file at its path was replaced (a rebuild during a
/// render) or deleted; elsewhere, the file at its path.
pub fn build_id() -> u64 {
    static ID: std::sync::OnceLock<u64> = std::sync::OnceLock::new();
    *ID.get_or_init(|| {
        #[cfg(target_os = "linux")]
        if let Ok(bytes) = std::fs::read("/proc/self/exe") {
            return xxh64(&bytes).max(1);
        }
        std::env::current_exe().and_then(std::fs::read).map_or(0, |bytes| xxh64(&bytes).max(1))
    })
}

/// The warning for films of other builds than `this` among `films` (name, build), or None: builds 0
/// (unknown) are not compared.
pub fn other_builds_warning(films: &[(String, u64)], this: u64, what: &str) -> Option<String> {
    let others: Vec<&str> = films.iter().filter(|(_, b)| *b != 0 && this != 0 && *b != this).map(|(n, _)| n.as_str()).collect();
    (!others.is_empty()).then(|| {
        format!(
            "warning: {} rendered by another build of strata than {what}: the image is what each build's samples \
             give, and matches no single build's one-process render bit for bit",
            if others.len() == 1 { format!("{} was", others[0]) } else { format!("{} were", others.join(", ")) }
        )
    })
}

/// A film with its header.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FilmFile {
    pub header: FilmHeader,
    pub film: Film,
}

/// The profile as stored in a film: JSON in field-declaration order (serde_json keeps it), without the
/// name, which is only a label: `--profile final` and a copy of final.toml render the same image.
pub fn profile_record(p: &Profile) -> String {
    let mut p = p.clone();
    p.name.clear();
    serde_json::to_string(&p).expect("a profile always serializes")
}

impl FilmHeader {
    /// The header of a render of `samples` of `scene` under `profile` and `seed` in units of `tile`, no
    /// unit done yet, its build not yet stamped (0: [`FilmHeader::stamped`] stamps it where a film is
    /// written, so that a render that writes none does not read its own executable).
    pub fn fresh(scene: &crate::scene::Scene, profile: &Profile, samples: Range<u32>, tile: u32, seed: u64) -> FilmHeader {
        let n_units = crate::render::unit_count(scene.width, scene.height, tile, samples.clone());
        FilmHeader {
            width: scene.width,
            height: scene.height,
            spp: profile.spp,
            samples,
            tile,
            scene_hash: scene.hash,
            seed,
            profile: profile_record(profile),
            completed: vec![false; n_units],
            build: 0,
        }
    }

    /// This header with `completed`, stamped with this strata's [`build_id`], or 0 for a film whose
    /// samples come from several builds (`mixed`).
    pub fn stamped(&self, completed: Vec<bool>, mixed: bool) -> FilmHeader {
        FilmHeader { completed, build: if mixed { 0 } else { build_id() }, ..self.clone() }
    }

    pub fn profile_hash(&self) -> u64 {
        xxh64(self.profile.as_bytes())
    }

    pub fn units_done(&self) -> usize {
        self.completed.iter().filter(|&&c| c).count()
    }

    pub fn is_complete(&self) -> bool {
        self.completed.iter().all(|&c| c)
    }

    /// Differences that make two films belong to different renders (image size, scene, seed, spp,
    /// profile), described as `what: <self> vs <other>`. The sample range and tile are not compared.
    pub fn identity_differences(&self, other: &FilmHeader, names: (&str, &str)) -> Vec<String> {
        let (a, b) = names;
        let mut d = Vec::new();
        if (self.width, self.height) != (other.width, other.height) {
            d.push(format!("image size: {a} {}x{}, {b} {}x{}", self.width, self.height, other.width, other.height));
        }
        if self.scene_hash != other.scene_hash {
            d.push(format!("scene: {a} {:016x}, {b} {:016x} (the scene file's text differs)", self.scene_hash, other.scene_hash));
        }
        if self.seed != other.seed {
            d.push(format!("seed: {a} {}, {b} {}", self.seed, other.seed));
        }
        if self.spp != other.spp {
            d.push(format!("spp: {a} {}, {b} {}", self.spp, other.spp));
        }
        if self.profile != other.profile {
            d.push(format!("profile: {}", profile_differences(&self.profile, &other.profile, names)));
        }
        d
    }
}

/// Which profile fields differ between two records, e.g. `light_samples film 2, this render 4`.
fn profile_differences(x: &str, y: &str, (a, b): (&str, &str)) -> String {
    let parse = |s: &str| serde_json::from_str::<serde_json::Map<String, serde_json::Value>>(s).unwrap_or_default();
    let (px, py) = (parse(x), parse(y));
    let keys: std::collections::BTreeSet<&String> = px.keys().chain(py.keys()).collect();
    // A field left out of a record is at its default: `light_selection` is written only when not "all"
    // (`Profile::light_selection`); others are older renderers' records, which lack newer fields.
    let show = |k: &str, v: Option<&serde_json::Value>| match v {
        Some(v) => v.to_string(),
        None if k == "light_selection" => "\"all\"".into(),
        None => "absent".into(),
    };
    let diffs: Vec<String> = keys
        .into_iter()
        .filter(|k| px.get(*k) != py.get(*k))
        .map(|k| format!("{k} {a} {}, {b} {}", show(k, px.get(k)), show(k, py.get(k))))
        .collect();
    if diffs.is_empty() {
        "the profile records differ".into()
    } else {
        diffs.join("; ")
    }
}

/// The header's bytes: everything before the pixels.
pub fn header_bytes(header: &FilmHeader) -> Vec<u8> {
    let n_units = header.completed.len();
    let mut out = Vec::with_capacity(FIXED_HEADER + header.profile.len() + 8 + n_units.div_ceil(8));
    out.extend_from_slice(&MAGIC);
    for v in [VERSION, header.width, header.height, header.spp, header.samples.start, header.samples.end, header.tile, n_units as u32] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for v in [header.scene_hash, header.seed, header.profile_hash()] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out.extend_from_slice(&(header.profile.len() as u32).to_le_bytes());
    out.extend_from_slice(header.profile.as_bytes());
    out.extend_from_slice(&header.build.to_le_bytes());
    let mut bits = vec![0u8; n_units.div_ceil(8)];
    for (i, _) in header.completed.iter().enumerate().filter(|(_, &c)| c) {
        bits[i / 8] |= 1 << (i % 8);
    }
    out.extend_from_slice(&bits);
    out
}

/// Pixels encoded (or decoded) at a time: 416 KiB of records.
const CHUNK_PIXELS: usize = 4096;

/// Write a film file (header, pixels, checksum) to `w`, pixel records a chunk at a time and hashed as
/// they go: the same bytes as [`encode`], without the whole file in memory.
pub fn write_film_to<W: Write>(w: &mut W, header: &FilmHeader, film: &Film) -> std::io::Result<()> {
    write_film_until(w, header, film, &|| false).map(|_| ())
}

/// [`write_film_to`], stopping between chunks where `stop` says so: whether it wrote the whole film.
fn write_film_until<W: Write>(w: &mut W, header: &FilmHeader, film: &Film, stop: &dyn Fn() -> bool) -> std::io::Result<bool> {
    assert_eq!((header.width, header.height), (film.width, film.height), "film and header sizes differ");
    let mut hash = Xxh64::new();
    let head = header_bytes(header);
    hash.update(&head);
    w.write_all(&head)?;
    let mut chunk = Vec::with_capacity(CHUNK_PIXELS.min(film.len()) * PIXEL_BYTES);
    for start in (0..film.len()).step_by(CHUNK_PIXELS) {
        if stop() {
            return Ok(false);
        }
        chunk.clear();
        for i in start..(start + CHUNK_PIXELS).min(film.len()) {
            let p = film.pixel(i);
            for v in p.sum.iter().chain(&p.sum_sq) {
                chunk.extend_from_slice(&v.to_le_bytes());
            }
            chunk.extend_from_slice(&p.count.to_le_bytes());
        }
        hash.update(&chunk);
        w.write_all(&chunk)?;
    }
    w.write_all(&hash.finish().to_le_bytes())?;
    Ok(true)
}

/// Serialize a film file (header, pixels, checksum) into memory (small films and tests; files are
/// written streaming, [`write_film`]).
pub fn encode(header: &FilmHeader, film: &Film) -> Vec<u8> {
    let mut out =
        Vec::with_capacity(FIXED_HEADER + header.profile.len() + 8 + header.completed.len().div_ceil(8) + film.len() * PIXEL_BYTES + 8);
    write_film_to(&mut out, header, film).expect("writing to memory does not fail");
    out
}

/// The bytes of a film file being read: those before the checksum (`left` of them still unread) go
/// through the hash as they are read.
struct Source<R: Read> {
    r: R,
    hash: Xxh64,
    left: u64,
}

impl<R: Read> Source<R> {
    /// The next `buf.len()` bytes (within the checksummed part: the caller checked the length).
    fn fill(&mut self, buf: &mut [u8]) -> Result<(), String> {
        debug_assert!(buf.len() as u64 <= self.left);
        self.r.read_exact(buf).map_err(|e| format!("reading: {e}"))?;
        self.hash.update(buf);
        self.left -= buf.len() as u64;
        Ok(())
    }
    fn u64(&mut self) -> Result<u64, String> {
        let mut b = [0; 8];
        self.fill(&mut b)?;
        Ok(u64::from_le_bytes(b))
    }
    /// Whether the stored checksum matches the bytes before it, reading (and hashing) what is left of
    /// them first, a chunk at a time.
    fn checksum_holds(&mut self) -> Result<bool, String> {
        let mut buf = vec![0u8; (self.left.min(1 << 20)) as usize];
        while self.left > 0 {
            let n = self.left.min(buf.len() as u64) as usize;
            self.fill(&mut buf[..n])?;
        }
        let mut stored = [0; 8];
        self.r.read_exact(&mut stored).map_err(|e| format!("reading: {e}"))?;
        Ok(self.hash.finish() == u64::from_le_bytes(stored))
    }
}

/// A film file whose header has been read and checked, its pixels not yet read: the header can be
/// compared with a render's before a byte of the pixels is read (or memory taken for them), and the
/// pixels are then read straight into a film ([`FilmReader::read_into`]) or added to one
/// ([`FilmReader::merge_into`]), never held as bytes. The checksum, which covers the whole file, is
/// checked when the pixels have been read: a film whose header reads is not yet known to be intact.
pub struct FilmReader<R: Read> {
    header: FilmHeader,
    src: Source<R>,
}

impl FilmReader<std::io::BufReader<std::fs::File>> {
    /// Open a film file and read its header; errors start with the path.
    pub fn open(path: &Path) -> Result<Self, String> {
        let at = |e: String| format!("{}: {e}", path.display());
        let f = std::fs::File::open(path).map_err(|e| at(e.to_string()))?;
        // Not a pipe or a device (`/dev/zero` would be read until memory runs out), nor beyond the
        // largest film a render can write.
        let meta = f.metadata().map_err(|e| at(e.to_string()))?;
        if !meta.is_file() {
            return Err(at("not a regular file (a film is read from a file)".into()));
        }
        if meta.len() > MAX_FILM_BYTES {
            return Err(at(format!("larger than any film strata writes ({MAX_FILM_BYTES} bytes at most): not a film")));
        }
        FilmReader::new(std::io::BufReader::with_capacity(1 << 16, f), meta.len()).map_err(at)
    }
}

impl<R: Read> FilmReader<R> {
    /// Read and check the header of the `len`-byte film file `r`. Errors say what is wrong, without the
    /// path, and are those reading the whole file gives: where the header is inconsistent or implies
    /// another length, the rest of the file is hashed (nothing kept) to tell a corrupted file (checksum
    /// mismatch) from one written so by something else than strata.
    pub fn new(r: R, len: u64) -> Result<Self, String> {
        let mut fixed = [0u8; FIXED_HEADER];
        let head = len.min(FIXED_HEADER as u64) as usize;
        // (A file of the header's length at least: the fixed header lies in the checksummed bytes.)
        let mut src = Source { r, hash: Xxh64::new(), left: len.saturating_sub(8) };
        if len >= FIXED_HEADER as u64 + 8 {
            src.fill(&mut fixed)?;
        } else {
            src.r.read_exact(&mut fixed[..head]).map_err(|e| format!("reading: {e}"))?;
        }
        let bytes = &fixed[..head];
        if len < 12 || bytes[..8] != MAGIC {
            return Err(if len >= 8 && bytes[..8] != MAGIC {
                "not a Strata film file (bad magic; expected \"STRATAFM\")".to_string()
            } else {
                format!("not a Strata film file (only {len} bytes)")
            });
        }
        let version = u32::from_le_bytes(bytes[8..12].try_into().unwrap());
        if version != VERSION && version != 1 {
            return Err(format!("film format version {version} is not supported (this strata reads versions 1 and {VERSION})"));
        }
        if len < FIXED_HEADER as u64 + 8 {
            return Err(format!("truncated: {len} bytes is shorter than the {}-byte header", FIXED_HEADER + 8));
        }
        let mut c = Cursor { bytes: &fixed, at: 8 };
        let version = c.u32();
        let build_bytes = if version >= 2 { 8 } else { 0 };
        let (width, height, spp) = (c.u32(), c.u32(), c.u32());
        let samples = c.u32()..c.u32();
        let (tile, n_units) = (c.u32(), c.u32() as usize);
        let (scene_hash, seed, profile_hash) = (c.u64(), c.u64(), c.u64());
        let profile_len = c.u32() as usize;

        // The size the header implies (u128: a corrupted header must not overflow the arithmetic).
        let expected = FIXED_HEADER as u128
            + profile_len as u128
            + build_bytes
            + n_units.div_ceil(8) as u128
            + width as u128 * height as u128 * PIXEL_BYTES as u128
            + 8;
        if expected != len as u128 {
            return Err(if !src.checksum_holds()? {
                format!("truncated or corrupted: the header implies {expected} bytes, the file has {len} (checksum mismatch)")
            } else {
                format!("size mismatch: the header implies {expected} bytes, the file has {len}")
            });
        }

        // With a checksum that holds, these can only fail for a file written by something else than
        // strata; with one that does not, the file is corrupted, which is said instead.
        let header = (|| -> Result<Result<FilmHeader, String>, String> {
            let bad = |m: String| Ok(Err(format!("inconsistent header: {m}")));
            if width == 0 || height == 0 || width > crate::scene::MAX_IMAGE_SIDE as u32 || height > crate::scene::MAX_IMAGE_SIDE as u32 {
                return bad(format!("image size {width}x{height}"));
            }
            if !(samples.start < samples.end && samples.end <= spp) {
                return bad(format!("sample range {}..{} of spp {spp}", samples.start, samples.end));
            }
            if tile == 0 {
                return bad("tile side 0".into());
            }
            let want_units = crate::render::unit_count(width, height, tile, samples.clone());
            if n_units != want_units {
                return bad(format!("{n_units} work units, the size, tile and range give {want_units}"));
            }
            if profile_len > MAX_PROFILE_RECORD {
                return bad(format!("profile record of {profile_len} bytes"));
            }
            let mut record = vec![0u8; profile_len];
            src.fill(&mut record)?;
            let Ok(profile) = String::from_utf8(record) else { return bad("profile record is not UTF-8".into()) };
            if xxh64(profile.as_bytes()) != profile_hash {
                return bad("profile hash does not match the profile record".into());
            }
            if let Err(e) = serde_json::from_str::<Profile>(&profile) {
                return bad(format!("profile record: {e}"));
            }
            let build = if version >= 2 { src.u64()? } else { 0 };
            let mut bits = vec![0u8; n_units.div_ceil(8)];
            src.fill(&mut bits)?;
            let completed: Vec<bool> = (0..n_units).map(|i| bits[i / 8] >> (i % 8) & 1 == 1).collect();
            if n_units % 8 != 0 && bits[n_units / 8] >> (n_units % 8) != 0 {
                return bad("bits set past the last work unit".into());
            }
            Ok(Ok(FilmHeader { width, height, spp, samples: samples.clone(), tile, scene_hash, seed, profile, completed, build }))
        })()?;
        match header {
            Ok(header) => Ok(FilmReader { header, src }),
            Err(_) if !src.checksum_holds()? => Err(CORRUPTED.to_string()),
            Err(e) => Err(e),
        }
    }

    pub fn header(&self) -> &FilmHeader {
        &self.header
    }

    /// Read the pixels, handing each to `sink` (index, pixel) in order, then check the checksum. Each
    /// pixel is checked first ([`Pixel::inconsistency`]): its count against the samples of the
    /// completed work units that cover it, its sums against what that count of samples can give. At
    /// the first that fails (or that `sink` refuses, saying why) no further pixel goes to `sink`, the
    /// rest of the file is hashed, and the error is the checksum's where it does not hold (a corrupted
    /// file), else the pixel's, naming it (x, y): a file written so by something else than strata.
    fn pixels(mut self, mut sink: impl FnMut(usize, Pixel) -> Result<(), String>) -> Result<FilmHeader, String> {
        let (w, h) = (self.header.width, self.header.height);
        let n = w as usize * h as usize;
        // The samples each pixel holds: those of its tile's completed units (one table of tiles, and
        // each column's tile; a row adds its first tile's index).
        let units = crate::render::WorkUnits::new(w, h, self.header.tile, self.header.samples.clone());
        let per_tile = units.tile_samples(&self.header.completed);
        let column: Vec<usize> = (0..w).map(|x| units.column_of(x)).collect();
        let mut buf = vec![0u8; CHUNK_PIXELS.min(n) * PIXEL_BYTES];
        let mut bad = None;
        let (mut x, mut y) = (0usize, 0u32);
        let mut row = units.row_of(0);
        'read: for start in (0..n).step_by(CHUNK_PIXELS) {
            let m = (n - start).min(CHUNK_PIXELS);
            let chunk = &mut buf[..m * PIXEL_BYTES];
            self.src.fill(chunk)?;
            for (k, rec) in chunk.chunks_exact(PIXEL_BYTES).enumerate() {
                let v = |j: usize| i128::from_le_bytes(rec[16 * j..16 * j + 16].try_into().unwrap());
                let count = u64::from_le_bytes(rec[96..104].try_into().unwrap());
                let p = Pixel { sum: [v(0), v(1), v(2)], sum_sq: [v(3), v(4), v(5)], count };
                let why = match p.inconsistency(per_tile[row + column[x]]) {
                    None => sink(start + k, p).err(),
                    why => why,
                };
                if let Some(why) = why {
                    bad = Some(format!("inconsistent pixel ({x}, {y}): {why}"));
                    break 'read;
                }
                x += 1;
                if x == w as usize {
                    (x, y) = (0, y + 1);
                    row = units.row_of(y);
                }
            }
        }
        if !self.src.checksum_holds()? {
            return Err(CORRUPTED.to_string());
        }
        match bad {
            Some(e) => Err(e),
            None => Ok(self.header),
        }
    }

    /// Read the pixels into `film` (a film of the header's size, as [`Film::try_new`] gives it), each
    /// replacing the film's; the header once the checksum and every pixel hold (else the film holds
    /// what was read).
    pub fn read_into(self, film: &mut Film) -> Result<FilmHeader, String> {
        assert_eq!((film.width, film.height), (self.header.width, self.header.height), "film and header sizes differ");
        self.pixels(|i, p| {
            film.set_pixel(i, p);
            Ok(())
        })
    }

    /// Add the pixels to `film`'s (exact: as [`Film::merge`]); the header once the checksum and every
    /// pixel hold. A sum that would overflow is an error, not a wrap (films of one render's disjoint
    /// ranges cannot reach it: see [`Pixel::merge`]). Where it fails, `film` holds the pixels read
    /// added: the caller discards it.
    pub fn merge_into(self, film: &mut Film) -> Result<FilmHeader, String> {
        assert_eq!((film.width, film.height), (self.header.width, self.header.height), "film and header sizes differ");
        self.pixels(|i, p| {
            if film.try_merge_pixel(i, &p) {
                Ok(())
            } else {
                Err(format!("its sums added to the film's ({:?}) overflow", film.pixel(i)))
            }
        })
    }

    /// Check the whole file (the checksum and every pixel) without keeping its pixels: the header of an
    /// intact film.
    pub fn verify(self) -> Result<FilmHeader, String> {
        self.pixels(|_, _| Ok(()))
    }

    /// The whole film, in a film allocated for it (fallibly: an error where memory runs out).
    pub fn read(self) -> Result<FilmFile, String> {
        let mut film = Film::try_new(self.header.width, self.header.height)?;
        let header = self.read_into(&mut film)?;
        Ok(FilmFile { header, film })
    }
}

const CORRUPTED: &str = "corrupted: checksum mismatch (the file was changed after it was written)";

/// Little-endian reader over a byte slice whose length has already been checked.
struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Cursor<'_> {
    fn take(&mut self, n: usize) -> &[u8] {
        let s = &self.bytes[self.at..self.at + n];
        self.at += n;
        s
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take(4).try_into().unwrap())
    }
    fn u64(&mut self) -> u64 {
        u64::from_le_bytes(self.take(8).try_into().unwrap())
    }
    #[cfg(test)]
    fn i128(&mut self) -> i128 {
        i128::from_le_bytes(self.take(16).try_into().unwrap())
    }
}

/// Parse and validate a film file held in memory. Errors say what is wrong, without the path (the
/// caller adds it).
pub fn decode(bytes: &[u8]) -> Result<FilmFile, String> {
    FilmReader::new(bytes, bytes.len() as u64)?.read()
}

/// Read and validate a film file, streaming its pixels into one film; errors start with the path.
pub fn read_film(path: &Path) -> Result<FilmFile, String> {
    let reader = FilmReader::open(path)?;
    reader.read().map_err(|e| format!("{}: {e}", path.display()))
}

/// Read and check a film file's header alone (a few KB: the pixels are not read, nor the checksum
/// checked, which [`read_film`] and [`verify_film`] do); errors start with the path.
pub fn read_film_header(path: &Path) -> Result<FilmHeader, String> {
    Ok(FilmReader::open(path)?.header)
}

/// Read and validate a film file as [`read_film`] does (every check, the checksum's too), keeping only
/// its header: memory for a buffer, not the film; errors start with the path.
pub fn verify_film(path: &Path) -> Result<FilmHeader, String> {
    FilmReader::open(path)?.verify().map_err(|e| format!("{}: {e}", path.display()))
}

/// The largest film file: the largest image's pixels, plus 64 MiB for the header, the profile record and
/// the work units' completion bits (at most 8.4 MB: one bit per unit of the largest render).
pub const MAX_FILM_BYTES: u64 = crate::scene::MAX_PIXELS * PIXEL_BYTES as u64 + (64 << 20);

/// Write a film file atomically (temporary file, fsync, rename), streaming: the pixels are encoded a
/// chunk at a time into a buffered writer, never as a whole file in memory.
pub fn write_film(path: &Path, header: &FilmHeader, film: &Film) -> Result<(), String> {
    write_film_unless(path, header, film, &AtomicBool::new(false)).map(|_| ())
}

/// [`write_film`], given up where `stop` is set while it writes (a checkpoint that the render's final
/// film supersedes): its temporary file is removed and the file at `path` left as it was. Whether it
/// wrote the film.
pub fn write_film_unless(path: &Path, header: &FilmHeader, film: &Film, stop: &AtomicBool) -> Result<bool, String> {
    let stopped = AtomicBool::new(false);
    let written = write_atomic(path, |tmp| {
        let at = |e: std::io::Error| format!("{}: {e}", path.display());
        let f = std::fs::File::create(tmp).map_err(at)?;
        let mut w = std::io::BufWriter::with_capacity(1 << 20, f);
        if !write_film_until(&mut w, header, film, &|| stop.load(Ordering::Relaxed)).map_err(at)? {
            stopped.store(true, Ordering::Relaxed);
            return Err("stopped".into());
        }
        let f = w.into_inner().map_err(|e| at(e.into_error()))?;
        f.sync_all().map_err(at)
    });
    match written {
        Err(_) if stopped.load(Ordering::Relaxed) => Ok(false),
        r => r.map(|_| true),
    }
}

/// A new film (`--film`) named as an image is a slip: another program would take it for an image and
/// fail. (A film being resumed keeps whatever name it has.)
pub fn check_film_name(path: &Path) -> Result<(), String> {
    match path.extension().and_then(|e| e.to_str()).filter(|e| ["png", "exr"].contains(&e.to_ascii_lowercase().as_str())) {
        Some(ext) => Err(format!("{}: a film is not an image (`.{ext}`): name it `.film`", path.display())),
        None => Ok(()),
    }
}

/// Check before rendering that a film can be written at `path` (its directory exists and is writable).
pub fn check_film_writable(path: &Path) -> Result<(), String> {
    if path.file_name().is_none() || path.is_dir() {
        return Err(format!("{}: not a file name", path.display()));
    }
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(format!("{}: directory {} does not exist", path.display(), dir.display()));
    }
    let probe = dir.join(format!(".strata-probe.{}", std::process::id()));
    std::fs::write(&probe, b"").map_err(|e| format!("{}: cannot write here: {e}", path.display()))?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::film::{MAX_QUANTIZED, MAX_SQUARE_TERM};

    /// The samples each pixel of `h`'s film holds by its completed work units (row-major), from the
    /// list of work units (not the reader's table of tiles).
    fn held(h: &FilmHeader) -> Vec<u64> {
        let mut n = vec![0u64; h.width as usize * h.height as usize];
        for (u, _) in crate::render::work_units(h.width, h.height, h.tile, h.samples.clone()).iter().zip(&h.completed).filter(|(_, &c)| c) {
            for y in u.tile.y0..u.tile.y1 {
                for x in u.tile.x0..u.tile.x1 {
                    n[(y * h.width + x) as usize] += u.samples.len() as u64;
                }
            }
        }
        n
    }

    /// Fill `film` with pixels a render of `h` can give: each holds the samples of its completed units
    /// (one fewer for every `discard`-th: a discarded sample), its sums in range; where `wide(i)` and
    /// it holds 2 samples or more, sums beyond 64 bits (near their bound) of both signs.
    fn fill(h: &FilmHeader, film: &mut Film, discard: usize, wide: impl Fn(usize) -> bool) {
        let held = held(h);
        for (i, &held) in held.iter().enumerate() {
            let count = held - (held > 0 && (i + 1) % discard == 0) as u64;
            let n = count as i128;
            let p = if count == 0 {
                Pixel::default()
            } else if wide(i) && count >= 2 {
                Pixel { sum: [n * MAX_QUANTIZED - i as i128, -n * MAX_QUANTIZED, 3], sum_sq: [n * MAX_SQUARE_TERM, 0, 1 << 50], count }
            } else {
                Pixel { sum: [i as i128 - 7, i as i128 * 1000, -(1i128 << 40)], sum_sq: [1, 2, i as i128 * 11], count }
            };
            film.set_pixel(i, p);
        }
    }

    fn sample() -> (FilmHeader, Film) {
        let profile = profile_record(&Profile::builtin("preview"));
        let n = crate::render::unit_count(5, 3, 2, 1..4);
        let completed = (0..n).map(|i| i % 3 != 1).collect();
        let (scene_hash, seed, build) = (0xdead_beef, 9, 0x5eed);
        let h = FilmHeader { width: 5, height: 3, spp: 4, samples: 1..4, tile: 2, scene_hash, seed, profile, completed, build };
        // Odd pixels use the high bits and the sign of the 128-bit sums (the film keeps them in its
        // side table), even ones fit its 64-bit cells.
        let mut film = Film::new(5, 3);
        fill(&h, &mut film, 4, |i| i % 2 == 1);
        assert!(film.pixels().any(|p| p.count == 0) && film.pixels().any(|p| p.count == 2));
        (h, film)
    }

    /// A version-1 film (before the build field, session 41) still reads, its build unknown (0); the
    /// version-2 layout keeps the build.
    #[test]
    fn version_1_films_read_with_an_unknown_build() {
        let (h, film) = sample();
        let v2 = encode(&h, &film);
        assert_eq!(decode(&v2).unwrap().header.build, 0x5eed);
        // Version 1: the same bytes without the 8 after the profile record, its own checksum.
        let at = FIXED_HEADER + h.profile.len();
        let mut v1 = [&v2[..at], &v2[at + 8..v2.len() - 8]].concat();
        v1[8..12].copy_from_slice(&1u32.to_le_bytes());
        let sum = xxh64(&v1);
        v1.extend_from_slice(&sum.to_le_bytes());
        let back = decode(&v1).unwrap();
        assert_eq!(back.header, FilmHeader { build: 0, ..h });
        assert!(back.film == film);
        let mut v3 = v2.clone();
        v3[8..12].copy_from_slice(&3u32.to_le_bytes());
        assert!(decode(&v3).unwrap_err().contains("version 3 is not supported"));
    }

    /// A device or a pipe is refused before it is read (`/dev/zero` was read until memory ran out).
    #[cfg(unix)]
    #[test]
    fn a_device_is_not_read_as_a_film() {
        let Err(e) = read_film(Path::new("/dev/zero")) else { panic!("/dev/zero read as a film") };
        assert!(e.starts_with("/dev/zero: not a regular file"), "{e}");
    }

    /// The decoder as it was before films were read streaming (the whole file in memory, read with
    /// [`Cursor`]): the reference for the streamed reader's results and error messages.
    fn decode_whole(bytes: &[u8]) -> Result<FilmFile, String> {
        let len = bytes.len();
        if len < 12 || bytes[..8] != MAGIC {
            return Err(if len >= 8 && bytes[..8] != MAGIC {
                "not a Strata film file (bad magic; expected \"STRATAFM\")".to_string()
            } else {
                format!("not a Strata film file (only {len} bytes)")
            });
        }
        let version = u32::from_le_bytes(bytes[8..12].try_into().unwrap());
        if version != VERSION && version != 1 {
            return Err(format!("film format version {version} is not supported (this strata reads versions 1 and {VERSION})"));
        }
        let build_bytes = if version >= 2 { 8 } else { 0 };
        if len < FIXED_HEADER + 8 {
            return Err(format!("truncated: {len} bytes is shorter than the {}-byte header", FIXED_HEADER + 8));
        }
        let mut c = Cursor { bytes, at: 12 };
        let (width, height, spp) = (c.u32(), c.u32(), c.u32());
        let samples = c.u32()..c.u32();
        let (tile, n_units) = (c.u32(), c.u32() as usize);
        let (scene_hash, seed, profile_hash) = (c.u64(), c.u64(), c.u64());
        let profile_len = c.u32() as usize;

        // The size the header implies (u128: a corrupted header must not overflow the arithmetic).
        let expected = FIXED_HEADER as u128
            + profile_len as u128
            + build_bytes
            + n_units.div_ceil(8) as u128
            + width as u128 * height as u128 * PIXEL_BYTES as u128
            + 8;
        let stored_sum = u64::from_le_bytes(bytes[len - 8..].try_into().unwrap());
        if xxh64(&bytes[..len - 8]) != stored_sum {
            return Err(if expected != len as u128 {
                format!("truncated or corrupted: the header implies {expected} bytes, the file has {len} (checksum mismatch)")
            } else {
                "corrupted: checksum mismatch (the file was changed after it was written)".to_string()
            });
        }
        if expected != len as u128 {
            return Err(format!("size mismatch: the header implies {expected} bytes, the file has {len}"));
        }

        // The checksum holds, so these can only fail for a file written by something else than strata.
        let bad = |m: String| Err(format!("inconsistent header: {m}"));
        if width == 0 || height == 0 || width > crate::scene::MAX_IMAGE_SIDE as u32 || height > crate::scene::MAX_IMAGE_SIDE as u32 {
            return bad(format!("image size {width}x{height}"));
        }
        if !(samples.start < samples.end && samples.end <= spp) {
            return bad(format!("sample range {}..{} of spp {spp}", samples.start, samples.end));
        }
        if tile == 0 {
            return bad("tile side 0".into());
        }
        let want_units = crate::render::unit_count(width, height, tile, samples.clone());
        if n_units != want_units {
            return bad(format!("{n_units} work units, the size, tile and range give {want_units}"));
        }
        if profile_len > MAX_PROFILE_RECORD {
            return bad(format!("profile record of {profile_len} bytes"));
        }
        let profile =
            String::from_utf8(c.take(profile_len).to_vec()).map_err(|_| "inconsistent header: profile record is not UTF-8".to_string())?;
        if xxh64(profile.as_bytes()) != profile_hash {
            return bad("profile hash does not match the profile record".into());
        }
        if let Err(e) = serde_json::from_str::<Profile>(&profile) {
            return bad(format!("profile record: {e}"));
        }
        let build = if version >= 2 { c.u64() } else { 0 };
        let bits = c.take(n_units.div_ceil(8));
        let completed: Vec<bool> = (0..n_units).map(|i| bits[i / 8] >> (i % 8) & 1 == 1).collect();
        if n_units % 8 != 0 && bits[n_units / 8] >> (n_units % 8) != 0 {
            return bad("bits set past the last work unit".into());
        }
        let mut film = Film::new(width, height);
        for i in 0..film.len() {
            film.set_pixel(i, Pixel { sum: [c.i128(), c.i128(), c.i128()], sum_sq: [c.i128(), c.i128(), c.i128()], count: c.u64() });
        }
        let header = FilmHeader { width, height, spp, samples, tile, scene_hash, seed, profile, completed, build };
        Ok(FilmFile { header, film })
    }

    /// The encoder as it was before films were written streaming (the whole file in one buffer): the
    /// reference the streamed writer's bytes are held to.
    fn encode_whole(header: &FilmHeader, film: &Film) -> Vec<u8> {
        let n_units = header.completed.len();
        let mut out = Vec::new();
        out.extend_from_slice(&MAGIC);
        for v in [VERSION, header.width, header.height, header.spp, header.samples.start, header.samples.end, header.tile, n_units as u32] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        for v in [header.scene_hash, header.seed, header.profile_hash()] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&(header.profile.len() as u32).to_le_bytes());
        out.extend_from_slice(header.profile.as_bytes());
        out.extend_from_slice(&header.build.to_le_bytes());
        let mut bits = vec![0u8; n_units.div_ceil(8)];
        for (i, _) in header.completed.iter().enumerate().filter(|(_, &c)| c) {
            bits[i / 8] |= 1 << (i % 8);
        }
        out.extend_from_slice(&bits);
        for p in film.pixels() {
            for v in p.sum.iter().chain(&p.sum_sq) {
                out.extend_from_slice(&v.to_le_bytes());
            }
            out.extend_from_slice(&p.count.to_le_bytes());
        }
        let sum = xxh64(&out);
        out.extend_from_slice(&sum.to_le_bytes());
        out
    }

    /// A film of more pixels than one chunk of the streamed writer and reader (4096), wide (128-bit)
    /// pixels among compact ones, and its header.
    fn large_sample() -> (FilmHeader, Film) {
        let (w, h) = (83, 61);
        let n = crate::render::unit_count(w, h, 16, 0..8);
        let completed = (0..n).map(|i| i % 5 != 0).collect();
        let profile = profile_record(&Profile::builtin("final"));
        let header =
            FilmHeader { width: w, height: h, spp: 8, samples: 0..8, tile: 16, scene_hash: 1, seed: 2, profile, completed, build: 3 };
        let mut film = Film::new(w, h);
        fill(&header, &mut film, 7, |i| i % 37 == 5);
        assert!(film.pixels().any(|p| p.count == 0) && film.pixels().any(|p| p.count == 7));
        (header, film)
    }

    /// The streamed writer (in memory and through `write_film`'s buffered file) gives the bytes of the
    /// whole-file encoder, checksum included, for a small film of wide and compact pixels and one of
    /// several chunks; reading the file back gives the film and header written.
    #[test]
    fn streamed_writer_gives_the_whole_file_encoders_bytes() {
        let dir = std::env::temp_dir().join(format!("strata-film-stream-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for (k, (h, f)) in [sample(), large_sample()].into_iter().enumerate() {
            assert!(f.pixels().any(|p| p.sum.iter().any(|&s| s != s as i64 as i128)), "film {k} has no wide pixel");
            let want = encode_whole(&h, &f);
            assert!(encode(&h, &f) == want, "film {k}: streamed encode differs");
            let path = dir.join(format!("f{k}.film"));
            write_film(&path, &h, &f).unwrap();
            assert!(std::fs::read(&path).unwrap() == want, "film {k}: the written file differs");
            let back = read_film(&path).unwrap();
            assert_eq!(back.header, h);
            assert!(back.film == f, "film {k}: read(write(film)) differs");
            assert_eq!(verify_film(&path).unwrap(), h);
            assert_eq!(read_film_header(&path).unwrap(), h);
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// A write given up leaves the file there as it was, and no temporary file.
    #[test]
    fn a_write_given_up_leaves_the_previous_file() {
        let dir = std::env::temp_dir().join(format!("strata-film-stop-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("c.film");
        let (h, f) = large_sample();
        assert_eq!(write_film_unless(&path, &h, &f, &AtomicBool::new(false)), Ok(true));
        let before = std::fs::read(&path).unwrap();
        let (h2, f2) = sample();
        assert_eq!(write_film_unless(&path, &h2, &f2, &AtomicBool::new(true)), Ok(false));
        assert!(std::fs::read(&path).unwrap() == before);
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1, "a temporary file was left");
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// The header is read and checked alone: no byte of the pixels is read (a resume or merge refuses a
    /// film of another render before reading them), and a film whose pixels are damaged still reads
    /// its header; reading the pixels then finds the damage. Pixels added to a film as they are read
    /// give `Film::merge`'s sums.
    #[test]
    fn the_header_is_read_without_the_pixels() {
        struct Counting<'a>(&'a [u8], usize);
        impl Read for Counting<'_> {
            fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
                let n = self.0.read(buf)?;
                self.1 += n;
                Ok(n)
            }
        }
        let (h, f) = large_sample();
        let bytes = encode(&h, &f);
        let head = header_bytes(&h).len();
        let mut r = Counting(&bytes, 0);
        let reader = FilmReader::new(&mut r, bytes.len() as u64).unwrap();
        assert_eq!(reader.header(), &h);
        drop(reader);
        assert_eq!(r.1, head, "the header read read {} bytes, the header has {head}", r.1);
        let mut damaged = bytes.clone();
        damaged[head + 1000] ^= 1;
        let reader = FilmReader::new(&damaged[..], damaged.len() as u64).unwrap();
        assert_eq!(reader.header(), &h);
        let e = reader.read().unwrap_err();
        assert!(e.contains("checksum mismatch"), "{e}");
        let mut sum = f.clone();
        let mut want = f.clone();
        want.merge(&f);
        FilmReader::new(&bytes[..], bytes.len() as u64).unwrap().merge_into(&mut sum).unwrap();
        assert!(sum == want);
    }

    /// Memory for a film that cannot be had is an error naming the size, not an abort (256 TB: beyond
    /// any address space).
    #[test]
    fn a_film_too_large_for_memory_is_an_error() {
        let e = Film::try_new(1 << 21, 1 << 21).unwrap_err();
        assert!(e.contains("2097152x2097152") && e.contains("281474976710656 bytes"), "{e}");
    }

    #[test]
    fn round_trip_is_exact() {
        let (h, f) = sample();
        let bytes = encode(&h, &f);
        let back = decode(&bytes).unwrap();
        assert_eq!(back.header, h);
        assert_eq!(back.film, f);
        assert_eq!(encode(&back.header, &back.film), bytes);
    }

    #[test]
    fn every_single_byte_corruption_and_truncation_is_detected() {
        let (h, f) = sample();
        let bytes = encode(&h, &f);
        let verify = |b: &[u8]| FilmReader::new(b, b.len() as u64).and_then(|r| r.verify());
        for i in 0..bytes.len() {
            let mut b = bytes.clone();
            b[i] ^= 0x10;
            assert!(decode(&b).is_err(), "flipped bit in byte {i} went unnoticed");
            assert_eq!(decode(&b).unwrap_err(), decode_whole(&b).unwrap_err(), "byte {i}: not the whole-file reader's error");
            assert_eq!(verify(&b).unwrap_err(), decode(&b).unwrap_err(), "byte {i}");
        }
        // The same flips with the checksum made to match (a file written by something else than
        // strata): the header's own checks, the results and their messages those of the whole-file
        // reader; pixels that no render gives are refused too.
        let mut inconsistent = 0;
        for i in 0..bytes.len() - 8 {
            let mut b = bytes[..bytes.len() - 8].to_vec();
            b[i] ^= 0x10;
            let sum = xxh64(&b);
            b.extend_from_slice(&sum.to_le_bytes());
            match (decode(&b), decode_whole(&b)) {
                (Ok(x), Ok(y)) => assert!(x == y, "byte {i}"),
                // (The whole-file reader did not check pixels: a count or sum out of range, or a
                // completion flag that leaves a pixel more samples than its units hold.)
                (Err(e), Ok(_)) => {
                    assert!(e.starts_with("inconsistent pixel ("), "byte {i}: {e}");
                    inconsistent += 1;
                }
                (x, y) => assert_eq!(x.map(|_| ()), y.map(|_| ()), "byte {i}"),
            }
            assert_eq!(verify(&b), decode(&b).map(|f| f.header), "byte {i}");
        }
        // Flips in counts (their bit 4: above 3) and in the top bytes of sums, and completion flags
        // cleared under pixels with samples.
        assert!(inconsistent > 1000, "{inconsistent} flips found inconsistent");
        for n in 0..bytes.len() {
            assert!(decode(&bytes[..n]).is_err(), "truncation to {n} bytes went unnoticed");
            assert_eq!(decode(&bytes[..n]).unwrap_err(), decode_whole(&bytes[..n]).unwrap_err(), "{n} bytes");
            assert_eq!(verify(&bytes[..n]).unwrap_err(), decode(&bytes[..n]).unwrap_err(), "{n} bytes");
        }
        let e = decode(&bytes[..bytes.len() - 10]).unwrap_err();
        assert!(e.contains("truncated"), "{e}");
        let mut b = bytes.clone();
        b[200] ^= 1;
        assert!(decode(&b).unwrap_err().contains("checksum"));
        b = bytes.clone();
        b[8] = 7;
        assert!(decode(&b).unwrap_err().contains("version 7"));
        b[0] = b'X';
        assert!(decode(&b).unwrap_err().contains("magic"));
    }

    /// `bytes` (a film file) with pixel `i`'s record changed by `f` and the checksum made to match
    /// again (with the module's own xxh64): a film written so by something else than strata.
    fn with_pixel(bytes: &[u8], h: &FilmHeader, i: usize, f: impl Fn(&mut Pixel)) -> Vec<u8> {
        let at = header_bytes(h).len() + i * PIXEL_BYTES;
        let mut b = bytes[..bytes.len() - 8].to_vec();
        let rec = &b[at..at + PIXEL_BYTES];
        let v = |j: usize| i128::from_le_bytes(rec[16 * j..16 * j + 16].try_into().unwrap());
        let mut p = Pixel { sum: [v(0), v(1), v(2)], sum_sq: [v(3), v(4), v(5)], count: u64::from_le_bytes(rec[96..].try_into().unwrap()) };
        f(&mut p);
        let mut rec = Vec::new();
        for v in p.sum.iter().chain(&p.sum_sq) {
            rec.extend_from_slice(&v.to_le_bytes());
        }
        rec.extend_from_slice(&p.count.to_le_bytes());
        b[at..at + PIXEL_BYTES].copy_from_slice(&rec);
        let sum = xxh64(&b);
        b.extend_from_slice(&sum.to_le_bytes());
        b
    }

    /// A pixel that no render gives, in a film whose checksum holds (the reviewer's crafted films: sums
    /// of 1.5 2^126, a count of 2^64 - 1, a count of 0 under sums, each merged into a wrong image and a
    /// film with a valid checksum), is refused by every reader (read, verify, merge), naming the pixel
    /// (x, y) and what is wrong: a count above the samples of its completed units (a complete film's
    /// and a partial one's), sums beyond what its count of samples can give (one past the bound, either
    /// sign; the bound itself reads), a negative sum of squares or one past its bound, sums under no
    /// samples. The checksum's error comes first where both fail.
    #[test]
    fn inconsistent_pixels_are_refused_naming_them() {
        // A complete film of samples 0..4 (4 per pixel) and the partial one of `sample`.
        let (mut h, _) = sample();
        h.samples = 0..4;
        h.completed = vec![true; crate::render::unit_count(5, 3, 2, 0..4)];
        let mut film = Film::new(5, 3);
        fill(&h, &mut film, 1000, |i| i % 2 == 1);
        let bytes = encode(&h, &film);
        assert!(decode(&bytes).unwrap().film == film);
        let (ph, pf) = sample();
        let partial = encode(&ph, &pf);
        let held = held(&ph);
        // (6 = (1, 1): in a completed unit, 3 samples; 13 = (3, 2): in none.)
        assert_eq!((held[6], held[13], pf.pixel(6).count, pf.pixel(13).count), (3, 0, 3, 0));
        let (q, s2) = (MAX_QUANTIZED, MAX_SQUARE_TERM);
        type Case = (usize, fn(&mut Pixel), &'static str);
        let cases: [Case; 12] = [
            (0, |p| p.sum = [3 << 125; 3], "inconsistent pixel (0, 0): red sum 127605887595351923798765477786913079296 (in units of 2^-32) is beyond what 4 samples can give (|sum| <= 4 x (2^63 - 2^39) = 36893485948395847680)"),
            (6, |p| p.count = u64::MAX, "inconsistent pixel (1, 1): 18446744073709551615 samples, but the film's completed work units hold 4 samples for it"),
            (6, |p| p.count = 5, "inconsistent pixel (1, 1): 5 samples, but the film's completed work units hold 4 samples for it"),
            (2, |p| p.count = 0, "inconsistent pixel (2, 0): red sum -5 (in units of 2^-32) with no samples (a pixel of no samples sums to 0)"),
            (2, |p| *p = Pixel { sum_sq: [0, 0, 1], ..Pixel::default() }, "inconsistent pixel (2, 0): blue sum of squares 1 (in units of 2^-32) with no samples (a pixel of no samples sums to 0)"),
            (3, |p| p.sum[0] = 4 * MAX_QUANTIZED + 1, "inconsistent pixel (3, 0): red sum 36893485948395847681 (in units of 2^-32) is beyond what 4 samples can give (|sum| <= 4 x (2^63 - 2^39) = 36893485948395847680)"),
            (3, |p| p.sum[1] = -4 * MAX_QUANTIZED - 1, "inconsistent pixel (3, 0): green sum -36893485948395847681 (in units of 2^-32) is beyond what 4 samples can give (|sum| <= 4 x (2^63 - 2^39) = 36893485948395847680)"),
            (4, |p| p.sum_sq[1] = -1, "inconsistent pixel (4, 0): green sum of squares -1 (in units of 2^-32) is negative"),
            (14, |p| p.sum_sq[2] = 4 * MAX_SQUARE_TERM + 1, "inconsistent pixel (4, 2): blue sum of squares 79228153069531653329230233601 (in units of 2^-32) is beyond what 4 samples can give (<= 4 x (2^94 - 2^71 + 2^46) = 79228153069531653329230233600)"),
            (14, |p| p.sum_sq[0] = i128::MIN, "inconsistent pixel (4, 2): red sum of squares -170141183460469231731687303715884105728 (in units of 2^-32) is negative"),
            (1, |p| *p = Pixel { sum: [1, 0, 0], sum_sq: [0; 3], count: 1 }, ""),
            (1, |p| p.sum = [i128::MIN; 3], "inconsistent pixel (1, 0): red sum -170141183460469231731687303715884105728 (in units of 2^-32) is beyond what 4 samples can give (|sum| <= 4 x (2^63 - 2^39) = 36893485948395847680)"),
        ];
        let verify = |b: &[u8]| FilmReader::new(b, b.len() as u64).and_then(|r| r.verify());
        let merge = |b: &[u8]| FilmReader::new(b, b.len() as u64).and_then(|r| r.merge_into(&mut Film::new(5, 3)));
        for (i, f, want) in cases {
            let b = with_pixel(&bytes, &h, i, f);
            if want.is_empty() {
                // (A pixel of 1 sample of 1 unit of 2^-32, its square term rounding to 0: consistent.)
                assert!(decode(&b).is_ok() && verify(&b).is_ok() && merge(&b).is_ok(), "pixel {i}");
                continue;
            }
            assert_eq!(decode(&b).unwrap_err(), want);
            assert_eq!(verify(&b).unwrap_err(), want);
            assert_eq!(merge(&b).unwrap_err(), want);
            // The same file damaged too: the checksum's error.
            let mut d = b.clone();
            *d.last_mut().unwrap() ^= 1;
            assert_eq!(decode(&d).unwrap_err(), CORRUPTED);
        }
        // The bounds themselves are sums a render can give: they read.
        let b = with_pixel(&bytes, &h, 3, |p| *p = Pixel { sum: [4 * q, -4 * q, 0], sum_sq: [4 * s2, 0, 4 * s2], count: 4 });
        assert_eq!(decode(&b).unwrap().film.pixel(3), Pixel { sum: [4 * q, -4 * q, 0], sum_sq: [4 * s2, 0, 4 * s2], count: 4 });
        // A partial film: a pixel of a completed unit may hold its samples (or fewer: discarded ones),
        // not more; one of no completed unit holds none.
        for (i, count, want) in [
            (6, 2, None),
            (6, 4, Some("inconsistent pixel (1, 1): 4 samples, but the film's completed work units hold 3 samples for it")),
            (13, 1, Some("inconsistent pixel (3, 2): 1 sample, but the film's completed work units hold 0 samples for it")),
        ] {
            let b = with_pixel(&partial, &ph, i, |p| p.count = count);
            assert_eq!(decode(&b).err().as_deref(), want, "pixel {i}, count {count}");
        }
        // Completion flags cleared under a pixel with samples: that pixel's count is too many.
        let mut cleared = ph.clone();
        cleared.completed[0] = false;
        let e = decode(&encode(&cleared, &pf)).unwrap_err();
        assert_eq!(e, "inconsistent pixel (0, 0): 3 samples, but the film's completed work units hold 0 samples for it");
    }

    /// Films added to a film as they are read (a merge) whose sums would overflow 128 bits are an error
    /// naming the pixel, the film unchanged there, not a wrap: with a film already near the top (no
    /// render of one film gives it; many films of 2^32 samples a pixel could).
    #[test]
    fn a_merge_that_would_overflow_is_an_error() {
        let (h, f) = large_sample();
        let bytes = encode(&h, &f);
        let i = (0..f.len()).find(|&i| f.pixel(i).sum_sq[0] > 0).unwrap();
        let mut sum = Film::new(h.width, h.height);
        let top = Pixel { sum: [0; 3], sum_sq: [i128::MAX, 0, 0], count: 1 };
        sum.set_pixel(i, top);
        let e = FilmReader::new(&bytes[..], bytes.len() as u64).unwrap().merge_into(&mut sum).unwrap_err();
        let (x, y) = (i % h.width as usize, i / h.width as usize);
        assert!(
            e.starts_with(&format!("inconsistent pixel ({x}, {y}): its sums added to the film's (")) && e.ends_with(") overflow"),
            "{e}"
        );
        assert_eq!(sum.pixel(i), top);
        // A count that would overflow, in a compact cell and a wide pixel alike.
        for top in [Pixel { count: u64::MAX, ..Pixel::default() }, Pixel { sum: [1 << 100, 0, 0], sum_sq: [0; 3], count: u64::MAX }] {
            let mut sum = Film::new(h.width, h.height);
            sum.set_pixel(i, top);
            assert!(FilmReader::new(&bytes[..], bytes.len() as u64).unwrap().merge_into(&mut sum).is_err());
            assert_eq!(sum.pixel(i), top);
        }
    }

    #[test]
    fn differences_name_the_field() {
        let (h, _) = sample();
        let mut o = h.clone();
        o.seed = 10;
        let mut p = Profile::builtin("preview");
        p.light_samples = 3;
        o.profile = profile_record(&p);
        let d = h.identity_differences(&o, ("film", "this render"));
        assert_eq!(d.len(), 2, "{d:?}");
        assert!(d[0].contains("seed: film 9, this render 10"), "{d:?}");
        assert!(d[1].contains("light_samples film 1, this render 3"), "{d:?}");
        // `all`, left out of the record, is named as such.
        p.light_samples = 1;
        p.light_selection = crate::scene::LightSelection::Local;
        o.profile = profile_record(&p);
        let d = h.identity_differences(&o, ("film", "this render"));
        assert!(d[1].contains("light_selection film \"all\", this render \"local\""), "{d:?}");
    }
}
