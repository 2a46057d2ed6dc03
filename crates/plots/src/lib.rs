//! The project's figures as PNG (for the README) and SVG (for papers), drawn with
//! plotters. Text uses an embedded DejaVu Sans, so figures render the same on machines
//! without system fonts.

use std::path::Path;
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

/// Font family name the figures use (registered from the embedded file).
const FONT: &str = "sans-serif";
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

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        for style in [FontStyle::Normal, FontStyle::Bold] {
            // The embedded file is a valid TrueType font; a failure would only cost labels.
            let _ = plotters::style::register_font(FONT, style, FONT_BYTES);
        }
    });
}

/// One curve: a value with a spread per x.
#[derive(Debug, Clone)]
pub struct Curve {
    /// Legend label.
    pub label: String,
    /// (x, mean, std) points.
    pub points: Vec<(f64, f64, f64)>,
}

const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

/// Mean curves with ±std error bars on a log y axis, as the paper's mental-simulation
/// figure. Writes `stem.png` and `stem.svg`.
pub fn curves_with_error_bars(
    stem: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    curves: &[Curve],
) -> Result<(), PlotError> {
    register_font();
    if !curves
        .iter()
        .flat_map(|c| &c.points)
        .any(|p| p.1 > 0.0 && p.1.is_finite())
    {
        return Err(PlotError {
            path: stem.display().to_string(),
            problem: "no positive finite values to plot".into(),
        });
    }
    let png = stem.with_extension("png");
    let svg = stem.with_extension("svg");
    draw_curves(
        BitMapBackend::new(&png, (900, 600)).into_drawing_area(),
        title,
        x_label,
        y_label,
        curves,
    )
    .map_err(|problem| PlotError {
        path: png.display().to_string(),
        problem,
    })?;
    draw_curves(
        SVGBackend::new(&svg, (900, 600)).into_drawing_area(),
        title,
        x_label,
        y_label,
        curves,
    )
    .map_err(|problem| PlotError {
        path: svg.display().to_string(),
        problem,
    })
}

fn draw_curves<DB: DrawingBackend>(
    root: DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    x_label: &str,
    y_label: &str,
    curves: &[Curve],
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let err = |e: &dyn std::fmt::Display| e.to_string();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let xs = curves.iter().flat_map(|c| c.points.iter().map(|p| p.0));
    let (x_min, x_max) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
        (a.min(x), b.max(x))
    });
    let ys = curves
        .iter()
        .flat_map(|c| c.points.iter().flat_map(|p| [p.1 - p.2, p.1 + p.2, p.1]));
    let positive: Vec<f64> = ys.filter(|y| *y > 0.0 && y.is_finite()).collect();
    if positive.is_empty() || !x_min.is_finite() {
        return Err("no positive finite values to plot".into());
    }
    let y_min = positive.iter().cloned().fold(f64::INFINITY, f64::min) * 0.8;
    let y_max = positive.iter().cloned().fold(f64::NEG_INFINITY, f64::max) * 1.25;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, (FONT, 22))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(80)
        .build_cartesian_2d((x_min - 0.5)..(x_max + 0.5), (y_min..y_max).log_scale())
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .label_style((FONT, 14))
        .y_label_formatter(&|v| format!("{v:.1e}"))
        .x_label_formatter(&|v| format!("{v:.0}"))
        .draw()
        .map_err(|e| err(&e))?;
    for (i, curve) in curves.iter().enumerate() {
        let color = PALETTE[i % PALETTE.len()];
        chart
            .draw_series(LineSeries::new(
                curve.points.iter().map(|p| (p.0, p.1)),
                color.stroke_width(2),
            ))
            .map_err(|e| err(&e))?
            .label(curve.label.clone())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
        chart
            .draw_series(curve.points.iter().map(|&(x, m, s)| {
                ErrorBar::new_vertical(x, (m - s).max(y_min), m, m + s, color.filled(), 8)
            }))
            .map_err(|e| err(&e))?;
    }
    chart
        .configure_series_labels()
        .label_font((FONT, 15))
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperLeft)
        .draw()
        .map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))
}

