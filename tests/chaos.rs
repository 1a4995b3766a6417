//! Chaos test: one full mission, graph in separate processes on simulated time
//! (`use_sim_time:=true`), in which each of the five nodes in turn is SIGKILLed at a random moment
//! and started again by the graph's respawn (a respawned bridge starts simulated time again). The nodes start
//! unconfigured (`autostart:=false`) and `rover lifecycle-manager` brings them up, the respawned
//! ones too; later the decision node is deactivated through its lifecycle services for a while
//! (the rover stops and holds) and activated again, and a peer publishes a terrain scan stamped a
//! day ahead, which mapping skips. The mission completes; home and the collected
//! count never change across a restart; after a kill the mapped share drops by at most a point
//! more than it does anywhere else in the mission. The kill moments come from `CHAOS_SEED`
//! (printed; default: the clock), so a failing run can be repeated.
//!
//! And a node that is not heard from before the mission begins (hung at its first start, as a node
//! whose DDS Security handshake was lost is to the evaluator) is started again, and the mission
//! begins.

mod support;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use rover::missions::chaos::Chaos;
use rover::missions::eval::RunResult;
use rover::missions::in_graph::{SIMULATOR_PROCESS, run_graph_mission};
use rover::missions::picture::write_mission_png;
use rover::processes::graph::{GraphConfig, RemoteNodes};
use rover::processes::nodes::Node;
use rover_msgs::msg::{MapStats, Telemetry, TerrainScan};
use rover_runtime::lifecycle::{LifecycleClient, State, Transition};
use rover_runtime::topics;
use rover_sim::sim::SimConfig;
use support::{Domain, Latest, graph_config, test_runtime};

/// The procedural world of the mission.
const WORLD_SEED: u64 = 0;
/// The first kill's slot starts here, simulated seconds.
const FIRST_SLOT_S: f64 = 20.0;
/// Each node is killed at a random moment of a slot this long, simulated seconds: the five slots
/// end at 320 s, before the mission on world 0 can end (404-489 s measured in the graph; with
/// slots of 90 s the last kill could come after a quick mission had ended).
const SLOT_S: f64 = 60.0;
/// How far the mapped share may drop after a kill, below its value at the kill, percentage points,
/// beyond the largest drop of the same mission away from the kills (new views can turn mapped
/// floor into obstacle for a while: 1.2 points within 30 s after a kill of the decision node,
/// which holds no map, was seen).
const MAPPED_DROP_LIMIT_PCT: f64 = 1.0;
/// The drop is watched for this long after each kill, simulated seconds.
const AFTER_KILL_S: f64 = 30.0;

/// The decision node is deactivated at this simulated time (after the last kill's slot)...
const HOLD_AT_S: f64 = 330.0;
/// ...for this long, simulated seconds.
const HOLD_S: f64 = 10.0;
/// Deactivated, the rover is below 0.2 m/s with the brake on within this many frames (1 simulated
/// second).
const STOP_WITHIN_FRAMES: usize = 25;

/// A peer publishes a terrain scan stamped a day ahead at this simulated time (after the last
/// kill's slot, so that mapping is up).
const FUTURE_SCAN_AT_S: f64 = 325.0;

/// Publishes, once at [`FUTURE_SCAN_AT_S`], the latest terrain scan stamped a day ahead, as a
/// hostile peer could.
struct FutureScan {
    latest: Arc<Mutex<Option<TerrainScan>>>,
    publisher: rover_runtime::Publisher<TerrainScan>,
    sent: AtomicBool,
}

impl FutureScan {
    fn new(node: &mut rover_runtime::RosNode) -> Self {
        let latest = Arc::new(Mutex::new(None));
        let sink = latest.clone();
        let subscription = node.subscription(&topics::TERRAIN).expect("subscribe to the scans");
        rover_runtime::spawn_subscriber(subscription, tracing::Span::none(), move |scan| {
            *rover_runtime::sync::lock(&sink) = Some(scan)
        });
        let publisher = node.publisher(&topics::TERRAIN).expect("a publisher of scans");
        FutureScan { latest, publisher, sent: AtomicBool::new(false) }
    }

    fn act(&self, sim_s: f64) {
        if sim_s < FUTURE_SCAN_AT_S || self.sent.load(Ordering::SeqCst) {
            return;
        }
        if let Some(mut scan) = rover_runtime::sync::lock(&self.latest).take() {
            scan.header.stamp.sec += 86_400;
            rover_runtime::publish_or_warn(&self.publisher, &topics::TERRAIN, scan);
            self.sent.store(true, Ordering::SeqCst);
        }
    }
}

