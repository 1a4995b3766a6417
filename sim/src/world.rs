//! The world: a 200 m x 200 m height field (1 cell = 1 m, row = y, column = x), the floor being the
//! navigable ground, plus the rock samples and the start pose.

use crate::random::SplitMix64;

/// Side of the world, metres and cells.
pub const WORLD_SIZE: usize = 200;
/// Height of the highest terrain, which is also the terrain outside the map, metres.
pub const MAX_TERRAIN_HEIGHT_M: f32 = 25.0;
/// Resolution of the wall-distance field used for shading, metres.
const DISTANCE_FIELD_RESOLUTION_M: f64 = 0.25;

/// A rock sample on the ground.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Centre x, metres.
    pub x_m: f64,
    /// Centre y, metres.
    pub y_m: f64,
    /// Radius, metres (the samples are 0.14 to 0.20 m across).
    pub radius_m: f64,
}

/// Where and how the rover starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StartPose {
    /// x, metres.
    pub x_m: f64,
    /// y, metres.
    pub y_m: f64,
    /// Yaw, degrees counter-clockwise from +x.
    pub yaw_deg: f64,
}

/// The world the rover drives in.
#[derive(Debug, Clone)]
pub struct World {
    heights_m: Vec<f32>,
    ground_truth: Vec<bool>,
    wall_distance: DistanceField,
    /// Samples on the ground, in the order the simulator reports them.
    pub samples: Vec<Sample>,
    /// The rover's start pose.
    pub start: StartPose,
}

/// Errors building a world from a map image.
#[derive(Debug, thiserror::Error)]
pub enum WorldError {
    /// The map is not a 200x200 image.
    #[error("map image is {0}x{1}, expected 200x200 (1 px = 1 m, row = y, column = x)")]
    WrongSize(usize, usize),
    /// The map cannot be decoded.
    #[error("cannot read the map image: {0}")]
    Unreadable(String),
    /// Too little navigable ground.
    #[error("map has only {0} navigable pixels (values > 0); a world needs at least 100")]
    TooSmall(usize),
}

/// The 33 sample placeholders of the Unity scene (unity-sim-spec 5.3), x and z in metres.
pub const UNITY_SAMPLE_CANDIDATES: [(f64, f64); 33] = [
    (97.44, 74.65),
    (104.56, 80.78),
    (109.78, 89.84),
    (113.27, 12.97),
    (122.28, 51.66),
    (108.997, 101.96),
    (144.631, 94.533),
    (148.776, 109.56),
    (110.699, 165.008),
    (103.774, 192.692),
    (76.22, 71.358),
    (61.86, 105.154),
    (39.6647, 94.2979),
    (21.724, 102.178),
    (12.096, 101.04),
    (21.69, 94.143),
    (32.631, 99.635),
    (62.626, 96.247),
    (62.705, 88.004),
    (70.31, 87.774),
    (76.47, 78.364),
    (82.8, 75.0),
    (86.03, 83.67),
    (102.953, 96.36),
    (106.962, 66.13),
    (106.115, 53.507),
    (110.14, 36.94),
    (117.486, 20.447),
    (125.22, 99.41),
    (127.463, 121.259),
    (116.034, 131.28),
    (115.726, 151.234),
    (102.46, 170.09),
];

/// The Unity scene's rover start position (unity-sim-spec 5.2).
pub const UNITY_START: (f64, f64) = (99.67, 85.589);

/// Height of the bank along the foot of the walls, metres: drivable, but rock to the camera.
pub const BANK_HEIGHT_M: f32 = 0.08;

/// Number of samples spawned per run.
pub const SAMPLE_COUNT: usize = 6;

impl World {
    /// Builds a world from a height field (row-major, `WORLD_SIZE` x `WORLD_SIZE`, 0 = floor) whose
    /// ground truth for scoring is its floor.
    pub fn from_heights(heights_m: Vec<f32>, samples: Vec<Sample>, start: StartPose) -> Self {
        let ground_truth = heights_m.iter().map(|&h| h <= 0.0).collect();
        Self::with_ground_truth(heights_m, ground_truth, samples, start)
    }

    /// Builds a world whose scoring ground truth differs from its floor.
    pub fn with_ground_truth(
        heights_m: Vec<f32>,
        ground_truth: Vec<bool>,
        samples: Vec<Sample>,
        start: StartPose,
    ) -> Self {
        assert_eq!(heights_m.len(), WORLD_SIZE * WORLD_SIZE, "height field must be 200x200");
        assert_eq!(ground_truth.len(), WORLD_SIZE * WORLD_SIZE, "ground truth must be 200x200");
        let wall_distance = DistanceField::build(&heights_m);
        World { heights_m, ground_truth, wall_distance, samples, start }
    }

