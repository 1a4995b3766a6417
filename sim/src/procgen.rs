//! Seeded procedural worlds: connected canyons carved by wandering walkers, boulders on the floor
//! and against the walls, and six samples lying next to walls, so that the default demo needs no
//! data files. As in the Unity world, the flat floor reaches a little beyond the navigable map
//! into the foot of the walls, and the map counts no ground a boulder stands on or overhangs.

use crate::boulder::{Boulder, BoulderKind, BoulderSpec, Cap};
use crate::obstacle::Obstacle;
use crate::random::SplitMix64;
use crate::world::{
    Ground, SAMPLE_COUNT, Sample, StartPose, WORLD_SIZE, World, WorldPlan, neighbours4, reached_from, widen_floor,
};

/// Keep canyons this far from the edge of the world, cells.
const BORDER_CELLS: f64 = 12.0;
/// Samples are at least this far from each other and from the start, metres.
const SAMPLE_SPACING_M: f64 = 14.0;
/// Samples keep this far from the rim of any boulder, metres.
const SAMPLE_BOULDER_CLEARANCE_M: f64 = 1.5;
/// Boulders against the walls: how many at most, and the range of their footprint radius, metres.
const WALL_BOULDERS: usize = 8;
const WALL_BOULDER_RADIUS_M: (f64, f64) = (1.2, 2.6);
/// A wall boulder may take at most this many navigable cells from the map.
const WALL_BOULDER_MAX_CELLS: usize = 3;
/// Ground under a boulder up to this height counts as the boulder's for the map, metres (an
/// overhang's rim included, as `map_bw.png` counts the floor under Unity's overhanging boulder).
const OVERHANG_COUNTED_M: f64 = 3.0;

/// The world for `seed`: the same seed always gives the same world.
pub fn procedural_world(seed: u64) -> World {
    let mut rng = SplitMix64::new(seed);
    let target = rng.range(1900.0, 2600.0) as usize;
    let centre = WORLD_SIZE as f64 / 2.0;
    let mut map = vec![false; WORLD_SIZE * WORLD_SIZE];
    carve_disc(&mut map, centre, centre, 4.0);
    carve_canyons(&mut map, &mut rng, target);
    let islands = place_islands(&mut map, &mut rng, (centre, centre));
    let mut floor = widen_floor(&map);
    let mut boulders = Vec::new();
    for cells in &islands {
        cells.iter().for_each(|&c| floor[c] = true);
        boulders.push(island_boulder(cells, &mut rng));
    }
    place_wall_boulders(&mut map, &mut boulders, &mut rng, (centre, centre));
    let samples = place_samples(&floor, &boulders, &mut rng, (centre, centre));
    let start = StartPose { x_m: centre + 0.5, y_m: centre + 0.5, yaw_deg: rng.range(0.0, 360.0) };
    let ground = Ground::Generated { salt: rng.next_u64() };
    World::build(WorldPlan { floor, ground_truth: map, boulders, surveyed_rocks: Vec::new(), samples, start, ground })
}

/// A canyon's carving head: where it is, metres, where it goes, and how wide it carves.
struct Walker {
    x_m: f64,
    y_m: f64,
    heading_rad: f64,
    half_width_m: f64,
}

fn carve_canyons(floor: &mut [bool], rng: &mut SplitMix64, target: usize) {
    let centre = WORLD_SIZE as f64 / 2.0;
    let mut walkers = vec![Walker {
        x_m: centre,
        y_m: centre,
        heading_rad: rng.range(0.0, std::f64::consts::TAU),
        half_width_m: 2.0,
    }];
    let mut carved = floor.iter().filter(|&&f| f).count();
    let mut steps = 0;
    while carved < target && steps < 200_000 {
        steps += 1;
        let index = rng.below(walkers.len());
        let walker = &mut walkers[index];
        walker.heading_rad += rng.range(-0.25, 0.25);
        steer_away_from_border(walker);
        walker.x_m += walker.heading_rad.cos();
        walker.y_m += walker.heading_rad.sin();
        walker.half_width_m = (walker.half_width_m + rng.range(-0.3, 0.3)).clamp(2.0, 5.0);
        let radius = if rng.unit() < 0.02 { rng.range(5.0, 9.0) } else { walker.half_width_m };
        let (x, y, heading) = (walker.x_m, walker.y_m, walker.heading_rad);
        carve_disc(floor, x, y, radius);
        if rng.unit() < 0.015 && walkers.len() < 12 {
            let turn = if rng.unit() < 0.5 { 1.0 } else { -1.0 } * rng.range(1.0, 1.8);
            walkers.push(Walker { x_m: x, y_m: y, heading_rad: heading + turn, half_width_m: rng.range(2.0, 3.5) });
        }
        carved = floor.iter().filter(|&&f| f).count();
    }
}

