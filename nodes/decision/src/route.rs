//! Routes on the map: path costs, a path to one goal replanned as the map grows, the lookahead
//! point of a path that the rover steers toward, and where to start a straight final approach.

use rover_msgs::map_grid::{cell_centre_m, cell_of_point};

use std::cell::RefCell;
use std::sync::Arc;

use crate::grid::{Cell, CostMap, Costs, Grid};
use crate::params::DecisionParams;
use crate::pose::Position;

/// A goal on an obstacle cell is reached through the cheapest reachable cell this close, cells.
pub(crate) const GOAL_SLACK_CELLS: usize = 3;
/// Path cost of crossing an obstacle cell when a plan goes past obstacles (the map may be wrong,
/// e.g. an exit mapped as rock).
pub(crate) const OBSTACLE_CROSSING_COST: f32 = 50.0;

/// The path costs of `params`.
pub fn path_costs(params: &DecisionParams) -> Costs {
    Costs {
        unknown: params.unknown_cost as f32,
        near_wall: params.near_wall_cost as f32,
        cross_unknown: true,
        obstacle: None,
    }
}

/// The point of `path` the rover steers toward: the first cell at least `lookahead_m` away after
/// the cell nearest to the rover (the last cell when all are nearer), or a later one up to
/// `max_lookahead_m` away while the straight line to it keeps clear of walls: on open ground the
/// rover cuts the grid path's corners and drives straight.
pub fn lookahead(grid: &Grid, path: &[usize], at: &Position, params: &DecisionParams) -> Option<(f64, f64)> {
    let distance = |&cell: &usize| at.distance_to(cell_centre_m(cell));
    let nearest = (0..path.len()).min_by(|&a, &b| distance(&path[a]).total_cmp(&distance(&path[b])))?;
    let ahead = &path[nearest..];
    let first = ahead.iter().position(|cell| distance(cell) >= params.lookahead_m).unwrap_or(ahead.len() - 1);
    let straight = ahead[first + 1..]
        .iter()
        .take_while(|cell| distance(cell) <= params.max_lookahead_m && grid.clear_line((at.x_m, at.y_m), **cell))
        .count();
    Some(cell_centre_m(ahead[first + straight]))
}

/// A free cell beside `goal` (within `radius_cells`) with a clear line of sight to it on the
/// map (past the wall cells right around it), at least `away_m` from every point of
/// `avoid`, the cheapest to reach from `at`: where to start a straight final approach to a
/// sample by a wall after one from `avoid` failed.
pub fn staging_cell(
    grid: &Grid,
    goal: (f64, f64),
    at: &Position,
    (radius_cells, away_m): (usize, f64),
    avoid: &[(f64, f64)],
    params: &DecisionParams,
) -> Option<usize> {
    let (start, goal) = (cell_of_point(at.x_m, at.y_m)?, cell_of_point(goal.0, goal.1)?);
    let costs = grid.costs_from(start, &path_costs(params));
    let far_from_failures = |cell: usize| {
        let (x, y) = cell_centre_m(cell);
        avoid.iter().all(|p| (p.0 - x).hypot(p.1 - y) >= away_m)
    };
    Grid::cells_around(goal, radius_cells)
        .filter(|&cell| cell != goal && grid.cell(cell) == Cell::Free && costs.distance(cell).is_finite())
        .filter(|&cell| far_from_failures(cell) && grid.line_of_sight(cell_centre_m(cell), goal, 1))
        .min_by(|&a, &b| costs.distance(a).total_cmp(&costs.distance(b)))
}

/// The map that plans are made on, and its version: a new map is a reason to plan again. It keeps
/// the path costs it gave last, for a request that repeats (a rover that has not left its cell
/// since the last plan), and makes path costs ahead of time, between two frames, so that the frame
/// that asks for them does not wait for their cells' entry costs: a periodic replan's
/// ([`PlanningMap::prepare`]), or the first plan's on a map built before it takes effect
/// ([`PlanningMap::make_ahead`]). The search itself goes only as far as the frame's questions
/// need ([`CostMap`]).
#[derive(Debug, Clone)]
pub struct PlanningMap {
    grid: Grid,
    version: u64,
    /// The frame on which the next map is expected to take effect, if known.
    next_map_frame: Option<u64>,
    searched: RefCell<Searched>,
}

/// What path costs are asked for: from which cell, with which costs.
#[derive(Debug, Clone, Copy, PartialEq)]
struct CostsRequest {
    start_cell: usize,
    costs: Costs,
}

/// Path costs searched on a planning map, and the request they answer.
#[derive(Debug, Clone)]
struct Answer {
    request: CostsRequest,
    costs: Arc<CostMap>,
}

