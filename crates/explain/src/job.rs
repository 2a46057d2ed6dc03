//! The one explain entry point: [`run`] does the whole job of `causal-arm explain` and of
//! the explainer node (load, attribute, decide, score, write every file atomically), so the
//! two front ends only parse, print or publish, and cannot decide differently.

use std::path::{Path, PathBuf};
use std::time::Instant;

use causal_arm_dataset::{ActionSource, Cache, Dataset, load_bags};
use causal_arm_models::load_model;
use causal_arm_scoring::{EdgeClaims, Verdict};
use causal_arm_truth::{ScoreRow, Truth};

use crate::influence::{
    ErrorFloors, InfluenceSettings, Rule, agreement_effects, cai_effects, claims_by_context,
    holdout_effects,
};
use crate::multistep::{self, MultiStep};
use crate::output::{write_all, write_json};
use crate::{
    BackgroundKind, ExplainError, Explainer, Explanation, Method, Relevance, Result, Settings,
    calibrated_relevance,
};

/// What an explain job computes: a SHAP attribution (with the default three-valued
/// verdicts), or an influence measure with its own decision rule.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExplainMethod {
    /// Deep SHAP (the paper's).
    Deep,
    /// Kernel SHAP.
    Kernel,
    /// Causal influence: spread of the prediction when one action is resampled.
    Cai,
    /// Signed influence reproduced across independently trained models.
    Agreement,
    /// Signed influence against a_j drawn given the rest of the state.
    Holdout,
}

causal_arm_protocol::choice!(ExplainMethod, "SHAP method", [
    ExplainMethod::Deep => "deep",
    ExplainMethod::Kernel => "kernel",
    ExplainMethod::Cai => "cai",
    ExplainMethod::Agreement => "agreement",
    ExplainMethod::Holdout => "holdout",
]);

impl ExplainMethod {
    /// The SHAP method, or `None` for an influence method.
    pub fn shap(self) -> Option<Method> {
        match self {
            Self::Deep => Some(Method::Deep),
            Self::Kernel => Some(Method::Kernel),
            Self::Cai | Self::Agreement | Self::Holdout => None,
        }
    }
}

/// Everything an explain job needs, as a front end parsed it.
#[derive(Debug, Clone)]
pub struct ExplainRequest {
    /// Model directory written by `causal-arm train`.
    pub model: PathBuf,
    /// Forward model file stem in it.
    pub name: String,
    /// Bags the observations and the background come from.
    pub bags: Vec<PathBuf>,
    /// What is computed.
    pub method: ExplainMethod,
    /// Observations explained (SHAP) or averaged over (influence).
    pub samples: usize,
    /// Background rows or k-means centres (`None`: the method's default).
    pub background: Option<usize>,
    /// How the background is drawn (`None`: the method's default).
    pub background_kind: Option<BackgroundKind>,
    /// Kernel SHAP coalitions per observation (`None`: shap's "auto").
    pub kernel_samples: Option<usize>,
    /// Relevance threshold of the SHAP rule, as a share of the feature's change std.
    pub threshold: f64,
    /// Action columns (`None`: what the model was trained on).
    pub action: Option<ActionSource>,
    /// Seed of every draw.
    pub seed: u64,
    /// Worker threads (`None`: all cores).
    pub threads: Option<usize>,
    /// Whether the per-pair PDP files are drawn.
    pub pair_plots: bool,
    /// Further models for [`ExplainMethod::Agreement`].
    pub also_models: Vec<PathBuf>,
    /// Ground truth (`causal-arm intervene` output) every claim set is scored against.
    pub truth: Option<PathBuf>,
    /// Calibrated rule: an edge's lower bound of effect / model error must exceed it.
    pub kappa: f64,
    /// CAI draws of each action per observation.
    pub resamples: usize,
    /// CAI through the forward model chained this many steps.
    pub horizon: Option<usize>,
    /// Where the files go; `None` writes nothing (the node publishes instead).
    pub out: Option<PathBuf>,
    /// Dataset cache directory (`None`: the default one).
    pub cache: Option<PathBuf>,
}

impl ExplainRequest {
    /// The output directory `causal-arm explain` uses when none is given.
    pub fn default_out(&self) -> PathBuf {
        match self.horizon {
            Some(h) => self.model.join(format!("explain-{}-h{h}", self.method)),
            None => self.model.join(format!("explain-{}", self.method)),
        }
    }

    /// The influence part's settings.
    pub fn influence(&self) -> InfluenceSettings {
        InfluenceSettings {
            observations: self.samples,
            resamples: self.resamples,
            kappa: self.kappa,
            seed: self.seed,
            ..InfluenceSettings::default()
        }
    }

