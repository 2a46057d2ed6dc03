//! The project's figures as PNG (for the README) and SVG (for papers), drawn with
//! plotters. Text uses an embedded DejaVu Sans, so figures render the same on machines
//! without system fonts.

mod axis;
mod curves;
mod heatmap;
mod scatter;

use std::path::Path;
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;

pub use curves::{Curve, curves_with_error_bars};
pub use heatmap::{HeatmapScale, heatmap};
pub use scatter::{Scatter, scatter, scatter_grid};

/// Font family name the figures use (registered from the embedded file).
pub(crate) const FONT: &str = "sans-serif";
static FONT_BYTES: &[u8] = include_bytes!("../fonts/DejaVuSans.ttf");

/// Why a figure could not be drawn.
#[derive(Debug, thiserror::Error)]
#[error("{path}: cannot draw figure: {problem}")]
pub struct PlotError {
    /// Output file.
    pub path: String,
    /// What failed.
    pub problem: String,
}

pub(crate) fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        for style in [FontStyle::Normal, FontStyle::Bold] {
            // The embedded file is a valid TrueType font; a failure would only cost labels.
            let _ = plotters::style::register_font(FONT, style, FONT_BYTES);
        }
    });
}

/// Series colours (matplotlib's tab10).
pub(crate) const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

/// Draws one figure into `stem.png` and then `stem.svg` (two closures because the
/// backends are different types).
pub(crate) fn save(
    stem: &Path,
    size: (u32, u32),
    png_draw: impl FnOnce(DrawingArea<BitMapBackend<'_>, Shift>) -> Result<(), String>,
    svg_draw: impl FnOnce(DrawingArea<SVGBackend<'_>, Shift>) -> Result<(), String>,
) -> Result<(), PlotError> {
    let png = stem.with_extension("png");
    let svg = stem.with_extension("svg");
    png_draw(BitMapBackend::new(&png, size).into_drawing_area()).map_err(|problem| PlotError {
        path: png.display().to_string(),
        problem,
    })?;
    svg_draw(SVGBackend::new(&svg, size).into_drawing_area()).map_err(|problem| PlotError {
        path: svg.display().to_string(),
        problem,
    })
}

pub(crate) fn err_string(e: impl std::fmt::Display) -> String {
    e.to_string()
}
