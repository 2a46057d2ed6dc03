//! `causal_arm_reacher`: stands in for the babbler and drives the arm to one target
//! effector position per episode with a controller of `causal_arm_control`: the
//! Jacobian baseline, babbling, or the learned inverse model served by a trainer node
//! (`/trainer/predict_action`, asked each step over DDS).
//!
//! Each episode starts from the simulator's reset home pose. Once the effector is within
//! 5 mm the reacher holds the arm still for the rest of the episode, so an episode of
//! `max_steps + 1` states scores exactly as `causal-arm reach --in-process` does with
//! `max_steps`. The report is the same JSON.

use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use anyhow::{Context as _, bail};
use causal_arm_control::{
    CemSettings, Controller, Episode, ForwardModel, ImController, InverseModel, JacobianController,
    MpcController, PlaceController, PlaceTrial, RandomController, StateLayout, Vector3,
    check_reachable, experiment_targets, hold, next_state_indices, sample_spots, summarize,
    summarize_place,
};
use causal_arm_kinematics::ArmModel;
use causal_arm_msgs::srv::{
    GetModelInfo, GetModelInfo_Request, PredictAction, PredictAction_Request,
    PredictAction_Response, PredictNextState, PredictNextState_Request, PredictNextState_Response,
};
use causal_arm_node::params::{ReacherParams, RunParams};
use causal_arm_node::runtime::block_on_timeout;
use causal_arm_node::{RosArgs, RosNode};
use causal_arm_protocol::{Drawn, Experiment};
use ros2_client::Client;

use crate::answer::answer_states;
use crate::{RunSetup, stop_flag};

/// The trainer's services the IM controller asks.
pub const PREDICT_ACTION: &str = "/trainer/predict_action";
/// See [`PREDICT_ACTION`].
pub const MODEL_INFO: &str = "/trainer/model_info";
/// The trainer's service the FM-MPC controller asks (one batch per horizon step of each
/// CEM iteration, every sampled sequence a row: `/trainer/rollout` takes one sequence
/// per call).
pub const PREDICT_NEXT_STATE: &str = "/trainer/predict_next_state";

/// Runs the reacher node until every episode of the run is answered or SIGINT/SIGTERM.
pub fn run(ros_args: &RosArgs) -> anyhow::Result<()> {
    let mut node = RosNode::new(ReacherParams::NODE, &ReacherParams::specs()?, ros_args)?;
    let run = RunSetup::from_params(&RunParams::from_params(node.params())?, "")?;
    let own = ReacherParams::from_params(node.params())?;
    if run.options.plan.steps_per_episode < 2 {
        bail!("steps must be at least 2 (the home state and one action per episode)");
    }
    let stop = stop_flag();
    let mut json = match own.task.as_str() {
        "reach" => reach(&mut node, &run, &own, &stop)?,
        "place" => place(&mut node, &run, &own, &stop)?,
        other => bail!("task {other:?} is not one of reach, place"),
    };
    let report = &own.report;
    if !report.is_empty() {
        json["max_steps"] = (run.options.plan.steps_per_episode - 1).into();
        json["seed"] = own.target_seed.into();
        json["over"] = "dds".into();
        std::fs::write(report, serde_json::to_string_pretty(&json)?)
            .with_context(|| format!("writing the report {report}"))?;
    }
    Ok(())
}

