//! Accepting the graph's data only from the graph's own nodes (see
//! [`causal_arm_protocol::identity`]). One [`Screen`] per node reads `ros_discovery_info`
//! into a writer directory; each subscription asks it which nodes its topic trusts: the
//! node the graph file names as the topic's publisher, in this node's namespace, unless
//! the `trusted_publishers` parameter names others (`*`: any writer).

use std::cell::RefCell;
use std::rc::Rc;
use std::time::Duration;

use causal_arm_msgs::rmw_dds_common::msg::ParticipantEntitiesInfo;
use causal_arm_node::RosNode;
use causal_arm_protocol::graph::graph;
use causal_arm_protocol::{Gid, Quarantine, QuarantineCounts, Trusted, WriterDirectory};
use ros2_client::{MessageInfo, Subscription};

use crate::feed::LOGGED;
use crate::take_next;

/// A node's view of which node owns which writer.
pub struct Screen {
    announcements: Subscription<ParticipantEntitiesInfo>,
    directory: RefCell<WriterDirectory>,
    /// The `trusted_publishers` parameter.
    setting: String,
    namespace: String,
    unreadable: std::cell::Cell<u64>,
}

impl Screen {
    /// Subscribes `node` to `ros_discovery_info`, trusting as its `trusted_publishers`
    /// parameter says.
    pub fn new(node: &mut RosNode, trusted_publishers: &str) -> anyhow::Result<Self> {
        Ok(Self {
            announcements: node.discovery_info()?,
            directory: RefCell::new(WriterDirectory::default()),
            setting: trusted_publishers.to_owned(),
            namespace: node.namespace().to_owned(),
            unreadable: std::cell::Cell::new(0),
        })
    }

    /// For a node outside the graph file (the launcher following the run): trusts each
    /// topic's publishers as the graph file names them.
    pub fn of_graph_file(node: &mut RosNode) -> anyhow::Result<Self> {
        Self::new(node, "")
    }

    /// The nodes `topic`'s samples are accepted from.
    pub fn trusted(&self, topic: &str) -> anyhow::Result<Trusted> {
        let publishers: Vec<&str> = (graph()?.publishers_of(topic))
            .map(|n| n.name.as_str())
            .collect();
        Ok(Trusted::parse(&self.setting, &self.namespace, &publishers))
    }

    /// Takes the announcements that arrived since the last call.
    pub fn refresh(&self) {
        loop {
            match self.announcements.take() {
                Ok(Some((info, _))) => {
                    let nodes = info.node_entities_info_seq.into_iter().map(|n| {
                        let base = n.node_namespace.trim_end_matches('/');
                        let name = format!("{base}/{}", n.node_name);
                        (name, n.writer_gid_seq.into_iter().map(|g| g.data).collect())
                    });
                    let mut directory = self.directory.borrow_mut();
                    let refused_before = directory.refused();
                    directory.update(info.gid.data, nodes);
                    if directory.refused() > refused_before && refused_before < LOGGED {
                        tracing::warn!(
                            "the writer directory is full ({} writers): refused {} announced writers so far; their samples are held as unknown",
                            directory.len(),
                            directory.refused()
                        );
                    }
                }
                Ok(None) => return,
                Err(e) => {
                    let n = self.unreadable.get() + 1;
                    self.unreadable.set(n);
                    if n <= LOGGED {
                        tracing::warn!("ignoring an unreadable ros_discovery_info sample: {e:?}");
                    }
                }
            }
        }
    }

    /// The directory as of the last [`Screen::refresh`].
    pub fn directory(&self) -> std::cell::Ref<'_, WriterDirectory> {
        self.directory.borrow()
    }
}

/// One topic's samples let through only from its trusted writers: samples of another
/// node's writer are dropped (counted), those of a writer not yet announced are held until
/// [`Screen`] learns whose it is. Every subscription of the graph's data goes through one.
pub struct Gate<T> {
    topic: &'static str,
    screen: Rc<Screen>,
    trusted: Trusted,
    quarantine: Quarantine<T>,
}

impl<T> Gate<T> {
    /// A gate for `topic`, trusting the nodes `screen` names for it.
    pub fn new(topic: &'static str, screen: Rc<Screen>) -> anyhow::Result<Self> {
        Ok(Self {
            topic,
            trusted: screen.trusted(topic)?,
            screen,
            quarantine: Quarantine::default(),
        })
    }

