//! `causal-arm train`: cross-validate the paper's models on bags and write model files.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::bail;
use causal_arm_dataset::{ActionSource, Cache, CacheOutcome, Dataset, Experiment, load_bags};
use causal_arm_models::fit::{Progress, ProgressLog};
use causal_arm_models::job::{SavedRun, train_and_save};
use causal_arm_models::problems::FmTarget;
use causal_arm_models::structure::{Auxiliary, FoundGraph};
use causal_arm_models::{Figure, LrSchedule, ModelKind, ModelRequest, Profile, TrainOptions};
// The trainer node's defaults of the settings `train` shares with it (their declarations
// in launch_scripts/graph.toml), so the command and the node cannot disagree.
use causal_arm_params::trainer;
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};

use crate::choice::choice;
use crate::progress::PLAIN_EVERY;

/// Arguments of `causal-arm train`.
#[derive(Debug, Args)]
pub struct TrainArgs {
    /// How to treat damage in the bags read.
    #[command(flatten)]
    pub read: crate::bag_cmd::ReadArgs,
    /// Bag directory (repeat for several bags of one experiment).
    #[arg(long = "bag", required = true)]
    bags: Vec<PathBuf>,
    /// fm, im-mono, im-pre, ablation, fm-factored (needs --graph), or all (every model of
    /// the bag's experiment).
    #[arg(long, default_value = trainer::models::default_text(), value_parser = choice::<ModelRequest>())]
    model: ModelRequest,
    /// Epoch budgets: paper (60-4,000 epochs) or quick.
    #[arg(long, default_value = trainer::profile::default_text(), value_parser = choice::<Profile>())]
    profile: Profile,
    /// Epochs of every network (overrides the profile).
    #[arg(long)]
    epochs: Option<usize>,
    /// Cross-validation folds.
    #[arg(long, default_value = trainer::folds::default_text())]
    folds: usize,
    /// Run only the first N folds (each still holds out 1/folds of the rows).
    #[arg(long)]
    max_folds: Option<usize>,
    /// Refuse bags that are not this experiment (default: whatever the first bag holds).
    #[arg(long, value_parser = choice::<Experiment>())]
    experiment: Option<Experiment>,
    /// Action vector: realized (θ(t+1) − θ(t), the paper's) or commanded deltas (default:
    /// realized on the kinematic arm's bags, commanded on the dynamic arm's).
    #[arg(long, value_parser = choice::<ActionSource>())]
    action: Option<ActionSource>,
    /// Forward-model output: delta (s(t+1) − s(t), added back) or absolute.
    #[arg(long, default_value = "delta", value_parser = choice::<FmTarget>())]
    fm_target: FmTarget,
    /// FM hidden layer widths.
    #[arg(long, value_delimiter = ',', default_value = "256,256,256")]
    fm_hidden: Vec<usize>,
    /// IM / base IM / pre-network hidden layer widths.
    #[arg(long, value_delimiter = ',', default_value = "256,256,256,256")]
    im_hidden: Vec<usize>,
    /// Rows per mini-batch.
    #[arg(long, default_value_t = 256)]
    batch_size: usize,
    /// Learning rate.
    #[arg(allow_negative_numbers = true, long, default_value_t = 1e-3)]
    lr: f64,
    /// Learning-rate schedule: constant (the paper's), cosine (decay to 1 % over the
    /// epochs) or cosine:FLOOR. Cosine wins on paper-size runs, constant on short ones
    /// (docs/RESULTS.md, "Learning-rate schedule").
    #[arg(long, default_value = trainer::lr_schedule::default_text())]
    lr_schedule: String,
    /// Measure the held-out MAE every N epochs: a learning curve per network, printed and
    /// stored in metrics.json (costs one pass over the fold's test rows each time).
    #[arg(long)]
    eval_every: Option<usize>,
    /// Seed of folds, weights and shuffles.
    #[arg(long, default_value = trainer::seed::default_text())]
    seed: u64,
    /// Dataset cache directory (default: $CAUSAL_ARM_CACHE or ~/.cache/causal-arm).
    #[arg(long)]
    cache: Option<PathBuf>,
    /// Decode the bags even if a cached dataset exists, and do not cache.
    #[arg(long)]
    no_cache: bool,
    /// Causal graph found by `causal-arm explain` (its claims.json; the default claims are
    /// used): the state features no action drives are left out of the FM and IM, and
    /// fm-factored gives each FM head only the actions that drive it.
    #[arg(long)]
    graph: Option<PathBuf>,
    /// Hidden layer widths of each head network of fm-factored.
    #[arg(long, value_delimiter = ',', default_value = "128,128,128")]
    factored_hidden: Vec<usize>,
    /// Which other outputs each fm-factored network learns beside its head (only the
    /// head's own error is reported): none; upstream, the features driven by a strict
    /// subset of the actions of one of the head's features (θ(t+1) for ef(t+1));
    /// determined, every feature driven only by the head's actions; auto, per head the one
    /// that predicts it best on the last twentieth of the training rows.
    #[arg(long, default_value = "auto", value_parser = choice::<Auxiliary>())]
    factored_auxiliary: Auxiliary,
    /// Output directory for model files and metrics.json.
    #[arg(long)]
    out: PathBuf,
}

