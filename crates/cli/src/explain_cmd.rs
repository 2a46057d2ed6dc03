//! `causal-arm explain`: SHAP attributions of a trained forward model on transitions from
//! bags, with the heat map, partial dependence plots and relevance report.

use std::path::{Path, PathBuf};

use anyhow::Context;
use causal_arm_dataset::{ActionSource, Cache, Dataset, load_bags};
use causal_arm_explain::influence::{
    ErrorFloors, InfluenceSettings, Rule, agreement_effects, cai_effects, claims_by_context,
    holdout_effects,
};
use causal_arm_explain::multistep;
use causal_arm_explain::output::{Written, write_all};
use causal_arm_explain::{
    BackgroundKind, Explainer, Explanation, Method, Relevance, Settings, calibrated_relevance,
};
use causal_arm_models::load_model;
use causal_arm_protocol::graph::server_default_text;
use causal_arm_scoring::{EdgeClaims, Verdict};
use causal_arm_truth::{Truth, check_names, score_claims, score_table};
use clap::Args;

use crate::choice::choice;
use crate::progress::Counter;

/// What `causal-arm explain` computes: a SHAP attribution, or an influence measure with
/// its own decision rule.
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
    fn shap(self) -> Option<Method> {
        match self {
            Self::Deep => Some(Method::Deep),
            Self::Kernel => Some(Method::Kernel),
            Self::Cai | Self::Agreement | Self::Holdout => None,
        }
    }
}

/// The explainer node's default of a setting `explain` shares with it (its declaration in
/// launch_scripts/graph.toml), so the command and the node cannot disagree. The method
/// is not shared: the command defaults to the paper's Deep SHAP, the node to Kernel SHAP.
fn explainer_default(param: &str) -> &'static str {
    server_default_text("causal_arm_explainer", param)
}

/// Arguments of `causal-arm explain`.
#[derive(Debug, Args)]
pub struct ExplainArgs {
    /// How to treat damage in the bags read.
    #[command(flatten)]
    pub read: crate::bag_cmd::ReadArgs,
    /// Model directory written by `causal-arm train`.
    #[arg(long)]
    model: PathBuf,
    /// Forward model file stem in the model directory.
    #[arg(long, default_value = explainer_default("forward_model"))]
    name: String,
    /// Bag(s) the observations and the background are drawn from (the paper: the
    /// training data).
    #[arg(long = "bag", required = true)]
    bags: Vec<PathBuf>,
    /// Method: deep (Deep SHAP, the paper's), kernel (Kernel SHAP), cai (causal influence:
    /// spread of the prediction when one action is resampled from its marginal) or
    /// agreement (signed influence reproduced across --model and every --also-model).
    #[arg(long, default_value = "deep", value_parser = choice::<ExplainMethod>())]
    method: ExplainMethod,
    /// Observations to explain (the paper: 200).
    #[arg(long, default_value = explainer_default("samples"))]
    samples: usize,
    /// Background rows (deep, default 100) or k-means centres (kernel, default 50).
    #[arg(long)]
    background: Option<usize>,
    /// How the background is drawn: sample or kmeans (default: sample for deep, kmeans
    /// for kernel).
    #[arg(long, value_parser = choice::<BackgroundKind>())]
    background_kind: Option<BackgroundKind>,
    /// Kernel SHAP coalitions per observation (default 2·M + 2048, shap's "auto"; at least
    /// 2^M − 2 enumerates them all and gives exact Shapley values).
    #[arg(long)]
    kernel_samples: Option<usize>,
    /// Relevance threshold: an action drives a state feature when its mean |SHAP| reaches
    /// this fraction of the feature's standard deviation.
    #[arg(allow_negative_numbers = true, long, default_value = explainer_default("threshold"))]
    threshold: f64,
    /// Action columns: realized or commanded (default: what the model was trained on,
    /// from metrics.json, else realized).
    #[arg(long, value_parser = choice::<ActionSource>())]
    action: Option<ActionSource>,
    /// Seed of the observation/background draws and of Kernel SHAP's sampler.
    #[arg(long, default_value = explainer_default("seed"))]
    seed: u64,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Skip the per-pair PDP files (pdp/<action>__<state>.png/svg); the grid is always drawn.
    #[arg(long)]
    no_pair_plots: bool,
    /// Further forward models trained independently of --model (other seed or fold), for
    /// --method agreement: edges must be reproduced across models.
    #[arg(long = "also-model")]
    also_models: Vec<PathBuf>,
    /// Score the claims against this ground truth (`causal-arm intervene` output) and print
    /// precision, recall, F1, SHD, AUROC and AP per method, context and block.
    #[arg(long)]
    truth: Option<PathBuf>,
    /// Calibrated rule: an edge needs the lower bound of mean effect / model error above this.
    #[arg(allow_negative_numbers = true, long, default_value = explainer_default("kappa"))]
    kappa: f64,
    /// CAI: draws of each action from its marginal per observation.
    #[arg(long, default_value = explainer_default("resamples"))]
    resamples: usize,
    /// With --method cai: attribute a(t) on s(t+1) … s(t+K) through the forward model
    /// chained K steps (1–10) with the recorded actions after a(t); writes multistep.json
    /// and scores every horizon against the truth's matrix at that horizon.
    #[arg(long)]
    horizon: Option<usize>,
    /// Output directory (default: MODEL/explain-<method>).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Dataset cache directory (default: $CAUSAL_ARM_CACHE or ~/.cache/causal-arm).
    #[arg(long)]
    cache: Option<PathBuf>,
}