    /// The Unity world from `map_bw.png`-style bytes: terrain for the map ([`terrain_for_map`]);
    /// 6 of the 33 placeholders get samples and the start yaw is drawn from `seed`, as Unity does in
    /// autonomous mode. The scoring ground truth is the map itself.
    pub fn from_map_png(png: &[u8], seed: u64) -> Result<Self, WorldError> {
        let image = rover_imaging::decode_png(png).map_err(|e| WorldError::Unreadable(e.to_string()))?;
        if (image.width, image.height) != (WORLD_SIZE, WORLD_SIZE) {
            return Err(WorldError::WrongSize(image.width, image.height));
        }
        let navigable: Vec<bool> = image.data.chunks_exact(3).map(|p| p[0] > 0).collect();
        let count = navigable.iter().filter(|&&n| n).count();
        if count < 100 {
            return Err(WorldError::TooSmall(count));
        }
        let mut rng = SplitMix64::new(seed);
        let mut heights_m = terrain_for_map(&navigable, &mut SplitMix64::new(0));
        for &(x, y) in &UNITY_SAMPLE_CANDIDATES {
            carve_access(&mut heights_m, x, y);
        }
        let mut candidates: Vec<(f64, f64)> = UNITY_SAMPLE_CANDIDATES.to_vec();
        let mut samples = Vec::with_capacity(SAMPLE_COUNT);
        while samples.len() < SAMPLE_COUNT && !candidates.is_empty() {
            let (x_m, y_m) = candidates.swap_remove(rng.below(candidates.len()));
            samples.push(Sample { x_m, y_m, radius_m: rng.range(0.07, 0.10) });
        }
        let start = StartPose { x_m: UNITY_START.0, y_m: UNITY_START.1, yaw_deg: rng.range(0.0, 360.0) };
        Ok(World::with_ground_truth(heights_m, navigable, samples, start))
    }

    /// The scoring ground truth as a `map_bw.png`-style PNG: navigable pixels white, the rest
    /// black (row = y, column = x).
    pub fn ground_truth_png(&self) -> Result<Vec<u8>, rover_imaging::ImageError> {
        let mut image = rover_imaging::RgbImage::new(WORLD_SIZE, WORLD_SIZE);
        for (i, _) in self.ground_truth.iter().enumerate().filter(|(_, navigable)| **navigable) {
            image.set_pixel(i % WORLD_SIZE, i / WORLD_SIZE, [255, 255, 255]);
        }
        rover_imaging::encode_png(&image)
    }

    /// Terrain height of the cell containing (x, y), metres; 0 is floor. Outside the map: a wall.
    pub fn height_at(&self, x_m: f64, y_m: f64) -> f32 {
        self.cell_height(x_m.floor() as i64, y_m.floor() as i64)
    }

    /// Terrain height of cell (column `ix`, row `iy`).
    pub fn cell_height(&self, ix: i64, iy: i64) -> f32 {
        if ix < 0 || iy < 0 || ix >= WORLD_SIZE as i64 || iy >= WORLD_SIZE as i64 {
            return MAX_TERRAIN_HEIGHT_M;
        }
        self.heights_m[iy as usize * WORLD_SIZE + ix as usize]
    }

    /// True if the rover can drive on the cell (column `ix`, row `iy`): floor or bank.
    pub fn is_floor(&self, ix: i64, iy: i64) -> bool {
        self.cell_height(ix, iy) <= BANK_HEIGHT_M
    }

    /// The ground-truth navigable map for scoring, row-major (row = y, column = x).
    pub fn ground_truth(&self) -> &[bool] {
        &self.ground_truth
    }

    /// Distance from (x, y) to the nearest non-floor cell, metres (capped at a few metres).
    pub fn wall_distance(&self, x_m: f64, y_m: f64) -> f32 {
        self.wall_distance.at(x_m, y_m)
    }
}

