use super::*;

const COSTS: Costs = Costs { unknown: 2.0, near_wall: 3.0, cross_unknown: true, obstacle: None };

#[test]
fn an_obstacle_hides_what_lies_behind_it() {
    let mut data = vec![0i8; CELLS];
    data[cell_at(12, 10)] = 100;
    data[cell_at(14, 10)] = 100;
    let grid = Grid::from_occupancy(&data).unwrap();
    assert!(grid.line_of_sight((10.5, 10.5), cell_of_point(12.5, 10.5).unwrap(), 0), "the obstacle itself is seen");
    assert!(!grid.line_of_sight((10.5, 10.5), cell_of_point(13.5, 10.5).unwrap(), 0), "behind it is hidden");
    assert!(grid.line_of_sight((10.5, 10.5), cell_of_point(13.5, 12.5).unwrap(), 0), "beside it is not");
    assert!(grid.line_of_sight((10.5, 10.5), cell_of_point(13.5, 10.5).unwrap(), 1), "unless it is let through");
}

#[test]
fn a_blocked_cell_is_planned_around() {
    let mut data = vec![0i8; CELLS];
    data[cell_at(10, 10)] = 100;
    let mut grid = Grid::from_occupancy(&data).unwrap();
    let (start, goal) = (cell_of_point(5.5, 12.5).unwrap(), cell_of_point(15.5, 12.5).unwrap());
    let straight = grid.costs_from(start, &COSTS).path_to(goal).unwrap();
    let blocked = cell_of_point(10.5, 12.5).unwrap();
    assert!(straight.contains(&blocked));
    grid.block(blocked);
    let around = grid.costs_from(start, &COSTS).path_to(goal).unwrap();
    assert!(!around.contains(&blocked) && grid.cell(blocked) == Cell::Blocked, "{around:?}");
}

fn corridor() -> Vec<i8> {
    let mut data = vec![100i8; CELLS];
    for x in 10..60 {
        for y in 10..14 {
            data[cell_at(x, y)] = 0;
        }
    }
    for y in 14..40 {
        for x in 55..60 {
            data[cell_at(x, y)] = -1;
        }
    }
    data
}

#[test]
fn paths_go_around_walls_and_through_unknown_ground() {
    let grid = Grid::from_occupancy(&corridor()).unwrap();
    let start = cell_of_point(11.5, 11.5).unwrap();
    let costs = grid.costs_from(start, &COSTS);
    let goal = cell_of_point(57.5, 30.5).unwrap();
    let path = costs.path_to(goal).unwrap();
    assert_eq!(path[0], start);
    assert_eq!(*path.last().unwrap(), goal);
    assert!(path.iter().all(|&i| grid.cell(i) != Cell::Blocked));
    assert!(costs.path_to(cell_of_point(5.5, 5.5).unwrap()).is_none(), "walls are not crossed");
    let no_unknown = grid.costs_from(start, &Costs { cross_unknown: false, ..COSTS });
    assert!(no_unknown.path_to(goal).is_none());
}

#[test]
fn cells_near_a_wall_are_the_free_and_unknown_cells_beside_an_obstacle() {
    for seed in 0..4 {
        let mut data = random_patch(seed);
        data[cell_at(0, 7)] = 0;
        data[cell_at(SIDE_CELLS - 1, SIDE_CELLS - 1)] = 0;
        let grid = Grid::from_occupancy(&data).unwrap();
        for i in 0..CELLS {
            let beside = grid.cell(i) != Cell::Blocked && neighbours8(i).any(|n| grid.cell(n) == Cell::Blocked);
            assert_eq!(grid.near_wall(i), beside, "seed {seed}, cell {:?}", cell_xy(i));
        }
    }
}

#[test]
fn frontiers_are_free_cells_next_to_unknown_ones() {
    let grid = Grid::from_occupancy(&corridor()).unwrap();
    let frontiers = grid.frontiers(|n| grid.cell(n) == Cell::Unknown);
    assert!(!frontiers.is_empty());
    assert!(frontiers.iter().all(|&i| grid.cell(i) == Cell::Free && cell_centre_m(i).1 < 14.0));
    assert_eq!(Grid::from_occupancy(&[0; 3]).map(|_| ()), None);
    let corner = cell_of_point(0.5, 0.5).unwrap();
    assert_eq!(Grid::cells_around(corner, 2).count(), 9, "clipped at the edge");
    assert_eq!(Grid::cells_around(cell_of_point(50.5, 50.5).unwrap(), 2).count(), 25);
}

