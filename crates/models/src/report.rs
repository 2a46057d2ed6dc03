//! What a cross-validation run reports: figures per fold beside the paper's and the
//! predict-the-mean baseline, and the epochs, wall time and size of every network.

use causal_arm_dataset::Experiment;
use causal_arm_mlp::Regressor;
use serde::{Deserialize, Serialize};

use crate::ModelKind;
use crate::fit::FitSettings;
use crate::problems::{HeadInfo, Problem};

/// The paper's 5-fold CV MAE for a figure key (`fm/theta`, `im_pre/assembly`, …).
pub fn paper_figure(experiment: Experiment, key: &str) -> Option<f64> {
    let table: &[(&str, f64)] = match experiment {
        Experiment::Exp1 => &[
            ("fm/ef", 6.9e-3),
            ("fm/theta", 3.4e-3),
            ("im_mono/joint", 0.0529),
            ("im_pre/base", 3.06e-4),
            ("im_pre/pre", 0.0481),
            ("im_pre/assembly", 0.0481),
            ("ablation/zero", 0.322),
            ("ablation/sampled", 0.371),
        ],
        Experiment::Exp2 => &[
            ("fm/obj_pos", 0.0089),
            ("fm/obj_rot", 0.0721),
            ("fm/colour", 0.004),
            ("fm/ef_pos", 0.008),
            ("fm/ef_rot", 0.0625),
            ("fm/theta", 0.0084),
            ("fm/magnet", 1.3e-4),
            ("im_mono/joint", 0.0077),
            ("im_mono/magnet", 4.56e-4),
        ],
    };
    table.iter().find(|(k, _)| *k == key).map(|(_, v)| *v)
}

/// One figure of one fold.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FoldFigure {
    /// Model MAE on the fold's held-out rows.
    pub mae: f64,
    /// Predict-the-training-mean MAE on the same rows.
    pub baseline: f64,
}

/// A figure across folds, next to the paper.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Figure {
    /// `model/head`, e.g. `fm/theta`.
    pub key: String,
    /// Unit of the MAE.
    pub unit: String,
    /// Per fold.
    pub folds: Vec<FoldFigure>,
    /// Mean MAE over folds.
    pub mean: f64,
    /// Standard deviation over folds.
    pub std: f64,
    /// Mean baseline MAE over folds.
    pub baseline: f64,
    /// The paper's figure, if it reports one.
    pub paper: Option<f64>,
}

/// Result of cross-validating one model kind.
#[derive(Debug)]
pub struct KindReport {
    /// Which model.
    pub kind: ModelKind,
    /// Figures with per-fold values.
    pub figures: Vec<Figure>,
    /// Epochs and wall time of each network trained.
    pub runs: Vec<RunRecord>,
    /// Networks from the first fold, to save: (file stem, model, problem metadata).
    pub models: Vec<(String, Regressor, ProblemInfo, FitSettings)>,
}

/// Epochs and wall time of one trained network.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct RunRecord {
    /// `fm fold 1/5`, …
    pub label: String,
    /// Epochs run.
    pub epochs: usize,
    /// Training rows.
    pub rows: usize,
    /// Seconds spent training.
    pub wall_s: f64,
    /// Trainable weights and biases of the network.
    #[serde(default)]
    pub parameters: usize,
    /// Held-out MAE per head during training (with `eval_every`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub curve: Vec<CurvePoint>,
    /// How the network fared as one of several candidates for a factored head.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub selection: Option<Selection>,
}

/// A candidate network of `--factored-auxiliary auto` on the validation rows.
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
pub struct Selection {
    /// The head's MAE on the validation rows (never the test fold).
    pub validation_mae: f64,
    /// The candidate kept for the head.
    pub chosen: bool,
    /// For the best candidate of a head: how it fared against the full FM's head on the
    /// same rows (it is kept only if significantly better).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub against_full_fm: Option<FullFmComparison>,
}

/// A factored head's best candidate against the full FM's head, row by row on the
/// validation rows. The full FM is the model the factored one must not be worse than, so
/// a head keeps the full FM's own network unless its candidate wins by more than chance.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FullFmComparison {
    /// The full FM's MAE on the head over the validation rows.
    pub full_fm_validation_mae: f64,
    /// Candidate minus full FM MAE (negative: the candidate is better).
    pub difference: f64,
    /// Standard error of the difference by batch means over contiguous blocks of rows (the
    /// rows of one episode are not independent).
    pub standard_error: f64,
    /// The difference is below −2 standard errors: the candidate is kept.
    pub candidate_better: bool,
}

impl FullFmComparison {
    /// Blocks the validation rows are cut into for the batch-means standard error.
    pub const BLOCKS: usize = 30;

