//! rclpy against the whole graph, run against the headless simulator: a plain rclpy process
//! (`tests/python/interop_probe.py`) sees every node and topic of the graph (`rover_runtime::topics`) with its type, checks
//! the content of the messages, joins the latched map late, sets a bridge parameter through the
//! standard parameter services, drives the rover over `cmd_vel`, and times discovery. Run once with
//! every node in its own process and once with all of them in one (`rover all`).

mod support;

use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use rover::processes::graph::{Graph, GraphConfig};
use rover_runtime::sync::lock;
use support::{Domain, Process, start_process};

/// Seed of the procedural world (no sample is picked up during the probe's teleop phases).
const SEED: &str = "7";
/// From the start of the node processes to the first message on every graph topic. The probe has
/// imported rclpy already and joins the domain once every node is active: a Fast DDS participant
/// that joins while the RustDDS participants still create their endpoints can miss some of them for
/// good (see docs/ros2-tools.md).
const DISCOVERY_LIMIT_S: f64 = 2.0;
/// The longest the nodes may take to reach `active` on a loaded host.
const ACTIVATION_LIMIT: Duration = Duration::from_secs(20);
/// The same for the topics of images (120-154 kB, several datagrams each): on a loaded host an
/// image that the probe's full receive buffer lost waits for the writer's next heartbeat, up to
/// 1 s in RustDDS (seen: the first `/map/image` 2.15 s after the start, the `/rover/map_stats`
/// published with it 1.00 s).
const IMAGE_DISCOVERY_LIMIT_S: f64 = 3.0;
/// The image topics among [`STREAMING_TOPICS`].
const IMAGE_TOPICS: [&str; 3] = ["/camera/image_raw", "/map/image", "/rover/vision"];
/// The probe normally finishes in about 20 s.
const PROBE_TIMEOUT: Duration = Duration::from_secs(90);
/// Topics of `rover_runtime::topics` that carry messages while the rover drives; not among them: the
/// on-demand `rover/pickup`, the teleop input `cmd_vel`, the latched `/tf_static` and
/// `rover/plan`, and `/clock`.
const STREAMING_TOPICS: [&str; 16] = [
    "/camera/image_raw/compressed",
    "/camera/image_raw",
    "/camera/camera_info",
    "/odom",
    "/tf",
    "/rover/telemetry",
    "/sim/sample_truth",
    "/rover/terrain",
    "/rover/vision",
    "/map",
    "/map/image",
    "/rover/map_stats",
    "/rover/rocks",
    "/rover/drive_cmd",
    "/rover/mode",
    "/diagnostics",
];

/// The two modes share the two CPU cores badly; they run one after the other.
static ONE_GRAPH_AT_A_TIME: Mutex<()> = Mutex::new(());

/// How the graph's nodes are started.
#[derive(Debug, Clone, Copy)]
enum Mode {
    /// Each node in its own process (`rover bridge`, `rover perception`, ...).
    MultiProcess,
    /// Every node in one process (`rover all`).
    SingleProcess,
}

#[test]
fn rclpy_sees_checks_configures_and_drives_the_multi_process_graph() {
    run_probe_against_graph(Mode::MultiProcess);
}

#[test]
fn rclpy_sees_checks_configures_and_drives_the_single_process_graph() {
    run_probe_against_graph(Mode::SingleProcess);
}

fn run_probe_against_graph(mode: Mode) {
    let Some(python) = support::python_with(&["rclpy", "rover_msgs.msg", "tf2_msgs.msg", "PIL", "numpy"]) else {
        return;
    };
    support::assert_isolated();
    let _one_at_a_time = lock(&ONE_GRAPH_AT_A_TIME);
    let domain = Domain::reserve();
    let report_path = std::env::temp_dir().join(format!("rover-interop-{}-{}.json", domain.id, std::process::id()));
    let signals = [".ready", ".go"].map(|suffix| PathBuf::from(format!("{}{suffix}", report_path.display())));
    for file in signals.iter().chain([&report_path]) {
        let _ = std::fs::remove_file(file);
    }

    let wall_start = Instant::now();
    let mut probe = start_probe(&python, &domain, &report_path);
    let [ready, go] = &signals;
    assert!(support::eventually(Duration::from_secs(60), || ready.exists()), "the probe did not start");
    let graph_started_at = epoch_seconds(SystemTime::now());
    let mut graph = start_graph(mode, &domain);
    support::wait_for_port(domain.port(), Duration::from_secs(20));
    let active = support::eventually(ACTIVATION_LIMIT, || every_node_is_active(&mut graph));
    assert!(active, "{mode:?}: not every node reached `active`{}", log_tails(&mut graph, &probe));
    std::fs::write(go, b"go\n").expect("tell the probe the graph is up");
    let port = domain.port().to_string();
    let _sim =
        start_process(&support::rover(), &["sim", "--port", &port, "--seed", SEED, "--realtime"], &domain, "sim");
    let status = probe.wait_for_exit(PROBE_TIMEOUT);
    let logs = log_tails(&mut graph, &probe);

    assert!(status.is_some_and(|s| s.success()), "the probe did not finish cleanly ({status:?}){logs}");
    let report: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(&report_path).unwrap_or_else(|e| panic!("read {}: {e}{logs}", report_path.display())),
    )
    .expect("the probe's report is JSON");
    for file in signals.iter().chain([&report_path]) {
        let _ = std::fs::remove_file(file);
    }
    let discovery = discovery_figures(&report, graph_started_at);
    print_report(mode, &report, &discovery, wall_start.elapsed());

    let failed = failed_checks(&report);
    assert!(failed.is_empty(), "{mode:?}: failed checks:\n  {}{logs}", failed.join("\n  "));
    let crashed = graph.exited();
    assert!(crashed.is_empty(), "{mode:?}: nodes exited while the probe ran: {crashed:?}{logs}");
    assert_discovery_within_limit(mode, &discovery);
    let unclean = graph.stop(Duration::from_secs(10));
    assert!(unclean.is_empty(), "{mode:?}: nodes did not stop cleanly on SIGINT: {unclean:?}");
}

