//! Accepting the graph's data only from the graph's own nodes (see
//! [`causal_arm_protocol::identity`]). One [`Screen`] per node reads `ros_discovery_info`
//! into a writer directory; each subscription asks it which nodes its topic trusts: the
//! node the graph file names as the topic's publisher, in this node's namespace, unless
//! the `trusted_publishers` parameter names others (`*`: any writer).

use std::cell::RefCell;

use causal_arm_msgs::rmw_dds_common::msg::ParticipantEntitiesInfo;
use causal_arm_node::RosNode;
use causal_arm_protocol::graph::graph;
use causal_arm_protocol::{Trusted, WriterDirectory};
use ros2_client::Subscription;

use crate::feed::LOGGED;

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
    /// Subscribes `node` to `ros_discovery_info`; reads its `trusted_publishers` parameter.
    pub fn new(node: &mut RosNode) -> anyhow::Result<Self> {
        Ok(Self {
            announcements: node.discovery_info()?,
            directory: RefCell::new(WriterDirectory::default()),
            setting: node.params().string("trusted_publishers").to_owned(),
            namespace: node.namespace().to_owned(),
            unreadable: std::cell::Cell::new(0),
        })
    }

    /// The nodes `topic`'s samples are accepted from.
    pub fn trusted(&self, topic: &str) -> anyhow::Result<Trusted> {
        let publishers: Vec<&str> = graph()?
            .nodes
            .iter()
            .filter(|n| n.publishes.iter().any(|t| t == topic))
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
                    self.directory.borrow_mut().update(info.gid.data, nodes);
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
