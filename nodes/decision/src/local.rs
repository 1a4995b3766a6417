//! Free space ahead, from one terrain scan: for a fan of directions, how far the ground is known
//! to be navigable along a lane as wide as the rover.

use rover_msgs::msg::TerrainScan;

/// The scan geometry the rays were laid out for.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Geometry {
    rows: u32,
    cols: u32,
    resolution_m: f32,
    origin_x_m: f32,
    origin_y_m: f32,
}

impl Geometry {
    fn of(scan: &TerrainScan) -> Self {
        Geometry {
            rows: scan.rows,
            cols: scan.cols,
            resolution_m: scan.resolution_m,
            origin_x_m: scan.origin_x_m,
            origin_y_m: scan.origin_y_m,
        }
    }

    /// The scan cell containing rover-frame point (x, y): `Ok(None)` before the first row (under
    /// the rover, assumed free), `Err(())` outside the scan or beyond 32-bit cell numbers.
    fn cell(&self, x: f64, y: f64) -> Result<Option<u32>, ()> {
        let res = self.resolution_m as f64;
        let row = ((x - self.origin_x_m as f64) / res).floor();
        let col = ((y - self.origin_y_m as f64) / res).floor();
        if row < 0.0 {
            return Ok(None);
        }
        if row >= self.rows as f64 || col < 0.0 || col >= self.cols as f64 {
            return Err(());
        }
        let index = u64::from(row as u32) * u64::from(self.cols) + col as u64;
        u32::try_from(index).map(Some).map_err(|_| ())
    }
}

/// One lane: the scan cells along it, with their distance from the rover.
type Lane = Vec<(u32, f32)>;

/// Rays laid out once for a scan geometry.
#[derive(Debug, Clone)]
pub struct FreeSpaceRays {
    geometry: Option<Geometry>,
    directions_rad: Vec<f32>,
    half_width_m: f64,
    max_range_m: f64,
    lanes: Vec<[Lane; 3]>,
}

/// Known-free distance per direction of one scan.
#[derive(Debug, Clone, PartialEq)]
pub struct FreeSpace {
    /// Directions, radians, positive left, ascending.
    pub directions_rad: Vec<f32>,
    /// Free distance along each, metres.
    pub free_m: Vec<f32>,
}

impl FreeSpace {
    /// Free distance in the direction closest to `bearing_rad`.
    pub fn toward(&self, bearing_rad: f32) -> f32 {
        let index = self
            .directions_rad
            .iter()
            .enumerate()
            .min_by(|a, b| (a.1 - bearing_rad).abs().total_cmp(&(b.1 - bearing_rad).abs()))
            .map_or(0, |(i, _)| i);
        self.free_m.get(index).copied().unwrap_or(0.0)
    }

    /// The longest free distance of the directions within `half_angle_rad` of `bearing_rad`: the
    /// room ahead the rover can still steer into.
    pub(crate) fn longest_within(&self, bearing_rad: f32, half_angle_rad: f32) -> f32 {
        let within = |direction: f32| (direction - bearing_rad).abs() <= half_angle_rad + ANGLE_TOLERANCE_RAD;
        self.directions_rad
            .iter()
            .zip(&self.free_m)
            .filter(|&(&d, _)| within(d))
            .map(|(_, &free)| free)
            .fold(0.0, f32::max)
    }

    /// The direction closest to `bearing_rad` with at least `clearance_m` free, if any.
    pub fn best_toward(&self, bearing_rad: f32, clearance_m: f32) -> Option<f32> {
        self.directions_rad
            .iter()
            .zip(&self.free_m)
            .filter(|&(_, &free)| free >= clearance_m)
            .min_by(|a, b| (a.0 - bearing_rad).abs().total_cmp(&(b.0 - bearing_rad).abs()))
            .map(|(&direction, _)| direction)
    }

