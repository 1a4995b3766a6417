//! The order of visits: frontier cells grouped into clusters, each reached at its cheapest cell
//! (its anchor), and a tour from the rover through the clusters that ends at home. Following
//! the tour explores a dead-end passage in one go, out along one side and back along the other,
//! instead of heading for whichever frontier is nearest and leaving small ones behind to come
//! back for.

use rover_msgs::map_grid::cell_centre_m;

use crate::grid::{CostMap, Costs, Grid, Planner};

/// Frontier cells within this distance of a cluster's anchor belong to its cluster, metres.
const CLUSTER_RADIUS_M: f64 = 3.0;
/// A tour visits at most this many clusters, the cheapest to reach.
const MAX_STOPS: usize = 16;

/// The anchors of the clusters of `frontiers`: the cheapest frontier cell to reach (by
/// `costs`) that no cheaper anchor's cluster holds, cheapest first, at most [`MAX_STOPS`].
pub fn cluster_anchors(mut frontiers: Vec<usize>, costs: &CostMap) -> Vec<usize> {
    frontiers.sort_by(|&a, &b| costs.distance(a).total_cmp(&costs.distance(b)));
    let mut anchors: Vec<usize> = Vec::new();
    for cell in frontiers {
        let centre = cell_centre_m(cell);
        let covered = anchors.iter().any(|&anchor| {
            let other = cell_centre_m(anchor);
            (centre.0 - other.0).hypot(centre.1 - other.1) <= CLUSTER_RADIUS_M
        });
        if !covered {
            anchors.push(cell);
            if anchors.len() == MAX_STOPS {
                break;
            }
        }
    }
    anchors
}

/// The costs of a tour: from the rover to each stop, between stops, and from each stop home.
struct Legs {
    from_rover: Vec<f64>,
    between: Vec<Vec<f64>>,
    home: Vec<f64>,
}

impl Legs {
    /// The legs between `anchors` on `grid`: over known free ground with `costs`, or, between two
    /// anchors that known ground does not join, by way of the rover (`from_rover`); legs home
    /// that known ground does not make are as the crow flies.
    fn measure(grid: &Grid, anchors: &[usize], from_rover: Vec<f64>, home: Option<usize>, costs: &Costs) -> Self {
        let mut planner = Planner::new(grid, &Costs { cross_unknown: false, obstacle: None, ..*costs });
        let between = anchors
            .iter()
            .enumerate()
            .map(|(i, &from)| {
                let reach = planner.costs_to(from, anchors);
                reach
                    .iter()
                    .enumerate()
                    .map(|(j, &cost)| finite_or(cost as f64, from_rover[i] + from_rover[j]))
                    .collect()
            })
            .collect();
        let home = match home {
            Some(home_cell) => {
                let reach = planner.costs_to(home_cell, anchors);
                anchors.iter().zip(reach).map(|(&a, cost)| finite_or(cost as f64, crow_flies(a, home_cell))).collect()
            }
            None => vec![0.0; anchors.len()],
        };
        Legs { from_rover, between, home }
    }

    /// The cost of visiting the stops in `order`, then going home.
    fn cost(&self, order: &[usize]) -> f64 {
        let (Some(&first), Some(&last)) = (order.first(), order.last()) else { return 0.0 };
        let between: f64 = order.windows(2).map(|pair| self.between[pair[0]][pair[1]]).sum();
        self.from_rover[first] + between + self.home[last]
    }

    /// The nearest stop next, each time, from the rover on.
    fn greedy_order(&self) -> Vec<usize> {
        let mut left: Vec<usize> = (0..self.from_rover.len()).collect();
        let mut order: Vec<usize> = Vec::with_capacity(left.len());
        while !left.is_empty() {
            let leg = |next: usize| match order.last() {
                Some(&at) => self.between[at][next],
                None => self.from_rover[next],
            };
            let pick = (0..left.len()).min_by(|&a, &b| leg(left[a]).total_cmp(&leg(left[b])));
            order.push(left.swap_remove(pick.expect("stops are left")));
        }
        order
    }

    /// `order` improved by reversing stretches of it while that makes the tour cheaper (2-opt).
    fn untangled(&self, mut order: Vec<usize>) -> Vec<usize> {
        let mut best = self.cost(&order);
        let mut improved = true;
        while improved {
            improved = false;
            for i in 0..order.len() {
                for j in i + 1..order.len() {
                    order[i..=j].reverse();
                    let cost = self.cost(&order);
                    if cost + 1e-6 < best {
                        best = cost;
                        improved = true;
                    } else {
                        order[i..=j].reverse();
                    }
                }
            }
        }
        order
    }
}

/// The first stop of a short tour from the rover through `anchors` that ends at `home` (or
/// anywhere, without one): `from_rover` gives the cost of each first leg.
pub(crate) fn first_stop(
    grid: &Grid,
    anchors: &[usize],
    from_rover: impl Fn(usize) -> f64,
    home: Option<usize>,
    costs: &Costs,
) -> Option<usize> {
    if anchors.len() <= 1 {
        return anchors.first().copied();
    }
    let legs = Legs::measure(grid, anchors, anchors.iter().map(|&a| from_rover(a)).collect(), home, costs);
    let order = legs.untangled(legs.greedy_order());
    order.first().map(|&stop| anchors[stop])
}

