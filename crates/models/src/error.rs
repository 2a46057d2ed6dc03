//! Why training or evaluation failed, one type for every step from options to model files.

use causal_arm_mlp::MlpError;

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
