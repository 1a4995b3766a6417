//! The rover's body as the nodes assume it (unity-sim-spec 4): where the camera sits, how far the
//! arm reaches, and how far the rock evidence of one sample spreads. The one definition of these
//! facts for every node that needs them. The simulator takes Unity's steering facts from here and
//! keeps its own model of the rest of the true rover.

/// The camera's mounting on the body.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraMount {
    /// Camera ahead of the reported position, metres.
    pub forward_m: f64,
    /// Camera above the body origin, metres.
    pub above_origin_m: f64,
    /// Body origin below the floor, metres.
    pub origin_below_floor_m: f64,
}

impl CameraMount {
    /// The Unity rover's camera: 0.4287 m ahead of the position and 0.2391 m above the body
    /// origin, which rests 0.0247 m below the floor (so 0.2144 m above level ground).
    pub const UNITY: CameraMount =
        CameraMount { forward_m: 0.4287, above_origin_m: 0.2391, origin_below_floor_m: 0.0247 };
}

impl Default for CameraMount {
    fn default() -> Self {
        CameraMount::UNITY
    }
}

/// The arm reaches this far ahead of the rover's position, metres.
pub const ARM_REACH_M: f64 = 0.84;

/// The rock evidence of one sample spreads this far, metres: a sample seen from afar projects up
/// to 3 m beyond where it lies, and no two sample places of the Unity world are closer than 7 m.
/// Rocks this close are one sample, and a pickup clears the rock evidence this close to the arm.
pub const SAMPLE_SPREAD_M: f64 = 4.0;

/// Distance between the front and rear axles, metres (unity-sim-spec 3.1).
pub const WHEELBASE_M: f64 = 0.722;

/// The steering command's limit, degrees either side.
pub const MAX_STEER_DEG: f64 = 15.0;

/// Yaw rate of a turn in place at full steering, degrees per second (unity-sim-spec 3.3).
pub const TURN_IN_PLACE_DPS: f64 = 45.0;

/// Forward speed cap, m/s (unity-sim-spec 3.3).
pub const MAX_FORWARD_MPS: f64 = 5.0;

/// The front wheels' range at `speed_mps`, degrees either side: Unity narrows it from 15 degrees
/// at standstill to 5 at full speed (unity-sim-spec 3.3).
fn wheel_range_deg(speed_mps: f64) -> f64 {
    5.0 + 10.0 * (1.0 - speed_mps.abs() / MAX_FORWARD_MPS).clamp(0.0, 1.0)
}

/// The front wheels' angle for `steering_deg` at `speed_mps` going forward, degrees.
pub fn wheel_angle_deg(steering_deg: f64, speed_mps: f64) -> f64 {
    wheel_range_deg(speed_mps) * steering_deg.clamp(-MAX_STEER_DEG, MAX_STEER_DEG) / MAX_STEER_DEG
}

/// The steering command that turns the front wheels by `wheel_deg` at `speed_mps` going forward
/// (clamped to the command's limit), degrees.
pub fn steering_for_wheel_angle_deg(wheel_deg: f64, speed_mps: f64) -> f64 {
    (wheel_deg * MAX_STEER_DEG / wheel_range_deg(speed_mps)).clamp(-MAX_STEER_DEG, MAX_STEER_DEG)
}

/// Sideways acceleration of the rover going forward at `speed_mps` with `steering_deg`, m/s^2.
pub fn lateral_accel_mps2(steering_deg: f64, speed_mps: f64) -> f64 {
    speed_mps * speed_mps * wheel_angle_deg(steering_deg, speed_mps).to_radians().tan().abs() / WHEELBASE_M
}

/// The fastest forward speed at which `steering_deg` keeps the sideways acceleration within
/// `accel_mps2`, m/s (the speed cap when even that is within it).
pub fn speed_in_turn_mps(steering_deg: f64, accel_mps2: f64) -> f64 {
    if lateral_accel_mps2(steering_deg, MAX_FORWARD_MPS) <= accel_mps2 {
        return MAX_FORWARD_MPS;
    }
    let (mut within_mps, mut beyond_mps) = (0.0, MAX_FORWARD_MPS);
    for _ in 0..40 {
        let middle_mps = 0.5 * (within_mps + beyond_mps);
        if lateral_accel_mps2(steering_deg, middle_mps) <= accel_mps2 {
            within_mps = middle_mps;
        } else {
            beyond_mps = middle_mps;
        }
    }
    within_mps
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_wheels_turn_fifteen_degrees_at_standstill_and_five_at_full_speed() {
        assert_eq!(wheel_angle_deg(15.0, 0.0), 15.0);
        assert_eq!(wheel_angle_deg(-15.0, MAX_FORWARD_MPS), -5.0);
        assert!((wheel_angle_deg(15.0, 4.3) - 6.4).abs() < 1e-9, "unity-sim-spec 3.3: 6.4 degrees at 4.3 m/s");
        let wheel_deg = wheel_angle_deg(7.0, 3.0);
        assert!((steering_for_wheel_angle_deg(wheel_deg, 3.0) - 7.0).abs() < 1e-12);
        assert_eq!(steering_for_wheel_angle_deg(20.0, 3.0), MAX_STEER_DEG, "beyond the range: full lock");
    }

    #[test]
    fn the_speed_in_a_turn_keeps_the_sideways_acceleration_at_the_limit() {
        let accel_mps2 = 1.5;
        let full_lock_mps = speed_in_turn_mps(15.0, accel_mps2);
        assert!((lateral_accel_mps2(15.0, full_lock_mps) - accel_mps2).abs() < 1e-6, "{full_lock_mps}");
        assert!(full_lock_mps > 2.0, "faster than the standstill radius allows, the wheels narrow: {full_lock_mps}");
        assert!(speed_in_turn_mps(10.0, accel_mps2) > full_lock_mps);
        assert_eq!(speed_in_turn_mps(0.0, accel_mps2), MAX_FORWARD_MPS);
        assert_eq!(speed_in_turn_mps(1.0, accel_mps2), MAX_FORWARD_MPS);
    }
}
