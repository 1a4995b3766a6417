//! `metadata.yaml` of a rosbag2 bag, version 9 (the fields ROS 2 Jazzy and Kilted write).

use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::{BagError, QosProfile, STORAGE_IDENTIFIER, TopicInfo, files};

/// The metadata file's name in the bag folder.
pub(crate) const FILE_NAME: &str = "metadata.yaml";
/// The version of the metadata format written.
pub(crate) const VERSION: u32 = 9;
/// The longest `metadata.yaml` read, bytes (one of a bag with thousands of topics is far shorter).
pub(crate) const MAX_FILE_BYTES: u64 = 16 << 20;
/// The ROS distribution the bags are written for.
pub(crate) const ROS_DISTRO: &str = "kilted";

/// The file's single top-level key.
#[derive(Debug, Serialize, Deserialize)]
struct MetadataFile {
    rosbag2_bagfile_information: BagMetadata,
}

/// A span of time, nanoseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Nanoseconds {
    /// Nanoseconds.
    pub nanoseconds: u64,
}

/// A point in time, nanoseconds since the epoch.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct StartingTime {
    /// Nanoseconds since the epoch.
    pub nanoseconds_since_epoch: u64,
}

/// A topic's entry in `metadata.yaml`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct TopicMetadata {
    /// Topic name.
    pub name: String,
    /// Message type, `pkg/msg/Name`.
    #[serde(rename = "type")]
    pub type_name: String,
    /// `cdr`.
    pub serialization_format: String,
    /// The QoS profiles the publishers offered (a list since version 9, YAML text before).
    #[serde(default, deserialize_with = "qos_list_or_text")]
    pub offered_qos_profiles: Vec<QosProfile>,
    /// RIHS01 hash of the type description; empty when unknown.
    #[serde(default)]
    pub type_description_hash: String,
}

/// A topic and how many messages it has in the bag.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct TopicWithMessageCount {
    /// The topic.
    pub topic_metadata: TopicMetadata,
    /// Messages recorded on it.
    pub message_count: u64,
}

/// One storage file of the bag.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct FileInformation {
    /// File name, relative to the bag folder.
    pub path: String,
    /// Log time of its first message.
    pub starting_time: StartingTime,
    /// From its first to its last message.
    pub duration: Nanoseconds,
    /// Messages in it.
    pub message_count: u64,
}

/// The content of `metadata.yaml`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct BagMetadata {
    /// Format version ([`VERSION`] when written here).
    pub version: u32,
    /// Storage plugin: [`STORAGE_IDENTIFIER`].
    pub storage_identifier: String,
    /// The storage files, relative to the bag folder.
    pub relative_file_paths: Vec<String>,
    /// From the first to the last message.
    pub duration: Nanoseconds,
    /// Log time of the first message.
    pub starting_time: StartingTime,
    /// Messages in the bag.
    pub message_count: u64,
    /// Every topic with its message count.
    pub topics_with_message_count: Vec<TopicWithMessageCount>,
    /// Compression format, empty for none.
    #[serde(default)]
    pub compression_format: String,
    /// Compression mode, empty for none.
    #[serde(default)]
    pub compression_mode: String,
    /// The storage files with their times and counts.
    #[serde(default)]
    pub files: Vec<FileInformation>,
    /// Free key-value data.
    #[serde(default, deserialize_with = "null_as_empty")]
    pub custom_data: BTreeMap<String, String>,
    /// ROS distribution of the recorder.
    #[serde(default)]
    pub ros_distro: String,
}

/// Reads `offered_qos_profiles` as a list of profiles or, as before version 9, as YAML text of
/// one; profiles that are not understood are left out (the QoS of a topic is only informative).
fn qos_list_or_text<'de, D: serde::Deserializer<'de>>(deserializer: D) -> Result<Vec<QosProfile>, D::Error> {
    let value = serde_yaml_ng::Value::deserialize(deserializer)?;
    let list = match value {
        serde_yaml_ng::Value::String(text) => serde_yaml_ng::from_str(&text).unwrap_or_default(),
        other => other,
    };
    Ok(serde_yaml_ng::from_value(list).unwrap_or_default())
}

