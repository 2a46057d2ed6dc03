//! `causal-arm explain`: SHAP attributions of a trained forward model on transitions from
//! bags, with the heat map, partial dependence plots and relevance report.

use std::path::PathBuf;

use causal_arm_dataset::ActionSource;
use causal_arm_explain::job::{ExplainMethod, ExplainRequest, Outcome, ShapOutcome};
use causal_arm_explain::{BackgroundKind, multistep};
// The explainer node's defaults of the settings `explain` shares with it (their
// declarations in launch_scripts/graph.toml), so the command and the node cannot disagree.
// The method is not shared: the command defaults to the paper's Deep SHAP, the node to
// Kernel SHAP.
use causal_arm_params::explainer;
use causal_arm_truth::score_table;
use clap::Args;

use crate::choice::choice;
use crate::progress::Counter;

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
    #[arg(long, default_value = explainer::forward_model::default_text())]
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
    #[arg(long, default_value = explainer::samples::default_text())]
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
    #[arg(allow_negative_numbers = true, long, default_value = explainer::threshold::default_text())]
    threshold: f64,
    /// Action columns: realized or commanded (default: what the model was trained on,
    /// from metrics.json, else realized).
    #[arg(long, value_parser = choice::<ActionSource>())]
    action: Option<ActionSource>,
    /// Seed of the observation/background draws and of Kernel SHAP's sampler.
    #[arg(long, default_value = explainer::seed::default_text())]
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
    /// (Checked as the explainer node checks its `kappa`, with the same words.)
    #[arg(allow_negative_numbers = true, long, default_value = explainer::kappa::default_text(),
          value_parser = explainer::kappa::parse)]
    kappa: f64,
    /// CAI: draws of each action from its marginal per observation.
    #[arg(long, default_value = explainer::resamples::default_text())]
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

impl ExplainArgs {
    /// The job these arguments ask for.
    fn request(&self) -> ExplainRequest {
        ExplainRequest {
            model: self.model.clone(),
            name: self.name.clone(),
            bags: self.bags.clone(),
            method: self.method,
            samples: self.samples,
            background: self.background,
            background_kind: self.background_kind,
            kernel_samples: self.kernel_samples,
            threshold: self.threshold,
            action: self.action,
            seed: self.seed,
            threads: self.threads,
            pair_plots: !self.no_pair_plots,
            also_models: self.also_models.clone(),
            truth: self.truth.clone(),
            kappa: self.kappa,
            resamples: self.resamples,
            horizon: self.horizon,
            out: None,
            cache: self.cache.clone(),
        }
    }
}

/// Runs `causal-arm explain`: the library's one explain job, then what it found on stdout.
pub fn run(args: &ExplainArgs) -> anyhow::Result<()> {
    let mut request = args.request();
    request.out = Some(args.out.clone().unwrap_or_else(|| request.default_out()));
    let mut counter: Option<Counter> = None;
    let outcome = causal_arm_explain::run(&request, &mut |done, total| {
        counter
            .get_or_insert_with(|| Counter::new(total as u64, "SHAP", "observations"))
            .set(done as u64)
    })?;
    if let Some(counter) = counter {
        counter.finish();
    }
    print_outcome(&request, &outcome);
    list_written(&outcome.written);
    Ok(())
}

/// What the job found: the run in one line, the verdicts, and the scores with a truth.
fn print_outcome(request: &ExplainRequest, outcome: &Outcome) {
    if let Some(shap) = &outcome.shap {
        print_relevance(request, shap);
    }
    if let Some(influence) = &outcome.influence {
        println!(
            "{} {} influence of {}/{}: {} observations × {} resamples per action in {:.2} s",
            outcome.explainer.experiment(),
            request.method,
            request.model.display(),
            request.name,
            influence.observations,
            request.resamples,
            influence.seconds
        );
    }
    match &outcome.multistep {
        Some(result) => print_multistep(request, outcome, result),
        None => print_claims(request, outcome),
    }
}

/// Every state feature's verdict and what drives it: the knowledge extracted.
fn print_relevance(request: &ExplainRequest, shap: &ShapOutcome) {
    let (explanation, report) = (&shap.explanation, &shap.report);
    println!(
        "{} {} SHAP of {}/{}: {} observations × {} background rows in {:.2} s (efficiency error {:.1e})",
        explanation.experiment,
        shap.settings.method,
        request.model.display(),
        request.name,
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

/// The default claims (the first of context `all`), their verdict counts and, with a
/// truth, every claim set's scores over all states or all pairs.
fn print_claims(request: &ExplainRequest, outcome: &Outcome) {
    if let Some(headline) = outcome.claims.iter().find(|c| c.context == "all") {
        print!("{}", headline.summary());
    }
    if let Some(truth) = &request.truth {
        println!(
            "scored against {} (blocks over all states, contexts over all pairs; every row in scores.json):",
            truth.display()
        );
        let shown: Vec<_> = (outcome.scores.iter())
            .filter(|r| r.context == "all" || r.block == "all")
            .cloned()
            .collect();
        print!("{}", score_table(&shown));
    }
}

/// Per horizon the verdict counts, the scores with a truth, and the magnet pair's line.
fn print_multistep(request: &ExplainRequest, outcome: &Outcome, result: &multistep::MultiStep) {
    println!(
        "{} cai through the FM chained {} steps ({}/{}): {} observations × {} resamples per action, {} chainable rows, {:.2} s",
        outcome.explainer.experiment(),
        result.horizon,
        request.model.display(),
        request.name,
        result.observations,
        request.resamples,
        result.chainable_rows,
        result.seconds
    );
    for h in &result.horizons {
        let (drives, does_not, undecided) = h.default.verdict_counts();
        let (data_drives, ..) = h.data.verdict_counts();
        println!(
            "h={:<2} {}: {drives} drives, {does_not} does not, {undecided} undecided (all states); the data test alone claims {data_drives}",
            h.horizon,
            multistep::DEFAULT_METHOD
        );
    }
    if let Some(truth) = &request.truth {
        println!(
            "scored against {} per horizon, all states and all pairs (per block and context in multistep.json):",
            truth.display()
        );
        let shown: Vec<_> = (outcome.scores.iter())
            .filter(|r| r.context == "all" && r.block == "all")
            .cloned()
            .collect();
        print!("{}", score_table(&shown));
    }
    let (action, state) = multistep::MAGNET_PAIR;
    if let Some(line) = result.pair_line(action, state) {
        println!("{line}");
    }
}

/// The files written, the per-pair PDPs counted rather than listed (there are
/// actions × states of them).
fn list_written(written: &[PathBuf]) {
    let in_pdp = |p: &&PathBuf| p.parent().is_some_and(|d| d.ends_with("pdp"));
    for f in written.iter().filter(|p| !in_pdp(p)) {
        eprintln!("wrote {}", f.display());
    }
    let pairs: Vec<&PathBuf> = written.iter().filter(in_pdp).collect();
    if let Some(first) = pairs.first() {
        eprintln!(
            "wrote {} per-pair PDP files into {}",
            pairs.len(),
            first.parent().unwrap_or(first).display()
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use causal_arm_explain::influence::InfluenceSettings;
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
        for text in [
            explainer::forward_model::default_text(),
            explainer::samples::default_text(),
            explainer::threshold::default_text(),
            explainer::kappa::default_text(),
            explainer::resamples::default_text(),
            explainer::seed::default_text(),
        ] {
            assert!(!text.is_empty());
        }
    }
}
