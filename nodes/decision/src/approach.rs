//! Approaching a sample: along the map while it is far, straight at it when near, by way of a
//! staging cell after an approach failed, and given up when the camera should see it but does not.

use rover_msgs::map_grid::{cell_centre_m, cell_of_point};

use crate::grid::Grid;
use crate::params::DecisionParams;
use crate::pose::Position;
use crate::route::{PlanStart, Route, staging_cell};

/// Farther than this the rover drives to a sample along the map and around obstacles; closer, it
/// drives straight at it (samples lie by the walls, where little ground counts as free).
const ROUTE_APPROACH_M: f64 = 4.0;
/// After a failed approach the next one starts from a free cell this close to the sample, cells...
const STAGING_RADIUS_CELLS: usize = 2;
/// ...at least this far from where the failed ones ended, metres...
const STAGING_AWAY_M: f64 = 1.5;
/// ...reached within this distance, metres.
const STAGING_REACHED_M: f64 = 0.7;
/// A remembered sample between these distances ahead, metres (nearer, it is below the camera's
/// view)...
const CHECK_RANGE_M: (f64, f64) = (1.2, 3.0);
/// ...and within this bearing, degrees, with no obstacle of the map in between...
const CHECK_BEARING_DEG: f64 = 20.0;
/// ...that the camera does not see for this long, seconds, is not there (an echo of a sample
/// seen from afar, or one picked up already).
pub(crate) const UNSEEN_S: f64 = 1.0;

/// A sample being approached.
#[derive(Debug, Clone)]
pub(crate) struct Chase {
    /// Where the sample is, metres.
    pub at: (f64, f64),
    /// Where the sample was thought to be when the approach began (a remembered rock's place on
    /// the map, which the camera's sighting may then move by metres).
    pub first_at: (f64, f64),
    /// The approach is given up at this frame.
    pub give_up_frame: u64,
    route: Option<Route>,
    staging: Option<(f64, f64)>,
    unseen_since: Option<u64>,
    /// The approach is worth a route up to this path cost on the map.
    max_cost: f64,
}

/// How to drive on toward the sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Aim {
    /// Toward this point of the route, around what the camera sees: the sample is still far.
    AroundObstacles((f64, f64)),
    /// Straight at this point: the sample, or the staging cell on the way to it.
    Straight((f64, f64)),
}

impl Chase {
    /// An approach from `rover` to the sample at `at`, given up at `give_up_frame`, worth a route
    /// up to `max_cost`. After approaches that failed at the points `failed`, it goes by way of a
    /// free cell beside the sample on `grid`, away from them, that sees the sample.
    pub(crate) fn new(
        at: (f64, f64),
        (give_up_frame, max_cost): (u64, f64),
        (grid, rover): (&Grid, &Position),
        failed: &[(f64, f64)],
        params: &DecisionParams,
    ) -> Self {
        let staging = Some(failed)
            .filter(|failed| !failed.is_empty())
            .and_then(|failed| staging_cell(grid, at, rover, (STAGING_RADIUS_CELLS, STAGING_AWAY_M), failed, params))
            .map(cell_centre_m);
        Chase { at, first_at: at, give_up_frame, max_cost, route: None, staging, unseen_since: None }
    }

    /// The cells of the route's latest plan (empty while the rover drives straight at the sample).
    pub(crate) fn path(&self) -> &[usize] {
        self.route.as_ref().map_or(&[], Route::path)
    }

    /// Whether the route's latest plan costs more than the approach is worth: the map has shown
    /// the way to the sample to be a long way round.
    pub(crate) fn out_of_the_way(&self) -> bool {
        self.route.as_ref().and_then(Route::cost).is_some_and(|cost| cost > self.max_cost)
    }

    /// Whether the sample is not where it was thought to be: ahead, in the camera's view and in
    /// clear sight on the map, but not seen (`rock_seen` false) for [`UNSEEN_S`].
    pub(crate) fn missing(&mut self, from: &PlanStart, rock_seen: bool) -> bool {
        let (rover, frame) = (from.at, from.frame);
        let in_view = (CHECK_RANGE_M.0..=CHECK_RANGE_M.1).contains(&rover.distance_to(self.at))
            && rover.bearing_to(self.at).abs() <= CHECK_BEARING_DEG.to_radians()
            && cell_of_point(self.at.0, self.at.1)
                .is_some_and(|cell| from.map.grid().line_of_sight((rover.x_m, rover.y_m), cell, 0));
        self.unseen_since = (in_view && !rock_seen).then(|| self.unseen_since.unwrap_or(frame));
        self.unseen_since.is_some_and(|since| frame >= since + from.params.frames(UNSEEN_S))
    }

