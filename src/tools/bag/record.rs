//! `rover bag record`: typed subscriptions to topics of the table; each message serialized again
//! with ros2-client's CDR serializer (the bytes its publisher sent) and written by a thread of
//! its own, so that writing never holds up the DDS readers. The queue to that thread is bounded:
//! when the writer falls behind (a slow or full disk), messages are dropped and counted, never
//! waited for.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError, sync_channel};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use rover_bag::{BagError, BagMetadata, BagWriter, CHECKPOINT_PERIOD, MessageTime, TopicId};
use rover_msgs::RosMessage;
use rover_runtime::rejections::worth_logging;
use rover_runtime::sync::lock;
use rover_runtime::topics::{Topic, TopicVisitor, visit_all};
use rover_runtime::{MessageInfo, NoParams, RosNode, Runtime, spawn_subscriber_with_info};
use tokio::task::JoinHandle;

use super::{add_topic, check_known, now_ns, resolve_names, resolved_table_names, summary};

/// The recorder's node name (as `ros2 bag record`'s).
const RECORDER_NODE: &str = "rosbag2_recorder";
/// Messages each of the recorder's readers keeps while the recorder lags behind.
const READER_HISTORY_DEPTH: usize = 1000;
/// How often `rover bag record` prints its progress line.
const PROGRESS_PERIOD: Duration = Duration::from_secs(5);
/// Most messages waiting for the writer thread.
const MAX_QUEUED_MESSAGES: usize = 10_000;
/// Most bytes of message data waiting for the writer thread.
const MAX_QUEUED_BYTES: u64 = 256 << 20;

/// Options of `rover bag record`.
#[derive(Debug, Clone, clap::Args)]
pub struct RecordArgs {
    /// The bag folder to create (it must not exist yet); the MCAP file inside is DIR_NAME_0.mcap.
    #[arg(short = 'o', long = "output", value_name = "DIR")]
    pub output: PathBuf,
    /// Record every topic of the graph's topic table.
    #[arg(short = 'a', long = "all", conflicts_with = "topics")]
    pub all: bool,
    /// The topics to record, as named in the topic table (e.g. rover/telemetry, /tf) or resolved
    /// (e.g. /rover/telemetry).
    #[arg(value_name = "TOPIC", required_unless_present = "all")]
    pub topics: Vec<String>,
}

/// A message received, on its way to the writer thread.
struct Received {
    topic: TopicId,
    time: MessageTime,
    data: Vec<u8>,
}

/// The queue from the subscriptions to the writer thread, bounded by messages and bytes.
#[derive(Clone)]
struct WriterQueue {
    sender: SyncSender<Received>,
    counts: Arc<QueueCounts>,
}

/// What is in the queue and what did not fit.
#[derive(Debug)]
struct QueueCounts {
    max_messages: usize,
    queued_bytes: AtomicU64,
    max_bytes: u64,
    dropped: AtomicU64,
}

/// The writer thread's end of a [`WriterQueue`].
struct QueueReceiver {
    receiver: Receiver<Received>,
    counts: Arc<QueueCounts>,
}

impl WriterQueue {
    /// A queue of at most `max_messages` messages and `max_bytes` bytes of data.
    fn bounded(max_messages: usize, max_bytes: u64) -> (Self, QueueReceiver) {
        let (sender, receiver) = sync_channel(max_messages);
        let counts = Arc::new(QueueCounts {
            max_messages,
            queued_bytes: AtomicU64::new(0),
            max_bytes,
            dropped: AtomicU64::new(0),
        });
        (WriterQueue { sender, counts: counts.clone() }, QueueReceiver { receiver, counts })
    }

    /// Queues `received` if it fits; otherwise drops it, counts it and warns (the 1st, 2nd, 4th...
    /// time). Never blocks.
    fn offer(&self, received: Received) {
        let bytes = received.data.len() as u64;
        let queued_bytes = self.counts.queued_bytes.fetch_add(bytes, Ordering::Relaxed) + bytes;
        let refused = if queued_bytes > self.counts.max_bytes {
            Some(format!("it is behind by {queued_bytes} bytes"))
        } else {
            match self.sender.try_send(received) {
                Ok(()) => None,
                Err(TrySendError::Full(_)) => Some(format!("it is behind by {} messages", self.counts.max_messages)),
                Err(TrySendError::Disconnected(_)) => Some("it has stopped".to_string()),
            }
        };
        if let Some(why) = refused {
            self.counts.queued_bytes.fetch_sub(bytes, Ordering::Relaxed);
            self.count_dropped(&why);
        }
    }

    /// Counts a message dropped because of `why` and warns the 1st, 2nd, 4th... time.
    fn count_dropped(&self, why: &str) {
        let dropped = self.counts.dropped.fetch_add(1, Ordering::Relaxed) + 1;
        if worth_logging(dropped) {
            tracing::warn!("dropped a message for the bag writer: {why} ({dropped} dropped so far)");
        }
    }

    /// Messages dropped so far.
    fn dropped(&self) -> u64 {
        self.counts.dropped.load(Ordering::Relaxed)
    }
}

