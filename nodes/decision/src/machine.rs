//! The decision state machine: explore, approach a sample, wait for the pickup, recover, return
//! home, done. One [`Machine::step`] per frame turns an observation into a drive command.

use rover_msgs::tally::SampleTally;

use crate::drive::{Drive, Steering};
use crate::grid::Grid;
use crate::local::FreeSpace;
use crate::params::DecisionParams;
use crate::plan::{Explorer, Position, Route};

/// Within this distance a rock is taken to be one already given up or collected, metres.
const SAME_ROCK_M: f64 = 3.0;
/// A rock is given up after this many approaches that ended stuck.
const APPROACHES_PER_ROCK: usize = 2;
/// Farther than this the rover drives to a sample along the map and around obstacles; closer, it
/// drives straight at it (samples lie by the walls, where little ground counts as free).
const ROUTE_APPROACH_M: f64 = 4.0;
/// The arm reaches this far ahead of the rover's position, metres.
const ARM_REACH_M: f64 = 0.84;
/// Below this speed the rover counts as stopped, m/s.
const STOPPED_MPS: f64 = 0.05;
/// Moving less than this while driving counts toward being stuck, metres.
const STUCK_PROGRESS_M: f64 = 0.3;
/// Moving less than this, whatever the rover is told, counts toward being stalled, metres.
const STALL_PROGRESS_M: f64 = 1.0;

/// Watches the rover's progress: how long it has stayed within some distance of one spot.
#[derive(Debug, Clone, Copy, Default)]
struct ProgressWatch {
    anchor: Option<(u64, f64, f64)>,
}

impl ProgressWatch {
    /// Frames the rover at `obs` has stayed within `radius_m` of where this watch last anchored.
    fn frames_within(&mut self, obs: &Observation, radius_m: f64) -> u64 {
        let (x, y) = (obs.position.x_m, obs.position.y_m);
        match self.anchor {
            Some((since, ax, ay)) if (x - ax).hypot(y - ay) <= radius_m => obs.frame.saturating_sub(since),
            _ => {
                self.anchor = Some((obs.frame, x, y));
                0
            }
        }
    }

    /// Forgets the anchor: the next frame starts a new watch.
    fn reset(&mut self) {
        self.anchor = None;
    }
}

/// The modes of the state machine, as published on `rover/mode`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Driving to frontiers of the map.
    Explore,
    /// Driving slowly to a seen or remembered sample.
    ApproachSample,
    /// Stopped next to a sample, waiting for the arm.
    Pickup,
    /// Backing up and turning after getting stuck or tilted.
    Recover,
    /// Driving back to the start.
    ReturnHome,
    /// Stopped at the start.
    Done,
}

impl Mode {
    /// The name published on `rover/mode`.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Explore => "explore",
            Mode::ApproachSample => "approach_sample",
            Mode::Pickup => "pickup",
            Mode::Recover => "recover",
            Mode::ReturnHome => "return_home",
            Mode::Done => "done",
        }
    }
}

/// A sample seen in the current camera frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sighting {
    /// Bearing from the heading, radians, positive left.
    pub bearing_rad: f64,
    /// Distance from the rover, metres.
    pub distance_m: f64,
}

/// What the machine knows about one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Observation {
    /// Lock-step frame number.
    pub frame: u64,
    /// Pose in the world.
    pub position: Position,
    /// Body pitch, radians.
    pub pitch_rad: f64,
    /// Body roll, radians.
    pub roll_rad: f64,
    /// Forward speed, m/s.
    pub speed_mps: f64,
    /// A sample is within reach of the arm.
    pub near_sample: bool,
    /// The arm is busy.
    pub picking_up: bool,
    /// Samples still on the ground.
    pub samples_remaining: u8,
    /// Free ground ahead, from the camera.
    pub free: FreeSpace,
    /// A sample in view, if any.
    pub rock: Option<Sighting>,
}

/// The state the machine reports, published on `rover/mode`.
#[derive(Debug, Clone, PartialEq)]
pub struct Status {
    /// Current mode.
    pub mode: Mode,
    /// Why the machine entered it.
    pub reason: String,
    /// Current goal in the world, if the mode has one.
    pub target: Option<(f64, f64)>,
    /// Samples collected.
    pub samples_collected: u32,
    /// The start, where the mission ends.
    pub home: Option<(f64, f64)>,
}