/// How [`heatmap`] maps cell values to colours.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum HeatmapScale {
    /// Colour proportional to the value, from `min(0, smallest value)` to the largest; for
    /// values of similar magnitude.
    #[default]
    Linear,
    /// Colour proportional to `log10(value)`, over at most six decades below the largest
    /// value (smaller values and zeros get the lowest colour); for mean |SHAP| values, which
    /// differ by orders of magnitude between (action, output) pairs. Values must be
    /// non-negative and at least one positive.
    Log,
}

/// Matrix of `values` (row-major, `row_labels.len()` × `col_labels.len()`) as coloured
/// cells with a colour bar, as the paper's SHAP knowledge-extraction figure (rows =
/// actions, columns = state outputs, colour = mean |SHAP|). Writes `stem.png` and
/// `stem.svg`. Column labels are turned vertical when they do not fit a cell's width.
pub fn heatmap(
    stem: &Path,
    title: &str,
    row_labels: &[String],
    col_labels: &[String],
    values: &[f64],
    colorbar_label: &str,
    scale: HeatmapScale,
) -> Result<(), PlotError> {
    register_font();
    let invalid = |problem: String| PlotError {
        path: stem.display().to_string(),
        problem,
    };
    let fig = HeatmapFigure::new(title, row_labels, col_labels, values, colorbar_label, scale)
        .map_err(invalid)?;
    let (width, height) = fig.size();
    save(
        stem,
        (width, height),
        |root| fig.draw(root),
        |root| fig.draw(root),
    )
}

/// One partial dependence panel: points (x, y) with axis labels (in the paper, x = an
/// action's value in each observation, y = that action's SHAP contribution to one
/// state output).
#[derive(Debug, Clone, Default)]
pub struct Scatter {
    /// Panel caption, e.g. "a3 → ef_x".
    pub title: String,
    /// X axis description.
    pub x_label: String,
    /// Y axis description.
    pub y_label: String,
    /// (x, y) points; all must be finite. May be empty (an empty panel is drawn).
    pub points: Vec<(f64, f64)>,
}

/// One scatter panel (640×480) with a horizontal line at y = 0, as a single partial
/// dependence plot. Writes `stem.png` and `stem.svg`.
pub fn scatter(stem: &Path, panel: &Scatter) -> Result<(), PlotError> {
    register_font();
    validate_scatter(0, panel).map_err(|problem| PlotError {
        path: stem.display().to_string(),
        problem,
    })?;
    let sizes = PanelSizes {
        title: 20,
        labels: 14,
        desc: 15,
    };
    save(
        stem,
        (640, 480),
        |root| draw_scatter(&root, panel, sizes),
        |root| draw_scatter(&root, panel, sizes),
    )
}

/// Many scatter panels in a grid of `columns` columns (each 400×320 with its own axis
/// ranges) under a common `title`, as the paper's grid of partial dependence plots.
/// Writes `stem.png` and `stem.svg`.
pub fn scatter_grid(
    stem: &Path,
    title: &str,
    panels: &[Scatter],
    columns: usize,
) -> Result<(), PlotError> {
    register_font();
    let invalid = |problem: String| PlotError {
        path: stem.display().to_string(),
        problem,
    };
    if panels.is_empty() {
        return Err(invalid("no panels to draw".into()));
    }
    if columns == 0 {
        return Err(invalid("columns must be at least 1".into()));
    }
    for (i, panel) in panels.iter().enumerate() {
        validate_scatter(i, panel).map_err(invalid)?;
    }
    let columns = columns.min(panels.len());
    let rows = panels.len().div_ceil(columns);
    let (panel_w, panel_h, title_h) = (400u32, 320u32, 50u32);
    let size = (panel_w * columns as u32, title_h + panel_h * rows as u32);
    save(
        stem,
        size,
        |root| draw_grid(root, title, panels, (rows, columns), title_h),
        |root| draw_grid(root, title, panels, (rows, columns), title_h),
    )
}

