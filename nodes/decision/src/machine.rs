//! The decision state machine: explore, approach a sample, wait for the pickup, recover, return
//! home, done. One [`Machine::step`] per frame turns an observation into a drive command; each
//! mode is a module of its own, and the machine holds what they share and dispatches.

use rover_msgs::tally::SampleTally;

use crate::approach::Chase;
use crate::drive::{Drive, Steering};
use crate::explore::{Explorer, ExplorerMemory};
use crate::grid::Grid;
use crate::local::FreeSpace;
use crate::params::DecisionParams;
use crate::pose::Position;
use crate::route::Route;
use crate::samples::SampleMemory;
use crate::trail::Trail;

mod approach;
mod commands;
mod explore;
mod look_around;
mod maps;
mod navigate;
mod pickup;
mod recover;
mod return_home;
#[cfg(test)]
mod tests;

pub use commands::CommandAnswer;
use commands::Orders;
use explore::Search;
use maps::Maps;
pub use navigate::{GoalFailure, NavigationEnd, NavigationProgress};
use recover::{Recovery, Watches};

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
    /// Holding still until the mission is started.
    Idle,
    /// Holding still until the mission is resumed.
    Paused,
    /// Driving to a goal given from outside; the mission waits.
    Navigate,
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
            Mode::Idle => "idle",
            Mode::Paused => "paused",
            Mode::Navigate => "navigate",
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

