//! The rover's dynamics (unity-sim-spec 3 and 5.4): throttle, brake and speed caps, steering that
//! shrinks with speed, turning in place, collisions, body pitch and roll, the sample pickup. The
//! steering facts are Unity's, shared with the nodes through `rover_msgs::body`.

use nalgebra::Vector2;
use rover_msgs::body::{MAX_FORWARD_MPS, MAX_STEER_DEG, TURN_IN_PLACE_DPS, WHEELBASE_M, wheel_angle_deg};
use rover_msgs::unity::ReportedState;

use crate::terrain::TERRAIN_STEP_M;
use crate::wire::command::Command;
use crate::world::{Sample, World};

/// Reverse speed cap, m/s.
pub(crate) const MAX_REVERSE_MPS: f64 = 2.0;
/// Duration of a pickup, seconds.
pub(crate) const PICKUP_SECONDS: f64 = 10.0;
/// Physics step of the Unity project, seconds.
pub(crate) const PHYSICS_STEP_S: f64 = 0.02;
/// Distance between the left and right wheels, metres.
const TRACK_M: f64 = 0.64;
/// Drive acceleration per unit throttle and speed damping under throttle (fit to robot_log.csv).
const THROTTLE_ACCEL_MPS2: f64 = 0.944;
const THROTTLE_DAMPING_PER_S: f64 = 0.140;
/// Coasting deceleration: proportional part and constant part.
const COAST_DAMPING_PER_S: f64 = 0.057;
const COAST_FRICTION_MPS2: f64 = 0.05;
/// Braking deceleration per unit brake, and the friction limit.
const BRAKE_ACCEL_MPS2: f64 = 3.59;
const BRAKE_LIMIT_MPS2: f64 = 4.9;
/// Turning in place starts below this speed, m/s.
const TURN_IN_PLACE_BELOW_MPS: f64 = 0.316;
/// Radius of the rover's footprint around its reported position, metres.
pub(crate) const FOOTPRINT_RADIUS_M: f64 = 0.5;
/// A blocked move slides along the obstacle when at least this fraction of it is left; otherwise
/// the rover stops.
const SLIDE_MIN_FRACTION: f64 = 0.2;
/// A new contact is a collision when the rover keeps less than this fraction of its speed (a stop,
/// or a slide at a steep angle).
const COLLISION_BELOW_SPEED_KEPT: f64 = 0.5;
/// A contact ends only once the rover is this far from the obstacle, metres.
const CONTACT_MARGIN_M: f64 = 0.05;
/// The arm reaches samples around this point ahead of the position, metres.
const REACH_AHEAD_M: f64 = 0.8435;
const REACH_RADIUS_M: f64 = 0.5;
/// Body pitch per m/s^2 of forward acceleration and roll per m/s^2 of lateral acceleration, degrees.
const PITCH_PER_ACCEL: f64 = 1.7;
const ROLL_PER_ACCEL: f64 = 1.1;
/// The sway's limits, degrees: on the flat floor the recorded rover rolls no more than about
/// 1.2 degrees in turns of 1.5-3 m/s^2 (larger rolls in the logs come from the ground's slope).
const PITCH_LIMIT_DEG: f64 = 1.6;
const ROLL_LIMIT_DEG: f64 = 1.2;
const TILT_TIME_CONSTANT_S: f64 = 0.25;

/// A turn in place started by `fixed_turn`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct FixedTurn {
    remaining_deg: f64,
    rate_dps: f64,
}

/// A pickup in progress.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Pickup {
    elapsed_s: f64,
    sample: usize,
}

/// What happened during one step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct StepEvents {
    /// The rover ran into something it was not touching before.
    pub collision: bool,
    /// Throttle was applied but the rover could not move.
    pub stuck: bool,
    /// Distance driven, metres.
    pub distance_m: f64,
}