/// Deactivates the decision node at [`HOLD_AT_S`] and activates it [`HOLD_S`] later through its
/// lifecycle services, as `ros2 lifecycle set` does; notes when each transition was done.
struct Hold {
    decision: Arc<LifecycleClient>,
    telemetry: Latest<Telemetry>,
    busy: Arc<AtomicBool>,
    /// When the deactivation and the activation were done: the simulated time, and how many
    /// telemetry frames had come (one a frame; a respawned bridge numbers its frames afresh).
    done_at: Arc<Mutex<Vec<(f64, usize)>>>,
}

impl Hold {
    fn new(decision: LifecycleClient, telemetry: Latest<Telemetry>) -> Self {
        Hold { decision: Arc::new(decision), telemetry, busy: Arc::default(), done_at: Arc::default() }
    }

    /// Asks for the transition due at `sim_s`, if one is and none is under way.
    fn act(&self, sim_s: f64) {
        let done = rover_runtime::sync::lock(&self.done_at).clone();
        let due = match done.as_slice() {
            [] if sim_s >= HOLD_AT_S => (State::Active, Transition::Deactivate),
            [(deactivated_s, _)] if sim_s >= deactivated_s + HOLD_S => (State::Inactive, Transition::Activate),
            _ => return,
        };
        if self.busy.swap(true, Ordering::SeqCst) {
            return;
        }
        let (decision, busy, done_at) = (self.decision.clone(), self.busy.clone(), self.done_at.clone());
        let telemetry = self.telemetry.clone();
        tokio::spawn(async move {
            if decision.change(due.0, due.1).await {
                rover_runtime::sync::lock(&done_at).push((sim_s, telemetry.count()));
            }
            busy.store(false, Ordering::SeqCst);
        });
    }

    /// The deactivation and the activation, once both were done.
    fn done(&self) -> Option<[(f64, usize); 2]> {
        rover_runtime::sync::lock(&self.done_at).as_slice().try_into().ok()
    }
}

/// Whether, from [`STOP_WITHIN_FRAMES`] after telemetry frame number `from` (counted as they
/// came) until `until`, every frame shows the rover below 0.2 m/s with the brake on.
fn held_still(telemetry: &[Telemetry], from: usize, until: usize) -> Result<usize, String> {
    let held = telemetry.get(from + STOP_WITHIN_FRAMES..until).unwrap_or_default();
    match held.iter().find(|t| t.speed_mps.abs() >= 0.2 || t.brake <= 0.0) {
        _ if held.is_empty() => Err(format!("no telemetry between the frames {from} and {until} that came")),
        Some(moving) => Err(format!("the rover moves while the decision node is inactive: {moving:?}")),
        None => Ok(held.len()),
    }
}

fn chaos_seed() -> u64 {
    std::env::var("CHAOS_SEED").ok().and_then(|s| s.parse().ok()).unwrap_or_else(|| {
        std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs())
    })
}

/// The home that every `rover/map_stats` message names, and whether the collected count ever
/// went down.
fn check_map_stats(stats: &[MapStats]) -> Result<(f64, f64), String> {
    let known: Vec<&MapStats> = stats.iter().filter(|s| s.home_x_m.is_finite()).collect();
    let first = known.first().ok_or("no rover/map_stats named a home")?;
    let home = (first.home_x_m, first.home_y_m);
    if let Some(moved) = known.iter().find(|s| (s.home_x_m, s.home_y_m) != home) {
        return Err(format!("home moved from {home:?} to ({}, {})", moved.home_x_m, moved.home_y_m));
    }
    if let Some(pair) = known.windows(2).find(|w| w[1].samples_collected < w[0].samples_collected) {
        return Err(format!(
            "the collected count went from {} to {}",
            pair[0].samples_collected, pair[1].samples_collected
        ));
    }
    Ok(home)
}

