//! Seeded procedural worlds: connected canyons carved by wandering walkers, scattered boulders,
//! and six samples lying next to walls, so that the default demo needs no data files. As in the
//! Unity world, a low drivable bank lines the walls outside the navigable map.

use std::collections::VecDeque;

use crate::random::SplitMix64;
use crate::world::{SAMPLE_COUNT, Sample, StartPose, WORLD_SIZE, World, terrain_for_map, widen_floor};

/// Fewest navigable cells a procedural world has.
pub const MIN_NAVIGABLE_CELLS: usize = 1500;
/// Keep canyons this far from the edge of the world, cells.
const BORDER: f64 = 12.0;
/// Samples are at least this far from each other and from the start, metres.
const SAMPLE_SPACING_M: f64 = 14.0;

/// The world for `seed`: the same seed always gives the same world.
pub fn procedural_world(seed: u64) -> World {
    let mut rng = SplitMix64::new(seed);
    let target = rng.range(1900.0, 2600.0) as usize;
    let centre = WORLD_SIZE as f64 / 2.0;
    let mut map = vec![false; WORLD_SIZE * WORLD_SIZE];
    carve_disc(&mut map, centre, centre, 4.0);
    carve_canyons(&mut map, &mut rng, target);
    place_boulders(&mut map, &mut rng, (centre, centre));
    let heights = terrain_for_map(&map, &mut rng);
    let samples = place_samples(&widen_floor(&map), &mut rng, (centre, centre));
    let start = StartPose { x_m: centre + 0.5, y_m: centre + 0.5, yaw_deg: rng.range(0.0, 360.0) };
    World::with_ground_truth(heights, map, samples, start)
}

struct Walker {
    x: f64,
    y: f64,
    heading: f64,
    half_width: f64,
}

fn carve_canyons(floor: &mut [bool], rng: &mut SplitMix64, target: usize) {
    let centre = WORLD_SIZE as f64 / 2.0;
    let mut walkers =
        vec![Walker { x: centre, y: centre, heading: rng.range(0.0, std::f64::consts::TAU), half_width: 2.0 }];
    let mut carved = floor.iter().filter(|&&f| f).count();
    let mut steps = 0;
    while carved < target && steps < 200_000 {
        steps += 1;
        let index = rng.below(walkers.len());
        let walker = &mut walkers[index];
        walker.heading += rng.range(-0.25, 0.25);
        steer_away_from_border(walker);
        walker.x += walker.heading.cos();
        walker.y += walker.heading.sin();
        walker.half_width = (walker.half_width + rng.range(-0.3, 0.3)).clamp(2.0, 5.0);
        let radius = if rng.unit() < 0.02 { rng.range(5.0, 9.0) } else { walker.half_width };
        let (x, y, heading) = (walker.x, walker.y, walker.heading);
        carve_disc(floor, x, y, radius);
        if rng.unit() < 0.015 && walkers.len() < 12 {
            let turn = if rng.unit() < 0.5 { 1.0 } else { -1.0 } * rng.range(1.0, 1.8);
            walkers.push(Walker { x, y, heading: heading + turn, half_width: rng.range(2.0, 3.5) });
        }
        carved = floor.iter().filter(|&&f| f).count();
    }
}

