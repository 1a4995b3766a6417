//! The nodes of the graph, each run by the `rover` subcommand of its name: the one list that
//! `rover all`, the process graph of [`crate::processes::graph`], the launchers (through `rover nodes`) and
//! the tests take the nodes from.

use futures::future::{FutureExt as _, LocalBoxFuture, try_join_all};
use rover_runtime::Runtime;
use rover_runtime::params::{NodeParams, ParamSpec};

/// The help on ROS arguments that the node subcommands print.
pub const ROS_ARGS_HELP: &str = "ROS arguments (after the subcommand's own options):
  --ros-args [-r FROM:=TO]... [-p NAME:=VALUE]... [--params-file FILE]... [--log-level [NODE:=]LEVEL]...
             [--disable-rosout-logs] [--disable-stdout-logs] [-e ENCLAVE] [--]
  -r __ns:=/NAMESPACE and -r __node:=NAME rename a node; prefix a rule with NODE: to aim it at one node.
  -p autostart:=false leaves the node unconfigured until `ros2 lifecycle set NODE configure` and `activate`.
Environment: ROS_DOMAIN_ID (default 0) selects the DDS domain; RUST_LOG filters the log;
  ROS_SECURITY_ENABLE=true with ROS_SECURITY_KEYSTORE (tools/keystore) secures the participant with
  the files of its enclave (-e, or ROS_SECURITY_ENCLAVE_OVERRIDE); ROS_SECURITY_STRATEGY=Enforce.";

/// A node of the graph, run by the `rover` subcommand of its name; ordered as they start.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, clap::Subcommand)]
pub enum Node {
    /// Run the bridge node: Socket.IO server for the simulator, telemetry and camera topics out,
    /// drive and pickup commands back.
    #[command(after_help = ROS_ARGS_HELP)]
    Bridge,
    /// Run the perception node: camera JPEGs to rover-frame terrain scans and the bird's-eye view.
    #[command(after_help = ROS_ARGS_HELP)]
    Perception,
    /// Run the mapping node: terrain scans to the world map, its image, statistics and rocks.
    #[command(after_help = ROS_ARGS_HELP)]
    Mapping,
    /// Run the decision node: the state machine that explores, approaches samples, recovers and
    /// returns home; one drive command per frame.
    #[command(after_help = ROS_ARGS_HELP)]
    Decision,
    /// Run the pickup node: one pickup request when a sample is in reach and the rover has stopped.
    #[command(after_help = ROS_ARGS_HELP)]
    Pickup,
}

impl Node {
    /// Every node, in start order (the bridge first, so the simulator finds its port).
    pub const ALL: [Node; 5] = [Node::Bridge, Node::Perception, Node::Mapping, Node::Decision, Node::Pickup];

    /// The node's name: its `rover` subcommand, its ROS node name and the name of its log file.
    pub const fn name(self) -> &'static str {
        match self {
            Node::Bridge => "bridge",
            Node::Perception => "perception",
            Node::Mapping => "mapping",
            Node::Decision => "decision",
            Node::Pickup => "pickup",
        }
    }

    /// The parameters the node declares.
    pub fn param_specs(self) -> Vec<ParamSpec> {
        match self {
            Node::Bridge => rover_bridge::node::BridgeParams::specs(),
            Node::Perception => rover_perception::params::PerceptionParams::specs(),
            Node::Mapping => rover_mapping::params::MappingParams::specs(),
            Node::Decision => rover_decision::params::DecisionParams::specs(),
            Node::Pickup => rover_pickup::PickupParams::specs(),
        }
    }

    /// Runs the node on `runtime` until it shuts down.
    pub fn run(self, runtime: &Runtime) -> LocalBoxFuture<'_, anyhow::Result<()>> {
        match self {
            Node::Bridge => rover_bridge::node::run(runtime).boxed_local(),
            Node::Perception => {
                rover_runtime::run_node::<rover_perception::node::PerceptionNode>(runtime).boxed_local()
            }
            Node::Mapping => rover_runtime::run_node::<rover_mapping::node::MappingNode>(runtime).boxed_local(),
            Node::Decision => rover_runtime::run_node::<rover_decision::node::DecisionNode>(runtime).boxed_local(),
            Node::Pickup => rover_runtime::run_node::<rover_pickup::node::PickupNode>(runtime).boxed_local(),
        }
    }
}

impl std::str::FromStr for Node {
    type Err = String;

    /// The node of a name as `rover nodes` lists it.
    fn from_str(name: &str) -> Result<Self, String> {
        Node::ALL
            .into_iter()
            .find(|node| node.name() == name)
            .ok_or_else(|| format!("no node '{name}'; expected one of {}", node_names().collect::<Vec<_>>().join(", ")))
    }
}

/// The names of every node, in start order.
pub fn node_names() -> impl Iterator<Item = &'static str> {
    Node::ALL.into_iter().map(Node::name)
}

/// The DDS Security enclave of the process of node `name` (`tools/keystore` makes one per node).
pub fn enclave_of(name: &str) -> String {
    format!("/rover/{name}")
}

