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

pub fn to_srgb8(rgb: &[Vec3]) -> Vec<u8> {
    rgb.iter().flat_map(|c| c.to_array()).map(|x| (linear_to_srgb(if x.is_finite() { x } else { 0.0 }) * 255.0 + 0.5) as u8).collect()
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
    let dir = parent_dir(path);
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

/// Write a linear RGB image (row-major) as PNG or EXR according to the extension.
pub fn write_image(path: &Path, width: u32, height: u32, rgb: &[Vec3]) -> Result<(), String> {
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
            let layer = Layer::new((w, height as usize), LayerAttributes::default(), encoding, channels);
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
