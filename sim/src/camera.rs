//! The rover camera (unity-sim-spec 4.1): a 320x160 pinhole with a 70 degree vertical field of
//! view, mounted 0.4287 m ahead of the reported position and 0.2391 m above the body origin,
//! which rests 0.0247 m below the floor, so 0.2144 m above the floor on level ground.

use nalgebra::{Point3, Rotation3, Vector3};

/// Pose of the rover body in the world: position of the reported origin and body angles.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BodyPose {
    /// x, metres.
    pub x_m: f64,
    /// y, metres.
    pub y_m: f64,
    /// Yaw, degrees counter-clockwise from +x.
    pub yaw_deg: f64,
    /// Pitch, degrees, positive nose down.
    pub pitch_deg: f64,
    /// Roll, degrees, positive right side down.
    pub roll_deg: f64,
    /// Height of the ground under the body above the floor, metres (0 on the floor).
    pub ground_m: f64,
}

/// The camera's intrinsics and mounting.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraModel {
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// Focal length, pixels (80 / tan 35 degrees).
    pub focal_px: f64,
    /// Mount offset ahead of the body origin, metres.
    pub forward_m: f64,
    /// Mount height above the body origin, metres.
    pub mount_height_m: f64,
    /// Depth of the body origin below the floor, metres.
    pub origin_below_floor_m: f64,
}

impl BodyPose {
    /// The turn by yaw about the vertical.
    pub fn yaw(&self) -> Rotation3<f64> {
        Rotation3::from_axis_angle(&Vector3::z_axis(), self.yaw_deg.to_radians())
    }

    /// The turn by pitch about the body's y axis (positive nose down).
    pub fn pitch(&self) -> Rotation3<f64> {
        Rotation3::from_axis_angle(&Vector3::y_axis(), self.pitch_deg.to_radians())
    }

    /// The turn by roll about the body's x axis (positive right side down).
    pub fn roll(&self) -> Rotation3<f64> {
        Rotation3::from_axis_angle(&Vector3::x_axis(), self.roll_deg.to_radians())
    }
}

impl CameraModel {
    /// The Unity rover camera.
    pub fn rover() -> Self {
        CameraModel {
            width: 320,
            height: 160,
            focal_px: 80.0 / 35f64.to_radians().tan(),
            forward_m: 0.4287,
            mount_height_m: 0.2391,
            origin_below_floor_m: 0.0247,
        }
    }

    /// Principal point (numpy index coordinates: the centre of the image).
    pub fn principal_point(&self) -> (f64, f64) {
        ((self.width as f64 - 1.0) / 2.0, (self.height as f64 - 1.0) / 2.0)
    }

    /// Camera position in the world (x, y, height above the floor) for a body pose.
    pub fn position(&self, pose: &BodyPose) -> Point3<f64> {
        let mount = body_to_world(pose, &Vector3::new(self.forward_m, 0.0, self.mount_height_m));
        Point3::new(pose.x_m, pose.y_m, pose.ground_m) + mount - Vector3::z() * self.origin_below_floor_m
    }
}

/// Rotates a body-frame vector (x forward, y left, z up) into the world frame:
/// yaw about z, then pitch about y (positive nose down), then roll about x (positive right side down).
pub fn body_to_world(pose: &BodyPose, v: &Vector3<f64>) -> Vector3<f64> {
    pose.yaw() * tilt(pose, v)
}

/// Applies only pitch and roll: body frame into the yaw-aligned level frame.
pub fn tilt(pose: &BodyPose, v: &Vector3<f64>) -> Vector3<f64> {
    pose.pitch() * (pose.roll() * v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn camera_sits_0_2144_m_above_the_floor_and_0_4287_m_ahead() {
        let camera = CameraModel::rover();
        assert!((camera.focal_px - 114.25).abs() < 0.01);
        let pose = BodyPose { x_m: 10.0, y_m: 20.0, yaw_deg: 90.0, ..Default::default() };
        let camera_at = camera.position(&pose);
        let (x, y, z) = (camera_at.x, camera_at.y, camera_at.z);
        assert!((x - 10.0).abs() < 1e-9 && (y - 20.4287).abs() < 1e-9, "({x}, {y})");
        assert!((z - 0.2144).abs() < 1e-9, "{z}");
        let on_a_bank = BodyPose { ground_m: 0.3, ..pose };
        assert!((camera.position(&on_a_bank).z - 0.5144).abs() < 1e-9);
    }

    #[test]
    fn pitch_down_lowers_the_nose_and_roll_lowers_the_right_side() {
        let nose_down = BodyPose { pitch_deg: 10.0, ..Default::default() };
        assert!(body_to_world(&nose_down, &Vector3::x()).z < 0.0);
        let right_down = BodyPose { roll_deg: 10.0, ..Default::default() };
        assert!(body_to_world(&right_down, &-Vector3::y()).z < 0.0);
        assert!(body_to_world(&right_down, &Vector3::y()).z > 0.0);
    }
}
