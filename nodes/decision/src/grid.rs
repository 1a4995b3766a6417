//! Planning on the 200 x 200 occupancy grid: path costs from the rover to every cell (Dijkstra with
//! wall clearance and a premium for unknown ground), frontiers, and paths.

use std::sync::Mutex;

use rover_msgs::map_grid::{
    CELLS, OCCUPANCY_UNKNOWN, SIDE_CELLS, cell_at, cell_centre_m, cell_of_point, cell_xy, checked_cell_at,
};

/// What a cell of the occupancy grid says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Cell {
    /// Mapped navigable (0).
    Free = 0,
    /// Mapped obstacle (100, or anything above 50).
    Blocked = 1,
    /// Not mapped yet (-1).
    Unknown = 2,
}

/// The kinds of cell, each at the index of its discriminant.
const CELL_KINDS: [Cell; 3] = [Cell::Free, Cell::Blocked, Cell::Unknown];

/// Costs of moving through cells. The extra costs are never negative: planning relies on every
/// step costing at least as much as a free cell's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Costs {
    /// Extra cost of an unknown cell (1 is a free cell).
    pub unknown: f32,
    /// Extra cost of a free cell next to an obstacle.
    pub near_wall: f32,
    /// Whether unknown cells may be crossed at all.
    pub cross_unknown: bool,
    /// Extra cost of crossing an obstacle cell beyond the escape radius; `None`: they block.
    pub obstacle: Option<f32>,
}

/// The occupancy grid with planning helpers.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    cells: Vec<Cell>,
    near_wall: Vec<bool>,
}

impl Grid {
    /// A grid from `nav_msgs/OccupancyGrid` data (row = y).
    pub fn from_occupancy(data: &[i8]) -> Option<Self> {
        if data.len() != CELLS {
            return None;
        }
        let cells: Vec<Cell> = data
            .iter()
            .map(|&v| match v {
                OCCUPANCY_UNKNOWN => Cell::Unknown,
                v if v > 50 => Cell::Blocked,
                _ => Cell::Free,
            })
            .collect();
        let near_wall = near_walls(&cells);
        Some(Grid { cells, near_wall })
    }

    /// Marks cell `i` as an obstacle (the rover got stuck there although the map says free).
    pub fn block(&mut self, i: usize) {
        self.cells[i] = Cell::Blocked;
        self.near_wall[i] = false;
        for n in neighbours8(i) {
            self.near_wall[n] = self.cells[n] != Cell::Blocked;
        }
    }

    /// An empty (all unknown) grid.
    pub fn unknown() -> Self {
        Grid { cells: vec![Cell::Unknown; CELLS], near_wall: vec![false; CELLS] }
    }

    /// The cell at index `i`.
    pub fn cell(&self, i: usize) -> Cell {
        self.cells[i]
    }

    /// Whether cell `i` is not an obstacle but one of its eight neighbours is.
    pub fn near_wall(&self, i: usize) -> bool {
        self.near_wall[i]
    }

    /// Path costs from `start` to every cell and each cell's predecessor: [`Planner::costs_from`].
    pub fn costs_from(&self, start: usize, costs: &Costs) -> CostMap {
        Planner::new(self, costs).costs_from(start)
    }

    /// Frontier cells: free cells with a 4-neighbour that is still `unexplored`.
    pub fn frontiers(&self, unexplored: impl Fn(usize) -> bool) -> Vec<usize> {
        (0..CELLS).filter(|&i| self.cells[i] == Cell::Free && neighbours4(i).any(&unexplored)).collect()
    }

    /// Whether cell `to` can be seen from point `from` (metres): no obstacle cell farther than
    /// `around_cells` from `to` lies on the straight line between them (unknown cells may be
    /// floor and do not block the view).
    pub fn line_of_sight(&self, from: (f64, f64), to: usize, around_cells: usize) -> bool {
        cells_on_line(from, to).all(|cell| {
            cell.is_none_or(|cell| chebyshev(cell, to) <= around_cells || self.cells[cell] != Cell::Blocked)
        })
    }

