//! Every topic of the graph: relative name, message type and QoS, in one table (docs/architecture.md).

use std::marker::PhantomData;

use ros2_client::QosProfile;
use ros2_client::qos::History;
use rover_msgs::RosMessage;
use rover_msgs::diagnostic_msgs::DiagnosticArray;
use rover_msgs::geometry_msgs::{PoseArray, PoseStamped, Twist};
use rover_msgs::msg::{DecisionState, DriveCommand, MapStats, PickupRequest, Telemetry, TerrainScan};
use rover_msgs::nav_msgs::{OccupancyGrid, Odometry, Path};
use rover_msgs::rosgraph_msgs::Clock;
use rover_msgs::sensor_msgs::{CameraInfo, CompressedImage, Image};
use rover_msgs::tf2_msgs::TFMessage;
use rover_msgs::visualization_msgs::MarkerArray;

use crate::qos::{latched, reliable};

/// A topic: its name (relative unless it starts with `/`), its message type `M` and its QoS.
pub struct Topic<M> {
    /// Topic name as the nodes use it before namespacing and remapping.
    pub name: &'static str,
    /// QoS of publishers (offered to every reader: reliable ones such as rclpy's defaults too).
    pub qos: QosProfile,
    /// Whether the graph reads it best effort (a message of the lock-step loop, see
    /// [`Topic::per_frame`]).
    read_best_effort: bool,
    message: PhantomData<fn() -> M>,
}

impl<M> Topic<M> {
    const fn new(name: &'static str, qos: QosProfile) -> Self {
        Topic { name, qos, read_best_effort: false, message: PhantomData }
    }

    /// A topic of the lock-step loop, one message a frame, that the graph's nodes read best
    /// effort: a frame's message repaired after its deadline is worth nothing (the bridge holds
    /// the last command instead), and a reliable reader would answer every sample's heartbeat
    /// with an acknowledgement and hold later frames back behind a lost one. A best-effort
    /// reader also takes a best-effort publisher's messages (rclpy's `qos_profile_sensor_data`).
    const fn per_frame(name: &'static str, qos: QosProfile) -> Self {
        Topic { name, qos, read_best_effort: true, message: PhantomData }
    }

    /// QoS of subscriptions: the publishers' `qos`, best effort for a topic of the loop.
    pub fn reader_qos(&self) -> QosProfile {
        let qos = self.qos.clone();
        if self.read_best_effort { qos.reliability_best_effort() } else { qos }
    }

    /// The same topic read reliably with a history of `depth` messages, for a reader that must
    /// not lose messages while it lags behind, such as a recorder (history is not part of QoS
    /// matching).
    pub fn with_history_depth(&self, depth: usize) -> Self {
        Topic::new(self.name, self.qos.clone().history(History::KeepLast { depth }))
    }
}

/// Something done with topics of the table whatever their message type (see [`visit_all`]).
pub trait TopicVisitor {
    /// Visits one topic.
    fn visit<M: RosMessage>(&mut self, topic: &Topic<M>) -> anyhow::Result<()>;
}

/// Visits every topic of the table, in the order of the table; stops at the first error.
pub fn visit_all(visitor: &mut impl TopicVisitor) -> anyhow::Result<()> {
    visitor.visit(&CAMERA_COMPRESSED)?;
    visitor.visit(&CAMERA_RAW)?;
    visitor.visit(&CAMERA_INFO)?;
    visitor.visit(&ODOM)?;
    visitor.visit(&TF)?;
    visitor.visit(&TF_STATIC)?;
    visitor.visit(&TELEMETRY)?;
    visitor.visit(&SAMPLE_TRUTH)?;
    visitor.visit(&TERRAIN)?;
    visitor.visit(&VISION)?;
    visitor.visit(&MAP)?;
    visitor.visit(&MAP_IMAGE)?;
    visitor.visit(&MAP_STATS)?;
    visitor.visit(&ROCKS)?;
    visitor.visit(&SAMPLE_MARKERS)?;
    visitor.visit(&DRIVE_CMD)?;
    visitor.visit(&PICKUP)?;
    visitor.visit(&MODE)?;
    visitor.visit(&PLAN)?;
    visitor.visit(&CMD_VEL)?;
    visitor.visit(&GOAL_POSE)?;
    visitor.visit(&CLOCK)?;
    visitor.visit(&DIAGNOSTICS)
}

