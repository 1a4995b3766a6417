//! Rust types for the ROS 2 messages of the rover graph.
//!
//! [`msg`] holds the `rover_msgs` interfaces, generated at build time from `msg/*.msg`.
//! [`validate`] checks the fields of received messages before a node uses them.
//! The other modules mirror the standard messages the graph uses, field for field in wire order;
//! a test checks each of them against the `.msg` files of an installed ROS 2 distribution.
//! Every type implements [`RosMessage`] (its DDS type name and field list) and
//! [`ros2_client::Message`], so it can be published and subscribed with `ros2-client`.
//!
//! Beside the messages, the facts the nodes share about what the messages carry: [`map_grid`]
//! (the map's cells), [`body`] (the camera mount, the arm's reach), [`frame_ids`] (the coordinate
//! frames), [`tally`] (samples counted from telemetry) and [`unity`] (the rover's state as the
//! simulator reports it).

pub mod body;
pub mod frame_ids;
pub mod frames;
pub mod idl;
pub mod map_grid;
pub mod tally;
pub mod unity;
pub mod validate;
#[macro_use]
mod macros;
mod fixed_array;
mod int8_bytes;

pub use fixed_array::Covariance;

/// A ROS 2 message type: its package, its name and its fields in wire order.
pub trait RosMessage: ros2_client::Message + RosFieldType + Clone + Send + Sync + 'static {
    /// ROS package, e.g. `sensor_msgs`.
    const PACKAGE: &'static str;
    /// Message name within the package, e.g. `Image`.
    const NAME: &'static str;
    /// Field names and normalised ROS types, in wire order.
    fn fields() -> Vec<(&'static str, String)>;
    /// The name rclpy and the ROS tools show, e.g. `sensor_msgs/msg/Image`.
    fn type_name() -> String {
        format!("{}/msg/{}", Self::PACKAGE, Self::NAME)
    }
    /// This type's definition first, then those of every message type nested in it, each once,
    /// in depth-first order of first use.
    fn definitions() -> Vec<Definition> {
        let mut definitions = Vec::new();
        Self::add_definitions(&mut definitions);
        definitions
    }
}

/// The definition of one message type: its name and its fields.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Definition {
    /// `package/Name`, as a field of this type is written, e.g. `geometry_msgs/Pose`.
    pub type_name: String,
    /// Field names and normalised ROS types, in wire order.
    pub fields: Vec<(&'static str, String)>,
}

/// The ROS type of a Rust field type, e.g. `float64[]` for `Vec<f64>`.
pub trait RosFieldType {
    /// Normalised ROS type name.
    fn ros_type() -> String;
    /// Appends the definitions of the message types this type is made of that `definitions`
    /// lacks (none for a primitive).
    fn add_definitions(_definitions: &mut Vec<Definition>) {}
}

macro_rules! primitive_field_types {
    ($($rust:ty => $ros:literal),* $(,)?) => {
        $(impl RosFieldType for $rust { fn ros_type() -> String { $ros.to_string() } })*
    };
}

primitive_field_types! {
    bool => "bool", i8 => "int8", u8 => "uint8", i16 => "int16", u16 => "uint16",
    i32 => "int32", u32 => "uint32", i64 => "int64", u64 => "uint64",
    f32 => "float32", f64 => "float64", String => "string",
}

impl<T: RosFieldType> RosFieldType for Vec<T> {
    fn ros_type() -> String {
        format!("{}[]", T::ros_type())
    }
    fn add_definitions(definitions: &mut Vec<Definition>) {
        T::add_definitions(definitions);
    }
}

impl<T: RosFieldType, const N: usize> RosFieldType for [T; N] {
    fn ros_type() -> String {
        format!("{}[{N}]", T::ros_type())
    }
    fn add_definitions(definitions: &mut Vec<Definition>) {
        T::add_definitions(definitions);
    }
}

/// The `rover_msgs` interfaces, generated from `msg/*.msg`.
pub mod msg {
    include!(concat!(env!("OUT_DIR"), "/rover_msgs.rs"));
}

/// `builtin_interfaces` messages.
pub mod builtin_interfaces {
    ros_message! {
        /// A point in time: seconds and nanoseconds since the Unix epoch.
        "builtin_interfaces" / Time { sec: i32, nanosec: u32 }
    }

