//! `causal_arm_trainer`: serves a model directory as ROS 2 services
//! (`/trainer/predict_next_state`, `/trainer/predict_action`, `/trainer/rollout`,
//! `/trainer/model_info`). The directory is either written by `causal-arm train` or, with
//! `-p bag:=DIR[,DIR…]`, trained by the node itself first (same files, same metrics).
//! Every request gets a reply; bad ones a `success: false` reply saying why, and the node
//! keeps serving.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::{anyhow, bail};
use causal_arm_dataset::{ActionSource, Cache, load_bags};
use causal_arm_models::fit::ProgressLog;
use causal_arm_models::job::train_and_save;
use causal_arm_models::serve::ModelSet;
use causal_arm_models::{ModelRequest, TrainOptions};
use causal_arm_msgs::srv::{GetModelInfo, PredictAction, PredictNextState, Rollout};
use causal_arm_node::replies::Replies;
use causal_arm_node::run::{node_main, serve_until_stopped, stop_flag};
use causal_arm_node::{RosArgs, RosNode, server_param_specs};
use causal_arm_protocol::graph::server_default_text;
use futures::FutureExt;

/// Service names (relative names resolve in the node's namespace, as ROS does).
const PREDICT_NEXT_STATE: &str = "/trainer/predict_next_state";
const PREDICT_ACTION: &str = "/trainer/predict_action";
const ROLLOUT: &str = "/trainer/rollout";
const MODEL_INFO: &str = "/trainer/model_info";

fn run(ros_args: &RosArgs) -> anyhow::Result<()> {
    // First of all: a SIGINT that arrives while the node starts up must not be lost (a
    // background job of a non-interactive shell starts with SIGINT ignored until then).
    let stop = stop_flag();
    let mut node = RosNode::new(
        "causal_arm_trainer",
        &server_param_specs("causal_arm_trainer")?,
        ros_args,
    )?;
    let dir = node.params().string("model_dir").to_owned();
    if dir.is_empty() {
        bail!(
            "parameter model_dir is required: --ros-args -p model_dir:=DIR (a directory written by `causal-arm train`, or where to train to with -p bag:=DIR)"
        );
    }
    let bags = node.params().string_array("bag").to_vec();
    if !bags.is_empty() {
        match train_first(&node, &bags, std::path::Path::new(&dir), &stop) {
            Err(e) if stop.load(Ordering::SeqCst) => {
                tracing::info!("stopping: {e}");
                return Ok(());
            }
            result => result?,
        }
    }
    // The default inverse model may be absent (a directory of forward models); one the
    // user named must exist.
    let inverse = node.params().string("inverse_model");
    let default_inverse = server_default_text("causal_arm_trainer", "inverse_model");
    let models = ModelSet::load(
        std::path::Path::new(&dir),
        node.params().string("forward_model"),
        inverse,
        inverse != default_inverse,
    )?;
    serve(&mut node, &models, &dir, &stop)
}

/// Answers the four services from `models` until SIGINT or shutdown; every request gets a
/// reply, so one bad request never stops the node.
fn serve(
    node: &mut RosNode,
    models: &ModelSet,
    dir: &str,
    stop: &Arc<AtomicBool>,
) -> anyhow::Result<()> {
    let next_state = node.server::<PredictNextState>(PREDICT_NEXT_STATE)?;
    let action = node.server::<PredictAction>(PREDICT_ACTION)?;
    let rollout = node.server::<Rollout>(ROLLOUT)?;
    let info = node.server::<GetModelInfo>(MODEL_INFO)?;
    tracing::info!(
        "serving {} models from {dir} ({}): {PREDICT_NEXT_STATE}, {PREDICT_ACTION}, {ROLLOUT}, {MODEL_INFO}",
        models.experiment(),
        models.model_info(&Default::default()).models.join(", ")
    );
    let replies = Replies::default();
    serve_until_stopped(stop, || async {
        futures::select! {
            r = next_state.async_receive_request().fuse() => replies.reply(&next_state, r, |req| models.predict_next_state(req)),
            r = action.async_receive_request().fuse() => replies.reply(&action, r, |req| models.predict_action(req)),
            r = rollout.async_receive_request().fuse() => replies.reply(&rollout, r, |req| models.rollout(req)),
            r = info.async_receive_request().fuse() => replies.reply(&info, r, |req| models.model_info(req)),
            served = replies.resend_due().fuse() => served,
        }
    });
    replies.finish();
    tracing::info!("stopping");
    Ok(())
}

/// Trains the requested models from `bags` into `out`, logging progress (to `/rosout` too).
fn train_first(
    node: &RosNode,
    bags: &[String],
    out: &std::path::Path,
    stop: &Arc<AtomicBool>,
) -> anyhow::Result<()> {
    let params = node.params();
    let bags: Vec<PathBuf> = bags.iter().map(PathBuf::from).collect();
    // Declared ranges keep these non-negative.
    let count = |name: &str| params.integer(name) as usize;
    // -1 asks for the default; 0 epochs or folds would train nothing.
    let optional_count = |name: &str| match params.integer(name) {
        -1 => Ok(None),
        0 => Err(anyhow!(
            "parameter {name}: 0 would train nothing; give at least 1, or -1 for the default"
        )),
        n => Ok(Some(n as usize)),
    };
    let requested = params.string("models");
    let requested: ModelRequest = requested
        .parse()
        .map_err(|e| anyhow!("parameter models: {e}"))?;
    let options = TrainOptions {
        profile: params
            .string("profile")
            .parse()
            .map_err(|e| anyhow!("parameter profile: {e}"))?,
        epochs: optional_count("epochs")?,
        folds: count("folds"),
        max_folds: optional_count("max_folds")?,
        lr_schedule: params
            .string("lr_schedule")
            .parse()
            .map_err(|e| anyhow!("parameter lr_schedule: {e}"))?,
        seed: count("seed") as u64,
        stop: Some(stop.clone()),
        ..TrainOptions::default()
    };
    let cache = match params.string("cache") {
        "" => Cache::new(Cache::default_dir()),
        dir => Cache::new(PathBuf::from(dir)),
    };
    let action = ActionSource::of_bags(&bags)?;
    let (data, _) = load_bags(&bags, None, action, Some(&cache))?;
    tracing::info!(
        "training on {} {} transitions from {}",
        data.rows(),
        data.experiment,
        bags.iter()
            .map(|b| b.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    );
    let kinds = requested.kinds(data.experiment);
    let mut log = ProgressLog::new(LOG_EVERY);
    let saved = train_and_save(&data, &kinds, &options, action, out, &mut |p| {
        if let Some(line) = log.line(&p) {
            tracing::info!("{line}");
        }
    })?;
    for figure in &saved.figures {
        let paper = figure
            .paper
            .map(|p| format!(", paper {p:.3e}"))
            .unwrap_or_default();
        tracing::info!(
            "{}: MAE {:.3e} ± {:.1e} {} (mean baseline {:.3e}{paper})",
            figure.key,
            figure.mean,
            figure.std,
            figure.unit,
            figure.baseline
        );
    }
    tracing::info!(
        "wrote {} model files and {}",
        saved.written.len(),
        saved.metrics.display()
    );
    Ok(())
}

/// Longest silence between training progress lines.
const LOG_EVERY: Duration = Duration::from_secs(5);

fn main() -> std::process::ExitCode {
    node_main(run)
}
