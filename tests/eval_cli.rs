//! The `rover eval` command line: option conflicts are refused with a message, an in-process run
//! stops on Ctrl-C (it runs on the main runtime's thread, so nothing else would stop it), and the
//! second mission of a graph eval is timed from its own start.

mod support;

use std::process::Command;
use std::time::{Duration, Instant};

#[test]
fn an_in_process_eval_stops_on_sigint_naming_the_seed() {
    let mut command = Command::new(support::rover());
    command.args(["eval", "--in-process", "--procedural", "--seeds", "3"]);
    let log = std::env::temp_dir().join(format!("rover-test-eval-sigint-{}.log", std::process::id()));
    let mut eval = support::Process::spawn("eval", command, log).expect("start rover eval");
    let under_way = support::eventually(Duration::from_secs(60), || eval.log_text().contains("seed 3:"));
    assert!(under_way, "no progress line of the mission within 60 s:\n{}", eval.log_text());
    let interrupted = Instant::now();
    let status = eval.interrupt(Duration::from_secs(10));
    let stderr = eval.log_text();
    assert!(status.is_some(), "rover eval --in-process ignored SIGINT for 10 s:\n{stderr}");
    eprintln!("stopped {:.2} s after SIGINT", interrupted.elapsed().as_secs_f64());
    assert!(!status.is_some_and(|s| s.success()), "an interrupted run is no success");
    assert!(stderr.contains("seed 3: interrupted at"), "{stderr}");
}

#[test]
fn chaos_needs_the_graph() {
    let output = Command::new(support::rover())
        .args(["eval", "--in-process", "--chaos", "--seeds", "0"])
        .output()
        .expect("run rover eval");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success(), "--chaos with --in-process is refused");
    assert!(stderr.contains("--chaos") && stderr.contains("--in-process"), "{stderr}");
}

#[test]
fn each_graph_mission_is_timed_from_its_own_start() {
    support::assert_isolated();
    let output = Command::new(support::rover())
        .args(["eval", "--procedural", "--seeds", "0..1", "--max-sim-seconds", "110", "--json"])
        .output()
        .expect("run rover eval");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    let runs: Vec<serde_json::Value> = serde_json::from_slice(&output.stdout).expect("a JSON list of runs");
    assert_eq!(runs.len(), 2, "{stderr}");
    for run in &runs {
        let sim_s = run["sim_seconds"].as_f64().expect("sim_seconds");
        let collected_at_s = run["collected_at_s"].as_array().expect("collected_at_s");
        assert!(collected_at_s.iter().all(|t| t.as_f64().is_some_and(|t| t <= sim_s)), "{run}");
        let mapped = run["mapped_pct_by_100_s"].as_array().expect("mapped_pct_by_100_s");
        assert_eq!(mapped.len(), 1, "one entry, at 100 s of a 110 s mission: {run}");
        assert!(mapped[0].as_f64().is_some_and(|pct| pct > 0.0), "the map at 100 s: {run}");
    }
}
