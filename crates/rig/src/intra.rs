//! In-process delivery between nodes composed into one process (`causal-arm launch
//! --composed`), as rclcpp's intra-process manager does for a component container: a
//! publisher hands each message straight to the subscribers of its topic that live in the
//! same process, and writes it on DDS as well, so `ros2 topic echo`, another recorder or
//! any outside node still sees every topic, with its type and QoS, as before.
//!
//! Which links exist is read from the graph file: a node of the container that subscribes
//! to a topic another node of the container publishes gets it in process, and does not
//! subscribe to it on DDS (as rclcpp's intra-process subscriptions ignore their own
//! process's DDS samples). Each link is an unbounded channel: the lock-step and the
//! simulator's acknowledgement window already bound how far a publisher runs ahead.

use std::any::Any;
use std::collections::{BTreeMap, BTreeSet};
use std::sync::Mutex;
use std::sync::mpsc::{Receiver, Sender, channel};

use anyhow::{anyhow, bail};
use causal_arm_msgs::RosMessage;
use causal_arm_protocol::graph::GraphSpec;

/// One link's channel, made by whichever side asks first (the node threads start in any
/// order); what was sent before the subscriber took its end waits in the channel.
struct Link<M> {
    sender: Sender<M>,
    receiver: Option<Receiver<M>>,
}

/// The in-process links of one container: (topic, subscribing node) → channel.
pub struct IntraBus {
    links: Mutex<BTreeMap<(String, String), Box<dyn Any + Send>>>,
    /// The in-process subscribers of each topic.
    subscribers: BTreeMap<String, BTreeSet<String>>,
}

impl IntraBus {
    /// The links among `nodes` (names of the graph file's nodes run in this process): each
    /// topic one of them subscribes and another of them publishes.
    pub fn for_nodes(graph: &GraphSpec, nodes: &[&str]) -> anyhow::Result<Self> {
        let mut subscribers: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
        for &name in nodes {
            let node = graph
                .node(name)
                .ok_or_else(|| anyhow!("the graph file declares no node {name}"))?;
            for topic in &node.subscribes {
                let local_publisher = graph
                    .publishers_of(topic)
                    .any(|p| p.name != name && nodes.contains(&p.name.as_str()));
                if local_publisher {
                    subscribers
                        .entry(topic.clone())
                        .or_default()
                        .insert(name.to_owned());
                }
            }
        }
        Ok(Self {
            links: Mutex::new(BTreeMap::new()),
            subscribers,
        })
    }

    /// `node`'s view of the bus.
    pub fn port<'a>(&'a self, node: &'a str) -> IntraPort<'a> {
        IntraPort { bus: self, node }
    }

    /// Runs `use_link` on the link of `topic` to `subscriber`, making it if it is new.
    fn with_link<M: Send + 'static, T>(
        &self,
        topic: &str,
        subscriber: &str,
        use_link: impl FnOnce(&mut Link<M>) -> T,
    ) -> anyhow::Result<T> {
        let mut links = self
            .links
            .lock()
            .map_err(|_| anyhow!("in-process links poisoned by a node that panicked"))?;
        let slot = links
            .entry((topic.to_owned(), subscriber.to_owned()))
            .or_insert_with(|| {
                let (sender, receiver) = channel::<M>();
                Box::new(Link {
                    sender,
                    receiver: Some(receiver),
                })
            });
        let link = slot.downcast_mut::<Link<M>>().ok_or_else(|| {
            anyhow!(
                "{topic} is carried in process as {}, but {subscriber}'s link holds another type",
                std::any::type_name::<M>()
            )
        })?;
        Ok(use_link(link))
    }
}

/// One node's end of an [`IntraBus`].
#[derive(Clone, Copy)]
pub struct IntraPort<'a> {
    bus: &'a IntraBus,
    node: &'a str,
}

impl IntraPort<'_> {
    /// Whether this node takes `topic` in process (and so must not subscribe on DDS).
    pub fn takes(&self, topic: &str) -> bool {
        self.bus
            .subscribers
            .get(topic)
            .is_some_and(|s| s.contains(self.node))
    }

    /// The receiving end of `topic` for this node; `None` when it comes over DDS.
    pub fn receiver<M: Send + 'static>(&self, topic: &str) -> anyhow::Result<Option<Receiver<M>>> {
        if !self.takes(topic) {
            return Ok(None);
        }
        match self
            .bus
            .with_link(topic, self.node, |l: &mut Link<M>| l.receiver.take())?
        {
            Some(receiver) => Ok(Some(receiver)),
            None => bail!("{} took its in-process end of {topic} twice", self.node),
        }
    }

    /// One sender per in-process subscriber of `topic` (none: DDS only).
    pub fn senders<M: Send + 'static>(&self, topic: &str) -> anyhow::Result<Vec<Sender<M>>> {
        let Some(subscribers) = self.bus.subscribers.get(topic) else {
            return Ok(Vec::new());
        };
        subscribers
            .iter()
            .filter(|s| s.as_str() != self.node)
            .map(|s| {
                self.bus
                    .with_link(topic, s, |l: &mut Link<M>| l.sender.clone())
            })
            .collect()
    }
}

/// The receiving end of `topic` when `port` (if any) takes it in process; `None`: it comes
/// over DDS.
pub fn local_receiver<M: Send + 'static>(
    port: Option<IntraPort<'_>>,
    topic: &str,
) -> anyhow::Result<Option<Receiver<M>>> {
    match port {
        Some(port) => port.receiver(topic),
        None => Ok(None),
    }
}

/// A publisher that hands each message to the topic's in-process subscribers and writes
/// it on DDS for everyone else.
pub struct Outlet<M: serde::Serialize> {
    dds: ros2_client::Publisher<M>,
    local: Vec<Sender<M>>,
    topic: &'static str,
}

