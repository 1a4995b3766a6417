//! The shared node runtime of the rover graph: ROS arguments, names and remaps, typed parameters,
//! QoS profiles, the topic table, the CDR bytes of messages, logging to the console and `/rosout`, the count of rejected
//! inputs, and shutdown.
//!
//! A node binary creates a [`Runtime`] once per process, asks it for a [`RosNode`] with its
//! parameter struct, and wires the node's [`topics`] to a plain library.

mod adapter;
pub mod cdr;
mod command_servers;
pub mod commands;
mod discovery;
pub mod executor;
pub mod graph;
mod handshakes;
mod ip_network;
pub mod lifecycle;
pub mod logging;
mod matching;
pub mod names;
mod node;
pub mod node_core;
pub mod pairing;
mod param_services;
pub mod params;
mod ports;
pub mod qos;
pub mod rejections;
pub mod ros_args;
pub mod rtps_ports;
mod security;
mod services;
mod shutdown;
pub mod snapshot;
mod static_peers;
pub mod sync;
pub mod topics;

pub use adapter::{Build, run_node, run_node_with};
pub use ip_network::IpNetwork;
pub use node::{
    Params, RosNode, Runtime, domain_id_from_env, messages, publish_or_warn, resolve_params, spawn_subscriber,
    spawn_subscriber_with_info,
};
pub use params::{NoParams, NodeParams};
pub use rejections::Rejections;
pub use ros_args::{RosArgs, split_ros_args};
pub use ros2_client::{MessageInfo, Publisher, Subscription};
pub use shutdown::Shutdown;
pub use static_peers::StaticPeers;
