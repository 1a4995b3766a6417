//! The lock-step loop's latency budget, hop by hop. A Unity-dialect client replays the 283 real
//! frames of `../shared/udacity/test_dataset` (images and poses) through the whole graph (bridge,
//! perception, mapping, decision, pickup, each its own process) and times every telemetry to its
//! reply. A second pass adds a probe that subscribes to `rover/telemetry`, `rover/terrain` and
//! `rover/drive_cmd` and splits that time into hops (the probe's own delivery delays each stamp
//! alike). The baseline, in the same run: the Python seed solution
//! (`tests/python/seed_baseline/drive_baseline.py`) answering the same frames. For both, the CPU
//! time a frame took in each process (the client is this benchmark's own process): with two
//! telemetries always in flight, the loop's mean latency is about the CPU time of a frame when
//! the two cores are busy. Beside the first pass a thread times a fixed piece of work every 2 ms
//! ([`rover::processes::steadiness`]): the share of the run the host slowed the cores, and the latency of the
//! frames clear of those spells (the thread's CPU, about 0.03 ms a frame, counts as the client's).
//! The verdicts hold the latency against issue 19's goal three ways: as it is, for the frames
//! clear of the spells, and as ratios to the seed solution (the goal was set beside its 20.8 and
//! 33.0 ms).
//!
//! Run inside the loopback-only namespace: `tools/isolated cargo bench --bench loop_latency`.

#[path = "../tests/support/mod.rs"]
mod support;

use std::collections::HashMap;
use std::path::PathBuf;
use std::process::Stdio;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use rover::processes::cpu::{CpuMeter, ms_per_frame};
use rover::processes::graph::Graph;
use rover::processes::steadiness::{PERIOD, SLOW_FACTOR, Steadiness, SteadinessRecord};
use rover_bridge::stats::HOP_NAMES;
use rover_msgs::diagnostic_msgs::DiagnosticArray;
use rover_runtime::{spawn_subscriber, topics};
use rover_sim::wire::client::{ClientConfig, Simulation, run_client};
use rover_sim::wire::command::Command;
use support::echo_sim::{LoadedFrame, recorded_frames, telemetry_json};
use support::{Domain, Percentiles, percentiles, test_runtime, wait_for_port};

/// Times the 283 frames are replayed in each pass.
const ROUNDS: usize = 4;
/// Replies left out at the start of each pass.
const WARM_UP_REPLIES: usize = 100;
/// Issue 19's goal for the loop on one host: p50 and p99, ms.
const GOAL_MS: (f64, f64) = (2.0, 5.0);
/// The Python seed solution's p50 and p99 in the run that the goal was set beside (issue 19), ms:
/// the goal as ratios to a baseline that slows with the host.
const SEED_BESIDE_GOAL_MS: (f64, f64) = (20.8, 33.0);
/// The Python modules of the seed solution.
const SEED_MODULES: [&str; 6] = ["socketio", "engineio", "eventlet", "numpy", "cv2", "PIL"];

/// The client side of a pass: sends the recorded frames in turn and notes when each telemetry
/// left and when the reply answering it came back (replies come in order).
struct Replay {
    frames: Vec<LoadedFrame>,
    sent: Vec<Instant>,
    replied: Vec<Instant>,
    /// Replies that answer no telemetry (drive_rover.py sends one when a client connects).
    unsolicited: usize,
    limit: usize,
}

impl Replay {
    fn new(frames: Vec<LoadedFrame>, unsolicited: usize) -> Self {
        let limit = WARM_UP_REPLIES + ROUNDS * frames.len();
        Replay { frames, sent: Vec::new(), replied: Vec::new(), unsolicited, limit }
    }

    /// Telemetry sent to reply received, for each answered telemetry after the warm-up.
    fn latencies(&self) -> Vec<Duration> {
        self.latencies_where(|_, _| true)
    }

    /// The same for the telemetries whose (sent, replied) times pass `keep`.
    fn latencies_where(&self, keep: impl Fn(Instant, Instant) -> bool) -> Vec<Duration> {
        let answered = self.sent.iter().zip(&self.replied).skip(WARM_UP_REPLIES);
        answered.filter(|&(&sent, &replied)| keep(sent, replied)).map(|(sent, replied)| *replied - *sent).collect()
    }
}