impl<M: RosMessage + Clone + Send + 'static> Outlet<M> {
    /// `node`'s DDS publisher of `topic` with `qos`, plus the topic's in-process
    /// subscribers on `port` (if any).
    pub fn open(
        node: &mut causal_arm_node::RosNode,
        port: Option<IntraPort<'_>>,
        topic: &'static str,
        qos: ros2_client::QosProfile,
    ) -> anyhow::Result<Self> {
        let local = match port {
            Some(port) => port.senders(topic)?,
            None => Vec::new(),
        };
        let dds = node.publisher(topic, qos)?;
        Ok(Self { dds, local, topic })
    }

    /// In-process subscribers this outlet feeds (they are not DDS readers to wait for).
    pub fn local_subscribers(&self) -> usize {
        self.local.len()
    }

    /// The DDS side, for waits on its readers.
    pub fn dds(&self) -> &ros2_client::Publisher<M> {
        &self.dds
    }

    /// Hands `message` to every in-process subscriber, then writes it on DDS. A subscriber
    /// that has already stopped is not an error: the node that stops first ends the run.
    pub fn publish(&self, message: M) -> Result<(), String> {
        for sender in &self.local {
            let _ = sender.send(message.clone());
        }
        self.dds
            .publish(message)
            .map_err(|e| format!("publishing on {}: {e:?}", self.topic))
    }
}

/// A subscription that is a DDS reader, or an in-process link when a node composed with
/// this one publishes the topic. For topics whose samples are taken as they come, without
/// screening their writers (the latched ones).
pub enum Inlet<M> {
    /// Over DDS.
    Dds(Box<ros2_client::Subscription<M>>),
    /// From a node in this process.
    Local(Receiver<M>),
}

impl<M: RosMessage + Send + 'static> Inlet<M> {
    /// `topic` for `node`: in process if `port` takes it, else a DDS reader with `qos`.
    pub fn open(
        node: &mut causal_arm_node::RosNode,
        port: Option<IntraPort<'_>>,
        topic: &str,
        qos: ros2_client::QosProfile,
    ) -> anyhow::Result<Self> {
        Ok(match local_receiver(port, topic)? {
            Some(receiver) => Self::Local(receiver),
            None => Self::Dds(Box::new(node.subscription(topic, qos)?)),
        })
    }

    /// The next sample already waiting, if any (one DDS could not read is skipped).
    pub fn try_take(&self) -> Option<M> {
        match self {
            Self::Dds(subscription) => subscription.take().ok().flatten().map(|(m, _)| m),
            Self::Local(receiver) => receiver.try_recv().ok(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use causal_arm_protocol::graph::graph;
    use causal_arm_protocol::topics;

    const ALL: [&str; 3] = [
        "causal_arm_sim",
        "causal_arm_babbler",
        "causal_arm_recorder",
    ];

    #[test]
    fn the_links_follow_the_graph_file() {
        let bus = IntraBus::for_nodes(graph().unwrap(), &ALL).unwrap();
        let babbler = bus.port("causal_arm_babbler");
        let recorder = bus.port("causal_arm_recorder");
        let sim = bus.port("causal_arm_sim");
        assert!(babbler.takes(topics::JOINT_STATES));
        assert!(
            !babbler.takes(topics::CLOCK),
            "the babbler does not read /clock"
        );
        assert!(recorder.takes(topics::ACTION) && recorder.takes(topics::TF_STATIC));
        assert!(sim.takes(topics::ACTION) && sim.takes(topics::RECORDER_ACK));
        assert_eq!(sim.senders::<u8>(topics::MAGNET_STATE).unwrap().len(), 2);
        assert_eq!(sim.senders::<u8>(topics::CLOCK).unwrap().len(), 1);
        assert_eq!(sim.senders::<u8>(topics::SCENE_MARKERS).unwrap().len(), 0);
    }

    #[test]
    fn a_node_outside_the_container_is_no_local_publisher() {
        let bus = IntraBus::for_nodes(graph().unwrap(), &ALL[..2]).unwrap();
        let sim = bus.port("causal_arm_sim");
        assert!(
            !sim.takes(topics::RECORDER_ACK),
            "the recorder runs elsewhere"
        );
        assert_eq!(sim.senders::<u8>(topics::JOINT_STATES).unwrap().len(), 1);
    }

    #[test]
    fn messages_sent_before_the_subscriber_took_its_end_wait_for_it() {
        let bus = IntraBus::for_nodes(graph().unwrap(), &ALL).unwrap();
        let senders = bus
            .port("causal_arm_sim")
            .senders::<u32>(topics::TF)
            .unwrap();
        senders[0].send(7).unwrap();
        let receiver = bus.port("causal_arm_recorder");
        let receiver = receiver.receiver::<u32>(topics::TF).unwrap().unwrap();
        assert_eq!(receiver.try_recv(), Ok(7));
        let twice = bus.port("causal_arm_recorder").receiver::<u32>(topics::TF);
        assert!(twice.unwrap_err().to_string().contains("twice"));
    }

    #[test]
    fn a_type_mismatch_names_the_topic() {
        let bus = IntraBus::for_nodes(graph().unwrap(), &ALL).unwrap();
        let _ = bus
            .port("causal_arm_sim")
            .senders::<u32>(topics::TF)
            .unwrap();
        let wrong = bus
            .port("causal_arm_recorder")
            .receiver::<String>(topics::TF);
        assert!(wrong.unwrap_err().to_string().contains("/tf"));
    }

    #[test]
    fn an_unknown_node_is_refused() {
        let err = IntraBus::for_nodes(graph().unwrap(), &["nobody"])
            .err()
            .unwrap();
        assert!(err.to_string().contains("nobody"));
    }
}
