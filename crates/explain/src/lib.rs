//! The paper's knowledge extraction: SHAP attributions of the forward model's inputs
//! (state s(t) and action a(t)) on its outputs s(t+1), aggregated into a heat map, partial
//! dependence plots and a report of which state features the robot's actions can change.
//!
//! The library does the work, without DDS; `causal-arm explain` and the
//! `causal_arm_explainer` node (`nodes/explainer`) are thin front ends. The explained function is the forward model's network with its offset
//! columns added (a delta model predicts s(t+1) − s(t)), in raw units, *without* wrapping
//! Euler angles into (−π, π]: wrapping is a discontinuity whose attributions mean nothing.

#![warn(missing_docs)]

pub mod decide;
pub mod influence;
pub mod job;
pub mod multistep;
mod node_request;
pub mod output;
pub mod report;
pub mod serve;
pub mod verdicts;

use std::time::Instant;

use causal_arm_dataset::{Dataset, Experiment};
use causal_arm_models::LoadedModel;
use causal_arm_shap::{
    Attributions, Background, DeepModel, DeepOptions, KernelOptions, OBSERVATION_SEED_STRIDE,
    RegressorModel, ShapError, kernel_shap, kmeans,
};
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand::seq::index::sample;

pub use job::{ExplainMethod, ExplainRequest, Outcome, run};
pub use report::{Relevance, calibrated_relevance, relevance};

