//! Maps and poses shared by the unit tests of the planning modules.

use rover_msgs::map_grid::{CELLS, cell_at};

use crate::grid::Grid;
use crate::params::DecisionParams;
use crate::pose::Position;
use crate::route::{PlanStart, PlanningMap};

/// A map with a known corridor along y = 50..54 from x = 20 to 60, unknown beyond x = 60.
pub(crate) fn half_explored() -> Grid {
    let mut data = vec![100i8; CELLS];
    for y in 50..54 {
        for x in 20..90 {
            data[cell_at(x, y)] = if x < 60 { 0 } else { -1 };
        }
    }
    Grid::from_occupancy(&data).unwrap()
}

pub(crate) fn at(x_m: f64, y_m: f64) -> Position {
    Position { x_m, y_m, yaw_rad: 0.0 }
}

/// `grid` as version `version` of the planning map.
pub(crate) fn planning(grid: &Grid, version: u64) -> PlanningMap {
    PlanningMap::new(grid.clone(), version)
}

/// A plan on `map` from `at` at `frame` with `params`.
pub(crate) fn plan_from<'a>(
    map: &'a PlanningMap,
    at: &'a Position,
    frame: u64,
    params: &'a DecisionParams,
) -> PlanStart<'a> {
    PlanStart { map, at, frame, params }
}
