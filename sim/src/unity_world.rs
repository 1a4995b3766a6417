//! The Unity world behind `map_bw.png` (unity-sim-spec 5, `../shared/udacity-world/README.md`):
//! its sample places and start, its floor and ground, and the rocks that stand on it: surveyed
//! when the surveys are given, else built from the map and the rocks' places and scales.

use crate::boulder::{Boulder, BoulderKind, BoulderSpec, Cap};
use crate::elevation::Elevation;
use crate::obstacle::Obstacle;
use crate::random::SplitMix64;
use crate::rock_survey::read_rock_survey;
use crate::world::{
    BODY_TOP_M, Ground, MIN_MAP_NAVIGABLE_CELLS, SAMPLE_COUNT, Sample, StartPose, WORLD_SIZE, World, WorldError,
    WorldPlan, neighbours4, outer_region, read_mask, widen_floor,
};

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

/// A rock of the Unity scene that stands on the floor: position, the instance's scale and shape.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UnityRock {
    /// x, metres.
    pub x_m: f64,
    /// y, metres.
    pub y_m: f64,
    /// The instance's uniform scale.
    pub scale: f64,
    /// Shape.
    pub kind: BoulderKind,
}

const fn rock(x_m: f64, y_m: f64, scale: f64, kind: BoulderKind) -> UnityRock {
    UnityRock { x_m, y_m, scale, kind }
}

/// The cap of the rock pack boulder at (106.8, 102.9), fitted to the real frames that look at it
/// (`robocam_2017_05_02_11_16_27_*` to `_28_*`): it reaches over the floor towards the south-west,
/// its underside about 2 m up.
const UNITY_OVERHANG: Cap = Cap { offset_m: [-1.5, -2.5], radius_m: 5.0, underside_m: 2.0, thickness_m: 3.0 };

/// The 16 rock obstacles of the scene whose base is near the floor (`udacity-world` README
/// section 3): boulders and rock clusters are lumps, the "rock pack" boulders clusters, the one at
/// (106.8, 102.9) overhangs the floor.
pub const UNITY_ROCKS: [UnityRock; 16] = [
    rock(5.6, 97.6, 8.0, BoulderKind::Lump),
    rock(13.9, 93.5, 5.0, BoulderKind::Cluster),
    rock(81.1, 71.5, 3.02, BoulderKind::Pillar),
    rock(84.8, 74.3, 3.02, BoulderKind::Pillar),
    rock(91.0, 82.5, 1.0, BoulderKind::Lump),
    rock(92.9, 73.2, 2.54, BoulderKind::Lump),
    rock(94.2, 83.8, 1.0, BoulderKind::Lump),
    rock(95.0, 84.8, 1.0, BoulderKind::Lump),
    rock(97.1, 70.1, 1.0, BoulderKind::Lump),
    rock(97.8, 79.8, 0.7, BoulderKind::Cluster),
    rock(99.3, 77.3, 0.7, BoulderKind::Cluster),
    rock(106.8, 102.9, 5.98, BoulderKind::Overhang(UNITY_OVERHANG)),
    rock(107.2, 80.0, 3.81, BoulderKind::Cluster),
    rock(110.0, 87.3, 3.81, BoulderKind::Cluster),
    rock(114.9, 92.9, 5.98, BoulderKind::Cluster),
    rock(152.0, 106.2, 5.0, BoulderKind::Lump),
];

/// Footprint radius per unit of scale, metres: the unit-scale rocks' islands in `map_bw.png` are
/// one to two cells across.
const FOOTPRINT_RADIUS_PER_SCALE_M: f64 = 0.7;
/// A fitted boulder's footprint lies between these tenths of the radius its scale gives.
const FOOTPRINT_FIT_TENTHS: (usize, usize) = (5, 15);
/// Salt of the Unity world's wall shapes and boulder facets (one terrain for every run).
const UNITY_TERRAIN_SALT: u64 = 0x0_5eed_u64;

