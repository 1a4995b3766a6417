//! The decision node (`rover decision`): terrain scans (each with its frame's telemetry), the map
//! and the located rocks in; one drive command per frame and the state machine's mode out. It
//! serves the mission's commands and `navigate_to_pose`, and takes goals on `goal_pose`.

use std::collections::VecDeque;

use rover_msgs::builtin_interfaces::Time;
use rover_msgs::frame_ids;
use rover_msgs::frames::MissionFrames;
use rover_msgs::geometry_msgs::{Point, Pose, PoseArray, PoseStamped, Quaternion};
use rover_msgs::map_grid::{SIDE_CELLS, cell_centre_m};
use rover_msgs::msg::{DecisionState, DriveCommand, MapStats, Telemetry, TerrainScan};
use rover_msgs::nav_msgs::{OccupancyGrid, Path};
use rover_msgs::nav2_msgs::NavigateToPoseResult;
use rover_msgs::sample_return::SampleReturnResult;
use rover_msgs::std_msgs::Header;
use rover_runtime::commands::{self, Commands, GoalEnd, GoalId};
use rover_runtime::node_core::{FromParams, Inputs, NodeCore, Outbox};
use rover_runtime::snapshot::SnapshotFile;
use rover_runtime::{Rejections, topics};

use crate::checked_observation;
use crate::drive::Drive;
use crate::grid::Grid;
use crate::local::FreeSpaceRays;
use crate::machine::{Machine, Memory, Observation};
use crate::params::DecisionParams;
use crate::snapshot::{self, Snapshot};

mod served;

use served::{RunningGoal, answer};

/// The mode is published at least every this many frames, even when it does not change.
const STATUS_EVERY_FRAMES: u64 = 25;
/// How many scans' frames are remembered by stamp, to date the maps and rocks that come in.
const STAMPS_KEPT: usize = 64;

/// The bridge's frame numbers of the last scans, by stamp. The mapping node stamps a map with its
/// last scan, so that the machine can put the map into effect at a fixed frame after it
/// ([`crate::arrivals`]).
#[derive(Default)]
struct FrameStamps {
    recent: VecDeque<(Time, u64)>,
}

impl FrameStamps {
    fn note(&mut self, stamp: &Time, bridge_frame: u64) {
        if self.recent.len() == STAMPS_KEPT {
            self.recent.pop_front();
        }
        self.recent.push_back((stamp.clone(), bridge_frame));
    }

    fn bridge_frame_of(&self, stamp: &Time) -> Option<u64> {
        self.recent.iter().rev().find(|(s, _)| s == stamp).map(|&(_, frame)| frame)
    }
}

/// The decision node: one drive command for each terrain scan, decided by the [`Machine`] on the
/// latest map and rocks; the mode and the planned path for whoever watches.
pub struct DecisionNode {
    machine: Machine,
    rays: FreeSpaceRays,
    /// The cells of the path last published on `rover/plan`.
    planned: Vec<usize>,
    first_frame: Option<u64>,
    mission_frames: MissionFrames,
    stamps: FrameStamps,
    resumed: bool,
    frames: u64,
    rejections: Rejections,
    snapshot_file: SnapshotFile,
    goal: Option<RunningGoal>,
    /// The goal of `sample_return` that follows the mission.
    mission_goal: Option<GoalId>,
    /// The mapping node's latest statistics.
    map_stats: MapStats,
    /// The node braked frames while inactive since the machine last decided.
    held: bool,
}

impl NodeCore for DecisionNode {
    type Params = DecisionParams;
    const NAME: &'static str = "decision";

    fn inputs() -> Inputs<Self> {
        Inputs::new()
            .on(&topics::TERRAIN, Self::on_scan)
            .on(&topics::MAP, |node, map, _| node.set_map(map))
            .on(&topics::ROCKS, |node, rocks, _| node.set_rocks(rocks))
            .on(&topics::MAP_STATS, Self::on_map_stats)
            .on(&topics::GOAL_POSE, Self::on_goal_pose)
    }

    fn commands() -> Commands<Self> {
        Commands::new()
            .action(&commands::NAVIGATE_TO_POSE, Self::on_navigate_goal, Self::on_navigate_cancel)
            .action(&commands::SAMPLE_RETURN, Self::on_mission_goal, Self::on_mission_cancel)
            .service(&commands::START_MISSION, |node, _, _| answer(node.machine.start_mission()))
            .service(&commands::PAUSE_MISSION, |node, _, _| answer(node.machine.pause()))
            .service(&commands::RESUME_MISSION, |node, _, _| answer(node.machine.resume_after_pause()))
            .service(&commands::RETURN_HOME, Self::on_return_home)
    }

    fn inactive_inputs() -> Inputs<Self> {
        Inputs::new().on(&topics::TERRAIN, Self::brake_for)
    }

    fn start(&mut self, _out: &mut Outbox) {
        self.recall();
    }

    fn set_params(&mut self, params: DecisionParams) {
        self.rays = params.free_space_rays();
        self.machine.set_params(params);
    }

