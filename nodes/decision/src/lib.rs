//! The rover's decisions: a state machine that explores the map's frontiers, steers around what
//! the camera sees, approaches and waits for samples, recovers when stuck and returns home.
//!
//! Plain types and no DDS here; [`node`] wires the machine to the topics.

pub mod drive;
pub mod grid;
pub mod local;
pub mod machine;
pub mod node;
pub mod params;
pub mod plan;

use rover_msgs::msg::{Telemetry, TerrainScan};

use crate::local::FreeSpaceRays;
use crate::machine::{Observation, Sighting};
use crate::plan::Position;

/// The observation of one frame: the telemetry and the terrain scan of its camera image.
pub fn observation(telemetry: &Telemetry, scan: &TerrainScan, rays: &mut FreeSpaceRays) -> Observation {
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

/// Whether every number of the telemetry is finite (a frame with NaN is not decided on).
pub fn telemetry_is_finite(telemetry: &Telemetry) -> bool {
    [telemetry.x_m, telemetry.y_m].iter().all(|v| v.is_finite())
        && [telemetry.yaw_rad, telemetry.pitch_rad, telemetry.roll_rad, telemetry.speed_mps]
            .iter()
            .all(|v| v.is_finite())
}
