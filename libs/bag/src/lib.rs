//! rosbag2 bags in MCAP storage, as `ros2 bag record` writes them and `ros2 bag play`, rosbags and
//! Foxglove read them: a folder with `metadata.yaml` and `FOLDER_NAME_0.mcap`.
//!
//! The MCAP file has the `ros2` profile; each topic is a channel with message encoding `cdr` and
//! its offered QoS profiles in the channel metadata, whose schema is the message type
//! (`pkg/msg/Name`) in `ros2msg` encoding: the type's definition followed by each nested type's
//! ([`schema`]). The messages are the CDR bytes as published, encapsulation header included.
//! This crate deals in plain types and bytes; the `rover bag` command wires it to DDS.

mod files;
mod metadata;
mod qos;
mod reader;
pub mod schema;
mod writer;

use std::path::{Path, PathBuf};

pub use metadata::BagMetadata;
pub use qos::QosProfile;
pub use reader::{BagMessage, BagReader};
pub use writer::{BagWriter, CHECKPOINT_PERIOD, TopicId};

/// The storage identifier of MCAP bags in `metadata.yaml`.
pub const STORAGE_IDENTIFIER: &str = "mcap";
/// The serialization format of every topic: CDR, as DDS carries it.
pub const SERIALIZATION_FORMAT: &str = "cdr";

/// A topic of a bag: its name, message type and the QoS its publishers offered.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TopicInfo {
    /// Fully qualified topic name, e.g. `/rover/telemetry`.
    pub name: String,
    /// Message type, e.g. `rover_msgs/msg/Telemetry`.
    pub type_name: String,
    /// The QoS the topic's publishers offer.
    pub qos: QosProfile,
}

/// When a message was recorded: reception (log) and publication time, nanoseconds since the epoch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MessageTime {
    /// When the recorder received it.
    pub log_ns: u64,
    /// When its publisher sent it.
    pub publish_ns: u64,
}

/// What can go wrong with a bag, naming the file or folder.
#[derive(Debug, thiserror::Error)]
pub enum BagError {
    /// The folder does not exist.
    #[error("bag folder {0} does not exist")]
    MissingFolder(PathBuf),
    /// The folder has no `metadata.yaml`.
    #[error("{0} is not a rosbag2 bag: it has no metadata.yaml")]
    NotABag(PathBuf),
    /// The output folder is already there (a bag is never overwritten).
    #[error("{0} already exists: give a folder that does not exist yet")]
    OutputExists(PathBuf),
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What failed.
        source: std::io::Error,
    },
    /// `metadata.yaml` is not valid.
    #[error("{path}: {problem}")]
    Metadata {
        /// The metadata file.
        path: PathBuf,
        /// What is wrong with it.
        problem: String,
    },
    /// The bag uses something this crate cannot read.
    #[error("{path}: {what} is not supported")]
    Unsupported {
        /// The metadata or storage file.
        path: PathBuf,
        /// What is not supported.
        what: String,
    },
    /// The MCAP file is corrupt or could not be written.
    #[error("{path}: {source}")]
    Mcap {
        /// The MCAP file.
        path: PathBuf,
        /// What the MCAP library reported.
        source: mcap::McapError,
    },
    /// A storage file that `metadata.yaml` lists is outside the bag folder or not a regular file.
    #[error("{dir}/metadata.yaml: storage file {path:?} {problem}")]
    StoragePath {
        /// The bag folder.
        dir: PathBuf,
        /// The path as listed.
        path: String,
        /// What is wrong with it and what was expected.
        problem: String,
    },
    /// A message names a topic the writer was not given.
    #[error("no topic with id {0} was added to this bag")]
    UnknownTopic(usize),
}

impl BagError {
    fn io(path: &Path, source: std::io::Error) -> Self {
        BagError::Io { path: path.to_path_buf(), source }
    }

    /// An MCAP error on `path`; an I/O error is kept as one, so that its cause (e.g. a full
    /// disk) is in the message.
    fn mcap(path: &Path, source: mcap::McapError) -> Self {
        match source {
            mcap::McapError::Io(source) => BagError::io(path, source),
            source => BagError::Mcap { path: path.to_path_buf(), source },
        }
    }
}
