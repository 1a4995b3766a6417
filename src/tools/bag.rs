//! `rover bag`: records topics of the graph into a rosbag2 bag in MCAP storage, plays a bag back
//! with its timing, tells what a bag holds, and turns a recorded Udacity dataset into a bag. The bag format is
//! [`rover_bag`]; this module wires it to the topic table ([`rover_runtime::topics`]) and DDS.

pub mod from_dataset;
pub mod info;
pub mod play;
pub mod record;

use std::path::Path;

use rover_bag::{BagMetadata, BagWriter, MessageTime, QosProfile, TopicId, TopicInfo};
use rover_msgs::RosMessage;
use rover_runtime::names::NodeIdentity;
use rover_runtime::topics::{Topic, TopicVisitor, visit_all};

/// Options of `rover bag`.
#[derive(Debug, Clone, clap::Args)]
pub struct BagArgs {
    /// What to do.
    #[command(subcommand)]
    pub command: BagCommand,
}

/// The `rover bag` subcommands.
#[derive(Debug, Clone, clap::Subcommand)]
pub enum BagCommand {
    /// Record topics of the graph into a new rosbag2 bag (MCAP storage) until Ctrl-C or SIGTERM;
    /// a progress line every few seconds, the message count of each topic at the end.
    #[command(after_help = crate::processes::nodes::ROS_ARGS_HELP)]
    Record(record::RecordArgs),
    /// Play a bag back: each message on its topic, with the topic table's QoS, at the bag's
    /// pace (the log times, divided by --rate), until the end or Ctrl-C.
    #[command(after_help = crate::processes::nodes::ROS_ARGS_HELP)]
    Play(play::PlayArgs),
    /// Turn a recorded dataset (robot_log.csv + IMG/) into a bag of the topics the bridge
    /// publishes for each frame (camera image and info, telemetry, odom, /tf, and /tf_static
    /// once), stamped at the frame times of the image names.
    #[command(name = "from-dataset", after_help = crate::processes::nodes::ROS_ARGS_HELP)]
    FromDataset(from_dataset::FromDatasetArgs),
    /// Print what a bag holds: its size, duration and the messages of each topic (as its
    /// metadata.yaml lists them), and whether its recording was interrupted.
    Info(info::InfoArgs),
}

/// The name of every topic of the table, resolved for `identity` (namespace and remaps).
pub fn resolved_table_names(identity: &NodeIdentity) -> anyhow::Result<Vec<String>> {
    struct Collect<'a>(&'a NodeIdentity, Vec<String>);
    impl TopicVisitor for Collect<'_> {
        fn visit<M: RosMessage>(&mut self, topic: &Topic<M>) -> anyhow::Result<()> {
            self.1.push(self.0.resolve_topic(topic.name)?);
            Ok(())
        }
    }
    let mut collect = Collect(identity, Vec::new());
    visit_all(&mut collect)?;
    Ok(collect.1)
}

/// `requested` topic names resolved as `identity` resolves them (relative names get its namespace).
fn resolve_names(identity: &NodeIdentity, requested: &[String]) -> anyhow::Result<Vec<String>> {
    requested.iter().map(|name| Ok(identity.resolve_topic(name)?)).collect()
}

/// Fails, naming them, if some of `requested` (resolved names) are not among `known`.
fn check_known(requested: &[String], known: &[String], what: &str) -> anyhow::Result<()> {
    let unknown: Vec<&str> = requested.iter().filter(|name| !known.contains(name)).map(String::as_str).collect();
    anyhow::ensure!(
        unknown.is_empty(),
        "{} not {what}; the known topics are: {}",
        if unknown.len() == 1 {
            format!("topic {} is", unknown[0])
        } else {
            format!("topics {} are", unknown.join(", "))
        },
        known.join(", ")
    );
    Ok(())
}

/// The rosbag2 QoS profile of `qos`.
fn bag_qos(qos: &ros2_client::QosProfile) -> QosProfile {
    use ros2_client::qos::{Durability, History, Reliability};
    let depth = match qos.history {
        History::KeepLast { depth } => depth as u64,
        History::KeepAll => 0,
    };
    let mut profile = QosProfile::keep_last(
        depth,
        matches!(qos.reliability, Reliability::Reliable { .. }),
        qos.durability == Durability::TransientLocal,
    );
    if qos.history == History::KeepAll {
        profile.history = "keep_all".to_string();
    }
    profile
}

/// Adds `topic`, named as `identity` names it, to the bag with its type's schema and its QoS.
fn add_topic<M: RosMessage>(
    writer: &mut BagWriter,
    identity: &NodeIdentity,
    topic: &Topic<M>,
) -> anyhow::Result<TopicId> {
    let info =
        TopicInfo { name: identity.resolve_topic(topic.name)?, type_name: M::type_name(), qos: bag_qos(&topic.qos) };
    Ok(writer.add_topic(info, &rover_bag::schema::schema_text(&M::definitions()))?)
}

/// Writes `message` on `topic`, serialized as ros2-client publishes it.
fn write_message<M: RosMessage>(
    writer: &mut BagWriter,
    topic: TopicId,
    time: MessageTime,
    message: &M,
) -> anyhow::Result<()> {
    Ok(writer.write(topic, time, &rover_runtime::cdr::encode(message)?)?)
}

/// The size of the bag's storage files, bytes.
fn storage_bytes(dir: &Path, metadata: &BagMetadata) -> u64 {
    metadata
        .storage_paths(dir)
        .unwrap_or_default()
        .iter()
        .filter_map(|path| std::fs::metadata(path).ok())
        .map(|m| m.len())
        .sum()
}

/// The end-of-run summary of a bag: its size, its duration, the messages of each topic.
pub fn summary(dir: &Path, metadata: &BagMetadata) -> String {
    let seconds = metadata.duration.nanoseconds as f64 / 1e9;
    let rate = if seconds > 0.0 { metadata.message_count as f64 / seconds } else { 0.0 };
    let mut text = format!(
        "bag {}: {} messages over {seconds:.1} s ({rate:.0} messages/s), {:.1} MB\n",
        dir.display(),
        metadata.message_count,
        storage_bytes(dir, metadata) as f64 / 1e6
    );
    let width = metadata.topics_with_message_count.iter().map(|t| t.topic_metadata.name.len()).max().unwrap_or(0);
    for topic in &metadata.topics_with_message_count {
        let meta = &topic.topic_metadata;
        text.push_str(&format!("  {:<width$}  {:<34}  {:>8}\n", meta.name, meta.type_name, topic.message_count));
    }
    text
}

/// Nanoseconds since the epoch, now.
fn now_ns() -> u64 {
    let since_epoch = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap_or_default();
    u64::try_from(since_epoch.as_nanos()).unwrap_or(u64::MAX)
}