/// Draws one figure into `stem.png` and then `stem.svg` (two closures because the
/// backends are different types).
fn save(
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

fn err_string(e: impl std::fmt::Display) -> String {
    e.to_string()
}

/// Viridis, sampled at 9 evenly spaced points (matplotlib's values) and interpolated
/// linearly: perceptually ordered and readable in grey scale.
const VIRIDIS: [(u8, u8, u8); 9] = [
    (68, 1, 84),
    (71, 44, 122),
    (59, 82, 139),
    (44, 113, 142),
    (33, 145, 140),
    (40, 174, 128),
    (94, 201, 98),
    (170, 220, 50),
    (253, 231, 37),
];

/// Colour of `t` in [0, 1] (clamped) on the viridis map.
fn viridis(t: f64) -> RGBColor {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let x = t * (VIRIDIS.len() - 1) as f64;
    let i = (x.floor() as usize).min(VIRIDIS.len() - 2);
    let f = x - i as f64;
    let lerp = |a: u8, b: u8| (a as f64 + (b as f64 - a as f64) * f).round() as u8;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    RGBColor(lerp(a.0, b.0), lerp(a.1, b.1), lerp(a.2, b.2))
}

/// `10` with `e` as superscript digits, e.g. "10⁻³".
fn power_of_ten(e: i32) -> String {
    const SUP: [char; 10] = ['⁰', '¹', '²', '³', '⁴', '⁵', '⁶', '⁷', '⁸', '⁹'];
    let mut s = String::from("10");
    if e < 0 {
        s.push('⁻');
    }
    for d in e.unsigned_abs().to_string().bytes() {
        s.push(SUP[(d - b'0') as usize]);
    }
    s
}

/// A "nice" tick step (1, 2 or 5 × 10ⁿ) giving about `n` ticks over `span`.
fn nice_step(span: f64, n: f64) -> f64 {
    let raw = span / n;
    let mag = 10f64.powf(raw.log10().floor());
    let f = raw / mag;
    let nice = if f < 1.5 {
        1.0
    } else if f < 3.5 {
        2.0
    } else if f < 7.5 {
        5.0
    } else {
        10.0
    };
    nice * mag
}

/// Tick label for `v` when ticks are about `step` apart: plain decimals for ordinary
/// magnitudes, scientific notation for very small or large ones.
fn tick_label(v: f64, step: f64) -> String {
    if v.abs() < step.abs() * 1e-6 || v == 0.0 {
        return "0".into();
    }
    let step_exp = step.abs().log10().floor();
    let mag = v.abs().max(step.abs());
    if mag >= 1e5 || step_exp < -4.0 {
        let digits = (mag.log10().floor() - step_exp).clamp(0.0, 6.0) as usize;
        format!("{v:.digits$e}")
    } else {
        let decimals = (-step_exp).max(0.0) as usize;
        format!("{v:.decimals$}")
    }
}

/// Validated heat map with its colour scale.
struct HeatmapFigure<'a> {
    title: &'a str,
    rows: &'a [String],
    cols: &'a [String],
    values: &'a [f64],
    colorbar_label: &'a str,
    scale: HeatmapScale,
    /// Colour scale bounds (log10 of the value for the log scale).
    lo: f64,
    hi: f64,
}

const HM_TITLE: u32 = 22;
const HM_ROW_FONT: u32 = 16;
const HM_COL_FONT: u32 = 14;
const HM_TICK_FONT: u32 = 14;

