//! The rover's decisions: a state machine that explores the map's frontiers, steers around what
//! the camera sees, approaches and waits for samples, recovers when stuck and returns home.
//!
//! The machine, its modes and its planning are plain types; [`node`] is the node's core (messages
//! in, messages out), which the runtime runs over DDS or in process.

mod approach;
mod arrivals;
mod drive;
mod explore;
mod goals;
pub mod grid;
pub mod local;
pub mod machine;
pub mod node;
pub mod params;
mod pose;
pub mod route;
mod samples;
mod snapshot;
mod stuck;
#[cfg(test)]
mod test_maps;
pub mod tour;
mod trail;

use rover_msgs::msg::TerrainScan;
use rover_runtime::{Rejections, topics};

use crate::local::FreeSpaceRays;
use crate::machine::{Observation, Sighting};
use crate::pose::Position;

/// The observation of one frame: the terrain scan of its camera image and the telemetry the scan
/// carries, which must have passed their checks (see [`checked_observation`]).
pub fn observation(scan: &TerrainScan, rays: &mut FreeSpaceRays) -> Observation {
    let telemetry = &scan.telemetry;
    Observation {
        frame: telemetry.frame,
        position: Position { x_m: telemetry.x_m, y_m: telemetry.y_m, yaw_rad: telemetry.yaw_rad as f64 },
        pitch_rad: telemetry.pitch_rad as f64,
        roll_rad: telemetry.roll_rad as f64,
        speed_mps: telemetry.speed_mps as f64,
        near_sample: telemetry.near_sample,
        picking_up: telemetry.picking_up,
        samples_remaining: telemetry.samples_remaining,
        free: rays.measure(scan),
        rock: scan
            .rock_seen
            .then_some(Sighting { bearing_rad: scan.rock_bearing_rad as f64, distance_m: scan.rock_distance_m as f64 }),
    }
}

/// The observation of one frame received from DDS, if the scan and the telemetry it carries pass
/// their checks; one that does not is counted and logged in `rejections` (a scan with a zero cell
/// size would otherwise lay its free-space rays forever).
pub fn checked_observation(
    scan: &TerrainScan,
    rays: &mut FreeSpaceRays,
    rejections: &mut Rejections,
) -> Option<Observation> {
    rejections.accept(topics::TERRAIN.name, scan).then(|| observation(scan, rays))
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use super::*;

    /// A navigable scan 2 m deep and 2 m wide at 0.1 m, as perception sends them.
    fn scan() -> TerrainScan {
        let (rows, cols) = (20, 20);
        let cells = vec![TerrainScan::NAVIGABLE; rows * cols];
        TerrainScan {
            resolution_m: 0.1,
            origin_x_m: 0.3,
            origin_y_m: -1.0,
            rows: rows as u32,
            cols: cols as u32,
            cells,
            ..TerrainScan::default()
        }
    }

    /// `checked_observation` on another thread; `None` if it takes longer than a second.
    fn observe_within_a_second(scan: TerrainScan) -> Option<(Option<Observation>, Rejections)> {
        let (sender, receiver) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let mut rejections = Rejections::default();
            let mut rays = FreeSpaceRays::for_decision(0.6);
            let observed = checked_observation(&scan, &mut rays, &mut rejections);
            let _ = sender.send((observed, rejections));
        });
        receiver.recv_timeout(Duration::from_secs(1)).ok()
    }

    #[test]
    fn a_valid_scan_is_observed() {
        let (observed, rejections) = observe_within_a_second(scan()).expect("observed within a second");
        assert!(observed.is_some_and(|o| o.free.toward(0.0) > 1.0));
        assert_eq!(rejections.count(topics::TERRAIN.name), 0);
    }

    #[test]
    fn a_zero_resolution_scan_is_rejected_promptly() {
        let zero = TerrainScan { resolution_m: 0.0, ..scan() };
        let (observed, rejections) = observe_within_a_second(zero).expect("rejected within a second, no endless rays");
        assert!(observed.is_none());
        assert_eq!(rejections.count(topics::TERRAIN.name), 1);
    }

    #[test]
    fn a_scan_whose_cell_numbers_overflow_32_bits_is_rejected() {
        let absurd = TerrainScan { rows: 61, cols: 1 << 27, ..scan() };
        let (observed, rejections) = observe_within_a_second(absurd).expect("rejected within a second, no panic");
        assert!(observed.is_none());
        assert_eq!(rejections.count(topics::TERRAIN.name), 1);
    }
}
