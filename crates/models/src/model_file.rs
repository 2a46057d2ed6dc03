//! Model files: `<name>.safetensors` (weights and standardisation) beside `<name>.json`
//! (architecture, feature names, heads, training settings, provenance), so a model can be
//! served, explained or loaded into numpy without this code.

use std::path::{Path, PathBuf};

use causal_arm_dataset::{BagSource, Experiment};
use causal_arm_mlp::{MlpSpec, Regressor};
use serde::{Deserialize, Serialize};

use crate::fit::{FitSettings, predict};
use crate::{ProblemInfo, TrainError};

/// The JSON half of a model file.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ModelMeta {
    /// File stem (`fm`, `im-mono`, `im-pre-base`, `im-pre-pre`).
    pub name: String,
    /// Experiment whose data model the features follow.
    pub experiment: String,
    /// Network architecture.
    pub architecture: MlpSpec,
    /// Features, heads and output offset.
    pub problem: ProblemInfo,
    /// Input standardisation (also in the safetensors file).
    pub input_mean: Vec<f32>,
    /// Input standard deviations.
    pub input_std: Vec<f32>,
    /// Output standardisation.
    pub output_mean: Vec<f32>,
    /// Output standard deviations.
    pub output_std: Vec<f32>,
    /// Optimizer, learning rate, batch size, epochs, hidden sizes.
    pub training: FitSettings,
    /// Which rows it was trained on.
    pub trained_on: String,
    /// Bags of the dataset, with content hashes.
    pub sources: Vec<BagSource>,
}

/// A model loaded for serving.
#[derive(Debug, Clone)]
pub struct LoadedModel {
    /// Description.
    pub meta: ModelMeta,
    /// Network with standardisation.
    pub regressor: Regressor,
}

impl LoadedModel {
    /// Raw-unit predictions for row-major raw inputs (offsets added back).
    pub fn predict(&self, inputs: &[f32]) -> Result<Vec<f32>, TrainError> {
        predict(
            &self.regressor,
            inputs,
            self.meta.problem.offset_columns.as_deref(),
            &self.meta.problem.heads,
        )
    }

    /// The experiment this model was trained for.
    pub fn experiment(&self) -> Result<Experiment, TrainError> {
        self.meta.experiment.parse().map_err(TrainError::Options)
    }
}

fn file_err(path: &Path, problem: impl std::fmt::Display) -> TrainError {
    TrainError::File {
        path: path.to_owned(),
        problem: problem.to_string(),
    }
}

/// Writes `dir/<name>.safetensors` and `dir/<name>.json`; returns both paths. Both are
/// written beside their place and renamed in only once complete, so a failed write (a
/// full disk) never destroys the model already there.
pub fn save_model(
    dir: &Path,
    model: &Regressor,
    meta: &ModelMeta,
) -> Result<(PathBuf, PathBuf), TrainError> {
    std::fs::create_dir_all(dir).map_err(|e| file_err(dir, e))?;
    let weights = dir.join(format!("{}.safetensors", meta.name));
    let json = dir.join(format!("{}.json", meta.name));
    let weights_tmp = dir.join(format!(".{}.safetensors.partial", meta.name));
    let json_tmp = dir.join(format!(".{}.json.partial", meta.name));
    let written = (|| {
        model
            .save(&weights_tmp)
            .map_err(|e| file_err(&weights, e))?;
        let text = serde_json::to_string_pretty(meta).map_err(|e| file_err(&json, e))?;
        std::fs::write(&json_tmp, text + "\n").map_err(|e| file_err(&json, e))?;
        std::fs::rename(&weights_tmp, &weights).map_err(|e| file_err(&weights, e))?;
        std::fs::rename(&json_tmp, &json).map_err(|e| file_err(&json, e))
    })();
    if written.is_err() {
        let _ = std::fs::remove_file(&weights_tmp);
        let _ = std::fs::remove_file(&json_tmp);
    }
    written.map(|()| (weights, json))
}

/// Reads a model written by [`save_model`], checking the two halves agree.
pub fn load_model(dir: &Path, name: &str) -> Result<LoadedModel, TrainError> {
    let json = dir.join(format!("{name}.json"));
    let text = std::fs::read_to_string(&json)
        .map_err(|e| file_err(&json, format!("cannot read model description: {e}")))?;
    let meta: ModelMeta = serde_json::from_str(&text)
        .map_err(|e| file_err(&json, format!("not a model description: {e}")))?;
    let weights = dir.join(format!("{name}.safetensors"));
    let regressor =
        Regressor::load(meta.architecture.clone(), &weights).map_err(|e| file_err(&weights, e))?;
    if meta.problem.input_names.len() != meta.architecture.inputs
        || meta.problem.output_names.len() != meta.architecture.outputs()
    {
        return Err(file_err(
            &json,
            "feature names do not match the architecture",
        ));
    }
    Ok(LoadedModel { meta, regressor })
}

/// Builds the description of a freshly trained model.
pub fn describe(
    name: &str,
    experiment: Experiment,
    model: &Regressor,
    problem: &ProblemInfo,
    training: &FitSettings,
    trained_on: String,
    sources: &[BagSource],
) -> ModelMeta {
    ModelMeta {
        name: name.to_owned(),
        experiment: experiment.to_string(),
        architecture: model.mlp.spec().clone(),
        problem: problem.clone(),
        input_mean: model.input.mean.clone(),
        input_std: model.input.std.clone(),
        output_mean: model.output.mean.clone(),
        output_std: model.output.std.clone(),
        training: training.clone(),
        trained_on,
        sources: sources.to_vec(),
    }
}
