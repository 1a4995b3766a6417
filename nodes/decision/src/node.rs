//! The decision node (`rover decision`): terrain scans (each with its frame's telemetry), the map
//! and the located rocks in; one drive command per frame and the state machine's mode out.

use std::collections::VecDeque;

use futures::StreamExt;
use rover_msgs::builtin_interfaces::Time;
use rover_msgs::frame_ids;
use rover_msgs::frames::MissionFrames;
use rover_msgs::geometry_msgs::{Point, Pose, PoseArray, PoseStamped, Quaternion};
use rover_msgs::map_grid::{SIDE_CELLS, cell_centre_m};
use rover_msgs::msg::{DecisionState, DriveCommand, MapStats, Telemetry, TerrainScan};
use rover_msgs::nav_msgs::{OccupancyGrid, Path};
use rover_msgs::std_msgs::Header;
use rover_runtime::snapshot::SnapshotFile;
use rover_runtime::{Publisher, Rejections, Runtime, publish_or_warn, topics};
use tracing::Instrument as _;

use crate::checked_observation;
use crate::drive::Drive;
use crate::grid::Grid;
use crate::local::FreeSpaceRays;
use crate::machine::{Machine, Memory, Observation};
use crate::params::DecisionParams;
use crate::snapshot::{self, Snapshot};

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

struct Decision {
    machine: Machine,
    rays: FreeSpaceRays,
    drive: Publisher<DriveCommand>,
    mode: Publisher<DecisionState>,
    plan: Publisher<Path>,
    /// The cells of the path last published on `rover/plan`.
    planned: Vec<usize>,
    first_frame: Option<u64>,
    mission_frames: MissionFrames,
    stamps: FrameStamps,
    resumed: bool,
    frames: u64,
    rejections: Rejections,
}

impl Decision {
    /// Decides the frame's drive command and publishes it, then prepares the next frame's plan
    /// while the simulator and the other nodes work on that frame.
    fn decide(&mut self, scan: &TerrainScan) {
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
        let command = DriveCommand {
            header: Header { frame_id: frame_ids::BASE_LINK.to_string(), ..telemetry.header.clone() },
            frame: telemetry.frame,
            throttle: drive.throttle as f32,
            brake: drive.brake as f32,
            steering_angle_deg: drive.steering_deg as f32,
        };
        publish_or_warn(&self.drive, &topics::DRIVE_CMD, command);
        if self.machine.take_change() || telemetry.frame.is_multiple_of(STATUS_EVERY_FRAMES) {
            self.publish_status(telemetry);
        }
        if self.machine.path() != self.planned {
            self.planned = self.machine.path().to_vec();
            self.publish_plan(telemetry);
        }
        if let Some(position) = position {
            self.machine.prepare_next_frame(&position);
        }
    }

    fn publish_plan(&mut self, telemetry: &Telemetry) {
        let header = Header { frame_id: frame_ids::MAP.to_string(), ..telemetry.header.clone() };
        publish_or_warn(&self.plan, &topics::PLAN, path_message(&self.planned, header));
    }

    fn publish_status(&mut self, telemetry: &Telemetry) {
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
        publish_or_warn(&self.mode, &topics::MODE, state);
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
    fn recall(&mut self, file: &SnapshotFile) {
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
    fn save_if_due(&self, file: &mut SnapshotFile) {
        if file.due(std::time::Duration::from_secs_f64(self.machine.params().snapshot_every_ms / 1000.0)) {
            self.save(file);
        }
    }

    /// Writes the snapshot.
    fn save(&self, file: &mut SnapshotFile) {
        let snapshot = Snapshot { recollection: self.machine.recollection(), mission_frames: self.mission_frames };
        file.save(&snapshot::encode(&snapshot));
    }

    /// Takes over home and collected samples from the mapping node when its mission started
    /// before this node's first frame: the mission was already under way (this node was restarted).
    fn resume_from(&mut self, stats: &MapStats) {
        let earlier = stats.home_frame > 0 && self.first_frame.is_none_or(|first| stats.home_frame < first);
        if !self.rejections.accept(topics::MAP_STATS.name, stats) || self.resumed || !earlier {
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

/// Runs the decision node until shutdown.
pub async fn run(runtime: &Runtime) -> anyhow::Result<()> {
    let (mut node, params) = runtime.node::<DecisionParams>("decision")?;
    let span = node.span();
    let settings = params.get();
    let mut decision = Decision {
        rays: settings.free_space_rays(),
        machine: Machine::new(settings),
        drive: node.publisher(&topics::DRIVE_CMD)?,
        mode: node.publisher(&topics::MODE)?,
        plan: node.publisher(&topics::PLAN)?,
        planned: Vec::new(),
        first_frame: None,
        mission_frames: MissionFrames::default(),
        stamps: FrameStamps::default(),
        resumed: false,
        frames: 0,
        rejections: Rejections::default(),
    };
    let mut scans = std::pin::pin!(node.messages(&topics::TERRAIN)?);
    let mut maps = std::pin::pin!(node.messages(&topics::MAP)?);
    let mut rocks = std::pin::pin!(node.messages(&topics::ROCKS)?);
    let mut stats = std::pin::pin!(node.messages(&topics::MAP_STATS)?);
    let mut snapshot_file = SnapshotFile::new(&decision.machine.params().state_dir, snapshot::FILE_NAME);
    decision.recall(&snapshot_file);
    let mut changes = params.watch();
    let shutdown = runtime.shutdown();
    async {
        loop {
            tokio::select! {
                () = shutdown.wait() => break,
                Some(scan) = scans.next() => {
                    decision.stamps.note(&scan.header.stamp, scan.telemetry.frame);
                    decision.decide(&scan);
                    decision.save_if_due(&mut snapshot_file);
                }
                Some(map) = maps.next() => decision.set_map(&map),
                Some(located) = rocks.next() => decision.set_rocks(&located),
                Some(s) = stats.next() => decision.resume_from(&s),
                Ok(()) = changes.changed() => {
                    let updated = changes.borrow_and_update().clone();
                    decision.rays = updated.free_space_rays();
                    decision.machine.set_params(updated);
                }
            }
        }
        decision.save(&mut snapshot_file);
        tracing::info!(
            "decision: {} frames decided, rejected {}, final mode {}",
            decision.frames,
            decision.rejections,
            decision.machine.status().mode.name()
        );
    }
    .instrument(span)
    .await;
    Ok(())
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
