//! Mean curves with error bars on a log axis (the paper's mental-simulation figure).

use std::path::Path;

use plotters::prelude::*;

use crate::{FONT, PALETTE, PlotError, register_font};

/// One curve: a value with a spread per x.
#[derive(Debug, Clone)]
pub struct Curve {
    /// Legend label.
    pub label: String,
    /// (x, mean, std) points.
    pub points: Vec<(f64, f64, f64)>,
}

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