/// The rover.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Rover {
    /// x, metres.
    pub x_m: f64,
    /// y, metres.
    pub y_m: f64,
    /// Yaw, degrees counter-clockwise from +x.
    pub yaw_deg: f64,
    /// Signed forward speed, m/s.
    pub speed_mps: f64,
    /// Pitch, degrees, positive nose down: the ground's under the wheels plus the body's sway.
    pub pitch_deg: f64,
    /// Roll, degrees, positive right side down: the ground's plus the body's sway.
    pub roll_deg: f64,
    /// Height of the ground under the rover above the floor, metres.
    pub ground_m: f64,
    /// Last accepted throttle.
    pub throttle: f64,
    /// Last accepted brake.
    pub brake: f64,
    /// Steering angle applied, degrees, positive left.
    pub steer_deg: f64,
    /// A sample is within reach.
    pub near_sample: bool,
    /// A pickup is running (or just ended this frame).
    pub picking_up: bool,
    sway_pitch_deg: f64,
    sway_roll_deg: f64,
    turning_in_place: bool,
    reversing: bool,
    in_contact: bool,
    fixed_turn: Option<FixedTurn>,
    pickup: Option<Pickup>,
}

impl Rover {
    /// A rover at rest at (x, y) facing `yaw_deg`.
    pub(crate) fn new(x_m: f64, y_m: f64, yaw_deg: f64) -> Self {
        Rover {
            x_m,
            y_m,
            yaw_deg,
            speed_mps: 0.0,
            pitch_deg: 0.0,
            roll_deg: 0.0,
            ground_m: 0.0,
            throttle: 0.0,
            brake: 0.0,
            steer_deg: 0.0,
            near_sample: false,
            picking_up: false,
            sway_pitch_deg: 0.0,
            sway_roll_deg: 0.0,
            turning_in_place: false,
            reversing: false,
            in_contact: false,
            fixed_turn: None,
            pickup: None,
        }
    }

    /// What Unity reports of this rover: its roll positive with the right side up.
    pub(crate) fn reported_state(&self) -> ReportedState {
        ReportedState {
            steering_angle_deg: self.steer_deg,
            throttle: self.throttle,
            brake: self.brake,
            speed_mps: self.speed_mps,
            x_m: self.x_m,
            y_m: self.y_m,
            pitch_deg: self.pitch_deg,
            yaw_deg: self.yaw_deg,
            roll_deg: -self.roll_deg,
        }
    }

    fn motor_input(&self) -> bool {
        self.throttle != 0.0 || self.brake != 0.0
    }

    /// Unit vector along the rover's heading.
    fn heading(&self) -> Vector2<f64> {
        let (sin_yaw, cos_yaw) = self.yaw_deg.to_radians().sin_cos();
        Vector2::new(cos_yaw, sin_yaw)
    }

    fn frozen(&self) -> bool {
        self.pickup.is_some() || self.fixed_turn.is_some()
    }

    /// Applies a command; drive commands are ignored while picking up or turning by `fixed_turn`.
    /// A pickup with no sample within reach is ignored.
    pub(crate) fn apply(&mut self, command: Command, samples: &[Sample]) {
        match command {
            Command::Drive { steering_deg, throttle, brake } if !self.frozen() => {
                self.throttle = throttle;
                self.brake = brake;
                self.steer_deg = steering_deg.clamp(-MAX_STEER_DEG, MAX_STEER_DEG);
                if self.steer_deg == 0.0 || self.motor_input() {
                    self.turning_in_place = false;
                }
                if throttle != 0.0 {
                    self.reversing = throttle < 0.0;
                }
            }
            Command::Pickup if self.pickup.is_none() => {
                if let Some(sample) = self.reachable_sample(samples) {
                    self.pickup = Some(Pickup { elapsed_s: 0.0, sample });
                    self.picking_up = true;
                    self.speed_mps = 0.0;
                }
            }
            Command::FixedTurn { angle_deg, time_s } => {
                let idle = self.speed_mps == 0.0 && !self.motor_input() && self.steer_deg == 0.0;
                if idle && !self.frozen() && angle_deg != 0.0 {
                    let duration = if time_s == 0.0 { angle_deg.abs() / TURN_IN_PLACE_DPS } else { time_s.abs() };
                    self.fixed_turn = Some(FixedTurn { remaining_deg: -angle_deg, rate_dps: -angle_deg / duration });
                }
            }
            _ => {}
        }
    }

