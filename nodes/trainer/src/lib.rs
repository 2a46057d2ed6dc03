//! The learning half of the paper: forward models (FM) and inverse models (IM) trained
//! from experiment datasets, judged by k-fold cross-validation next to the paper's figures
//! and the predict-the-mean baseline, saved as safetensors + JSON model files.
//!
//! Node logic lives here without DDS; the `causal_arm_trainer` node serves loaded models
//! as ROS 2 services, and `causal-arm train` drives [`cross_validate`] from the CLI.

pub mod fit;
pub mod job;
pub mod mental;
pub mod model_file;
pub mod problems;
pub mod serve;
pub mod structure;

use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use causal_arm_dataset::{Dataset, Experiment};
pub use causal_arm_mlp::LrSchedule;
use causal_arm_mlp::{MlpError, Optimizer, Regressor, TrainConfig};
use serde::{Deserialize, Serialize};

use fit::{
    FitSettings, FitWatch, Progress, fit, folds, head_mae, mean_baseline_mae, predict, take_rows,
    training_rows,
};
pub use model_file::{LoadedModel, ModelMeta, load_model, save_model};
use problems::{FmTarget, HeadInfo, Problem};

/// Why training or evaluation failed.
#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    /// The network library refused (shapes, file format).
    #[error(transparent)]
    Mlp(#[from] MlpError),
    /// Bad options.
    #[error("{0}")]
    Options(String),
    /// The loss became NaN or infinite.
    #[error(
        "{label}: training diverged at epoch {epoch} (loss is not finite); lower the learning rate"
    )]
    Diverged {
        /// Model and fold.
        label: String,
        /// Epoch.
        epoch: usize,
    },
    /// Training was asked to stop (Ctrl-C in the trainer node).
    #[error("{label}: stopped before epoch {} on request", epoch + 1)]
    Stopped {
        /// Model and fold.
        label: String,
        /// Epochs completed.
        epoch: usize,
    },
    /// A model file could not be read or written.
    #[error("{path}: {problem}")]
    File {
        /// File.
        path: std::path::PathBuf,
        /// What failed.
        problem: String,
    },
}

/// The paper's models.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ModelKind {
    /// Forward model [s(t), a(t)] → s(t+1), one head per state sub-vector.
    Fm,
    /// Monolithic inverse model [s(t), s′(t+1)] → a(t).
    ImMono,
    /// Pre-computation IM: base IM, pre-network and their assembly (exp 1).
    ImPre,
    /// The base IM fed θ(t+1) = 0 or θ(t+1) sampled from the dataset (exp 1).
    Ablation,
    /// Forward model factored by a found causal graph: one network per head, fed only the
    /// head's parents ([`structure::head_problem`]). Needs [`TrainOptions::graph`].
    FmFactored,
}

impl ModelKind {
    /// Every model the paper trains for `experiment`, in the order `all` runs them.
    pub fn all_for(experiment: Experiment) -> Vec<ModelKind> {
        match experiment {
            Experiment::Exp1 => vec![Self::Fm, Self::ImMono, Self::ImPre, Self::Ablation],
            Experiment::Exp2 => vec![Self::Fm, Self::ImMono],
        }
    }

    /// Name on the command line and in files.
    pub fn name(self) -> &'static str {
        match self {
            Self::Fm => "fm",
            Self::ImMono => "im-mono",
            Self::ImPre => "im-pre",
            Self::Ablation => "ablation",
            Self::FmFactored => "fm-factored",
        }
    }
}

impl std::str::FromStr for ModelKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        [
            Self::Fm,
            Self::ImMono,
            Self::ImPre,
            Self::Ablation,
            Self::FmFactored,
        ]
        .into_iter()
        .find(|k| k.name() == s)
        .ok_or_else(|| {
            format!(
                "unknown model {s:?}: expected fm, im-mono, im-pre, ablation, fm-factored or all"
            )
        })
    }
}

