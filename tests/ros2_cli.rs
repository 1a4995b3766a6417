//! The official `ros2` command line against the graph (issue 17): in one loopback-only namespace,
//! `ros2 daemon start` first, then the graph in separate processes with the headless simulator
//! (`launch_scripts/rover-graph --sim 0`), then `ros2 node list`, `topic list -t`, `topic echo
//! --once` (telemetry, the latched map and static transforms, odom, `/clock`), `topic hz`, `topic info -v`,
//! `param list/get/set` and `interface show`, each checked on its output. The graph runs with
//! `use_sim_time:=true`, so its stamps must be the simulated time of `/clock`, not the wall clock. The CLI comes from the wheels of
//! `../shared/ros2-python` that `tools/setup-ros` installs into `.venv`.

mod support;

use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use support::{Domain, STOP_TIMEOUT, eventually, ros2_cli, rover, start_process};

/// Every topic of the graph but `/clock` (checked on its own) with its type, as
/// `ros2 topic list -t` prints it.
const TOPICS: [&str; 20] = [
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
    "/rover/drive_cmd [rover_msgs/msg/DriveCommand]",
    "/rover/pickup [rover_msgs/msg/PickupRequest]",
    "/rover/mode [rover_msgs/msg/DecisionState]",
    "/rover/plan [nav_msgs/msg/Path]",
    "/cmd_vel [geometry_msgs/msg/Twist]",
    "/diagnostics [diagnostic_msgs/msg/DiagnosticArray]",
];

/// The output (stdout and stderr) of a `ros2` command on `domain`, stopped with SIGINT after
/// `limit`, and whether it exited with status 0.
fn ros2(domain: &Domain, limit: Duration, args: &[&str]) -> (bool, String) {
    let output = Command::new("timeout")
        .args(["--signal=INT", "--kill-after=5", &format!("{}", limit.as_secs_f64())])
        .arg(ros2_cli())
        .args(args)
        .env("ROS_DOMAIN_ID", domain.id.to_string())
        .env("PYTHONUNBUFFERED", "1")
        .output()
        .expect("run ros2");
    let text = format!("{}{}", String::from_utf8_lossy(&output.stdout), String::from_utf8_lossy(&output.stderr));
    (output.status.success(), text)
}

/// A `ros2` command that must succeed within 30 s; its output.
fn ros2_ok(domain: &Domain, args: &[&str]) -> String {
    let (ok, output) = ros2(domain, Duration::from_secs(30), args);
    assert!(ok, "`ros2 {}` failed:\n{output}", args.join(" "));
    output
}

/// Stamps below this many seconds are simulated time; the wall clock is past 1.7e9 s.
const SIM_TIME_LIMIT_S: i64 = 1_000_000;

/// The first `sec:` value of a `ros2 topic echo` output.
fn first_sec(output: &str) -> Option<i64> {
    output.lines().find_map(|line| line.trim().strip_prefix("sec: ")).and_then(|sec| sec.trim().parse().ok())
}

fn assert_sim_time(output: &str, what: &str) {
    let sec = first_sec(output);
    assert!(sec.is_some_and(|sec| sec < SIM_TIME_LIMIT_S), "{what}: not stamped in simulated time:\n{output}");
}

fn assert_contains(output: &str, expected: &[&str], what: &str) {
    for line in expected {
        assert!(output.contains(line), "{what}: no `{line}` in\n{output}");
    }
}

/// The `ros2` daemon of a domain, stopped when dropped.
struct Daemon<'a> {
    domain: &'a Domain,
}

impl<'a> Daemon<'a> {
    fn start(domain: &'a Domain) -> Daemon<'a> {
        ros2_ok(domain, &["daemon", "start"]);
        let daemon = Daemon { domain };
        assert_contains(&ros2_ok(domain, &["daemon", "status"]), &["The daemon is running"], "ros2 daemon status");
        daemon
    }
}

impl Drop for Daemon<'_> {
    fn drop(&mut self) {
        let _ = ros2(self.domain, Duration::from_secs(15), &["daemon", "stop"]);
    }
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
        // Without the type named: only rosgraph_msgs/msg/Clock may be on /clock.
        let clock = scope.spawn(|| ros2_ok(domain, &["topic", "echo", "--once", "/clock"]));
        let sim_time = scope.spawn(|| ros2_ok(domain, &["param", "get", "/mapping", "use_sim_time"]));
        let hz = scope.spawn(|| ros2(domain, Duration::from_secs(20), &["topic", "hz", "/rover/telemetry"]).1);
        let info = scope.spawn(|| ros2_ok(domain, &["topic", "info", "-v", "/map"]));
        let interface = scope.spawn(|| ros2_ok(domain, &["interface", "show", "rover_msgs/msg/Telemetry"]));
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