    /// The SHAP part's settings (a SHAP method only).
    fn shap_settings(&self, method: Method) -> Settings {
        let mut settings = Settings::for_method(method);
        settings.samples = self.samples;
        if let Some(b) = self.background {
            settings.background = b;
        }
        if let Some(kind) = self.background_kind {
            settings.background_kind = kind;
        }
        settings.kernel_samples = self.kernel_samples;
        settings.seed = self.seed;
        settings.threads = self.threads;
        settings
    }

    /// Every check that needs no file: the one validation of the CLI, the node and the
    /// library, run before anything is loaded.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(ExplainError::Options(m));
        if !(self.threshold.is_finite() && self.threshold > 0.0) {
            return bad(format!(
                "--threshold must be a positive number, got {}",
                self.threshold
            ));
        }
        if let Some(method) = self.method.shap() {
            self.shap_settings(method).check()?;
        }
        self.influence().validate()?;
        if self.bags.is_empty() {
            return bad("no bag to draw observations from".into());
        }
        if let Some(horizon) = self.horizon {
            if self.method != ExplainMethod::Cai {
                return bad(format!(
                    "a horizon attributes through the chained forward model with CAI; use it with --method cai, not {:?}",
                    self.method.to_string()
                ));
            }
            multistep::check_horizon(horizon)?;
        }
        if !self.also_models.is_empty() && self.method != ExplainMethod::Agreement {
            return bad(format!(
                "further models are compared by the agreement method only, not by {}",
                self.method
            ));
        }
        Ok(())
    }
}

/// What a SHAP job found.
#[derive(Debug)]
pub struct ShapOutcome {
    /// The settings it ran with.
    pub settings: Settings,
    /// The attributions.
    pub explanation: Explanation,
    /// Per state feature, its verdict and what drives it.
    pub report: Relevance,
}

/// What an influence job (CAI, agreement, holdout) measured.
#[derive(Debug, Clone, Copy)]
pub struct InfluenceOutcome {
    /// Observations the influence was averaged over.
    pub observations: usize,
    /// Wall time, s.
    pub seconds: f64,
}

/// Everything a job computed, for the front end to print or publish.
pub struct Outcome {
    /// The model's explainer (the node serves it afterwards).
    pub explainer: Explainer,
    /// The transitions read.
    pub data: Dataset,
    /// A SHAP job's result.
    pub shap: Option<ShapOutcome>,
    /// An influence job's summary.
    pub influence: Option<InfluenceOutcome>,
    /// A multi-step job's result.
    pub multistep: Option<MultiStep>,
    /// Every claim set, the default first.
    pub claims: Vec<EdgeClaims>,
    /// Their scores against the truth (empty without one).
    pub scores: Vec<ScoreRow>,
    /// Every file written, in order.
    pub written: Vec<PathBuf>,
}

/// Runs the job `request` describes; `progress(done, total)` follows the SHAP
/// observations. A truth that cannot score this job is refused before any attribution.
pub fn run(request: &ExplainRequest, progress: &mut dyn FnMut(usize, usize)) -> Result<Outcome> {
    request.validate()?;
    let truth = request
        .truth
        .as_deref()
        .map(causal_arm_truth::load)
        .transpose()?;
    if let (Some(truth), Some(horizon)) = (&truth, request.horizon) {
        // The horizon asked for is named first, then any shorter one the truth lacks.
        for h in std::iter::once(horizon).chain(1..horizon) {
            causal_arm_truth::check_horizon(truth, h)?;
        }
    }
    let (explainer, data) = load(request, truth.as_ref())?;
    let mut outcome = Outcome {
        explainer,
        data,
        shap: None,
        influence: None,
        multistep: None,
        claims: Vec::new(),
        scores: Vec::new(),
        written: Vec::new(),
    };
    if let Some(horizon) = request.horizon {
        run_multistep(request, &mut outcome, horizon)?;
    } else if let Some(method) = request.method.shap() {
        run_shap(request, &mut outcome, method, progress)?;
    } else {
        run_influence(request, &mut outcome)?;
    }
    if let Some(truth) = &truth {
        outcome.scores = match request.horizon {
            Some(_) => causal_arm_truth::score_horizons(truth, &outcome.claims)?,
            None => score_all(truth, &outcome.claims)?,
        };
    }
    if let Some(out) = &request.out {
        write_results(request, out, &mut outcome)?;
    }
    Ok(outcome)
}

