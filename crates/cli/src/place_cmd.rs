//! `causal-arm place`: FM-MPC moves the cube to spots on the table (exp 2), picking it
//! with the magnet, carrying it and releasing it over the spot; reports how often the
//! cube comes to rest within 3 cm and 1 cm. In process.

use std::path::PathBuf;

use anyhow::{Context as _, bail};
use causal_arm_control::{
    MpcController, PlaceController, PlaceTrial, StateLayout, run_place_trial, sample_spots,
    summarize_place,
};
use causal_arm_kinematics::ArmModel;
use causal_arm_protocol::{Experiment, RunPlan};
use clap::Args;

use crate::progress::Counter;
use crate::reach_cmd::CemArgs;
use crate::reach_models::TrainedFm;

/// `causal-arm place` options.
#[derive(Debug, Args)]
pub struct PlaceArgs {
    /// Trials, each with a fresh cube where the simulator spawns it and a spot drawn on
    /// the table.
    #[arg(long, default_value_t = 50, allow_negative_numbers = true)]
    trials: i64,
    /// Seed of the spots, the simulator's cubes and the planner.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Model directory of `causal-arm train` holding an exp 2 forward model.
    #[arg(long)]
    model_dir: PathBuf,
    /// The forward model's file name in --model-dir.
    #[arg(long, default_value = "fm")]
    forward_model: String,
    #[command(flatten)]
    cem: CemArgs,
    /// Steps per trial before giving up.
    #[arg(long, default_value_t = 400, allow_negative_numbers = true)]
    max_steps: i64,
    /// Directory for report.json.
    #[arg(long)]
    out: PathBuf,
}

/// Runs `causal-arm place`.
pub fn run(args: &PlaceArgs) -> anyhow::Result<()> {
    let (trials, max_steps) = match (args.trials, args.max_steps) {
        (t, m) if t > 0 && m > 0 => (t as usize, m as usize),
        (t, m) => bail!("--trials and --max-steps must be positive numbers, got {t} and {m}"),
    };
    let model = ArmModel::embedded();
    let fm = TrainedFm::load(&args.model_dir, &args.forward_model, Experiment::Exp2)?;
    let layout = StateLayout::of(Experiment::Exp2, &model);
    let mpc = MpcController::new(model, layout, fm, args.cem.settings(), args.seed)?;
    let plan = RunPlan {
        episodes: trials as u64,
        steps_per_episode: max_steps as u64,
    };
    let options = causal_arm_datagen::GenerateOptions::new(Experiment::Exp2, plan, args.seed, "");
    let mut sim = causal_arm_datagen::simulator(&options)?;
    let scene = sim.config().scene();
    let spots = sample_spots(&scene, sim.config().spawn_margin, trials, args.seed);
    let mut controller = PlaceController::new(mpc, scene);
    let mut counter = Counter::new(trials as u64, "place with fm-mpc", "trials");
    let mut done: Vec<PlaceTrial> = Vec::with_capacity(trials);
    for (i, spot) in spots.iter().enumerate() {
        if i > 0 {
            sim.reset_episode();
        }
        done.push(run_place_trial(&mut sim, &mut controller, spot, max_steps)?);
        counter.set(i as u64 + 1);
    }
    counter.finish();
    let summary = summarize_place(&done);
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let file = args.out.join("report.json");
    let report = serde_json::json!({"summary": summary, "trials": done, "seed": args.seed,
        "max_steps": max_steps, "planner": controller.report()});
    std::fs::write(&file, serde_json::to_string_pretty(&report)?)
        .with_context(|| format!("writing {}", file.display()))?;
    println!(
        "fm-mpc place: {} trials, within 3 cm {:.0} %, within 1 cm {:.0} %, held {:.0} %, final distance p50 {:.4} m ({})",
        summary.trials,
        100.0 * summary.placed_3cm,
        100.0 * summary.placed_1cm,
        100.0 * summary.held,
        summary.final_distance_p10_p50_p90[1],
        file.display()
    );
    Ok(())
}
