//! Low-level driving: a speed controller, steering toward a bearing, turning in place with
//! hysteresis, and steering around what the camera sees.

use rover_msgs::body::{MAX_STEER_DEG, WHEELBASE_M, speed_in_turn_mps};

use crate::local::FreeSpace;
use crate::params::DecisionParams;
/// Below this speed the rover counts as stopped, m/s.
pub(crate) const STOPPED_MPS: f64 = 0.05;
/// Below this speed a turn in place toward a new bearing may start, m/s (the rest of the speed is
/// braked off by the turn).
const TURN_IN_PLACE_BELOW_MPS: f64 = 0.2;
/// Throttle that holds 1 m/s against rolling resistance.
const THROTTLE_PER_MPS: f64 = 0.15;
/// Speed kept when free ground ahead runs short, m/s.
const MIN_CRUISE_MPS: f64 = 0.6;
/// A turn in place changes side when the goal moves to the other side within this bearing,
/// degrees; beyond it the bearing may just have wrapped past 180 degrees while turning.
const SIDE_SWITCH_DEG: f64 = 135.0;
/// With nothing free in view, the rover still creeps along the map's bearing when it is within
/// this multiple of `turn_done_deg` (narrow canyons look blocked to the camera).
const CREEP_BEARING_FACTOR: f64 = 2.0;

/// One drive command.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Drive {
    /// Throttle, -1..1 (negative reverses).
    pub throttle: f64,
    /// Brake, 0 or more.
    pub brake: f64,
    /// Steering angle, degrees, positive left.
    pub steering_deg: f64,
}

impl Drive {
    /// Braking to a standstill.
    pub fn stop(brake: f64) -> Self {
        Drive { throttle: 0.0, brake, steering_deg: 0.0 }
    }

    /// Turning in place, left (counter-clockwise) or right.
    pub fn turn_in_place(left: bool) -> Self {
        Drive { throttle: 0.0, brake: 0.0, steering_deg: if left { MAX_STEER_DEG } else { -MAX_STEER_DEG } }
    }

    /// Whether this command asks the rover to roll forward or back (not turning in place, not braking).
    pub fn drives(&self) -> bool {
        self.throttle.abs() > 0.05 && self.brake == 0.0
    }
}

/// Steering with memory: once the rover turns in place it keeps turning until it faces the goal.
#[derive(Debug, Clone, Default)]
pub(crate) struct Steering {
    turning: Option<bool>,
}

impl Steering {
    /// Forgets a turn in progress.
    pub(crate) fn reset(&mut self) {
        self.turning = None;
    }

    /// Starts a turn in place toward `bearing_deg` (after braking from `speed_mps`), for `why`;
    /// logged, as these turns and the braking and speeding up around them cost much of a mission.
    /// None starts for a goal within `turn_done_deg`: that turn would be over at once.
    fn start_turn(&mut self, bearing_deg: f64, speed_mps: f64, why: &str, params: &DecisionParams) {
        if bearing_deg.abs() <= params.turn_done_deg {
            return;
        }
        tracing::debug!(bearing_deg = bearing_deg.round(), speed_mps, why, "turn in place");
        self.turning = Some(bearing_deg > 0.0);
    }

    /// Drives toward `bearing_rad` (relative to the heading, positive left) at up to `target_mps`
    /// (`speed_mps` is the rover's speed now), turning in place when the bearing is large. A turn
    /// keeps its side while the goal stays on that side (or behind), and changes side when a new
    /// goal lies on the other.
    pub(crate) fn toward(
        &mut self,
        bearing_rad: f64,
        target_mps: f64,
        speed_mps: f64,
        params: &DecisionParams,
    ) -> Drive {
        let bearing_deg = bearing_rad.to_degrees();
        let goal_switched_side =
            self.turning.is_some_and(|left| left != (bearing_deg > 0.0) && bearing_deg.abs() < SIDE_SWITCH_DEG);
        if goal_switched_side {
            self.start_turn(bearing_deg, speed_mps, "the goal moved to the other side", params);
        } else if self.turning.is_none() && bearing_deg.abs() > params.turn_in_place_deg {
            self.start_turn(bearing_deg, speed_mps, "the goal is far off the heading", params);
        }
        if let Some(left) = self.turning {
            if bearing_deg.abs() > params.turn_done_deg {
                return stop_then_turn(left, speed_mps, params);
            }
            self.turning = None;
        }
        let steering_deg = (params.steer_gain * bearing_deg).clamp(-MAX_STEER_DEG, MAX_STEER_DEG);
        let target_mps = target_mps.min(speed_in_turn(steering_deg, params));
        Drive { steering_deg, ..hold_speed(target_mps, speed_mps, params) }
    }

