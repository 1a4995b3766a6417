//! Writing a bag: the folder, its MCAP file and `metadata.yaml`, rewritten at each checkpoint so
//! that a recording killed or stopped by a full disk stays a bag of what was written.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use crate::schema::SCHEMA_ENCODING;
use crate::{BagError, BagMetadata, MessageTime, SERIALIZATION_FORMAT, TopicInfo};

/// How often [`BagWriter::checkpoint_if_due`] makes what was written durable and listed in
/// `metadata.yaml`: the most a crash loses.
pub const CHECKPOINT_PERIOD: Duration = Duration::from_secs(1);

/// The MCAP profile of ROS 2 bags.
pub(crate) const MCAP_PROFILE: &str = "ros2";
/// The MCAP channel metadata key of a topic's offered QoS profiles.
pub(crate) const QOS_METADATA_KEY: &str = "offered_qos_profiles";

/// A topic added to a [`BagWriter`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TopicId(usize);

impl TopicId {
    /// Its position among the topics added, from 0.
    pub fn index(self) -> usize {
        self.0
    }
}

/// One topic being written: its MCAP channel, its message count so far.
#[derive(Debug)]
struct WrittenTopic {
    info: TopicInfo,
    channel: u16,
    messages: u64,
    sequence: u32,
}

/// A bag being written. Every [`CHECKPOINT_PERIOD`] (checked on each message, or by calling
/// [`BagWriter::checkpoint_if_due`]) the open MCAP chunk is ended, the file synced and
/// `metadata.yaml` replaced with the messages written so far; [`BagWriter::finish`] adds the MCAP
/// summary at the end.
pub struct BagWriter {
    dir: PathBuf,
    file_name: String,
    mcap: mcap::Writer<BufWriter<File>>,
    /// A second handle on the MCAP file, to sync it.
    file: File,
    topics: Vec<WrittenTopic>,
    log_ns_range: Option<(u64, u64)>,
    last_checkpoint: Instant,
    /// Messages that the last `metadata.yaml` lists.
    listed_messages: u64,
    /// Whether something was added since the last checkpoint.
    changed: bool,
}

impl BagWriter {
    /// Creates the bag folder `dir` (which must not exist yet), its MCAP file `NAME_0.mcap`, `NAME`
    /// being the folder's name, and a `metadata.yaml` of no messages.
    pub fn create(dir: &Path) -> Result<Self, BagError> {
        if dir.exists() {
            return Err(BagError::OutputExists(dir.to_path_buf()));
        }
        let name = dir.file_name().and_then(|n| n.to_str()).ok_or_else(|| BagError::Unsupported {
            path: dir.to_path_buf(),
            what: "a bag folder without a UTF-8 name".to_string(),
        })?;
        let file_name = format!("{name}_0.mcap");
        std::fs::create_dir_all(dir).map_err(|e| BagError::io(dir, e))?;
        let path = dir.join(&file_name);
        let file = File::create(&path).map_err(|e| BagError::io(&path, e))?;
        let sync_handle = file.try_clone().map_err(|e| BagError::io(&path, e))?;
        let mcap = mcap::WriteOptions::new()
            .profile(MCAP_PROFILE)
            .compression(None)
            .create(BufWriter::new(file))
            .map_err(|e| BagError::mcap(&path, e))?;
        let mut writer = BagWriter {
            dir: dir.to_path_buf(),
            file_name,
            mcap,
            file: sync_handle,
            topics: Vec::new(),
            log_ns_range: None,
            last_checkpoint: Instant::now(),
            listed_messages: 0,
            changed: false,
        };
        writer.checkpoint()?;
        Ok(writer)
    }

    /// The MCAP file.
    fn mcap_path(&self) -> PathBuf {
        self.dir.join(&self.file_name)
    }