/// The entry costs of a plan from `start`: the planner's, with the escape around the start open.
fn steps_from(grid: &Grid, start: usize, costs: &Costs) -> Steps {
    let mut planner = Planner::new(grid, costs);
    planner.open_escape(start);
    planner.steps
}

/// The cost of the step from cell `from` into its neighbour `to`, restated from the rules of
/// [`Grid::costs_from`] with the entry costs `steps` of straight steps: a diagonal step costs
/// SQRT_2 times as much and may not cut the corner of an obstacle that walls the plan off.
fn step_between(grid: &Grid, steps: &Steps, from: usize, to: usize) -> f32 {
    let step = |cell: usize| steps.straight[padded(cell)];
    let ((fx, fy), (tx, ty)) = (cell_xy(from), cell_xy(to));
    if fx == tx || fy == ty {
        return step(to);
    }
    let walls = |c: usize| grid.cell(c) == Cell::Blocked && step(c).is_infinite();
    if walls(cell_at(tx, fy)) || walls(cell_at(fx, ty)) { f32::INFINITY } else { step(to) * std::f32::consts::SQRT_2 }
}

/// Path costs by relaxing every step until nothing changes (Bellman-Ford), for comparison.
fn costs_by_relaxation(grid: &Grid, start: usize, costs: &Costs) -> Vec<f32> {
    let steps = steps_from(grid, start, costs);
    let mut distance = vec![f32::INFINITY; CELLS];
    distance[start] = 0.0;
    let mut changed = true;
    while changed {
        changed = false;
        for from in 0..CELLS {
            for to in neighbours8(from) {
                let via = distance[from] + step_between(grid, &steps, from, to);
                if via < distance[to] {
                    distance[to] = via;
                    changed = true;
                }
            }
        }
    }
    distance
}

/// A 30 x 30 patch of random free, blocked and unknown cells walled in by obstacles.
fn random_patch(seed: u64) -> Vec<i8> {
    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state % 100
    };
    (0..CELLS)
        .map(|i| {
            let (x, y) = cell_xy(i);
            let inside = (20..50).contains(&x) && (20..50).contains(&y);
            match next() {
                _ if !inside => 100,
                r if r < 15 => 100,
                r if r < 30 => -1,
                _ => 0,
            }
        })
        .collect()
}

#[test]
fn path_costs_are_the_least_over_all_paths_and_each_cell_is_reached_from_its_predecessor() {
    let variants = [
        COSTS,
        Costs { cross_unknown: false, ..COSTS },
        Costs { obstacle: Some(30.0), ..COSTS },
        Costs { unknown: 0.0, near_wall: 0.0, ..COSTS },
    ];
    for seed in 0..8 {
        let grid = Grid::from_occupancy(&random_patch(seed)).unwrap();
        let costs = &variants[seed as usize % variants.len()];
        let start = cell_at(25 + seed as usize, 30);
        let found = grid.costs_from(start, costs);
        let least = costs_by_relaxation(&grid, start, costs);
        let steps = steps_from(&grid, start, costs);
        for (cell, &want) in least.iter().enumerate() {
            let got = found.distance(cell);
            assert!(got == want || (got - want).abs() < 1e-3, "seed {seed}, cell {cell}: {got} against {want}");
            let Some(path) = found.path_to(cell) else { continue };
            assert_eq!((path[0], path.last()), (start, Some(&cell)));
            if let [.., before, last] = path[..] {
                let via = found.distance(before) + step_between(&grid, &steps, before, last);
                assert_eq!(via, got, "seed {seed}: cell {cell} is reached from its predecessor {before}");
            }
        }
    }
}

