//! Checks of received messages, one place for every node: the numbers a node computes with are
//! finite and within sane bounds, sizes agree with their arrays, and no field asks for unbounded
//! work or memory. A node checks each message it takes from DDS before using it (see
//! `rover_runtime::rejections`).

use std::fmt;

use crate::geometry_msgs::{Pose, PoseArray, Twist, Vector3};
use crate::msg::{MapStats, Telemetry, TerrainScan};
use crate::nav_msgs::OccupancyGrid;

/// Positions farther than this from the world origin are rejected, metres (the Udacity world is
/// 200 m wide; a path or a line of sight to a far point takes work in proportion to its length).
pub const MAX_POSITION_M: f64 = 10_000.0;
/// Grid cells smaller than this are rejected, metres (rays are laid out in half-cell steps).
pub const MIN_CELL_SIZE_M: f64 = 0.01;
/// Grid cells larger than this are rejected, metres.
pub const MAX_CELL_SIZE_M: f64 = 10.0;
/// Most cells a terrain scan or an occupancy grid may have (rows x columns).
pub const MAX_GRID_CELLS: u64 = 1 << 22;
/// Frame numbers above this are rejected: nodes add timeouts in frames to them. At 1000 frames
/// per second the bridge would take 285 000 years to get there.
pub const MAX_FRAME: u64 = 1 << 53;

/// The first field of a message that fails its check.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct InvalidField {
    /// Path of the field, e.g. `resolution_m` or `poses[3].position.x`.
    pub field: String,
    /// Its value, as text.
    pub value: String,
    /// What the field must be.
    pub expected: String,
}

impl fmt::Display for InvalidField {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "field `{}` = {} (expected {})", self.field, self.value, self.expected)
    }
}

impl std::error::Error for InvalidField {}

/// A message that can check its fields.
pub trait Validate {
    /// The first field that fails its check, if any.
    fn validate(&self) -> Result<(), InvalidField>;
}

/// A number field of a message (`{:?}` shows `1e300` and `NaN` compactly).
trait Number: Into<f64> + fmt::Debug + Copy {}

impl Number for f32 {}
impl Number for f64 {}

fn invalid(field: impl Into<String>, value: String, expected: impl Into<String>) -> InvalidField {
    InvalidField { field: field.into(), value, expected: expected.into() }
}

fn finite(field: &str, value: impl Number) -> Result<(), InvalidField> {
    if value.into().is_finite() { Ok(()) } else { Err(invalid(field, format!("{value:?}"), "a finite number")) }
}

fn within(field: &str, value: impl Number, lo: f64, hi: f64) -> Result<(), InvalidField> {
    if (lo..=hi).contains(&value.into()) {
        Ok(())
    } else {
        Err(invalid(field, format!("{value:?}"), format!("a number in [{lo}, {hi}]")))
    }
}

fn frame(value: u64) -> Result<(), InvalidField> {
    if value <= MAX_FRAME { Ok(()) } else { Err(invalid("frame", value.to_string(), format!("at most {MAX_FRAME}"))) }
}

fn position_m(field: &str, value: impl Number) -> Result<(), InvalidField> {
    within(field, value, -MAX_POSITION_M, MAX_POSITION_M)
}

fn cell_size_m(field: &str, value: impl Number) -> Result<(), InvalidField> {
    within(field, value, MIN_CELL_SIZE_M, MAX_CELL_SIZE_M)
}

/// Checks that a grid of `rows` x `cols` is bounded and has exactly `len` cells; the product is
/// taken in 64 bits, so that it cannot overflow.
fn grid_size(rows: (&str, u32), cols: (&str, u32), cells: (&str, usize)) -> Result<(), InvalidField> {
    let count = u64::from(rows.1) * u64::from(cols.1);
    if count > MAX_GRID_CELLS {
        return Err(invalid(
            rows.0,
            rows.1.to_string(),
            format!("at most {MAX_GRID_CELLS} cells with {} = {}", cols.0, cols.1),
        ));
    }
    if count != cells.1 as u64 {
        return Err(invalid(cells.0, format!("{} values", cells.1), format!("{} x {} = {count}", rows.0, cols.0)));
    }
    Ok(())
}

/// Checks that every value of `values` is allowed; names the first that is not. The check runs
/// over all values without stopping (the compiler then takes many at once); only a message that
/// fails it is searched for the first bad value.
fn each_allowed<T: fmt::Display + Copy>(
    field: &str,
    values: &[T],
    allowed: impl Fn(T) -> bool,
    expected: &str,
) -> Result<(), InvalidField> {
    if values.iter().fold(true, |all, &v| all & allowed(v)) {
        return Ok(());
    }
    match values.iter().position(|&v| !allowed(v)) {
        Some(index) => Err(invalid(format!("{field}[{index}]"), values[index].to_string(), expected)),
        None => Ok(()),
    }
}