impl<'a> HeatmapFigure<'a> {
    fn new(
        title: &'a str,
        rows: &'a [String],
        cols: &'a [String],
        values: &'a [f64],
        colorbar_label: &'a str,
        scale: HeatmapScale,
    ) -> Result<Self, String> {
        if rows.is_empty() {
            return Err("heat map has no rows (row_labels is empty)".into());
        }
        if cols.is_empty() {
            return Err("heat map has no columns (col_labels is empty)".into());
        }
        if values.len() != rows.len() * cols.len() {
            return Err(format!(
                "values has {} entries, expected rows × columns = {} × {} = {}",
                values.len(),
                rows.len(),
                cols.len(),
                rows.len() * cols.len()
            ));
        }
        let at = |k: usize| {
            format!(
                "value at row {} ({}), column {} ({})",
                k / cols.len(),
                rows[k / cols.len()],
                k % cols.len(),
                cols[k % cols.len()]
            )
        };
        if let Some(k) = values.iter().position(|v| !v.is_finite()) {
            return Err(format!("{} is not finite: {}", at(k), values[k]));
        }
        let max = values.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        let min = values.iter().cloned().fold(f64::INFINITY, f64::min);
        let (lo, hi) = match scale {
            HeatmapScale::Linear => {
                let lo = min.min(0.0);
                if max > lo { (lo, max) } else { (lo, lo + 1.0) }
            }
            HeatmapScale::Log => {
                if let Some(k) = values.iter().position(|v| *v < 0.0) {
                    return Err(format!(
                        "log scale needs non-negative values, but {} is {}",
                        at(k),
                        values[k]
                    ));
                }
                if max <= 0.0 {
                    return Err("log scale needs at least one positive value (all are 0)".into());
                }
                let floor = max * 1e-6;
                let min_shown = values
                    .iter()
                    .cloned()
                    .filter(|v| *v >= floor)
                    .fold(f64::INFINITY, f64::min);
                let (mut lo, mut hi) = (min_shown.log10(), max.log10());
                if hi - lo < 1e-9 {
                    lo = hi - 1.0;
                }
                // At least two whole decades as colour bar ticks.
                if hi.floor() - lo.ceil() < 1.0 {
                    lo = lo.floor();
                    hi = hi.ceil();
                    if hi - lo < 1.0 {
                        lo = hi - 1.0;
                    }
                }
                (lo, hi)
            }
        };
        Ok(Self {
            title,
            rows,
            cols,
            values,
            colorbar_label,
            scale,
            lo,
            hi,
        })
    }

    /// Figure size: 1400 px wide (wider for many columns), height from the row count.
    fn size(&self) -> (u32, u32) {
        let width = 1400.max(330 + 44 * self.cols.len() as u32);
        let cell_h = if self.rows.len() <= 12 { 52 } else { 36 };
        // Bottom area: room for vertical column labels (about 9 px per character).
        let longest = self
            .cols
            .iter()
            .map(|c| c.chars().count())
            .max()
            .unwrap_or(1) as u32;
        let height = 70 + cell_h * self.rows.len() as u32 + 40 + 9 * longest;
        (width, height.max(360))
    }

    /// Position of a value on the colour scale, in [0, 1].
    fn fraction(&self, v: f64) -> f64 {
        let x = match self.scale {
            HeatmapScale::Linear => v,
            HeatmapScale::Log if v > 0.0 => v.log10(),
            HeatmapScale::Log => self.lo,
        };
        ((x - self.lo) / (self.hi - self.lo)).clamp(0.0, 1.0)
    }

    /// Colour bar ticks as (fraction along the bar, label).
    fn ticks(&self) -> Vec<(f64, String)> {
        let span = self.hi - self.lo;
        match self.scale {
            HeatmapScale::Log => {
                let (first, last) = (self.lo.ceil() as i32, self.hi.floor() as i32);
                let every = ((last - first) / 8 + 1).max(1);
                (first..=last)
                    .filter(|e| (e - first) % every == 0)
                    .map(|e| ((e as f64 - self.lo) / span, power_of_ten(e)))
                    .collect()
            }
            HeatmapScale::Linear => {
                let step = nice_step(span, 6.0);
                let first = (self.lo / step).ceil() as i64;
                let last = (self.hi / step + 1e-9).floor() as i64;
                (first..=last)
                    .map(|k| {
                        let v = k as f64 * step;
                        ((v - self.lo) / span, tick_label(v, step))
                    })
                    .collect()
            }
        }
    }