/// The files the Unity world is built from: a `map_bw.png`-style map (the scoring ground truth)
/// and, each optional, the floor (e.g. `floor_flat.png`, white where the terrain is flat), the
/// survey of the ground's heights (`elevation_cm.png`) and that of the rocks (`rocks.json`).
#[derive(Debug, Clone, Copy, Default)]
pub struct UnityFiles<'a> {
    /// The map's PNG bytes.
    pub map_png: &'a [u8],
    /// The floor's PNG bytes.
    pub floor_png: Option<&'a [u8]>,
    /// The ground survey's PNG bytes.
    pub elevation_png: Option<&'a [u8]>,
    /// The rock survey's JSON bytes.
    pub rocks_json: Option<&'a [u8]>,
}

/// The Unity world built from `files`. Without a floor image the floor is the surveyed ground
/// below half a metre, or without a survey the map widened by one cell; without a ground survey
/// the walls rise from the floor as the measured profile does; without a rock survey the rocks of
/// [`UNITY_ROCKS`] are faceted boulders fitted to the map. 6 of the 33 placeholders get samples
/// and the start yaw is drawn from `seed`, as Unity does in autonomous mode.
pub fn unity_world(files: &UnityFiles, seed: u64) -> Result<World, WorldError> {
    unity_plan(files, seed).map(World::build)
}

/// What [`unity_world`] builds, before it is built.
pub fn unity_plan(files: &UnityFiles, seed: u64) -> Result<WorldPlan, WorldError> {
    let navigable = read_mask(files.map_png, "map")?;
    let count = navigable.iter().filter(|&&n| n).count();
    if count < MIN_MAP_NAVIGABLE_CELLS {
        return Err(WorldError::TooSmall(count));
    }
    let elevation = files.elevation_png.map(Elevation::from_png).transpose()?;
    let mut floor = match (files.floor_png, &elevation) {
        (Some(png), _) => read_mask(png, "floor")?,
        (None, Some(elevation)) => elevation.floor(),
        (None, None) => widen_floor(&navigable),
    };
    let missing = navigable.iter().zip(&floor).filter(|(n, f)| **n && !**f).count();
    if missing > 0 {
        return Err(WorldError::FloorMissesMap(missing));
    }
    let ground = match elevation {
        Some(elevation) => Ground::Surveyed(elevation),
        None => {
            for &(x, y) in &UNITY_SAMPLE_CANDIDATES {
                carve_access(&mut floor, x, y);
            }
            Ground::Generated { salt: UNITY_TERRAIN_SALT }
        }
    };
    let mut rng = SplitMix64::new(seed);
    let mut candidates: Vec<(f64, f64)> = UNITY_SAMPLE_CANDIDATES.to_vec();
    let mut samples = Vec::with_capacity(SAMPLE_COUNT);
    while samples.len() < SAMPLE_COUNT && !candidates.is_empty() {
        let (x_m, y_m) = candidates.swap_remove(rng.below(candidates.len()));
        samples.push(Sample { x_m, y_m, radius_m: rng.range(0.07, 0.10) });
    }
    let start = StartPose { x_m: UNITY_START.0, y_m: UNITY_START.1, yaw_deg: rng.range(0.0, 360.0) };
    let (boulders, surveyed_rocks) = match files.rocks_json {
        Some(json) => (Vec::new(), read_rock_survey(json)?),
        None => {
            let islands = enclosed_cells(&navigable);
            let keep_free = free_ground(&navigable);
            let fitted =
                UNITY_ROCKS.iter().enumerate().map(|(i, rock)| fitted_boulder(rock, &keep_free, &islands, i as u64));
            (fitted.collect(), Vec::new())
        }
    };
    Ok(WorldPlan { floor, ground_truth: navigable, boulders, surveyed_rocks, samples, start, ground })
}

