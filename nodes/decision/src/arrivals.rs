//! Maps and rocks take effect a fixed number of frames after the scan they include, so that the
//! machine decides alike whether they reach it at once (in process) or a frame or two later, when
//! the mapping node's DDS messages happen to come in (the graph).

use std::collections::VecDeque;

/// Frames between the scan that a map (or a list of rocks) includes and the first frame decided
/// with it. In the graph the map of frame `f` reaches the decision node while frame `f + 1` is on
/// its way, well before `f + 3` (each frame is a full lock-step round trip).
pub(crate) const ARRIVAL_DELAY_FRAMES: u64 = 3;
/// At most this many values wait; beyond, the oldest is dropped. While frames are decided one or
/// two wait; more pile up only while none is but maps still come (scans that this node rejects
/// and the mapping node maps), and then the newest are the ones that matter.
const MAX_WAITING: usize = 8;

/// Values waiting for their frame, oldest first.
#[derive(Debug, Clone)]
pub(crate) struct Delayed<T> {
    waiting: VecDeque<(u64, T)>,
}

impl<T> Default for Delayed<T> {
    fn default() -> Self {
        Delayed { waiting: VecDeque::new() }
    }
}

/// Whether a value made at mission frame `made_at` is in effect at `frame`.
fn due_at(made_at: u64, frame: u64) -> bool {
    made_at.saturating_add(ARRIVAL_DELAY_FRAMES) <= frame
}

impl<T> Delayed<T> {
    /// Keeps `value`, made from the scans up to mission frame `made_at_frame`, until it is due.
    pub(crate) fn push(&mut self, made_at_frame: u64, value: T) {
        if self.waiting.len() == MAX_WAITING {
            self.waiting.pop_front();
        }
        self.waiting.push_back((made_at_frame, value));
    }

    /// The newest value due at `frame`: the one [`Delayed::take_due`] would take.
    pub(crate) fn newest_due(&self, frame: u64) -> Option<&T> {
        self.due_count(frame).checked_sub(1).and_then(|last| self.waiting.get(last)).map(|(_, value)| value)
    }

    /// The newest value due at `frame` and the frame it was made at (older due ones are dropped:
    /// each value is a whole state).
    pub(crate) fn take_due(&mut self, frame: u64) -> Option<(u64, T)> {
        let due = self.due_count(frame);
        self.waiting.drain(..due).last()
    }

    /// How many values, from the oldest on, are due at `frame`.
    fn due_count(&self, frame: u64) -> usize {
        self.waiting.iter().take_while(|&&(made_at, _)| due_at(made_at, frame)).count()
    }
}

/// When maps come: the mapping node makes one every so many scans, so the frames of the last two
/// maps taken tell when the next one will take effect.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct MapCadence {
    last_made_at: Option<u64>,
    frames_between: Option<u64>,
}

impl MapCadence {
    /// Notes that the map made at mission frame `made_at` took effect.
    pub(crate) fn record(&mut self, made_at: u64) {
        if let Some(last) = self.last_made_at.filter(|&last| last < made_at) {
            self.frames_between = Some(made_at - last);
        }
        self.last_made_at = Some(made_at);
    }

    /// The frame on which the next map will take effect if it comes as often as the last did.
    pub(crate) fn next_due(&self) -> Option<u64> {
        let made_at = self.last_made_at?.checked_add(self.frames_between?)?;
        made_at.checked_add(ARRIVAL_DELAY_FRAMES)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_value_takes_effect_the_delay_after_its_frame_and_the_newest_due_wins() {
        let mut maps = Delayed::default();
        maps.push(10, "a");
        maps.push(11, "b");
        maps.push(20, "c");
        assert_eq!(maps.newest_due(10 + ARRIVAL_DELAY_FRAMES - 1), None);
        assert_eq!(maps.newest_due(10 + ARRIVAL_DELAY_FRAMES), Some(&"a"));
        assert_eq!(maps.take_due(10 + ARRIVAL_DELAY_FRAMES - 1), None);
        assert_eq!(maps.newest_due(11 + ARRIVAL_DELAY_FRAMES), Some(&"b"));
        assert_eq!(maps.take_due(11 + ARRIVAL_DELAY_FRAMES), Some((11, "b")), "a is superseded");
        assert_eq!(maps.take_due(19 + ARRIVAL_DELAY_FRAMES), None);
        assert_eq!(maps.take_due(20 + ARRIVAL_DELAY_FRAMES), Some((20, "c")));
        assert_eq!(maps.take_due(u64::MAX), None);
    }

    #[test]
    fn values_waiting_while_no_frame_is_decided_are_bounded_and_the_newest_kept() {
        let mut maps = Delayed::default();
        for frame in 0..100 {
            maps.push(frame, frame);
        }
        assert_eq!(maps.waiting.len(), MAX_WAITING);
        assert_eq!(maps.take_due(u64::MAX), Some((99, 99)));
    }

    #[test]
    fn a_value_that_arrives_late_takes_effect_at_the_next_frame() {
        let mut rocks = Delayed::default();
        rocks.push(5, 1);
        assert_eq!(rocks.take_due(100), Some((5, 1)));
    }

    #[test]
    fn the_next_map_is_expected_as_long_after_the_last_as_that_one_after_the_one_before() {
        let mut cadence = MapCadence::default();
        assert_eq!(cadence.next_due(), None, "no map yet");
        cadence.record(25);
        assert_eq!(cadence.next_due(), None, "one map: no cadence yet");
        cadence.record(50);
        assert_eq!(cadence.next_due(), Some(75 + ARRIVAL_DELAY_FRAMES));
        cadence.record(80);
        assert_eq!(cadence.next_due(), Some(110 + ARRIVAL_DELAY_FRAMES));
        cadence.record(80);
        assert_eq!(cadence.next_due(), Some(110 + ARRIVAL_DELAY_FRAMES), "the same map again keeps the cadence");
    }
}
