//! The return-home mode: follow a path on the map to the start, picking up a sample located on
//! the way while there is time; done within `home_tolerance_m`.

use super::{Machine, Next, Observation, State};
use crate::drive::Drive;
use crate::route::{PlanStart, Route};

impl Machine {
    /// Steps the way home along `route`: done within `home_tolerance_m`, a sample on the way while
    /// there is time, else the route's next waypoint.
    pub(super) fn return_home(&mut self, obs: &Observation, route: Option<Route>) -> Next {
        let Some(home) = self.mission.status.home else {
            return Next::Stay(State::ReturnHome(route), Drive::stop(self.params.brake));
        };
        let distance_m = obs.position.distance_to(home);
        if distance_m <= self.params.home_tolerance_m {
            return Next::Enter(State::Done, "home");
        }
        let detour =
            self.time_to_go_home(obs).is_none().then(|| self.sample_to_chase(obs, self.params.sample_detour_cost));
        if let Some(chase) = detour.flatten() {
            return Next::EnterAndStep(State::Approach(chase), "sample located on the way home");
        }
        let mut route = route.or_else(|| Route::to(home));
        let waypoint = self.reachable_waypoint_on(route.as_mut(), obs).unwrap_or(home);
        let bearing = obs.position.bearing_to(waypoint);
        let p = &self.params;
        let cruise = p.max_speed_mps.min(distance_m.max(p.approach_speed_mps));
        let drive = self.driving.steering.around_obstacles(bearing, cruise, obs.speed_mps, &obs.free, p);
        Next::Stay(State::ReturnHome(route), drive)
    }

    /// The point of `route` to steer toward, as [`Machine::waypoint_on`]; when the goal cannot be
    /// reached, the cells where the rover got stuck are freed and the route tried again.
    pub(super) fn reachable_waypoint_on(
        &mut self,
        mut route: Option<&mut Route>,
        obs: &Observation,
    ) -> Option<(f64, f64)> {
        let waypoint = self.waypoint_on(route.as_deref_mut(), obs);
        if waypoint.is_some() || !self.maps.forget_stuck_marks() {
            return waypoint;
        }
        tracing::info!("goal unreachable: the cells where the rover got stuck are free again");
        self.waypoint_on(route, obs)
    }

    /// The point of `route` to steer toward from the rover's position on the planning map; none
    /// without a route or when its goal cannot be reached.
    fn waypoint_on(&self, route: Option<&mut Route>, obs: &Observation) -> Option<(f64, f64)> {
        let start = PlanStart { map: &self.maps.planning, at: &obs.position, frame: obs.frame, params: &self.params };
        route?.waypoint(&start)
    }
}
