//! Telemetry-in to reply-out latency of the bridge, 5,000 frames, with a minimal echo node in
//! another process answering over DDS (the full lock-step path), against a baseline measured in
//! the same run: the same bridge with a zero reply deadline and no node, i.e. the websocket,
//! parsing and publishing without the DDS round trip.
//!
//! Run inside the loopback-only namespace: `tools/isolated cargo bench --bench bridge_latency`.

#[path = "../tests/support/mod.rs"]
mod support;

use std::time::Duration;

use support::echo_sim::{EchoCheckingSimulator, run_fake_unity};
use support::{Domain, Percentiles, echo_node, percentiles, rover, start_process, wait_for_port};

const FRAMES: usize = 5000;
const WARM_UP_FRAMES: usize = 300;

async fn measure(domain: &Domain, bridge_params: &[&str], with_echo: bool) -> (Percentiles, usize) {
    let port = format!("port:={}", domain.port());
    let mut args = vec!["bridge", "--ros-args", "-p", port.as_str()];
    for param in bridge_params {
        args.extend(["-p", param]);
    }
    let _bridge = start_process(&rover(), &args, domain, "bench-bridge");
    wait_for_port(domain.port(), Duration::from_secs(20));
    let _echo = with_echo.then(|| start_process(&echo_node(), &[], domain, "bench-echo"));
    let mut simulation = EchoCheckingSimulator::new(WARM_UP_FRAMES + FRAMES);
    run_fake_unity(&mut simulation, domain.port()).await;
    let measured: Vec<Duration> = simulation.replies[WARM_UP_FRAMES..].iter().map(|r| r.latency).collect();
    let fresh = simulation.replies[WARM_UP_FRAMES..].iter().filter(|r| r.throttle > 0.0).count();
    (percentiles(&measured), fresh)
}

fn main() {
    support::assert_isolated();
    let runtime = tokio::runtime::Runtime::new().expect("tokio runtime");
    let domain = Domain::reserve();
    println!("bridge latency, {FRAMES} frames after {WARM_UP_FRAMES} warm-up frames, telemetry sent -> reply received");
    let (baseline, _) = runtime.block_on(measure(&domain, &["reply_deadline_ms:=0.0"], false));
    let (full, fresh) = runtime.block_on(measure(&domain, &[], true));
    println!(
        "baseline (no DDS round trip):      p50 {:.3} ms  p99 {:.3} ms  max {:.3} ms",
        baseline.p50_ms, baseline.p99_ms, baseline.max_ms
    );
    println!(
        "bridge + echo node over DDS:       p50 {:.3} ms  p99 {:.3} ms  max {:.3} ms  ({fresh}/{FRAMES} replies carried the echo's command)",
        full.p50_ms, full.p99_ms, full.max_ms
    );
    println!(
        "ratio full / baseline:             p50 {:.2}x  p99 {:.2}x",
        full.p50_ms / baseline.p50_ms,
        full.p99_ms / baseline.p99_ms
    );
    let verdict = |ok: bool| if ok { "met" } else { "MISSED" };
    println!("targets: p50 <= 2 ms {}, p99 <= 5 ms {}", verdict(full.p50_ms <= 2.0), verdict(full.p99_ms <= 5.0));
}
