//! The launchers of `launch_scripts/`: `rover-graph` (no ROS needed) and `rover.launch.py` (run by
//! the real `ros2 launch`, from the wheels of `../shared/ros2-python`), each starting the real graph
//! with the headless simulator, checked from a DDS subscriber in the test, and stopped with SIGINT,
//! after which none of their processes is left. Both start a killed node again; with `rover-graph`
//! the mapping node then carries on from its snapshot (under `ros2 launch` the test accepts a start
//! without one).

mod support;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use nix::sys::signal::Signal;
use rover::processes::graph::send_signal;
use rover::processes::nodes::Node;
use support::launched::{Launcher, Watcher, command_line, is_running, launched_processes};
use support::{Domain, eventually, rover};

/// How long a whole procedural mission of a launched graph may take, wall clock.
const MISSION_LIMIT: Duration = Duration::from_secs(240);

/// The processes a launcher with the simulator starts: every node, then the simulator.
fn processes() -> Vec<&'static str> {
    rover::processes::nodes::node_names().chain(["sim"]).collect()
}

fn launch_scripts() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("launch_scripts")
}

/// The `(name, pid, log)` lines `rover-graph: started NAME pid PID log LOG` of the output.
fn started_processes(output: &str) -> Vec<(String, u32, PathBuf)> {
    output
        .lines()
        .filter_map(|line| line.strip_prefix("rover-graph: started "))
        .map(|rest| {
            let fields: Vec<&str> = rest.split_whitespace().collect();
            assert_eq!((fields.len(), fields[1], fields[3]), (5, "pid", "log"), "unexpected line: {rest}");
            (fields[0].to_string(), fields[2].parse().expect("a pid"), PathBuf::from(fields[4]))
        })
        .collect()
}

/// `rover-graph` on the test's domain with the launcher options `options` (e.g. `--sim 4`).
fn rover_graph(domain: &Domain, namespace: &str, log_dir: &Path, options: &[&str]) -> Command {
    let mut command = Command::new(launch_scripts().join("rover-graph"));
    command.arg("--rover").arg(rover()).arg("--log-dir").arg(log_dir);
    command.args(["--domain", &domain.id.to_string(), "--port", &domain.port().to_string(), "--namespace", namespace]);
    command.args(options);
    command.args(["--", "-p", "bridge:diagnostics_period_ms:=250.0", "-p", "mapping:snapshot_every_ms:=200.0"]);
    command
}

/// `rover-graph` with the simulator on world seed `sim_seed` under `namespace`, its logs in a fresh folder
/// named after `name`, once the test's watcher sees its frames.
fn watched_graph(domain: &Domain, namespace: &str, name: &str, sim_seed: &str) -> (Watcher, PathBuf, Launcher) {
    let watcher = Watcher::start(domain, namespace);
    let log_dir = std::env::temp_dir().join(format!("{name}-test-{}", std::process::id()));
    let launcher = Launcher::start(&mut rover_graph(domain, namespace, &log_dir, &["--sim", sim_seed]), name);
    assert!(watcher.graph_runs(), "no frames on {namespace}/rover/telemetry; launcher output:\n{}", launcher.output());
    (watcher, log_dir, launcher)
}

/// The pid of the running process `name` of `started`, the last one started under that name.
fn pid_of(started: &[(String, u32, PathBuf)], name: &str) -> u32 {
    started.iter().rev().find(|(n, _, _)| n == name).unwrap_or_else(|| panic!("{name} was started")).1
}

