//! Conversion of a parsed telemetry frame into the ROS messages the bridge publishes.

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

/// Frame of the world map and of the odometry origin.
pub const ODOM_FRAME: &str = "odom";
/// Frame of the rover body.
pub const BASE_FRAME: &str = "base_link";
/// Optical frame of the camera.
pub const CAMERA_FRAME: &str = "camera_optical_frame";

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
        PinholeCamera { width: 320, height: 160, focal_px: 80.0 / 35f64.to_radians().tan() }
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
        x_m: t.x_m,
        y_m: t.y_m,
        yaw_rad: wrapped_rad(t.yaw_deg) as f32,
        pitch_rad: wrapped_rad(t.pitch_deg) as f32,
        roll_rad: rep103_roll_rad(t.roll_deg) as f32,
        speed_mps: t.speed_mps as f32,
        throttle: t.throttle as f32,
        brake: t.brake as f32,
        steering_angle_deg: t.steering_angle_deg as f32,
        near_sample: t.near_sample,
        picking_up: t.picking_up,
        samples_remaining: t.sample_count.min(u8::MAX as u32) as u8,
    }
}

fn body_pose(t: &SimTelemetry) -> Pose {
    Pose {
        position: Point { x: t.x_m, y: t.y_m, z: 0.0 },
        orientation: Quaternion::from_rpy(
            rep103_roll_rad(t.roll_deg),
            wrapped_rad(t.pitch_deg),
            wrapped_rad(t.yaw_deg),
        ),
    }
}

/// The `odom` message: pose of `base_link` in `odom`, forward speed in `base_link`.
pub fn odometry_message(t: &SimTelemetry, header: Header) -> Odometry {
    Odometry {
        header,
        child_frame_id: BASE_FRAME.to_string(),
        pose: PoseWithCovariance { pose: body_pose(t), covariance: Default::default() },
        twist: TwistWithCovariance {
            twist: Twist { linear: Vector3 { x: t.speed_mps, y: 0.0, z: 0.0 }, angular: Vector3::default() },
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
            child_frame_id: BASE_FRAME.to_string(),
            transform: Transform {
                translation: Vector3 { x: pose.position.x, y: pose.position.y, z: 0.0 },
                rotation: pose.orientation,
            },
        }],
    }
}

/// The `camera/image_raw/compressed` message, with the simulator's JPEG untouched.
pub fn compressed_image_message(t: &SimTelemetry, header: Header) -> CompressedImage {
    CompressedImage { header, format: "jpeg".to_string(), data: t.image_jpeg.clone() }
}

/// The `sim/sample_truth` message: true positions of the samples on the ground.
pub fn sample_truth_message(t: &SimTelemetry, header: Header) -> PoseArray {
    PoseArray {
        header,
        poses: t
            .samples
            .iter()
            .map(|&(x, y)| Pose { position: Point { x, y, z: 0.0 }, orientation: Quaternion::from_yaw(0.0) })
            .collect(),
    }
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

    #[test]
    fn camera_info_is_the_calibrated_pinhole() {
        let info = PinholeCamera::rover().camera_info(Header::default());
        assert!((info.k[0] - 114.25).abs() < 0.01, "f = {}", info.k[0]);
        assert_eq!((info.k[2], info.k[5]), (159.5, 79.5));
        assert_eq!(info.p[2], 159.5);
    }
}
