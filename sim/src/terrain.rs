//! The terrain: a height field on a grid of 0.25 m, flat on the floor and rising into smooth walls
//! as the Unity terrain does (`../shared/udacity-world/README.md` section 2): gentle at the foot,
//! steepening to 55-65 degrees, with the spread of slopes the measured table gives.

use crate::distance::distance_to;
use crate::random::value_noise;
use crate::world::{WORLD_SIZE, inside_world};

/// Spacing of the height field's nodes, metres.
pub(crate) const TERRAIN_STEP_M: f64 = 0.25;
/// Nodes per metre along each axis.
pub(crate) const NODES_PER_M: usize = 4;
/// Height of the highest terrain, which is also the terrain outside the map, metres.
pub(crate) const MAX_TERRAIN_HEIGHT_M: f32 = 38.7;
/// The flat floor stops this far inside the edge of the floor cells, metres: the terrain of a
/// floor cell's centre stays flat, and that of the next cell's centre is at about 0.5 m, as in
/// `floor_flat.png` (white where the terrain at the cell centre is below 0.5 m).
const FLAT_INSET_M: f64 = 0.3;
/// Surveyed ground higher than this is the foot of a wall, metres.
const WALL_FOOT_M: f32 = 0.02;

/// Height of the walls against the distance from the flat floor, metres: the 10th, 50th and 90th
/// percentiles of the Unity terrain (measured over its 513x513 samples; distance at the middle of
/// each measured band, but for the two nearest bands, set nearer the floor so that the terrain
/// measured the same way gives their figures: at their middles it gave 30 % less).
const WALL_PROFILE: [(f64, [f64; 3]); 10] = [
    (0.0, [0.0, 0.0, 0.0]),
    (0.35, [0.07, 0.19, 0.49]),
    (0.6, [0.38, 0.76, 1.70]),
    (1.25, [0.95, 1.74, 3.27]),
    (1.75, [1.68, 3.00, 4.99]),
    (2.5, [2.71, 4.93, 8.18]),
    (3.5, [4.20, 7.15, 11.69]),
    (5.0, [5.78, 10.14, 15.46]),
    (7.0, [8.40, 13.93, 18.81]),
    (10.0, [11.64, 18.38, 22.19]),
];

/// The height of a wall point `distance_m` from the flat floor, at quantile `q` (0..1) of the
/// measured spread: linear between the measured distances and between the 10th, 50th and 90th
/// percentiles, extended beyond both.
pub(crate) fn wall_height_m(distance_m: f64, q: f64) -> f64 {
    let at = |row: &[f64; 3]| {
        if q <= 0.5 {
            row[0] + (q - 0.1) / 0.4 * (row[1] - row[0])
        } else {
            row[1] + (q - 0.5) / 0.4 * (row[2] - row[1])
        }
    };
    let last = WALL_PROFILE.len() - 1;
    let segment = WALL_PROFILE.windows(2).position(|w| distance_m < w[1].0).unwrap_or(last - 1);
    let ((d0, h0), (d1, h1)) = (WALL_PROFILE[segment], WALL_PROFILE[segment + 1]);
    let fraction = (distance_m - d0) / (d1 - d0);
    let height = at(&h0) + fraction * (at(&h1) - at(&h0));
    height.clamp(0.0, MAX_TERRAIN_HEIGHT_M as f64)
}

/// The terrain of one world.
#[derive(Debug, Clone)]
pub struct Terrain {
    side: usize,
    /// The node heights with a border of one node copied from the edge, so that bilinear lookups
    /// anywhere inside the world need no bounds: node (nx, ny) at `(ny + 1) * (side + 2) + nx + 1`.
    padded_m: Vec<f32>,
    edge_distance_m: Vec<f32>,
    cell_max_m: Vec<f32>,
}

