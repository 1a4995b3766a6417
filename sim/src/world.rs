//! The world: a 200 m x 200 m terrain (row = y, column = x) with its boulders, the ground truth
//! the run is scored against, the rock samples and the start pose, and how it looks.

use nalgebra::Point3;

use crate::boulder::Boulder;
use crate::elevation::Elevation;
use crate::look::Look;
use crate::obstacle::Obstacle;
use crate::rock_survey::SurveyedRock;
use crate::terrain::{NODES_PER_M, TERRAIN_STEP_M, Terrain};

/// Floor under a boulder up to this height has the floor's colour, metres: Unity's floor runs on
/// under its overhanging rock, although the map leaves that ground out.
const PAINT_UNDER_ROCK_M: f64 = 8.0;
/// Side of the world, metres and map cells.
pub const WORLD_SIZE: usize = 200;

/// True if (x, y), metres, lies inside the world's square.
pub(crate) fn inside_world(x_m: f64, y_m: f64) -> bool {
    let size = WORLD_SIZE as f64;
    (0.0..size).contains(&x_m) && (0.0..size).contains(&y_m)
}

/// Fewest navigable cells a world read from a map image may have.
pub const MIN_MAP_NAVIGABLE_CELLS: usize = 100;

/// Number of samples spawned per run.
pub const SAMPLE_COUNT: usize = 6;
/// The rover cannot drive where the terrain rises more than this per metre (56 degrees)...
const MAX_DRIVABLE_SLOPE: f64 = 1.5;
/// ...nor where it is higher than this above the floor, about a wheel's radius, metres: its
/// wheels ride up the foot of a wall, not the wall.
const MAX_DRIVABLE_HEIGHT_M: f32 = 0.15;
/// A boulder blocks the rover where it fills the space up to this height above the ground, the
/// top of the rover's body, metres.
pub const BODY_TOP_M: f64 = 0.55;

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

impl Sample {
    /// Its centre, metres: Unity spawns the samples at the floor's height whatever the ground
    /// there, so one on the foot of a wall sits partly in the slope, as low as one on the floor.
    pub fn centre(&self) -> Point3<f64> {
        Point3::new(self.x_m, self.y_m, self.radius_m * 0.75)
    }
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

/// Everything a world is made of, before the derived fields are computed.
#[derive(Debug, Clone)]
pub struct WorldPlan {
    /// Cells where the terrain is flat floor (`WORLD_SIZE` x `WORLD_SIZE`, row = y).
    pub floor: Vec<bool>,
    /// Cells that count as navigable when the map is scored.
    pub ground_truth: Vec<bool>,
    /// Faceted rocks standing on the ground.
    pub boulders: Vec<Boulder>,
    /// Surveyed rocks standing on the ground.
    pub surveyed_rocks: Vec<SurveyedRock>,
    /// Samples, in the order the simulator reports them.
    pub samples: Vec<Sample>,
    /// The rover's start pose.
    pub start: StartPose,
    /// The shape of the ground.
    pub ground: Ground,
}

/// Where the shape of the ground comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum Ground {
    /// Walls rising from the floor as the measured profile of the Unity walls does; `salt`
    /// varies their shape.
    Generated {
        /// Varies the walls' shape.
        salt: u64,
    },
    /// The heights of a survey.
    Surveyed(Elevation),
}

/// The world the rover drives in.
#[derive(Debug, Clone)]
pub struct World {
    terrain: Terrain,
    boulders: Vec<Boulder>,
    surveyed_rocks: Vec<SurveyedRock>,
    ground_truth: Vec<bool>,
    floor: Vec<bool>,
    painted: Vec<bool>,
    blocked: Vec<bool>,
    /// Samples on the ground, in the order the simulator reports them.
    pub samples: Vec<Sample>,
    /// The rover's start pose.
    pub start: StartPose,
    /// How the world looks to the camera.
    pub look: Look,
}