/// The drivable ground of a map: its navigable cells plus every cell next to one (8-neighbourhood)
/// that belongs to the outer non-navigable region. The Unity terrain is flat (below 0.5 m) on 829
/// cells around the 1993 navigable ones of `map_bw.png`, mostly along the walls: the map is
/// conservative, and the rover drives where the map says it cannot (the narrow north canyon is
/// passable). One cell of widening adds 874 cells. Enclosed non-navigable spots (rocks on the
/// floor) stay solid.
pub fn widen_floor(navigable: &[bool]) -> Vec<bool> {
    let outer = outer_region(navigable);
    (0..navigable.len())
        .map(|index| {
            let (x, y) = ((index % WORLD_SIZE) as i64, (index / WORLD_SIZE) as i64);
            let next_to_floor = || {
                (-1..=1).flat_map(|dy| (-1..=1).map(move |dx| (x + dx, y + dy))).any(|(nx, ny)| {
                    (0..WORLD_SIZE as i64).contains(&nx)
                        && (0..WORLD_SIZE as i64).contains(&ny)
                        && navigable[ny as usize * WORLD_SIZE + nx as usize]
                })
            };
            navigable[index] || (outer[index] && next_to_floor())
        })
        .collect()
}

/// The non-navigable cells connected (4-neighbourhood) to the map's border.
fn outer_region(navigable: &[bool]) -> Vec<bool> {
    let side = WORLD_SIZE as i64;
    let mut outer = vec![false; navigable.len()];
    let border = (0..side).flat_map(|i| [(i, 0), (i, side - 1), (0, i), (side - 1, i)]);
    let mut queue: std::collections::VecDeque<usize> = border.map(|(x, y)| (y * side + x) as usize).collect();
    while let Some(index) = queue.pop_front() {
        if navigable[index] || outer[index] {
            continue;
        }
        outer[index] = true;
        queue.extend(neighbours4(index));
    }
    outer
}

/// Heights for a navigable map: 0 on its cells, a low drivable bank ([`BANK_HEIGHT_M`]) on the
/// cells that [`widen_floor`] adds, then the walls. The camera sees the bank as rock, not as
/// navigable ground, as it sees the wall foot in the recorded Unity frames.
pub fn terrain_for_map(navigable: &[bool], rng: &mut SplitMix64) -> Vec<f32> {
    let drivable = widen_floor(navigable);
    let mut heights_m = terrain_from_mask(&drivable, rng);
    for (index, height_m) in heights_m.iter_mut().enumerate() {
        if drivable[index] && !navigable[index] {
            *height_m = BANK_HEIGHT_M;
        }
    }
    heights_m
}

/// Heights for a floor mask: 0 on the floor, then steep rock walls rising with the distance
/// from the floor to ridges of uneven height, with noise.
pub fn terrain_from_mask(navigable: &[bool], rng: &mut SplitMix64) -> Vec<f32> {
    let distance = cell_distance_to(navigable, true);
    let salt = rng.next_u64();
    let ridge_salt = rng.next_u64();
    (0..navigable.len())
        .map(|index| {
            if navigable[index] {
                return 0.0;
            }
            let (x, y) = ((index % WORLD_SIZE) as f64, (index / WORLD_SIZE) as f64);
            let roughness = crate::random::value_noise(x, y, 4.0, salt) as f64;
            let d = distance[index] as f64;
            let ridge =
                9.0 + (MAX_TERRAIN_HEIGHT_M as f64 - 9.0) * crate::random::value_noise(x, y, 9.0, ridge_salt) as f64;
            (0.6 + 2.4 * d + 3.0 * roughness * d.sqrt()).min(ridge) as f32
        })
        .collect()
}

/// Makes the ground around a sample placeholder drivable, with a path to the nearest floor: in the
/// Unity scene the samples lie on flat ground that `map_bw.png` (which is conservative) may not
/// mark navigable. The ground truth for scoring stays the map itself.
fn carve_access(heights_m: &mut [f32], x_m: f64, y_m: f64) {
    let (sx, sy) = (x_m.floor() as i64, y_m.floor() as i64);
    let index = |x: i64, y: i64| {
        (y.clamp(0, WORLD_SIZE as i64 - 1) as usize) * WORLD_SIZE + x.clamp(0, WORLD_SIZE as i64 - 1) as usize
    };
    let mut came_from = vec![usize::MAX; heights_m.len()];
    let start = index(sx, sy);
    came_from[start] = start;
    let mut queue = std::collections::VecDeque::from([start]);
    let mut reached = None;
    while let Some(cell) = queue.pop_front() {
        let (x, y) = ((cell % WORLD_SIZE) as i64, (cell / WORLD_SIZE) as i64);
        if heights_m[cell] <= 0.0 && (x - sx).abs().max((y - sy).abs()) > 1 {
            reached = Some(cell);
            break;
        }
        for (dx, dy) in [(1, 0), (-1, 0), (0, 1), (0, -1)] {
            let next = index(x + dx, y + dy);
            if came_from[next] == usize::MAX {
                came_from[next] = cell;
                queue.push_back(next);
            }
        }
    }
    let mut cell = reached.unwrap_or(start);
    while cell != start {
        heights_m[cell] = 0.0;
        cell = came_from[cell];
    }
    for dy in -1..=1 {
        for dx in -1..=1 {
            heights_m[index(sx + dx, sy + dy)] = 0.0;
        }
    }
}

