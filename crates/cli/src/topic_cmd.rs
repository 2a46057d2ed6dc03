//! `causal-arm topic pub|echo`: publish and print any message type the project knows,
//! as JSON, like `ros2 topic pub/echo` — the Rust peer in interop tests and a debugging
//! tool for users without a ROS 2 install.

use std::io::Write as _;
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};
use causal_arm_msgs::{MessageTypeVisitor, RosMessage, visit_message_type};
use causal_arm_node::{RosArgs, RosNode, qos};
use clap::{Args, Subcommand};

/// `causal-arm topic …`
#[derive(Debug, Args)]
pub struct TopicArgs {
    #[command(subcommand)]
    command: TopicCommand,
}

#[derive(Debug, Subcommand)]
enum TopicCommand {
    /// Publish JSON messages on a topic.
    Pub(PubArgs),
    /// Print messages received on a topic, one JSON object per line.
    Echo(EchoArgs),
    /// List the message types this build knows.
    Types,
}

#[derive(Debug, Args)]
struct PubArgs {
    /// Topic name, e.g. /joint_states.
    topic: String,
    /// Message type, e.g. sensor_msgs/msg/JointState.
    #[arg(long = "type")]
    msg_type: String,
    /// Message as JSON (field names as in the .msg file). Missing fields take defaults.
    #[arg(long)]
    json: String,
    /// How many times to publish it.
    #[arg(long, default_value_t = 1)]
    count: u64,
    /// Publishing rate in Hz.
    #[arg(allow_negative_numbers = true, long, default_value_t = 10.0)]
    rate: f64,
    /// Wait until this many subscribers matched before publishing.
    #[arg(long, default_value_t = 0)]
    wait_subscribers: usize,
    /// Give up waiting for subscribers after this many seconds.
    #[arg(allow_negative_numbers = true, long, default_value_t = 30.0)]
    timeout: f64,
    /// QoS profile: recorded, clock, latched, default, services, best_effort.
    #[arg(long, default_value = "default", value_parser = clap::builder::PossibleValuesParser::new(qos::PROFILE_NAMES))]
    qos: String,
    /// After subscribers matched, wait up to this long until they have matched us on their
    /// side too (a reader drops samples from writers it has not matched yet; a reliable
    /// one confirms with its first ACKNACK).
    #[arg(allow_negative_numbers = true, long, default_value_t = 0.5)]
    settle: f64,
    /// Keep the writer alive this long after the last sample so reliable delivery completes.
    #[arg(allow_negative_numbers = true, long, default_value_t = 1.0)]
    linger: f64,
}

#[derive(Debug, Args)]
struct EchoArgs {
    /// Topic name, e.g. /joint_states.
    topic: String,
    /// Message type, e.g. sensor_msgs/msg/JointState.
    #[arg(long = "type")]
    msg_type: String,
    /// Exit after this many messages (0 = run until interrupted).
    #[arg(long, default_value_t = 0)]
    count: u64,
    /// Fail if `count` messages did not arrive within this many seconds (0 = no limit).
    #[arg(allow_negative_numbers = true, long, default_value_t = 0.0)]
    timeout: f64,
    /// QoS profile: recorded, clock, latched, default, services, best_effort.
    #[arg(long, default_value = "default", value_parser = clap::builder::PossibleValuesParser::new(qos::PROFILE_NAMES))]
    qos: String,
}

/// Runs `causal-arm topic …`.
pub fn run(args: &TopicArgs, ros_args: &RosArgs) -> anyhow::Result<()> {
    match &args.command {
        TopicCommand::Types => {
            for t in causal_arm_msgs::message_types() {
                println!("{t}");
            }
            Ok(())
        }
        TopicCommand::Pub(a) => visit(&a.msg_type, PubVisitor { args: a, ros_args })?,
        TopicCommand::Echo(a) => visit(&a.msg_type, EchoVisitor { args: a, ros_args })?,
    }
}