/// Errors building a world from map images.
#[derive(Debug, thiserror::Error)]
pub enum WorldError {
    /// A map image is not the size of the world.
    #[error("{name} image is {width}x{height}, expected {expected}x{expected} (row = y, column = x)")]
    WrongSize {
        /// Which image.
        name: &'static str,
        /// Its width.
        width: usize,
        /// Its height.
        height: usize,
        /// The side it must have.
        expected: usize,
    },
    /// A map image cannot be decoded.
    #[error("cannot read the {name} image: {reason}")]
    Unreadable {
        /// Which image.
        name: &'static str,
        /// What went wrong.
        reason: String,
    },
    /// Too little navigable ground.
    #[error("map has only {0} navigable pixels (values > 0); a world needs at least {MIN_MAP_NAVIGABLE_CELLS}")]
    TooSmall(usize),
    /// The floor image leaves navigable map cells out.
    #[error("the floor image leaves out {0} navigable cells of the map; it must contain all of them")]
    FloorMissesMap(usize),
}

impl World {
    /// Builds the world of `plan`, with the default look.
    pub fn build(plan: WorldPlan) -> Self {
        assert_eq!(plan.floor.len(), WORLD_SIZE * WORLD_SIZE, "floor must be 200x200");
        assert_eq!(plan.ground_truth.len(), WORLD_SIZE * WORLD_SIZE, "ground truth must be 200x200");
        let terrain = match &plan.ground {
            Ground::Generated { salt } => Terrain::from_floor(&plan.floor, *salt),
            Ground::Surveyed(elevation) => Terrain::from_heights(elevation.node_heights_m()),
        };
        let obstacles =
            || plan.boulders.iter().map(|b| b as &dyn Obstacle).chain(plan.surveyed_rocks.iter().map(|r| r as _));
        let heights_m: Vec<f32> = terrain.nodes().map(|(_, _, h)| h).collect();
        let blocked = blocked_nodes(&terrain, &covered_nodes(&heights_m, obstacles()));
        let mut painted = match plan.ground {
            Ground::Generated { .. } => plan.ground_truth.clone(),
            Ground::Surveyed(_) => vec![true; plan.ground_truth.len()],
        };
        let floor_under_rock = obstacles().flat_map(|o| o.cells_under(&plan.floor, PAINT_UNDER_ROCK_M));
        floor_under_rock.collect::<Vec<_>>().into_iter().for_each(|cell| painted[cell] = true);
        World {
            terrain,
            boulders: plan.boulders,
            surveyed_rocks: plan.surveyed_rocks,
            ground_truth: plan.ground_truth,
            floor: plan.floor,
            painted,
            blocked,
            samples: plan.samples,
            start: plan.start,
            look: Look::default(),
        }
    }

    /// A world whose floor is also its ground truth, without boulders or samples (for tests).
    pub fn open(floor: Vec<bool>, start: StartPose) -> Self {
        World::build(WorldPlan {
            ground_truth: floor.clone(),
            floor,
            boulders: vec![],
            surveyed_rocks: vec![],
            samples: vec![],
            start,
            ground: Ground::Generated { salt: 0 },
        })
    }

    /// The same world with another look.
    pub fn with_look(mut self, look: Look) -> Self {
        self.look = look;
        self
    }

    /// The terrain.
    pub fn terrain(&self) -> &Terrain {
        &self.terrain
    }

    /// The faceted rocks.
    pub fn boulders(&self) -> &[Boulder] {
        &self.boulders
    }

    /// The surveyed rocks.
    pub fn surveyed_rocks(&self) -> &[SurveyedRock] {
        &self.surveyed_rocks
    }

    /// The ground-truth navigable map for scoring, row-major (row = y, column = x).
    pub fn ground_truth(&self) -> &[bool] {
        &self.ground_truth
    }

    /// The cells whose ground has the floor's colour where it is flat: on generated ground the
    /// navigable map and the floor it leaves out under rocks, on surveyed ground every cell
    /// (row-major).
    pub fn painted(&self) -> &[bool] {
        &self.painted
    }