/// The action source the model was trained with, as `causal-arm train` recorded it.
fn trained_action_source(model_dir: &Path, name: &str) -> Option<String> {
    let text = std::fs::read_to_string(model_dir.join("metrics.json")).ok()?;
    let metrics: serde_json::Value = serde_json::from_str(&text).ok()?;
    metrics["models"][name]["options"]["action"]
        .as_str()
        .map(str::to_owned)
}

/// The model, its explainer and the data; a truth of other features is refused first.
fn load(request: &ExplainRequest, truth: Option<&Truth>) -> Result<(Explainer, Dataset)> {
    let explainer = Explainer::new(load_model(&request.model, &request.name)?)?;
    if let Some(truth) = truth {
        causal_arm_truth::check_names(
            truth,
            &request.method.to_string(),
            explainer.action_names(),
            explainer.state_names(),
        )?;
    }
    // The source the model was trained on; for a model without a training record, the
    // bags' own default (commanded on the dynamic arm's), as `train` and `discover` take.
    let action = match (
        request.action,
        trained_action_source(&request.model, &request.name),
    ) {
        (Some(action), _) => action,
        (None, Some(text)) => text.parse().map_err(ExplainError::Options)?,
        (None, None) => ActionSource::of_bags(&request.bags)?,
    };
    let cache = Cache::new(request.cache.clone().unwrap_or_else(Cache::default_dir));
    let (data, _) = load_bags(
        &request.bags,
        Some(explainer.experiment()),
        action,
        Some(&cache),
    )?;
    Ok((explainer, data))
}