fn visit<V: MessageTypeVisitor<Output = anyhow::Result<()>>>(
    msg_type: &str,
    v: V,
) -> anyhow::Result<anyhow::Result<()>> {
    visit_message_type(msg_type, v)
        .map_err(|e| anyhow::anyhow!("{e}; run `causal-arm topic types` for the list"))
}

fn qos_profile(name: &str) -> anyhow::Result<ros2_client::QosProfile> {
    qos::by_name(name).with_context(|| {
        format!(
            "unknown --qos {name:?}; expected one of {}",
            qos::PROFILE_NAMES.join(", ")
        )
    })
}

fn positive_seconds(value: f64, flag: &str) -> anyhow::Result<Duration> {
    Duration::try_from_secs_f64(value)
        .with_context(|| format!("{flag} must be a non-negative number of seconds, got {value}"))
}

struct PubVisitor<'a> {
    args: &'a PubArgs,
    ros_args: &'a RosArgs,
}

impl MessageTypeVisitor for PubVisitor<'_> {
    type Output = anyhow::Result<()>;

    fn visit<M: RosMessage>(self) -> anyhow::Result<()> {
        let a = self.args;
        let value: serde_json::Value = serde_json::from_str(&a.json)
            .with_context(|| format!("--json is not valid JSON: {}", a.json))?;
        let message: M = serde_json::from_value(value)
            .with_context(|| format!("--json does not match {}", M::ROS_TYPE))?;
        if !(a.rate > 0.0 && a.rate.is_finite()) {
            bail!("--rate must be a positive number of Hz, got {}", a.rate);
        }
        let period = Duration::from_secs_f64(1.0 / a.rate);
        let timeout = positive_seconds(a.timeout, "--timeout")?;
        let linger = positive_seconds(a.linger, "--linger")?;
        let qos = qos_profile(&a.qos)?;
        let mut node = RosNode::new("causal_arm_topic_pub", &[], self.ros_args)?;
        let publisher = node.publisher::<M>(&a.topic, qos)?;
        if a.wait_subscribers > 0 {
            let never = std::sync::atomic::AtomicBool::new(false);
            let settle = positive_seconds(a.settle, "--settle")?;
            if !node.wait_for_subscribers(&publisher, a.wait_subscribers, timeout, settle, &never) {
                bail!(
                    "{} subscriber(s) of {} did not appear within {:.1} s",
                    a.wait_subscribers,
                    a.topic,
                    a.timeout
                );
            }
        }
        for i in 0..a.count {
            publisher
                .publish(message.clone())
                .map_err(|e| anyhow::anyhow!("publishing on {}: {e:?}", a.topic))?;
            if i + 1 < a.count {
                std::thread::sleep(period);
            }
        }
        std::thread::sleep(linger);
        Ok(())
    }
}

struct EchoVisitor<'a> {
    args: &'a EchoArgs,
    ros_args: &'a RosArgs,
}

impl MessageTypeVisitor for EchoVisitor<'_> {
    type Output = anyhow::Result<()>;

    fn visit<M: RosMessage>(self) -> anyhow::Result<()> {
        let a = self.args;
        let qos = qos_profile(&a.qos)?;
        let timeout = positive_seconds(a.timeout, "--timeout")?;
        let mut node = RosNode::new("causal_arm_topic_echo", &[], self.ros_args)?;
        let subscription = node.subscription::<M>(&a.topic, qos)?;
        let start = Instant::now();
        let mut received = 0u64;
        let stdout = std::io::stdout();
        while a.count == 0 || received < a.count {
            match subscription.take() {
                Ok(Some((msg, _info))) => {
                    received += 1;
                    let mut out = stdout.lock();
                    serde_json::to_writer(&mut out, &msg)?;
                    writeln!(out)?;
                    out.flush()?;
                }
                Ok(None) => std::thread::sleep(Duration::from_millis(2)),
                Err(e) => tracing::warn!("dropping undecodable sample on {}: {e:?}", a.topic),
            }
            if !timeout.is_zero() && start.elapsed() > timeout {
                bail!(
                    "received {received} of {} message(s) on {} within {:.1} s",
                    a.count,
                    a.topic,
                    a.timeout
                );
            }
        }
        Ok(())
    }
}
