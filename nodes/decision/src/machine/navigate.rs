//! Navigating to a goal given from outside (`navigate_to_pose`, `goal_pose`): a path on the map to
//! the goal, driven with the same steering around what the camera sees, recoveries when stuck;
//! it ends at the goal, or given up when the goal turns out blocked or out of reach. The mission
//! waits meanwhile and goes on from where it was afterwards.

use rover_msgs::map_grid::{cell_centre_m, cell_of_point};

use super::{Machine, Observation, Recovery};
use crate::drive::Drive;
use crate::grid::{Cell, Grid};
use crate::pose::Position;
use crate::route::Route;

/// Why a goal cannot be reached.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GoalFailure {
    /// The goal lies outside the map.
    OutsideMap,
    /// The goal lies inside an obstacle of the map.
    Occupied,
    /// No path on the map leads to the goal.
    NoPath,
    /// The rover got stuck too often on the way.
    NoProgress,
}

impl GoalFailure {
    /// Why, for the goal's client.
    pub fn message(self, goal: (f64, f64)) -> String {
        let (x, y) = goal;
        match self {
            GoalFailure::OutsideMap => format!("goal ({x:.2}, {y:.2}) is outside the map (0..200 m on both axes)"),
            GoalFailure::Occupied => format!("goal ({x:.2}, {y:.2}) lies inside an obstacle of the map"),
            GoalFailure::NoPath => format!("no path on the map leads to goal ({x:.2}, {y:.2})"),
            GoalFailure::NoProgress => format!("stuck too often on the way to goal ({x:.2}, {y:.2})"),
        }
    }
}

/// How a navigation ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NavigationEnd {
    /// The rover is within `goal_tolerance_m` of the goal.
    Reached,
    /// The goal was given up.
    Failed(GoalFailure),
}

/// How far the running navigation has come.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NavigationProgress {
    /// The goal, world metres.
    pub goal: (f64, f64),
    /// Length of the planned path left, metres.
    pub distance_remaining_m: f64,
    /// Mission frames since the navigation started.
    pub frames: u64,
    /// Recoveries on the way so far.
    pub recoveries: u32,
}

/// A running navigation.
#[derive(Debug, Clone)]
pub(super) struct Navigation {
    goal: (f64, f64),
    route: Option<Route>,
    since_frame: Option<u64>,
    recoveries: u32,
    /// The recovery under way.
    recovering: Option<Recovery>,
    distance_remaining_m: f64,
}

impl Machine {
    /// Starts driving to `goal` (world metres, the `map` frame), in place of a navigation that
    /// runs; refused when the goal is outside the map or on an obstacle.
    pub fn navigate_to(&mut self, goal: (f64, f64)) -> Result<(), GoalFailure> {
        cell_of_point(goal.0, goal.1).ok_or(GoalFailure::OutsideMap)?;
        if self.driving.last_position.is_some_and(|at| self.seen_inside_obstacle(goal, &at)) {
            return Err(GoalFailure::Occupied);
        }
        let distance_remaining_m = self.driving.last_position.map_or(0.0, |at| at.distance_to(goal));
        self.orders.navigation = Some(Navigation {
            goal,
            route: Route::to(goal),
            since_frame: None,
            recoveries: 0,
            recovering: None,
            distance_remaining_m,
        });
        self.orders.navigation_end = None;
        self.show_mode("navigating to a goal");
        Ok(())
    }

    /// Stops the running navigation, if any (the rover brakes); whether one ran.
    pub fn cancel_navigation(&mut self) -> bool {
        let ran = self.orders.navigation.take().is_some();
        if ran {
            self.show_mode("goal canceled");
        }
        ran
    }

    /// How the last navigation ended, once.
    pub fn take_navigation_end(&mut self) -> Option<NavigationEnd> {
        self.orders.navigation_end.take()
    }

    /// The progress of the running navigation.
    pub fn navigation_progress(&self) -> Option<NavigationProgress> {
        self.orders.navigation.as_ref().map(|nav| NavigationProgress {
            goal: nav.goal,
            distance_remaining_m: nav.distance_remaining_m,
            frames: nav.since_frame.map_or(0, |since| self.mission.frame.saturating_sub(since)),
            recoveries: nav.recoveries,
        })
    }

    /// The cells of the running navigation's path.
    pub(super) fn navigation_path(&self) -> Option<&[usize]> {
        self.orders.navigation.as_ref().map(|nav| nav.route.as_ref().map_or(&[][..], |route| route.path()))
    }