/// What a restarted machine takes over from the one before (from the latched `rover/mode`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Memory {
    /// The start of the mission.
    pub home: (f64, f64),
    /// Samples collected so far.
    pub samples_collected: u32,
}

#[derive(Debug, Clone)]
enum State {
    Explore,
    Approach(Chase),
    Pickup { since_frame: u64, arm_seen: bool },
    Recover { since_frame: u64, turn_left: bool },
    ReturnHome(Option<Route>),
    Done,
}

/// A sample being approached.
#[derive(Debug, Clone)]
struct Chase {
    at: (f64, f64),
    give_up_frame: u64,
    route: Option<Route>,
}

/// The decision state machine.
#[derive(Debug, Clone)]
pub struct Machine {
    params: DecisionParams,
    state: State,
    status: Status,
    changed: bool,
    grid: Grid,
    map_version: u64,
    rocks: Vec<(f64, f64)>,
    ignored_rocks: Vec<(f64, f64)>,
    failed_approaches: Vec<((f64, f64), u64)>,
    explorer: Explorer,
    steering: Steering,
    stuck_watch: ProgressWatch,
    stall_watch: ProgressWatch,
    last_drive: Drive,
    frame: u64,
    tally: SampleTally,
}

impl Machine {
    /// A machine at the start of a mission.
    pub fn new(params: DecisionParams) -> Self {
        Machine {
            params,
            state: State::Explore,
            status: Status {
                mode: Mode::Explore,
                reason: "start".to_string(),
                target: None,
                samples_collected: 0,
                home: None,
            },
            changed: true,
            grid: Grid::unknown(),
            map_version: 0,
            rocks: Vec::new(),
            ignored_rocks: Vec::new(),
            failed_approaches: Vec::new(),
            explorer: Explorer::default(),
            steering: Steering::default(),
            stuck_watch: ProgressWatch::default(),
            stall_watch: ProgressWatch::default(),
            last_drive: Drive::stop(0.0),
            frame: 0,
            tally: SampleTally::default(),
        }
    }

    /// Takes over a mission an earlier machine started: its home and the samples it collected.
    pub fn resume(&mut self, memory: Memory) {
        self.status.home = Some(memory.home);
        self.tally = SampleTally::starting_at(memory.samples_collected);
        self.status.samples_collected = memory.samples_collected;
        self.status.reason = "resumed".to_string();
        self.changed = true;
    }

    /// Replaces the parameters (a parameter was set at run time).
    pub fn set_params(&mut self, params: DecisionParams) {
        self.params = params;
    }

    /// Takes a new map.
    /// A map without free cells (the mapping node's first publication, before any scan) says
    /// nothing yet and is ignored, so that it cannot end the exploration.
    pub fn set_map(&mut self, grid: Grid) {
        if grid.counts().0 == 0 {
            return;
        }
        self.grid = grid;
        self.map_version += 1;
    }

    /// Takes the located rocks, world positions.
    pub fn set_rocks(&mut self, rocks: Vec<(f64, f64)>) {
        self.rocks = rocks;
    }

    /// The reported state.
    pub fn status(&self) -> &Status {
        &self.status
    }

    /// Whether the mode changed since the last call.
    pub fn take_change(&mut self) -> bool {
        std::mem::take(&mut self.changed)
    }

    /// Decides the drive command for one frame.
    pub fn step(&mut self, obs: &Observation) -> Drive {
        self.status.home.get_or_insert((obs.position.x_m, obs.position.y_m));
        self.frame = obs.frame;
        self.explorer.inspect(&obs.position, &self.params);
        self.tally.update(obs.samples_remaining);
        self.status.samples_collected = self.tally.collected();
        let drive = self.decide(obs);
        self.status.target = self.target();
        tracing::trace!(
            frame = obs.frame,
            x = obs.position.x_m,
            y = obs.position.y_m,
            yaw_deg = obs.position.yaw_rad.to_degrees(),
            speed = obs.speed_mps,
            mode = self.status.mode.name(),
            target = ?self.status.target,
            rock = ?obs.rock,
            ?drive,
            "decided"
        );
        self.last_drive = drive;
        drive
    }

