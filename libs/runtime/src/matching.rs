//! Which remote readers and writers the endpoints of a process have matched, from the DDS
//! participant's status events; and, from the same events, the DDS Security handshakes that do
//! not complete, each logged once. A participant has one status channel, so the process reads it
//! once, here, for all its nodes.

use std::collections::{BTreeMap, BTreeSet};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use futures::StreamExt;
use ros2_client::dds::rustdds::{DomainParticipant, DomainParticipantStatusEvent, GUID, StatusEvented};
use tokio::sync::watch;

use crate::handshakes::{Handshakes, STALLED_AFTER};
use crate::sync::lock;

/// How often handshakes are checked for stalling.
const HANDSHAKE_CHECK_PERIOD: Duration = Duration::from_secs(5);

/// The remote endpoints matched by each local endpoint of one participant.
#[derive(Clone)]
pub(crate) struct Matches {
    matched: Arc<Mutex<BTreeMap<GUID, BTreeSet<GUID>>>>,
    changes: watch::Receiver<u64>,
}

impl Matches {
    /// Follows the status events of `participant` in a task of the current tokio runtime until
    /// the participant's status channel closes.
    pub(crate) fn follow(participant: &DomainParticipant) -> Self {
        let matched = Arc::new(Mutex::new(BTreeMap::new()));
        let (sender, changes) = watch::channel(0);
        let listener = participant.status_listener();
        let table = Arc::clone(&matched);
        tokio::spawn(async move {
            let mut events = std::pin::pin!(listener.as_async_status_stream());
            let mut handshakes = Handshakes::default();
            let mut checks = tokio::time::interval(HANDSHAKE_CHECK_PERIOD);
            loop {
                tokio::select! {
                    event = events.next() => {
                        let Some(event) = event else { break };
                        if let DomainParticipantStatusEvent::Authentication { participant, status } = &event {
                            handshakes.note(format!("{participant:?}"), &format!("{status:?}"), Instant::now());
                        }
                        if apply(&mut lock(&table), event) {
                            sender.send_modify(|version| *version += 1);
                        }
                    }
                    _ = checks.tick() => warn_stalled(&mut handshakes),
                }
            }
        });
        Matches { matched, changes }
    }

    /// How many remote endpoints `local` has matched.
    pub(crate) fn count(&self, local: GUID) -> usize {
        lock(&self.matched).get(&local).map_or(0, BTreeSet::len)
    }

    /// Resolves once `local` has matched a remote endpoint (at once if it has).
    pub(crate) async fn first(&self, local: GUID) {
        let mut changes = self.changes.clone();
        while self.count(local) == 0 {
            if changes.changed().await.is_err() {
                std::future::pending::<()>().await;
            }
        }
    }
}

/// Logs the handshakes that have newly stalled.
fn warn_stalled(handshakes: &mut Handshakes) {
    for remote in handshakes.newly_stalled(Instant::now()) {
        tracing::warn!(
            "DDS Security: no handshake with participant {remote} within {} s: its certificate is from another \
             CA, or the handshake was lost (RustDDS does not try again); restart one of the two if they should talk",
            STALLED_AFTER.as_secs()
        );
    }
}

/// Applies one status event to `matched`; returns whether a match came or went.
fn apply(matched: &mut BTreeMap<GUID, BTreeSet<GUID>>, event: DomainParticipantStatusEvent) -> bool {
    use DomainParticipantStatusEvent as Event;
    match event {
        Event::RemoteReaderMatched { local_writer: local, remote_reader: remote }
        | Event::RemoteWriterMatched { local_reader: local, remote_writer: remote } => {
            matched.entry(local).or_default().insert(remote)
        }
        Event::ReaderLost { guid, .. } | Event::WriterLost { guid, .. } => {
            let mut removed = false;
            for remotes in matched.values_mut() {
                removed |= remotes.remove(&guid);
            }
            removed
        }
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use ros2_client::dds::rustdds::LostReason;

    use super::*;

    fn guid(n: u8) -> GUID {
        GUID::from_bytes([n; 16])
    }

    #[test]
    fn matches_come_with_the_match_events_and_go_with_the_lost_remote() {
        let mut matched = BTreeMap::new();
        let (writer, reader, remote_a, remote_b) = (guid(1), guid(2), guid(3), guid(4));
        assert!(apply(
            &mut matched,
            DomainParticipantStatusEvent::RemoteReaderMatched { local_writer: writer, remote_reader: remote_a }
        ));
        assert!(apply(
            &mut matched,
            DomainParticipantStatusEvent::RemoteReaderMatched { local_writer: writer, remote_reader: remote_b }
        ));
        assert!(apply(
            &mut matched,
            DomainParticipantStatusEvent::RemoteWriterMatched { local_reader: reader, remote_writer: remote_a }
        ));
        assert!(!apply(
            &mut matched,
            DomainParticipantStatusEvent::RemoteWriterMatched { local_reader: reader, remote_writer: remote_a }
        ));
        assert_eq!((matched[&writer].len(), matched[&reader].len()), (2, 1));
        let lost = DomainParticipantStatusEvent::ReaderLost { guid: remote_a, reason: LostReason::Disposed };
        assert!(apply(&mut matched, lost));
        assert_eq!((matched[&writer].len(), matched[&reader].len()), (1, 0), "gone from every local endpoint");
        let unknown = DomainParticipantStatusEvent::WriterLost { guid: guid(9), reason: LostReason::Disposed };
        assert!(!apply(&mut matched, unknown));
    }
}