#[test]
fn rover_graph_runs_the_graph_with_the_simulator_and_stops_every_process_on_sigint() {
    support::assert_isolated();
    let domain = Domain::reserve();
    let (_watcher, log_dir, mut launcher) = watched_graph(&domain, "/plain", "rover-graph", "4");

    let output = launcher.output();
    assert!(output.contains(&format!("logs in {}", log_dir.display())), "{output}");
    let started = started_processes(&output);
    let names: Vec<&str> = started.iter().map(|(name, _, _)| name.as_str()).collect();
    assert_eq!(names, processes(), "{output}");
    let params_file = launch_scripts().join("rover_params.yaml");
    for (name, pid, log) in &started {
        assert!(log.starts_with(&log_dir) && log.exists(), "{name}: log {}", log.display());
        let command = command_line(*pid);
        if name != "sim" {
            assert!(command.contains(&format!("--params-file {}", params_file.display())), "{name}: {command}");
            assert!(command.contains("-r __ns:=/plain -p bridge:diagnostics_period_ms:=250.0"), "{name}: {command}");
            assert!(command.ends_with(&format!("--enclave /rover/{name} ")), "{name}'s own enclave: {command}");
        }
        if name == "mapping" || name == "decision" {
            let state_dir = log_dir.join("state");
            assert!(command.contains(&format!("-p state_dir:={}", state_dir.display())), "{name}: {command}");
        }
    }

    let output = launcher.interrupt_cleanly();
    for (name, pid, _) in &started {
        assert!(
            output.contains(&format!("rover-graph: {name:<10} exited: 0")),
            "{name} did not exit cleanly:\n{output}"
        );
        assert!(!is_running(*pid), "{name} (pid {pid}) still runs");
    }
}

#[test]
fn rover_graph_starts_a_killed_node_again_and_mapping_carries_on_from_its_snapshot() {
    support::assert_isolated();
    let domain = Domain::reserve();
    let (watcher, log_dir, mut launcher) = watched_graph(&domain, "/respawn", "rover-graph-respawn", "2");
    let snapshot = log_dir.join("state").join("mapping.snapshot");
    assert!(eventually(Duration::from_secs(10), || snapshot.exists()), "no snapshot at {}", snapshot.display());
    let mapping = pid_of(&started_processes(&launcher.output()), "mapping");
    send_signal(mapping, Signal::SIGKILL);

    let restarted = eventually(Duration::from_secs(10), || {
        started_processes(&launcher.output()).iter().filter(|(name, _, _)| name == "mapping").count() == 2
    });
    let output = launcher.output();
    assert!(restarted, "mapping was not started again:\n{output}");
    assert!(output.contains("rover-graph: mapping exited with status -9; starting it again in 0.25 s"), "{output}");
    let mapping_log = log_dir.join("mapping.log");
    let restored = eventually(Duration::from_secs(10), || {
        std::fs::read_to_string(&mapping_log).is_ok_and(|log| log.contains("restored the map from"))
    });
    let log = std::fs::read_to_string(&mapping_log).unwrap_or_default();
    assert!(restored, "the new mapping node did not restore the snapshot:\n{log}");
    assert!(log.contains("---- mapping started again ----"), "the log goes on in the same file:\n{log}");
    let frames_before = watcher.telemetry.all().len();
    assert!(
        eventually(Duration::from_secs(10), || watcher.telemetry.all().len() > frames_before + 30),
        "frames flow after the restart"
    );

    let output = launcher.interrupt_cleanly();
    for (name, pid, _) in started_processes(&output).iter().filter(|(_, pid, _)| *pid != mapping) {
        assert!(!is_running(*pid), "{name} (pid {pid}) still runs");
    }
}

#[test]
fn rover_graph_without_autostart_has_the_manager_bring_the_graph_and_a_respawned_node_up() {
    support::assert_isolated();
    let domain = Domain::reserve();
    let watcher = Watcher::start(&domain, "/managed");
    let log_dir = std::env::temp_dir().join(format!("rover-graph-managed-test-{}", std::process::id()));
    let options = ["--sim", "5", "--no-autostart"];
    let mut launcher =
        Launcher::start(&mut rover_graph(&domain, "/managed", &log_dir, &options), "rover-graph-managed");
    assert!(watcher.graph_runs(), "the managed graph did not come up; launcher output:\n{}", launcher.output());
    let started = started_processes(&launcher.output());
    let names: Vec<&str> = started.iter().map(|(name, _, _)| name.as_str()).collect();
    let expected: Vec<&str> = rover::processes::nodes::node_names().chain(["lifecycle_manager", "sim"]).collect();
    assert_eq!(names, expected);
    assert!(command_line(pid_of(&started, "decision")).contains("-p autostart:=false"));

    send_signal(pid_of(&started, "decision"), Signal::SIGKILL);
    let manager_log = log_dir.join("lifecycle_manager.log");
    let brought_up_again = eventually(Duration::from_secs(30), || {
        let log = std::fs::read_to_string(&manager_log).unwrap_or_default();
        log.matches("/managed/decision: configured and active").count() == 2
    });
    let log = std::fs::read_to_string(&manager_log).unwrap_or_default();
    assert!(brought_up_again, "the respawned decision node was not brought up again:\n{log}");
    let commands_before = watcher.drive.all().len();
    assert!(
        eventually(Duration::from_secs(20), || watcher.drive.all().len() > commands_before + 30),
        "no drive commands after the decision node came back"
    );
    launcher.interrupt_cleanly();
}