/// Chessboard-ish distance (in cells) from each cell to the nearest cell where `mask == target`.
fn cell_distance_to(mask: &[bool], target: bool) -> Vec<u16> {
    let mut distance = vec![u16::MAX; mask.len()];
    let mut queue = std::collections::VecDeque::new();
    for (index, &m) in mask.iter().enumerate() {
        if m == target {
            distance[index] = 0;
            queue.push_back(index);
        }
    }
    while let Some(index) = queue.pop_front() {
        for next in neighbours4(index) {
            if distance[next] == u16::MAX {
                distance[next] = distance[index] + 1;
                queue.push_back(next);
            }
        }
    }
    distance
}

/// The cells left, right, below and above `index` that lie on the map.
fn neighbours4(index: usize) -> impl Iterator<Item = usize> {
    let (x, y) = ((index % WORLD_SIZE) as i64, (index / WORLD_SIZE) as i64);
    [(x + 1, y), (x - 1, y), (x, y + 1), (x, y - 1)]
        .into_iter()
        .filter(|&(nx, ny)| (0..WORLD_SIZE as i64).contains(&nx) && (0..WORLD_SIZE as i64).contains(&ny))
        .map(|(nx, ny)| ny as usize * WORLD_SIZE + nx as usize)
}

/// Distance to the nearest wall on a fine grid, for shading the floor near walls.
#[derive(Debug, Clone)]
struct DistanceField {
    side: usize,
    values_cm: Vec<u16>,
}

impl DistanceField {
    fn build(heights_m: &[f32]) -> Self {
        let per_cell = (1.0 / DISTANCE_FIELD_RESOLUTION_M) as usize;
        let side = WORLD_SIZE * per_cell;
        let inside_wall = |fx: usize, fy: usize| heights_m[(fy / per_cell) * WORLD_SIZE + fx / per_cell] > 0.0;
        let mut values = vec![f32::INFINITY; side * side];
        for fy in 0..side {
            for fx in 0..side {
                if inside_wall(fx, fy) {
                    values[fy * side + fx] = 0.0;
                }
            }
        }
        chamfer(&mut values, side, DISTANCE_FIELD_RESOLUTION_M as f32);
        let values_cm = values.iter().map(|&d| (d * 100.0).min(u16::MAX as f32) as u16).collect();
        DistanceField { side, values_cm }
    }

    fn at(&self, x_m: f64, y_m: f64) -> f32 {
        let gx = (x_m / DISTANCE_FIELD_RESOLUTION_M - 0.5).clamp(0.0, (self.side - 1) as f64);
        let gy = (y_m / DISTANCE_FIELD_RESOLUTION_M - 0.5).clamp(0.0, (self.side - 1) as f64);
        let (ix, iy) = (gx as usize, gy as usize);
        let (jx, jy) = ((ix + 1).min(self.side - 1), (iy + 1).min(self.side - 1));
        let (fx, fy) = ((gx - ix as f64) as f32, (gy - iy as f64) as f32);
        let v = |x: usize, y: usize| self.values_cm[y * self.side + x] as f32 / 100.0;
        let top = v(ix, iy) + (v(jx, iy) - v(ix, iy)) * fx;
        let bottom = v(ix, jy) + (v(jx, jy) - v(ix, jy)) * fx;
        top + (bottom - top) * fy
    }
}

