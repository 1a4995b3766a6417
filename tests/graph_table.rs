//! The graph table (`libs/runtime/src/graph.rs`) is the one description of the graph: a node of
//! the graph opens only the topics it gives the node, and the node list, the architecture
//! document's table of topics and the README's picture agree with it.

mod support;

use std::collections::BTreeSet;

use rover::processes::nodes::node_names;
use rover_runtime::graph::{GRAPH, inputs_from_outside};
use rover_runtime::{NoParams, RosArgs, Runtime, Shutdown, topics};
use support::Domain;

fn read(path: &str) -> String {
    let path = format!("{}/{path}", env!("CARGO_MANIFEST_DIR"));
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// Every topic that the table names.
fn table_topics() -> BTreeSet<&'static str> {
    GRAPH.iter().flat_map(|n| n.reads.iter().chain(n.writes)).copied().collect()
}

/// The topics among the `code` spans of `text`.
fn topics_named_in(text: &str) -> BTreeSet<String> {
    let known = table_topics();
    text.split('`').skip(1).step_by(2).filter(|span| known.contains(span)).map(str::to_string).collect()
}

#[test]
fn the_node_list_is_the_tables_in_start_order() {
    assert_eq!(node_names().collect::<Vec<_>>(), GRAPH.iter().map(|n| n.node).collect::<Vec<_>>());
}

#[test]
fn the_architecture_documents_table_gives_each_node_the_topics_of_the_graph_table() {
    let doc = read("docs/architecture.md");
    for node in &GRAPH {
        let row = doc
            .lines()
            .find(|line| line.starts_with(&format!("| `{}` |", node.node)))
            .unwrap_or_else(|| panic!("docs/architecture.md has no row for {}", node.node));
        let cells: Vec<&str> = row.split('|').map(str::trim).collect();
        let (reads, writes) = (topics_named_in(cells[2]), topics_named_in(cells[3]));
        let expected = |topics: &[&str]| topics.iter().map(|t| t.to_string()).collect::<BTreeSet<_>>();
        assert_eq!(reads, expected(node.reads), "{} reads", node.node);
        assert_eq!(writes, expected(node.writes), "{} writes", node.node);
    }
}

#[test]
fn the_readmes_picture_and_its_caption_show_every_topic_between_two_nodes() {
    let readme = read("README.md");
    let picture_end = readme.find("## The two commands").expect("the README's sections");
    let (picture, caption) = readme[..picture_end].split_once("```\n\n").expect("the picture's code block");
    let shown: BTreeSet<&str> = table_topics().into_iter().filter(|t| picture.contains(t)).collect();
    let named = topics_named_in(caption);
    let between_nodes = GRAPH.iter().flat_map(|n| n.reads.iter().copied());
    for topic in between_nodes.chain(inputs_from_outside()) {
        assert!(shown.contains(topic) || named.contains(topic), "{topic} is neither drawn nor named");
    }
    for node in &GRAPH {
        assert!(picture.contains(node.node), "{} is not in the picture", node.node);
    }
}

#[test]
fn a_node_of_the_graph_opens_only_the_topics_the_table_gives_it() {
    support::assert_isolated();
    let tokio = tokio::runtime::Runtime::new().expect("a tokio runtime");
    let _entered = tokio.enter();
    let domain = Domain::reserve();
    let runtime = Runtime::on_domain(domain.id, RosArgs::default(), Shutdown::new()).expect("a DDS participant");
    let (mut pickup, _) = runtime.node::<NoParams>("pickup").expect("the pickup node");
    let refused = pickup.publisher(&topics::DRIVE_CMD).map(drop).expect_err("pickup does not drive");
    assert!(refused.to_string().contains("does not let node pickup write rover/drive_cmd"), "{refused}");
    assert!(pickup.subscription(&topics::MAP).is_err(), "pickup does not read the map");
    assert!(pickup.publisher(&topics::PICKUP).is_ok() && pickup.subscription(&topics::TELEMETRY).is_ok());
    let (mut tool, _) = runtime.node::<NoParams>("observer").expect("a node outside the graph");
    assert!(tool.publisher(&topics::DRIVE_CMD).is_ok(), "a tool outside the graph opens any topic");
}