    fn target(&self) -> Option<(f64, f64)> {
        match &self.state {
            State::Explore => self.explorer.target(),
            State::Approach(chase) => Some(chase.at),
            State::ReturnHome(_) | State::Done => self.status.home,
            State::Pickup { .. } | State::Recover { .. } => None,
        }
    }

    fn enter(&mut self, state: State, reason: &str) {
        let mode = match state {
            State::Explore => Mode::Explore,
            State::Approach(_) => Mode::ApproachSample,
            State::Pickup { .. } => Mode::Pickup,
            State::Recover { .. } => Mode::Recover,
            State::ReturnHome(_) => Mode::ReturnHome,
            State::Done => Mode::Done,
        };
        tracing::info!("mode {} -> {}: {reason}", self.status.mode.name(), mode.name());
        self.state = state;
        self.status.mode = mode;
        self.status.reason = reason.to_string();
        self.changed = true;
        self.steering.reset();
        self.stuck_watch.reset();
        self.stall_watch.reset();
    }

    fn decide(&mut self, obs: &Observation) -> Drive {
        let (pickup, done) = (matches!(self.state, State::Pickup { .. }), matches!(self.state, State::Done));
        if !pickup && !done && (obs.picking_up || obs.near_sample) {
            let reason = if obs.picking_up { "the arm is picking up" } else { "sample within reach" };
            self.enter(State::Pickup { since_frame: obs.frame, arm_seen: false }, reason);
        } else if !pickup && !done && !matches!(self.state, State::Recover { .. }) {
            if self.tilted(obs) {
                self.start_recovery(obs, "tilted");
            } else if self.stuck(obs) {
                self.start_recovery(obs, "stuck");
            } else if self.stalled(obs) {
                self.start_recovery(obs, "no progress");
            }
        }
        match self.state.clone() {
            State::Explore => self.explore(obs),
            State::Approach(chase) => self.approach(obs, chase),
            State::Pickup { since_frame, arm_seen } => self.pickup(obs, since_frame, arm_seen),
            State::Recover { since_frame, turn_left } => self.recover(obs, since_frame, turn_left),
            State::ReturnHome(route) => self.return_home(obs, route),
            State::Done => Drive::stop(self.params.brake),
        }
    }

    fn tilted(&self, obs: &Observation) -> bool {
        let limit = self.params.tilt_limit_deg.to_radians();
        obs.pitch_rad.abs() > limit || obs.roll_rad.abs() > limit
    }

    /// Whether the rover has been told to drive for a while without getting anywhere.
    fn stuck(&mut self, obs: &Observation) -> bool {
        if !self.last_drive.drives() {
            self.stuck_watch.reset();
            return false;
        }
        self.stuck_watch.frames_within(obs, STUCK_PROGRESS_M) >= self.params.frames(self.params.stuck_s)
    }

    /// Whether the rover has stayed in one spot for long, turning or not (a goal that the camera
    /// and the map disagree about can keep it turning back and forth).
    fn stalled(&mut self, obs: &Observation) -> bool {
        self.stall_watch.frames_within(obs, STALL_PROGRESS_M) >= self.params.frames(self.params.stall_s)
    }

    fn start_recovery(&mut self, obs: &Observation, reason: &str) {
        match &self.state {
            State::Explore => self.explorer.note_recovery(),
            State::Approach(chase) => self.failed_approaches.push((chase.at, obs.frame)),
            _ => {}
        }
        let turn_left = obs.free.most_open() >= 0.0;
        self.enter(State::Recover { since_frame: obs.frame, turn_left }, reason);
    }

