//! `causal_arm_trainer`: serves a model directory as ROS 2 services
//! (`/trainer/predict_next_state`, `/trainer/predict_action`, `/trainer/rollout`,
//! `/trainer/model_info`). The directory is either written by `causal-arm train` or, with
//! `-p bag:=DIR[,DIR…]`, trained by the node itself first (same files, same metrics).
//! Every request gets a reply; bad ones a `success: false` reply saying why, and the node
//! keeps serving.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use causal_arm_models::node_job::TrainerJob;
use causal_arm_models::serve::ModelSet;
use causal_arm_msgs::srv::{GetModelInfo, PredictAction, PredictNextState, Rollout};
use causal_arm_node::params::TrainerParams;
use causal_arm_node::replies::Replies;
use causal_arm_node::run::{node_main, serve_until_stopped, stop_flag};
use causal_arm_node::{RosArgs, RosNode};
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
    let mut node = RosNode::new(TrainerParams::NODE, &TrainerParams::specs()?, ros_args)?;
    let job = TrainerJob::from_params(&TrainerParams::from_params(node.params())?, stop.clone())?;
    if !job.bags.is_empty() {
        // The files and figures written are logged as they come.
        if let Err(e) = job.train(&mut |line| tracing::info!("{line}")) {
            if stop.load(Ordering::SeqCst) {
                tracing::info!("stopping: {e}");
                return Ok(());
            }
            return Err(e);
        }
    }
    let models = job.load()?;
    serve(
        &mut node,
        &models,
        &job.model_dir.display().to_string(),
        &stop,
    )
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

fn main() -> std::process::ExitCode {
    node_main(run)
}