    /// Index of a sample within reach of the arm, if any.
    pub(crate) fn reachable_sample(&self, samples: &[Sample]) -> Option<usize> {
        let arm = self.heading() * REACH_AHEAD_M;
        let (rx, ry) = (self.x_m + arm.x, self.y_m + arm.y);
        samples.iter().position(|sample| (sample.x_m - rx).hypot(sample.y_m - ry) <= REACH_RADIUS_M + sample.radius_m)
    }

    /// Advances the rover by `dt` seconds in physics steps of 0.02 s. Returns the index of a sample
    /// whose pickup finished (to be removed from the world) and what happened.
    pub(crate) fn step(&mut self, dt: f64, world: &World, samples: &[Sample]) -> (Option<usize>, StepEvents) {
        let mut events = StepEvents::default();
        let mut picked = None;
        if self.pickup.is_none() && self.picking_up {
            self.picking_up = false;
        }
        let substeps = (dt / PHYSICS_STEP_S).round().max(1.0) as usize;
        let h = dt / substeps as f64;
        for _ in 0..substeps {
            if self.pickup.is_some() {
                picked = self.advance_pickup(h);
                if picked.is_some() {
                    break;
                }
            } else {
                self.advance_motion(h, world, samples, &mut events);
                self.near_sample = self.reachable_sample(samples).is_some();
            }
        }
        (picked, events)
    }

    fn advance_pickup(&mut self, h: f64) -> Option<usize> {
        let pickup = self.pickup.as_mut()?;
        pickup.elapsed_s += h;
        self.speed_mps = 0.0;
        self.near_sample = true;
        if pickup.elapsed_s + 1e-9 < PICKUP_SECONDS {
            return None;
        }
        let sample = pickup.sample;
        self.pickup = None;
        self.near_sample = false;
        Some(sample)
    }

    fn advance_motion(&mut self, h: f64, world: &World, samples: &[Sample], events: &mut StepEvents) {
        if let Some(turn) = self.fixed_turn.as_mut() {
            let step = (turn.rate_dps * h).clamp(-turn.remaining_deg.abs(), turn.remaining_deg.abs());
            self.yaw_deg = wrap_degrees(self.yaw_deg + step);
            turn.remaining_deg -= step;
            if turn.remaining_deg.abs() < 1e-9 {
                self.fixed_turn = None;
            }
            return;
        }
        let previous_speed = self.speed_mps;
        self.speed_mps = self.next_speed(h);
        let acceleration = (self.speed_mps - previous_speed) / h;
        if self.steer_deg != 0.0 && !self.motor_input() && self.speed_mps.abs() < TURN_IN_PLACE_BELOW_MPS {
            self.turning_in_place = true;
        }
        let yaw_rate_dps = if self.turning_in_place {
            self.speed_mps = 0.0;
            TURN_IN_PLACE_DPS * self.steer_deg / MAX_STEER_DEG
        } else {
            let mut wheel_deg = wheel_angle_deg(self.steer_deg, self.speed_mps);
            if self.reversing {
                wheel_deg *= 2.0;
            }
            (self.speed_mps * wheel_deg.to_radians().tan() / WHEELBASE_M).to_degrees()
        };
        self.yaw_deg = wrap_degrees(self.yaw_deg + yaw_rate_dps * h);
        self.move_forward(h, world, samples, events);
        self.settle_body(h, acceleration, self.speed_mps * yaw_rate_dps.to_radians());
        self.follow_ground(world);
    }

