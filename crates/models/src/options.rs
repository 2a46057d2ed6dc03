//! What `causal-arm train` and the trainer node decide: the model kinds, the epochs of each
//! network in a profile and every option of a cross-validation run.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use causal_arm_dataset::Experiment;
use causal_arm_mlp::{LrSchedule, Optimizer, TrainConfig};
use causal_arm_protocol::Profile;
use serde::{Deserialize, Serialize};

use crate::TrainError;
use crate::fit::FitSettings;
use crate::problems::{FmTarget, Problem};
use crate::structure;

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
        causal_arm_protocol::Choice::choice_name(self)
    }
}

causal_arm_protocol::choice!(ModelKind, "model", [
    ModelKind::Fm => "fm",
    ModelKind::ImMono => "im-mono",
    ModelKind::ImPre => "im-pre",
    ModelKind::Ablation => "ablation",
    ModelKind::FmFactored => "fm-factored",
]);

/// The models a run trains: every model of the data's experiment, or one kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelRequest {
    /// Every model the paper trains for the experiment ([`ModelKind::all_for`]).
    All,
    /// One kind.
    One(ModelKind),
}

causal_arm_protocol::choice!(ModelRequest, "model", [
    ModelRequest::One(ModelKind::Fm) => "fm",
    ModelRequest::One(ModelKind::ImMono) => "im-mono",
    ModelRequest::One(ModelKind::ImPre) => "im-pre",
    ModelRequest::One(ModelKind::Ablation) => "ablation",
    ModelRequest::One(ModelKind::FmFactored) => "fm-factored",
    ModelRequest::All => "all",
]);

impl ModelRequest {
    /// The kinds to train on data of `experiment`.
    pub fn kinds(self, experiment: Experiment) -> Vec<ModelKind> {
        match self {
            Self::All => ModelKind::all_for(experiment),
            Self::One(kind) => vec![kind],
        }
    }

    /// The one kind asked for, if not all.
    pub fn one(self) -> Option<ModelKind> {
        match self {
            Self::All => None,
            Self::One(kind) => Some(kind),
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
    /// The fit settings of one network (`part`: fm, im_mono, base or pre).
    pub(crate) fn settings(
        &self,
        part: &str,
        experiment: Experiment,
        hidden: &[usize],
    ) -> FitSettings {
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
    pub(crate) fn reduced(&self, problem: Problem) -> Result<Problem, TrainError> {
        match &self.graph {
            Some(graph) if !graph.unaffected().is_empty() => {
                structure::reduce(&problem, &graph.unaffected())
            }
            _ => Ok(problem),
        }
    }

    pub(crate) fn validate(&self) -> Result<(), TrainError> {
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