/// Drives the effector to one target per episode; the report's summary and episodes.
fn reach(
    node: &mut RosNode,
    run: &RunSetup,
    own: &ReacherParams,
    stop: &AtomicBool,
) -> anyhow::Result<serde_json::Value> {
    let plan = run.options.plan;
    let model = ArmModel::embedded();
    let experiment = run.options.experiment;
    let targets = targets(own, &model, experiment, plan.episodes as usize)?;
    let layout = StateLayout::of(experiment, &model);
    let sigma = run.options.exp1.sigma;
    let mut controller = controller(node, own, (&model, layout, sigma), stop)?;
    let mut episodes: Vec<Episode> = Vec::with_capacity(targets.len());
    let components = experiment.action_components();
    answer_states(
        "reacher",
        (node, None),
        run,
        &own.into(),
        0,
        stop,
        |state, place| {
            let target = &targets[place.episode as usize];
            if place.in_episode == 0 {
                episodes.push(Episode::start(target, state));
            }
            let episode = episodes
                .last_mut()
                .expect("started at step 0 of its episode");
            if place.in_episode > 0 && !episode.reached() {
                episode.record(state);
            }
            // The last state of an episode gets no command of the controller: its action's
            // outcome would be the next episode's reset.
            let last = place.in_episode + 1 == plan.steps_per_episode;
            let command = match episode.reached() || last {
                true => hold(state),
                false => controller.command(state, target)?,
            };
            Ok(Drawn::scripted(command, components))
        },
    )?;
    let summary = summarize(controller.name(), &episodes);
    tracing::info!(
        "{}: {} of {} targets, within 1 cm {:.0} %, within 5 mm {:.0} %",
        summary.controller,
        episodes.len(),
        targets.len(),
        100.0 * summary.success_1cm,
        100.0 * summary.success_5mm
    );
    Ok(serde_json::json!({"summary": summary, "episodes": episodes,
        "step_m": own.step, "controller": controller.report()}))
}

/// Moves the cube to one spot on the table per episode by FM-MPC (exp 2); the report's
/// summary and trials.
fn place(
    node: &mut RosNode,
    run: &RunSetup,
    own: &ReacherParams,
    stop: &AtomicBool,
) -> anyhow::Result<serde_json::Value> {
    let plan = run.options.plan;
    if run.options.experiment != Experiment::Exp2 {
        bail!(
            "task place moves exp2's cube; the run is {}",
            run.options.experiment
        );
    }
    let model = ArmModel::embedded();
    let scene = run.options.sim.scene();
    let episodes = plan.episodes as usize;
    // The declared range keeps the seed non-negative.
    let seed = own.target_seed as u64;
    let spots = match own.targets_file.as_str() {
        "" => sample_spots(&scene, run.options.sim.spawn_margin, episodes, seed),
        file => read_points(Path::new(file))?,
    };
    if spots.len() != episodes {
        bail!("{} spots for a run of {episodes} episodes", spots.len());
    }
    let settings = cem_settings(own)?;
    let fm = ServedFm::connect(node, own, stop)?;
    let layout = StateLayout::of(Experiment::Exp2, &model);
    let mpc = MpcController::new(model, layout, fm, settings, seed)?;
    let mut controller = PlaceController::new(mpc, scene);
    let mut trials: Vec<PlaceTrial> = Vec::with_capacity(episodes);
    let mut magnet = 0;
    answer_states(
        "reacher",
        (node, None),
        run,
        &own.into(),
        0,
        stop,
        |state, place| {
            let spot = &spots[place.episode as usize];
            if place.in_episode == 0 {
                controller.reset();
                trials.push(PlaceTrial::start(spot, state, &scene));
            }
            let trial = trials.last_mut().expect("started at step 0 of its episode");
            if place.in_episode > 0 && !trial.over() {
                trial.record(magnet, state, &scene, controller.grasps());
            }
            let last = place.in_episode + 1 == plan.steps_per_episode;
            let command = match trial.over() || last {
                true => hold(state),
                false => controller.command(state, spot)?,
            };
            magnet = command.magnet;
            Ok(Drawn::scripted(
                command,
                Experiment::Exp2.action_components(),
            ))
        },
    )?;
    let summary = summarize_place(&trials);
    tracing::info!(
        "fm-mpc place: {} trials, within 3 cm {:.0} %",
        trials.len(),
        100.0 * summary.placed_3cm
    );
    Ok(serde_json::json!({"summary": summary, "trials": trials, "planner": controller.report()}))
}

