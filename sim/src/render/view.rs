//! The geometry of a frame: the level camera, the part of its view a frame needs, and the rotation
//! by the body's pitch and roll that turns the level view into the camera image.

use std::ops::Range;

use nalgebra::{Point3, Vector3};

use super::truncated_index;
use crate::camera::{BodyPose, CameraModel, tilt};

/// Extra pixels around the level view, so that pitch and roll up to about 19 degrees stay inside.
pub(super) const MARGIN_PX: usize = 40;
/// Rays closer than this do not hit boulders or samples, metres.
pub(super) const NEAR_M: f64 = 0.05;

/// The rectangle of the level view drawn for a frame: columns u0..u1, rows v0..v1.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct Window {
    /// First column.
    pub(super) u0: usize,
    /// Column after the last.
    pub(super) u1: usize,
    /// First row.
    pub(super) v0: usize,
    /// Row after the last.
    pub(super) v1: usize,
}

impl Window {
    /// The part of a level view of `level` (width, height) pixels that an image of `camera` rotated
    /// by `rotation` needs: the camera's own rectangle when level, otherwise the bounding box of the
    /// rotated rectangle plus one pixel for the rounding to the nearest level pixel.
    pub(super) fn needed(rotation: &Rotation, camera: &CameraModel, level: (usize, usize)) -> Self {
        let (width, height) = (camera.width, camera.height);
        if rotation.is_identity() {
            return Window { u0: MARGIN_PX, u1: MARGIN_PX + width, v0: MARGIN_PX, v1: MARGIN_PX + height };
        }
        let corners =
            [(0, 0), (width - 1, 0), (0, height - 1), (width - 1, height - 1)].map(|(u, v)| rotation.level_pixel(u, v));
        let (min_u, max_u) = corners.iter().fold((f64::MAX, f64::MIN), |(lo, hi), c| (lo.min(c.0), hi.max(c.0)));
        let (min_v, max_v) = corners.iter().fold((f64::MAX, f64::MIN), |(lo, hi), c| (lo.min(c.1), hi.max(c.1)));
        Window {
            u0: (min_u - 1.0).max(0.0) as usize,
            u1: ((max_u + 2.0).max(0.0) as usize).min(level.0),
            v0: (min_v - 1.0).max(0.0) as usize,
            v1: ((max_v + 2.0).max(0.0) as usize).min(level.1),
        }
    }
}

/// The level camera of one frame: position and the horizontal axes.
pub(super) struct LevelView {
    /// Camera position (x, y, height above the floor), metres.
    pub(super) camera: Point3<f64>,
    /// Unit vector of the camera's heading on the floor.
    pub(super) forward: [f64; 2],
    /// Unit vector to the camera's right on the floor.
    pub(super) right: [f64; 2],
    /// Principal point in level-view pixels (the margin included): column...
    pub(super) cx_px: f64,
    /// ...and row.
    pub(super) cy_px: f64,
    /// Focal length, pixels.
    pub(super) focal_px: f64,
}

impl LevelView {
    /// Horizontal direction of level column `u`, scaled so that the parameter is forward depth.
    pub(super) fn column_direction(&self, u: usize) -> [f64; 2] {
        let r = (u as f64 - self.cx_px) / self.focal_px;
        [self.forward[0] + r * self.right[0], self.forward[1] + r * self.right[1]]
    }

    /// Vertical component of the ray of level row `v` (per metre of forward depth).
    pub(super) fn row_rise(&self, v: usize) -> f64 {
        -(v as f64 - self.cy_px) / self.focal_px
    }

    /// The depth of ground one level row covers at forward depth `depth` on the floor, metres.
    pub(super) fn footprint_m(&self, depth: f64) -> f32 {
        (depth * depth / (self.focal_px * self.camera.z.max(0.05))) as f32
    }

    /// Row where a point at forward depth `depth` and height `z` appears.
    pub(super) fn row(&self, depth: f64, z: f64) -> f64 {
        self.cy_px + self.focal_px * (self.camera.z - z) / depth
    }

    /// The level camera of a camera at `position` (x, y, height) with the body's yaw, for a level
    /// view with the margins around the image.
    pub(super) fn new(camera: &CameraModel, position: Point3<f64>, yaw_deg: f64) -> Self {
        let (sin_yaw, cos_yaw) = yaw_deg.to_radians().sin_cos();
        let (cx, cy) = camera.principal_point();
        LevelView {
            camera: position,
            forward: [cos_yaw, sin_yaw],
            right: [sin_yaw, -cos_yaw],
            cx_px: cx + MARGIN_PX as f64,
            cy_px: cy + MARGIN_PX as f64,
            focal_px: camera.focal_px,
        }
    }

    /// Forward depth of the world point `p`, metres (negative behind the camera).
    pub(super) fn depth(&self, p: &Point3<f64>) -> f64 {
        (p.x - self.camera.x) * self.forward[0] + (p.y - self.camera.y) * self.forward[1]
    }

    /// Level pixel (column, row) and forward depth of the world point `p`, if it is ahead.
    pub(super) fn project(&self, p: &Point3<f64>) -> Option<(f64, f64, f64)> {
        self.project_near(p).filter(|&(_, _, depth)| depth > NEAR_M)
    }

