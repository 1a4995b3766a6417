//! Getting stuck: watches of the rover's progress, and the cells at the rover's front where it
//! got stuck, which planning takes as obstacles for a while (the map says free what the rover cannot
//! drive through).

use rover_msgs::map_grid::{cell_centre_m, cell_of_point};

use crate::grid::{Cell, Grid};
use crate::params::DecisionParams;
use crate::pose::Position;

/// A cell marked at the rover's front where it got stuck is an obstacle for planning for this
/// long, seconds.
pub(crate) const STUCK_MARK_S: f64 = 120.0;
/// The marked cell is one this far ahead of the rover's position: its front, metres.
const STUCK_MARK_AHEAD_M: f64 = 0.9;
/// Where along the rover's front a mark goes, metres to the left of its heading: straight ahead
/// first; when the rover gets stuck again where that cell is blocked already, the next of these
/// that is not (a mark on a blocked cell would change no plan, and the next one would lead the
/// rover into the same spot again).
const STUCK_MARK_LATERAL_M: [f64; 5] = [0.0, 1.0, -1.0, 2.0, -2.0];
/// When every cell of the front is blocked already, the mark goes on the next cell of the plan's
/// path within this distance of the rover, metres: the plan leads on through cells that the rover
/// did not get through (a path that hugs a boulder closer than the rover follows it).
const PATH_MARK_REACH_M: f64 = 2.0;

/// Watches the rover's progress: how long it has stayed within some distance of one spot.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct ProgressWatch {
    anchor: Option<(u64, f64, f64)>,
}

impl ProgressWatch {
    /// Frames the rover `at` has stayed within `radius_m` of where this watch last anchored, as of
    /// `frame`.
    pub(crate) fn frames_within(&mut self, at: &Position, frame: u64, radius_m: f64) -> u64 {
        match self.anchor {
            Some((since, x_m, y_m)) if at.distance_to((x_m, y_m)) <= radius_m => frame.saturating_sub(since),
            _ => {
                self.anchor = Some((frame, at.x_m, at.y_m));
                0
            }
        }
    }

    /// Forgets the anchor: the next frame starts a new watch.
    pub(crate) fn reset(&mut self) {
        self.anchor = None;
    }
}

/// Watches how long the rover has been told to drive without leaving one spot. Frames in which it
/// was told to stand or turn in place do not count, but they do not start the watch again either:
/// a rover that pushes against a rock and turns a little in between is stuck all the same.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct DrivingWatch {
    spot: ProgressWatch,
    driving_frames: u64,
}

impl DrivingWatch {
    /// Frames in which the rover was told to drive (`driving` for this one) since it last left a
    /// circle of `radius_m`, as of `frame`, the rover being `at`.
    pub(crate) fn driving_frames_within(&mut self, at: &Position, frame: u64, radius_m: f64, driving: bool) -> u64 {
        if self.spot.frames_within(at, frame, radius_m) == 0 {
            self.driving_frames = 0;
        }
        self.driving_frames += u64::from(driving);
        self.driving_frames
    }

    /// Forgets the spot and the frames counted there.
    pub(crate) fn reset(&mut self) {
        *self = DrivingWatch::default();
    }
}

/// The cells of `path` after the one nearest the rover `at`, up to [`PATH_MARK_REACH_M`] from it,
/// the rover's own cell left out.
fn next_path_cells<'a>(at: &'a Position, path: &'a [usize]) -> impl Iterator<Item = usize> + 'a {
    let distance_m = move |cell: usize| at.distance_to(cell_centre_m(cell));
    let nearest = (0..path.len()).min_by(|&a, &b| distance_m(path[a]).total_cmp(&distance_m(path[b])));
    let own = cell_of_point(at.x_m, at.y_m);
    path[nearest.map_or(path.len(), |i| i + 1)..]
        .iter()
        .copied()
        .take_while(move |&cell| distance_m(cell) <= PATH_MARK_REACH_M)
        .filter(move |&cell| Some(cell) != own)
}

/// `map` with `cells` blocked.
fn blocked(map: &Grid, cells: impl Iterator<Item = usize>) -> Grid {
    let mut grid = map.clone();
    for cell in cells {
        grid.block(cell);
    }
    grid
}

/// Whether a mark kept until `until_frame` still holds at `frame`.
fn holds_at(frame: u64, until_frame: u64) -> bool {
    frame < until_frame
}

/// The cells marked as obstacles for planning where the rover got stuck lately.
#[derive(Debug, Clone, Default)]
pub(crate) struct StuckMarks {
    marks: Vec<(usize, u64)>,
}

impl StuckMarks {
    /// Notes that the rover `at` got stuck at `frame`, following the plan's `path`: the first
    /// cell along its front ([`STUCK_MARK_LATERAL_M`]) that `planning` (the map planned on, these
    /// marks included) does not block, else the next such cell of `path` near the rover
    /// ([`PATH_MARK_REACH_M`]), is marked until [`STUCK_MARK_S`] later, and returned (none when
    /// all are blocked or off the map).
    pub(crate) fn note_stuck(
        &mut self,
        (at, frame): (&Position, u64),
        planning: &Grid,
        path: &[usize],
        params: &DecisionParams,
    ) -> Option<usize> {
        let unblocked = |cell: &usize| planning.cell(*cell) != Cell::Blocked;
        let front = STUCK_MARK_LATERAL_M.iter().filter_map(|&lateral_m| {
            let bearing_rad = lateral_m.atan2(STUCK_MARK_AHEAD_M);
            let ahead = at.point_at(bearing_rad, STUCK_MARK_AHEAD_M.hypot(lateral_m));
            cell_of_point(ahead.0, ahead.1)
        });
        let cell = front.chain(next_path_cells(at, path)).find(unblocked)?;
        self.marks.push((cell, frame + params.frames(STUCK_MARK_S)));
        Some(cell)
    }

