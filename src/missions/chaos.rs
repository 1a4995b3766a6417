//! Crashes on a schedule: SIGKILL to nodes of a running graph at set moments of simulated time,
//! for the graph's respawn to answer (`rover eval --chaos`, `tests/chaos.rs`).

use rover_sim::random::SplitMix64;

use crate::processes::graph::Graph;
use crate::processes::nodes::Node;

/// A node to kill at a moment of simulated time.
#[derive(Debug, Clone, PartialEq)]
pub struct Kill {
    /// When, simulated seconds.
    pub at_sim_s: f64,
    /// Which node.
    pub node: Node,
}

/// The kills of one mission, in time order, and how far the mission has got through them.
#[derive(Debug, Clone)]
pub struct Chaos {
    kills: Vec<Kill>,
    done: usize,
}

impl Chaos {
    /// A random node every `period_s` of simulated time, from `period_s` until `until_s`.
    pub fn every(period_s: f64, until_s: f64, seed: u64) -> Self {
        let mut random = SplitMix64::new(seed);
        let count = (until_s / period_s).floor() as usize;
        let kills = (1..=count)
            .map(|k| Kill { at_sim_s: k as f64 * period_s, node: Node::ALL[random.below(Node::ALL.len())] })
            .collect();
        Chaos { kills, done: 0 }
    }

    /// Every node once, in a random order, each at a random moment of its own slot: the slots are
    /// `slot_s` of simulated time each, the first starting at `from_s`.
    pub fn each_node_once(from_s: f64, slot_s: f64, seed: u64) -> Self {
        let mut random = SplitMix64::new(seed);
        let mut nodes = Node::ALL.to_vec();
        for i in (1..nodes.len()).rev() {
            nodes.swap(i, random.below(i + 1));
        }
        let kills = nodes
            .into_iter()
            .enumerate()
            .map(|(slot, node)| Kill { at_sim_s: from_s + (slot as f64 + random.unit()) * slot_s, node })
            .collect();
        Chaos { kills, done: 0 }
    }

    /// The planned kills.
    pub fn kills(&self) -> &[Kill] {
        &self.kills
    }

    /// Kills the nodes whose moment has come by `sim_s` ([`Graph::crash`]); returns them.
    pub fn act(&mut self, sim_s: f64, graph: &mut Graph) -> Vec<Node> {
        let mut killed = Vec::new();
        while let Some(kill) = self.kills.get(self.done).filter(|k| k.at_sim_s <= sim_s) {
            tracing::warn!("chaos: killing node {} at {:.1} sim s", kill.node.name(), sim_s);
            graph.crash(kill.node.name());
            killed.push(kill.node);
            self.done += 1;
        }
        killed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_node_is_killed_once_in_its_own_slot() {
        let chaos = Chaos::each_node_once(30.0, 80.0, 4);
        let mut nodes: Vec<&str> = chaos.kills().iter().map(|k| k.node.name()).collect();
        for (slot, kill) in chaos.kills().iter().enumerate() {
            let start = 30.0 + 80.0 * slot as f64;
            assert!((start..start + 80.0).contains(&kill.at_sim_s), "{kill:?} in slot {slot}");
        }
        nodes.sort_unstable();
        assert_eq!(nodes, ["bridge", "decision", "mapping", "perception", "pickup"]);
        let other = Chaos::each_node_once(30.0, 80.0, 5);
        assert_ne!(chaos.kills(), other.kills(), "the seed picks the order and moments");
    }

    #[test]
    fn a_kill_every_period_until_the_end() {
        let chaos = Chaos::every(60.0, 1200.0, 0);
        assert_eq!(chaos.kills().len(), 20);
        assert_eq!(chaos.kills()[0].at_sim_s, 60.0);
        assert_eq!(chaos.kills()[19].at_sim_s, 1200.0);
        let distinct: std::collections::HashSet<&str> = chaos.kills().iter().map(|k| k.node.name()).collect();
        assert!(distinct.len() >= 4, "random nodes: {distinct:?}");
    }
}
