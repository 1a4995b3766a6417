//! Frontier exploration: which cells the camera has seen up close, which frontier to head for
//! next, and when to give a target up.

use std::sync::Arc;

use rover_msgs::map_grid::{CELLS, SIDE_CELLS, cell_at, cell_centre_m, cell_of_point};

use crate::grid::{Cell, CostMap, Costs, Grid};
use crate::params::DecisionParams;
use crate::pose::Position;
use crate::route::{GOAL_SLACK_CELLS, OBSTACLE_CROSSING_COST, PlanStart, PlanningMap, lookahead, path_costs};
use crate::tour;

/// A frontier needs enough unknown cells within this many cells.
const FRONTIER_RADIUS_CELLS: usize = 2;
/// Cells within this distance of a reached or abandoned target stop being frontier candidates.
const EXPLORED_RADIUS_CELLS: usize = 3;
/// Recoveries on the way to one target before it is abandoned.
const RECOVERIES_PER_TARGET: u32 = 2;
/// A plan that reaches fewer cells than this is walled in by the map.
const WALLED_IN_CELLS: usize = 25;
/// Longest look at the unexplored cells of a reached target, seconds (a half turn takes 4 s).
const LOOK_S: f64 = 5.0;
/// A new target at least this far off the heading, degrees, turns the rover around: it is chosen
/// again on the next map, which holds what the camera saw while the rover got there.
const TURN_AROUND_DEG: f64 = 100.0;

/// Frontier exploration. A cell is explored once it is free on the map or has been in close view
/// of the camera: obstacle cells seen only from afar may be floor hidden behind the projection
/// of a wall. The explorer picks the best frontier (a free cell next to unexplored ones), goes
/// there, and abandons targets that take too long or keep the rover stuck. A target reached with
/// its unexplored cells still beside or behind the rover (a side passage) is first looked at:
/// the rover turns toward those cells until the camera has seen them, then moves on.
#[derive(Debug, Clone)]
pub(crate) struct Explorer {
    target: Option<Target>,
    look: Option<Look>,
    past_obstacles: bool,
    inspected: Vec<bool>,
    /// The cells seen up close before the search for a missing sample forgot them (see
    /// [`Explorer::forget_inspected`]), until recalled.
    forgotten: Option<Vec<bool>>,
    explored: Vec<bool>,
    costs: Option<Arc<CostMap>>,
    planned: Option<(u64, u64)>,
}

/// A look at the unexplored cells around a reached target.
#[derive(Debug, Clone, Copy)]
struct Look {
    around: usize,
    until_frame: u64,
}

#[derive(Debug, Clone)]
struct Target {
    cell: usize,
    chosen_frame: u64,
    allowed_frames: u64,
    path: Vec<usize>,
    recoveries: u32,
    /// The version of the map a turn-around target was chosen on, until a newer map confirms it.
    unconfirmed_on_map: Option<u64>,
}

impl Target {
    /// A target at frontier `cell`, chosen at `frame` from `at` on map `version`.
    fn new(
        cell: usize,
        costs: &CostMap,
        (at, version): (&Position, u64),
        frame: u64,
        params: &DecisionParams,
    ) -> Target {
        let (cost, centre) = (costs.distance(cell), cell_centre_m(cell));
        let bearing_deg = at.bearing_to(centre).to_degrees();
        tracing::debug!(
            frame,
            at = ?(at.x_m, at.y_m),
            target = ?centre,
            cost,
            bearing_deg = bearing_deg.round(),
            "new frontier target"
        );
        Target {
            cell,
            chosen_frame: frame,
            allowed_frames: params.frames_for_way(params.target_timeout_s, cost as f64),
            path: Vec::new(),
            recoveries: 0,
            unconfirmed_on_map: (bearing_deg.abs() >= TURN_AROUND_DEG).then_some(version),
        }
    }

    /// Whether the target's time (from its choice, or from the end of a detour) is up at `frame`.
    fn timed_out(&self, frame: u64) -> bool {
        frame >= self.chosen_frame + self.allowed_frames
    }
}