    /// Whether the straight line from point `from` (metres) to cell `to` crosses only cells that
    /// are neither obstacles nor next to one (the cell of `from` aside).
    pub fn clear_line(&self, from: (f64, f64), to: usize) -> bool {
        let start = cell_of_point(from.0, from.1);
        cells_on_line(from, to).all(|cell| {
            cell.is_some_and(|cell| Some(cell) == start || (self.cells[cell] != Cell::Blocked && !self.near_wall[cell]))
        })
    }

    /// Cells within `radius` cells of cell `i` (a square neighbourhood, clipped at the edges).
    pub fn cells_around(i: usize, radius: usize) -> impl Iterator<Item = usize> {
        let (x, y) = cell_xy(i);
        let rows = y.saturating_sub(radius)..(y + radius + 1).min(SIDE_CELLS);
        rows.flat_map(move |row| {
            (x.saturating_sub(radius)..(x + radius + 1).min(SIDE_CELLS)).map(move |col| cell_at(col, row))
        })
    }

    /// Counts of free, blocked and unknown cells.
    pub fn counts(&self) -> (usize, usize, usize) {
        let count = |c: Cell| self.cells.iter().filter(|&&x| x == c).count();
        (count(Cell::Free), count(Cell::Blocked), count(Cell::Unknown))
    }
}

/// Whether each cell is not an obstacle but one of its eight neighbours is: for each row, the
/// obstacles of the rows above, at and below it column by column, then of the columns beside
/// each cell (rows and columns off the map count as the edge ones, which changes nothing).
fn near_walls(cells: &[Cell]) -> Vec<bool> {
    let blocked: Vec<u8> = cells.iter().map(|&c| u8::from(c == Cell::Blocked)).collect();
    let row = |y: usize| &blocked[cell_at(0, y)..][..SIDE_CELLS];
    let mut near = vec![false; CELLS];
    let mut in_rows = [0u8; SIDE_CELLS + 2];
    for y in 0..SIDE_CELLS {
        let (above, here, below) = (row(y.saturating_sub(1)), row(y), row((y + 1).min(SIDE_CELLS - 1)));
        for (x, any) in in_rows[1..=SIDE_CELLS].iter_mut().enumerate() {
            *any = above[x] | here[x] | below[x];
        }
        (in_rows[0], in_rows[SIDE_CELLS + 1]) = (in_rows[1], in_rows[SIDE_CELLS]);
        for (x, near) in near[cell_at(0, y)..][..SIDE_CELLS].iter_mut().enumerate() {
            *near = here[x] == 0 && (in_rows[x] | in_rows[x + 1] | in_rows[x + 2]) != 0;
        }
    }
    near
}

/// Step along a line of sight, metres.
const SIGHT_STEP_M: f64 = 0.25;
/// Obstacle cells up to this far from the start of a plan can be crossed, cells.
const ESCAPE_RADIUS_CELLS: usize = 1;

/// Chebyshev distance between two cells, cells.
fn chebyshev(a: usize, b: usize) -> usize {
    let ((ax, ay), (bx, by)) = (cell_xy(a), cell_xy(b));
    ax.abs_diff(bx).max(ay.abs_diff(by))
}

/// The predecessor of a cell that has none (the start, and cells not reached).
const NO_PARENT: u32 = u32::MAX;

/// The key of cell `i` at path cost `d` among the open cells: ordered by cost, then by cell (a cost is never
/// negative or NaN, and the bits of such an `f32` order as the numbers do).
fn order_key(d: f32, i: usize) -> u64 {
    (u64::from(d.to_bits()) << 32) | i as u64
}

/// The path cost and cell of an open cell's key.
fn from_order_key(key: u64) -> (f32, usize) {
    (f32::from_bits((key >> 32) as u32), (key & u64::from(u32::MAX)) as usize)
}

/// Side of the padded grid of a search: the map with a border of cells that cannot be entered,
/// so that every cell of the map has eight neighbours at fixed offsets.
const PADDED_SIDE: usize = SIDE_CELLS + 2;
/// Cells of the padded grid.
const PADDED_CELLS: usize = PADDED_SIDE * PADDED_SIDE;

