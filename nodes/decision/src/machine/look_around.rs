//! Looking around: before the rover concludes that no frontier is left, it turns a full circle
//! where it stands if the map leaves ground within the camera's reach unseen, so that a rover
//! started facing a wall sees what lies behind it; and it concludes nothing from a map that has
//! seen no ground in reach even then.

use rover_msgs::map_grid::{cell_centre_m, cell_of_point};

use super::{Machine, Observation};
use crate::drive::Drive;
use crate::grid::{Cell, Grid};
use crate::pose::{Position, wrap_rad};

/// Within this distance of a spot where the rover turned a full circle, it does not look again,
/// metres.
const LOOKED_NEAR_M: f64 = 2.0;

/// The look-arounds of a mission: the one in progress and where the rover has looked.
#[derive(Debug, Clone, Default)]
pub(super) struct LookAround {
    turn: Option<Turn>,
    /// Where the rover turned full circles.
    looked_at: Vec<(f64, f64)>,
    /// Whether the rover is braked until the map shows ground in reach.
    waiting_for_map: bool,
}

/// A turn in progress.
#[derive(Debug, Clone, Copy)]
struct Turn {
    /// The heading at the last frame, radians.
    last_yaw_rad: f64,
    /// How far the rover has turned so far, radians.
    turned_rad: f64,
}

impl LookAround {
    /// Gives up the turn in progress and ends a wait for the map: a frontier showed up, or the
    /// mode changed.
    pub(super) fn interrupt(&mut self) {
        self.turn = None;
        self.waiting_for_map = false;
    }

    fn looked_near(&self, at: &Position) -> bool {
        self.looked_at.iter().any(|&spot| at.distance_to(spot) < LOOKED_NEAR_M)
    }

    /// Adds the heading `yaw_rad` to the turn in progress; true once it makes a full circle.
    fn turned_full_circle(&mut self, yaw_rad: f64) -> bool {
        let Some(turn) = self.turn.as_mut() else { return false };
        turn.turned_rad += wrap_rad(yaw_rad - turn.last_yaw_rad).abs();
        turn.last_yaw_rad = yaw_rad;
        turn.turned_rad >= std::f64::consts::TAU
    }
}

impl Machine {
    /// With no frontier left: the drive of a look-around, unless the rover has looked all around
    /// near here or the map already knows the ground in the camera's reach.
    pub(super) fn look_around(&mut self, obs: &Observation) -> Option<Drive> {
        let at = &obs.position;
        if self.search.look_around.turn.is_some() {
            if self.search.look_around.turned_full_circle(at.yaw_rad) {
                self.search.look_around.turn = None;
                self.search.look_around.looked_at.push((at.x_m, at.y_m));
                return None;
            }
        } else {
            if self.search.look_around.looked_near(at)
                || !unseen_in_reach(&self.maps.received, at, self.params.inspect_range_m)
            {
                return None;
            }
            tracing::info!(x = at.x_m, y = at.y_m, "no frontier left with ground in reach unseen: looking all around");
            self.search.look_around.turn = Some(Turn { last_yaw_rad: at.yaw_rad, turned_rad: 0.0 });
            self.start_afresh();
        }
        Some(Drive::turn_in_place(true))
    }

    /// Whether the map has seen ground within the camera's reach of the rover. One that has not,
    /// after a look-around, is not following the rover (the mapping node is starting, or its
    /// inputs are cut off): concluding from it would end the mission blind, so the rover waits,
    /// and the frames it waits do not count as stuck.
    pub(super) fn map_shows_ground_in_reach(&mut self, obs: &Observation) -> bool {
        let shown = in_sight(&self.maps.received, &obs.position, self.params.inspect_range_m)
            .any(|cell| self.maps.received.cell(cell) != Cell::Unknown);
        if !shown {
            if !self.search.look_around.waiting_for_map {
                tracing::warn!("no frontier left, but the map shows no ground around the rover: waiting for the map");
            }
            self.start_afresh();
        }
        self.search.look_around.waiting_for_map = !shown;
        shown
    }
}

/// The cells of `map` within `range_m` of the rover and in its line of sight.
fn in_sight<'a>(map: &'a Grid, at: &'a Position, range_m: f64) -> impl Iterator<Item = usize> + 'a {
    let centre = cell_of_point(at.x_m, at.y_m);
    let from = (at.x_m, at.y_m);
    let around = centre.into_iter().flat_map(move |centre| Grid::cells_around(centre, range_m.ceil() as usize));
    around.filter(move |&cell| at.distance_to(cell_centre_m(cell)) <= range_m && map.line_of_sight(from, cell, 0))
}

/// Whether a cell of `map` within `range_m` of the rover is unknown and in its line of sight.
fn unseen_in_reach(map: &Grid, at: &Position, range_m: f64) -> bool {
    in_sight(map, at, range_m).any(|cell| map.cell(cell) == Cell::Unknown)
}

#[cfg(test)]
mod tests {
    use rover_msgs::map_grid::CELLS;

    use super::*;
    use crate::test_maps::at;

    /// A map known free within `free_m` of the rover at (100.5, 100.5), behind a ring of wall
    /// `wall_m` thick when `wall_m` is above zero, and unknown beyond.
    fn known_around(free_m: f64, wall_m: f64) -> Grid {
        let distance = |cell: usize| at(100.5, 100.5).distance_to(cell_centre_m(cell));
        let occupancy = (0..CELLS).map(|cell| match distance(cell) {
            d if d <= free_m => 0,
            d if d <= free_m + wall_m => 100,
            _ => -1,
        });
        Grid::from_occupancy(&occupancy.collect::<Vec<i8>>()).unwrap()
    }

    #[test]
    fn a_full_circle_is_counted_across_the_wrap_of_the_heading() {
        let mut look = LookAround { turn: Some(Turn { last_yaw_rad: 3.0, turned_rad: 0.0 }), ..LookAround::default() };
        let headings = (1..=16).map(|step| wrap_rad(3.0 + step as f64 * std::f64::consts::TAU / 16.0));
        let circle: Vec<bool> = headings.map(|yaw| look.turned_full_circle(yaw)).collect();
        assert_eq!(circle.iter().position(|&full| full), Some(15), "{circle:?}");
    }

    #[test]
    fn ground_in_reach_is_unseen_unless_the_map_knows_it_or_a_wall_hides_it() {
        let rover = at(100.5, 100.5);
        assert!(unseen_in_reach(&Grid::unknown(), &rover, 5.0), "an unknown map");
        assert!(unseen_in_reach(&known_around(3.0, 0.0), &rover, 5.0), "known up to 3 m");
        assert!(!unseen_in_reach(&known_around(6.0, 0.0), &rover, 5.0), "known up to 6 m");
        assert!(!unseen_in_reach(&known_around(2.0, 1.0), &rover, 5.0), "walled in at 2 m");
    }
}
