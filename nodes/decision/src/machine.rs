//! The decision state machine: explore, approach a sample, wait for the pickup, recover, return
//! home, done. One [`Machine::step`] per frame turns an observation into a drive command.

use rover_msgs::body::ARM_REACH_M;
use rover_msgs::map_grid::{cell_centre_m, cell_of_point};
use rover_msgs::tally::SampleTally;

use crate::approach::{Aim, Chase};
use crate::arrivals::{Delayed, MapCadence};
use crate::drive::{Drive, STOPPED_MPS, Steering, speed_to_stop_in};
use crate::explore::{Explorer, ExplorerMemory};
use crate::grid::Grid;
use crate::local::FreeSpace;
use crate::params::DecisionParams;
use crate::pose::{Position, one_frame_on};
use crate::route::{PlanStart, PlanningMap, Route};
use crate::samples::SampleMemory;
use crate::stuck::{DrivingWatch, ProgressWatch, StuckMarks};

/// Moving less than this while driving counts toward being stuck, metres...
const STUCK_PROGRESS_M: f64 = 0.3;
/// ...when the rover has come to a stop, m/s (a slow approach is not stuck).
const STUCK_SPEED_MPS: f64 = 0.1;
/// Moving less than this, whatever the rover is told, counts toward being stalled, metres.
const STALL_PROGRESS_M: f64 = 1.0;
/// With no frontier in reach because the map walls the rover in, it backs out up to this many
/// times before it gives the frontiers up.
const WALLED_IN_RECOVERIES: u32 = 3;
/// With no frontier left (given-up ones and paths past obstacles included) while samples are
/// missing, the explorer forgets the walls it has seen up close and looks again, up to this many
/// times, before the rover goes home.
const INSPECTION_RESETS: u32 = 2;
/// Exploring forgets the stuck marks that cut off every frontier only once the rover is this far
/// from where it last did so, metres: nearer, it got stuck there again, and the marks hold.
const MARKS_HOLD_NEAR_M: f64 = 3.0;
/// A sample whose route turns out to cost more than its approach is worth is left alone for this
/// long, seconds, while the rover explores on (the map may yet show a shorter way).
const OUT_OF_THE_WAY_S: f64 = 10.0;
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
    pub const fn name(self) -> &'static str {
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

/// What a restarted machine takes over from the one before (from the mapping node's
/// `rover/map_stats`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Memory {
    /// The start of the mission.
    pub home: (f64, f64),
    /// Samples collected so far.
    pub samples_collected: u32,
}

/// What a restarted machine takes over from the earlier machine's snapshot: what the exploration
/// learnt, the rocks it gave up on, and whether it was already on its way home (or there).
#[derive(Debug, Clone, PartialEq)]
pub struct Recollection {
    /// The explorer's memory.
    pub explorer: ExplorerMemory,
    /// Rocks picked up or given up on, world metres.
    pub ignored_rocks: Vec<(f64, f64)>,
    /// The mode, reduced to where the mission stands: exploring (or on the way to a sample),
    /// returning home, or done.
    pub stage: Stage,
}

/// Where a mission stands, as a snapshot keeps it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// Exploring and collecting samples.
    Exploring,
    /// On the way home.
    ReturningHome,
    /// Home: the mission is over.
    Done,
}

#[derive(Debug, Clone)]
enum State {
    Explore,
    Approach(Chase),
    Pickup {
        since_frame: u64,
        arm_seen: bool,
    },
    /// Backing off and turning; then back to exploring, or on the way home when that was
    /// interrupted (exploring would forget the stuck marks that lead the next route around).
    Recover {
        since_frame: u64,
        turn_left: bool,
        then_home: bool,
    },
    ReturnHome(Option<Route>),
    Done,
}

