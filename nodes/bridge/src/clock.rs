//! Simulated time. The simulator sends no time, so the bridge counts its telemetry frames: frame `n`
//! happens at `n` times the frame period. The bridge publishes it on `/clock` and, with
//! `use_sim_time`, stamps its messages with it.

use std::sync::atomic::{AtomicU64, Ordering};

use rover_msgs::builtin_interfaces::Time;
use rover_msgs::rosgraph_msgs::Clock;

/// The bridge's clock: simulated time from frame numbers, and the stamps it gives messages.
#[derive(Debug)]
pub(crate) struct SimClock {
    frame_period_ns: u64,
    use_sim_time: bool,
    latest_frame: AtomicU64,
}

impl SimClock {
    /// A clock whose frames are `frame_period_s` apart; stamps are simulated when `use_sim_time`.
    pub(crate) fn new(frame_period_s: f64, use_sim_time: bool) -> Self {
        SimClock {
            frame_period_ns: (frame_period_s * 1e9).round() as u64,
            use_sim_time,
            latest_frame: AtomicU64::new(0),
        }
    }

    /// The `/clock` message of frame `frame` (numbered from 1, so the clock never reads zero).
    pub(crate) fn clock_message(&self, frame: u64) -> Clock {
        Clock { clock: self.sim_time(frame) }
    }

    /// Notes `frame` as the latest and returns the stamp of its messages.
    pub(crate) fn stamp_frame(&self, frame: u64) -> Time {
        self.latest_frame.fetch_max(frame, Ordering::Relaxed);
        if self.use_sim_time { self.sim_time(frame) } else { Time::now() }
    }

    /// The stamp of a message not tied to a frame: the latest frame's simulated time, or the wall clock.
    pub(crate) fn now(&self) -> Time {
        if self.use_sim_time { self.sim_time(self.latest_frame.load(Ordering::Relaxed)) } else { Time::now() }
    }

    fn sim_time(&self, frame: u64) -> Time {
        Time::from_nanos(frame.saturating_mul(self.frame_period_ns).min(i64::MAX as u64) as i64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_n_is_n_periods_after_the_start() {
        let clock = SimClock::new(0.04, true);
        assert_eq!(clock.clock_message(1).clock, Time { sec: 0, nanosec: 40_000_000 });
        assert_eq!(clock.clock_message(2_501).clock, Time { sec: 100, nanosec: 40_000_000 });
    }

    #[test]
    fn with_sim_time_stamps_follow_the_latest_frame() {
        let clock = SimClock::new(0.04, true);
        assert_eq!(clock.now(), Time { sec: 0, nanosec: 0 });
        assert_eq!(clock.stamp_frame(50), Time { sec: 2, nanosec: 0 });
        assert_eq!(clock.stamp_frame(25), Time { sec: 1, nanosec: 0 }, "a late frame keeps its own time");
        assert_eq!(clock.now(), Time { sec: 2, nanosec: 0 });
    }

    #[test]
    fn without_sim_time_stamps_are_wall_clock() {
        let clock = SimClock::new(0.04, false);
        let year_2020_s = 1_577_836_800;
        assert!(clock.stamp_frame(50).sec > year_2020_s);
        assert!(clock.now().sec > year_2020_s);
        assert_eq!(clock.clock_message(50).clock, Time { sec: 2, nanosec: 0 }, "/clock is simulated time anyway");
    }
}