    /// Drives to a point `distance_m` away at `bearing_rad` as [`Steering::toward`] does, but first
    /// turns in place when the point lies inside the rover's tightest turn (it would circle it).
    pub(crate) fn toward_point(
        &mut self,
        bearing_rad: f64,
        distance_m: f64,
        target_mps: f64,
        speed_mps: f64,
        params: &DecisionParams,
    ) -> Drive {
        if self.turning.is_none() && !on_reachable_arc(bearing_rad, distance_m) {
            let why = "the point lies inside the tightest turn";
            self.start_turn(bearing_rad.to_degrees(), speed_mps, why, params);
        }
        self.toward(bearing_rad, target_mps, speed_mps, params)
    }

    /// Drives toward `bearing_rad` along the nearest direction with free ground ahead, slowing when
    /// little is free. When nothing ahead is free it creeps at the approach speed if it roughly
    /// faces the bearing (the map says the way is open; getting stuck ends that), and otherwise
    /// stops and turns in place toward the bearing.
    pub(crate) fn around_obstacles(
        &mut self,
        bearing_rad: f64,
        cruise_mps: f64,
        speed_mps: f64,
        free: &FreeSpace,
        params: &DecisionParams,
    ) -> Drive {
        let beyond_turn_in_place = bearing_rad.to_degrees().abs() > params.turn_in_place_deg;
        if self.turning.is_none()
            && beyond_turn_in_place
            && let Some(drive) = arc_turn(bearing_rad, speed_mps, free, params)
        {
            return drive;
        }
        if self.turning.is_some() || beyond_turn_in_place {
            return self.toward(bearing_rad, cruise_mps, speed_mps, params);
        }
        match free.best_toward(bearing_rad as f32, params.clearance_m as f32) {
            Some(direction) => {
                let room_m = free.longest_within(direction, ROOM_HALF_ANGLE_DEG.to_radians());
                let stoppable_mps = speed_to_stop_within(room_m as f64, params);
                let target_mps = stoppable_mps.clamp(MIN_CRUISE_MPS.min(cruise_mps), cruise_mps);
                self.toward(direction as f64, target_mps, speed_mps, params)
            }
            None if bearing_rad.to_degrees().abs() <= CREEP_BEARING_FACTOR * params.turn_done_deg => {
                self.toward(bearing_rad, params.approach_speed_mps, speed_mps, params)
            }
            None => stop_then_turn(bearing_rad > 0.0, speed_mps, params),
        }
    }
}

/// Ahead of obstacles the speed counts the free ground within this angle either side of the
/// chosen direction, degrees: under way the rover steers that far within a few metres, so a wall
/// straight ahead where the way bends calls for no stop.
const ROOM_HALF_ANGLE_DEG: f32 = 15.0;

/// A turn in place to the left (or right), once the rover has all but stopped: braking until then.
fn stop_then_turn(left: bool, speed_mps: f64, params: &DecisionParams) -> Drive {
    if speed_mps.abs() > TURN_IN_PLACE_BELOW_MPS { Drive::stop(params.brake) } else { Drive::turn_in_place(left) }
}

/// The speed from which braking at `stop_decel_mps2` stops the rover within `distance_m`, m/s.
pub(crate) fn speed_to_stop_in(distance_m: f64, params: &DecisionParams) -> f64 {
    (2.0 * params.stop_decel_mps2 * distance_m.max(0.0)).sqrt()
}

/// The speed from which braking at `stop_decel_mps2` stops the rover `clearance_m` short of the
/// end of `free_m` of free ground, m/s.
fn speed_to_stop_within(free_m: f64, params: &DecisionParams) -> f64 {
    speed_to_stop_in(free_m - params.clearance_m, params)
}