/// The action source the model was trained with, as `causal-arm train` recorded it.
fn trained_action_source(model_dir: &Path, name: &str) -> Option<String> {
    let text = std::fs::read_to_string(model_dir.join("metrics.json")).ok()?;
    let metrics: serde_json::Value = serde_json::from_str(&text).ok()?;
    metrics["models"][name]["options"]["action"]
        .as_str()
        .map(str::to_owned)
}

/// Settings from the command line, checked.
fn settings(args: &ExplainArgs) -> anyhow::Result<Settings> {
    let method = args
        .method
        .shap()
        .expect("influence methods take another path");
    let mut settings = Settings::for_method(method);
    settings.samples = args.samples;
    if let Some(b) = args.background {
        settings.background = b;
    }
    if let Some(kind) = args.background_kind {
        settings.background_kind = kind;
    }
    settings.kernel_samples = args.kernel_samples;
    settings.seed = args.seed;
    settings.threads = args.threads;
    if !(args.threshold.is_finite() && args.threshold > 0.0) {
        anyhow::bail!(
            "--threshold must be a positive number, got {}",
            args.threshold
        );
    }
    Ok(settings)
}

/// The model, its explainer and the data its observations come from; a `truth` that
/// cannot score this model's claims is refused before any of them are computed.
fn load(args: &ExplainArgs, truth: Option<&Truth>) -> anyhow::Result<(Explainer, Dataset)> {
    let model = load_model(&args.model, &args.name)?;
    let explainer = Explainer::new(model)?;
    if let Some(truth) = truth {
        check_names(
            truth,
            &args.method.to_string(),
            explainer.action_names(),
            explainer.state_names(),
        )?;
    }
    let action = match args.action {
        Some(action) => action,
        None => trained_action_source(&args.model, &args.name)
            .map_or(Ok(ActionSource::Realized), |text| text.parse())
            .map_err(anyhow::Error::msg)?,
    };
    let cache = Cache::new(args.cache.clone().unwrap_or_else(Cache::default_dir));
    let (data, _) = load_bags(
        &args.bags,
        Some(explainer.experiment()),
        action,
        Some(&cache),
    )?;
    Ok((explainer, data))
}

fn influence_settings(args: &ExplainArgs) -> InfluenceSettings {
    InfluenceSettings {
        observations: args.samples,
        resamples: args.resamples,
        kappa: args.kappa,
        seed: args.seed,
        ..InfluenceSettings::default()
    }
}

/// Runs `causal-arm explain`.
pub fn run(args: &ExplainArgs) -> anyhow::Result<()> {
    // A bad truth file is refused before minutes of attribution.
    let truth = args
        .truth
        .as_deref()
        .map(causal_arm_truth::load)
        .transpose()?;
    if let Some(horizon) = args.horizon {
        return run_multistep(args, truth.as_ref(), horizon);
    }
    if args.method.shap().is_none() {
        return run_influence(args, truth.as_ref());
    }
    let settings = settings(args)?;
    let (explainer, data) = load(args, truth.as_ref())?;
    let mut counter = Counter::new(
        settings.samples as u64,
        &format!("{} SHAP", settings.method),
        "observations",
    );
    let explanation =
        explainer.explain_dataset(&data, &settings, &mut |done, _| counter.set(done as u64))?;
    counter.finish();
    let claims = shap_and_cai_claims(args, &explainer, &data, &explanation)?;
    let report = calibrated_relevance(&explanation, args.threshold, &claims)?;
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| args.model.join(format!("explain-{}", settings.method)));
    let written = write_all(&out, &explanation, &report, !args.no_pair_plots)
        .with_context(|| format!("cannot write the explanation into {}", out.display()))?;
    finish_claims(args, &out, &claims, truth.as_ref())?;
    print_relevance(args, &settings, &explanation, &report);
    draw_mental_simulation_if_run(args, &out, &explanation)?;
    list_written(&written, &out);
    Ok(())
}

