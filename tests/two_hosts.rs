//! `tools/two-hosts`: the graph split over two network namespaces joined by an impaired link. The
//! drive commands cross the link, so the bridge's reply latency cannot be under the two one-way
//! delays; a cut link brakes the rover; the namespaces and the link are gone afterwards, also
//! after Ctrl-C.

mod support;

use std::path::PathBuf;
use std::process::{Child, Command, Output, Stdio};
use std::time::Duration;

use nix::sys::signal::Signal;
use rover::processes::graph::send_signal;

const ONE_WAY_DELAY_MS: f64 = 10.0;

/// `tools/two-hosts` with `args`, SIGINT at its default as under a terminal (a shell started with
/// SIGINT ignored cannot trap it; see [`support::with_default_sigint`]).
fn two_hosts(args: &[&str]) -> Command {
    let mut command = Command::new(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tools/two-hosts"));
    support::with_default_sigint(&mut command)
        .args(args)
        .env("ROVER", support::rover())
        .env("LINK_EMULATOR", support::link_emulator())
        .stdin(Stdio::null());
    command
}

/// The namespaces a run named on stderr (`two-hosts: rover-PID <-> base-PID ...`).
fn namespaces_of(stderr: &str) -> [String; 2] {
    let line = stderr.lines().find(|l| l.starts_with("two-hosts: rover-")).unwrap_or_else(|| panic!("{stderr}"));
    let words: Vec<&str> = line.split_whitespace().collect();
    [words[1].to_string(), words[3].trim_end_matches(',').to_string()]
}

fn existing_namespaces() -> String {
    let output = Command::new("ip").args(["netns", "list"]).output().expect("ip netns list");
    String::from_utf8_lossy(&output.stdout).into_owned()
}

fn assert_cleaned_up(stderr: &str) {
    let existing = existing_namespaces();
    for namespace in namespaces_of(stderr) {
        assert!(!existing.contains(&namespace), "{namespace} left behind: {existing}");
    }
}

/// Runs procedural world 0 for `sim_seconds` over a link with `link` options; returns the eval's
/// JSON row and what the run printed on stderr.
fn run_over(link: &[&str], sim_seconds: &str) -> (serde_json::Value, String) {
    let world = ["--procedural", "--seeds", "0", "--max-sim-seconds", sim_seconds, "--json"];
    let Output { status, stdout, stderr } =
        two_hosts(&[link, &world[..]].concat()).output().expect("run tools/two-hosts");
    let stderr = String::from_utf8_lossy(&stderr).into_owned();
    assert!(status.success(), "{stderr}");
    let runs: serde_json::Value = serde_json::from_slice(&stdout).expect("the eval's JSON");
    (runs[0].clone(), stderr)
}

#[test]
fn a_mission_runs_across_a_delayed_lossy_link_and_leaves_nothing_behind() {
    let (run, stderr) = run_over(&["--delay-ms", "10", "--jitter-ms", "2", "--loss-pct", "1"], "15");
    let number = |key: &str| run[key].as_f64().unwrap_or_else(|| panic!("{key} in {run}"));
    assert!(number("sim_seconds") >= 14.9, "{run}");
    assert!(number("distance_m") > 1.0, "drive commands came back across the link: {run}");
    assert!(number("mapped_pct") > 0.0, "the mapping node across the link got scans: {run}");
    assert!(
        number("reply_p50_ms") >= 2.0 * (ONE_WAY_DELAY_MS - 2.0),
        "telemetry out and the command back cross the link, 8-12 ms each way: {run}"
    );
    assert!(run["deadline_misses"].is_u64() && run["silence_brakes"].is_u64(), "{run}");
    assert!(stderr.contains("packets") && stderr.contains("lost"), "the link's counts: {stderr}");
    assert_cleaned_up(&stderr);
}

#[test]
fn a_cut_link_brakes_the_rover_once_the_silence_limit_has_passed() {
    let (run, stderr) = run_over(&["--delay-ms", "5", "--cut-after-packets", "6000"], "15");
    let count = |key: &str| run[key].as_u64().unwrap_or_else(|| panic!("{key} in {run}"));
    assert!(run["distance_m"].as_f64().is_some_and(|d| d > 1.0), "it drove before the cut: {run}");
    assert!(count("silence_brakes") > 25, "more than a second of braked frames after the cut: {run}");
    assert!(count("deadline_misses") >= count("silence_brakes"), "{run}");
    assert_cleaned_up(&stderr);
}

#[test]
fn a_secured_graph_runs_across_the_link_with_the_keystore() {
    let keystore = support::keystore("two-hosts");
    let args = [
        "--procedural",
        "--seeds",
        "0",
        "--max-sim-seconds",
        "15",
        "--json",
        "--ros-args",
        "--enclave",
        "/rover/tools",
    ];
    let mut command = two_hosts(&args);
    let Output { status, stdout, stderr } =
        command.envs(support::security_env(&keystore)).output().expect("run tools/two-hosts");
    let stderr = String::from_utf8_lossy(&stderr).into_owned();
    assert!(status.success(), "{stderr}");
    let runs: serde_json::Value = serde_json::from_slice(&stdout).expect("the eval's JSON");
    let number = |key: &str| runs[0][key].as_f64().unwrap_or_else(|| panic!("{key} in {runs}"));
    assert!(number("distance_m") > 1.0, "secured drive commands came back across the link: {runs}");
    assert!(number("mapped_pct") > 0.0, "the secured mapping node across the link got scans: {runs}");
    assert!(stderr.contains("DDS Security on: enclave"), "the evaluator was secured: {stderr}");
    assert_cleaned_up(&stderr);
}

fn wait_for_line(child: &mut Child, log: &std::path::Path, needle: &str) -> String {
    let found = support::eventually(Duration::from_secs(60), || {
        std::fs::read_to_string(log).is_ok_and(|text| text.contains(needle))
    });
    let text = std::fs::read_to_string(log).unwrap_or_default();
    if !found {
        let _ = child.kill();
        panic!("no {needle:?} within 60 s:\n{text}");
    }
    text
}

#[test]
fn ctrl_c_stops_the_run_and_removes_the_namespaces() {
    let log = std::env::temp_dir().join(format!("two-hosts-sigint-{}.log", std::process::id()));
    let mut child = two_hosts(&["--delay-ms", "1", "--procedural", "--seeds", "0"])
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&log).expect("log file"))
        .spawn()
        .expect("start tools/two-hosts");
    wait_for_line(&mut child, &log, "connected to");
    send_signal(child.id(), Signal::SIGINT);
    let stopped = support::eventually(Duration::from_secs(20), || child.try_wait().ok().flatten().is_some());
    if !stopped {
        let _ = child.kill();
    }
    let stderr = std::fs::read_to_string(&log).unwrap_or_default();
    assert!(stopped, "tools/two-hosts ignored SIGINT for 20 s:\n{stderr}");
    assert_cleaned_up(&stderr);
    assert!(stderr.contains("stopping the mission"), "the eval stopped its graph: {stderr}");
    let _ = std::fs::remove_file(&log);
}