/// What a mode's step decides for one frame.
enum Next {
    /// Stay in the mode, with this state, and drive.
    Stay(State, Drive),
    /// Enter another mode for a reason, braking this frame.
    Enter(State, &'static str),
    /// Enter another mode for a reason and step it in this same frame.
    EnterAndStep(State, &'static str),
    /// Leave the mode in state `from` for a recovery, braking this frame.
    Recover { from: State, reason: &'static str },
}

#[derive(Debug, Clone)]
enum State {
    Explore,
    Approach(Chase),
    Pickup {
        since_frame: u64,
        arm_seen: bool,
    },
    /// Backing off and turning, or retracing the way in; then back to exploring, or on the way
    /// home when that was interrupted (exploring would forget the stuck marks that lead the next
    /// route around).
    Recover {
        recovery: Recovery,
        then_home: bool,
    },
    ReturnHome(Option<Route>),
    Done,
}

impl State {
    /// The mode this state is published as.
    fn mode(&self) -> Mode {
        match self {
            State::Explore => Mode::Explore,
            State::Approach(_) => Mode::ApproachSample,
            State::Pickup { .. } => Mode::Pickup,
            State::Recover { .. } => Mode::Recover,
            State::ReturnHome(_) => Mode::ReturnHome,
            State::Done => Mode::Done,
        }
    }
}

/// Where the mission stands: what the machine reports, the samples collected, and home.
#[derive(Debug, Clone)]
struct Mission {
    status: Status,
    /// The status changed since it was last taken ([`Machine::take_change`]).
    changed: bool,
    tally: SampleTally,
    /// The frame of the last step.
    frame: u64,
    /// Recalled from an earlier machine: home comes from the mission ([`Machine::resume`]), not
    /// from where the rover happens to stand at this machine's first frame, and until it does
    /// the machine brakes (its map, rocks and tally may not have caught up with the mission).
    awaits_home: bool,
}

/// The decision state machine.
#[derive(Debug, Clone)]
pub struct Machine {
    params: DecisionParams,
    state: State,
    mission: Mission,
    maps: Maps,
    samples: SampleMemory,
    explorer: Explorer,
    driving: Driving,
    search: Search,
    orders: Orders,
}

/// How the rover drives and whether it gets anywhere: shared by every mode that moves.
#[derive(Debug, Clone, Default)]
struct Driving {
    steering: Steering,
    watches: Watches,
    /// Where the rover was at the last frame.
    last_position: Option<Position>,
    /// The way it came, to retrace out of a pocket.
    trail: Trail,
}

impl Machine {
    /// A machine at the start of a mission.
    pub fn new(params: DecisionParams) -> Self {
        let started = params.start_mission;
        let mode = if started { Mode::Explore } else { Mode::Idle };
        let status = Status { mode, reason: "start".to_string(), target: None, samples_collected: 0, home: None };
        Machine {
            params,
            state: State::Explore,
            mission: Mission { status, changed: true, tally: SampleTally::default(), frame: 0, awaits_home: false },
            maps: Maps::default(),
            samples: SampleMemory::default(),
            explorer: Explorer::default(),
            driving: Driving::default(),
            search: Search::default(),
            orders: Orders { started, ..Orders::default() },
        }
    }

    /// Takes over a mission an earlier machine started: its home and the samples it collected.
    pub fn resume(&mut self, memory: Memory) {
        let mission = &mut self.mission;
        mission.status.home = Some(memory.home);
        mission.awaits_home = false;
        mission.tally = SampleTally::starting_at(memory.samples_collected);
        mission.status.samples_collected = memory.samples_collected;
        mission.status.reason = "resumed".to_string();
        mission.changed = true;
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
        self.mission.awaits_home = self.mission.status.home.is_none();
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
    /// unless it says nothing yet (no free cell: the mapping node's first publication).
    pub fn set_map(&mut self, map: Grid) {
        self.maps.set_map(map, self.mission.frame);
    }

    /// Takes the located rocks, world positions.
    pub fn set_rocks(&mut self, rocks: Vec<(f64, f64)>) {
        self.samples.set_located(rocks);
    }

    /// Takes a map made from the scans up to mission frame `made_at_frame`, in effect
    /// a few frames after it, as a map travels (at once if that frame has passed).
    pub fn receive_map(&mut self, made_at_frame: u64, map: Grid) {
        self.maps.receive_map(made_at_frame, map);
    }

    /// Takes the rocks located by the scans up to mission frame `made_at_frame`, in effect as a
    /// map received with them.
    pub fn receive_rocks(&mut self, made_at_frame: u64, rocks: Vec<(f64, f64)>) {
        self.maps.receive_rocks(made_at_frame, rocks);
    }

    /// The reported state.
    pub fn status(&self) -> &Status {
        &self.mission.status
    }

    /// The cells of the path on the map that the rover follows now: to the frontier, the sample or
    /// home (empty when it follows none: turning, picking up, recovering, done).
    pub fn path(&self) -> &[usize] {
        if let Some(path) = self.navigation_path() {
            return path;
        }
        match &self.state {
            State::Explore => self.explorer.path(),
            State::Approach(chase) => chase.path(),
            State::ReturnHome(Some(route)) => route.path(),
            _ => &[],
        }
    }

    /// Whether the mode changed since the last call.
    pub fn take_change(&mut self) -> bool {
        std::mem::take(&mut self.mission.changed)
    }

    /// Decides the drive command for one frame.
    pub fn step(&mut self, obs: &Observation) -> Drive {
        if !self.mission.awaits_home {
            self.mission.status.home.get_or_insert((obs.position.x_m, obs.position.y_m));
        }
        self.mission.frame = obs.frame;
        if let Some(rocks) = self.maps.take_arrivals(obs.frame) {
            self.set_rocks(rocks);
        }
        self.explorer.inspect(&obs.position, &self.params);
        self.mission.tally.update(obs.samples_remaining);
        self.mission.status.samples_collected = self.mission.tally.collected();
        let drive = self.decide(obs);
        self.driving.last_position = Some(obs.position);
        self.driving.trail.record((obs.position.x_m, obs.position.y_m));
        self.mission.status.target = self.target();
        tracing::trace!(
            frame = obs.frame,
            x = obs.position.x_m,
            y = obs.position.y_m,
            yaw_deg = obs.position.yaw_rad.to_degrees(),
            speed = obs.speed_mps,
            mode = self.mission.status.mode.name(),
            target = ?self.mission.status.target,
            rock = ?obs.rock,
            ?drive,
            "decided"
        );
        self.driving.watches.last_drive = drive;
        drive
    }

    /// The stuck and stall watches and the steering start afresh: after the rover was held still
    /// from outside (the node inactive), so that the held frames do not count as stuck, and
    /// whenever what the rover does changes.
    pub fn start_afresh(&mut self) {
        self.driving.steering.reset();
        self.driving.watches.reset();
    }

    /// Between frames, after the drive command of the last one went out, the rover now at `at`:
    /// makes ahead the path costs the next frame will likely ask for. What the machine decides
    /// does not change, only when the search runs.
    pub fn prepare_next_frame(&mut self, at: &Position) {
        self.maps.prepare_next_frame(self.mission.frame, at, &self.params);
    }

    /// The goal of the current mode in the world, if it has one.
    fn target(&self) -> Option<(f64, f64)> {
        if let Some(progress) = self.navigation_progress() {
            return Some(progress.goal);
        }
        match &self.state {
            State::Explore => self.explorer.target(),
            State::Approach(chase) => Some(chase.at),
            State::ReturnHome(_) | State::Done => self.mission.status.home,
            State::Pickup { .. } | State::Recover { .. } => None,
        }
    }

    /// Switches to `state` for `reason`: logged, reported, and the watches and steering start
    /// afresh.
    fn enter(&mut self, state: State, reason: &str) {
        let mode = state.mode();
        let status = &mut self.mission.status;
        tracing::info!("mode {} -> {}: {reason}", status.mode.name(), mode.name());
        if mode == Mode::Explore && matches!(status.mode, Mode::ApproachSample | Mode::Pickup) {
            self.explorer.resume_after_detour(self.mission.frame);
        }
        self.search.look_around.interrupt();
        self.state = state;
        status.mode = mode;
        status.reason = reason.to_string();
        self.mission.changed = true;
        self.start_afresh();
    }

    /// The mode shown: a command's hold or navigation over the mission, else the mission's mode.
    fn shown_mode(&self) -> Mode {
        if self.orders.paused {
            Mode::Paused
        } else if self.orders.navigation.is_some() {
            Mode::Navigate
        } else if !self.orders.started {
            Mode::Idle
        } else {
            self.state.mode()
        }
    }

    /// Reports the mode shown when a command changed it, for `reason`; the watches and steering
    /// start afresh (the rover held still or drove elsewhere meanwhile).
    fn show_mode(&mut self, reason: &str) {
        let mode = self.shown_mode();
        let status = &mut self.mission.status;
        if status.mode != mode {
            tracing::info!("mode {} -> {}: {reason}", status.mode.name(), mode.name());
            status.mode = mode;
            status.reason = reason.to_string();
            self.mission.changed = true;
        }
        self.start_afresh();
    }

    /// Holds still while paused, not started or recalled without home yet; drives a navigation;
    /// else enters pickup when the arm is busy or a sample is in reach, recovers when in trouble,
    /// and runs the mode's step.
    fn decide(&mut self, obs: &Observation) -> Drive {
        if self.mission.awaits_home || self.orders.paused {
            return Drive::stop(self.params.brake);
        }
        if let Some(navigation) = self.orders.navigation.take() {
            return self.navigate(obs, navigation);
        }
        if !self.orders.started {
            return Drive::stop(self.params.brake);
        }
        let (pickup, done) = (matches!(self.state, State::Pickup { .. }), matches!(self.state, State::Done));
        if !pickup && !done && (obs.picking_up || obs.near_sample) {
            let reason = if obs.picking_up { "the arm is picking up" } else { "sample within reach" };
            self.enter(State::Pickup { since_frame: obs.frame, arm_seen: false }, reason);
        } else if !pickup && !done && !matches!(self.state, State::Recover { .. }) {
            self.check_for_trouble(obs);
        }
        let drive = self.step_mode(obs);
        debug_assert_eq!(self.state.mode(), self.mission.status.mode, "a mode put its state back");
        drive
    }

    /// Steps the mode and follows its [`Next`]: a mode entered to be stepped at once steps in
    /// the same frame.
    fn step_mode(&mut self, obs: &Observation) -> Drive {
        let brake = Drive::stop(self.params.brake);
        loop {
            // A mode takes its state while it steps and hands back the one that follows;
            // meanwhile `status.mode` says which mode runs.
            let next = match std::mem::replace(&mut self.state, State::Done) {
                State::Explore => self.explore(obs),
                State::Approach(chase) => self.approach(obs, chase),
                State::Pickup { since_frame, arm_seen } => self.pickup(obs, since_frame, arm_seen),
                State::Recover { recovery, then_home } => self.recover(obs, recovery, then_home),
                State::ReturnHome(route) => self.return_home(obs, route),
                State::Done => Next::Stay(State::Done, brake),
            };
            match next {
                Next::Stay(state, drive) => {
                    self.state = state;
                    return drive;
                }
                Next::Enter(state, reason) => {
                    self.enter(state, reason);
                    return brake;
                }
                Next::EnterAndStep(state, reason) => self.enter(state, reason),
                Next::Recover { from, reason } => {
                    self.state = from;
                    self.start_recovery(obs, reason);
                    return brake;
                }
            }
        }
    }
}