/// One target per episode: those of `targets_file`, or sampled from `target_seed`.
fn targets(
    own: &ReacherParams,
    model: &ArmModel,
    experiment: Experiment,
    episodes: usize,
) -> anyhow::Result<Vec<Vector3<f64>>> {
    let file = own.targets_file.as_str();
    let targets = match file {
        "" => {
            let seed = own.target_seed as u64;
            experiment_targets(experiment, model, episodes, seed)?
        }
        file => read_targets(Path::new(file), model)?,
    };
    if targets.len() != episodes {
        bail!(
            "{file}: {} targets for a run of {episodes} episodes (one target per episode)",
            targets.len()
        );
    }
    Ok(targets)
}

/// Positions from a JSON file `[[x, y, z], …]`.
fn read_points(file: &Path) -> anyhow::Result<Vec<Vector3<f64>>> {
    let text = std::fs::read_to_string(file)
        .with_context(|| format!("reading the targets file {}", file.display()))?;
    let points: Vec<[f64; 3]> = serde_json::from_str(&text).with_context(|| {
        format!(
            "{}: expected a JSON list of [x, y, z] positions",
            file.display()
        )
    })?;
    Ok(points.into_iter().map(Vector3::from).collect())
}

/// Reachable targets from a JSON file `[[x, y, z], …]`.
fn read_targets(file: &Path, model: &ArmModel) -> anyhow::Result<Vec<Vector3<f64>>> {
    read_points(file)?
        .into_iter()
        .enumerate()
        .map(|(i, goal)| {
            check_reachable(model, &goal)
                .with_context(|| format!("{}: target {i}", file.display()))?;
            Ok(goal)
        })
        .collect()
}

/// The controller the `controller` parameter names.
fn controller(
    node: &mut RosNode,
    own: &ReacherParams,
    (model, layout, sigma): (&ArmModel, StateLayout, f64),
    stop: &AtomicBool,
) -> anyhow::Result<Box<dyn Controller>> {
    let (step, seed) = (own.step, own.target_seed as u64);
    Ok(match own.controller.as_str() {
        "jacobian" => Box::new(JacobianController::new(model.clone(), step)),
        "random" => Box::new(RandomController::new(model, sigma, seed)?),
        "im" => {
            let im = ServedIm::connect(node, own, stop)?;
            Box::new(ImController::new(model.clone(), layout, im, step))
        }
        "fm-mpc" => {
            let settings = cem_settings(own)?;
            let fm = ServedFm::connect(node, own, stop)?;
            Box::new(MpcController::new(
                model.clone(),
                layout,
                fm,
                settings,
                seed,
            )?)
        }
        other => bail!("controller {other:?} is not one of jacobian, im, fm-mpc, random"),
    })
}

/// The cross-entropy method's settings from the node's parameters.
fn cem_settings(own: &ReacherParams) -> anyhow::Result<CemSettings> {
    let count = |value: i64, name: &str| -> anyhow::Result<usize> {
        usize::try_from(value).with_context(|| format!("parameter {name} must not be negative"))
    };
    Ok(CemSettings {
        horizon: count(own.horizon, "horizon")?,
        samples: count(own.samples, "samples")?,
        elites: count(own.elites, "elites")?,
        iterations: count(own.iterations, "iterations")?,
        spread: own.spread,
        max_delta: own.max_delta,
    })
}

/// Waits for the trainer's `service` (as `client` asks it), naming what to start if it
/// does not appear; returns early on SIGINT.
fn await_trainer<Req, Resp>(
    node: &RosNode,
    client: &Client<Req, Resp>,
    service: &str,
    (timeout, stop): (Duration, &AtomicBool),
) -> anyhow::Result<()>
where
    Req: ros2_client::Message + 'static,
    Resp: ros2_client::Message + 'static,
{
    let matched = node.wait_for_service(client, timeout, Duration::from_millis(500));
    if !matched && !stop.load(std::sync::atomic::Ordering::SeqCst) {
        bail!(
            "no server of {service} within {timeout:?}: start the trainer node on a model directory (`causal_arm_trainer --ros-args -p model_dir:=DIR`)"
        );
    }
    Ok(())
}