    ros_message! {
        /// A span of time: seconds and nanoseconds.
        "builtin_interfaces" / Duration { sec: i32, nanosec: u32 }
    }

    impl Duration {
        /// The duration of `seconds` (negative or not finite: zero).
        pub fn from_secs_f64(seconds: f64) -> Self {
            let seconds = if seconds.is_finite() { seconds.clamp(0.0, i32::MAX as f64) } else { 0.0 };
            Duration { sec: seconds.trunc() as i32, nanosec: (seconds.fract() * 1e9) as u32 }
        }

        /// The duration in seconds.
        pub fn as_secs_f64(&self) -> f64 {
            self.sec as f64 + self.nanosec as f64 * 1e-9
        }
    }

    impl Time {
        /// The current wall-clock time.
        pub fn now() -> Self {
            let since_epoch = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap_or_default();
            Time { sec: since_epoch.as_secs() as i32, nanosec: since_epoch.subsec_nanos() }
        }

        /// The time `nanos` nanoseconds after the epoch (negative values clamp to the epoch).
        pub fn from_nanos(nanos: i64) -> Self {
            let nanos = nanos.max(0);
            Time { sec: (nanos / 1_000_000_000) as i32, nanosec: (nanos % 1_000_000_000) as u32 }
        }

        /// Seconds since the epoch.
        pub fn as_secs_f64(&self) -> f64 {
            self.sec as f64 + self.nanosec as f64 * 1e-9
        }
    }
}

/// `std_msgs` messages.
pub mod std_msgs {
    ros_message! {
        /// Time stamp and coordinate frame of a message.
        "std_msgs" / Header { stamp: crate::builtin_interfaces::Time, frame_id: String }
    }
    ros_message! { /// A colour, each channel 0 to 1.
    "std_msgs" / ColorRGBA { r: f32, g: f32, b: f32, a: f32 } }

    impl Header {
        /// A header stamped now in `frame_id`.
        pub fn now(frame_id: &str) -> Self {
            Header::at(frame_id, crate::builtin_interfaces::Time::now())
        }

        /// A header stamped `stamp` in `frame_id`.
        pub fn at(frame_id: &str, stamp: crate::builtin_interfaces::Time) -> Self {
            Header { stamp, frame_id: frame_id.to_string() }
        }
    }
}

/// `geometry_msgs` messages.
pub mod geometry_msgs {
    use crate::std_msgs::Header;

    ros_message! { /// A position in space, metres.
    "geometry_msgs" / Point { x: f64, y: f64, z: f64 } }
    ros_message! { /// A vector in space.
    "geometry_msgs" / Vector3 { x: f64, y: f64, z: f64 } }
    ros_message! { /// An orientation as a unit quaternion.
    "geometry_msgs" / Quaternion { x: f64, y: f64, z: f64, w: f64 } }
    ros_message! { /// A position and an orientation.
    "geometry_msgs" / Pose { position: Point, orientation: Quaternion } }
    ros_message! { /// A set of poses in one frame.
    "geometry_msgs" / PoseArray { header: Header, poses: Vec<Pose> } }
    ros_message! { /// A pose in the frame of its header.
    "geometry_msgs" / PoseStamped { header: Header, pose: Pose } }
    ros_message! { /// Linear (m/s) and angular (rad/s) velocity.
    "geometry_msgs" / Twist { linear: Vector3, angular: Vector3 } }
    ros_message! { /// A pose with its 6x6 covariance.
    "geometry_msgs" / PoseWithCovariance { pose: Pose, covariance: crate::Covariance } }
    ros_message! { /// A twist with its 6x6 covariance.
    "geometry_msgs" / TwistWithCovariance { twist: Twist, covariance: crate::Covariance } }
    ros_message! { /// A rigid transform.
    "geometry_msgs" / Transform { translation: Vector3, rotation: Quaternion } }
    ros_message! { /// A transform from `header.frame_id` to `child_frame_id`.
    "geometry_msgs" / TransformStamped { header: Header, child_frame_id: String, transform: Transform } }

    impl PoseArray {
        /// Points (x, y) on the floor of `header`'s frame, metres, as poses without rotation.
        pub fn of_points(header: Header, points: &[(f64, f64)]) -> Self {
            let pose =
                |&(x, y): &(f64, f64)| Pose { position: Point { x, y, z: 0.0 }, orientation: Quaternion::IDENTITY };
            PoseArray { header, poses: points.iter().map(pose).collect() }
        }

