//! A mission with every node in its own process: the graph of [`crate::processes::graph`] started from this
//! executable, the simulator's Unity client running in this process, and an evaluator node that
//! scores the published `map` against the simulator's true world. `rover demo` and `rover eval`
//! run missions this way.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use rover_msgs::RosMessage;
use rover_msgs::diagnostic_msgs::DiagnosticArray;
use rover_msgs::geometry_msgs::PoseArray;
use rover_msgs::msg::{DecisionState, Telemetry};
use rover_msgs::nav_msgs::OccupancyGrid;
use rover_runtime::topics::{self, Topic};
use rover_runtime::{NoParams, RosNode, Runtime, Shutdown, Subscription, spawn_subscriber};
use rover_sim::sim::{SimConfig, SimReport, Simulator};
use rover_sim::wire::client::{ClientConfig, run_client};
use rover_sim::world::World;
use tokio::sync::Notify;

use crate::missions::evaluator::Evaluator;
use crate::missions::in_process::Progress;
use crate::missions::picture::MissionMap;
use crate::processes::cpu::CpuMeter;
use crate::processes::graph::{Graph, GraphConfig};

/// How often the progress callback runs, wall clock.
const PROGRESS_PERIOD: Duration = Duration::from_millis(500);
/// How often dead nodes are looked for (and, with respawn, started again), wall clock.
const SUPERVISION_PERIOD: Duration = Duration::from_millis(100);
/// How long the graph's nodes get to be discovered before the mission begins, wall clock.
const DISCOVERY_LIMIT: Duration = Duration::from_secs(60);
/// With DDS Security, RustDDS stops resending a handshake message after ten tries a second apart
/// and a lost one is never tried again; a node not heard from for this long is started again, on
/// a new participant that shakes hands afresh, wall clock.
const HANDSHAKE_WINDOW: Duration = Duration::from_secs(20);
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
    let subscriptions = EvaluatorSubscriptions::open(&mut node)?;
    let mut graph = Graph::start(config)?;
    let shutdown = runtime.shutdown();
    if let Err(problem) = wait_for_graph(&node, &subscriptions, &mut graph, &shutdown).await {
        graph.stop(STOP_TIMEOUT);
        return Err(problem);
    }
    tracing::info!("the graph is discovered; the mission begins");
    let subscribers = subscriptions.spawn(&node, &evaluator, &done, step_s);
    let mut simulator = Simulator::new(world, sim_config);
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
    let (progress, mission_map) = evaluator.lock().expect("evaluator lock").finish(&simulator);
    Ok(GraphOutcome { report: simulator.report(), progress, mission_map, unclean_nodes, cpu })
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

/// The evaluator's subscriptions, opened before the graph starts so that none of its messages is
/// missed.
struct EvaluatorSubscriptions {
    map: Subscription<OccupancyGrid>,
    rocks: Subscription<PoseArray>,
    telemetry: Subscription<Telemetry>,
    mode: Subscription<DecisionState>,
    diagnostics: Subscription<DiagnosticArray>,
}

impl EvaluatorSubscriptions {
    fn open(node: &mut RosNode) -> anyhow::Result<Self> {
        Ok(EvaluatorSubscriptions {
            map: mission_subscription(node, &topics::MAP)?,
            rocks: mission_subscription(node, &topics::ROCKS)?,
            telemetry: mission_subscription(node, &topics::TELEMETRY)?,
            mode: mission_subscription(node, &topics::MODE)?,
            diagnostics: mission_subscription(node, &topics::DIAGNOSTICS)?,
        })
    }