    fn stop(&mut self, out: &mut Outbox) {
        let stopping = NavigateToPoseResult::error(NavigateToPoseResult::UNKNOWN, "the decision node stopped");
        self.end_goal(GoalEnd::Aborted, stopping, out);
        if let Some(id) = self.mission_goal.take() {
            let stopping = SampleReturnResult::ended_early("the decision node stopped");
            out.finish(&commands::SAMPLE_RETURN, id, GoalEnd::Aborted, stopping);
        }
        self.save();
        tracing::info!(
            "decision: {} frames decided, rejected {}, final mode {}",
            self.frames,
            self.rejections,
            self.machine.status().mode.name()
        );
    }
}

impl FromParams for DecisionNode {
    fn new(settings: DecisionParams) -> anyhow::Result<Self> {
        let snapshot_file = SnapshotFile::new(&settings.state_dir, snapshot::FILE_NAME);
        Ok(DecisionNode {
            rays: settings.free_space_rays(),
            machine: Machine::new(settings),
            planned: Vec::new(),
            first_frame: None,
            mission_frames: MissionFrames::default(),
            stamps: FrameStamps::default(),
            resumed: false,
            frames: 0,
            rejections: Rejections::default(),
            snapshot_file,
            goal: None,
            mission_goal: None,
            map_stats: MapStats::default(),
            held: false,
        })
    }
}

impl DecisionNode {
    /// While inactive: the brake for each frame, so that the rover stops and holds where it is
    /// until the node is active again and the machine goes on from where it was.
    fn brake_for(&mut self, scan: &TerrainScan, out: &mut Outbox) {
        let brake = Drive::stop(self.machine.params().brake);
        out.publish(&topics::DRIVE_CMD, drive_command(&scan.telemetry, &brake));
        self.held = true;
    }

    fn on_scan(&mut self, scan: &TerrainScan, out: &mut Outbox) {
        if std::mem::take(&mut self.held) {
            self.machine.start_afresh();
        }
        self.stamps.note(&scan.header.stamp, scan.telemetry.frame);
        self.decide(scan, out);
        self.report_on_goal(&scan.telemetry, out);
        self.report_on_mission(&scan.telemetry, out);
        self.save_if_due();
    }

    /// Keeps the mapping node's statistics for the mission's feedback, and takes over a mission
    /// under way from them.
    fn on_map_stats(&mut self, stats: &MapStats, _out: &mut Outbox) {
        if self.rejections.accept(topics::MAP_STATS.name, stats) {
            self.map_stats = stats.clone();
            self.resume_from(stats);
        }
    }

    /// Decides the frame's drive command and publishes it, then prepares the next frame's plan
    /// while the simulator and the other nodes work on that frame.
    fn decide(&mut self, scan: &TerrainScan, out: &mut Outbox) {
        let telemetry = &scan.telemetry;
        let observation = checked_observation(scan, &mut self.rays, &mut self.rejections);
        let position = observation.as_ref().map(|o| o.position);
        let drive = match observation {
            Some(observation) => {
                self.first_frame.get_or_insert(telemetry.frame);
                self.frames += 1;
                self.machine.step(&Observation { frame: self.mission_frames.of(telemetry.frame), ..observation })
            }
            None => Drive::stop(self.machine.params().brake),
        };
        out.publish(&topics::DRIVE_CMD, drive_command(telemetry, &drive));
        if self.machine.take_change() || telemetry.frame.is_multiple_of(STATUS_EVERY_FRAMES) {
            self.publish_status(telemetry, out);
        }
        if self.machine.path() != self.planned {
            self.planned = self.machine.path().to_vec();
            self.publish_plan(telemetry, out);
        }
        if let Some(position) = position {
            self.machine.prepare_next_frame(&position);
        }
    }

    fn publish_plan(&self, telemetry: &Telemetry, out: &mut Outbox) {
        let header = Header { frame_id: frame_ids::MAP.to_string(), ..telemetry.header.clone() };
        out.publish(&topics::PLAN, path_message(&self.planned, header));
    }

    fn publish_status(&self, telemetry: &Telemetry, out: &mut Outbox) {
        let status = self.machine.status();
        let (target_x_m, target_y_m) = status.target.unwrap_or((f64::NAN, f64::NAN));
        let (home_x_m, home_y_m) = status.home.unwrap_or((f64::NAN, f64::NAN));
        let state = DecisionState {
            header: Header { frame_id: frame_ids::MAP.to_string(), ..telemetry.header.clone() },
            frame: telemetry.frame,
            mode: status.mode.name().to_string(),
            target_x_m,
            target_y_m,
            reason: status.reason.clone(),
            samples_collected: status.samples_collected,
            home_x_m,
            home_y_m,
        };
        out.publish(&topics::MODE, state);
    }

    fn set_map(&mut self, map: &OccupancyGrid) {
        if !self.rejections.accept(topics::MAP.name, map) {
            return;
        }
        let info = &map.info;
        match Grid::from_occupancy(&map.data).filter(|_| is_the_planning_grid(map)) {
            Some(grid) => self.machine.receive_map(self.mission_frame_of(&map.header.stamp), grid),
            None => self.rejections.reject(
                topics::MAP.name,
                &format_args!(
                    "ignored a map of {}x{} cells of {} m: expected {SIDE_CELLS}x{SIDE_CELLS} cells of 1 m",
                    info.width, info.height, info.resolution
                ),
            ),
        }
    }

