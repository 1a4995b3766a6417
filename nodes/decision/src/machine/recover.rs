//! The recover mode: when the rover is tilted, stuck or stalled it backs off, stops, turns toward
//! the most open side, and goes back to what it was doing; stuck again and again at one spot, it
//! drives back the way it came in instead.

use rover_msgs::map_grid::cell_centre_m;

use super::{Machine, Next, Observation, State};
use crate::drive::{Drive, STOPPED_MPS};
use crate::params::DecisionParams;
use crate::stuck::{DrivingWatch, ProgressWatch};
use crate::trail::WayBack;

/// Moving less than this while driving counts toward being stuck, metres...
const STUCK_PROGRESS_M: f64 = 0.3;
/// ...when the rover has come to a stop, m/s (a slow approach is not stuck).
const STUCK_SPEED_MPS: f64 = 0.1;
/// Moving less than this, whatever the rover is told, counts toward being stalled, metres.
const STALL_PROGRESS_M: f64 = 1.0;
/// Retracing the way in ends after this long, seconds.
const RETRACE_S: f64 = 20.0;

/// A recovery under way.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Recovery {
    since_frame: u64,
    /// The turn after backing off goes to the left.
    turn_left: bool,
    /// The way back out of a pocket: retraced instead of backing off and turning.
    way_back: Option<WayBack>,
}

/// What tells that the rover is stuck or stalled.
#[derive(Debug, Clone)]
pub(super) struct Watches {
    stuck: DrivingWatch,
    stall: ProgressWatch,
    /// The drive command of the frame before.
    pub(super) last_drive: Drive,
}

impl Default for Watches {
    fn default() -> Self {
        Watches { stuck: DrivingWatch::default(), stall: ProgressWatch::default(), last_drive: Drive::stop(0.0) }
    }
}

impl Watches {
    /// Starts watching afresh (a new mode).
    pub(super) fn reset(&mut self) {
        self.stuck.reset();
        self.stall.reset();
    }

    /// Whether the rover, told to drive, has stopped at a spot where it was told to drive for a
    /// while without getting anywhere (turns in place in between included).
    pub(super) fn stuck(&mut self, obs: &Observation, params: &DecisionParams) -> bool {
        let driving = self.last_drive.drives();
        let frames = self.stuck.driving_frames_within(&obs.position, obs.frame, STUCK_PROGRESS_M, driving);
        driving && frames >= params.frames(params.stuck_s) && obs.speed_mps.abs() < STUCK_SPEED_MPS
    }

    /// Whether the rover has stayed in one spot for long, turning or not (a goal that the camera
    /// and the map disagree about can keep it turning back and forth).
    fn stalled(&mut self, obs: &Observation, params: &DecisionParams) -> bool {
        self.stall.frames_within(&obs.position, obs.frame, STALL_PROGRESS_M) >= params.frames(params.stall_s)
    }
}

/// Whether the body pitches or rolls beyond `tilt_limit_deg`.
fn tilted(obs: &Observation, params: &DecisionParams) -> bool {
    let limit = params.tilt_limit_deg.to_radians();
    obs.pitch_rad.abs() > limit || obs.roll_rad.abs() > limit
}

impl Machine {
    /// Starts a recovery when the rover is tilted, stuck or stalled; stuck and stalled mark the
    /// cell ahead for planning.
    pub(super) fn check_for_trouble(&mut self, obs: &Observation) {
        if let Some(trouble) = self.trouble(obs) {
            if trouble != "tilted" {
                self.mark_stuck_cell(obs);
            }
            self.start_recovery(obs, trouble);
        }
    }

