//! Reading a bag: its metadata and its messages in the order they were written.

use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

use crate::{BagError, BagMetadata, MessageTime, SERIALIZATION_FORMAT, STORAGE_IDENTIFIER, TopicInfo};

/// The newest metadata version this reader knows.
const NEWEST_VERSION: u32 = 9;

/// One message of a bag.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BagMessage {
    /// Its topic's name.
    pub topic: String,
    /// When it was logged and published.
    pub time: MessageTime,
    /// Its serialized bytes (CDR with the encapsulation header).
    pub data: Vec<u8>,
}

/// An opened bag: its metadata, checked, and its storage files.
#[derive(Debug)]
pub struct BagReader {
    metadata: BagMetadata,
    files: Vec<PathBuf>,
}

impl BagReader {
    /// Opens the bag in `dir`: reads `metadata.yaml`, checks that the bag is an uncompressed MCAP
    /// bag of CDR messages and that each storage file starts as an MCAP file does.
    pub fn open(dir: &Path) -> Result<Self, BagError> {
        let metadata = BagMetadata::read(dir)?;
        let metadata_path = dir.join(crate::metadata::FILE_NAME);
        let unsupported = |what: String| BagError::Unsupported { path: metadata_path.clone(), what };
        if metadata.version > NEWEST_VERSION {
            return Err(unsupported(format!("metadata version {}", metadata.version)));
        }
        if metadata.storage_identifier != STORAGE_IDENTIFIER {
            return Err(unsupported(format!(
                "storage {:?} (only {STORAGE_IDENTIFIER:?})",
                metadata.storage_identifier
            )));
        }
        if !metadata.compression_mode.is_empty() && !metadata.compression_mode.eq_ignore_ascii_case("none") {
            return Err(unsupported(format!("compression {:?}", metadata.compression_mode)));
        }
        if let Some(topic) = metadata
            .topics_with_message_count
            .iter()
            .find(|t| t.topic_metadata.serialization_format != SERIALIZATION_FORMAT)
        {
            return Err(unsupported(format!(
                "serialization format {:?} of {}",
                topic.topic_metadata.serialization_format, topic.topic_metadata.name
            )));
        }
        let files = metadata.storage_paths(dir);
        for file in &files {
            check_mcap_magic(file)?;
        }
        Ok(BagReader { metadata, files })
    }

    /// The bag's metadata.
    pub fn metadata(&self) -> &BagMetadata {
        &self.metadata
    }

    /// The bag's topics.
    pub fn topics(&self) -> Vec<TopicInfo> {
        self.metadata.topics()
    }

    /// Every message, file after file, in the order written; a corrupt file ends the messages
    /// with an error naming it.
    pub fn messages(&self) -> impl Iterator<Item = Result<BagMessage, BagError>> + '_ {
        self.files.iter().flat_map(|path| FileMessages::open(path))
    }
}

/// Fails unless `path` begins with the MCAP magic bytes.
fn check_mcap_magic(path: &Path) -> Result<(), BagError> {
    let mut file = File::open(path).map_err(|e| BagError::io(path, e))?;
    let mut magic = [0u8; 8];
    let read = file.read(&mut magic).map_err(|e| BagError::io(path, e))?;
    if read < magic.len() || magic != mcap::MAGIC {
        return Err(BagError::Unsupported { path: path.to_path_buf(), what: "a file that is not MCAP".to_string() });
    }
    Ok(())
}

/// The messages of one MCAP file.
enum FileMessages {
    Reading { path: PathBuf, reader: Box<mcap::io::MessageReader<BufReader<File>>> },
    Failed(Option<BagError>),
}

impl FileMessages {
    /// Opens `path` for reading; no record is read longer than the file (a corrupt length fails
    /// instead of allocating it), and a chunk's CRC is checked before any of its messages is used.
    fn open(path: &Path) -> Self {
        let opened = File::open(path).and_then(|file| Ok((file.metadata()?.len(), file)));
        match opened {
            Ok((file_len, file)) => {
                let options = mcap::sans_io::LinearReaderOptions::default()
                    .with_record_length_limit(usize::try_from(file_len).unwrap_or(usize::MAX))
                    .with_prevalidate_chunk_crcs(true);
                FileMessages::Reading {
                    path: path.to_path_buf(),
                    reader: Box::new(mcap::io::MessageReader::new_with_options(BufReader::new(file), options)),
                }
            }
            Err(e) => FileMessages::Failed(Some(BagError::io(path, e))),
        }
    }
}

