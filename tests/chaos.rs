//! Fault test: the decision node dies mid-mission, the bridge brakes the rover within its silence
//! limit, and a restarted decision node resumes the mission from the mapping node's memory and the
//! latched map and carries it to its end: the one full mission, graph in separate processes, of
//! the tests.

mod support;

use std::time::{Duration, Instant};

use rover::eval::RunResult;
use rover::graph::GraphConfig;
use rover::graph_mission::run_graph_mission;
use rover_msgs::msg::Telemetry;
use rover_node::topics;
use rover_sim::sim::SimConfig;
use support::{Domain, Latest, NoParams, rover, test_runtime};

/// Sim time at which the decision node is killed, seconds.
const KILL_AT_SIM_S: f64 = 20.0;
/// The procedural world of the mission: one that the rover maps well beyond the 90 % a complete
/// mission needs (97-98 %), so that the test checks the fault handling, not that margin (world 0
/// maps 89.6-91.9 %).
const SEED: u64 = 7;
/// Wall time the graph runs without a decision node.
const DEAD_FOR: Duration = Duration::from_secs(4);

/// Where the fault injection stands.
enum Phase {
    Running,
    Killed { at: Instant, braked_after: Option<Duration> },
    Restarted { braked_after: Option<Duration>, drove_again: bool },
}

fn braking(telemetry: &Latest<Telemetry>) -> bool {
    telemetry.last().is_some_and(|t| t.brake > 0.0 && t.throttle == 0.0)
}

fn driving(telemetry: &Latest<Telemetry>) -> bool {
    telemetry.last().is_some_and(|t| t.throttle > 0.0 && t.brake == 0.0)
}

#[tokio::test(flavor = "multi_thread")]
async fn a_killed_decision_node_brakes_the_rover_and_a_restarted_one_finishes_the_mission() {
    support::assert_isolated();
    let domain = Domain::reserve();
    let runtime = test_runtime(&domain);
    let (mut observer, _) = runtime.node::<NoParams>("fault_observer").expect("observer node");
    let telemetry = Latest::subscribe(&mut observer, &topics::TELEMETRY);
    let log_dir = std::env::temp_dir().join(format!("rover-test-fault-{}", std::process::id()));
    let config =
        GraphConfig { rover: rover(), domain_id: Some(domain.id), port: domain.port(), ros_args: Vec::new(), log_dir };
    let decision_log = config.log_dir.join("decision.log");
    let world = rover_sim::procgen::procedural_world(SEED);
    let samples = world.samples.len();
    let sim_config = SimConfig { max_sim_seconds: Some(1200.0), ..SimConfig::default() };
    let started = Instant::now();
    let mut phase = Phase::Running;
    let mut collected_at_kill = None;
    let outcome = run_graph_mission(&runtime, config, world, sim_config, |progress, graph| {
        phase = match std::mem::replace(&mut phase, Phase::Running) {
            Phase::Running if progress.sim_seconds >= KILL_AT_SIM_S => {
                graph.kill("decision");
                collected_at_kill = Some(progress.collected);
                Phase::Killed { at: Instant::now(), braked_after: None }
            }
            Phase::Killed { at, braked_after } if at.elapsed() >= DEAD_FOR => {
                graph.restart("decision").expect("restart the decision node");
                Phase::Restarted { braked_after, drove_again: false }
            }
            Phase::Killed { at, braked_after } => {
                let braked_after = braked_after.or_else(|| braking(&telemetry).then(|| at.elapsed()));
                Phase::Killed { at, braked_after }
            }
            Phase::Restarted { braked_after, drove_again } => {
                Phase::Restarted { braked_after, drove_again: drove_again || driving(&telemetry) }
            }
            running => running,
        }
    })
    .await
    .expect("the mission ran");
    let Phase::Restarted { braked_after, drove_again } = phase else {
        panic!("the decision node was never killed and restarted");
    };
    let braked_after = braked_after.expect("the bridge braked while the decision node was dead");
    println!("bridge braking {:.2} s after the decision node died", braked_after.as_secs_f64());
    // The silence limit is 1 s; the check runs every 0.5 s of wall time.
    assert!(braked_after <= Duration::from_millis(2500), "braked {braked_after:?} after the kill");
    assert!(drove_again, "the rover drove again after the restart");
    let log = std::fs::read_to_string(&decision_log).unwrap_or_default();
    assert!(log.contains("resuming a mission"), "the new decision node resumed: {log}");
    let result = RunResult::of(SEED, samples, &outcome.report, &outcome.progress, started.elapsed().as_secs_f64());
    println!("{}", rover::eval::table(std::slice::from_ref(&result)));
    let collected_at_kill = collected_at_kill.expect("killed");
    assert!(result.collected > collected_at_kill, "samples collected after the restart: {result:?}");
    assert!(result.deadline_misses > 0, "the frames without a decision node count as late: {result:?}");
    assert!(result.complete(), "the mission completed (map, every sample, home, in time): {result:?}");
}
