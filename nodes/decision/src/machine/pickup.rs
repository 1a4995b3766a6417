//! The pickup mode: stopped next to a sample while the pickup node asks for the pickup and the arm
//! works; back to exploring once the arm is done, the sample is out of reach or no pickup came.

use rover_msgs::body::ARM_REACH_M;

use super::{Machine, Observation, State};
use crate::drive::{Drive, STOPPED_MPS};

impl Machine {
    /// Steps the pickup begun at `since_frame` (`arm_seen`: the arm has been seen busy): stopped
    /// until the arm is done, the sample is out of reach or no pickup came.
    pub(super) fn pickup(&mut self, obs: &Observation, since_frame: u64, arm_seen: bool) -> Drive {
        let p = &self.params;
        let (brake, waited) = (p.brake, obs.frame.saturating_sub(since_frame));
        let no_pickup_came = waited >= p.frames(p.pickup_wait_s);
        if obs.picking_up {
            self.state = State::Pickup { since_frame, arm_seen: true };
        } else if arm_seen {
            self.samples.ignore(obs.position.point_at(0.0, ARM_REACH_M));
            self.enter(State::Explore, "sample collected");
        } else if !obs.near_sample && obs.speed_mps.abs() < STOPPED_MPS {
            self.enter(State::Explore, "sample out of reach");
        } else if no_pickup_came {
            self.samples.ignore(obs.position.point_at(0.0, ARM_REACH_M));
            self.enter(State::Explore, "no pickup came");
        }
        Drive::stop(brake)
    }
}
