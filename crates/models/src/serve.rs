//! What the trainer node's services answer, without DDS: every request gets a reply,
//! malformed ones a `success = false` reply saying what is wrong.

use std::collections::BTreeMap;
use std::path::Path;

use causal_arm_dataset::{Experiment, action_names, state_names};
use causal_arm_msgs::srv::{
    GetModelInfo_Request, GetModelInfo_Response, PredictAction_Request, PredictAction_Response,
    PredictNextState_Request, PredictNextState_Response, Rollout_Request, Rollout_Response,
};

use crate::{LoadedModel, TrainError, load_model};

/// Largest batch a request may carry (rows × features stays far below the DDS sample
/// limits and a reply comes back in milliseconds).
pub const MAX_ROWS: usize = 100_000;
/// Longest mental simulation a rollout request may ask for.
pub const MAX_STEPS: usize = 10_000;

/// The models a trainer node serves.
pub struct ModelSet {
    models: BTreeMap<String, LoadedModel>,
    forward: String,
    inverse: String,
    experiment: Experiment,
    metrics: serde_json::Value,
}

/// Checks a flat batch of a service request: length and finiteness, naming the field,
/// row and column (shared with the explainer's service).
pub fn check_batch(field: &str, values: &[f64], rows: usize, width: usize) -> Result<(), String> {
    if values.len() != rows * width {
        return Err(format!(
            "{field} has {} values, expected rows × {width} = {}",
            values.len(),
            rows * width
        ));
    }
    // The models compute in float32: a finite f64 beyond its range would become inf.
    if let Some(i) = values.iter().position(|v| !(*v as f32).is_finite()) {
        let beyond = if values[i].is_finite() {
            ", beyond the float32 range (±3.4e38) the models compute in"
        } else {
            ""
        };
        return Err(format!(
            "{field}[{i}] (row {}, column {}) is {:?}{beyond}",
            i / width,
            i % width,
            values[i]
        ));
    }
    Ok(())
}

/// Runs `model` and refuses a non-finite answer (inputs far outside the training data can
/// overflow a head) instead of replying `success` with NaN or inf.
fn predict_finite(model: &LoadedModel, inputs: &[f32]) -> Result<Vec<f64>, String> {
    let out = model.predict(inputs).map_err(|e| e.to_string())?;
    let width = model.meta.architecture.outputs().max(1);
    if let Some(i) = out.iter().position(|v| !v.is_finite()) {
        return Err(format!(
            "the model's output is {} at row {}, column {}: the inputs are too far outside the data it was trained on",
            out[i],
            i / width,
            i % width
        ));
    }
    Ok(out.into_iter().map(f64::from).collect())
}

fn check_rows(rows: u32, limit: usize, what: &str) -> Result<usize, String> {
    let rows = rows as usize;
    if rows == 0 {
        return Err(format!("{what} must be at least 1"));
    }
    if rows > limit {
        return Err(format!(
            "{what} = {rows} exceeds the limit of {limit}; split the batch"
        ));
    }
    Ok(rows)
}

fn to_f32(values: &[f64]) -> Vec<f32> {
    values.iter().map(|&v| v as f32).collect()
}