    /// The direction with the most free distance (ties to the one nearest straight ahead).
    pub fn most_open(&self) -> f32 {
        self.directions_rad
            .iter()
            .zip(&self.free_m)
            .max_by(|a, b| a.1.total_cmp(b.1).then(b.0.abs().total_cmp(&a.0.abs())))
            .map_or(0.0, |(&d, _)| d)
    }
}

/// Directions this close count as the same, radians (they are laid out in single precision).
const ANGLE_TOLERANCE_RAD: f32 = 1e-4;

/// A lane is blocked where this many cells that are not navigable (obstacle or rock) lie within
/// [`BLOCKING_SPAN_CELLS`] consecutive cells of it; fewer are specks, not obstacles (the real
/// floor's dark dimples fail the navigable colour rule on a few per cent of its pixels).
const BLOCKING_CELLS: usize = 3;
/// See [`BLOCKING_CELLS`].
const BLOCKING_SPAN_CELLS: usize = 4;

/// The decision measures free space in directions within this angle either side of the heading,
/// degrees...
const DECISION_SPAN_DEG: f32 = 45.0;
/// ...every this many degrees...
const DECISION_STEP_DEG: f32 = 5.0;
/// ...up to this distance, metres.
const DECISION_RANGE_M: f64 = 6.0;

impl FreeSpaceRays {
    /// The rays the decision steers by, lanes `half_width_m` either side.
    pub fn for_decision(half_width_m: f64) -> Self {
        Self::new(DECISION_SPAN_DEG, DECISION_STEP_DEG, half_width_m, DECISION_RANGE_M)
    }

    /// Rays every `step_deg` within +-`span_deg`, lanes `half_width_m` either side, up to `max_range_m`.
    pub fn new(span_deg: f32, step_deg: f32, half_width_m: f64, max_range_m: f64) -> Self {
        let count = (2.0 * span_deg / step_deg).round() as i32;
        let directions_rad = (0..=count).map(|i| (-span_deg + i as f32 * step_deg).to_radians()).collect();
        FreeSpaceRays { geometry: None, directions_rad, half_width_m, max_range_m, lanes: Vec::new() }
    }

    fn lay_out(&mut self, geometry: Geometry) {
        let step = geometry.resolution_m as f64 / 2.0;
        self.lanes = self
            .directions_rad
            .iter()
            .map(|&theta| {
                let (s, c) = (theta as f64).sin_cos();
                [-self.half_width_m, 0.0, self.half_width_m].map(|offset| {
                    let mut lane = Lane::new();
                    let mut d = 0.0;
                    while d <= self.max_range_m {
                        let (x, y) = (d * c - offset * s, d * s + offset * c);
                        match geometry.cell(x, y) {
                            Ok(Some(cell)) if lane.last().is_none_or(|&(last, _)| last != cell) => {
                                lane.push((cell, d as f32))
                            }
                            Ok(_) => {}
                            Err(()) => {
                                lane.push((u32::MAX, d as f32));
                                break;
                            }
                        }
                        d += step;
                    }
                    lane
                })
            })
            .collect();
        self.geometry = Some(geometry);
    }

    /// The free space of `scan`: along each lane, the distance to where it is blocked (see
    /// [`BLOCKING_CELLS`]) or leaves the view once it has entered it (the blind strip in front of
    /// the camera counts as free); a direction is as free as its narrowest lane.
    pub fn measure(&mut self, scan: &TerrainScan) -> FreeSpace {
        let geometry = Geometry::of(scan);
        if self.geometry != Some(geometry) {
            self.lay_out(geometry);
        }
        let free_m = self
            .lanes
            .iter()
            .map(|lanes| lanes.iter().map(|lane| self.free_along(lane, &scan.cells)).fold(f32::INFINITY, f32::min))
            .collect();
        FreeSpace { directions_rad: self.directions_rad.clone(), free_m }
    }

