//! The simulator's causal ground truth, made: re-simulate a bag from its own commands
//! (checked bit for bit against the recorded joints), then intervene on each action in the
//! states it visited ([`intervene`]). The result is a [`causal_arm_truth::Truth`]; reading,
//! writing and scoring it need no physics and live in `causal_arm_truth`.

#![warn(missing_docs)]

mod engine;
mod trace;

use std::path::PathBuf;

pub use engine::intervene;
pub use trace::{Trace, TraceStep};

/// Why a ground truth could not be made.
#[derive(Debug, thiserror::Error)]
pub enum InterveneError {
    /// An option is out of range.
    #[error("{0}")]
    Options(String),
    /// The bag cannot be re-simulated (wrong experiment, missing settings, bad messages).
    #[error("{bag}: {problem}")]
    Bag {
        /// Bag directory.
        bag: PathBuf,
        /// What is wrong.
        problem: String,
    },
    /// The bag could not be read.
    #[error(transparent)]
    Read(#[from] causal_arm_bag::BagError),
    /// The simulator refused its settings or a command.
    #[error(transparent)]
    Sim(#[from] causal_arm_sim::SimError),
    /// The plan or the truth made is refused.
    #[error(transparent)]
    Truth(#[from] causal_arm_truth::TruthError),
}
