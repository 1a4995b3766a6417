//! The explore mode: drive to the frontiers of the map; go for a sample when one is located within
//! reach; widen the search when no frontier is left; then home.

use super::look_around::LookAround;
use super::{Machine, Next, Observation, State};
use crate::drive::Drive;
use crate::route::PlanStart;

/// With no frontier in reach because the map walls the rover in, it backs out up to this many
/// times before it gives the frontiers up.
const WALLED_IN_RECOVERIES: u32 = 3;

/// How far the search has been widened when frontiers ran out.
#[derive(Debug, Clone, Default)]
pub(super) struct Widening {
    /// Recoveries started since the last frontier because the map walls the rover in.
    walled_in_recoveries: u32,
    /// The explorer forgot the cells seen up close because no frontier was left.
    walls_looked_at_again: bool,
    /// A step has widened the search: the rover explores on only to find samples.
    pub(super) for_samples: bool,
}

/// What widens the search when no frontier is left: the looks around and the widening so far.
#[derive(Debug, Clone, Default)]
pub(super) struct Search {
    pub(super) widening: Widening,
    pub(super) look_around: LookAround,
}

impl Machine {
    /// Steps the explore mode: home at the deadline, a located sample within reach, else the next
    /// frontier; with none left, the search widens, then the rover goes home.
    pub(super) fn explore(&mut self, obs: &Observation) -> Next {
        if let Some(reason) = self.time_to_go_home(obs) {
            return Next::EnterAndStep(State::ReturnHome(None), reason);
        }
        if let Some(chase) = self.sample_to_chase(obs, self.params.sample_detour_cost) {
            return Next::EnterAndStep(State::Approach(chase), "sample located");
        }
        if obs.samples_remaining == 0 {
            self.explorer.recall_inspected();
        }
        let (p, home) = (&self.params, self.mission.status.home);
        let from = PlanStart { map: &self.maps.planning, at: &obs.position, frame: obs.frame, params: p };
        if let Some(waypoint) = self.explorer.waypoint(&from, home) {
            self.search.widening.walled_in_recoveries = 0;
            self.search.look_around.interrupt();
            let bearing = obs.position.bearing_to(waypoint);
            tracing::trace!(
                bearing_deg = bearing.to_degrees(),
                free_ahead = obs.free.toward(0.0),
                best = ?obs.free.best_toward(bearing as f32, p.clearance_m as f32),
                "explore"
            );
            let drive = self.driving.steering.around_obstacles(bearing, p.max_speed_mps, obs.speed_mps, &obs.free, p);
            return Next::Stay(State::Explore, drive);
        }
        if self.maps.planning.version() == 0 {
            let drive = self.driving.steering.around_obstacles(0.0, p.max_speed_mps, obs.speed_mps, &obs.free, p);
            return Next::Stay(State::Explore, drive);
        }
        if let Some(turn) = self.look_around(obs) {
            return Next::Stay(State::Explore, turn);
        }
        let brake = Drive::stop(self.params.brake);
        if !self.map_shows_ground_in_reach(obs) {
            return Next::Stay(State::Explore, brake);
        }
        if self.explorer.walled_in() && self.search.widening.walled_in_recoveries < WALLED_IN_RECOVERIES {
            self.search.widening.walled_in_recoveries += 1;
            let reason = "walled in by the map (a restart next to a rock?): backing out";
            return Next::Recover { from: State::Explore, reason };
        }
        if self.maps.forget_stuck_marks_to_explore(&obs.position) {
            tracing::info!("no frontier reachable: the cells where the rover got stuck are free again");
            return Next::Stay(State::Explore, brake);
        }
        match self.widen_search(obs.samples_remaining) {
            Some(step) => {
                tracing::info!("no frontier left, {} samples not found: {step}", obs.samples_remaining);
                Next::Stay(State::Explore, brake)
            }
            None => self.finish_exploring(obs),
        }
    }

    /// With no frontier left and `samples_remaining` samples not found, widens the search by one
    /// step: the frontiers given up, then planning past obstacle cells, then, once, the walls seen
    /// before; what it did, or `None` when nothing is left to widen. Once the walls have been
    /// looked at again, the search ends the next time no frontier is left (the rover has then
    /// seen every wall up close twice).
    pub(super) fn widen_search(&mut self, samples_remaining: u8) -> Option<&'static str> {
        if samples_remaining == 0 || self.search.widening.walls_looked_at_again {
            return None;
        }
        let step = self.widening_step();
        self.search.widening.for_samples |= step.is_some();
        step
    }

    /// The next step of [`Machine::widen_search`], if any is left.
    fn widening_step(&mut self) -> Option<&'static str> {
        if self.explorer.forget_explored() {
            return Some("trying given-up frontiers again");
        }
        if self.explorer.look_past_obstacles() {
            return Some("planning past obstacle cells");
        }
        if self.explorer.forget_inspected() {
            self.search.widening.walls_looked_at_again = true;
            return Some("looking again at the walls seen before");
        }
        None
    }

    /// The end of exploring: a sample left on the map at any cost, else home.
    fn finish_exploring(&mut self, obs: &Observation) -> Next {
        if let Some(chase) = self.sample_to_chase(obs, f64::INFINITY) {
            return Next::EnterAndStep(State::Approach(chase), "map explored, sample left");
        }
        let (free_cells, obstacle_cells, unknown_cells) = self.maps.received.counts();
        tracing::info!(
            free_cells,
            obstacle_cells,
            unknown_cells,
            map_version = self.maps.planning.version(),
            at = ?(obs.position.x_m, obs.position.y_m),
            rocks = ?self.samples.located(),
            given_up = ?self.samples.ignored(),
            "no frontier left"
        );
        Next::EnterAndStep(State::ReturnHome(None), "no frontier left")
    }

    /// Whether the rover was asked to return home, or the way home, at the return speed, would end
    /// past the mission's deadline.
    pub(super) fn time_to_go_home(&self, obs: &Observation) -> Option<&'static str> {
        if self.orders.sent_home {
            return Some("asked to return home");
        }
        let p = &self.params;
        let home = self.mission.status.home?;
        let elapsed_s = obs.frame as f64 * p.frame_period_s;
        // The explorer's costs are from where it last planned, which an approach may have left
        // far behind; the way home is no shorter than the straight line from here.
        let straight_m = obs.position.distance_to(home);
        let way_home_m = self.explorer.cost_to(home).map_or(straight_m, |cost_m| cost_m.max(straight_m));
        let return_s = way_home_m / (p.max_speed_mps * p.return_speed_fraction);
        (elapsed_s + return_s >= p.mission_deadline_s).then_some("mission deadline")
    }
}
