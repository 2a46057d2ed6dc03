//! `causal-arm rollout`: mental simulation of a trained forward model on fresh trajectories.

use std::path::PathBuf;

use anyhow::Context;
use causal_arm_dataset::{ActionSource, Cache, load_bags};
use causal_arm_models::load_model;
use causal_arm_models::mental::mental_simulation;
use clap::Args;

use crate::train_cmd::show;

/// Arguments of `causal-arm rollout`.
#[derive(Debug, Args)]
pub struct RolloutArgs {
    /// How to treat damage in the bags read.
    #[command(flatten)]
    pub read: crate::bag_cmd::ReadArgs,
    /// Model directory written by `causal-arm train`.
    #[arg(long)]
    model: PathBuf,
    /// Forward model file stem in the model directory.
    #[arg(long, default_value = "fm")]
    name: String,
    /// Bag of fresh ground-truth trajectories (not the training bag), e.g. from
    /// `causal-arm generate exp1 --steps 60000 --seed 99`.
    #[arg(long)]
    bag: PathBuf,
    /// Trajectories to evaluate (non-overlapping windows of the bag).
    #[arg(long, default_value_t = 6000)]
    trajectories: usize,
    /// Steps to chain the forward model.
    #[arg(long, default_value_t = 10)]
    steps: usize,
    /// Where to write mental_simulation.{json,png,svg} (default: the model directory).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Dataset cache directory (default: $CAUSAL_ARM_CACHE or ~/.cache/causal-arm).
    #[arg(long)]
    cache: Option<PathBuf>,
}

/// Runs `causal-arm rollout`.
pub fn run(args: &RolloutArgs) -> anyhow::Result<()> {
    let fm = load_model(&args.model, &args.name)?;
    let experiment = fm.experiment()?;
    let cache = Cache::new(args.cache.clone().unwrap_or_else(Cache::default_dir));
    let (data, _) = load_bags(
        std::slice::from_ref(&args.bag),
        Some(experiment),
        ActionSource::Realized,
        Some(&cache),
    )?;
    let result = mental_simulation(&fm, &data, args.trajectories, args.steps)?;
    let out = args.out.clone().unwrap_or_else(|| args.model.clone());
    std::fs::create_dir_all(&out).with_context(|| format!("cannot create {}", out.display()))?;
    let json = out.join("mental_simulation.json");
    std::fs::write(&json, serde_json::to_string_pretty(&result)? + "\n")
        .with_context(|| format!("cannot write {}", json.display()))?;
    let stem = out.join("mental_simulation");
    causal_arm_explain::output::draw_mental_simulation(&stem, &result, &experiment.to_string())?;
    println!(
        "{experiment} mental simulation, {} trajectories of {} steps:",
        result.trajectories, result.steps
    );
    print!("{:>4}", "step");
    for c in &result.curves {
        print!(" {:>26}", c.group);
    }
    println!();
    for k in 0..result.steps {
        print!("{:>4}", k + 1);
        for c in &result.curves {
            print!(
                " {:>26}",
                format!("{} ± {}", show(c.mean[k], &c.unit), show(c.std[k], ""))
            );
        }
        println!();
    }
    eprintln!(
        "wrote {}, {}.png and {}.svg",
        json.display(),
        stem.display(),
        stem.display()
    );
    Ok(())
}