        /// The position (x, y) of every pose, metres.
        pub fn points(&self) -> Vec<(f64, f64)> {
            self.poses.iter().map(|pose| (pose.position.x, pose.position.y)).collect()
        }
    }

    impl Quaternion {
        /// No rotation.
        pub const IDENTITY: Quaternion = Quaternion { x: 0.0, y: 0.0, z: 0.0, w: 1.0 };

        /// The rotation by `yaw_rad` about z.
        pub fn from_yaw(yaw_rad: f64) -> Self {
            Self::from_rpy(0.0, 0.0, yaw_rad)
        }

        /// The rotation by roll, then pitch, then yaw (fixed axes x, y, z), all in radians.
        pub fn from_rpy(roll_rad: f64, pitch_rad: f64, yaw_rad: f64) -> Self {
            let (sr, cr) = (roll_rad / 2.0).sin_cos();
            let (sp, cp) = (pitch_rad / 2.0).sin_cos();
            let (sy, cy) = (yaw_rad / 2.0).sin_cos();
            Quaternion {
                x: sr * cp * cy - cr * sp * sy,
                y: cr * sp * cy + sr * cp * sy,
                z: cr * cp * sy - sr * sp * cy,
                w: cr * cp * cy + sr * sp * sy,
            }
        }
    }
}

/// `nav_msgs` messages.
pub mod nav_msgs {
    use crate::geometry_msgs::{Pose, PoseStamped, PoseWithCovariance, TwistWithCovariance};
    use crate::std_msgs::Header;

    ros_message! { /// Pose and velocity estimate of `child_frame_id` in `header.frame_id`.
    "nav_msgs" / Odometry {
        header: Header, child_frame_id: String, pose: PoseWithCovariance, twist: TwistWithCovariance,
    } }
    ros_message! { /// Geometry of an occupancy grid.
    "nav_msgs" / MapMetaData {
        map_load_time: crate::builtin_interfaces::Time, resolution: f32, width: u32, height: u32, origin: Pose,
    } }
    ros_message! { /// A 2-D occupancy grid: 0 free, 100 occupied, -1 unknown, row-major from the origin.
    "nav_msgs" / OccupancyGrid {
        header: Header, info: MapMetaData, #[serde(with = "crate::int8_bytes")] data: Vec<i8>,
    } }
    ros_message! { /// A path for a robot to follow, pose by pose.
    "nav_msgs" / Path { header: Header, poses: Vec<PoseStamped> } }
}

/// `sensor_msgs` messages.
pub mod sensor_msgs {
    use crate::std_msgs::Header;

    ros_message! { /// A compressed image (`format` is e.g. `jpeg`).
    "sensor_msgs" / CompressedImage {
        header: Header, format: String, #[serde(with = "serde_bytes")] data: Vec<u8>,
    } }
    ros_message! { /// An uncompressed image.
    "sensor_msgs" / Image {
        header: Header, height: u32, width: u32, encoding: String, is_bigendian: u8, step: u32,
        #[serde(with = "serde_bytes")] data: Vec<u8>,
    } }
    ros_message! { /// A region of an image.
    "sensor_msgs" / RegionOfInterest { x_offset: u32, y_offset: u32, height: u32, width: u32, do_rectify: bool } }
    ros_message! { /// Calibration of a camera: intrinsics, distortion, rectification and projection.
    "sensor_msgs" / CameraInfo {
        header: Header, height: u32, width: u32, distortion_model: String, d: Vec<f64>,
        k: [f64; 9], r: [f64; 9], p: [f64; 12], binning_x: u32, binning_y: u32, roi: RegionOfInterest,
    } }
}

/// `visualization_msgs` messages: the markers that RViz and Foxglove draw.
pub mod visualization_msgs {
    use crate::geometry_msgs::{Point, Pose, Vector3};
    use crate::std_msgs::{ColorRGBA, Header};