/// The padded index of map cell `i`. Padded indices are row-major too, so they order cells as
/// map indices do.
fn padded(i: usize) -> usize {
    let (x, y) = cell_xy(i);
    padded_at(x, y)
}

/// The padded index of the map cell at column `x`, row `y`.
const fn padded_at(x: usize, y: usize) -> usize {
    (y + 1) * PADDED_SIDE + x + 1
}

/// The map cell of padded index `p` (inside the border).
fn unpadded(p: usize) -> usize {
    cell_at(p % PADDED_SIDE - 1, p / PADDED_SIDE - 1)
}

/// The entry costs of a plan on the padded grid: straight and diagonal (SQRT_2 times as much)
/// steps into each cell, infinite where it cannot be entered; which of those wall off the
/// corners of diagonal steps past them (obstacles, not unknown ground); the dearest finite step
/// a plan may take.
struct Steps {
    straight: Vec<f32>,
    diagonal: Vec<f32>,
    walls: Vec<bool>,
    max: f32,
}

impl Steps {
    /// The steps of `grid` with `costs`, where obstacle cells cost `obstacle` and those around a
    /// start `escape`.
    fn new(grid: &Grid, costs: &Costs, (obstacle, escape): (f32, f32)) -> Self {
        let unknown = if costs.cross_unknown { 1.0 + costs.unknown } else { f32::INFINITY };
        let step_into = |cell: Cell, near_wall: bool| match cell {
            Cell::Blocked => obstacle,
            Cell::Unknown => unknown,
            Cell::Free if near_wall => 1.0 + costs.near_wall,
            Cell::Free => 1.0,
        };
        let by_kind = CELL_KINDS.map(|cell| [step_into(cell, false), step_into(cell, true)]);
        let walls_off = obstacle == f32::INFINITY;
        let mut steps = Steps {
            straight: vec![f32::INFINITY; PADDED_CELLS],
            diagonal: vec![f32::INFINITY; PADDED_CELLS],
            walls: vec![false; PADDED_CELLS],
            max: if obstacle.is_finite() { obstacle } else { escape },
        };
        for (y, cells) in grid.cells.chunks_exact(SIDE_CELLS).enumerate() {
            let near_wall = &grid.near_wall[cell_at(0, y)..][..SIDE_CELLS];
            let row = padded_at(0, y)..padded_at(0, y) + SIDE_CELLS;
            for ((step, &cell), &near_wall) in steps.straight[row.clone()].iter_mut().zip(cells).zip(near_wall) {
                *step = by_kind[cell as usize][usize::from(near_wall)];
            }
            for (walls, &cell) in steps.walls[row].iter_mut().zip(cells) {
                *walls = walls_off && cell == Cell::Blocked;
            }
        }
        for (diagonal, &straight) in steps.diagonal.iter_mut().zip(&steps.straight) {
            *diagonal = straight * std::f32::consts::SQRT_2;
        }
        steps
    }

    /// Sets the straight step into padded cell `p` and whether the cell `walls` off corners.
    fn set(&mut self, p: usize, straight: f32, walls: bool) {
        self.straight[p] = straight;
        self.diagonal[p] = straight * std::f32::consts::SQRT_2;
        self.walls[p] = walls;
    }
}

/// Plans on one grid with one set of costs, from any number of starts: the entry costs of the
/// cells are taken once (a tour's legs are many plans on the same map).
pub struct Planner<'a> {
    grid: &'a Grid,
    steps: Steps,
    /// The step into an obstacle cell, and into one right around the start (the escape).
    obstacle_step: f32,
    escape_step: f32,
}

impl<'a> Planner<'a> {
    /// Plans on `grid` with `costs`.
    pub fn new(grid: &'a Grid, costs: &Costs) -> Self {
        debug_assert!(costs.near_wall >= 0.0 && costs.unknown >= 0.0 && costs.obstacle.is_none_or(|c| c >= 0.0));
        let escape_step = 1.0 + costs.near_wall + costs.unknown;
        let obstacle_step = costs.obstacle.map_or(f32::INFINITY, |extra| escape_step + extra);
        let steps = Steps::new(grid, costs, (obstacle_step, escape_step));
        Planner { grid, steps, obstacle_step, escape_step }
    }

