//! The learning half of the paper: forward models (FM) and inverse models (IM) trained
//! from experiment datasets, judged by k-fold cross-validation next to the paper's figures
//! and the predict-the-mean baseline, saved as safetensors + JSON model files.
//!
//! A library without DDS: the `causal_arm_trainer` node (`nodes/trainer`) serves loaded
//! models as ROS 2 services through [`serve::ModelSet`], and `causal-arm train` drives
//! [`cross_validate`] from the CLI.

mod cv;
mod error;
pub mod fit;
pub mod job;
pub mod mental;
pub mod model_file;
pub mod node_job;
mod options;
pub mod problems;
mod report;
pub mod serve;
pub mod structure;

pub use causal_arm_mlp::LrSchedule;
pub use causal_arm_protocol::Profile;
pub use cv::cross_validate;
pub use error::TrainError;
pub use model_file::{LoadedModel, ModelMeta, load_model, save_model};
pub use options::{ModelKind, ModelRequest, TrainOptions};
pub use report::{
    CurvePoint, Figure, FoldFigure, FullFmComparison, KindReport, ProblemInfo, RunRecord,
    Selection, paper_figure,
};
