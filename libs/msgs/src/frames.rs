//! Frame numbers of one mission. The bridge numbers its lock-step frames from 1, and a restarted
//! bridge starts again from 1; a node that times things in frames counts on across such restarts.

use crate::validate::MAX_FRAME;

/// Turns the bridge's frame numbers into mission frame numbers that never go back.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct MissionFrames {
    /// The last bridge frame and the mission frame it became.
    last: Option<(u64, u64)>,
}

impl MissionFrames {
    /// Carries on from `last`, the last (bridge frame, mission frame) of an earlier count (e.g. a
    /// restarted node's snapshot).
    pub fn resumed(last: Option<(u64, u64)>) -> Self {
        MissionFrames { last }
    }

    /// The last (bridge frame, mission frame), once a frame was counted.
    pub fn last(&self) -> Option<(u64, u64)> {
        self.last
    }

    /// The mission frame of bridge frame `frame`: while the bridge's numbers go up, they go up
    /// alike; when they go back (a new bridge), the mission goes on from one past its last frame.
    /// It stops at [`MAX_FRAME`], so that nodes can add timeouts in frames to it.
    pub fn of(&mut self, frame: u64) -> u64 {
        let mission = match self.last {
            None => frame,
            Some((bridge, mission)) if frame >= bridge => mission.saturating_add(frame - bridge),
            Some((_, mission)) => mission.saturating_add(1),
        }
        .min(MAX_FRAME);
        self.last = Some((frame, mission));
        mission
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_count_on_across_a_new_bridge() {
        let mut frames = MissionFrames::default();
        assert_eq!([5, 6, 6, 9].map(|f| frames.of(f)), [5, 6, 6, 9], "the bridge's own numbers while they go up");
        assert_eq!([1, 2, 4].map(|f| frames.of(f)), [10, 11, 13], "a new bridge's frames follow the last one");
        assert_eq!(frames.of(MAX_FRAME), MAX_FRAME);
        assert_eq!(frames.of(0), MAX_FRAME, "stops at the largest frame a message may carry");
        let mut alternating = MissionFrames::default();
        let last = (0..10_000).map(|i| alternating.of(if i % 2 == 0 { MAX_FRAME } else { 0 })).last();
        assert_eq!(last, Some(MAX_FRAME), "frames that jump up and back never pass it");
    }
}