/// Reads a map that may be written as `null` (`~`) when empty.
fn null_as_empty<'de, D: serde::Deserializer<'de>>(deserializer: D) -> Result<BTreeMap<String, String>, D::Error> {
    Ok(Option::<BTreeMap<String, String>>::deserialize(deserializer)?.unwrap_or_default())
}

impl BagMetadata {
    /// The metadata of a bag of one storage file `file_name` holding `topics` with their message
    /// counts, the first message logged at `start_ns` and the last at `end_ns`.
    pub fn single_file(file_name: &str, topics: &[(TopicInfo, u64)], start_ns: u64, end_ns: u64) -> Self {
        let message_count = topics.iter().map(|(_, count)| count).sum();
        let starting_time = StartingTime { nanoseconds_since_epoch: start_ns };
        let duration = Nanoseconds { nanoseconds: end_ns.saturating_sub(start_ns) };
        BagMetadata {
            version: VERSION,
            storage_identifier: STORAGE_IDENTIFIER.to_string(),
            relative_file_paths: vec![file_name.to_string()],
            duration,
            starting_time,
            message_count,
            topics_with_message_count: topics
                .iter()
                .map(|(topic, count)| TopicWithMessageCount {
                    topic_metadata: TopicMetadata {
                        name: topic.name.clone(),
                        type_name: topic.type_name.clone(),
                        serialization_format: crate::SERIALIZATION_FORMAT.to_string(),
                        offered_qos_profiles: vec![topic.qos.clone()],
                        type_description_hash: String::new(),
                    },
                    message_count: *count,
                })
                .collect(),
            compression_format: String::new(),
            compression_mode: String::new(),
            files: vec![FileInformation { path: file_name.to_string(), starting_time, duration, message_count }],
            custom_data: BTreeMap::new(),
            ros_distro: ROS_DISTRO.to_string(),
        }
    }

    /// The YAML text of `metadata.yaml`.
    pub fn to_yaml(&self) -> String {
        let file = MetadataFile { rosbag2_bagfile_information: self.clone() };
        serde_yaml_ng::to_string(&file).expect("bag metadata always serializes")
    }

    /// Parses the text of `metadata.yaml`; `path` names the file in errors.
    pub fn from_yaml(text: &str, path: &Path) -> Result<Self, BagError> {
        let file: MetadataFile = serde_yaml_ng::from_str(text)
            .map_err(|e| BagError::Metadata { path: path.to_path_buf(), problem: e.to_string() })?;
        Ok(file.rosbag2_bagfile_information)
    }

    /// Replaces `dir/metadata.yaml` atomically: a crash leaves the previous one or this one.
    pub fn write(&self, dir: &Path) -> Result<(), BagError> {
        files::replace_atomically(&dir.join(FILE_NAME), self.to_yaml().as_bytes())
    }