/// The run in one line, then every state feature's verdict and what drives it: the
/// knowledge extracted, on stdout.
fn print_relevance(
    args: &ExplainArgs,
    settings: &Settings,
    explanation: &Explanation,
    report: &Relevance,
) {
    println!(
        "{} {} SHAP of {}/{}: {} observations × {} background rows in {:.2} s (efficiency error {:.1e})",
        explanation.experiment,
        settings.method,
        args.model.display(),
        args.name,
        explanation.attributions.n_obs,
        explanation.background.rows(),
        explanation.seconds,
        explanation.efficiency_error()
    );
    println!(
        "{:<14} {:<26} {:>9}  {:<20} mean |SHAP| / change std, strongest",
        "state feature",
        format!("verdict ({})", report.decision_method),
        "score",
        "driven by"
    );
    for v in &report.states {
        println!(
            "{:<14} {:<26} {:>9.2}  {:<20} {:>9.2e} {}",
            v.name,
            v.verdict(),
            v.decision_score,
            v.driven_by.first().map(String::as_str).unwrap_or("-"),
            v.score,
            v.strongest_action
        );
    }
    if report.unaffected.is_empty() {
        println!("every state feature is driven by some action");
    } else {
        println!(
            "not affected by any action (removable from the state): {}",
            report.unaffected.join(", ")
        );
    }
}

/// The mental-simulation figure, if `causal-arm rollout` was run on this model, so the
/// explanation directory holds every figure of the paper for it.
fn draw_mental_simulation_if_run(
    args: &ExplainArgs,
    out: &Path,
    explanation: &Explanation,
) -> anyhow::Result<()> {
    let mental = args.model.join("mental_simulation.json");
    if let Ok(text) = std::fs::read_to_string(&mental) {
        let result: causal_arm_models::mental::MentalSimulation = serde_json::from_str(&text)
            .with_context(|| format!("{}: not a mental simulation result", mental.display()))?;
        let stem = out.join("mental_simulation");
        crate::rollout_cmd::draw_mental_simulation(
            &stem,
            &result,
            &explanation.experiment.to_string(),
        )?;
        eprintln!("wrote {}.png and {}.svg", stem.display(), stem.display());
    }
    Ok(())
}

/// The files written, the per-pair PDPs counted rather than listed (there are
/// actions × states of them).
fn list_written(written: &Written, out: &Path) {
    let pairs = written
        .files
        .iter()
        .filter(|p| p.parent().is_some_and(|d| d.ends_with("pdp")))
        .count();
    for f in written
        .files
        .iter()
        .filter(|p| !p.parent().is_some_and(|d| d.ends_with("pdp")))
    {
        eprintln!("wrote {}", f.display());
    }
    if pairs > 0 {
        eprintln!(
            "wrote {pairs} per-pair PDP files into {}",
            out.join("pdp").display()
        );
    }
}

/// The claims of a SHAP run, the default (`<method>+cai+data`) first: one piece of code with the
/// explainer node ([`causal_arm_explain::verdicts::shap_and_cai_claims`]).
fn shap_and_cai_claims(
    args: &ExplainArgs,
    explainer: &Explainer,
    data: &Dataset,
    explanation: &causal_arm_explain::Explanation,
) -> anyhow::Result<Vec<EdgeClaims>> {
    Ok(causal_arm_explain::verdicts::shap_and_cai_claims(
        explainer,
        data,
        explanation,
        args.threshold,
        &influence_settings(args),
    )?)
}

/// A heat map of `claims`' verdicts: 1 drives, 0 does not, and undecided in a colour of its
/// own (0.5), so an honest "don't know" never looks like either answer.
fn draw_verdicts(stem: &Path, claims: &EdgeClaims) -> anyhow::Result<()> {
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
    eprintln!("wrote {}.png and {}.svg", stem.display(), stem.display());
    Ok(())
}