    /// Adds a topic whose messages have the `ros2msg` schema `schema_text`.
    pub fn add_topic(&mut self, info: TopicInfo, schema_text: &str) -> Result<TopicId, BagError> {
        let path = self.mcap_path();
        let schema = self
            .mcap
            .add_schema(&info.type_name, SCHEMA_ENCODING, schema_text.as_bytes())
            .map_err(|e| BagError::mcap(&path, e))?;
        let metadata = BTreeMap::from([(QOS_METADATA_KEY.to_string(), info.qos.channel_metadata_yaml())]);
        let channel = self
            .mcap
            .add_channel(schema, &info.name, SERIALIZATION_FORMAT, &metadata)
            .map_err(|e| BagError::mcap(&path, e))?;
        self.topics.push(WrittenTopic { info, channel, messages: 0, sequence: 0 });
        self.changed = true;
        Ok(TopicId(self.topics.len() - 1))
    }

    /// Writes one message of `topic`: its serialized bytes, as published; checkpoints when due.
    pub fn write(&mut self, topic: TopicId, time: MessageTime, data: &[u8]) -> Result<(), BagError> {
        let path = self.mcap_path();
        let written = self.topics.get_mut(topic.0).ok_or(BagError::UnknownTopic(topic.0))?;
        written.sequence = written.sequence.wrapping_add(1);
        let header = mcap::records::MessageHeader {
            channel_id: written.channel,
            sequence: written.sequence,
            log_time: time.log_ns,
            publish_time: time.publish_ns,
        };
        self.mcap.write_to_known_channel(&header, data).map_err(|e| BagError::mcap(&path, e))?;
        written.messages += 1;
        self.log_ns_range = Some(match self.log_ns_range {
            None => (time.log_ns, time.log_ns),
            Some((first, last)) => (first.min(time.log_ns), last.max(time.log_ns)),
        });
        self.changed = true;
        self.checkpoint_if_due()
    }

    /// Checkpoints if something was added and the last checkpoint is [`CHECKPOINT_PERIOD`] old.
    pub fn checkpoint_if_due(&mut self) -> Result<(), BagError> {
        if self.changed && self.last_checkpoint.elapsed() >= CHECKPOINT_PERIOD {
            self.checkpoint()?;
        }
        Ok(())
    }

    /// Ends the open MCAP chunk, syncs the file and replaces `metadata.yaml` with the messages
    /// written so far: a reader gets them all even if the writer never finishes.
    pub(crate) fn checkpoint(&mut self) -> Result<(), BagError> {
        let path = self.mcap_path();
        self.mcap.flush().map_err(|e| BagError::mcap(&path, e))?;
        self.file.sync_data().map_err(|e| BagError::io(&path, e))?;
        let metadata = self.metadata();
        metadata.write(&self.dir)?;
        (self.last_checkpoint, self.listed_messages, self.changed) = (Instant::now(), metadata.message_count, false);
        Ok(())
    }

    /// The messages that `metadata.yaml` lists: those written up to the last checkpoint.
    pub fn listed_messages(&self) -> u64 {
        self.listed_messages
    }

    /// The metadata of the messages written so far.
    fn metadata(&self) -> BagMetadata {
        let (start_ns, end_ns) = self.log_ns_range.unwrap_or((0, 0));
        let topics: Vec<(TopicInfo, u64)> = self.topics.iter().map(|t| (t.info.clone(), t.messages)).collect();
        BagMetadata::single_file(&self.file_name, &topics, start_ns, end_ns)
    }

    /// Ends the MCAP file with its summary and writes `metadata.yaml`; returns the metadata.
    pub fn finish(mut self) -> Result<BagMetadata, BagError> {
        let path = self.mcap_path();
        self.mcap.finish().map_err(|e| BagError::mcap(&path, e))?;
        let metadata = self.metadata();
        let file = self.mcap.into_inner().into_inner().map_err(|e| BagError::io(&path, e.into_error()))?;
        file.sync_all().map_err(|e| BagError::io(&path, e))?;
        metadata.write(&self.dir)?;
        Ok(metadata)
    }
}
