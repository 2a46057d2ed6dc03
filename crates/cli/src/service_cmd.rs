//! `causal-arm service call`: call one of the project's services with a JSON request and
//! print the JSON reply (like `ros2 service call`).

use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use causal_arm_msgs::RosService;
use causal_arm_msgs::srv::{Explain, GetModelInfo, PredictAction, PredictNextState, Rollout};
use causal_arm_node::{RosArgs, RosNode};
use clap::{Args, Subcommand};

/// `causal-arm service …`
#[derive(Debug, Args)]
pub struct ServiceArgs {
    #[command(subcommand)]
    command: ServiceCommand,
}

#[derive(Debug, Subcommand)]
enum ServiceCommand {
    /// Send one request and print the reply as JSON.
    Call(CallArgs),
}

/// Arguments of `service call`.
#[derive(Debug, Args)]
struct CallArgs {
    /// Service name, e.g. /trainer/predict_next_state.
    name: String,
    /// Service type, e.g. causal_arm_msgs/srv/PredictNextState.
    #[arg(long = "type")]
    service_type: String,
    /// Request as JSON (fields of the request part of the .srv), or `@FILE` to read it
    /// from a file (large requests do not fit on a command line).
    #[arg(long, default_value = "{}")]
    json: String,
    /// Seconds to wait for the server and for the reply.
    #[arg(allow_negative_numbers = true, long, default_value_t = 10.0)]
    timeout: f64,
}

/// Pause after the server is seen, so it can see us too before the request goes out.
const SERVER_SETTLE: Duration = Duration::from_secs(1);

const TYPES: [&str; 5] = [
    "causal_arm_msgs/srv/PredictNextState",
    "causal_arm_msgs/srv/PredictAction",
    "causal_arm_msgs/srv/Rollout",
    "causal_arm_msgs/srv/GetModelInfo",
    "causal_arm_msgs/srv/Explain",
];

fn call<S: RosService>(args: &CallArgs, ros_args: &RosArgs) -> anyhow::Result<()>
where
    S::Request: ros2_client::Message,
    S::Response: ros2_client::Message,
{
    let text = match args.json.strip_prefix('@') {
        Some(file) => std::fs::read_to_string(file)
            .with_context(|| format!("--json @{file}: cannot read the request file"))?,
        None => args.json.clone(),
    };
    let request: S::Request = serde_json::from_str(&text)
        .with_context(|| format!("--json does not match the request of {}", S::ROS_TYPE))?;
    if !(args.timeout.is_finite() && args.timeout > 0.0) {
        bail!(
            "--timeout must be a positive number of seconds, got {}",
            args.timeout
        );
    }
    let timeout = Duration::from_secs_f64(args.timeout);
    let mut node = RosNode::new("causal_arm_service_call", &[], ros_args)?;
    let client = node.client::<S>(&args.name)?;
    // Matching is only known from our side: a volatile server reader that has not yet
    // matched our request writer drops the request (Fast DDS skips what was sent before its
    // first HEARTBEAT). 300 ms lost a request now and then on a loaded machine; 1 s did not.
    if !node.wait_for_service(&client, timeout, SERVER_SETTLE) {
        bail!(
            "no server of {} ({}) appeared within {timeout:?}",
            args.name,
            S::ROS_TYPE
        );
    }
    let id = client
        .send_request(request)
        .map_err(|e| anyhow::anyhow!("sending the request: {e:?}"))?;
    let deadline = Instant::now() + timeout;
    while Instant::now() < deadline {
        match client.receive_response() {
            Ok(Some((reply_id, response))) if reply_id == id => {
                println!("{}", serde_json::to_string_pretty(&response)?);
                return Ok(());
            }
            Ok(_) => std::thread::sleep(Duration::from_millis(1)),
            Err(e) => bail!("reading the reply: {e:?}"),
        }
    }
    bail!("no reply from {} within {timeout:?}", args.name)
}

/// Runs `causal-arm service …`.
pub fn run(args: &ServiceArgs, ros_args: &RosArgs) -> anyhow::Result<()> {
    let ServiceCommand::Call(call_args) = &args.command;
    match call_args.service_type.as_str() {
        "causal_arm_msgs/srv/PredictNextState" => call::<PredictNextState>(call_args, ros_args),
        "causal_arm_msgs/srv/PredictAction" => call::<PredictAction>(call_args, ros_args),
        "causal_arm_msgs/srv/Rollout" => call::<Rollout>(call_args, ros_args),
        "causal_arm_msgs/srv/GetModelInfo" => call::<GetModelInfo>(call_args, ros_args),
        "causal_arm_msgs/srv/Explain" => call::<Explain>(call_args, ros_args),
        other => bail!(
            "unknown service type {other:?}; expected one of {}",
            TYPES.join(", ")
        ),
    }
}
