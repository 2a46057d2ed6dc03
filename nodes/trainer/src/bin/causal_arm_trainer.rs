//! `causal_arm_trainer`: serves a model directory written by `causal-arm train` as ROS 2
//! services (`/trainer/predict_next_state`, `/trainer/predict_action`, `/trainer/rollout`,
//! `/trainer/model_info`). Every request gets a reply; bad ones a `success: false` reply
//! saying why, and the node keeps serving.

use anyhow::bail;
use causal_arm_msgs::srv::{GetModelInfo, PredictAction, PredictNextState, Rollout};
use causal_arm_node::run::{Served, node_main, serve_until_stopped, stop_flag};
use causal_arm_node::{ParamSpec, ParamValue, RosArgs, RosNode};
use causal_arm_trainer::serve::ModelSet;
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
    let specs = [
        ParamSpec::new(
            "model_dir",
            ParamValue::String(String::new()),
            "directory written by `causal-arm train --out`",
        ),
        ParamSpec::new(
            "forward_model",
            ParamValue::String("fm".into()),
            "model file serving predict_next_state and rollout",
        ),
        ParamSpec::new(
            "inverse_model",
            ParamValue::String("im-mono".into()),
            "model file serving predict_action",
        ),
    ];
    let mut node = RosNode::new("causal_arm_trainer", &specs, ros_args)?;
    let dir = node.params().string("model_dir").to_owned();
    if dir.is_empty() {
        bail!(
            "parameter model_dir is required: --ros-args -p model_dir:=DIR (a directory written by `causal-arm train`)"
        );
    }
    let models = ModelSet::load(
        std::path::Path::new(&dir),
        node.params().string("forward_model"),
        node.params().string("inverse_model"),
    )?;
    let next_state = node.server::<PredictNextState>(PREDICT_NEXT_STATE)?;
    let action = node.server::<PredictAction>(PREDICT_ACTION)?;
    let rollout = node.server::<Rollout>(ROLLOUT)?;
    let info = node.server::<GetModelInfo>(MODEL_INFO)?;
    tracing::info!(
        "serving {} models from {dir} ({}): {PREDICT_NEXT_STATE}, {PREDICT_ACTION}, {ROLLOUT}, {MODEL_INFO}",
        models.experiment(),
        models.model_info(&Default::default()).models.join(", ")
    );
    serve_until_stopped(&stop, || async {
        futures::select! {
            r = next_state.async_receive_request().fuse() => Served::from_turn(r.map(|(id, req)| next_state.send_response(id, models.predict_next_state(&req)).is_ok())),
            r = action.async_receive_request().fuse() => Served::from_turn(r.map(|(id, req)| action.send_response(id, models.predict_action(&req)).is_ok())),
            r = rollout.async_receive_request().fuse() => Served::from_turn(r.map(|(id, req)| rollout.send_response(id, models.rollout(&req)).is_ok())),
            r = info.async_receive_request().fuse() => Served::from_turn(r.map(|(id, req)| info.send_response(id, models.model_info(&req)).is_ok())),
        }
    });
    tracing::info!("stopping");
    Ok(())
}

fn main() -> std::process::ExitCode {
    node_main(run)
}