fn bar_for(label: &str, epochs: usize, rows: usize) -> ProgressBar {
    let bar = ProgressBar::new((epochs * rows) as u64);
    bar.set_style(
        ProgressStyle::with_template("{prefix:>22} [{bar:25}] {msg} {per_sec} ETA {eta}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    bar.set_prefix(label.to_owned());
    bar.set_message(format!("epoch 0/{epochs}"));
    bar
}

/// Formats an MAE with its unit.
pub fn show(value: f64, unit: &str) -> String {
    let number = if value != 0.0 && (value.abs() < 1e-2 || value.abs() >= 1e3) {
        format!("{value:.3e}")
    } else {
        format!("{value:.4}")
    };
    if unit.is_empty() {
        number
    } else {
        format!("{number} {unit}")
    }
}

/// Prints the figures as a table next to the paper and the baseline.
pub fn print_table(figures: &[Figure]) {
    println!(
        "{:<20} {:>26} {:>16} {:>14} {:>8}",
        "figure", "ours (mean ± std)", "mean baseline", "paper", "≤ paper"
    );
    for f in figures {
        let ours = format!("{} ± {}", show(f.mean, &f.unit), show(f.std, ""));
        let paper = f
            .paper
            .map(|p| show(p, &f.unit))
            .unwrap_or_else(|| "—".into());
        let verdict = match f.paper {
            Some(p) if f.mean <= p => "yes",
            Some(_) => "no",
            None => "",
        };
        println!(
            "{:<20} {:>26} {:>16} {:>14} {:>8}",
            f.key,
            ours,
            show(f.baseline, &f.unit),
            paper,
            verdict
        );
    }
}

/// Runs `causal-arm train`.
pub fn run(args: &TrainArgs) -> anyhow::Result<()> {
    let CheckedArgs {
        mut options,
        action,
        expected,
        requested,
    } = checked_options(args)?;
    let start = Instant::now();
    let data = load_dataset(args, expected, action, start)?;
    if let Some(path) = &args.graph {
        let graph = FoundGraph::load(path, data.experiment)?;
        eprintln!(
            "graph: {}; left out as driven by no action: {:?}",
            graph.source,
            graph.unaffected()
        );
        options.graph = Some(graph);
    } else if requested == Some(ModelKind::FmFactored) {
        bail!(
            "--model fm-factored needs --graph CLAIMS_JSON (the claims.json of `causal-arm explain`)"
        );
    }
    let kinds = args.model.kinds(data.experiment);

    let mut progress = TrainingProgress::new();
    let saved = train_and_save(&data, &kinds, &options, action, &args.out, &mut |p| {
        progress.show(p)
    })?;
    progress.finish();
    print_results(&data, &options, &saved);
    eprintln!(
        "wrote {} ({:.1} s in all)",
        saved.metrics.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

/// The command line parsed and checked, so a typo is refused before the bags are read.
struct CheckedArgs {
    options: TrainOptions,
    action: ActionSource,
    /// The experiment the bags must hold, if given.
    expected: Option<Experiment>,
    /// One model kind, or `None` for every model of the experiment.
    requested: Option<ModelKind>,
}

/// Parses and checks every option of `args` (all but the graph, which needs the data's
/// experiment) into the trainer's options.
fn checked_options(args: &TrainArgs) -> anyhow::Result<CheckedArgs> {
    let (profile, fm_target) = (args.profile, args.fm_target);
    let action = ActionSource::given_or_of_bags(args.action, &args.bags)?;
    let lr_schedule: LrSchedule = args.lr_schedule.parse().map_err(anyhow::Error::msg)?;
    let expected = args.experiment;
    let requested = args.model.one();
    if args.max_folds == Some(0) {
        bail!("--max-folds must be at least 1 (leave it out to run every fold)");
    }
    if args.eval_every == Some(0) {
        bail!("--eval-every must be at least 1");
    }
    if args.fm_hidden.is_empty()
        || args.im_hidden.is_empty()
        || args.fm_hidden.contains(&0)
        || args.im_hidden.contains(&0)
        || args.factored_hidden.is_empty()
        || args.factored_hidden.contains(&0)
    {
        bail!("hidden layer widths must be positive, e.g. --fm-hidden 256,256,256");
    }
    let options = TrainOptions {
        profile,
        epochs: args.epochs,
        folds: args.folds,
        fm_hidden: args.fm_hidden.clone(),
        im_hidden: args.im_hidden.clone(),
        batch_size: args.batch_size,
        learning_rate: args.lr,
        lr_schedule,
        fm_target,
        seed: args.seed,
        max_folds: args.max_folds,
        stop: None,
        eval_every: args.eval_every,
        graph: None,
        factored_hidden: args.factored_hidden.clone(),
        factored_auxiliary: args.factored_auxiliary,
    };
    Ok(CheckedArgs {
        options,
        action,
        expected,
        requested,
    })
}

/// The bags' transitions (through the cache unless `--no-cache`), saying where each bag
/// came from and what the data holds, since decoding can take minutes.
fn load_dataset(
    args: &TrainArgs,
    expected: Option<Experiment>,
    action: ActionSource,
    start: Instant,
) -> anyhow::Result<Dataset> {
    let cache =
        (!args.no_cache).then(|| Cache::new(args.cache.clone().unwrap_or_else(Cache::default_dir)));
    let (data, outcomes) = load_bags(&args.bags, expected, action, cache.as_ref())?;
    for (bag, outcome) in &outcomes {
        let how = match outcome {
            CacheOutcome::Hit => "from cache",
            CacheOutcome::Built => "decoded",
        };
        eprintln!("dataset: {} ({how})", bag.display());
    }
    eprintln!(
        "dataset: {} {} transitions, s {} features, a {} features, {:.1} s",
        data.rows(),
        data.experiment,
        data.state_width(),
        data.action_width(),
        start.elapsed().as_secs_f64()
    );
    Ok(data)
}

/// Training progress on stderr: a bar per network on a terminal, plain lines at most
/// [`PLAIN_EVERY`] apart elsewhere (a bar cannot draw into a pipe or a log file).
struct TrainingProgress {
    bar: Option<ProgressBar>,
    epochs_planned: usize,
    plain_log: Option<ProgressLog>,
}

impl TrainingProgress {
    /// Bars or plain lines, chosen by whether stderr is a terminal.
    fn new() -> Self {
        Self {
            bar: None,
            epochs_planned: 0,
            plain_log: (!std::io::stderr().is_terminal()).then(|| ProgressLog::new(PLAIN_EVERY)),
        }
    }

    /// Shows one progress event of the trainer.
    fn show(&mut self, p: Progress) {
        if let Some(log) = &mut self.plain_log {
            if let Some(line) = log.line(&p) {
                eprintln!("{line}");
            }
            return;
        }
        match p {
            Progress::Start {
                label,
                epochs,
                rows,
            } => {
                if let Some(b) = self.bar.take() {
                    b.finish_and_clear();
                }
                self.epochs_planned = epochs;
                self.bar = Some(bar_for(&label, epochs, rows));
            }
            Progress::Rows(n) => {
                if let Some(b) = &self.bar {
                    b.inc(n as u64);
                }
            }
            Progress::Epoch { epoch, loss } => {
                if let Some(b) = &self.bar {
                    b.set_message(format!(
                        "epoch {epoch}/{} loss {loss:.4}",
                        self.epochs_planned
                    ));
                }
            }
        }
    }

    /// Clears the last bar so the results print on a clean line.
    fn finish(&mut self) {
        if let Some(b) = self.bar.take() {
            b.finish_and_clear();
        }
    }
}

/// What was written and how long each network took (stderr), then the figures next to
/// the paper's (stdout, the result a script keeps).
fn print_results(data: &Dataset, options: &TrainOptions, saved: &SavedRun) {
    for pair in saved.written.chunks(2) {
        let names: Vec<_> = pair.iter().map(|p| p.display().to_string()).collect();
        eprintln!("wrote {}", names.join(" and "));
    }
    for run in &saved.runs {
        let selection = match run.selection {
            Some(s) => format!(
                ", validation MAE {:.4e}{}{}",
                s.validation_mae,
                if s.chosen { " (kept)" } else { "" },
                match s.against_full_fm {
                    Some(c) => format!(
                        "; full FM {:.4e}, difference {:+.3e} ± {:.3e} (2 SE){}",
                        c.full_fm_validation_mae,
                        c.difference,
                        2.0 * c.standard_error,
                        if c.candidate_better {
                            ""
                        } else {
                            ": the full FM's head is kept"
                        }
                    ),
                    None => String::new(),
                }
            ),
            None => String::new(),
        };
        eprintln!(
            "  {}: {} epochs on {} rows in {:.1} s{selection}",
            run.label, run.epochs, run.rows, run.wall_s
        );
        for point in &run.curve {
            let maes: Vec<String> = point.mae.iter().map(|m| format!("{m:.4e}")).collect();
            eprintln!(
                "    epoch {:>5} {:>8.1} s  held-out MAE {}",
                point.epoch,
                point.wall_s,
                maes.join(" ")
            );
        }
    }
    println!(
        "{} on {} transitions ({} folds):",
        data.experiment,
        data.rows(),
        options.folds
    );
    print_table(&saved.figures);
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Debug, Parser)]
    struct Cli {
        #[command(flatten)]
        args: TrainArgs,
    }

    #[test]
    fn shared_defaults_are_the_trainer_nodes_and_the_librarys() {
        let cli = Cli::parse_from(["train", "--bag", "b", "--out", "o"]);
        let a = cli.args;
        let library = TrainOptions::default();
        assert_eq!(a.model, ModelRequest::All);
        assert_eq!(a.profile, library.profile);
        assert_eq!(a.folds, library.folds);
        assert_eq!(a.seed, library.seed);
        assert_eq!(
            a.lr_schedule.parse::<LrSchedule>().unwrap(),
            library.lr_schedule
        );
    }
}
