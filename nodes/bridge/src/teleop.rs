//! Teleoperation: a `cmd_vel` twist turned into the simulator's throttle, brake and steering.

use rover_msgs::body::{MAX_STEER_DEG, TURN_IN_PLACE_DPS, WHEELBASE_M, steering_for_wheel_angle_deg};
use rover_msgs::geometry_msgs::Twist;
use rover_msgs::validate::Validate as _;

use crate::reply::DriveValues;

/// Below this speed the rover turns in place rather than steering.
const TURN_IN_PLACE_BELOW_MPS: f64 = 0.3;

/// Gains of the teleoperation speed controller.
#[derive(Debug, Clone, Copy)]
pub(crate) struct TeleopGains {
    /// Throttle per m/s of speed error.
    pub throttle_per_mps: f64,
    /// Brake applied when asked to stop while moving.
    pub brake: f64,
}

/// Converts a twist (linear.x m/s, angular.z rad/s, REP-103) into drive values at the current
/// speed. A twist with a NaN or infinite component, or one whose values overflow, brakes with
/// `gains.brake`.
pub(crate) fn twist_to_drive(twist: &Twist, speed_mps: f64, gains: TeleopGains) -> DriveValues {
    let braking = DriveValues::brake(gains.brake as f32);
    if twist.validate().is_err() {
        return braking;
    }
    let (throttle, brake, steering_deg) = drive_controls(twist, speed_mps, gains);
    DriveValues::checked(throttle as f32, brake as f32, steering_deg as f32).unwrap_or(braking)
}

/// Throttle, brake and steering (degrees) that follow a finite twist.
fn drive_controls(twist: &Twist, speed_mps: f64, gains: TeleopGains) -> (f64, f64, f64) {
    let target_mps = twist.linear.x;
    let yaw_rate_dps = twist.angular.z.to_degrees();
    let stopping = target_mps.abs() < 0.05;
    if stopping && speed_mps.abs() < TURN_IN_PLACE_BELOW_MPS {
        return (0.0, 0.0, (yaw_rate_dps / TURN_IN_PLACE_DPS) * MAX_STEER_DEG);
    }
    if stopping {
        return (0.0, gains.brake, 0.0);
    }
    let throttle = gains.throttle_per_mps * (target_mps - speed_mps);
    let wheel_deg = (twist.angular.z * WHEELBASE_M / target_mps.abs().max(0.1)).atan().to_degrees();
    (throttle, 0.0, steering_for_wheel_angle_deg(wheel_deg, speed_mps))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rover_msgs::geometry_msgs::Vector3;

    const GAINS: TeleopGains = TeleopGains { throttle_per_mps: 0.5, brake: 10.0 };

    fn twist(linear: f64, angular: f64) -> Twist {
        Twist {
            linear: Vector3 { x: linear, ..Default::default() },
            angular: Vector3 { z: angular, ..Default::default() },
        }
    }

    #[test]
    fn forward_left_turn() {
        let drive = twist_to_drive(&twist(2.0, 0.5), 1.0, GAINS);
        assert!((drive.throttle - 0.5).abs() < 1e-6);
        assert!(drive.steering_deg > 0.0 && drive.steering_deg <= 15.0);
        assert_eq!(drive.brake, 0.0);
    }

    #[test]
    fn stop_brakes_then_turns_in_place() {
        assert_eq!(twist_to_drive(&twist(0.0, 0.0), 2.0, GAINS), DriveValues::brake(10.0));
        let spin = twist_to_drive(&twist(0.0, -std::f64::consts::FRAC_PI_4), 0.0, GAINS);
        assert!((spin.steering_deg + 15.0).abs() < 1e-4, "{spin:?}");
        assert_eq!(spin.throttle, 0.0);
    }

    #[test]
    fn nan_or_infinite_twists_brake_whether_moving_or_standing() {
        for (linear, angular) in [(f64::NAN, 0.0), (0.0, f64::NAN), (f64::INFINITY, 0.0), (0.0, f64::NEG_INFINITY)] {
            for speed_mps in [0.0, 2.0] {
                let drive = twist_to_drive(&twist(linear, angular), speed_mps, GAINS);
                assert_eq!(drive, DriveValues::brake(10.0), "twist ({linear}, {angular}) at {speed_mps} m/s");
            }
        }
    }

    #[test]
    fn the_twists_yaw_rate_is_driven_at_speed_where_the_wheels_turn_less() {
        let (speed_mps, yaw_rate_rps) = (3.0, 0.3);
        let drive = twist_to_drive(&twist(speed_mps, yaw_rate_rps), speed_mps, GAINS);
        let wheel_deg = rover_msgs::body::wheel_angle_deg(drive.steering_deg as f64, speed_mps);
        let driven_rps = speed_mps * wheel_deg.to_radians().tan() / WHEELBASE_M;
        assert!((driven_rps - yaw_rate_rps).abs() < 1e-3, "{driven_rps} rad/s from {drive:?}");
    }

    #[test]
    fn a_twist_that_overflows_the_throttle_brakes() {
        assert_eq!(twist_to_drive(&twist(f64::MAX, 0.0), 2.0, GAINS), DriveValues::brake(10.0));
    }
}