fn pose(field: &str, pose: &Pose) -> Result<(), InvalidField> {
    let p = &pose.position;
    for (axis, value) in [("x", p.x), ("y", p.y), ("z", p.z)] {
        position_m(&format!("{field}.position.{axis}"), value)?;
    }
    let q = &pose.orientation;
    for (axis, value) in [("x", q.x), ("y", q.y), ("z", q.z), ("w", q.w)] {
        finite(&format!("{field}.orientation.{axis}"), value)?;
    }
    Ok(())
}

fn vector(field: &str, vector: &Vector3) -> Result<(), InvalidField> {
    for (axis, value) in [("x", vector.x), ("y", vector.y), ("z", vector.z)] {
        finite(&format!("{field}.{axis}"), value)?;
    }
    Ok(())
}

/// The frame number and pose of telemetry: a frame number, a position and finite angles.
fn frame_and_pose(frame_number: u64, (x_m, y_m): (f64, f64), [yaw, pitch, roll]: [f32; 3]) -> Result<(), InvalidField> {
    frame(frame_number)?;
    position_m("x_m", x_m)?;
    position_m("y_m", y_m)?;
    all_finite(&[("yaw_rad", yaw), ("pitch_rad", pitch), ("roll_rad", roll)])
}

/// Every one of `fields` (name, value) is finite.
fn all_finite(fields: &[(&str, f32)]) -> Result<(), InvalidField> {
    fields.iter().try_for_each(|&(field, value)| finite(field, value))
}

/// The named `f32` fields of `message` are finite.
macro_rules! finite_fields {
    ($message:ident: $($field:ident),+) => {
        all_finite(&[$((stringify!($field), $message.$field)),+])
    };
}

impl Validate for Telemetry {
    fn validate(&self) -> Result<(), InvalidField> {
        frame_and_pose(self.frame, (self.x_m, self.y_m), [self.yaw_rad, self.pitch_rad, self.roll_rad])?;
        finite_fields!(self: speed_mps, throttle, brake, steering_angle_deg)
    }
}

impl Validate for TerrainScan {
    fn validate(&self) -> Result<(), InvalidField> {
        self.telemetry.validate().map_err(|e| InvalidField { field: format!("telemetry.{}", e.field), ..e })?;
        finite_fields!(self: navigable_bearing_rad, navigable_distance_m, rock_bearing_rad, rock_distance_m)?;
        cell_size_m("resolution_m", self.resolution_m)?;
        position_m("origin_x_m", self.origin_x_m)?;
        position_m("origin_y_m", self.origin_y_m)?;
        grid_size(("rows", self.rows), ("cols", self.cols), ("cells", self.cells.len()))?;
        each_allowed("cells", &self.cells, |c| c <= TerrainScan::ROCK, "a class code from 0 to 3")
    }
}

impl Validate for OccupancyGrid {
    fn validate(&self) -> Result<(), InvalidField> {
        let info = &self.info;
        cell_size_m("info.resolution", info.resolution)?;
        pose("info.origin", &info.origin)?;
        grid_size(("info.height", info.height), ("info.width", info.width), ("data", self.data.len()))?;
        each_allowed("data", &self.data, |v| v == -1 || (0..=100).contains(&v), "-1 or an occupancy from 0 to 100")
    }
}

impl Validate for PoseArray {
    fn validate(&self) -> Result<(), InvalidField> {
        self.poses.iter().enumerate().try_for_each(|(index, p)| pose(&format!("poses[{index}]"), p))
    }
}

impl Validate for MapStats {
    fn validate(&self) -> Result<(), InvalidField> {
        if self.home_frame > 0 {
            position_m("home_x_m", self.home_x_m)?;
            position_m("home_y_m", self.home_y_m)?;
        }
        Ok(())
    }
}

