//! The figures of the multi-step report: score against horizon of the strongest pairs,
//! and the magnet's effect on the cube's height per context.

use std::path::{Path, PathBuf};

use causal_arm_dataset::Context;

use super::MultiStep;
use crate::Result;

/// Pairs drawn in the score figure besides the magnet's effect on the cube's height.
const FIGURE_PAIRS: usize = 5;

/// The paper's multi-step finding: turning the magnet on is followed by lifting the cube.
pub const MAGNET_PAIR: (&str, &str) = ("a_mgt", "o_z");

/// Writes `multistep_scores.png/svg` (score vs horizon of the strongest pairs and of
/// a_mgt → o_z, bars = the 95 % bootstrap interval) and, where the data has a magnet,
/// `multistep_a_mgt_o_z.png/svg` (its spread per context beside the chained error on o_z):
/// what the report shows of the multi-step effects. Returns the PNG paths.
pub fn draw_figures(result: &MultiStep, dir: &Path) -> Result<Vec<PathBuf>> {
    let label =
        |a: usize, s: usize| format!("{} → {}", result.action_names[a], result.state_names[s]);
    let mut pairs = result.strongest_pairs(FIGURE_PAIRS);
    let magnet = (
        result.action_names.iter().position(|n| n == MAGNET_PAIR.0),
        result.state_names.iter().position(|n| n == MAGNET_PAIR.1),
    );
    if let (Some(a), Some(s)) = magnet
        && !pairs.contains(&(a, s))
    {
        pairs.push((a, s));
    }
    let curves: Vec<causal_arm_plots::Curve> = pairs
        .iter()
        .filter_map(|&(a, s)| {
            let curve = result.pair(
                Context::ALL,
                &result.action_names[a],
                &result.state_names[s],
            )?;
            Some(causal_arm_plots::Curve {
                label: label(a, s),
                points: curve
                    .iter()
                    .map(|p| {
                        let half = (p.interval[1] - p.interval[0]) / 2.0;
                        (p.horizon as f64, p.score, half)
                    })
                    .collect(),
            })
        })
        .collect();
    let stem = dir.join("multistep_scores");
    causal_arm_plots::curves_with_error_bars(
        &stem,
        &format!(
            "CAI through the chained FM (verdict: lower bound > {})",
            result.settings.kappa
        ),
        "horizon h of s(t+h)",
        "mean effect / chained h-step error",
        &curves,
    )?;
    let mut written = vec![stem.with_extension("png")];
    if let (Some(_), Some(_)) = magnet {
        written.push(draw_magnet(result, dir)?);
    }
    Ok(written)
}

/// The a_mgt → o_z figure: mean spread of the predicted cube height per context and the
/// chained model's error on it over all states, against the horizon.
fn draw_magnet(result: &MultiStep, dir: &Path) -> Result<PathBuf> {
    let (action, state) = MAGNET_PAIR;
    let mut curves = Vec::new();
    for context in [Context::ALL, "holding", "not_holding"] {
        if let Some(curve) = result.pair(context, action, state) {
            curves.push(causal_arm_plots::Curve {
                label: format!("spread, {context}"),
                points: curve
                    .iter()
                    .map(|p| (p.horizon as f64, p.effect, 0.0))
                    .collect(),
            });
        }
    }
    if let Some(curve) = result.pair(Context::ALL, action, state) {
        curves.push(causal_arm_plots::Curve {
            label: "chained FM error, all".into(),
            points: curve
                .iter()
                .map(|p| (p.horizon as f64, p.floor, 0.0))
                .collect(),
        });
    }
    let stem = dir.join("multistep_a_mgt_o_z");
    causal_arm_plots::curves_with_error_bars(
        &stem,
        &format!("{action} → {state} through the chained FM"),
        "horizon h of s(t+h)",
        "m",
        &curves,
    )?;
    Ok(stem.with_extension("png"))
}
