//! Process-level helpers every node binary shares: clean stop on SIGINT/SIGTERM, waiting
//! for samples without polling, and turning a node's error into a message and exit code.

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
