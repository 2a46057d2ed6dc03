//! What a fit is asked to do: the optimizer, the learning-rate schedule and the batch.

use serde::{Deserialize, Serialize};

/// The paper's optimizers (PyTorch semantics: AdamW decays weights decoupled from the
/// gradient, Adam has no decay).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum Optimizer {
    /// Adam, β = (0.9, 0.999), ε = 1e-8.
    Adam,
    /// AdamW with the given decoupled weight decay (the paper uses 0.004).
    AdamW {
        /// Decay factor per unit learning rate.
        weight_decay: f64,
    },
}

/// How the step size moves over a fit. The paper keeps it constant; decaying it lets the
/// last epochs settle into the minimum instead of rattling around it at full step size,
/// which is where most of the late-epoch gains of a constant rate come from anyway.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum LrSchedule {
    /// The learning rate throughout (the paper's).
    #[default]
    Constant,
    /// Half a cosine from the learning rate down to `floor` × it over the planned batches
    /// (see [`Fitter::plan_batches`]); constant if no plan was given.
    Cosine {
        /// Final fraction of the learning rate.
        floor: f64,
    },
}

impl LrSchedule {
    /// Factor on the learning rate after `done` of `total` batches.
    pub fn factor(self, done: u64, total: Option<u64>) -> f64 {
        match (self, total) {
            (Self::Cosine { floor }, Some(total)) if total > 0 => {
                let progress = (done as f64 / total as f64).min(1.0);
                floor + (1.0 - floor) * 0.5 * (1.0 + (std::f64::consts::PI * progress).cos())
            }
            _ => 1.0,
        }
    }
}

impl std::str::FromStr for LrSchedule {
    type Err = String;

    /// `constant`, `cosine` (down to 1 % of the rate) or `cosine:FLOOR`.
    fn from_str(s: &str) -> std::result::Result<Self, Self::Err> {
        let bad = || {
            format!(
                "unknown learning-rate schedule {s:?}: expected constant, cosine or cosine:FLOOR with 0 <= FLOOR <= 1"
            )
        };
        match s.split_once(':') {
            None if s == "constant" => Ok(Self::Constant),
            None if s == "cosine" => Ok(Self::Cosine { floor: 0.01 }),
            Some(("cosine", floor)) => match floor.parse::<f64>() {
                Ok(floor) if (0.0..=1.0).contains(&floor) => Ok(Self::Cosine { floor }),
                _ => Err(bad()),
            },
            _ => Err(bad()),
        }
    }
}

impl std::fmt::Display for LrSchedule {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Constant => write!(f, "constant"),
            Self::Cosine { floor } => write!(f, "cosine:{floor}"),
        }
    }
}

/// How to fit; stored in model files so a result can be reproduced.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrainConfig {
    /// Optimizer and its decay.
    pub optimizer: Optimizer,
    /// Step size (the paper: 1e-3).
    pub learning_rate: f64,
    /// Rows per mini-batch.
    pub batch_size: usize,
    /// Seed of the per-epoch shuffles.
    pub seed: u64,
    /// Learning-rate schedule (model files written before it existed were constant).
    #[serde(default)]
    pub schedule: LrSchedule,
}

impl Default for TrainConfig {
    fn default() -> Self {
        Self {
            optimizer: Optimizer::Adam,
            learning_rate: 1e-3,
            batch_size: 256,
            seed: 0,
            schedule: LrSchedule::Constant,
        }
    }
}

pub(super) const BETA1: f64 = 0.9;
pub(super) const BETA2: f64 = 0.999;
pub(super) const EPSILON: f64 = 1e-8;