impl Iterator for FileMessages {
    type Item = Result<BagMessage, BagError>;

    fn next(&mut self) -> Option<Self::Item> {
        match self {
            FileMessages::Failed(error) => error.take().map(Err),
            FileMessages::Reading { path, reader } => Some(match reader.next()? {
                Ok(message) => Ok(BagMessage {
                    topic: message.channel.topic.clone(),
                    time: MessageTime { log_ns: message.log_time, publish_ns: message.publish_time },
                    data: message.data.into_owned(),
                }),
                Err(e) => Err(BagError::mcap(path, e)),
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use rover_msgs::RosMessage;
    use rover_msgs::msg::MapStats;
    use rover_msgs::nav_msgs::Odometry;

    use super::*;
    use crate::schema::schema_text;
    use crate::{BagWriter, QosProfile};

    fn temp_dir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("rover-bag-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        dir
    }

    fn topic<M: RosMessage>(name: &str) -> TopicInfo {
        TopicInfo { name: name.into(), type_name: M::type_name(), qos: QosProfile::keep_last(10, true, false) }
    }

    /// Writes a bag of 3 `/odom` and 2 `/rover/map_stats` messages in `dir`.
    fn write_bag(dir: &Path) -> Vec<BagMessage> {
        let mut writer = BagWriter::create(dir).unwrap();
        let odom = writer.add_topic(topic::<Odometry>("/odom"), &schema_text(&Odometry::definitions())).unwrap();
        let stats =
            writer.add_topic(topic::<MapStats>("/rover/map_stats"), &schema_text(&MapStats::definitions())).unwrap();
        let mut written = Vec::new();
        for (index, (id, name)) in [
            (odom, "/odom"),
            (stats, "/rover/map_stats"),
            (odom, "/odom"),
            (odom, "/odom"),
            (stats, "/rover/map_stats"),
        ]
        .into_iter()
        .enumerate()
        {
            let time = MessageTime { log_ns: 1_000 + index as u64 * 40, publish_ns: 990 + index as u64 * 40 };
            let data = vec![0, 1, 0, 0, index as u8, 7, 7];
            writer.write(id, time, &data).unwrap();
            written.push(BagMessage { topic: name.into(), time, data });
        }
        let metadata = writer.finish().unwrap();
        assert_eq!(metadata.message_count, 5);
        written
    }

    #[test]
    fn written_messages_read_back_in_order_with_their_topics_and_counts() {
        let dir = temp_dir("round-trip");
        let written = write_bag(&dir);
        assert!(dir.join(format!("{}_0.mcap", dir.file_name().unwrap().to_str().unwrap())).is_file());
        let bag = BagReader::open(&dir).unwrap();
        let read: Vec<BagMessage> = bag.messages().collect::<Result<_, _>>().unwrap();
        assert_eq!(read, written);
        let counts: Vec<(String, u64)> = bag
            .metadata()
            .topics_with_message_count
            .iter()
            .map(|t| (t.topic_metadata.name.clone(), t.message_count))
            .collect();
        assert_eq!(counts, [("/odom".to_string(), 3), ("/rover/map_stats".to_string(), 2)]);
        assert_eq!(
            (bag.metadata().starting_time.nanoseconds_since_epoch, bag.metadata().duration.nanoseconds),
            (1_000, 160)
        );
        assert_eq!(bag.topics()[0].type_name, "nav_msgs/msg/Odometry");
        let again = BagWriter::create(&dir).err().unwrap().to_string();
        assert!(again.contains("already exists"), "{again}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn the_mcap_file_has_the_ros2_profile_schemas_and_qos_metadata() {
        let dir = temp_dir("layout");
        write_bag(&dir);
        let bag = BagReader::open(&dir).unwrap();
        let bytes = std::fs::read(&bag.files[0]).unwrap();
        let summary = mcap::Summary::read(&bytes).unwrap().expect("a summary section");
        let channel = summary.channels.values().find(|c| c.topic == "/odom").unwrap();
        assert_eq!(channel.message_encoding, "cdr");
        assert!(channel.metadata["offered_qos_profiles"].contains("reliability: reliable"));
        let schema = channel.schema.as_ref().unwrap();
        assert_eq!((schema.name.as_str(), schema.encoding.as_str()), ("nav_msgs/msg/Odometry", "ros2msg"));
        assert!(String::from_utf8_lossy(&schema.data).contains("MSG: geometry_msgs/PoseWithCovariance\n"));
        let header = mcap::read::LinearReader::new(&bytes).unwrap().next().unwrap().unwrap();
        assert!(matches!(header, mcap::records::Record::Header(h) if h.profile == "ros2"));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn corrupt_or_foreign_files_are_errors_naming_the_file_never_panics() {
        let dir = temp_dir("corrupt");
        write_bag(&dir);
        let file = BagReader::open(&dir).unwrap().files[0].clone();
        let good = std::fs::read(&file).unwrap();
        for cut in (8..good.len()).step_by(7) {
            std::fs::write(&file, &good[..cut]).unwrap();
            let results: Vec<_> = BagReader::open(&dir).unwrap().messages().collect();
            assert!(
                results.iter().any(Result::is_err),
                "a file cut at {cut} of {} bytes reads without error",
                good.len()
            );
            let error = results.into_iter().find_map(Result::err).unwrap().to_string();
            assert!(error.contains(&file.display().to_string()), "{error}");
        }
        for at in (8..good.len()).step_by(5) {
            let mut flipped = good.clone();
            flipped[at] ^= 0x5a;
            std::fs::write(&file, &flipped).unwrap();
            let _ = BagReader::open(&dir).unwrap().messages().count();
        }
        std::fs::write(&file, b"SQLite format 3\0").unwrap();
        let foreign = BagReader::open(&dir).unwrap_err().to_string();
        assert!(foreign.contains("not MCAP") && foreign.contains(&file.display().to_string()), "{foreign}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    mod fuzz {
        use proptest::prelude::*;
        use rover_fuzzing::mutation::{mutated_bytes, mutated_text};

        use super::*;

        /// A bag written once in a folder named after `name`, its MCAP bytes and its metadata text.
        fn valid_bag(name: &str) -> (Vec<u8>, String) {
            let dir = temp_dir(name);
            write_bag(&dir);
            let bag = BagReader::open(&dir).unwrap();
            let mcap = std::fs::read(&bag.files[0]).unwrap();
            let metadata = std::fs::read_to_string(dir.join(crate::metadata::FILE_NAME)).unwrap();
            std::fs::remove_dir_all(&dir).unwrap();
            (mcap, metadata)
        }

        proptest! {
            #[test]
            fn fuzz_bag_mutated_mcap(bytes in mutated_bytes(valid_bag("fuzz-mcap-seed").0)) {
                let dir = temp_dir("fuzz-mcap");
                write_bag(&dir);
                let file = BagReader::open(&dir).unwrap().files[0].clone();
                std::fs::write(&file, &bytes).unwrap();
                if let Ok(bag) = BagReader::open(&dir) {
                    for message in bag.messages() {
                        if let Err(e) = message {
                            prop_assert!(e.to_string().contains(&file.display().to_string()), "{}", e);
                        }
                    }
                }
                std::fs::remove_dir_all(&dir).unwrap();
            }

            #[test]
            fn fuzz_bag_mutated_metadata(text in mutated_text(vec![valid_bag("fuzz-metadata-seed").1])) {
                let path = Path::new("fuzz/metadata.yaml");
                if let Err(e) = BagMetadata::from_yaml(&text, path) {
                    prop_assert!(e.to_string().contains("fuzz/metadata.yaml"), "{}", e);
                }
            }
        }
    }
}