/// The predecessor of each cell as a binary heap finds it: cells expanded in order of cost,
/// then of cell, each predecessor kept unless a later one reaches the cell more cheaply.
fn parents_by_heap(grid: &Grid, start: usize, costs: &Costs) -> Vec<Option<usize>> {
    let steps = steps_from(grid, start, costs);
    let (mut distance, mut parent) = (vec![f32::INFINITY; CELLS], vec![None; CELLS]);
    let mut open = std::collections::BinaryHeap::new();
    distance[start] = 0.0;
    open.push(std::cmp::Reverse(order_key(0.0, start)));
    while let Some(std::cmp::Reverse(key)) = open.pop() {
        let (d, from) = from_order_key(key);
        if d > distance[from] {
            continue;
        }
        for to in neighbours8(from) {
            let via = d + step_between(grid, &steps, from, to);
            if via < distance[to] {
                (distance[to], parent[to]) = (via, Some(from));
                open.push(std::cmp::Reverse(order_key(via, to)));
            }
        }
    }
    parent
}

#[test]
fn of_two_equally_cheap_predecessors_the_one_a_heap_expands_first_is_kept() {
    let free = vec![0; CELLS];
    let plans = [(free, cell_at(100, 100), COSTS), (corridor(), cell_at(11, 11), COSTS)].into_iter();
    let patches = (0..6).map(|seed| (random_patch(seed), cell_at(25 + seed as usize, 30), COSTS));
    for (data, start, costs) in plans.chain(patches) {
        let grid = Grid::from_occupancy(&data).unwrap();
        let found = grid.costs_from(start, &costs);
        for (cell, parent) in parents_by_heap(&grid, start, &costs).into_iter().enumerate() {
            let before = found.path_to(cell).and_then(|path| path.len().checked_sub(2).map(|i| path[i]));
            assert_eq!(before, parent, "cell {cell}");
        }
    }
}

#[test]
fn costs_to_goals_are_those_of_the_whole_search_also_where_unreachable() {
    let (mut reached, mut unreachable) = (0, 0);
    for seed in 0..8 {
        let grid = Grid::from_occupancy(&random_patch(seed)).unwrap();
        let costs = Costs { cross_unknown: seed % 2 == 0, ..COSTS };
        let mut planner = Planner::new(&grid, &costs);
        let start = cell_at(25 + seed as usize, 30);
        let whole = grid.costs_from(start, &costs);
        let patch: Vec<usize> = Grid::cells_around(cell_at(35, 35), 15).collect();
        for &goal in &patch {
            assert_eq!(planner.costs_to(start, &[goal]), [whole.distance(goal)], "seed {seed}, goal {goal}");
        }
        let goals: Vec<usize> = patch.iter().copied().step_by(97).collect();
        let want: Vec<f32> = goals.iter().map(|&goal| whole.distance(goal)).collect();
        assert_eq!(planner.costs_to(start, &goals), want, "seed {seed}");
        reached += want.iter().filter(|d| d.is_finite()).count();
        unreachable += want.iter().filter(|d| d.is_infinite()).count();
    }
    assert!(reached > 0 && unreachable > 0, "{reached} goals reached, {unreachable} not");
}

#[test]
fn a_cost_map_gives_the_whole_search_in_any_order_and_searches_only_as_far_as_asked() {
    for seed in 0..6 {
        let grid = Grid::from_occupancy(&random_patch(seed)).unwrap();
        let costs = Costs { cross_unknown: seed % 2 == 0, ..COSTS };
        let start = cell_at(25 + seed as usize, 30);
        let whole = grid.costs_from(start, &costs);
        let reachable = whole.reachable_cells();
        let lazy = grid.costs_from(start, &costs);
        let near = cell_at(26 + seed as usize, 31);
        let near_cost = lazy.distance(near);
        let searched_for_near = lazy.lazy().search.next_bucket;
        let searched_for_all = whole.lazy().search.next_bucket;
        assert!(searched_for_near < searched_for_all, "seed {seed}: the near cell searched everything");
        for cell in (0..CELLS).rev() {
            let (from_whole, from_lazy) = (whole.distance(cell), lazy.distance(cell));
            assert_eq!(from_whole.to_bits(), from_lazy.to_bits(), "seed {seed}, cell {cell}");
            assert_eq!(whole.path_to(cell), lazy.path_to(cell), "seed {seed}, cell {cell}");
        }
        assert_eq!(near_cost.to_bits(), whole.distance(near).to_bits());
        assert_eq!(lazy.reachable_cells(), reachable);
    }
}