/// The forward model a trainer node serves, asked over DDS.
struct ServedFm {
    client: Client<PredictNextState_Request, PredictNextState_Response>,
    timeout: Duration,
}

impl ServedFm {
    fn connect(node: &mut RosNode, own: &ReacherParams, stop: &AtomicBool) -> anyhow::Result<Self> {
        let timeout = Duration::from_secs_f64(own.timeout);
        let client = node.client::<PredictNextState>(PREDICT_NEXT_STATE)?;
        await_trainer(node, &client, PREDICT_NEXT_STATE, (timeout, stop))?;
        Ok(Self { client, timeout })
    }
}

impl ForwardModel for ServedFm {
    fn next_states(
        &self,
        states: &[f64],
        actions: &[f64],
        rows: usize,
    ) -> Result<Vec<f64>, String> {
        let request = PredictNextState_Request {
            state: states.to_vec(),
            action: actions.to_vec(),
            rows: rows as u32,
        };
        let reply = block_on_timeout(self.client.async_call_service(request), self.timeout)
            .ok_or_else(|| {
                format!(
                    "no reply from {PREDICT_NEXT_STATE} within {:?}",
                    self.timeout
                )
            })?
            .map_err(|e| format!("calling {PREDICT_NEXT_STATE}: {e:?}"))?;
        match reply.success {
            true => Ok(reply.next_state),
            false => Err(format!("{PREDICT_NEXT_STATE} refused: {}", reply.message)),
        }
    }
}

/// The inverse model a trainer node serves, asked over DDS.
struct ServedIm {
    client: Client<PredictAction_Request, PredictAction_Response>,
    /// Which state features, in order, the IM takes as its next state.
    next: Vec<usize>,
    timeout: Duration,
}

impl ServedIm {
    /// Finds the trainer's services and asks which next-state features its IM takes.
    fn connect(node: &mut RosNode, own: &ReacherParams, stop: &AtomicBool) -> anyhow::Result<Self> {
        let timeout = Duration::from_secs_f64(own.timeout);
        let info = node.client::<GetModelInfo>(MODEL_INFO)?;
        let client = node.client::<PredictAction>(PREDICT_ACTION)?;
        await_trainer(node, &info, MODEL_INFO, (timeout, stop))?;
        await_trainer(node, &client, PREDICT_ACTION, (timeout, stop))?;
        let reply = block_on_timeout(
            info.async_call_service(GetModelInfo_Request::default()),
            timeout,
        )
        .with_context(|| format!("no reply from {MODEL_INFO} within {timeout:?}"))?
        .map_err(|e| anyhow::anyhow!("calling {MODEL_INFO}: {e:?}"))?;
        let next = next_state_indices(&reply.state_names, &reply.next_state_names)
            .with_context(|| format!("the model {MODEL_INFO} describes"))?;
        tracing::info!(
            "asking the served IM ({}) for actions; it takes next-state features {:?}",
            reply.models.join(", "),
            reply.next_state_names
        );
        Ok(Self {
            client,
            next,
            timeout,
        })
    }
}

impl InverseModel for ServedIm {
    fn action(&self, state: &[f64], next_state: &[f64]) -> Result<Vec<f64>, String> {
        let request = PredictAction_Request {
            state: state.to_vec(),
            next_state: self.next.iter().map(|&i| next_state[i]).collect(),
            rows: 1,
        };
        let reply = block_on_timeout(self.client.async_call_service(request), self.timeout)
            .ok_or_else(|| format!("no reply from {PREDICT_ACTION} within {:?}", self.timeout))?
            .map_err(|e| format!("calling {PREDICT_ACTION}: {e:?}"))?;
        match reply.success {
            true => Ok(reply.action),
            false => Err(format!("{PREDICT_ACTION} refused: {}", reply.message)),
        }
    }
}