/// The decision state machine.
#[derive(Debug, Clone)]
pub struct Machine {
    params: DecisionParams,
    state: State,
    status: Status,
    changed: bool,
    received_map: Grid,
    /// Maps and rocks received but not yet due ([`crate::arrivals`]).
    arriving_maps: Delayed<Grid>,
    arriving_rocks: Delayed<Vec<(f64, f64)>>,
    /// When the maps taken came, to expect the next.
    map_cadence: MapCadence,
    planning: PlanningMap,
    /// The planning map of the map due on the next frame, made between frames with the path costs
    /// its first plan will likely ask for ([`Machine::prepare_next_frame`]).
    next_planning: Option<PlanningMap>,
    samples: SampleMemory,
    explorer: Explorer,
    steering: Steering,
    stuck_watch: DrivingWatch,
    stall_watch: ProgressWatch,
    stuck_marks: StuckMarks,
    /// Where the rover was when exploring last forgot the stuck marks.
    marks_forgotten_at: Option<(f64, f64)>,
    last_drive: Drive,
    frame: u64,
    /// The frame [`Machine::prepare_next_frame`] last ran after and where the rover was then, to
    /// guess where it will be on the next.
    prepared_at: Option<(u64, Position)>,
    tally: SampleTally,
    /// Recalled from an earlier machine: home comes from the mission ([`Machine::resume`]), not
    /// from where the rover happens to stand at this machine's first frame, and until it does
    /// the machine brakes (its map, rocks and tally may not have caught up with the mission).
    awaits_home: bool,
    /// Recoveries started since the last frontier because the map walls the rover in.
    walled_in_recoveries: u32,
    /// Times the explorer forgot the cells seen up close because no frontier was left.
    inspections_forgotten: u32,
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
            received_map: Grid::unknown(),
            arriving_maps: Delayed::default(),
            arriving_rocks: Delayed::default(),
            map_cadence: MapCadence::default(),
            planning: PlanningMap::new(Grid::unknown(), 0),
            next_planning: None,
            samples: SampleMemory::default(),
            explorer: Explorer::default(),
            steering: Steering::default(),
            stuck_watch: DrivingWatch::default(),
            stall_watch: ProgressWatch::default(),
            stuck_marks: StuckMarks::default(),
            marks_forgotten_at: None,
            last_drive: Drive::stop(0.0),
            frame: 0,
            prepared_at: None,
            tally: SampleTally::default(),
            awaits_home: false,
            walled_in_recoveries: 0,
            inspections_forgotten: 0,
        }
    }

    /// Takes over a mission an earlier machine started: its home and the samples it collected.
    pub fn resume(&mut self, memory: Memory) {
        self.status.home = Some(memory.home);
        self.awaits_home = false;
        self.tally = SampleTally::starting_at(memory.samples_collected);
        self.status.samples_collected = memory.samples_collected;
        self.status.reason = "resumed".to_string();
        self.changed = true;
    }

    /// What a restarted machine needs from this one (see [`Machine::recall`]).
    pub fn recollection(&self) -> Recollection {
        let stage = match self.state {
            State::ReturnHome(_) | State::Recover { then_home: true, .. } => Stage::ReturningHome,
            State::Done => Stage::Done,
            _ => Stage::Exploring,
        };
        Recollection { explorer: self.explorer.memory(), ignored_rocks: self.samples.ignored().to_vec(), stage }
    }

    /// Carries on from an earlier machine's recollection.
    pub fn recall(&mut self, recollection: Recollection) {
        self.explorer = Explorer::with_memory(recollection.explorer);
        self.samples.set_ignored(recollection.ignored_rocks);
        self.awaits_home = self.status.home.is_none();
        match recollection.stage {
            Stage::Exploring => {}
            Stage::ReturningHome => self.enter(State::ReturnHome(None), "resumed on the way home"),
            Stage::Done => self.enter(State::Done, "resumed at home"),
        }
    }

    /// The parameters.
    pub fn params(&self) -> &DecisionParams {
        &self.params
    }

    /// Replaces the parameters (a parameter was set at run time).
    pub fn set_params(&mut self, params: DecisionParams) {
        self.params = params;
    }

    /// Takes a new map, with the cells where the rover got stuck lately marked as obstacles,
    /// unless it is ignored ([`is_ignored`]).
    pub fn set_map(&mut self, map: Grid) {
        if is_ignored(&map) {
            return;
        }
        self.stuck_marks.expire(self.frame);
        self.received_map = map;
        self.apply_stuck_marks();
    }

    /// Plans on the received map with the stuck marks as a new version: the planning map made
    /// ahead for it when that is the same map.
    fn apply_stuck_marks(&mut self) {
        let (grid, version) = (self.stuck_marks.applied_to(&self.received_map), self.planning.version() + 1);
        self.planning = match self.next_planning.take() {
            Some(made) if made.version() == version && *made.grid() == grid => made,
            _ => PlanningMap::new(grid, version),
        };
        self.planning.expect_next_map_at(self.map_cadence.next_due());
    }

    /// Forgets the cells marked where the rover got stuck; returns whether there were any.
    fn forget_stuck_marks(&mut self) -> bool {
        if !self.stuck_marks.forget() {
            return false;
        }
        self.apply_stuck_marks();
        true
    }

    /// Forgets the stuck marks that cut off every frontier ([`Machine::forget_stuck_marks`]),
    /// unless the rover `at` is still near where it last did so ([`MARKS_HOLD_NEAR_M`]); returns
    /// whether it forgot any.
    fn forget_stuck_marks_to_explore(&mut self, at: &Position) -> bool {
        if self.marks_forgotten_at.is_some_and(|spot| at.distance_to(spot) < MARKS_HOLD_NEAR_M) {
            return false;
        }
        let forgot = self.forget_stuck_marks();
        if forgot {
            self.marks_forgotten_at = Some((at.x_m, at.y_m));
        }
        forgot
    }

    /// Takes the located rocks, world positions.
    pub fn set_rocks(&mut self, rocks: Vec<(f64, f64)>) {
        self.samples.set_located(rocks);
    }

    /// Takes a map made from the scans up to mission frame `made_at_frame`, in effect
    /// [`crate::arrivals::ARRIVAL_DELAY_FRAMES`] frames after it (at once if that frame has passed).
    pub fn receive_map(&mut self, made_at_frame: u64, map: Grid) {
        self.arriving_maps.push(made_at_frame, map);
    }

    /// Takes the rocks located by the scans up to mission frame `made_at_frame`, in effect as a
    /// map received with them.
    pub fn receive_rocks(&mut self, made_at_frame: u64, rocks: Vec<(f64, f64)>) {
        self.arriving_rocks.push(made_at_frame, rocks);
    }

    /// Puts the maps and rocks due at `frame` into effect.
    fn take_arrivals(&mut self, frame: u64) {
        if let Some((made_at, map)) = self.arriving_maps.take_due(frame) {
            self.map_cadence.record(made_at);
            self.set_map(map);
        }
        if let Some((_, rocks)) = self.arriving_rocks.take_due(frame) {
            self.set_rocks(rocks);
        }
    }

    /// The reported state.
    pub fn status(&self) -> &Status {
        &self.status
    }

    /// The cells of the path on the map that the rover follows now: to the frontier, the sample or
    /// home (empty when it follows none: turning, picking up, recovering, done).
    pub fn path(&self) -> &[usize] {
        match &self.state {
            State::Explore => self.explorer.path(),
            State::Approach(chase) => chase.path(),
            State::ReturnHome(Some(route)) => route.path(),
            _ => &[],
        }
    }

    /// Whether the mode changed since the last call.
    pub fn take_change(&mut self) -> bool {
        std::mem::take(&mut self.changed)
    }

    /// Decides the drive command for one frame.
    pub fn step(&mut self, obs: &Observation) -> Drive {
        if !self.awaits_home {
            self.status.home.get_or_insert((obs.position.x_m, obs.position.y_m));
        }
        self.frame = obs.frame;
        self.take_arrivals(obs.frame);
        self.next_planning = None;
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

    /// Between frames, after the drive command of the last one went out: makes ahead the path
    /// costs the next frame will likely ask for, the rover now at `at`: for a periodic replan
    /// ([`PlanningMap::prepare`]), or for the first plan on a new map that takes effect then,
    /// from the cell the rover will be in if it goes on as it did since the frame before. What
    /// the machine decides does not change, only when the search runs.
    pub fn prepare_next_frame(&mut self, at: &Position) {
        let next_frame = self.frame.saturating_add(1);
        let (x_m, y_m) = match self.prepared_at.replace((self.frame, *at)) {
            Some((frame, before)) if frame + 1 == self.frame => one_frame_on(&before, at),
            _ => (at.x_m, at.y_m),
        };
        let Some(start) = cell_of_point(x_m, y_m) else { return };
        match self.arriving_maps.newest_due(next_frame).filter(|map| !is_ignored(map)) {
            Some(map) => self.next_planning = self.planning_ahead(map, start, next_frame),
            None => self.planning.prepare(start, next_frame, &self.params),
        }
    }

    /// The planning map that `map`, due at `next_frame`, will make (as [`Machine::set_map`] will,
    /// the stuck marks as they are then), with the path costs from cell `start` made on it; none
    /// when nothing plans.
    fn planning_ahead(&self, map: &Grid, start: usize, next_frame: u64) -> Option<PlanningMap> {
        let costs = self.planning.costs_in_use(next_frame, &self.params)?;
        let planning = PlanningMap::new(self.stuck_marks.applied_at(map, next_frame), self.planning.version() + 1);
        planning.make_ahead(start, &costs);
        Some(planning)
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
        if mode == Mode::Explore && matches!(self.state, State::Approach(_) | State::Pickup { .. }) {
            self.explorer.resume_after_detour(self.frame);
        }
        self.state = state;
        self.status.mode = mode;
        self.status.reason = reason.to_string();
        self.changed = true;
        self.steering.reset();
        self.stuck_watch.reset();
        self.stall_watch.reset();
    }

    fn decide(&mut self, obs: &Observation) -> Drive {
        if self.awaits_home {
            return Drive::stop(self.params.brake);
        }
        let (pickup, done) = (matches!(self.state, State::Pickup { .. }), matches!(self.state, State::Done));
        if !pickup && !done && (obs.picking_up || obs.near_sample) {
            let reason = if obs.picking_up { "the arm is picking up" } else { "sample within reach" };
            self.enter(State::Pickup { since_frame: obs.frame, arm_seen: false }, reason);
        } else if !pickup && !done && !matches!(self.state, State::Recover { .. }) {
            if self.tilted(obs) {
                self.start_recovery(obs, "tilted");
            } else if self.stuck(obs) {
                self.mark_stuck_cell(obs);
                self.start_recovery(obs, "stuck");
            } else if self.stalled(obs) {
                self.mark_stuck_cell(obs);
                self.start_recovery(obs, "no progress");
            }
        }
        match self.state.clone() {
            State::Explore => self.explore(obs),
            State::Approach(chase) => self.approach(obs, chase),
            State::Pickup { since_frame, arm_seen } => self.pickup(obs, since_frame, arm_seen),
            State::Recover { since_frame, turn_left, then_home } => {
                self.recover(obs, since_frame, turn_left, then_home)
            }
            State::ReturnHome(route) => self.return_home(obs, route),
            State::Done => Drive::stop(self.params.brake),
        }
    }

    fn tilted(&self, obs: &Observation) -> bool {
        let limit = self.params.tilt_limit_deg.to_radians();
        obs.pitch_rad.abs() > limit || obs.roll_rad.abs() > limit
    }

    /// Whether the rover, told to drive, has stopped at a spot where it was told to drive for a
    /// while without getting anywhere (turns in place in between included).
    fn stuck(&mut self, obs: &Observation) -> bool {
        let driving = self.last_drive.drives();
        let frames = self.stuck_watch.driving_frames_within(&obs.position, obs.frame, STUCK_PROGRESS_M, driving);
        driving && frames >= self.params.frames(self.params.stuck_s) && obs.speed_mps.abs() < STUCK_SPEED_MPS
    }

    /// Whether the rover has stayed in one spot for long, turning or not (a goal that the camera
    /// and the map disagree about can keep it turning back and forth).
    fn stalled(&mut self, obs: &Observation) -> bool {
        self.stall_watch.frames_within(&obs.position, obs.frame, STALL_PROGRESS_M)
            >= self.params.frames(self.params.stall_s)
    }

    /// Makes a cell at the stuck rover's front, or the next one of its plan, an obstacle for
    /// planning for a while, so that the next plan leads around what the map did not show.
    fn mark_stuck_cell(&mut self, obs: &Observation) {
        let path = self.path().to_vec();
        let (at, grid) = ((&obs.position, obs.frame), self.planning.grid());
        if let Some(cell) = self.stuck_marks.note_stuck(at, grid, &path, &self.params) {
            tracing::debug!(
                cell = ?cell_centre_m(cell),
                "stuck: a cell at the front or on the plan is an obstacle for a while"
            );
            self.apply_stuck_marks();
        }
    }

    fn start_recovery(&mut self, obs: &Observation, reason: &str) {
        match &self.state {
            State::Explore => self.explorer.note_recovery(),
            State::Approach(chase) => self.note_failed_approach(chase.at, obs),
            _ => {}
        }
        let turn_left = obs.free.most_open() >= 0.0;
        tracing::debug!(
            at = ?(obs.position.x_m, obs.position.y_m),
            yaw_deg = obs.position.yaw_rad.to_degrees(),
            pitch_deg = obs.pitch_rad.to_degrees(),
            roll_deg = obs.roll_rad.to_degrees(),
            turn_left,
            "recovering"
        );
        let then_home = matches!(self.state, State::ReturnHome(_));
        self.enter(State::Recover { since_frame: obs.frame, turn_left, then_home }, reason);
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
        let p = &self.params.clone();
        match self.explorer.waypoint(
            &PlanStart { map: &self.planning, at: &obs.position, frame: obs.frame, params: p },
            self.status.home,
        ) {
            Some(waypoint) => {
                self.walled_in_recoveries = 0;
                let bearing = obs.position.bearing_to(waypoint);
                tracing::trace!(
                    bearing_deg = bearing.to_degrees(),
                    free_ahead = obs.free.toward(0.0),
                    best = ?obs.free.best_toward(bearing as f32, p.clearance_m as f32),
                    "explore"
                );
                self.steering.around_obstacles(bearing, p.max_speed_mps, obs.speed_mps, &obs.free, p)
            }
            None if self.planning.version() == 0 => {
                self.steering.around_obstacles(0.0, p.max_speed_mps, obs.speed_mps, &obs.free, p)
            }
            None if self.explorer.walled_in() && self.walled_in_recoveries < WALLED_IN_RECOVERIES => {
                self.walled_in_recoveries += 1;
                self.start_recovery(obs, "walled in by the map (a restart next to a rock?): backing out");
                Drive::stop(p.brake)
            }
            None if self.forget_stuck_marks_to_explore(&obs.position) => {
                tracing::info!("no frontier reachable: the cells where the rover got stuck are free again");
                Drive::stop(p.brake)
            }
            None => match self.widen_search(obs.samples_remaining) {
                Some(step) => {
                    tracing::info!("no frontier left, {} samples not found: {step}", obs.samples_remaining);
                    Drive::stop(p.brake)
                }
                None => self.finish_exploring(obs),
            },
        }
    }

    /// With no frontier left and `samples_remaining` samples not found, widens the search by one
    /// step: the frontiers given up, then planning past obstacle cells, then the walls seen before
    /// (a few times); what it did, or `None` when nothing is left to widen.
    fn widen_search(&mut self, samples_remaining: u8) -> Option<&'static str> {
        if samples_remaining == 0 {
            return None;
        }
        if self.explorer.forget_explored() {
            return Some("trying given-up frontiers again");
        }
        if self.explorer.look_past_obstacles() {
            return Some("planning past obstacle cells");
        }
        if self.inspections_forgotten < INSPECTION_RESETS && self.explorer.forget_inspected() {
            self.inspections_forgotten += 1;
            return Some("looking again at the walls seen before");
        }
        None
    }

    /// The end of exploring: a sample left on the map at any cost, else home.
    fn finish_exploring(&mut self, obs: &Observation) -> Drive {
        match self.sample_to_chase(obs, f64::INFINITY) {
            Some(chase) => {
                self.enter(State::Approach(chase.clone()), "map explored, sample left");
                self.approach(obs, chase)
            }
            None => {
                let (free_cells, obstacle_cells, unknown_cells) = self.received_map.counts();
                tracing::info!(
                    free_cells,
                    obstacle_cells,
                    unknown_cells,
                    map_version = self.planning.version(),
                    at = ?(obs.position.x_m, obs.position.y_m),
                    rocks = ?self.samples.located(),
                    given_up = ?self.samples.ignored(),
                    "no frontier left"
                );
                self.enter(State::ReturnHome(None), "no frontier left");
                self.return_home(obs, None)
            }
        }
    }

    /// A seen sample within sight or a remembered one, either within `max_cost` on the map, or
    /// at any cost once every sample still missing is remembered (exploring on finds no other).
    fn sample_to_chase(&self, obs: &Observation, max_cost: f64) -> Option<Chase> {
        if obs.samples_remaining == 0 {
            return None;
        }
        let p = &self.params;
        let max_cost = if self.all_missing_samples_located(obs) { f64::INFINITY } else { max_cost };
        let new = |(at, way_m): ((f64, f64), f64)| {
            let give_up_frame = obs.frame + p.frames_for_way(p.sample_timeout_s, way_m);
            let (map, failed) = ((self.planning.grid(), &obs.position), &self.samples.failed_from(at));
            Chase::new(at, (give_up_frame, max_cost), map, failed, p)
        };
        let seen = obs
            .rock
            .filter(|s| s.distance_m <= p.sample_sight_m)
            .map(|s| (obs.position.point_at(s.bearing_rad, s.distance_m), s.distance_m))
            .filter(|&(at, _)| !self.is_ignored(at))
            .filter(|&(at, _)| self.explorer.cost_to(at).is_none_or(|cost| cost <= max_cost));
        seen.or_else(|| {
            self.samples
                .located()
                .iter()
                .copied()
                .filter(|&at| !self.is_ignored(at))
                .filter_map(|at| Some((at, self.explorer.cost_to(at)?)))
                .filter(|&(_, cost)| cost <= max_cost)
                .min_by(|a, b| a.1.total_cmp(&b.1))
        })
        .map(new)
    }

    fn note_failed_approach(&mut self, sample: (f64, f64), obs: &Observation) {
        self.samples.note_failed_approach(sample, obs.frame, (obs.position.x_m, obs.position.y_m));
    }

    /// Whether the rock at `at` is collected, given up, or failed too often lately.
    fn is_given_up(&self, at: (f64, f64)) -> bool {
        self.samples.is_ignored(at, self.frame, self.params.frames(self.params.sample_retry_s))
    }

    /// Whether the rock at `at` is given up ([`Machine::is_given_up`]) or left alone for now as
    /// out of the way.
    fn is_ignored(&self, at: (f64, f64)) -> bool {
        self.is_given_up(at) || self.samples.is_deferred(at, self.frame)
    }

    /// Whether the map holds at least as many rocks not given up as samples are missing.
    fn all_missing_samples_located(&self, obs: &Observation) -> bool {
        let waiting = self.samples.located().iter().filter(|&&at| !self.is_given_up(at));
        waiting.count() >= obs.samples_remaining as usize
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
            self.note_failed_approach(chase.at, obs);
            self.enter(State::Explore, "sample not reached in time");
            return Drive::stop(p.brake);
        }
        let from = PlanStart { map: &self.planning, at: &obs.position, frame: obs.frame, params: &p };
        if chase.missing(&from, obs.rock.is_some()) {
            self.note_failed_approach(chase.at, obs);
            self.enter(State::Explore, "sample not where remembered");
            return Drive::stop(p.brake);
        }
        let aim = chase.aim(&from);
        if chase.out_of_the_way() {
            let until_frame = obs.frame + p.frames(OUT_OF_THE_WAY_S);
            self.samples.defer(chase.at, until_frame);
            self.samples.defer(chase.first_at, until_frame);
            self.enter(State::Explore, "sample out of the way on the map");
            return self.explore(obs);
        }
        let distance_m = obs.position.distance_to(chase.at);
        let speed = speed_to_stop_in(distance_m - ARM_REACH_M, &p).clamp(p.approach_speed_mps, p.max_speed_mps);
        let drive = match aim {
            Aim::AroundObstacles(point) => {
                let bearing = obs.position.bearing_to(point);
                self.steering.around_obstacles(bearing, p.max_speed_mps, obs.speed_mps, &obs.free, &p)
            }
            Aim::Straight(point) => {
                let (bearing, distance_m) = (obs.position.bearing_to(point), obs.position.distance_to(point));
                self.steering.toward_point(bearing, distance_m, speed, obs.speed_mps, &p)
            }
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
            self.samples.ignore(obs.position.point_at(0.0, ARM_REACH_M));
            self.enter(State::Explore, "sample collected");
        } else if !obs.near_sample && obs.speed_mps.abs() < STOPPED_MPS {
            self.enter(State::Explore, "sample out of reach");
        } else if waited >= p.frames(p.pickup_wait_s) {
            self.samples.ignore(obs.position.point_at(0.0, ARM_REACH_M));
            self.enter(State::Explore, "no pickup came");
        }
        Drive::stop(p.brake)
    }

    fn recover(&mut self, obs: &Observation, since_frame: u64, turn_left: bool, then_home: bool) -> Drive {
        let p = self.params.clone();
        let elapsed = obs.frame.saturating_sub(since_frame);
        let back = p.frames(p.recover_back_s);
        if elapsed < back {
            return Drive { throttle: -p.recover_throttle, brake: 0.0, steering_deg: 0.0 };
        }
        if elapsed < back + p.frames(p.recover_turn_s) {
            // Backing up ends in a full stop before the turn.
            return if obs.speed_mps.abs() > STOPPED_MPS {
                Drive::stop(p.brake)
            } else {
                Drive::turn_in_place(turn_left)
            };
        }
        self.enter(if then_home { State::ReturnHome(None) } else { State::Explore }, "recovered");
        Drive::stop(p.brake)
    }

    fn return_home(&mut self, obs: &Observation, route: Option<Route>) -> Drive {
        let p = self.params.clone();
        let Some(home) = self.status.home else {
            self.state = State::ReturnHome(route);
            return Drive::stop(p.brake);
        };
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
        let mut waypoint = self.waypoint_on(route.as_mut(), obs);
        if waypoint.is_none() && self.forget_stuck_marks() {
            tracing::info!("home unreachable: the cells where the rover got stuck are free again");
            waypoint = self.waypoint_on(route.as_mut(), obs);
        }
        let waypoint = waypoint.unwrap_or(home);
        let bearing = obs.position.bearing_to(waypoint);
        let cruise = p.max_speed_mps.min(distance_m.max(p.approach_speed_mps));
        let drive = self.steering.around_obstacles(bearing, cruise, obs.speed_mps, &obs.free, &p);
        self.state = State::ReturnHome(route);
        drive
    }

    /// The point of `route` to steer toward from the rover's position on the planning map; none
    /// without a route or when its goal cannot be reached.
    fn waypoint_on(&self, route: Option<&mut Route>, obs: &Observation) -> Option<(f64, f64)> {
        let start = PlanStart { map: &self.planning, at: &obs.position, frame: obs.frame, params: &self.params };
        route?.waypoint(&start)
    }
}

