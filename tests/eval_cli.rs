//! The `rover eval` command line: option conflicts are refused with a message, and an in-process
//! run stops on Ctrl-C (it runs on the main runtime's thread, so nothing else would stop it).

mod support;

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use nix::sys::signal::Signal;
use rover::graph::send_signal;

#[test]
fn an_in_process_eval_stops_on_sigint_naming_the_seed() {
    let mut eval = Command::new(support::rover())
        .args(["eval", "--in-process", "--procedural", "--seeds", "3"])
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start rover eval");
    std::thread::sleep(Duration::from_secs(3));
    assert!(eval.try_wait().expect("poll").is_none(), "the mission is still running after 3 s");
    let interrupted = Instant::now();
    send_signal(eval.id(), Signal::SIGINT);
    let stopped = support::eventually(Duration::from_secs(10), || eval.try_wait().ok().flatten().is_some());
    if !stopped {
        let _ = eval.kill();
    }
    let output = eval.wait_with_output().expect("rover eval's output");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stopped, "rover eval --in-process ignored SIGINT for 10 s:\n{stderr}");
    eprintln!("stopped {:.2} s after SIGINT", interrupted.elapsed().as_secs_f64());
    assert!(!output.status.success(), "an interrupted run is no success");
    assert!(stderr.contains("seed 3") && stderr.contains("interrupted at"), "{stderr}");
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
