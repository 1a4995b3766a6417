//! What the bridge answers to each telemetry frame: exactly one `data`, `pickup` or `manual` event.

use std::time::{Duration, Instant};

use rover_msgs::body::MAX_STEER_DEG;
use serde::Serialize;

/// The three values of a `data` command.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriveValues {
    /// Throttle, -1..1.
    pub throttle: f32,
    /// Brake, >= 0.
    pub brake: f32,
    /// Steering, degrees, positive left, within +-15.
    pub steering_deg: f32,
}

impl DriveValues {
    /// A command that holds the rover still.
    pub fn brake(brake: f32) -> Self {
        DriveValues { throttle: 0.0, brake, steering_deg: 0.0 }
    }

    /// Checks a command from a node: rejects NaN and infinities, clamps to the simulator's ranges.
    pub fn checked(throttle: f32, brake: f32, steering_deg: f32) -> Result<Self, String> {
        if !(throttle.is_finite() && brake.is_finite() && steering_deg.is_finite()) {
            return Err(format!(
                "drive command has a non-finite value (throttle {throttle}, brake {brake}, steering {steering_deg})"
            ));
        }
        Ok(DriveValues {
            throttle: throttle.clamp(-1.0, 1.0),
            brake: brake.max(0.0),
            steering_deg: steering_deg.clamp(-MAX_STEER_DEG as f32, MAX_STEER_DEG as f32),
        })
    }
}

/// Where the values of a `data` reply came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CommandSource {
    /// The drive command for this very frame.
    Fresh,
    /// The last drive command, because none arrived for this frame within the deadline.
    Held,
    /// A brake, because no drive command arrived for longer than the silence limit.
    SilenceBrake,
    /// Teleoperation from `cmd_vel`.
    Teleop,
    /// A brake, because the telemetry frame was rejected.
    RejectedFrame,
    /// A brake, because the bridge is not active (lifecycle).
    Inactive,
}

/// The event to send back for one telemetry frame.
#[derive(Debug, Clone, PartialEq)]
pub enum Reply {
    /// `data` with drive values.
    Data(DriveValues, CommandSource),
    /// `pickup`.
    Pickup,
    /// `manual` (the answer to empty telemetry).
    Manual,
}

/// Timing rules for replies.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ReplyPolicy {
    /// How long to wait for the drive command of a frame.
    pub deadline: Duration,
    /// After this long without any drive command, brake.
    pub silence_limit: Duration,
    /// Brake value used when braking on silence or rejected frames.
    pub brake: f32,
}

/// The last drive command received and when.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LastCommand {
    /// Its values.
    pub values: DriveValues,
    /// When it arrived.
    pub received_at: Instant,
}

impl ReplyPolicy {
    /// Chooses the `data` values for a frame: the fresh command if one came, else the last one while
    /// it is younger than the silence limit, else a brake.
    pub(crate) fn drive_reply(&self, fresh: Option<DriveValues>, last: Option<LastCommand>, now: Instant) -> Reply {
        match (fresh, last) {
            (Some(values), _) => Reply::Data(values, CommandSource::Fresh),
            (None, Some(last)) if now.duration_since(last.received_at) < self.silence_limit => {
                Reply::Data(last.values, CommandSource::Held)
            }
            _ => Reply::Data(DriveValues::brake(self.brake), CommandSource::SilenceBrake),
        }
    }
}

/// The JSON object of a `data` event: every value a string, as the simulator requires.
#[derive(Debug, Serialize)]
pub(crate) struct DataEvent<'a> {
    /// Throttle as text.
    pub throttle: String,
    /// Brake as text.
    pub brake: String,
    /// Steering angle as text, degrees.
    pub steering_angle: String,
    /// Base64 JPEG of the world map inset, or empty.
    pub inset_image1: &'a str,
    /// Base64 JPEG of the vision inset, or empty.
    pub inset_image2: &'a str,
}

impl<'a> DataEvent<'a> {
    /// Formats `values` as the simulator expects.
    pub(crate) fn new(values: DriveValues, inset_image1: &'a str, inset_image2: &'a str) -> Self {
        DataEvent {
            throttle: values.throttle.to_string(),
            brake: values.brake.to_string(),
            steering_angle: values.steering_deg.to_string(),
            inset_image1,
            inset_image2,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const POLICY: ReplyPolicy =
        ReplyPolicy { deadline: Duration::from_millis(50), silence_limit: Duration::from_secs(1), brake: 10.0 };

    #[test]
    fn fresh_then_held_then_brake() {
        let start = Instant::now();
        let go = DriveValues { throttle: 0.2, brake: 0.0, steering_deg: 3.0 };
        assert_eq!(POLICY.drive_reply(Some(go), None, start), Reply::Data(go, CommandSource::Fresh));
        let last = Some(LastCommand { values: go, received_at: start });
        let soon = start + Duration::from_millis(300);
        assert_eq!(POLICY.drive_reply(None, last, soon), Reply::Data(go, CommandSource::Held));
        let late = start + Duration::from_millis(1500);
        assert_eq!(
            POLICY.drive_reply(None, last, late),
            Reply::Data(DriveValues::brake(10.0), CommandSource::SilenceBrake)
        );
        assert_eq!(
            POLICY.drive_reply(None, None, start),
            Reply::Data(DriveValues::brake(10.0), CommandSource::SilenceBrake)
        );
    }

    #[test]
    fn commands_are_checked_and_clamped() {
        assert!(DriveValues::checked(f32::NAN, 0.0, 0.0).is_err());
        assert!(DriveValues::checked(0.0, f32::INFINITY, 0.0).is_err());
        let clamped = DriveValues::checked(3.0, -1.0, -40.0).unwrap();
        assert_eq!(clamped, DriveValues { throttle: 1.0, brake: 0.0, steering_deg: -15.0 });
    }

    #[test]
    fn data_event_values_are_strings() {
        let event = DataEvent::new(DriveValues { throttle: 0.2, brake: 0.0, steering_deg: -4.5 }, "", "abc");
        let json = serde_json::to_value(&event).unwrap();
        for (key, value) in json.as_object().unwrap() {
            assert!(value.is_string(), "{key} is not a string");
        }
        assert_eq!(json["throttle"], "0.2");
        assert_eq!(json["steering_angle"], "-4.5");
        assert_eq!(json["inset_image2"], "abc");
    }
}
