//! `causal-arm reach`: drive the simulated arm to target effector positions with a
//! controller (the Jacobian baseline, a learned inverse model, or babbling) and report
//! how often and how fast it gets there. Over DDS (the simulator, recorder and
//! `causal_arm_reacher` nodes, and a trainer node serving the IM) or, with
//! `--in-process`, with the simulator library; exp 1 only for now (issue 17).

use std::path::{Path, PathBuf};

use anyhow::{Context as _, bail};
use causal_arm_control::{
    CemSettings, Controller, Episode, ImController, JacobianController, MpcController,
    RandomController, StateLayout, Summary, Vector3, check_reachable, experiment_targets,
    run_fixed_episode, summarize,
};
use causal_arm_datagen::GenerateOptions;
use causal_arm_kinematics::ArmModel;
use causal_arm_node::RosArgs;
use causal_arm_protocol::Experiment;
use causal_arm_protocol::RunPlan;
use causal_arm_protocol::graph::graph;
use clap::{Args, ValueEnum};

use crate::choice::choice;
use crate::launch_cmd;
use crate::progress::Counter;
use crate::reach_models::{TrainedFm, TrainedIm};
use causal_arm_rig::launch::{LaunchPlan, Process, STOP_TIMEOUT, node_binary, stop_all};

/// Which policy drives the arm.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum ControllerKind {
    /// Damped least squares on the URDF's Jacobian (the analytic baseline).
    Jacobian,
    /// The learned inverse model of --model-dir, asked for the action to an intermediate state.
    Im,
    /// Exp 1's random joint targets (the floor).
    Random,
    /// Model-predictive control: the cross-entropy method plans in mental simulation with
    /// the forward model of --model-dir and the first action is executed.
    FmMpc,
}

impl ControllerKind {
    /// The name the reacher node's `controller` parameter takes.
    fn name(self) -> &'static str {
        match self {
            Self::Jacobian => "jacobian",
            Self::Im => "im",
            Self::Random => "random",
            Self::FmMpc => "fm-mpc",
        }
    }
}

/// `causal-arm reach` options.
#[derive(Debug, Args)]
pub struct ReachArgs {
    /// exp1 or exp2 (targets where that experiment babbles, its models' state layout).
    #[arg(value_parser = choice::<Experiment>())]
    experiment: Experiment,
    /// Target effector positions to reach, sampled where exp 1 babbles.
    #[arg(
        long,
        default_value_t = 100,
        allow_negative_numbers = true,
        conflicts_with = "target"
    )]
    targets: i64,
    /// A target effector position of your own, world frame, m (repeat for several; in
    /// place of the sampled ones). Refused if the arm cannot reach it.
    #[arg(long, num_args = 3, value_names = ["X", "Y", "Z"], allow_negative_numbers = true)]
    target: Vec<f64>,
    /// Seed of the targets (and of the random controller).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// The policy.
    #[arg(long, value_enum, default_value_t = ControllerKind::Jacobian)]
    controller: ControllerKind,
    /// Model directory of `causal-arm train` (needed by --controller im and fm-mpc).
    #[arg(long)]
    model_dir: Option<PathBuf>,
    /// The inverse model's file name in --model-dir.
    #[arg(long, default_value = "im-mono")]
    inverse_model: String,
    /// The forward model's file name in --model-dir (fm-mpc).
    #[arg(long, default_value = "fm")]
    forward_model: String,
    #[command(flatten)]
    cem: CemArgs,
    /// Steps per target before giving up.
    #[arg(long, default_value_t = 300, allow_negative_numbers = true)]
    max_steps: i64,
    /// Effector displacement asked for in one step, m. The IM is always asked for a step
    /// of this length and its action scaled down near the target. The best length depends
    /// on the model (docs/runs/reach/exp1_100_targets.txt, within 1 cm: the paper-profile
    /// IM 84 % at 5 cm, 91 % at 10 cm; a 30-epoch IM 70 % and 27 %; both 0 % at 2 cm).
    #[arg(long, default_value_t = 0.05, allow_negative_numbers = true)]
    step: f64,
    #[command(flatten)]
    run: ControlRunArgs,
}

/// Where a control run (`reach`, `place`) runs and writes; shared so both read the same.
#[derive(Debug, Args)]
pub(crate) struct ControlRunArgs {
    /// Run in this process with the simulator library, instead of over DDS with the
    /// simulator, recorder and reacher nodes (and a trainer node for a learned model).
    #[arg(long)]
    pub(crate) in_process: bool,
    /// Directory for report.json and, over DDS, the run's bag in OUT/bag and its targets
    /// or spots in OUT/targets.json.
    #[arg(long)]
    pub(crate) out: PathBuf,
    /// Replace a bag already in OUT/bag.
    #[arg(long)]
    pub(crate) overwrite: bool,
}

