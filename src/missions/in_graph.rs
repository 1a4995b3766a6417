//! A mission with every node in its own process: the graph of [`crate::processes::graph`] started from this
//! executable, the simulator's Unity client running in this process, and an evaluator node that
//! scores the published `map` against the simulator's true world. `rover demo` and `rover eval`
//! run missions this way.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use rover_bridge::stats::{DEADLINE_MISSES_KEY, REPLY_P50_KEY, REPLY_P99_KEY, SILENCE_BRAKES_KEY};
use rover_decision::machine::Mode;
use rover_mapping::score::{LocatedSamples, occupancy_scores};
use rover_msgs::RosMessage;
use rover_msgs::diagnostic_msgs::DiagnosticArray;
use rover_msgs::frames::MissionFrames;
use rover_msgs::geometry_msgs::PoseArray;
use rover_msgs::msg::{DecisionState, Telemetry};
use rover_msgs::nav_msgs::OccupancyGrid;
use rover_runtime::topics::{self, Topic};
use rover_runtime::{NoParams, RosNode, Runtime, Subscription, spawn_subscriber};
use rover_sim::sim::{SimConfig, SimReport, Simulator};
use rover_sim::wire::client::{ClientConfig, run_client};
use rover_sim::world::World;
use tokio::sync::Notify;

use crate::missions::in_process::{Progress, Replies};
use crate::missions::picture::{MissionMap, sample_marks};
use crate::missions::time_by_mode::{ModeClock, TimeByMode, activity_of};
use crate::missions::timeline::Timeline;
use crate::processes::cpu::CpuMeter;
use crate::processes::graph::{Graph, GraphConfig};

/// How often the progress callback runs, wall clock.
const PROGRESS_PERIOD: Duration = Duration::from_millis(500);
/// How often dead nodes are looked for (and, with respawn, started again), wall clock.
const SUPERVISION_PERIOD: Duration = Duration::from_millis(100);
/// Without a new telemetry frame for this long the graph counts as stalled and the run ends.
const STALL_LIMIT: Duration = Duration::from_secs(60);
/// How long each node gets to exit after SIGINT.
const STOP_TIMEOUT: Duration = Duration::from_secs(5);

/// How a graph mission ended.
#[derive(Debug)]
pub struct GraphOutcome {
    /// The simulator's report.
    pub report: SimReport,
    /// The evaluator's last snapshot.
    pub progress: Progress,
    /// The last map the mapping node published, the path and the samples, for the mission's
    /// picture.
    pub mission_map: MissionMap,
    /// Nodes that did not exit cleanly at the end.
    pub unclean_nodes: Vec<String>,
    /// The CPU time each process used during the mission: [`SIMULATOR_PROCESS`] and the nodes.
    pub cpu: BTreeMap<String, Duration>,
}

/// The name the CPU time of this process goes by: the simulator, its Unity client and the
/// evaluator node.
pub const SIMULATOR_PROCESS: &str = "simulator";

/// The processes of a graph mission: this one and the graph's nodes.
fn mission_processes(graph: &Graph) -> impl Iterator<Item = (&str, u32)> {
    std::iter::once((SIMULATOR_PROCESS, std::process::id())).chain(graph.processes())
}

/// What the evaluator has heard from the graph.
#[derive(Debug)]
struct Evaluator {
    samples: usize,
    located: LocatedSamples,
    progress: Progress,
    last_frame_at: Instant,
    frames: MissionFrames,
    clock: ModeClock,
    /// The map, path and start so far; the samples are filled in at the end.
    mission_map: MissionMap,
}

impl Evaluator {
    fn new(world: &World) -> Self {
        let samples = world.samples.iter().map(|s| (s.x_m, s.y_m)).collect::<Vec<_>>();
        let progress = Progress {
            sim_seconds: 0.0,
            mapped_pct: 0.0,
            fidelity_pct: 0.0,
            located: 0,
            collected: 0,
            mode: "starting".to_string(),
            time_by_mode: TimeByMode::default(),
            timeline: Timeline::default(),
            replies: Replies::default(),
        };
        let mission_map = MissionMap {
            ground_truth: world.ground_truth().to_vec(),
            home_m: (world.start.x_m, world.start.y_m),
            ..MissionMap::default()
        };
        Evaluator {
            samples: samples.len(),
            located: LocatedSamples::new(samples),
            progress,
            last_frame_at: Instant::now(),
            frames: MissionFrames::default(),
            clock: ModeClock::default(),
            mission_map,
        }
    }

    /// The progress so far, with the time by activity.
    fn snapshot(&self) -> Progress {
        Progress { time_by_mode: self.clock.times().clone(), ..self.progress.clone() }
    }

    fn on_map(&mut self, map: &OccupancyGrid) {
        let scores = occupancy_scores(&map.data, &self.mission_map.ground_truth);
        self.progress.mapped_pct = scores.mapped_pct;
        self.progress.fidelity_pct = scores.fidelity_pct;
        self.mission_map.occupancy.clone_from(&map.data);
    }

