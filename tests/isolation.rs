//! Graphs side by side without crosstalk: three complete graphs (`rover sim` + the five nodes, each
//! its own process) run at once in one network namespace: A in `/a` and B in `/b` on one DDS
//! domain, C in `/a` again on a second domain. Every namespace of every domain carries only its own
//! simulator's frames, and each simulator's rover is driven only by its own decision node: when the
//! decision nodes of B and C die, their bridges brake for lack of commands while A's, which shares
//! B's domain and C's namespace, keeps getting fresh ones.

mod support;

use std::collections::BTreeSet;
use std::path::Path;
use std::time::Duration;

use rover::processes::graph::{Graph, GraphConfig};
use rover_bridge::stats::SILENCE_BRAKES_KEY;
use rover_msgs::diagnostic_msgs::DiagnosticArray;
use rover_msgs::geometry_msgs::PoseArray;
use rover_msgs::msg::{DriveCommand, Telemetry};
use rover_runtime::ros_args::Remap;
use rover_runtime::{RosArgs, RosNode, Runtime, Shutdown, topics};
use support::{Domain, Latest, Process, STOP_TIMEOUT, eventually, graph_config, rover, start_process};

/// What a test node receives in one namespace of one domain.
struct Observer {
    telemetry: Latest<Telemetry>,
    drive: Latest<DriveCommand>,
    sample_truth: Latest<PoseArray>,
    _node: RosNode,
}

impl Observer {
    fn start(runtime: &Runtime, name: &str) -> Observer {
        let (mut node, _) = runtime.node::<rover_runtime::NoParams>(name).expect("create the observer node");
        Observer {
            telemetry: Latest::subscribe(&mut node, &topics::TELEMETRY),
            drive: Latest::subscribe(&mut node, &topics::DRIVE_CMD),
            sample_truth: Latest::subscribe(&mut node, &topics::SAMPLE_TRUTH),
            _node: node,
        }
    }

    fn is_silent(&self) -> bool {
        self.telemetry.all().is_empty() && self.drive.all().is_empty() && self.sample_truth.all().is_empty()
    }
}

/// The test's view of one DDS domain: `/diagnostics` and observers in the namespaces `/a` and `/b`.
struct DomainView {
    diagnostics: Latest<DiagnosticArray>,
    a: Observer,
    b: Observer,
    _diagnostics_node: RosNode,
    _runtime: Runtime,
}

impl DomainView {
    fn start(domain: &Domain) -> DomainView {
        let remap =
            |node: &str, namespace: &str| Remap { node: Some(node.into()), from: "__ns".into(), to: namespace.into() };
        let ros_args = RosArgs { remaps: vec![remap("obs_a", "/a"), remap("obs_b", "/b")], ..RosArgs::default() };
        let runtime = Runtime::on_domain(domain.id, ros_args, Shutdown::new()).expect("the test's DDS participant");
        let a = Observer::start(&runtime, "obs_a");
        let b = Observer::start(&runtime, "obs_b");
        let (mut node, _) =
            runtime.node::<rover_runtime::NoParams>("obs_diagnostics").expect("create the diagnostics observer");
        let diagnostics = Latest::subscribe(&mut node, &topics::DIAGNOSTICS);
        DomainView { diagnostics, a, b, _diagnostics_node: node, _runtime: runtime }
    }

    /// The names of the bridges that published `/diagnostics` on this domain.
    fn bridges(&self) -> BTreeSet<String> {
        self.diagnostics.all().iter().flat_map(|d| d.status.iter()).map(|s| s.name.clone()).collect()
    }

    /// Counter `key` of the latest `/diagnostics` of the bridge `/NAMESPACE/bridge`.
    fn counter(&self, namespace: &str, key: &str) -> Option<u64> {
        let name = format!("{namespace}/bridge: simulator link");
        let all = self.diagnostics.all();
        let status = all.iter().rev().flat_map(|d| d.status.iter()).find(|s| s.name == name)?;
        status.value(key)?.parse().ok()
    }
}

/// One graph with its simulator.
struct SimulatedGraph {
    label: &'static str,
    graph: Graph,
    sim: Process,
}

