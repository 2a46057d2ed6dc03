//! `causal-arm intervene`: the simulator's causal ground truth for the states of a bag.

use std::path::PathBuf;

use anyhow::Context;
use causal_arm_intervene::intervene;
use causal_arm_protocol::Experiment;
use causal_arm_truth::{Edge, Plan, write_all};
use clap::Args;

use crate::choice::choice;
use crate::progress::Counter;

/// Arguments of `causal-arm intervene`.
#[derive(Debug, Args)]
pub struct InterveneArgs {
    /// How to treat damage in the bags read.
    #[command(flatten)]
    pub read: crate::bag_cmd::ReadArgs,
    /// Experiment of the bag: exp1 or exp2.
    #[arg(value_parser = choice::<Experiment>())]
    experiment: Experiment,
    /// Bag written by `causal-arm generate` or `launch` (its recorded settings let the
    /// simulator revisit every state exactly).
    #[arg(long)]
    bag: PathBuf,
    /// States to intervene on, drawn uniformly from the bag's transitions.
    #[arg(long, default_value_t = 1000)]
    states: usize,
    /// Seed of the state draw.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Compare s(t+1) … s(t+H); after the intervened step the recorded commands follow.
    #[arg(long, default_value_t = 1)]
    horizon: usize,
    /// Joint interventions: ± these multiples of the std of each joint's commanded delta.
    #[arg(long, value_delimiter = ',', default_value = "0.1,0.5,1,2")]
    delta_scales: Vec<f64>,
    /// An effect counts when it exceeds this, in the feature's unit (m, rad).
    #[arg(allow_negative_numbers = true, long, default_value_t = 1e-6)]
    tolerance: f64,
    /// An effect counts only when it also exceeds this multiple of the std of the
    /// feature's one-step change over the intervened states (0: any effect; the dynamic
    /// arm's joints all move each other a little, see docs/RESULTS.md).
    #[arg(allow_negative_numbers = true, long, default_value_t = 0.0)]
    effect_size: f64,
    /// Edges active in fewer than this share of states (but some) are "rare": not scored.
    #[arg(allow_negative_numbers = true, long, default_value_t = 0.01)]
    min_fraction: f64,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Output directory for truth.json, truth.csv and truth_heatmap.png/svg.
    #[arg(long)]
    out: PathBuf,
}

/// Runs `causal-arm intervene`.
pub fn run(args: &InterveneArgs) -> anyhow::Result<()> {
    let experiment = args.experiment;
    let plan = Plan {
        states: args.states,
        seed: args.seed,
        horizon: args.horizon,
        delta_scales: args.delta_scales.clone(),
        tolerance: args.tolerance,
        effect_size: args.effect_size,
        min_fraction: args.min_fraction,
        threads: args.threads,
    };
    plan.check()?;
    let mut counter: Option<Counter> = None;
    let truth = intervene(&args.bag, experiment, &plan, &mut |done, total| {
        let c = counter.get_or_insert_with(|| Counter::new(total, "re-simulating", "steps"));
        if done % 512 == 0 || done == total {
            c.set(done);
        }
    })
    .with_context(|| format!("intervening on {}", args.bag.display()))?;
    if let Some(c) = counter {
        c.finish();
    }
    let written = write_all(&args.out, &truth)
        .with_context(|| format!("cannot write the truth into {}", args.out.display()))?;
    let m = truth.one_step();
    println!(
        "{experiment} ground truth from {} states of {} ({} steps re-simulated bit-identical to the bag) in {:.1} s; noise floor of an identical replay: {:e}",
        m.states,
        args.bag.display(),
        truth.resimulated_steps,
        truth.seconds,
        truth.noise_floor
    );
    for (a, action) in truth.action_names.iter().enumerate() {
        let edges: Vec<String> = truth
            .state_names
            .iter()
            .enumerate()
            .filter(|&(k, _)| m.edge(a, k, plan.min_fraction) == Edge::Present)
            .map(|(k, s)| format!("{s} ({:.0} %)", 100.0 * m.active_fraction[a][k]))
            .collect();
        println!("{action:<6} changes {}", edges.join(", "));
    }
    for f in written {
        eprintln!("wrote {}", f.display());
    }
    Ok(())
}