    fn on_rocks(&mut self, rocks: &PoseArray) {
        let cells = rocks
            .poses
            .iter()
            .filter(|p| p.position.x >= 0.0 && p.position.y >= 0.0)
            .map(|p| (p.position.x as usize, p.position.y as usize))
            .collect::<Vec<_>>();
        self.located.update(&cells);
        self.progress.located = self.located.count();
    }

    /// Adds the progress so far to the timeline.
    fn note_timeline(&mut self) {
        let Progress { sim_seconds, mapped_pct, collected, .. } = self.progress;
        self.progress.timeline.note(sim_seconds, mapped_pct, collected);
    }

    fn on_diagnostics(&mut self, diagnostics: &DiagnosticArray) {
        let replies = &mut self.progress.replies;
        update_from(&mut replies.deadline_misses, diagnostics, DEADLINE_MISSES_KEY);
        update_from(&mut replies.silence_brakes, diagnostics, SILENCE_BRAKES_KEY);
        update_from(&mut replies.reply_p50_ms, diagnostics, REPLY_P50_KEY);
        update_from(&mut replies.reply_p99_ms, diagnostics, REPLY_P99_KEY);
    }

    fn on_telemetry(&mut self, telemetry: &Telemetry, step_s: f64) {
        let frame = self.frames.of(telemetry.frame);
        self.progress.sim_seconds = frame as f64 * step_s;
        self.clock.on_frame(frame, activity_of(&self.progress.mode, telemetry), step_s);
        self.progress.collected = self.samples.saturating_sub(telemetry.samples_remaining as usize);
        self.note_timeline();
        self.mission_map.path.record(telemetry.x_m, telemetry.y_m);
        self.last_frame_at = Instant::now();
    }
}

/// Runs one mission in `world` with the graph of `config`, the evaluator on `runtime` (same DDS
/// domain), until the decision node reports `done`, the simulator's time limit, or shutdown.
/// `on_progress` runs twice a second with the evaluator's snapshot and the graph, which it may
/// act on (a test kills and restarts nodes there).
pub async fn run_graph_mission(
    runtime: &Runtime,
    config: GraphConfig,
    world: World,
    sim_config: SimConfig,
    mut on_progress: impl FnMut(&Progress, &mut Graph),
) -> anyhow::Result<GraphOutcome> {
    let step_s = sim_config.step_s;
    let client_config = ClientConfig::unity("127.0.0.1", config.port);
    let evaluator = Arc::new(Mutex::new(Evaluator::new(&world)));
    let done = Arc::new(Notify::new());
    let (mut node, _) = runtime.node::<NoParams>("evaluator")?;
    let subscribers = subscribe_evaluator(&mut node, &evaluator, &done, step_s)?;
    let mut graph = Graph::start(config)?;
    let mut simulator = Simulator::new(world, sim_config);
    let shutdown = runtime.shutdown();
    let stop = async {
        tokio::select! {
            () = done.notified() => tracing::info!("the decision node reports done"),
            () = shutdown.wait() => tracing::info!("stopping the mission"),
        }
    };
    let mut ticks = tokio::time::interval(PROGRESS_PERIOD);
    let mut supervision = tokio::time::interval(SUPERVISION_PERIOD);
    let cpu_meter = CpuMeter::start(mission_processes(&graph));
    let mut client = Box::pin(run_client(&mut simulator, &client_config, stop));
    let failure = loop {
        tokio::select! {
            _ = &mut client => break None,
            _ = ticks.tick() => {
                let progress = evaluator.lock().expect("evaluator lock").snapshot();
                on_progress(&progress, &mut graph);
            }
            _ = supervision.tick() => {
                if let Some(problem) = supervise(&mut graph, &evaluator) {
                    break Some(problem);
                }
            }
        }
    };
    drop(client);
    let cpu = cpu_meter.used(mission_processes(&graph));
    let unclean_nodes = graph.stop(STOP_TIMEOUT);
    for subscriber in subscribers {
        subscriber.abort();
    }
    if let Some(problem) = failure {
        anyhow::bail!("{problem}");
    }
    let report = simulator.report();
    let mut evaluator = evaluator.lock().expect("evaluator lock");
    evaluator.progress.sim_seconds = report.sim_seconds;
    evaluator.progress.collected = report.samples_collected;
    evaluator.note_timeline();
    let mission_map = MissionMap { samples: sample_marks(&simulator), ..std::mem::take(&mut evaluator.mission_map) };
    Ok(GraphOutcome { report, progress: evaluator.snapshot(), mission_map, unclean_nodes, cpu })
}