impl QueueReceiver {
    /// The next message, or `Ok(None)` when none came within `timeout`; `Err` once every sender
    /// is gone.
    fn next(&self, timeout: Duration) -> Result<Option<Received>, RecvTimeoutError> {
        match self.receiver.recv_timeout(timeout) {
            Ok(received) => {
                self.counts.queued_bytes.fetch_sub(received.data.len() as u64, Ordering::Relaxed);
                Ok(Some(received))
            }
            Err(RecvTimeoutError::Timeout) => Ok(None),
            Err(disconnected) => Err(disconnected),
        }
    }
}

/// What the writer thread has written so far.
#[derive(Debug, Clone, Default)]
struct Written {
    /// Messages per topic, in the order the topics were added.
    messages: Vec<u64>,
    /// Bytes of message data.
    bytes: u64,
}

/// A recording in progress: the subscriptions of the recorder node and the writer thread.
pub struct Recorder {
    _node: RosNode,
    subscribers: Vec<JoinHandle<()>>,
    writer: JoinHandle<anyhow::Result<BagMetadata>>,
    written: Arc<Mutex<Written>>,
    queue: WriterQueue,
    dir: PathBuf,
    started: Instant,
}

impl Recorder {
    /// Creates the bag `dir` and subscribes to `topics` (resolved or table names; every topic of
    /// the table when empty) with a node on `runtime`.
    pub fn start(runtime: &Runtime, dir: &Path, topics: &[String]) -> anyhow::Result<Self> {
        let (mut node, _) = runtime.node::<NoParams>(RECORDER_NODE)?;
        let selected = selected_topics(&node, topics)?;
        let mut writer = BagWriter::create(dir)?;
        let (queue, receiver) = WriterQueue::bounded(MAX_QUEUED_MESSAGES, MAX_QUEUED_BYTES);
        let mut subscribe =
            Subscribe { node: &mut node, selected, writer: &mut writer, queue: queue.clone(), subscribers: Vec::new() };
        visit_all(&mut subscribe)?;
        let subscribers = std::mem::take(&mut subscribe.subscribers);
        let topic_count = subscribers.len();
        let written = Arc::new(Mutex::new(Written { messages: vec![0; topic_count], bytes: 0 }));
        let writer = tokio::task::spawn_blocking({
            let written = written.clone();
            move || write_until_closed(writer, receiver, &written)
        });
        tracing::info!("recording {topic_count} topics into {}", dir.display());
        Ok(Recorder {
            _node: node,
            subscribers,
            writer,
            written,
            queue,
            dir: dir.to_path_buf(),
            started: Instant::now(),
        })
    }

    /// One line on the recording so far: time, messages, megabytes, messages dropped.
    pub fn progress_line(&self) -> String {
        let written = lock(&self.written).clone();
        format!(
            "recording {}: {:.0} s, {} messages on {} topics, {:.1} MB, {} dropped",
            self.dir.display(),
            self.started.elapsed().as_secs_f64(),
            written.messages.iter().sum::<u64>(),
            written.messages.iter().filter(|&&count| count > 0).count(),
            written.bytes as f64 / 1e6,
            self.queue.dropped()
        )
    }

    /// Whether the writer thread has stopped (it stops early only on an error).
    pub fn writer_stopped(&self) -> bool {
        self.writer.is_finished()
    }

    /// Stops the subscriptions, writes what was received and ends the bag; returns its metadata.
    pub async fn finish(self) -> anyhow::Result<BagMetadata> {
        for subscriber in &self.subscribers {
            subscriber.abort();
        }
        for subscriber in self.subscribers {
            let _ = subscriber.await;
        }
        let dropped = self.queue.dropped();
        drop(self.queue);
        if dropped > 0 {
            tracing::warn!("{dropped} messages dropped: the bag writer fell behind");
        }
        self.writer.await.map_err(|e| anyhow::anyhow!("the bag writer thread failed: {e}"))?
    }
}

/// The resolved names of `requested` topics (all of the table's when empty), each checked to be
/// in the table.
fn selected_topics(node: &RosNode, requested: &[String]) -> anyhow::Result<Vec<String>> {
    let table = resolved_table_names(node.identity())?;
    if requested.is_empty() {
        return Ok(table);
    }
    let resolved = resolve_names(node.identity(), requested)?;
    check_known(&resolved, &table, "in the graph's topic table")?;
    Ok(resolved)
}

/// Writes what arrives on `receiver` until every sender is gone, checkpointing the bag when no
/// message comes, then ends the bag. A write error ends the recording: the bag's metadata then
/// lists what was written up to the last checkpoint.
fn write_until_closed(
    mut writer: BagWriter,
    receiver: QueueReceiver,
    written: &Mutex<Written>,
) -> anyhow::Result<BagMetadata> {
    while let Ok(next) = receiver.next(CHECKPOINT_PERIOD) {
        let outcome = match next {
            Some(received) => write_received(&mut writer, &received, written),
            None => writer.checkpoint_if_due(),
        };
        outcome.map_err(|e| {
            anyhow::anyhow!(
                "{e}; the recording stopped there, its metadata.yaml lists the {} messages written before",
                writer.listed_messages()
            )
        })?;
    }
    Ok(writer.finish()?)
}