    fn free_along(&self, lane: &Lane, cells: &[u8]) -> f32 {
        let mut in_view = false;
        let mut earlier = [(usize::MAX, 0f32); BLOCKING_CELLS - 1];
        for (index, &(cell, distance_m)) in lane.iter().enumerate() {
            match cells.get(cell as usize).copied() {
                Some(TerrainScan::NAVIGABLE) => in_view = true,
                Some(TerrainScan::UNKNOWN) if !in_view => {}
                Some(TerrainScan::UNKNOWN) | None => return if in_view { distance_m } else { 0.0 },
                Some(_) => {
                    let (first, first_m) = earlier[0];
                    if first != usize::MAX && index - first < BLOCKING_SPAN_CELLS {
                        return first_m;
                    }
                    earlier.rotate_left(1);
                    earlier[BLOCKING_CELLS - 2] = (index, distance_m);
                    in_view = true;
                }
            }
        }
        if in_view { self.max_range_m as f32 } else { 0.0 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scan 6 m deep and 8 m wide at 0.1 m, navigable except a wall across x >= 3 for y < 0.
    fn scan() -> TerrainScan {
        let (rows, cols) = (60u32, 80u32);
        let mut cells = vec![TerrainScan::NAVIGABLE; (rows * cols) as usize];
        for row in 0..rows {
            for col in 0..cols {
                let (x, y) = (0.3 + row as f32 * 0.1, -4.0 + col as f32 * 0.1);
                if x < 0.8 || y.abs() > 3.5 {
                    cells[(row * cols + col) as usize] = TerrainScan::UNKNOWN;
                } else if x >= 3.0 && y < 0.0 {
                    cells[(row * cols + col) as usize] = TerrainScan::OBSTACLE;
                }
            }
        }
        TerrainScan {
            rows,
            cols,
            resolution_m: 0.1,
            origin_x_m: 0.3,
            origin_y_m: -4.0,
            cells,
            ..TerrainScan::default()
        }
    }

    #[test]
    fn specks_do_not_block_a_lane_but_a_wall_does() {
        let mut speckled = scan();
        for cell in speckled.cells.iter_mut().filter(|c| **c == TerrainScan::OBSTACLE) {
            *cell = TerrainScan::NAVIGABLE;
        }
        let cols = speckled.cols as usize;
        for (row, col) in [(20, 42), (25, 38), (31, 40), (36, 41), (41, 39), (47, 40), (52, 43)] {
            speckled.cells[row * cols + col] = TerrainScan::OBSTACLE;
        }
        let mut rays = FreeSpaceRays::new(40.0, 5.0, 0.4, 5.5);
        let ahead = rays.measure(&speckled).toward(0.0);
        assert!(ahead > 5.4, "single obstacle cells ahead are specks: {ahead}");
        for row in 30..34 {
            speckled.cells[row * cols + 36..][..9].fill(TerrainScan::OBSTACLE);
        }
        let ahead = rays.measure(&speckled).toward(0.0);
        assert!((3.2..3.5).contains(&ahead), "a boulder 0.4 m deep from x = 3.3 m blocks: {ahead}");
    }

    #[test]
    fn open_and_blocked_directions() {
        let mut rays = FreeSpaceRays::new(40.0, 5.0, 0.4, 5.5);
        let space = rays.measure(&scan());
        assert_eq!(space.directions_rad.len(), 17);
        let right = space.toward(-30f32.to_radians());
        let left = space.toward(30f32.to_radians());
        assert!(right < 3.6, "the wall on the right: {right}");
        assert!(left > 4.5, "open on the left: {left}");
        let chosen = space.best_toward(-20f32.to_radians(), 4.5).unwrap();
        assert!(chosen > 0.0, "steers left of the wall: {chosen}");
        assert!(space.most_open() > 0.0);
        assert!(space.toward(0.0) > 2.9, "the blind strip in front counts as free");
        let (ahead, around) = (space.toward(-10f32.to_radians()), space.longest_within(-10f32.to_radians(), 0.7));
        assert!(around > ahead && around <= space.toward(30f32.to_radians()), "{ahead} ahead, {around} around");
        assert_eq!(space.longest_within(-30f32.to_radians(), 0.0), right, "a window of one direction");
    }
}