impl ModelSet {
    /// Loads every model in `dir` (each `<name>.json` + `<name>.safetensors`) and picks the
    /// forward and inverse models the prediction services use. A missing inverse model is
    /// refused when `inverse_required` (the user named it), else only warned about
    /// (a directory may hold forward models only).
    pub fn load(
        dir: &Path,
        forward: &str,
        inverse: &str,
        inverse_required: bool,
    ) -> Result<Self, TrainError> {
        let file_err = |problem: String| TrainError::File {
            path: dir.to_owned(),
            problem,
        };
        let entries = std::fs::read_dir(dir)
            .map_err(|e| file_err(format!("cannot list the model directory: {e}")))?;
        let mut models = BTreeMap::new();
        for entry in entries.flatten() {
            let path = entry.path();
            if path.extension().is_some_and(|x| x == "json")
                && let Some(stem) = path.file_stem().and_then(|s| s.to_str())
                && stem != "metrics"
                && path.with_extension("safetensors").exists()
            {
                models.insert(stem.to_owned(), load_model(dir, stem)?);
            }
        }
        let found = models.keys().cloned().collect::<Vec<_>>().join(", ");
        if !models.contains_key(forward) {
            return Err(file_err(format!(
                "no forward model {forward:?} (found: {found})"
            )));
        }
        if !models.contains_key(inverse) {
            if inverse_required {
                return Err(file_err(format!(
                    "no inverse model {inverse:?} (found: {found}); name one of those as inverse_model, or leave it at its default"
                )));
            }
            tracing::warn!(
                "no inverse model {inverse:?} in {} (found: {found}); predict_action will refuse requests",
                dir.display()
            );
        }
        let experiment = models[forward].experiment()?;
        for (name, model) in &models {
            if model.experiment()? != experiment {
                return Err(file_err(format!(
                    "model {name} is for {}, the forward model for {experiment}",
                    model.meta.experiment
                )));
            }
        }
        let metrics = std::fs::read_to_string(dir.join("metrics.json"))
            .ok()
            .and_then(|t| serde_json::from_str(&t).ok())
            .unwrap_or(serde_json::Value::Null);
        Ok(Self {
            models,
            forward: forward.to_owned(),
            inverse: inverse.to_owned(),
            experiment,
            metrics,
        })
    }

    /// The experiment whose feature order the services use.
    pub fn experiment(&self) -> Experiment {
        self.experiment
    }

    fn forward(&self) -> &LoadedModel {
        &self.models[&self.forward]
    }

    fn inverse(&self) -> Result<&LoadedModel, String> {
        self.models
            .get(&self.inverse)
            .ok_or_else(|| format!("no inverse model {:?} is loaded (train one with `causal-arm train --model im-mono`)", self.inverse))
    }

    fn next_states(&self, state: &[f64], action: &[f64], rows: usize) -> Result<Vec<f64>, String> {
        let (sw, aw) = (
            state_names(self.experiment).len(),
            action_names(self.experiment).len(),
        );
        let mut inputs = Vec::with_capacity(rows * (sw + aw));
        for r in 0..rows {
            inputs.extend(to_f32(&state[r * sw..(r + 1) * sw]));
            inputs.extend(to_f32(&action[r * aw..(r + 1) * aw]));
        }
        predict_finite(self.forward(), &inputs)
    }

    /// `/trainer/predict_next_state`: FM on a batch.
    pub fn predict_next_state(&self, req: &PredictNextState_Request) -> PredictNextState_Response {
        let (sw, aw) = (
            state_names(self.experiment).len(),
            action_names(self.experiment).len(),
        );
        let result = check_rows(req.rows, MAX_ROWS, "rows").and_then(|rows| {
            check_batch("state", &req.state, rows, sw)?;
            check_batch("action", &req.action, rows, aw)?;
            self.next_states(&req.state, &req.action, rows)
                .map(|v| (v, rows))
        });
        match result {
            Ok((next_state, rows)) => PredictNextState_Response {
                success: true,
                message: String::new(),
                next_state,
                state_names: state_names(self.experiment),
                rows: rows as u32,
            },
            Err(message) => PredictNextState_Response {
                success: false,
                message,
                ..Default::default()
            },
        }
    }

    /// Width of the next-state features the inverse model takes.
    pub fn inverse_next_width(&self) -> Result<usize, String> {
        Ok(self.inverse()?.meta.architecture.inputs - state_names(self.experiment).len())
    }

    /// The next-state features the inverse model `name` takes after the state, in
    /// order (its input names past the state's, without their `_next` suffix), so a
    /// client of `/trainer/predict_action` knows what to send.
    fn next_state_names(&self, model: &LoadedModel) -> Vec<String> {
        let sw = state_names(self.experiment).len();
        (model.meta.problem.input_names.iter().skip(sw))
            .map(|n| n.strip_suffix("_next").unwrap_or(n).to_owned())
            .collect()
    }