    /// Height of the ground at (x, y) above the floor, metres.
    pub fn ground_height(&self, x_m: f64, y_m: f64) -> f32 {
        self.terrain.height_at(x_m, y_m)
    }

    /// True if the rover can drive at (x, y): gentle terrain, no boulder, inside the world.
    pub fn is_drivable(&self, x_m: f64, y_m: f64) -> bool {
        let side = (WORLD_SIZE * NODES_PER_M) as f64;
        let (nx, ny) = (x_m / TERRAIN_STEP_M, y_m / TERRAIN_STEP_M);
        (0.0..side).contains(&nx)
            && (0.0..side).contains(&ny)
            && !self.blocked[ny as usize * side as usize + nx as usize]
    }

    /// The squares (side [`TERRAIN_STEP_M`], lower corner given) within `r` of (x, y) where the
    /// rover cannot drive.
    pub fn blocked_squares_near(&self, x_m: f64, y_m: f64, r: f64) -> impl Iterator<Item = [f64; 2]> + '_ {
        let step = TERRAIN_STEP_M;
        let range = move |c: f64| ((c - r) / step).floor() as i64..=((c + r) / step).floor() as i64;
        range(y_m).flat_map(move |ny| range(x_m).map(move |nx| [nx as f64 * step, ny as f64 * step])).filter(
            move |&[sx, sy]| {
                let (cx, cy) = (sx + step / 2.0, sy + step / 2.0);
                !self.is_drivable(cx, cy) && (x_m.clamp(sx, sx + step) - x_m).hypot(y_m.clamp(sy, sy + step) - y_m) < r
            },
        )
    }

    /// The 1 m cells where the rover can drive all over (row-major, row = y): every terrain
    /// square of the cell is drivable.
    pub fn drivable_cells(&self) -> Vec<bool> {
        let quarters = [0.25, 0.75];
        (0..WORLD_SIZE * WORLD_SIZE)
            .map(|i| {
                let (x, y) = ((i % WORLD_SIZE) as f64, (i / WORLD_SIZE) as f64);
                quarters.iter().all(|dy| quarters.iter().all(|dx| self.is_drivable(x + dx, y + dy)))
            })
            .collect()
    }

    /// The cells of flat floor whose centre the rover can drive on (no rock there), row-major:
    /// the ground an honest map holds as navigable. Wider than the ground truth, which leaves out
    /// the floor at the foot of the walls (`floor_flat.png` against `map_bw.png`).
    pub fn open_floor(&self) -> Vec<bool> {
        let centre_is_drivable = |cell: usize| {
            let (x_m, y_m) = cell_centre(cell);
            self.is_drivable(x_m, y_m)
        };
        self.floor.iter().enumerate().map(|(cell, &floor)| floor && centre_is_drivable(cell)).collect()
    }

    /// Cells as a `map_bw.png`-style PNG: true pixels white, the rest black (row = y,
    /// column = x); e.g. the scoring ground truth ([`World::ground_truth`]).
    pub fn cells_png(cells: &[bool]) -> Result<Vec<u8>, rover_imaging::ImageError> {
        let mut image = rover_imaging::RgbImage::new(WORLD_SIZE, WORLD_SIZE);
        for (i, _) in cells.iter().enumerate().filter(|(_, on)| **on) {
            image.set_pixel(i % WORLD_SIZE, i / WORLD_SIZE, [255, 255, 255]);
        }
        rover_imaging::encode_png(&image)
    }
}

/// The terrain nodes (ground heights `heights_m`, row by row) where one of `obstacles` stands in
/// the rover's way: it fills the space from just above the ground up to [`BODY_TOP_M`].
fn covered_nodes<'a>(heights_m: &[f32], obstacles: impl Iterator<Item = &'a dyn Obstacle>) -> Vec<bool> {
    let side = WORLD_SIZE * NODES_PER_M;
    let mut covered = vec![false; side * side];
    for obstacle in obstacles {
        let [lo, hi] = obstacle.bounds_m();
        let range = |axis: usize| {
            (lo[axis] / TERRAIN_STEP_M).floor().max(0.0) as usize
                ..=((hi[axis] / TERRAIN_STEP_M).max(0.0) as usize).min(side - 1)
        };
        for ny in range(1) {
            for nx in range(0) {
                let (x, y) = ((nx as f64 + 0.5) * TERRAIN_STEP_M, (ny as f64 + 0.5) * TERRAIN_STEP_M);
                covered[ny * side + nx] |= obstacle.covers(x, y, heights_m[ny * side + nx] as f64, BODY_TOP_M);
            }
        }
    }
    covered
}