fn finite_or(value: f64, otherwise: f64) -> f64 {
    if value.is_finite() { value } else { otherwise }
}

fn crow_flies(a: usize, b: usize) -> f64 {
    let ((ax, ay), (bx, by)) = (cell_centre_m(a), cell_centre_m(b));
    (ax - bx).hypot(ay - by)
}

#[cfg(test)]
mod tests {
    use rover_msgs::map_grid::{CELLS, cell_at, cell_of_point};

    use super::*;

    const COSTS: Costs = Costs { unknown: 1.5, near_wall: 0.0, cross_unknown: true, obstacle: None };

    /// A corridor 20..80 x 50..54 of free ground, walls around it.
    fn corridor() -> Grid {
        let mut data = vec![100i8; CELLS];
        for y in 50..54 {
            for x in 20..80 {
                data[cell_at(x, y)] = 0;
            }
        }
        Grid::from_occupancy(&data).unwrap()
    }

    fn cell(x: f64, y: f64) -> usize {
        cell_of_point(x, y).unwrap()
    }

    #[test]
    fn frontier_cells_close_together_are_one_cluster_reached_at_its_cheapest_cell() {
        let grid = corridor();
        let costs = grid.costs_from(cell(20.5, 51.5), &COSTS);
        let frontiers = vec![cell(41.5, 50.5), cell(40.5, 50.5), cell(42.5, 50.5), cell(60.5, 53.5), cell(61.5, 53.5)];
        assert_eq!(cluster_anchors(frontiers, &costs), vec![cell(40.5, 50.5), cell(60.5, 53.5)]);
    }

    #[test]
    fn the_tour_clears_the_dead_end_before_going_home_past_the_nearest_stop() {
        let grid = corridor();
        let rover = cell(50.5, 51.5);
        let costs = grid.costs_from(rover, &COSTS);
        let (toward_home, dead_end) = (cell(45.5, 51.5), cell(70.5, 51.5));
        let from_rover = |a: usize| costs.distance(a) as f64;
        let home = Some(cell(21.5, 51.5));
        assert!(from_rover(toward_home) < from_rover(dead_end));
        assert_eq!(first_stop(&grid, &[toward_home, dead_end], from_rover, home, &COSTS), Some(dead_end));
        let far_from_home = Some(cell(78.5, 51.5));
        assert_eq!(first_stop(&grid, &[toward_home, dead_end], from_rover, far_from_home, &COSTS), Some(toward_home));
    }

    #[test]
    fn a_corridor_is_swept_out_along_one_wall_and_back_along_the_other() {
        let grid = corridor();
        let legs_of = |anchors: &[usize]| {
            let costs = grid.costs_from(cell(21.5, 51.5), &COSTS);
            let from_rover = anchors.iter().map(|&a| costs.distance(a) as f64).collect();
            Legs::measure(&grid, anchors, from_rover, Some(cell(21.5, 51.5)), &COSTS)
        };
        let lower: Vec<usize> = (0..5).map(|k| cell(30.5 + 10.0 * k as f64, 50.5)).collect();
        let upper: Vec<usize> = (0..5).map(|k| cell(30.5 + 10.0 * k as f64, 53.5)).collect();
        let zigzag: Vec<usize> = lower.iter().zip(&upper).flat_map(|(&l, &u)| [l, u]).collect();
        let legs = legs_of(&zigzag);
        let order = legs.untangled(legs.greedy_order());
        let out_and_back = legs.cost(&order);
        let stops: Vec<usize> = order.iter().map(|&i| zigzag[i]).collect();
        let turn = stops.iter().position(|&s| cell_centre_m(s).0 > 70.0).unwrap();
        let (out, back) = stops.split_at(turn + 1);
        assert!(out.windows(2).all(|p| cell_centre_m(p[0]).0 <= cell_centre_m(p[1]).0), "{stops:?}");
        assert!(back.windows(2).all(|p| cell_centre_m(p[0]).0 >= cell_centre_m(p[1]).0), "{stops:?}");
        assert!(out_and_back <= legs.cost(&(0..zigzag.len()).collect::<Vec<_>>()));
    }

    #[test]
    fn stops_that_known_ground_does_not_join_are_joined_by_way_of_the_rover() {
        let mut data = vec![-1i8; CELLS];
        for x in 20..30 {
            data[cell_at(x, 50)] = 0;
        }
        let grid = Grid::from_occupancy(&data).unwrap();
        let (a, b) = (cell(20.5, 50.5), cell(40.5, 50.5));
        let legs = Legs::measure(&grid, &[a, b], vec![3.0, 4.0], None, &COSTS);
        assert_eq!(legs.between[0][1], 7.0);
        assert_eq!(legs.home, vec![0.0, 0.0], "no home: the tour ends anywhere");
        assert_eq!(first_stop(&grid, &[], |_| 0.0, None, &COSTS), None);
    }
}