/// A group of nodes as one argument, `NODE,NODE...` (`rover nodes --group`).
#[derive(Clone, Debug, PartialEq)]
pub struct Group(pub Vec<Node>);

impl std::str::FromStr for Group {
    type Err = String;

    fn from_str(list: &str) -> Result<Self, String> {
        let nodes = list.split(',').map(str::trim).filter(|name| !name.is_empty()).map(str::parse);
        let nodes = nodes.collect::<Result<Vec<Node>, String>>()?;
        if nodes.is_empty() {
            return Err(format!("no node in '{list}'; expected NODE,NODE..."));
        }
        Ok(Group(nodes))
    }
}

/// The processes of a graph whose `groups` each run in one process: every group's nodes
/// together, every other node alone, each process in start order of its nodes and the processes
/// in start order of their first node. Refuses a node in two groups.
pub fn processes(groups: &[Group]) -> anyhow::Result<Vec<Vec<Node>>> {
    let grouped: Vec<Node> = groups.iter().flat_map(|group| group.0.iter().copied()).collect();
    check_each_once(&grouped).map_err(|_| anyhow::anyhow!("{}", in_two_groups(&grouped)))?;
    let mut processes: Vec<Vec<Node>> = groups.iter().map(|group| sorted(&group.0)).collect();
    processes.extend(Node::ALL.into_iter().filter(|node| !grouped.contains(node)).map(|node| vec![node]));
    processes.sort_by_key(|process| process[0]);
    Ok(processes)
}

/// `nodes` in start order.
fn sorted(nodes: &[Node]) -> Vec<Node> {
    let mut nodes = nodes.to_vec();
    nodes.sort();
    nodes
}

/// The message for a node that is in two groups.
fn in_two_groups(grouped: &[Node]) -> String {
    let twice = grouped.iter().enumerate().find(|(i, node)| grouped[..*i].contains(node)).map(|(_, node)| node.name());
    format!("node '{}' is in two groups: a node runs in one process", twice.unwrap_or_default())
}

/// Runs `nodes` on one runtime (`rover all`, `rover container`), each at most once; the first
/// to fail stops the others.
pub async fn run_together(runtime: &Runtime, nodes: &[Node]) -> anyhow::Result<()> {
    check_each_once(nodes)?;
    let result = try_join_all(nodes.iter().map(|node| node.run(runtime))).await;
    runtime.shutdown().request();
    result.map(drop)
}

/// Refuses a node named twice: two nodes of one name would answer each other's services.
fn check_each_once(nodes: &[Node]) -> anyhow::Result<()> {
    for (i, node) in nodes.iter().enumerate() {
        anyhow::ensure!(
            !nodes[..i].contains(node),
            "node '{}' given twice: a process runs each node once",
            node.name()
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use clap::Subcommand as _;

    use super::*;

    #[test]
    fn a_node_is_run_at_most_once_in_a_process() {
        assert!(check_each_once(&Node::ALL).is_ok());
        let twice = check_each_once(&[Node::Mapping, Node::Decision, Node::Mapping]).unwrap_err().to_string();
        assert!(twice.contains("node 'mapping' given twice"), "{twice}");
    }

    #[test]
    fn groups_make_one_process_each_and_every_other_node_runs_alone_in_start_order() {
        let groups: Vec<Group> = ["pickup,mapping", "perception , bridge"].map(|g| g.parse().unwrap()).to_vec();
        let grouped = processes(&groups).unwrap();
        let names: Vec<Vec<&str>> = grouped.iter().map(|p| p.iter().map(|n| n.name()).collect()).collect();
        assert_eq!(names, [vec!["bridge", "perception"], vec!["mapping", "pickup"], vec!["decision"]]);
        let alone: Vec<usize> = processes(&[]).unwrap().iter().map(Vec::len).collect();
        assert_eq!(alone, [1; 5]);
    }

    #[test]
    fn a_group_with_a_wrong_name_or_a_node_in_two_groups_is_refused() {
        let wrong = "bridge,brige".parse::<Group>().unwrap_err();
        assert_eq!(wrong, "no node 'brige'; expected one of bridge, perception, mapping, decision, pickup");
        assert!(" , ".parse::<Group>().unwrap_err().contains("expected NODE,NODE"));
        let groups: Vec<Group> = ["bridge,mapping", "mapping,decision"].map(|g| g.parse().unwrap()).to_vec();
        let twice = processes(&groups).unwrap_err().to_string();
        assert_eq!(twice, "node 'mapping' is in two groups: a node runs in one process");
    }

    #[test]
    fn a_node_is_found_by_its_name_and_a_wrong_name_lists_the_right_ones() {
        assert_eq!("decision".parse::<Node>(), Ok(Node::Decision));
        let wrong = "brige".parse::<Node>().unwrap_err();
        assert_eq!(wrong, "no node 'brige'; expected one of bridge, perception, mapping, decision, pickup");
    }

    #[test]
    fn every_node_subcommand_is_in_the_list_under_its_name() {
        let command = Node::augment_subcommands(clap::Command::new("rover"));
        let subcommands: Vec<&str> = command.get_subcommands().map(clap::Command::get_name).collect();
        assert_eq!(subcommands, node_names().collect::<Vec<_>>());
    }
}
