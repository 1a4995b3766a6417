//! The world map: per-cell evidence of navigable ground, obstacles and rocks, gathered from terrain
//! scans, each cell counted at most once per frame and class, and the decisions drawn from it.

use rover_msgs::body::{ARM_REACH_M, CameraMount, SAMPLE_SPREAD_M};
use rover_msgs::map_grid::{
    CELLS, OCCUPANCY_FREE, OCCUPANCY_OCCUPIED, OCCUPANCY_UNKNOWN, SIDE_CELLS, cell_at, cell_of_point, cell_xy,
};

use crate::projection::{Pose, Projector};
use crate::rocks::{RockCell, rock_positions};
use crate::score::{Scores, occupancy_counts, occupancy_scores};

/// Terrain-scan class codes (`rover_msgs/TerrainScan`).
const NAVIGABLE: u8 = rover_msgs::msg::TerrainScan::NAVIGABLE;
const ROCK: u8 = rover_msgs::msg::TerrainScan::ROCK;
const OBSTACLE: u8 = rover_msgs::msg::TerrainScan::OBSTACLE;

/// How scans become evidence and evidence becomes a map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapConfig {
    /// Scan cells farther than this from the rover are ignored, metres.
    pub max_range_m: f64,
    /// Frames whose pitch or roll exceeds this are skipped, degrees.
    pub max_tilt_deg: f64,
    /// Re-project scan cells through the tilted camera.
    pub correct_tilt: bool,
    /// A cell is navigable after this many navigable frames...
    pub min_navigable_hits: u16,
    /// ...and when its navigable evidence is at least this many times its obstacle evidence.
    pub navigable_ratio: f32,
    /// A frame that sees a cell within this range weighs fully as evidence of its class; farther,
    /// it weighs (this range / its range) squared, as the far floor's pixels are darker, hazier
    /// and each covers more ground, metres.
    pub full_weight_range_m: f64,
    /// Obstacle scan cells farther than this beyond the nearest obstacle cell of their bearing are
    /// not evidence (the face of a wall projected onto the ground behind it), metres.
    pub shadow_margin_m: f64,
    /// A cell that is not navigable is an obstacle after this many obstacle frames.
    pub min_obstacle_hits: u16,
    /// A cell holds a rock after this many rock frames.
    pub min_rock_hits: u16,
}

impl Default for MapConfig {
    /// The configuration of the mapping node's default parameters.
    fn default() -> Self {
        crate::params::MappingParams::default().map_config()
    }
}

impl MapConfig {
    /// What a cell with `hits` (navigable, obstacle frames) and `weighed` (navigable, obstacle
    /// evidence) is, as an occupancy value.
    fn occupancy(&self, hits: [u16; 2], weighed: [f32; 2]) -> i8 {
        let [nav, obs] = weighed;
        if hits[0] >= self.min_navigable_hits && nav >= self.navigable_ratio * obs {
            OCCUPANCY_FREE
        } else if hits[1] >= self.min_obstacle_hits && obs >= nav {
            OCCUPANCY_OCCUPIED
        } else {
            OCCUPANCY_UNKNOWN
        }
    }
}

/// Samples lie on the floor or at the foot of a wall, so a rock cell with no navigable cell within
/// this distance, metres, is an echo: a sample on the foot of a wall, seen from afar, projected
/// as if it lay on the floor, which puts it metres into the wall behind it.
const ROCK_FLOOR_REACH_M: f64 = 2.5;

/// Whether `occupancy` has a free cell within `reach_m` of the centre of cell `(x, y)`.
fn floor_within(occupancy: &[i8], (x, y): (usize, usize), reach_m: f64) -> bool {
    let reach = reach_m as usize;
    let near = |v: usize| v.saturating_sub(reach)..=(v + reach).min(SIDE_CELLS - 1);
    near(y).any(|cy| {
        near(x).any(|cx| {
            let distance_m = (cx as f64 - x as f64).hypot(cy as f64 - y as f64);
            distance_m <= reach_m && occupancy[cell_at(cx, cy)] == OCCUPANCY_FREE
        })
    })
}