impl Default for Explorer {
    fn default() -> Self {
        let cells = CELLS;
        Explorer {
            target: None,
            look: None,
            past_obstacles: false,
            inspected: vec![false; cells],
            forgotten: None,
            explored: vec![false; cells],
            costs: None,
            planned: None,
        }
    }
}

/// What the explorer has learnt about the world, for a restarted node to take over (see
/// [`crate::snapshot`]). One entry per map cell in each vector.
#[derive(Debug, Clone, PartialEq)]
pub struct ExplorerMemory {
    /// Cells seen up close by the camera.
    pub inspected: Vec<bool>,
    /// Cells around targets that were reached or given up.
    pub explored: Vec<bool>,
    /// Whether plans already go past obstacle cells.
    pub past_obstacles: bool,
}

impl Explorer {
    /// What the explorer has learnt so far.
    pub(crate) fn memory(&self) -> ExplorerMemory {
        ExplorerMemory {
            inspected: self.inspected.clone(),
            explored: self.explored.clone(),
            past_obstacles: self.past_obstacles,
        }
    }

    /// An explorer that carries on from `memory`, without a target.
    pub(crate) fn with_memory(memory: ExplorerMemory) -> Self {
        let ExplorerMemory { inspected, explored, past_obstacles } = memory;
        Explorer { inspected, explored, past_obstacles, ..Explorer::default() }
    }

    /// The cells of the path to the current target (empty without one).
    pub(crate) fn path(&self) -> &[usize] {
        self.target.as_ref().map_or(&[], |t| &t.path)
    }

    /// The current target's centre, if any.
    pub(crate) fn target(&self) -> Option<(f64, f64)> {
        self.target.as_ref().map(|t| cell_centre_m(t.cell))
    }

    /// Path cost from the rover (as of the last plan) to the cell containing `point`, or to the
    /// cheapest reachable cell next to it when that is an obstacle.
    pub(crate) fn cost_to(&self, point: (f64, f64)) -> Option<f64> {
        let costs = self.costs.as_ref()?;
        let cell = costs.reachable_near(cell_of_point(point.0, point.1)?, GOAL_SLACK_CELLS)?;
        Some(costs.distance(cell) as f64)
    }

    /// Marks the cells in close view of the camera at `at` as inspected.
    pub(crate) fn inspect(&mut self, at: &Position, params: &DecisionParams) {
        let range_m = params.inspect_range_m;
        let half_angle_rad = params.inspect_half_angle_deg.to_radians();
        let (x0, x1) = ((at.x_m - range_m).floor() as i64, (at.x_m + range_m).ceil() as i64);
        let (y0, y1) = ((at.y_m - range_m).floor() as i64, (at.y_m + range_m).ceil() as i64);
        let side = SIDE_CELLS as i64;
        for y in y0.max(0)..y1.min(side) {
            for x in x0.max(0)..x1.min(side) {
                let cell = cell_at(x as usize, y as usize);
                let centre = cell_centre_m(cell);
                if at.distance_to(centre) <= range_m && at.bearing_to(centre).abs() <= half_angle_rad {
                    self.inspected[cell] = true;
                }
            }
        }
    }

    fn unexplored(&self, grid: &Grid, cell: usize) -> bool {
        grid.cell(cell) != Cell::Free && !self.inspected[cell]
    }

    /// Whether the last plan reached hardly any cells: the map walls the rover in (it stands in
    /// or among obstacle cells, e.g. started again next to a rock), so that no frontier says
    /// anything about the world.
    pub(crate) fn walled_in(&self) -> bool {
        self.costs.as_ref().is_some_and(|costs| costs.reachable_cells() < WALLED_IN_CELLS)
    }

    /// Starts the current target's clock again after a detour (to a sample): the time away does
    /// not count against it, nor against the look at it, which starts again once it is reached.
    pub(crate) fn resume_after_detour(&mut self, frame: u64) {
        if let Some(target) = self.target.as_mut() {
            target.chosen_frame = frame;
        }
        self.look = None;
    }

