//! Reading a bag: its metadata and its messages in the order they were written.

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use crate::{BagError, BagMetadata, MessageTime, SERIALIZATION_FORMAT, STORAGE_IDENTIFIER, TopicInfo, files};

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
    files: Vec<StorageFile>,
}

/// A storage file of an opened bag.
#[derive(Debug, Clone)]
struct StorageFile {
    path: PathBuf,
    /// The messages `metadata.yaml` lists for it.
    listed_messages: u64,
}

impl BagReader {
    /// Opens the bag in `dir`: reads `metadata.yaml`, checks that the bag is an uncompressed MCAP
    /// bag of CDR messages and that each storage file is a regular file in `dir` that starts as
    /// an MCAP file does.
    pub fn open(dir: &Path) -> Result<Self, BagError> {
        let metadata = BagMetadata::read(dir)?;
        check_supported(&metadata, &dir.join(crate::metadata::FILE_NAME))?;
        let paths = metadata.storage_paths(dir)?;
        let files = paths
            .into_iter()
            .zip(&metadata.relative_file_paths)
            .map(|(path, relative)| StorageFile { path, listed_messages: metadata.listed_messages_of(relative) })
            .collect::<Vec<_>>();
        for file in &files {
            check_mcap_magic(&file.path)?;
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

    /// The storage files whose writer never ended them (no MCAP summary and end magic): what an
    /// interrupted recording leaves.
    pub fn unfinished_files(&self) -> Result<Vec<PathBuf>, BagError> {
        let mut unfinished = Vec::new();
        for file in &self.files {
            if !ends_with_mcap_magic(&file.path)? {
                unfinished.push(file.path.clone());
            }
        }
        Ok(unfinished)
    }

    /// Every message, file after file, in the order written. A file that ends in an incomplete
    /// or corrupt record after the messages `metadata.yaml` lists for it (an interrupted
    /// recording) ends there with a warning; one that ends before them ends the messages with
    /// an error naming it.
    pub fn messages(&self) -> impl Iterator<Item = Result<BagMessage, BagError>> + '_ {
        self.files.iter().flat_map(FileMessages::open)
    }
}

/// Fails unless `metadata` describes an uncompressed MCAP bag of CDR messages that this reader
/// knows; `path` (the metadata file) names the bag in the error.
fn check_supported(metadata: &BagMetadata, path: &Path) -> Result<(), BagError> {
    let unsupported = |what: String| BagError::Unsupported { path: path.to_path_buf(), what };
    if metadata.version > NEWEST_VERSION {
        return Err(unsupported(format!("metadata version {}", metadata.version)));
    }
    if metadata.storage_identifier != STORAGE_IDENTIFIER {
        return Err(unsupported(format!("storage {:?} (only {STORAGE_IDENTIFIER:?})", metadata.storage_identifier)));
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
    Ok(())
}

/// Opens the storage file `path`: a regular file of any length.
fn open_storage(path: &Path) -> Result<(File, u64), BagError> {
    files::open_regular(path, "a storage file", u64::MAX)
}

/// Fails unless `path` begins with the MCAP magic bytes.
fn check_mcap_magic(path: &Path) -> Result<(), BagError> {
    let (mut file, _) = open_storage(path)?;
    let mut magic = [0u8; 8];
    let read = file.read(&mut magic).map_err(|e| BagError::io(path, e))?;
    if read < magic.len() || magic != mcap::MAGIC {
        return Err(BagError::Unsupported { path: path.to_path_buf(), what: "a file that is not MCAP".to_string() });
    }
    Ok(())
}

/// Whether `path` ends with the MCAP magic bytes, as a finished MCAP file does.
fn ends_with_mcap_magic(path: &Path) -> Result<bool, BagError> {
    let (mut file, len) = open_storage(path)?;
    let magic_len = mcap::MAGIC.len() as u64;
    if len < 2 * magic_len {
        return Ok(false);
    }
    let mut end = [0u8; 8];
    file.seek(SeekFrom::Start(len - magic_len))
        .and_then(|_| file.read_exact(&mut end))
        .map_err(|e| BagError::io(path, e))?;
    Ok(end == mcap::MAGIC)
}

/// The messages of one MCAP file.
enum FileMessages {
    Reading {
        path: PathBuf,
        reader: Box<mcap::io::MessageReader<BufReader<File>>>,
        /// Messages read so far.
        read: u64,
        /// Messages that `metadata.yaml` lists for the file.
        listed: u64,
    },
    Failed(Option<BagError>),
}

impl FileMessages {
    /// Opens `file` for reading; no record is read longer than the file (a corrupt length fails
    /// instead of allocating it), and a chunk's CRC is checked before any of its messages is used.
    fn open(file: &StorageFile) -> Self {
        match open_storage(&file.path) {
            Ok((opened, file_len)) => {
                let options = mcap::sans_io::LinearReaderOptions::default()
                    .with_record_length_limit(usize::try_from(file_len).unwrap_or(usize::MAX))
                    .with_prevalidate_chunk_crcs(true);
                FileMessages::Reading {
                    path: file.path.clone(),
                    reader: Box::new(mcap::io::MessageReader::new_with_options(BufReader::new(opened), options)),
                    read: 0,
                    listed: file.listed_messages,
                }
            }
            Err(e) => FileMessages::Failed(Some(e)),
        }
    }
}

impl Iterator for FileMessages {
    type Item = Result<BagMessage, BagError>;

    fn next(&mut self) -> Option<Self::Item> {
        match self {
            FileMessages::Failed(error) => error.take().map(Err),
            FileMessages::Reading { path, reader, read, listed } => match reader.next()? {
                Ok(message) => {
                    *read += 1;
                    Some(Ok(BagMessage {
                        topic: message.channel.topic.clone(),
                        time: MessageTime { log_ns: message.log_time, publish_ns: message.publish_time },
                        data: message.data.into_owned(),
                    }))
                }
                Err(e) if *read >= *listed => {
                    tracing::warn!(
                        "{}: ends after {read} messages ({listed} listed in metadata.yaml) in an incomplete \
                         record, as an interrupted recording does: {e}",
                        path.display()
                    );
                    *self = FileMessages::Failed(None);
                    None
                }
                Err(e) => {
                    let error = BagError::mcap(path, e);
                    *self = FileMessages::Failed(None);
                    Some(Err(error))
                }
            },
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
        let bytes = std::fs::read(&bag.files[0].path).unwrap();
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
        let written = write_bag(&dir);
        let file = BagReader::open(&dir).unwrap().files[0].path.clone();
        let good = std::fs::read(&file).unwrap();
        let mut errors = 0;
        for cut in (8..good.len()).step_by(7) {
            std::fs::write(&file, &good[..cut]).unwrap();
            let results: Vec<_> = BagReader::open(&dir).unwrap().messages().collect();
            match results.iter().find_map(|result| result.as_ref().err()) {
                Some(error) => {
                    errors += 1;
                    assert!(error.to_string().contains(&file.display().to_string()), "{error}");
                }
                None => {
                    let read: Vec<BagMessage> = results.into_iter().map(Result::unwrap).collect();
                    assert_eq!(read, written, "a file cut at {cut} of {} bytes lost listed messages", good.len());
                }
            }
        }
        assert!(errors > 0, "no cut of the file is an error");
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

    /// Rewrites the storage file list of the bag in `dir` to `listed`.
    fn list_storage(dir: &Path, listed: &str) {
        let path = dir.join(crate::metadata::FILE_NAME);
        let mut metadata = BagMetadata::read(dir).unwrap();
        metadata.relative_file_paths = vec![listed.to_string()];
        metadata.files.clear();
        std::fs::write(path, metadata.to_yaml()).unwrap();
    }

    #[test]
    fn storage_files_outside_the_folder_or_not_regular_are_refused_without_blocking() {
        let dir = temp_dir("hostile");
        write_bag(&dir);
        for (listed, expected) in [
            ("/etc/passwd", "is absolute"),
            ("../x", "has a '..' part"),
            ("..\\x", "has a '..' part"),
            ("/dev/zero", "is absolute"),
        ] {
            list_storage(&dir, listed);
            let error = BagReader::open(&dir).unwrap_err().to_string();
            assert!(error.contains(&format!("{listed:?}")) && error.contains(expected), "{listed}: {error}");
            assert!(error.contains("expected a file name relative to the bag folder"), "{error}");
        }
        let fifo = dir.join("fifo.mcap");
        assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
        list_storage(&dir, "fifo.mcap");
        let error = BagReader::open(&dir).unwrap_err().to_string();
        assert!(error.contains("\"fifo.mcap\" is a FIFO; expected a regular file"), "{error}");
        std::fs::remove_file(dir.join(crate::metadata::FILE_NAME)).unwrap();
        assert!(
            std::process::Command::new("mkfifo").arg(dir.join(crate::metadata::FILE_NAME)).status().unwrap().success()
        );
        let error = BagReader::open(&dir).unwrap_err().to_string();
        assert!(error.contains("metadata.yaml") && error.contains("a FIFO (expected a regular file)"), "{error}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn windows_separators_in_listed_paths_are_read() {
        let dir = temp_dir("windows");
        let written = write_bag(&dir);
        let name = dir.file_name().unwrap().to_str().unwrap().to_string();
        std::fs::create_dir_all(dir.join("storage")).unwrap();
        std::fs::rename(dir.join(format!("{name}_0.mcap")), dir.join(format!("storage/{name}_0.mcap"))).unwrap();
        list_storage(&dir, &format!(".\\storage\\{name}_0.mcap"));
        let read: Vec<BagMessage> = BagReader::open(&dir).unwrap().messages().collect::<Result<_, _>>().unwrap();
        assert_eq!(read, written);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A bag of `/odom` messages whose writer stops without finishing, as a killed recorder does
    /// (its buffers lost): `checkpointed` messages written and checkpointed, then `lost` more.
    fn killed_recording(dir: &Path, checkpointed: u8, lost: u8) -> Vec<BagMessage> {
        let mut writer = BagWriter::create(dir).unwrap();
        let odom = writer.add_topic(topic::<Odometry>("/odom"), &schema_text(&Odometry::definitions())).unwrap();
        let mut written = Vec::new();
        for index in 0..checkpointed + lost {
            if index == checkpointed {
                writer.checkpoint().unwrap();
            }
            let time = MessageTime { log_ns: 1_000 + u64::from(index), publish_ns: 1_000 };
            writer.write(odom, time, &[0, 1, 0, 0, index]).unwrap();
            written.push(BagMessage { topic: "/odom".into(), time, data: vec![0, 1, 0, 0, index] });
        }
        std::mem::forget(writer);
        written
    }

    #[test]
    fn a_recording_that_never_finished_reads_up_to_its_last_checkpoint() {
        let dir = temp_dir("killed");
        let written = killed_recording(&dir, 3, 2);
        let file = dir.join(format!("{}_0.mcap", dir.file_name().unwrap().to_str().unwrap()));
        let mut bytes = std::fs::read(&file).unwrap();
        bytes.extend_from_slice(&[0x06, 0xff, 0x01]);
        std::fs::write(&file, &bytes).unwrap();
        let bag = BagReader::open(&dir).unwrap();
        assert_eq!(bag.metadata().message_count, 3);
        assert_eq!(bag.metadata().topics_with_message_count[0].message_count, 3);
        let read: Vec<BagMessage> = bag.messages().collect::<Result<_, _>>().unwrap();
        assert_eq!(read, written[..3]);
        assert_eq!(bag.unfinished_files().unwrap(), [file]);
        std::fs::remove_dir_all(&dir).unwrap();
        killed_recording(&dir, 0, 2);
        let bag = BagReader::open(&dir).unwrap();
        assert_eq!((bag.metadata().message_count, bag.topics().len(), bag.messages().count()), (0, 1, 0));
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
            let mcap = std::fs::read(&bag.files[0].path).unwrap();
            let metadata = std::fs::read_to_string(dir.join(crate::metadata::FILE_NAME)).unwrap();
            std::fs::remove_dir_all(&dir).unwrap();
            (mcap, metadata)
        }

        proptest! {
            #[test]
            fn fuzz_bag_mutated_mcap(bytes in mutated_bytes(valid_bag("fuzz-mcap-seed").0)) {
                let dir = temp_dir("fuzz-mcap");
                write_bag(&dir);
                let file = BagReader::open(&dir).unwrap().files[0].path.clone();
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