/// The path costs last given by a planning map (and on which frame), and those made ahead for the
/// next request.
#[derive(Debug, Clone, Default)]
struct Searched {
    last: Option<(Answer, u64)>,
    made: Option<Answer>,
}

impl Searched {
    /// The last costs given or those made ahead, if they answer `request`.
    fn answer(&self, request: &CostsRequest) -> Option<&Answer> {
        self.last.as_ref().map(|(answer, _)| answer).into_iter().chain(&self.made).find(|a| a.request == *request)
    }
}

impl PlanningMap {
    /// `grid` as version `version` of the map.
    pub fn new(grid: Grid, version: u64) -> Self {
        PlanningMap { grid, version, next_map_frame: None, searched: RefCell::default() }
    }

    /// The map.
    pub fn grid(&self) -> &Grid {
        &self.grid
    }

    /// Expects the next map to take effect on `frame` (none: not known), for
    /// [`PlanningMap::replan_frame`].
    pub fn expect_next_map_at(&mut self, frame: Option<u64>) {
        self.next_map_frame = frame;
    }

    /// The frame on which a plan made at `planned_at` is made again for its age alone:
    /// `replan_frames` after it, or on the next map's frame when that is expected at most
    /// `replan_waits_for_map_frames` later (the new map is planned on anyway; a replan on this
    /// one a frame or two before would be used for that long only).
    fn replan_frame(&self, planned_at: u64, params: &DecisionParams) -> u64 {
        let due = planned_at.saturating_add(params.replan_frames as u64);
        let latest = due.saturating_add(params.replan_waits_for_map_frames as u64);
        self.next_map_frame.filter(|map_frame| (due..=latest).contains(map_frame)).unwrap_or(due)
    }

    /// Goes up by one with every new map.
    pub fn version(&self) -> u64 {
        self.version
    }

    /// Path costs from cell `start` with `costs` for a plan at `frame` ([`Grid::costs_from`]):
    /// the last ones given or those made ahead when they are those, else searched now (the same
    /// costs either way: the map does not change).
    pub fn costs_from(&self, start: usize, costs: &Costs, frame: u64) -> Arc<CostMap> {
        let request = CostsRequest { start_cell: start, costs: *costs };
        let mut searched = self.searched.borrow_mut();
        let known = searched.answer(&request).map(|answer| Arc::clone(&answer.costs));
        let costs = known.unwrap_or_else(|| Arc::new(self.grid.costs_from(start, costs)));
        searched.made = None;
        searched.last = Some((Answer { request, costs: Arc::clone(&costs) }, frame));
        costs
    }

    /// Makes the path costs that frame `next_frame` will ask for from cell `start` if the last
    /// request (its start aside) is repeated there as a route's or the explorer's periodic replan
    /// ([`PlanningMap::replan_frame`]) and they are not known yet; nothing on other frames. A guess:
    /// when the next request differs (the rover crossed into another cell, the map changed), it is
    /// searched as before.
    pub fn prepare(&self, start: usize, next_frame: u64, params: &DecisionParams) {
        let last = self.searched.borrow().last.as_ref().map(|(answer, frame)| (answer.request.costs, *frame));
        if let Some((costs, frame)) = last
            && next_frame == self.replan_frame(frame, params)
        {
            self.make_ahead(start, &costs);
        }
    }

    /// The costs of the last request if it came at most `replan_frames` before `next_frame`: a
    /// route or the explorer is planning on this map and will plan again on the next one.
    pub(crate) fn costs_in_use(&self, next_frame: u64, params: &DecisionParams) -> Option<Costs> {
        let searched = self.searched.borrow();
        let (answer, frame) = searched.last.as_ref()?;
        (next_frame <= self.replan_frame(*frame, params)).then_some(answer.request.costs)
    }

    /// The frame on which the next map is expected, if known.
    #[cfg(test)]
    pub(crate) fn next_map_frame(&self) -> Option<u64> {
        self.next_map_frame
    }

    /// The start cell of the path costs made ahead, if any.
    #[cfg(test)]
    pub(crate) fn made_from(&self) -> Option<usize> {
        self.searched.borrow().made.as_ref().map(|answer| answer.request.start_cell)
    }

    /// The path costs made ahead, if any.
    #[cfg(test)]
    pub(crate) fn made_costs(&self) -> Option<Arc<CostMap>> {
        self.searched.borrow().made.as_ref().map(|answer| Arc::clone(&answer.costs))
    }