    /// Notes a recovery on the way to the current target; abandons it after a few.
    pub(crate) fn note_recovery(&mut self) {
        if let Some(target) = self.target.as_mut() {
            target.recoveries += 1;
            if target.recoveries >= RECOVERIES_PER_TARGET {
                self.abandon_target();
            }
        }
    }

    /// Plans past obstacle cells from now on, at a high cost: frontiers that the map walls off
    /// become candidates. Returns whether it did not already.
    pub(crate) fn look_past_obstacles(&mut self) -> bool {
        !std::mem::replace(&mut self.past_obstacles, true)
    }

    fn costs(&self, params: &DecisionParams) -> Costs {
        let obstacle = self.past_obstacles.then_some(OBSTACLE_CROSSING_COST);
        Costs { obstacle, ..path_costs(params) }
    }

    /// Forgets which cells the camera has seen up close, so that walls seen before count as
    /// frontiers again (the map may have been wrong there, e.g. an exit mapped as rock); returns
    /// whether any cell had been seen.
    pub(crate) fn forget_inspected(&mut self) -> bool {
        let any = self.inspected.iter().any(|&i| i);
        let forgotten = self.forgotten.get_or_insert_with(|| vec![false; CELLS]);
        forgotten.iter_mut().zip(&self.inspected).for_each(|(forgotten, &seen)| *forgotten |= seen);
        self.inspected.fill(false);
        any
    }

    /// Remembers again the cells seen up close that [`Explorer::forget_inspected`] forgot: once no
    /// sample is missing, looking at those walls again would find nothing new.
    pub(crate) fn recall_inspected(&mut self) {
        if let Some(forgotten) = self.forgotten.take() {
            self.inspected.iter_mut().zip(&forgotten).for_each(|(seen, &before)| *seen |= before);
        }
    }

    /// Makes every frontier a candidate again; returns whether any had been ruled out.
    pub(crate) fn forget_explored(&mut self) -> bool {
        let any = self.explored.iter().any(|&e| e);
        self.explored.fill(false);
        any
    }

    /// The point to steer toward, or `None` when no frontier is left (or the rover is off the map);
    /// new targets are the first stops of tours that end at `home`.
    pub(crate) fn waypoint(&mut self, from: &PlanStart, home: Option<(f64, f64)>) -> Option<(f64, f64)> {
        let PlanStart { map, at, frame, params } = *from;
        let (grid, start) = (map.grid(), cell_of_point(at.x_m, at.y_m)?);
        if let Some(point) = self.look_point(grid, frame) {
            return Some(point);
        }
        if let Some((cell, timed_out)) = self.target.as_ref().map(|t| (t.cell, t.timed_out(frame))) {
            let reached = at.distance_to(cell_centre_m(cell)) < params.frontier_reached_m;
            if reached && !timed_out {
                self.look = Some(Look { around: cell, until_frame: frame + params.frames(LOOK_S) });
                if let Some(point) = self.look_point(grid, frame) {
                    tracing::debug!(target = ?cell_centre_m(cell), ?point, "frontier target reached: looking");
                    return Some(point);
                }
            }
            if timed_out || reached {
                tracing::debug!(target = ?cell_centre_m(cell), timed_out, "frontier target done");
                self.abandon_target();
            }
        }
        if self.target.is_none() || from.replan_due(self.planned) {
            let home = home.and_then(|(x, y)| cell_of_point(x, y));
            self.replan(map, (start, home), at, frame, params);
            self.planned = Some((frame, map.version()));
        }
        lookahead(grid, &self.target.as_ref()?.path, at, params)
    }

    /// While looking at a reached target: the middle of its unexplored cells. The look (and the
    /// target) ends once the camera has seen them all or the time is up.
    fn look_point(&mut self, grid: &Grid, frame: u64) -> Option<(f64, f64)> {
        let look = self.look?;
        let unexplored: Vec<(f64, f64)> = Grid::cells_around(look.around, FRONTIER_RADIUS_CELLS)
            .filter(|&n| self.unexplored(grid, n))
            .map(cell_centre_m)
            .collect();
        if unexplored.is_empty() || frame >= look.until_frame {
            self.abandon_target();
            return None;
        }
        let count = unexplored.len() as f64;
        Some((unexplored.iter().map(|p| p.0).sum::<f64>() / count, unexplored.iter().map(|p| p.1).sum::<f64>() / count))
    }