/// Epoch budgets: the paper's protocol, or a small one for demos and tests.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Profile {
    /// FM 60 (exp 1) / 100 (exp 2) epochs, IM 1,000, base IM 100, pre-network 4,000.
    Paper,
    /// A few epochs of each, minutes on 2 cores.
    Quick,
}

impl std::str::FromStr for Profile {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "paper" => Ok(Self::Paper),
            "quick" => Ok(Self::Quick),
            other => Err(format!(
                "unknown profile {other:?}: expected paper or quick"
            )),
        }
    }
}

/// One network of a model kind: its label, its epochs in `profile`, and optimizer.
fn schedule(kind_part: &str, experiment: Experiment, profile: Profile) -> (usize, Optimizer) {
    let adamw = Optimizer::AdamW {
        weight_decay: 0.004,
    };
    match (kind_part, profile) {
        ("fm", Profile::Paper) => (
            if experiment == Experiment::Exp1 {
                60
            } else {
                100
            },
            Optimizer::Adam,
        ),
        ("fm", Profile::Quick) => (20, Optimizer::Adam),
        ("im_mono", Profile::Paper) => (1000, adamw),
        ("im_mono", Profile::Quick) => (30, adamw),
        ("base", Profile::Paper) => (100, Optimizer::Adam),
        ("base", Profile::Quick) => (20, Optimizer::Adam),
        ("pre", Profile::Paper) => (4000, adamw),
        ("pre", _) => (40, adamw),
        _ => (20, Optimizer::Adam),
    }
}

/// Everything `causal-arm train` decides.
#[derive(Debug, Clone)]
pub struct TrainOptions {
    /// Epoch budget profile.
    pub profile: Profile,
    /// Overrides every network's epochs.
    pub epochs: Option<usize>,
    /// Cross-validation folds (≥ 2).
    pub folds: usize,
    /// FM hidden layers (the paper does not give sizes).
    pub fm_hidden: Vec<usize>,
    /// IM, base IM and pre-network hidden layers ("4x" stacked in the paper's figure).
    pub im_hidden: Vec<usize>,
    /// Rows per mini-batch.
    pub batch_size: usize,
    /// Learning rate (the paper: 1e-3).
    pub learning_rate: f64,
    /// Learning-rate schedule (the paper: constant).
    pub lr_schedule: LrSchedule,
    /// How the FM predicts s(t+1).
    pub fm_target: FmTarget,
    /// Seed of folds, initial weights and shuffles.
    pub seed: u64,
    /// Run only the first `n` folds (each still holds out 1/k of the rows).
    pub max_folds: Option<usize>,
    /// Set from elsewhere to end training before the next epoch.
    pub stop: Option<Arc<AtomicBool>>,
    /// Measure the held-out MAE every `n` epochs (a learning curve in each [`RunRecord`]).
    pub eval_every: Option<usize>,
    /// A causal graph found by the explainer: the state features no action drives are left
    /// out of the FM and IM, and `fm-factored` gives each head only its parents.
    pub graph: Option<structure::FoundGraph>,
    /// Hidden layers of each network of `fm-factored`.
    pub factored_hidden: Vec<usize>,
    /// Which other outputs each `fm-factored` network learns beside its head
    /// ([`structure::Auxiliary`]).
    pub factored_auxiliary: structure::Auxiliary,
}

impl Default for TrainOptions {
    fn default() -> Self {
        Self {
            profile: Profile::Paper,
            epochs: None,
            folds: 5,
            fm_hidden: vec![256; 3],
            im_hidden: vec![256; 4],
            batch_size: 256,
            learning_rate: 1e-3,
            lr_schedule: LrSchedule::Constant,
            fm_target: FmTarget::Delta,
            seed: 0,
            max_folds: None,
            stop: None,
            eval_every: None,
            graph: None,
            factored_hidden: vec![128; 3],
            factored_auxiliary: structure::Auxiliary::Auto,
        }
    }
}