    /// Sets the ground height, pitch and roll from the ground under the four wheels.
    pub(crate) fn follow_ground(&mut self, world: &World) {
        let (s, c) = self.yaw_deg.to_radians().sin_cos();
        let wheel = |ahead: f64, left: f64| {
            world.ground_height(self.x_m + ahead * c - left * s, self.y_m + ahead * s + left * c) as f64
        };
        let (half_base, half_track) = (WHEELBASE_M / 2.0, TRACK_M / 2.0);
        let [front_left, front_right] = [wheel(half_base, half_track), wheel(half_base, -half_track)];
        let [rear_left, rear_right] = [wheel(-half_base, half_track), wheel(-half_base, -half_track)];
        self.ground_m = (front_left + front_right + rear_left + rear_right) / 4.0;
        let nose_drop = (rear_left + rear_right - front_left - front_right) / 2.0;
        let right_drop = (front_left + rear_left - front_right - rear_right) / 2.0;
        self.pitch_deg = self.sway_pitch_deg + nose_drop.atan2(WHEELBASE_M).to_degrees();
        self.roll_deg = self.sway_roll_deg + right_drop.atan2(TRACK_M).to_degrees();
    }

    fn next_speed(&self, h: f64) -> f64 {
        let v = self.speed_mps;
        let mut accel = if self.motor_input() {
            THROTTLE_ACCEL_MPS2 * self.throttle - THROTTLE_DAMPING_PER_S * v
        } else {
            -COAST_DAMPING_PER_S * v - COAST_FRICTION_MPS2 * sign(v)
        };
        if self.brake > 0.0 {
            accel -= (BRAKE_ACCEL_MPS2 * self.brake).min(BRAKE_LIMIT_MPS2) * sign(v);
        }
        let next = v + accel * h;
        let stopping = !self.motor_input() || self.brake > 0.0;
        let next = if stopping && next * v < 0.0 { 0.0 } else { next };
        let cap = if self.reversing { MAX_REVERSE_MPS } else { MAX_FORWARD_MPS };
        if next.abs() < 1e-4 && self.throttle == 0.0 { 0.0 } else { next.clamp(-cap, cap) }
    }

    fn move_forward(&mut self, h: f64, world: &World, samples: &[Sample], events: &mut StepEvents) {
        let step = self.heading() * (self.speed_mps * h);
        let free_at =
            |d: Vector2<f64>| !footprint_blocked(world, samples, self.x_m + d.x, self.y_m + d.y, FOOTPRINT_RADIUS_M);
        let (moved, speed_kept) = if self.speed_mps == 0.0 || free_at(step) {
            (step, 1.0)
        } else {
            let slide = contact_normal(world, samples, self.x_m + step.x, self.y_m + step.y, FOOTPRINT_RADIUS_M)
                .map(|normal| without_part_along(step, normal))
                .filter(|&slide| free_at(slide));
            let length = step.x.hypot(step.y);
            let slide = slide.or_else(|| {
                let along = slide_along_contacts(world, samples, self.x_m, self.y_m, step);
                free_at(along).then_some(along)
            });
            match slide {
                Some(slide) if slide.x.hypot(slide.y) > SLIDE_MIN_FRACTION * length => {
                    (slide, slide.x.hypot(slide.y) / length)
                }
                _ => {
                    let free = furthest_free_fraction(|f| !free_at(step * f));
                    (step * free, 0.0)
                }
            }
        };
        if speed_kept < 1.0 {
            if !self.in_contact && speed_kept < COLLISION_BELOW_SPEED_KEPT {
                events.collision = true;
            }
            self.in_contact = true;
            self.speed_mps *= speed_kept;
        } else {
            self.in_contact &= footprint_blocked(
                world,
                samples,
                self.x_m + moved.x,
                self.y_m + moved.y,
                FOOTPRINT_RADIUS_M + CONTACT_MARGIN_M,
            );
        }
        events.distance_m += moved.x.hypot(moved.y);
        self.x_m += moved.x;
        self.y_m += moved.y;
        if self.throttle.abs() > 0.05 && self.brake == 0.0 && self.speed_mps.abs() < 0.05 && !self.turning_in_place {
            events.stuck = true;
        }
    }

