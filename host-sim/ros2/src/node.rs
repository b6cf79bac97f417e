//! The DDS side: a ROS 2 node of `ros2-client` (RustDDS, no ROS installation), its topics,
//! publishers and subscriptions.
//!
//! Topics are relative to the node's namespace (`/rspr` by default: DDS topic
//! `rt/rspr/measured_cp`), except `/tf` and `/joint_states`, which are where
//! `robot_state_publisher`, RViz and Foxglove look for them. QoS: ROS 2's default profile (reliable, volatile,
//! keep the last 10) on every topic, as `rclcpp` publishers and subscriptions use by
//! default. Discovery and traffic stay on the loopback interface unless asked otherwise
//! ([`Network`]): RustDDS is told to use only 127.0.0.1 and to announce itself to the
//! local well-known discovery ports.

use crate::messages::{
    DiagnosticArray, JointState, OperatingState, PoseStamped, RosType, StdString, StringStamped,
    TfMessage,
};
use ros2_client::dds::rustdds::DomainParticipantBuilder;
use ros2_client::dds::{Context, Node, Publisher, Subscription};
use ros2_client::qos::{Durability, History, WhenFull};
use ros2_client::{MessageTypeName, Name, NodeName, NodeOptions, QosProfile};
use serde::de::DeserializeOwned;
use serde::Serialize;
use std::net::{IpAddr, Ipv4Addr};
use thiserror::Error;

/// Why the node could not be set up.
#[derive(Debug, Error)]
pub enum NodeError {
    #[error("the DDS domain participant (domain {domain}): {error}")]
    Participant { domain: u16, error: String },
    #[error("ROS 2 name {name:?}: {error}")]
    Name { name: String, error: String },
    #[error("the ROS 2 node {name:?}: {error}")]
    Node { name: String, error: String },
    #[error("topic {topic:?} ({kind}): {error}")]
    Topic {
        topic: String,
        kind: &'static str,
        error: String,
    },
}

/// Which interfaces DDS uses.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Network {
    /// The loopback only (127.0.0.1): peers on this machine.
    Loopback,
    /// These interfaces' addresses.
    Only(Vec<IpAddr>),
    /// Every interface (RustDDS's default: multicast discovery on the LAN).
    All,
}

/// Where the node lives on the ROS graph.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NodeConfig {
    /// The DDS domain (`ROS_DOMAIN_ID`).
    pub domain: u16,
    /// The namespace of the node and its relative topics, e.g. `/rspr`.
    pub namespace: String,
    /// The node's name.
    pub name: String,
    /// The interfaces.
    pub network: Network,
}

impl Default for NodeConfig {
    /// Domain 0, `/rspr/board`, the loopback only.
    fn default() -> Self {
        NodeConfig {
            domain: 0,
            namespace: "/rspr".into(),
            name: "board".into(),
            network: Network::Loopback,
        }
    }
}

/// The QoS of every topic: ROS 2's default (reliable, volatile, keep last 10).
pub fn qos() -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::DEFAULT)
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 10 })
}

/// The node and its endpoints.
pub struct RosNode {
    node: Node,
    /// Where the relative topics are, e.g. `/rspr`.
    pub namespace: String,
    pub measured_cp: Publisher<PoseStamped>,
    pub setpoint_cp: Publisher<PoseStamped>,
    pub measured_js: Publisher<JointState>,
    pub setpoint_js: Publisher<JointState>,
    pub operating_state: Publisher<OperatingState>,
    pub diagnostics: Publisher<DiagnosticArray>,
    pub refusal: Publisher<StdString>,
    pub tf: Publisher<TfMessage>,
    pub joint_states: Publisher<JointState>,
    pub servo_cp: Subscription<PoseStamped>,
    pub servo_jp: Subscription<JointState>,
    pub state_command: Subscription<StringStamped>,
}