/// Whether `map` says nothing yet and is ignored: a map without free cells (the mapping node's
/// first publication, before any scan), which could otherwise end the exploration.
fn is_ignored(map: &Grid) -> bool {
    map.counts().0 == 0
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use rover_msgs::map_grid::{CELLS, cell_at, cell_of_point};

    use crate::approach::UNSEEN_S;
    use crate::arrivals::ARRIVAL_DELAY_FRAMES;
    use crate::grid::Cell;
    use crate::samples::APPROACHES_PER_ROCK;
    use crate::stuck::STUCK_MARK_S;

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

    /// A machine with the default parameters that has received `map`.
    fn machine_on(map: Grid) -> Machine {
        machine_on_with(map, DecisionParams::default())
    }

    /// A machine with `params` that has received `map`.
    fn machine_on_with(map: Grid, params: DecisionParams) -> Machine {
        let mut machine = Machine::new(params);
        machine.set_map(map);
        machine
    }

    /// A corridor along y = 100 from x = 90 to 130, unknown beyond x = 130.
    fn corridor() -> Grid {
        let mut data = vec![100i8; CELLS];
        for y in 98..103 {
            for x in 90..140 {
                data[cell_at(x, y)] = if x < 130 { 0 } else { -1 };
            }
        }
        Grid::from_occupancy(&data).unwrap()
    }

    #[test]
    fn a_map_without_free_cells_does_not_end_the_exploration() {
        let params = DecisionParams::default();
        let mut machine = machine_on(Grid::unknown());
        for frame in 1..params.frames(params.stuck_s) {
            let drive = machine.step(&observation(frame, 100.5, 100.5));
            assert!(drive.throttle > 0.0, "frame {frame}: {drive:?}");
        }
        assert_eq!(machine.status().mode, Mode::Explore);
    }

    #[test]
    fn a_rover_that_the_map_walls_in_backs_out_instead_of_giving_the_frontiers_up() {
        let params = DecisionParams::default();
        let mut machine = machine_on(corridor());
        let among_rock_cells = observation(1, 110.5, 106.5);
        machine.step(&among_rock_cells);
        assert_eq!(machine.status().mode, Mode::Recover, "{:?}", machine.status());
        assert!(machine.status().reason.contains("walled in"), "{:?}", machine.status());
        let mut in_the_corridor = Machine::new(params);
        in_the_corridor.set_map(corridor());
        in_the_corridor.step(&observation(1, 110.5, 100.5));
        assert_eq!(in_the_corridor.status().mode, Mode::Explore);
    }

    #[test]
    fn a_recalled_machine_keeps_what_the_exploration_learnt_and_the_way_home() {
        let params = DecisionParams::default();
        let mut first = machine_on(corridor());
        for frame in 1..50 {
            first.step(&observation(frame, 100.5 + frame as f64 * 0.1, 100.5));
        }
        let learnt = first.recollection();
        assert!(learnt.explorer.inspected.iter().any(|&cell| cell), "the camera saw cells up close");
        let mut second = Machine::new(params);
        second.recall(learnt.clone());
        assert_eq!(second.recollection(), learnt);
        second.recall(Recollection { stage: Stage::ReturningHome, ..learnt });
        assert_eq!(second.status().mode, Mode::ReturnHome);
    }

    /// A machine recalled at `stage` from one whose home is (100.5, 100.5), on the corridor map,
    /// that has been stepped for ten frames at (`x_m`, 100.5) before the mission reached it:
    /// it braked in `mode` on every one.
    fn recalled_and_braked(stage: Stage, x_m: f64, mode: Mode) -> Machine {
        let mut first = machine_on(corridor());
        first.step(&observation(1, 100.5, 100.5));
        let mut second = machine_on(corridor());
        second.recall(Recollection { stage, ..first.recollection() });
        for frame in 100..110 {
            let drive = second.step(&observation(frame, x_m, 100.5));
            assert_eq!((drive.throttle, second.status().mode), (0.0, mode), "frame {frame}");
            assert!(drive.brake > 0.0, "brakes while the mission is unknown");
        }
        second
    }

    #[test]
    fn a_machine_recalled_while_exploring_brakes_until_the_mission_arrives_then_explores() {
        let mut machine = recalled_and_braked(Stage::Exploring, 104.5, Mode::Explore);
        machine.resume(Memory { home: (100.5, 100.5), samples_collected: 2 });
        let drive = machine.step(&observation(110, 104.5, 100.5));
        let moves = drive.throttle > 0.0 || drive.steering_deg != 0.0;
        assert!(moves && drive.brake == 0.0 && machine.status().mode == Mode::Explore, "explores: {drive:?}");
    }

    #[test]
    fn a_machine_recalled_on_the_way_home_waits_for_the_missions_home_before_it_is_done() {
        let mut machine = recalled_and_braked(Stage::ReturningHome, 110.5, Mode::ReturnHome);
        machine.resume(Memory { home: (100.5, 100.5), samples_collected: 6 });
        let drive = machine.step(&observation(110, 110.5, 100.5));
        assert_eq!(machine.status().mode, Mode::ReturnHome, "10 m from home is not home");
        assert_eq!(machine.status().home, Some((100.5, 100.5)));
        assert!(drive.brake == 0.0, "{drive:?}");
    }

    #[test]
    fn the_path_followed_while_exploring_leads_to_the_frontier_target() {
        let mut machine = machine_on(corridor());
        assert!(machine.path().is_empty(), "no plan before the first frame");
        machine.step(&observation(1, 100.5, 100.5));
        let path = machine.path();
        let (first, last) = (cell_centre_m(path[0]), cell_centre_m(path[path.len() - 1]));
        assert_eq!(first, (100.5, 100.5), "from the rover's cell");
        assert_eq!(Some(last), machine.explorer.target(), "to the target");
    }

    #[test]
    fn a_rover_that_turns_on_one_spot_for_long_recovers() {
        let params = DecisionParams::default();
        let mut machine = machine_on(corridor());
        let facing_away = |frame| {
            let mut obs = observation(frame, 91.5, 100.5);
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
    fn a_sample_ahead_is_approached_as_fast_as_braking_leaves_it_in_reach() {
        let params = DecisionParams::default();
        let speed_toward = |distance_m: f64, speed_mps: f64| {
            let mut machine = machine_on(corridor());
            let mut obs = observation(1, 100.5, 100.5);
            (obs.rock, obs.speed_mps) = (Some(Sighting { bearing_rad: 0.0, distance_m }), speed_mps);
            machine.step(&obs)
        };
        let far = speed_toward(3.5, 2.0);
        assert!(far.throttle > 0.0 && far.brake == 0.0, "2 m/s is safe 3.5 m off: {far:?}");
        let near = speed_toward(1.2, 2.0);
        assert!(near.brake > 0.0, "2 m/s 1.2 m off would overrun the sample: {near:?}");
        let creep = speed_toward(0.9, params.approach_speed_mps * 0.5);
        assert!(creep.throttle > 0.0, "the last metres at the approach speed: {creep:?}");
        let stopping_m = |v: f64| v * v / (2.0 * params.stop_decel_mps2);
        let v = speed_to_stop_in(3.5 - ARM_REACH_M, &params);
        assert!((stopping_m(v) - (3.5 - ARM_REACH_M)).abs() < 1e-9);
    }

    /// Two corridors along y = 98..103 and y = 106..111 from x = 90 to 140, joined at x = 135..140.
    fn two_corridors() -> Grid {
        let mut data = vec![100i8; CELLS];
        for y in (98..103).chain(106..111) {
            for x in 90..140 {
                data[cell_at(x, y)] = 0;
            }
        }
        for y in 103..106 {
            for x in 135..140 {
                data[cell_at(x, y)] = 0;
            }
        }
        Grid::from_occupancy(&data).unwrap()
    }

    #[test]
    fn a_seen_sample_that_the_map_puts_a_long_way_round_is_left_for_later_unless_it_is_the_last() {
        let sample_across_the_wall = |sample_detour_cost: f64, samples_remaining: u8| {
            let mut machine =
                machine_on_with(two_corridors(), DecisionParams { sample_detour_cost, ..Default::default() });
            machine.set_rocks(vec![(100.5, 107.5)]);
            let mut modes = Vec::new();
            for frame in 1..machine.params.frames(machine.params.stuck_s) {
                let mut obs = Observation { samples_remaining, ..observation(frame, 100.5, 100.5) };
                obs.rock = Some(Sighting { bearing_rad: std::f64::consts::FRAC_PI_2, distance_m: 7.0 });
                machine.step(&obs);
                modes.push(machine.status().mode);
            }
            (modes, machine.status().reason.clone())
        };
        let (modes, reason) = sample_across_the_wall(60.0, 2);
        assert!(modes.iter().all(|&mode| mode == Mode::Explore), "{modes:?}");
        assert_eq!(reason, "sample out of the way on the map");
        let (modes, _) = sample_across_the_wall(200.0, 2);
        assert!(modes.iter().all(|&mode| mode == Mode::ApproachSample), "80 m round is worth 200: {modes:?}");
        let (modes, _) = sample_across_the_wall(60.0, 1);
        assert!(modes.iter().all(|&mode| mode == Mode::ApproachSample), "the last sample missing: {modes:?}");
    }

    #[test]
    fn a_remembered_sample_that_the_camera_places_a_long_way_round_is_left_alone_where_both_put_it() {
        let mut machine = machine_on(two_corridors());
        machine.set_rocks(vec![(110.5, 101.5)]);
        for frame in 1..machine.params.frames(machine.params.stuck_s) {
            let mut obs = Observation { samples_remaining: 2, ..observation(frame, 100.5, 100.5) };
            let across_the_wall = (108.5f64 - 100.5).atan2(107.5 - 100.5);
            obs.rock = Some(Sighting { bearing_rad: across_the_wall, distance_m: 7.0f64.hypot(8.0) });
            machine.step(&obs);
            assert_eq!(machine.status().mode, Mode::Explore, "frame {frame}");
        }
        assert!(machine.is_ignored((110.5, 101.5)) && machine.is_ignored((107.5, 108.5)));
    }

    #[test]
    fn a_remembered_sample_that_the_camera_does_not_see_from_close_by_is_given_up_for_a_while() {
        let params = DecisionParams::default();
        let mut machine = machine_on(corridor());
        machine.set_rocks(vec![(102.5, 100.5)]);
        machine.step(&observation(1, 100.5, 100.5));
        let mut given_up = Vec::new();
        for frame in 2..10 * params.frames(UNSEEN_S) {
            machine.step(&observation(frame, 100.5, 100.5));
            if machine.take_change() && machine.status().reason == "sample not where remembered" {
                given_up.push((machine.status().mode, machine.is_ignored((102.5, 100.5))));
            }
        }
        assert_eq!(given_up.len(), APPROACHES_PER_ROCK, "approached and not seen, then given up: {given_up:?}");
        assert_eq!(given_up.last(), Some(&(Mode::Explore, true)), "back to exploring, the sample ignored");
        machine.frame += params.frames(params.sample_retry_s);
        assert!(!machine.is_ignored((102.5, 100.5)), "tried again later");
    }

    #[test]
    fn a_slow_approach_is_not_stuck_a_stopped_rover_is() {
        let params = DecisionParams::default();
        let mut machine = Machine::new(params.clone());
        machine.last_drive = Drive { throttle: 0.2, brake: 0.0, steering_deg: 0.0 };
        let slow = |frame: u64, speed_mps: f64| {
            let mut obs = observation(frame, 100.0 + 0.004 * frame as f64, 100.5);
            obs.speed_mps = speed_mps;
            obs
        };
        let watch = params.frames(params.stuck_s) + 2;
        assert!((1..watch).all(|frame| !machine.stuck(&slow(frame, 0.15))), "0.15 m/s, less than 0.3 m in 1.5 s");
        assert!((watch..2 * watch).any(|frame| machine.stuck(&slow(frame, 0.0))), "stopped");
    }

    #[test]
    fn a_rover_that_pushes_against_a_rock_and_turns_in_between_is_stuck() {
        let params = DecisionParams::default();
        let mut machine = Machine::new(params.clone());
        let (push, turn) = (Drive { throttle: 1.0, brake: 0.0, steering_deg: 0.0 }, Drive::turn_in_place(true));
        let stuck_at = (1..20 * params.frames(params.stuck_s)).find(|&frame| {
            machine.last_drive = if frame % 8 < 4 { push } else { turn };
            machine.stuck(&observation(frame, 100.0, 100.5))
        });
        let stuck_at = stuck_at.expect("stuck while alternating pushes and turns");
        assert!(
            stuck_at <= 2 * params.frames(params.stuck_s) + 8,
            "stuck after {stuck_at} frames: about twice the time of a push"
        );
    }

    #[test]
    fn getting_stuck_makes_the_cell_ahead_an_obstacle_until_nothing_else_is_left() {
        let params = DecisionParams::default();
        let mut machine = machine_on(corridor());
        let ahead = cell_of_point(101.4, 100.5).unwrap();
        assert_eq!(machine.planning.grid().cell(ahead), Cell::Free);
        machine.mark_stuck_cell(&observation(10, 100.5, 100.5));
        assert_eq!(machine.planning.grid().cell(ahead), Cell::Blocked, "stuck here: the cell ahead is an obstacle");
        assert_eq!(machine.received_map.cell(ahead), Cell::Free, "the map itself is kept");
        machine.set_map(corridor());
        assert_eq!(machine.planning.grid().cell(ahead), Cell::Blocked, "and stays marked in the next map");
        assert!(machine.forget_stuck_marks() && machine.planning.grid().cell(ahead) == Cell::Free);
        machine.mark_stuck_cell(&observation(300, 100.5, 100.5));
        machine.frame = 300 + params.frames(STUCK_MARK_S) - 1;
        machine.set_map(corridor());
        assert_eq!(machine.planning.grid().cell(ahead), Cell::Blocked, "marked again");
        machine.frame += 1;
        machine.set_map(corridor());
        assert_eq!(machine.planning.grid().cell(ahead), Cell::Free, "until the mark expires");
    }

    #[test]
    fn exploring_keeps_the_stuck_marks_where_forgetting_them_got_the_rover_stuck_again() {
        let mut machine = machine_on(corridor());
        let ahead = cell_of_point(101.4, 100.5).unwrap();
        let stuck_here = observation(10, 100.5, 100.5);
        machine.mark_stuck_cell(&stuck_here);
        assert!(machine.forget_stuck_marks_to_explore(&stuck_here.position), "forgotten the first time");
        assert_eq!(machine.planning.grid().cell(ahead), Cell::Free);
        machine.mark_stuck_cell(&observation(20, 101.0, 100.5));
        assert!(!machine.forget_stuck_marks_to_explore(&observation(21, 101.0, 100.5).position));
        assert_eq!(machine.planning.grid().cell(ahead), Cell::Blocked, "stuck again there: the mark holds");
        assert!(machine.forget_stuck_marks_to_explore(&observation(90, 104.5, 100.5).position), "away from there");
        assert_eq!(machine.planning.grid().cell(ahead), Cell::Free);
    }

    #[test]
    fn a_way_home_that_the_stuck_marks_cut_off_is_planned_again_without_them() {
        let params = DecisionParams::default();
        let mut machine = machine_on(corridor());
        machine.step(&observation(1, 100.5, 100.5));
        for y in 98..103 {
            let facing_the_corridor_wall = Position { x_m: 119.5, y_m: y as f64 + 0.5, yaw_rad: 0.0 };
            machine.stuck_marks.note_stuck((&facing_the_corridor_wall, 2), machine.planning.grid(), &[], &params);
            machine.apply_stuck_marks();
        }
        let across = cell_of_point(120.5, 100.5).unwrap();
        assert_eq!(machine.planning.grid().cell(across), Cell::Blocked, "the marks close the corridor");
        machine.enter(State::ReturnHome(None), "test");
        let mut beyond_the_marks = observation(3, 125.5, 100.5);
        beyond_the_marks.position.yaw_rad = std::f64::consts::PI;
        let drive = machine.step(&beyond_the_marks);
        assert_eq!(machine.planning.grid().cell(across), Cell::Free, "the marks are forgotten");
        assert!(!machine.path().is_empty(), "a route home along the corridor");
        assert!(drive.throttle > 0.0 && drive.steering_deg.abs() < 1.0, "straight home: {drive:?}");
    }

    #[test]
    fn a_received_map_is_planned_on_from_the_arrival_delay_after_its_frame() {
        let mut machine = Machine::new(DecisionParams::default());
        machine.receive_map(5, corridor());
        machine.step(&observation(5 + ARRIVAL_DELAY_FRAMES - 1, 100.5, 100.5));
        assert_eq!(machine.received_map.counts(), Grid::unknown().counts(), "not yet due");
        machine.step(&observation(5 + ARRIVAL_DELAY_FRAMES, 100.5, 100.5));
        assert_eq!(machine.received_map.counts(), corridor().counts(), "due");
    }

    #[test]
    fn after_two_maps_the_planning_map_expects_the_next_as_long_after_the_last() {
        let mut machine = Machine::new(DecisionParams::default());
        for made_at in [5, 30] {
            machine.receive_map(made_at, corridor());
            machine.step(&observation(made_at + ARRIVAL_DELAY_FRAMES, 100.5, 100.5));
        }
        assert_eq!(machine.planning.next_map_frame(), Some(55 + ARRIVAL_DELAY_FRAMES));
        machine.receive_map(50, corridor());
        machine.step(&observation(50 + ARRIVAL_DELAY_FRAMES, 100.5, 100.5));
        assert_eq!(machine.planning.next_map_frame(), Some(70 + ARRIVAL_DELAY_FRAMES), "a map 20 frames on");
    }

    /// A machine planning in [`corridor`] at frame 3 that has prepared the next frame, on which
    /// a copy of the corridor map takes effect; that frame's observation.
    fn prepared_for_a_map_due_next() -> (Machine, Observation) {
        let (mut machine, _) = started_at_home_in_the_corridor();
        let here = observation(3, 100.5, 100.5);
        machine.receive_map(here.frame + 1 - ARRIVAL_DELAY_FRAMES, corridor());
        machine.step(&here);
        machine.prepare_next_frame(&here.position);
        (machine, observation(here.frame + 1, 100.5, 100.5))
    }

    #[test]
    fn the_first_plan_on_a_map_due_next_frame_is_searched_between_frames() {
        let (mut machine, next_frame) = prepared_for_a_map_due_next();
        let version = machine.planning.version();
        let next = machine.next_planning.as_ref().expect("made for the map due next");
        assert_eq!((next.version(), next.made_from()), (version + 1, cell_of_point(100.5, 100.5)));
        let made = next.made_costs().expect("costs made ahead");
        machine.step(&next_frame);
        assert_eq!(machine.planning.version(), version + 1);
        let taken = machine.planning.last_costs().expect("planned on the new map");
        assert!(Arc::ptr_eq(&made, &taken), "the first plan on it took the costs made ahead");
        machine.receive_map(next_frame.frame + 1 - ARRIVAL_DELAY_FRAMES, Grid::unknown());
        machine.prepare_next_frame(&next_frame.position);
        assert!(machine.next_planning.is_none(), "nothing made for a map that will be ignored");
    }

    #[test]
    fn costs_made_ahead_start_where_the_rover_will_be_if_it_keeps_going() {
        let (mut machine, _) = started_at_home_in_the_corridor();
        let before = observation(2, 100.3, 100.5);
        machine.step(&before);
        machine.prepare_next_frame(&before.position);
        let here = observation(3, 100.7, 100.5);
        machine.receive_map(here.frame + 1 - ARRIVAL_DELAY_FRAMES, corridor());
        machine.step(&here);
        machine.prepare_next_frame(&here.position);
        let one_frame_on = cell_of_point(101.1, 100.5);
        assert_ne!(one_frame_on, cell_of_point(100.7, 100.5), "the next frame is in the next cell");
        let next = machine.next_planning.as_ref().expect("made for the map due next");
        assert_eq!(next.made_from(), one_frame_on);
        let made = next.made_costs().expect("costs made ahead");
        machine.step(&observation(here.frame + 1, 101.1, 100.5));
        let taken = machine.planning.last_costs().expect("planned on the new map");
        assert!(Arc::ptr_eq(&made, &taken), "the next frame took the costs made ahead");
    }

    #[test]
    fn a_planning_map_made_ahead_for_another_map_is_not_taken() {
        let (mut machine, next_frame) = prepared_for_a_map_due_next();
        let made = machine.next_planning.as_ref().and_then(PlanningMap::made_costs).expect("made ahead");
        let mut other = corridor();
        other.block(cell_of_point(100.5, 101.5).unwrap());
        machine.receive_map(next_frame.frame - ARRIVAL_DELAY_FRAMES, other.clone());
        machine.step(&next_frame);
        assert!(machine.next_planning.is_none(), "dropped once the frame has begun");
        assert_eq!(*machine.planning.grid(), other, "the newer map");
        let taken = machine.planning.last_costs().expect("planned on the new map");
        assert!(!Arc::ptr_eq(&made, &taken), "searched on the newer map");
    }

    /// A machine that started its mission at (100.5, 100.5) in [`corridor`], and the frame of its
    /// mission deadline.
    fn started_at_home_in_the_corridor() -> (Machine, u64) {
        let params = DecisionParams::default();
        let mut machine = machine_on(corridor());
        machine.step(&observation(1, 100.5, 100.5));
        (machine, params.frames(params.mission_deadline_s))
    }

    #[test]
    fn a_rover_stuck_on_the_way_home_recovers_and_goes_on_home() {
        let (mut machine, late) = started_at_home_in_the_corridor();
        machine.step(&observation(late, 120.5, 100.5));
        assert_eq!(machine.status().mode, Mode::ReturnHome);
        let mut frame = late;
        while machine.status().mode == Mode::ReturnHome {
            frame += 1;
            let mut blocked = observation(frame, 120.5, 100.5);
            blocked.position.yaw_rad = std::f64::consts::PI;
            machine.step(&blocked);
            assert!(frame < late + 100, "never stuck");
        }
        assert_eq!((machine.status().mode, machine.status().reason.as_str()), (Mode::Recover, "stuck"));
        while machine.status().mode == Mode::Recover {
            frame += 1;
            machine.step(&observation(frame, 120.0, 100.5));
        }
        assert_eq!(machine.status().mode, Mode::ReturnHome, "after the recovery: {:?}", machine.status());
    }

    #[test]
    fn at_the_deadline_the_rover_goes_home_without_detours_and_stops_there() {
        let (mut machine, late) = started_at_home_in_the_corridor();
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