#[test]
fn rover_graph_without_respawn_stops_every_node_when_one_exits() {
    support::assert_isolated();
    let domain = Domain::reserve();
    let log_dir = std::env::temp_dir().join(format!("rover-graph-crash-test-{}", std::process::id()));
    let mut launcher =
        Launcher::start(&mut rover_graph(&domain, "/crash", &log_dir, &["--no-respawn"]), "rover-graph-crash");
    assert!(eventually(Duration::from_secs(10), || started_processes(&launcher.output()).len() == Node::ALL.len()));
    let mapping = pid_of(&started_processes(&launcher.output()), "mapping");
    std::thread::sleep(Duration::from_secs(1));
    send_signal(mapping, Signal::SIGKILL);

    let exited = eventually(Duration::from_secs(30), || launcher.child.try_wait().ok().flatten().is_some());
    let output = launcher.output();
    assert!(exited, "rover-graph kept running after mapping died:\n{output}");
    assert_eq!(launcher.child.wait().ok().and_then(|s| s.code()), Some(1), "{output}");
    assert!(output.contains("rover-graph: mapping exited with status -9; stopping the others"), "{output}");
    for (name, pid, _) in started_processes(&output).iter().filter(|(name, _, _)| name != "mapping") {
        assert!(output.contains(&format!("rover-graph: {name:<10} exited: 0")), "{name}:\n{output}");
        assert!(!is_running(*pid), "{name} (pid {pid}) still runs");
    }
}

#[test]
fn rover_nodes_with_groups_prints_one_process_a_line() {
    let output = Command::new(rover()).args(["nodes", "--group", "pickup,bridge", "--group=perception"]).output();
    let output = output.expect("run rover nodes");
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let printed = String::from_utf8_lossy(&output.stdout);
    assert_eq!(printed.lines().collect::<Vec<_>>(), ["bridge pickup", "perception", "mapping", "decision"]);
}

#[test]
fn rover_nodes_prints_every_node_in_start_order_for_the_launchers() {
    let output = Command::new(rover()).arg("nodes").output().expect("run rover nodes");
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let printed = String::from_utf8_lossy(&output.stdout);
    assert_eq!(printed.lines().collect::<Vec<_>>(), rover::processes::nodes::node_names().collect::<Vec<_>>());
}

#[test]
fn rover_graph_help_names_its_options() {
    let output = Command::new(launch_scripts().join("rover-graph")).arg("--help").output().expect("run rover-graph");
    let help = String::from_utf8_lossy(&output.stdout);
    assert!(output.status.success(), "{help}");
    for option in [
        "--rover",
        "--params-file",
        "--namespace",
        "--domain",
        "--port",
        "--sim SEED",
        "--log-dir",
        "--no-respawn",
        "--no-autostart",
        "-- ROS_ARG",
    ] {
        assert!(help.contains(option), "--help does not mention {option}:\n{help}");
    }
}

#[test]
fn the_launch_file_is_valid_python() {
    let file = launch_scripts().join("rover.launch.py");
    let output = Command::new("python3")
        .args(["-c", "import ast, sys; ast.parse(open(sys.argv[1]).read(), sys.argv[1])"])
        .arg(&file)
        .output()
        .expect("run python3");
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
}