fn steer_away_from_border(walker: &mut Walker) {
    let limit = WORLD_SIZE as f64 - BORDER_CELLS;
    let centre = WORLD_SIZE as f64 / 2.0;
    if walker.x_m < BORDER_CELLS || walker.x_m > limit || walker.y_m < BORDER_CELLS || walker.y_m > limit {
        walker.heading_rad = (centre - walker.y_m).atan2(centre - walker.x_m);
        walker.x_m = walker.x_m.clamp(BORDER_CELLS, limit);
        walker.y_m = walker.y_m.clamp(BORDER_CELLS, limit);
    }
}

fn carve_disc(floor: &mut [bool], x: f64, y: f64, radius: f64) {
    let reach = radius.ceil() as i64;
    let (cx, cy) = (x.floor() as i64, y.floor() as i64);
    for iy in cy - reach..=cy + reach {
        for ix in cx - reach..=cx + reach {
            let (dx, dy) = (ix as f64 + 0.5 - x, iy as f64 + 0.5 - y);
            if dx * dx + dy * dy <= radius * radius && inside(ix, iy) {
                floor[iy as usize * WORLD_SIZE + ix as usize] = true;
            }
        }
    }
}

fn inside(ix: i64, iy: i64) -> bool {
    ix >= 1 && iy >= 1 && ix < WORLD_SIZE as i64 - 1 && iy < WORLD_SIZE as i64 - 1
}

/// Number of floor cells reachable from `from`.
fn reachable(floor: &[bool], from: usize) -> usize {
    reached_from(floor, from).iter().filter(|&&r| r).count()
}

/// Islands of one to four cells in open floor where boulders will stand, never cutting the floor
/// apart; returns the cells of each.
fn place_islands(floor: &mut [bool], rng: &mut SplitMix64, start: (f64, f64)) -> Vec<Vec<usize>> {
    let start_cell = start.1 as usize * WORLD_SIZE + start.0 as usize;
    let wanted = 8 + rng.below(10);
    let mut islands = Vec::new();
    for _ in 0..2000 {
        if islands.len() == wanted {
            break;
        }
        let (x, y) = (rng.below(WORLD_SIZE) as i64, rng.below(WORLD_SIZE) as i64);
        let far_from_start = ((x as f64 - start.0).powi(2) + (y as f64 - start.1).powi(2)).sqrt() > 8.0;
        let open = (-2..=2).all(|dy| {
            (-2..=2).all(|dx| inside(x + dx, y + dy) && floor[((y + dy) as usize) * WORLD_SIZE + (x + dx) as usize])
        });
        if !far_from_start || !open {
            continue;
        }
        let (w, h) = (1 + rng.below(2) as i64, 1 + rng.below(2) as i64);
        let cells: Vec<usize> =
            (0..h).flat_map(|dy| (0..w).map(move |dx| ((y + dy) as usize) * WORLD_SIZE + (x + dx) as usize)).collect();
        if remove_keeping_connected(floor, &cells, start_cell) {
            islands.push(cells);
        }
    }
    islands
}

/// Removes `cells` from `floor` unless that cuts some of it off from `start_cell`; true if removed.
fn remove_keeping_connected(floor: &mut [bool], cells: &[usize], start_cell: usize) -> bool {
    let before = reachable(floor, start_cell);
    let removed: Vec<usize> = cells.iter().copied().filter(|&c| floor[c]).collect();
    removed.iter().for_each(|&c| floor[c] = false);
    if reachable(floor, start_cell) == before - removed.len() {
        return true;
    }
    removed.iter().for_each(|&c| floor[c] = true);
    false
}