impl Simulation for Replay {
    fn telemetry_json(&mut self) -> String {
        let frame = &self.frames[self.sent.len() % self.frames.len()];
        let json = telemetry_json(frame, frame.frame.state.x_m);
        self.sent.push(Instant::now());
        json
    }

    fn apply(&mut self, _command: Command) {
        if self.unsolicited > 0 {
            self.unsolicited -= 1;
        } else {
            self.replied.push(Instant::now());
        }
    }

    fn finished(&self) -> bool {
        self.replied.len() >= self.limit
    }
}

async fn replay(port: u16, unsolicited: usize) -> Replay {
    let mut replay = Replay::new(recorded_frames(), unsolicited);
    let config = ClientConfig::unity("127.0.0.1", port);
    tokio::time::timeout(Duration::from_secs(300), run_client(&mut replay, &config, std::future::pending()))
        .await
        .expect("a pass ends within 5 minutes");
    replay
}

/// When the probe received each frame's message of one topic.
#[derive(Clone, Default)]
struct Arrivals(Arc<Mutex<HashMap<u64, Instant>>>);

impl Arrivals {
    fn note(&self, frame: u64) {
        self.0.lock().expect("arrivals lock").entry(frame).or_insert_with(Instant::now);
    }

    fn at(&self, frame: u64) -> Option<Instant> {
        self.0.lock().expect("arrivals lock").get(&frame).copied()
    }
}

/// The probe's view of the loop: arrival times of telemetry, scans and drive commands by frame.
struct Probe {
    telemetry: Arrivals,
    terrain: Arrivals,
    drive: Arrivals,
    diagnostics: support::Latest<DiagnosticArray>,
    _node: rover_runtime::RosNode,
    _runtime: rover_runtime::Runtime,
}

impl Probe {
    fn start(domain: &Domain) -> Probe {
        let runtime = test_runtime(domain);
        let (mut node, _) = runtime.node::<rover_runtime::NoParams>("latency_probe").expect("the probe node");
        let (telemetry, terrain, drive) = (Arrivals::default(), Arrivals::default(), Arrivals::default());
        let sink = telemetry.clone();
        let subscription = node.subscription(&topics::TELEMETRY).expect("subscribe");
        spawn_subscriber(subscription, tracing::Span::none(), move |m| sink.note(m.frame));
        let sink = terrain.clone();
        let subscription = node.subscription(&topics::TERRAIN).expect("subscribe");
        spawn_subscriber(subscription, tracing::Span::none(), move |m| sink.note(m.telemetry.frame));
        let sink = drive.clone();
        let subscription = node.subscription(&topics::DRIVE_CMD).expect("subscribe");
        spawn_subscriber(subscription, tracing::Span::none(), move |m| sink.note(m.frame));
        let diagnostics = support::Latest::subscribe(&mut node, &topics::DIAGNOSTICS);
        Probe { telemetry, terrain, drive, diagnostics, _node: node, _runtime: runtime }
    }

    /// The hops of each answered frame after the warm-up (bridge frames count from 1 in the
    /// order the telemetry was sent): bridge in, perception, decision, bridge out.
    fn hops(&self, replay: &Replay) -> [Vec<Duration>; 4] {
        let mut hops: [Vec<Duration>; 4] = Default::default();
        for (index, (sent, replied)) in replay.sent.iter().zip(&replay.replied).enumerate().skip(WARM_UP_REPLIES) {
            let frame = index as u64 + 1;
            let (Some(telemetry), Some(terrain), Some(drive)) =
                (self.telemetry.at(frame), self.terrain.at(frame), self.drive.at(frame))
            else {
                continue;
            };
            let stamps = [*sent, telemetry, terrain, drive, *replied];
            for (hop, pair) in hops.iter_mut().zip(stamps.windows(2)) {
                hop.push(pair[1].saturating_duration_since(pair[0]));
            }
        }
        hops
    }
}

