//! [`RosNode`]: one ROS 2 node with everything a causal-arm node needs, built from the
//! environment and `--ros-args`.

use std::time::Duration;

use causal_arm_msgs::{RosMessage, RosService};
use ros2_client::{
    Client, Context, MessageTypeName, Name, Node, NodeName, NodeOptions, Publisher, QosProfile,
    ROSTime, Server, ServiceTypeName, Subscription,
};
use thiserror::Error;

use crate::env::{EnvError, RosEnv};
use crate::logging;
use crate::params::{Describe, ParamError, ParamSpec, Params, RosArgs, ToRos};
use crate::qos;
use causal_arm_security::SecurityMode;

/// Why a node could not start; every variant says what to fix.
#[derive(Debug, Error)]
pub enum NodeError {
    /// A ROS environment variable is invalid.
    #[error(transparent)]
    Env(#[from] EnvError),
    /// `--ros-args` or a parameter is invalid.
    #[error(transparent)]
    Param(#[from] ParamError),
    /// Node or topic name is not a valid ROS 2 name.
    #[error("invalid ROS name {name:?}: {reason}")]
    Name {
        /// The rejected name.
        name: String,
        /// What the name checker said.
        reason: String,
    },
    /// DDS refused to create an entity.
    #[error("DDS error while creating {what}: {reason}")]
    Dds {
        /// Which entity was being created.
        what: String,
        /// The DDS error.
        reason: String,
    },
}

fn dds_err(what: impl Into<String>) -> impl FnOnce(ros2_client::CreateError) -> NodeError {
    let what = what.into();
    move |e| NodeError::Dds {
        what,
        reason: format!("{e:?}"),
    }
}

/// How long one wait for a DDS match lasts before it is re-armed (see
/// [`crate::runtime::wait_rearmed`]).
const REARM: Duration = Duration::from_millis(250);

/// How long after a participant joins the participants already present have answered
/// its announcement: they do at once (Fast DDS, Cyclone DDS, rustdds) on loopback.
const DISCOVERY_ANSWER: std::time::Duration = std::time::Duration::from_millis(100);

/// A running node: context, ros2-client node (with its spinner serving parameters and
/// `/clock`), validated parameters and rosout logging.
pub struct RosNode {
    env: RosEnv,
    params: Params,
    remaps: Vec<(String, String)>,
    /// Always `Some` until drop, which must drop the node before joining its spinner.
    node: Option<Node>,
    spinner: Option<tokio::task::JoinHandle<()>>,
    _context: Context,
    /// When the participant joined: those already present answer its announcement at once.
    joined: std::time::Instant,
}

impl RosNode {
    /// Creates the node `default_name` (overridable with `-r __node:=`), in the namespace
    /// given by `-r __ns:=` (default `/`), with `specs` resolved from `ros_args`.
    pub fn new(
        default_name: &str,
        specs: &[ParamSpec],
        ros_args: &RosArgs,
    ) -> Result<Self, NodeError> {
        let env = RosEnv::from_env()?;
        Self::with_env(env, default_name, specs, ros_args)
    }

    /// As [`RosNode::new`] with an explicit environment.
    pub fn with_env(
        env: RosEnv,
        default_name: &str,
        specs: &[ParamSpec],
        ros_args: &RosArgs,
    ) -> Result<Self, NodeError> {
        logging::init_with_level(ros_args.log_level.as_deref());
        let name = ros_args.node_name.as_deref().unwrap_or(default_name);
        let namespace = ros_args.namespace.as_deref().unwrap_or("/");
        let params = Params::resolve(name, specs, &ros_args.params)?;
        let node_name = NodeName::new(namespace, name).map_err(|e| NodeError::Name {
            name: format!("{namespace}/{name}"),
            reason: format!("{e:?}"),
        })?;
        let security = env
            .security
            .resolve(ros_args.enclave.as_deref())
            .map_err(EnvError::from)?;
        if let SecurityMode::Unsecured { reason } = &security {
            tracing::warn!("{reason}");
        }
        let participant = env
            .domain_participant(&security)
            .map_err(|e| NodeError::Dds {
                what: format!("DDS participant in domain {} ({security})", env.domain_id),
                reason: format!("{e:?}"),
            })?;
        let context =
            Context::from_domain_participant(participant).map_err(dds_err("ROS context"))?;
        // The parameter services speak the mapping of the rmw the user runs, as ours do.
        let mut options = NodeOptions::new()
            .enable_rosout(true)
            .parameter_service_mapping(env.service_mapping);
        for (pname, value) in params.iter() {
            options = options.declare_parameter(pname, value.to_ros());
        }
        for spec in specs.iter().chain([&crate::params::use_sim_time_spec()]) {
            options = options.describe_parameter(spec.descriptor());
        }
        let mut node = context
            .new_node(node_name, options)
            .map_err(|e| NodeError::Dds {
                what: format!("node {name}"),
                reason: format!("{e:?}"),
            })?;
        let spinner = node.spinner().map_err(dds_err("node spinner"))?;
        let spinner = crate::runtime::runtime().spawn(async move {
            if let Err(e) = spinner.spin().await {
                tracing::error!("spinner stopped: {e:?}");
            }
        });
        logging::attach_rosout(node.logging_handle());
        tracing::info!(
            "node {} up: domain {}, discovery {:?}, {security}, use_sim_time {}",
            name,
            env.domain_id,
            env.discovery_range,
            params.use_sim_time()
        );
        Ok(Self {
            env,
            params,
            remaps: ros_args.remaps.clone(),
            node: Some(node),
            spinner: Some(spinner),
            _context: context,
            joined: std::time::Instant::now(),
        })
    }

    fn node_mut(&mut self) -> &mut Node {
        self.node.as_mut().expect("node lives until drop")
    }

    fn node_ref(&self) -> &Node {
        self.node.as_ref().expect("node lives until drop")
    }

    /// Waits until a server of `client`'s service has matched (or `timeout` passed);
    /// returns whether it did. Then waits `settle` more, as a matched reader may still
    /// drop the first request (see `wait_for_subscribers`).
    pub fn wait_for_service<
        Req: ros2_client::Message + 'static,
        Resp: ros2_client::Message + 'static,
    >(
        &self,
        client: &Client<Req, Resp>,
        timeout: Duration,
        settle: Duration,
    ) -> bool {
        let start = std::time::Instant::now();
        let matched = crate::runtime::wait_rearmed(
            || client.wait_for_service(self.node_ref()),
            REARM,
            || start.elapsed() > timeout,
        );
        if matched {
            std::thread::sleep(settle);
        }
        matched
    }

    /// The validated parameters.
    pub fn params(&self) -> &Params {
        &self.params
    }

    /// The environment the node was built from.
    pub fn env(&self) -> &RosEnv {
        &self.env
    }

    /// The underlying ros2-client node, for what this wrapper does not cover.
    pub fn inner(&mut self) -> &mut Node {
        self.node_mut()
    }

    /// Current time: `/clock` when `use_sim_time` is true, else the wall clock.
    pub fn now(&self) -> ROSTime {
        self.node_ref().time_now()
    }

    /// Waits until `publisher` has `count` matched subscriptions, then up to `settle` more
    /// until they have matched it on their side too (see [`RosNode::confirm_subscribers`]).
    /// Returns false on timeout or when `stop` is set.
    pub fn wait_for_subscribers<M: RosMessage>(
        &mut self,
        publisher: &Publisher<M>,
        count: usize,
        timeout: std::time::Duration,
        settle: std::time::Duration,
        stop: &std::sync::atomic::AtomicBool,
    ) -> bool {
        use std::sync::atomic::Ordering;
        let start = std::time::Instant::now();
        let gave_up = || stop.load(Ordering::SeqCst) || start.elapsed() > timeout;
        let node = self.node_ref();
        // The first match goes through ros2-client's own wait, which also registers the
        // publisher with the node's graph tracking (counting before that logs errors).
        if !crate::runtime::wait_rearmed(|| publisher.wait_for_subscription(node), REARM, gave_up) {
            return false;
        }
        while publisher.get_subscription_count(node) < count {
            if gave_up() {
                return false;
            }
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        Self::confirm_subscribers(publisher, count, std::time::Instant::now() + settle);
        true
    }

    /// Waits until `count` of `publisher`'s matched subscriptions have matched it on their
    /// side too, or until `deadline`; returns whether they have. A subscription drops
    /// messages from a publisher it does not know yet (they come later, by repair), so a
    /// publisher whose first messages should arrive at once waits for this. A reliable
    /// subscription confirms with its first ACKNACK (rustdds and Fast DDS ones at once);
    /// others (best effort, or peers that wait for a HEARTBEAT) are given until
    /// `deadline`, as a fixed settle time would.
    pub fn confirm_subscribers<M: RosMessage>(
        publisher: &Publisher<M>,
        count: usize,
        deadline: std::time::Instant,
    ) -> bool {
        let left = deadline.saturating_duration_since(std::time::Instant::now());
        publisher.wait_for_confirmed_subscriptions(count, left)
    }

    /// Waits until this node has exchanged endpoints with every participant already on
    /// the network, both ways, or `max_wait` passed: a node about to publish the first
    /// step of a run calls it, so that a subscriber that was running before the run
    /// (an rclpy `echo`) gets that step too. Returns whether all settled.
    pub fn wait_for_discovery_settled(&self, max_wait: std::time::Duration) -> bool {
        let heard_back = self.joined + DISCOVERY_ANSWER;
        std::thread::sleep(heard_back.saturating_duration_since(std::time::Instant::now()));
        let unsettled = self
            ._context
            .domain_participant()
            .wait_for_discovery_settled(max_wait);
        if !unsettled.is_empty() {
            tracing::debug!(
                "discovery with {} participant(s) not settled within {max_wait:?}: {unsettled:?}",
                unsettled.len()
            );
        }
        unsettled.is_empty()
    }

    /// Applies `-r from:=to` remappings to a topic or service name.
    pub fn resolve_name(&self, name: &str) -> String {
        self.remaps
            .iter()
            .find(|(from, _)| from == name)
            .map(|(_, to)| to.clone())
            .unwrap_or_else(|| name.to_owned())
    }

    fn ros_name(&self, name: &str) -> Result<Name, NodeError> {
        let resolved = self.resolve_name(name);
        Name::parse(&resolved).map_err(|e| NodeError::Name {
            name: resolved,
            reason: format!("{e:?}"),
        })
    }

    fn topic<M: RosMessage>(
        &mut self,
        name: &str,
        qos: &QosProfile,
    ) -> Result<rustdds::Topic, NodeError> {
        let ros_name = self.ros_name(name)?;
        self.node_mut()
            .create_topic(&ros_name, MessageTypeName::new(M::PACKAGE, M::NAME), qos)
            .map_err(dds_err(format!("topic {name}")))
    }

    /// A publisher of `M` on `topic` with `qos`.
    pub fn publisher<M: RosMessage>(
        &mut self,
        topic: &str,
        qos: QosProfile,
    ) -> Result<Publisher<M>, NodeError> {
        let t = self.topic::<M>(topic, &qos)?;
        self.node_mut()
            .create_publisher(&t, Some(qos::with_type_hash(qos, M::TYPE_HASH)))
            .map_err(dds_err(format!("publisher on {topic}")))
    }

    /// A subscription to `ros_discovery_info`, where every ROS 2 participant announces its
    /// nodes and their readers' and writers' GIDs (rmw_dds_common): what tells the graph's
    /// own writers from strays. Reliable and transient local as rmw publishes it; the
    /// reader keeps many samples, as one topic instance carries every participant's.
    pub fn discovery_info(
        &mut self,
    ) -> Result<
        Subscription<causal_arm_msgs::rmw_dds_common::msg::ParticipantEntitiesInfo>,
        NodeError,
    > {
        let qos = qos::discovery_info();
        let topic = self
            ._context
            .domain_participant()
            .create_topic(
                "ros_discovery_info".into(),
                "rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_".into(),
                &(&qos).into(),
                rustdds::TopicKind::NoKey,
            )
            .map_err(|e| NodeError::Dds {
                what: "topic ros_discovery_info".into(),
                reason: format!("{e:?}"),
            })?;
        let hash = <causal_arm_msgs::rmw_dds_common::msg::ParticipantEntitiesInfo as RosMessage>::TYPE_HASH;
        self.node_mut()
            .create_subscription(&topic, Some(qos::with_type_hash(qos, hash)))
            .map_err(dds_err("subscription to ros_discovery_info"))
    }

    /// The node's namespace (`/` unless `-r __ns:=` set one).
    pub fn namespace(&self) -> &str {
        self.node_ref().namespace()
    }

    /// A subscription to `M` on `topic` with `qos`.
    pub fn subscription<M: RosMessage>(
        &mut self,
        topic: &str,
        qos: QosProfile,
    ) -> Result<Subscription<M>, NodeError> {
        let t = self.topic::<M>(topic, &qos)?;
        self.node_mut()
            .create_subscription(&t, Some(qos::with_type_hash(qos, M::TYPE_HASH)))
            .map_err(dds_err(format!("subscription to {topic}")))
    }

    fn service_type<S: RosService>() -> ServiceTypeName {
        let (package, rest) = S::ROS_TYPE.split_once('/').unwrap_or(("", S::ROS_TYPE));
        let name = rest.rsplit('/').next().unwrap_or(rest);
        ServiceTypeName::new(package, name)
    }

    /// The QoS of service `S`'s request and response topics: each announces its own
    /// message's type hash, as rmw_fastrtps does (not the service's).
    fn service_qos<S: RosService>() -> (QosProfile, QosProfile) {
        (
            qos::with_type_hash(qos::services(), <S::Request as RosMessage>::TYPE_HASH),
            qos::with_type_hash(qos::services(), <S::Response as RosMessage>::TYPE_HASH),
        )
    }

    /// A server of service `S` at `name`, mapped as `RMW_IMPLEMENTATION` asks.
    pub fn server<S: RosService>(
        &mut self,
        name: &str,
    ) -> Result<Server<S::Request, S::Response>, NodeError>
    where
        S::Request: ros2_client::Message,
        S::Response: ros2_client::Message,
    {
        let ros_name = self.ros_name(name)?;
        let mapping = self.env.service_mapping;
        let (request_qos, response_qos) = Self::service_qos::<S>();
        self.node_mut()
            .create_server(
                mapping,
                &ros_name,
                &Self::service_type::<S>(),
                request_qos,
                response_qos,
            )
            .map_err(dds_err(format!("service server {name}")))
    }

    /// A client of service `S` at `name`.
    pub fn client<S: RosService>(
        &mut self,
        name: &str,
    ) -> Result<Client<S::Request, S::Response>, NodeError>
    where
        S::Request: ros2_client::Message,
        S::Response: ros2_client::Message,
    {
        let ros_name = self.ros_name(name)?;
        let mapping = self.env.service_mapping;
        let (request_qos, response_qos) = Self::service_qos::<S>();
        self.node_mut()
            .create_client(
                mapping,
                &ros_name,
                &Self::service_type::<S>(),
                request_qos,
                response_qos,
            )
            .map_err(dds_err(format!("service client {name}")))
    }
}

impl Drop for RosNode {
    fn drop(&mut self) {
        logging::detach_rosout();
        // Dropping the node signals its spinner to stop.
        drop(self.node.take());
        if let Some(handle) = self.spinner.take() {
            let _ = crate::runtime::block_on_timeout(handle, Duration::from_secs(2));
        }
    }
}