    fn explore(&mut self, obs: &Observation) -> Drive {
        if let Some(reason) = self.time_to_go_home(obs) {
            self.enter(State::ReturnHome(None), reason);
            return self.return_home(obs, None);
        }
        if let Some(chase) = self.sample_to_chase(obs, self.params.sample_detour_cost) {
            self.enter(State::Approach(chase.clone()), "sample located");
            return self.approach(obs, chase);
        }
        let p = &self.params;
        match self.explorer.waypoint(&self.grid, self.map_version, &obs.position, obs.frame, p) {
            Some(waypoint) => {
                let bearing = obs.position.bearing_to(waypoint);
                tracing::trace!(bearing_deg = bearing.to_degrees(), free_ahead = obs.free.toward(0.0), best = ?obs.free.best_toward(bearing as f32, p.clearance_m as f32), "explore");
                self.steering.around_obstacles(bearing, p.max_speed_mps, obs.speed_mps, &obs.free, p)
            }
            None if self.map_version == 0 => {
                self.steering.around_obstacles(0.0, p.max_speed_mps, obs.speed_mps, &obs.free, p)
            }
            None if obs.samples_remaining > 0 && self.explorer.forget_explored() => {
                tracing::info!("no frontier left, {} samples not found: trying given-up frontiers again", obs.samples_remaining);
                Drive::stop(p.brake)
            }
            None => match self.sample_to_chase(obs, f64::INFINITY) {
                Some(chase) => {
                    self.enter(State::Approach(chase.clone()), "map explored, sample left");
                    self.approach(obs, chase)
                }
                None => {
                    tracing::debug!(rocks = ?self.rocks, given_up = ?self.ignored_rocks, "no frontier left");
                    self.enter(State::ReturnHome(None), "no frontier left");
                    self.return_home(obs, None)
                }
            },
        }
    }

    /// A seen sample within sight, or a remembered one within `max_cost` on the map.
    fn sample_to_chase(&self, obs: &Observation, max_cost: f64) -> Option<Chase> {
        if obs.samples_remaining == 0 {
            return None;
        }
        let p = &self.params;
        let new = |(at, way_m): ((f64, f64), f64)| Chase {
            at,
            give_up_frame: obs.frame + p.frames(p.sample_timeout_s + way_m / p.max_speed_mps),
            route: None,
        };
        let seen = obs
            .rock
            .filter(|s| s.distance_m <= p.sample_sight_m)
            .map(|s| (obs.position.point_at(s.bearing_rad, s.distance_m), s.distance_m))
            .filter(|&(at, _)| !self.is_ignored(at));
        seen.or_else(|| {
            self.rocks
                .iter()
                .copied()
                .filter(|&at| !self.is_ignored(at))
                .filter_map(|at| Some((at, self.explorer.cost_to(at)?)))
                .filter(|&(_, cost)| cost <= max_cost)
                .min_by(|a, b| a.1.total_cmp(&b.1))
        })
        .map(new)
    }

    /// Whether the rock at `at` is collected, given up, or failed too often lately.
    fn is_ignored(&self, at: (f64, f64)) -> bool {
        let near = |(x, y): (f64, f64)| (x - at.0).hypot(y - at.1) < SAME_ROCK_M;
        let recent = |frame: u64| frame + self.params.frames(self.params.sample_retry_s) > self.frame;
        self.ignored_rocks.iter().any(|&p| near(p))
            || self.failed_approaches.iter().filter(|&&(p, frame)| near(p) && recent(frame)).count()
                >= APPROACHES_PER_ROCK
    }