    /// The mission frame of the telemetry stamped `stamp`, counted from the last decided frame by
    /// the bridge's numbers; 0 (long past: in effect at once) for a stamp of no recent telemetry
    /// (e.g. the latched map a restarted node receives).
    fn mission_frame_of(&self, stamp: &Time) -> u64 {
        match (self.stamps.bridge_frame_of(stamp), self.mission_frames.last()) {
            (Some(frame), Some((bridge, mission))) => mission.saturating_add(frame).saturating_sub(bridge),
            _ => 0,
        }
    }

    fn set_rocks(&mut self, rocks: &PoseArray) {
        if self.rejections.accept(topics::ROCKS.name, rocks) {
            let located = rocks.points();
            self.machine.receive_rocks(self.mission_frame_of(&rocks.header.stamp), located);
        }
    }

    /// Carries on from the snapshot of an earlier decision node, if there is one.
    fn recall(&mut self) {
        let file = &self.snapshot_file;
        if let Some(snapshot) = file.load(snapshot::decode) {
            tracing::info!(
                "recalled the exploration from {}: {} cells inspected, {} rocks given up, {:?}",
                file.path().map_or_else(String::new, |p| p.display().to_string()),
                snapshot.recollection.explorer.inspected.iter().filter(|&&c| c).count(),
                snapshot.recollection.ignored_rocks.len(),
                snapshot.recollection.stage
            );
            self.machine.recall(snapshot.recollection);
            self.mission_frames = snapshot.mission_frames;
        }
    }

    /// Writes the snapshot if `snapshot_every_ms` has passed since the last one.
    fn save_if_due(&mut self) {
        if self.snapshot_file.due(std::time::Duration::from_secs_f64(self.machine.params().snapshot_every_ms / 1000.0))
        {
            self.save();
        }
    }

    /// Writes the snapshot.
    fn save(&mut self) {
        let snapshot = Snapshot { recollection: self.machine.recollection(), mission_frames: self.mission_frames };
        self.snapshot_file.save(&snapshot::encode(&snapshot));
    }

    /// Takes over home and collected samples from the mapping node when its mission started
    /// before this node's first frame: the mission was already under way (this node was restarted).
    fn resume_from(&mut self, stats: &MapStats) {
        let earlier = stats.home_frame > 0 && self.first_frame.is_none_or(|first| stats.home_frame < first);
        if self.resumed || !earlier {
            return;
        }
        self.resumed = true;
        let memory = Memory { home: (stats.home_x_m, stats.home_y_m), samples_collected: stats.samples_collected };
        tracing::info!(
            "resuming a mission: home ({:.1}, {:.1}), {} samples collected",
            memory.home.0,
            memory.home.1,
            memory.samples_collected
        );
        self.machine.resume(memory);
    }
}

/// The drive command `drive` for the frame of `telemetry`, in `rover/drive_cmd`'s `f32`.
fn drive_command(telemetry: &Telemetry, drive: &Drive) -> DriveCommand {
    DriveCommand {
        header: Header { frame_id: frame_ids::BASE_LINK.to_string(), ..telemetry.header.clone() },
        frame: telemetry.frame,
        throttle: drive.throttle as f32,
        brake: drive.brake as f32,
        steering_angle_deg: drive.steering_deg as f32,
    }
}

/// The path through the centres of `cells`, in the map frame of `header`.
fn path_message(cells: &[usize], header: Header) -> Path {
    let pose = |cell: usize| {
        let (x, y) = cell_centre_m(cell);
        let pose = Pose { position: Point { x, y, z: 0.0 }, orientation: Quaternion::IDENTITY };
        PoseStamped { header: header.clone(), pose }
    };
    Path { poses: cells.iter().map(|&cell| pose(cell)).collect(), header }
}

/// Whether a map has the size and cell size of the grid the machine plans on.
fn is_the_planning_grid(map: &OccupancyGrid) -> bool {
    (map.info.width as usize, map.info.height as usize, map.info.resolution) == (SIDE_CELLS, SIDE_CELLS, 1.0)
}

#[cfg(test)]
mod tests {
    use rover_msgs::map_grid::cell_at;

    use super::*;

    #[test]
    fn a_plan_goes_through_the_centres_of_its_cells_in_the_map_frame() {
        let header = Header { frame_id: frame_ids::MAP.to_string(), ..Header::default() };
        let path = path_message(&[cell_at(10, 20), cell_at(11, 21)], header);
        let points: Vec<(f64, f64)> = path.poses.iter().map(|p| (p.pose.position.x, p.pose.position.y)).collect();
        assert_eq!(points, [(10.5, 20.5), (11.5, 21.5)]);
        assert!(path.poses.iter().all(|p| p.header.frame_id == "map" && p.pose.orientation == Quaternion::IDENTITY));
        assert_eq!(path.header.frame_id, "map");
        assert!(path_message(&[], Header::default()).poses.is_empty());
    }
}