/// The real `ros2 launch` of the launch file on the test's domain under `namespace`, with the
/// simulator on world `seed` and the launch arguments `extra`.
fn ros2_launch(domain: &Domain, namespace: &str, seed: &str, extra: &[&str]) -> Command {
    ros2_launch_of("rover.launch.py", domain, namespace, seed, extra)
}

/// [`ros2_launch`] of the launch file `file` of `launch_scripts/`.
fn ros2_launch_of(file: &str, domain: &Domain, namespace: &str, seed: &str, extra: &[&str]) -> Command {
    let mut command = Command::new(support::ros2_cli());
    command.arg("launch").arg(launch_scripts().join(file));
    command.arg(format!("rover:={}", rover().display()));
    command.args([format!("namespace:={namespace}"), "sim:=true".into(), format!("seed:={seed}")]);
    command.arg(format!("port:={}", domain.port())).args(extra);
    command.env("ROS_DOMAIN_ID", domain.id.to_string()).env("PYTHONUNBUFFERED", "1");
    command
}

#[test]
fn ros2_launch_of_the_launch_file_starts_the_graph_with_the_simulator_and_sigint_leaves_no_process_behind() {
    let Some(domain) = support::ros2_domain_or_skip() else { return };
    let watcher = Watcher::start(&domain, "/launched");
    let teleop = ["cmd_vel:=/teleop/cmd_vel"];
    let mut launcher = Launcher::start(&mut ros2_launch(&domain, "/launched", "6", &teleop), "ros2-launch");
    assert!(watcher.graph_runs(), "no frames on /launched/rover/telemetry; ros2 launch output:\n{}", launcher.output());
    let launched = launched_processes(&launcher.output());
    let names: Vec<&str> = launched.iter().map(|(name, _)| name.as_str()).collect();
    assert_eq!(names, processes(), "{}", launcher.output());
    assert_launched_by_launch_ros(&launched, "/launched");
    let bridge = command_line(launched[0].1);
    assert!(bridge.contains("-r cmd_vel:=/teleop/cmd_vel"), "the bridge's cmd_vel remapped: {bridge}");
    let mapping = launched.iter().find(|(name, _)| name == "mapping").expect("mapping was launched").1;
    send_signal(mapping, Signal::SIGKILL);
    let respawned =
        eventually(Duration::from_secs(15), || launched_processes(&launcher.output()).len() == launched.len() + 1);
    assert!(respawned, "ros2 launch did not start the killed mapping node again:\n{}", launcher.output());
    let launched = launched_processes(&launcher.output());
    assert_eq!(launched.last().map(|(name, _)| name.as_str()), Some("mapping"), "{}", launcher.output());
    // The new mapping node is up once it is active again, its memory read (restored or not).
    let activated = |line: &str| line.starts_with("[mapping-") && line.contains(support::ACTIVATED_LOG_LINE);
    let up = eventually(Duration::from_secs(15), || launcher.output().lines().filter(|l| activated(l)).count() >= 2);
    assert!(up, "the new mapping node did not start:\n{}", launcher.output());

    let interrupted = std::time::Instant::now();
    let status = launcher.interrupt();
    let output = launcher.output();
    let running: Vec<&str> =
        launched.iter().filter(|(_, pid)| is_running(*pid)).map(|(name, _)| name.as_str()).collect();
    assert!(
        status.is_some_and(|s| s.code().is_some()),
        "ros2 launch did not exit by itself on SIGINT ({status:?}, None: still running after 30 s; \
         its processes still running: {running:?}):\n{output}"
    );
    eprintln!(
        "ros2 launch: {} processes, stopped {:.1} s after SIGINT",
        launched.len(),
        interrupted.elapsed().as_secs_f64()
    );
    for (name, pid) in launched.iter().filter(|(_, pid)| *pid != mapping) {
        let finished = format!("[{name}-");
        let clean =
            output.lines().any(|line| line.contains(&finished) && line.contains("process has finished cleanly"));
        assert!(clean, "{name} did not finish cleanly:\n{output}");
        assert!(!is_running(*pid), "{name} (pid {pid}) still runs after ros2 launch exited");
    }
}

