//! `rover bag record`: typed subscriptions to topics of the table; each message serialized again
//! with ros2-client's CDR serializer (the bytes its publisher sent) and written by a thread of
//! its own, so that writing never holds up the DDS readers.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use rover_bag::{BagMetadata, BagWriter, MessageTime, TopicId};
use rover_msgs::RosMessage;
use rover_runtime::sync::lock;
use rover_runtime::topics::{Topic, TopicVisitor, visit_all};
use rover_runtime::{MessageInfo, NoParams, RosNode, Runtime, spawn_subscriber_with_info};
use tokio::sync::mpsc;
use tokio::task::JoinHandle;

use super::{add_topic, check_known, now_ns, resolve_names, resolved_table_names, summary};

/// The recorder's node name (as `ros2 bag record`'s).
const RECORDER_NODE: &str = "rosbag2_recorder";
/// Messages each of the recorder's readers keeps while the recorder lags behind.
const READER_HISTORY_DEPTH: usize = 1000;
/// How often `rover bag record` prints its progress line.
const PROGRESS_PERIOD: Duration = Duration::from_secs(5);

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
        let (sender, receiver) = mpsc::unbounded_channel();
        let mut subscribe =
            Subscribe { node: &mut node, selected, writer: &mut writer, sender, subscribers: Vec::new() };
        visit_all(&mut subscribe)?;
        let subscribers = std::mem::take(&mut subscribe.subscribers);
        let topic_count = subscribers.len();
        let written = Arc::new(Mutex::new(Written { messages: vec![0; topic_count], bytes: 0 }));
        let writer = tokio::task::spawn_blocking({
            let written = written.clone();
            move || write_until_closed(writer, receiver, &written)
        });
        tracing::info!("recording {topic_count} topics into {}", dir.display());
        Ok(Recorder { _node: node, subscribers, writer, written, dir: dir.to_path_buf(), started: Instant::now() })
    }

    /// One line on the recording so far: time, messages, megabytes.
    pub fn progress_line(&self) -> String {
        let written = lock(&self.written).clone();
        format!(
            "recording {}: {:.0} s, {} messages on {} topics, {:.1} MB",
            self.dir.display(),
            self.started.elapsed().as_secs_f64(),
            written.messages.iter().sum::<u64>(),
            written.messages.iter().filter(|&&count| count > 0).count(),
            written.bytes as f64 / 1e6
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

/// Writes what arrives on `receiver` until every sender is gone, then ends the bag.
fn write_until_closed(
    mut writer: BagWriter,
    mut receiver: mpsc::UnboundedReceiver<Received>,
    written: &Mutex<Written>,
) -> anyhow::Result<BagMetadata> {
    while let Some(received) = receiver.blocking_recv() {
        writer.write(received.topic, received.time, &received.data)?;
        let mut written = lock(written);
        written.messages[received.topic.index()] += 1;
        written.bytes += received.data.len() as u64;
    }
    Ok(writer.finish()?)
}

/// Adds each selected topic to the bag and subscribes to it.
struct Subscribe<'a> {
    node: &'a mut RosNode,
    selected: Vec<String>,
    writer: &'a mut BagWriter,
    sender: mpsc::UnboundedSender<Received>,
    subscribers: Vec<JoinHandle<()>>,
}

impl TopicVisitor for Subscribe<'_> {
    fn visit<M: RosMessage>(&mut self, topic: &Topic<M>) -> anyhow::Result<()> {
        if !self.selected.contains(&self.node.identity().resolve_topic(topic.name)?) {
            return Ok(());
        }
        let id = add_topic(self.writer, self.node.identity(), topic)?;
        let subscription = self.node.subscription(&topic.with_history_depth(READER_HISTORY_DEPTH))?;
        let sender = self.sender.clone();
        let handler = move |message: M, info: MessageInfo| match rover_runtime::cdr::encode(&message) {
            Ok(data) => {
                let _ = sender.send(Received { topic: id, time: message_time(&info), data });
            }
            Err(e) => tracing::warn!("{e:#}"),
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
    let mut ticks = tokio::time::interval(PROGRESS_PERIOD);
    ticks.tick().await;
    loop {
        tokio::select! {
            () = shutdown.wait() => break,
            _ = ticks.tick() => {
                if recorder.writer_stopped() {
                    break;
                }
                eprintln!("{}", recorder.progress_line());
            }
        }
    }
    let metadata = recorder.finish().await?;
    print!("{}", summary(&args.output, &metadata));
    Ok(metadata)
}
