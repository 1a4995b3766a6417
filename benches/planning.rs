//! The decision node's planning grid from a map message (`Grid::from_occupancy`) and its path
//! costs (`Grid::costs_from`, a Dijkstra over the 200 x 200 map, searched to the end, and only as
//! far as the costs of the map's frontier cells need, as exploring asks for them) on two
//! maps: the one perception and mapping make of the 283 recorded frames (mostly unknown, as early
//! in a mission) and `map_bw.png` fully known (as late in one), from every recorded pose. The
//! baseline, in the same run: a textbook Dijkstra with a binary heap over the same step costs,
//! which also checks the costs found. Then a frontier tour's legs on the recorded frames' map
//! (`Planner::costs_to`, the costs between the anchors of the 16 nearest frontier clusters and
//! from home, over known ground), against a whole search from each anchor as before.
//!
//! Run: `cargo bench --bench planning`.

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use rover::tools::dataset::read_log;
use rover::tools::replay::{read_ground_truth, replay_frames};
use rover_decision::grid::{Cell, CostMap, Costs, Grid, Planner};
use rover_decision::params::DecisionParams;
use rover_decision::route::path_costs;
use rover_decision::tour::cluster_anchors;
use rover_mapping::params::MappingParams;
use rover_msgs::map_grid::{CELLS, SIDE_CELLS, cell_of_point};
use rover_perception::params::PerceptionParams;

/// Times every start is planned from.
const PASSES: usize = 3;

fn median_ms(mut samples: Vec<Duration>) -> f64 {
    samples.sort();
    samples[samples.len() / 2].as_secs_f64() * 1000.0
}

/// Path costs by a textbook Dijkstra (binary heap, lazy deletion), 8-connected with diagonals at
/// SQRT_2 and no corner cutting past cells that cannot be entered; `step` is each cell's entry cost.
fn textbook_costs(step: &[f32], start: usize) -> Vec<f32> {
    let mut distance = vec![f32::INFINITY; CELLS];
    let mut open = BinaryHeap::new();
    distance[start] = 0.0;
    open.push(Reverse((0u32, start)));
    while let Some(Reverse((bits, cell))) = open.pop() {
        let d = f32::from_bits(bits);
        if d > distance[cell] {
            continue;
        }
        let (x, y) = ((cell % SIDE_CELLS) as i64, (cell / SIDE_CELLS) as i64);
        for (dx, dy) in [(1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1), (-1, -1)] {
            let (nx, ny) = (x + dx, y + dy);
            let inside = |x: i64, y: i64| (0..SIDE_CELLS as i64).contains(&x) && (0..SIDE_CELLS as i64).contains(&y);
            if !inside(nx, ny) {
                continue;
            }
            let at = |x: i64, y: i64| (y * SIDE_CELLS as i64 + x) as usize;
            let n = at(nx, ny);
            let diagonal = dx != 0 && dy != 0;
            if diagonal && (step[at(nx, y)].is_infinite() || step[at(x, ny)].is_infinite()) {
                continue;
            }
            let via = d + if diagonal { step[n] * std::f32::consts::SQRT_2 } else { step[n] };
            if via < distance[n] {
                distance[n] = via;
                open.push(Reverse((via.to_bits(), n)));
            }
        }
    }
    distance
}

/// The entry cost of each cell for a plan far from any obstacle (the escape rule aside).
fn step_costs(grid: &Grid, costs: &Costs) -> Vec<f32> {
    (0..CELLS)
        .map(|i| match grid.cell(i) {
            Cell::Blocked => f32::INFINITY,
            Cell::Unknown => 1.0 + costs.unknown,
            Cell::Free if grid.near_wall(i) => 1.0 + costs.near_wall,
            Cell::Free => 1.0,
        })
        .collect()
}

