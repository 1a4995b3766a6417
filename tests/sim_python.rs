//! The headless simulator against an independent Socket.IO 4.x server: python-socketio 4.6.1 with
//! python-engineio 3.13.2, the versions the Udacity starter code needs, with a handler that
//! decodes every field as the starter does and drives the rover in a closed loop.

mod support;

use std::process::{Command, Stdio};
use std::time::Duration;

use rover_sim::sim::{SimConfig, Simulator};
use rover_sim::wire::client::{ClientConfig, run_client};

#[tokio::test(flavor = "multi_thread")]
async fn python_socketio_4_drives_the_simulator_for_500_frames_with_one_telemetry_per_command() {
    let Some(python) = support::python_with(&["socketio", "engineio", "eventlet", "PIL", "numpy"]) else { return };
    let port = support::free_port();
    let stats_file = std::env::temp_dir().join(format!("rover-python-sim-{}.json", std::process::id()));
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/python/unity_dialect_server.py");
    let mut server = Command::new(python)
        .args(["-W", "ignore", script, "--port", &port.to_string(), "--frames", "500", "--out"])
        .arg(&stats_file)
        .stdout(Stdio::null())
        .spawn()
        .expect("start the python-socketio server");
    support::wait_for_port(port, Duration::from_secs(30));

    let mut simulator = Simulator::new(rover_sim::procgen::procedural_world(2), SimConfig::default());
    let config = ClientConfig::unity("127.0.0.1", port);
    let stopped = async {
        while !stats_file.exists() {
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    };
    let client = tokio::time::timeout(Duration::from_secs(120), run_client(&mut simulator, &config, stopped))
        .await
        .expect("the closed loop finished within 2 minutes");
    let status = server.wait().expect("the server exits");
    assert!(status.success(), "python server failed: {status}");

    let stats: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&stats_file).unwrap()).unwrap();
    let _ = std::fs::remove_file(&stats_file);
    eprintln!("client {client:?}\nserver {stats}");
    let number = |key: &str| stats[key].as_u64().unwrap_or_else(|| panic!("{key} in {stats}"));
    assert_eq!(number("connects"), 1, "the Socket.IO 4 server saw one connection without a 40 packet");
    assert!(stats["errors"].as_array().unwrap().is_empty(), "every telemetry decoded: {}", stats["errors"]);
    assert!(number("telemetry") >= 500);
    assert_eq!(number("decoded"), number("telemetry"));
    assert_eq!(number("empty"), 0);
    assert_eq!(client.commands_dropped, 0, "every command of python-socketio was understood");
    assert_eq!(client.connections, 1);
    assert_eq!(
        client.telemetry_sent,
        2 + client.commands_applied,
        "one telemetry on open, one on the 0{{...}} packet, then exactly one per command"
    );
    assert_eq!(client.telemetry_sent, number("telemetry"), "the server received every telemetry");
    assert!(stats["moved_m"].as_f64().unwrap() > 0.5, "the closed loop drove the rover: {}", stats["moved_m"]);
    assert_eq!(stats["first"]["sample_count"], 6);
    assert_eq!(stats["first"]["samples"].as_array().unwrap().len(), 6);
}
