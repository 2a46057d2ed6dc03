//! Scatter panels, alone or in a grid (the paper's partial dependence plots).

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::axis::{nice_step, tick_label};
use crate::{FONT, PALETTE, PlotError, err_string, register_font, save};

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