fn main() -> anyhow::Result<()> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let frames = read_log(&root.join("../shared/udacity/test_dataset"))?.frames;
    let (_, map) = replay_frames(&frames, &PerceptionParams::default(), &MappingParams::default(), None, None)?;
    let truth = read_ground_truth(&root.join("../shared/udacity/calibration_images/map_bw.png"))?;
    let known: Vec<i8> = truth.iter().map(|&floor| if floor { 0 } else { 100 }).collect();
    let costs = path_costs(&DecisionParams::default());
    let starts: Vec<usize> = frames.iter().filter_map(|f| cell_of_point(f.state.x_m, f.state.y_m)).collect();
    println!("path costs from {} recorded poses x {PASSES} passes, median per plan", starts.len());
    for (name, data) in [("map of the recorded frames", map.occupancy()), ("map_bw.png, all known", known)] {
        let grid = Grid::from_occupancy(&data).expect("a 200 x 200 map");
        let received: Vec<Duration> = (0..starts.len())
            .map(|_| {
                let started = Instant::now();
                std::hint::black_box(Grid::from_occupancy(&data));
                started.elapsed()
            })
            .collect();
        let step = step_costs(&grid, &costs);
        let frontiers = grid.frontiers(|cell| grid.cell(cell) == Cell::Unknown);
        let (mut ours, mut to_frontiers, mut textbook) = (Vec::new(), Vec::new(), Vec::new());
        for _ in 0..PASSES {
            for &start in &starts {
                let started = Instant::now();
                let found = grid.costs_from(start, &costs);
                std::hint::black_box(frontiers.iter().map(|&cell| found.distance(cell)).sum::<f32>());
                to_frontiers.push(started.elapsed());
                let started = Instant::now();
                let found = grid.costs_from(start, &costs);
                std::hint::black_box(found.reachable_cells());
                ours.push(started.elapsed());
                let started = Instant::now();
                let reference = std::hint::black_box(textbook_costs(&step, start));
                textbook.push(started.elapsed());
                check_costs(&grid, start, &found, &reference);
            }
        }
        let (ours_ms, textbook_ms) = (median_ms(ours), median_ms(textbook));
        println!(
            "{name:<28} from_occupancy {:.3} ms   costs_from {ours_ms:.3} ms   textbook Dijkstra {textbook_ms:.3} ms   ratio {:.2}x",
            median_ms(received),
            textbook_ms / ours_ms
        );
        let frontiers_ms = median_ms(to_frontiers);
        println!(
            "{:<28} to its {} frontier cells {frontiers_ms:.3} ms   ratio to the whole search {:.2}x",
            "",
            frontiers.len(),
            ours_ms / frontiers_ms
        );
    }
    time_tour_legs(&Grid::from_occupancy(&map.occupancy()).expect("a 200 x 200 map"), &starts, &costs);
    Ok(())
}

/// Times the legs of a frontier tour from every start: the anchors of the frontier clusters
/// nearest to it, the costs between them and from home (the first start) over known ground.
fn time_tour_legs(grid: &Grid, starts: &[usize], costs: &Costs) {
    let known = Costs { cross_unknown: false, obstacle: None, ..*costs };
    let frontiers = grid.frontiers(|n| grid.cell(n) == Cell::Unknown);
    let (mut ours, mut whole, mut legs) = (Vec::new(), Vec::new(), 0);
    for &start in starts {
        let anchors = cluster_anchors(frontiers.clone(), &grid.costs_from(start, costs));
        let froms = || anchors.iter().chain(&starts[..1]);
        let started = Instant::now();
        let mut planner = Planner::new(grid, &known);
        let found: Vec<Vec<f32>> = froms().map(|&from| planner.costs_to(from, &anchors)).collect();
        ours.push(started.elapsed());
        let started = Instant::now();
        let reference: Vec<Vec<f32>> = froms()
            .map(|&from| {
                let reach = grid.costs_from(from, &known);
                anchors.iter().map(|&to| reach.distance(to)).collect()
            })
            .collect();
        whole.push(started.elapsed());
        assert_eq!(found, reference, "the legs of the tour from {start}");
        legs += anchors.len() * (anchors.len() + 1);
    }
    let (ours_ms, whole_ms) = (median_ms(ours), median_ms(whole));
    println!(
        "tour legs ({:.0} a tour)          Planner::costs_to {ours_ms:.3} ms   a whole search each {whole_ms:.3} ms   ratio {:.2}x",
        legs as f64 / starts.len() as f64,
        whole_ms / ours_ms
    );
}

/// Panics unless the costs found equal the textbook's away from the start's escape square.
fn check_costs(grid: &Grid, start: usize, found: &CostMap, reference: &[f32]) {
    if grid.cell(start) != Cell::Free || grid.near_wall(start) {
        return;
    }
    for (cell, &b) in reference.iter().enumerate() {
        let a = found.distance(cell);
        assert!(a == b || (a - b).abs() <= 1e-3 * b, "cell {cell} from {start}: {a} against the textbook's {b}");
    }
}