    fn draw<DB: DrawingBackend>(&self, root: DrawingArea<DB, Shift>) -> Result<(), String>
    where
        DB::ErrorType: 'static,
    {
        root.fill(&WHITE).map_err(err_string)?;
        let (width, height) = root.dim_in_pixel();
        let (width, height) = (width as i32, height as i32);
        let text = |size: u32| TextStyle::from((FONT, size).into_font());
        let text_width = |s: &str, style: &TextStyle| {
            root.estimate_text_size(s, style)
                .map(|(w, _)| w as i32)
                .map_err(err_string)
        };

        // Title.
        root.draw(&Text::new(
            self.title.to_string(),
            (width / 2, 15),
            TextStyle::from((FONT, HM_TITLE).into_font().style(FontStyle::Bold))
                .pos(Pos::new(HPos::Center, VPos::Top)),
        ))
        .map_err(err_string)?;

        // Layout: [margin | row labels | cells | colour bar + ticks + label | margin].
        let row_style = text(HM_ROW_FONT).pos(Pos::new(HPos::Right, VPos::Center));
        let mut row_w = 0;
        for r in self.rows {
            row_w = row_w.max(text_width(r, &row_style)?);
        }
        let tick_style = text(HM_TICK_FONT).pos(Pos::new(HPos::Left, VPos::Center));
        let ticks = self.ticks();
        let mut tick_w = 0;
        for (_, t) in &ticks {
            tick_w = tick_w.max(text_width(t, &tick_style)?);
        }
        let (bar_gap, bar_w) = (28, 22);
        let right = bar_gap + bar_w + 6 + tick_w + 16 + 22 + 15;
        let left = 15 + row_w + 10;
        let top = 60;
        let x0 = left;
        let x1 = width - right;
        let ncols = self.cols.len() as i32;
        let nrows = self.rows.len() as i32;
        let cell_w = (x1 - x0) as f64 / ncols as f64;

        let col_style = text(HM_COL_FONT);
        let mut col_w = 0;
        for c in self.cols {
            col_w = col_w.max(text_width(c, &col_style)?);
        }
        let vertical = col_w as f64 > cell_w - 6.0;
        let label_h = if vertical { col_w } else { HM_COL_FONT as i32 };
        let y1 = (height - 20 - label_h - 8).max(top + nrows);
        let cell_h = (y1 - top) as f64 / nrows as f64;
        let cx = |c: f64| x0 + (c * cell_w).round() as i32;
        let cy = |r: f64| top + (r * cell_h).round() as i32;

        // Cells, separated by thin white lines.
        for (k, v) in self.values.iter().enumerate() {
            let (r, c) = ((k / self.cols.len()) as f64, (k % self.cols.len()) as f64);
            let color = viridis(self.fraction(*v));
            root.draw(&Rectangle::new(
                [(cx(c), cy(r)), (cx(c + 1.0), cy(r + 1.0))],
                color.filled(),
            ))
            .map_err(err_string)?;
            root.draw(&Rectangle::new(
                [(cx(c), cy(r)), (cx(c + 1.0), cy(r + 1.0))],
                WHITE.stroke_width(1),
            ))
            .map_err(err_string)?;
        }
        root.draw(&Rectangle::new(
            [(x0, top), (x1, y1)],
            BLACK.stroke_width(1),
        ))
        .map_err(err_string)?;

        // Row labels left of the cells, column labels below them.
        for (r, label) in self.rows.iter().enumerate() {
            root.draw(&Text::new(
                label.clone(),
                (x0 - 8, cy(r as f64 + 0.5)),
                row_style.clone(),
            ))
            .map_err(err_string)?;
        }
        let col_style = if vertical {
            // Reads bottom to top, ending just below the cells.
            col_style
                .transform(FontTransform::Rotate270)
                .pos(Pos::new(HPos::Right, VPos::Center))
        } else {
            col_style.pos(Pos::new(HPos::Center, VPos::Top))
        };
        for (c, label) in self.cols.iter().enumerate() {
            root.draw(&Text::new(
                label.clone(),
                (cx(c as f64 + 0.5), y1 + 7),
                col_style.clone(),
            ))
            .map_err(err_string)?;
        }

        // Colour bar: one-pixel bands from the lowest (bottom) to the highest (top) colour.
        let bx0 = x1 + bar_gap;
        let bx1 = bx0 + bar_w;
        let bar_h = (y1 - top).max(1);
        for i in 0..bar_h {
            let t = (i as f64 + 0.5) / bar_h as f64;
            root.draw(&Rectangle::new(
                [(bx0, y1 - i - 1), (bx1, y1 - i)],
                viridis(t).filled(),
            ))
            .map_err(err_string)?;
        }
        root.draw(&Rectangle::new(
            [(bx0, top), (bx1, y1)],
            BLACK.stroke_width(1),
        ))
        .map_err(err_string)?;
        for (t, label) in &ticks {
            let y = y1 - (t * bar_h as f64).round() as i32;
            root.draw(&PathElement::new(vec![(bx1, y), (bx1 + 5, y)], BLACK))
                .map_err(err_string)?;
            root.draw(&Text::new(label.clone(), (bx1 + 8, y), tick_style.clone()))
                .map_err(err_string)?;
        }
        root.draw(&Text::new(
            self.colorbar_label.to_string(),
            (bx1 + 8 + tick_w + 16, (top + y1) / 2),
            text(HM_ROW_FONT)
                .transform(FontTransform::Rotate270)
                .pos(Pos::new(HPos::Center, VPos::Top)),
        ))
        .map_err(err_string)?;
        root.present().map_err(err_string)
    }
}