/// The speed at which steering by `steering_deg` keeps the sideways acceleration at
/// `turn_accel_mps2`, m/s (the wheels turn less the faster the rover goes).
fn speed_in_turn(steering_deg: f64, params: &DecisionParams) -> f64 {
    speed_in_turn_mps(steering_deg, params.turn_accel_mps2)
}

/// The radius of the circle the rover drives on at walking pace when steering by `steering_deg`,
/// metres (unbounded when steering straight).
fn turn_radius_m(steering_deg: f64) -> f64 {
    WHEELBASE_M / steering_deg.to_radians().tan().abs()
}

/// Whether the rover can reach a point `distance_m` away at `bearing_rad` on an arc no tighter
/// than its full-lock turn: the arc through it, tangent to the heading, has a radius of
/// `distance_m / (2 sin |bearing|)`.
fn on_reachable_arc(bearing_rad: f64, distance_m: f64) -> bool {
    distance_m >= 2.0 * turn_radius_m(MAX_STEER_DEG) * bearing_rad.sin().abs()
}

/// A rover under way turns toward a bearing up to this large on the move, degrees...
const ARC_TURN_MAX_DEG: f64 = 120.0;
/// ...when it moves at least this fast, m/s...
const ARC_TURN_MIN_MPS: f64 = 0.8;
/// ...and this much ground is free on that side, metres...
const ARC_TURN_FREE_M: f32 = 2.5;
/// ...in these directions, degrees (the rays at 45 degrees leave the camera's view and read short).
const ARC_TURN_CHECK_DEG: [f64; 2] = [15.0, 30.0];

/// Turning on the move at full steering and the speed of such a turn, toward a bearing beyond the
/// turn-in-place threshold: cheaper than braking, turning in place and speeding up again, where
/// the ground on that side is free.
fn arc_turn(bearing_rad: f64, speed_mps: f64, free: &FreeSpace, params: &DecisionParams) -> Option<Drive> {
    let side = bearing_rad.signum();
    let side_free =
        ARC_TURN_CHECK_DEG.iter().all(|deg| free.toward((side * deg.to_radians()) as f32) >= ARC_TURN_FREE_M);
    let possible = bearing_rad.to_degrees().abs() <= ARC_TURN_MAX_DEG && speed_mps >= ARC_TURN_MIN_MPS && side_free;
    possible.then(|| {
        let steering_deg = side * MAX_STEER_DEG;
        Drive { steering_deg, ..hold_speed(speed_in_turn(steering_deg, params), speed_mps, params) }
    })
}