/// Width of the bearing bins of [`NearestObstacles`], degrees.
const BEARING_BIN_DEG: f64 = 1.0;
/// Bearing bins from -90 to +90 degrees.
const BEARING_BINS: usize = (180.0 / BEARING_BIN_DEG) as usize + 1;

/// A scan cell within range of the rover: its index, rover-frame centre (x ahead, y left), range
/// (squared and not) and bearing bin.
#[derive(Debug, Clone, Copy)]
struct CellInRange {
    index: usize,
    x: f64,
    y: f64,
    range_sq: f64,
    range_m: f64,
    bin: u8,
}

/// The cells of one scan layout (rows, columns, resolution and origin) within its range limit,
/// row by row, listed once and not for every frame.
#[derive(Debug, Clone, Default)]
struct LayoutTable {
    layout: Option<(usize, usize, u64, u64, u64, u64)>,
    in_range: Vec<CellInRange>,
}

impl LayoutTable {
    /// The cells within `max_range_m` of `scan`'s layout, listed again when the layout or the
    /// range differs from the last one.
    fn for_scan(&mut self, scan: &ScanGrid, max_range_m: f64) -> &[CellInRange] {
        let layout = (
            scan.rows,
            scan.cols,
            scan.resolution_m.to_bits(),
            scan.origin_x_m.to_bits(),
            scan.origin_y_m.to_bits(),
            max_range_m.to_bits(),
        );
        if self.layout != Some(layout) {
            self.layout = Some(layout);
            self.in_range = scan.cells_within(max_range_m).collect();
        }
        &self.in_range
    }
}

/// The bearing bin of rover-frame point (x, y), x ahead.
fn bearing_bin(x: f64, y: f64) -> u8 {
    ((y.atan2(x).to_degrees() + 90.0) / BEARING_BIN_DEG).round().clamp(0.0, (BEARING_BINS - 1) as f64) as u8
}

/// The range of the nearest obstacle cell of a scan in each bearing bin, plus a margin: obstacle
/// cells beyond it are in the shadow of a nearer one.
struct NearestObstacles {
    shadow_sq: [f64; BEARING_BINS],
}

impl NearestObstacles {
    /// The nearest obstacle of each bearing among the scan cells `in_range` (classes `cells`),
    /// plus `margin_m`.
    fn of(cells: &[u8], in_range: &[CellInRange], margin_m: f64) -> Self {
        let mut range_m = [f64::INFINITY; BEARING_BINS];
        for cell in in_range.iter().filter(|cell| cells[cell.index] == OBSTACLE) {
            let bin = cell.bin as usize;
            range_m[bin] = range_m[bin].min(cell.range_m);
        }
        NearestObstacles { shadow_sq: range_m.map(|r| (r + margin_m).powi(2)) }
    }

    /// True if a scan cell in bearing bin `bin`, `range_sq` away, lies in the shadow of a nearer
    /// obstacle.
    fn shadowed(&self, bin: u8, range_sq: f64) -> bool {
        range_sq > self.shadow_sq[bin as usize]
    }
}

/// The rover-frame grid of one scan (see `rover_msgs/TerrainScan`).
#[derive(Debug, Clone, Copy)]
pub struct ScanGrid<'a> {
    /// Rows (forward bins).
    pub rows: usize,
    /// Columns (lateral bins).
    pub cols: usize,
    /// Cell size, metres.
    pub resolution_m: f64,
    /// Near edge of the grid, metres ahead of the rover.
    pub origin_x_m: f64,
    /// Right edge of the grid, metres (left positive).
    pub origin_y_m: f64,
    /// Class codes, row-major.
    pub cells: &'a [u8],
}

impl<'a> ScanGrid<'a> {
    /// The grid of a `rover_msgs/TerrainScan`.
    pub fn of(scan: &'a rover_msgs::msg::TerrainScan) -> Self {
        ScanGrid {
            rows: scan.rows as usize,
            cols: scan.cols as usize,
            resolution_m: scan.resolution_m as f64,
            origin_x_m: scan.origin_x_m as f64,
            origin_y_m: scan.origin_y_m as f64,
            cells: &scan.cells,
        }
    }