    /// The path costs given last, if any.
    #[cfg(test)]
    pub(crate) fn last_costs(&self) -> Option<Arc<CostMap>> {
        self.searched.borrow().last.as_ref().map(|(answer, _)| Arc::clone(&answer.costs))
    }

    /// Makes the path costs from cell `start` with `costs` now, for the next request to take,
    /// unless they are known already.
    pub(crate) fn make_ahead(&self, start: usize, costs: &Costs) {
        let request = CostsRequest { start_cell: start, costs: *costs };
        let mut searched = self.searched.borrow_mut();
        if searched.answer(&request).is_none() {
            searched.made = Some(Answer { request, costs: Arc::new(self.grid.costs_from(start, costs)) });
        }
    }
}

/// Where a plan on the map starts this frame.
#[derive(Debug, Clone, Copy)]
pub struct PlanStart<'a> {
    /// The map to plan on.
    pub map: &'a PlanningMap,
    /// The rover.
    pub at: &'a Position,
    /// The current frame.
    pub frame: u64,
    /// The decision's parameters.
    pub params: &'a DecisionParams,
}

impl PlanStart<'_> {
    /// Whether a plan made at `planned` (frame, map version) is due to be made again: never made,
    /// made on another map, or old enough ([`PlanningMap::replan_frame`]).
    pub(crate) fn replan_due(&self, planned: Option<(u64, u64)>) -> bool {
        planned.is_none_or(|(at_frame, version)| {
            version != self.map.version() || self.frame >= self.map.replan_frame(at_frame, self.params)
        })
    }
}

/// A path to one goal, replanned every few frames.
#[derive(Debug, Clone)]
pub struct Route {
    goal: usize,
    path: Vec<usize>,
    cost: Option<f64>,
    planned: Option<(u64, u64)>,
    past_obstacles: bool,
}

impl Route {
    /// A route to the cell containing `goal`, or `None` when that is off the map.
    pub fn to(goal: (f64, f64)) -> Option<Self> {
        let goal = cell_of_point(goal.0, goal.1)?;
        Some(Route { goal, path: Vec::new(), cost: None, planned: None, past_obstacles: false })
    }

    /// The cells of the latest plan, from the rover's cell on (empty before the first plan or when
    /// the goal cannot be reached).
    pub fn path(&self) -> &[usize] {
        &self.path
    }

    /// The path cost of the latest plan (see [`path_costs`]); `None` before the first plan or
    /// when the goal cannot be reached on the map.
    pub fn cost(&self) -> Option<f64> {
        self.cost
    }

    /// Plans past obstacle cells from now on, at a high cost; whether it did not already.
    pub fn plan_past_obstacles(&mut self) -> bool {
        self.planned = None;
        !std::mem::replace(&mut self.past_obstacles, true)
    }

    /// The point to steer toward on the way from `at`, replanning when the route is older than
    /// `replan_frames` or the map changed; the goal itself once the path's end is within the
    /// lookahead (a path that ends next to a goal on an obstacle cell would otherwise leave the
    /// rover circling its own cell); `None` when the goal cannot be reached on the map.
    pub fn waypoint(&mut self, from: &PlanStart) -> Option<(f64, f64)> {
        let PlanStart { map, at, frame, params } = *from;
        let (grid, start) = (map.grid(), cell_of_point(at.x_m, at.y_m)?);
        if from.replan_due(self.planned) {
            let obstacle = self.past_obstacles.then_some(OBSTACLE_CROSSING_COST);
            let costs = map.costs_from(start, &Costs { obstacle, ..path_costs(params) }, frame);
            let end = costs.reachable_near(self.goal, GOAL_SLACK_CELLS);
            self.path = end.and_then(|cell| costs.path_to(cell)).unwrap_or_default();
            self.cost = end.map(|cell| costs.distance(cell) as f64);
            self.planned = Some((frame, map.version()));
        }
        let point = lookahead(grid, &self.path, at, params)?;
        Some(if at.distance_to(point) < params.lookahead_m { cell_centre_m(self.goal) } else { point })
    }
}

#[cfg(test)]
mod tests {
    use rover_msgs::map_grid::{CELLS, cell_at};

    use super::*;
    use crate::test_maps::{at, half_explored, plan_from, planning};