    /// The body's sway on its suspension under acceleration and turning.
    fn settle_body(&mut self, h: f64, forward_accel: f64, lateral_accel: f64) {
        let blend = 1.0 - (-h / TILT_TIME_CONSTANT_S).exp();
        let pitch_target = (PITCH_PER_ACCEL * forward_accel).clamp(-PITCH_LIMIT_DEG, PITCH_LIMIT_DEG);
        let roll_target = (ROLL_PER_ACCEL * lateral_accel).clamp(-ROLL_LIMIT_DEG, ROLL_LIMIT_DEG);
        self.sway_pitch_deg += (pitch_target - self.sway_pitch_deg) * blend;
        self.sway_roll_deg += (roll_target - self.sway_roll_deg) * blend;
    }
}

/// The unit vector from the nearest blocking point to (x, y), for a footprint of radius `r` that
/// overlaps a wall cell or a sample there.
fn contact_normal(world: &World, samples: &[Sample], x: f64, y: f64, r: f64) -> Option<Vector2<f64>> {
    contact_normals(world, samples, x, y, r).first().copied()
}

/// The unit vectors from every blocking point within `r` of (x, y) to it, nearest first.
fn contact_normals(world: &World, samples: &[Sample], x: f64, y: f64, r: f64) -> Vec<Vector2<f64>> {
    let mut contacts: Vec<(f64, Vector2<f64>)> = Vec::new();
    let mut consider = |qx: f64, qy: f64, clearance: f64| {
        let length = (x - qx).hypot(y - qy);
        if length - clearance < r && length > 1e-9 {
            contacts.push((length - clearance, Vector2::new(x - qx, y - qy) / length));
        }
    };
    for [sx, sy] in world.blocked_squares_near(x, y, r) {
        consider(x.clamp(sx, sx + TERRAIN_STEP_M), y.clamp(sy, sy + TERRAIN_STEP_M), 0.0);
    }
    for sample in samples {
        consider(sample.x_m, sample.y_m, sample.radius_m);
    }
    contacts.sort_by(|a, b| a.0.total_cmp(&b.0));
    contacts.into_iter().map(|(_, normal)| normal).collect()
}

/// `step` without its part into any wall or sample touching the footprint at (x, y): a rover
/// wedged between two walls can still move along the gap.
fn slide_along_contacts(world: &World, samples: &[Sample], x: f64, y: f64, step: Vector2<f64>) -> Vector2<f64> {
    let mut slide = step;
    for normal in contact_normals(world, samples, x, y, FOOTPRINT_RADIUS_M + CONTACT_MARGIN_M) {
        if slide.dot(&normal) < 0.0 {
            slide = without_part_along(slide, normal);
        }
    }
    slide
}

/// `step` less its component along the unit vector `normal`.
fn without_part_along(step: Vector2<f64>, normal: Vector2<f64>) -> Vector2<f64> {
    step - normal * step.dot(&normal)
}

/// The largest fraction of a move in [0, 1] that stays free, by bisection (`blocked(0)` is false).
fn furthest_free_fraction(blocked: impl Fn(f64) -> bool) -> f64 {
    let (mut free, mut hit) = (0.0, 1.0);
    for _ in 0..12 {
        let middle = (free + hit) / 2.0;
        if blocked(middle) { hit = middle } else { free = middle }
    }
    free
}

/// True if a footprint of radius `r` at (x, y) overlaps ground the rover cannot drive on or a sample.
pub(crate) fn footprint_blocked(world: &World, samples: &[Sample], x: f64, y: f64, r: f64) -> bool {
    world.blocked_squares_near(x, y, r).next().is_some()
        || samples.iter().any(|s| (s.x_m - x).hypot(s.y_m - y) < r + s.radius_m)
}

/// -1, 0 or 1 (unlike `f64::signum`, 0 for 0).
fn sign(value: f64) -> f64 {
    if value > 0.0 {
        1.0
    } else if value < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// Wraps degrees into [0, 360), as Unity's `localEulerAngles` report them (a tiny negative angle,
/// which `rem_euclid` rounds up to 360, is 0).
pub(crate) fn wrap_degrees(degrees: f64) -> f64 {
    let wrapped = degrees.rem_euclid(360.0);
    if wrapped >= 360.0 { 0.0 } else { wrapped }
}

#[cfg(test)]
mod tests;
