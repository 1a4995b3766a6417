//! A whole mission in one thread, without DDS or sockets: the simulator linked as the bridge links
//! it ([`DirectLink`]), and the cores of the perception, mapping, decision and pickup nodes run by
//! the in-process [`Executor`] over the graph table. It is the fast loop for developing the
//! decision logic and for tests of it; `rover eval` runs the same cores with every node in its
//! own process.

use std::time::Instant;

use rover_bridge::direct::{DirectLink, UnityPeer};
use rover_decision::node::DecisionNode;
use rover_decision::params::DecisionParams;
use rover_mapping::node::MappingNode;
use rover_mapping::params::MappingParams;
use rover_msgs::builtin_interfaces::Time;
use rover_perception::node::PerceptionNode;
use rover_perception::params::PerceptionParams;
use rover_pickup::PickupParams;
use rover_pickup::node::PickupNode;
use rover_runtime::executor::Executor;
use rover_runtime::{RosArgs, Shutdown, resolve_params, topics};
use rover_sim::sim::{SimConfig, SimReport, Simulator};
use rover_sim::wire::client::Simulation as _;
use rover_sim::world::World;
use serde::Serialize;

use crate::missions::evaluator::Evaluator;
use crate::missions::picture::MissionMap;
use crate::missions::time_by_mode::TimeByMode;
use crate::missions::timeline::Timeline;
use crate::processes::nodes::Node;

/// The parameters of every node of the mission.
#[derive(Debug, Clone, Default)]
pub struct NodeSettings {
    /// Perception.
    pub perception: PerceptionParams,
    /// Mapping.
    pub mapping: MappingParams,
    /// Decision.
    pub decision: DecisionParams,
    /// Pickup.
    pub pickup: PickupParams,
}

impl NodeSettings {
    /// The parameters of every node as the ROS arguments `ros_args` set them.
    pub fn resolve(ros_args: &RosArgs) -> anyhow::Result<Self> {
        Ok(NodeSettings {
            perception: resolve_params(Node::Perception.name(), ros_args)?,
            mapping: resolve_params(Node::Mapping.name(), ros_args)?,
            decision: resolve_params(Node::Decision.name(), ros_args)?,
            pickup: resolve_params(Node::Pickup.name(), ros_args)?,
        })
    }
}

/// A snapshot of a running mission, for progress lines.
#[derive(Debug, Clone, PartialEq)]
pub struct Progress {
    /// Simulated time, seconds.
    pub sim_seconds: f64,
    /// Udacity mapped %, against the world's ground truth.
    pub mapped_pct: f64,
    /// Udacity fidelity %.
    pub fidelity_pct: f64,
    /// Fidelity % against the world's open floor (`World::open_floor`) instead of the ground
    /// truth, whose conservative edge leaves out the floor at the foot of the walls.
    pub floor_fidelity_pct: f64,
    /// Samples located on the map at any time (collected ones stay counted).
    pub located: usize,
    /// Samples picked up.
    pub collected: usize,
    /// Decision mode.
    pub mode: String,
    /// Simulated seconds by activity so far.
    pub time_by_mode: TimeByMode,
    /// When samples were collected and how the mapped share grew.
    pub timeline: Timeline,
    /// How the bridge answered the simulator (all zero without a bridge).
    pub replies: Replies,
}

/// How the bridge answered the simulator, from its `/diagnostics`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Replies {
    /// Frames whose drive command missed the reply deadline, so that the bridge held the last one.
    pub deadline_misses: u64,
    /// Frames answered with the brake because the graph had been silent too long.
    pub silence_brakes: u64,
    /// Telemetry in to reply out, median over the bridge's recent frames, milliseconds.
    pub reply_p50_ms: f64,
    /// The same, 99th percentile.
    pub reply_p99_ms: f64,
}

/// How a mission ended.
#[derive(Debug)]
pub struct MissionOutcome {
    /// The simulator's report.
    pub report: SimReport,
    /// The last progress snapshot.
    pub progress: Progress,
    /// The final map, the path and the samples, for the mission's picture.
    pub mission_map: MissionMap,
}

/// Runs one mission in `world` until the decision is done or `max_sim_seconds` pass; `on_progress`
/// gets a snapshot every `progress_every_frames` frames. A `shutdown` request (Ctrl-C) ends it
/// with an error at the next frame.
pub fn run_in_process(
    world: World,
    settings: &NodeSettings,
    max_sim_seconds: f64,
    progress_every_frames: u64,
    shutdown: &Shutdown,
    mut on_progress: impl FnMut(&Progress),
) -> anyhow::Result<MissionOutcome> {
    tracing::debug!("samples at {:.1?}", world.samples.iter().map(|s| (s.x_m, s.y_m)).collect::<Vec<_>>());
    let step_s = settings.decision.frame_period_s;
    let mut evaluator = Evaluator::new(&world);
    let config = SimConfig { step_s, ..SimConfig::default() };
    let mut link = DirectLink::open(SimulatorPeer(Simulator::new(world, config)), step_s)?;
    let mut graph = graph_of_cores(settings)?;
    evaluator.observe(&graph.start(Time::default()));
    let started = Instant::now();
    for frame in 1.. {
        if shutdown.is_requested() {
            anyhow::bail!("interrupted at {:.1} sim s", link.peer().0.report().sim_seconds);
        }
        let messages = link.next_frame(frame).expect("each command sent brings the telemetry of a frame");
        let now = messages.telemetry.header.stamp.clone();
        evaluator.on_telemetry(&messages.telemetry, step_s);
        let mut written = graph.publish(&topics::TELEMETRY, messages.telemetry, now.clone());
        written.extend(graph.publish(&topics::CAMERA_COMPRESSED, messages.compressed, now));
        let done = evaluator.observe(&written);
        let pickup_requested = written.iter().any(|sent| sent.on(&topics::PICKUP).is_some());
        let drive = written.iter().find_map(|sent| sent.on(&topics::DRIVE_CMD));
        link.answer(pickup_requested, drive, settings.decision.brake as f32)?;
        if frame % progress_every_frames.max(1) == 0 {
            on_progress(&evaluator.snapshot());
        }
        if done || link.peer().0.report().sim_seconds >= max_sim_seconds {
            break;
        }
    }
    evaluator.observe(&graph.stop());
    tracing::debug!("mission took {:.1} s", started.elapsed().as_secs_f64());
    let simulator = &link.peer().0;
    let (progress, mission_map) = evaluator.finish(simulator);
    Ok(MissionOutcome { report: simulator.report(), progress, mission_map })
}

/// The graph's nodes but the bridge, in one executor.
fn graph_of_cores(settings: &NodeSettings) -> anyhow::Result<Executor> {
    let mut graph = Executor::new(&[topics::MAP.name, topics::ROCKS.name, topics::MODE.name]);
    graph.add::<PerceptionNode>(settings.perception.clone())?;
    graph.add::<MappingNode>(settings.mapping.clone())?;
    graph.add::<DecisionNode>(settings.decision.clone())?;
    graph.add::<PickupNode>(settings.pickup.clone())?;
    Ok(graph)
}

/// The simulator as the bridge's peer in this process.
struct SimulatorPeer(Simulator);

impl UnityPeer for SimulatorPeer {
    fn telemetry_json(&mut self) -> String {
        self.0.telemetry()
    }

    fn receive(&mut self, event: &str, data: &serde_json::Value) -> anyhow::Result<bool> {
        Ok(self.0.receive_event(event, Some(data))?)
    }
}
