//! What the rover cannot drive through: the shared questions about a rock standing on the ground,
//! whatever its shape is made of (faceted boulders, surveyed rocks).

use crate::world::WORLD_SIZE;

/// Rock lower than this above the ground does not block the rover, metres.
pub(crate) const CLEARANCE_M: f64 = 0.05;

/// A rock standing on the ground.
pub(crate) trait Obstacle {
    /// True if the rock fills the vertical line through (x, y) somewhere between [`CLEARANCE_M`] above `ground_m` and `up_to_m` above it.
    fn covers(&self, x_m: f64, y_m: f64, ground_m: f64, up_to_m: f64) -> bool;

    /// The horizontal box that holds the rock: south-west and north-east corners (x, y), metres.
    fn bounds_m(&self) -> [[f64; 2]; 2];

    /// The cells of a `WORLD_SIZE` x `WORLD_SIZE` mask that are set and whose centre lies under the
    /// rock at some height up to `up_to_m` above the floor.
    fn cells_under(&self, mask: &[bool], up_to_m: f64) -> Vec<usize> {
        let [[x0, y0], [x1, y1]] = self.bounds_m();
        let last = WORLD_SIZE as i64 - 1;
        let cells = |lo: f64, hi: f64| (lo.floor() as i64).max(0)..=(hi.floor() as i64).min(last);
        cells(y0, y1)
            .flat_map(|y| cells(x0, x1).map(move |x| (x, y)))
            .map(|(x, y)| (x, y, y as usize * WORLD_SIZE + x as usize))
            .filter(|&(x, y, cell)| mask[cell] && self.covers(x as f64 + 0.5, y as f64 + 0.5, 0.0, up_to_m))
            .map(|(_, _, cell)| cell)
            .collect()
    }
}