#[test]
fn ros2_launch_with_autostart_false_runs_the_lifecycle_manager_that_brings_the_graph_up() {
    let Some(domain) = support::ros2_domain_or_skip() else { return };
    let watcher = Watcher::start(&domain, "/managed_launch");
    let mut command = ros2_launch(&domain, "/managed_launch", "7", &["autostart:=false"]);
    let mut launcher = Launcher::start(&mut command, "ros2-launch-managed");
    assert!(watcher.graph_runs(), "the managed graph did not come up; ros2 launch output:\n{}", launcher.output());
    let output = launcher.output();
    let names: Vec<String> = launched_processes(&output).into_iter().map(|(name, _)| name).collect();
    let expected: Vec<&str> = rover::processes::nodes::node_names().chain(["lifecycle_manager", "sim"]).collect();
    assert_eq!(names, expected, "{output}");
    for node in rover::processes::nodes::node_names() {
        let up = format!("/managed_launch/{node}: configured and active");
        assert!(output.contains(&up), "no `{up}` in\n{output}");
    }
    assert!(launcher.interrupt().is_some_and(|s| s.code().is_some()), "ros2 launch did not exit on SIGINT");
}

#[test]
fn rover_graph_runs_each_group_of_nodes_in_one_container_process() {
    support::assert_isolated();
    let domain = Domain::reserve();
    let watcher = Watcher::start(&domain, "/grouped");
    let log_dir = std::env::temp_dir().join(format!("rover-graph-groups-test-{}", std::process::id()));
    let options = ["--sim", "5", "--group", "pickup,decision,mapping", "--group", "bridge,perception"];
    let mut launcher = Launcher::start(&mut rover_graph(&domain, "/grouped", &log_dir, &options), "rover-graph-groups");
    assert!(watcher.graph_runs(), "no frames from the grouped graph:\n{}", launcher.output());
    let started = started_processes(&launcher.output());
    let names: Vec<&str> = started.iter().map(|(name, _, _)| name.as_str()).collect();
    assert_eq!(names, ["bridge+perception", "mapping+decision+pickup", "sim"], "{}", launcher.output());
    let front = command_line(pid_of(&started, "bridge+perception"));
    assert!(front.contains("container bridge perception --ros-args") && front.contains("-p bridge:port:="), "{front}");
    let back = command_line(pid_of(&started, "mapping+decision+pickup"));
    let state_dir = log_dir.join("state");
    for node in ["mapping", "decision"] {
        assert!(back.contains(&format!("-p {node}:state_dir:={}", state_dir.display())), "{back}");
    }
    launcher.interrupt_cleanly();
}

/// Every node of `launched` (all but the simulator) was started by launch_ros: named, namespaced
/// into `namespace`, given its DDS Security enclave and a parameter file.
fn assert_launched_by_launch_ros(launched: &[(String, u32)], namespace: &str) {
    for (name, pid) in launched.iter().filter(|(name, _)| name != "sim") {
        let command = command_line(*pid);
        let parts = [
            format!("rover {name} --ros-args"),
            format!("-r __node:={name}"),
            format!("-r __ns:={namespace}"),
            format!("--enclave /rover/{name}"),
        ];
        assert!(parts.iter().all(|part| command.contains(part.as_str())), "{name} as a launch_ros node: {command}");
        assert!(command.contains("--params-file"), "{name}: {command}");
    }
}

#[test]
fn ros2_launch_of_the_xml_launch_file_runs_the_same_graph_through_a_whole_mission() {
    let Some(domain) = support::ros2_domain_or_skip() else { return };
    let watcher = Watcher::start(&domain, "/xml");
    let rover_arg = format!("rover:={}", rover().display());
    let mut command =
        ros2_launch_of("rover.launch.xml", &domain, "/xml", "3", &[&rover_arg, "cmd_vel:=/teleop/cmd_vel"]);
    let mut launcher = Launcher::start(&mut command, "ros2-launch-xml");
    let end = watcher.mission_completes(MISSION_LIMIT);
    let end =
        end.unwrap_or_else(|e| panic!("the XML-launched mission: {e}; ros2 launch output:\n{}", launcher.output()));
    eprintln!("rover.launch.xml, seed 3: {end:?}");
    let launched = launched_processes(&launcher.output());
    let names: Vec<&str> = launched.iter().map(|(name, _)| name.as_str()).collect();
    assert_eq!(names, processes(), "the XML file's nodes are `rover nodes`:\n{}", launcher.output());
    assert_launched_by_launch_ros(&launched, "/xml");
    let bridge = command_line(launched[0].1);
    assert!(bridge.contains("-r cmd_vel:=/teleop/cmd_vel"), "the bridge's cmd_vel remapped: {bridge}");
    interrupt_and_assert_none_left(&mut launcher, &launched);
}