/// The ground no rock may stand on: the map's navigable cells and the cells around the sample
/// places (Unity's samples lie on open ground).
fn free_ground(navigable: &[bool]) -> Vec<bool> {
    let mut free = navigable.to_vec();
    for &(x, y) in &UNITY_SAMPLE_CANDIDATES {
        let (cx, cy) = (x.floor() as usize, y.floor() as usize);
        (cy - 1..=cy + 1)
            .flat_map(|y| (cx - 1..=cx + 1).map(move |x| (x, y)))
            .for_each(|(x, y)| free[y * WORLD_SIZE + x] = true);
    }
    free
}

/// The boulder of `rock`, its footprint fitted to the map: between half and one and a half times
/// the size its scale gives, covering as many of the map's islands (`islands`: enclosed
/// non-navigable cells) and no cell of `keep_free`, and otherwise as close to its scale as
/// possible.
pub fn fitted_boulder(rock: &UnityRock, keep_free: &[bool], islands: &[bool], index: u64) -> Boulder {
    let nominal_m = rock.scale * FOOTPRINT_RADIUS_PER_SCALE_M;
    let boulder_of = |tenths: usize| {
        let spec = BoulderSpec {
            x_m: rock.x_m,
            y_m: rock.y_m,
            footprint_radius_m: nominal_m * tenths as f64 / 10.0,
            kind: rock.kind,
        };
        Boulder::new(&spec, &mut SplitMix64::new(UNITY_TERRAIN_SALT ^ index))
    };
    let (smallest, largest) = FOOTPRINT_FIT_TENTHS;
    let fits = (smallest..=largest)
        .map(|tenths| (tenths, boulder_of(tenths)))
        .filter(|(_, boulder)| boulder.cells_under(keep_free, BODY_TOP_M).is_empty())
        .max_by_key(|(tenths, boulder)| {
            (boulder.cells_under(islands, BODY_TOP_M).len(), std::cmp::Reverse(tenths.abs_diff(10)))
        });
    fits.map_or_else(|| boulder_of(smallest), |(_, boulder)| boulder)
}

/// The non-navigable cells that the navigable ones enclose: rocks on the floor.
pub fn enclosed_cells(navigable: &[bool]) -> Vec<bool> {
    let outer = outer_region(navigable);
    navigable.iter().zip(&outer).map(|(n, o)| !n && !o).collect()
}

