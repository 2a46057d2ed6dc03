//! Logging: `tracing` everywhere, printed to stderr and forwarded to `/rosout`.
//!
//! Node code only uses `tracing::info!` and friends. [`init`] installs a subscriber that
//! prints (filtered by `RUST_LOG`, default `info`) and, once a node exists
//! ([`attach_rosout`]), also publishes every event of level INFO and above as
//! `rcl_interfaces/Log` on `/rosout`, so `ros2 topic echo /rosout` and rqt_console see it.

use std::cell::Cell;
use std::fmt::Write as _;
use std::io::IsTerminal as _;
use std::sync::{Mutex, OnceLock};
use std::thread::ThreadId;

use ros2_client::{NodeLoggingHandle, RosoutRaw, builtin_interfaces::Time, ros2::LogLevel};
use tracing::field::{Field, Visit};
use tracing::{Event, Level, Subscriber};
use tracing_subscriber::layer::{Context, SubscriberExt};
use tracing_subscriber::{EnvFilter, Layer};

/// The rosout writer of each node in the process, with the thread it runs on: several
/// nodes composed in one process each log as themselves (see [`attach_rosout`]).
static ROSOUT: OnceLock<Mutex<Vec<(ThreadId, NodeLoggingHandle)>>> = OnceLock::new();

thread_local! {
    static FORWARDING: Cell<bool> = const { Cell::new(false) };
}

/// Installs the process-wide subscriber. Safe to call more than once (later calls are
/// no-ops), so tests and binaries can both call it.
pub fn init() {
    init_with_level(None);
}

/// Like [`init`], with a default level from `--ros-args --log-level` when `RUST_LOG` is unset.
pub fn init_with_level(level: Option<&str>) {
    let default = level.unwrap_or("info");
    // DDS internals are chatty at info; keep them at warn unless asked.
    let filter = EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| EnvFilter::new(format!("{default},rustdds=warn,ros2_client=warn")));
    let fmt = tracing_subscriber::fmt::layer()
        .with_writer(std::io::stderr)
        // Colours on a terminal only: logs piped to a file or a launcher stay plain lines.
        .with_ansi(std::io::stderr().is_terminal())
        .with_target(false)
        .with_filter(filter);
    let subscriber = tracing_subscriber::registry().with(fmt).with(RosoutLayer);
    if tracing::subscriber::set_global_default(subscriber).is_ok() {
        // rustdds logs through `log`; bridge only its errors (its warnings are noise
        // such as per-datagram size notes), unless RUST_LOG names rustdds: then what
        // the filter lets through, for debugging DDS.
        // discovery_db reports ros2-client's own /clock reader (typed builtin_interfaces/Time)
        // meeting our correctly typed rosgraph_msgs/Clock writers as an error on every start.
        let dds_asked = std::env::var("RUST_LOG").is_ok_and(|v| v.contains("rustdds"));
        if log::set_boxed_logger(Box::new(DdsLogBridge(tracing_log::LogTracer::new()))).is_ok() {
            log::set_max_level(match dds_asked {
                true => log::LevelFilter::Trace,
                false => log::LevelFilter::Error,
            });
        }
    }
}

/// Forwards rustdds's `log` records into `tracing`, except discovery_db's (see [`init`])
/// and one known false alarm.
///
/// When a node exits, its publishers drop together and rustdds queues each writer's
/// removal on a 4-slot channel to its event loop with a 20 ms timeout
/// (`InnerPublisher::remove_writer`). On a busy machine the loop does not drain it in time
/// and rustdds logs "Cannot remove Writer … TrySendError::Full" at ERROR. Nothing is lost:
/// the participant, and with it every writer, is torn down right after. That record goes
/// to DEBUG so a clean run prints no ERROR line; any other rustdds error still shows.
struct DdsLogBridge(tracing_log::LogTracer);

impl DdsLogBridge {
    fn is_writer_removal_at_exit(record: &log::Record<'_>) -> bool {
        record.target().starts_with("rustdds::dds::pubsub") && {
            let text = record.args().to_string();
            text.starts_with("Cannot remove Writer") && text.contains("Full")
        }
    }
}

impl log::Log for DdsLogBridge {
    fn enabled(&self, metadata: &log::Metadata<'_>) -> bool {
        self.0.enabled(metadata)
    }

    fn log(&self, record: &log::Record<'_>) {
        if record
            .target()
            .starts_with("rustdds::discovery::discovery_db")
        {
            return;
        }
        if Self::is_writer_removal_at_exit(record) {
            tracing::debug!(target: "rustdds", "at exit: {}", record.args());
            return;
        }
        self.0.log(record);
    }