    /// Path costs from map cell `start` to every cell and each cell's predecessor (Dijkstra,
    /// 8-connected, no corner cutting past obstacles). The start cell is free of charge whatever
    /// it holds, and obstacle cells right around it can be crossed at a premium: a rover that the
    /// map puts in or against a wall (a sample by the wall, a wall margin) can still leave. The
    /// search goes only as far as the cells asked for need (see [`CostMap`]).
    pub fn costs_from(mut self, start: usize) -> CostMap {
        self.open_escape(start);
        let search = Search::new(padded(start), self.steps.max);
        CostMap { lazy: Mutex::new(LazySearch { search, steps: self.steps }) }
    }

    /// The path costs from map cell `start` to each of `goals` (infinite where unreachable), as
    /// [`Planner::costs_from`] gives them; the search ends once they are all final.
    pub fn costs_to(&mut self, start: usize, goals: &[usize]) -> Vec<f32> {
        let goals: Vec<usize> = goals.iter().map(|&goal| padded(goal)).collect();
        let search = self.search(start, |distance, below| goals.iter().all(|&goal| distance[goal] < below));
        goals.iter().map(|&goal| search.distance[goal]).collect()
    }

    /// Runs the search from map cell `start`, the escape around it open, until `done` says the
    /// costs it needs are final ([`Search::expand_until`]).
    fn search(&mut self, start: usize, done: impl Fn(&[f32], f32) -> bool) -> Search {
        let escapes = self.open_escape(start);
        let steps = &self.steps;
        let mut search = Search::new(padded(start), steps.max);
        search.expand_until(steps, done);
        self.close_escape(&escapes);
        search
    }

    /// Lets the plan cross the obstacle cells right around map cell `start`; returns their padded
    /// indices.
    fn open_escape(&mut self, start: usize) -> Vec<usize> {
        let escapes: Vec<usize> = Grid::cells_around(start, ESCAPE_RADIUS_CELLS)
            .filter(|&n| self.grid.cells[n] == Cell::Blocked)
            .map(padded)
            .collect();
        for &p in &escapes {
            self.steps.set(p, self.escape_step, false);
        }
        escapes
    }

    /// Makes the padded cells `escapes` obstacles again.
    fn close_escape(&mut self, escapes: &[usize]) {
        for &p in escapes {
            self.steps.set(p, self.obstacle_step, self.obstacle_step == f32::INFINITY);
        }
    }
}

/// The state of a search on the padded grid: the best cost found so far of each cell
/// and its predecessor (a padded index), the cells still to expand, and the next bucket of them.
struct Search {
    distance: Vec<f32>,
    parent: Vec<u32>,
    open: UnitBuckets,
    /// The bucket expanded next: every cost below `next_bucket + 1` is final.
    next_bucket: usize,
}

impl Search {
    /// A search from padded cell `start` with steps of at most `max_step` (straight).
    fn new(start: usize, max_step: f32) -> Self {
        let mut search = Search {
            distance: vec![f32::INFINITY; PADDED_CELLS],
            parent: vec![NO_PARENT; PADDED_CELLS],
            open: UnitBuckets::new(max_step * std::f32::consts::SQRT_2),
            next_bucket: 0,
        };
        search.distance[start] = 0.0;
        search.open.push(0.0, start);
        search
    }

    /// Expands bucket after bucket until no cell is left open or `done(distances, below)` says
    /// the costs it needs are final: with the buckets below k expanded, every cost below k + 1
    /// and its predecessor are, as a lower cost or a tie could only come from a cell at least 1
    /// cheaper, expanded already.
    fn expand_until(&mut self, steps: &Steps, done: impl Fn(&[f32], f32) -> bool) {
        while self.open.len > 0 && !done(&self.distance, (self.next_bucket + 1) as f32) {
            let k = self.next_bucket;
            let keys = self.open.take(k);
            for (d, p) in keys.iter().map(|&key| from_order_key(key)) {
                if d <= self.distance[p] {
                    self.expand(p, d, steps);
                }
            }
            self.open.give_back(k, keys);
            self.next_bucket += 1;
        }
    }

