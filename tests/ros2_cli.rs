//! The official `ros2` command line against the graph (issue 17): in one loopback-only namespace,
//! `ros2 daemon start` first, then the graph in separate processes with the headless simulator
//! (`launch_scripts/rover-graph --sim 0`), then `ros2 node list`, `topic list -t`, `topic echo
//! --once` (telemetry, the latched map and static transforms, odom, `/clock`), `topic hz`, `topic info -v`,
//! `param list/get/set/dump/load`, `node info`, `service list`, `doctor --report` (every QoS pair
//! compatible), `interface show` and `lifecycle nodes/get/list/set` (the decision node
//! deactivated, so that the rover stops, and activated again), each checked on its output. The graph runs with
//! `use_sim_time:=true`, so its stamps must be the simulated time of `/clock`, not the wall clock.
//! A node's WARN reaches `ros2 topic echo /rosout`, and the logging ROS arguments
//! (`--log-level NODE:=LEVEL`, `--disable-rosout-logs`, `--disable-stdout-logs`) are obeyed. The CLI comes from the wheels of
//! `../shared/ros2-python` that `tools/setup-ros` installs into `.venv`.

mod support;

use std::path::Path;
use std::time::{Duration, Instant};

use support::ros2::{Daemon, assert_contains, echoed_value, ros2, ros2_ok, ros2_with_env};
use support::{Domain, STOP_TIMEOUT, eventually, rover, start_process};

/// Every topic of the graph but `/clock` (checked on its own) with its type, as
/// `ros2 topic list -t` prints it.
const TOPICS: [&str; 22] = [
    "/camera/image_raw/compressed [sensor_msgs/msg/CompressedImage]",
    "/camera/image_raw [sensor_msgs/msg/Image]",
    "/camera/camera_info [sensor_msgs/msg/CameraInfo]",
    "/odom [nav_msgs/msg/Odometry]",
    "/tf [tf2_msgs/msg/TFMessage]",
    "/tf_static [tf2_msgs/msg/TFMessage]",
    "/rover/telemetry [rover_msgs/msg/Telemetry]",
    "/sim/sample_truth [geometry_msgs/msg/PoseArray]",
    "/rover/terrain [rover_msgs/msg/TerrainScan]",
    "/rover/vision [sensor_msgs/msg/Image]",
    "/map [nav_msgs/msg/OccupancyGrid]",
    "/map/image [sensor_msgs/msg/Image]",
    "/rover/map_stats [rover_msgs/msg/MapStats]",
    "/rover/rocks [geometry_msgs/msg/PoseArray]",
    "/rover/sample_markers [visualization_msgs/msg/MarkerArray]",
    "/rover/drive_cmd [rover_msgs/msg/DriveCommand]",
    "/rover/pickup [rover_msgs/msg/PickupRequest]",
    "/rover/mode [rover_msgs/msg/DecisionState]",
    "/rover/plan [nav_msgs/msg/Path]",
    "/cmd_vel [geometry_msgs/msg/Twist]",
    "/goal_pose [geometry_msgs/msg/PoseStamped]",
    "/diagnostics [diagnostic_msgs/msg/DiagnosticArray]",
];

/// Stamps below this many seconds are simulated time; the wall clock is past 1.7e9 s.
const SIM_TIME_LIMIT_S: i64 = 1_000_000;

/// The first `sec:` value of a `ros2 topic echo` output.
fn first_sec(output: &str) -> Option<i64> {
    echoed_value(output, "sec")
}

fn assert_sim_time(output: &str, what: &str) {
    let sec = first_sec(output);
    assert!(sec.is_some_and(|sec| sec < SIM_TIME_LIMIT_S), "{what}: not stamped in simulated time:\n{output}");
}