    ros_message! { /// A texture coordinate of a mesh.
    "visualization_msgs" / UVCoordinate { u: f32, v: f32 } }
    ros_message! { /// A mesh file sent inline.
    "visualization_msgs" / MeshFile { filename: String, #[serde(with = "serde_bytes")] data: Vec<u8> } }
    ros_message! { /// A shape to draw in the frame of its header.
    "visualization_msgs" / Marker {
        header: Header, ns: String, id: i32, r#type: i32, action: i32, pose: Pose, scale: Vector3,
        color: ColorRGBA, lifetime: crate::builtin_interfaces::Duration, frame_locked: bool,
        points: Vec<Point>, colors: Vec<ColorRGBA>, texture_resource: String,
        texture: crate::sensor_msgs::CompressedImage, uv_coordinates: Vec<UVCoordinate>, text: String,
        mesh_resource: String, mesh_file: MeshFile, mesh_use_embedded_materials: bool,
    } }
    ros_message! { /// Markers published together.
    "visualization_msgs" / MarkerArray { markers: Vec<Marker> } }

    impl Marker {
        /// Type: a sphere (or ellipsoid) of `scale` at `pose`.
        pub const SPHERE: i32 = 2;
        /// Action: add or replace the marker of this `ns` and `id`.
        pub const ADD: i32 = 0;
        /// Action: delete every marker of this `ns` (every marker when `ns` is empty).
        pub const DELETEALL: i32 = 3;
    }
}

/// `tf2_msgs` messages.
pub mod tf2_msgs {
    ros_message! { /// A batch of transforms for `/tf`.
    "tf2_msgs" / TFMessage { transforms: Vec<crate::geometry_msgs::TransformStamped> } }
}

/// `rosgraph_msgs` messages.
pub mod rosgraph_msgs {
    ros_message! { /// The simulated time, published on `/clock`.
    "rosgraph_msgs" / Clock { clock: crate::builtin_interfaces::Time } }
}

/// `lifecycle_msgs` messages and the request and response types of its services: the interface
/// of managed nodes.
pub mod lifecycle_msgs {
    ros_message! { /// A state of the lifecycle: its id and label.
    "lifecycle_msgs" / State { id: u8, label: String } }
    ros_message! { /// A transition of the lifecycle: its id and label.
    "lifecycle_msgs" / Transition { id: u8, label: String } }
    ros_message! { /// A transition with the states it goes from and to.
    "lifecycle_msgs" / TransitionDescription { transition: Transition, start_state: State, goal_state: State } }
    ros_message! { /// A transition that happened, on `<node>/transition_event`.
    "lifecycle_msgs" / TransitionEvent {
        timestamp: u64, transition: Transition, start_state: State, goal_state: State,
    } }
    ros_message! { /// `change_state` request.
    "lifecycle_msgs" / ChangeStateRequest { transition: Transition } }
    ros_message! { /// `change_state` response.
    "lifecycle_msgs" / ChangeStateResponse { success: bool } }
    ros_message! { /// The request of a lifecycle service that takes no argument.
    "lifecycle_msgs" / EmptyRequest { structure_needs_at_least_one_member: u8 } }
    ros_message! { /// `get_state` response.
    "lifecycle_msgs" / GetStateResponse { current_state: State } }
    ros_message! { /// `get_available_states` response.
    "lifecycle_msgs" / GetAvailableStatesResponse { available_states: Vec<State> } }
    ros_message! { /// `get_available_transitions` and `get_transition_graph` response.
    "lifecycle_msgs" / GetAvailableTransitionsResponse { available_transitions: Vec<TransitionDescription> } }
}

/// The goal, result and feedback of `rover_msgs/action/SampleReturn` (`action/SampleReturn.action`):
/// the sample-return mission as one action.
pub mod sample_return {
    ros_message! { /// The goal: nothing to give; the mission starts where the rover stands.
    "rover_msgs" / SampleReturnGoal { structure_needs_at_least_one_member: u8 } }
    ros_message! { /// The result: the mission's score at its end.
    "rover_msgs" / SampleReturnResult {
        complete: bool, mapped_pct: f32, fidelity_pct: f32, samples_located: u32, samples_collected: u32,
        samples_remaining: u8, home_distance_m: f32, mission_time_s: f64, message: String,
    } }
    ros_message! { /// The feedback: how the mission goes.
    "rover_msgs" / SampleReturnFeedback {
        mode: String, mapped_pct: f32, fidelity_pct: f32, samples_located: u32, samples_collected: u32,
        mission_time_s: f64,
    } }

    impl SampleReturnResult {
        /// The result of a goal that ended before the mission did (refused, preempted, canceled),
        /// for the reason `message`: no score.
        pub fn ended_early(message: impl Into<String>) -> Self {
            SampleReturnResult { message: message.into(), ..SampleReturnResult::default() }
        }
    }
}

/// `std_srvs` service types.
pub mod std_srvs {
    ros_message! { /// `std_srvs/srv/Trigger` request: no argument.
    "std_srvs" / TriggerRequest { structure_needs_at_least_one_member: u8 } }
    ros_message! { /// `std_srvs/srv/Trigger` response: whether it worked, and a message for the caller.
    "std_srvs" / TriggerResponse { success: bool, message: String } }
}

/// `nav2_msgs/action/NavigateToPose` of Nav2 Kilted (1.4), field for field, so that Nav2's tools
/// and scripts written for Nav2 talk to the rover unchanged.
pub mod nav2_msgs {
    use crate::builtin_interfaces::Duration;
    use crate::geometry_msgs::PoseStamped;

    ros_message! { /// The goal: a pose, and a behaviour tree (ignored by the rover).
    "nav2_msgs" / NavigateToPoseGoal { pose: PoseStamped, behavior_tree: String } }
    ros_message! { /// The result: an error code (0: none) and its message.
    "nav2_msgs" / NavigateToPoseResult { error_code: u16, error_msg: String } }
    ros_message! { /// The feedback while driving to the goal.
    "nav2_msgs" / NavigateToPoseFeedback {
        current_pose: PoseStamped, navigation_time: Duration, estimated_time_remaining: Duration,
        number_of_recoveries: i16, distance_remaining: f32,
    } }

    impl NavigateToPoseResult {
        /// No error: the goal was reached.
        pub const NONE: u16 = 0;
        /// Any other error (Nav2's navigator code).
        pub const UNKNOWN: u16 = 9000;
        /// The goal is in a frame the rover cannot transform (Nav2's navigator code).
        pub const TF_ERROR: u16 = 9002;
        /// The goal lies outside the map (Nav2's planner code).
        pub const GOAL_OUTSIDE_MAP: u16 = 204;
        /// The goal lies on an obstacle (Nav2's planner code).
        pub const GOAL_OCCUPIED: u16 = 206;
        /// No path leads to the goal (Nav2's planner code).
        pub const NO_VALID_PATH: u16 = 208;

        /// The result of a goal given up because `what` came in its place.
        pub fn preempted_by(what: &str) -> Self {
            NavigateToPoseResult::error(NavigateToPoseResult::UNKNOWN, format!("preempted by {what}"))
        }

        /// The result of a goal that failed with `error_code` for the reason `error_msg`.
        pub fn error(error_code: u16, error_msg: impl Into<String>) -> Self {
            NavigateToPoseResult { error_code, error_msg: error_msg.into() }
        }
    }
}

/// `diagnostic_msgs` messages.
pub mod diagnostic_msgs {
    use crate::std_msgs::Header;

    ros_message! { /// A key and a value.
    "diagnostic_msgs" / KeyValue { key: String, value: String } }
    ros_message! { /// State of one component.
    "diagnostic_msgs" / DiagnosticStatus {
        level: u8, name: String, message: String, hardware_id: String, values: Vec<KeyValue>,
    } }
    ros_message! { /// Diagnostics of several components.
    "diagnostic_msgs" / DiagnosticArray { header: Header, status: Vec<DiagnosticStatus> } }

    impl DiagnosticStatus {
        /// Level: everything is fine.
        pub const OK: u8 = 0;
        /// Level: something needs attention.
        pub const WARN: u8 = 1;
        /// Level: something is wrong.
        pub const ERROR: u8 = 2;
        /// Level: no recent data.
        pub const STALE: u8 = 3;

        /// The value of `key`, if this status has one.
        pub fn value(&self, key: &str) -> Option<&str> {
            self.values.iter().find(|kv| kv.key == key).map(|kv| kv.value.as_str())
        }
    }

    impl DiagnosticArray {
        /// The value of `key` in the first status that has one.
        pub fn value(&self, key: &str) -> Option<&str> {
            self.status.iter().find_map(|status| status.value(key))
        }
    }
}

#[cfg(test)]
mod tests;