/// `causal-arm explain --method cai|agreement`: influence of every action on the forward
/// model(s), with verdicts by the method's rule.
fn run_influence(args: &ExplainArgs, truth: Option<&Truth>) -> anyhow::Result<()> {
    let (explainer, data) = load(args, truth)?;
    let settings = influence_settings(args);
    let started = std::time::Instant::now();
    let (effects, claims) = if args.method == ExplainMethod::Cai {
        let effects = cai_effects(&explainer, &data, &settings)?;
        let floors = ErrorFloors::measure(&explainer, &data, &settings)?;
        let claims = claims_by_context(
            &explainer,
            &data,
            &effects,
            &settings,
            Rule::ErrorRatio(&floors),
        );
        (effects, claims)
    } else if args.method == ExplainMethod::Holdout {
        let effects = holdout_effects(&explainer, &data, &settings)?;
        let claims = claims_by_context(&explainer, &data, &effects, &settings, Rule::Significance);
        (effects, claims)
    } else {
        let mut others = Vec::new();
        for dir in &args.also_models {
            others.push(Explainer::new(load_model(dir, &args.name)?)?);
        }
        let mut all = vec![&explainer];
        all.extend(others.iter());
        let effects = agreement_effects(&all, &data, &settings)?;
        let claims = claims_by_context(&explainer, &data, &effects, &settings, Rule::Significance);
        (effects, claims)
    };
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| args.model.join(format!("explain-{}", args.method)));
    println!(
        "{} {} influence of {}/{}: {} observations × {} resamples per action in {:.2} s",
        explainer.experiment(),
        args.method,
        args.model.display(),
        args.name,
        effects.rows.len(),
        settings.resamples,
        started.elapsed().as_secs_f64()
    );
    finish_claims(args, &out, &claims, truth)
}

/// Writes `claims.json`, prints what the default claims say and, with `--truth`, scores
/// every claim set against it (`scores.json`).
fn finish_claims(
    args: &ExplainArgs,
    out: &Path,
    claims: &[EdgeClaims],
    truth: Option<&Truth>,
) -> anyhow::Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let path = out.join("claims.json");
    std::fs::write(&path, serde_json::to_string_pretty(claims)?)
        .with_context(|| format!("cannot write {}", path.display()))?;
    eprintln!("wrote {}", path.display());
    // The first claim set of a run is its default.
    if let Some(headline) = claims.iter().find(|c| c.context == "all") {
        for (a, action) in headline.action_names.iter().enumerate() {
            let driven: Vec<&str> = headline
                .state_names
                .iter()
                .enumerate()
                .filter(|&(k, _)| headline.drives[a][k])
                .map(|(_, s)| s.as_str())
                .collect();
            println!(
                "{action:<6} drives ({}) {}",
                headline.method,
                driven.join(", ")
            );
        }
        let (drives, does_not, undecided) = headline.verdict_counts();
        println!(
            "verdicts ({}): {drives} drives, {does_not} does not, {undecided} undecided",
            headline.method
        );
    }
    // The default claims as verdicts_heatmap, every method's all-states claims beside it.
    let all_states = claims
        .iter()
        .filter(|c| c.context == "all" && c.horizon == 1);
    for (i, c) in all_states.enumerate() {
        let file = match i {
            0 => "verdicts_heatmap".to_owned(),
            _ => format!("verdicts_{}", c.method.replace(['/', '+'], "_")),
        };
        draw_verdicts(&out.join(file), c)?;
    }
    let (Some(truth), Some(truth_path)) = (truth, &args.truth) else {
        return Ok(());
    };
    let mut rows = Vec::new();
    for c in claims {
        rows.extend(score_claims(truth, c)?);
    }
    println!(
        "scored against {} ({} states; blocks over all states, contexts over all pairs; every row in scores.json):",
        truth_path.display(),
        truth.one_step().states
    );
    let shown: Vec<_> = rows
        .iter()
        .filter(|r| r.context == "all" || r.block == "all")
        .cloned()
        .collect();
    print!("{}", score_table(&shown));
    let path = out.join("scores.json");
    std::fs::write(&path, serde_json::to_string_pretty(&rows)?)
        .with_context(|| format!("cannot write {}", path.display()))?;
    eprintln!("wrote {}", path.display());
    Ok(())
}

