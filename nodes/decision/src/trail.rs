//! The way the rover came: a point every [`CRUMB_SPACING_M`] of the last stretch driven, and
//! how often in a row it has got stuck at one spot. A rover that keeps getting stuck where it
//! stands has driven into a pocket that backing off and turning do not leave; the way it came in
//! is the one way known to lead out.

use std::collections::VecDeque;

/// A point of the trail every this many metres driven.
const CRUMB_SPACING_M: f64 = 0.5;
/// The trail keeps this many points (the last 20 m).
const MAX_CRUMBS: usize = 40;
/// Recoveries within this distance of the first of a series count as at one spot, metres...
const SAME_SPOT_M: f64 = 1.0;
/// ...and the series ends once the rover is this far from that spot, metres.
const LEFT_SPOT_M: f64 = 3.0;

/// The trail and the series of recoveries at one spot.
#[derive(Debug, Clone, Default)]
pub(crate) struct Trail {
    /// Oldest first.
    crumbs: VecDeque<(f64, f64)>,
    /// Where the current series of recoveries began, and how many it holds.
    stuck_at: Option<((f64, f64), u32)>,
}

impl Trail {
    /// Adds `at` to the trail once it lies [`CRUMB_SPACING_M`] from the last point; a series of
    /// recoveries ends once the rover has left its spot.
    pub(crate) fn record(&mut self, at: (f64, f64)) {
        if self.stuck_at.is_some_and(|(spot, _)| distance_m(spot, at) > LEFT_SPOT_M) {
            self.stuck_at = None;
        }
        if self.crumbs.back().is_some_and(|&last| distance_m(last, at) < CRUMB_SPACING_M) {
            return;
        }
        if self.crumbs.len() == MAX_CRUMBS {
            self.crumbs.pop_front();
        }
        self.crumbs.push_back(at);
    }

    /// Counts a recovery at `at`; returns how many recoveries in a row have been at this spot
    /// (within [`SAME_SPOT_M`] of where the series began), this one included.
    pub(crate) fn note_recovery(&mut self, at: (f64, f64)) -> u32 {
        let series = match self.stuck_at {
            Some((spot, count)) if distance_m(spot, at) <= SAME_SPOT_M => (spot, count + 1),
            _ => (at, 1),
        };
        self.stuck_at = Some(series);
        series.1
    }

    /// The stretch of the trail that leads back from `from`: its points in the order driven,
    /// from the last one at least `min_distance_m` from `from` on (retraced by taking them from
    /// the end); `None` when the whole trail lies closer.
    pub(crate) fn way_back(&self, from: (f64, f64), min_distance_m: f64) -> Option<Vec<(f64, f64)>> {
        let far = self.crumbs.iter().rposition(|&crumb| distance_m(crumb, from) >= min_distance_m)?;
        Some(self.crumbs.range(far..).copied().collect())
    }
}

fn distance_m(a: (f64, f64), b: (f64, f64)) -> f64 {
    (a.0 - b.0).hypot(a.1 - b.1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_way_back_follows_the_trail_to_a_point_far_enough_from_the_spot() {
        let mut trail = Trail::default();
        (0..=20).for_each(|i| trail.record((f64::from(i) * 0.5, 0.0)));
        (0..10).for_each(|_| trail.record((10.0, 0.1)));
        let way: Vec<(f64, f64)> = (14..=20).map(|i| (f64::from(i) * 0.5, 0.0)).collect();
        assert_eq!(trail.way_back((10.0, 0.0), 3.0), Some(way));
        assert_eq!(trail.way_back((10.0, 0.0), 30.0), None, "the trail is shorter");
    }

    #[test]
    fn the_trail_keeps_its_last_stretch_only() {
        let mut trail = Trail::default();
        (0..200).for_each(|i| trail.record((f64::from(i), 0.0)));
        assert_eq!(trail.crumbs.len(), MAX_CRUMBS);
        assert_eq!(trail.way_back((199.0, 0.0), 1000.0), None);
        assert_eq!(trail.way_back((199.0, 0.0), 39.0).and_then(|way| way.first().copied()), Some((160.0, 0.0)));
    }

    #[test]
    fn recoveries_count_in_a_row_at_one_spot() {
        let mut trail = Trail::default();
        assert_eq!(trail.note_recovery((5.0, 5.0)), 1);
        assert_eq!(trail.note_recovery((5.5, 5.3)), 2);
        assert_eq!(trail.note_recovery((5.2, 4.6)), 3);
        assert_eq!(trail.note_recovery((9.0, 5.0)), 1, "another spot starts a new series");
        assert_eq!(trail.note_recovery((9.0, 5.5)), 2);
        trail.record((12.5, 5.0));
        assert_eq!(trail.note_recovery((9.0, 5.0)), 1, "the rover had left the spot");
    }
}