impl Terrain {
    /// The terrain of a floor mask (`WORLD_SIZE` x `WORLD_SIZE` cells, row = y): flat on the floor
    /// cells, walls everywhere else; `salt` varies the walls' shape.
    pub fn from_floor(floor: &[bool], salt: u64) -> Self {
        assert_eq!(floor.len(), WORLD_SIZE * WORLD_SIZE, "the floor mask must be 200x200");
        let side = WORLD_SIZE * NODES_PER_M;
        let edge_distance_m = floor_edge_distances_m(floor);
        let quantile = uniform_quantiles(side, salt);
        let heights_m: Vec<f32> = (0..side * side)
            .map(|i| {
                let d = edge_distance_m[i] as f64;
                if d <= 0.0 {
                    return 0.0;
                }
                let (x, y) = node_position(i, side);
                let roughness = 1.0 + 0.16 * (value_noise(x, y, 1.7, salt ^ 0x5151) as f64 - 0.5);
                let ridge = 24.0 + (MAX_TERRAIN_HEIGHT_M as f64 - 24.0) * value_noise(x, y, 23.0, salt ^ 0x7e7e) as f64;
                (wall_height_m(d, quantile[i] as f64) * roughness).min(ridge) as f32
            })
            .collect();
        Terrain::with_heights(heights_m, edge_distance_m)
    }

    /// The terrain of surveyed heights: `heights_m` of every node (`WORLD_SIZE * NODES_PER_M`
    /// a side, row = y, node (nx, ny) at ((nx + 0.5), (ny + 0.5)) x [`TERRAIN_STEP_M`]); the
    /// walls start where it rises above [`WALL_FOOT_M`].
    pub fn from_heights(heights_m: Vec<f32>) -> Self {
        let side = WORLD_SIZE * NODES_PER_M;
        assert_eq!(heights_m.len(), side * side, "one height per node");
        let heights_m: Vec<f32> = heights_m
            .into_iter()
            .map(|h| if h.is_finite() { h.clamp(0.0, MAX_TERRAIN_HEIGHT_M) } else { 0.0 })
            .collect();
        let wall: Vec<bool> = heights_m.iter().map(|&h| h > WALL_FOOT_M).collect();
        let edge_distance_m = signed_node_distances_m(&wall).into_iter().map(|d| d as f32).collect();
        Terrain::with_heights(heights_m, edge_distance_m)
    }

    fn with_heights(heights_m: Vec<f32>, edge_distance_m: Vec<f32>) -> Self {
        let side = WORLD_SIZE * NODES_PER_M;
        let padded_side = side as i64 + 2;
        let padded_m = (0..padded_side * padded_side)
            .map(|i| {
                let (nx, ny) =
                    ((i % padded_side - 1).clamp(0, side as i64 - 1), (i / padded_side - 1).clamp(0, side as i64 - 1));
                heights_m[ny as usize * side + nx as usize]
            })
            .collect();
        let mut terrain = Terrain { side, padded_m, edge_distance_m, cell_max_m: Vec::new() };
        terrain.cell_max_m = terrain.cell_maxima();
        terrain
    }

    /// The highest node whose height reaches into each 1 m cell (bilinear patches overlap by half
    /// a node spacing), for skipping cells while rendering.
    fn cell_maxima(&self) -> Vec<f32> {
        (0..WORLD_SIZE * WORLD_SIZE)
            .map(|c| {
                let (cx, cy) = ((c % WORLD_SIZE) as i64, (c / WORLD_SIZE) as i64);
                let nodes = |c: i64| (c * NODES_PER_M as i64 - 1)..=(c * NODES_PER_M as i64 + NODES_PER_M as i64);
                nodes(cy)
                    .flat_map(|ny| nodes(cx).map(move |nx| (nx, ny)))
                    .map(|(nx, ny)| self.node(nx, ny))
                    .fold(0.0, f32::max)
            })
            .collect()
    }

    /// Height of node (column `nx`, row `ny`); beyond the edge, the nearest node's.
    fn node(&self, nx: i64, ny: i64) -> f32 {
        let last = self.side as i64 - 1;
        let (px, py) = (nx.clamp(0, last) as usize + 1, ny.clamp(0, last) as usize + 1);
        self.padded_m[py * (self.side + 2) + px]
    }

    /// Terrain height at (x, y), metres above the floor (bilinear between nodes); outside the
    /// world, the highest terrain.
    pub fn height_at(&self, x_m: f64, y_m: f64) -> f32 {
        if !inside_world(x_m, y_m) {
            return MAX_TERRAIN_HEIGHT_M;
        }
        let (gx, gy) = (x_m * NODES_PER_M as f64 - 0.5, y_m * NODES_PER_M as f64 - 0.5);
        let (ix, iy) = (floor_from_minus_one(gx), floor_from_minus_one(gy));
        let (fx, fy) = ((gx - ix as f64) as f32, (gy - iy as f64) as f32);
        let stride = self.side + 2;
        let at = (iy + 1) as usize * stride + (ix + 1) as usize;
        let (a, b, c, d) =
            (self.padded_m[at], self.padded_m[at + 1], self.padded_m[at + stride], self.padded_m[at + stride + 1]);
        let top = a + (b - a) * fx;
        let bottom = c + (d - c) * fx;
        top + (bottom - top) * fy
    }