    /// `/trainer/predict_action`: IM on a batch.
    pub fn predict_action(&self, req: &PredictAction_Request) -> PredictAction_Response {
        let sw = state_names(self.experiment).len();
        let result = check_rows(req.rows, MAX_ROWS, "rows").and_then(|rows| {
            let inverse = self.inverse()?;
            let nw = self.inverse_next_width()?;
            check_batch("state", &req.state, rows, sw)?;
            check_batch("next_state", &req.next_state, rows, nw)?;
            let mut inputs = Vec::with_capacity(rows * (sw + nw));
            for r in 0..rows {
                inputs.extend(to_f32(&req.state[r * sw..(r + 1) * sw]));
                inputs.extend(to_f32(&req.next_state[r * nw..(r + 1) * nw]));
            }
            Ok((
                predict_finite(inverse, &inputs)?,
                rows,
                inverse.meta.problem.output_names.clone(),
            ))
        });
        match result {
            Ok((action, rows, action_names)) => PredictAction_Response {
                success: true,
                message: String::new(),
                action,
                action_names,
                rows: rows as u32,
            },
            Err(message) => PredictAction_Response {
                success: false,
                message,
                ..Default::default()
            },
        }
    }

    /// `/trainer/rollout`: the FM chained over an action sequence (mental simulation).
    pub fn rollout(&self, req: &Rollout_Request) -> Rollout_Response {
        let (sw, aw) = (
            state_names(self.experiment).len(),
            action_names(self.experiment).len(),
        );
        let result = check_rows(req.steps, MAX_STEPS, "steps").and_then(|steps| {
            check_batch("initial_state", &req.initial_state, 1, sw)?;
            check_batch("actions", &req.actions, steps, aw)?;
            let mut state = req.initial_state.clone();
            let mut states = Vec::with_capacity(steps * sw);
            for k in 0..steps {
                state = self.next_states(&state, &req.actions[k * aw..(k + 1) * aw], 1)?;
                states.extend_from_slice(&state);
            }
            Ok((states, steps))
        });
        match result {
            Ok((states, steps)) => Rollout_Response {
                success: true,
                message: String::new(),
                states,
                state_names: state_names(self.experiment),
                steps: steps as u32,
            },
            Err(message) => Rollout_Response {
                success: false,
                message,
                ..Default::default()
            },
        }
    }

    /// `/trainer/model_info`: names and metrics of one model, or of all.
    pub fn model_info(&self, req: &GetModelInfo_Request) -> GetModelInfo_Response {
        let models: Vec<String> = self.models.keys().cloned().collect();
        let metrics_of = |kind: &str| {
            self.metrics
                .get("models")
                .and_then(|m| m.get(kind))
                .cloned()
        };
        let (metrics, action, next) = if req.model.is_empty() {
            (
                self.metrics
                    .get("models")
                    .cloned()
                    .unwrap_or(serde_json::Value::Null),
                action_names(self.experiment),
                self.inverse()
                    .map(|im| self.next_state_names(im))
                    .unwrap_or_default(),
            )
        } else if let Some(model) = self.models.get(&req.model) {
            // Model files are named after their kind or `<kind>-<part>`.
            let kind = ["im-mono", "im-pre", "fm"]
                .into_iter()
                .find(|k| req.model.starts_with(k))
                .unwrap_or(&req.model);
            let (action, next) = if req.model == self.inverse {
                let next = self.next_state_names(model);
                (model.meta.problem.output_names.clone(), next)
            } else {
                (action_names(self.experiment), Vec::new())
            };
            (
                metrics_of(kind).unwrap_or(serde_json::Value::Null),
                action,
                next,
            )
        } else {
            return GetModelInfo_Response {
                success: false,
                message: format!(
                    "unknown model {:?}; loaded: {}",
                    req.model,
                    models.join(", ")
                ),
                models,
                ..Default::default()
            };
        };
        GetModelInfo_Response {
            success: true,
            message: String::new(),
            models,
            state_names: state_names(self.experiment),
            action_names: action,
            next_state_names: next,
            metrics_json: metrics.to_string(),
        }
    }
}
