//! `rover bag from-dataset`: the frames of a recorded dataset written as the bridge would have
//! published them, each stamped (and logged) at the time in its image's name.

use std::path::PathBuf;

use rover_bag::{BagMetadata, BagWriter, MessageTime, TopicId};
use rover_bridge::convert::{FrameMessages, PinholeCamera, static_transforms_message};
use rover_msgs::body::CameraMount;
use rover_msgs::builtin_interfaces::Time;
use rover_msgs::frame_ids;
use rover_msgs::std_msgs::Header;
use rover_runtime::RosArgs;
use rover_runtime::names::NodeIdentity;
use rover_runtime::topics;

use super::{add_topic, summary, write_message};
use crate::tools::dataset::{RecordedFrame, read_log};

/// The node name the topics are resolved for (namespace and remaps as for a recorder).
const CONVERTER_NODE: &str = "rosbag2_recorder";

/// Options of `rover bag from-dataset`.
#[derive(Debug, Clone, clap::Args)]
pub struct FromDatasetArgs {
    /// Recorded dataset: a folder with robot_log.csv and IMG/ (e.g. ../shared/udacity/test_dataset),
    /// or the log itself, as the simulator wrote it on any machine.
    #[arg(value_name = "DATASET")]
    pub dataset: PathBuf,
    /// The bag folder to create (it must not exist yet).
    #[arg(short = 'o', long = "output", value_name = "DIR")]
    pub output: PathBuf,
}

/// The bag's topics.
struct DatasetTopics {
    camera: TopicId,
    camera_info: TopicId,
    telemetry: TopicId,
    odom: TopicId,
    tf: TopicId,
    tf_static: TopicId,
}

impl DatasetTopics {
    fn add(writer: &mut BagWriter, identity: &NodeIdentity) -> anyhow::Result<Self> {
        Ok(DatasetTopics {
            camera: add_topic(writer, identity, &topics::CAMERA_COMPRESSED)?,
            camera_info: add_topic(writer, identity, &topics::CAMERA_INFO)?,
            telemetry: add_topic(writer, identity, &topics::TELEMETRY)?,
            odom: add_topic(writer, identity, &topics::ODOM)?,
            tf: add_topic(writer, identity, &topics::TF)?,
            tf_static: add_topic(writer, identity, &topics::TF_STATIC)?,
        })
    }

    /// Writes frame number `number` (from 1) of the dataset; the static transforms before the first.
    fn write_frame(&self, writer: &mut BagWriter, frame: &RecordedFrame, number: u64) -> anyhow::Result<()> {
        let time_ns = frame.time_ns()?;
        let time = MessageTime { log_ns: time_ns, publish_ns: time_ns };
        let stamp = Time::from_nanos(i64::try_from(time_ns)?);
        if number == 1 {
            let transforms = static_transforms_message(&CameraMount::UNITY, &Header::at(frame_ids::MAP, stamp.clone()));
            write_message(writer, self.tf_static, time, &transforms)?;
        }
        let messages = FrameMessages::new(&frame.sim_telemetry(frame.jpeg()?), number, stamp, &PinholeCamera::rover());
        write_message(writer, self.camera, time, &messages.compressed)?;
        write_message(writer, self.camera_info, time, &messages.camera_info)?;
        write_message(writer, self.telemetry, time, &messages.telemetry)?;
        write_message(writer, self.odom, time, &messages.odom)?;
        write_message(writer, self.tf, time, &messages.tf)
    }
}

/// Writes the bag of `args.dataset` into `args.output`; topic names follow the namespace and
/// remaps of `ros_args`.
pub fn from_dataset(args: &FromDatasetArgs, ros_args: &RosArgs) -> anyhow::Result<BagMetadata> {
    let frames = read_log(&args.dataset)?.frames;
    anyhow::ensure!(!frames.is_empty(), "{}: robot_log.csv has no frames", args.dataset.display());
    let identity = NodeIdentity::resolve(CONVERTER_NODE, ros_args)?;
    let mut writer = BagWriter::create(&args.output)?;
    let topics = DatasetTopics::add(&mut writer, &identity)?;
    for (frame, number) in frames.iter().zip(1..) {
        topics.write_frame(&mut writer, frame, number)?;
    }
    let metadata = writer.finish()?;
    print!("{}", summary(&args.output, &metadata));
    Ok(metadata)
}
