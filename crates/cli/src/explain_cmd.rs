//! `causal-arm explain`: SHAP attributions of a trained forward model on transitions from
//! bags, with the heat map, partial dependence plots and relevance report.

use std::path::{Path, PathBuf};

use anyhow::Context;
use causal_arm_dataset::{ActionSource, Cache, load_bags};
use causal_arm_explainer::output::write_all;
use causal_arm_explainer::report::DEFAULT_THRESHOLD;
use causal_arm_explainer::{BackgroundKind, Explainer, Method, Settings, relevance};
use causal_arm_trainer::load_model;
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};

/// Arguments of `causal-arm explain`.
#[derive(Debug, Args)]
pub struct ExplainArgs {
    /// Model directory written by `causal-arm train`.
    #[arg(long)]
    model: PathBuf,
    /// Forward model file stem in the model directory.
    #[arg(long, default_value = "fm")]
    name: String,
    /// Bag(s) the observations and the background are drawn from (the paper: the
    /// training data).
    #[arg(long = "bag", required = true)]
    bags: Vec<PathBuf>,
    /// Attribution method: deep (Deep SHAP, the paper's) or kernel (Kernel SHAP).
    #[arg(long, default_value = "deep")]
    method: String,
    /// Observations to explain (the paper: 200).
    #[arg(long, default_value_t = 200)]
    samples: usize,
    /// Background rows (deep, default 100) or k-means centres (kernel, default 50).
    #[arg(long)]
    background: Option<usize>,
    /// How the background is drawn: sample or kmeans (default: sample for deep, kmeans
    /// for kernel).
    #[arg(long)]
    background_kind: Option<String>,
    /// Kernel SHAP coalitions per observation (default 2·M + 2048, shap's "auto"; at least
    /// 2^M − 2 enumerates them all and gives exact Shapley values).
    #[arg(long)]
    kernel_samples: Option<usize>,
    /// Relevance threshold: an action drives a state feature when its mean |SHAP| reaches
    /// this fraction of the feature's standard deviation.
    #[arg(long, default_value_t = DEFAULT_THRESHOLD)]
    threshold: f64,
    /// Action columns: realized or commanded (default: what the model was trained on,
    /// from metrics.json, else realized).
    #[arg(long)]
    action: Option<String>,
    /// Seed of the observation/background draws and of Kernel SHAP's sampler.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Skip the per-pair PDP files (pdp/<action>__<state>.png/svg); the grid is always drawn.
    #[arg(long)]
    no_pair_plots: bool,
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
    let method: Method = args.method.parse().map_err(anyhow::Error::msg)?;
    let mut settings = Settings::for_method(method);
    settings.samples = args.samples;
    if let Some(b) = args.background {
        settings.background = b;
    }
    if let Some(kind) = &args.background_kind {
        settings.background_kind = kind.parse::<BackgroundKind>().map_err(anyhow::Error::msg)?;
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

/// Runs `causal-arm explain`.
pub fn run(args: &ExplainArgs) -> anyhow::Result<()> {
    let settings = settings(args)?;
    let model = load_model(&args.model, &args.name)?;
    let explainer = Explainer::new(model)?;
    let action_text = args
        .action
        .clone()
        .or_else(|| trained_action_source(&args.model, &args.name))
        .unwrap_or_else(|| "realized".into());
    let action: ActionSource = action_text.parse().map_err(anyhow::Error::msg)?;
    let cache = Cache::new(args.cache.clone().unwrap_or_else(Cache::default_dir));
    let (data, _) = load_bags(
        &args.bags,
        Some(explainer.experiment()),
        action,
        Some(&cache),
    )?;
    let bar = ProgressBar::new(settings.samples as u64);
    bar.set_style(
        ProgressStyle::with_template(
            "{msg} [{bar:30}] {pos}/{len} observations, {per_sec}, ETA {eta}",
        )
        .expect("a valid template")
        .progress_chars("=> "),
    );
    bar.set_message(format!("{} SHAP", settings.method));
    let explanation = explainer.explain_dataset(&data, &settings, &mut |done, _| {
        bar.set_position(done as u64)
    })?;
    bar.finish_and_clear();
    let report = relevance(&explanation, args.threshold);
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| args.model.join(format!("explain-{}", settings.method)));
    let written = write_all(&out, &explanation, &report, !args.no_pair_plots)
        .with_context(|| format!("cannot write the explanation into {}", out.display()))?;

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
    println!("state feature  verdict                      score  strongest action");
    for v in &report.states {
        println!(
            "{:<14} {:<26} {:>9.2e}  {}",
            v.name,
            v.verdict(),
            v.score,
            v.strongest_action
        );
    }
    for a in &report.actions {
        println!("{:<6} drives {}", a.name, a.drives.join(", "));
    }
    if report.unaffected.is_empty() {
        println!("every state feature is driven by some action");
    } else {
        println!(
            "not affected by any action (removable from the state): {}",
            report.unaffected.join(", ")
        );
    }
    // The mental-simulation figure, if `causal-arm rollout` was run on this model.
    let mental = args.model.join("mental_simulation.json");
    if let Ok(text) = std::fs::read_to_string(&mental) {
        let result: causal_arm_trainer::mental::MentalSimulation = serde_json::from_str(&text)
            .with_context(|| format!("{}: not a mental simulation result", mental.display()))?;
        let stem = out.join("mental_simulation");
        crate::rollout_cmd::draw_mental_simulation(
            &stem,
            &result,
            &explanation.experiment.to_string(),
        )?;
        eprintln!("wrote {}.png and {}.svg", stem.display(), stem.display());
    }
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
    Ok(())
}