impl SimulatedGraph {
    fn start(label: &'static str, domain: &Domain, port: u16, namespace: &'static str, seed: u64) -> SimulatedGraph {
        let params = Path::new(env!("CARGO_MANIFEST_DIR")).join("launch_scripts/rover_params.yaml");
        let ros_args = ["--params-file", params.to_str().expect("a UTF-8 path"), "-r"]
            .into_iter()
            .map(String::from)
            .chain([format!("__ns:={namespace}"), "-p".into(), "bridge:diagnostics_period_ms:=200.0".into()])
            .collect();
        let log_dir = std::env::temp_dir().join(format!("rover-isolation-{label}-{}", std::process::id()));
        let config = GraphConfig { port, ros_args, ..graph_config(domain, log_dir) };
        let graph = Graph::start(config).unwrap_or_else(|e| panic!("start graph {label}: {e:#}"));
        let port = port.to_string();
        let seed = seed.to_string();
        let args = ["sim", "--seed", &seed, "--port", &port, "--realtime"];
        let sim = start_process(&rover(), &args, domain, &format!("isolation-sim-{label}"));
        SimulatedGraph { label, graph, sim }
    }

    /// Stops the graph and the simulator; fails unless every remaining process exits cleanly.
    fn stop(mut self) {
        let unclean = self.graph.stop(Duration::from_secs(10));
        assert!(unclean.is_empty(), "graph {}: {unclean:?} did not exit cleanly", self.label);
        let status = self.sim.interrupt(STOP_TIMEOUT).expect("the simulator stops on SIGINT");
        assert!(status.success(), "simulator of graph {}: {status}", self.label);
    }
}

/// Fails unless the frame numbers of `what` strictly increase, as they do from a single bridge.
fn assert_one_frame_sequence(what: &str, frames: &[u64]) {
    assert!(!frames.is_empty(), "{what}: nothing received");
    if let Some(pair) = frames.windows(2).find(|w| w[1] <= w[0]) {
        panic!("{what}: frame {} after {}: two sources on one topic ({} frames)", pair[1], pair[0], frames.len());
    }
}

/// The sample positions of a sample-truth message, to the centimetre.
fn sample_set(message: &PoseArray) -> BTreeSet<(i64, i64)> {
    message
        .poses
        .iter()
        .map(|p| ((p.position.x * 100.0).round() as i64, (p.position.y * 100.0).round() as i64))
        .collect()
}

/// Fails unless every sample-truth message of `what` is the first one or a part of it (pickups only
/// remove samples); returns the first.
fn assert_one_world(what: &str, messages: &[PoseArray]) -> BTreeSet<(i64, i64)> {
    let first = sample_set(messages.first().unwrap_or_else(|| panic!("{what}: no sample truth received")));
    for message in &messages[1..] {
        assert!(sample_set(message).is_subset(&first), "{what}: sample truth of another world: {message:?}");
    }
    first
}

fn check_namespace(what: &str, observer: &Observer) -> BTreeSet<(i64, i64)> {
    let telemetry: Vec<u64> = observer.telemetry.all().iter().map(|t| t.frame).collect();
    assert_one_frame_sequence(&format!("{what} rover/telemetry"), &telemetry);
    let drive: Vec<u64> = observer.drive.all().iter().map(|d| d.frame).collect();
    assert_one_frame_sequence(&format!("{what} rover/drive_cmd"), &drive);
    assert_one_world(&format!("{what} sim/sample_truth"), &observer.sample_truth.all())
}

/// The bridge counters the test follows, read from `/diagnostics`: per graph, the replies with a
/// fresh command of a decision node (`*_fresh`) and the brakes for lack of commands (`*_braking`).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Counters {
    a_fresh: u64,
    a_braking: u64,
    b_fresh: u64,
    b_braking: u64,
    c_fresh: u64,
    c_braking: u64,
}

