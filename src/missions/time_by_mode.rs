//! Where a mission's time goes: every frame is counted once, to what the rover was doing then:
//! picking up, turning in place or standing still, and otherwise the decision's mode (explore,
//! approach_sample, recover, return_home). The counts add up to the mission's time.

use std::collections::BTreeMap;

use rover_decision::machine::Mode;
use rover_msgs::msg::Telemetry;
use serde::Serialize;

/// Below this speed the rover counts as standing, m/s.
const STANDING_MPS: f64 = 0.05;

/// The activities a frame is counted to, besides the decision's modes: picking up, the decision's
/// own pickup mode.
pub const PICKUP: &str = Mode::Pickup.name();
/// Turning on the spot: standing, steering, neither throttle nor brake.
pub const TURNING_IN_PLACE: &str = "turning_in_place";
/// Standing still for any other reason.
pub const STOPPED: &str = "stopped";

/// What the rover in decision mode `mode` did in a frame where its telemetry read `speed_mps`,
/// `steering_deg`, `throttle` and `brake`.
pub fn activity(mode: &str, speed_mps: f64, steering_deg: f64, throttle: f64, brake: f64) -> &str {
    let standing = speed_mps.abs() < STANDING_MPS;
    if mode == PICKUP {
        PICKUP
    } else if standing && steering_deg != 0.0 && throttle == 0.0 && brake == 0.0 {
        TURNING_IN_PLACE
    } else if standing {
        STOPPED
    } else {
        mode
    }
}

/// What the rover in decision mode `mode` did in the frame of `telemetry` (see [`activity`]).
pub fn activity_of<'a>(mode: &'a str, telemetry: &Telemetry) -> &'a str {
    let (speed, steering) = (telemetry.speed_mps as f64, telemetry.steering_angle_deg as f64);
    activity(mode, speed, steering, telemetry.throttle as f64, telemetry.brake as f64)
}

/// Simulated seconds by activity.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
#[serde(transparent)]
pub struct TimeByMode(BTreeMap<String, f64>);

impl TimeByMode {
    /// Counts `seconds` to `activity`.
    pub fn add(&mut self, activity: &str, seconds: f64) {
        *self.0.entry(activity.to_string()).or_default() += seconds;
    }

    /// Seconds counted to `activity`.
    pub fn seconds(&self, activity: &str) -> f64 {
        self.0.get(activity).copied().unwrap_or(0.0)
    }
}

/// Counts a mission's frames by telemetry: each frame's time goes to the activity of the frame
/// before it (what the rover did until this one), so frames that were not seen still count.
#[derive(Debug, Clone, Default)]
pub struct ModeClock {
    last: Option<(u64, String)>,
    times: TimeByMode,
}

impl ModeClock {
    /// Notes frame `frame` (frames `step_s` seconds apart), in which the rover did `activity`.
    pub fn on_frame(&mut self, frame: u64, activity: &str, step_s: f64) {
        if let Some((last_frame, last_activity)) = &self.last
            && frame > *last_frame
        {
            self.times.add(last_activity, (frame - last_frame) as f64 * step_s);
        }
        if self.last.as_ref().is_none_or(|(last_frame, _)| frame >= *last_frame) {
            self.last = Some((frame, activity.to_string()));
        }
    }

    /// The seconds counted so far.
    pub fn times(&self) -> &TimeByMode {
        &self.times
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_is_counted_to_pickup_turning_standing_or_else_the_mode() {
        assert_eq!(activity("pickup", 0.0, 0.0, 0.0, 0.0), PICKUP);
        assert_eq!(activity("explore", 0.0, -15.0, 0.0, 0.0), TURNING_IN_PLACE);
        assert_eq!(activity("explore", 0.01, 0.0, 0.0, 10.0), STOPPED);
        assert_eq!(activity("explore", 0.0, -15.0, 0.0, 10.0), STOPPED, "braking with the wheels turned");
        assert_eq!(activity("return_home", 1.2, -15.0, 0.3, 0.0), "return_home");
        assert_eq!(activity("recover", -0.8, 0.0, -0.5, 0.0), "recover");
    }

    #[test]
    fn the_clock_counts_each_frame_once_to_what_came_before_it() {
        let mut clock = ModeClock::default();
        clock.on_frame(1, "explore", 0.04);
        clock.on_frame(2, "explore", 0.04);
        clock.on_frame(5, STOPPED, 0.04);
        clock.on_frame(5, STOPPED, 0.04);
        clock.on_frame(4, "explore", 0.04);
        clock.on_frame(6, "explore", 0.04);
        let times = clock.times();
        assert!((times.seconds("explore") - 0.16).abs() < 1e-9, "frames 1-5: {times:?}");
        assert!((times.seconds(STOPPED) - 0.04).abs() < 1e-9);
        assert_eq!(times.seconds("recover"), 0.0);
        assert_eq!(serde_json::to_value(times).unwrap()["stopped"], 0.04);
    }
}