/// Writes `received` and counts it.
fn write_received(writer: &mut BagWriter, received: &Received, written: &Mutex<Written>) -> Result<(), BagError> {
    writer.write(received.topic, received.time, &received.data)?;
    let mut written = lock(written);
    written.messages[received.topic.index()] += 1;
    written.bytes += received.data.len() as u64;
    Ok(())
}

/// Adds each selected topic to the bag and subscribes to it.
struct Subscribe<'a> {
    node: &'a mut RosNode,
    selected: Vec<String>,
    writer: &'a mut BagWriter,
    queue: WriterQueue,
    subscribers: Vec<JoinHandle<()>>,
}

impl TopicVisitor for Subscribe<'_> {
    fn visit<M: RosMessage>(&mut self, topic: &Topic<M>) -> anyhow::Result<()> {
        if !self.selected.contains(&self.node.identity().resolve_topic(topic.name)?) {
            return Ok(());
        }
        let id = add_topic(self.writer, self.node.identity(), topic)?;
        let subscription = self.node.subscription(&topic.with_history_depth(READER_HISTORY_DEPTH))?;
        let queue = self.queue.clone();
        let handler = move |message: M, info: MessageInfo| match rover_runtime::cdr::encode(&message) {
            Ok(data) => queue.offer(Received { topic: id, time: message_time(&info), data }),
            Err(e) => queue.count_dropped(&format!("cannot encode it ({e:#})")),
        };
        self.subscribers.push(spawn_subscriber_with_info(subscription, self.node.span(), handler));
        Ok(())
    }
}

/// When a message was received (log time) and sent (publish time; its reception when the
/// publisher gave no source time).
pub(crate) fn message_time(info: &MessageInfo) -> MessageTime {
    let nanos = |time: ros2_client::ROSTime| u64::try_from(time.to_nanos()).unwrap_or(0);
    let log_ns = info.received_timestamp().map_or_else(now_ns, nanos);
    MessageTime { log_ns, publish_ns: info.source_timestamp().map_or(log_ns, nanos) }
}

/// Runs `rover bag record` until shutdown: a progress line every few seconds, the summary at the end.
pub async fn record(args: &RecordArgs, runtime: &Runtime) -> anyhow::Result<BagMetadata> {
    let recorder = Recorder::start(runtime, &args.output, &args.topics)?;
    let shutdown = runtime.shutdown();
    let mut checks = tokio::time::interval(CHECKPOINT_PERIOD);
    let mut next_progress = Instant::now() + PROGRESS_PERIOD;
    loop {
        tokio::select! {
            () = shutdown.wait() => break,
            _ = checks.tick() => {
                if recorder.writer_stopped() {
                    break;
                }
                if Instant::now() >= next_progress {
                    eprintln!("{}", recorder.progress_line());
                    next_progress += PROGRESS_PERIOD;
                }
            }
        }
    }
    let metadata = recorder.finish().await?;
    print!("{}", summary(&args.output, &metadata));
    Ok(metadata)
}

#[cfg(test)]
mod tests {
    use rover_bag::{QosProfile, TopicInfo};

    use super::*;

    /// A topic id of a bag made for the test in a fresh folder named after `name`.
    fn topic_id(name: &str) -> (TopicId, PathBuf) {
        let dir = std::env::temp_dir().join(format!("rover-record-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let mut writer = BagWriter::create(&dir).unwrap();
        let info = TopicInfo {
            name: "/x".into(),
            type_name: "std_msgs/msg/Empty".into(),
            qos: QosProfile::keep_last(1, true, false),
        };
        (writer.add_topic(info, "").unwrap(), dir)
    }

    fn message(topic: TopicId, bytes: usize) -> Received {
        Received { topic, time: MessageTime { log_ns: 1, publish_ns: 1 }, data: vec![0; bytes] }
    }

    #[test]
    fn a_full_queue_drops_and_counts_messages_without_blocking() {
        let (topic, dir) = topic_id("queue");
        let (queue, receiver) = WriterQueue::bounded(3, 100);
        for _ in 0..5 {
            queue.offer(message(topic, 10));
        }
        assert_eq!(queue.dropped(), 2, "3 messages fit");
        queue.offer(message(topic, 71));
        assert_eq!(queue.dropped(), 3, "30 bytes queued, 71 more do not fit in 100");
        assert_eq!(receiver.next(Duration::ZERO).unwrap().map(|m| m.data.len()), Some(10));
        queue.offer(message(topic, 70));
        assert_eq!(queue.dropped(), 3, "20 bytes queued, 70 more fit");
        assert_eq!(receiver.next(Duration::ZERO).unwrap().map(|m| m.data.len()), Some(10));
        drop(receiver);
        queue.offer(message(topic, 1));
        assert_eq!(queue.dropped(), 4, "a stopped writer takes nothing");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