/// Two-pass 3x3 chamfer distance transform in place (0 = source), `step` metres per cell.
fn chamfer(values: &mut [f32], side: usize, step: f32) {
    let diagonal = step * std::f32::consts::SQRT_2;
    let forward = [(-1i64, -1i64, diagonal), (0, -1, step), (1, -1, diagonal), (-1, 0, step)];
    let backward = [(1i64, 1i64, diagonal), (0, 1, step), (-1, 1, diagonal), (1, 0, step)];
    let side_i = side as i64;
    let relax = |values: &mut [f32], x: i64, y: i64, offsets: &[(i64, i64, f32)]| {
        let mut best = values[(y * side_i + x) as usize];
        for &(dx, dy, cost) in offsets {
            let (nx, ny) = (x + dx, y + dy);
            if nx >= 0 && ny >= 0 && nx < side_i && ny < side_i {
                best = best.min(values[(ny * side_i + nx) as usize] + cost);
            }
        }
        values[(y * side_i + x) as usize] = best;
    };
    for y in 0..side_i {
        for x in 0..side_i {
            relax(values, x, y, &forward);
        }
    }
    for y in (0..side_i).rev() {
        for x in (0..side_i).rev() {
            relax(values, x, y, &backward);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn corridor_world() -> World {
        let mut heights = vec![5.0f32; WORLD_SIZE * WORLD_SIZE];
        for y in 95..105 {
            for x in 50..150 {
                heights[y * WORLD_SIZE + x] = 0.0;
            }
        }
        World::from_heights(heights, vec![], StartPose { x_m: 100.0, y_m: 100.0, yaw_deg: 0.0 })
    }

    #[test]
    fn heights_and_floor() {
        let world = corridor_world();
        assert!(world.is_floor(100, 100));
        assert!(!world.is_floor(100, 94));
        assert_eq!(world.height_at(-1.0, 5.0), MAX_TERRAIN_HEIGHT_M);
        assert_eq!(world.ground_truth().iter().filter(|&&n| n).count(), 1000);
    }

    #[test]
    fn the_exported_map_is_the_ground_truth() {
        let world = crate::procgen::procedural_world(3);
        let png = world.ground_truth_png().unwrap();
        let reloaded = World::from_map_png(&png, 3).unwrap();
        assert_eq!(reloaded.ground_truth(), world.ground_truth());
    }

    #[test]
    fn wall_distance_grows_away_from_walls() {
        let world = corridor_world();
        assert!(world.wall_distance(100.0, 95.1) < 0.3);
        let middle = world.wall_distance(100.0, 100.0);
        assert!((middle - 5.0).abs() < 0.3, "{middle}");
    }

    #[test]
    fn the_drivable_ground_widens_into_the_walls_but_not_into_enclosed_rocks() {
        let mut navigable = vec![false; WORLD_SIZE * WORLD_SIZE];
        for y in 10..20 {
            for x in 10..20 {
                navigable[y * WORLD_SIZE + x] = (x, y) != (15, 15);
            }
        }
        let floor = widen_floor(&navigable);
        assert!(!floor[15 * WORLD_SIZE + 15], "the enclosed rock stays");
        assert!(floor[9 * WORLD_SIZE + 9] && floor[20 * WORLD_SIZE + 15], "one cell around the map");
        assert!(!floor[8 * WORLD_SIZE + 15] && !floor[21 * WORLD_SIZE + 21]);
        assert_eq!(floor.iter().filter(|&&f| f).count(), 12 * 12 - 1);
    }

    #[test]
    fn the_unity_map_builds_with_six_samples_and_a_random_yaw() {
        let png =
            std::fs::read(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/udacity/calibration_images/map_bw.png"))
                .expect("../shared/udacity/calibration_images/map_bw.png");
        let world = World::from_map_png(&png, 3).unwrap();
        assert_eq!(world.ground_truth().iter().filter(|&&n| n).count(), 1993);
        let floor =
            (0..WORLD_SIZE * WORLD_SIZE).filter(|&i| world.is_floor((i % WORLD_SIZE) as i64, (i / WORLD_SIZE) as i64));
        assert!((2800..2950).contains(&floor.count()), "the rover drives on the map widened by one cell");
        let bank = (0..WORLD_SIZE * WORLD_SIZE).filter(|&i| world.heights_m[i] == BANK_HEIGHT_M).count();
        assert!((700..900).contains(&bank), "{bank} bank cells");
        for &(x, y) in &UNITY_SAMPLE_CANDIDATES {
            assert!(world.is_floor(x as i64, y as i64), "sample placeholder ({x}, {y}) is reachable");
        }
        assert_eq!(world.samples.len(), 6);
        assert!(world.samples.iter().all(|s| UNITY_SAMPLE_CANDIDATES.contains(&(s.x_m, s.y_m))));
        assert!(world.is_floor(UNITY_START.0 as i64, UNITY_START.1 as i64));
        let other = World::from_map_png(&png, 4).unwrap();
        assert_ne!(world.start.yaw_deg, other.start.yaw_deg);
        assert_eq!(World::from_map_png(&png, 3).unwrap().samples, world.samples);
    }
}