    fn time_to_go_home(&self, obs: &Observation) -> Option<&'static str> {
        let p = &self.params;
        let home = self.status.home?;
        let elapsed_s = obs.frame as f64 * p.frame_period_s;
        let way_home_m = self.explorer.cost_to(home).unwrap_or_else(|| obs.position.distance_to(home));
        let return_s = way_home_m / (p.max_speed_mps * p.return_speed_fraction);
        (elapsed_s + return_s >= p.mission_deadline_s).then_some("mission deadline")
    }

    fn approach(&mut self, obs: &Observation, mut chase: Chase) -> Drive {
        let p = self.params.clone();
        if let Some(seen) = obs.rock.filter(|s| s.distance_m <= p.sample_sight_m) {
            chase.at = obs.position.point_at(seen.bearing_rad, seen.distance_m);
        }
        if obs.frame >= chase.give_up_frame || obs.samples_remaining == 0 {
            self.failed_approaches.push((chase.at, obs.frame));
            self.enter(State::Explore, "sample not reached in time");
            return Drive::stop(p.brake);
        }
        let distance_m = obs.position.distance_to(chase.at);
        let bearing = obs.position.bearing_to(chase.at);
        let drive = if distance_m > ROUTE_APPROACH_M {
            let route =
                chase.route.get_or_insert_with(|| Route::to(chase.at).expect("sample positions are on the map"));
            let waypoint =
                route.waypoint(&self.grid, self.map_version, &obs.position, obs.frame, &p).unwrap_or(chase.at);
            let bearing = obs.position.bearing_to(waypoint);
            self.steering.around_obstacles(bearing, p.max_speed_mps, obs.speed_mps, &obs.free, &p)
        } else {
            let speed = p.approach_speed_mps * (distance_m / ROUTE_APPROACH_M).clamp(0.5, 1.0);
            self.steering.toward(bearing, speed, obs.speed_mps, &p)
        };
        self.state = State::Approach(chase);
        drive
    }

    fn pickup(&mut self, obs: &Observation, since_frame: u64, arm_seen: bool) -> Drive {
        let p = self.params.clone();
        let waited = obs.frame.saturating_sub(since_frame);
        if obs.picking_up {
            self.state = State::Pickup { since_frame, arm_seen: true };
        } else if arm_seen {
            self.ignored_rocks.push(obs.position.point_at(0.0, ARM_REACH_M));
            self.enter(State::Explore, "sample collected");
        } else if !obs.near_sample && obs.speed_mps.abs() < STOPPED_MPS {
            self.enter(State::Explore, "sample out of reach");
        } else if waited >= p.frames(p.pickup_wait_s) {
            self.ignored_rocks.push(obs.position.point_at(0.0, ARM_REACH_M));
            self.enter(State::Explore, "no pickup came");
        }
        Drive::stop(p.brake)
    }

    fn recover(&mut self, obs: &Observation, since_frame: u64, turn_left: bool) -> Drive {
        let p = self.params.clone();
        let elapsed = obs.frame.saturating_sub(since_frame);
        let back = p.frames(p.recover_back_s);
        if elapsed < back {
            return Drive { throttle: -p.recover_throttle, brake: 0.0, steering_deg: 0.0 };
        }
        if elapsed < back + p.frames(p.recover_turn_s) {
            return if obs.speed_mps.abs() > STOPPED_MPS {
                Drive::stop(p.brake)
            } else {
                Drive::turn_in_place(turn_left)
            };
        }
        self.enter(State::Explore, "recovered");
        Drive::stop(p.brake)
    }

    fn return_home(&mut self, obs: &Observation, route: Option<Route>) -> Drive {
        let p = self.params.clone();
        let home = self.status.home.unwrap_or((obs.position.x_m, obs.position.y_m));
        let distance_m = obs.position.distance_to(home);
        if distance_m <= p.home_tolerance_m {
            self.enter(State::Done, "home");
            return Drive::stop(p.brake);
        }
        let detour = self.time_to_go_home(obs).is_none().then(|| self.sample_to_chase(obs, p.sample_detour_cost));
        if let Some(chase) = detour.flatten() {
            self.enter(State::Approach(chase.clone()), "sample located on the way home");
            return self.approach(obs, chase);
        }
        let mut route = route.or_else(|| Route::to(home));
        let waypoint = route
            .as_mut()
            .and_then(|r| r.waypoint(&self.grid, self.map_version, &obs.position, obs.frame, &p))
            .unwrap_or(home);
        let bearing = obs.position.bearing_to(waypoint);
        let cruise = p.max_speed_mps.min(distance_m.max(p.approach_speed_mps));
        let drive = self.steering.around_obstacles(bearing, cruise, obs.speed_mps, &obs.free, &p);
        self.state = State::ReturnHome(route);
        drive
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::SIDE;

    fn open_ahead() -> FreeSpace {
        FreeSpace { directions_rad: vec![-0.3, 0.0, 0.3], free_m: vec![6.0, 6.0, 6.0] }
    }

    fn observation(frame: u64, x_m: f64, y_m: f64) -> Observation {
        Observation {
            frame,
            position: Position { x_m, y_m, yaw_rad: 0.0 },
            pitch_rad: 0.0,
            roll_rad: 0.0,
            speed_mps: 0.0,
            near_sample: false,
            picking_up: false,
            samples_remaining: 6,
            free: open_ahead(),
            rock: None,
        }
    }

    /// A corridor along y = 100 from x = 90 to 130, unknown beyond x = 130.
    fn corridor() -> Grid {
        let mut data = vec![100i8; SIDE * SIDE];
        for y in 98..103 {
            for x in 90..140 {
                data[y * SIDE + x] = if x < 130 { 0 } else { -1 };
            }
        }
        Grid::from_occupancy(&data).unwrap()
    }

    #[test]
    fn a_map_without_free_cells_does_not_end_the_exploration() {
        let params = DecisionParams::default();
        let mut machine = Machine::new(params.clone());
        machine.set_map(Grid::unknown());
        for frame in 1..params.frames(params.stuck_s) {
            let drive = machine.step(&observation(frame, 100.5, 100.5));
            assert!(drive.throttle > 0.0, "frame {frame}: {drive:?}");
        }
        assert_eq!(machine.status().mode, Mode::Explore);
    }

    #[test]
    fn a_rover_that_turns_on_one_spot_for_long_recovers() {
        let params = DecisionParams::default();
        let mut machine = Machine::new(params.clone());
        machine.set_map(corridor());
        let facing_away = |frame| {
            let mut obs = observation(frame, 100.5, 100.5);
            obs.position.yaw_rad = std::f64::consts::PI;
            obs
        };
        let stall = params.frames(params.stall_s);
        for frame in 1..stall {
            assert_eq!(machine.step(&facing_away(frame)).throttle, 0.0, "turns in place");
            assert_eq!(machine.status().mode, Mode::Explore, "frame {frame}");
        }
        machine.step(&facing_away(stall + 1));
        assert_eq!((machine.status().mode, machine.status().reason.as_str()), (Mode::Recover, "no progress"));
    }

    #[test]
    fn a_seen_sample_is_approached_and_picked_up() {
        let mut machine = Machine::new(DecisionParams::default());
        machine.set_map(corridor());
        let mut obs = observation(1, 100.5, 100.5);
        obs.rock = Some(Sighting { bearing_rad: 0.1, distance_m: 3.0 });
        machine.step(&obs);
        assert_eq!(machine.status().mode, Mode::ApproachSample);
        obs.frame = 2;
        obs.near_sample = true;
        assert_eq!(machine.step(&obs).throttle, 0.0);
        assert_eq!(machine.status().mode, Mode::Pickup);
        obs.frame = 3;
        obs.picking_up = true;
        machine.step(&obs);
        obs.frame = 4;
        (obs.picking_up, obs.near_sample, obs.samples_remaining, obs.rock) = (false, false, 5, None);
        machine.step(&obs);
        assert_eq!(machine.status().mode, Mode::Explore);
        assert_eq!((machine.status().reason.as_str(), machine.status().samples_collected), ("sample collected", 1));
    }

    #[test]
    fn at_the_deadline_the_rover_goes_home_without_detours_and_stops_there() {
        let params = DecisionParams::default();
        let mut machine = Machine::new(params.clone());
        machine.set_map(corridor());
        machine.step(&observation(1, 100.5, 100.5));
        let late = params.frames(params.mission_deadline_s);
        let mut sample_in_view = observation(late, 120.5, 100.5);
        sample_in_view.rock = Some(Sighting { bearing_rad: 0.0, distance_m: 3.0 });
        machine.step(&sample_in_view);
        assert_eq!(machine.status().mode, Mode::ReturnHome, "no detour for a sample at the deadline");
        assert_eq!(machine.status().target, Some((100.5, 100.5)));
        machine.step(&observation(late + 1, 101.0, 100.5));
        assert_eq!(machine.status().mode, Mode::Done);
        assert_eq!(machine.step(&observation(late + 2, 101.0, 100.5)).throttle, 0.0);
    }
}