/// Makes the ground around a sample placeholder floor, with a path to the nearest floor: in the
/// Unity scene the samples lie on flat ground that a conservative floor mask may leave out.
fn carve_access(floor: &mut [bool], x_m: f64, y_m: f64) {
    let (sx, sy) = (x_m.floor() as i64, y_m.floor() as i64);
    let index = |x: i64, y: i64| {
        (y.clamp(0, WORLD_SIZE as i64 - 1) as usize) * WORLD_SIZE + x.clamp(0, WORLD_SIZE as i64 - 1) as usize
    };
    let mut came_from = vec![usize::MAX; floor.len()];
    let start = index(sx, sy);
    came_from[start] = start;
    let mut queue = std::collections::VecDeque::from([start]);
    let mut reached = None;
    while let Some(cell) = queue.pop_front() {
        let (x, y) = ((cell % WORLD_SIZE) as i64, (cell / WORLD_SIZE) as i64);
        if floor[cell] && (x - sx).abs().max((y - sy).abs()) > 1 {
            reached = Some(cell);
            break;
        }
        for next in neighbours4(cell) {
            if came_from[next] == usize::MAX {
                came_from[next] = cell;
                queue.push_back(next);
            }
        }
    }
    let mut cell = reached.unwrap_or(start);
    while cell != start {
        floor[cell] = true;
        cell = came_from[cell];
    }
    for dy in -1..=1 {
        for dx in -1..=1 {
            floor[index(sx + dx, sy + dy)] = true;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shared(path: &str) -> Vec<u8> {
        let path = format!("{}/../../shared/{path}", env!("CARGO_MANIFEST_DIR"));
        std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
    }

    #[test]
    fn the_unity_map_builds_with_six_samples_and_a_random_yaw() {
        let png = shared("udacity/calibration_images/map_bw.png");
        let world = unity_world(&UnityFiles { map_png: &png, ..Default::default() }, 3).unwrap();
        assert_eq!(world.ground_truth().iter().filter(|&&n| n).count(), 1993);
        for &(x, y) in &UNITY_SAMPLE_CANDIDATES {
            assert!(world.is_drivable(x, y), "sample placeholder ({x}, {y}) is reachable");
        }
        assert_eq!(world.samples.len(), 6);
        assert!(world.samples.iter().all(|s| UNITY_SAMPLE_CANDIDATES.contains(&(s.x_m, s.y_m))));
        assert!(world.is_drivable(UNITY_START.0, UNITY_START.1));
        let other = unity_world(&UnityFiles { map_png: &png, ..Default::default() }, 4).unwrap();
        assert_ne!(world.start.yaw_deg, other.start.yaw_deg);
        assert_eq!(unity_world(&UnityFiles { map_png: &png, ..Default::default() }, 3).unwrap().samples, world.samples);
    }

    #[test]
    fn the_walls_rise_as_the_unity_terrain_does_and_the_floor_is_where_floor_flat_says() {
        use crate::distance::distance_to;
        use crate::terrain::TERRAIN_STEP_M;
        let (map, floor_png) =
            (shared("udacity/calibration_images/map_bw.png"), shared("udacity-world/floor_flat.png"));
        let world =
            unity_world(&UnityFiles { map_png: &map, floor_png: Some(&floor_png), ..Default::default() }, 0).unwrap();
        let nodes: Vec<(f64, f64, f32)> = world.terrain().nodes().collect();
        let side = (nodes.len() as f64).sqrt() as usize;
        let flat: Vec<bool> = nodes.iter().map(|n| n.2 < 0.05).collect();
        let distance_m: Vec<f64> = distance_to(&flat, side).iter().map(|&d| d as f64 * TERRAIN_STEP_M).collect();
        // The measured bands of `udacity-world/README.md` section 2: distance, then p10, median, p90.
        let table = [
            ((0.5, 1.0), [0.38, 0.76, 1.70]),
            ((1.0, 1.5), [0.95, 1.74, 3.27]),
            ((2.0, 3.0), [2.71, 4.93, 8.18]),
            ((4.0, 6.0), [5.78, 10.14, 15.46]),
            ((8.0, 12.0), [11.64, 18.38, 22.19]),
        ];
        for ((near, far), measured) in table {
            let mut heights: Vec<f64> =
                (0..nodes.len()).filter(|&i| (near..far).contains(&distance_m[i])).map(|i| nodes[i].2 as f64).collect();
            heights.sort_by(f64::total_cmp);
            let percentile = |q: f64| heights[((heights.len() - 1) as f64 * q) as usize];
            let simulated = [percentile(0.1), percentile(0.5), percentile(0.9)];
            eprintln!("{near}-{far} m from the floor: simulated {simulated:.2?}, Unity {measured:?}");
            for (s, m) in simulated.iter().zip(measured) {
                assert!((s / m - 1.0).abs() < 0.2, "{near}-{far} m: simulated {simulated:.2?}, Unity {measured:?}");
            }
        }
        let floor = read_mask(&floor_png, "floor").unwrap();
        let agreeing = (0..WORLD_SIZE * WORLD_SIZE)
            .filter(|&c| {
                let (x, y) = ((c % WORLD_SIZE) as f64 + 0.5, (c / WORLD_SIZE) as f64 + 0.5);
                (world.ground_height(x, y) < 0.5) == floor[c]
            })
            .count();
        let share = agreeing as f64 / (WORLD_SIZE * WORLD_SIZE) as f64;
        assert!(share > 0.99, "terrain below 0.5 m at a cell's centre where floor_flat.png is white: {share:.4}");
    }

    #[test]
    fn the_surveyed_world_stands_on_the_surveyed_ground_among_the_surveyed_rocks() {
        let (map, floor_png) =
            (shared("udacity/calibration_images/map_bw.png"), shared("udacity-world/floor_flat.png"));
        let (elevation_png, rocks) = (shared("udacity-world/elevation_cm.png"), shared("udacity-world/rocks.json"));
        let files = UnityFiles {
            map_png: &map,
            floor_png: None,
            elevation_png: Some(&elevation_png),
            rocks_json: Some(&rocks),
        };
        let world = unity_world(&files, 0).unwrap();
        let elevation = Elevation::from_png(&elevation_png).unwrap();
        for (x, y) in [(99.625, 85.625), (60.125, 110.375), (130.875, 40.125), (5.125, 195.875)] {
            assert!((world.ground_height(x, y) - elevation.height_at(x, y)).abs() < 1e-4, "({x}, {y})");
        }
        let floor = read_mask(&floor_png, "floor").unwrap();
        let agreeing = elevation.floor().iter().zip(&floor).filter(|(a, b)| a == b).count();
        assert!(agreeing as f64 > 0.99 * floor.len() as f64, "the surveyed floor is floor_flat.png's: {agreeing}");
        assert_eq!((world.surveyed_rocks().len(), world.boulders().len()), (16, 0));
        assert!(world.is_drivable(UNITY_START.0, UNITY_START.1));
        assert!(!world.is_drivable(110.0, 87.3), "the rock pack boulder stands in the way");
        let overhang = &world.surveyed_rocks()[11];
        let under_rim = (0..overhang.columns.len()).find_map(|i| {
            let (x, y) = (
                overhang.origin_m[0] + ((i % overhang.cols) as f64 + 0.5) * overhang.cell_m,
                overhang.origin_m[1] + ((i / overhang.cols) as f64 + 0.5) * overhang.cell_m,
            );
            let raised = overhang.columns[i].is_some_and(|c| c.bottom_m as f64 > BODY_TOP_M + 0.2);
            (raised && world.ground_height(x, y) < 0.05).then_some((x, y))
        });
        let (x, y) = under_rim.expect("floor under the overhanging rock");
        assert!(world.is_drivable(x, y), "the rover fits under the rim at ({x}, {y})");
    }

    #[test]
    fn a_floor_image_must_contain_the_map() {
        let map = shared("udacity/calibration_images/map_bw.png");
        let empty = rover_imaging::encode_png(&rover_imaging::RgbImage::new(WORLD_SIZE, WORLD_SIZE)).unwrap();
        let error = unity_world(&UnityFiles { map_png: &map, floor_png: Some(&empty), ..Default::default() }, 0)
            .unwrap_err()
            .to_string();
        assert!(error.contains("leaves out 1993 navigable cells"), "{error}");
        let small = rover_imaging::encode_png(&rover_imaging::RgbImage::new(20, 20)).unwrap();
        let error = unity_world(&UnityFiles { map_png: &map, floor_png: Some(&small), ..Default::default() }, 0)
            .unwrap_err()
            .to_string();
        assert!(error.contains("floor image is 20x20"), "{error}");
    }

    #[test]
    fn the_rocks_cover_the_maps_islands_and_no_navigable_cell() {
        let map = shared("udacity/calibration_images/map_bw.png");
        let floor = shared("udacity-world/floor_flat.png");
        let world =
            unity_world(&UnityFiles { map_png: &map, floor_png: Some(&floor), ..Default::default() }, 0).unwrap();
        let navigable = read_mask(&map, "map").unwrap();
        for boulder in world.boulders() {
            assert!(boulder.cells_under(&navigable, BODY_TOP_M).is_empty(), "boulder at {:?}", boulder.centre);
        }

        let islands = enclosed_cells(&navigable);
        assert_eq!(islands.iter().filter(|&&i| i).count(), 8, "the map has four islands of 1, 1, 2 and 4 cells");
        for cell in (0..islands.len()).filter(|&i| islands[i]) {
            let (x, y) = ((cell % WORLD_SIZE) as f64 + 0.5, (cell / WORLD_SIZE) as f64 + 0.5);
            let covered = world.boulders().iter().any(|b| b.covers(x, y, 0.0, BODY_TOP_M));
            assert!(covered, "a rock stands on the island cell ({x}, {y})");
        }
    }
}
