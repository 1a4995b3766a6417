//! From the rover frame to the world: a terrain-scan cell's ground point, corrected for the body's
//! pitch and roll with the camera model, then rotated by yaw and moved to the rover's position.

use nalgebra::{Point3, Rotation3, Vector3};
use rover_msgs::body::CameraMount;

/// The body's attitude and position for one frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Pose {
    /// x, metres.
    pub x_m: f64,
    /// y, metres.
    pub y_m: f64,
    /// Yaw, radians counter-clockwise from +x.
    pub yaw_rad: f64,
    /// Pitch, radians, positive nose down.
    pub pitch_rad: f64,
    /// Roll, radians, positive right side down.
    pub roll_rad: f64,
}

impl Pose {
    /// The pose a `rover_msgs/TerrainScan` was taken at.
    pub fn of_scan(scan: &rover_msgs::msg::TerrainScan) -> Self {
        let telemetry = &scan.telemetry;
        Pose {
            x_m: telemetry.x_m,
            y_m: telemetry.y_m,
            yaw_rad: telemetry.yaw_rad as f64,
            pitch_rad: telemetry.pitch_rad as f64,
            roll_rad: telemetry.roll_rad as f64,
        }
    }
}

/// Projects rover-frame ground points of one frame into the world.
#[derive(Debug, Clone, Copy)]
pub struct Projector {
    pose: Pose,
    sin_yaw: f64,
    cos_yaw: f64,
    /// Level camera position (rover frame) and the tilted one, and the tilt rotation.
    level_camera: Point3<f64>,
    camera: Point3<f64>,
    tilt: Option<Rotation3<f64>>,
}

/// Rotation by roll about x, then pitch about y (positive nose down).
fn tilt_rotation(pitch_rad: f64, roll_rad: f64) -> Rotation3<f64> {
    Rotation3::from_axis_angle(&Vector3::y_axis(), pitch_rad) * Rotation3::from_axis_angle(&Vector3::x_axis(), roll_rad)
}

impl Projector {
    /// A projector for `pose`; with `correct_tilt` the ground points are re-projected through the
    /// tilted camera, otherwise the level-ground points are used as they are.
    pub fn new(pose: Pose, mount: CameraMount, correct_tilt: bool) -> Self {
        let below_floor = Vector3::z() * mount.origin_below_floor_m;
        let mount_offset = Vector3::new(mount.forward_m, 0.0, mount.above_origin_m);
        let level_camera = Point3::from(mount_offset) - below_floor;
        let tilt = correct_tilt.then(|| tilt_rotation(pose.pitch_rad, pose.roll_rad));
        let camera = match &tilt {
            Some(rotation) => Point3::from(rotation * mount_offset) - below_floor,
            None => level_camera,
        };
        let (sin_yaw, cos_yaw) = pose.yaw_rad.sin_cos();
        Projector { pose, sin_yaw, cos_yaw, level_camera, camera, tilt }
    }

    /// The world position of the level-ground point (x, y) of the rover frame, or `None` when the
    /// tilted camera's ray through it does not reach the ground.
    #[inline]
    pub fn world(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        let (gx, gy) = match &self.tilt {
            None => (x, y),
            Some(rotation) => {
                let ray = rotation * (Point3::new(x, y, 0.0) - self.level_camera);
                if ray.z >= -1e-9 {
                    return None;
                }
                let ground = self.camera + ray * (-self.camera.z / ray.z);
                (ground.x, ground.y)
            }
        };
        Some((
            self.pose.x_m + gx * self.cos_yaw - gy * self.sin_yaw,
            self.pose.y_m + gx * self.sin_yaw + gy * self.cos_yaw,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn level_points_rotate_with_yaw_and_move_with_position() {
        let pose = Pose { x_m: 10.0, y_m: 20.0, yaw_rad: std::f64::consts::FRAC_PI_2, ..Pose::default() };
        let (x, y) = Projector::new(pose, CameraMount::default(), true).world(2.0, 1.0).unwrap();
        assert!((x - 9.0).abs() < 1e-12 && (y - 22.0).abs() < 1e-12, "({x}, {y})");
    }

    #[test]
    fn nose_down_pulls_far_points_closer() {
        let level = Projector::new(Pose::default(), CameraMount::default(), true).world(5.0, 0.0).unwrap();
        assert!((level.0 - 5.0).abs() < 1e-12);
        let pitched = Pose { pitch_rad: 1f64.to_radians(), ..Pose::default() };
        let (x, _) = Projector::new(pitched, CameraMount::default(), true).world(5.0, 0.0).unwrap();
        assert!(x < 4.0 && x > 2.5, "a 1 degree nose-down pitch puts the 5 m point at {x}");
        let uncorrected = Projector::new(pitched, CameraMount::default(), false).world(5.0, 0.0).unwrap();
        assert_eq!(uncorrected.0, 5.0);
    }

    #[test]
    fn nose_up_makes_far_rays_miss_the_ground() {
        let up = Pose { pitch_rad: -3f64.to_radians(), ..Pose::default() };
        assert!(Projector::new(up, CameraMount::default(), true).world(15.0, 0.0).is_none());
    }

    #[test]
    fn roll_right_side_down_pushes_left_points_away_and_right_points_closer() {
        let rolled =
            Projector::new(Pose { roll_rad: 2f64.to_radians(), ..Pose::default() }, CameraMount::default(), true);
        let (left_x, _) = rolled.world(3.0, 2.0).unwrap();
        let (right_x, _) = rolled.world(3.0, -2.0).unwrap();
        let (ahead_x, ahead_y) = rolled.world(3.0, 0.0).unwrap();
        assert!(left_x > 3.8 && right_x < 2.6, "left {left_x}, right {right_x}");
        assert!((ahead_x - 3.0).abs() < 0.05 && ahead_y.abs() < 0.01, "straight ahead stays: ({ahead_x}, {ahead_y})");
    }
}