/// SHAP, the default verdicts beside the other claim sets, and the relevance report.
fn run_shap(
    request: &ExplainRequest,
    outcome: &mut Outcome,
    method: Method,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<()> {
    let settings = request.shap_settings(method);
    let (explainer, data) = (&outcome.explainer, &outcome.data);
    let explanation = explainer.explain_dataset(data, &settings, progress)?;
    let claims = crate::verdicts::shap_and_cai_claims(
        explainer,
        data,
        &explanation,
        request.threshold,
        &request.influence(),
    )?;
    let report = calibrated_relevance(&explanation, request.threshold, &claims)?;
    outcome.claims = claims;
    outcome.shap = Some(ShapOutcome {
        settings,
        explanation,
        report,
    });
    Ok(())
}

/// CAI, agreement or holdout influence, with verdicts by the method's rule.
fn run_influence(request: &ExplainRequest, outcome: &mut Outcome) -> Result<()> {
    let (explainer, data) = (&outcome.explainer, &outcome.data);
    let settings = request.influence();
    let started = Instant::now();
    let (effects, claims) = match request.method {
        ExplainMethod::Cai => {
            let effects = cai_effects(explainer, data, &settings)?;
            let floors = ErrorFloors::measure(explainer, data, &settings)?;
            let rule = Rule::ErrorRatio(&floors);
            let claims = claims_by_context(explainer, data, &effects, &settings, rule);
            (effects, claims)
        }
        ExplainMethod::Holdout => {
            let effects = holdout_effects(explainer, data, &settings)?;
            let claims =
                claims_by_context(explainer, data, &effects, &settings, Rule::Significance);
            (effects, claims)
        }
        _ => {
            let mut others = Vec::new();
            for dir in &request.also_models {
                others.push(Explainer::new(load_model(dir, &request.name)?)?);
            }
            let all: Vec<&Explainer> = std::iter::once(explainer).chain(&others).collect();
            let effects = agreement_effects(&all, data, &settings)?;
            let claims =
                claims_by_context(explainer, data, &effects, &settings, Rule::Significance);
            (effects, claims)
        }
    };
    outcome.claims = claims;
    outcome.influence = Some(InfluenceOutcome {
        observations: effects.rows.len(),
        seconds: started.elapsed().as_secs_f64(),
    });
    Ok(())
}

/// CAI through the forward model chained `horizon` steps, verdicts per horizon.
fn run_multistep(request: &ExplainRequest, outcome: &mut Outcome, horizon: usize) -> Result<()> {
    let result = multistep::multistep_cai(
        &outcome.explainer,
        &outcome.data,
        &request.influence(),
        horizon,
    )?;
    outcome.claims = result.claims().cloned().collect();
    outcome.multistep = Some(result);
    Ok(())
}

/// Every claim set scored against `truth`.
fn score_all(truth: &Truth, claims: &[EdgeClaims]) -> Result<Vec<ScoreRow>> {
    let mut rows = Vec::new();
    for c in claims {
        rows.extend(causal_arm_truth::score_claims(truth, c)?);
    }
    Ok(rows)
}

/// Every file of the job into `out`: the explanation's (SHAP), `claims.json` and the verdict
/// maps, `scores.json` with a truth, or `multistep.json` and its figures.
/// A SHAP job also redraws the mental-simulation figure, if `causal-arm rollout` was run on
/// the model, so the directory holds every figure of the paper for it.
fn write_results(request: &ExplainRequest, out: &Path, outcome: &mut Outcome) -> Result<()> {
    let mut written = Vec::new();
    if let Some(shap) = &outcome.shap {
        let files = write_all(out, &shap.explanation, &shap.report, request.pair_plots)?;
        written.extend(files.files);
        written.extend(redraw_mental_simulation(
            &request.model,
            out,
            &shap.explanation,
        )?);
    }
    std::fs::create_dir_all(out).map_err(|e| crate::output::file_err(out, e))?;
    if let Some(result) = &outcome.multistep {
        written.push(write_multistep(out, result, &outcome.scores)?);
        written.extend(multistep::draw_figures(result, out)?);
    } else {
        let claims = out.join("claims.json");
        write_json(&claims, &outcome.claims)?;
        written.push(claims);
        written.extend(draw_all_verdicts(out, &outcome.claims)?);
        if !outcome.scores.is_empty() {
            let scores = out.join("scores.json");
            write_json(&scores, &outcome.scores)?;
            written.push(scores);
        }
    }
    outcome.written.extend(written);
    Ok(())
}

/// The mental-simulation figure from the model directory's `mental_simulation.json`, if any.
fn redraw_mental_simulation(
    model: &Path,
    out: &Path,
    explanation: &Explanation,
) -> Result<Option<PathBuf>> {
    let mental = model.join("mental_simulation.json");
    let Ok(text) = std::fs::read_to_string(&mental) else {
        return Ok(None);
    };
    let result: causal_arm_models::mental::MentalSimulation =
        serde_json::from_str(&text).map_err(|e| {
            crate::output::file_err(&mental, format!("not a mental simulation result: {e}"))
        })?;
    let stem = out.join("mental_simulation");
    crate::output::draw_mental_simulation(&stem, &result, &explanation.experiment.to_string())?;
    Ok(Some(stem.with_extension("png")))
}

/// `multistep.json`: per horizon its effects, error floors, verdicts and scores.
fn write_multistep(out: &Path, result: &MultiStep, rows: &[ScoreRow]) -> Result<PathBuf> {
    let path = out.join("multistep.json");
    let mut json = serde_json::to_value(result).expect("the result serialises");
    if let Some(horizons) = json["horizons"].as_array_mut() {
        for h in horizons {
            let k = h["horizon"].as_u64().unwrap_or(0) as usize;
            let scores: Vec<_> = rows.iter().filter(|r| r.horizon == k).collect();
            h["scores"] = serde_json::to_value(scores).expect("scores serialise");
        }
    }
    write_json(&path, &json)?;
    Ok(path)
}

/// The default claims as `verdicts_heatmap`, every method's all-states claims beside it.
fn draw_all_verdicts(out: &Path, claims: &[EdgeClaims]) -> Result<Vec<PathBuf>> {
    let all_states = claims
        .iter()
        .filter(|c| c.context == "all" && c.horizon == 1);
    let mut files = Vec::new();
    for (i, c) in all_states.enumerate() {
        let file = match i {
            0 => "verdicts_heatmap".to_owned(),
            _ => format!("verdicts_{}", c.method.replace(['/', '+'], "_")),
        };
        let stem = out.join(file);
        draw_verdicts(&stem, c)?;
        files.extend([stem.with_extension("png"), stem.with_extension("svg")]);
    }
    Ok(files)
}

/// A heat map of `claims`' verdicts: 1 drives, 0 does not, and undecided in a colour of its
/// own (0.5), so an honest "don't know" never looks like either answer.
fn draw_verdicts(stem: &Path, claims: &EdgeClaims) -> Result<()> {
    let (na, ns) = (claims.action_names.len(), claims.state_names.len());
    let values: Vec<f64> = (0..na * ns)
        .map(|i| match claims.verdict(i / ns, i % ns) {
            Verdict::Drives => 1.0,
            Verdict::Undecided => 0.5,
            Verdict::DoesNot => 0.0,
        })
        .collect();
    let legend = if claims.decisions.is_some() {
        "1 = drives, 0.5 = undecided, 0 = does not"
    } else {
        "1 = claimed"
    };
    causal_arm_plots::heatmap(
        stem,
        &format!(
            "{}: which action drives which s(t+1) ({legend})",
            claims.method
        ),
        &claims.action_names,
        &claims.state_names,
        &values,
        "claimed",
        causal_arm_plots::HeatmapScale::Linear,
    )?;
    Ok(())
}
