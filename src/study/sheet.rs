//! `sheet.png`, the contact sheet: the renders side by side, one row per strategy and one column per
//! sample count (the first seed's image), labelled, like the textbook's "1, 9, 36, 100 samples" figure.
//!
//! Layout: a label column of [`LABEL_W`] pixels, a header row of [`HEADER_H`], cells separated by
//! [`GAP`]. Each cell is the render scaled by an integer factor: small renders are enlarged (nearest
//! neighbour, so the pixels stay visible) to at least [`MIN_CELL_W`] wide; large ones are reduced (box
//! average in linear light) to at most [`MAX_CELL_W`].

use super::plot::{ensure_font, save_rgb};
use crate::film::output::to_srgb8;
use crate::sample::Strategy;
use glam::Vec3;
use plotters::prelude::*;
use std::path::Path;

pub const LABEL_W: u32 = 110;
pub const HEADER_H: u32 = 30;
pub const GAP: u32 = 6;
pub const MIN_CELL_W: u32 = 128;
pub const MAX_CELL_W: u32 = 256;

/// A cell's size and scale for a `w x h` render: `(cell_w, cell_h, up, down)`, one of `up`, `down` being 1.
/// By the render's longer side, so that neither side of a cell passes [`MAX_CELL_W`] (by the width alone,
/// a 1 x 409 render became a cell 128 x 52,352, and its sheet's size overflowed).
pub fn cell_size(w: u32, h: u32) -> (u32, u32, u32, u32) {
    let side = w.max(h).max(1);
    if side < MIN_CELL_W {
        let up = MIN_CELL_W.div_ceil(side);
        (w * up, h * up, up, 1)
    } else if side > MAX_CELL_W {
        let down = side.div_ceil(MAX_CELL_W);
        ((w / down).max(1), (h / down).max(1), 1, down)
    } else {
        (w, h, 1, 1)
    }
}

/// The most pixels a sheet may have (300 MB of RGB): a study of more counts and strategies is refused
/// before its runs ([`check_size`]).
pub const MAX_SHEET_PIXELS: u64 = 100_000_000;

/// Size of the sheet for `rows x cols` renders of `w x h` (in u64: rows and columns are the user's).
pub fn sheet_size_u64(w: u32, h: u32, rows: u64, cols: u64) -> (u64, u64) {
    let (cw, ch, _, _) = cell_size(w, h);
    (LABEL_W as u64 + cols * (cw + GAP) as u64 + GAP as u64, HEADER_H as u64 + rows * (ch + GAP) as u64 + GAP as u64)
}

/// Size of the sheet for `rows x cols` renders of `w x h` (within [`MAX_SHEET_PIXELS`]: see [`check_size`]).
pub fn sheet_size(w: u32, h: u32, rows: u32, cols: u32) -> (u32, u32) {
    let (sw, sh) = sheet_size_u64(w, h, rows as u64, cols as u64);
    (sw.min(u32::MAX as u64) as u32, sh.min(u32::MAX as u64) as u32)
}

/// Whether the sheet of `rows x cols` renders of `w x h` is within [`MAX_SHEET_PIXELS`]: else the
/// message saying so.
pub fn check_size(w: u32, h: u32, rows: usize, cols: usize) -> Result<(), String> {
    let (sw, sh) = sheet_size_u64(w, h, rows as u64, cols as u64);
    if sw.saturating_mul(sh) > MAX_SHEET_PIXELS {
        return Err(format!(
            "--sheet: {rows} strategies x {cols} counts of {w}x{h} renders make a sheet of {sw} x {sh} pixels, more than \
             {MAX_SHEET_PIXELS}; study fewer counts or strategies, or leave out --sheet"
        ));
    }
    Ok(())
}

/// Scale a linear render to its cell (see the module doc).
fn scale(img: &[Vec3], w: u32, h: u32) -> Vec<Vec3> {
    let (cw, ch, up, down) = cell_size(w, h);
    let mut out = Vec::with_capacity((cw * ch) as usize);
    for y in 0..ch {
        for x in 0..cw {
            let mut s = Vec3::ZERO;
            for dy in 0..down {
                for dx in 0..down {
                    let (sx, sy) = ((x * down + dx) / up, (y * down + dy) / up);
                    s += img[(sy.min(h - 1) * w + sx.min(w - 1)) as usize];
                }
            }
            out.push(s / (down * down) as f32);
        }
    }
    out
}

/// Draw the sheet. `images` holds (strategy, count, linear image) for every cell; `unit` names the
/// count in the column headers ("spp", "light samples"; "samples" is singular for 1).
pub fn draw(
    images: &[(Strategy, u32, Vec<Vec3>)],
    strategies: &[Strategy],
    counts: &[u32],
    w: u32,
    h: u32,
    unit: &str,
) -> Result<(u32, u32, Vec<u8>), String> {
    ensure_font();
    let (cw, ch, _, _) = cell_size(w, h);
    let (sw, sh) = sheet_size(w, h, strategies.len() as u32, counts.len() as u32);
    check_size(w, h, strategies.len(), counts.len())?;
    let mut buf = vec![255u8; sw as usize * sh as usize * 3];
    let origin = |row: usize, col: usize| (LABEL_W + GAP + col as u32 * (cw + GAP), HEADER_H + row as u32 * (ch + GAP));
    for (st, n, img) in images {
        let (Some(row), Some(col)) = (strategies.iter().position(|s| s == st), counts.iter().position(|c| c == n)) else {
            continue;
        };
        let cell = to_srgb8(&scale(img, w, h));
        let (x0, y0) = origin(row, col);
        for y in 0..ch {
            let dst = ((y0 + y) as usize * sw as usize + x0 as usize) * 3;
            let src = y as usize * cw as usize * 3;
            buf[dst..dst + cw as usize * 3].copy_from_slice(&cell[src..src + cw as usize * 3]);
        }
    }
    let res: Result<(), Box<dyn std::error::Error>> = (|| {
        let root = BitMapBackend::with_buffer(&mut buf, (sw, sh)).into_drawing_area();
        let style = ("sans-serif", 15).into_font().color(&BLACK);
        for (col, n) in counts.iter().enumerate() {
            let (x0, _) = origin(0, col);
            let unit = if *n == 1 && unit.ends_with("samples") { &unit[..unit.len() - 1] } else { unit };
            root.draw(&Text::new(format!("{n} {unit}"), (x0 as i32 + 2, 7), style.clone()))?;
        }
        for (row, st) in strategies.iter().enumerate() {
            let (_, y0) = origin(row, 0);
            root.draw(&Text::new(st.name().to_string(), (GAP as i32, (y0 + ch / 2) as i32 - 8), style.clone()))?;
        }
        root.present()?;
        Ok(())
    })();
    res.map_err(|e| format!("sheet: {e}"))?;
    Ok((sw, sh, buf))
}

/// Write `sheet.png`.
pub fn write(
    path: &Path,
    images: &[(Strategy, u32, Vec<Vec3>)],
    strategies: &[Strategy],
    counts: &[u32],
    w: u32,
    h: u32,
    unit: &str,
) -> Result<(), String> {
    let (sw, sh, buf) = draw(images, strategies, counts, w, h, unit)?;
    save_rgb(path, sw, sh, buf)
}