    /// The same for points on the near plane too.
    pub(super) fn project_near(&self, p: &Point3<f64>) -> Option<(f64, f64, f64)> {
        let depth = self.depth(p);
        let lateral = (p.x - self.camera.x) * self.right[0] + (p.y - self.camera.y) * self.right[1];
        (depth >= NEAR_M * 0.999).then(|| (self.cx_px + self.focal_px * lateral / depth, self.row(depth, p.z), depth))
    }
}

/// Where the pixels of the tilted camera are in the level view: a pure rotation, so a homography.
pub(super) struct Rotation {
    base: Vector3<f64>,
    per_u: Vector3<f64>,
    per_v: Vector3<f64>,
    cx_px: f64,
    cy_px: f64,
    focal_px: f64,
}

impl Rotation {
    /// The rotation of the image of `camera` by the pitch and roll of `pose`.
    pub(super) fn new(pose: &BodyPose, camera: &CameraModel) -> Self {
        let (cx_px, cy_px) = camera.principal_point();
        let focal_px = camera.focal_px;
        Rotation {
            base: tilt(pose, &Vector3::x()),
            per_u: tilt(pose, &Vector3::new(0.0, -1.0 / focal_px, 0.0)),
            per_v: tilt(pose, &Vector3::new(0.0, 0.0, -1.0 / focal_px)),
            cx_px,
            cy_px,
            focal_px,
        }
    }

    /// True when pitch and roll move no pixel by more than a hundredth.
    pub(super) fn is_identity(&self) -> bool {
        let corner = self.level_pixel(0, 0);
        let opposite = self.level_pixel((2.0 * self.cx_px) as usize, (2.0 * self.cy_px) as usize);
        (corner.0 - MARGIN_PX as f64).abs() < 0.01
            && (corner.1 - MARGIN_PX as f64).abs() < 0.01
            && (opposite.0 - 2.0 * self.cx_px - MARGIN_PX as f64).abs() < 0.01
            && (opposite.1 - 2.0 * self.cy_px - MARGIN_PX as f64).abs() < 0.01
    }

    /// Level-view coordinates of output pixel (u, v).
    pub(super) fn level_pixel(&self, u: usize, v: usize) -> (f64, f64) {
        let (du, dv) = (u as f64 - self.cx_px, v as f64 - self.cy_px);
        let ray = self.base + self.per_u * du + self.per_v * dv;
        let scale = self.focal_px / ray.x;
        (self.cx_px + MARGIN_PX as f64 - ray.y * scale, self.cy_px + MARGIN_PX as f64 - ray.z * scale)
    }

    /// The map from output pixels to level-view coordinates, in single precision for the
    /// resampling of a frame.
    pub(super) fn pixel_map(&self) -> PixelMap {
        let f32s = |v: Vector3<f64>| v.map(|c| c as f32);
        PixelMap {
            base: f32s(self.base - self.per_u * self.cx_px - self.per_v * self.cy_px),
            per_u: f32s(self.per_u),
            per_v: f32s(self.per_v),
            centre: ((self.cx_px + MARGIN_PX as f64) as f32, (self.cy_px + MARGIN_PX as f64) as f32),
            focal_px: self.focal_px as f32,
        }
    }
}

/// Where output pixels are in the level view (see [`Rotation::pixel_map`]).
pub(super) struct PixelMap {
    base: Vector3<f32>,
    per_u: Vector3<f32>,
    per_v: Vector3<f32>,
    centre: (f32, f32),
    focal_px: f32,
}

impl PixelMap {
    /// Level-view coordinates of output pixel (u, v).
    pub(super) fn level_pixel(&self, u: usize, v: usize) -> (f32, f32) {
        let (u, v) = (u as f32, v as f32);
        let ray = self.base + self.per_u * u + self.per_v * v;
        let scale = self.focal_px / ray.x;
        (self.centre.0 - ray.y * scale, self.centre.1 - ray.z * scale)
    }
}

/// The whole pixels from `first` to `last` (fractional pixel coordinates, both included), within
/// `limits`.
pub(super) fn whole_pixels(first: f64, last: f64, limits: Range<usize>) -> Range<usize> {
    let end = if last < 0.0 { 0 } else { truncated_index(last).saturating_add(1) };
    ceil_row(first).max(limits.start)..end.clamp(limits.start, limits.end)
}

/// The first whole row at or below `row` (rows above the image give 0).
pub(super) fn ceil_row(row: f64) -> usize {
    if row <= 0.0 {
        return 0;
    }
    let whole = truncated_index(row);
    if (whole as f64) < row { whole + 1 } else { whole }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn whole_pixels_are_those_between_two_fractional_coordinates_within_the_limits() {
        assert_eq!(whole_pixels(2.5, 7.0, 0..100), 3..8);
        assert_eq!(whole_pixels(3.0, 6.9, 0..100), 3..7);
        assert_eq!(whole_pixels(-4.2, 2.1, 1..100), 1..3);
        assert_eq!(whole_pixels(95.5, 130.0, 0..100), 96..100);
        assert!(whole_pixels(-9.0, -3.5, 0..100).is_empty());
        assert!(whole_pixels(4.2, 4.8, 0..100).is_empty());
        assert!(whole_pixels(120.0, 140.0, 0..100).is_empty());
    }
}
