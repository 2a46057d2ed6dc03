//! Action × feature heat maps with a colour bar (the paper's SHAP knowledge-extraction
//! figure).

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::axis::{nice_step, tick_label};
use crate::{FONT, PlotError, err_string, register_font, save};

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

    /// Draws the whole figure; the layout is measured first because the cell area is
    /// what the labels and the colour bar leave free.
    fn draw<DB: DrawingBackend>(&self, root: DrawingArea<DB, Shift>) -> Result<(), String>
    where
        DB::ErrorType: 'static,
    {
        root.fill(&WHITE).map_err(err_string)?;
        let (width, _) = root.dim_in_pixel();

        // Title.
        root.draw(&Text::new(
            self.title.to_string(),
            (width as i32 / 2, 15),
            TextStyle::from((FONT, HM_TITLE).into_font().style(FontStyle::Bold))
                .pos(Pos::new(HPos::Center, VPos::Top)),
        ))
        .map_err(err_string)?;

        let layout = self.layout(&root)?;
        self.draw_cells(&root, &layout)?;
        self.draw_labels(&root, &layout)?;
        self.draw_colour_bar(&root, &layout)?;
        root.present().map_err(err_string)
    }

    /// Measures the labels and places the cells and the colour bar: the cells take what
    /// the row labels (left), the colour bar with its ticks (right) and the column labels
    /// (below, vertical when too wide for a cell) leave.
    fn layout<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
    ) -> Result<HeatmapLayout, String>
    where
        DB::ErrorType: 'static,
    {
        let (width, height) = root.dim_in_pixel();
        let (width, height) = (width as i32, height as i32);
        let widest = |labels: &mut dyn Iterator<Item = &String>, style: &TextStyle| {
            let mut widest = 0;
            for s in labels {
                let (w, _) = root.estimate_text_size(s, style).map_err(err_string)?;
                widest = widest.max(w as i32);
            }
            Ok::<i32, String>(widest)
        };

        // Layout: [margin | row labels | cells | colour bar + ticks + label | margin].
        let row_style = text(HM_ROW_FONT).pos(Pos::new(HPos::Right, VPos::Center));
        let row_w = widest(&mut self.rows.iter(), &row_style)?;
        let tick_style = text(HM_TICK_FONT).pos(Pos::new(HPos::Left, VPos::Center));
        let ticks = self.ticks();
        let tick_w = widest(&mut ticks.iter().map(|(_, t)| t), &tick_style)?;
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
        let col_w = widest(&mut self.cols.iter(), &col_style)?;
        let vertical = col_w as f64 > cell_w - 6.0;
        let label_h = if vertical { col_w } else { HM_COL_FONT as i32 };
        let y1 = (height - 20 - label_h - 8).max(top + nrows);
        let cell_h = (y1 - top) as f64 / nrows as f64;
        let col_style = if vertical {
            // Reads bottom to top, ending just below the cells.
            col_style
                .transform(FontTransform::Rotate270)
                .pos(Pos::new(HPos::Right, VPos::Center))
        } else {
            col_style.pos(Pos::new(HPos::Center, VPos::Top))
        };
        Ok(HeatmapLayout {
            x0,
            x1,
            top,
            y1,
            cell_w,
            cell_h,
            row_style,
            col_style,
            tick_style,
            ticks,
            tick_w,
            bar_gap,
            bar_w,
        })
    }

    /// The cells, separated by thin white lines, framed in black.
    fn draw_cells<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        layout: &HeatmapLayout,
    ) -> Result<(), String>
    where
        DB::ErrorType: 'static,
    {
        let (cx, cy) = (|c| layout.cx(c), |r| layout.cy(r));
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
            [(layout.x0, layout.top), (layout.x1, layout.y1)],
            BLACK.stroke_width(1),
        ))
        .map_err(err_string)
    }

    /// Row labels left of the cells, column labels below them.
    fn draw_labels<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        layout: &HeatmapLayout,
    ) -> Result<(), String>
    where
        DB::ErrorType: 'static,
    {
        for (r, label) in self.rows.iter().enumerate() {
            root.draw(&Text::new(
                label.clone(),
                (layout.x0 - 8, layout.cy(r as f64 + 0.5)),
                layout.row_style.clone(),
            ))
            .map_err(err_string)?;
        }
        for (c, label) in self.cols.iter().enumerate() {
            root.draw(&Text::new(
                label.clone(),
                (layout.cx(c as f64 + 0.5), layout.y1 + 7),
                layout.col_style.clone(),
            ))
            .map_err(err_string)?;
        }
        Ok(())
    }

    /// Colour bar: one-pixel bands from the lowest (bottom) to the highest (top) colour,
    /// its ticks and its label.
    fn draw_colour_bar<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        layout: &HeatmapLayout,
    ) -> Result<(), String>
    where
        DB::ErrorType: 'static,
    {
        let (top, y1) = (layout.top, layout.y1);
        let bx0 = layout.x1 + layout.bar_gap;
        let bx1 = bx0 + layout.bar_w;
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
        for (t, label) in &layout.ticks {
            let y = y1 - (t * bar_h as f64).round() as i32;
            root.draw(&PathElement::new(vec![(bx1, y), (bx1 + 5, y)], BLACK))
                .map_err(err_string)?;
            root.draw(&Text::new(
                label.clone(),
                (bx1 + 8, y),
                layout.tick_style.clone(),
            ))
            .map_err(err_string)?;
        }
        root.draw(&Text::new(
            self.colorbar_label.to_string(),
            (bx1 + 8 + layout.tick_w + 16, (top + y1) / 2),
            text(HM_ROW_FONT)
                .transform(FontTransform::Rotate270)
                .pos(Pos::new(HPos::Center, VPos::Top)),
        ))
        .map_err(err_string)
    }
}

/// The text style of a heat map at `size` pixels; one place for the figure's font.
fn text(size: u32) -> TextStyle<'static> {
    TextStyle::from((FONT, size).into_font())
}

/// Where the parts of a heat map go (pixels) and the styles measured for them, computed
/// once so cells, labels and colour bar line up.
struct HeatmapLayout {
    /// Left and right edge of the cells.
    x0: i32,
    x1: i32,
    /// Top and bottom edge of the cells (and of the colour bar).
    top: i32,
    y1: i32,
    cell_w: f64,
    cell_h: f64,
    row_style: TextStyle<'static>,
    col_style: TextStyle<'static>,
    tick_style: TextStyle<'static>,
    /// Colour bar ticks as (fraction along the bar, label).
    ticks: Vec<(f64, String)>,
    /// Widest tick label, which places the colour bar's label.
    tick_w: i32,
    /// Gap between the cells and the colour bar, and the bar's width.
    bar_gap: i32,
    bar_w: i32,
}

impl HeatmapLayout {
    /// x of the left edge of column `c` (fractional for centres).
    fn cx(&self, c: f64) -> i32 {
        self.x0 + (c * self.cell_w).round() as i32
    }

    /// y of the top edge of row `r` (fractional for centres).
    fn cy(&self, r: f64) -> i32 {
        self.top + (r * self.cell_h).round() as i32
    }
}