    #[test]
    fn a_staging_cell_sees_the_goal_past_the_wall_corner() {
        let mut data = vec![0i8; CELLS];
        let wall = (79..=83).flat_map(|x| (104..=110).map(move |y| (x, y)));
        for (x, y) in wall.chain([(84, 109), (84, 110), (84, 111), (83, 111)]) {
            data[cell_at(x, y)] = 100;
        }
        let grid = Grid::from_occupancy(&data).unwrap();
        let params = DecisionParams::default();
        let rover = Position { x_m: 82.5, y_m: 111.5, yaw_rad: 0.0 };
        let goal = cell_of_point(84.5, 109.5).unwrap();
        assert!(!grid.line_of_sight((82.5, 111.5), goal, 1), "the corner is in the way");
        let cell = staging_cell(&grid, (84.5, 109.5), &rover, (2, 1.5), &[(82.5, 111.5)], &params).unwrap();
        let centre = cell_centre_m(cell);
        assert!(grid.cell(cell) == Cell::Free && centre.0 > 84.0, "beside the goal, past the corner: {centre:?}");
        assert!(grid.line_of_sight(centre, goal, 1));
    }

    /// An open square 20..60 x 20..60 with a wall block 40..60 x 20..40 in its lower right.
    fn room_with_a_corner() -> Grid {
        let mut data = vec![100i8; CELLS];
        for y in 20..60 {
            for x in 20..60 {
                data[cell_at(x, y)] = if x >= 40 && y < 40 { 100 } else { 0 };
            }
        }
        Grid::from_occupancy(&data).unwrap()
    }

    #[test]
    fn on_open_ground_the_rover_steers_straight_past_the_grid_paths_kinks_but_not_past_a_corner() {
        let grid = room_with_a_corner();
        let params = DecisionParams { max_lookahead_m: 8.0, ..DecisionParams::default() };
        let rover = at(25.5, 25.5);
        let path = grid.costs_from(cell_of_point(25.5, 25.5).unwrap(), &path_costs(&params));
        let diagonal_then_straight = path.path_to(cell_of_point(35.5, 45.5).unwrap()).unwrap();
        let point = lookahead(&grid, &diagonal_then_straight, &rover, &params).unwrap();
        let distance = rover.distance_to(point);
        assert!(
            distance > params.lookahead_m + 2.0 && distance <= params.max_lookahead_m,
            "farther than the lookahead: {point:?}"
        );
        let around_the_corner = path.path_to(cell_of_point(55.5, 45.5).unwrap()).unwrap();
        let below_the_corner = at(35.5, 30.5);
        let point = lookahead(&grid, &around_the_corner, &below_the_corner, &params).unwrap();
        assert!(point.1 < 42.0 && point.0 < 40.0, "short of the corner at (40, 40): {point:?}");
        assert!(grid.clear_line((35.5, 30.5), cell_of_point(point.0, point.1).unwrap()));
        assert!(!grid.clear_line((35.5, 30.5), cell_of_point(45.5, 45.5).unwrap()), "the corner is in the way");
    }

    /// Whether `costs` holds every cell's cost and path of a search from `start` on `grid`.
    fn searched_from(costs: &CostMap, grid: &Grid, start: usize, with: &Costs) -> bool {
        let searched = grid.costs_from(start, with);
        (0..CELLS).all(|cell| {
            costs.distance(cell).to_bits() == searched.distance(cell).to_bits()
                && costs.path_to(cell) == searched.path_to(cell)
        })
    }

    /// A planning map of [`half_explored`], parameters replanning every 12 frames, their path
    /// costs, and two neighbouring start cells.
    fn replanning_map() -> (PlanningMap, DecisionParams, Costs, usize, usize) {
        let params = DecisionParams { replan_frames: 12, ..DecisionParams::default() };
        let costs = path_costs(&params);
        let (here, next) = (cell_of_point(25.5, 51.5).unwrap(), cell_of_point(26.5, 51.5).unwrap());
        (planning(&half_explored(), 1), params, costs, here, next)
    }

    #[test]
    fn a_periodic_replans_costs_are_made_ahead_once_and_only_used_when_they_are_the_ones_asked_for() {
        let (map, params, costs, here, next) = replanning_map();
        map.costs_from(here, &costs, 100);
        map.prepare(next, 111, &params);
        assert_eq!(map.made_from(), None, "not due before 12 frames");
        map.prepare(next, 112, &params);
        assert_eq!(map.made_from(), Some(next));
        assert!(searched_from(&map.costs_from(next, &costs, 112), map.grid(), next, &costs));
        assert_eq!(map.made_from(), None, "taken by the request");
        map.prepare(next, 124, &params);
        assert!(searched_from(&map.costs_from(here, &costs, 124), map.grid(), here, &costs), "another start");
        assert_eq!(map.made_from(), None, "dropped by the request it did not fit");
        map.prepare(here, 136, &params);
        let other = Costs { cross_unknown: false, ..costs };
        assert!(searched_from(&map.costs_from(here, &other, 136), map.grid(), here, &other), "other costs");
    }