/// The centre of a group of cells, metres.
fn cells_centre(cells: &[usize]) -> (f64, f64) {
    let n = cells.len() as f64;
    let sum = cells
        .iter()
        .fold((0.0, 0.0), |(x, y), &c| (x + (c % WORLD_SIZE) as f64 + 0.5, y + (c / WORLD_SIZE) as f64 + 0.5));
    (sum.0 / n, sum.1 / n)
}

/// A boulder standing on an island: a lump or a small cluster as wide as the island.
fn island_boulder(cells: &[usize], rng: &mut SplitMix64) -> Boulder {
    let (x_m, y_m) = cells_centre(cells);
    let footprint_radius_m = if cells.len() > 1 { 1.0 } else { 0.65 } * rng.range(0.9, 1.1);
    let kind = if rng.unit() < 0.5 { BoulderKind::Lump } else { BoulderKind::Cluster };
    Boulder::new(&BoulderSpec { x_m, y_m, footprint_radius_m, kind }, rng)
}

/// Boulders half sunk into the walls, some overhanging the floor; the map loses the few cells each
/// stands on or overhangs, as long as the rest stays connected.
fn place_wall_boulders(map: &mut [bool], boulders: &mut Vec<Boulder>, rng: &mut SplitMix64, start: (f64, f64)) {
    let start_cell = start.1 as usize * WORLD_SIZE + start.0 as usize;
    let edges: Vec<(usize, usize)> = (0..map.len())
        .filter(|&c| map[c])
        .filter_map(|c| neighbours4(c).find(|&n| !map[n]).map(|wall| (c, wall)))
        .collect();
    let mut placed = 0;
    for _ in 0..200 {
        if placed == WALL_BOULDERS || edges.is_empty() {
            break;
        }
        let (cell, wall) = edges[rng.below(edges.len())];
        let (x, y) = cells_centre(&[cell]);
        let (wx, wy) = cells_centre(&[wall]);
        let radius = rng.range(WALL_BOULDER_RADIUS_M.0, WALL_BOULDER_RADIUS_M.1);
        let (x_m, y_m) = (x + (wx - x) * (radius + 0.5), y + (wy - y) * (radius + 0.5));
        let far_from_start = (x_m - start.0).hypot(y_m - start.1) > 10.0;
        let apart = boulders.iter().all(|b| (b.centre[0] - x_m).hypot(b.centre[1] - y_m) > b.reach_m() + radius + 3.0);
        if !far_from_start || !apart {
            continue;
        }
        let kind = match rng.below(10) {
            0..=2 => {
                let reach = rng.range(0.6, 1.2) * radius;
                let offset_m = [(x - wx) * reach, (y - wy) * reach];
                let underside_m = rng.range(1.4, 2.6);
                let thickness_m = rng.range(1.5, 3.0);
                BoulderKind::Overhang(Cap {
                    offset_m,
                    radius_m: radius * rng.range(1.3, 1.7),
                    underside_m,
                    thickness_m,
                })
            }
            3..=5 => BoulderKind::Cluster,
            _ => BoulderKind::Lump,
        };
        let boulder = Boulder::new(&BoulderSpec { x_m, y_m, footprint_radius_m: radius, kind }, rng);
        let taken = boulder.cells_under(map, OVERHANG_COUNTED_M);
        if taken.len() <= WALL_BOULDER_MAX_CELLS && remove_keeping_connected(map, &taken, start_cell) {
            boulders.push(boulder);
            placed += 1;
        }
    }
}