    /// Plans from cell `start` again, choosing a new target (on the way to cell `home`) when the
    /// target is no longer a frontier, or when it turns the rover around and a newer map than the
    /// one it was chosen on has come (which keeps it if it is still the best).
    fn replan(
        &mut self,
        map: &PlanningMap,
        (start, home): (usize, Option<usize>),
        at: &Position,
        frame: u64,
        params: &DecisionParams,
    ) {
        let (grid, version) = (map.grid(), map.version());
        let costs = map.costs_from(start, &self.costs(params), frame);
        let frontier = self.target.as_ref().is_some_and(|t| self.is_candidate(grid, &costs, t.cell, params));
        let confirmed = self.target.as_ref().is_some_and(|t| t.unconfirmed_on_map.is_none_or(|v| v == version));
        if !(frontier && confirmed) {
            let best = self.best_frontier(grid, &costs, (at, home), params);
            match self.target.as_mut() {
                Some(target) if frontier && best == Some(target.cell) => target.unconfirmed_on_map = None,
                _ => self.target = best.map(|cell| Target::new(cell, &costs, (at, version), frame, params)),
            }
        }
        if let Some(target) = self.target.as_mut() {
            target.path = costs.path_to(target.cell).unwrap_or_default();
        }
        self.costs = Some(costs);
    }

    fn is_candidate(&self, grid: &Grid, costs: &CostMap, cell: usize, params: &DecisionParams) -> bool {
        !self.explored[cell]
            && grid.cell(cell) == Cell::Free
            && costs.distance(cell).is_finite()
            && Grid::cells_around(cell, FRONTIER_RADIUS_CELLS).filter(|&n| self.unexplored(grid, n)).count()
                >= params.frontier_min_unknown as usize
    }

    /// The frontier to head for from `at`: the cheapest (its path cost plus a penalty for the turn
    /// toward it), or, with `frontier_tour`, the first stop of a tour of the frontier clusters
    /// that ends at cell `home`.
    fn best_frontier(
        &self,
        grid: &Grid,
        costs: &CostMap,
        (at, home): (&Position, Option<usize>),
        params: &DecisionParams,
    ) -> Option<usize> {
        let score = |cell: usize| {
            let turn = at.bearing_to(cell_centre_m(cell)).abs() / std::f64::consts::PI;
            costs.distance(cell) as f64 + params.turn_penalty_m * turn
        };
        let candidates = grid
            .frontiers(|n| self.unexplored(grid, n))
            .into_iter()
            .filter(|&cell| self.is_candidate(grid, costs, cell, params))
            .filter(|&cell| at.distance_to(cell_centre_m(cell)) >= params.frontier_reached_m);
        if !params.frontier_tour {
            return candidates.min_by(|&a, &b| score(a).total_cmp(&score(b)));
        }
        let anchors = tour::cluster_anchors(candidates.collect(), costs);
        tour::first_stop(grid, &anchors, score, home, &self.costs(params))
    }

    fn abandon_target(&mut self) {
        self.look = None;
        let Some(target) = self.target.take() else { return };
        for cell in Grid::cells_around(target.cell, EXPLORED_RADIUS_CELLS) {
            self.explored[cell] = true;
        }
    }
}

#[cfg(test)]
mod tests {
    use rover_msgs::map_grid::{CELLS, cell_at};

    use super::*;
    use crate::route::PlanningMap;
    use crate::test_maps::{at, half_explored, planning};

    /// An explorer of a test on `map`, with the default parameters.
    struct Probe {
        explorer: Explorer,
        map: PlanningMap,
        params: DecisionParams,
    }

    impl Probe {
        /// On the half-explored corridor, nothing inspected yet.
        fn in_the_corridor() -> Self {
            Probe {
                explorer: Explorer::default(),
                map: planning(&half_explored(), 1),
                params: DecisionParams::default(),
            }
        }

