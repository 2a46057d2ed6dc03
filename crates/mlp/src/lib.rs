//! Multi-head tanh MLPs in candle: the forward and inverse models of the paper, and the
//! networks the explainer attributes.
//!
//! A network is tanh hidden layers followed by one linear layer whose outputs are split
//! into named heads (θ, ef, object position, …). Heads sharing one output matrix is the
//! same function as one linear head per sub-vector; the loss is the equally weighted sum
//! of per-head mean squared errors, as the paper trains its forward model.
//!
//! Training uses a hand-written backward pass (an MLP's gradient is three matrix products
//! per layer) instead of candle's autograd graph: no graph is built per batch, and the
//! element-wise work can be fused. Inputs and targets are standardised by a
//! [`Regressor`], which stores the statistics with the weights so a saved model predicts
//! in raw units.

mod kernels;
mod network;
mod standardize;
mod train;

pub use kernels::flush_denormals;
pub use network::{Head, Layer, Mlp, MlpSpec};
pub use standardize::{Regressor, Standardizer};
pub use train::{Fitter, LrSchedule, Optimizer, TrainConfig};

/// Why a network could not be built, trained, loaded or evaluated.
#[derive(Debug, thiserror::Error)]
pub enum MlpError {
    /// A tensor operation failed (usually a shape mismatch).
    #[error(transparent)]
    Candle(#[from] candle_core::Error),
    /// The architecture or the data disagree with what was asked.
    #[error("{0}")]
    Shape(String),
    /// A stored model is missing a tensor or has one of the wrong shape.
    #[error("model file: {0}")]
    Format(String),
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, MlpError>;
