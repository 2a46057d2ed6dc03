//! The job a `causal_arm_trainer` node's parameters ask for (train from bags first if
//! given, then serve the directory), built and run here without DDS, so the node only
//! reads its parameters, logs and answers its services.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use anyhow::anyhow;
use causal_arm_dataset::{ActionSource, Cache, load_bags};
use causal_arm_params::{TrainerParams, trainer};

use crate::fit::ProgressLog;
use crate::job::{SavedRun, train_and_save};
use crate::serve::ModelSet;
use crate::{ModelRequest, TrainError, TrainOptions};

/// Longest silence between training progress lines.
const LOG_EVERY: Duration = Duration::from_secs(5);

/// What the trainer node does, from its parameters.
#[derive(Debug)]
pub struct TrainerJob {
    /// The model directory served (and trained into, with bags).
    pub model_dir: PathBuf,
    /// Bags to train on first; none to serve what the directory holds.
    pub bags: Vec<PathBuf>,
    /// Which models to train.
    pub request: ModelRequest,
    /// How to train them.
    pub options: TrainOptions,
    /// Dataset cache.
    pub cache: Cache,
    /// Forward model file stem served.
    pub forward_model: String,
    /// Inverse model file stem served.
    pub inverse_model: String,
    /// The user named the inverse model, so it must exist (the default may be absent:
    /// a directory of forward models).
    pub inverse_required: bool,
}

impl TrainerJob {
    /// Checks every setting before anything is read; `stop` ends training early.
    pub fn from_params(p: &TrainerParams, stop: Arc<AtomicBool>) -> anyhow::Result<Self> {
        if p.model_dir.is_empty() {
            anyhow::bail!(
                "parameter model_dir is required: --ros-args -p model_dir:=DIR (a directory written by `causal-arm train`, or where to train to with -p bag:=DIR)"
            );
        }
        // -1 asks for the default; 0 epochs or folds would train nothing.
        let optional_count = |value: i64, name: &str| match value {
            -1 => Ok(None),
            0 => Err(anyhow!(
                "parameter {name}: 0 would train nothing; give at least 1, or -1 for the default"
            )),
            n => Ok(Some(n as usize)),
        };
        let parsed = |name: &str, e: String| anyhow!("parameter {name}: {e}");
        let options = TrainOptions {
            profile: p.profile.parse().map_err(|e| parsed("profile", e))?,
            epochs: optional_count(p.epochs, "epochs")?,
            // Declared ranges keep these non-negative.
            folds: p.folds as usize,
            max_folds: optional_count(p.max_folds, "max_folds")?,
            lr_schedule: p
                .lr_schedule
                .parse()
                .map_err(|e| parsed("lr_schedule", e))?,
            seed: p.seed as u64,
            stop: Some(stop),
            ..TrainOptions::default()
        };
        Ok(Self {
            model_dir: PathBuf::from(&p.model_dir),
            bags: p.bag.iter().map(PathBuf::from).collect(),
            request: p.models.parse().map_err(|e| parsed("models", e))?,
            options,
            cache: match p.cache.as_str() {
                "" => Cache::new(Cache::default_dir()),
                dir => Cache::new(PathBuf::from(dir)),
            },
            forward_model: p.forward_model.clone(),
            inverse_model: p.inverse_model.clone(),
            inverse_required: p.inverse_model != trainer::inverse_model::default_text(),
        })
    }

    /// Trains the requested models from the bags into the model directory, giving `log`
    /// progress and the figures, each beside its baseline and the paper's.
    pub fn train(&self, log: &mut dyn FnMut(String)) -> anyhow::Result<SavedRun> {
        let action = ActionSource::of_bags(&self.bags)?;
        let (data, _) = load_bags(&self.bags, None, action, Some(&self.cache))?;
        log(format!(
            "training on {} {} transitions from {}",
            data.rows(),
            data.experiment,
            (self.bags.iter())
                .map(|b| b.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ));
        let kinds = self.request.kinds(data.experiment);
        let mut progress = ProgressLog::new(LOG_EVERY);
        let saved = train_and_save(
            &data,
            &kinds,
            &self.options,
            action,
            &self.model_dir,
            &mut |p| {
                if let Some(line) = progress.line(&p) {
                    log(line);
                }
            },
        )?;
        for figure in &saved.figures {
            let paper = (figure.paper)
                .map(|p| format!(", paper {p:.3e}"))
                .unwrap_or_default();
            log(format!(
                "{}: MAE {:.3e} ± {:.1e} {} (mean baseline {:.3e}{paper})",
                figure.key, figure.mean, figure.std, figure.unit, figure.baseline
            ));
        }
        log(format!(
            "wrote {} model files and {}",
            saved.written.len(),
            saved.metrics.display()
        ));
        Ok(saved)
    }

    /// The models to serve.
    pub fn load(&self) -> Result<ModelSet, TrainError> {
        ModelSet::load(
            &self.model_dir,
            &self.forward_model,
            &self.inverse_model,
            self.inverse_required,
        )
    }
}
