//! Samples collected, counted from the `samples_remaining` of successive `rover/telemetry` frames.

/// A running count of collected samples.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SampleTally {
    last_remaining: Option<u8>,
    collected: u32,
}

impl SampleTally {
    /// A tally that starts from `collected` samples (e.g. taken over from an earlier node).
    pub fn starting_at(collected: u32) -> Self {
        SampleTally { last_remaining: None, collected }
    }

    /// A tally that carries on from `collected` samples with `samples_remaining` in the last frame
    /// it followed (e.g. restored from a snapshot: pickups since then still count).
    pub fn resumed(collected: u32, last_remaining: Option<u8>) -> Self {
        SampleTally { last_remaining, collected }
    }

    /// `samples_remaining` of the last frame followed, if any.
    pub fn last_remaining(&self) -> Option<u8> {
        self.last_remaining
    }

    /// Follows one frame's `samples_remaining`; returns how many samples were picked up since the
    /// previous frame.
    pub fn update(&mut self, samples_remaining: u8) -> u32 {
        let picked = self.last_remaining.map_or(0, |last| u32::from(last.saturating_sub(samples_remaining)));
        self.last_remaining = Some(samples_remaining);
        self.collected = self.collected.saturating_add(picked);
        picked
    }

    /// Samples collected so far.
    pub fn collected(&self) -> u32 {
        self.collected
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_decrements_only() {
        let mut tally = SampleTally::starting_at(1);
        assert_eq!(tally.update(5), 0, "the first frame sets the baseline");
        assert_eq!(tally.update(4), 1);
        assert_eq!(tally.update(4), 0);
        assert_eq!(tally.update(6), 0, "a restarted simulator does not count");
        assert_eq!(tally.update(3), 3);
        assert_eq!(tally.collected(), 5);
    }

    #[test]
    fn a_count_taken_over_from_a_message_cannot_overflow() {
        let mut tally = SampleTally::starting_at(u32::MAX);
        tally.update(2);
        tally.update(1);
        assert_eq!(tally.collected(), u32::MAX);
    }
}