/// The bridge's own split of its recent frames, from its last `/diagnostics`, one line per hop.
fn bridge_hops(diagnostics: &[DiagnosticArray]) -> Vec<String> {
    let Some(last) = diagnostics.last() else { return vec!["  (no /diagnostics received)".to_string()] };
    HOP_NAMES
        .iter()
        .map(|hop| {
            let value = |q: &str| last.value(&format!("hop_{hop}_{q}_ms")).unwrap_or("?").to_string();
            format!("  bridge's clock: {hop:<13} p50 {:>7} ms  p99 {:>7} ms", value("p50"), value("p99"))
        })
        .collect()
}

/// The whole graph, each node its own process, on `domain`.
fn start_graph(domain: &Domain, label: &str) -> Graph {
    start_graph_with_env(domain, label, Vec::new())
}

/// [`start_graph`] with the environment variables `env` for every node.
fn start_graph_with_env(domain: &Domain, label: &str, env: Vec<(String, String)>) -> Graph {
    let log_dir = std::env::temp_dir().join(format!("rover-loop-latency-{}-{label}", std::process::id()));
    let config = rover::processes::graph::GraphConfig { env, ..support::graph_config(domain, log_dir) };
    let graph = Graph::start(config).expect("start the graph");
    wait_for_port(domain.port(), Duration::from_secs(20));
    graph
}

/// The seed solution's server on `port`, if Python has its modules.
fn start_seed_solution(domain: &Domain) -> Option<support::Process> {
    let python = support::python_with(&SEED_MODULES)?;
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/python/seed_baseline/drive_baseline.py");
    let port = domain.port().to_string();
    let mut command = std::process::Command::new(python);
    command.args(["-W", "ignore"]).arg(script).args(["--port", &port, "--quiet"]).stdin(Stdio::null());
    let log = std::env::temp_dir().join(format!("rover-loop-latency-{}-seed.log", std::process::id()));
    let process = support::Process::spawn("seed", command, log).expect("start drive_baseline.py");
    wait_for_port(domain.port(), Duration::from_secs(30));
    Some(process)
}

/// The name this benchmark's own process (the Unity-dialect client) goes by.
const CLIENT: &str = "client";

/// Replays the frames to the server on the domain's port (`unsolicited` replies answering none)
/// and measures the CPU time a frame took in `processes` and this one: a line to print.
fn replay_measuring_cpu(
    runtime: &tokio::runtime::Runtime,
    domain: &Domain,
    unsolicited: usize,
    processes: &[(&str, u32)],
) -> (Replay, String) {
    let measured = || processes.iter().copied().chain([(CLIENT, std::process::id())]);
    let meter = CpuMeter::start(measured());
    let replay = runtime.block_on(replay(domain.port(), unsolicited));
    let per_frame = ms_per_frame(&meter.used(measured()), replay.sent.len() as u64);
    let parts: Vec<String> = per_frame.iter().map(|(name, ms)| format!("{name} {ms:.3}")).collect();
    let line = format!("  CPU ms a frame: {}; all {:.3}", parts.join(", "), per_frame.values().sum::<f64>());
    (replay, line)
}

fn print_row(label: &str, samples: &[Duration]) -> Percentiles {
    let p = percentiles(samples);
    println!("{label:<34} p50 {:>7.3} ms  p99 {:>7.3} ms  ({} frames)", p.p50_ms, p.p99_ms, samples.len());
    p
}

/// Prints how steadily the cores ran during `replay` and the latency of its frames that no slow
/// spell touched; returns their percentiles.
fn print_steadiness(steadiness: &SteadinessRecord, replay: &Replay) -> Percentiles {
    println!(
        "  host: a fixed piece of work took {:.0} us at the median; over {SLOW_FACTOR}x that in {:.1} % of {} runs, {} ms apart",
        steadiness.median().as_secs_f64() * 1e6,
        steadiness.slow_share() * 100.0,
        steadiness.slots(),
        PERIOD.as_millis()
    );
    print_row(
        "  frames clear of slow spells",
        &replay.latencies_where(|sent, replied| !steadiness.slowed(sent, replied)),
    )
}

