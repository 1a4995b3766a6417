//! DDS Security handshakes that do not complete. RustDDS stops resending a handshake message after
//! ten tries a second apart and never starts that handshake again, and its handshake reader keeps
//! only the latest message of a burst, so a handshake can be lost for good: the two participants
//! stay deaf to each other until one of them restarts. The process says so, once per remote.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

/// How long a handshake may take before it is reported as stalled.
pub(crate) const STALLED_AFTER: Duration = Duration::from_secs(20);

/// The handshakes under way with remote participants, by their GUID prefix.
#[derive(Debug, Default)]
pub(crate) struct Handshakes {
    /// Since when each remote has been authenticating, and whether it was reported.
    pending: BTreeMap<String, (Instant, bool)>,
}

impl Handshakes {
    /// Notes the authentication status of `remote` at `now`, named as RustDDS names it
    /// (`Authenticating`, `Authenticated`, `Rejected`, ...).
    pub(crate) fn note(&mut self, remote: String, status: &str, now: Instant) {
        if status == "Authenticating" {
            self.pending.entry(remote).or_insert((now, false));
        } else {
            self.pending.remove(&remote);
        }
    }

    /// The remotes authenticating for [`STALLED_AFTER`] or more at `now` that were not reported
    /// yet; each is reported once.
    pub(crate) fn newly_stalled(&mut self, now: Instant) -> Vec<String> {
        let stalled = self
            .pending
            .iter_mut()
            .filter(|(_, (since, reported))| !*reported && now.saturating_duration_since(*since) >= STALLED_AFTER);
        stalled
            .map(|(remote, (_, reported))| {
                *reported = true;
                remote.clone()
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_handshake_pending_too_long_is_reported_once_and_a_completed_one_never() {
        let start = Instant::now();
        let mut handshakes = Handshakes::default();
        handshakes.note("a".into(), "Authenticating", start);
        handshakes.note("b".into(), "Authenticating", start);
        handshakes.note("b".into(), "Authenticated", start + Duration::from_secs(2));
        assert!(handshakes.newly_stalled(start + STALLED_AFTER - Duration::from_secs(1)).is_empty(), "not yet");
        assert_eq!(handshakes.newly_stalled(start + STALLED_AFTER), ["a"]);
        assert!(handshakes.newly_stalled(start + 2 * STALLED_AFTER).is_empty(), "reported once");
        handshakes.note("a".into(), "Authenticating", start + 2 * STALLED_AFTER);
        assert!(handshakes.newly_stalled(start + 3 * STALLED_AFTER).is_empty(), "still the same handshake");
    }
}
