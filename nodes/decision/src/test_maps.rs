//! Maps and poses shared by the unit tests of the planning modules.

use rover_msgs::map_grid::{CELLS, cell_at};

use crate::grid::Grid;
use crate::pose::Position;

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