    /// Drops the marks that have expired by `frame`.
    pub(crate) fn expire(&mut self, frame: u64) {
        self.marks.retain(|&(_, until_frame)| holds_at(frame, until_frame));
    }

    /// `map` with the marked cells blocked.
    pub(crate) fn applied_to(&self, map: &Grid) -> Grid {
        blocked(map, self.marks.iter().map(|&(cell, _)| cell))
    }

    /// `map` with the cells blocked that are still marked at `frame` (those that
    /// [`StuckMarks::expire`] at `frame` keeps).
    pub(crate) fn applied_at(&self, map: &Grid, frame: u64) -> Grid {
        let live = self.marks.iter().filter(|&&(_, until_frame)| holds_at(frame, until_frame));
        blocked(map, live.map(|&(cell, _)| cell))
    }

    /// Forgets every mark; returns whether there were any.
    pub(crate) fn forget(&mut self) -> bool {
        let any = !self.marks.is_empty();
        self.marks.clear();
        any
    }
}

#[cfg(test)]
mod tests {
    use rover_msgs::map_grid::cell_at;

    use super::*;
    use crate::test_maps::{at, half_explored};

    #[test]
    fn a_watch_counts_the_frames_spent_near_its_anchor() {
        let mut watch = ProgressWatch::default();
        assert_eq!(watch.frames_within(&at(10.0, 10.0), 5, 1.0), 0, "the first frame anchors");
        assert_eq!(watch.frames_within(&at(10.5, 10.0), 30, 1.0), 25);
        assert_eq!(watch.frames_within(&at(12.0, 10.0), 40, 1.0), 0, "moved away: anchored again");
        watch.reset();
        assert_eq!(watch.frames_within(&at(12.0, 10.0), 50, 1.0), 0);
    }

    #[test]
    fn a_driving_watch_counts_only_the_frames_told_to_drive_and_starts_again_once_the_rover_moves() {
        let mut watch = DrivingWatch::default();
        let counts: Vec<u64> =
            (0..6).map(|frame| watch.driving_frames_within(&at(10.0, 10.0), frame, 0.3, frame % 2 == 0)).collect();
        assert_eq!(counts, [1, 1, 2, 2, 3, 3], "turning in between neither counts nor starts again");
        assert_eq!(watch.driving_frames_within(&at(10.5, 10.0), 6, 0.3, true), 1, "moved away: counted anew");
        watch.reset();
        assert_eq!(watch.driving_frames_within(&at(10.5, 10.0), 7, 0.3, false), 0);
    }

    #[test]
    fn getting_stuck_marks_the_cell_ahead_until_the_mark_expires() {
        let params = DecisionParams::default();
        let mut marks = StuckMarks::default();
        let map = half_explored();
        let cell = marks.note_stuck((&at(30.5, 51.5), 10), &map, &[], &params).expect("on the map");
        assert_eq!(cell, cell_of_point(31.4, 51.5).unwrap(), "the cell ahead");
        assert_eq!((map.cell(cell), marks.applied_to(&map).cell(cell)), (Cell::Free, Cell::Blocked));
        let until = 10 + params.frames(STUCK_MARK_S);
        assert_eq!(marks.applied_at(&map, until - 1).cell(cell), Cell::Blocked, "still marked then");
        assert_eq!(marks.applied_at(&map, until), Grid::clone(&map), "expired then");
        marks.expire(until - 1);
        assert_eq!(marks.applied_to(&map).cell(cell), Cell::Blocked, "not yet expired");
        marks.expire(until);
        assert_eq!(marks.applied_to(&map).cell(cell), Cell::Free, "expired");
        assert!(!marks.forget(), "nothing left to forget");
        assert_eq!(marks.note_stuck((&at(-5.0, 51.5), 20), &map, &[], &params), None, "off the map");
    }

    #[test]
    fn getting_stuck_again_where_the_cell_ahead_is_blocked_marks_the_front_beside_it() {
        let params = DecisionParams::default();
        let mut marks = StuckMarks::default();
        let rover = at(30.5, 51.5);
        let mut cells = Vec::new();
        let mut planning = half_explored();
        while let Some(cell) = marks.note_stuck((&rover, 10), &planning, &[], &params) {
            cells.push(cell_centre_m(cell));
            planning = marks.applied_to(&half_explored());
        }
        assert_eq!(
            cells,
            [(31.5, 51.5), (31.5, 52.5), (31.5, 50.5), (31.5, 53.5)],
            "ahead, then left and right of it, one cell each time the rover gets stuck there, up to the \
             corridor's walls"
        );
    }

    #[test]
    fn getting_stuck_where_the_whole_front_is_blocked_marks_the_next_cells_of_the_plan() {
        let params = DecisionParams::default();
        let mut marks = StuckMarks::default();
        let rover = at(30.5, 51.5);
        let mut planning = half_explored();
        while marks.note_stuck((&rover, 10), &planning, &[], &params).is_some() {
            planning = marks.applied_to(&half_explored());
        }
        let back_along_the_corridor: Vec<usize> = (26..=31).rev().map(|x| cell_at(x, 51)).collect();
        let mut cells = Vec::new();
        while let Some(cell) = marks.note_stuck((&rover, 10), &planning, &back_along_the_corridor, &params) {
            cells.push(cell_centre_m(cell));
            planning = marks.applied_to(&half_explored());
        }
        assert_eq!(
            cells,
            [(29.5, 51.5), (28.5, 51.5)],
            "the plan's cells after the rover's own, as far as 2 m from it, one each time it gets stuck"
        );
    }
}
