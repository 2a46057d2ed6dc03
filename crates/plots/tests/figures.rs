//! The SHAP figures (heat map, partial dependence scatters) render to PNG and SVG, reject
//! bad input with a clear error, and survive degenerate ranges.

use std::path::PathBuf;

use causal_arm_plots::{HeatmapScale, Scatter, heatmap, scatter, scatter_grid};

/// A fresh directory per test (tests run in parallel within one process).
fn out_dir(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "causal-arm-plots-figures-{}-{test}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Both files exist, the PNG has the PNG signature and is not trivially small, and the SVG
/// holds every expected text.
fn assert_rendered(stem: &std::path::Path, texts: &[&str]) {
    let png = std::fs::read(stem.with_extension("png")).unwrap();
    assert!(png.len() > 2_000, "PNG too small: {} bytes", png.len());
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    let svg = std::fs::read_to_string(stem.with_extension("svg")).unwrap();
    assert!(svg.contains("<svg") && svg.len() > 2_000);
    for text in texts {
        assert!(svg.contains(text), "SVG lacks {text:?}");
    }
}

fn labels(prefix: &str, n: usize) -> Vec<String> {
    (0..n).map(|i| format!("{prefix}{i}")).collect()
}

/// Mean |SHAP| spread over five orders of magnitude, with a zero.
fn log_spread(rows: usize, cols: usize) -> Vec<f64> {
    (0..rows * cols)
        .map(|k| {
            if k == 1 {
                0.0
            } else {
                10f64.powi(-((k % 6) as i32))
            }
        })
        .collect()
}

#[test]
fn heatmap_renders_log_and_linear_scales() {
    let dir = out_dir("heatmap");
    let rows = labels("a", 8);
    let cols = labels("out_", 23);
    let values = log_spread(8, 23);
    for (name, scale) in [("log", HeatmapScale::Log), ("linear", HeatmapScale::Linear)] {
        let stem = dir.join(format!("heatmap_{name}"));
        heatmap(
            &stem,
            "Mean SHAP",
            &rows,
            &cols,
            &values,
            "mean abs SHAP",
            scale,
        )
        .unwrap();
        assert_rendered(&stem, &["Mean SHAP", "a7", "out_22", "mean abs SHAP"]);
    }
    let svg = std::fs::read_to_string(dir.join("heatmap_log.svg")).unwrap();
    assert!(
        svg.contains("10⁰") && svg.contains("10⁻⁵"),
        "colour bar in decades"
    );
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn heatmap_handles_long_labels_and_constant_values() {
    let dir = out_dir("heatmap-edge");
    let rows = vec!["only row".to_string()];
    let cols: Vec<String> = labels("a_rather_long_column_label_", 23);
    for scale in [HeatmapScale::Log, HeatmapScale::Linear] {
        let stem = dir.join(format!("constant_{scale:?}"));
        heatmap(&stem, "t", &rows, &cols, &[0.5; 23], "v", scale).unwrap();
        assert_rendered(&stem, &["a_rather_long_column_label_22"]);
    }
    let stem = dir.join("zeros_linear");
    heatmap(
        &stem,
        "t",
        &rows,
        &cols,
        &[0.0; 23],
        "v",
        HeatmapScale::Linear,
    )
    .unwrap();
    assert_rendered(&stem, &["only row"]);
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn heatmap_rejects_bad_input() {
    let dir = out_dir("heatmap-bad");
    let stem = dir.join("bad");
    let rows = labels("a", 2);
    let cols = labels("c", 3);
    let err = |rows: &[String], cols: &[String], values: &[f64], scale| {
        heatmap(&stem, "t", rows, cols, values, "v", scale)
            .unwrap_err()
            .to_string()
    };
    let e = err(&rows, &cols, &[1.0; 5], HeatmapScale::Linear);
    assert!(
        e.contains("values has 5 entries") && e.contains("2 × 3 = 6"),
        "{e}"
    );
    let e = err(&rows, &[], &[], HeatmapScale::Linear);
    assert!(e.contains("no columns"), "{e}");
    let e = err(&[], &cols, &[], HeatmapScale::Linear);
    assert!(e.contains("no rows"), "{e}");
    let mut values = [1.0; 6];
    values[4] = f64::NAN;
    let e = err(&rows, &cols, &values, HeatmapScale::Linear);
    assert!(
        e.contains("not finite") && e.contains("row 1 (a1), column 1 (c1)"),
        "{e}"
    );
    values[4] = f64::INFINITY;
    assert!(err(&rows, &cols, &values, HeatmapScale::Log).contains("not finite"));
    values[4] = -0.1;
    let e = err(&rows, &cols, &values, HeatmapScale::Log);
    assert!(e.contains("non-negative") && e.contains("-0.1"), "{e}");
    let e = err(&rows, &cols, &[0.0; 6], HeatmapScale::Log);
    assert!(e.contains("at least one positive"), "{e}");
    // Negative values are fine on a linear scale.
    heatmap(&stem, "t", &rows, &cols, &values, "v", HeatmapScale::Linear).unwrap();
    std::fs::remove_dir_all(dir).unwrap();
}

fn line_panel(i: usize) -> Scatter {
    Scatter {
        title: format!("a{i} → theta{i}"),
        x_label: format!("a{i}"),
        y_label: format!("SHAP a{i}"),
        points: (0..200)
            .map(|k| {
                let x = k as f64 / 100.0 - 1.0;
                (x, 10f64.powi(-(i as i32)) * x)
            })
            .collect(),
    }
}

#[test]
fn scatter_and_grid_render() {
    let dir = out_dir("scatter");
    let stem = dir.join("single");
    scatter(&stem, &line_panel(1)).unwrap();
    assert_rendered(&stem, &["a1 → theta1", "SHAP a1"]);
    let stem = dir.join("grid");
    let panels: Vec<Scatter> = (0..10).map(line_panel).collect();
    scatter_grid(&stem, "PDPs", &panels, 4).unwrap();
    assert_rendered(&stem, &["PDPs", "a0 → theta0", "a9 → theta9", "SHAP a9"]);
    // More columns than panels.
    scatter_grid(&stem, "PDPs", &panels[..2], 4).unwrap();
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn scatter_survives_degenerate_ranges() {
    let dir = out_dir("scatter-degenerate");
    let constant_x = Scatter {
        title: "always 0".into(),
        points: (0..50).map(|k| (0.0, k as f64 * 1e-7)).collect(),
        ..Scatter::default()
    };
    let zero_y = Scatter {
        title: "no effect".into(),
        points: (0..50).map(|k| (k as f64, 0.0)).collect(),
        ..Scatter::default()
    };
    let single = Scatter {
        title: "one point".into(),
        points: vec![(3.0, -2.0)],
        ..Scatter::default()
    };
    let huge = Scatter {
        title: "huge".into(),
        points: vec![(1e9, 1e12), (1e9 + 1.0, 1e12)],
        ..Scatter::default()
    };
    let empty = Scatter {
        title: "empty".into(),
        ..Scatter::default()
    };
    let panels = [constant_x, zero_y, single, huge, empty];
    for (i, panel) in panels.iter().enumerate() {
        let stem = dir.join(format!("panel{i}"));
        scatter(&stem, panel).unwrap();
        assert_rendered(&stem, &[&panel.title]);
    }
    let stem = dir.join("grid");
    scatter_grid(&stem, "degenerate", &panels, 3).unwrap();
    assert_rendered(&stem, &["always 0", "no effect", "empty"]);
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn scatter_rejects_bad_input() {
    let dir = out_dir("scatter-bad");
    let stem = dir.join("bad");
    let mut panel = line_panel(0);
    panel.points[7] = (0.5, f64::NAN);
    let e = scatter(&stem, &panel).unwrap_err().to_string();
    assert!(e.contains("point 7 is not finite"), "{e}");
    let e = scatter_grid(&stem, "t", &[line_panel(1), panel], 2)
        .unwrap_err()
        .to_string();
    assert!(e.contains("panel 1") && e.contains("not finite"), "{e}");
    let e = scatter_grid(&stem, "t", &[], 2).unwrap_err().to_string();
    assert!(e.contains("no panels"), "{e}");
    let e = scatter_grid(&stem, "t", &[line_panel(1)], 0)
        .unwrap_err()
        .to_string();
    assert!(e.contains("columns must be at least 1"), "{e}");
    std::fs::remove_dir_all(dir).unwrap();
}
