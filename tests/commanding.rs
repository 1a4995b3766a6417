//! Commanding the rover as ROS users do, against the graph and the headless simulator: an rclpy
//! script in the pattern of Nav2's simple commander (`tests/python/navigate_goals.py`) drives the
//! rover to goals drawn over the reachable floor of a procedural world and of the Unity world,
//! preempts a goal with another, sends a goal off the map and one inside a wall, and cancels a
//! goal mid-way; the real `ros2`
//! command line publishes a goal pose, sends a goal, calls each mission service, and is refused
//! clearly by a decision node that is not active; the official Foxglove client publishes a goal
//! through `rover live-view`; the README's example script drives the rover on the Unity world; a
//! decision node stopped during a goal ends it aborted, and its respawn takes the next one.

mod support;

use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Duration;

use rover::processes::graph::{Graph, GraphConfig};
use rover_msgs::msg::{DecisionState, Telemetry};
use rover_runtime::sync::lock;
use rover_runtime::topics;
use support::ros2::{assert_contains, ros2, ros2_ok};
use support::{Domain, Latest, eventually, start_process};

/// The goals of one world take about a minute.
const PROBE_TIMEOUT: Duration = Duration::from_secs(600);
/// A goal counts as reached this close, metres.
const REACHED_M: f64 = 1.5;
/// A canceled goal's rover brakes within this many frames (1 simulated second) of the cancel
/// request, counted from the telemetry the client had then.
const BRAKE_FRAMES: u64 = 25;

/// Two graphs at once share the two CPU cores badly.
static ONE_GRAPH_AT_A_TIME: Mutex<()> = Mutex::new(());

#[test]
fn an_rclpy_navigator_drives_to_goals_drawn_over_a_procedural_world() {
    navigate_drawn_goals("procedural", &["--seed", "11"], "11");
}

#[test]
fn an_rclpy_navigator_drives_to_goals_drawn_over_the_unity_world() {
    let world = support::surveyed_world_args();
    let world: Vec<&str> = world.iter().map(String::as_str).collect();
    navigate_drawn_goals("unity", &world, "5");
}

