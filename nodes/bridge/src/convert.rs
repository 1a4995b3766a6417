//! Conversion of a parsed telemetry frame into the ROS messages the bridge publishes.

use rover_msgs::body::CameraMount;
use rover_msgs::builtin_interfaces::Time;
use rover_msgs::frame_ids;
use rover_msgs::geometry_msgs::{
    Point, Pose, PoseArray, PoseWithCovariance, Quaternion, Transform, TransformStamped, Twist, TwistWithCovariance,
    Vector3,
};
use rover_msgs::msg::Telemetry;
use rover_msgs::nav_msgs::Odometry;
use rover_msgs::sensor_msgs::{CameraInfo, CompressedImage, RegionOfInterest};
use rover_msgs::std_msgs::Header;
use rover_msgs::tf2_msgs::TFMessage;

use crate::telemetry::SimTelemetry;

/// Rotation of an optical frame in its camera body frame: roll -90 degrees, then yaw -90 degrees.
const OPTICAL_IN_CAMERA_LINK: Quaternion = Quaternion { x: -0.5, y: 0.5, z: -0.5, w: 0.5 };

/// The simulator camera's pinhole model: 320x160, vertical field of view 70 degrees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PinholeCamera {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Focal length, pixels.
    pub focal_px: f64,
}

impl PinholeCamera {
    /// The Unity rover camera (unity-sim-spec 4.1): f = 80 / tan(35 deg) = 114.25 px.
    pub fn rover() -> Self {
        Self::of_size(320, 160)
    }

    /// The rover camera's 70 degree vertical field of view at `width` x `height` pixels.
    pub fn of_size(width: u32, height: u32) -> Self {
        PinholeCamera { width, height, focal_px: (height as f64 / 2.0) / 35f64.to_radians().tan() }
    }

    /// The `CameraInfo` message of this camera.
    pub fn camera_info(&self, header: Header) -> CameraInfo {
        let (f, cx, cy) = (self.focal_px, (self.width as f64 - 1.0) / 2.0, (self.height as f64 - 1.0) / 2.0);
        CameraInfo {
            header,
            height: self.height,
            width: self.width,
            distortion_model: "plumb_bob".to_string(),
            d: vec![0.0; 5],
            k: [f, 0.0, cx, 0.0, f, cy, 0.0, 0.0, 1.0],
            r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            p: [f, 0.0, cx, 0.0, 0.0, f, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
            binning_x: 0,
            binning_y: 0,
            roi: RegionOfInterest::default(),
        }
    }
}

/// Wraps an angle in degrees to (-180, 180] and converts it to radians.
pub fn wrapped_rad(degrees: f64) -> f64 {
    let wrapped = (degrees + 180.0).rem_euclid(360.0) - 180.0;
    let wrapped = if wrapped == -180.0 { 180.0 } else { wrapped };
    wrapped.to_radians()
}

/// Unity's roll (its `localEulerAngles.z`, about the forward axis of a left-handed frame) is
/// positive with the right side up; REP-103 roll is positive with the right side down.
pub fn rep103_roll_rad(unity_roll_deg: f64) -> f64 {
    -wrapped_rad(unity_roll_deg)
}

/// The `rover/telemetry` message of frame `frame`.
pub fn telemetry_message(t: &SimTelemetry, frame: u64, header: Header) -> Telemetry {
    Telemetry {
        header,
        frame,
        x_m: t.state.x_m,
        y_m: t.state.y_m,
        yaw_rad: wrapped_rad(t.state.yaw_deg) as f32,
        pitch_rad: wrapped_rad(t.state.pitch_deg) as f32,
        roll_rad: rep103_roll_rad(t.state.roll_deg) as f32,
        speed_mps: t.state.speed_mps as f32,
        throttle: t.state.throttle as f32,
        brake: t.state.brake as f32,
        steering_angle_deg: t.state.steering_angle_deg as f32,
        near_sample: t.near_sample,
        picking_up: t.picking_up,
        samples_remaining: t.sample_count.min(u8::MAX as u32) as u8,
    }
}

fn body_pose(t: &SimTelemetry) -> Pose {
    Pose {
        position: Point { x: t.state.x_m, y: t.state.y_m, z: 0.0 },
        orientation: Quaternion::from_rpy(
            rep103_roll_rad(t.state.roll_deg),
            wrapped_rad(t.state.pitch_deg),
            wrapped_rad(t.state.yaw_deg),
        ),
    }
}

/// The `odom` message: pose of `base_link` in `odom`, forward speed in `base_link`.
pub fn odometry_message(t: &SimTelemetry, header: Header) -> Odometry {
    Odometry {
        header,
        child_frame_id: frame_ids::BASE_LINK.to_string(),
        pose: PoseWithCovariance { pose: body_pose(t), covariance: Default::default() },
        twist: TwistWithCovariance {
            twist: Twist { linear: Vector3 { x: t.state.speed_mps, y: 0.0, z: 0.0 }, angular: Vector3::default() },
            covariance: Default::default(),
        },
    }
}

/// The `/tf` message: `odom` -> `base_link`.
pub fn transform_message(t: &SimTelemetry, header: Header) -> TFMessage {
    let pose = body_pose(t);
    TFMessage {
        transforms: vec![TransformStamped {
            header,
            child_frame_id: frame_ids::BASE_LINK.to_string(),
            transform: Transform {
                translation: Vector3 { x: pose.position.x, y: pose.position.y, z: 0.0 },
                rotation: pose.orientation,
            },
        }],
    }
}

/// The `/tf_static` message: `map` -> `odom` (the same place), `base_link` -> `camera_link` (the
/// camera `mount`) and `camera_link` -> `camera_optical_frame`.
pub fn static_transforms_message(mount: &CameraMount, header: &Header) -> TFMessage {
    let camera_height_m = mount.above_origin_m - mount.origin_below_floor_m;
    let transform = |parent: &str, child: &str, translation: Vector3, rotation: Quaternion| TransformStamped {
        header: Header { frame_id: parent.to_string(), ..header.clone() },
        child_frame_id: child.to_string(),
        transform: Transform { translation, rotation },
    };
    TFMessage {
        transforms: vec![
            transform(frame_ids::MAP, frame_ids::ODOM, Vector3::default(), Quaternion::IDENTITY),
            transform(
                frame_ids::BASE_LINK,
                frame_ids::CAMERA_LINK,
                Vector3 { x: mount.forward_m, y: 0.0, z: camera_height_m },
                Quaternion::IDENTITY,
            ),
            transform(frame_ids::CAMERA_LINK, frame_ids::CAMERA_OPTICAL, Vector3::default(), OPTICAL_IN_CAMERA_LINK),
        ],
    }
}

/// The `camera/image_raw/compressed` message, with the simulator's JPEG untouched.
pub fn compressed_image_message(t: &SimTelemetry, header: Header) -> CompressedImage {
    CompressedImage { header, format: "jpeg".to_string(), data: t.image_jpeg.clone() }
}

/// The messages the bridge publishes for every telemetry frame (besides `/clock`), stamped alike.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameMessages {
    /// `rover/telemetry`, in `odom`.
    pub telemetry: Telemetry,
    /// `camera/image_raw/compressed`, in `camera_optical_frame`.
    pub compressed: CompressedImage,
    /// `camera/camera_info`, in `camera_optical_frame`.
    pub camera_info: CameraInfo,
    /// `odom`.
    pub odom: Odometry,
    /// `/tf`: `odom` -> `base_link`.
    pub tf: TFMessage,
}

