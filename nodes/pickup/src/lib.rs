//! The pickup logic: when a sample is within reach, the rover has stopped and the arm is idle, ask
//! for one pickup; follow the arm to the end; count the samples collected.
//!
//! Plain types and no DDS here; [`node`] wires it to the topics.

pub mod node;

use rover_msgs::frames::MissionFrames;
use rover_msgs::msg::Telemetry;
use rover_msgs::tally::SampleTally;
use rover_runtime::{Rejections, topics};

rover_runtime::node_params! {
    /// Parameters of the pickup node.
    pub struct PickupParams {
        /// The rover counts as stopped below this speed, m/s.
        stopped_mps: f64 [0.0, 1.0] = 0.05,
        /// Ask again when the arm has not started this long after a request, seconds.
        retry_s: f64 [0.1, 100.0] = 2.0,
        /// Simulated time per frame, seconds.
        frame_period_s: f64 [0.001, 1.0] = rover_msgs::unity::FRAME_PERIOD_S,
    }
}

/// What the pickup logic needs from one telemetry frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmInput {
    /// Lock-step frame number.
    pub frame: u64,
    /// Forward speed, m/s.
    pub speed_mps: f64,
    /// A sample is within reach of the arm.
    pub near_sample: bool,
    /// The arm is busy.
    pub picking_up: bool,
    /// Samples still on the ground.
    pub samples_remaining: u8,
}

/// What the pickup logic needs from one telemetry message, if the message passes its checks (a
/// NaN speed would never count as stopped); one that does not is counted and logged in
/// `rejections`.
pub fn checked_arm_input(telemetry: &Telemetry, rejections: &mut Rejections) -> Option<ArmInput> {
    rejections.accept(topics::TELEMETRY.name, telemetry).then_some(ArmInput {
        frame: telemetry.frame,
        speed_mps: telemetry.speed_mps as f64,
        near_sample: telemetry.near_sample,
        picking_up: telemetry.picking_up,
        samples_remaining: telemetry.samples_remaining,
    })
}

/// The pickup state: the last request, the arm, the count.
#[derive(Debug, Clone, Default)]
pub struct Pickup {
    mission_frames: MissionFrames,
    requested_frame: Option<u64>,
    tally: SampleTally,
    /// Pickup requests sent.
    pub requests: u64,
}

impl Pickup {
    /// Follows one telemetry frame; returns `true` when a pickup request should be sent for it.
    pub fn on_telemetry(&mut self, input: &ArmInput, params: &PickupParams) -> bool {
        if self.tally.update(input.samples_remaining) > 0 {
            tracing::info!("sample collected: {} so far, {} left", self.tally.collected(), input.samples_remaining);
        }
        if input.picking_up {
            self.requested_frame = None;
            return false;
        }
        let frame = self.mission_frames.of(input.frame);
        let retry_frames = (params.retry_s / params.frame_period_s).ceil() as u64;
        let waiting = self.requested_frame.is_some_and(|requested| frame < requested + retry_frames);
        let ready = input.near_sample && input.speed_mps.abs() <= params.stopped_mps && input.samples_remaining > 0;
        if ready && !waiting {
            self.requested_frame = Some(frame);
            self.requests += 1;
            return true;
        }
        false
    }

    /// Samples collected since the node started.
    pub fn collected(&self) -> u32 {
        self.tally.collected()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn input(frame: u64, speed_mps: f64, near_sample: bool, picking_up: bool, samples_remaining: u8) -> ArmInput {
        ArmInput { frame, speed_mps, near_sample, picking_up, samples_remaining }
    }

    #[test]
    fn one_request_when_stopped_next_to_a_sample_then_counts_it() {
        let params = PickupParams::default();
        let mut pickup = Pickup::default();
        assert!(!pickup.on_telemetry(&input(1, 0.5, true, false, 6), &params), "still moving");
        assert!(pickup.on_telemetry(&input(2, 0.0, true, false, 6), &params));
        assert!(!pickup.on_telemetry(&input(3, 0.0, true, false, 6), &params), "one request, not one per frame");
        assert!(!pickup.on_telemetry(&input(4, 0.0, true, true, 6), &params));
        for frame in 5..255 {
            assert!(!pickup.on_telemetry(&input(frame, 0.0, true, true, 6), &params), "never while the arm works");
        }
        assert!(!pickup.on_telemetry(&input(255, 0.0, false, false, 5), &params));
        assert_eq!((pickup.collected(), pickup.requests), (1, 1));
    }

    #[test]
    fn never_without_a_sample_in_reach_and_retries_an_ignored_request() {
        let params = PickupParams::default();
        let mut pickup = Pickup::default();
        for frame in 0..100 {
            assert!(!pickup.on_telemetry(&input(frame, 0.0, false, false, 6), &params));
        }
        assert!(pickup.on_telemetry(&input(100, 0.0, true, false, 6), &params));
        assert!(!pickup.on_telemetry(&input(149, 0.0, true, false, 6), &params));
        assert!(pickup.on_telemetry(&input(150, 0.0, true, false, 6), &params), "asks again after retry_s");
        assert!(!pickup.on_telemetry(&input(400, 0.0, true, false, 0), &params), "nothing left to pick up");
    }

    #[test]
    fn telemetry_with_a_nan_speed_gives_no_input_and_is_counted() {
        let mut rejections = Rejections::default();
        let stopped = Telemetry { frame: 7, near_sample: true, samples_remaining: 6, ..Telemetry::default() };
        assert_eq!(checked_arm_input(&stopped, &mut rejections), Some(input(7, 0.0, true, false, 6)));
        let nan = Telemetry { speed_mps: f32::NAN, ..stopped };
        assert_eq!(checked_arm_input(&nan, &mut rejections), None);
        assert_eq!(rejections.count(topics::TELEMETRY.name), 1);
    }

    #[test]
    fn a_new_bridge_numbering_frames_from_one_does_not_block_the_retry() {
        let params = PickupParams::default();
        let mut pickup = Pickup::default();
        assert!(pickup.on_telemetry(&input(5000, 0.0, true, false, 6), &params));
        assert!(!pickup.on_telemetry(&input(1, 0.0, true, false, 6), &params), "the new bridge's first frame");
        assert!(!pickup.on_telemetry(&input(48, 0.0, true, false, 6), &params));
        assert!(
            pickup.on_telemetry(&input(50, 0.0, true, false, 6), &params),
            "asks again after retry_s, not at frame 5050"
        );
    }
}