#[tokio::test(flavor = "multi_thread")]
async fn every_node_killed_in_turn_is_respawned_and_the_mission_completes() {
    support::assert_isolated();
    let seed = chaos_seed();
    println!("CHAOS_SEED={seed}");
    let domain = Domain::reserve();
    let runtime = test_runtime(&domain);
    let (mut observer, _) = runtime.node::<rover_runtime::NoParams>("chaos_observer").expect("observer node");
    let map_stats = Latest::subscribe(&mut observer, &topics::MAP_STATS);
    let telemetry = Latest::subscribe(&mut observer, &topics::TELEMETRY);
    let decision = observer.lifecycle_client("/decision").expect("a client of the decision's lifecycle");
    let log_dir = std::env::temp_dir().join(format!("rover-test-chaos-{}", std::process::id()));
    let ros_args = ["-p", "autostart:=false", "-p", "use_sim_time:=true"].map(String::from).to_vec();
    let config = GraphConfig { respawn: true, ros_args, ..graph_config(&domain, log_dir.clone()) };
    let future_scan = FutureScan::new(&mut observer);
    let _manager = support::start_process(&support::rover(), &["lifecycle-manager"], &domain, "lifecycle-manager");
    let logs = config.clone();
    let world = rover_sim::procgen::procedural_world(WORLD_SEED);
    let samples = world.samples.len();
    let sim_config = SimConfig { max_sim_seconds: Some(1200.0), ..SimConfig::default() };
    let hold = Hold::new(decision, telemetry.clone());
    let mut chaos = Chaos::each_node_once(FIRST_SLOT_S, SLOT_S, seed);
    println!("kills: {:?}", chaos.kills());
    let started = Instant::now();
    let mut mapped_pct = Vec::new();
    let mut restarts = Vec::new();
    let outcome = run_graph_mission(&runtime, config, world, sim_config, |progress, graph| {
        chaos.act(progress.sim_seconds, graph);
        hold.act(progress.sim_seconds);
        future_scan.act(progress.sim_seconds);
        mapped_pct.push((progress.sim_seconds, progress.mapped_pct));
        restarts = Node::ALL.iter().map(|node| (node.name(), graph.restarts(node.name()))).collect();
    })
    .await
    .expect("the mission ran");
    let wall_seconds = started.elapsed().as_secs_f64();
    let result = RunResult::of(WORLD_SEED, samples, &outcome.report, &outcome.progress, wall_seconds, &outcome.cpu);
    println!("{}", rover::missions::eval::table(std::slice::from_ref(&result)));
    let picture = log_dir.join("map.png");
    write_mission_png(&picture, &outcome.mission_map, &result).expect("write the mission's picture");
    println!("the mission's picture: {}", picture.display());
    println!("restarts: {restarts:?}");
    let log = |name: &str| std::fs::read_to_string(logs.log_file(name)).unwrap_or_default();
    let measured: Vec<&str> = outcome.cpu.keys().map(String::as_str).collect();
    let mut expected: Vec<&str> = Node::ALL.iter().map(|node| node.name()).chain([SIMULATOR_PROCESS]).collect();
    expected.sort_unstable();
    assert_eq!(measured, expected, "the CPU time of every process, the nodes started again included");
    assert!(outcome.cpu.values().all(|time| !time.is_zero()), "{:?}", outcome.cpu);
    for (name, count) in &restarts {
        assert_eq!(*count, 1, "node {name} was started again once after its kill: {restarts:?}");
        assert!(log(name).contains("started again"), "the log of {name} goes on after the restart");
    }
    assert!(log("mapping").contains("restored the map from"), "mapping restored its snapshot:\n{}", log("mapping"));
    assert!(log("mapping").contains(" s after this node's clock"), "the future scan was skipped");
    assert!(log("decision").contains("resuming a mission"), "the new decision node resumed:\n{}", log("decision"));
    assert!(log("decision").contains("recalled the exploration from"), "the new decision node read its snapshot");
    let home = check_map_stats(&map_stats.all()).unwrap_or_else(|problem| panic!("{problem}"));
    println!("home ({:.2}, {:.2}) throughout", home.0, home.1);
    let kill_times: Vec<f64> = chaos.kills().iter().map(|kill| kill.at_sim_s).collect();
    let usual_drop = largest_drop_away_from(&mapped_pct, &kill_times);
    println!("away from the kills the mapped share dropped at most {usual_drop:.2} points within {AFTER_KILL_S} s");
    for kill in chaos.kills() {
        let drop = mapped_drop_after(&mapped_pct, kill.at_sim_s);
        println!(
            "kill of {} at {:.0} sim s: the mapped share dropped {drop:.2} points",
            kill.node.name(),
            kill.at_sim_s
        );
        assert!(
            drop <= usual_drop + MAPPED_DROP_LIMIT_PCT,
            "the mapped share dropped {drop:.2} points after {kill:?}, {usual_drop:.2} at most elsewhere"
        );
    }
    let [(deactivated_s, from), (activated_s, until)] =
        hold.done().expect("the decision node was deactivated and activated again");
    let held = held_still(&telemetry.all(), from, until).unwrap_or_else(|problem| panic!("{problem}"));
    println!("decision inactive from {deactivated_s:.1} to {activated_s:.1} sim s: {held} frames held still");
    let timeline = &result.timeline;
    assert_eq!(timeline.collected_at_s.len(), result.collected, "a time for each collection: {timeline:?}");
    assert!(timeline.collected_at_s.windows(2).all(|w| w[0] <= w[1]), "in order: {timeline:?}");
    assert_eq!(timeline.mapped_pct_by_100_s.len(), (result.sim_seconds / 100.0) as usize, "{timeline:?}");
    assert!(
        result.complete(),
        "the mission completed (map, every sample, home, in time): {result:?}\ndecision log:\n{}",
        mode_changes(&log("decision"))
    );
}