/// The cross-entropy method of `--controller fm-mpc` (defaults: `CemSettings::default()`,
/// which the reacher node's parameters in graph.toml repeat; a test keeps them equal).
#[derive(Debug, Args)]
pub(crate) struct CemArgs {
    /// fm-mpc: steps each sampled action sequence looks ahead.
    #[arg(long, default_value_t = CemSettings::default().horizon)]
    horizon: usize,
    /// fm-mpc: sequences sampled per CEM iteration (one FM batch per horizon step).
    #[arg(long, default_value_t = CemSettings::default().samples)]
    samples: usize,
    /// fm-mpc: best sequences the sampling is refitted to.
    #[arg(long, default_value_t = CemSettings::default().elites)]
    elites: usize,
    /// fm-mpc: CEM iterations per decision.
    #[arg(long, default_value_t = CemSettings::default().iterations)]
    iterations: usize,
    /// fm-mpc: initial spread of each joint delta, rad.
    #[arg(long, default_value_t = CemSettings::default().spread)]
    spread: f64,
    /// fm-mpc: largest joint delta of one step, rad.
    #[arg(long, default_value_t = CemSettings::default().max_delta)]
    max_delta: f64,
}

impl CemArgs {
    pub(crate) fn settings(&self) -> CemSettings {
        CemSettings {
            horizon: self.horizon,
            samples: self.samples,
            elites: self.elites,
            iterations: self.iterations,
            spread: self.spread,
            max_delta: self.max_delta,
        }
    }

    /// The same settings as the reacher node's parameters.
    pub(crate) fn ros_params(&self) -> [String; 6] {
        [
            format!("horizon:={}", self.horizon),
            format!("samples:={}", self.samples),
            format!("elites:={}", self.elites),
            format!("iterations:={}", self.iterations),
            format!("spread:={:?}", self.spread),
            format!("max_delta:={:?}", self.max_delta),
        ]
    }
}

/// Runs `causal-arm reach`.
pub fn run(args: &ReachArgs, ros_args: &RosArgs) -> anyhow::Result<()> {
    let (targets, max_steps) = (
        positive(args.targets, "--targets")?,
        positive(args.max_steps, "--max-steps")?,
    );
    if !(args.step.is_finite() && args.step > 0.0) {
        bail!(
            "--step must be a positive number of metres, got {}",
            args.step
        );
    }
    let model = ArmModel::embedded();
    let goals = match args.target.as_slice() {
        [] => experiment_targets(args.experiment, &model, targets, args.seed)?,
        given => given
            .chunks(3)
            .map(|p| {
                let goal = Vector3::new(p[0], p[1], p[2]);
                check_reachable(&model, &goal)
                    .with_context(|| format!("--target {} {} {}", p[0], p[1], p[2]))?;
                Ok(goal)
            })
            .collect::<anyhow::Result<_>>()?,
    };
    // Refuse a model directory without a usable IM before anything starts.
    let mut controller = controller(args, &model)?;
    std::fs::create_dir_all(&args.run.out)
        .with_context(|| format!("creating {}", args.run.out.display()))?;
    let file = args.run.out.join("report.json");
    let summary = match args.run.in_process {
        true => in_process(args, controller.as_mut(), &goals, max_steps, &file)?,
        false => over_dds(args, ros_args, &goals, max_steps, &file)?,
    };
    println!(
        "{}: {} targets, within 1 cm {:.0} %, within 5 mm {:.0} %, median steps to 1 cm {}, final error p50 {:.4} m ({})",
        summary.controller,
        summary.episodes,
        100.0 * summary.success_1cm,
        100.0 * summary.success_5mm,
        summary
            .median_steps_to_1cm
            .map_or("-".into(), |s| s.to_string()),
        summary.final_error_p10_p50_p90[1],
        file.display()
    );
    Ok(())
}