    /// The terrain's slope at (x, y): height change per metre along x and along y.
    pub fn gradient_at(&self, x_m: f64, y_m: f64) -> [f64; 2] {
        let h = TERRAIN_STEP_M / 2.0;
        [
            (self.height_at(x_m + h, y_m) - self.height_at(x_m - h, y_m)) as f64 / (2.0 * h),
            (self.height_at(x_m, y_m + h) - self.height_at(x_m, y_m - h)) as f64 / (2.0 * h),
        ]
    }

    /// Signed distance from the edge of the flat floor at (x, y), metres: negative on the floor
    /// (minus the distance to the nearest wall foot), positive on the walls.
    pub fn edge_distance_at(&self, x_m: f64, y_m: f64) -> f32 {
        if !inside_world(x_m, y_m) {
            return f32::MAX;
        }
        let (nx, ny) = ((x_m * NODES_PER_M as f64) as usize, (y_m * NODES_PER_M as f64) as usize);
        self.edge_distance_m[ny.min(self.side - 1) * self.side + nx.min(self.side - 1)]
    }

    /// The highest terrain anywhere within cell (column `ix`, row `iy`); outside the world, the
    /// highest terrain.
    pub fn cell_max_height(&self, ix: i64, iy: i64) -> f32 {
        if ix < 0 || iy < 0 || ix >= WORLD_SIZE as i64 || iy >= WORLD_SIZE as i64 {
            return MAX_TERRAIN_HEIGHT_M;
        }
        self.cell_max_m[iy as usize * WORLD_SIZE + ix as usize]
    }

    /// Every node as (x, y, height), metres, row by row.
    pub fn nodes(&self) -> impl Iterator<Item = (f64, f64, f32)> + '_ {
        (0..self.side * self.side).map(|i| {
            let (x, y) = node_position(i, self.side);
            (x, y, self.node((i % self.side) as i64, (i / self.side) as i64))
        })
    }
}

/// The floor of `v` for `v` above -1, as an integer (no call into the maths library, which the
/// baseline x86-64 target needs for `f64::floor`).
pub(crate) fn floor_from_minus_one(v: f64) -> i64 {
    (v + 1.0) as i64 - 1
}

/// Signed distance of every terrain node from the edge of the flat floor (see [`FLAT_INSET_M`]),
/// metres: negative on the floor.
fn floor_edge_distances_m(floor: &[bool]) -> Vec<f32> {
    signed_edge_distances_m(floor)
        .into_iter()
        .map(|edge_m| (edge_m + FLAT_INSET_M).min(f32::MAX as f64) as f32)
        .collect()
}

/// Signed distance of every terrain node from the edge of `cells` (the 1 m cells of the world, row
/// = y, set on one side of the edge), metres: negative on the cells, positive beyond them.
pub(crate) fn signed_edge_distances_m(cells: &[bool]) -> Vec<f64> {
    let side = WORLD_SIZE * NODES_PER_M;
    let on_cells: Vec<bool> =
        (0..side * side).map(|i| cells[(i / side / NODES_PER_M) * WORLD_SIZE + (i % side) / NODES_PER_M]).collect();
    signed_node_distances_m(&on_cells.iter().map(|on| !on).collect::<Vec<_>>())
}

/// Signed distance of every terrain node from the edge of the nodes `beyond`, metres: positive on
/// them, negative off them.
fn signed_node_distances_m(beyond: &[bool]) -> Vec<f64> {
    let side = WORLD_SIZE * NODES_PER_M;
    let outside = distance_to(beyond, side);
    let inside = distance_to(&beyond.iter().map(|b| !b).collect::<Vec<_>>(), side);
    let half_step = TERRAIN_STEP_M / 2.0;
    (0..side * side)
        .map(|i| {
            if beyond[i] {
                inside[i] as f64 * TERRAIN_STEP_M - half_step
            } else {
                half_step - outside[i] as f64 * TERRAIN_STEP_M
            }
        })
        .collect()
}