    /// The topics of the subscriptions that have matched no publisher yet.
    fn unheard(&self, node: &RosNode) -> Vec<&'static str> {
        let counts = [
            (topics::MAP.name, node.publisher_count(&self.map)),
            (topics::ROCKS.name, node.publisher_count(&self.rocks)),
            (topics::TELEMETRY.name, node.publisher_count(&self.telemetry)),
            (topics::MODE.name, node.publisher_count(&self.mode)),
            (topics::DIAGNOSTICS.name, node.publisher_count(&self.diagnostics)),
        ];
        counts.into_iter().filter(|&(_, count)| count == 0).map(|(topic, _)| topic).collect()
    }

    /// Resolves once every subscription has matched a publisher: the bridge, mapping and decision
    /// nodes are discovered (and, with DDS Security, authenticated).
    async fn matched(&self, node: &RosNode) {
        futures::join!(
            node.publisher_matched(&self.map),
            node.publisher_matched(&self.rocks),
            node.publisher_matched(&self.telemetry),
            node.publisher_matched(&self.mode),
            node.publisher_matched(&self.diagnostics),
        );
    }

    fn spawn(
        self,
        node: &RosNode,
        evaluator: &Arc<Mutex<Evaluator>>,
        done: &Arc<Notify>,
        step_s: f64,
    ) -> Vec<tokio::task::JoinHandle<()>> {
        let span = node.span();
        let done = done.clone();
        let on_mode = move |e: &mut Evaluator, state: DecisionState| {
            if e.on_mode(&state) {
                done.notify_one();
            }
        };
        vec![
            spawn_subscriber(self.map, span.clone(), handler(evaluator, |e, m: OccupancyGrid| e.on_map(&m))),
            spawn_subscriber(self.rocks, span.clone(), handler(evaluator, |e, r: PoseArray| e.on_rocks(&r))),
            spawn_subscriber(
                self.telemetry,
                span.clone(),
                handler(evaluator, move |e, t: Telemetry| e.on_telemetry(&t, step_s)),
            ),
            spawn_subscriber(self.mode, span.clone(), handler(evaluator, on_mode)),
            spawn_subscriber(self.diagnostics, span, handler(evaluator, |e, d: DiagnosticArray| e.on_diagnostics(&d))),
        ]
    }
}

/// Waits until the evaluator has matched the graph's publishers, so that the simulator's first
/// frame does not go out to a graph still discovering itself; every [`HANDSHAKE_WINDOW`] meanwhile
/// the nodes not heard from start again. Fails when a node exits or after [`DISCOVERY_LIMIT`].
async fn wait_for_graph(
    node: &RosNode,
    subscriptions: &EvaluatorSubscriptions,
    graph: &mut Graph,
    shutdown: &Shutdown,
) -> anyhow::Result<()> {
    let logs = graph.config().log_dir.display().to_string();
    let mut matched = std::pin::pin!(tokio::time::timeout(DISCOVERY_LIMIT, subscriptions.matched(node)));
    let mut supervision = tokio::time::interval(SUPERVISION_PERIOD);
    let mut handshakes = tokio::time::interval_at(tokio::time::Instant::now() + HANDSHAKE_WINDOW, HANDSHAKE_WINDOW);
    loop {
        tokio::select! {
            found = &mut matched => {
                return found.map_err(|_| anyhow::anyhow!(
                    "the evaluator heard no publisher of {} within {} s; see the logs in {logs}",
                    subscriptions.unheard(node).join(", "),
                    DISCOVERY_LIMIT.as_secs()
                ));
            }
            () = shutdown.wait() => return Ok(()),
            _ = handshakes.tick() => restart_unheard(&subscriptions.unheard(node), graph)?,
            _ = supervision.tick() => {
                if let Some((name, status)) = graph.exited().into_iter().next() {
                    anyhow::bail!("node {name} exited ({status}) before the mission began; see {logs}");
                }
            }
        }
    }
}

/// Starts again the nodes of `graph` that the graph table says publish one of the `unheard`
/// topics.
fn restart_unheard(unheard: &[&str], graph: &mut Graph) -> anyhow::Result<()> {
    let running: Vec<String> = graph.processes().map(|(name, _)| name.to_string()).collect();
    let writers = rover_runtime::graph::GRAPH.iter().filter(|n| n.writes.iter().any(|topic| unheard.contains(topic)));
    for name in writers.map(|n| n.node).filter(|name| running.iter().any(|r| r == name)) {
        tracing::warn!(
            "no publisher of {} heard within {} s (a DDS Security handshake lost?): starting node {name} again",
            unheard.join(", "),
            HANDSHAKE_WINDOW.as_secs()
        );
        graph.restart(name)?;
    }
    Ok(())
}