    /// Relaxes the neighbours of padded cell `p`, reached at cost `d`; no diagonal step cuts the
    /// corner of a cell that walls off the plan. Inlined into the search loop (as `relax`): called
    /// once for every cell searched, it is the loop.
    #[inline(always)]
    fn expand(&mut self, p: usize, d: f32, steps: &Steps) {
        const ROW: usize = PADDED_SIDE;
        for n in [p + 1, p - 1, p + ROW, p - ROW] {
            self.relax(n, d + steps.straight[n], (p, d));
        }
        let diagonals = [(p + ROW + 1, p + 1, p + ROW), (p - ROW + 1, p + 1, p - ROW)];
        let diagonals = diagonals.into_iter().chain([(p + ROW - 1, p - 1, p + ROW), (p - ROW - 1, p - 1, p - ROW)]);
        for (n, beside, ahead) in diagonals {
            if !steps.walls[beside] && !steps.walls[ahead] {
                self.relax(n, d + steps.diagonal[n], (p, d));
            }
        }
    }

    /// Reaches padded cell `n` at cost `d` from padded cell `from`, itself reached at cost
    /// `from_d`: if that is cheaper than before, or as cheap from a predecessor that a binary heap
    /// would have expanded first (lower cost, then lower cell), which it then keeps as the parent,
    /// so that the paths do not depend on the order in which a bucket's cells are expanded. (A
    /// kept predecessor was expanded, so its cost is final and orders it as when it was kept.)
    #[inline(always)]
    fn relax(&mut self, n: usize, d: f32, (from, from_d): (usize, f32)) {
        let known = self.distance[n];
        if d < known {
            self.distance[n] = d;
            self.parent[n] = from as u32;
            self.open.push(d, n);
        } else if d == known && d < f32::INFINITY {
            let kept = self.parent[n] as usize;
            if order_key(from_d, from) < order_key(self.distance[kept], kept) {
                self.parent[n] = from as u32;
            }
        }
    }
}

/// The open cells of [`Grid::costs_from`], in buckets of unit path cost: as no step costs less
/// than 1, a cell taken from the bucket of costs in [k, k + 1) only adds cells to later buckets
/// and its cost is final, whatever the order in which the bucket's cells are taken.
struct UnitBuckets {
    /// Keys by the integer part of their cost, modulo the number of buckets (a power of 2).
    ring: Vec<Vec<u64>>,
    /// Keys in the ring.
    len: usize,
}

impl UnitBuckets {
    /// Buckets for steps of at most `max_step` (diagonals included).
    fn new(max_step: f32) -> Self {
        UnitBuckets { ring: vec![Vec::new(); (max_step as usize + 2).next_power_of_two()], len: 0 }
    }

    /// The bucket of the costs in [k, k + 1).
    fn slot(&self, k: usize) -> usize {
        k & (self.ring.len() - 1)
    }

    /// Adds cell `i` at cost `d`.
    fn push(&mut self, d: f32, i: usize) {
        let slot = self.slot(d as usize);
        self.ring[slot].push(order_key(d, i));
        self.len += 1;
    }

    /// The keys of bucket `k`, leaving it empty for reuse.
    fn take(&mut self, k: usize) -> Vec<u64> {
        let slot = self.slot(k);
        let keys = std::mem::take(&mut self.ring[slot]);
        self.len -= keys.len();
        keys
    }

    /// Hands an emptied bucket's storage back.
    fn give_back(&mut self, k: usize, mut keys: Vec<u64>) {
        keys.clear();
        let slot = self.slot(k);
        if self.ring[slot].is_empty() {
            self.ring[slot] = keys;
        }
    }
}

