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
/// Every this many recoveries in a row at one spot the rover retraces the way it came in, back
/// to where it was this far from the spot, metres.
const RETRACE_EVERY_RECOVERIES: u32 = 3;
const RETRACE_M: f64 = 3.0;
/// Retracing, a point of the trail counts as reached this close, metres.
const REACHED_M: f64 = 0.3;

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

    /// Counts a recovery at `at`; every [`RETRACE_EVERY_RECOVERIES`] in a row at this spot
    /// (within [`SAME_SPOT_M`] of where the series began), the way back out of it: the stretch of
    /// the trail from where the rover was [`RETRACE_M`] from the spot, in the order driven.
    pub(crate) fn note_recovery(&mut self, at: (f64, f64)) -> Option<WayBack> {
        let series = match self.stuck_at {
            Some((spot, count)) if distance_m(spot, at) <= SAME_SPOT_M => (spot, count + 1),
            _ => (at, 1),
        };
        self.stuck_at = Some(series);
        (series.1 % RETRACE_EVERY_RECOVERIES == 0).then(|| self.way_back(at, RETRACE_M)).flatten()
    }

    /// The stretch of the trail that leads back from `from`: its points in the order driven,
    /// from the last one at least `min_distance_m` from `from` on (retraced by taking them from
    /// the end); `None` when the whole trail lies closer.
    fn way_back(&self, from: (f64, f64), min_distance_m: f64) -> Option<WayBack> {
        let far = self.crumbs.iter().rposition(|&crumb| distance_m(crumb, from) >= min_distance_m)?;
        Some(WayBack(self.crumbs.range(far..).copied().collect()))
    }
}

/// Points of the trail to drive back along, in the order driven (the next one last).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct WayBack(Vec<(f64, f64)>);

impl WayBack {
    /// The point to drive to from `at`, the points reached dropped; `None` once all are.
    pub(crate) fn next_point(&mut self, at: (f64, f64)) -> Option<(f64, f64)> {
        while self.0.last().is_some_and(|&point| distance_m(point, at) <= REACHED_M) {
            self.0.pop();
        }
        self.0.last().copied()
    }

    /// Where it ends.
    pub(crate) fn end(&self) -> Option<(f64, f64)> {
        self.0.first().copied()
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
        let mut way_back = trail.way_back((10.0, 0.0), 3.0).unwrap();
        assert_eq!(way_back, WayBack(way));
        assert_eq!(way_back.next_point((10.0, 0.0)), Some((9.5, 0.0)), "the spot's own point is reached");
        assert_eq!(way_back.next_point((9.4, 0.0)), Some((9.0, 0.0)), "then the one before");
        let driven_back: Vec<_> = (0..=20).map(|i| way_back.next_point((9.0 - f64::from(i) * 0.1, 0.0))).collect();
        assert_eq!(driven_back.last(), Some(&None), "all reached at 7 m");
        assert_eq!(trail.way_back((10.0, 0.0), 30.0), None, "the trail is shorter");
    }

    #[test]
    fn the_trail_keeps_its_last_stretch_only() {
        let mut trail = Trail::default();
        (0..200).for_each(|i| trail.record((f64::from(i), 0.0)));
        assert_eq!(trail.crumbs.len(), MAX_CRUMBS);
        assert_eq!(trail.way_back((199.0, 0.0), 1000.0), None);
        assert_eq!(trail.way_back((199.0, 0.0), 39.0).and_then(|way| way.end()), Some((160.0, 0.0)));
    }

    #[test]
    fn every_third_recovery_in_a_row_at_one_spot_retraces_the_trail() {
        let mut trail = Trail::default();
        (0..=10).for_each(|i| trail.record((f64::from(i), 5.0)));
        let spot = |trail: &mut Trail, at: (f64, f64)| trail.note_recovery(at).and_then(|way| way.end());
        assert_eq!(spot(&mut trail, (10.0, 5.0)), None);
        assert_eq!(spot(&mut trail, (10.5, 5.3)), None);
        assert_eq!(spot(&mut trail, (10.2, 4.6)), Some((7.0, 5.0)), "the third at the spot");
        assert_eq!(spot(&mut trail, (14.0, 5.0)), None, "another spot starts a new series");
        assert_eq!(spot(&mut trail, (14.0, 5.5)), None);
        trail.record((17.5, 5.0));
        assert_eq!(spot(&mut trail, (14.0, 5.0)), None, "the rover had left the spot");
        assert_eq!(spot(&mut trail, (14.0, 5.0)), None);
        assert!(spot(&mut trail, (14.0, 5.0)).is_some());
    }
}
