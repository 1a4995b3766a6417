//! The maps the machine plans on: the received map with the stuck marks applied, the maps and
//! rocks still arriving, and the path costs made ahead between frames.

use rover_msgs::map_grid::cell_of_point;

use crate::arrivals::{Delayed, MapCadence};
use crate::grid::Grid;
use crate::params::DecisionParams;
use crate::pose::{Position, one_frame_on};
use crate::route::PlanningMap;
use crate::stuck::StuckMarks;

/// Exploring forgets the stuck marks that cut off every frontier only once the rover is this far
/// from where it last did so, metres: nearer, it got stuck there again, and the marks hold.
const MARKS_HOLD_NEAR_M: f64 = 3.0;

/// What the machine plans on, and what is on its way to it.
#[derive(Debug, Clone)]
pub(super) struct Maps {
    pub(super) received: Grid,
    /// Maps and rocks received but not yet due ([`crate::arrivals`]).
    arriving_maps: Delayed<Grid>,
    arriving_rocks: Delayed<Vec<(f64, f64)>>,
    /// When the maps taken came, to expect the next.
    cadence: MapCadence,
    pub(super) planning: PlanningMap,
    /// The planning map of the map due on the next frame, made between frames with the path costs
    /// its first plan will likely ask for ([`Maps::prepare_next_frame`]).
    pub(super) next_planning: Option<PlanningMap>,
    pub(super) stuck_marks: StuckMarks,
    /// Where the rover was when exploring last forgot the stuck marks.
    marks_forgotten_at: Option<(f64, f64)>,
    /// The frame [`Maps::prepare_next_frame`] last ran after and where the rover was then, to
    /// guess where it will be on the next.
    prepared_at: Option<(u64, Position)>,
}

impl Default for Maps {
    fn default() -> Self {
        Maps {
            received: Grid::unknown(),
            arriving_maps: Delayed::default(),
            arriving_rocks: Delayed::default(),
            cadence: MapCadence::default(),
            planning: PlanningMap::new(Grid::unknown(), 0),
            next_planning: None,
            stuck_marks: StuckMarks::default(),
            marks_forgotten_at: None,
            prepared_at: None,
        }
    }
}

impl Maps {
    /// Takes a new map at `frame`, with the cells where the rover got stuck lately marked as
    /// obstacles, unless it is ignored ([`is_ignored`]).
    pub(super) fn set_map(&mut self, map: Grid, frame: u64) {
        if is_ignored(&map) {
            return;
        }
        self.stuck_marks.expire(frame);
        self.received = map;
        self.apply_stuck_marks();
    }

    /// Plans on the received map with the stuck marks as a new version: the planning map made
    /// ahead for it when that is the same map.
    pub(super) fn apply_stuck_marks(&mut self) {
        let (grid, version) = (self.stuck_marks.applied_to(&self.received), self.planning.version() + 1);
        self.planning = match self.next_planning.take() {
            Some(made) if made.version() == version && *made.grid() == grid => made,
            _ => PlanningMap::new(grid, version),
        };
        self.planning.expect_next_map_at(self.cadence.next_due());
    }

    /// Forgets the cells marked where the rover got stuck; returns whether there were any.
    pub(super) fn forget_stuck_marks(&mut self) -> bool {
        if !self.stuck_marks.forget() {
            return false;
        }
        self.apply_stuck_marks();
        true
    }

    /// Forgets the stuck marks that cut off every frontier ([`Maps::forget_stuck_marks`]),
    /// unless the rover `at` is still near where it last did so ([`MARKS_HOLD_NEAR_M`]); returns
    /// whether it forgot any.
    pub(super) fn forget_stuck_marks_to_explore(&mut self, at: &Position) -> bool {
        if self.marks_forgotten_at.is_some_and(|spot| at.distance_to(spot) < MARKS_HOLD_NEAR_M) {
            return false;
        }
        let forgot = self.forget_stuck_marks();
        if forgot {
            self.marks_forgotten_at = Some((at.x_m, at.y_m));
        }
        forgot
    }

    /// Takes a map made from the scans up to mission frame `made_at_frame`, in effect
    /// [`crate::arrivals::ARRIVAL_DELAY_FRAMES`] frames after it.
    pub(super) fn receive_map(&mut self, made_at_frame: u64, map: Grid) {
        self.arriving_maps.push(made_at_frame, map);
    }

    /// Takes the rocks located by the scans up to mission frame `made_at_frame`.
    pub(super) fn receive_rocks(&mut self, made_at_frame: u64, rocks: Vec<(f64, f64)>) {
        self.arriving_rocks.push(made_at_frame, rocks);
    }

    /// Puts the map due at `frame` into effect (the planning map made ahead for it, if any, is
    /// taken or dropped then); the rocks due then, if any.
    pub(super) fn take_arrivals(&mut self, frame: u64) -> Option<Vec<(f64, f64)>> {
        if let Some((made_at, map)) = self.arriving_maps.take_due(frame) {
            self.cadence.record(made_at);
            self.set_map(map, frame);
        }
        self.next_planning = None;
        self.arriving_rocks.take_due(frame).map(|(_, rocks)| rocks)
    }

    /// Marks a cell at the front of the rover stuck `at` (or the next one of `path`) as an
    /// obstacle for planning for a while; the cell marked, if any.
    pub(super) fn mark_stuck(
        &mut self,
        at: (&Position, u64),
        path: &[usize],
        params: &DecisionParams,
    ) -> Option<usize> {
        let cell = self.stuck_marks.note_stuck(at, self.planning.grid(), path, params)?;
        self.apply_stuck_marks();
        Some(cell)
    }

    /// Between frames, after `frame`'s drive command went out: makes ahead the path costs the next
    /// frame will likely ask for, the rover now at `at`: for a periodic replan
    /// ([`PlanningMap::prepare`]), or for the first plan on a new map that takes effect then,
    /// from the cell the rover will be in if it goes on as it did since the frame before. What
    /// the machine decides does not change, only when the search runs.
    pub(super) fn prepare_next_frame(&mut self, frame: u64, at: &Position, params: &DecisionParams) {
        let next_frame = frame.saturating_add(1);
        let (x_m, y_m) = match self.prepared_at.replace((frame, *at)) {
            Some((before_frame, before)) if before_frame + 1 == frame => one_frame_on(&before, at),
            _ => (at.x_m, at.y_m),
        };
        let Some(start) = cell_of_point(x_m, y_m) else { return };
        match self.arriving_maps.newest_due(next_frame).filter(|map| !is_ignored(map)) {
            Some(map) => self.next_planning = self.planning_ahead(map, start, next_frame, params),
            None => self.planning.prepare(start, next_frame, params),
        }
    }

    /// The planning map that `map`, due at `next_frame`, will make (as [`Maps::set_map`] will,
    /// the stuck marks as they are then), with the path costs from cell `start` made on it; none
    /// when nothing plans.
    fn planning_ahead(
        &self,
        map: &Grid,
        start: usize,
        next_frame: u64,
        params: &DecisionParams,
    ) -> Option<PlanningMap> {
        let costs = self.planning.costs_in_use(next_frame, params)?;
        let planning = PlanningMap::new(self.stuck_marks.applied_at(map, next_frame), self.planning.version() + 1);
        planning.make_ahead(start, &costs);
        Some(planning)
    }
}

/// Whether `map` says nothing yet and is ignored: a map without free cells (the mapping node's
/// first publication, before any scan), which could otherwise end the exploration.
fn is_ignored(map: &Grid) -> bool {
    map.counts().0 == 0
}