    /// Steps the navigation `nav`: a recovery under way, the end at the goal or when it is out of
    /// reach, else the path's next waypoint.
    pub(super) fn navigate(&mut self, obs: &Observation, mut nav: Navigation) -> Drive {
        let brake = self.params.brake;
        nav.since_frame.get_or_insert(obs.frame);
        if let Some(recovery) = nav.recovering.as_mut() {
            if let Some(drive) = self.recovery_drive(obs, recovery) {
                self.orders.navigation = Some(nav);
                return drive;
            }
            nav.recovering = None;
            self.start_afresh();
        }
        nav.distance_remaining_m = obs.position.distance_to(nav.goal);
        if nav.distance_remaining_m <= self.params.goal_tolerance_m {
            return self.end_navigation(NavigationEnd::Reached);
        }
        if self.seen_inside_obstacle(nav.goal, &obs.position) {
            return self.end_navigation(NavigationEnd::Failed(GoalFailure::Occupied));
        }
        if obs.picking_up {
            self.orders.navigation = Some(nav);
            return Drive::stop(brake);
        }
        if let Some(trouble) = self.trouble(obs) {
            nav.recoveries += 1;
            if f64::from(nav.recoveries) > self.params.goal_max_recoveries {
                return self.end_navigation(NavigationEnd::Failed(GoalFailure::NoProgress));
            }
            tracing::info!("navigating: {trouble}, recovery {} on the way", nav.recoveries);
            self.mark_stuck_cell(obs);
            nav.recovering = Some(self.begin_recovery(obs));
            self.orders.navigation = Some(nav);
            return Drive::stop(brake);
        }
        let mut route = nav.route.take();
        let Some(waypoint) = self.waypoint_past_obstacles_if_need_be(route.as_mut(), obs) else {
            return self.end_navigation(NavigationEnd::Failed(GoalFailure::NoPath));
        };
        if let Some(route) = &route {
            nav.distance_remaining_m = path_length_m(route.path(), obs, nav.goal);
        }
        let p = &self.params;
        let cruise = p.max_speed_mps.min(obs.position.distance_to(nav.goal).max(p.approach_speed_mps));
        let bearing = obs.position.bearing_to(waypoint);
        let drive = self.driving.steering.around_obstacles(bearing, cruise, obs.speed_mps, &obs.free, p);
        nav.route = route;
        self.orders.navigation = Some(nav);
        drive
    }

    /// The point of `route` to steer toward; when the map shows no way to the goal, the route
    /// plans past obstacle cells from then on (the map may be wrong: a narrow passage mapped as
    /// rock), and the steering around what the camera sees and the recoveries do the rest.
    fn waypoint_past_obstacles_if_need_be(
        &mut self,
        mut route: Option<&mut Route>,
        obs: &Observation,
    ) -> Option<(f64, f64)> {
        let waypoint = self.reachable_waypoint_on(route.as_deref_mut(), obs);
        if waypoint.is_some() || !route.as_deref_mut().is_some_and(Route::plan_past_obstacles) {
            return waypoint;
        }
        tracing::info!("no way to the goal on the map: planning past obstacle cells");
        self.reachable_waypoint_on(route, obs)
    }

    /// Whether `goal` lies inside an obstacle of the map as the camera saw it up close from `at`
    /// (within `goal_seen_m`): its cell and the cells around it are blocked. A goal at the foot
    /// of a wall that the map draws a cell too thick is not, nor one that the map blocks from
    /// afar (it may be wrong there: the rover drives on and looks).
    fn seen_inside_obstacle(&self, goal: (f64, f64), at: &Position) -> bool {
        if at.distance_to(goal) > self.params.goal_seen_m {
            return false;
        }
        let grid = self.maps.planning.grid();
        cell_of_point(goal.0, goal.1)
            .is_some_and(|cell| Grid::cells_around(cell, 1).all(|c| grid.cell(c) == Cell::Blocked))
    }

    /// Ends the navigation as `end`: the rover brakes, and the mission goes on from where it was.
    fn end_navigation(&mut self, end: NavigationEnd) -> Drive {
        self.orders.navigation = None;
        self.orders.navigation_end = Some(end);
        self.show_mode(match end {
            NavigationEnd::Reached => "goal reached",
            NavigationEnd::Failed(_) => "goal given up",
        });
        Drive::stop(self.params.brake)
    }
}

/// The length of `path` from the rover on to `goal`, metres: to the path's cell nearest to the
/// rover (the path may be a few frames old), along the cells after it, then to the goal.
fn path_length_m(path: &[usize], obs: &Observation, goal: (f64, f64)) -> f64 {
    let centres: Vec<(f64, f64)> = path.iter().map(|&cell| cell_centre_m(cell)).collect();
    let nearest = (0..centres.len())
        .min_by(|&a, &b| obs.position.distance_to(centres[a]).total_cmp(&obs.position.distance_to(centres[b])));
    let (Some(nearest), Some(&last)) = (nearest, centres.last()) else {
        return obs.position.distance_to(goal);
    };
    let ahead = &centres[nearest..];
    let along: f64 = ahead.windows(2).map(|pair| (pair[1].0 - pair[0].0).hypot(pair[1].1 - pair[0].1)).sum();
    obs.position.distance_to(ahead[0]) + along + (goal.0 - last.0).hypot(goal.1 - last.1)
}
