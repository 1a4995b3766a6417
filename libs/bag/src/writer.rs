//! Writing a bag: the folder, its MCAP file and, at the end, `metadata.yaml`.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use crate::schema::SCHEMA_ENCODING;
use crate::{BagError, BagMetadata, MessageTime, SERIALIZATION_FORMAT, TopicInfo};

/// The MCAP profile of ROS 2 bags.
pub const MCAP_PROFILE: &str = "ros2";
/// The MCAP channel metadata key of a topic's offered QoS profiles.
pub const QOS_METADATA_KEY: &str = "offered_qos_profiles";

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

/// A bag being written. Call [`BagWriter::finish`] at the end: without it the MCAP file has no
/// summary and the folder no `metadata.yaml`.
pub struct BagWriter {
    dir: PathBuf,
    file_name: String,
    mcap: mcap::Writer<BufWriter<File>>,
    topics: Vec<WrittenTopic>,
    log_ns_range: Option<(u64, u64)>,
}

impl BagWriter {
    /// Creates the bag folder `dir` (which must not exist yet) and its MCAP file `NAME_0.mcap`,
    /// `NAME` being the folder's name.
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
        let mcap = mcap::WriteOptions::new()
            .profile(MCAP_PROFILE)
            .compression(None)
            .create(BufWriter::new(file))
            .map_err(|e| BagError::mcap(&path, e))?;
        Ok(BagWriter { dir: dir.to_path_buf(), file_name, mcap, topics: Vec::new(), log_ns_range: None })
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
        Ok(TopicId(self.topics.len() - 1))
    }

    /// Writes one message of `topic`: its serialized bytes, as published.
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
        Ok(())
    }

    /// Ends the MCAP file with its summary and writes `metadata.yaml`; returns the metadata.
    pub fn finish(mut self) -> Result<BagMetadata, BagError> {
        let path = self.mcap_path();
        self.mcap.finish().map_err(|e| BagError::mcap(&path, e))?;
        let file = self.mcap.into_inner().into_inner().map_err(|e| BagError::io(&path, e.into_error()))?;
        file.sync_all().map_err(|e| BagError::io(&path, e))?;
        let (start_ns, end_ns) = self.log_ns_range.unwrap_or((0, 0));
        let topics: Vec<(TopicInfo, u64)> = self.topics.into_iter().map(|t| (t.info, t.messages)).collect();
        let metadata = BagMetadata::single_file(&self.file_name, &topics, start_ns, end_ns);
        metadata.write(&self.dir)?;
        Ok(metadata)
    }
}