/// The result of [`Grid::costs_from`]: a search from one start that goes on, bucket by bucket,
/// only until the cost asked for is final. The costs and paths are those of the whole search
/// whatever is asked in which order, but a plan that asks only for cells near the rover (the
/// frontiers, a sample, home) leaves the far unknown ground unsearched.
pub struct CostMap {
    lazy: Mutex<LazySearch>,
}

/// A search from one start with its own entry costs, expanded as far as it was asked to.
struct LazySearch {
    search: Search,
    steps: Steps,
}

impl LazySearch {
    /// Expands buckets until the cost of padded cell `p` is final (at once for a cell that
    /// cannot be entered); the cost.
    fn settle(&mut self, p: usize) -> f32 {
        if self.steps.straight[p] == f32::INFINITY && self.search.distance[p] == f32::INFINITY {
            return f32::INFINITY;
        }
        self.search.expand_until(&self.steps, |distance, below| distance[p] < below);
        self.search.distance[p]
    }

    /// Expands every bucket left.
    fn settle_all(&mut self) -> &Search {
        self.search.expand_until(&self.steps, |_, _| false);
        &self.search
    }
}

impl std::fmt::Debug for CostMap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CostMap").field("final_below", &(self.lazy().search.next_bucket + 1)).finish_non_exhaustive()
    }
}

impl CostMap {
    /// The search, as far as it has gone.
    fn lazy(&self) -> std::sync::MutexGuard<'_, LazySearch> {
        self.lazy.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// Path cost to map cell `cell` (infinite when unreachable).
    pub fn distance(&self, cell: usize) -> f32 {
        self.lazy().settle(padded(cell))
    }

    /// How many cells can be reached.
    pub fn reachable_cells(&self) -> usize {
        self.lazy().settle_all().distance.iter().filter(|d| d.is_finite()).count()
    }

    /// `goal` when it is reachable, else the cheapest reachable cell within `radius` cells of it
    /// (a sample by a wall lies on cells the map holds as obstacles).
    pub fn reachable_near(&self, goal: usize, radius: usize) -> Option<usize> {
        if self.distance(goal).is_finite() {
            return Some(goal);
        }
        Grid::cells_around(goal, radius)
            .filter(|&cell| self.distance(cell).is_finite())
            .min_by(|&a, &b| self.distance(a).total_cmp(&self.distance(b)))
    }

    /// The cells from the start to `goal`, or `None` when unreachable.
    pub fn path_to(&self, goal: usize) -> Option<Vec<usize>> {
        if !self.distance(goal).is_finite() {
            return None;
        }
        let lazy = self.lazy();
        let mut path = vec![goal];
        let mut at = padded(goal);
        while lazy.search.parent[at] != NO_PARENT {
            at = lazy.search.parent[at] as usize;
            path.push(unpadded(at));
        }
        path.reverse();
        Some(path)
    }
}

/// The cells under points every `SIGHT_STEP_M` along the straight line from point `from`
/// (metres, excluded) to the centre of cell `to` (included); `None` for points off the map.
fn cells_on_line(from: (f64, f64), to: usize) -> impl Iterator<Item = Option<usize>> {
    let target = cell_centre_m(to);
    let steps = ((target.0 - from.0).hypot(target.1 - from.1) / SIGHT_STEP_M).ceil() as usize;
    (1..=steps).map(move |k| {
        let t = k as f64 / steps as f64;
        cell_of_point(from.0 + t * (target.0 - from.0), from.1 + t * (target.1 - from.1))
    })
}

const NEIGHBOURS8: [(i64, i64); 8] = [(1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1), (-1, -1)];

fn neighbours(i: usize, offsets: &'static [(i64, i64)]) -> impl Iterator<Item = usize> {
    let (x, y) = cell_xy(i);
    offsets.iter().filter_map(move |&(dx, dy)| checked_cell_at(x as i64 + dx, y as i64 + dy))
}

fn neighbours4(i: usize) -> impl Iterator<Item = usize> {
    neighbours(i, &NEIGHBOURS8[..4])
}

fn neighbours8(i: usize) -> impl Iterator<Item = usize> {
    neighbours(i, &NEIGHBOURS8)
}

#[cfg(test)]
mod tests;
