//! Causal ground truth from the simulator itself: its format, files and the scores of
//! claims against it. The interventions that make it run in `causal_arm_intervene`; this
//! crate builds no physics, so the learning libraries score against a truth without it.
//!
//! Every causal claim of the project (an action a_j drives the next-state feature s_k) is
//! scored against what the simulator does under intervention: take a state the bag visited
//! (re-simulated from the bag's own commands, checked bit for bit against the recorded
//! joints), step once with the recorded command, then step from a snapshot of the same
//! state with do(command_j := command_j + δ) for several δ of both signs spanning the
//! babbling distribution, and with every other magnet command. A feature an intervention
//! moves by more than the tolerance is an active edge in that state. An identical replay is
//! run too: its difference is the noise floor, and it must be 0.
//!
//! The result ([`Truth`]) holds, per context (cube held or not, magnet on or off, cube on
//! the table or elsewhere) and per horizon (s(t+k), the rest of the trajectory keeping the
//! recorded commands), the fraction of states in which each edge is active and its mean and
//! largest effect.

#![warn(missing_docs)]

mod output;
mod score;

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

pub use causal_arm_dataset::Context;
pub use output::{load, write_all};
pub use score::{
    ScoreRow, check_horizon, check_names, score_claims, score_horizons, score_table, truth_horizons,
};

/// Why a ground truth could not be made or read.
#[derive(Debug, thiserror::Error)]
pub enum TruthError {
    /// An option is out of range.
    #[error("{0}")]
    Options(String),
    /// A truth file is malformed or does not fit what it is compared with.
    #[error("{path}: {problem}")]
    File {
        /// File or directory.
        path: PathBuf,
        /// What is wrong.
        problem: String,
    },
    /// A figure could not be drawn.
    #[error(transparent)]
    Plot(#[from] causal_arm_plots::PlotError),
}

/// How the interventions are run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    /// States of the bag intervened on, drawn uniformly (seeded) from its transitions.
    pub states: usize,
    /// Seed of the state draw.
    pub seed: u64,
    /// Largest horizon k of s(t+k) compared (1 = the next state, what a forward model predicts).
    pub horizon: usize,
    /// Joint interventions δ = ± scale × (std of that joint's commanded delta over the bag).
    pub delta_scales: Vec<f64>,
    /// An effect counts when |Δ s_k| exceeds this, in the feature's unit (m, rad, 1).
    pub tolerance: f64,
    /// An effect counts only when |Δ s_k| also exceeds this multiple of the std of the
    /// feature's own one-step change over the intervened states (0: any effect above
    /// `tolerance`). A force-limited arm is one coupled body, where every joint moves
    /// every other by a little; this asks which effects matter on the feature's own scale.
    #[serde(default)]
    pub effect_size: f64,
    /// Edges active in fewer than this fraction of a context's states (but in some) are
    /// "rare": neither present nor absent when claims are scored.
    pub min_fraction: f64,
    /// Worker threads (`None`: all cores).
    pub threads: Option<usize>,
}

impl Default for Plan {
    fn default() -> Self {
        Self {
            states: 1000,
            seed: 0,
            horizon: 1,
            delta_scales: vec![0.1, 0.5, 1.0, 2.0],
            tolerance: 1e-6,
            effect_size: 0.0,
            min_fraction: 0.01,
            threads: None,
        }
    }
}

impl Plan {
    /// Refuses plans that cannot produce a truth.
    pub fn check(&self) -> Result<(), TruthError> {
        let bad = |m: String| Err(TruthError::Options(m));
        if self.states == 0 {
            return bad("--states must be at least 1 state to intervene on, got 0".into());
        }
        if self.horizon == 0 {
            return bad("--horizon must be at least 1 step, got 0".into());
        }
        if self.delta_scales.is_empty()
            || self
                .delta_scales
                .iter()
                .any(|s| !(s.is_finite() && *s > 0.0))
        {
            return bad(format!(
                "intervention scales must be positive numbers, got {:?}",
                self.delta_scales
            ));
        }
        if !(self.tolerance.is_finite() && self.tolerance >= 0.0) {
            return bad(format!(
                "--tolerance must be a non-negative number, got {}",
                self.tolerance
            ));
        }
        if !(self.effect_size.is_finite() && self.effect_size >= 0.0) {
            return bad(format!(
                "--effect-size must be a non-negative number, got {}",
                self.effect_size
            ));
        }
        if !(0.0..=1.0).contains(&self.min_fraction) {
            return bad(format!(
                "--min-fraction must lie in [0, 1], got {}",
                self.min_fraction
            ));
        }
        if self.threads == Some(0) {
            return bad("--threads must be at least 1".into());
        }
        Ok(())
    }
}

