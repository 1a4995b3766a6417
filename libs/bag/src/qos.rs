//! The QoS profile of a topic as rosbag2 writes it: in `metadata.yaml` (a list of profiles, one per
//! publisher) and as YAML text in the MCAP channel's `offered_qos_profiles` metadata.

use serde::{Deserialize, Serialize};

/// A duration of a QoS policy.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct QosDuration {
    /// Whole seconds.
    pub sec: i64,
    /// Nanoseconds beyond `sec`.
    pub nsec: u64,
}

impl QosDuration {
    /// No deadline, no expiry, an endless lease: the largest duration in nanoseconds, as rosbag2
    /// writes it.
    pub const INFINITE: QosDuration = QosDuration { sec: 9_223_372_036, nsec: 854_775_807 };
}

/// One offered QoS profile, with rosbag2's field names and values.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct QosProfile {
    /// `keep_last` or `keep_all`.
    pub history: String,
    /// Messages kept with `keep_last`.
    pub depth: u64,
    /// `reliable` or `best_effort`.
    pub reliability: String,
    /// `volatile` or `transient_local`.
    pub durability: String,
    /// Deadline policy.
    pub deadline: QosDuration,
    /// Lifespan policy.
    pub lifespan: QosDuration,
    /// `automatic` or `manual_by_topic`.
    pub liveliness: String,
    /// Liveliness lease.
    pub liveliness_lease_duration: QosDuration,
    /// Whether the topic name is used as given, without the ROS prefix.
    pub avoid_ros_namespace_conventions: bool,
}

impl QosProfile {
    /// Keep last `depth`, reliable or best effort, transient local or volatile; no deadline, no
    /// lifespan, automatic liveliness with an infinite lease (ros2-client's defaults).
    pub fn keep_last(depth: u64, reliable: bool, transient_local: bool) -> Self {
        QosProfile {
            history: "keep_last".to_string(),
            depth,
            reliability: if reliable { "reliable" } else { "best_effort" }.to_string(),
            durability: if transient_local { "transient_local" } else { "volatile" }.to_string(),
            deadline: QosDuration::INFINITE,
            lifespan: QosDuration::INFINITE,
            liveliness: "automatic".to_string(),
            liveliness_lease_duration: QosDuration::INFINITE,
            avoid_ros_namespace_conventions: false,
        }
    }

    /// The YAML text of the MCAP channel metadata `offered_qos_profiles`: a list of this profile.
    pub fn channel_metadata_yaml(&self) -> String {
        serde_yaml_ng::to_string(std::slice::from_ref(self)).expect("a QoS profile always serializes")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn channel_metadata_is_a_yaml_list_with_rosbag2_names() {
        let yaml = QosProfile::keep_last(5, true, false).channel_metadata_yaml();
        assert!(
            yaml.starts_with("- history: keep_last\n  depth: 5\n  reliability: reliable\n  durability: volatile\n"),
            "{yaml}"
        );
        let back: Vec<QosProfile> = serde_yaml_ng::from_str(&yaml).unwrap();
        assert_eq!(back, [QosProfile::keep_last(5, true, false)]);
        assert_eq!(QosProfile::keep_last(1, true, true).durability, "transient_local");
    }
}