#[test]
fn the_ros2_command_line_started_before_the_graph_sees_reads_and_configures_it() {
    let Some(domain) = support::ros2_domain_or_skip() else { return };
    let started = Instant::now();
    let daemon = Daemon::start(&domain);

    let graph_script = Path::new(env!("CARGO_MANIFEST_DIR")).join("launch_scripts/rover-graph");
    let log_dir = std::env::temp_dir().join(format!("rover-ros2-cli-{}-{}", domain.id, std::process::id()));
    let (rover, port, domain_id) = (rover(), domain.port().to_string(), domain.id.to_string());
    let log_dir = log_dir.to_str().unwrap();
    // camera/image_raw is published only on request; the test wants every topic of the graph.
    let args = ["--rover", rover.to_str().unwrap(), "--sim", "0", "--domain", &domain_id, "--port", &port];
    let ros_args = ["-p", "bridge:publish_raw_image:=true", "-p", "use_sim_time:=true"];
    let args = [&args[..], &["--log-dir", log_dir, "--"], &ros_args[..]].concat();
    let mut graph = start_process(&graph_script, &args, &domain, "ros2-cli-graph");

    // Through the daemon, which existed before any participant of the graph.
    let mut nodes = String::new();
    let listed = eventually(Duration::from_secs(30), || {
        nodes = ros2(&domain, Duration::from_secs(15), &["node", "list"]).1;
        rover::processes::nodes::node_names().all(|node| nodes.lines().any(|line| line.trim() == format!("/{node}")))
    });
    assert!(listed, "`ros2 node list` lacks nodes:\n{nodes}\ngraph log:\n{}", graph.log_text());
    eprintln!(
        "ros2 node list: all five nodes {:.1} s after the test started the daemon",
        started.elapsed().as_secs_f64()
    );

    std::thread::scope(|scope| {
        let domain = &domain;
        let topics = scope.spawn(|| ros2_ok(domain, &["topic", "list", "-t"]));
        let telemetry = scope.spawn(|| ros2_ok(domain, &["topic", "echo", "--once", "/rover/telemetry"]));
        let map = scope.spawn(|| ros2_ok(domain, &["topic", "echo", "--once", "--no-arr", "/map"]));
        let odom = scope.spawn(|| ros2_ok(domain, &["topic", "echo", "--once", "/odom"]));
        let tf_static = scope.spawn(|| ros2_ok(domain, &["topic", "echo", "--once", "/tf_static"]));
        let markers = scope.spawn(|| ros2_ok(domain, &["topic", "echo", "--once", "/rover/sample_markers"]));
        // Without the type named: only rosgraph_msgs/msg/Clock may be on /clock.
        let clock = scope.spawn(|| ros2_ok(domain, &["topic", "echo", "--once", "/clock"]));
        let sim_time = scope.spawn(|| ros2_ok(domain, &["param", "get", "/mapping", "use_sim_time"]));
        let hz = scope.spawn(|| ros2(domain, Duration::from_secs(20), &["topic", "hz", "/rover/telemetry"]).1);
        let info = scope.spawn(|| ros2_ok(domain, &["topic", "info", "-v", "/map"]));
        let interface = scope.spawn(|| ros2_ok(domain, &["interface", "show", "rover_msgs/msg/Telemetry"]));
        let lifecycle = scope.spawn(|| lifecycle_of_the_decision_node(domain));
        let everyday = scope.spawn(|| everyday_commands(domain));
        let params = scope.spawn(|| {
            let list = ros2_ok(domain, &["param", "list", "/bridge"]);
            let before = ros2_ok(domain, &["param", "get", "/bridge", "teleop_timeout_ms"]);
            let set = ros2_ok(domain, &["param", "set", "/bridge", "teleop_timeout_ms", "1500.0"]);
            let after = ros2_ok(domain, &["param", "get", "/bridge", "teleop_timeout_ms"]);
            let refused =
                ros2(domain, Duration::from_secs(30), &["param", "set", "/bridge", "teleop_timeout_ms", "-1.0"]).1;
            let described = ros2_ok(domain, &["param", "describe", "/bridge", "teleop_timeout_ms"]);
            (list, before, set, after, refused, described)
        });

        let topics = topics.join().unwrap();
        for topic in TOPICS {
            assert!(topics.lines().any(|line| line.trim() == topic), "`ros2 topic list -t`: no `{topic}` in\n{topics}");
        }
        let clock_line = topics.lines().find(|line| line.starts_with("/clock ["));
        assert_eq!(
            clock_line.map(str::trim),
            Some("/clock [rosgraph_msgs/msg/Clock]"),
            "`ros2 topic list -t`: /clock must have the one type rosgraph_msgs/msg/Clock in\n{topics}"
        );
        let clock = clock.join().unwrap();
        assert_contains(&clock, &["clock:", "nanosec: "], "/clock");
        assert!(first_sec(&clock).is_some_and(|sec| sec > 0), "/clock is still at zero:\n{clock}");
        assert_sim_time(&clock, "/clock");
        assert_contains(&sim_time.join().unwrap(), &["Boolean value is: True"], "ros2 param get use_sim_time");
        let telemetry = telemetry.join().unwrap();
        assert_sim_time(&telemetry, "telemetry");
        assert_contains(
            &telemetry,
            &["frame_id: odom", "frame: ", "x_m: ", "speed_mps: ", "samples_remaining: ", "---"],
            "telemetry",
        );
        let map = map.join().unwrap();
        assert_sim_time(&map, "latched map");
        assert_contains(&map, &["frame_id: map", "resolution: ", "width: 200", "height: 200"], "latched map");
        assert_contains(
            &odom.join().unwrap(),
            &["frame_id: odom", "child_frame_id: base_link", "position:", "orientation:"],
            "odom",
        );
        assert_contains(
            &tf_static.join().unwrap(),
            &[
                "frame_id: map",
                "child_frame_id: odom",
                "child_frame_id: camera_link",
                "child_frame_id: camera_optical_frame",
            ],
            "latched static transforms",
        );
        // The latched markers decode field by field: the first deletes the earlier ones.
        assert_contains(&markers.join().unwrap(), &["markers:", "frame_id: map", "action: 3", "mesh_file:"], "markers");
        let hz = hz.join().unwrap();
        let rate = hz
            .lines()
            .filter_map(|line| line.trim().strip_prefix("average rate: "))
            .filter_map(|rate| rate.trim().parse::<f64>().ok())
            .next_back();
        assert!(
            rate.is_some_and(|rate| rate > 1.0),
            "`ros2 topic hz /rover/telemetry` printed no rate above 1 Hz:\n{hz}"
        );
        eprintln!("ros2 topic hz /rover/telemetry: {:.1} Hz", rate.unwrap_or_default());
        assert_contains(
            &info.join().unwrap(),
            &[
                "Type: nav_msgs/msg/OccupancyGrid",
                "Publisher count: 1",
                "Node name: mapping",
                "Node name: decision",
                "Endpoint type: PUBLISHER",
                "Endpoint type: SUBSCRIPTION",
                "Durability: TRANSIENT_LOCAL",
            ],
            "ros2 topic info -v /map",
        );
        assert_contains(
            &interface.join().unwrap(),
            &["std_msgs/Header header", "uint64 frame", "uint8 samples_remaining"],
            "interface show",
        );
        check_lifecycle(&lifecycle.join().unwrap());
        check_everyday_commands(&everyday.join().unwrap());
        let (list, before, set, after, refused, described) = params.join().unwrap();
        assert_contains(&list, &["teleop_timeout_ms", "diagnostics_period_ms", "port"], "ros2 param list /bridge");
        assert_contains(&before, &["Double value is: 500.0"], "ros2 param get");
        assert_contains(&set, &["Set parameter successful"], "ros2 param set");
        assert_contains(&after, &["Double value is: 1500.0"], "ros2 param get after the set");
        assert_contains(
            &refused,
            &["Setting parameter failed", "outside the allowed range"],
            "ros2 param set out of range",
        );
        assert_contains(
            &described,
            &["Type: double", "Description: ", "Min value: 0.0", "Max value: 2000.0"],
            "ros2 param describe",
        );
    });

    drop(daemon);
    let status = graph.interrupt(STOP_TIMEOUT);
    assert!(
        status.is_some_and(|s| s.success()),
        "the graph did not stop cleanly on SIGINT: {status:?}\n{}",
        graph.log_text()
    );
    eprintln!("ros2 command line test: {:.1} s", started.elapsed().as_secs_f64());
}