/// Why an explanation could not be made; every bad input is reported, never a panic.
#[derive(Debug, thiserror::Error)]
pub enum ExplainError {
    /// An option or request field is out of range.
    #[error("{0}")]
    Options(String),
    /// The model and the data disagree (experiment, feature names, widths).
    #[error("model and data disagree: {0}")]
    Mismatch(String),
    /// The attribution method refused its input.
    #[error(transparent)]
    Shap(#[from] ShapError),
    /// A file could not be written.
    #[error("{path}: {problem}")]
    File {
        /// File or directory.
        path: String,
        /// What failed.
        problem: String,
    },
    /// A figure could not be drawn.
    #[error(transparent)]
    Plot(#[from] causal_arm_plots::PlotError),
    /// The model could not be loaded.
    #[error(transparent)]
    Model(#[from] causal_arm_models::TrainError),
    /// The bags could not be read.
    #[error(transparent)]
    Data(#[from] causal_arm_dataset::DatasetError),
    /// The truth could not be read or does not fit the model.
    #[error(transparent)]
    Truth(#[from] causal_arm_truth::TruthError),
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, ExplainError>;

/// Attribution method: the paper uses Deep SHAP; Kernel SHAP is the model-agnostic check.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// DeepLIFT rescale rules averaged over the background (`shap.DeepExplainer`).
    Deep,
    /// Shapley-kernel weighted regression over coalitions (`shap.KernelExplainer`).
    Kernel,
}

causal_arm_protocol::choice!(Method, "SHAP method", [Method::Deep => "deep", Method::Kernel => "kernel"]);

/// How the background (the reference distribution attributions are measured against) is
/// drawn from the data.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BackgroundKind {
    /// Rows drawn uniformly, equal weights (what `shap.DeepExplainer` is given).
    Sample,
    /// Weighted k-means centres of a data sample (`shap.kmeans`, for Kernel SHAP, whose cost
    /// grows with every background row).
    Kmeans,
}

causal_arm_protocol::choice!(BackgroundKind, "background kind", [
    BackgroundKind::Sample => "sample",
    BackgroundKind::Kmeans => "kmeans",
]);

/// Rows k-means summarises at most (more adds time, not a better summary of 50 centres).
pub const KMEANS_POOL: usize = 20_000;

/// Everything that decides an explanation besides the model and the data.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Settings {
    /// Attribution method.
    pub method: Method,
    /// Observations explained (the paper: 200).
    pub samples: usize,
    /// Background rows (sample) or k-means centres.
    pub background: usize,
    /// How the background is drawn.
    pub background_kind: BackgroundKind,
    /// Kernel SHAP coalitions per observation (`None`: 2·M + 2048, as shap's "auto").
    pub kernel_samples: Option<usize>,
    /// Seed of the observation and background draws and of the coalition sampler.
    pub seed: u64,
    /// Worker threads (`None`: all cores).
    pub threads: Option<usize>,
}

impl Settings {
    /// The defaults of `method`: 200 observations; Deep SHAP against 100 sampled rows,
    /// Kernel SHAP against 50 k-means centres (the figures of DESIGN's `shap` benchmark).
    pub fn for_method(method: Method) -> Self {
        let (background, background_kind) = match method {
            Method::Deep => (100, BackgroundKind::Sample),
            Method::Kernel => (50, BackgroundKind::Kmeans),
        };
        Self {
            method,
            samples: 200,
            background,
            background_kind,
            kernel_samples: None,
            seed: 0,
            threads: None,
        }
    }

    /// Refuses settings no explanation can run with (the job checks them before loading).
    pub(crate) fn check(&self) -> Result<()> {
        if self.samples == 0 {
            return Err(ExplainError::Options(
                "samples must be at least 1 observation".into(),
            ));
        }
        if self.background == 0 {
            return Err(ExplainError::Options(
                "background must be at least 1 row".into(),
            ));
        }
        if self.method == Method::Deep && self.background_kind == BackgroundKind::Kmeans {
            return Err(ExplainError::Options(
                "Deep SHAP averages over background rows with equal weights; use --background-kind sample (k-means centres carry weights)".into(),
            ));
        }
        if self.kernel_samples == Some(0) {
            return Err(ExplainError::Options(
                "kernel samples must be at least 1 coalition".into(),
            ));
        }
        Ok(())
    }
}

/// A forward model ready to explain, with its feature names split into state and action.
pub struct Explainer {
    model: LoadedModel,
    deep: DeepModel,
    experiment: Experiment,
    n_state: usize,
}

impl Explainer {
    /// Prepares `model` (a forward model file: inputs = state ++ action, outputs = next
    /// state) for both methods.
    pub fn new(model: LoadedModel) -> Result<Self> {
        let experiment = model
            .experiment()
            .map_err(|e| ExplainError::Mismatch(e.to_string()))?;
        let state = causal_arm_dataset::state_names(experiment);
        let action = causal_arm_dataset::action_names(experiment);
        let problem = &model.meta.problem;
        let expected_inputs: Vec<String> = state.iter().chain(&action).cloned().collect();
        if problem.input_names != expected_inputs {
            return Err(ExplainError::Mismatch(format!(
                "model {:?} has inputs {:?}; a forward model of {experiment} has [state, action] = {:?}",
                model.meta.name, problem.input_names, expected_inputs
            )));
        }
        if problem.output_names.len() != state.len() {
            return Err(ExplainError::Mismatch(format!(
                "model {:?} has {} outputs; a forward model of {experiment} predicts the {} state features",
                model.meta.name,
                problem.output_names.len(),
                state.len()
            )));
        }
        let deep = DeepModel::from_regressor(&model.regressor, problem.offset_columns.as_deref())?;
        Ok(Self {
            n_state: state.len(),
            model,
            deep,
            experiment,
        })
    }

    /// The experiment whose feature order the model uses.
    pub fn experiment(&self) -> Experiment {
        self.experiment
    }

    /// Input names: state features, then actions.
    pub fn input_names(&self) -> &[String] {
        &self.model.meta.problem.input_names
    }

    /// State feature names (the outputs, without the `_next` suffix).
    pub fn state_names(&self) -> &[String] {
        &self.input_names()[..self.n_state]
    }

    /// Action feature names.
    pub fn action_names(&self) -> &[String] {
        &self.input_names()[self.n_state..]
    }

    /// Output names as the model file states them (`o_x_next`, …).
    pub fn output_names(&self) -> &[String] {
        &self.model.meta.problem.output_names
    }

    /// Number of inputs (state + action features).
    pub fn n_inputs(&self) -> usize {
        self.input_names().len()
    }

    /// The loaded model.
    pub fn model(&self) -> &LoadedModel {
        &self.model
    }

    /// Attributions of the rows `x` (`[n, state ++ action]`, raw units) against
    /// `background`, with the method's options from `settings`.
    pub fn attribute(
        &self,
        x: &[f32],
        background: &Background,
        settings: &Settings,
    ) -> Result<(Attributions, f64)> {
        let started = Instant::now();
        let attributions = match settings.method {
            Method::Deep => {
                if background.weights().windows(2).any(|w| w[0] != w[1]) {
                    return Err(ExplainError::Options(
                        "Deep SHAP needs an equally weighted background".into(),
                    ));
                }
                self.deep.explain(
                    x,
                    background.data(),
                    &DeepOptions {
                        threads: settings.threads,
                        ..Default::default()
                    },
                )?
            }
            Method::Kernel => {
                let model = RegressorModel::new(
                    &self.model.regressor,
                    self.model.meta.problem.offset_columns.as_deref(),
                )?;
                kernel_shap(
                    &model,
                    background,
                    x,
                    &KernelOptions {
                        nsamples: settings.kernel_samples,
                        seed: settings.seed,
                        threads: settings.threads,
                        ..Default::default()
                    },
                )?
            }
        };
        Ok((attributions, started.elapsed().as_secs_f64()))
    }

    /// [`Self::attribute`] in chunks of observations, reporting progress after each; the
    /// chunks' attributions are concatenated and equal one call's (Kernel SHAP chunks
    /// continue the per-observation seed streams).
    pub fn attribute_chunked(
        &self,
        x: &[f32],
        background: &Background,
        settings: &Settings,
        progress: &mut dyn FnMut(usize, usize),
    ) -> Result<Attributions> {
        let width = self.n_inputs();
        let total = x.len() / width.max(1);
        let chunk = match settings.method {
            Method::Deep => 50,
            Method::Kernel => 4,
        };
        let mut all: Option<Attributions> = None;
        for start in (0..total).step_by(chunk) {
            let end = (start + chunk).min(total);
            let chunk_settings = Settings {
                seed: settings
                    .seed
                    .wrapping_add((start as u64).wrapping_mul(OBSERVATION_SEED_STRIDE)),
                ..settings.clone()
            };
            let (a, _) =
                self.attribute(&x[start * width..end * width], background, &chunk_settings)?;
            match &mut all {
                None => all = Some(a),
                Some(all) => {
                    all.n_obs += a.n_obs;
                    all.values.extend(a.values);
                    all.outputs.extend(a.outputs);
                }
            }
            progress(end, total);
        }
        all.ok_or_else(|| ExplainError::Options("no observations to explain".into()))
    }

    /// Explains `settings.samples` transitions drawn from `data` (seeded) against a
    /// background drawn from the other rows, as the paper's 200-observation analysis.
    /// `progress(done, total)` is called after every chunk of observations.
    pub fn explain_dataset(
        &self,
        data: &Dataset,
        settings: &Settings,
        progress: &mut dyn FnMut(usize, usize),
    ) -> Result<Explanation> {
        settings.check()?;
        if data.experiment != self.experiment {
            return Err(ExplainError::Mismatch(format!(
                "the data is {}, the model {}",
                data.experiment, self.experiment
            )));
        }
        let picks = Picks::draw(data.rows(), settings)?;
        let inputs = |rows: &[usize]| forward_inputs(data, rows);
        let observations = inputs(&picks.observations);
        let background = match settings.background_kind {
            BackgroundKind::Sample => {
                Background::sample(&inputs(&picks.background), self.n_inputs())?
            }
            BackgroundKind::Kmeans => kmeans(
                &inputs(&picks.background),
                self.n_inputs(),
                settings.background,
                settings.seed,
            )?,
        };
        let started = Instant::now();
        let attributions =
            self.attribute_chunked(&observations, &background, settings, progress)?;
        let seconds = started.elapsed().as_secs_f64();
        Ok(Explanation {
            settings: settings.clone(),
            experiment: self.experiment,
            input_names: self.input_names().to_vec(),
            output_names: self.output_names().to_vec(),
            n_state: self.n_state,
            observation_rows: picks.observations,
            observations,
            background,
            attributions,
            seconds,
            state_scale: change_scale(data),
        })
    }
}

/// The forward model's input rows `[state ++ action]` of the transitions `rows`.
pub fn forward_inputs(data: &Dataset, rows: &[usize]) -> Vec<f32> {
    let mut out = Vec::with_capacity(rows.len() * (data.state_width() + data.action_width()));
    for &r in rows {
        out.extend_from_slice(data.state(r));
        out.extend_from_slice(data.action(r));
    }
    out
}

/// Row indices of the observations and of the background pool.
struct Picks {
    observations: Vec<usize>,
    background: Vec<usize>,
}

impl Picks {
    /// Disjoint seeded draws: the observations, then the background (or the k-means pool)
    /// from the remaining rows.
    fn draw(rows: usize, settings: &Settings) -> Result<Self> {
        let pool_size = match settings.background_kind {
            BackgroundKind::Sample => settings.background,
            BackgroundKind::Kmeans => settings.background.max(KMEANS_POOL.min(rows)),
        };
        if settings.samples + settings.background > rows {
            return Err(ExplainError::Options(format!(
                "the data has {rows} transitions; {} observations + {} background rows need more (lower --samples/--background or give a larger bag)",
                settings.samples, settings.background
            )));
        }
        let pool_size = pool_size.min(rows - settings.samples);
        let mut rng = StdRng::seed_from_u64(settings.seed);
        let drawn = sample(&mut rng, rows, settings.samples + pool_size).into_vec();
        let (observations, background) = drawn.split_at(settings.samples);
        Ok(Self {
            observations: observations.to_vec(),
            background: background.to_vec(),
        })
    }
}

/// Standard deviation of every state feature's one-step change s(t+1) − s(t) over the data
/// (Euler angles wrapped): the unit the relevance threshold is measured in. Actions cause
/// *changes*, so an effect is judged against how much the feature really moves per step,
/// in its own unit; a feature that never changes within a transition (colour within an
/// episode) has scale 0 and no action can be shown to affect it.
pub fn change_scale(data: &Dataset) -> Vec<f64> {
    let w = data.state_width();
    let delta = |r: usize| data.change(r).into_iter();
    let n = data.rows().max(1) as f64;
    let mut mean = vec![0f64; w];
    for r in 0..data.rows() {
        mean.iter_mut().zip(delta(r)).for_each(|(m, d)| *m += d);
    }
    mean.iter_mut().for_each(|m| *m /= n);
    let mut var = vec![0f64; w];
    for r in 0..data.rows() {
        for ((v, d), m) in var.iter_mut().zip(delta(r)).zip(&mean) {
            *v += (d - m).powi(2);
        }
    }
    var.into_iter().map(|v| (v / n).sqrt()).collect()
}

/// `value` in units of a feature's one-step change `scale` (see [`change_scale`]); 0 for a
/// feature that never changes in the data (whatever small effect a network gives it, the
/// data shows no action changing it).
pub(crate) fn in_change_units(value: f64, scale: f64) -> f64 {
    if scale > 0.0 { value / scale } else { 0.0 }
}

/// One explanation run: what was explained, against what, and the attributions.
#[derive(Debug)]
pub struct Explanation {
    /// How it was made.
    pub settings: Settings,
    /// Experiment of the model and data.
    pub experiment: Experiment,
    /// State then action feature names.
    pub input_names: Vec<String>,
    /// Next-state output names.
    pub output_names: Vec<String>,
    /// Number of state features (the first inputs); the rest are actions.
    pub n_state: usize,
    /// Dataset rows of the observations.
    pub observation_rows: Vec<usize>,
    /// Explained rows `[n_obs, n_inputs]`, raw units.
    pub observations: Vec<f32>,
    /// Background the attributions are measured against.
    pub background: Background,
    /// The attributions (`[n_obs, n_inputs, n_outputs]`).
    pub attributions: Attributions,
    /// Wall time of the attribution step alone, s.
    pub seconds: f64,
    /// Standard deviation of each state feature's one-step change (see [`change_scale`]).
    pub state_scale: Vec<f64>,
}

impl Explanation {
    /// State feature names (the outputs).
    pub fn state_names(&self) -> &[String] {
        &self.input_names[..self.n_state]
    }

    /// Action feature names.
    pub fn action_names(&self) -> &[String] {
        &self.input_names[self.n_state..]
    }

    /// Mean |SHAP| of every action on every state output, `[n_action][n_state]`: the
    /// paper's heat map.
    pub fn action_mean_abs(&self) -> Vec<Vec<f64>> {
        let all = self.attributions.mean_abs();
        let n_out = self.attributions.n_outputs;
        (self.n_state..self.input_names.len())
            .map(|i| all[i * n_out..(i + 1) * n_out].to_vec())
            .collect()
    }

    /// |SHAP| of every action on every output per observation, as effects the calibrated
    /// decision rule judges ([`influence::calibrated_claims`]).
    pub fn effects(&self) -> influence::Effects {
        let n_action = self.input_names.len() - self.n_state;
        let mut values = Vec::with_capacity(self.attributions.n_obs * n_action * self.n_state);
        for o in 0..self.attributions.n_obs {
            for a in 0..n_action {
                for k in 0..self.n_state {
                    values.push(self.attributions.get(o, self.n_state + a, k).abs());
                }
            }
        }
        influence::Effects {
            method: self.settings.method.to_string(),
            rows: self.observation_rows.clone(),
            n_action,
            n_state: self.n_state,
            values,
        }
    }

    /// (action value, its contribution to `output`) per observation: one PDP panel.
    pub fn dependence(&self, action: usize, output: usize) -> Vec<(f64, f64)> {
        let input = self.n_state + action;
        let n_in = self.input_names.len();
        (0..self.attributions.n_obs)
            .map(|o| {
                (
                    self.observations[o * n_in + input] as f64,
                    self.attributions.get(o, input, output),
                )
            })
            .collect()
    }

    /// Worst relative efficiency violation (Σ φ vs f(x) − E f), floor 1e-9 × output scale.
    pub fn efficiency_error(&self) -> f64 {
        let scale = self
            .attributions
            .outputs
            .iter()
            .fold(0f64, |m, v| m.max(v.abs()));
        self.attributions.efficiency_error(1e-6 * scale.max(1e-12))
    }
}