impl Counters {
    fn read(one: &DomainView, two: &DomainView) -> Counters {
        let value = |view: &DomainView, namespace: &str, key: &str| view.counter(namespace, key).unwrap_or(0);
        Counters {
            a_fresh: value(one, "/a", "replies_fresh"),
            a_braking: value(one, "/a", SILENCE_BRAKES_KEY),
            b_fresh: value(one, "/b", "replies_fresh"),
            b_braking: value(one, "/b", SILENCE_BRAKES_KEY),
            c_fresh: value(two, "/a", "replies_fresh"),
            c_braking: value(two, "/a", SILENCE_BRAKES_KEY),
        }
    }

    /// Every graph has been driven by its decision node.
    fn all_driven(&self) -> bool {
        self.a_fresh > 0 && self.b_fresh > 0 && self.c_fresh > 0
    }
}

#[test]
fn graphs_in_two_namespaces_and_two_domains_do_not_cross_talk() {
    support::assert_isolated();
    let tokio = tokio::runtime::Runtime::new().expect("a tokio runtime");
    let _entered = tokio.enter();
    let (first, second) = (Domain::reserve(), Domain::reserve());
    let (one, two) = (DomainView::start(&first), DomainView::start(&second));
    let a = SimulatedGraph::start("a", &first, first.port(), "/a", 1);
    let mut b = SimulatedGraph::start("b", &first, first.port() + 1, "/b", 2);
    let mut c = SimulatedGraph::start("c", &second, second.port(), "/a", 3);

    let all_running = eventually(Duration::from_secs(45), || {
        [&one.a, &one.b, &two.a].iter().all(|o| o.telemetry.all().len() >= 30 && !o.drive.all().is_empty())
            && Counters::read(&one, &two).all_driven()
    });
    assert!(
        all_running,
        "not every graph runs (logs in {}/rover-isolation-*): telemetry {} / {} / {}, {:?}, bridges {:?} / {:?}",
        std::env::temp_dir().display(),
        one.a.telemetry.all().len(),
        one.b.telemetry.all().len(),
        two.a.telemetry.all().len(),
        Counters::read(&one, &two),
        one.bridges(),
        two.bridges()
    );

    let running = Counters::read(&one, &two);
    b.graph.kill("decision");
    c.graph.kill("decision");
    // The bridges of B and C brake once no command came for their silence limit: from then on no
    // fresh command of the killed nodes is still on its way.
    let braking = eventually(Duration::from_secs(15), || {
        let now = Counters::read(&one, &two);
        now.b_braking > running.b_braking && now.c_braking > running.c_braking
    });
    assert!(braking, "the bridges of B and C brake after their decision nodes are killed");
    let before = Counters::read(&one, &two);
    let settled = eventually(Duration::from_secs(15), || {
        let now = Counters::read(&one, &two);
        now.b_braking > before.b_braking + 10
            && now.c_braking > before.c_braking + 10
            && now.a_fresh > before.a_fresh + 10
    });
    let after = Counters::read(&one, &two);
    assert!(settled, "after killing the decision nodes of B and C: before {before:?}, after {after:?}");
    assert_eq!(after.b_fresh, before.b_fresh, "B's bridge got fresh commands without its decision node");
    assert_eq!(after.c_fresh, before.c_fresh, "C's bridge got fresh commands without its decision node");
    assert_eq!(after.a_braking, before.a_braking, "A's bridge braked for lack of commands while its decision ran");

    let world_a = check_namespace("domain 1 /a", &one.a);
    let world_b = check_namespace("domain 1 /b", &one.b);
    let world_c = check_namespace("domain 2 /a", &two.a);
    assert!(world_a != world_b && world_a != world_c && world_b != world_c, "the seeds give different worlds");
    assert!(two.b.is_silent(), "domain 2 has no /b graph, yet /b received messages (from domain 1?)");
    let bridge = |namespace: &str| format!("{namespace}/bridge: simulator link");
    assert_eq!(one.bridges(), BTreeSet::from([bridge("/a"), bridge("/b")]), "/diagnostics of domain 1");
    assert_eq!(two.bridges(), BTreeSet::from([bridge("/a")]), "/diagnostics of domain 2");
    eprintln!(
        "frames received: A {}, B {}, C {}; counters {after:?}",
        one.a.telemetry.all().len(),
        one.b.telemetry.all().len(),
        two.a.telemetry.all().len()
    );
    for graph in [a, b, c] {
        graph.stop();
    }
}