impl FrameMessages {
    /// The messages of telemetry frame `frame` of `camera`, stamped `stamp`.
    pub fn new(t: &SimTelemetry, frame: u64, stamp: Time, camera: &PinholeCamera) -> Self {
        let odom_header = Header::at(frame_ids::ODOM, stamp);
        let camera_header = Header { frame_id: frame_ids::CAMERA_OPTICAL.to_string(), ..odom_header.clone() };
        FrameMessages {
            telemetry: telemetry_message(t, frame, odom_header.clone()),
            compressed: compressed_image_message(t, camera_header.clone()),
            camera_info: camera.camera_info(camera_header),
            odom: odometry_message(t, odom_header.clone()),
            tf: transform_message(t, odom_header),
        }
    }
}

/// The `sim/sample_truth` message: true positions of the samples on the ground.
pub fn sample_truth_message(t: &SimTelemetry, header: Header) -> PoseArray {
    PoseArray::of_points(header, &t.samples)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angles_wrap_to_plus_minus_pi() {
        assert!((wrapped_rad(359.5) - (-0.5f64).to_radians()).abs() < 1e-12);
        assert!((wrapped_rad(56.8255) - 56.8255f64.to_radians()).abs() < 1e-12);
        assert_eq!(wrapped_rad(180.0), std::f64::consts::PI);
        assert_eq!(wrapped_rad(-180.0), std::f64::consts::PI);
        assert!((wrapped_rad(360.0)).abs() < 1e-12);
    }

    /// `v` rotated by the unit quaternion `q`.
    fn rotate(q: &Quaternion, v: [f64; 3]) -> [f64; 3] {
        let (u, w) = ([q.x, q.y, q.z], q.w);
        let cross = |a: [f64; 3], b: [f64; 3]| {
            [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
        };
        let t = cross(u, v).map(|c| 2.0 * c);
        let ut = cross(u, t);
        [0, 1, 2].map(|i| v[i] + w * t[i] + ut[i])
    }

    #[test]
    fn static_transforms_place_the_camera_and_turn_its_optical_frame() {
        let message = static_transforms_message(&CameraMount::UNITY, &Header::default());
        let pairs: Vec<(&str, &str)> =
            message.transforms.iter().map(|t| (t.header.frame_id.as_str(), t.child_frame_id.as_str())).collect();
        assert_eq!(pairs, [("map", "odom"), ("base_link", "camera_link"), ("camera_link", "camera_optical_frame")]);
        let camera = &message.transforms[1].transform.translation;
        assert_eq!(camera.x, 0.4287);
        assert!((camera.z - 0.2144).abs() < 1e-12, "camera above the floor: {}", camera.z);
        let optical = &message.transforms[2].transform.rotation;
        let close = |a: [f64; 3], b: [f64; 3]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12);
        assert!(close(rotate(optical, [0.0, 0.0, 1.0]), [1.0, 0.0, 0.0]), "optical z looks forward");
        assert!(close(rotate(optical, [1.0, 0.0, 0.0]), [0.0, -1.0, 0.0]), "optical x points right");
        assert!(close(rotate(optical, [0.0, 1.0, 0.0]), [0.0, 0.0, -1.0]), "optical y points down");
    }

    #[test]
    fn camera_info_is_the_calibrated_pinhole() {
        let info = PinholeCamera::rover().camera_info(Header::default());
        assert!((info.k[0] - 114.25).abs() < 0.01, "f = {}", info.k[0]);
        assert_eq!((info.k[2], info.k[5]), (159.5, 79.5));
        assert_eq!(info.p[2], 159.5);
    }
}
