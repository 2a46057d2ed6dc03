//! Causal discovery straight from babbling transitions: which action a_j changes which
//! state feature s_k, decided by tests on the recorded data rather than through a learned
//! model.
//!
//! Motor babbling draws each action at random given the state, so whether a_j explains the
//! one-step change Δs_k = s_k(t+1) − s_k(t) beyond everything else in (s(t), a(t)) is
//! evidence of a causal edge, as in a randomized experiment. The tests here are
//! - the standard anchors: linear Granger tests of a_j on Δs_k, with and without
//!   action × state terms (an F test per pair, Bonferroni over all pairs);
//! - the data half of the product's verdicts ([`DataTest`]): the action × state design with
//!   squared actions and a heteroscedasticity-robust Wald test, which also says "does not"
//!   where the change is predicted to the recording's own resolution without a_j, and
//!   "undecided" otherwise; the features that stand still in much of the data (the cube,
//!   the magnet) are also tested within each context of the state ([`ContextTest`]).
//!
//! Pure functions of a [`Dataset`]; no I/O.

#![warn(missing_docs)]

mod changes;
mod contexts;
mod design;
mod fit;
mod granger;

pub use changes::{CLUSTER_SPAN, Changes};
pub use contexts::{ContextTest, INTERMITTENT_SHARE};
pub use design::Terms;
pub use fit::PairTest;
pub use granger::{DataTest, GrangerSettings, granger_claims};

/// Why a test could not run.
#[derive(Debug, thiserror::Error)]
pub enum DiscoveryError {
    /// A setting is out of range or the data too small for it.
    #[error("{0}")]
    Options(String),
}

/// Result of this crate's functions.
pub type Result<T> = std::result::Result<T, DiscoveryError>;