    /// `sample` of `writer`: what may pass now (it, after any held samples of the same
    /// writer), or nothing while the writer is unknown or another node's.
    pub fn admit(&mut self, writer: Gid, sample: T) -> Vec<T> {
        let before = self.quarantine.counts();
        let passed = self
            .quarantine
            .admit(&self.trusted, &self.screen.directory(), writer, sample);
        self.log_screened(before);
        passed
    }

    /// The held samples whose writers were announced since, as trusted.
    pub fn release(&mut self) -> Vec<T> {
        if self.quarantine.held() == 0 {
            return Vec::new();
        }
        let before = self.quarantine.counts();
        let released = self
            .quarantine
            .release(&self.trusted, &self.screen.directory());
        self.log_screened(before);
        released
    }

    /// Samples held for writers not yet announced.
    pub fn held(&self) -> usize {
        self.quarantine.held()
    }

    /// Samples kept out so far.
    pub fn counts(&self) -> QuarantineCounts {
        self.quarantine.counts()
    }

    fn log_screened(&self, before: QuarantineCounts) {
        let now = self.quarantine.counts();
        if now.foreign > before.foreign && now.foreign <= LOGGED {
            tracing::warn!(
                "ignoring a {} sample from a writer of another node than {:?}",
                self.topic,
                self.trusted
            );
        }
        if now.unidentified > before.unidentified && now.unidentified <= LOGGED {
            tracing::warn!(
                "dropping a {} sample of a writer no ROS 2 participant announced (quarantine full)",
                self.topic
            );
        }
    }
}

/// A DDS subscription whose samples pass a [`Gate`]: only those of the topic's trusted
/// writers are taken.
pub struct Screened<M, T> {
    pub(crate) subscription: Subscription<M>,
    pub(crate) screen: Rc<Screen>,
    pub(crate) gate: Gate<T>,
}

impl<M: causal_arm_msgs::RosMessage, T> Screened<M, T> {
    /// Subscribes `node` to `topic` with `qos`, screened by `screen`.
    pub fn new(
        node: &mut RosNode,
        topic: &'static str,
        qos: ros2_client::QosProfile,
        screen: &Rc<Screen>,
    ) -> anyhow::Result<Self> {
        Ok(Self {
            subscription: node.subscription::<M>(topic, qos)?,
            gate: Gate::new(topic, Rc::clone(screen))?,
            screen: Rc::clone(screen),
        })
    }

    /// Every sample already waiting, screened: how many arrived (those that could not be
    /// read included, each handed to `unreadable`), and what the gate admits, as `convert`
    /// makes it, after the held samples it admits now. Reads the graph's announcements
    /// only when there is something to screen, so an idle poll costs one empty take.
    pub fn take_admitted(
        &mut self,
        convert: impl Fn(M) -> T,
        mut unreadable: impl FnMut(anyhow::Error),
    ) -> (usize, Vec<T>) {
        let mut arrived = Vec::new();
        let mut count = 0;
        loop {
            match self.subscription.take() {
                Ok(Some(sample)) => arrived.push(sample),
                Ok(None) => break,
                Err(e) => unreadable(anyhow::anyhow!("{e:?}")),
            }
            count += 1;
        }
        if arrived.is_empty() && self.gate.held() == 0 {
            return (count, Vec::new());
        }
        self.screen.refresh();
        let mut admitted = self.gate.release();
        for (sample, info) in arrived {
            admitted.extend(self.admit(sample, &info, &convert));
        }
        (count, admitted)
    }

    /// Waits up to `timeout` for one sample (one that cannot be read goes to
    /// `unreadable`), then screens it: whether one arrived, and what the gate admits, as
    /// `convert` makes it, after the held samples it admits now.
    pub fn wait_admitted(
        &mut self,
        timeout: Duration,
        convert: impl Fn(M) -> T,
        unreadable: impl FnOnce(anyhow::Error),
    ) -> (bool, Vec<T>) {
        let taken = take_next(&self.subscription, timeout);
        self.screen.refresh();
        let mut admitted = self.gate.release();
        match taken {
            Some(Ok((sample, info))) => admitted.extend(self.admit(sample, &info, &convert)),
            Some(Err(e)) => unreadable(e),
            None => return (false, admitted),
        }
        (true, admitted)
    }

    fn admit(&mut self, sample: M, info: &MessageInfo, convert: &impl Fn(M) -> T) -> Vec<T> {
        let writer = info.publisher_gid().to_bytes16();
        self.gate.admit(writer, convert(sample))
    }

    /// Samples kept out so far.
    pub fn counts(&self) -> QuarantineCounts {
        self.gate.counts()
    }
}