/// What the everyday commands printed: `node info` of each node, `service list -t`, `param dump`,
/// `param load` of the dump with one value changed, `param get` after it, `topic echo /rosout`,
/// `doctor --report`; and the dumps of nodes started with `--params-file` of a dump, beside the
/// originals'.
struct EverydayOutputs {
    node_info: Vec<(&'static str, String)>,
    services: String,
    reproduced: Vec<(String, String)>,
    dump: String,
    load: String,
    loaded: String,
    rosout: String,
    doctor: String,
}

fn everyday_commands(domain: &Domain) -> EverydayOutputs {
    let node_info = rover::processes::nodes::node_names()
        .map(|node| (node, ros2_ok(domain, &["node", "info", &format!("/{node}")])))
        .collect();
    let services = ros2_ok(domain, &["service", "list", "-t"]);
    let reproduced = ["pickup", "decision"].map(|node| dump_and_copy(domain, node)).to_vec();
    let dump = ros2_ok(domain, &["param", "dump", "/pickup"]);
    let file = std::env::temp_dir().join(format!("rover-ros2-cli-pickup-{}-{}.yaml", domain.id, std::process::id()));
    // `ros2 param load` of ros2param 0.36.1 counts the parameters it expects from the wildcard
    // section only (it reads the file without the node's name), so the file holds them under `/**`.
    let wildcard = dump.replace("/pickup:", "/**:").replace("retry_s: 2.0", "retry_s: 3.5");
    std::fs::write(&file, wildcard).expect("write the parameter file");
    let load = ros2(domain, Duration::from_secs(30), &["param", "load", "/pickup", file.to_str().unwrap()]).1;
    assert!(load.contains("successful"), "ros2 param load of\n{dump}\nprinted\n{load}");
    let loaded = ros2_ok(domain, &["param", "get", "/pickup", "retry_s"]);
    let _ = std::fs::remove_file(&file);
    let rosout = ros2_ok(domain, &["topic", "echo", "--once", "/rosout"]);
    let doctor = ros2_ok(domain, &["doctor", "--report"]);
    EverydayOutputs { node_info, services, reproduced, dump, load, loaded, rosout, doctor }
}

/// `ros2 param dump /NODE`, and the dump of a copy of the node started in namespace `/copy` with
/// `--params-file` of that dump (its section keyed `/**`), named as the original.
fn dump_and_copy(domain: &Domain, node: &str) -> (String, String) {
    let dump = ros2_ok(domain, &["param", "dump", &format!("/{node}")]);
    let file = std::env::temp_dir().join(format!("rover-ros2-cli-{node}-{}-{}.yaml", domain.id, std::process::id()));
    std::fs::write(&file, dump.replace(&format!("/{node}:"), "/**:")).expect("write the dump");
    let args = [node, "--ros-args", "-r", "__ns:=/copy", "--params-file", file.to_str().unwrap()];
    let mut copy = start_process(&rover(), &args, domain, &format!("ros2-cli-{node}-copy"));
    let mut copied = String::new();
    eventually(Duration::from_secs(30), || {
        copied = ros2(domain, Duration::from_secs(20), &["param", "dump", &format!("/copy/{node}")]).1;
        copied.contains("ros__parameters:")
    });
    copy.interrupt(STOP_TIMEOUT);
    let _ = std::fs::remove_file(&file);
    (dump, copied.replace(&format!("/copy/{node}:"), &format!("/{node}:")))
}

/// What `ros2 node info /NODE` must list for each node: a topic it publishes, one it takes, and
/// its services and actions.
const NODE_INFO: [(&str, &[&str]); 5] = [
    ("bridge", &["/rover/telemetry: rover_msgs/msg/Telemetry", "/rover/drive_cmd: rover_msgs/msg/DriveCommand"]),
    (
        "perception",
        &[
            "/camera/image_raw/compressed: sensor_msgs/msg/CompressedImage",
            "/rover/terrain: rover_msgs/msg/TerrainScan",
        ],
    ),
    (
        "mapping",
        &[
            "/rover/terrain: rover_msgs/msg/TerrainScan",
            "/map: nav_msgs/msg/OccupancyGrid",
            "/rover/sample_markers: visualization_msgs/msg/MarkerArray",
        ],
    ),
    (
        "decision",
        &[
            "/map: nav_msgs/msg/OccupancyGrid",
            "/rover/drive_cmd: rover_msgs/msg/DriveCommand",
            "Action Servers:",
            "/navigate_to_pose: nav2_msgs/action/NavigateToPose",
            "/decision/start_mission: std_srvs/srv/Trigger",
        ],
    ),
    ("pickup", &["/rover/telemetry: rover_msgs/msg/Telemetry", "/rover/pickup: rover_msgs/msg/PickupRequest"]),
];

fn check_everyday_commands(outputs: &EverydayOutputs) {
    for ((node, info), (expected_node, expected)) in outputs.node_info.iter().zip(NODE_INFO) {
        assert_eq!(*node, expected_node, "the nodes in start order");
        let common = [
            "Subscribers:",
            "Publishers:",
            "Service Servers:",
            "/get_parameters: rcl_interfaces/srv/GetParameters",
            "/change_state: lifecycle_msgs/srv/ChangeState",
        ];
        assert_contains(info, &common, &format!("ros2 node info /{node}"));
        assert_contains(info, expected, &format!("ros2 node info /{node}"));
    }
    let services = [
        "/bridge/set_parameters [rcl_interfaces/srv/SetParameters]",
        "/decision/get_state [lifecycle_msgs/srv/GetState]",
        "/pickup/list_parameters [rcl_interfaces/srv/ListParameters]",
    ];
    assert_contains(&outputs.services, &services, "ros2 service list -t");
    for (dump, copied) in &outputs.reproduced {
        assert_eq!(copied, dump, "a node started with --params-file of a dump has the dumped parameters");
    }
    assert_contains(&outputs.dump, &["/pickup:", "ros__parameters:", "retry_s: 2.0"], "ros2 param dump /pickup");
    assert_contains(&outputs.load, &["Set parameter retry_s successful"], "ros2 param load");
    assert_contains(&outputs.loaded, &["Double value is: 3.5"], "ros2 param get after the load");
    assert_contains(&outputs.rosout, &["name: ", "msg: ", "level: "], "ros2 topic echo /rosout");
    let report = ["RMW MIDDLEWARE", "QOS COMPATIBILITY LIST", "TOPIC LIST", "topic               : /rover/telemetry"];
    assert_contains(&outputs.doctor, &report, "ros2 doctor --report");
    let pairs = outputs.doctor.lines().filter(|line| line.starts_with("compatibility status")).collect::<Vec<_>>();
    assert!(
        !pairs.is_empty() && pairs.iter().all(|line| line.ends_with(": OK")),
        "ros2 doctor --report: every publisher/subscriber pair's QoS must be compatible:\n{}",
        outputs.doctor
    );
}

/// What `ros2 lifecycle` printed as it took the decision node down to inactive and back up.
struct LifecycleOutputs {
    nodes: String,
    active: String,
    listed: String,
    refused: String,
    deactivated: String,
    inactive: String,
    telemetry_while_inactive: String,
    activated: String,
    active_again: String,
}

/// `ros2 lifecycle nodes`, `get`, `list` and `set` on the decision node: deactivate it, read the
/// rover's telemetry once it has had time to stop, activate it again.
fn lifecycle_of_the_decision_node(domain: &Domain) -> LifecycleOutputs {
    let nodes = ros2_ok(domain, &["lifecycle", "nodes"]);
    let active = ros2_ok(domain, &["lifecycle", "get", "/decision"]);
    let listed = ros2_ok(domain, &["lifecycle", "list", "/decision"]);
    let refused = ros2(domain, Duration::from_secs(30), &["lifecycle", "set", "/decision", "configure"]).1;
    let deactivated = ros2_ok(domain, &["lifecycle", "set", "/decision", "deactivate"]);
    let inactive = ros2_ok(domain, &["lifecycle", "get", "/decision"]);
    std::thread::sleep(Duration::from_secs(3));
    let telemetry_while_inactive = ros2_ok(domain, &["topic", "echo", "--once", "/rover/telemetry"]);
    let activated = ros2_ok(domain, &["lifecycle", "set", "/decision", "activate"]);
    let active_again = ros2_ok(domain, &["lifecycle", "get", "/decision"]);
    LifecycleOutputs {
        nodes,
        active,
        listed,
        refused,
        deactivated,
        inactive,
        telemetry_while_inactive,
        activated,
        active_again,
    }
}

fn check_lifecycle(outputs: &LifecycleOutputs) {
    for node in rover::processes::nodes::node_names().map(|name| format!("/{name}")) {
        assert!(
            outputs.nodes.lines().any(|l| l.trim() == node.as_str()),
            "`ros2 lifecycle nodes` lacks {node}:\n{}",
            outputs.nodes
        );
    }
    assert_contains(&outputs.active, &["active [3]"], "ros2 lifecycle get, at start");
    assert_contains(
        &outputs.listed,
        &["- deactivate [4]", "- shutdown [7]", "Start: active", "Goal: deactivating"],
        "ros2 lifecycle list",
    );
    assert_contains(&outputs.refused, &["Unknown transition requested", "deactivate [4]"], "configure while active");
    assert_contains(&outputs.deactivated, &["Transitioning successful"], "ros2 lifecycle set deactivate");
    assert_contains(&outputs.inactive, &["inactive [2]"], "ros2 lifecycle get, deactivated");
    let telemetry = &outputs.telemetry_while_inactive;
    let speed_mps = echoed_value::<f64>(telemetry, "speed_mps").expect("speed_mps in the telemetry");
    let brake = echoed_value::<f64>(telemetry, "brake").expect("brake in the telemetry");
    assert!(
        speed_mps.abs() < 0.2 && brake > 0.0,
        "the rover still moves with the decision node inactive:\n{telemetry}"
    );
    assert_contains(&outputs.activated, &["Transitioning successful"], "ros2 lifecycle set activate");
    assert_contains(&outputs.active_again, &["active [3]"], "ros2 lifecycle get, activated again");
}

#[test]
fn the_ros2_command_line_shows_the_rover_interfaces() {
    let Some(domain) = support::ros2_domain_or_skip() else { return };
    let (ok, shown) = ros2(&domain, Duration::from_secs(30), &["interface", "show", "rover_msgs/msg/DriveCommand"]);
    assert!(ok, "{shown}");
    assert_contains(
        &shown,
        &["std_msgs/Header header", "uint64 frame"],
        "ros2 interface show rover_msgs/msg/DriveCommand",
    );
    let (ok, packages) = ros2(&domain, Duration::from_secs(30), &["interface", "package", "rover_msgs"]);
    assert!(ok, "{packages}");
    for message in ["DecisionState", "DriveCommand", "MapStats", "PickupRequest", "Telemetry", "TerrainScan"] {
        assert!(
            packages.lines().any(|l| l.trim() == format!("rover_msgs/msg/{message}")),
            "{message} missing:\n{packages}"
        );
    }
}

/// The graph reads the loop's per-frame topics best effort, so a publisher with ROS's sensor-data
/// profile (best effort, which a reliable reader refuses) reaches them: `ros2 topic pub
/// --qos-profile sensor_data` on `rover/telemetry` gets the echo node's answer on `rover/drive_cmd`.
#[tokio::test(flavor = "multi_thread")]
async fn a_sensor_data_publisher_reaches_the_loops_readers() {
    let Some(domain) = support::ros2_domain_or_skip() else { return };
    let _echo = start_process(&support::echo_node(), &[], &domain, "ros2-cli-echo");
    let runtime = support::test_runtime(&domain);
    let (mut node, _) = runtime.node::<rover_runtime::NoParams>("sensor_data_observer").expect("the observer node");
    let replies = support::Latest::subscribe(&mut node, &rover_runtime::topics::DRIVE_CMD);
    let telemetry = "{frame: 7, x_m: 3.0}";
    let args = ["topic", "pub", "--qos-profile", "sensor_data", "-r", "10", "-t", "50"];
    let args = [&args[..], &["/rover/telemetry", "rover_msgs/msg/Telemetry", telemetry]].concat();
    let (_, published) = ros2(&domain, Duration::from_secs(8), &args);
    let answers: Vec<_> = replies.all().into_iter().filter(|reply| reply.frame == 7).collect();
    assert!(!answers.is_empty(), "no drive command answered the sensor-data telemetry; ros2 topic pub:\n{published}");
    assert!(answers.iter().all(|reply| reply.brake == 7.0 && (reply.throttle - 0.003).abs() < 1e-6));
}

/// With `ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST` on both sides, the `ros2` command line (Fast
/// DDS) and a node of the graph still find each other on the one host.
#[test]
fn the_ros2_command_line_finds_a_node_when_both_keep_discovery_on_this_host() {
    let Some(domain) = support::ros2_domain_or_skip() else { return };
    let localhost = [("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")];
    let log =
        std::env::temp_dir().join(format!("rover-test-{}-localhost-pickup-{}.log", domain.id, std::process::id()));
    let mut command = std::process::Command::new(rover());
    command.arg("pickup").env("ROS_DOMAIN_ID", domain.id.to_string()).envs(localhost);
    let mut pickup = support::Process::spawn("localhost-pickup", command, log).expect("start the pickup node");
    let mut nodes = String::new();
    let found = eventually(Duration::from_secs(30), || {
        nodes = ros2_with_env(&domain, &localhost, Duration::from_secs(15), &["node", "list", "--no-daemon"]).1;
        nodes.contains("/pickup")
    });
    assert!(found, "`ros2 node list` on LOCALHOST did not list /pickup:\n{nodes}\nnode log:\n{}", pickup.log_text());
    let status = pickup.interrupt(STOP_TIMEOUT);
    assert!(status.is_some_and(|s| s.success()), "pickup did not stop cleanly: {status:?}\n{}", pickup.log_text());
}

/// A node started with `autostart:=false` waits unconfigured, with no publisher of its data, and
/// `ros2 lifecycle set` brings it up (the publisher appears) and shuts it down: the pickup node,
/// alone.
#[test]
fn a_node_started_without_autostart_comes_up_through_ros2_lifecycle_set() {
    let Some(domain) = support::ros2_domain_or_skip() else { return };
    let args = ["pickup", "--ros-args", "-p", "autostart:=false"];
    let mut pickup = start_process(&rover(), &args, &domain, "lifecycle-pickup");
    let mut state = String::new();
    let listed = eventually(Duration::from_secs(30), || {
        state = ros2(&domain, Duration::from_secs(15), &["lifecycle", "get", "/pickup"]).1;
        state.contains('[')
    });
    assert!(listed, "`ros2 lifecycle get /pickup` found no state:\n{state}\nnode log:\n{}", pickup.log_text());
    assert_contains(&state, &["unconfigured [1]"], "ros2 lifecycle get, autostart false");
    // With no endpoint at all on it, the topic is unknown to the graph: no publisher either.
    let publishers = |count: &str| {
        let expected = format!("Publisher count: {count}");
        let mut info = String::new();
        let seen = eventually(Duration::from_secs(20), || {
            info = ros2(&domain, Duration::from_secs(15), &["topic", "info", "/rover/pickup"]).1;
            info.contains(&expected) || (count == "0" && info.contains("Unknown topic '/rover/pickup'"))
        });
        assert!(seen, "`ros2 topic info /rover/pickup`: no `{expected}` in\n{info}");
    };
    publishers("0");
    let set = |transition: &str, state: &str| {
        let set = ros2_ok(&domain, &["lifecycle", "set", "/pickup", transition]);
        assert_contains(&set, &["Transitioning successful"], &format!("ros2 lifecycle set {transition}"));
        assert_contains(&ros2_ok(&domain, &["lifecycle", "get", "/pickup"]), &[state], transition);
    };
    set("configure", "inactive [2]");
    publishers("1");
    set("activate", "active [3]");
    set("shutdown", "finalized [4]");
    let status = pickup.interrupt(STOP_TIMEOUT);
    assert!(status.is_some_and(|s| s.success()), "pickup did not stop cleanly: {status:?}\n{}", pickup.log_text());
}

/// A graph started unconfigured (`rover all -p autostart:=false`) holds the rover with the brake;
/// `rover lifecycle-manager` brings its five nodes up in start order, and the rover drives.
#[test]
fn the_lifecycle_manager_brings_an_unconfigured_graph_up_and_the_rover_drives() {
    let Some(domain) = support::ros2_domain_or_skip() else { return };
    let port = domain.port().to_string();
    let port_param = format!("bridge:port:={port}");
    let args = ["all", "--ros-args", "-p", "autostart:=false", "-p", &port_param];
    let mut graph = start_process(&rover(), &args, &domain, "manager-graph");
    let mut sim = start_process(&rover(), &["sim", "--seed", "0", "--port", &port], &domain, "manager-sim");
    let states = || -> Vec<String> {
        rover::processes::nodes::node_names()
            .map(|name| ros2(&domain, Duration::from_secs(15), &["lifecycle", "get", &format!("/{name}")]).1)
            .collect()
    };
    let mut seen = Vec::new();
    let unconfigured = eventually(Duration::from_secs(30), || {
        seen = states();
        seen.iter().all(|state| state.contains("unconfigured [1]"))
    });
    assert!(unconfigured, "not every node waits unconfigured: {seen:?}\ngraph log:\n{}", graph.log_text());
    let held = ros2_ok(&domain, &["topic", "echo", "--once", "/rover/telemetry"]);
    let brake = echoed_value::<f64>(&held, "brake").expect("brake in the telemetry");
    assert!(brake > 0.0, "the unconfigured graph does not hold the rover:\n{held}");
    let diagnostics = ros2_ok(&domain, &["topic", "echo", "--once", "/diagnostics"]);
    assert!(diagnostics.contains("bridge"), "the unconfigured bridge reports its health:\n{diagnostics}");

    let mut manager = start_process(&rover(), &["lifecycle-manager"], &domain, "manager");
    let active = eventually(Duration::from_secs(60), || {
        seen = states();
        seen.iter().all(|state| state.contains("active [3]") && !state.contains("inactive"))
    });
    assert!(active, "the manager did not bring every node up: {seen:?}\nmanager log:\n{}", manager.log_text());
    let mut telemetry = String::new();
    let drives = eventually(Duration::from_secs(60), || {
        telemetry = ros2_ok(&domain, &["topic", "echo", "--once", "/rover/telemetry"]);
        echoed_value::<f64>(&telemetry, "speed_mps").is_some_and(|speed| speed > 0.3)
    });
    assert!(drives, "the rover does not drive once the graph is up:\n{telemetry}\ngraph log:\n{}", graph.log_text());
    let order: Vec<usize> = rover::processes::nodes::node_names()
        .map(|name| manager.log_text().find(&format!("/{name}: configured and active")).unwrap_or(usize::MAX))
        .collect();
    assert!(order.windows(2).all(|pair| pair[0] < pair[1]), "not brought up in start order:\n{}", manager.log_text());
    for process in [&mut manager, &mut sim, &mut graph] {
        let status = process.interrupt(STOP_TIMEOUT);
        assert!(
            status.is_some_and(|s| s.success()),
            "a process did not stop cleanly: {status:?}\n{}",
            process.log_text()
        );
    }
}

/// Two containers (`rover container bridge perception`, `rover container mapping decision
/// pickup`) make the whole graph: `ros2 node list` lists the five nodes and the rover drives;
/// stopping the second container takes its three nodes away and leaves the first two.
#[test]
fn two_containers_make_the_graph_and_each_takes_its_own_nodes_away() {
    let Some(domain) = support::ros2_domain_or_skip() else { return };
    let port = domain.port().to_string();
    let port_param = format!("bridge:port:={port}");
    let front_args = ["container", "bridge", "perception", "--ros-args", "-p", &port_param];
    let mut front = start_process(&rover(), &front_args, &domain, "container-front");
    let mut back = start_process(&rover(), &["container", "mapping", "decision", "pickup"], &domain, "container-back");
    let _sim = start_process(&rover(), &["sim", "--seed", "0", "--port", &port], &domain, "container-sim");
    let node_list = || ros2(&domain, Duration::from_secs(15), &["node", "list", "--no-daemon"]).1;
    let listed = |list: &str, names: &[&str]| names.iter().all(|name| list.lines().any(|line| line.trim() == *name));
    let (all, front_nodes, back_nodes) = (
        ["/bridge", "/perception", "/mapping", "/decision", "/pickup"],
        ["/bridge", "/perception"],
        ["/mapping", "/decision", "/pickup"],
    );
    let mut nodes = String::new();
    let graph_up = eventually(Duration::from_secs(30), || {
        nodes = node_list();
        listed(&nodes, &all)
    });
    assert!(graph_up, "not every node listed:\n{nodes}\nfront log:\n{}", front.log_text());
    let mut telemetry = String::new();
    let drives = eventually(Duration::from_secs(60), || {
        telemetry = ros2_ok(&domain, &["topic", "echo", "--once", "/rover/telemetry"]);
        echoed_value::<f64>(&telemetry, "speed_mps").is_some_and(|speed| speed > 0.3)
    });
    assert!(drives, "the rover does not drive:\n{telemetry}\nback log:\n{}", back.log_text());
    let status = back.interrupt(STOP_TIMEOUT);
    assert!(status.is_some_and(|s| s.success()), "the container did not stop cleanly:\n{}", back.log_text());
    let back_gone = eventually(Duration::from_secs(30), || {
        nodes = node_list();
        listed(&nodes, &front_nodes) && !back_nodes.iter().any(|name| listed(&nodes, &[name]))
    });
    assert!(back_gone, "after the second container stopped:\n{nodes}");
    let status = front.interrupt(STOP_TIMEOUT);
    assert!(status.is_some_and(|s| s.success()), "the container did not stop cleanly:\n{}", front.log_text());
}

/// A telemetry frame with a NaN speed, which the pickup and perception nodes reject with a WARN.
const NAN_TELEMETRY: &str = "{frame: 1, speed_mps: .nan}";

#[test]
fn a_nodes_warning_reaches_rosout_and_the_log_arguments_choose_where_each_nodes_log_goes() {
    let Some(domain) = support::ros2_domain_or_skip() else { return };
    let _daemon = Daemon::start(&domain);
    let pickup_args = ["pickup", "--ros-args", "--log-level", "pickup:=WARN"];
    let mut pickup = start_process(&rover(), &pickup_args, &domain, "logs-pickup");
    let perception_args = ["perception", "--ros-args", "--disable-rosout-logs", "--disable-stdout-logs"];
    let mut perception = start_process(&rover(), &perception_args, &domain, "logs-perception");
    let listed = eventually(Duration::from_secs(30), || {
        let nodes = ros2(&domain, Duration::from_secs(20), &["node", "list"]).1;
        nodes.contains("/pickup") && nodes.contains("/perception")
    });
    assert!(listed, "the pickup and perception nodes are not listed");

    let echo = ["topic", "echo", "/rosout", "rcl_interfaces/msg/Log", "--filter", "m.level == 30"];
    let warnings = std::thread::scope(|scope| {
        let domain = &domain;
        let echoed = scope.spawn(|| ros2(domain, Duration::from_secs(15), &echo).1);
        std::thread::sleep(Duration::from_secs(3));
        let publish = ["topic", "pub", "-w", "2", "--times", "3", "/rover/telemetry", "rover_msgs/msg/Telemetry"];
        ros2_ok(domain, &[&publish[..], &[NAN_TELEMETRY]].concat());
        echoed.join().expect("the echo thread")
    });
    let rejected = "rejected a rover/telemetry message: field `speed_mps` = NaN";
    assert_contains(&warnings, &["level: 30", "name: pickup", rejected], "WARN on /rosout");
    assert!(!warnings.contains("name: perception"), "perception's /rosout logs are disabled:\n{warnings}");

    for process in [&mut pickup, &mut perception] {
        assert!(process.interrupt(STOP_TIMEOUT).is_some_and(|s| s.success()), "{} on SIGINT", process.name);
    }
    let pickup_log = pickup.log_text();
    assert!(pickup_log.contains(rejected) && !pickup_log.contains(" INFO node{"), "pickup at WARN:\n{pickup_log}");
    let perception_log = perception.log_text();
    assert!(!perception_log.contains("perception"), "perception's console logs are disabled:\n{perception_log}");
}
