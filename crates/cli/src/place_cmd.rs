//! `causal-arm place`: FM-MPC moves the cube to spots on the table (exp 2), picking it
//! with the magnet, carrying it and releasing it over the spot; reports how often the
//! cube comes to rest within 3 cm and 1 cm. Over DDS (the reacher node with
//! `task:=place`, a trainer node serving the FM) or, with `--in-process`, in process;
//! both run each trial to `max_steps + 1` actions and agree trial for trial.

use std::path::PathBuf;

use anyhow::{Context as _, bail};
use causal_arm_control::{
    MpcController, PlaceController, PlaceSummary, PlaceTrial, StateLayout, Vector3,
    run_place_trial, sample_spots, summarize_place,
};
use causal_arm_datagen::GenerateOptions;
use causal_arm_kinematics::ArmModel;
use causal_arm_node::RosArgs;
use causal_arm_protocol::Experiment;
use clap::Args;

use crate::progress::Counter;
use crate::reach_cmd::{CemArgs, ControlRunArgs, ReacherRun, run_options, run_reacher_graph};
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
    #[command(flatten)]
    run: ControlRunArgs,
}

/// Runs `causal-arm place`.
pub fn run(args: &PlaceArgs, ros_args: &RosArgs) -> anyhow::Result<()> {
    let (trials, max_steps) = match (args.trials, args.max_steps) {
        (t, m) if t > 0 && m > 0 => (t as usize, m as usize),
        (t, m) => bail!("--trials and --max-steps must be positive numbers, got {t} and {m}"),
    };
    // Refuse a directory without an exp 2 FM before anything starts.
    let fm = TrainedFm::load(&args.model_dir, &args.forward_model, Experiment::Exp2)?;
    let options = run_options(
        Experiment::Exp2,
        args.seed,
        &args.run.out,
        trials,
        max_steps,
    );
    let spots = sample_spots(
        &options.sim.scene(),
        options.sim.spawn_margin,
        trials,
        args.seed,
    );
    std::fs::create_dir_all(&args.run.out)
        .with_context(|| format!("creating {}", args.run.out.display()))?;
    let file = args.run.out.join("report.json");
    let report = match args.run.in_process {
        true => in_process(args, fm, &options, &spots, max_steps)?,
        false => {
            let mut reacher = vec!["task:=place".to_owned()];
            reacher.extend(args.cem.ros_params());
            let run = ReacherRun {
                options,
                overwrite: args.run.overwrite,
                points: &spots,
                reacher,
                trainer: Some((&args.model_dir, &args.forward_model, &args.forward_model)),
                report: &file,
            };
            run_reacher_graph(&run, ros_args)?
        }
    };
    std::fs::write(&file, serde_json::to_string_pretty(&report)?)
        .with_context(|| format!("writing {}", file.display()))?;
    let summary: PlaceSummary = serde_json::from_value(report["summary"].clone())?;
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

/// Every trial in this process, with the simulator the simulator node would run.
fn in_process(
    args: &PlaceArgs,
    fm: TrainedFm,
    options: &GenerateOptions,
    spots: &[Vector3<f64>],
    max_steps: usize,
) -> anyhow::Result<serde_json::Value> {
    let model = ArmModel::embedded();
    let layout = StateLayout::of(Experiment::Exp2, &model);
    let mpc = MpcController::new(model, layout, fm, args.cem.settings(), args.seed)?;
    let mut sim = causal_arm_datagen::simulator(options)?;
    let mut controller = PlaceController::new(mpc, sim.config().scene());
    let mut counter = Counter::new(spots.len() as u64, "place with fm-mpc", "trials");
    let mut trials: Vec<PlaceTrial> = Vec::with_capacity(spots.len());
    for (i, spot) in spots.iter().enumerate() {
        if i > 0 {
            sim.reset_episode();
        }
        trials.push(run_place_trial(&mut sim, &mut controller, spot, max_steps)?);
        counter.set(i as u64 + 1);
    }
    counter.finish();
    Ok(
        serde_json::json!({"summary": summarize_place(&trials), "trials": trials,
        "seed": args.seed, "max_steps": max_steps, "over": "process",
        "planner": controller.report()}),
    )
}