/// A command prefix whose first run hangs instead of starting the node (the marker file `$1` does
/// not exist yet: it is made) and whose later runs start it.
const HANGS_AT_FIRST: &str = r#"if [ ! -e "$1" ]; then : > "$1"; exec sleep 600; fi; shift; exec "$@""#;

#[tokio::test(flavor = "multi_thread")]
async fn a_node_not_heard_from_before_the_mission_is_started_again() {
    support::assert_isolated();
    let domain = Domain::reserve();
    let runtime = test_runtime(&domain);
    let log_dir = std::env::temp_dir().join(format!("rover-test-unheard-{}", std::process::id()));
    let marker = log_dir.join("mapping-hung-once");
    let _ = std::fs::remove_file(&marker);
    std::fs::create_dir_all(&log_dir).expect("the log folder");
    let exec = ["sh", "-c", HANGS_AT_FIRST, "sh", marker.to_str().unwrap()].map(String::from).to_vec();
    let remote = RemoteNodes { nodes: vec!["mapping".into()], exec };
    let config = GraphConfig { remote: Some(remote), ..graph_config(&domain, log_dir.clone()) };
    let logs = config.clone();
    let world = rover_sim::procgen::procedural_world(WORLD_SEED);
    let sim_config = SimConfig { max_sim_seconds: Some(30.0), ..SimConfig::default() };
    let outcome = run_graph_mission(&runtime, config, world, sim_config, |_, _| {}).await;
    let mapping_log = std::fs::read_to_string(logs.log_file("mapping")).unwrap_or_default();
    let outcome = outcome.unwrap_or_else(|e| panic!("the mission began: {e:#}\nmapping:\n{mapping_log}"));
    assert!(marker.exists(), "the first start of mapping hung");
    assert!(mapping_log.contains("started again"), "mapping was started again:\n{mapping_log}");
    assert!(outcome.progress.mapped_pct > 1.0, "the restarted mapping node maps: {:?}", outcome.progress.mapped_pct);
}

/// How far the mapped share fell within [`AFTER_KILL_S`] after `kill_s` below its value at
/// `kill_s`, from `(sim s, mapped %)` samples.
fn mapped_drop_after(samples: &[(f64, f64)], kill_s: f64) -> f64 {
    let at_kill = samples.iter().rev().find(|(t, _)| *t <= kill_s).map_or(0.0, |s| s.1);
    let lowest_after = samples
        .iter()
        .filter(|(t, _)| *t > kill_s && *t <= kill_s + AFTER_KILL_S)
        .map(|s| s.1)
        .fold(f64::INFINITY, f64::min);
    (at_kill - lowest_after).max(0.0)
}

/// The largest [`mapped_drop_after`] from a sample's moment that is not within [`AFTER_KILL_S`]
/// of a kill in `kills_s`: how far the mapped share falls in the mission of its own accord.
fn largest_drop_away_from(samples: &[(f64, f64)], kills_s: &[f64]) -> f64 {
    let near_a_kill = |t: f64| kills_s.iter().any(|kill_s| (t - kill_s).abs() <= AFTER_KILL_S);
    samples.iter().filter(|(t, _)| !near_a_kill(*t)).map(|(t, _)| mapped_drop_after(samples, *t)).fold(0.0, f64::max)
}

/// The decision log's lines about mode changes and resumption, for a failure message.
fn mode_changes(log: &str) -> String {
    log.lines()
        .filter(|l| l.contains(" -> ") || l.contains("resum") || l.contains("frontier"))
        .collect::<Vec<_>>()
        .join("\n")
}