/// The terrain nodes the rover cannot drive on: too steep, too high, or `covered` by a rock.
fn blocked_nodes(terrain: &Terrain, covered: &[bool]) -> Vec<bool> {
    terrain
        .nodes()
        .zip(covered)
        .map(|((x, y, h), &covered)| {
            let [gx, gy] = terrain.gradient_at(x, y);
            covered || h > MAX_DRIVABLE_HEIGHT_M || gx.hypot(gy) > MAX_DRIVABLE_SLOPE
        })
        .collect()
}

/// The drivable ground of a map: its navigable cells plus every cell next to one (8-neighbourhood)
/// that belongs to the outer non-navigable region. The Unity terrain is flat (below 0.5 m) on 829
/// cells around the 1993 navigable ones of `map_bw.png`, mostly along the walls: the map is
/// conservative, and the rover drives where the map says it cannot. One cell of widening adds 874
/// cells. Enclosed non-navigable spots (rocks on the floor) stay solid.
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
pub fn outer_region(navigable: &[bool]) -> Vec<bool> {
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

/// The cells left, right, below and above `index` that lie on the map.
pub fn neighbours4(index: usize) -> impl Iterator<Item = usize> {
    let (x, y) = ((index % WORLD_SIZE) as i64, (index / WORLD_SIZE) as i64);
    [(x + 1, y), (x - 1, y), (x, y + 1), (x, y - 1)]
        .into_iter()
        .filter(|&(nx, ny)| (0..WORLD_SIZE as i64).contains(&nx) && (0..WORLD_SIZE as i64).contains(&ny))
        .map(|(nx, ny)| ny as usize * WORLD_SIZE + nx as usize)
}

/// The cells of `floor` connected to `from` through their 4-neighbours (`from` counts as reached).
pub fn reached_from(floor: &[bool], from: usize) -> Vec<bool> {
    let mut seen = vec![false; floor.len()];
    let mut queue = vec![from];
    seen[from] = true;
    while let Some(cell) = queue.pop() {
        for next in neighbours4(cell) {
            if floor[next] && !seen[next] {
                seen[next] = true;
                queue.push(next);
            }
        }
    }
    seen
}

/// The centre of the row-major cell `cell`, metres (x, y).
pub(crate) fn cell_centre(cell: usize) -> (f64, f64) {
    ((cell % WORLD_SIZE) as f64 + 0.5, (cell / WORLD_SIZE) as f64 + 0.5)
}

/// A mask that is true on the cells of columns `columns` in rows `rows`, for tests.
#[cfg(test)]
pub(crate) fn rectangle(columns: std::ops::Range<usize>, rows: std::ops::Range<usize>) -> Vec<bool> {
    (0..WORLD_SIZE * WORLD_SIZE)
        .map(|i| columns.contains(&(i % WORLD_SIZE)) && rows.contains(&(i / WORLD_SIZE)))
        .collect()
}

/// A `map_bw.png`-style mask: a 200x200 image, true where the pixel is brighter than black.
pub fn read_mask(png: &[u8], name: &'static str) -> Result<Vec<bool>, WorldError> {
    let image = rover_imaging::decode_png(png).map_err(|e| WorldError::Unreadable { name, reason: e.to_string() })?;
    if (image.width, image.height) != (WORLD_SIZE, WORLD_SIZE) {
        return Err(WorldError::WrongSize { name, width: image.width, height: image.height, expected: WORLD_SIZE });
    }
    Ok(image.data.chunks_exact(3).map(|p| p[0] > 0).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::boulder::{BoulderKind, BoulderSpec};
    use crate::random::SplitMix64;

    fn corridor() -> Vec<bool> {
        rectangle(50..150, 95..105)
    }

    #[test]
    fn the_rover_drives_on_the_floor_and_the_foot_but_not_up_the_wall() {
        let world = World::open(corridor(), StartPose { x_m: 100.0, y_m: 100.0, yaw_deg: 0.0 });
        assert!(world.is_drivable(100.0, 100.0) && world.is_drivable(100.0, 95.1));
        assert!(!world.is_drivable(100.0, 93.5), "1.5 m into the wall");
        assert!(!world.is_drivable(-1.0, 100.0) && !world.is_drivable(100.0, 200.5));
        assert_eq!(world.ground_truth().iter().filter(|&&n| n).count(), 1000);
        assert_eq!(world.blocked_squares_near(100.0, 100.0, 1.0).count(), 0);
        assert!(world.blocked_squares_near(100.0, 94.0, 0.5).count() > 0);
    }

    #[test]
    fn boulders_block_the_rover() {
        let spec = BoulderSpec { x_m: 100.0, y_m: 100.0, footprint_radius_m: 1.0, kind: BoulderKind::Lump };
        let boulder = Boulder::new(&spec, &mut SplitMix64::new(1));
        let plan = WorldPlan {
            floor: corridor(),
            ground_truth: corridor(),
            boulders: vec![boulder],
            surveyed_rocks: vec![],
            samples: vec![],
            start: StartPose { x_m: 60.0, y_m: 100.0, yaw_deg: 0.0 },
            ground: Ground::Generated { salt: 0 },
        };
        let world = World::build(plan);
        assert!(!world.is_drivable(100.0, 100.0) && world.is_drivable(102.0, 100.0));
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
    fn the_exported_map_is_the_ground_truth() {
        let world = crate::procgen::procedural_world(3);
        let png = World::cells_png(world.ground_truth()).unwrap();
        assert_eq!(read_mask(&png, "map").unwrap(), world.ground_truth());
        assert!(matches!(read_mask(b"not a png", "map"), Err(WorldError::Unreadable { name: "map", .. })));
    }

    #[test]
    fn drivable_cells_are_floor_without_the_boulders() {
        let world = crate::procgen::procedural_world(3);
        let drivable = world.drivable_cells();
        let (cells, floor) =
            (drivable.iter().filter(|&&d| d).count(), world.ground_truth().iter().filter(|&&f| f).count());
        assert!(cells > floor / 2, "most of the floor: {cells} of {floor}");
        assert!(!world.boulders().is_empty(), "a world with boulders");
        let centre_cell = |b: &Boulder| b.centre[1] as usize * WORLD_SIZE + b.centre[0] as usize;
        let under_boulders = world.boulders().iter().filter(|b| !drivable[centre_cell(b)]).count();
        assert_eq!(under_boulders, world.boulders().len(), "no boulder's centre is drivable");
    }

    #[test]
    fn the_open_floor_is_the_floor_but_where_a_rock_stands() {
        let spec = BoulderSpec { x_m: 100.5, y_m: 100.5, footprint_radius_m: 1.0, kind: BoulderKind::Lump };
        let world = World::build(WorldPlan {
            floor: rectangle(50..150, 94..106),
            ground_truth: corridor(),
            boulders: vec![Boulder::new(&spec, &mut SplitMix64::new(1))],
            surveyed_rocks: vec![],
            samples: vec![],
            start: StartPose { x_m: 60.0, y_m: 100.0, yaw_deg: 0.0 },
            ground: Ground::Generated { salt: 0 },
        });
        let open = world.open_floor();
        let cell = |x: usize, y: usize| open[y * WORLD_SIZE + x];
        assert!(!cell(100, 100), "under the rock");
        assert!(cell(110, 100) && cell(110, 94), "the floor, also beyond the ground truth");
        assert!(!cell(110, 93) && !cell(40, 100), "not the walls");
    }
}