    /// Reads `dir/metadata.yaml`, telling a missing folder and a folder that is no bag apart; a
    /// `metadata.yaml` that is not a regular file or is longer than [`MAX_FILE_BYTES`] is refused.
    pub fn read(dir: &Path) -> Result<Self, BagError> {
        if !dir.is_dir() {
            return Err(BagError::MissingFolder(dir.to_path_buf()));
        }
        let path = dir.join(FILE_NAME);
        match std::fs::symlink_metadata(&path) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Err(BagError::NotABag(dir.to_path_buf())),
            Err(e) => return Err(BagError::io(&path, e)),
            Ok(_) => {}
        }
        let (mut file, _) = files::open_regular(&path, "a metadata file", MAX_FILE_BYTES)?;
        let mut text = String::new();
        file.read_to_string(&mut text).map_err(|e| BagError::io(&path, e))?;
        Self::from_yaml(&text, &path)
    }

    /// The storage files as paths in `dir`, each checked to be a regular file inside it.
    pub fn storage_paths(&self, dir: &Path) -> Result<Vec<PathBuf>, BagError> {
        self.relative_file_paths.iter().map(|file| files::confined_storage_path(dir, file)).collect()
    }

    /// The messages that the storage file `relative` (as listed) holds at least: its count in
    /// `files`, the bag's count when it has one file, else none known.
    pub(crate) fn listed_messages_of(&self, relative: &str) -> u64 {
        match self.files.iter().find(|file| file.path == relative) {
            Some(file) => file.message_count,
            None if self.relative_file_paths.len() == 1 => self.message_count,
            None => 0,
        }
    }

    /// The topics with their message types and QoS (the first offered profile, or reliable keep
    /// last 10 when none was recorded).
    pub fn topics(&self) -> Vec<TopicInfo> {
        self.topics_with_message_count
            .iter()
            .map(|entry| TopicInfo {
                name: entry.topic_metadata.name.clone(),
                type_name: entry.topic_metadata.type_name.clone(),
                qos: entry
                    .topic_metadata
                    .offered_qos_profiles
                    .first()
                    .cloned()
                    .unwrap_or_else(|| QosProfile::keep_last(10, true, false)),
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn topic(name: &str, type_name: &str, latched: bool) -> TopicInfo {
        TopicInfo { name: name.into(), type_name: type_name.into(), qos: QosProfile::keep_last(1, true, latched) }
    }

    #[test]
    fn metadata_round_trips_through_yaml_with_rosbag2_keys() {
        let topics = [
            (topic("/map", "nav_msgs/msg/OccupancyGrid", true), 3),
            (topic("/tf", "tf2_msgs/msg/TFMessage", false), 40),
        ];
        let metadata = BagMetadata::single_file("run_0.mcap", &topics, 1_000, 6_000);
        let yaml = metadata.to_yaml();
        for key in [
            "rosbag2_bagfile_information:",
            "version: 9",
            "storage_identifier: mcap",
            "- run_0.mcap",
            "nanoseconds_since_epoch: 1000",
            "nanoseconds: 5000",
            "message_count: 43",
            "type: nav_msgs/msg/OccupancyGrid",
            "serialization_format: cdr",
            "durability: transient_local",
            "ros_distro: kilted",
        ] {
            assert!(yaml.contains(key), "{key} missing in\n{yaml}");
        }
        let back = BagMetadata::from_yaml(&yaml, Path::new("metadata.yaml")).unwrap();
        assert_eq!(back, metadata);
        let older = yaml.replace("custom_data: {}", "custom_data: ~");
        assert_eq!(BagMetadata::from_yaml(&older, Path::new("metadata.yaml")).unwrap(), metadata);
        assert_eq!(back.topics(), topics.iter().map(|(t, _)| t.clone()).collect::<Vec<_>>());
    }

    #[test]
    fn a_missing_folder_a_folder_without_metadata_and_bad_yaml_are_told_apart() {
        let dir = std::env::temp_dir().join(format!("rover-bag-metadata-{}", std::process::id()));
        let missing = BagMetadata::read(&dir).unwrap_err().to_string();
        assert!(missing.contains("does not exist"), "{missing}");
        std::fs::create_dir_all(&dir).unwrap();
        let not_a_bag = BagMetadata::read(&dir).unwrap_err().to_string();
        assert!(not_a_bag.contains("is not a rosbag2 bag"), "{not_a_bag}");
        std::fs::write(dir.join(FILE_NAME), "rosbag2_bagfile_information: {version: nine}\n").unwrap();
        let bad = BagMetadata::read(&dir).unwrap_err().to_string();
        assert!(bad.contains("metadata.yaml") && bad.contains("version"), "{bad}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
