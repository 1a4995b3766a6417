//! Rover messages with hostile fields, as a broken or malicious DDS peer could publish them:
//! NaN, infinities, huge and zero numbers, huge grid sizes and cell arrays that do not match
//! them. Most numbers are ordinary, so that a fair share of the messages pass their checks and
//! reach the code behind them. Cell arrays are bounded, so that no input takes long.

use proptest::prelude::*;
use rover_msgs::msg::{Telemetry, TerrainScan};
use rover_msgs::nav_msgs::OccupancyGrid;

/// Most cells a generated grid has.
pub const MAX_CELLS: usize = 1 << 16;

/// A number that is usually ordinary and sometimes NaN, infinite, zero, tiny or huge.
pub fn hostile_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        12 => -300.0..300.0f64,
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(f64::NEG_INFINITY),
        1 => Just(0.0),
        1 => Just(f64::MIN_POSITIVE),
        1 => prop_oneof![Just(1e300), Just(-1e300), Just(f64::MAX)],
        1 => any::<f64>(),
    ]
}

/// [`hostile_f64`] as a 32-bit float (huge values become infinite).
pub fn hostile_f32() -> impl Strategy<Value = f32> {
    hostile_f64().prop_map(|value| value as f32)
}

/// A grid cell size: usually a valid one, sometimes zero, negative or any hostile number.
pub fn cell_size() -> impl Strategy<Value = f32> {
    prop_oneof![4 => 0.01..1.0f32, 1 => Just(0.0), 1 => hostile_f32()]
}

/// A grid side: zero, small, the decision grid's 200, or huge.
pub fn grid_side() -> impl Strategy<Value = u32> {
    prop_oneof![Just(0), 1..64u32, Just(200), Just(u32::MAX), any::<u32>()]
}

/// `count` values repeating `pattern` when `count` is at most [`MAX_CELLS`] and `consistent`,
/// otherwise `pattern` itself (a cell array that rarely matches the grid's size).
fn cells<T: Copy>(pattern: Vec<T>, count: u64, consistent: bool) -> Vec<T> {
    match usize::try_from(count) {
        Ok(count) if consistent && count <= MAX_CELLS && !pattern.is_empty() => {
            pattern.iter().copied().cycle().take(count).collect()
        }
        _ => pattern,
    }
}

/// A frame number: usually small, sometimes beyond `rover_msgs::validate::MAX_FRAME`.
fn frame() -> impl Strategy<Value = u64> {
    prop_oneof![4 => 0..100_000u64, 1 => any::<u64>()]
}

/// A `rover_msgs/Telemetry` with any frame, position (x, y) and angles (yaw, pitch, roll), and
/// the other fields at their defaults.
fn posed_telemetry() -> impl Strategy<Value = Telemetry> {
    let pose = (frame(), (hostile_f64(), hostile_f64()), (hostile_f32(), hostile_f32(), hostile_f32()));
    pose.prop_map(|(frame, (x_m, y_m), (yaw_rad, pitch_rad, roll_rad))| Telemetry {
        frame,
        x_m,
        y_m,
        yaw_rad,
        pitch_rad,
        roll_rad,
        ..Telemetry::default()
    })
}

/// Any `rover_msgs/Telemetry`.
pub fn telemetry() -> impl Strategy<Value = Telemetry> {
    let drive = (hostile_f32(), hostile_f32(), hostile_f32(), hostile_f32());
    let flags = (any::<bool>(), any::<bool>(), any::<u8>());
    (posed_telemetry(), drive, flags).prop_map(|(posed, drive, flags)| Telemetry {
        speed_mps: drive.0,
        throttle: drive.1,
        brake: drive.2,
        steering_angle_deg: drive.3,
        near_sample: flags.0,
        picking_up: flags.1,
        samples_remaining: flags.2,
        ..posed
    })
}

/// Any `rover_msgs/TerrainScan`; class codes are mostly valid (0 to 3) and sometimes not. Its
/// telemetry has any frame and pose, and the other fields at their defaults (what mapping and
/// decision read of it is the pose; [`telemetry`] covers the rest).
pub fn terrain_scan() -> impl Strategy<Value = TerrainScan> {
    let grid = (cell_size(), hostile_f32(), hostile_f32(), grid_side(), grid_side());
    let classes = (proptest::collection::vec(prop_oneof![8 => 0..=3u8, 1 => any::<u8>()], 0..64), any::<bool>());
    let sightings = (any::<u32>(), hostile_f32(), hostile_f32(), any::<bool>(), hostile_f32(), hostile_f32());
    (posed_telemetry(), grid, classes, sightings).prop_map(|(telemetry, grid, (pattern, consistent), seen)| {
        let (resolution_m, origin_x_m, origin_y_m, rows, cols) = grid;
        TerrainScan {
            telemetry,
            resolution_m,
            origin_x_m,
            origin_y_m,
            rows,
            cols,
            cells: cells(pattern, u64::from(rows) * u64::from(cols), consistent),
            navigable_count: seen.0,
            navigable_bearing_rad: seen.1,
            navigable_distance_m: seen.2,
            rock_seen: seen.3,
            rock_bearing_rad: seen.4,
            rock_distance_m: seen.5,
            ..TerrainScan::default()
        }
    })
}

/// Any `nav_msgs/OccupancyGrid`; occupancies are mostly valid (-1 or 0 to 100) and sometimes not.
pub fn occupancy_grid() -> impl Strategy<Value = OccupancyGrid> {
    let occupancy = prop_oneof![4 => Just(-1i8), 8 => 0..=100i8, 1 => any::<i8>()];
    let data = (proptest::collection::vec(occupancy, 0..64), any::<bool>());
    (cell_size(), grid_side(), grid_side(), (hostile_f64(), hostile_f64()), data).prop_map(
        |(resolution, width, height, (x, y), (pattern, consistent))| {
            let mut grid = OccupancyGrid {
                data: cells(pattern, u64::from(width) * u64::from(height), consistent),
                ..Default::default()
            };
            (grid.info.resolution, grid.info.width, grid.info.height) = (resolution, width, height);
            (grid.info.origin.position.x, grid.info.origin.position.y) = (x, y);
            grid
        },
    )
}