    /// Compares the row errors of a candidate with the full FM's on the same rows.
    pub fn from_row_errors(candidate: &[f64], full_fm: &[f64]) -> Self {
        let n = candidate.len().min(full_fm.len());
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
        let differences: Vec<f64> = (0..n).map(|i| candidate[i] - full_fm[i]).collect();
        let difference = mean(&differences);
        let block = n.div_ceil(Self::BLOCKS).max(1);
        let block_means: Vec<f64> = differences.chunks(block).map(mean).collect();
        let k = block_means.len();
        let standard_error = if k < 2 {
            f64::INFINITY
        } else {
            let var = block_means
                .iter()
                .map(|m| (m - difference).powi(2))
                .sum::<f64>()
                / (k - 1) as f64;
            (var / k as f64).sqrt()
        };
        Self {
            full_fm_validation_mae: mean(&full_fm[..n]),
            difference,
            standard_error,
            candidate_better: difference < -2.0 * standard_error,
        }
    }
}

/// One point of a learning curve.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CurvePoint {
    /// Epochs done.
    pub epoch: usize,
    /// Training seconds so far (the evaluations themselves not counted).
    pub wall_s: f64,
    /// Held-out MAE of each head, in the heads' order.
    pub mae: Vec<f64>,
}

/// What a saved model needs to know about its problem.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ProblemInfo {
    /// Input feature names.
    pub input_names: Vec<String>,
    /// Output names.
    pub output_names: Vec<String>,
    /// Heads.
    pub heads: Vec<HeadInfo>,
    /// Input columns added to the outputs (delta FM).
    pub offset_columns: Option<Vec<usize>>,
}

impl From<&Problem> for ProblemInfo {
    fn from(p: &Problem) -> Self {
        Self {
            input_names: p.input_names.clone(),
            output_names: p.output_names.clone(),
            heads: p.heads.clone(),
            offset_columns: p.offset_columns.clone(),
        }
    }
}

/// Figures of a kind as its folds are evaluated, in the order first recorded.
#[derive(Default)]
pub(crate) struct FigureTable {
    rows: Vec<(String, String, Vec<FoldFigure>)>,
}

impl FigureTable {
    /// Adds one fold's MAE and baseline of each of `heads` under `prefix/head`.
    pub(crate) fn record(
        &mut self,
        prefix: &str,
        heads: &[HeadInfo],
        mae: &[f64],
        baseline: &[f64],
    ) {
        for ((h, &mae), &baseline) in heads.iter().zip(mae).zip(baseline) {
            let key = format!("{prefix}/{}", h.name);
            let fold = FoldFigure { mae, baseline };
            match self.rows.iter_mut().find(|(k, ..)| *k == key) {
                Some((.., folds)) => folds.push(fold),
                None => self.rows.push((key, h.unit.clone(), vec![fold])),
            }
        }
    }

    /// Adds one fold of a figure that is not a head of a problem (`im_pre/assembly`, …).
    pub(crate) fn single(&mut self, key: &str, unit: &str, mae: f64, baseline: f64) {
        let (prefix, name) = key.rsplit_once('/').unwrap_or((key, key));
        let head = HeadInfo {
            name: name.to_owned(),
            start: 0,
            len: 1,
            unit: unit.to_owned(),
            angular: false,
        };
        self.record(prefix, &[head], &[mae], &[baseline]);
    }

    /// Mean and spread over folds, beside the paper's figure.
    pub(crate) fn summarise(self, experiment: Experiment) -> Vec<Figure> {
        self.rows
            .into_iter()
            .map(|(key, unit, folds)| {
                let n = folds.len().max(1) as f64;
                let mean = folds.iter().map(|f| f.mae).sum::<f64>() / n;
                let var = folds.iter().map(|f| (f.mae - mean).powi(2)).sum::<f64>() / n;
                Figure {
                    paper: paper_figure(experiment, &key),
                    baseline: folds.iter().map(|f| f.baseline).sum::<f64>() / n,
                    key,
                    unit,
                    mean,
                    std: var.sqrt(),
                    folds,
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::FullFmComparison;

    #[test]
    fn a_candidate_is_better_only_by_more_than_two_batch_standard_errors() {
        // Full FM errors alternate 1, 3 per block; the candidate is 0.5 lower everywhere:
        // a constant shift has no spread, so it is significant.
        let full: Vec<f64> = (0..300)
            .map(|i| if (i / 10) % 2 == 0 { 1.0 } else { 3.0 })
            .collect();
        let shifted: Vec<f64> = full.iter().map(|e| e - 0.5).collect();
        let c = FullFmComparison::from_row_errors(&shifted, &full);
        assert!((c.difference + 0.5).abs() < 1e-12 && c.standard_error < 1e-12);
        assert!(c.candidate_better);
        assert_eq!(c.full_fm_validation_mae, 2.0);
        // Better on half the blocks by 1, worse on the other half by 0.9: lower on the mean
        // (−0.05) but well inside the blocks' spread.
        let noisy: Vec<f64> = (0..300)
            .map(|i| full[i] + if (i / 10) % 2 == 0 { -1.0 } else { 0.9 })
            .collect();
        let c = FullFmComparison::from_row_errors(&noisy, &full);
        assert!(c.difference < 0.0 && c.standard_error > 0.1, "{c:?}");
        assert!(!c.candidate_better);
        // Equal errors (the same network) are never "better"; one block gives no spread.
        assert!(!FullFmComparison::from_row_errors(&full, &full).candidate_better);
        assert!(!FullFmComparison::from_row_errors(&[0.0], &[1.0]).candidate_better);
    }
}