        /// On the corridor, both of its walls looked at from close by.
        fn with_the_walls_inspected() -> Self {
            let mut probe = Probe::in_the_corridor();
            for x in (18..57).step_by(2) {
                for yaw_rad in [std::f64::consts::FRAC_PI_2, -std::f64::consts::FRAC_PI_2] {
                    probe.explorer.inspect(&Position { x_m: x as f64, y_m: 52.0, yaw_rad }, &probe.params);
                }
            }
            probe
        }

        /// The explorer's waypoint from `at` at `frame`.
        fn waypoint(&mut self, at: Position, frame: u64) -> Option<(f64, f64)> {
            self.explorer.waypoint(&PlanStart { map: &self.map, at: &at, frame, params: &self.params }, None)
        }

        /// A new version of the same map.
        fn new_map_version(&mut self) {
            self.map = PlanningMap::new(self.map.grid().clone(), self.map.version() + 1);
        }
    }

    #[test]
    fn walls_seen_only_from_afar_are_frontiers() {
        let mut probe = Probe::in_the_corridor();
        probe.waypoint(at(25.5, 51.5), 0);
        let target = probe.explorer.target().unwrap();
        assert!(target.0 < 40.0, "the near walls are not inspected yet: {target:?}");
    }

    #[test]
    fn the_explorer_heads_for_the_unknown_end_of_the_corridor() {
        let mut probe = Probe::with_the_walls_inspected();
        let rover = at(25.5, 51.5);
        let waypoint = probe.waypoint(rover, 0).unwrap();
        let target = probe.explorer.target().unwrap();
        assert!((58.0..61.0).contains(&target.0), "target at the frontier: {target:?}");
        let params = &probe.params;
        let farthest_m = params.lookahead_m.max(params.max_lookahead_m) + std::f64::consts::SQRT_2;
        assert!(waypoint.0 > rover.x_m && (params.lookahead_m..=farthest_m).contains(&rover.distance_to(waypoint)));
        assert!(probe.explorer.cost_to((40.5, 51.5)).is_some() && probe.explorer.cost_to((5.5, 5.5)).is_none());
    }

    #[test]
    fn with_every_wall_seen_up_close_no_frontier_is_left_until_they_are_forgotten() {
        let mut probe = Probe::with_the_walls_inspected();
        probe.explorer.inspect(&at(56.5, 51.5), &probe.params);
        assert_eq!(probe.waypoint(at(25.5, 51.5), 0), None);
        assert!(probe.explorer.forget_inspected());
        probe.new_map_version();
        assert!(probe.waypoint(at(25.5, 51.5), 1).is_some());
        assert!(!probe.explorer.forget_inspected(), "nothing was seen since");
        probe.explorer.recall_inspected();
        probe.new_map_version();
        assert_eq!(probe.waypoint(at(25.5, 51.5), 2), None, "the walls seen before the forgetting are recalled");
    }

    #[test]
    fn reached_targets_are_looked_at_then_not_chosen_again() {
        let mut probe = Probe::with_the_walls_inspected();
        probe.waypoint(at(25.5, 51.5), 0);
        let first = probe.explorer.target().unwrap();
        let facing_back = Position { x_m: first.0, y_m: first.1, yaw_rad: std::f64::consts::PI };
        let look = probe.waypoint(facing_back, 1).unwrap();
        assert!(look.0 > first.0, "looks at the unknown cells behind the rover: {look:?} from {first:?}");
        assert_eq!(probe.explorer.target(), Some(first), "the target stays while looking");
        let look_end = probe.params.frames(LOOK_S) + 1;
        probe.waypoint(facing_back, look_end);
        let second = probe.explorer.target();
        assert!(
            second.is_none_or(|s| (s.0 - first.0).abs() + (s.1 - first.1).abs() > 3.0),
            "{first:?} then {second:?}"
        );
        assert!(probe.explorer.forget_explored());
    }

