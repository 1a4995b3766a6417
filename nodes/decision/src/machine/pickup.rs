//! The pickup mode: stopped next to a sample while the pickup node asks for the pickup and the arm
//! works; back to exploring once the arm is done, the sample is out of reach or no pickup came.

use rover_msgs::body::ARM_REACH_M;

use super::{Machine, Next, Observation, State};
use crate::drive::{Drive, STOPPED_MPS};

impl Machine {
    /// Steps the pickup begun at `since_frame` (`arm_seen`: the arm has been seen busy): stopped
    /// until the arm is done, the sample is out of reach or no pickup came.
    pub(super) fn pickup(&mut self, obs: &Observation, since_frame: u64, arm_seen: bool) -> Next {
        let p = &self.params;
        let no_pickup_came = obs.frame.saturating_sub(since_frame) >= p.frames(p.pickup_wait_s);
        let stay = Next::Stay(State::Pickup { since_frame, arm_seen: obs.picking_up }, Drive::stop(p.brake));
        if obs.picking_up {
            stay
        } else if arm_seen {
            self.samples.ignore(obs.position.point_at(0.0, ARM_REACH_M));
            Next::Enter(State::Explore, "sample collected")
        } else if !obs.near_sample && obs.speed_mps.abs() < STOPPED_MPS {
            Next::Enter(State::Explore, "sample out of reach")
        } else if no_pickup_came {
            self.samples.ignore(obs.position.point_at(0.0, ARM_REACH_M));
            Next::Enter(State::Explore, "no pickup came")
        } else {
            stay
        }
    }
}