/// Position of node `index` of a `side` x `side` grid, metres.
fn node_position(index: usize, side: usize) -> (f64, f64) {
    (((index % side) as f64 + 0.5) * TERRAIN_STEP_M, ((index / side) as f64 + 0.5) * TERRAIN_STEP_M)
}

/// A smooth random field over the nodes whose values are spread uniformly over 0..1 (noise
/// mapped through its own histogram), so that walls take every quantile of the measured spread.
fn uniform_quantiles(side: usize, salt: u64) -> Vec<f32> {
    const BINS: usize = 4096;
    let raw: Vec<f32> = (0..side * side)
        .map(|i| {
            let (x, y) = node_position(i, side);
            0.7 * value_noise(x, y, 9.0, salt ^ 0x1234) + 0.3 * value_noise(x, y, 3.1, salt ^ 0x4321)
        })
        .collect();
    let mut histogram = vec![0usize; BINS];
    let bin = |v: f32| ((v * BINS as f32) as usize).min(BINS - 1);
    raw.iter().for_each(|&v| histogram[bin(v)] += 1);
    let mut below = vec![0.0f32; BINS];
    let mut running = 0usize;
    for (b, count) in histogram.iter().enumerate() {
        below[b] = (running as f32 + *count as f32 / 2.0) / raw.len() as f32;
        running += count;
    }
    raw.iter().map(|&v| below[bin(v)]).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn corridor_floor() -> Vec<bool> {
        crate::world::rectangle(20..180, 90..110)
    }

    #[test]
    fn the_profile_passes_through_the_measured_percentiles() {
        assert!((wall_height_m(0.6, 0.5) - 0.76).abs() < 1e-9);
        assert!((wall_height_m(2.5, 0.1) - 2.71).abs() < 1e-9);
        assert!((wall_height_m(5.0, 0.9) - 15.46).abs() < 1e-9);
        assert_eq!(wall_height_m(0.0, 0.7), 0.0);
        assert!(wall_height_m(20.0, 0.5) > wall_height_m(10.0, 0.5), "keeps rising beyond the table");
        assert!(wall_height_m(1.0, 0.0) < wall_height_m(1.0, 0.1) && wall_height_m(1.0, 1.0) > wall_height_m(1.0, 0.9));
    }

    #[test]
    fn the_floor_is_flat_and_the_walls_rise_without_steps() {
        let terrain = Terrain::from_floor(&corridor_floor(), 1);
        assert_eq!(terrain.height_at(100.0, 100.0), 0.0);
        assert_eq!(terrain.height_at(100.0, 90.5), 0.0, "the edge floor cell's centre is flat");
        let outside = terrain.height_at(100.0, 89.5);
        assert!((0.3..2.5).contains(&outside), "the next cell's centre is on the wall's foot: {outside} m");
        let mut previous = 0.0;
        for step in 0..400 {
            let y = 91.0 - step as f64 * 0.02;
            let h = terrain.height_at(100.0, y);
            assert!(h >= previous - 0.05, "rises away from the floor at y = {y}");
            assert!(h - previous < 0.1, "no step at y = {y}: {previous} -> {h}");
            previous = h;
        }
        assert!(previous > 3.0, "a wall 8 m from the floor: {previous} m");
        assert_eq!(terrain.height_at(-1.0, 100.0), MAX_TERRAIN_HEIGHT_M);
        assert!(terrain.cell_max_height(100, 89) >= terrain.height_at(100.5, 89.5));
        assert_eq!(terrain.cell_max_height(100, 100), 0.0);
        assert!(terrain.edge_distance_at(100.0, 100.0) < -9.0 && terrain.edge_distance_at(100.0, 85.0) > 4.0);
    }

    #[test]
    fn the_quantile_field_is_uniform() {
        let q = uniform_quantiles(200, 3);
        let below = |limit: f32| q.iter().filter(|&&v| v < limit).count() as f64 / q.len() as f64;
        assert!((below(0.1) - 0.1).abs() < 0.01 && (below(0.5) - 0.5).abs() < 0.01 && (below(0.9) - 0.9).abs() < 0.01);
    }
}
