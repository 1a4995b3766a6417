//! How steadily the machine's cores run: a fixed piece of work, timed every [`PERIOD`] on a
//! thread of its own (about 2 % of a core). On a shared virtual machine the host can slow a core
//! to a half or a quarter for tens of milliseconds, with or without our processes running; every
//! process is slow at once then, and a latency measured across such a spell tells about the host
//! more than about the program.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Time between two pieces of work.
pub const PERIOD: Duration = Duration::from_millis(2);
/// A piece of work that takes more than this many times the median marks a slow spell.
pub const SLOW_FACTOR: f64 = 2.0;
/// Rounds of the work: about 40 us on this machine's cores at full speed.
const WORK_ROUNDS: u32 = 20_000;

/// One timed piece of work.
#[derive(Debug, Clone, Copy)]
struct Slot {
    at: Instant,
    took: Duration,
}

/// The work being timed in the background, until [`Steadiness::finish`].
pub struct Steadiness {
    stop: Arc<AtomicBool>,
    thread: JoinHandle<Vec<Slot>>,
}

impl Steadiness {
    /// Starts timing.
    pub fn start() -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let stopped = Arc::clone(&stop);
        let thread = std::thread::spawn(move || {
            let mut slots = Vec::new();
            while !stopped.load(Ordering::Relaxed) {
                let at = Instant::now();
                std::hint::black_box(fixed_work(slots.len() as u64));
                slots.push(Slot { at, took: at.elapsed() });
                std::thread::sleep(PERIOD);
            }
            slots
        });
        Steadiness { stop, thread }
    }

    /// Stops timing and returns what was seen.
    pub fn finish(self) -> SteadinessRecord {
        self.stop.store(true, Ordering::Relaxed);
        let slots = self.thread.join().expect("the steadiness thread does not panic");
        SteadinessRecord::of(slots)
    }
}

/// A xorshift run of [`WORK_ROUNDS`] steps from `seed`: work the compiler cannot skip.
fn fixed_work(seed: u64) -> u64 {
    let mut x = seed | 1;
    for _ in 0..WORK_ROUNDS {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
    }
    x
}

/// The timed pieces of work of a run.
pub struct SteadinessRecord {
    slots: Vec<Slot>,
    median: Duration,
}

impl SteadinessRecord {
    fn of(slots: Vec<Slot>) -> Self {
        let mut took: Vec<Duration> = slots.iter().map(|s| s.took).collect();
        took.sort();
        let median = took.get(took.len() / 2).copied().unwrap_or_default();
        SteadinessRecord { slots, median }
    }

    /// The median time of the work.
    pub fn median(&self) -> Duration {
        self.median
    }

    /// How many pieces of work were timed.
    pub fn slots(&self) -> usize {
        self.slots.len()
    }

    /// The share of the pieces of work that took over [`SLOW_FACTOR`] times the median.
    pub fn slow_share(&self) -> f64 {
        let slow = self.slots.iter().filter(|s| self.is_slow(s)).count();
        slow as f64 / self.slots.len().max(1) as f64
    }

    /// Whether a slow piece of work stands for a moment between `from` and `to`: each stands for
    /// the time until the next one starts.
    pub fn slowed(&self, from: Instant, to: Instant) -> bool {
        let first = self.slots.partition_point(|s| s.at <= from).saturating_sub(1);
        self.slots[first..].iter().take_while(|s| s.at <= to).any(|s| self.is_slow(s))
    }

    fn is_slow(&self, slot: &Slot) -> bool {
        slot.took.as_secs_f64() > SLOW_FACTOR * self.median.as_secs_f64()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(took_us: &[u64]) -> (Instant, SteadinessRecord) {
        let start = Instant::now();
        let slots = took_us
            .iter()
            .enumerate()
            .map(|(i, &us)| Slot { at: start + PERIOD * i as u32, took: Duration::from_micros(us) })
            .collect();
        (start, SteadinessRecord::of(slots))
    }

    #[test]
    fn spells_are_work_over_twice_the_median_and_cover_what_overlaps_them() {
        let (start, record) = record(&[40, 41, 40, 150, 120, 40, 39, 40]);
        assert_eq!(record.median(), Duration::from_micros(40));
        assert_eq!(record.slow_share(), 0.25);
        let ms = |m: u64| start + Duration::from_millis(m);
        assert!(!record.slowed(ms(0), ms(5)), "slots 0-2 are steady");
        assert!(record.slowed(ms(5), ms(7)), "slot 3 (6 ms) is slow");
        assert!(record.slowed(ms(9), ms(9)), "slot 4 (8 ms) started before and was slow");
        assert!(!record.slowed(ms(10), ms(15)), "slots 5-7 are steady");
    }

    #[test]
    fn the_work_is_timed_while_running() {
        let steadiness = Steadiness::start();
        std::thread::sleep(Duration::from_millis(50));
        let record = steadiness.finish();
        assert!(record.slots() >= 5, "{} slots in 50 ms", record.slots());
        assert!(record.median() > Duration::ZERO);
    }
}
