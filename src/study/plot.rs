//! `study.png`: log-log plots of MSE against samples (left) and against seconds (right), one line per
//! strategy (mean over seeds), the fitted slope in the legend. Drawn with plotters into an RGB buffer
//! and saved with `image`.
//!
//! Text uses plotters' `ab_glyph` backend with DejaVu Sans embedded in the binary
//! (`assets/fonts/DejaVuSans.ttf`, Bitstream Vera licence): plotters' `ttf` feature would find fonts
//! through fontconfig, which needs the system's font and -dev packages to build and to draw a label.

use super::run::{slopes, Summary};
use crate::sample::Strategy;
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

/// Size of `study.png` in pixels.
pub const PLOT_SIZE: (u32, u32) = (1000, 420);

static FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// Register the embedded font under the generic family names plotters asks for (once per process).
pub fn ensure_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        for family in ["sans-serif", "serif", "monospace"] {
            if plotters::style::register_font(family, FontStyle::Normal, FONT).is_err() {
                panic!("the embedded font does not parse");
            }
        }
    });
}

/// The colour of a strategy's line (same in every plot).
pub fn strategy_colour(s: Strategy) -> RGBColor {
    match s {
        Strategy::Center => RGBColor(110, 110, 110),
        Strategy::Grid => RGBColor(140, 60, 170),
        Strategy::Random => RGBColor(210, 50, 40),
        Strategy::Jittered => RGBColor(30, 90, 200),
        Strategy::Sobol => RGBColor(30, 150, 70),
    }
}

/// Positive bounds of some values, padded for a log axis; a degenerate range is widened.
fn log_range(values: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for v in values.filter(|v| v.is_finite() && *v > 0.0) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !(lo.is_finite() && hi > 0.0) {
        return 0.1..10.0;
    }
    if hi / lo < 1.5 {
        (lo, hi) = (lo / 2.0, hi * 2.0);
    }
    lo / 1.3..hi * 1.3
}

type DrawResult = Result<(), Box<dyn std::error::Error>>;

/// Draw one panel: `x(s)` against mean MSE for each strategy.
fn panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    summary: &[Summary],
    strategies: &[Strategy],
    title: &str,
    x_desc: &str,
    x: fn(&Summary) -> f64,
    slope_vs_time: bool,
) -> DrawResult
where
    DB::ErrorType: 'static,
{
    let xr = log_range(summary.iter().map(x));
    let yr = log_range(summary.iter().map(|s| s.mse));
    let mut chart = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(42)
        .y_label_area_size(70)
        .build_cartesian_2d(xr.log_scale(), yr.log_scale())?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc("MSE")
        // Few labels and faint minor lines: plotters' log mesh draws a line per minor tick, which over
        // a narrow range turns into a grey band.
        .x_labels(8)
        .y_labels(8)
        .max_light_lines(3)
        .bold_line_style(RGBColor(200, 200, 200))
        .light_line_style(RGBColor(238, 238, 238))
        .x_label_formatter(&|v| format!("{v:.3}").trim_end_matches('0').trim_end_matches('.').to_string())
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .label_style(("sans-serif", 13))
        .draw()?;
    let mut drawn = false;
    for &st in strategies {
        let pts: Vec<(f64, f64)> =
            summary.iter().filter(|s| s.strategy == st).map(|s| (x(s), s.mse)).filter(|p| p.0 > 0.0 && p.1 > 0.0).collect();
        if pts.is_empty() {
            continue;
        }
        drawn = true;
        let (vs_n, vs_t) = slopes(summary, st);
        let fit = if slope_vs_time { vs_t } else { vs_n };
        let label = match fit {
            Some(f) => format!("{st}  (slope {:+.2})", f.slope),
            None => format!("{st}"),
        };
        let c = strategy_colour(st);
        chart
            .draw_series(LineSeries::new(pts.clone(), c.stroke_width(2)))?
            .label(label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 22, y)], c.stroke_width(2)));
        chart.draw_series(pts.iter().map(|p| Circle::new(*p, 4, c.filled())))?;
    }
    // Rows with no error to draw on a log scale (MSE 0: the runs equal the reference) are said, not
    // silently left out (an empty plot without a word: a user trial).
    let zero = undrawn(summary, strategies);
    if zero > 0 {
        let note = format!("{zero} row{} with MSE 0 (equal to the reference): not on a log scale", if zero == 1 { "" } else { "s" });
        area.draw(&Text::new(note, (100, 48), ("sans-serif", 14).into_font().color(&RED)))?;
    }
    if !drawn {
        return Ok(());
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerLeft)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()?;
    Ok(())
}

/// The rows of `strategies` in `summary` that a log-scale plot cannot show for their MSE of 0.
pub fn undrawn(summary: &[Summary], strategies: &[Strategy]) -> usize {
    summary.iter().filter(|s| strategies.contains(&s.strategy) && s.mse == 0.0).count()
}

/// Draw the two panels into an RGB buffer of [`PLOT_SIZE`].
pub fn draw(summary: &[Summary], strategies: &[Strategy], what: &str) -> Result<Vec<u8>, String> {
    ensure_font();
    let (w, h) = PLOT_SIZE;
    let mut buf = vec![255u8; (w * h * 3) as usize];
    let res: DrawResult = (|| {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE)?;
        let (left, right) = root.split_horizontally(w / 2);
        panel(&left, summary, strategies, &format!("MSE vs {what}"), what, |s| s.n as f64, false)?;
        panel(&right, summary, strategies, "MSE vs render time", "seconds", |s| s.seconds, true)?;
        root.present()?;
        Ok(())
    })();
    res.map_err(|e| format!("plot: {e}"))?;
    Ok(buf)
}

/// Write `study.png`.
pub fn write(path: &Path, summary: &[Summary], strategies: &[Strategy], what: &str) -> Result<(), String> {
    let buf = draw(summary, strategies, what)?;
    save_rgb(path, PLOT_SIZE.0, PLOT_SIZE.1, buf)
}

/// Save an 8-bit RGB buffer as PNG, atomically, with the strongest compression (these images are
/// meant to be committed next to a README).
pub fn save_rgb(path: &Path, w: u32, h: u32, buf: Vec<u8>) -> Result<(), String> {
    use image::codecs::png::{CompressionType, FilterType, PngEncoder};
    use image::ImageEncoder;
    if buf.len() != (w * h * 3) as usize {
        return Err("image size mismatch".into());
    }
    crate::film::output::write_atomic(path, |tmp| {
        let file = std::fs::File::create(tmp).map_err(|e| format!("{}: {e}", path.display()))?;
        let enc = PngEncoder::new_with_quality(std::io::BufWriter::new(file), CompressionType::Best, FilterType::Adaptive);
        enc.write_image(&buf, w, h, image::ExtendedColorType::Rgb8).map_err(|e| format!("{}: {e}", path.display()))
    })
}