/// Prints the p50 and p99 of `over` as ratios to those of `under`.
fn print_ratio(label: &str, over: &Percentiles, under: &Percentiles) {
    println!("{label:<35}p50 {:.2}x  p99 {:.2}x", over.p50_ms / under.p50_ms, over.p99_ms / under.p99_ms);
}

fn main() {
    support::assert_isolated();
    let runtime = tokio::runtime::Runtime::new().expect("tokio runtime");
    let _entered = runtime.enter();
    let domain = Domain::reserve();
    let frames = recorded_frames().len();
    println!(
        "loop latency: {ROUNDS} x {frames} recorded frames after {WARM_UP_REPLIES} warm-up replies, telemetry sent -> reply received"
    );

    let graph = start_graph(&domain, "plain");
    let steadiness = Steadiness::start();
    let (plain, cpu) = replay_measuring_cpu(&runtime, &domain, 0, &graph.processes().collect::<Vec<_>>());
    let steadiness = steadiness.finish();
    drop(graph);
    let ours = print_row("rover graph (5 processes)", &plain.latencies());
    println!("{cpu}");
    let steady = print_steadiness(&steadiness, &plain);

    let keystore = support::keystore("loop-latency");
    let graph = start_graph_with_env(&domain, "secured", support::security_env(&keystore));
    let (secured, cpu) = replay_measuring_cpu(&runtime, &domain, 0, &graph.processes().collect::<Vec<_>>());
    drop(graph);
    let secured = print_row("rover graph, DDS Security", &secured.latencies());
    println!("{cpu}");
    print_ratio("ratio secured / plain:", &secured, &ours);

    let probe = Probe::start(&domain);
    let graph = start_graph(&domain, "probed");
    let probed = runtime.block_on(replay(domain.port(), 0));
    std::thread::sleep(Duration::from_millis(1100));
    drop(graph);
    print_row("rover graph with the probe", &probed.latencies());
    let names = [
        "  bridge in (socket -> telemetry)",
        "  perception (-> rover/terrain)",
        "  decision (-> rover/drive_cmd)",
        "  bridge out (-> reply received)",
    ];
    for (name, hop) in names.iter().zip(probe.hops(&probed)) {
        print_row(name, &hop);
    }
    for line in bridge_hops(&probe.diagnostics.all()) {
        println!("{line}");
    }

    let baseline = match start_seed_solution(&domain) {
        Some(seed_process) => {
            let (seed, cpu) = replay_measuring_cpu(&runtime, &domain, 1, &[("seed solution", seed_process.pid())]);
            let baseline = print_row("Python seed solution", &seed.latencies());
            println!("{cpu}");
            print_ratio("ratio rover / seed solution:", &ours, &baseline);
            Some(baseline)
        }
        None => {
            println!("Python seed solution: skipped (python3 lacks {SEED_MODULES:?})");
            None
        }
    };
    let verdict = |ok: bool| if ok { "met" } else { "MISSED" };
    let (p50_ms, p99_ms) = GOAL_MS;
    println!(
        "targets: p50 <= {p50_ms} ms {}, p99 <= {p99_ms} ms {}",
        verdict(ours.p50_ms <= p50_ms),
        verdict(ours.p99_ms <= p99_ms)
    );
    println!(
        "  clear of the host's slow spells: p50 <= {p50_ms} ms {}, p99 <= {p99_ms} ms {}",
        verdict(steady.p50_ms <= p50_ms),
        verdict(steady.p99_ms <= p99_ms)
    );
    if let Some(baseline) = baseline {
        let (seed_p50_ms, seed_p99_ms) = SEED_BESIDE_GOAL_MS;
        let (p50_ratio, p99_ratio) = (p50_ms / seed_p50_ms, p99_ms / seed_p99_ms);
        println!(
            "  as ratios to the seed solution ({p50_ms} / {seed_p50_ms} and {p99_ms} / {seed_p99_ms} ms): p50 <= {p50_ratio:.3}x {}, p99 <= {p99_ratio:.3}x {}",
            verdict(ours.p50_ms / baseline.p50_ms <= p50_ratio),
            verdict(ours.p99_ms / baseline.p99_ms <= p99_ratio)
        );
    }
}