/// The truth about one edge in one context.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Edge {
    /// Active in at least `min_fraction` of the context's states.
    Present,
    /// Active in none of them.
    Absent,
    /// Active in some, but fewer than `min_fraction`: not scored either way.
    Rare,
}

/// Edge statistics of one context at one horizon, `[action][state]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EdgeMatrix {
    /// Context name (`all`, `holding`, …; see [`Context`]).
    pub context: String,
    /// k of s(t+k).
    pub horizon: usize,
    /// States of the context.
    pub states: usize,
    /// Fraction of those states in which some intervention on the action moved the feature.
    pub active_fraction: Vec<Vec<f64>>,
    /// Mean over the active states of the largest |Δ| an intervention caused (0 if none).
    pub mean_effect: Vec<Vec<f64>>,
    /// Largest |Δ| over all states, also below the tolerance (shows how far from it an
    /// absent edge is).
    pub max_effect: Vec<Vec<f64>>,
}

impl EdgeMatrix {
    /// The verdict on edge (`action`, `state`) with the truth's `min_fraction`.
    pub fn edge(&self, action: usize, state: usize, min_fraction: f64) -> Edge {
        let f = self.active_fraction[action][state];
        if f <= 0.0 {
            Edge::Absent
        } else if f >= min_fraction {
            Edge::Present
        } else {
            Edge::Rare
        }
    }
}

/// What the simulator says each action changes (`truth.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Truth {
    /// File format tag.
    pub format: String,
    /// `exp1` or `exp2`.
    pub experiment: String,
    /// Bag the states came from.
    pub bag: String,
    /// Action names (rows).
    pub action_names: Vec<String>,
    /// State feature names (columns).
    pub state_names: Vec<String>,
    /// How the interventions were run.
    pub plan: Plan,
    /// The joint interventions δ used per joint, rad (both signs of each).
    pub joint_deltas: Vec<Vec<f64>>,
    /// Steps re-simulated and checked against the bag's recorded joints (all bit-identical,
    /// or the run stops with an error).
    pub resimulated_steps: usize,
    /// Largest |Δ| between two identical replays of the recorded command over every state,
    /// feature and horizon: the noise floor (0 for a deterministic simulator).
    pub noise_floor: f64,
    /// Std of each state feature's one-step change s_k(t+1) − s_k(t) over the intervened
    /// states (Euler angles wrapped), in the feature's unit: the scale of `plan.effect_size`.
    #[serde(default)]
    pub feature_step_std: Vec<f64>,
    /// Wall time of the run, s.
    pub seconds: f64,
    /// One matrix per (context, horizon); `all` at horizon 1 first.
    pub matrices: Vec<EdgeMatrix>,
}

/// Format tag of [`Truth`] files.
pub const FORMAT: &str = "causal-arm truth v1";

impl Truth {
    /// The matrix of `context` at `horizon`.
    pub fn matrix(&self, context: &str, horizon: usize) -> Option<&EdgeMatrix> {
        self.matrices
            .iter()
            .find(|m| m.context == context && m.horizon == horizon)
    }

    /// The matrix over all states at horizon 1: the one-step causal graph.
    pub fn one_step(&self) -> &EdgeMatrix {
        self.matrix(Context::ALL, 1)
            .expect("every truth holds the all-states matrix at horizon 1")
    }

    /// Index of an action by name.
    pub fn action_index(&self, name: &str) -> Option<usize> {
        self.action_names.iter().position(|n| n == name)
    }

    /// Index of a state feature by name.
    pub fn state_index(&self, name: &str) -> Option<usize> {
        self.state_names.iter().position(|n| n == name)
    }
}