    /// The corridor of [`half_explored`], walled at its west end, or with that end open: known
    /// floor on to x = 14 and unknown ground beyond.
    fn corridor(west_end_open: bool) -> PlanningMap {
        let mut data = vec![100i8; CELLS];
        for y in 50..54 {
            for x in 0..90 {
                data[cell_at(x, y)] = match x {
                    ..14 if west_end_open => -1,
                    14..20 if west_end_open => 0,
                    20..60 => 0,
                    60.. => -1,
                    _ => 100,
                };
            }
        }
        planning(&Grid::from_occupancy(&data).unwrap(), 1)
    }

    #[test]
    fn a_turn_around_is_chosen_again_on_the_next_map_and_then_kept() {
        let facing_west = Position { x_m: 36.5, y_m: 51.5, yaw_rad: std::f64::consts::PI };
        let turned_around = || {
            let mut probe = Probe { map: corridor(false), ..Probe::with_the_walls_inspected() };
            probe.waypoint(facing_west, 0);
            let behind = probe.explorer.target().unwrap();
            assert!(behind.0 > 55.0, "the only frontier is the east end, behind the rover: {behind:?}");
            probe.waypoint(facing_west, 1);
            assert_eq!(probe.explorer.target(), Some(behind), "kept on the map it was chosen on");
            (probe, behind)
        };
        let (mut opened, _) = turned_around();
        opened.map = PlanningMap::new(corridor(true).grid().clone(), 2);
        opened.waypoint(facing_west, 2);
        let ahead = opened.explorer.target().unwrap();
        assert!(ahead.0 < 20.0, "the next map opens the west end ahead: {ahead:?}");

        let (mut confirmed, behind) = turned_around();
        confirmed.new_map_version();
        confirmed.waypoint(facing_west, 2);
        assert_eq!(confirmed.explorer.target(), Some(behind), "the next map still says east");
        confirmed.map = PlanningMap::new(corridor(true).grid().clone(), 3);
        confirmed.waypoint(facing_west, 3);
        assert_eq!(confirmed.explorer.target(), Some(behind), "a confirmed target is kept while it is a frontier");
    }

    #[test]
    fn a_target_has_the_time_of_its_way_and_a_detour_does_not_count_against_it() {
        let mut probe = Probe::with_the_walls_inspected();
        probe.waypoint(at(25.5, 51.5), 0);
        let target = probe.explorer.target();
        let way_m = probe.explorer.cost_to(target.unwrap()).unwrap();
        let allowed = probe.params.frames_for_way(probe.params.target_timeout_s, way_m);
        assert!(allowed > probe.params.frames(probe.params.target_timeout_s + 5.0), "{way_m} m of way add time");
        let back = allowed + 10;
        probe.explorer.resume_after_detour(back);
        probe.waypoint(at(26.5, 51.5), back + allowed - 1);
        assert_eq!(probe.explorer.target(), target, "still the target after a detour longer than its time");
        probe.waypoint(at(26.5, 51.5), back + allowed);
        assert_ne!(probe.explorer.target(), target, "it times out on its own clock");
    }

    #[test]
    fn past_obstacles_a_walled_off_frontier_becomes_a_target() {
        let mut data = vec![100i8; CELLS];
        for y in 50..54 {
            for x in 20..40 {
                data[cell_at(x, y)] = match x {
                    24 | 25 => 100,
                    30.. => -1,
                    _ => 0,
                };
            }
        }
        let mut probe = Probe { map: planning(&Grid::from_occupancy(&data).unwrap(), 1), ..Probe::in_the_corridor() };
        for yaw_deg in [0.0f64, 90.0, 180.0, 270.0] {
            probe.explorer.inspect(&Position { x_m: 22.0, y_m: 52.0, yaw_rad: yaw_deg.to_radians() }, &probe.params);
        }
        assert_eq!(probe.waypoint(at(22.0, 52.0), 0), None, "the far side is walled off");
        assert!(probe.explorer.look_past_obstacles() && !probe.explorer.look_past_obstacles());
        probe.new_map_version();
        probe.waypoint(at(22.0, 52.0), 1);
        assert!(probe.explorer.target().is_some_and(|t| t.0 > 26.0), "{:?}", probe.explorer.target());
    }
}
