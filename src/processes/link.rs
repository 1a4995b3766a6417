//! An impaired network link, packet by packet: one-way delay, jitter and loss, as `netem` would
//! apply them (this kernel has no `netem`). Packets keep their order: one that would overtake the
//! packet before it leaves right after it instead, as on a Wi-Fi link.

use std::time::{Duration, Instant};

use rover_sim::random::SplitMix64;

/// What the link does to every packet in one direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Impairment {
    /// Mean one-way delay.
    pub delay: Duration,
    /// Each packet's delay is the mean plus a uniform draw in [-jitter, +jitter].
    pub jitter: Duration,
    /// Share of packets lost, percent.
    pub loss_pct: f64,
    /// From this instant on every packet is lost: the link is cut (`None`: never).
    pub cut_at: Option<Instant>,
}

/// What became of the packets of one direction so far.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LinkCounts {
    /// Packets that entered the link.
    pub packets: u64,
    /// Packets dropped.
    pub lost: u64,
    /// Bytes of all packets that entered the link.
    pub bytes: u64,
}

/// One direction of an impaired link: decides each packet's fate.
#[derive(Debug, Clone)]
pub struct Direction {
    impairment: Impairment,
    random: SplitMix64,
    last_departure: Option<Instant>,
    counts: LinkCounts,
}

impl Direction {
    /// A direction applying `impairment`, its draws seeded by `seed`.
    pub fn new(impairment: Impairment, seed: u64) -> Self {
        Direction { impairment, random: SplitMix64::new(seed), last_departure: None, counts: LinkCounts::default() }
    }

    /// When a packet of `bytes` that entered the link at `arrival` leaves it, or `None` when it
    /// is lost.
    pub fn departure(&mut self, arrival: Instant, bytes: usize) -> Option<Instant> {
        self.counts.packets += 1;
        self.counts.bytes += bytes as u64;
        let cut = self.impairment.cut_at.is_some_and(|at| arrival >= at);
        if cut || self.random.unit() * 100.0 < self.impairment.loss_pct {
            self.counts.lost += 1;
            return None;
        }
        let jitter_s = self.impairment.jitter.as_secs_f64() * self.random.range(-1.0, 1.0);
        let delay_s = (self.impairment.delay.as_secs_f64() + jitter_s).max(0.0);
        let departure = (arrival + Duration::from_secs_f64(delay_s)).max(self.last_departure.unwrap_or(arrival));
        self.last_departure = Some(departure);
        Some(departure)
    }

    /// The packets seen and lost so far.
    pub fn counts(&self) -> LinkCounts {
        self.counts
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn impairment(delay_ms: u64, jitter_ms: u64, loss_pct: f64) -> Impairment {
        Impairment {
            delay: Duration::from_millis(delay_ms),
            jitter: Duration::from_millis(jitter_ms),
            loss_pct,
            cut_at: None,
        }
    }

    #[test]
    fn packets_are_delayed_within_the_jitter_and_never_reordered() {
        let mut link = Direction::new(impairment(10, 2, 0.0), 7);
        let start = Instant::now();
        let mut last = start;
        let (mut shortest, mut longest) = (Duration::MAX, Duration::ZERO);
        for i in 0..10_000u64 {
            let arrival = start + Duration::from_micros(50 * i);
            let departure = link.departure(arrival, 100).expect("no loss asked");
            assert!(departure >= last, "packet {i} overtook the one before it");
            last = departure;
            let delay = departure - arrival;
            (shortest, longest) = (shortest.min(delay), longest.max(delay));
        }
        assert!(shortest >= Duration::from_millis(8), "{shortest:?}");
        assert!(longest <= Duration::from_millis(13), "{longest:?}");
        assert!(longest > Duration::from_millis(11), "the jitter spreads the delays: {longest:?}");
    }

    #[test]
    fn the_share_lost_is_the_share_asked() {
        let mut link = Direction::new(impairment(0, 0, 1.0), 3);
        let now = Instant::now();
        let delivered = (0..100_000).filter(|_| link.departure(now, 100).is_some()).count();
        let counts = link.counts();
        assert_eq!((counts.packets, counts.bytes), (100_000, 10_000_000));
        assert_eq!(counts.lost as usize, 100_000 - delivered);
        assert!((800..1200).contains(&counts.lost), "{counts:?}");
    }

    #[test]
    fn a_cut_link_loses_every_packet_from_the_cut_on() {
        let start = Instant::now();
        let cut_at = start + Duration::from_secs(1);
        let mut link = Direction::new(Impairment { cut_at: Some(cut_at), ..impairment(5, 0, 0.0) }, 2);
        assert!(link.departure(start, 100).is_some());
        assert!(link.departure(cut_at - Duration::from_millis(1), 100).is_some());
        assert!((0..100).all(|i| link.departure(cut_at + Duration::from_millis(i), 100).is_none()));
        assert_eq!(link.counts().lost, 100);
    }

    #[test]
    fn an_unimpaired_link_passes_every_packet_at_once() {
        let mut link = Direction::new(impairment(0, 0, 0.0), 1);
        let now = Instant::now();
        assert!((0..1000).all(|_| link.departure(now, 100) == Some(now)));
    }
}