fn validate_scatter(index: usize, panel: &Scatter) -> Result<(), String> {
    match panel
        .points
        .iter()
        .position(|(x, y)| !x.is_finite() || !y.is_finite())
    {
        Some(k) => Err(format!(
            "panel {index} ({:?}): point {k} is not finite: ({}, {})",
            panel.title, panel.points[k].0, panel.points[k].1
        )),
        None => Ok(()),
    }
}

/// Axis range over `values` with 5 % padding; a zero-width (or empty) range is widened
/// around its value so the chart has a non-degenerate coordinate system.
fn padded_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (min, max) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    });
    if !min.is_finite() || !max.is_finite() {
        return (-1.0, 1.0);
    }
    let span = max - min;
    let mid = 0.5 * (min + max);
    if span <= mid.abs() * 1e-9 || span <= f64::MIN_POSITIVE {
        let pad = if mid.abs() > 0.0 {
            mid.abs() * 0.1
        } else {
            1.0
        };
        (mid - pad, mid + pad)
    } else {
        (min - 0.05 * span, max + 0.05 * span)
    }
}

/// Font sizes of one scatter panel.
#[derive(Clone, Copy)]
struct PanelSizes {
    title: u32,
    labels: u32,
    desc: u32,
}

fn draw_grid<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    title: &str,
    panels: &[Scatter],
    (rows, columns): (usize, usize),
    title_h: u32,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(err_string)?;
    let (top, body) = root.split_vertically(title_h);
    top.draw(&Text::new(
        title.to_string(),
        (top.dim_in_pixel().0 as i32 / 2, title_h as i32 / 2),
        TextStyle::from((FONT, 22).into_font().style(FontStyle::Bold))
            .pos(Pos::new(HPos::Center, VPos::Center)),
    ))
    .map_err(err_string)?;
    let sizes = PanelSizes {
        title: 16,
        labels: 12,
        desc: 13,
    };
    for (area, panel) in body.split_evenly((rows, columns)).iter().zip(panels) {
        draw_scatter(area, panel, sizes)?;
    }
    root.present().map_err(err_string)
}