    /// The cells within `max_range_m` of the rover, row by row.
    fn cells_within(&self, max_range_m: f64) -> impl Iterator<Item = CellInRange> + '_ {
        let max_range_sq = max_range_m * max_range_m;
        (0..self.rows)
            .map(move |row| (row, self.origin_x_m + (row as f64 + 0.5) * self.resolution_m))
            .take_while(move |&(_, x)| x * x <= max_range_sq)
            .flat_map(move |(row, x)| {
                (0..self.cols).filter_map(move |col| {
                    let y = self.origin_y_m + (col as f64 + 0.5) * self.resolution_m;
                    let range_sq = x * x + y * y;
                    (range_sq <= max_range_sq).then(|| CellInRange {
                        index: row * self.cols + col,
                        x,
                        y,
                        range_sq,
                        range_m: x.hypot(y),
                        bin: bearing_bin(x, y),
                    })
                })
            })
    }
}

/// What a map update did with a frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Update {
    /// The frame was used; this many scan cells landed in the map.
    Used(usize),
    /// The body was tilted more than the limit.
    SkippedTilt,
    /// The scan's size does not match its cells.
    Malformed,
}

/// Classes of evidence: navigable, obstacle, rock (the scan's class codes minus one).
pub const CLASSES: usize = 3;
/// Classes whose evidence is also weighed by range: navigable and obstacle.
pub const WEIGHED: usize = 2;

/// What a map has gathered, without its configuration: what a restarted mapping node must get
/// back (see [`crate::snapshot`]). One entry per cell in each vector.
#[derive(Debug, Clone, PartialEq)]
pub struct Evidence {
    /// Navigable, obstacle and rock frames.
    pub hits: [Vec<u16>; CLASSES],
    /// Range-weighed navigable and obstacle evidence.
    pub weight: [Vec<f32>; WEIGHED],
    /// Nearest range a rock was seen at, metres (infinite: none).
    pub rock_range_m: Vec<f32>,
}

impl Evidence {
    /// No evidence yet.
    pub fn empty() -> Self {
        Evidence {
            hits: std::array::from_fn(|_| vec![0; CELLS]),
            weight: std::array::from_fn(|_| vec![0.0; CELLS]),
            rock_range_m: vec![f32::INFINITY; CELLS],
        }
    }
}

/// The evidence grid of the world.
#[derive(Debug, Clone)]
pub struct WorldMap {
    config: MapConfig,
    mount: CameraMount,
    hits: [Vec<u16>; CLASSES],
    weight: [Vec<f32>; WEIGHED],
    frame_weight: [Vec<f32>; WEIGHED],
    last_frame: [Vec<u32>; CLASSES],
    rock_range_m: Vec<f32>,
    frame: u32,
    scan_layout: LayoutTable,
}

impl WorldMap {
    /// An empty map.
    pub fn new(config: MapConfig) -> Self {
        Self::with_evidence(config, Evidence::empty())
    }

    /// A map that carries on from `evidence` (e.g. a snapshot of an earlier node's map).
    pub fn with_evidence(config: MapConfig, evidence: Evidence) -> Self {
        let Evidence { hits, weight, rock_range_m } = evidence;
        WorldMap {
            config,
            mount: CameraMount::default(),
            hits,
            weight,
            frame_weight: std::array::from_fn(|_| vec![0.0; CELLS]),
            last_frame: std::array::from_fn(|_| vec![u32::MAX; CELLS]),
            rock_range_m,
            frame: 0,
            scan_layout: LayoutTable::default(),
        }
    }

    /// A copy of the evidence gathered so far.
    pub fn gathered(&self) -> Evidence {
        Evidence { hits: self.hits.clone(), weight: self.weight.clone(), rock_range_m: self.rock_range_m.clone() }
    }

    /// The configuration.
    pub fn config(&self) -> &MapConfig {
        &self.config
    }

    /// Replaces the configuration (decisions follow at once; evidence is kept).
    pub fn set_config(&mut self, config: MapConfig) {
        self.config = config;
    }

