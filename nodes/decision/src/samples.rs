//! What the rover remembers of samples: the rocks located on the map, those picked up or given up
//! on, and the approaches that failed, with where they started.

use rover_msgs::body::SAMPLE_SPREAD_M;

/// A rock is given up after this many approaches that ended stuck.
pub(crate) const APPROACHES_PER_ROCK: usize = 2;
/// A rock set aside after failed approaches may be tried again at once (see
/// [`SampleMemory::may_retry_at_once`]) until this many approaches to it have failed.
const APPROACHES_BEFORE_WAITING: usize = 2 * APPROACHES_PER_ROCK;

/// Whether rocks located at `a` and `b` are taken to be one.
pub(crate) fn same_rock(a: (f64, f64), b: (f64, f64)) -> bool {
    (a.0 - b.0).hypot(a.1 - b.1) < SAMPLE_SPREAD_M
}

/// An approach to a sample that ended without it.
#[derive(Debug, Clone, Copy)]
struct FailedApproach {
    sample: (f64, f64),
    frame: u64,
    from: (f64, f64),
}

/// The samples the rover knows of, world metres.
#[derive(Debug, Clone, Default)]
pub(crate) struct SampleMemory {
    located: Vec<(f64, f64)>,
    ignored: Vec<(f64, f64)>,
    failed: Vec<FailedApproach>,
    deferred: Vec<((f64, f64), u64)>,
}

impl SampleMemory {
    /// Takes the rocks the map holds now.
    pub(crate) fn set_located(&mut self, rocks: Vec<(f64, f64)>) {
        self.located = rocks;
    }

    /// The rocks the map holds.
    pub(crate) fn located(&self) -> &[(f64, f64)] {
        &self.located
    }

    /// Rocks picked up or given up on.
    pub(crate) fn ignored(&self) -> &[(f64, f64)] {
        &self.ignored
    }

    /// Takes over the rocks an earlier machine picked up or gave up on.
    pub(crate) fn set_ignored(&mut self, rocks: Vec<(f64, f64)>) {
        self.ignored = rocks;
    }

    /// Stops chasing the rock at `at`: picked up, or not picked up when it should have been.
    pub(crate) fn ignore(&mut self, at: (f64, f64)) {
        self.ignored.push(at);
    }

    /// Leaves the rock at `at` alone until `until_frame`: the way to it is a long way round.
    pub(crate) fn defer(&mut self, at: (f64, f64), until_frame: u64) {
        self.deferred.retain(|&(rock, _)| !same_rock(rock, at));
        self.deferred.push((at, until_frame));
    }

    /// Notes an approach to `sample` that ended at `frame` with the rover at `from`.
    pub(crate) fn note_failed_approach(&mut self, sample: (f64, f64), frame: u64, from: (f64, f64)) {
        self.failed.push(FailedApproach { sample, frame, from });
    }

    /// Where the rover was when approaches to the rock at `at` failed.
    pub(crate) fn failed_from(&self, at: (f64, f64)) -> Vec<(f64, f64)> {
        self.failed.iter().filter(|f| same_rock(f.sample, at)).map(|f| f.from).collect()
    }

    /// Whether the rock at `at` is left alone at `frame` after [`SampleMemory::defer`].
    pub(crate) fn is_deferred(&self, at: (f64, f64), frame: u64) -> bool {
        self.deferred.iter().any(|&(rock, until)| same_rock(rock, at) && frame < until)
    }

    /// Whether the rock at `at` is ignored, or failed [`APPROACHES_PER_ROCK`] times within the
    /// last `retry_frames` before `frame`.
    pub(crate) fn is_ignored(&self, at: (f64, f64), frame: u64, retry_frames: u64) -> bool {
        let recent = |failed: u64| failed + retry_frames > frame;
        self.is_picked_up_or_given_up(at)
            || self.failed.iter().filter(|f| same_rock(f.sample, at) && recent(f.frame)).count() >= APPROACHES_PER_ROCK
    }

    /// Whether the rock at `at` was picked up or given up for good.
    pub(crate) fn is_picked_up_or_given_up(&self, at: (f64, f64)) -> bool {
        self.ignored.iter().any(|&p| same_rock(p, at))
    }

    /// Whether the rock at `at`, whatever its failed approaches, may be approached again now: it
    /// is neither picked up, given up for good nor deferred at `frame`, and fewer than
    /// [`APPROACHES_BEFORE_WAITING`] approaches to it have failed.
    pub(crate) fn may_retry_at_once(&self, at: (f64, f64), frame: u64) -> bool {
        let failures = self.failed.iter().filter(|f| same_rock(f.sample, at)).count();
        !self.is_picked_up_or_given_up(at) && !self.is_deferred(at, frame) && failures < APPROACHES_BEFORE_WAITING
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_rock_is_ignored_after_two_recent_failures_and_tried_again_later() {
        let mut memory = SampleMemory::default();
        let rock = (50.0, 60.0);
        let nearby = (50.0 + SAMPLE_SPREAD_M / 2.0, 60.0);
        memory.note_failed_approach(rock, 100, (47.0, 60.0));
        assert!(!memory.is_ignored(nearby, 110, 1000), "one failure");
        memory.note_failed_approach(nearby, 200, (50.0, 57.0));
        assert!(memory.is_ignored(rock, 210, 1000), "two failures of the same rock");
        assert!(!memory.is_ignored(rock, 1101, 1000), "both long ago: try again");
        assert_eq!(memory.failed_from(rock), vec![(47.0, 60.0), (50.0, 57.0)]);
        assert!(memory.failed_from((80.0, 60.0)).is_empty());
        assert!(memory.may_retry_at_once(rock, 210), "two failures: two more may follow at once");
        memory.note_failed_approach(rock, 220, (53.0, 60.0));
        memory.note_failed_approach(rock, 230, (50.0, 63.0));
        assert!(!memory.may_retry_at_once(rock, 240), "four failures: it waits its time");
    }

    #[test]
    fn picked_up_rocks_stay_ignored() {
        let mut memory = SampleMemory::default();
        memory.set_located(vec![(10.0, 10.0), (30.0, 30.0)]);
        memory.ignore((10.2, 10.0));
        assert!(memory.is_ignored((10.0, 10.0), 1_000_000, 1) && !memory.is_ignored((30.0, 30.0), 0, 1));
        assert!(!memory.may_retry_at_once((10.0, 10.0), 0), "picked up: never again");
        assert_eq!((memory.located().len(), memory.ignored()), (2, &[(10.2, 10.0)][..]));
    }

    #[test]
    fn a_deferred_rock_is_left_alone_until_its_time() {
        let mut memory = SampleMemory::default();
        memory.defer((10.0, 10.0), 500);
        memory.defer((10.5, 10.0), 300);
        assert!(memory.is_deferred((10.0, 10.0), 299), "the later deferral replaces the earlier one");
        assert!(!memory.is_deferred((10.0, 10.0), 300) && !memory.is_deferred((30.0, 30.0), 0));
        assert!(!memory.is_ignored((10.0, 10.0), 0, 1), "deferred, not ignored");
        assert!(!memory.may_retry_at_once((10.0, 10.0), 299) && memory.may_retry_at_once((10.0, 10.0), 500));
    }
}
