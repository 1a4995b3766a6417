//! The graph in one table: which topics of [`crate::topics`] each node reads and writes. A node
//! of the table can open a publisher or a subscription only on a topic the table gives it, so the
//! table is what the nodes do; the docs' picture of the graph is checked against it.

use crate::commands::{NAVIGATE_TO_POSE, PAUSE_MISSION, RESUME_MISSION, RETURN_HOME, SAMPLE_RETURN, START_MISSION};
use crate::topics::{
    CAMERA_COMPRESSED, CAMERA_INFO, CAMERA_RAW, CLOCK, CMD_VEL, DIAGNOSTICS, DRIVE_CMD, GOAL_POSE, MAP, MAP_IMAGE,
    MAP_STATS, MODE, ODOM, PICKUP, PLAN, ROCKS, SAMPLE_MARKERS, SAMPLE_TRUTH, TELEMETRY, TERRAIN, TF, TF_STATIC,
    VISION,
};

/// One node of the graph: its name and the topics it reads and writes (names as in the topic
/// table, before namespacing and remapping).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NodeTopics {
    /// The node's default name.
    pub node: &'static str,
    /// Topics it subscribes to.
    pub reads: &'static [&'static str],
    /// Topics it publishes.
    pub writes: &'static [&'static str],
    /// Services and actions of [`crate::commands`] it serves.
    pub serves: &'static [&'static str],
}

/// Every node of the graph, in start order. `/clock` is read by any node with `use_sim_time`
/// (the runtime's business, not the node's) and `/rosout` written by all, so neither is listed
/// as read or written by the nodes that do so only for that.
pub static GRAPH: [NodeTopics; 5] = [
    NodeTopics {
        node: "bridge",
        reads: &[DRIVE_CMD.name, PICKUP.name, CMD_VEL.name, MAP_IMAGE.name, VISION.name],
        writes: &[
            CAMERA_COMPRESSED.name,
            CAMERA_RAW.name,
            CAMERA_INFO.name,
            TELEMETRY.name,
            ODOM.name,
            TF.name,
            TF_STATIC.name,
            SAMPLE_TRUTH.name,
            CLOCK.name,
            DIAGNOSTICS.name,
        ],
        serves: &[],
    },
    NodeTopics {
        node: "perception",
        reads: &[CAMERA_COMPRESSED.name, TELEMETRY.name],
        writes: &[TERRAIN.name, VISION.name],
        serves: &[],
    },
    NodeTopics {
        node: "mapping",
        reads: &[TERRAIN.name, SAMPLE_TRUTH.name],
        writes: &[MAP.name, MAP_IMAGE.name, MAP_STATS.name, ROCKS.name, SAMPLE_MARKERS.name],
        serves: &[],
    },
    NodeTopics {
        node: "decision",
        reads: &[TERRAIN.name, MAP.name, ROCKS.name, MAP_STATS.name, GOAL_POSE.name],
        writes: &[DRIVE_CMD.name, MODE.name, PLAN.name],
        serves: &[
            NAVIGATE_TO_POSE.name,
            SAMPLE_RETURN.name,
            START_MISSION.name,
            PAUSE_MISSION.name,
            RESUME_MISSION.name,
            RETURN_HOME.name,
        ],
    },
    NodeTopics { node: "pickup", reads: &[TELEMETRY.name], writes: &[PICKUP.name], serves: &[] },
];

/// The table's entry of the node named `node`; none for a process outside the graph (a tool, a
/// recorder).
pub fn node_topics(node: &str) -> Option<&'static NodeTopics> {
    GRAPH.iter().find(|entry| entry.node == node)
}

/// Topics that come into the graph from outside it: read by a node, written by none.
pub fn inputs_from_outside() -> impl Iterator<Item = &'static str> {
    let written = |topic: &str| GRAPH.iter().any(|n| n.writes.contains(&topic));
    let mut inputs: Vec<&str> = GRAPH.iter().flat_map(|n| n.reads.iter().copied()).filter(|t| !written(t)).collect();
    inputs.sort_unstable();
    inputs.dedup();
    inputs.into_iter()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::topics::all_names;

    /// What users and their tools send the graph: teleoperation and goals.
    const FROM_USERS: [&str; 2] = [CMD_VEL.name, GOAL_POSE.name];

    #[test]
    fn every_topic_of_the_topic_table_is_written_by_a_node_or_comes_from_users() {
        for topic in all_names() {
            let written = GRAPH.iter().any(|n| n.writes.contains(&topic));
            assert!(written || FROM_USERS.contains(&topic), "{topic}: in the topic table but written by no node");
        }
    }

    #[test]
    fn only_teleoperation_and_goals_come_from_outside_the_graph() {
        assert_eq!(inputs_from_outside().collect::<Vec<_>>(), FROM_USERS);
    }

    #[test]
    fn every_command_of_the_command_table_is_served_by_one_node() {
        for command in crate::commands::all_names() {
            assert_eq!(GRAPH.iter().filter(|n| n.serves.contains(&command)).count(), 1, "{command}: one server");
        }
    }

    #[test]
    fn each_topic_has_one_writer_and_no_node_reads_what_it_writes() {
        for topic in GRAPH.iter().flat_map(|n| n.writes.iter()) {
            assert_eq!(GRAPH.iter().filter(|n| n.writes.contains(topic)).count(), 1, "{topic}: one writer");
        }
        for node in &GRAPH {
            assert!(node.reads.iter().all(|t| !node.writes.contains(t)), "{} reads what it writes", node.node);
        }
    }
}
