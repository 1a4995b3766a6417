//! The approach mode: drive to a sample seen or remembered, slowly enough to stop with it in the
//! arm's reach; give it up for a while when it is not reached or not where remembered.

use rover_msgs::body::ARM_REACH_M;

use super::{Machine, Next, Observation, State};
use crate::approach::{Aim, Chase};
use crate::drive::speed_to_stop_in;
use crate::route::PlanStart;

/// A sample whose route turns out to cost more than its approach is worth is left alone for this
/// long, seconds, while the rover explores on (the map may yet show a shorter way).
const OUT_OF_THE_WAY_S: f64 = 10.0;

impl Machine {
    /// Steps the approach of `chase`: home when asked or at the deadline, as exploring would; the
    /// sample's place from the camera when in sight, a slow drive to it, or back to exploring
    /// when it is not reached in time, not where remembered, or out of the way.
    pub(super) fn approach(&mut self, obs: &Observation, mut chase: Chase) -> Next {
        if let Some(reason) = self.time_to_go_home(obs) {
            return Next::EnterAndStep(State::ReturnHome(None), reason);
        }
        if let Some(seen) = obs.rock.filter(|s| s.distance_m <= self.params.sample_sight_m) {
            chase.at = obs.position.point_at(seen.bearing_rad, seen.distance_m);
        }
        if obs.frame >= chase.give_up_frame || obs.samples_remaining == 0 {
            self.note_failed_approach(chase.at, obs);
            return Next::Enter(State::Explore, "sample not reached in time");
        }
        let p = &self.params;
        let from = PlanStart { map: &self.maps.planning, at: &obs.position, frame: obs.frame, params: p };
        if chase.missing(&from, obs.rock.is_some()) {
            self.note_failed_approach(chase.at, obs);
            return Next::Enter(State::Explore, "sample not where remembered");
        }
        let aim = chase.aim(&from);
        if chase.out_of_the_way() {
            let until_frame = obs.frame + p.frames(OUT_OF_THE_WAY_S);
            self.samples.defer(chase.at, until_frame);
            self.samples.defer(chase.first_at, until_frame);
            return Next::EnterAndStep(State::Explore, "sample out of the way on the map");
        }
        let distance_m = obs.position.distance_to(chase.at);
        let speed = speed_to_stop_in(distance_m - ARM_REACH_M, p).clamp(p.approach_speed_mps, p.max_speed_mps);
        let drive = match aim {
            Aim::AroundObstacles(point) => {
                let bearing = obs.position.bearing_to(point);
                self.driving.steering.around_obstacles(bearing, p.max_speed_mps, obs.speed_mps, &obs.free, p)
            }
            Aim::Straight(point) => {
                let (bearing, distance_m) = (obs.position.bearing_to(point), obs.position.distance_to(point));
                self.driving.steering.toward_point(bearing, distance_m, speed, obs.speed_mps, p)
            }
        };
        Next::Stay(State::Approach(chase), drive)
    }

    /// A seen sample within sight or a remembered one, either within `max_cost` on the map, or
    /// at any cost once every sample still missing is remembered (exploring on finds no other).
    /// While the rover explores only to find samples and the map holds every one still missing,
    /// rocks set aside after failed approaches are tried again at once.
    pub(super) fn sample_to_chase(&self, obs: &Observation, max_cost: f64) -> Option<Chase> {
        if obs.samples_remaining == 0 {
            return None;
        }
        let p = &self.params;
        let retry_set_aside = self.search.widening.for_samples && self.map_holds_every_missing_sample(obs);
        let max_cost = if retry_set_aside || self.all_missing_samples_located(obs) { f64::INFINITY } else { max_cost };
        let chaseable =
            |at: (f64, f64)| !self.is_ignored(at) || (retry_set_aside && self.samples.may_retry_at_once(at, obs.frame));
        let new = |(at, way_m): ((f64, f64), f64)| {
            let give_up_frame = obs.frame + p.frames_for_way(p.sample_timeout_s, way_m);
            let (map, failed) = ((self.maps.planning.grid(), &obs.position), &self.samples.failed_from(at));
            Chase::new(at, (give_up_frame, max_cost), map, failed, p)
        };
        let seen = obs
            .rock
            .filter(|s| s.distance_m <= p.sample_sight_m)
            .map(|s| (obs.position.point_at(s.bearing_rad, s.distance_m), s.distance_m))
            .filter(|&(at, _)| chaseable(at))
            .filter(|&(at, _)| self.explorer.cost_to(at).is_none_or(|cost| cost <= max_cost));
        seen.or_else(|| {
            self.samples
                .located()
                .iter()
                .copied()
                .filter(|&at| chaseable(at))
                .filter_map(|at| Some((at, self.explorer.cost_to(at)?)))
                .filter(|&(_, cost)| cost <= max_cost)
                .min_by(|a, b| a.1.total_cmp(&b.1))
        })
        .map(new)
    }

    /// Notes an approach of `sample` that failed where the rover stands.
    pub(super) fn note_failed_approach(&mut self, sample: (f64, f64), obs: &Observation) {
        self.samples.note_failed_approach(sample, obs.frame, (obs.position.x_m, obs.position.y_m));
    }

    /// Whether the rock at `at` is collected, given up, or failed too often lately.
    fn is_given_up(&self, at: (f64, f64)) -> bool {
        self.samples.is_ignored(at, self.mission.frame, self.params.frames(self.params.sample_retry_s))
    }

    /// Whether the rock at `at` is given up ([`Machine::is_given_up`]) or left alone for now as
    /// out of the way.
    pub(super) fn is_ignored(&self, at: (f64, f64)) -> bool {
        self.is_given_up(at) || self.samples.is_deferred(at, self.mission.frame)
    }

    /// Whether the map holds at least as many rocks not given up as samples are missing.
    fn all_missing_samples_located(&self, obs: &Observation) -> bool {
        self.rocks_cover_missing_samples(obs, |at| !self.is_given_up(at))
    }

    /// Whether the map holds at least as many rocks neither picked up nor given up for good as
    /// samples are missing, counting those set aside after failed approaches.
    fn map_holds_every_missing_sample(&self, obs: &Observation) -> bool {
        self.rocks_cover_missing_samples(obs, |at| !self.samples.is_picked_up_or_given_up(at))
    }

    /// Whether at least as many rocks on the map are `counted` as samples are missing.
    fn rocks_cover_missing_samples(&self, obs: &Observation, counted: impl Fn((f64, f64)) -> bool) -> bool {
        self.samples.located().iter().filter(|&&at| counted(at)).count() >= obs.samples_remaining as usize
    }
}
