//! `causal-arm play BAG`: republish a bag on its topics, with its original timing (scaled
//! by `--rate`) or as fast as possible, like `ros2 bag play`.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};
use causal_arm_bag::BagReader;
use causal_arm_msgs::rosgraph_msgs::msg::Clock;
use causal_arm_msgs::{MessageTypeVisitor, RosMessage, visit_message_type};
use causal_arm_node::{RosArgs, RosNode, qos};
use causal_arm_protocol::time_from_ns;

/// Arguments of `causal-arm play`.
#[derive(Debug, clap::Args)]
pub struct PlayArgs {
    /// How to treat damage in the bags read.
    #[command(flatten)]
    pub read: crate::bag_cmd::ReadArgs,
    /// Bag directory (or .mcap file) to play.
    bag: PathBuf,
    /// Speed factor of the original timing; 0 = as fast as possible.
    #[arg(allow_negative_numbers = true, long, default_value_t = 1.0)]
    rate: f64,
    /// Also publish /clock from the bag's log times (for nodes with use_sim_time).
    #[arg(long)]
    clock: bool,
    /// Only these topics (default: all).
    #[arg(long, num_args = 1..)]
    topics: Vec<String>,
    /// Wait this long for subscribers to match before playing, s.
    #[arg(allow_negative_numbers = true, long, default_value_t = 1.0)]
    delay: f64,
}

type PublishFn = Box<dyn Fn(&[u8]) -> anyhow::Result<()>>;

struct MakePublisher<'a> {
    node: &'a mut RosNode,
    topic: &'a str,
}

impl MessageTypeVisitor for MakePublisher<'_> {
    type Output = anyhow::Result<PublishFn>;
    fn visit<M: RosMessage>(self) -> Self::Output {
        let qos = if causal_arm_protocol::topics::LATCHED.contains(&self.topic) {
            qos::latched()
        } else {
            qos::recorded()
        };
        let publisher = self.node.publisher::<M>(self.topic, qos)?;
        let topic = self.topic.to_owned();
        Ok(Box::new(move |cdr: &[u8]| {
            let msg: M =
                causal_arm_msgs::from_cdr(cdr).with_context(|| format!("decoding {topic}"))?;
            publisher
                .publish(msg)
                .map_err(|e| anyhow::anyhow!("publishing on {topic}: {e:?}"))
        }))
    }
}

/// Runs `causal-arm play`.
pub fn run(args: &PlayArgs, ros_args: &RosArgs) -> anyhow::Result<()> {
    if !(args.rate >= 0.0 && args.rate.is_finite()) {
        bail!("--rate must be a non-negative number, got {}", args.rate);
    }
    let reader = BagReader::open(&args.bag)?;
    if reader.message_count() == 0 {
        bail!(
            "{}: nothing to play (the bag holds no messages)",
            reader.path().display()
        );
    }
    let known: Vec<String> = reader.topics().iter().map(|t| t.name.clone()).collect();
    for t in &args.topics {
        if !known.contains(t) {
            bail!(
                "{}: no topic {t} (topics: {})",
                args.bag.display(),
                known.join(", ")
            );
        }
    }
    let mut node = RosNode::new("causal_arm_player", &[], ros_args)?;
    let mut publishers: BTreeMap<String, PublishFn> = BTreeMap::new();
    for topic in reader.topics() {
        if !args.topics.is_empty() && !args.topics.contains(&topic.name) {
            continue;
        }
        let make = MakePublisher {
            node: &mut node,
            topic: &topic.name,
        };
        let publish = visit_message_type(&topic.ros_type, make)
            .map_err(|e| anyhow::anyhow!("{}: topic {}: {e}", args.bag.display(), topic.name))??;
        publishers.insert(topic.name.clone(), publish);
    }
    let clock = if args.clock {
        Some(node.publisher::<Clock>("/clock", qos::clock())?)
    } else {
        None
    };
    std::thread::sleep(
        Duration::try_from_secs_f64(args.delay).context("--delay must be non-negative")?,
    );
    let start = Instant::now();
    let mut first: Option<u64> = None;
    let mut played = 0u64;
    for raw in reader.messages() {
        let raw = raw?;
        let Some(publish) = publishers.get(&raw.topic) else {
            continue;
        };
        let t0 = *first.get_or_insert(raw.log_time_ns);
        if args.rate > 0.0 {
            let due = Duration::from_secs_f64((raw.log_time_ns - t0) as f64 * 1e-9 / args.rate);
            if let Some(wait) = due.checked_sub(start.elapsed()) {
                std::thread::sleep(wait);
            }
        }
        if let Some(c) = &clock {
            let _ = c.publish(Clock {
                clock: time_from_ns(raw.log_time_ns),
            });
        }
        publish(&raw.data).with_context(|| {
            format!(
                "{}: message {played} ({} at {} ns)",
                reader.path().display(),
                raw.topic,
                raw.log_time_ns
            )
        })?;
        played += 1;
    }
    std::thread::sleep(Duration::from_millis(300));
    println!(
        "played {played} messages from {} in {:.1} s",
        args.bag.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}