impl TrainOptions {
    fn settings(&self, part: &str, experiment: Experiment, hidden: &[usize]) -> FitSettings {
        let (epochs, optimizer) = schedule(part, experiment, self.profile);
        FitSettings {
            hidden: hidden.to_vec(),
            train: TrainConfig {
                optimizer,
                learning_rate: self.learning_rate,
                batch_size: self.batch_size,
                seed: self.seed,
                schedule: self.lr_schedule,
            },
            epochs: self.epochs.unwrap_or(epochs),
        }
    }

    /// `problem` without the state features the graph finds unaffected (unchanged without
    /// a graph).
    fn reduced(&self, problem: Problem) -> Result<Problem, TrainError> {
        match &self.graph {
            Some(graph) if !graph.unaffected().is_empty() => {
                structure::reduce(&problem, &graph.unaffected())
            }
            _ => Ok(problem),
        }
    }

    fn validate(&self) -> Result<(), TrainError> {
        if self.folds < 2 {
            return Err(TrainError::Options(format!(
                "--folds must be at least 2, got {}",
                self.folds
            )));
        }
        if self.epochs == Some(0) {
            return Err(TrainError::Options("--epochs must be at least 1".into()));
        }
        if self.batch_size == 0 {
            return Err(TrainError::Options(
                "--batch-size must be at least 1".into(),
            ));
        }
        Ok(())
    }
}

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
}