/// Reaches every goal in this process, with the simulator library, and writes `file`.
fn in_process(
    args: &ReachArgs,
    controller: &mut dyn Controller,
    goals: &[Vector3<f64>],
    max_steps: usize,
    file: &Path,
) -> anyhow::Result<Summary> {
    // The simulator the simulator node would run for the same run.
    let mut sim = causal_arm_datagen::simulator(&run_options(
        args.experiment,
        args.seed,
        &args.run.out,
        goals.len(),
        max_steps,
    ))?;
    let mut counter = Counter::new(
        goals.len() as u64,
        &format!("reach with {}", controller.name()),
        "targets",
    );
    let mut episodes: Vec<Episode> = Vec::with_capacity(goals.len());
    for (i, goal) in goals.iter().enumerate() {
        if i > 0 {
            sim.reset_episode();
        }
        episodes.push(run_fixed_episode(&mut sim, controller, goal, max_steps)?);
        counter.set(i as u64 + 1);
    }
    counter.finish();
    let summary = summarize(controller.name(), &episodes);
    let report = serde_json::json!({"summary": summary, "episodes": episodes, "seed": args.seed,
        "max_steps": max_steps, "step_m": args.step, "over": "process",
        "controller": controller.report()});
    std::fs::write(file, serde_json::to_string_pretty(&report)?)
        .with_context(|| format!("writing {}", file.display()))?;
    Ok(summary)
}

/// The run the simulator node makes of `episodes` targets: an episode of `max_steps + 1`
/// states per target, recorded into OUT/bag.
pub(crate) fn run_options(
    experiment: Experiment,
    seed: u64,
    out: &Path,
    episodes: usize,
    max_steps: usize,
) -> GenerateOptions {
    let plan = RunPlan {
        episodes: episodes as u64,
        steps_per_episode: max_steps as u64 + 1,
    };
    GenerateOptions::new(experiment, plan, seed, out.join("bag"))
}

/// Reaches every goal over DDS: the simulator, recorder and reacher nodes (and, for the
/// IM or FM, a trainer node serving --model-dir) as separate processes, one episode per
/// goal of `max_steps + 1` states (the reacher holds the arm once within 5 mm).
fn over_dds(
    args: &ReachArgs,
    ros_args: &RosArgs,
    goals: &[Vector3<f64>],
    max_steps: usize,
    file: &Path,
) -> anyhow::Result<Summary> {
    let mut reacher = vec![
        "task:=reach".to_owned(),
        format!("controller:={}", args.controller.name()),
        format!("step:={:?}", args.step),
    ];
    reacher.extend(args.cem.ros_params());
    // IM reaching asks no FM: the IM serves both services.
    let trainer = match args.controller {
        ControllerKind::Im => Some((model_dir(args)?, &args.inverse_model, &args.inverse_model)),
        ControllerKind::FmMpc => Some((model_dir(args)?, &args.forward_model, &args.inverse_model)),
        _ => None,
    };
    let run = ReacherRun {
        options: run_options(
            args.experiment,
            args.seed,
            &args.run.out,
            goals.len(),
            max_steps,
        ),
        overwrite: args.run.overwrite,
        points: goals,
        reacher,
        trainer,
        report: file,
    };
    let report = run_reacher_graph(&run, ros_args)?;
    Ok(serde_json::from_value(report["summary"].clone())?)
}

/// One run of the reacher graph (`reach` and `place` over DDS).
pub(crate) struct ReacherRun<'a> {
    /// The simulator's run: one episode per point, recorded into its `out`.
    pub options: GenerateOptions,
    /// Replace a bag already there.
    pub overwrite: bool,
    /// One target (or spot) per episode, handed to the reacher in a targets file beside
    /// the report.
    pub points: &'a [Vector3<f64>],
    /// The reacher's own parameters (`name:=value`).
    pub reacher: Vec<String>,
    /// A trainer node to start first: model directory, forward and inverse model names.
    pub trainer: Option<(&'a Path, &'a String, &'a String)>,
    /// Where the reacher writes its report.
    pub report: &'a Path,
}

