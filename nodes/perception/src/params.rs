//! The perception node's parameters and the calibration, colour rules and pipeline they give.

use crate::classify::{RockRule, Thresholds};
use crate::scan::ScanGeometry;
use crate::{Calibration, Perception};

rover_runtime::node_params! {
    /// Parameters of the perception node.
    pub struct PerceptionParams {
        /// Calibration corners in the camera image: near-left x, y, near-right x, y, far-right x, y, far-left x, y (pixels).
        source_points_px: Vec<f64> = default_source_points_px(),
        /// Half the side of the calibration cell in the warped image, pixels.
        destination_half_size_px: f64 [1.0, 50.0] = f64::from(Calibration::default().destination_half_size_px),
        /// Warped rows between the bottom of the image and the calibration cell.
        bottom_offset_px: f64 [0.0, 100.0] = f64::from(Calibration::default().bottom_offset_px),
        /// Warped pixels per metre.
        pixels_per_metre: f64 [1.0, 100.0] = f64::from(Calibration::default().pixels_per_metre),
        /// Distance from the rover's position to the calibration cell's near edge, metres.
        near_edge_ahead_m: f64 [0.0, 5.0] = Calibration::default().near_edge_ahead_m,
        /// Navigable when red, green and blue all exceed these values.
        navigable_rgb_min: Vec<i64> = Thresholds::NAVIGABLE_RGB_MIN.map(i64::from).to_vec(),
        /// Rock rule: "rgb" (red > r, green > g, blue < b) or "hsv" (OpenCV HSV within bounds).
        rock_rule: String = "rgb",
        /// RGB rock rule: red above, green above, blue below.
        rock_rgb: Vec<i64> = Thresholds::ROCK_RGB.map(i64::from).to_vec(),
        /// HSV rock rule, lower bounds (H 0..180, S, V).
        rock_hsv_lower: Vec<i64> = vec![0i64, 120, 120],
        /// HSV rock rule, upper bounds.
        rock_hsv_upper: Vec<i64> = vec![40i64, 255, 255],
        /// Terrain scans keep warped pixels up to this distance ahead, metres.
        max_range_m: f64 [0.5, 20.0] = 8.0,
        /// Publish the classified bird's-eye view on rover/vision every this many frames (0: never).
        vision_every_frames: i64 [0, 100000] = 10,
    }
    read_at_start: all
}

/// The default calibration's corners, flattened as `source_points_px` lists them.
fn default_source_points_px() -> Vec<f64> {
    Calibration::default().source_px.as_flattened().iter().map(|&p| f64::from(p)).collect()
}

fn bytes<const N: usize>(name: &str, values: &[i64]) -> anyhow::Result<[u8; N]> {
    anyhow::ensure!(values.len() == N, "parameter {name} needs {N} values, got {}", values.len());
    let mut out = [0u8; N];
    for (slot, &value) in out.iter_mut().zip(values) {
        *slot = u8::try_from(value).map_err(|_| anyhow::anyhow!("parameter {name}: {value} is not in 0..=255"))?;
    }
    Ok(out)
}

impl PerceptionParams {
    /// The calibration these parameters describe.
    pub fn calibration(&self) -> anyhow::Result<Calibration> {
        let p = &self.source_points_px;
        anyhow::ensure!(p.len() == 8, "parameter source_points_px needs 8 numbers (4 corners), got {}", p.len());
        Ok(Calibration {
            source_px: [
                [p[0] as f32, p[1] as f32],
                [p[2] as f32, p[3] as f32],
                [p[4] as f32, p[5] as f32],
                [p[6] as f32, p[7] as f32],
            ],
            destination_half_size_px: self.destination_half_size_px as f32,
            bottom_offset_px: self.bottom_offset_px as f32,
            pixels_per_metre: self.pixels_per_metre as f32,
            near_edge_ahead_m: self.near_edge_ahead_m,
            ..Calibration::default()
        })
    }

    /// The colour rules these parameters describe.
    pub fn thresholds(&self) -> anyhow::Result<Thresholds> {
        let rock = match self.rock_rule.as_str() {
            "rgb" => {
                let [min_red, min_green, max_blue] = bytes("rock_rgb", &self.rock_rgb)?;
                RockRule::Rgb { min_red, min_green, max_blue }
            }
            "hsv" => RockRule::Hsv {
                lower: bytes("rock_hsv_lower", &self.rock_hsv_lower)?,
                upper: bytes("rock_hsv_upper", &self.rock_hsv_upper)?,
            },
            other => anyhow::bail!("parameter rock_rule = {other:?}: expected \"rgb\" or \"hsv\""),
        };
        Ok(Thresholds { navigable: bytes("navigable_rgb_min", &self.navigable_rgb_min)?, rock })
    }

    /// The perception pipeline and its scan geometry.
    pub fn pipeline(&self) -> anyhow::Result<(Perception, ScanGeometry)> {
        let calibration = self.calibration()?;
        let perception = Perception::new(calibration, self.thresholds()?)?;
        let geometry = ScanGeometry::new(&calibration, perception.table(), self.max_range_m);
        Ok((perception, geometry))
    }
}