/// Throttle or brake that brings `speed_mps` to `target_mps`.
pub(crate) fn hold_speed(target_mps: f64, speed_mps: f64, params: &DecisionParams) -> Drive {
    let error = target_mps - speed_mps;
    if error < -0.5 {
        return Drive { throttle: 0.0, brake: (-error).min(params.brake), steering_deg: 0.0 };
    }
    let throttle = (THROTTLE_PER_MPS * target_mps + params.throttle_gain * error).clamp(0.0, 1.0);
    Drive { throttle, brake: 0.0, steering_deg: 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params() -> DecisionParams {
        DecisionParams::default()
    }

    #[test]
    fn large_bearings_stop_then_turn_in_place_until_facing_the_goal() {
        let p = params();
        let mut steering = Steering::default();
        assert_eq!(steering.toward(90f64.to_radians(), 2.0, 1.5, &p), Drive::stop(p.brake));
        assert_eq!(steering.toward(90f64.to_radians(), 2.0, 0.0, &p), Drive::turn_in_place(true));
        let still_turning = steering.toward(30f64.to_radians(), 2.0, 0.0, &p);
        assert_eq!(still_turning, Drive::turn_in_place(true), "keeps turning below the start threshold");
        let driving = steering.toward(5f64.to_radians(), 2.0, 0.0, &p);
        assert!(driving.throttle > 0.0 && driving.steering_deg > 0.0 && driving.brake == 0.0, "{driving:?}");
    }

    #[test]
    fn a_turn_changes_side_when_the_goal_does_but_not_when_the_bearing_wraps() {
        let p = params();
        let mut steering = Steering::default();
        assert_eq!(steering.toward(170f64.to_radians(), 2.0, 0.0, &p), Drive::turn_in_place(true));
        let wrapped = steering.toward(-178f64.to_radians(), 2.0, 0.0, &p);
        assert_eq!(wrapped, Drive::turn_in_place(true), "the bearing wrapped past 180 degrees: same side");
        let new_goal = steering.toward(-30f64.to_radians(), 2.0, 0.0, &p);
        assert_eq!(new_goal, Drive::turn_in_place(false), "a new goal on the right: turn right");
    }

    #[test]
    fn speed_is_held_with_throttle_and_brake() {
        let p = params();
        assert!(hold_speed(2.0, 0.0, &p).throttle > hold_speed(2.0, 1.9, &p).throttle);
        let braking = hold_speed(0.5, 2.0, &p);
        assert!(braking.throttle == 0.0 && braking.brake > 0.0);
        assert!(!braking.drives() && hold_speed(2.0, 0.0, &p).drives());
    }

    #[test]
    fn blocked_ahead_turns_toward_the_goal_side() {
        let p = params();
        let free = FreeSpace { directions_rad: vec![-0.2, 0.0, 0.2], free_m: vec![0.5, 0.5, 0.5] };
        let beyond_creeping_rad = (CREEP_BEARING_FACTOR * p.turn_done_deg + 5.0).to_radians();
        let mut steering = Steering::default();
        assert_eq!(steering.around_obstacles(-beyond_creeping_rad, 2.0, 0.0, &free, &p), Drive::turn_in_place(false));
        assert_eq!(steering.around_obstacles(beyond_creeping_rad, 2.0, 0.0, &free, &p), Drive::turn_in_place(true));
        let open = FreeSpace { directions_rad: vec![-0.2, 0.0, 0.2], free_m: vec![0.5, 0.5, 6.0] };
        let mut steering = Steering::default();
        let drive = steering.around_obstacles(-0.1, 2.0, 0.0, &open, &p);
        assert!(drive.steering_deg > 0.0, "swerves to the free side: {drive:?}");
    }

    #[test]
    fn turns_are_driven_slower_than_straights() {
        let p = params();
        let cruise = p.max_speed_mps;
        let straight = Steering::default().toward(0.0, cruise, cruise, &p);
        assert!(straight.throttle > 0.0 && straight.brake == 0.0, "{straight:?}");
        let sharp = Steering::default().toward(MAX_STEER_DEG.to_radians(), cruise, cruise, &p);
        assert!(sharp.brake > 0.0, "a full-lock turn at cruising speed brakes: {sharp:?}");
        assert!(speed_in_turn(5.0, &p) > speed_in_turn(15.0, &p));
        let full_lock_mps = speed_in_turn(MAX_STEER_DEG, &p);
        let lateral_mps2 = rover_msgs::body::lateral_accel_mps2(MAX_STEER_DEG, full_lock_mps);
        assert!((lateral_mps2 - p.turn_accel_mps2).abs() < 1e-6, "{lateral_mps2} m/s^2 at {full_lock_mps} m/s");
    }

    #[test]
    fn the_speed_ahead_of_obstacles_leaves_room_to_stop() {
        let p = params();
        let free_m = 4.0;
        let v = speed_to_stop_within(free_m, &p);
        let stopping_m = v * v / (2.0 * p.stop_decel_mps2);
        assert!((stopping_m + p.clearance_m - free_m).abs() < 1e-9, "stops in {stopping_m} m");
        assert_eq!(speed_to_stop_within(p.clearance_m * 0.5, &p), 0.0);
        let lane = |free_m: f32| FreeSpace { directions_rad: vec![-0.2, 0.0, 0.2], free_m: vec![free_m; 3] };
        let open = Steering::default().around_obstacles(0.0, p.max_speed_mps, 3.0, &lane(6.0), &p);
        let short = Steering::default().around_obstacles(0.0, p.max_speed_mps, 3.0, &lane(1.5), &p);
        assert!(open.throttle > 0.0 && short.brake > 0.0, "open {open:?}, short {short:?}");
        let bend = FreeSpace {
            directions_rad: [-20f32, -10.0, 0.0, 10.0, 20.0].map(f32::to_radians).to_vec(),
            free_m: vec![1.5, 1.5, 1.5, 6.0, 6.0],
        };
        let into_bend = Steering::default().around_obstacles(0.0, p.max_speed_mps, 3.0, &bend, &p);
        assert!(into_bend.brake == 0.0, "the way bends left within reach: {into_bend:?}");
        let walled = FreeSpace { free_m: vec![1.5, 1.5, 1.5, 1.5, 6.0], ..bend };
        let at_wall = Steering::default().around_obstacles(0.0, p.max_speed_mps, 3.0, &walled, &p);
        assert!(at_wall.brake > 0.0, "free only 20 degrees off: {at_wall:?}");
    }

    #[test]
    fn a_point_inside_the_tightest_turn_is_turned_to_in_place_first() {
        let p = params();
        let bearing = 40f64.to_radians();
        let near = Steering::default().toward_point(bearing, 2.0, 1.5, 1.5, &p);
        assert_eq!(near, Drive::stop(p.brake), "2 m off at 40 degrees needs a 1.6 m radius: stop, then turn");
        let mut steering = Steering::default();
        assert_eq!(steering.toward_point(bearing, 2.0, 1.5, 0.0, &p), Drive::turn_in_place(true));
        let far = Steering::default().toward_point(bearing, 6.0, 1.5, 1.5, &p);
        assert!(far.steering_deg == MAX_STEER_DEG && far.brake == 0.0, "6 m off it is driven to on an arc: {far:?}");
        assert!(on_reachable_arc(0.0, 0.1) && !on_reachable_arc(1.0, 1.0));
    }

    #[test]
    fn under_way_a_large_bearing_is_turned_on_the_move_where_that_side_is_free() {
        let p = params();
        let fan = |left_m: f32, right_m: f32| FreeSpace {
            directions_rad: [-30f32, -15.0, 0.0, 15.0, 30.0].map(f32::to_radians).to_vec(),
            free_m: vec![right_m, right_m, 6.0, left_m, left_m],
        };
        let left = 80f64.to_radians();
        let arc = Steering::default().around_obstacles(left, p.max_speed_mps, 2.0, &fan(6.0, 0.5), &p);
        assert_eq!(arc.steering_deg, MAX_STEER_DEG, "full left on the move: {arc:?}");
        assert!(arc.brake == 0.0 || arc.brake < p.brake, "slows for the turn, does not stop: {arc:?}");
        let walled = Steering::default().around_obstacles(left, p.max_speed_mps, 2.0, &fan(0.5, 6.0), &p);
        assert_eq!(walled, Drive::stop(p.brake), "the left is blocked: stop and turn in place");
        let slow = Steering::default().around_obstacles(left, p.max_speed_mps, 0.3, &fan(6.0, 6.0), &p);
        assert_eq!(slow, Drive::stop(p.brake), "too slow to arc");
        let behind =
            Steering::default().around_obstacles(-150f64.to_radians(), p.max_speed_mps, 2.0, &fan(6.0, 6.0), &p);
        assert_eq!(behind, Drive::stop(p.brake), "a goal behind is turned to in place");
        let right = Steering::default().around_obstacles(-80f64.to_radians(), p.max_speed_mps, 2.0, &fan(0.5, 6.0), &p);
        assert_eq!(right.steering_deg, -MAX_STEER_DEG, "full right on the move: {right:?}");
    }

    #[test]
    fn blocked_but_facing_the_bearing_creeps_at_the_approach_speed() {
        let p = params();
        let blocked = FreeSpace { directions_rad: vec![-0.2, 0.0, 0.2], free_m: vec![0.5, 0.5, 0.5] };
        let mut steering = Steering::default();
        let creeping = steering.around_obstacles(-0.1, 2.0, 0.0, &blocked, &p);
        assert!(creeping.drives() && creeping.steering_deg < 0.0, "{creeping:?}");
        assert_eq!(creeping.throttle, hold_speed(p.approach_speed_mps, 0.0, &p).throttle);
        let at_speed = steering.around_obstacles(0.1, 2.0, p.approach_speed_mps, &blocked, &p);
        assert!(at_speed.brake == 0.0 && at_speed.steering_deg > 0.0, "keeps creeping: {at_speed:?}");
    }
}