#[test]
fn ros2_launch_with_groups_runs_bridge_and_perception_in_one_process_the_rest_in_another_through_a_mission() {
    let Some(domain) = support::ros2_domain_or_skip() else { return };
    let watcher = Watcher::start(&domain, "/two_processes");
    let groups = "groups:=bridge,perception mapping,decision,pickup";
    let mut command = ros2_launch(&domain, "/two_processes", "4", &[groups, "cmd_vel:=/teleop/cmd_vel"]);
    let mut launcher = Launcher::start(&mut command, "ros2-launch-groups");
    let end = watcher.mission_completes(MISSION_LIMIT);
    let end =
        end.unwrap_or_else(|e| panic!("the two-process mission: {e}; ros2 launch output:\n{}", launcher.output()));
    eprintln!("rover.launch.py groups, seed 4: {end:?}");
    // The latched sample markers, decoded by rclpy in the ros2 command line: one sphere per sample
    // in the last message. RustDDS 0.15.1 hands a late joiner every sample its writer kept while
    // no reader acknowledged them, not only the last, so the echo runs a while and the last counts.
    let topic = "/two_processes/rover/sample_markers";
    let echo = ["topic", "echo", topic, "visualization_msgs/msg/MarkerArray"];
    let markers = support::ros2::ros2(&domain, Duration::from_secs(8), &echo).1;
    let last = markers.rsplit("\n---").find(|message| message.contains("markers:")).unwrap_or_default();
    let spheres = last.matches("ns: collected").count();
    assert_eq!(spheres, end.samples_collected as usize, "collected samples as markers, last message:\n{last}");
    let launched = launched_processes(&launcher.output());
    let names: Vec<&str> = launched.iter().map(|(name, _)| name.as_str()).collect();
    assert_eq!(names, ["bridge+perception", "mapping+decision+pickup", "sim"], "{}", launcher.output());
    let front = command_line(launched[0].1);
    assert!(front.contains("-r bridge:cmd_vel:=/teleop/cmd_vel"), "the bridge's cmd_vel remapped: {front}");
    let back = command_line(launched[1].1);
    let aimed =
        ["container mapping decision pickup --ros-args", "-p mapping:state_dir:=", "-p decision:use_sim_time:=false"];
    assert!(aimed.iter().all(|part| back.contains(part)) && back.contains("-r __ns:=/two_processes"), "{back}");
    assert!(!back.contains("__node:="), "a container keeps its nodes' own names: {back}");
    interrupt_and_assert_none_left(&mut launcher, &launched);
}

/// Sends SIGINT to `ros2 launch` and checks that it exits and none of the processes it
/// `launched` is left running.
fn interrupt_and_assert_none_left(launcher: &mut Launcher, launched: &[(String, u32)]) {
    assert!(launcher.interrupt().is_some_and(|s| s.code().is_some()), "ros2 launch did not exit on SIGINT");
    for (name, pid) in launched {
        assert!(!is_running(*pid), "{name} (pid {pid}) still runs after ros2 launch exited");
    }
}

#[test]
fn ros2_launch_refuses_a_group_naming_no_node() {
    let Some(domain) = support::ros2_domain_or_skip() else { return };
    let output =
        ros2_launch(&domain, "/bad_group", "0", &["groups:=bridge,perceptoin"]).output().expect("run ros2 launch");
    let text = format!("{}{}", String::from_utf8_lossy(&output.stdout), String::from_utf8_lossy(&output.stderr));
    assert!(!output.status.success(), "{text}");
    assert!(text.contains("no node 'perceptoin'; expected one of bridge, perception"), "{text}");
}