fn draw_scatter<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    panel: &Scatter,
    sizes: PanelSizes,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    area.fill(&WHITE).map_err(err_string)?;
    let (x_min, x_max) = padded_range(panel.points.iter().map(|p| p.0));
    // The y range always includes 0, the reference line of a SHAP contribution.
    let (y_min, y_max) = padded_range(panel.points.iter().map(|p| p.1).chain(std::iter::once(0.0)));
    let x_step = nice_step(x_max - x_min, 5.0);
    let y_step = nice_step(y_max - y_min, 5.0);
    let x_fmt = move |v: &f64| tick_label(*v, x_step);
    let y_fmt = move |v: &f64| tick_label(*v, y_step);
    let mut y_label_w = 0;
    for v in [y_min, y_max, 0.5 * (y_min + y_max)] {
        let (w, _) = area
            .estimate_text_size(&y_fmt(&v), &TextStyle::from((FONT, sizes.labels)))
            .map_err(err_string)?;
        y_label_w = y_label_w.max(w);
    }
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.title, (FONT, sizes.title))
        .margin(10)
        // Room for the half of the last x tick label that extends past the axis.
        .margin_right(28)
        .x_label_area_size(sizes.labels * 2 + sizes.desc + 8)
        .y_label_area_size(y_label_w + sizes.desc + 22)
        .build_cartesian_2d(x_min..x_max, y_min..y_max)
        .map_err(err_string)?;
    chart
        .configure_mesh()
        .x_desc(panel.x_label.as_str())
        .y_desc(panel.y_label.as_str())
        .label_style((FONT, sizes.labels))
        .axis_desc_style((FONT, sizes.desc))
        .x_labels(6)
        .y_labels(6)
        .x_label_formatter(&x_fmt)
        .y_label_formatter(&y_fmt)
        .light_line_style(WHITE.mix(0.0))
        .bold_line_style(BLACK.mix(0.08))
        .draw()
        .map_err(err_string)?;
    chart
        .draw_series(LineSeries::new(
            [(x_min, 0.0), (x_max, 0.0)],
            BLACK.mix(0.6).stroke_width(1),
        ))
        .map_err(err_string)?;
    let color = PALETTE[0];
    chart
        .draw_series(
            panel
                .points
                .iter()
                .map(|&(x, y)| Circle::new((x, y), 2, color.mix(0.45).filled())),
        )
        .map_err(err_string)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn curves_render_to_png_and_svg() {
        let dir = std::env::temp_dir().join(format!("causal-arm-plots-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let stem = dir.join("curves");
        let curve = |label: &str, k: f64| Curve {
            label: label.into(),
            points: (1..=10)
                .map(|s| (s as f64, k * s as f64, 0.1 * k * s as f64))
                .collect(),
        };
        curves_with_error_bars(
            &stem,
            "test",
            "step",
            "MAE",
            &[curve("a", 1e-3), curve("b", 2e-2)],
        )
        .unwrap();
        let png = std::fs::read(stem.with_extension("png")).unwrap();
        assert_eq!(&png[1..4], b"PNG");
        let svg = std::fs::read_to_string(stem.with_extension("svg")).unwrap();
        assert!(
            svg.contains("<svg") && svg.matches("<text").count() > 10 && svg.contains("step"),
            "labels drawn as text"
        );
        let err = curves_with_error_bars(&stem, "t", "x", "y", &[])
            .unwrap_err()
            .to_string();
        assert!(err.contains("no positive finite values"), "{err}");
    }
}
