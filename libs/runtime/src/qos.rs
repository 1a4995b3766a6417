//! The QoS profiles of the graph, spelled out (ros2-client's defaults differ from rclpy's).

use ros2_client::QosProfile;
use ros2_client::qos::{Durability, History, WhenFull};

/// Reliable, volatile, keep last `depth`: rclpy's `create_publisher(T, topic, depth)`.
pub const fn reliable(depth: usize) -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::DEFAULT)
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth })
}

/// Reliable, volatile, keep last 10: rclpy's default for services.
pub const fn services() -> QosProfile {
    reliable(10)
}

/// Reliable and transient local, keep last 1: a latched topic such as `map`; late joiners get the last sample.
pub const fn latched() -> QosProfile {
    reliable(1).durability(Durability::TransientLocal)
}