    fn flush(&self) {
        self.0.flush();
    }
}

/// Starts forwarding the calling thread's events to `/rosout` through `handle` (the rosout
/// writer of the node this thread runs). Events of threads without a node of their own
/// (DDS, the runtime) go through the first node's.
pub fn attach_rosout(handle: NodeLoggingHandle) {
    let slot = ROSOUT.get_or_init(|| Mutex::new(Vec::new()));
    if let Ok(mut nodes) = slot.lock() {
        let thread = std::thread::current().id();
        nodes.retain(|(t, _)| *t != thread);
        nodes.push((thread, handle));
    }
}

/// Stops forwarding the calling thread's node (called when the node shuts down, before
/// its writer goes away).
pub fn detach_rosout() {
    if let Some(slot) = ROSOUT.get()
        && let Ok(mut nodes) = slot.lock()
    {
        let thread = std::thread::current().id();
        nodes.retain(|(t, _)| *t != thread);
    }
}

/// The `tracing` layer that publishes events on `/rosout`.
struct RosoutLayer;

impl<S: Subscriber> Layer<S> for RosoutLayer {
    fn on_event(&self, event: &Event<'_>, _ctx: Context<'_, S>) {
        let meta = event.metadata();
        if *meta.level() > Level::INFO {
            return;
        }
        // ros2-client echoes rosout into tracing itself; never loop.
        let target = meta.target();
        if target.starts_with("ros2_client") || target.starts_with("rustdds") || target == "log" {
            return;
        }
        let Some(slot) = ROSOUT.get() else { return };
        if FORWARDING.with(|f| f.replace(true)) {
            return;
        }
        let mut message = MessageText::default();
        event.record(&mut message);
        let thread = std::thread::current().id();
        if let Ok(nodes) = slot.lock()
            && let Some((_, handle)) = (nodes.iter().find(|(t, _)| *t == thread)).or(nodes.first())
        {
            let level = match *meta.level() {
                Level::ERROR => LogLevel::Error,
                Level::WARN => LogLevel::Warn,
                _ => LogLevel::Info,
            };
            handle.rosout_raw(
                wall_time(),
                level,
                handle.base_name(),
                &message.0,
                meta.file().unwrap_or(""),
                meta.module_path().unwrap_or(""),
                meta.line().unwrap_or(0),
            );
        }
        FORWARDING.with(|f| f.set(false));
    }
}

/// Renders an event's message and fields as one line.
#[derive(Default)]
struct MessageText(String);

impl Visit for MessageText {
    fn record_debug(&mut self, field: &Field, value: &dyn std::fmt::Debug) {
        if field.name() == "message" {
            let _ = write!(self.0, "{value:?}");
        } else {
            let _ = write!(self.0, " {}={value:?}", field.name());
        }
    }

    fn record_str(&mut self, field: &Field, value: &str) {
        if field.name() == "message" {
            self.0.push_str(value);
        } else {
            let _ = write!(self.0, " {}={value}", field.name());
        }
    }
}

/// Wall-clock stamp for log records (rcl stamps rosout with the system clock too).
fn wall_time() -> Time {
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap_or_default();
    Time::new(now.as_secs() as i32, now.subsec_nanos())
}

#[cfg(test)]
mod tests {
    use super::DdsLogBridge;

    fn downgraded(target: &str, text: std::fmt::Arguments<'_>) -> bool {
        DdsLogBridge::is_writer_removal_at_exit(
            &log::Record::builder()
                .level(log::Level::Error)
                .target(target)
                .args(text)
                .build(),
        )
    }

    #[test]
    fn only_the_writer_removal_notice_at_exit_is_downgraded() {
        let guid = "GUID {01.0f.aa.bb}";
        assert!(downgraded(
            "rustdds::dds::pubsub",
            format_args!("Cannot remove Writer {guid} : Full(..)")
        ));
        // Another failure of the same call, another module, another message: all kept.
        assert!(!downgraded(
            "rustdds::dds::pubsub",
            format_args!("Cannot remove Writer {guid} : Disconnected(..)")
        ));
        assert!(!downgraded(
            "rustdds::dds::participant",
            format_args!("Cannot remove Writer {guid} : Full(..)")
        ));
        assert!(!downgraded(
            "rustdds::dds::pubsub",
            format_args!("Cannot create Writer: Full")
        ));
    }
}
