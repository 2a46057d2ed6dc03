//! Process-level helpers every node binary shares: clean stop on SIGINT/SIGTERM, waiting
//! for samples without polling, and turning a node's error into a message and exit code.

pub use crate::runtime::stop_flag;

/// Waits up to `timeout` for the next message of `subscription` without polling: the
/// rustdds reader wakes us as soon as a sample arrives (this is the lock-step's latency).
/// The sample comes with its [`ros2_client::MessageInfo`] (who wrote it).
pub fn take_next<M: 'static + serde::de::DeserializeOwned>(
    subscription: &ros2_client::Subscription<M>,
    timeout: std::time::Duration,
) -> Option<anyhow::Result<(M, ros2_client::MessageInfo)>> {
    if let Ok(Some(taken)) = subscription.take() {
        return Some(Ok(taken));
    }
    crate::runtime::block_on_timeout(subscription.async_take(), timeout)
        .map(|taken| taken.map_err(|e| anyhow::anyhow!("reading a sample: {e:?}")))
}

/// What one turn of a service node's loop did (see [`serve_until_stopped`]).
pub enum Served {
    /// A request was answered.
    Replied,
    /// A request was handled but its reply could not be sent.
    ReplyNotSent,
    /// A request arrived that could not be read (rustdds dropped it).
    Unreadable,
    /// A reply waits for its client's reply reader (see [`crate::replies::Replies`]).
    Held,
}

/// A service node's main loop: `next()` waits for one request on any of the node's
/// servers and answers it, or for held replies to fall due ([`crate::replies::Replies`]);
/// the loop wakes at least every 200 ms to notice `stop`, logs replies that could not be
/// sent and requests that could not be read, and keeps serving.
pub fn serve_until_stopped<F, Fut>(stop: &std::sync::atomic::AtomicBool, mut next: F)
where
    F: FnMut() -> Fut,
    Fut: std::future::Future<Output = Served>,
{
    while !stop.load(std::sync::atomic::Ordering::SeqCst) {
        let turn = crate::runtime::block_on_timeout(next(), std::time::Duration::from_millis(200));
        match turn {
            None | Some(Served::Replied | Served::Held) => {}
            Some(Served::ReplyNotSent) => tracing::warn!("could not send a reply"),
            Some(Served::Unreadable) => tracing::warn!("could not read a request"),
        }
    }
}

/// Runs a node's main and turns errors into a message and exit code 1.
pub fn node_main(
    run: impl FnOnce(&crate::RosArgs) -> anyhow::Result<()>,
) -> std::process::ExitCode {
    let args: Vec<String> = std::env::args().collect();
    let (ros_args, rest) = match crate::RosArgs::split(&args) {
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