    /// What is wrong, if the rover is tilted, stuck or stalled.
    pub(super) fn trouble(&mut self, obs: &Observation) -> Option<&'static str> {
        if tilted(obs, &self.params) {
            Some("tilted")
        } else if self.driving.watches.stuck(obs, &self.params) {
            Some("stuck")
        } else if self.driving.watches.stalled(obs, &self.params) {
            Some("no progress")
        } else {
            None
        }
    }

    /// Makes a cell at the stuck rover's front, or the next one of its plan, an obstacle for
    /// planning for a while, so that the next plan leads around what the map did not show.
    pub(super) fn mark_stuck_cell(&mut self, obs: &Observation) {
        let path = self.path().to_vec();
        if let Some(cell) = self.maps.mark_stuck((&obs.position, obs.frame), &path, &self.params) {
            tracing::debug!(
                cell = ?cell_centre_m(cell),
                "stuck: a cell at the front or on the plan is an obstacle for a while"
            );
        }
    }

    /// Enters recover for `reason`: a failed approach or a recovery of the exploration is noted.
    pub(super) fn start_recovery(&mut self, obs: &Observation, reason: &str) {
        match &self.state {
            State::Explore => self.explorer.note_recovery(),
            State::Approach(chase) => self.note_failed_approach(chase.at, obs),
            _ => {}
        }
        let recovery = self.begin_recovery(obs);
        let then_home = matches!(self.state, State::ReturnHome(_));
        self.enter(State::Recover { recovery, then_home }, reason);
    }

    /// A recovery from here: back off and turn toward the most open side, or, stuck at this spot
    /// again and again, drive back along the trail (see [`crate::trail::Trail::note_recovery`]).
    pub(super) fn begin_recovery(&mut self, obs: &Observation) -> Recovery {
        let at = (obs.position.x_m, obs.position.y_m);
        let way_back = self.driving.trail.note_recovery(at);
        let recovery = Recovery { since_frame: obs.frame, turn_left: obs.free.most_open() >= 0.0, way_back };
        tracing::debug!(
            at = ?at,
            yaw_deg = obs.position.yaw_rad.to_degrees(),
            pitch_deg = obs.pitch_rad.to_degrees(),
            roll_deg = obs.roll_rad.to_degrees(),
            turn_left = recovery.turn_left,
            retrace_to = ?recovery.way_back.as_ref().and_then(WayBack::end),
            "recovering"
        );
        recovery
    }

    /// Recovers; then back to exploring or on the way home.
    pub(super) fn recover(&mut self, obs: &Observation, mut recovery: Recovery, then_home: bool) -> Next {
        match self.recovery_drive(obs, &mut recovery) {
            Some(drive) => Next::Stay(State::Recover { recovery, then_home }, drive),
            None => Next::Enter(if then_home { State::ReturnHome(None) } else { State::Explore }, "recovered"),
        }
    }

    /// The drive of `recovery`: back off, stop, turn, or retrace the way in; `None` once over.
    pub(super) fn recovery_drive(&mut self, obs: &Observation, recovery: &mut Recovery) -> Option<Drive> {
        let p = &self.params;
        let elapsed = obs.frame.saturating_sub(recovery.since_frame);
        if let Some(way_back) = recovery.way_back.as_mut() {
            return (elapsed < p.frames(RETRACE_S)).then(|| self.retrace(obs, way_back)).flatten();
        }
        let back = p.frames(p.recover_back_s);
        if elapsed < back {
            return Some(Drive { throttle: -p.recover_throttle, brake: 0.0, steering_deg: 0.0 });
        }
        if elapsed < back + p.frames(p.recover_turn_s) {
            // Backing up ends in a full stop before the turn.
            return Some(if obs.speed_mps.abs() > STOPPED_MPS {
                Drive::stop(p.brake)
            } else {
                Drive::turn_in_place(recovery.turn_left)
            });
        }
        None
    }

    /// Drives along `way_back` at the approach speed; `None` once at its end.
    fn retrace(&mut self, obs: &Observation, way_back: &mut WayBack) -> Option<Drive> {
        let point = way_back.next_point((obs.position.x_m, obs.position.y_m))?;
        let (p, distance_m) = (&self.params, obs.position.distance_to(point));
        let bearing = obs.position.bearing_to(point);
        Some(self.driving.steering.toward_point(bearing, distance_m, p.approach_speed_mps, obs.speed_mps, p))
    }
}