    /// Adds the evidence of one scan taken at `pose`.
    pub fn update(&mut self, scan: &ScanGrid, pose: Pose) -> Update {
        if scan.cells.len() != scan.rows * scan.cols || scan.resolution_m <= 0.0 {
            return Update::Malformed;
        }
        let limit = self.config.max_tilt_deg.to_radians();
        if pose.pitch_rad.abs() > limit || pose.roll_rad.abs() > limit {
            return Update::SkippedTilt;
        }
        self.frame = self.frame.wrapping_add(1);
        let projector = Projector::new(pose, self.mount, self.config.correct_tilt);
        let full_weight_sq = self.config.full_weight_range_m * self.config.full_weight_range_m;
        let (max_range_m, margin_m) = (self.config.max_range_m, self.config.shadow_margin_m);
        let mut scan_layout = std::mem::take(&mut self.scan_layout);
        let in_range = scan_layout.for_scan(scan, max_range_m);
        let nearest_obstacles = (margin_m < max_range_m).then(|| NearestObstacles::of(scan.cells, in_range, margin_m));
        let mut landed = 0;
        let mut nearest_rock: Option<(f64, f64, f64)> = None;
        for &CellInRange { index, x, y, range_sq, bin, .. } in in_range {
            let class = scan.cells[index];
            if !(NAVIGABLE..=ROCK).contains(&class) {
                continue;
            }
            if class == ROCK {
                if nearest_rock.is_none_or(|(r, ..)| range_sq < r) {
                    nearest_rock = Some((range_sq, x, y));
                }
                continue;
            }
            if class == OBSTACLE && nearest_obstacles.as_ref().is_some_and(|n| n.shadowed(bin, range_sq)) {
                continue;
            }
            if let Some(cell) = projector.world(x, y).and_then(|(wx, wy)| cell_of_point(wx, wy)) {
                let weight = (full_weight_sq / range_sq).min(1.0) as f32;
                self.add(cell, (class - 1) as usize, weight);
                landed += 1;
            }
        }
        self.scan_layout = scan_layout;
        let rock = nearest_rock.and_then(|(range_sq, x, y)| {
            let cell = projector.world(x, y).and_then(|(wx, wy)| cell_of_point(wx, wy))?;
            Some((cell, range_sq.sqrt() as f32))
        });
        if let Some((cell, range_m)) = rock {
            self.add(cell, (ROCK - 1) as usize, 1.0);
            self.rock_range_m[cell] = self.rock_range_m[cell].min(range_m);
            landed += 1;
        }
        Update::Used(landed)
    }

    /// Counts `class` in `cell` once per frame, and weighs it by the heaviest `weight` the
    /// frame gives it.
    #[inline]
    fn add(&mut self, cell: usize, class: usize, weight: f32) {
        let first_this_frame = self.last_frame[class][cell] != self.frame;
        if first_this_frame {
            self.last_frame[class][cell] = self.frame;
            self.hits[class][cell] = self.hits[class][cell].saturating_add(1);
        }
        if class < WEIGHED {
            let heaviest = if first_this_frame { 0.0 } else { self.frame_weight[class][cell] };
            if weight > heaviest {
                self.weight[class][cell] += weight - heaviest;
                self.frame_weight[class][cell] = weight;
            }
        }
    }

    /// Navigable frames, obstacle frames and rock frames of a cell.
    pub fn evidence(&self, cell: usize) -> (u16, u16, u16) {
        (self.hits[0][cell], self.hits[1][cell], self.hits[2][cell])
    }

    /// Range-weighed navigable and obstacle evidence of a cell (see
    /// [`MapConfig::full_weight_range_m`]).
    pub fn weighed_evidence(&self, cell: usize) -> (f32, f32) {
        (self.weight[0][cell], self.weight[1][cell])
    }

    /// What the map calls the cell, as an occupancy value (the tests' view of one cell of
    /// [`WorldMap::occupancy`]).
    #[cfg(test)]
    fn cell_occupancy(&self, cell: usize) -> i8 {
        let ((nav_hits, obs_hits, _), (nav, obs)) = (self.evidence(cell), self.weighed_evidence(cell));
        self.config.occupancy([nav_hits, obs_hits], [nav, obs])
    }

