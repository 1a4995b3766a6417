//! The headless simulator against the real bridge: it reconnects when the bridge goes away and
//! comes back, as the Unity client does, and the run then goes on; at its end the simulator closes
//! the connection as Unity does on quit, and the bridge sees a clean close.

mod support;

use std::sync::{Arc, Mutex};
use std::time::Duration;

use rover_sim::sim::{SimConfig, Simulator};
use rover_sim::wire::client::{ClientConfig, run_client};
use support::{Domain, echo_node, eventually, start_bridge, start_process};

#[tokio::test(flavor = "multi_thread")]
async fn the_simulator_reconnects_after_the_bridge_restarts() {
    support::assert_isolated();
    let domain = Arc::new(Domain::reserve());
    let _echo = start_process(&echo_node(), &[], &domain, "echo");
    let bridge = Arc::new(Mutex::new(Some(start_bridge(&domain, &[]))));
    let config = SimConfig { max_sim_seconds: Some(40.0), ..SimConfig::default() };
    let mut simulator = Simulator::new(rover_sim::procgen::procedural_world(4), config);
    let restarter = {
        let (bridge, domain) = (bridge.clone(), domain.clone());
        tokio::task::spawn_blocking(move || {
            std::thread::sleep(Duration::from_millis(800));
            if let Some(mut old) = bridge.lock().unwrap().take() {
                old.kill();
            }
            std::thread::sleep(Duration::from_millis(500));
            *bridge.lock().unwrap() = Some(start_bridge(&domain, &[]));
        })
    };
    let client = ClientConfig::unity("127.0.0.1", domain.port());
    let stats =
        tokio::time::timeout(Duration::from_secs(120), run_client(&mut simulator, &client, std::future::pending()))
            .await
            .expect("the run finished");
    restarter.await.unwrap();
    assert!(stats.connections >= 2, "reconnected: {stats:?}");
    assert!((simulator.report().sim_seconds - 40.0).abs() < 1e-6, "the run went on to its end");
    assert_eq!(stats.commands_dropped, 0);
    let bridge = bridge.lock().unwrap().take().expect("the restarted bridge");
    let closed = eventually(Duration::from_secs(5), || bridge.log_text().contains("simulator disconnected (closed)"));
    let log = bridge.log_text();
    assert!(closed, "the bridge saw a clean close: {log}");
    assert!(!log.contains("cannot send the reply"), "no reply failed: {log}");
}