/// Six samples at the centres of floor cells that touch a wall, clear of boulders, spread over the
/// world.
fn place_samples(floor: &[bool], boulders: &[Boulder], rng: &mut SplitMix64, start: (f64, f64)) -> Vec<Sample> {
    let clear_of_boulders = |(x, y): (f64, f64)| {
        boulders.iter().all(|b| (b.centre[0] - x).hypot(b.centre[1] - y) > b.reach_m() + SAMPLE_BOULDER_CLEARANCE_M)
    };
    let candidates: Vec<(f64, f64)> = (0..floor.len())
        .filter(|&c| floor[c] && neighbours4(c).any(|n| !floor[n]))
        .map(|c| cells_centre(&[c]))
        .filter(|&place| clear_of_boulders(place))
        .collect();
    let mut samples: Vec<Sample> = Vec::new();
    let mut spacing = SAMPLE_SPACING_M;
    while samples.len() < SAMPLE_COUNT && spacing > 1.0 {
        for _ in 0..5000 {
            if samples.len() == SAMPLE_COUNT || candidates.is_empty() {
                break;
            }
            let (x, y) = candidates[rng.below(candidates.len())];
            let clear = |px: f64, py: f64| ((x - px).powi(2) + (y - py).powi(2)).sqrt() >= spacing;
            if clear(start.0, start.1) && samples.iter().all(|s| clear(s.x_m, s.y_m)) {
                samples.push(Sample { x_m: x, y_m: y, radius_m: rng.range(0.07, 0.10) });
            }
        }
        spacing *= 0.7;
    }
    samples
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Fewest navigable cells the test accepts of a procedural world (the canyons are carved to
    /// 1,900-2,600 cells; islands and wall boulders take some back).
    const MIN_NAVIGABLE_CELLS: usize = 1500;

    #[test]
    fn procedural_worlds_are_connected_large_and_deterministic() {
        for seed in 0..8 {
            let world = procedural_world(seed);
            let map = world.ground_truth();
            let navigable = map.iter().filter(|&&f| f).count();
            assert!(navigable >= MIN_NAVIGABLE_CELLS, "seed {seed}: {navigable} navigable cells");
            let start = world.start.y_m as usize * WORLD_SIZE + world.start.x_m as usize;
            let drivable: Vec<bool> = (0..map.len())
                .map(|i| world.is_drivable((i % WORLD_SIZE) as f64 + 0.5, (i / WORLD_SIZE) as f64 + 0.5))
                .collect();
            let reached = reached_from(&drivable, start);
            let stranded = (0..map.len()).filter(|&i| map[i] && !reached[i]).count();
            assert!(stranded * 100 < navigable, "seed {seed}: {stranded} navigable cells cannot be reached");
            assert!(reachable(&drivable, start) > navigable + 200, "seed {seed}: the floor is wider than the map");
            assert_eq!(world.samples.len(), 6, "seed {seed}");
            for sample in &world.samples {
                assert!(world.is_drivable(sample.x_m, sample.y_m), "seed {seed}: sample on drivable ground");
                let cell = sample.y_m as usize * WORLD_SIZE + sample.x_m as usize;
                assert!(reached[cell], "seed {seed}: sample at ({}, {}) is reachable", sample.x_m, sample.y_m);
                let edge = world.terrain().edge_distance_at(sample.x_m, sample.y_m);
                assert!(edge > -1.0, "seed {seed}: sample next to a wall ({edge} m from its foot)");
            }
            let boulders = world.boulders();
            assert!(boulders.len() >= 8, "seed {seed}: {} boulders", boulders.len());
            let free_standing = boulders.iter().filter(|b| {
                let (x, y) = (b.centre[0].floor() as usize, b.centre[1].floor() as usize);
                map[y * WORLD_SIZE + x + 2]
                    && map[y * WORLD_SIZE + x - 2]
                    && map[(y + 2) * WORLD_SIZE + x]
                    && map[(y - 2) * WORLD_SIZE + x]
            });
            assert!(free_standing.count() > 0, "seed {seed}: some boulders stand free on the floor");
            for boulder in boulders {
                assert!(!world.is_drivable(boulder.centre[0], boulder.centre[1]), "seed {seed}: boulders are solid");
            }
        }
        assert_eq!(procedural_world(5).ground_truth(), procedural_world(5).ground_truth());
        assert_eq!(procedural_world(5).samples, procedural_world(5).samples);
        assert_ne!(procedural_world(5).ground_truth(), procedural_world(6).ground_truth());
    }
}