    /// True if the map holds a rock in the cell.
    pub fn is_rock(&self, cell: usize) -> bool {
        self.hits[2][cell] >= self.config.min_rock_hits
    }

    /// The occupancy grid: [`OCCUPANCY_FREE`] navigable, [`OCCUPANCY_OCCUPIED`] obstacle,
    /// [`OCCUPANCY_UNKNOWN`] unknown; row = y. One pass over the evidence: what is asked of the
    /// whole map (counts, scores, the inset) is best asked of this.
    pub fn occupancy(&self) -> Vec<i8> {
        let [nav_hits, obs_hits] = [&self.hits[0], &self.hits[1]];
        let [nav, obs] = [&self.weight[0], &self.weight[1]];
        nav_hits
            .iter()
            .zip(obs_hits)
            .zip(nav.iter().zip(obs))
            .map(|((&nav_hits, &obs_hits), (&nav, &obs))| self.config.occupancy([nav_hits, obs_hits], [nav, obs]))
            .collect()
    }

    /// Counts of navigable and obstacle cells.
    pub fn cell_counts(&self) -> (usize, usize) {
        occupancy_counts(&self.occupancy())
    }

    /// The Udacity scores of the map against a ground-truth navigable mask.
    pub fn scores(&self, ground_truth: &[bool]) -> Scores {
        occupancy_scores(&self.occupancy(), ground_truth)
    }

    /// Cells (x, y) holding a rock.
    pub fn rock_cells(&self) -> Vec<(usize, usize)> {
        (0..CELLS).filter(|&c| self.is_rock(c)).map(cell_xy).collect()
    }

    /// The located rocks, world metres, given this map's [`WorldMap::occupancy`]: rock cells
    /// within `merge_m` are one rock (see [`rock_positions`]); cells with no navigable cell within
    /// [`ROCK_FLOOR_REACH_M`] are left out (see there).
    pub fn rocks(&self, occupancy: &[i8], merge_m: f64) -> Vec<(f64, f64)> {
        let cells: Vec<RockCell> = self
            .rock_cells()
            .into_iter()
            .filter(|&(x, y)| floor_within(occupancy, (x, y), ROCK_FLOOR_REACH_M))
            .map(|(x, y)| RockCell { x, y, range_m: self.rock_range_m[cell_at(x, y)] })
            .collect();
        rock_positions(&cells, merge_m)
    }

    /// Forgets the rock the arm just picked up: the rock evidence around the arm of a rover at
    /// (x, y) facing `yaw_rad`.
    pub fn forget_picked_rock(&mut self, x_m: f64, y_m: f64, yaw_rad: f64) {
        let (arm_x_m, arm_y_m) = arm_point(x_m, y_m, yaw_rad);
        self.clear_rocks_near(arm_x_m, arm_y_m, SAMPLE_SPREAD_M);
    }

    /// Forgets the rock evidence within `radius_m` of (x, y), e.g. once the sample there is picked up.
    pub fn clear_rocks_near(&mut self, x_m: f64, y_m: f64, radius_m: f64) {
        let reach = radius_m.ceil() as i64 + 1;
        for iy in (y_m as i64 - reach)..=(y_m as i64 + reach) {
            for ix in (x_m as i64 - reach)..=(x_m as i64 + reach) {
                if let Some(cell) = cell_of_point(ix as f64 + 0.5, iy as f64 + 0.5)
                    && (ix as f64 + 0.5 - x_m).hypot(iy as f64 + 0.5 - y_m) <= radius_m
                {
                    self.hits[2][cell] = 0;
                    self.rock_range_m[cell] = f32::INFINITY;
                }
            }
        }
    }
}

/// Where the arm of a rover at (x, y) facing `yaw_rad` reaches, world metres: where a sample it
/// picks up lies.
pub fn arm_point(x_m: f64, y_m: f64, yaw_rad: f64) -> (f64, f64) {
    let (s, c) = yaw_rad.sin_cos();
    (x_m + ARM_REACH_M * c, y_m + ARM_REACH_M * s)
}
#[cfg(test)]
mod tests;
