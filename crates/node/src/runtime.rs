//! The one async runtime of a node process: tokio. ros2-client's spinner runs on it as a
//! task, SIGINT/SIGTERM arrive through its signal driver, and the nodes' blocking loops
//! wait on DDS futures with its timers. One worker thread is enough: the futures only
//! wait for rustdds, which does its own I/O on its event-loop thread.

use std::future::Future;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::Duration;

use tokio::runtime::Runtime;

/// The process's runtime, started on first use.
pub fn runtime() -> &'static Runtime {
    static RUNTIME: OnceLock<Runtime> = OnceLock::new();
    RUNTIME.get_or_init(|| {
        tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .thread_name("ros-runtime")
            .enable_all()
            .build()
            .expect("the tokio runtime starts (threads and a timer are all it needs)")
    })
}

/// Runs `future` to completion on the runtime, or gives up after `timeout` (`None`).
/// Called from the nodes' plain threads, never from inside the runtime.
pub fn block_on_timeout<F: Future>(future: F, timeout: Duration) -> Option<F::Output> {
    runtime().block_on(async { tokio::time::timeout(timeout, future).await.ok() })
}

/// Waits for a DDS match: `arm()` makes one ros2-client wait, which is given `rearm` and
/// then made afresh, until one completes (`true`) or `give_up()` says so (`false`).
///
/// ros2-client's waits listen to an 8-slot event channel whose sender drops events when it
/// is full (a busy machine, a big graph), so a single wait can miss its match for good;
/// each fresh wait re-reads the current match state before it listens.
pub fn wait_rearmed<F: Future>(
    mut arm: impl FnMut() -> F,
    rearm: Duration,
    give_up: impl Fn() -> bool,
) -> bool {
    loop {
        if block_on_timeout(arm(), rearm).is_some() {
            return true;
        }
        if give_up() {
            return false;
        }
    }
}

/// A flag set by the first SIGINT or SIGTERM, so nodes stop cleanly (the recorder then
/// finalizes its bag). Every call shares one flag; the handlers stay installed, so a
/// second signal does not kill the process halfway through finalizing.
pub fn stop_flag() -> Arc<AtomicBool> {
    static FLAG: OnceLock<Arc<AtomicBool>> = OnceLock::new();
    FLAG.get_or_init(|| {
        let flag = Arc::new(AtomicBool::new(false));
        if let Err(e) = watch_signals(flag.clone()) {
            tracing::warn!("cannot install the SIGINT/SIGTERM handlers: {e}");
        }
        flag
    })
    .clone()
}

/// Registers the handlers now (so no signal can slip by before the task runs) and sets
/// `flag` from a runtime task when one arrives.
fn watch_signals(flag: Arc<AtomicBool>) -> std::io::Result<()> {
    use tokio::signal::unix::{SignalKind, signal};
    let _context = runtime().enter();
    let mut interrupt = signal(SignalKind::interrupt())?;
    let mut terminate = signal(SignalKind::terminate())?;
    runtime().spawn(async move {
        loop {
            tokio::select! {
                _ = interrupt.recv() => {}
                _ = terminate.recv() => {}
            }
            flag.store(true, Ordering::SeqCst);
        }
    });
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_future_that_never_ends_times_out() {
        let started = std::time::Instant::now();
        let out = block_on_timeout(std::future::pending::<()>(), Duration::from_millis(50));
        assert!(out.is_none());
        assert!(started.elapsed() >= Duration::from_millis(50));
    }

    #[test]
    fn a_rearmed_wait_sees_a_match_a_single_wait_would_miss() {
        // The first two waits never complete (their event was dropped); the third sees the
        // match state directly.
        let tries = std::cell::Cell::new(0);
        let matched = wait_rearmed(
            || {
                tries.set(tries.get() + 1);
                let ready = tries.get() >= 3;
                async move {
                    if !ready {
                        std::future::pending::<()>().await;
                    }
                }
            },
            Duration::from_millis(10),
            || false,
        );
        assert!(matched);
        assert_eq!(tries.get(), 3);
        assert!(!wait_rearmed(
            std::future::pending::<()>,
            Duration::from_millis(5),
            || true
        ));
    }

    #[test]
    fn a_ready_future_gives_its_value() {
        assert_eq!(
            block_on_timeout(async { 7 }, Duration::from_secs(5)),
            Some(7)
        );
    }

    #[test]
    fn sigterm_sets_the_stop_flag_and_the_process_survives() {
        let flag = stop_flag();
        assert!(!flag.load(Ordering::SeqCst));
        // SAFETY: raising a signal at our own process, whose handler is installed above.
        unsafe { libc::raise(libc::SIGTERM) };
        let deadline = std::time::Instant::now() + Duration::from_secs(5);
        while !flag.load(Ordering::SeqCst) && std::time::Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(5));
        }
        assert!(flag.load(Ordering::SeqCst), "SIGTERM did not set the flag");
        assert!(Arc::ptr_eq(&flag, &stop_flag()), "one flag per process");
    }
}