    /// Where to drive on: along a route on the map while the sample is far or while a staging
    /// cell is still ahead (dropped once reached), otherwise straight at the sample.
    pub(crate) fn aim(&mut self, from: &PlanStart) -> Aim {
        if self.staging.is_some_and(|point| from.at.distance_to(point) < STAGING_REACHED_M) {
            (self.staging, self.route) = (None, None);
        }
        let distance_m = from.at.distance_to(self.at);
        match self.route_waypoint(from, distance_m) {
            Some(point) if distance_m > ROUTE_APPROACH_M => Aim::AroundObstacles(point),
            Some(point) => Aim::Straight(point),
            None => Aim::Straight(self.at),
        }
    }

    /// The route's waypoint toward the staging cell or the sample; `None` to drive straight at it.
    fn route_waypoint(&mut self, from: &PlanStart, distance_m: f64) -> Option<(f64, f64)> {
        let goal = self.staging.unwrap_or(self.at);
        if distance_m <= ROUTE_APPROACH_M && self.staging.is_none() {
            return None;
        }
        if self.route.is_none() {
            self.route = Route::to(goal);
        }
        let route = self.route.as_mut()?;
        Some(route.waypoint(from).unwrap_or(goal))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_maps::{at, half_explored, plan_from, planning};

    const SAMPLE: (f64, f64) = (30.5, 51.5);

    fn chase() -> Chase {
        chase_worth(f64::INFINITY)
    }

    fn chase_worth(max_cost: f64) -> Chase {
        Chase::new(SAMPLE, (1000, max_cost), (&half_explored(), &at(25.5, 51.5)), &[], &DecisionParams::default())
    }

    #[test]
    fn a_sample_in_view_that_the_camera_does_not_see_for_a_second_is_missing() {
        let (map, params, rover) = (planning(&half_explored(), 1), DecisionParams::default(), at(28.5, 51.5));
        let unseen_frames = params.frames(UNSEEN_S);
        let mut seen = chase();
        assert!((1..3 * unseen_frames).all(|frame| !seen.missing(&plan_from(&map, &rover, frame, &params), true)));
        let mut unseen = chase();
        let missing_at =
            (1..3 * unseen_frames).find(|&frame| unseen.missing(&plan_from(&map, &rover, frame, &params), false));
        assert_eq!(missing_at, Some(1 + unseen_frames));
        let behind = Position { yaw_rad: std::f64::consts::PI, ..rover };
        let mut out_of_view = chase();
        assert!(
            (1..3 * unseen_frames).all(|frame| !out_of_view.missing(&plan_from(&map, &behind, frame, &params), false))
        );
    }

    #[test]
    fn a_far_sample_is_aimed_at_along_the_route_a_near_one_straight() {
        let (map, params) = (planning(&half_explored(), 1), DecisionParams::default());
        let mut chase = chase();
        let far = chase.aim(&plan_from(&map, &at(20.5, 51.5), 0, &params));
        assert!(matches!(far, Aim::AroundObstacles(point) if point.0 > 20.5 && point.0 <= SAMPLE.0), "{far:?}");
        assert_eq!(chase.aim(&plan_from(&map, &at(28.5, 51.5), 1, &params)), Aim::Straight(SAMPLE));
    }

    #[test]
    fn a_sample_whose_route_costs_more_than_it_is_worth_is_out_of_the_way() {
        let (map, params, rover) = (planning(&half_explored(), 1), DecisionParams::default(), at(20.5, 51.5));
        let from = plan_from(&map, &rover, 0, &params);
        let (mut cheap, mut dear) = (chase_worth(15.0), chase_worth(5.0));
        assert!(!cheap.out_of_the_way() && !dear.out_of_the_way(), "no route planned yet");
        cheap.aim(&from);
        dear.aim(&from);
        assert!(!cheap.out_of_the_way(), "10 m of route is worth 15");
        assert!(dear.out_of_the_way(), "10 m of route is not worth 5");
    }
}
