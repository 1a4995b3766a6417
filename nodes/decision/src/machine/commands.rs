//! The mission as commands: start it (when `start_mission` held it back), pause and resume it,
//! and send the rover home now. Each answers whether it did something, and what.

use super::navigate::{Navigation, NavigationEnd};
use super::{Machine, State};

/// The answer to a command: done, or refused; with a message for the caller either way.
pub type CommandAnswer = Result<&'static str, &'static str>;

/// What was asked of the machine from outside: start, pause, go home, drive to a goal.
#[derive(Debug, Clone, Default)]
pub(super) struct Orders {
    /// The mission has started (at once unless `start_mission` is false).
    pub(super) started: bool,
    /// Held by a pause.
    pub(super) paused: bool,
    /// Asked to return home now: no more exploring or detours for samples.
    pub(super) sent_home: bool,
    /// A goal given from outside, driven to in place of the mission.
    pub(super) navigation: Option<Navigation>,
    /// How the last navigation ended, until taken.
    pub(super) navigation_end: Option<NavigationEnd>,
}

impl Machine {
    /// Starts the mission where the rover stands.
    pub fn start_mission(&mut self) -> CommandAnswer {
        set_order(&mut self.orders.started, true, "the mission has already started")?;
        self.show_mode("mission started");
        Ok("mission started")
    }

    /// Brakes and holds the mission (and a navigation) where they are.
    pub fn pause(&mut self) -> CommandAnswer {
        set_order(&mut self.orders.paused, true, "already paused")?;
        self.show_mode("paused");
        Ok("paused: the rover brakes and holds")
    }

    /// Goes on from where the pause held the rover.
    pub fn resume_after_pause(&mut self) -> CommandAnswer {
        set_order(&mut self.orders.paused, false, "not paused")?;
        self.show_mode("resumed");
        Ok("resumed")
    }

    /// Ends exploring and drives home now, without detours for samples (a navigation that runs is
    /// given up).
    pub fn return_home_now(&mut self) -> CommandAnswer {
        if self.mission.status.home.is_none() {
            return Err("home is not known yet: no frame has come in");
        }
        if matches!(self.state, State::Done) && self.orders.navigation.is_none() {
            return Err("the rover is home: the mission is over");
        }
        self.orders.started = true;
        self.orders.paused = false;
        self.orders.sent_home = true;
        self.orders.navigation = None;
        self.enter(State::ReturnHome(None), "asked to return home");
        self.show_mode("asked to return home");
        Ok("returning home")
    }
}

/// Sets an order to `value`; refused with `refusal` when it already has that value.
fn set_order(order: &mut bool, value: bool, refusal: &'static str) -> Result<(), &'static str> {
    if *order == value {
        return Err(refusal);
    }
    *order = value;
    Ok(())
}
