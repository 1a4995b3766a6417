//! The repository as the ROS 2 package `rover`, as a ROS user meets it after a colcon build
//! (`tools/colcon-build`, which the README's test command runs before the tests): the real
//! `ros2 pkg`, `ros2 run`, `ros2 launch` (a short mission: up to the first sample collected) and
//! `ros2 interface` against the install in
//! `target/ros_ws/install`. Skips like `tests/ros2_cli.rs` without the ROS tools, and without the
//! install unless `ROVER_REQUIRE_ROS` is set.

mod support;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use support::launched::{Launcher, Watcher, command_line, launched_processes};
use support::ros2::{Daemon, assert_contains, ros2_ok};
use support::{Domain, eventually};

/// How long the launched graph may take to collect its first sample, wall clock.
const SHORT_MISSION_LIMIT: Duration = Duration::from_secs(120);

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// Where `tools/colcon-build` installs the package.
fn install_prefix() -> PathBuf {
    repo().join("target/ros_ws/install/rover")
}

/// A domain for the test, or `None` to skip it: without the `ros2` tools, or without the colcon
/// install when `ROVER_REQUIRE_ROS` is unset.
fn installed_or_skip() -> Option<Domain> {
    let domain = support::ros2_domain_or_skip()?;
    if install_prefix().join("lib/rover/rover").exists() {
        return Some(domain);
    }
    assert!(
        std::env::var_os("ROVER_REQUIRE_ROS").is_none(),
        "no colcon install at {}: run tools/colcon-build",
        install_prefix().display()
    );
    eprintln!("skipped: no colcon install at {} (tools/colcon-build makes it)", install_prefix().display());
    None
}

#[test]
fn ros2_pkg_lists_the_rover_executable_and_no_test_helper() {
    let Some(domain) = installed_or_skip() else { return };
    let executables = ros2_ok(&domain, &["pkg", "executables", "rover"]);
    assert_eq!(executables.lines().collect::<Vec<_>>(), ["rover rover"], "ros2 pkg executables rover");
    let prefix = ros2_ok(&domain, &["pkg", "prefix", "rover"]);
    assert_eq!(Path::new(prefix.trim()), install_prefix(), "ros2 pkg prefix rover");
}

#[test]
fn the_installed_share_holds_the_launch_files_parameters_and_viewer_configurations_as_in_the_repository() {
    let Some(_domain) = installed_or_skip() else { return };
    let share = install_prefix().join("share/rover");
    let shipped =
        ["launch_scripts/rover.launch.py", "launch_scripts/rover.launch.xml", "launch_scripts/rover_params.yaml"];
    for file in shipped.into_iter().chain(["config/rover.rviz", "config/rover.foxglove-layout.json", "package.xml"]) {
        let installed = std::fs::read(share.join(file)).unwrap_or_else(|e| panic!("share/rover/{file}: {e}"));
        let source = std::fs::read(repo().join(file)).expect("the repository's file");
        assert!(installed == source, "share/rover/{file} differs from the repository's: run tools/colcon-build");
    }
}

#[test]
fn ros2_interface_show_reads_rover_msgs_from_the_install() {
    let Some(domain) = installed_or_skip() else { return };
    let state = ros2_ok(&domain, &["interface", "show", "rover_msgs/msg/DecisionState"]);
    assert_contains(&state, &["string mode", "uint32 samples_collected"], "ros2 interface show DecisionState");
    let package = ros2_ok(&domain, &["interface", "package", "rover_msgs"]);
    assert_contains(
        &package,
        &["rover_msgs/msg/Telemetry", "rover_msgs/action/SampleReturn"],
        "ros2 interface package",
    );
}

/// `ros2 run rover rover NODE` in `namespace` on the test's domain, the bridge on the domain's port.
fn ros2_run(domain: &Domain, node: &str, namespace: &str) -> Command {
    let mut command = Command::new(support::ros2_cli());
    command.args(["run", "rover", "rover", node, "--ros-args", "-r", &format!("__ns:={namespace}")]);
    if node == "bridge" {
        command.args(["-p", &format!("port:={}", domain.port())]);
    }
    command.env("ROS_DOMAIN_ID", domain.id.to_string()).env("PYTHONUNBUFFERED", "1");
    command
}

#[test]
fn ros2_run_starts_each_node_and_ctrl_c_stops_it_cleanly() {
    let Some(domain) = installed_or_skip() else { return };
    let _daemon = Daemon::start(&domain);
    let nodes: Vec<&str> = rover::processes::nodes::node_names().collect();
    let mut runs: Vec<Launcher> = nodes
        .iter()
        .map(|node| {
            Launcher::start_in_own_group(&mut ros2_run(&domain, node, "/colcon_run"), &format!("ros2-run-{node}"))
        })
        .collect();
    let expected: Vec<String> = nodes.iter().map(|node| format!("/colcon_run/{node}")).collect();
    let mut listed = String::new();
    let all_up = eventually(Duration::from_secs(60), || {
        listed = support::ros2::ros2(&domain, Duration::from_secs(20), &["node", "list"]).1;
        expected.iter().all(|name| listed.lines().any(|line| line.trim() == name))
    });
    assert!(all_up, "ros2 node list after `ros2 run rover rover NODE` of each node:\n{listed}");
    for (node, run) in nodes.iter().zip(&mut runs) {
        let status = run.interrupt();
        assert_eq!(status.and_then(|s| s.code()), Some(0), "ros2 run rover rover {node} on Ctrl-C:\n{}", run.output());
    }
}

#[test]
fn ros2_launch_of_the_installed_launch_file_runs_a_short_mission_from_the_install() {
    let Some(domain) = installed_or_skip() else { return };
    let watcher = Watcher::start(&domain, "/installed");
    let mut command = Command::new(support::ros2_cli());
    command.args(["launch", "rover", "rover.launch.py", "sim:=true", "seed:=1", "namespace:=/installed"]);
    command.arg(format!("port:={}", domain.port()));
    command.env("ROS_DOMAIN_ID", domain.id.to_string()).env("PYTHONUNBUFFERED", "1");
    let mut launcher = Launcher::start(&mut command, "ros2-launch-installed");
    let collected = watcher.collects_a_sample(SHORT_MISSION_LIMIT);
    assert!(collected, "the installed graph collected no sample; ros2 launch output:\n{}", launcher.output());
    let installed = install_prefix().join("lib/rover/rover");
    let share = install_prefix().join("share/rover/launch_scripts/rover_params.yaml");
    for (name, pid) in launched_processes(&launcher.output()) {
        let command = command_line(pid);
        assert!(command.starts_with(&installed.display().to_string()), "{name} runs the installed rover: {command}");
        let params = name == "sim" || command.contains(&share.display().to_string());
        assert!(params, "{name} reads the installed parameter file: {command}");
    }
    assert!(launcher.interrupt().is_some_and(|s| s.code().is_some()), "ros2 launch did not exit on SIGINT");
}

#[test]
fn the_readme_colcon_section_is_the_commands_ci_runs() {
    let script = std::fs::read_to_string(repo().join("tools/colcon-build")).expect("tools/colcon-build");
    let readme = std::fs::read_to_string(repo().join("README.md")).expect("README.md");
    let section = readme.split("## In a colcon workspace").nth(1).expect("a README section `In a colcon workspace`");
    let commands = script.lines().skip_while(|line| !line.starts_with("set -euo pipefail")).skip(2);
    for command in commands.filter(|line| !line.starts_with("set ")).map(|line| line.replace(" \"$@\"", "")) {
        assert!(section.contains(&command), "the README's colcon section lacks `{command}` of tools/colcon-build");
    }
}