impl Validate for Twist {
    fn validate(&self) -> Result<(), InvalidField> {
        vector("linear", &self.linear)?;
        vector("angular", &self.angular)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry_msgs::Point;

    fn scan() -> TerrainScan {
        TerrainScan { resolution_m: 0.1, rows: 2, cols: 3, cells: vec![0, 1, 2, 3, 1, 1], ..TerrainScan::default() }
    }

    fn message_of<M: Validate>(message: M) -> String {
        message.validate().unwrap_err().to_string()
    }

    #[test]
    fn a_scan_from_perception_passes() {
        assert_eq!(scan().validate(), Ok(()));
    }

    #[test]
    fn a_scan_with_a_zero_negative_or_non_finite_resolution_is_named() {
        for (resolution_m, shown) in [(0.0, "0.0"), (-0.1, "-0.1"), (f32::NAN, "NaN"), (f32::INFINITY, "inf")] {
            assert_eq!(
                message_of(TerrainScan { resolution_m, ..scan() }),
                format!("field `resolution_m` = {shown} (expected a number in [0.01, 10])")
            );
        }
    }

    #[test]
    fn a_scan_whose_size_disagrees_or_is_absurd_is_named() {
        assert_eq!(
            message_of(TerrainScan { rows: 3, ..scan() }),
            "field `cells` = 6 values (expected rows x cols = 9)"
        );
        assert_eq!(
            message_of(TerrainScan { rows: u32::MAX, cols: u32::MAX, ..scan() }),
            "field `rows` = 4294967295 (expected at most 4194304 cells with cols = 4294967295)"
        );
        let mut bad_class = scan();
        bad_class.cells[4] = 7;
        assert_eq!(message_of(bad_class), "field `cells[4]` = 7 (expected a class code from 0 to 3)");
    }

    #[test]
    fn a_scan_with_a_non_finite_pose_or_summary_is_named() {
        assert_eq!(
            message_of(TerrainScan { telemetry: Telemetry { x_m: f64::NAN, ..Telemetry::default() }, ..scan() }),
            "field `telemetry.x_m` = NaN (expected a number in [-10000, 10000])"
        );
        assert_eq!(
            message_of(TerrainScan { rock_distance_m: f32::NEG_INFINITY, ..scan() }),
            "field `rock_distance_m` = -inf (expected a finite number)"
        );
    }

    #[test]
    fn telemetry_with_nan_or_a_position_beyond_the_world_is_named() {
        assert_eq!(Telemetry::default().validate(), Ok(()));
        assert_eq!(
            message_of(Telemetry { speed_mps: f32::NAN, ..Telemetry::default() }),
            "field `speed_mps` = NaN (expected a finite number)"
        );
        assert_eq!(
            message_of(Telemetry { y_m: 1e300, ..Telemetry::default() }),
            "field `y_m` = 1e300 (expected a number in [-10000, 10000])"
        );
        assert_eq!(
            message_of(Telemetry { frame: u64::MAX, ..Telemetry::default() }),
            "field `frame` = 18446744073709551615 (expected at most 9007199254740992)"
        );
    }

    fn grid() -> OccupancyGrid {
        let mut grid = OccupancyGrid { data: vec![-1, 0, 100, 50], ..OccupancyGrid::default() };
        (grid.info.width, grid.info.height, grid.info.resolution) = (2, 2, 1.0);
        grid
    }

    #[test]
    fn occupancy_grids_are_checked_for_size_cell_size_and_values() {
        assert_eq!(grid().validate(), Ok(()));
        let mut short = grid();
        short.info.width = 3;
        assert_eq!(message_of(short), "field `data` = 4 values (expected info.height x info.width = 6)");
        let mut zero = grid();
        zero.info.resolution = 0.0;
        assert_eq!(message_of(zero), "field `info.resolution` = 0.0 (expected a number in [0.01, 10])");
        let mut odd = grid();
        odd.data[3] = -5;
        assert_eq!(message_of(odd), "field `data[3]` = -5 (expected -1 or an occupancy from 0 to 100)");
    }

    #[test]
    fn pose_arrays_name_the_first_non_finite_pose() {
        let at = |x: f64| Pose { position: Point { x, ..Point::default() }, ..Pose::default() };
        assert_eq!(PoseArray { poses: vec![at(1.0), at(2.0)], ..PoseArray::default() }.validate(), Ok(()));
        assert_eq!(
            message_of(PoseArray { poses: vec![at(1.0), at(f64::NAN)], ..PoseArray::default() }),
            "field `poses[1].position.x` = NaN (expected a number in [-10000, 10000])"
        );
    }

    #[test]
    fn map_stats_need_a_home_only_once_the_mission_started() {
        let before = MapStats { home_x_m: f64::NAN, home_y_m: f64::NAN, ..MapStats::default() };
        assert_eq!(before.validate(), Ok(()));
        assert_eq!(
            message_of(MapStats { home_frame: 5, ..before }),
            "field `home_x_m` = NaN (expected a number in [-10000, 10000])"
        );
    }

    #[test]
    fn twists_with_nan_or_infinity_are_named() {
        assert_eq!(Twist::default().validate(), Ok(()));
        let mut twist = Twist::default();
        twist.angular.z = f64::INFINITY;
        assert_eq!(message_of(twist), "field `angular.z` = inf (expected a finite number)");
    }
}