    #[test]
    fn a_replan_due_just_before_the_next_map_waits_for_it_and_one_due_earlier_does_not() {
        let (mut map, params, costs, _, next) = replanning_map();
        let params = DecisionParams { replan_waits_for_map_frames: 3, ..params };
        let mut route = Route::to((55.5, 52.5)).unwrap();
        let planned_on = |route: &Route| route.planned.map(|(frame, _)| frame);
        route.waypoint(&plan_from(&map, &at(25.5, 51.5), 100, &params));
        map.expect_next_map_at(Some(115));
        route.waypoint(&plan_from(&map, &at(25.5, 51.5), 112, &params));
        assert_eq!(planned_on(&route), Some(100), "due at 112, waits for the map of 115");
        map.prepare(next, 112, &params);
        assert_eq!(map.made_from(), None, "nothing made ahead for the frame the replan was due");
        assert_eq!(map.costs_in_use(115, &params), Some(costs), "the costs are in use until the map");
        map.prepare(next, 115, &params);
        assert_eq!(map.made_from(), Some(next), "made ahead for the map's frame, in case the map is late");
        route.waypoint(&plan_from(&map, &at(26.5, 51.5), 115, &params));
        assert_eq!(planned_on(&route), Some(115), "the map is late: replanned on its frame all the same");
        map.expect_next_map_at(Some(131));
        route.waypoint(&plan_from(&map, &at(25.5, 51.5), 127, &params));
        assert_eq!(planned_on(&route), Some(127), "a map 4 frames after the replan is not waited for");
    }

    #[test]
    fn a_repeated_request_gets_the_costs_given_last_without_a_search() {
        let (map, params, costs, here, next) = replanning_map();
        let first = map.costs_from(here, &costs, 100);
        map.prepare(here, 112, &params);
        assert!(map.searched.borrow().made.is_none(), "nothing made ahead for a request already answered");
        assert!(Arc::ptr_eq(&first, &map.costs_from(here, &costs, 112)), "the same costs, not searched again");
        let elsewhere = map.costs_from(next, &costs, 124);
        assert!(!Arc::ptr_eq(&first, &elsewhere) && searched_from(&elsewhere, map.grid(), next, &costs));
        let other = Costs { cross_unknown: false, ..costs };
        assert!(searched_from(&map.costs_from(next, &other, 125), map.grid(), next, &other), "other costs");
    }

    #[test]
    fn the_costs_in_use_are_those_last_asked_for_within_a_replan_period() {
        let (map, params, costs, here, _) = replanning_map();
        assert_eq!(map.costs_in_use(1, &params), None, "nothing asked yet");
        map.costs_from(here, &costs, 100);
        assert_eq!(map.costs_in_use(112, &params), Some(costs));
        assert_eq!(map.costs_in_use(113, &params), None, "no plan for longer than a replan period");
    }

    #[test]
    fn routes_follow_the_map() {
        let grid = half_explored();
        let params = DecisionParams::default();
        let mut route = Route::to((55.5, 52.5)).unwrap();
        let waypoint = route.waypoint(&plan_from(&planning(&grid, 1), &at(21.5, 51.5), 0, &params)).unwrap();
        assert!(waypoint.0 > 21.5 && (50.0..54.0).contains(&waypoint.1));
        let cost = route.cost().unwrap();
        assert!((34.0..60.0).contains(&cost), "at least the 34 m between, unknown cells dearer: {cost}");
        let mut nowhere = Route::to((5.5, 5.5)).unwrap();
        assert_eq!(nowhere.waypoint(&plan_from(&planning(&grid, 1), &at(21.5, 51.5), 0, &params)), None);
        assert_eq!(nowhere.cost(), None);
        assert!(Route::to((-1.0, 0.0)).is_none());
        let mut into_the_wall = Route::to((40.5, 55.5)).unwrap();
        let waypoint = into_the_wall.waypoint(&plan_from(&planning(&grid, 1), &at(21.5, 51.5), 0, &params)).unwrap();
        assert!(waypoint.0 > 21.5 && (50.0..54.0).contains(&waypoint.1), "a sample by the wall: {waypoint:?}");
        let near_the_end = into_the_wall.waypoint(&plan_from(&planning(&grid, 1), &at(39.5, 52.5), 100, &params));
        assert_eq!(near_the_end, Some((40.5, 55.5)), "the goal itself once the path's end is in reach");
        let mut deep_in_the_wall = Route::to((40.5, 58.5)).unwrap();
        assert_eq!(deep_in_the_wall.waypoint(&plan_from(&planning(&grid, 1), &at(21.5, 51.5), 0, &params)), None);
    }
}
