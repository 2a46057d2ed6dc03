//! The models of a `causal-arm train` directory, as `reach --in-process` hands them to
//! the controllers (either experiment's): the same `ModelSet` the trainer node serves, asked directly.

use std::path::Path;

use anyhow::{Context as _, bail};
use causal_arm_control::{ForwardModel, InverseModel, next_state_indices};
use causal_arm_models::serve::ModelSet;
use causal_arm_msgs::srv::{GetModelInfo_Request, PredictAction_Request, PredictNextState_Request};
use causal_arm_protocol::Experiment;

/// The inverse model of a model directory. The IM may take only some next-state
/// features (the paper's exp 1 IM takes ef(t+1) alone): `next` lists, in its input
/// order, which state features those are.
pub struct TrainedIm {
    models: ModelSet,
    next: Vec<usize>,
}

impl TrainedIm {
    /// The IM `name` of `dir` for `experiment`, its next-state inputs as the trainer
    /// node describes them.
    pub fn load(dir: &Path, name: &str, experiment: Experiment) -> anyhow::Result<Self> {
        // Reaching needs no forward model: the IM stands in for it in the set.
        let models = load_for(dir, name, experiment)?;
        let info = models.model_info(&GetModelInfo_Request {
            model: name.to_owned(),
        });
        let file = dir.join(format!("{name}.json"));
        if !info.action_names.iter().any(|a| a == "a0") {
            bail!(
                "{} is not an {experiment} inverse model (it predicts {:?}, not the actions)",
                file.display(),
                info.action_names
            );
        }
        let next = next_state_indices(&info.state_names, &info.next_state_names)
            .with_context(|| format!("{} as an inverse model", file.display()))?;
        Ok(Self { models, next })
    }
}

impl InverseModel for TrainedIm {
    fn action(&self, state: &[f64], next_state: &[f64]) -> Result<Vec<f64>, String> {
        let reply = self.models.predict_action(&PredictAction_Request {
            state: state.to_vec(),
            next_state: self.next.iter().map(|&i| next_state[i]).collect(),
            rows: 1,
        });
        match reply.success {
            true => Ok(reply.action),
            false => Err(reply.message),
        }
    }
}

/// The forward model of a model directory.
pub struct TrainedFm {
    models: ModelSet,
}

impl TrainedFm {
    /// The FM `name` of `dir` for `experiment`.
    pub fn load(dir: &Path, name: &str, experiment: Experiment) -> anyhow::Result<Self> {
        // Described as the set's inverse model, a model names its own outputs: an IM
        // predicts the actions, an FM the state.
        let models = load_for(dir, name, experiment)?;
        let info = models.model_info(&GetModelInfo_Request {
            model: name.to_owned(),
        });
        if info.action_names.iter().any(|a| a == "a0") {
            bail!(
                "{} is an inverse model, not a forward model",
                dir.join(format!("{name}.json")).display()
            );
        }
        Ok(Self { models })
    }
}

impl ForwardModel for TrainedFm {
    fn next_states(
        &self,
        states: &[f64],
        actions: &[f64],
        rows: usize,
    ) -> Result<Vec<f64>, String> {
        let reply = self.models.predict_next_state(&PredictNextState_Request {
            state: states.to_vec(),
            action: actions.to_vec(),
            rows: rows as u32,
        });
        match reply.success {
            true => Ok(reply.next_state),
            false => Err(reply.message),
        }
    }
}

/// The models of `dir` with `name` described as the set's inverse model (so a model names
/// its own outputs), which must be `experiment`'s.
fn load_for(dir: &Path, name: &str, experiment: Experiment) -> anyhow::Result<ModelSet> {
    let models = ModelSet::load(dir, name, name, true)
        .with_context(|| format!("loading the models in {}", dir.display()))?;
    if models.experiment() != experiment {
        bail!(
            "{} holds {} models; this task drives {experiment}",
            dir.display(),
            models.experiment()
        );
    }
    Ok(models)
}