fn steer_away_from_border(walker: &mut Walker) {
    let limit = WORLD_SIZE as f64 - BORDER;
    let centre = WORLD_SIZE as f64 / 2.0;
    if walker.x < BORDER || walker.x > limit || walker.y < BORDER || walker.y > limit {
        walker.heading = (centre - walker.y).atan2(centre - walker.x);
        walker.x = walker.x.clamp(BORDER, limit);
        walker.y = walker.y.clamp(BORDER, limit);
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

fn neighbours(index: usize) -> impl Iterator<Item = usize> {
    let (x, y) = ((index % WORLD_SIZE) as i64, (index / WORLD_SIZE) as i64);
    [(1, 0), (-1, 0), (0, 1), (0, -1)]
        .into_iter()
        .map(move |(dx, dy)| (x + dx, y + dy))
        .filter(|&(nx, ny)| inside(nx, ny))
        .map(|(nx, ny)| ny as usize * WORLD_SIZE + nx as usize)
}

/// The floor cells reachable from `from`.
fn reached(floor: &[bool], from: usize) -> Vec<bool> {
    let mut seen = vec![false; floor.len()];
    let mut queue = VecDeque::from([from]);
    seen[from] = true;
    while let Some(cell) = queue.pop_front() {
        for next in neighbours(cell) {
            if floor[next] && !seen[next] {
                seen[next] = true;
                queue.push_back(next);
            }
        }
    }
    seen
}

/// Number of floor cells reachable from `from`.
fn reachable(floor: &[bool], from: usize) -> usize {
    reached(floor, from).iter().filter(|&&r| r).count()
}

/// Boulders of one to four cells in open floor, never cutting the floor apart.
fn place_boulders(floor: &mut [bool], rng: &mut SplitMix64, start: (f64, f64)) {
    let start_cell = start.1 as usize * WORLD_SIZE + start.0 as usize;
    let wanted = 8 + rng.below(10);
    let mut placed = 0;
    for _ in 0..2000 {
        if placed == wanted {
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
        let before = reachable(floor, start_cell);
        cells.iter().for_each(|&c| floor[c] = false);
        if reachable(floor, start_cell) == before - cells.len() {
            placed += 1;
        } else {
            cells.iter().for_each(|&c| floor[c] = true);
        }
    }
}

/// Six samples on floor cells that touch a wall, spread over the world.
fn place_samples(floor: &[bool], rng: &mut SplitMix64, start: (f64, f64)) -> Vec<Sample> {
    let mut candidates: Vec<(usize, (f64, f64))> = Vec::new();
    for (index, &is_floor) in floor.iter().enumerate() {
        if !is_floor {
            continue;
        }
        let wall = neighbours(index).find(|&n| !floor[n]);
        if let Some(wall) = wall {
            let (x, y) = ((index % WORLD_SIZE) as f64 + 0.5, (index / WORLD_SIZE) as f64 + 0.5);
            let (wx, wy) = ((wall % WORLD_SIZE) as f64 + 0.5, (wall / WORLD_SIZE) as f64 + 0.5);
            candidates.push((index, (x + (wx - x) * 0.25, y + (wy - y) * 0.25)));
        }
    }
    let mut samples: Vec<Sample> = Vec::new();
    let mut spacing = SAMPLE_SPACING_M;
    while samples.len() < SAMPLE_COUNT && spacing > 1.0 {
        for _ in 0..5000 {
            if samples.len() == SAMPLE_COUNT || candidates.is_empty() {
                break;
            }
            let (_, (x, y)) = candidates[rng.below(candidates.len())];
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

    #[test]
    fn procedural_worlds_are_connected_large_and_deterministic() {
        for seed in 0..8 {
            let world = procedural_world(seed);
            let map = world.ground_truth();
            let navigable = map.iter().filter(|&&f| f).count();
            assert!(navigable >= MIN_NAVIGABLE_CELLS, "seed {seed}: {navigable} navigable cells");
            let start = world.start.y_m as usize * WORLD_SIZE + world.start.x_m as usize;
            let floor: Vec<bool> =
                (0..map.len()).map(|i| world.is_floor((i % WORLD_SIZE) as i64, (i / WORLD_SIZE) as i64)).collect();
            let reached = reached(&floor, start);
            assert!((0..map.len()).all(|i| !map[i] || reached[i]), "seed {seed}: every navigable cell is reachable");
            assert!(reachable(&floor, start) > navigable + 200, "seed {seed}: the floor is wider than the map");
            assert_eq!(world.samples.len(), 6, "seed {seed}");
            for sample in &world.samples {
                assert!(world.is_floor(sample.x_m as i64, sample.y_m as i64), "seed {seed}: sample on the floor");
                assert!(world.wall_distance(sample.x_m, sample.y_m) < 1.0, "seed {seed}: sample next to a wall");
            }
            let boulders = (0..map.len()).filter(|&i| !floor[i] && neighbours(i).all(|n| floor[n])).count();
            assert!(boulders > 0, "seed {seed}: some free-standing boulders");
        }
        assert_eq!(procedural_world(5).ground_truth(), procedural_world(5).ground_truth());
        assert_eq!(procedural_world(5).samples, procedural_world(5).samples);
        assert_ne!(procedural_world(5).ground_truth(), procedural_world(6).ground_truth());
    }
}
