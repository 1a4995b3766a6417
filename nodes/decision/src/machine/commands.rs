//! The mission as commands: start it (when `start_mission` held it back), pause and resume it,
//! and send the rover home now. Each answers whether it did something, and what.

use super::{Machine, State};

/// The answer to a command: done, or refused; with a message for the caller either way.
pub type CommandAnswer = Result<&'static str, &'static str>;

impl Machine {
    /// Starts the mission where the rover stands.
    pub fn start_mission(&mut self) -> CommandAnswer {
        if self.started {
            return Err("the mission has already started");
        }
        self.started = true;
        self.show_mode("mission started");
        Ok("mission started")
    }

    /// Brakes and holds the mission (and a navigation) where they are.
    pub fn pause(&mut self) -> CommandAnswer {
        if self.paused {
            return Err("already paused");
        }
        self.paused = true;
        self.show_mode("paused");
        Ok("paused: the rover brakes and holds")
    }

    /// Goes on from where the pause held the rover.
    pub fn resume_after_pause(&mut self) -> CommandAnswer {
        if !self.paused {
            return Err("not paused");
        }
        self.paused = false;
        self.show_mode("resumed");
        Ok("resumed")
    }

    /// Ends exploring and drives home now, without detours for samples (a navigation that runs is
    /// given up).
    pub fn return_home_now(&mut self) -> CommandAnswer {
        if self.mission.status.home.is_none() {
            return Err("home is not known yet: no frame has come in");
        }
        if matches!(self.state, State::Done) && self.navigation.is_none() {
            return Err("the rover is home: the mission is over");
        }
        self.started = true;
        self.paused = false;
        self.sent_home = true;
        self.navigation = None;
        self.enter(State::ReturnHome(None), "asked to return home");
        self.show_mode("asked to return home");
        Ok("returning home")
    }
}
