//! The cells of the world map as the `map` topic (`nav_msgs/OccupancyGrid`) lays them out: a
//! square of [`SIDE_CELLS`] x [`SIDE_CELLS`] cells of 1 m from the world origin, row-major with
//! row = y. The one definition of the map's size and cell numbering for every node that reads it.

/// Cells along each side of the map; a cell is 1 m, so this is also the side in metres.
pub const SIDE_CELLS: usize = 200;
/// Cells of the whole map.
pub const CELLS: usize = SIDE_CELLS * SIDE_CELLS;

/// The occupancy value of a navigable cell.
pub const OCCUPANCY_FREE: i8 = 0;
/// The occupancy value of an obstacle cell.
pub const OCCUPANCY_OCCUPIED: i8 = 100;
/// The occupancy value of a cell not known yet.
pub const OCCUPANCY_UNKNOWN: i8 = -1;

/// The cell at column `x`, row `y` (both on the map).
#[inline]
pub const fn cell_at(x: usize, y: usize) -> usize {
    y * SIDE_CELLS + x
}

/// The cell at column `x`, row `y`, if that is on the map.
#[inline]
pub fn checked_cell_at(x: i64, y: i64) -> Option<usize> {
    let side = 0..SIDE_CELLS as i64;
    (side.contains(&x) && side.contains(&y)).then(|| cell_at(x as usize, y as usize))
}

/// Column and row of `cell`.
#[inline]
pub const fn cell_xy(cell: usize) -> (usize, usize) {
    (cell % SIDE_CELLS, cell / SIDE_CELLS)
}

/// The cell containing the world point (`x_m`, `y_m`), if it is on the map.
#[inline]
pub fn cell_of_point(x_m: f64, y_m: f64) -> Option<usize> {
    let side_m = SIDE_CELLS as f64;
    (x_m >= 0.0 && y_m >= 0.0 && x_m < side_m && y_m < side_m).then(|| cell_at(x_m as usize, y_m as usize))
}

/// The centre of `cell`, world metres.
pub fn cell_centre_m(cell: usize) -> (f64, f64) {
    let (x, y) = cell_xy(cell);
    (x as f64 + 0.5, y as f64 + 0.5)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_are_numbered_row_major_from_the_origin_with_row_y() {
        assert_eq!(cell_at(3, 2), 2 * SIDE_CELLS + 3);
        assert_eq!(cell_xy(cell_at(3, 2)), (3, 2));
        assert_eq!(cell_of_point(3.9, 2.1), Some(cell_at(3, 2)));
        assert_eq!(cell_centre_m(cell_at(3, 2)), (3.5, 2.5));
        assert_eq!(checked_cell_at(3, 2), Some(cell_at(3, 2)));
    }

    #[test]
    fn points_and_cells_off_the_map_have_no_cell() {
        let side = SIDE_CELLS as f64;
        for (x_m, y_m) in [(-0.1, 5.0), (5.0, -0.1), (side, 5.0), (5.0, side), (f64::NAN, 5.0)] {
            assert_eq!(cell_of_point(x_m, y_m), None, "({x_m}, {y_m})");
        }
        assert_eq!(checked_cell_at(-1, 0), None);
        assert_eq!(checked_cell_at(0, SIDE_CELLS as i64), None);
        assert_eq!(cell_of_point(side - 0.01, side - 0.01), Some(CELLS - 1));
    }
}
