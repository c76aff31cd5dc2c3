//! Writing images: PNG (sRGB, 8-bit) or EXR (linear float), chosen by extension. Writes go to a
//! temporary file in the same directory and are renamed into place, so a failed or interrupted write never
//! leaves a truncated image and never destroys the previous one.

use glam::Vec3;
use std::path::{Path, PathBuf};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    Png,
    Exr,
}

/// The format named by a path's extension.
pub fn format_for(path: &Path) -> Result<ImageFormat, String> {
    match path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()) {
        Some(e) if e == "png" => Ok(ImageFormat::Png),
        Some(e) if e == "exr" => Ok(ImageFormat::Exr),
        _ => Err(format!("{}: output must end in .png or .exr", path.display())),
    }
}

/// Linear to sRGB transfer (IEC 61966-2-1).
#[inline]
pub fn linear_to_srgb(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// The 8-bit sRGB code of a linear value: [`linear_to_srgb`] scaled and rounded (non-finite values
/// give 0).
#[inline]
pub fn srgb8(x: f32) -> u8 {
    (linear_to_srgb(if x.is_finite() { x } else { 0.0 }) * 255.0 + 0.5) as u8
}

/// For each code `b` in 1..=255, the least non-negative `f32` whose [`srgb8`] is at least `b`
/// (`[0]` is -inf): found by bisection over the bit patterns of `[0, 1]`, which order as the values do.
fn srgb8_thresholds() -> &'static [f32; 256] {
    static T: std::sync::OnceLock<[f32; 256]> = std::sync::OnceLock::new();
    T.get_or_init(|| {
        let mut t = [f32::NEG_INFINITY; 256];
        for (b, t) in t.iter_mut().enumerate().skip(1) {
            let (mut lo, mut hi) = (0u32, 1.0f32.to_bits());
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                if srgb8(f32::from_bits(mid)) >= b as u8 {
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            *t = f32::from_bits(lo);
        }
        t
    })
}

/// [`srgb8`] of every channel, by a binary search of its thresholds (8 comparisons, no `powf`): the
/// same codes, as long as the codes rise with the value, which `srgb8_thresholds_give_srgb8` checks
/// around every threshold.
pub fn to_srgb8(rgb: &[Vec3]) -> Vec<u8> {
    let t = srgb8_thresholds();
    let code = |x: f32| {
        // (NaN compares false: code 0, as `srgb8` gives it; so do +inf, by the test below.)
        let x = if x.is_finite() { x } else { 0.0 };
        let mut b = 0usize;
        for step in [128, 64, 32, 16, 8, 4, 2, 1] {
            if x >= t[b + step] {
                b += step;
            }
        }
        b as u8
    };
    rgb.iter().flat_map(|c| c.to_array()).map(code).collect()
}

/// Check before rendering that `path` can be written: format known, directory exists and is writable.
pub fn check_writable(path: &Path) -> Result<(), String> {
    format_for(path)?;
    check_file_writable(path)
}

/// Check before rendering that a file can be written at `path` (any format): its directory exists and
/// takes a new file, and `path` is not itself a directory (the final rename would fail after the render).
pub fn check_file_writable(path: &Path) -> Result<(), String> {
    if path.is_dir() {
        return Err(format!("{}: is a directory", path.display()));
    }
    // (`x.png/` or `x.png/.` names a directory, which the write after the render would fail on.)
    let text = path.as_os_str().to_string_lossy();
    let last = path.components().next_back();
    let dotted = text.ends_with("/.") || text.ends_with("/..") || text == "." || text == "..";
    if text.ends_with(std::path::MAIN_SEPARATOR) || text.ends_with('/') || dotted || !matches!(last, Some(std::path::Component::Normal(_)))
    {
        return Err(format!("{}: names a directory, not a file (drop the trailing `/` or `.`)", path.display()));
    }
    let dir = parent_dir(path);
    if dir.exists() && !dir.is_dir() {
        return Err(format!("{}: {} is a file, not a directory", path.display(), dir.display()));
    }
    if !dir.is_dir() {
        return Err(format!("{}: directory {} does not exist", path.display(), dir.display()));
    }
    let probe = temp_path(path);
    std::fs::write(&probe, b"").map_err(|e| format!("{}: cannot write here: {e}", path.display()))?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

fn temp_path(path: &Path) -> PathBuf {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    parent_dir(path).join(format!(".{name}.{}.tmp", std::process::id()))
}

/// Write bytes atomically: temp file in the same directory, then rename.
pub fn write_atomic(path: &Path, write: impl FnOnce(&Path) -> Result<(), String>) -> Result<(), String> {
    let tmp = temp_path(path);
    let res = write(&tmp).and_then(|_| std::fs::rename(&tmp, path).map_err(|e| format!("{}: {e}", path.display())));
    if res.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    res
}

/// What a rendered image estimates and how it was made: written into an EXR's header as one text
/// attribute, `strata.provenance`, of five lines (`scene_hash 80b5240e2da06139`, `seed 1`, `samples 0..64
/// of 64`, `complete yes`, `profile {...}`; PNG carries none), so that `strata study --reference` can tell a reference
/// rendered with another filter, depth or scene from one of the studied estimator. (One attribute: the
/// exr crate writes a header's other attributes in the order of a `HashMap`, which differs from process to
/// process, and the same render must give the same bytes.)
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Provenance {
    /// FNV-1a of the scene file's text (as films record it).
    pub scene_hash: u64,
    pub seed: u64,
    /// The samples of each pixel the image holds, of `spp`.
    pub samples: std::ops::Range<u32>,
    pub spp: u32,
    /// The profile as films record it ([`crate::film::file::profile_record`]: JSON, name blanked).
    pub profile: String,
    /// Whether every work unit of `samples` is in the image (false: interrupted, or merged with gaps).
    pub complete: bool,
}

/// The EXR attribute holding an image's [`Provenance`].
const PROVENANCE_KEY: &str = "strata.provenance";

impl Provenance {
    /// The provenance of the image of a film with this header.
    pub fn of(h: &crate::film::file::FilmHeader) -> Provenance {
        let (samples, profile, complete) = (h.samples.clone(), h.profile.clone(), h.is_complete());
        Provenance { scene_hash: h.scene_hash, seed: h.seed, samples, spp: h.spp, profile, complete }
    }

    fn text(&self) -> String {
        let (a, b) = (self.samples.start, self.samples.end);
        let complete = if self.complete { "yes" } else { "no" };
        let (hash, seed, spp, profile) = (self.scene_hash, self.seed, self.spp, &self.profile);
        format!("scene_hash {hash:016x}\nseed {seed}\nsamples {a}..{b} of {spp}\ncomplete {complete}\nprofile {profile}")
    }

    fn parse(text: &str) -> Option<Provenance> {
        let mut lines = text.lines();
        let mut field = |name: &str| lines.next()?.strip_prefix(name)?.strip_prefix(' ');
        let hash = u64::from_str_radix(field("scene_hash")?, 16).ok()?;
        let seed = field("seed")?.parse().ok()?;
        let (range, spp) = field("samples")?.split_once(" of ")?;
        let (a, b) = range.split_once("..")?;
        let complete = match field("complete")? {
            "yes" => true,
            "no" => false,
            _ => return None,
        };
        let profile = field("profile")?.to_string();
        let samples = a.parse().ok()?..b.parse().ok()?;
        Some(Provenance { scene_hash: hash, seed, samples, spp: spp.parse().ok()?, profile, complete })
    }

    /// The provenance in an EXR's header: `Ok(None)` if it has none (another renderer's image, or one
    /// written before session 41).
    pub fn read(path: &Path) -> Result<Option<Provenance>, String> {
        use exr::meta::attribute::{AttributeValue, Text};
        let meta = exr::meta::MetaData::read_from_file(path, false).map_err(|e| format!("{}: {e}", path.display()))?;
        let Some(header) = meta.headers.first() else { return Ok(None) };
        match header.own_attributes.other.get(&Text::new_or_panic(PROVENANCE_KEY)) {
            Some(AttributeValue::Text(t)) => Provenance::parse(&t.to_string())
                .map(Some)
                .ok_or_else(|| format!("{}: malformed attribute `{PROVENANCE_KEY}`", path.display())),
            _ => Ok(None),
        }
    }
}

/// Write a linear RGB image (row-major) as PNG or EXR according to the extension.
pub fn write_image(path: &Path, width: u32, height: u32, rgb: &[Vec3]) -> Result<(), String> {
    write_image_with(path, width, height, rgb, None)
}

/// [`write_image`], an EXR with the image's [`Provenance`] in its header.
pub fn write_image_with(path: &Path, width: u32, height: u32, rgb: &[Vec3], provenance: Option<&Provenance>) -> Result<(), String> {
    let fmt = format_for(path)?;
    write_atomic(path, |tmp| match fmt {
        ImageFormat::Png => {
            let img = image::RgbImage::from_raw(width, height, to_srgb8(rgb)).ok_or("image size mismatch")?;
            img.save_with_format(tmp, image::ImageFormat::Png).map_err(|e| format!("{}: {e}", path.display()))
        }
        ImageFormat::Exr => {
            // Written with exr directly rather than through `image`: exr compresses blocks in parallel
            // and, with the default unspecified line order, writes them in completion order, so the same
            // pixels gave different bytes from run to run once an image has more than one 64x64 tile.
            // Increasing line order makes exr write the blocks sorted: same pixels, same bytes.
            use exr::prelude::{Encoding, Image, Layer, LayerAttributes, LineOrder, SpecificChannels, Vec2, WritableImage};
            let w = width as usize;
            if rgb.len() != w * height as usize {
                return Err("image size mismatch".into());
            }
            let encoding = Encoding { line_order: LineOrder::Increasing, ..Encoding::FAST_LOSSLESS };
            let channels = SpecificChannels::rgb(|p: Vec2<usize>| {
                let c = rgb[p.y() * w + p.x()];
                (c.x, c.y, c.z)
            });
            let mut attributes = LayerAttributes::default();
            // (EXR text is Latin-1: the profile record is ASCII, its name blanked; anything else would
            // be left out rather than mangled.)
            if let Some(v) = provenance.and_then(|p| exr::meta::attribute::Text::new_or_none(p.text())) {
                let key = exr::meta::attribute::Text::new_or_panic(PROVENANCE_KEY);
                attributes.other.insert(key, exr::meta::attribute::AttributeValue::Text(v));
            }
            let layer = Layer::new((w, height as usize), attributes, encoding, channels);
            Image::from_layer(layer).write().to_file(tmp).map_err(|e| format!("{}: {e}", path.display()))
        }
    })
}

/// Read an EXR or PNG back as linear RGB (PNG is decoded from sRGB).
pub fn read_image(path: &Path) -> Result<(u32, u32, Vec<Vec3>), String> {
    let img = image::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let fmt = format_for(path)?;
    let (w, h) = (img.width(), img.height());
    let px: Vec<Vec3> = match fmt {
        ImageFormat::Exr => img.into_rgb32f().pixels().map(|p| Vec3::new(p[0], p[1], p[2])).collect(),
        ImageFormat::Png => {
            img.into_rgb8().pixels().map(|p| Vec3::new(srgb_to_linear(p[0]), srgb_to_linear(p[1]), srgb_to_linear(p[2]))).collect()
        }
    };
    Ok((w, h, px))
}

fn srgb_to_linear(v: u8) -> f32 {
    let x = v as f32 / 255.0;
    if x <= 0.04045 {
        x / 12.92
    } else {
        ((x + 0.055) / 1.055).powf(2.4)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The threshold search gives [`srgb8`]'s codes: at every `f32` within 4096 ULPs of each threshold
    /// (where a code that did not rise with the value would show), at a million values spread over
    /// [-0.1, 1.2], and at zeros, negatives, values past 1, subnormals and non-finite values. The
    /// thresholds rise and span (0, 1].
    #[test]
    fn srgb8_thresholds_give_srgb8() {
        let t = srgb8_thresholds();
        assert!(t[1] > 0.0 && t[255] <= 1.0 && t.windows(2).all(|w| w[0] < w[1]), "{t:?}");
        let check = |xs: &[f32]| {
            let rgb: Vec<Vec3> = xs.chunks(3).map(|c| Vec3::new(c[0], c[1 % c.len()], c[2 % c.len()])).collect();
            let got = to_srgb8(&rgb);
            for (i, c) in rgb.iter().enumerate() {
                for (k, x) in c.to_array().into_iter().enumerate() {
                    assert_eq!(got[3 * i + k], srgb8(x), "value {x:e} ({:#x})", x.to_bits());
                }
            }
        };
        let mut near = Vec::new();
        for &x in &t[1..] {
            let b = x.to_bits() as i64;
            near.extend((b - 4096..=b + 4096).map(|v| f32::from_bits(v.max(0) as u32)));
        }
        check(&near);
        let mut seed = 0x5ab1_e5eed_u64;
        let spread: Vec<f32> = (0..1_000_000)
            .map(|_| {
                seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                ((seed >> 40) as f32 / (1u64 << 24) as f32) * 1.3 - 0.1
            })
            .collect();
        check(&spread);
        let odd = [0.0, -0.0, -1.0, 1.0, 1.5, 3e38, f32::MIN_POSITIVE, 1e-45, f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 0.0031308];
        check(&odd);
        assert_eq!(to_srgb8(&[Vec3::new(f32::NAN, f32::INFINITY, 2.0)]), [0, 0, 255]);
        // Codes known independently of both: IEC 61966-2-1 gives 0.5 -> 0.7354 (x 255 = 187.5), 18%
        // grey 0.18 -> 0.4614 (117.7), and 0.001 on the linear segment 12.92 x 0.001 (3.3).
        assert_eq!(to_srgb8(&[Vec3::new(0.5, 0.18, 0.001)]), [188, 118, 3]);
    }
}
