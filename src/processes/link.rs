//! An impaired network link, packet by packet: one-way delay, jitter and loss, as `netem` would
//! apply them (this kernel has no `netem`), and a cut after a number of packets. Packets keep their
//! order: one that would overtake the packet before it leaves right after it instead, as on a
//! Wi-Fi link.

use std::time::{Duration, Instant};

use rover_sim::random::SplitMix64;

/// What the link does to the packets.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Impairment {
    /// Mean one-way delay.
    pub delay: Duration,
    /// Each packet's delay is the mean plus a uniform draw in [-jitter, +jitter].
    pub jitter: Duration,
    /// Share of packets lost in each direction, percent.
    pub loss_pct: f64,
    /// Once this many packets have entered the link, both directions together, every later packet
    /// is lost: the link is cut (`None`: never). Counted in packets, not seconds, so that the cut
    /// lands at the same point of a lock-step mission on a fast machine as on a slow one.
    pub cut_after_packets: Option<u64>,
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

/// One of the link's two directions (its index into [`Link`]'s directions).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Way {
    /// From end a to end b.
    AToB = 0,
    /// From end b to end a.
    BToA = 1,
}

/// Both directions of an impaired link: decides each packet's fate.
#[derive(Debug, Clone)]
pub struct Link {
    impairment: Impairment,
    directions: [Direction; 2],
}

/// The draws, the last departure and the counts of one direction.
#[derive(Debug, Clone)]
struct Direction {
    random: SplitMix64,
    last_departure: Option<Instant>,
    counts: LinkCounts,
}

impl Link {
    /// A link applying `impairment`, its draws seeded by `seed` (a to b) and `seed + 1` (b to a).
    pub fn new(impairment: Impairment, seed: u64) -> Self {
        let direction =
            |seed| Direction { random: SplitMix64::new(seed), last_departure: None, counts: LinkCounts::default() };
        Link { impairment, directions: [direction(seed), direction(seed.wrapping_add(1))] }
    }

    /// When a packet of `bytes` that entered the link going `way` at `arrival` leaves it, or
    /// `None` when it is lost.
    pub fn departure(&mut self, way: Way, arrival: Instant, bytes: usize) -> Option<Instant> {
        let cut = self.impairment.cut_after_packets.is_some_and(|limit| self.packets() >= limit);
        let impairment = self.impairment;
        let direction = &mut self.directions[way as usize];
        direction.counts.packets += 1;
        direction.counts.bytes += bytes as u64;
        if cut || direction.random.unit() * 100.0 < impairment.loss_pct {
            direction.counts.lost += 1;
            return None;
        }
        let jitter_s = impairment.jitter.as_secs_f64() * direction.random.range(-1.0, 1.0);
        let delay_s = (impairment.delay.as_secs_f64() + jitter_s).max(0.0);
        let departure = (arrival + Duration::from_secs_f64(delay_s)).max(direction.last_departure.unwrap_or(arrival));
        direction.last_departure = Some(departure);
        Some(departure)
    }

    /// The packets seen and lost so far going `way`.
    pub fn counts(&self, way: Way) -> LinkCounts {
        self.directions[way as usize].counts
    }

    /// The packets that entered the link so far, both ways together.
    fn packets(&self) -> u64 {
        self.directions.iter().map(|d| d.counts.packets).sum()
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
            cut_after_packets: None,
        }
    }

    #[test]
    fn packets_are_delayed_within_the_jitter_and_never_reordered() {
        let mut link = Link::new(impairment(10, 2, 0.0), 7);
        let start = Instant::now();
        let mut last = start;
        let (mut shortest, mut longest) = (Duration::MAX, Duration::ZERO);
        for i in 0..10_000u64 {
            let arrival = start + Duration::from_micros(50 * i);
            let departure = link.departure(Way::AToB, arrival, 100).expect("no loss asked");
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
        let mut link = Link::new(impairment(0, 0, 1.0), 3);
        let now = Instant::now();
        let delivered = (0..100_000).filter(|_| link.departure(Way::BToA, now, 100).is_some()).count();
        let counts = link.counts(Way::BToA);
        assert_eq!((counts.packets, counts.bytes), (100_000, 10_000_000));
        assert_eq!(counts.lost as usize, 100_000 - delivered);
        assert!((800..1200).contains(&counts.lost), "{counts:?}");
        assert_eq!(link.counts(Way::AToB), LinkCounts::default());
    }

    #[test]
    fn a_cut_link_loses_every_packet_both_ways_once_the_count_is_reached() {
        let mut link = Link::new(Impairment { cut_after_packets: Some(3), ..impairment(5, 0, 0.0) }, 2);
        let now = Instant::now();
        assert!(link.departure(Way::AToB, now, 100).is_some());
        assert!(link.departure(Way::BToA, now, 100).is_some());
        assert!(link.departure(Way::AToB, now, 100).is_some());
        assert!((0..50).all(|_| link.departure(Way::AToB, now, 100).is_none()));
        assert!((0..50).all(|_| link.departure(Way::BToA, now, 100).is_none()));
        assert_eq!((link.counts(Way::AToB).lost, link.counts(Way::BToA).lost), (50, 50));
    }

    #[test]
    fn an_unimpaired_link_passes_every_packet_at_once() {
        let mut link = Link::new(impairment(0, 0, 0.0), 1);
        let now = Instant::now();
        assert!((0..1000).all(|_| link.departure(Way::AToB, now, 100) == Some(now)));
    }
}