/// Runs the recorder, simulator and reacher nodes (and the trainer) over DDS and returns
/// the reacher's report.
pub(crate) fn run_reacher_graph(
    run: &ReacherRun,
    ros_args: &RosArgs,
) -> anyhow::Result<serde_json::Value> {
    let mut options = run.options.clone();
    options.overwrite = run.overwrite;
    causal_arm_datagen::validate(&options)?;
    if !options.overwrite
        && let Some(found) = causal_arm_bag::existing_bag(&options.out)
    {
        bail!(
            "{} already holds a bag ({found}); pass --overwrite to replace it",
            options.out.display()
        );
    }
    let file = run.report;
    let targets_file = file.with_file_name("targets.json");
    let points: Vec<[f64; 3]> = run.points.iter().map(|g| [g.x, g.y, g.z]).collect();
    std::fs::write(&targets_file, serde_json::to_string(&points)?)
        .with_context(|| format!("writing {}", targets_file.display()))?;
    if file.exists() {
        std::fs::remove_file(file).with_context(|| format!("replacing {}", file.display()))?;
    }
    let mut reacher = run.reacher.clone();
    reacher.extend([
        format!("target_seed:={}", options.seed),
        format!("targets_file:={}", targets_file.display()),
        format!("report:={}", file.display()),
    ]);
    let mut plan = LaunchPlan::from_graph(graph()?, &options, ros_args.enclave.as_deref());
    plan.stand_in(graph()?, "causal_arm_reacher", &reacher)?;
    let bin_dir = launch_cmd::bin_dir()?;
    let mut trainer = match run.trainer {
        Some(models) => vec![trainer_process(models, ros_args, &bin_dir)?],
        None => Vec::new(),
    };
    let outcome = match plan.spawn(&bin_dir) {
        Ok(nodes) => launch_cmd::follow(&options, ros_args, &plan, nodes),
        Err(e) => Err(e),
    };
    stop_all(&mut trainer, STOP_TIMEOUT)?;
    outcome?;
    Ok(serde_json::from_str(
        &std::fs::read_to_string(file)
            .with_context(|| format!("the reacher wrote no report {}", file.display()))?,
    )?)
}

/// The trainer node serving model directory `dir` with the given forward and inverse
/// models.
fn trainer_process(
    (dir, forward, inverse): (&Path, &String, &String),
    ros_args: &RosArgs,
    bin_dir: &Path,
) -> anyhow::Result<Process> {
    let mut node_args: Vec<String> = vec!["--ros-args".into()];
    for p in [
        format!("model_dir:={}", dir.display()),
        format!("forward_model:={forward}"),
        format!("inverse_model:={inverse}"),
    ] {
        node_args.extend(["-p".to_owned(), p]);
    }
    if let Some(enclave) = &ros_args.enclave {
        node_args.extend(["--enclave".to_owned(), enclave.clone()]);
    }
    let name = "causal_arm_trainer";
    Process::spawn(name, &node_binary(bin_dir, name)?, &node_args)
}

fn controller(args: &ReachArgs, model: &ArmModel) -> anyhow::Result<Box<dyn Controller>> {
    Ok(match args.controller {
        ControllerKind::Jacobian => Box::new(JacobianController::new(model.clone(), args.step)),
        ControllerKind::Random => Box::new(RandomController::new(model, 0.35, args.seed)?),
        ControllerKind::Im => {
            let im = TrainedIm::load(model_dir(args)?, &args.inverse_model, args.experiment)?;
            let layout = StateLayout::of(args.experiment, model);
            Box::new(ImController::new(model.clone(), layout, im, args.step))
        }
        ControllerKind::FmMpc => {
            let fm = TrainedFm::load(model_dir(args)?, &args.forward_model, args.experiment)?;
            let (layout, settings) = (StateLayout::of(args.experiment, model), args.cem.settings());
            Box::new(MpcController::new(
                model.clone(),
                layout,
                fm,
                settings,
                args.seed,
            )?)
        }
    })
}

fn model_dir(args: &ReachArgs) -> anyhow::Result<&Path> {
    args.model_dir.as_deref().with_context(|| {
        format!(
            "--controller {} needs --model-dir (a directory written by `causal-arm train`)",
            args.controller.name()
        )
    })
}

fn positive(value: i64, flag: &str) -> anyhow::Result<usize> {
    match value {
        v if v > 0 => Ok(v as usize),
        v => bail!("{flag} must be a positive number, got {v}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use causal_arm_protocol::graph::ParamDefault;

    #[test]
    fn the_reacher_nodes_cem_defaults_are_the_librarys() {
        let reacher = graph().unwrap().node("causal_arm_reacher").unwrap();
        let default = |name: &str| -> f64 {
            match reacher
                .params
                .iter()
                .find(|p| p.name == name)
                .map(|p| &p.default)
            {
                Some(ParamDefault::Integer(v)) => *v as f64,
                Some(ParamDefault::Double(v)) => *v,
                other => panic!("reacher parameter {name}: {other:?}"),
            }
        };
        let d = CemSettings::default();
        assert_eq!(default("horizon"), d.horizon as f64);
        assert_eq!(default("samples"), d.samples as f64);
        assert_eq!(default("elites"), d.elites as f64);
        assert_eq!(default("iterations"), d.iterations as f64);
        assert_eq!(default("spread"), d.spread);
        assert_eq!(default("max_delta"), d.max_delta);
    }
}