/// Splits training rows into rows to fit on and the last twentieth, contiguous in time, on
/// which the candidates of a factored head are compared (so the test fold stays unseen).
fn selection_split(train: &[usize]) -> (&[usize], &[usize]) {
    let select = (train.len() / 20).max(1).min(train.len().saturating_sub(1));
    train.split_at(train.len() - select)
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

struct FigureAcc {
    key: String,
    unit: String,
    folds: Vec<FoldFigure>,
}

fn summarise(experiment: Experiment, acc: Vec<FigureAcc>) -> Vec<Figure> {
    acc.into_iter()
        .map(|a| {
            let n = a.folds.len().max(1) as f64;
            let mean = a.folds.iter().map(|f| f.mae).sum::<f64>() / n;
            let var = a.folds.iter().map(|f| (f.mae - mean).powi(2)).sum::<f64>() / n;
            Figure {
                paper: paper_figure(experiment, &a.key),
                baseline: a.folds.iter().map(|f| f.baseline).sum::<f64>() / n,
                key: a.key,
                unit: a.unit,
                mean,
                std: var.sqrt(),
                folds: a.folds,
            }
        })
        .collect()
}

fn record(
    acc: &mut Vec<FigureAcc>,
    prefix: &str,
    heads: &[HeadInfo],
    mae: &[f64],
    baseline: &[f64],
) {
    for ((h, &m), &b) in heads.iter().zip(mae).zip(baseline) {
        let key = format!("{prefix}/{}", h.name);
        let entry = match acc.iter_mut().position(|a| a.key == key) {
            Some(i) => &mut acc[i],
            None => {
                acc.push(FigureAcc {
                    key,
                    unit: h.unit.clone(),
                    folds: Vec::new(),
                });
                acc.last_mut().expect("pushed")
            }
        };
        entry.folds.push(FoldFigure {
            mae: m,
            baseline: b,
        });
    }
}

fn single(acc: &mut Vec<FigureAcc>, key: &str, unit: &str, mae: f64, baseline: f64) {
    let head = HeadInfo {
        name: key.rsplit('/').next().unwrap_or(key).to_owned(),
        start: 0,
        len: 1,
        unit: unit.to_owned(),
        angular: false,
    };
    let prefix = key.rsplit_once('/').map(|(p, _)| p).unwrap_or(key);
    record(acc, prefix, &[head], &[mae], &[baseline]);
}

/// MAE of each head of `model` on rows `test` of `problem`.
fn held_out_mae(
    problem: &Problem,
    model: &Regressor,
    test: &[usize],
) -> Result<Vec<f64>, TrainError> {
    let inputs = take_rows(&problem.inputs, problem.input_names.len(), test);
    let prediction = predict(
        model,
        &inputs,
        problem.offset_columns.as_deref(),
        &problem.heads,
    )?;
    let truth = take_rows(&problem.truth, problem.output_names.len(), test);
    Ok(head_mae(&prediction, &truth, &problem.heads))
}

/// Cross-validates one model kind on `data`.
pub fn cross_validate(
    data: &Dataset,
    kind: ModelKind,
    options: &TrainOptions,
    progress: &mut dyn FnMut(Progress),
) -> Result<KindReport, TrainError> {
    options.validate()?;
    let exp = data.experiment;
    if matches!(kind, ModelKind::ImPre | ModelKind::Ablation) && exp != Experiment::Exp1 {
        return Err(TrainError::Options(format!(
            "{} is defined for exp1 only (the paper's pre-computation study); exp2 has fm and im-mono",
            kind.name()
        )));
    }
    if data.rows() < options.folds * 2 {
        return Err(TrainError::Options(format!(
            "{} transitions are too few for {} folds",
            data.rows(),
            options.folds
        )));
    }
    let n = data.rows();
    let fold_sets = folds(n, options.folds, options.seed);
    let run_folds = options
        .max_folds
        .unwrap_or(options.folds)
        .clamp(1, options.folds);
    let mut acc = Vec::new();
    let mut runs = Vec::new();
    let mut models = Vec::new();
    let mut timed_fit = |problem: &Problem,
                         train: &[usize],
                         test: &[usize],
                         settings: &FitSettings,
                         label: String,
                         progress: &mut dyn FnMut(Progress)|
     -> Result<Regressor, TrainError> {
        let start = Instant::now();
        let mut curve = Vec::new();
        let mut evaluating = std::time::Duration::ZERO;
        let mut look = |epoch: usize, model: &Regressor| -> Result<(), TrainError> {
            let trained = start.elapsed() - evaluating;
            let mae = held_out_mae(problem, model, test)?;
            evaluating = start.elapsed() - trained;
            curve.push(CurvePoint {
                epoch,
                wall_s: trained.as_secs_f64(),
                mae,
            });
            Ok(())
        };
        let watch = FitWatch {
            progress,
            stop: options.stop.as_deref(),
            checkpoint: options
                .eval_every
                .map(|every| (every, &mut look as fit::Checkpoint<'_>)),
        };
        let model = fit(problem, train, settings, options.seed, &label, watch)?;
        let wall = start.elapsed() - evaluating;
        runs.push(RunRecord {
            label,
            epochs: settings.epochs,
            rows: train.len(),
            wall_s: wall.as_secs_f64(),
            parameters: model.mlp.spec().parameters(),
            curve,
            selection: None,
        });
        Ok(model)
    };
    // (label, selection) of every candidate network, set on its run record at the end.
    let mut selections: Vec<(String, Selection)> = Vec::new();
    let k = options.folds;
    for (f, test) in fold_sets.iter().take(run_folds).enumerate() {
        let train = training_rows(n, test);
        let tag = format!("fold {}/{k}", f + 1);
        // Records the figures of `heads` of the problem (auxiliary outputs are left out).
        let evaluate = |problem: &Problem,
                        heads: std::ops::Range<usize>,
                        model: &Regressor,
                        prefix: &str,
                        acc: &mut Vec<FigureAcc>|
         -> Result<(), TrainError> {
            let mae = held_out_mae(problem, model, test)?;
            let baseline = mean_baseline_mae(&problem.truth, &problem.heads, &train, test);
            let range = |v: &[f64]| v[heads.clone()].to_vec();
            let infos = &problem.heads[heads.clone()];
            record(acc, prefix, infos, &range(&mae), &range(&baseline));
            Ok(())
        };
        match kind {
            ModelKind::Fm => {
                let problem = options.reduced(problems::forward_model(data, options.fm_target))?;
                let settings = options.settings("fm", exp, &options.fm_hidden);
                let model = timed_fit(
                    &problem,
                    &train,
                    test,
                    &settings,
                    format!("fm {tag}"),
                    progress,
                )?;
                evaluate(&problem, 0..problem.heads.len(), &model, "fm", &mut acc)?;
                if f == 0 {
                    models.push((
                        "fm".to_owned(),
                        model,
                        ProblemInfo::from(&problem),
                        settings,
                    ));
                }
            }
            ModelKind::ImMono => {
                let problem = options.reduced(problems::inverse_model(data))?;
                let settings = options.settings("im_mono", exp, &options.im_hidden);
                let model = timed_fit(
                    &problem,
                    &train,
                    test,
                    &settings,
                    format!("im-mono {tag}"),
                    progress,
                )?;
                evaluate(
                    &problem,
                    0..problem.heads.len(),
                    &model,
                    "im_mono",
                    &mut acc,
                )?;
                if f == 0 {
                    models.push((
                        "im-mono".to_owned(),
                        model,
                        ProblemInfo::from(&problem),
                        settings,
                    ));
                }
            }
            ModelKind::FmFactored => {
                let Some(graph) = &options.graph else {
                    return Err(TrainError::Options(
                        "fm-factored needs the causal graph found by `causal-arm explain` (--graph CLAIMS_JSON)".into(),
                    ));
                };
                let full = options.reduced(problems::forward_model(data, options.fm_target))?;
                let settings = options.settings("fm", exp, &options.factored_hidden);
                for head in &full.heads {
                    let candidates =
                        structure::head_candidates(&full, head, graph, options.factored_auxiliary)?;
                    let (fit_rows, select_rows) = match candidates.len() {
                        1 => (&train[..], &[][..]),
                        _ => selection_split(&train),
                    };
                    let mut best: Option<(f64, String, structure::HeadNet, Regressor)> = None;
                    let mut scores = Vec::new();
                    for net in candidates {
                        let policy = net.auxiliary.name();
                        let label = format!("fm-factored {} [{policy}] {tag}", head.name);
                        let model = timed_fit(
                            &net.problem,
                            fit_rows,
                            test,
                            &settings,
                            label.clone(),
                            progress,
                        )?;
                        let score = match select_rows {
                            [] => 0.0,
                            rows => held_out_mae(&net.problem, &model, rows)?[net.primary],
                        };
                        if !select_rows.is_empty() {
                            tracing::info!("{label}: validation MAE {score:.4e}");
                            scores.push((label.clone(), score));
                        }
                        if best.as_ref().is_none_or(|(b, ..)| score < *b) {
                            best = Some((score, label, net, model));
                        }
                    }
                    let Some((_, chosen, net, model)) = best else {
                        return Err(TrainError::Options(format!(
                            "head {} has no candidate network",
                            head.name
                        )));
                    };
                    for (label, validation_mae) in scores {
                        let chosen = label == chosen;
                        selections.push((
                            label,
                            Selection {
                                validation_mae,
                                chosen,
                            },
                        ));
                    }
                    evaluate(
                        &net.problem,
                        net.primary..net.primary + 1,
                        &model,
                        "fm",
                        &mut acc,
                    )?;
                    if f == 0 {
                        models.push((
                            format!("fm-factored-{}", head.name),
                            model,
                            ProblemInfo::from(&net.problem),
                            settings.clone(),
                        ));
                    }
                }
            }
            ModelKind::ImPre | ModelKind::Ablation => {
                let base_problem = problems::base_inverse_model(data);
                let base_settings = options.settings("base", exp, &options.im_hidden);
                let base = timed_fit(
                    &base_problem,
                    &train,
                    test,
                    &base_settings,
                    format!("base IM {tag}"),
                    progress,
                )?;
                let test_truth = take_rows(&base_problem.truth, 7, test);
                let baseline =
                    mean_baseline_mae(&base_problem.truth, &base_problem.heads, &train, test)[0];
                let pre_problem = problems::pre_network(data);
                let test_pre_inputs =
                    take_rows(&pre_problem.inputs, pre_problem.input_names.len(), test);
                if kind == ModelKind::ImPre {
                    let base_mae = head_mae(
                        &predict(
                            &base,
                            &take_rows(&base_problem.inputs, base_problem.input_names.len(), test),
                            None,
                            &[],
                        )?,
                        &test_truth,
                        &base_problem.heads,
                    )[0];
                    single(&mut acc, "im_pre/base", "rad", base_mae, baseline);
                    let pre_settings = options.settings("pre", exp, &options.im_hidden);
                    let pre = timed_fit(
                        &pre_problem,
                        &train,
                        test,
                        &pre_settings,
                        format!("pre-network {tag}"),
                        progress,
                    )?;
                    let theta_hat = predict(&pre, &test_pre_inputs, None, &[])?;
                    let theta_truth = take_rows(&pre_problem.truth, 7, test);
                    let pre_mae = head_mae(&theta_hat, &theta_truth, &pre_problem.heads)[0];
                    let pre_baseline =
                        mean_baseline_mae(&pre_problem.truth, &pre_problem.heads, &train, test)[0];
                    single(&mut acc, "im_pre/pre", "rad", pre_mae, pre_baseline);
                    let assembled = problems::base_inputs_from(exp, &test_pre_inputs, &theta_hat);
                    let assembly_mae = head_mae(
                        &predict(&base, &assembled, None, &[])?,
                        &test_truth,
                        &base_problem.heads,
                    )[0];
                    single(&mut acc, "im_pre/assembly", "rad", assembly_mae, baseline);
                    if f == 0 {
                        models.push((
                            "im-pre-base".to_owned(),
                            base,
                            ProblemInfo::from(&base_problem),
                            base_settings,
                        ));
                        models.push((
                            "im-pre-pre".to_owned(),
                            pre,
                            ProblemInfo::from(&pre_problem),
                            pre_settings,
                        ));
                    }
                } else {
                    let rows = test.len();
                    let zeros = vec![0f32; rows * 7];
                    let zero_inputs = problems::base_inputs_from(exp, &test_pre_inputs, &zeros);
                    let zero_mae = head_mae(
                        &predict(&base, &zero_inputs, None, &[])?,
                        &test_truth,
                        &base_problem.heads,
                    )[0];
                    single(&mut acc, "ablation/zero", "rad", zero_mae, baseline);
                    // θ_i(t+1) drawn per joint from the training rows.
                    let mut rng = <rand::rngs::StdRng as rand::SeedableRng>::seed_from_u64(
                        options.seed ^ 0xab1a,
                    );
                    let sampled: Vec<f32> = (0..rows * 7)
                        .map(|i| {
                            let r = train[rand::Rng::random_range(&mut rng, 0..train.len())];
                            pre_problem.truth[r * 7 + i % 7]
                        })
                        .collect();
                    let sampled_inputs =
                        problems::base_inputs_from(exp, &test_pre_inputs, &sampled);
                    let sampled_mae = head_mae(
                        &predict(&base, &sampled_inputs, None, &[])?,
                        &test_truth,
                        &base_problem.heads,
                    )[0];
                    single(&mut acc, "ablation/sampled", "rad", sampled_mae, baseline);
                }
            }
        }
    }
    for (label, selection) in selections {
        if let Some(run) = runs.iter_mut().find(|r| r.label == label) {
            run.selection = Some(selection);
        }
    }
    Ok(KindReport {
        kind,
        figures: summarise(exp, acc),
        runs,
        models,
    })
}