fn name(namespace: &str, base: &str) -> Result<Name, NodeError> {
    Name::new(namespace, base).map_err(|e| NodeError::Name {
        name: format!("{namespace}/{base}"),
        error: format!("{e:?}"),
    })
}

fn topic_of<T: RosType>(
    node: &Node,
    n: &Name,
    shown: &str,
) -> Result<ros2_client::dds::rustdds::Topic, NodeError> {
    node.create_topic(n, MessageTypeName::new(T::PACKAGE, T::NAME), &qos())
        .map_err(|e| NodeError::Topic {
            topic: shown.to_string(),
            kind: "topic",
            error: format!("{e:?}"),
        })
}

fn publisher<T: RosType + Serialize>(
    node: &mut Node,
    namespace: &str,
    base: &str,
) -> Result<Publisher<T>, NodeError> {
    let n = name(namespace, base)?;
    let topic = topic_of::<T>(node, &n, base)?;
    node.create_publisher(&topic, Some(qos()))
        .map_err(|e| NodeError::Topic {
            topic: base.to_string(),
            kind: "publisher",
            error: format!("{e:?}"),
        })
}

fn subscription<T: RosType + DeserializeOwned + 'static>(
    node: &mut Node,
    base: &str,
) -> Result<Subscription<T>, NodeError> {
    let n = name("", base)?;
    let topic = topic_of::<T>(node, &n, base)?;
    node.create_subscription(&topic, Some(qos()))
        .map_err(|e| NodeError::Topic {
            topic: base.to_string(),
            kind: "subscription",
            error: format!("{e:?}"),
        })
}

impl RosNode {
    /// Joins the DDS domain and creates the node, its publishers and subscriptions.
    pub fn new(config: &NodeConfig) -> Result<Self, NodeError> {
        let mut builder = DomainParticipantBuilder::new(config.domain);
        builder = match &config.network {
            Network::Loopback => builder
                .with_only_networks([IpAddr::V4(Ipv4Addr::LOCALHOST)])
                .same_host_loopback(true),
            Network::Only(addrs) => builder.with_only_networks(addrs.clone()),
            Network::All => builder,
        };
        let participant = builder.build().map_err(|e| NodeError::Participant {
            domain: config.domain,
            error: format!("{e:?}"),
        })?;
        let context =
            Context::from_domain_participant(participant).map_err(|e| NodeError::Participant {
                domain: config.domain,
                error: format!("{e:?}"),
            })?;
        let node_name =
            NodeName::new(&config.namespace, &config.name).map_err(|e| NodeError::Name {
                name: format!("{}/{}", config.namespace, config.name),
                error: format!("{e:?}"),
            })?;
        let mut node = context
            .new_node(node_name, NodeOptions::new().enable_rosout(false))
            .map_err(|e| NodeError::Node {
                name: format!("{}/{}", config.namespace, config.name),
                error: format!("{e:?}"),
            })?;
        let n = &mut node;
        Ok(RosNode {
            namespace: config.namespace.clone(),
            measured_cp: publisher(n, "", "measured_cp")?,
            setpoint_cp: publisher(n, "", "setpoint_cp")?,
            measured_js: publisher(n, "", "measured_js")?,
            setpoint_js: publisher(n, "", "setpoint_js")?,
            operating_state: publisher(n, "", "operating_state")?,
            diagnostics: publisher(n, "", "diagnostics")?,
            refusal: publisher(n, "", "refusal")?,
            tf: publisher(n, "/", "tf")?,
            joint_states: publisher(n, "/", "joint_states")?,
            servo_cp: subscription(n, "servo_cp")?,
            servo_jp: subscription(n, "servo_jp")?,
            state_command: subscription(n, "state_command")?,
            node,
        })
    }

    /// The node.
    pub fn node(&self) -> &Node {
        &self.node
    }

    /// A relative topic's full ROS name, e.g. `/rspr/measured_cp`.
    pub fn topic(&self, base: &str) -> String {
        format!("{}/{base}", self.namespace.trim_end_matches('/'))
    }
}
