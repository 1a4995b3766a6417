//! How a mission progressed: when each sample was collected and how much of the world was mapped
//! at every hundredth simulated second, so that one can see which stretch of a mission added
//! nothing (the same ground crossed again, a region left for later).

use serde::Serialize;

/// Simulated seconds between two entries of [`Timeline::mapped_pct_by_100_s`].
pub const MAPPED_EVERY_S: f64 = 100.0;

/// A mission's progress over simulated time.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Timeline {
    /// Simulated seconds at which each sample was collected, in order.
    pub collected_at_s: Vec<f64>,
    /// Mapped % at 100, 200, 300 ... simulated seconds.
    pub mapped_pct_by_100_s: Vec<f64>,
}

impl Timeline {
    /// Notes the mission's state at `sim_s`: `mapped_pct` mapped, `collected` samples collected.
    /// Calls come in the order of simulated time; the mapped % is taken at the first call at or
    /// past each whole hundred seconds.
    pub fn note(&mut self, sim_s: f64, mapped_pct: f64, collected: usize) {
        while self.collected_at_s.len() < collected {
            self.collected_at_s.push(sim_s);
        }
        while sim_s >= MAPPED_EVERY_S * (self.mapped_pct_by_100_s.len() + 1) as f64 {
            self.mapped_pct_by_100_s.push(mapped_pct);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn collections_are_timed_and_the_map_read_every_hundred_seconds() {
        let mut timeline = Timeline::default();
        timeline.note(40.0, 10.0, 0);
        timeline.note(99.96, 19.0, 1);
        timeline.note(100.0, 20.0, 1);
        timeline.note(150.0, 30.0, 3);
        timeline.note(320.0, 55.0, 3);
        assert_eq!(timeline.collected_at_s, vec![99.96, 150.0, 150.0]);
        assert_eq!(timeline.mapped_pct_by_100_s, vec![20.0, 55.0, 55.0], "a gap repeats the value after it");
        let json = serde_json::to_value(&timeline).unwrap();
        assert_eq!(json["collected_at_s"][0], 99.96);
        assert_eq!(json["mapped_pct_by_100_s"].as_array().map(Vec::len), Some(3));
    }
}