/// `causal-arm explain --method cai --horizon K`: CAI through the forward model chained K
/// steps, verdicts per horizon and context, scored against the truth's matrix at each
/// horizon; a horizon the truth lacks is refused before any chaining.
fn run_multistep(args: &ExplainArgs, truth: Option<&Truth>, horizon: usize) -> anyhow::Result<()> {
    if args.method != ExplainMethod::Cai {
        anyhow::bail!(
            "--horizon attributes through the chained forward model with CAI; use it with --method cai, not {:?}",
            args.method.to_string()
        );
    }
    multistep::check_horizon(horizon)?;
    if let Some(truth) = truth {
        causal_arm_truth::check_horizon(truth, horizon)?;
        for h in 1..horizon {
            causal_arm_truth::check_horizon(truth, h)?;
        }
    }
    let (explainer, data) = load(args, truth)?;
    let settings = influence_settings(args);
    let result = multistep::multistep_cai(&explainer, &data, &settings, horizon)?;
    println!(
        "{} cai through the FM chained {horizon} steps ({}/{}): {} observations × {} resamples per action, {} chainable rows, {:.2} s",
        explainer.experiment(),
        args.model.display(),
        args.name,
        result.observations,
        settings.resamples,
        result.chainable_rows,
        result.seconds
    );
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| args.model.join(format!("explain-cai-h{horizon}")));
    let claims: Vec<EdgeClaims> = result.claims().cloned().collect();
    let rows = match truth {
        Some(truth) => causal_arm_truth::score_horizons(truth, &claims)?,
        None => Vec::new(),
    };
    write_multistep(&out, &result, &rows)?;
    for h in &result.horizons {
        let (drives, does_not, undecided) = h.default.verdict_counts();
        let (data_drives, ..) = h.data.verdict_counts();
        println!(
            "h={:<2} {}: {drives} drives, {does_not} does not, {undecided} undecided (all states); the data test alone claims {data_drives}",
            h.horizon,
            multistep::DEFAULT_METHOD
        );
    }
    if let (Some(truth), Some(path)) = (truth, &args.truth) {
        println!(
            "scored against {} ({} states) per horizon, all states and all pairs (per block and context in multistep.json):",
            path.display(),
            truth.one_step().states
        );
        let shown: Vec<_> = rows
            .iter()
            .filter(|r| r.context == "all" && r.block == "all")
            .cloned()
            .collect();
        print!("{}", score_table(&shown));
    }
    let (action, state) = multistep::MAGNET_PAIR;
    if let Some(line) = result.pair_line(action, state) {
        println!("{line}");
    }
    Ok(())
}

/// Writes `multistep.json` (per horizon: effects, error floors, verdicts and, with a truth,
/// their scores) and the figures into `out`.
fn write_multistep(
    out: &Path,
    result: &multistep::MultiStep,
    rows: &[causal_arm_truth::ScoreRow],
) -> anyhow::Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let mut json = serde_json::to_value(result)?;
    if let Some(horizons) = json["horizons"].as_array_mut() {
        for h in horizons {
            let k = h["horizon"].as_u64().unwrap_or(0) as usize;
            let scores: Vec<_> = rows.iter().filter(|r| r.horizon == k).collect();
            h["scores"] = serde_json::to_value(scores)?;
        }
    }
    let path = out.join("multistep.json");
    std::fs::write(&path, serde_json::to_string_pretty(&json)?)
        .with_context(|| format!("cannot write {}", path.display()))?;
    eprintln!("wrote {}", path.display());
    for png in multistep::draw_figures(result, out)? {
        eprintln!("wrote {} and .svg", png.display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use causal_arm_explain::report::DEFAULT_THRESHOLD;
    use clap::Parser;

    #[derive(Debug, Parser)]
    struct Cli {
        #[command(flatten)]
        args: ExplainArgs,
    }

    #[test]
    fn shared_defaults_are_the_explainer_nodes_and_the_librarys() {
        let cli = Cli::parse_from(["explain", "--model", "m", "--bag", "b"]);
        let a = cli.args;
        let influence = InfluenceSettings::default();
        assert_eq!(a.name, "fm");
        assert_eq!(a.samples, 200);
        assert_eq!(a.threshold, DEFAULT_THRESHOLD);
        assert_eq!(a.kappa, influence.kappa);
        assert_eq!(a.resamples, influence.resamples);
        assert_eq!(a.seed, 0);
        for param in [
            "forward_model",
            "samples",
            "threshold",
            "kappa",
            "resamples",
            "seed",
        ] {
            assert!(!explainer_default(param).is_empty(), "{param}");
        }
    }
}