/// The simulator's JPEG, untouched.
pub const CAMERA_COMPRESSED: Topic<CompressedImage> = Topic::per_frame("camera/image_raw/compressed", reliable(5));
/// The decoded camera image, rgb8 320x160 (optional).
pub const CAMERA_RAW: Topic<Image> = Topic::new("camera/image_raw", reliable(1));
/// The calibrated pinhole model of the camera.
pub const CAMERA_INFO: Topic<CameraInfo> = Topic::new("camera/camera_info", reliable(5));
/// Odometry of `base_link` in `odom`.
pub const ODOM: Topic<Odometry> = Topic::new("odom", reliable(10));
/// Transforms.
pub const TF: Topic<TFMessage> = Topic::new("/tf", reliable(100));
/// Static transforms (latched).
pub const TF_STATIC: Topic<TFMessage> = Topic::new("/tf_static", latched());
/// Parsed simulator telemetry, one per frame.
pub const TELEMETRY: Topic<Telemetry> = Topic::per_frame("rover/telemetry", reliable(10));
/// True sample positions (scoring only, never for decisions).
pub const SAMPLE_TRUTH: Topic<PoseArray> = Topic::new("sim/sample_truth", latched());
/// Classified terrain per camera frame.
pub const TERRAIN: Topic<TerrainScan> = Topic::per_frame("rover/terrain", reliable(10));
/// Classified bird's-eye view (becomes the simulator's `inset_image2`).
pub const VISION: Topic<Image> = Topic::new("rover/vision", reliable(1));
/// The world map (latched).
pub const MAP: Topic<OccupancyGrid> = Topic::new("map", latched());
/// Udacity-style world map image with statistics (becomes `inset_image1`).
pub const MAP_IMAGE: Topic<Image> = Topic::new("map/image", reliable(1));
/// Map quality statistics.
pub const MAP_STATS: Topic<MapStats> = Topic::new("rover/map_stats", reliable(10));
/// De-duplicated world positions of detected rock samples.
pub const ROCKS: Topic<PoseArray> = Topic::new("rover/rocks", latched());
/// The located rocks and the places of the collected samples, as markers (latched).
pub const SAMPLE_MARKERS: Topic<MarkerArray> = Topic::new("rover/sample_markers", latched());
/// Drive commands answering telemetry frames.
pub const DRIVE_CMD: Topic<DriveCommand> = Topic::per_frame("rover/drive_cmd", reliable(10));
/// Pickup requests.
pub const PICKUP: Topic<PickupRequest> = Topic::new("rover/pickup", reliable(10));
/// State of the decision node.
pub const MODE: Topic<DecisionState> = Topic::new("rover/mode", latched());
/// The path on the map that the decision node follows, cell centre by cell centre (empty while
/// it follows none).
pub const PLAN: Topic<Path> = Topic::new("rover/plan", latched());
/// Teleoperation velocity (overrides the decision node while fresh).
pub const CMD_VEL: Topic<Twist> = Topic::new("cmd_vel", reliable(10));
/// A goal to drive to, in `map` (what RViz's and Foxglove's "2D goal pose" tools publish).
pub const GOAL_POSE: Topic<PoseStamped> = Topic::new("goal_pose", reliable(10));
/// Simulated time, from the bridge (nodes with `use_sim_time` stamp with it).
pub const CLOCK: Topic<Clock> = Topic::new("/clock", reliable(1));
/// Bridge health.
pub const DIAGNOSTICS: Topic<DiagnosticArray> = Topic::new("/diagnostics", reliable(10));

/// The name of every topic of the table, in its order.
pub fn all_names() -> Vec<&'static str> {
    /// Collects the name of every topic visited.
    struct Names(Vec<&'static str>);

    impl TopicVisitor for Names {
        fn visit<M: RosMessage>(&mut self, topic: &Topic<M>) -> anyhow::Result<()> {
            self.0.push(topic.name);
            Ok(())
        }
    }

    let mut names = Names(Vec::new());
    visit_all(&mut names).expect("collecting names cannot fail");
    names.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_topic_constant_of_this_file_is_visited_once() {
        let names = all_names();
        let source = include_str!("topics.rs");
        let declared = source.lines().filter(|line| line.starts_with("pub const ") && line.contains("Topic<")).count();
        assert_eq!(names.len(), declared);
        let mut unique = names.clone();
        unique.sort();
        unique.dedup();
        assert_eq!(unique.len(), names.len(), "{names:?}");
    }
}
