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
    /// Send a request and print the reply as JSON (`--count N`: N calls, one after another).
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
    /// Calls to make, each once the previous one is answered. With more than one, each
    /// reply is printed as one JSON line, and the round-trip times' p50 / p99 / max go to
    /// stderr.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    count: u32,
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
    S::Request: ros2_client::Message + Clone,
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
    let mut round_trips = Vec::with_capacity(args.count as usize);
    for _ in 0..args.count {
        let sent = Instant::now();
        let response = call_once(&client, request.clone(), &args.name, timeout)?;
        round_trips.push(sent.elapsed());
        if args.count == 1 {
            println!("{}", serde_json::to_string_pretty(&response)?);
        } else {
            println!("{}", serde_json::to_string(&response)?);
        }
    }
    if args.count > 1 {
        eprintln!("{}", round_trip_summary(&mut round_trips));
    }
    Ok(())
}

/// Sends `request` and waits up to `timeout` for its reply.
fn call_once<Req, Resp>(
    client: &ros2_client::Client<Req, Resp>,
    request: Req,
    name: &str,
    timeout: Duration,
) -> anyhow::Result<Resp>
where
    Req: ros2_client::Message + 'static,
    Resp: ros2_client::Message + 'static,
{
    let id = client
        .send_request(request)
        .map_err(|e| anyhow::anyhow!("sending the request: {e:?}"))?;
    let deadline = Instant::now() + timeout;
    while Instant::now() < deadline {
        match client.receive_response() {
            Ok(Some((reply_id, response))) if reply_id == id => return Ok(response),
            Ok(_) => std::thread::sleep(REPLY_POLL),
            Err(e) => bail!("reading the reply: {e:?}"),
        }
    }
    bail!("no reply from {name} within {timeout:?}")
}

/// How often a waiting call looks for its reply: well below a loopback round trip's
/// share of a one-row call (~0.3 ms), so `--count` times the service, not the polling.
const REPLY_POLL: Duration = Duration::from_micros(50);

/// "N calls: p50 … ms, p99 … ms, max … ms" (nearest-rank percentiles).
fn round_trip_summary(round_trips: &mut [Duration]) -> String {
    round_trips.sort();
    let n = round_trips.len();
    let rank = |p: f64| round_trips[((p * n as f64).ceil() as usize).clamp(1, n) - 1];
    let ms = |d: Duration| d.as_secs_f64() * 1e3;
    format!(
        "{n} calls: round trip p50 {:.3} ms, p99 {:.3} ms, max {:.3} ms",
        ms(rank(0.50)),
        ms(rank(0.99)),
        ms(round_trips[n - 1])
    )
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_summary_gives_nearest_rank_percentiles() {
        let mut trips: Vec<Duration> = (1..=100).rev().map(Duration::from_millis).collect();
        assert_eq!(
            round_trip_summary(&mut trips),
            "100 calls: round trip p50 50.000 ms, p99 99.000 ms, max 100.000 ms"
        );
        let mut one = vec![Duration::from_micros(250)];
        assert_eq!(
            round_trip_summary(&mut one),
            "1 calls: round trip p50 0.250 ms, p99 0.250 ms, max 0.250 ms"
        );
    }
}