/// Runs the goal probe with goals drawn by `draw_seed` in the world of the simulator's
/// `world_args`, and checks its report.
fn navigate_drawn_goals(name: &str, world_args: &[&str], draw_seed: &str) {
    let Some(python) = support::python_with(&["rclpy", "rover_msgs.action", "nav2_msgs.action", "PIL", "numpy"]) else {
        return;
    };
    support::assert_isolated();
    let _one_at_a_time = lock(&ONE_GRAPH_AT_A_TIME);
    let domain = Domain::reserve();
    let work = work_dir(name);
    let floor = export_floor(world_args, &work);
    let mut graph = start_graph(&domain, &work);
    let port = domain.port().to_string();
    let sim_args: Vec<&str> = ["sim", "--port", &port].into_iter().chain(world_args.iter().copied()).collect();
    let _sim = start_process(&support::rover(), &sim_args, &domain, &format!("sim-{name}"));
    let report_path = work.join("report.json");
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/python/navigate_goals.py");
    let args =
        ["-W", "ignore", script, "--map", path_str(&floor), "--seed", draw_seed, "--out", path_str(&report_path)];
    let mut probe = start_process(&python, &args, &domain, &format!("goal-probe-{name}"));
    let status = probe.wait_for_exit(PROBE_TIMEOUT);
    let decision_log = graph.node_mut("all").map(|node| node.log_text()).unwrap_or_default();
    let logs = format!("\nprobe log:\n{}\ngraph log (tail):\n{}", probe.log_text(), tail(&decision_log, 60));
    assert!(status.is_some_and(|s| s.success()), "{name}: the goal probe did not finish ({status:?}){logs}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report_path).expect("the report")).expect("the report is JSON");
    eprintln!("{name}: {}", serde_json::to_string(&summary(&report)).unwrap_or_default());
    check_report(name, &report, &logs);
    let unclean = graph.stop(Duration::from_secs(10));
    assert!(unclean.is_empty(), "{name}: nodes did not stop cleanly: {unclean:?}");
}

/// A new folder of this test process for the test `name`.
fn work_dir(name: &str) -> PathBuf {
    let work = std::env::temp_dir().join(format!("rover-commanding-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&work).expect("create the test's folder");
    work
}

/// Writes the world's drivable cells to the test's folder: the floor the goals are drawn on.
fn export_floor(world_args: &[&str], work: &Path) -> PathBuf {
    let floor = work.join("floor.png");
    let status = std::process::Command::new(support::rover())
        .arg("sim")
        .args(world_args)
        .arg("--export-drivable")
        .arg(&floor)
        .status()
        .expect("run rover sim --export-drivable");
    assert!(status.success(), "rover sim --export-drivable failed");
    floor
}

/// Every node in one process, the mission held back: only goals move the rover.
fn start_graph(domain: &Domain, work: &Path) -> Graph {
    let ros_args = ["-p", &format!("bridge:port:={}", domain.port()), "-p", "decision:start_mission:=false"];
    let ros_args = ros_args.iter().map(|a| a.to_string()).collect();
    let config = GraphConfig { ros_args, ..support::graph_config(domain, work.join("logs")) };
    let graph = Graph::start_nodes(config, &["all"]).expect("start the graph");
    support::wait_for_port(domain.port(), Duration::from_secs(20));
    graph
}

fn check_report(name: &str, report: &serde_json::Value, logs: &str) {
    assert!(report["error"].is_null(), "{name}: {}{logs}", report["error"]);
    let goals = report["goals"].as_array().expect("goals in the report");
    assert_eq!(goals.len(), 5, "{name}: five goals");
    for goal in goals {
        assert_eq!(goal["status"], "SUCCEEDED", "{name}: {goal}{logs}");
        assert!(support::number(goal, "final_distance_m") <= REACHED_M, "{name}: {goal}");
        let feedback: Vec<f64> =
            goal["feedback"].as_array().expect("feedback").iter().filter_map(|d| d.as_f64()).collect();
        let (Some(first), Some(last)) = (feedback.first(), feedback.last()) else {
            panic!("{name}: no feedback: {goal}")
        };
        assert!(last < first, "{name}: distance_remaining falls: {goal}");
    }
    let preempt = &report["preempt"];
    assert_eq!(preempt["first"], "ABORTED", "{name}: a preempted goal: {preempt}");
    assert!(preempt["first_message"].as_str().is_some_and(|m| m.contains("preempted")), "{preempt}");
    assert_eq!(preempt["second"]["status"], "SUCCEEDED", "{name}: the goal that preempted: {preempt}");
    let off_map = &report["off_map"];
    assert_eq!((off_map["status"].as_str(), off_map["error_code"].as_u64()), (Some("ABORTED"), Some(204)), "{off_map}");
    let in_wall = &report["in_wall"];
    assert_eq!(in_wall["status"], "ABORTED", "{name}: a goal inside a wall: {in_wall}{logs}");
    assert!(in_wall["error_code"].as_u64().is_some_and(|code| code != 0), "{name}: {in_wall}");
    let cancel = &report["cancel"];
    assert_eq!((cancel["driving"].as_bool(), cancel["status"].as_str()), (Some(true), Some("CANCELED")), "{cancel}");
    assert_eq!((cancel["stopped"].as_bool(), cancel["brake"].as_bool()), (Some(true), Some(true)), "{cancel}");
    let frames = cancel["frames_to_brake"].as_u64().expect("frames_to_brake");
    assert!(frames <= BRAKE_FRAMES, "{name}: braked {frames} frames after the cancel, limit {BRAKE_FRAMES}: {cancel}");
    let mission = &report["mission"];
    assert_eq!((mission["status"].as_str(), mission["stopped"].as_bool()), (Some("CANCELED"), Some(true)), "{mission}");
    let modes = mission["feedback_modes"].as_array().map_or(0, Vec::len);
    assert!(modes >= 3, "{name}: the mission's feedback: {mission}");
}

/// The report without the feedback series: what the test prints.
fn summary(report: &serde_json::Value) -> serde_json::Value {
    let mut summary = report.clone();
    for goal in summary["goals"].as_array_mut().into_iter().flatten() {
        let feedback = goal["feedback"].as_array().map_or(0, Vec::len);
        goal["feedback"] = feedback.into();
    }
    summary
}

/// What the test process sees of the rover: its telemetry and the decision node's mode.
struct Watch {
    telemetry: Latest<Telemetry>,
    mode: Latest<DecisionState>,
    _node: rover_runtime::RosNode,
    _runtime: rover_runtime::Runtime,
}

impl Watch {
    fn start(domain: &Domain) -> Watch {
        let runtime = support::test_runtime(domain);
        let (mut node, _) = runtime.node::<rover_runtime::NoParams>("command_watch").expect("the test's node");
        let telemetry = Latest::subscribe(&mut node, &topics::TELEMETRY);
        let mode = Latest::subscribe(&mut node, &topics::MODE);
        Watch { telemetry, mode, _node: node, _runtime: runtime }
    }

    fn position(&self) -> (f64, f64) {
        self.telemetry.last().map_or((f64::NAN, f64::NAN), |t| (t.x_m, t.y_m))
    }

    fn mode(&self) -> String {
        self.mode.last().map(|m| m.mode).unwrap_or_default()
    }

    /// Whether within `seconds` the rover is moving (`true`) or stopped with the brake on.
    fn eventually_moving(&self, moving: bool, seconds: u64) -> bool {
        eventually(Duration::from_secs(seconds), || {
            self.telemetry
                .last()
                .is_some_and(|t| if moving { t.speed_mps > 0.5 } else { t.speed_mps.abs() < 0.2 && t.brake > 0.0 })
        })
    }
}

/// A goal `(x, y)` on the drivable floor of `floor_png` (with drivable cells all around), reached
/// from `start` over drivable cells, between `near_m` and `far_m` from it: the first such cell of a
/// breadth-first walk.
fn goal_on_floor(floor_png: &Path, start: (f64, f64), near_m: f64, far_m: f64) -> (f64, f64) {
    let image = rover_imaging::decode_png(&std::fs::read(floor_png).expect("the floor PNG")).expect("a PNG");
    let side = image.width;
    let drivable = |x: usize, y: usize| x < side && y < side && image.pixel(x, y)[0] > 0;
    let clear = |x: usize, y: usize| {
        (x.saturating_sub(1)..=x + 1).all(|cx| (y.saturating_sub(1)..=y + 1).all(|cy| drivable(cx, cy)))
    };
    let first = (start.0 as usize, start.1 as usize);
    let mut seen = vec![false; side * side];
    let mut queue = std::collections::VecDeque::from([first]);
    seen[first.1 * side + first.0] = true;
    while let Some((x, y)) = queue.pop_front() {
        let distance = (x as f64 + 0.5 - start.0).hypot(y as f64 + 0.5 - start.1);
        if (near_m..=far_m).contains(&distance) && clear(x, y) {
            return (x as f64 + 0.5, y as f64 + 0.5);
        }
        let next = [(x + 1, y), (x.wrapping_sub(1), y), (x, y + 1), (x, y.wrapping_sub(1))];
        for (nx, ny) in next.into_iter().filter(|&(nx, ny)| drivable(nx, ny)) {
            if !std::mem::replace(&mut seen[ny * side + nx], true) {
                queue.push_back((nx, ny));
            }
        }
    }
    panic!("no drivable cell {near_m}..{far_m} m from {start:?} in {}", floor_png.display());
}

/// A `geometry_msgs/PoseStamped` in `map` at `(x, y)`, as YAML for the `ros2` command line.
fn pose_yaml((x, y): (f64, f64)) -> String {
    format!("{{header: {{frame_id: map}}, pose: {{position: {{x: {x}, y: {y}}}, orientation: {{w: 1.0}}}}}}")
}

#[tokio::test(flavor = "multi_thread")]
async fn the_ros2_command_line_sends_goals_and_calls_the_mission_services() {
    let Some(domain) = support::ros2_domain_or_skip() else { return };
    let _one_at_a_time = lock(&ONE_GRAPH_AT_A_TIME);
    let work = work_dir("cli");
    let world = ["--seed", "12"];
    let floor = export_floor(&world, &work);
    let mut graph = start_graph(&domain, &work);
    let watch = Watch::start(&domain);
    let port = domain.port().to_string();
    let _sim = start_process(&support::rover(), &["sim", "--port", &port, "--seed", "12"], &domain, "sim-cli");
    assert!(eventually(Duration::from_secs(30), || watch.mode() == "idle"), "the rover holds until told");
    let start = watch.position();
    let log = |graph: &mut Graph| graph.node_mut("all").map(|node| tail(&node.log_text(), 40)).unwrap_or_default();
    let near = |goal: (f64, f64)| {
        let (x, y) = watch.position();
        (x - goal.0).hypot(y - goal.1) <= REACHED_M
    };

    let first = goal_on_floor(&floor, start, 6.0, 12.0);
    ros2_ok(
        &domain,
        &[
            "topic",
            "pub",
            "--once",
            "-w",
            "1",
            "--keep-alive",
            "5",
            "/goal_pose",
            "geometry_msgs/msg/PoseStamped",
            &pose_yaml(first),
        ],
    );
    let reached = eventually(Duration::from_secs(90), || near(first) && watch.mode() == "idle");
    assert!(
        reached,
        "goal_pose {first:?}: the rover is at {:?}, mode {}\n{}",
        watch.position(),
        watch.mode(),
        log(&mut graph)
    );

    let second = goal_on_floor(&floor, first, 6.0, 12.0);
    let goal = format!("{{pose: {}}}", pose_yaml(second));
    let action = ["action", "send_goal", "--feedback", "/navigate_to_pose", "nav2_msgs/action/NavigateToPose", &goal];
    let (_, sent) = ros2(&domain, Duration::from_secs(120), &action);
    assert_contains(
        &sent,
        &["Goal accepted", "distance_remaining", "Goal finished with status: SUCCEEDED"],
        "send_goal",
    );
    assert!(near(second), "send_goal {second:?}: the rover is at {:?}", watch.position());

    let call =
        |service: &str| ros2_ok(&domain, &["service", "call", &format!("/decision/{service}"), "std_srvs/srv/Trigger"]);
    assert_contains(&call("start_mission"), &["success=True", "mission started"], "start_mission");
    assert!(watch.eventually_moving(true, 60), "the mission drives the rover");
    assert_contains(&call("pause_mission"), &["success=True"], "pause_mission");
    assert!(watch.eventually_moving(false, 20) && watch.mode() == "paused", "pause brakes and holds");
    assert_contains(&call("pause_mission"), &["success=False", "already paused"], "pause twice");
    assert_contains(&call("resume_mission"), &["success=True"], "resume_mission");
    assert!(watch.eventually_moving(true, 60), "resume drives on");
    // The mission as an action: feedback while it runs (the rclpy probe cancels one).
    let mission = ["action", "send_goal", "--feedback", "/sample_return", "rover_msgs/action/SampleReturn", "{}"];
    let (_, followed) = ros2(&domain, Duration::from_secs(8), &mission);
    assert_contains(
        &followed,
        &["Goal accepted", "Feedback:", "mode: explore", "samples_collected: "],
        "sample_return",
    );
    assert_contains(&call("return_home"), &["success=True", "returning home"], "return_home");
    let homeward = eventually(Duration::from_secs(20), || ["return_home", "done"].contains(&watch.mode().as_str()));
    assert!(homeward, "return_home: mode {}", watch.mode());
    let (_, scored) = ros2(&domain, Duration::from_secs(120), &mission);
    let score = ["Goal finished with status: SUCCEEDED", "complete: false", "samples_remaining: ", "home with"];
    assert_contains(&scored, &score, "sample_return to the end of a mission sent home");

    ros2_ok(&domain, &["lifecycle", "set", "/decision", "deactivate"]);
    assert_contains(&call("pause_mission"), &["success=False", "is inactive", "ros2 lifecycle set"], "inactive");
    let (_, refused) = ros2(&domain, Duration::from_secs(60), &action);
    assert_contains(&refused, &["Goal finished with status: ABORTED", "is inactive"], "a goal while inactive");
    ros2_ok(&domain, &["lifecycle", "set", "/decision", "cleanup"]);
    assert_contains(&call("start_mission"), &["success=False", "is unconfigured"], "unconfigured");
    let _ = ros2(&domain, Duration::from_secs(15), &["daemon", "stop"]);
    let unclean = graph.stop(Duration::from_secs(10));
    assert!(unclean.is_empty(), "nodes did not stop cleanly: {unclean:?}");
}

#[test]
fn the_example_script_drives_three_goals_then_starts_the_mission() {
    let Some(python) = support::python_with(&["rclpy", "nav2_msgs.action", "std_srvs.srv"]) else { return };
    support::assert_isolated();
    let _one_at_a_time = lock(&ONE_GRAPH_AT_A_TIME);
    let domain = Domain::reserve();
    let work = work_dir("example");
    let graph = start_graph(&domain, &work);
    let port = domain.port().to_string();
    let world = support::surveyed_world_args();
    let sim_args: Vec<&str> = ["sim", "--port", &port].into_iter().chain(world.iter().map(String::as_str)).collect();
    let _sim = start_process(&support::rover(), &sim_args, &domain, "sim-example");
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/scripts/three_goals_then_mission.py");
    let example = std::process::Command::new("timeout")
        .args(["--signal=INT", "180"])
        .arg(&python)
        .args(["-W", "ignore", script])
        .env("ROS_DOMAIN_ID", domain.id.to_string())
        .output()
        .expect("run the example");
    let said = format!("{}{}", String::from_utf8_lossy(&example.stdout), String::from_utf8_lossy(&example.stderr));
    assert!(example.status.success(), "the example did not finish ({}):\n{said}", example.status);
    let reached = said.lines().filter(|line| line.contains(": status 4, error 0")).count();
    assert_eq!(reached, 3, "three goals SUCCEEDED (status 4):\n{said}");
    assert!(said.contains("start_mission: mission started"), "{said}");
    let unclean = graph.stop(Duration::from_secs(10));
    assert!(unclean.is_empty(), "nodes did not stop cleanly: {unclean:?}");
}

#[tokio::test(flavor = "multi_thread")]
async fn a_goal_ends_aborted_when_the_decision_node_is_stopped_and_its_respawn_takes_the_next() {
    let Some(domain) = support::ros2_domain_or_skip() else { return };
    let _one_at_a_time = lock(&ONE_GRAPH_AT_A_TIME);
    let work = work_dir("respawn");
    let world = ["--seed", "14"];
    let floor = export_floor(&world, &work);
    let ros_args = ["-p", &format!("bridge:port:={}", domain.port()), "-p", "decision:start_mission:=false"];
    let ros_args = ros_args.iter().map(|a| a.to_string()).collect();
    let config = GraphConfig { ros_args, respawn: true, ..support::graph_config(&domain, work.join("logs")) };
    let mut graph = Graph::start(config).expect("start the graph");
    let watch = Watch::start(&domain);
    let port = domain.port().to_string();
    let _sim = start_process(&support::rover(), &["sim", "--port", &port, "--seed", "14"], &domain, "sim-respawn");
    assert!(eventually(Duration::from_secs(30), || watch.mode() == "idle"), "the rover holds until told");

    let far = goal_on_floor(&floor, watch.position(), 25.0, 45.0);
    let goal = format!("{{pose: {}}}", pose_yaml(far));
    let send_goal = |goal: &str| {
        let args = ["action", "send_goal", "/navigate_to_pose", "nav2_msgs/action/NavigateToPose", goal];
        ros2(&domain, Duration::from_secs(120), &args).1
    };
    let ended = std::thread::scope(|scope| {
        let first = scope.spawn(|| send_goal(&goal));
        assert!(watch.eventually_moving(true, 60) && watch.mode() == "navigate", "the rover drives to {far:?}");
        let decision = graph.processes().find(|(name, _)| *name == "decision").map(|(_, pid)| pid).expect("decision");
        rover::processes::graph::send_signal(decision, nix::sys::signal::Signal::SIGTERM);
        first.join().expect("the first send_goal")
    });
    assert_contains(&ended, &["Goal finished with status: ABORTED", "the decision node stopped"], "stopped mid-goal");

    let respawned = eventually(Duration::from_secs(30), || {
        graph.respawn_dead();
        ros2(&domain, Duration::from_secs(10), &["lifecycle", "get", "/decision"]).1.contains("active [3]")
    });
    assert!(respawned, "the decision node is back and active");
    let next = goal_on_floor(&floor, watch.position(), 6.0, 12.0);
    let second = send_goal(&format!("{{pose: {}}}", pose_yaml(next)));
    assert_contains(&second, &["Goal finished with status: SUCCEEDED"], "a goal to the respawned node");
    let unclean = graph.stop(Duration::from_secs(10));
    assert!(unclean.is_empty(), "nodes did not stop cleanly: {unclean:?}");
}

/// Node.js with the Foxglove client that tools/setup-js installs; `None` (skip) without them,
/// which fails the test when `ROVER_REQUIRE_ROS` is set (tools/test-all).
fn node_with_foxglove_client() -> Option<PathBuf> {
    let modules = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/js/node_modules");
    let found = modules.join("@foxglove/ws-protocol").exists()
        && std::process::Command::new("node").arg("--version").output().is_ok_and(|o| o.status.success());
    assert!(
        found || std::env::var_os("ROVER_REQUIRE_ROS").is_none(),
        "no node or no {}: run tools/setup-js",
        modules.display()
    );
    found.then_some(modules)
}

#[tokio::test(flavor = "multi_thread")]
async fn a_foxglove_client_publishes_a_goal_through_the_live_view_and_the_rover_reaches_it() {
    let Some(node_modules) = node_with_foxglove_client() else { return };
    support::assert_isolated();
    let _one_at_a_time = lock(&ONE_GRAPH_AT_A_TIME);
    let domain = Domain::reserve();
    let work = work_dir("foxglove");
    let floor = export_floor(&["--seed", "13"], &work);
    let mut graph = start_graph(&domain, &work);
    let watch = Watch::start(&domain);
    let view_port = support::free_port().to_string();
    let _view = start_process(&support::rover(), &["live-view", "--port", &view_port], &domain, "live-view");
    let port = domain.port().to_string();
    let _sim = start_process(&support::rover(), &["sim", "--port", &port, "--seed", "13"], &domain, "sim-foxglove");
    assert!(eventually(Duration::from_secs(30), || watch.mode() == "idle"), "the rover holds until told");
    support::wait_for_port(view_port.parse().expect("a port"), Duration::from_secs(20));
    let goal = goal_on_floor(&floor, watch.position(), 6.0, 12.0);

    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/js/publish_goal.cjs");
    let url = format!("ws://127.0.0.1:{view_port}");
    let published = std::process::Command::new("node")
        .args([script, &url, &goal.0.to_string(), &goal.1.to_string()])
        .env("NODE_PATH", &node_modules)
        .output()
        .expect("run node");
    let said = format!("{}{}", String::from_utf8_lossy(&published.stdout), String::from_utf8_lossy(&published.stderr));
    assert!(published.status.success(), "the Foxglove client failed: {said}");

    let reached = eventually(Duration::from_secs(90), || {
        let (x, y) = watch.position();
        (x - goal.0).hypot(y - goal.1) <= REACHED_M && watch.mode() == "idle"
    });
    let log = graph.node_mut("all").map(|node| tail(&node.log_text(), 30)).unwrap_or_default();
    assert!(
        reached,
        "goal {goal:?} from Foxglove: the rover is at {:?}, mode {}\n{log}",
        watch.position(),
        watch.mode()
    );
    let unclean = graph.stop(Duration::from_secs(10));
    assert!(unclean.is_empty(), "nodes did not stop cleanly: {unclean:?}");
}

fn tail(text: &str, lines: usize) -> String {
    let all: Vec<&str> = text.lines().collect();
    all[all.len().saturating_sub(lines)..].join("\n")
}

fn path_str(path: &Path) -> &str {
    path.to_str().expect("a UTF-8 temporary path")
}
