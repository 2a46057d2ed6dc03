//! Renders example SHAP figures (a log-scale heat map of 8 actions × 23 state outputs and a
//! grid of 12 partial dependence panels) with synthetic values, to check the layout by eye:
//! `cargo run --release -p causal_arm_plots --example shap_figures_demo [out_dir]`
//! (default `/tmp/plots_demo`).

use std::path::{Path, PathBuf};

use causal_arm_plots::{HeatmapScale, Scatter, heatmap, scatter, scatter_grid};

/// Deterministic pseudo-random numbers in [0, 1) (no extra dependency for a demo).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = PathBuf::from(
        std::env::args()
            .nth(1)
            .unwrap_or_else(|| "/tmp/plots_demo".into()),
    );
    std::fs::create_dir_all(&dir)?;
    let mut rng = Lcg(42);
    let (rows, cols) = action_and_state_names();
    let values = mean_abs_shap(&mut rng, &rows, &cols);
    draw_heatmaps(&dir, &rows, &cols, &values)?;
    let panels = dependence_panels(&mut rng, &cols);
    scatter_grid(
        &dir.join("pdp_grid"),
        "Partial dependence: SHAP contribution vs action value",
        &panels,
        4,
    )?;
    scatter(&dir.join("pdp_single"), &panels[0])?;
    println!("wrote figures to {}", dir.display());
    Ok(())
}

/// Exp2's 8 actions (rows) and 23 state outputs (columns), so the demo has the real
/// figure's shape and label lengths.
fn action_and_state_names() -> (Vec<String>, Vec<String>) {
    let rows: Vec<String> = (0..7)
        .map(|i| format!("a{i}"))
        .chain(["a_mgt".to_string()])
        .collect();
    let cols: Vec<String> = (0..7)
        .map(|i| format!("theta{i}"))
        .chain(
            [
                "o_x", "o_y", "o_z", "o_R", "o_P", "o_Y", "ef_x", "ef_y", "ef_z", "ef_R", "ef_P",
                "ef_Y", "g_l", "g_r", "m",
            ]
            .map(String::from),
        )
        .collect();
    (rows, cols)
}

/// Values spread over six decades with one exact 0, as real mean |SHAP| values are, so
/// the log scale's floor and ticks get exercised.
fn mean_abs_shap(rng: &mut Lcg, rows: &[String], cols: &[String]) -> Vec<f64> {
    // Each action mostly drives its own joint angle; everything else is 1e-6 … 1e-2.
    (0..rows.len() * cols.len())
        .map(|k| {
            let (r, c) = (k / cols.len(), k % cols.len());
            if r == c {
                0.1 + 0.05 * rng.next()
            } else if r == 7 && c == 22 {
                0.0
            } else {
                10f64.powf(-6.0 + 4.0 * rng.next())
            }
        })
        .collect()
}

/// The heat map on both scales and with labels too long for a cell, the three layouts
/// worth checking by eye.
fn draw_heatmaps(
    dir: &Path,
    rows: &[String],
    cols: &[String],
    values: &[f64],
) -> Result<(), Box<dyn std::error::Error>> {
    heatmap(
        &dir.join("heatmap_log"),
        "Mean |SHAP| of each action on each state output",
        rows,
        cols,
        values,
        "mean |SHAP|",
        HeatmapScale::Log,
    )?;
    heatmap(
        &dir.join("heatmap_linear"),
        "Mean |SHAP| (linear scale)",
        rows,
        cols,
        values,
        "mean |SHAP|",
        HeatmapScale::Linear,
    )?;

    // Long column labels do not fit a cell's width and are drawn vertically.
    let long_cols: Vec<String> = cols.iter().map(|c| format!("{c}_(next)")).collect();
    heatmap(
        &dir.join("heatmap_long_labels"),
        "Long column labels",
        rows,
        &long_cols,
        values,
        "mean |SHAP|",
        HeatmapScale::Log,
    )?;
    Ok(())
}

/// Twelve partial dependence panels of different magnitudes, including the degenerate
/// ones (an action that is always 0, a contribution that is exactly 0) the axes must
/// survive.
fn dependence_panels(rng: &mut Lcg, cols: &[String]) -> Vec<Scatter> {
    (0..12)
        .map(|i| {
            let action = format!("a{}", i % 7);
            let output = &cols[(i * 5) % cols.len()];
            let points = (0..200)
                .map(|_| {
                    let x = match i {
                        10 => 0.0, // an action that is always 0
                        _ => 2.0 * rng.next() - 1.0,
                    };
                    let y = match i {
                        11 => 0.0, // a contribution that is exactly 0
                        _ => {
                            10f64.powi(-(i as i32 % 4) - 1) * (x * (1.0 + i as f64 * 0.3))
                                + 1e-3 * (rng.next() - 0.5)
                        }
                    };
                    (x, y)
                })
                .collect();
            Scatter {
                title: format!("{action} → {output}"),
                x_label: action.clone(),
                y_label: format!("SHAP({action} → {output})"),
                points,
            }
        })
        .collect()
}
