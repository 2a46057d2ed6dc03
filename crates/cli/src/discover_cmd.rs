//! `causal-arm discover`: which action drives which state feature, straight from the bag's
//! transitions (no model): the product's three-valued data test beside the standard linear
//! Granger anchors, scored against a ground truth when one is given.

use std::path::{Path, PathBuf};

use anyhow::Context;
use causal_arm_dataset::{ActionSource, Cache, load_bags};
use causal_arm_discovery::{Changes, DataTest, GrangerSettings, Terms};
use causal_arm_scoring::EdgeClaims;
use causal_arm_truth::{check_names, score_claims, score_table};
use clap::Args;

use crate::choice::choice;

/// Arguments of `causal-arm discover`.
#[derive(Debug, Args)]
pub struct DiscoverArgs {
    /// How to treat damage in the bags read.
    #[command(flatten)]
    pub read: crate::bag_cmd::ReadArgs,
    /// Bag(s) or shard sets of one experiment.
    #[arg(long = "bag", required = true)]
    bags: Vec<PathBuf>,
    /// Action columns: realized or commanded (default: realized on the kinematic arm's
    /// bags, commanded on the dynamic arm's, from the bag's custom_data).
    #[arg(long, value_parser = choice::<ActionSource>())]
    action: Option<ActionSource>,
    /// Family-wise error rate of the data test over all action × state pairs.
    #[arg(allow_negative_numbers = true, long, default_value_t = GrangerSettings::data_test().alpha)]
    alpha: f64,
    /// Transitions the tests use at most (a seeded draw beyond that).
    #[arg(long, default_value_t = GrangerSettings::data_test().max_rows)]
    max_rows: usize,
    /// Seed of that draw.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Score every claim set against this ground truth (`causal-arm intervene` output).
    #[arg(long)]
    truth: Option<PathBuf>,
    /// Also write the transitions (safetensors: states, actions, next_states, episodes, …)
    /// for tools outside the project, e.g. tests/bench/causal_anchors.py.
    #[arg(long)]
    export: Option<PathBuf>,
    /// Output directory for claims.json (and scores.json with --truth).
    #[arg(long)]
    out: PathBuf,
    /// Dataset cache directory (default: $CAUSAL_ARM_CACHE or ~/.cache/causal-arm).
    #[arg(long)]
    cache: Option<PathBuf>,
}

/// Runs `causal-arm discover`.
pub fn run(args: &DiscoverArgs) -> anyhow::Result<()> {
    let truth = args
        .truth
        .as_deref()
        .map(causal_arm_truth::load)
        .transpose()?;
    let cache = Cache::new(args.cache.clone().unwrap_or_else(Cache::default_dir));
    let action = ActionSource::given_or_of_bags(args.action, &args.bags)?;
    let (data, _) = load_bags(&args.bags, None, action, Some(&cache))?;
    println!("{}", data.design_summary());
    if let Some(truth) = &truth {
        let names = causal_arm_dataset::action_names(data.experiment);
        check_names(
            truth,
            "data",
            &names,
            &causal_arm_dataset::state_names(data.experiment),
        )?;
    }
    if let Some(path) = &args.export {
        causal_arm_dataset::write_safetensors(&data, path)?;
        eprintln!("wrote {} ({} transitions)", path.display(), data.rows());
    }
    let settings = GrangerSettings {
        alpha: args.alpha,
        max_rows: args.max_rows,
        seed: args.seed,
        ..GrangerSettings::data_test()
    };
    // One draw of the transitions serves the data test and both anchors.
    let all: Vec<usize> = (0..data.rows()).collect();
    let changes = Changes::draw(&data, &all, args.max_rows, args.seed);
    let test = DataTest::on(&changes, &data, &settings)?;
    let mut claims = vec![test.claims("data")];
    for (terms, name) in [
        (Terms::Linear, "granger"),
        (Terms::Interaction, "granger-x"),
    ] {
        let anchor = GrangerSettings {
            max_rows: args.max_rows,
            seed: args.seed,
            ..GrangerSettings::anchor(terms)
        };
        claims.push(DataTest::on(&changes, &data, &anchor)?.anchor_claims(name));
    }
    print_verdicts(&claims[0], &test);
    write_json(&args.out, "claims.json", &claims)?;
    if let Some(truth) = &truth {
        let mut rows = Vec::new();
        for c in &claims {
            rows.extend(score_claims(truth, c)?);
        }
        print!("{}", score_table(&rows));
        write_json(&args.out, "scores.json", &rows)?;
    }
    Ok(())
}

/// Arguments of `causal-arm score`.
#[derive(Debug, Args)]
pub struct ScoreArgs {
    /// Claim sets (a JSON list of claims, as `explain`, `discover` and
    /// tests/bench/causal_anchors.py write them).
    #[arg(long = "claims", required = true)]
    claims: Vec<PathBuf>,
    /// Ground truth directory or truth.json (`causal-arm intervene` output).
    #[arg(long)]
    truth: PathBuf,
    /// Write every score row here as JSON.
    #[arg(long)]
    out: Option<PathBuf>,
}

/// Runs `causal-arm score`: claims made anywhere, scored by the project's scorer.
pub fn score(args: &ScoreArgs) -> anyhow::Result<()> {
    let truth = causal_arm_truth::load(&args.truth)?;
    let mut rows = Vec::new();
    for path in &args.claims {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read claims {}", path.display()))?;
        let claims: Vec<EdgeClaims> = serde_json::from_str(&text)
            .with_context(|| format!("{}: not a JSON list of claim sets", path.display()))?;
        for c in &claims {
            rows.extend(
                score_claims(&truth, c)
                    .with_context(|| format!("{}: {}", path.display(), c.method))?,
            );
        }
    }
    print!("{}", score_table(&rows));
    if let Some(out) = &args.out {
        let dir = out
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        atomic_write(out, serde_json::to_string_pretty(&rows)?.as_bytes())?;
        eprintln!("wrote {}", out.display());
    }
    Ok(())
}

/// Per action the features it drives, then the verdict counts: what a user reads first.
pub(crate) fn print_verdicts(claims: &EdgeClaims, test: &DataTest) {
    println!(
        "{} data test on {} of {} transitions in {:.2} s ({})",
        claims.method, test.rows, test.data_rows, test.seconds, claims.rule
    );
    print!("{}", claims.summary());
}

fn write_json(dir: &Path, name: &str, value: &impl serde::Serialize) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let path = dir.join(name);
    let text = serde_json::to_string_pretty(value)?;
    atomic_write(&path, text.as_bytes())?;
    eprintln!("wrote {}", path.display());
    Ok(())
}

/// Writes a whole file or none (temporary sibling, fsync, rename).
fn atomic_write(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    use std::io::Write;
    let mut file = atomic_write_file::AtomicWriteFile::open(path)
        .with_context(|| format!("cannot write {}", path.display()))?;
    file.write_all(bytes)
        .and_then(|()| file.commit())
        .with_context(|| format!("cannot write {}", path.display()))
}
