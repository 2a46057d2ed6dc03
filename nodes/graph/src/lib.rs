//! The data-generation graph as ROS 2 nodes: `causal_arm_sim`, `causal_arm_babbler` and
//! `causal_arm_recorder`, each its own process.
//!
//! Lock-step protocol (so nothing is lost and a seed reproduces `causal-arm generate`):
//! 1. the simulator publishes the state of step k on all state topics, one stamp;
//! 2. the babbler, having every state topic for that stamp, publishes `/babbler/action`
//!    with the same stamp; the simulator waits for it and executes it;
//! 3. the recorder buffers messages per stamp, writes a step once all its topics are in
//!    (in the same order as `generate`), and publishes the stamp of the last complete step
//!    on `/recorder/ack`; the simulator never runs more than `ack_window` steps ahead.
//!
//! All three take the same run parameters (`experiment`, `profile`, `steps`, `episodes`,
//! `seed`, `sigma`) with `--ros-args -p name:=value`.

pub mod babbler_node;
pub mod plan;
pub mod recorder_node;
pub mod sim_node;

pub use plan::{RunParams, run_param_specs};

/// Acknowledgement topic of the recorder (`rosgraph_msgs/msg/Clock`: the stamp of the
/// last step it has written completely).
pub const ACK_TOPIC: &str = "/recorder/ack";

/// Installs a SIGINT/SIGTERM handler and returns the flag it sets, so nodes stop cleanly
/// (the recorder finalizes its bag).
pub fn stop_flag() -> std::sync::Arc<std::sync::atomic::AtomicBool> {
    let flag = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let setter = flag.clone();
    if let Err(e) =
        ctrlc::set_handler(move || setter.store(true, std::sync::atomic::Ordering::SeqCst))
    {
        tracing::warn!("cannot install the SIGINT/SIGTERM handler: {e}");
    }
    flag
}

/// Waits up to `timeout` for the next message of `subscription` without polling: the
/// rustdds reader wakes us as soon as a sample arrives (this is the lock-step's latency).
pub fn take_next<M: 'static + serde::de::DeserializeOwned>(
    subscription: &ros2_client::Subscription<M>,
    timeout: std::time::Duration,
) -> Option<anyhow::Result<M>> {
    if let Ok(Some((m, _))) = subscription.take() {
        return Some(Ok(m));
    }
    smol::block_on(smol::future::or(
        async {
            Some(
                subscription
                    .async_take()
                    .await
                    .map(|(m, _)| m)
                    .map_err(|e| anyhow::anyhow!("reading a sample: {e:?}")),
            )
        },
        async {
            smol::Timer::after(timeout).await;
            None
        },
    ))
}

/// Runs a node's main and turns errors into a message and exit code 1.
pub fn node_main(
    run: impl FnOnce(&causal_arm_node::RosArgs) -> anyhow::Result<()>,
) -> std::process::ExitCode {
    let args: Vec<String> = std::env::args().collect();
    let (ros_args, rest) = match causal_arm_node::RosArgs::split(&args) {
        Ok(split) => split,
        Err(e) => {
            eprintln!("error: {e}");
            return std::process::ExitCode::FAILURE;
        }
    };
    if rest.len() > 1 {
        eprintln!(
            "error: unexpected arguments {:?}; node settings are parameters: --ros-args -p name:=value",
            &rest[1..]
        );
        return std::process::ExitCode::FAILURE;
    }
    match run(&ros_args) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
