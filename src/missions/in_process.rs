//! A whole mission in one thread, without DDS or sockets: the simulator linked as the bridge links
//! it ([`DirectLink`]), and the library code the perception, mapping, decision and pickup nodes
//! run, called in the order the graph runs them. It is the fast loop for developing the decision logic and for
//! tests of it; `rover eval` runs the same mission with every node in its own process.

use std::time::Instant;

use rover_bridge::direct::{DirectLink, Frame, UnityPeer};
use rover_decision::drive::Drive;
use rover_decision::grid::Grid;
use rover_decision::machine::{Machine, Mode};
use rover_decision::params::DecisionParams;
use rover_mapping::map::WorldMap;
use rover_mapping::mapper::{MapPublication, MappingCore};
use rover_mapping::params::MappingParams;
use rover_mapping::score::{LocatedSamples, occupancy_scores};
use rover_msgs::msg::DriveCommand;
use rover_msgs::std_msgs::Header;
use rover_perception::params::PerceptionParams;
use rover_pickup::{Pickup, PickupParams, checked_arm_input};
use rover_runtime::{Rejections, RosArgs, Shutdown, resolve_params};
use rover_sim::sim::{SimConfig, SimReport, Simulator};
use rover_sim::wire::client::Simulation as _;
use rover_sim::world::World;
use serde::Serialize;

use crate::missions::picture::{DrivenPath, MissionMap, sample_marks};
use crate::missions::time_by_mode::{ModeClock, TimeByMode, activity_of};
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
    let truth = world.ground_truth().to_vec();
    let samples: Vec<(f64, f64)> = world.samples.iter().map(|s| (s.x_m, s.y_m)).collect();
    tracing::debug!("samples at {samples:.1?}");
    let config = SimConfig { step_s: settings.decision.frame_period_s, ..SimConfig::default() };
    let mut link = DirectLink::open(SimulatorPeer(Simulator::new(world, config)))?;
    let (mut perception, geometry) = settings.perception.pipeline()?;
    let mut mapping = MappingCore::new(settings.mapping.clone(), None);
    let mut machine = Machine::new(settings.decision.clone());
    let mut rays = settings.decision.free_space_rays();
    let mut pickup = Pickup::default();
    let mut pickup_rejections = Rejections::default();
    let mut located = LocatedSamples::new(samples);
    let mut clock = ModeClock::default();
    let mut path = DrivenPath::default();
    let (mut timeline, mut mapped_pct) = (Timeline::default(), 0.0);
    let snapshot = |sim: &Simulator,
                    map: &WorldMap,
                    located: &LocatedSamples,
                    mode: Mode,
                    clock: &ModeClock,
                    timeline: &Timeline| {
        let scores = map.scores(&truth);
        Progress {
            sim_seconds: sim.report().sim_seconds,
            mapped_pct: scores.mapped_pct,
            fidelity_pct: scores.fidelity_pct,
            located: located.count(),
            collected: sim.report().samples_collected,
            mode: mode.name().to_string(),
            time_by_mode: clock.times().clone(),
            timeline: timeline.clone(),
            replies: Replies::default(),
        }
    };
    let started = Instant::now();
    for frame in 1.. {
        if shutdown.is_requested() {
            anyhow::bail!("interrupted at {:.1} sim s", link.peer().0.report().sim_seconds);
        }
        let Frame { telemetry: message, image_jpeg } =
            link.next_frame(frame).expect("each command sent brings the telemetry of a frame");
        path.record(message.x_m, message.y_m);
        clock.on_frame(frame, activity_of(machine.status().mode.name(), &message), config.step_s);
        let classes = perception.process_jpeg(&image_jpeg)?;
        let scan = geometry.terrain_scan(classes, &message, Header::default());
        mapping.add_scan(&scan);
        if mapping.publication_due() {
            mapping.mark_published();
            located.update(&mapping.map().rock_cells());
            let MapPublication { occupancy, rocks, .. } = mapping.publication(Header::default());
            mapped_pct = occupancy_scores(&occupancy, &truth).mapped_pct;
            let grid = Grid::from_occupancy(&occupancy).expect("the map has the cells of map_grid");
            machine.receive_map(frame, grid);
            machine.receive_rocks(frame, rocks);
        }
        let observation = rover_decision::observation(&scan, &mut rays);
        let drive = machine.step(&observation);
        // As the decision node does after publishing; here nothing runs beside it, but the missions
        // that check decisions to the metre go through the plans it makes ahead.
        machine.prepare_next_frame(&observation.position);
        let arm = checked_arm_input(&message, &mut pickup_rejections);
        if arm.is_some_and(|arm| pickup.on_telemetry(&arm, &settings.pickup)) {
            link.send_pickup()?;
        } else {
            send_drive(&mut link, frame, &drive, settings.decision.brake)?;
        }
        let sim = &link.peer().0;
        timeline.note(sim.report().sim_seconds, mapped_pct, sim.report().samples_collected);
        let mode = machine.status().mode;
        if frame % progress_every_frames.max(1) == 0 {
            on_progress(&snapshot(sim, mapping.map(), &located, mode, &clock, &timeline));
        }
        if mode == Mode::Done || sim.report().sim_seconds >= max_sim_seconds {
            break;
        }
    }
    tracing::debug!("mission took {:.1} s", started.elapsed().as_secs_f64());
    let sim = &link.peer().0;
    let progress = snapshot(sim, mapping.map(), &located, machine.status().mode, &clock, &timeline);
    let start = sim.world().start;
    let mission_map = MissionMap {
        occupancy: mapping.map().occupancy(),
        ground_truth: truth,
        path,
        home_m: (start.x_m, start.y_m),
        samples: sample_marks(sim),
    };
    Ok(MissionOutcome { report: sim.report(), progress, mission_map })
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

/// Sends `drive` as the decision node publishes it for `frame`: in the `f32` of `rover/drive_cmd`.
fn send_drive(link: &mut DirectLink<SimulatorPeer>, frame: u64, drive: &Drive, brake: f64) -> anyhow::Result<()> {
    let command = DriveCommand {
        header: Header::default(),
        frame,
        throttle: drive.throttle as f32,
        brake: drive.brake as f32,
        steering_angle_deg: drive.steering_deg as f32,
    };
    link.send_drive(&command, brake as f32)
}