/// Starts dead nodes again (with respawn); returns why the run cannot go on: a node exited
/// (without respawn) or keeps dying, or no frame arrived for too long.
fn supervise(graph: &mut Graph, evaluator: &Mutex<Evaluator>) -> Option<String> {
    let logs = graph.config().log_dir.display().to_string();
    if graph.config().respawn {
        graph.respawn_dead();
        if let Some(name) = graph.given_up().first() {
            return Some(format!("node {name} keeps dying soon after each start; see {logs}"));
        }
    } else if let Some((name, status)) = graph.exited().into_iter().next() {
        return Some(format!("node {name} exited ({status}); see {logs}"));
    }
    let silent = evaluator.lock().expect("evaluator lock").last_frame_at.elapsed();
    (silent > STALL_LIMIT)
        .then(|| format!("no telemetry for {:.0} s: the graph stalled; see the logs in {}", silent.as_secs_f64(), logs))
}

/// A subscription handler that applies `update` to the shared evaluator.
fn handler<M>(
    evaluator: &Arc<Mutex<Evaluator>>,
    mut update: impl FnMut(&mut Evaluator, M) + Send + 'static,
) -> impl FnMut(M) + Send + 'static {
    let evaluator = evaluator.clone();
    move |message| update(&mut evaluator.lock().expect("evaluator lock"), message)
}

/// A subscription of the evaluator on `topic` without the messages of an earlier mission: this
/// process's DDS participant keeps each topic's last samples, and a new reader of the topic gets
/// them (a second seed's evaluator saw the first one's final telemetry, and counted its frames on
/// from there).
fn mission_subscription<M: RosMessage>(node: &mut RosNode, topic: &Topic<M>) -> anyhow::Result<Subscription<M>> {
    let subscription = node.subscription(topic)?;
    while let Ok(Some(_)) = subscription.take() {}
    Ok(subscription)
}

/// Sets `value` from the number under `key` in `diagnostics`, when there is one.
fn update_from<T: std::str::FromStr>(value: &mut T, diagnostics: &DiagnosticArray, key: &str) {
    if let Some(number) = diagnostics.value(key).and_then(|text| text.parse().ok()) {
        *value = number;
    }
}

/// How many frames a decision state may be ahead of the last telemetry the evaluator saw (the two
/// travel separately).
const MODE_AHEAD_FRAMES: u64 = 25;

/// True if a decision state of bridge frame `frame` belongs to this mission: the evaluator has seen
/// telemetry (`last`: bridge frame, mission frame) up to shortly before it. A latched `done` of the
/// previous mission's graph, still being stopped when this evaluator subscribed, has a frame far
/// ahead of a new mission's first frames, or comes before any.
fn answers_a_frame_seen(last: Option<(u64, u64)>, frame: u64) -> bool {
    last.is_some_and(|(bridge_frame, _)| frame <= bridge_frame + MODE_AHEAD_FRAMES)
}

fn subscribe_evaluator(
    node: &mut RosNode,
    evaluator: &Arc<Mutex<Evaluator>>,
    done: &Arc<Notify>,
    step_s: f64,
) -> anyhow::Result<Vec<tokio::task::JoinHandle<()>>> {
    let span = node.span();
    let done = done.clone();
    let on_mode = move |e: &mut Evaluator, state: DecisionState| {
        if state.mode == Mode::Done.name() && answers_a_frame_seen(e.frames.last(), state.frame) {
            done.notify_one();
        }
        e.progress.mode = state.mode;
    };
    Ok(vec![
        spawn_subscriber(
            mission_subscription(node, &topics::MAP)?,
            span.clone(),
            handler(evaluator, |e, m: OccupancyGrid| e.on_map(&m)),
        ),
        spawn_subscriber(
            mission_subscription(node, &topics::ROCKS)?,
            span.clone(),
            handler(evaluator, |e, r: PoseArray| e.on_rocks(&r)),
        ),
        spawn_subscriber(
            mission_subscription(node, &topics::TELEMETRY)?,
            span.clone(),
            handler(evaluator, move |e, t: Telemetry| e.on_telemetry(&t, step_s)),
        ),
        spawn_subscriber(mission_subscription(node, &topics::MODE)?, span.clone(), handler(evaluator, on_mode)),
        spawn_subscriber(
            mission_subscription(node, &topics::DIAGNOSTICS)?,
            span,
            handler(evaluator, |e, d: DiagnosticArray| e.on_diagnostics(&d)),
        ),
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_done_from_an_earlier_mission_is_not_this_missions_done() {
        assert!(!answers_a_frame_seen(None, 10), "no telemetry seen yet");
        assert!(!answers_a_frame_seen(Some((40, 40)), 26_300), "the last frame of a 1052 s mission");
        assert!(answers_a_frame_seen(Some((26_290, 26_290)), 26_300), "its own frame, a little ahead");
        assert!(answers_a_frame_seen(Some((500, 9_000)), 480), "after a bridge restart, in bridge frames");
    }
}
