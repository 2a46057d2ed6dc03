//! The explain job a `causal_arm_explainer` node's parameters ask for, built here (no DDS)
//! so the node only reads its parameters and publishes.

use std::path::PathBuf;

use causal_arm_params::ExplainerParams;

use crate::job::{ExplainMethod, ExplainRequest};
use crate::{ExplainError, Method};

impl TryFrom<&ExplainerParams> for ExplainRequest {
    type Error = ExplainError;

    /// The job of `causal-arm explain --method <method>` as the node's parameters give it:
    /// SHAP and the default verdicts on the same observations, no files written; checked
    /// before any data is loaded, so a bad setting costs no time.
    fn try_from(p: &ExplainerParams) -> Result<Self, ExplainError> {
        if p.model_dir.is_empty() || p.bag.is_empty() {
            return Err(ExplainError::Options(
                "parameters model_dir and bag are required: --ros-args -p model_dir:=DIR -p bag:=BAG (a directory written by `causal-arm train` and a bag of the same experiment)".into(),
            ));
        }
        let method = match p
            .method
            .parse()
            .map_err(|e: String| ExplainError::Options(e))?
        {
            Method::Deep => ExplainMethod::Deep,
            Method::Kernel => ExplainMethod::Kernel,
        };
        // Declared ranges keep the counts and the seed non-negative.
        let request = ExplainRequest {
            model: PathBuf::from(&p.model_dir),
            name: p.forward_model.clone(),
            bags: vec![PathBuf::from(&p.bag)],
            method,
            samples: p.samples as usize,
            background: None,
            background_kind: None,
            kernel_samples: None,
            threshold: p.threshold,
            action: None,
            seed: p.seed as u64,
            threads: None,
            pair_plots: false,
            also_models: Vec::new(),
            truth: None,
            kappa: p.kappa,
            resamples: p.resamples as usize,
            horizon: None,
            out: None,
            cache: (!p.cache.is_empty()).then(|| PathBuf::from(&p.cache)),
        };
        request.validate()?;
        Ok(request)
    }
}