fn start_graph(mode: Mode, domain: &Domain) -> Graph {
    let ros_args = ["-p", &format!("bridge:port:={}", domain.port()), "-p", "bridge:publish_raw_image:=true"];
    let log_dir = std::env::temp_dir().join(format!("rover-interop-{mode:?}-{}", std::process::id()));
    let ros_args = ros_args.iter().map(|a| a.to_string()).collect();
    let config = GraphConfig { ros_args, ..support::graph_config(domain, log_dir) };
    match mode {
        Mode::MultiProcess => Graph::start(config),
        Mode::SingleProcess => Graph::start_nodes(config, &["all"]),
    }
    .expect("start the graph")
}

fn start_probe(python: &Path, domain: &Domain, report: &Path) -> Process {
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/python/interop_probe.py");
    let report = report.to_str().expect("a UTF-8 temporary path");
    let nodes = rover::processes::nodes::node_names().collect::<Vec<_>>().join(",");
    start_process(python, &["-W", "ignore", script, "--out", report, "--nodes", &nodes], domain, "interop-probe")
}

fn epoch_seconds(time: SystemTime) -> f64 {
    time.duration_since(UNIX_EPOCH).expect("the clock is after 1970").as_secs_f64()
}

/// Seconds from the graph's start to the first message of every streaming topic (`None`: none came).
fn discovery_figures(report: &serde_json::Value, graph_started_at: f64) -> Vec<(&'static str, Option<f64>)> {
    STREAMING_TOPICS
        .iter()
        .map(|&topic| (topic, report["first_message_at"][topic].as_f64().map(|at| at - graph_started_at)))
        .collect()
}

fn failed_checks(report: &serde_json::Value) -> Vec<String> {
    let checks = report["checks"].as_object().expect("the report has checks");
    assert!(checks.len() > 20, "the probe reported only {} checks", checks.len());
    checks
        .iter()
        .filter(|(_, check)| check["ok"].as_bool() != Some(true))
        .map(|(name, check)| format!("{name}: {}", check["detail"].as_str().unwrap_or("?")))
        .collect()
}

fn assert_discovery_within_limit(mode: Mode, discovery: &[(&str, Option<f64>)]) {
    let silent: Vec<&str> = discovery.iter().filter(|(_, s)| s.is_none()).map(|(t, _)| *t).collect();
    assert!(silent.is_empty(), "{mode:?}: no message on {silent:?}");
    assert!(IMAGE_TOPICS.iter().all(|t| STREAMING_TOPICS.contains(t)), "{IMAGE_TOPICS:?} are streaming topics");
    let late: Vec<String> = discovery
        .iter()
        .filter_map(|&(topic, seconds)| {
            let limit_s = if IMAGE_TOPICS.contains(&topic) { IMAGE_DISCOVERY_LIMIT_S } else { DISCOVERY_LIMIT_S };
            let seconds = seconds?;
            (seconds > limit_s).then(|| format!("{topic} after {seconds:.3} s (limit {limit_s} s)"))
        })
        .collect();
    assert!(late.is_empty(), "{mode:?}: first messages after the nodes started: {}", late.join(", "));
}

fn print_report(mode: Mode, report: &serde_json::Value, discovery: &[(&str, Option<f64>)], wall: Duration) {
    println!("rclpy interop, {mode:?}: first message after the nodes started");
    for (topic, seconds) in discovery {
        match seconds {
            Some(s) => println!("  {topic:32} {s:7.3} s"),
            None => println!("  {topic:32}    none"),
        }
    }
    if let Some(checks) = report["checks"].as_object() {
        for (name, check) in checks {
            let mark = if check["ok"].as_bool() == Some(true) { "ok  " } else { "FAIL" };
            println!("  {mark} {name}: {}", check["detail"].as_str().unwrap_or("?"));
        }
    }
    if let Some(notes) = report["notes"].as_object() {
        for (name, note) in notes {
            println!("  note {name}: {}", note.as_str().unwrap_or("?"));
        }
    }
    println!("rclpy interop, {mode:?}: wall time {:.1} s", wall.as_secs_f64());
}

/// The processes a graph of either mode may hold: `rover all`, or one per node.
fn process_names() -> impl Iterator<Item = &'static str> {
    std::iter::once("all").chain(rover::processes::nodes::node_names())
}

/// Whether every node of the graph has logged its activation, in its own log or in the one of
/// `rover all`.
fn every_node_is_active(graph: &mut Graph) -> bool {
    let activated: usize = process_names()
        .filter_map(|name| {
            graph.node_mut(name).map(|node| node.log_text().matches(support::ACTIVATED_LOG_LINE).count())
        })
        .sum();
    activated >= rover::processes::nodes::node_names().count()
}

/// The last lines of the probe's and the nodes' logs, for failure messages.
fn log_tails(graph: &mut Graph, probe: &Process) -> String {
    let mut text = format!("\n--- probe log ({}):\n{}", probe.log.display(), tail(&probe.log_text(), 30));
    for name in process_names() {
        if let Some(node) = graph.node_mut(name) {
            text += &format!("\n--- {name} log ({}):\n{}", node.log.display(), tail(&node.log_text(), 10));
        }
    }
    text
}

fn tail(text: &str, lines: usize) -> String {
    let all: Vec<&str> = text.lines().collect();
    all[all.len().saturating_sub(lines)..].join("\n")
}
