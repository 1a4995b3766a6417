//! The surveyed ground of the Unity world: `elevation_cm.png` (`../shared/udacity-world/README.md`
//! section 2), the terrain's height above the floor every 0.5 m over the whole world, 16-bit
//! centimetres, pixel (i, j) at x = 0.5 i, y = 0.5 j.

use crate::terrain::{NODES_PER_M, TERRAIN_STEP_M};
use crate::world::{WORLD_SIZE, WorldError, cell_centre};

/// Spacing of the survey's samples, metres.
const SURVEY_STEP_M: f64 = 0.5;
/// Samples a side: both edges of the world are surveyed.
const SURVEY_SIDE: usize = WORLD_SIZE * 2 + 1;
/// Below this height at its centre a cell is floor, metres (as `floor_flat.png` is made).
const FLOOR_BELOW_M: f32 = 0.5;

/// The surveyed heights, metres above the floor.
#[derive(Debug, Clone, PartialEq)]
pub struct Elevation {
    heights_m: Vec<f32>,
}

impl Elevation {
    /// Reads a survey PNG (401x401, 16-bit greyscale, centimetres).
    pub fn from_png(png: &[u8]) -> Result<Self, WorldError> {
        let name = "elevation";
        let image = rover_imaging::decode_png_gray16(png)
            .map_err(|e| WorldError::Unreadable { name, reason: e.to_string() })?;
        if (image.width, image.height) != (SURVEY_SIDE, SURVEY_SIDE) {
            return Err(WorldError::WrongSize {
                name,
                width: image.width,
                height: image.height,
                expected: SURVEY_SIDE,
            });
        }
        Ok(Elevation { heights_m: image.data.iter().map(|&cm| cm as f32 / 100.0).collect() })
    }

    /// The height at (x, y), metres, bilinear between the samples; beyond the edge, the edge's.
    pub fn height_at(&self, x_m: f64, y_m: f64) -> f32 {
        let last = (SURVEY_SIDE - 1) as f64;
        let (gx, gy) = ((x_m / SURVEY_STEP_M).clamp(0.0, last), (y_m / SURVEY_STEP_M).clamp(0.0, last));
        let (ix, iy) = ((gx as usize).min(SURVEY_SIDE - 2), (gy as usize).min(SURVEY_SIDE - 2));
        let (fx, fy) = ((gx - ix as f64) as f32, (gy - iy as f64) as f32);
        let at = |dx: usize, dy: usize| self.heights_m[(iy + dy) * SURVEY_SIDE + ix + dx];
        let top = at(0, 0) + (at(1, 0) - at(0, 0)) * fx;
        let bottom = at(0, 1) + (at(1, 1) - at(0, 1)) * fx;
        top + (bottom - top) * fy
    }

    /// The height of every terrain node, row by row (see [`crate::terrain::Terrain::from_heights`]).
    pub fn node_heights_m(&self) -> Vec<f32> {
        let side = WORLD_SIZE * NODES_PER_M;
        (0..side * side)
            .map(|i| {
                let position = |n: usize| (n as f64 + 0.5) * TERRAIN_STEP_M;
                self.height_at(position(i % side), position(i / side))
            })
            .collect()
    }

    /// The cells whose centre is below half a metre: the floor, as `floor_flat.png` marks it.
    pub fn floor(&self) -> Vec<bool> {
        (0..WORLD_SIZE * WORLD_SIZE)
            .map(|cell| {
                let (x_m, y_m) = cell_centre(cell);
                self.height_at(x_m, y_m) < FLOOR_BELOW_M
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rover_imaging::{Gray16Image, encode_png_gray16};

    fn survey(height_cm: impl Fn(usize, usize) -> u16) -> Vec<u8> {
        let data = (0..SURVEY_SIDE * SURVEY_SIDE).map(|i| height_cm(i % SURVEY_SIDE, i / SURVEY_SIDE)).collect();
        encode_png_gray16(&Gray16Image { width: SURVEY_SIDE, height: SURVEY_SIDE, data }).unwrap()
    }

    #[test]
    fn heights_are_bilinear_between_the_samples_in_metres() {
        let elevation = Elevation::from_png(&survey(|i, j| (i + 2 * j) as u16)).unwrap();
        assert!((elevation.height_at(0.5, 0.0) - 0.01).abs() < 1e-6, "pixel (1, 0) is 1 cm");
        assert!((elevation.height_at(0.25, 0.5) - 0.025).abs() < 1e-6);
        assert!((elevation.height_at(200.0, 200.0) - 12.0).abs() < 1e-4, "the last sample is x = y = 200 m");
        assert_eq!(elevation.height_at(-5.0, 0.0), elevation.height_at(0.0, 0.0));
        let nodes = elevation.node_heights_m();
        assert_eq!(nodes.len(), 800 * 800);
        assert!((nodes[1] - elevation.height_at(0.375, 0.125)).abs() < 1e-6, "node 1 lies at (0.375, 0.125)");
    }

    #[test]
    fn the_floor_is_where_the_centre_is_below_half_a_metre() {
        let elevation = Elevation::from_png(&survey(|i, _| if i < 21 { 0 } else { 100 })).unwrap();
        let floor = elevation.floor();
        assert!(floor[9] && !floor[11], "the cells up to x = 10 m are floor");
    }

    #[test]
    fn other_images_are_refused_with_what_was_expected() {
        let small = encode_png_gray16(&Gray16Image { width: 3, height: 3, data: vec![0; 9] }).unwrap();
        let error = Elevation::from_png(&small).unwrap_err().to_string();
        assert!(error.contains("3x3") && error.contains("401x401"), "{error}");
        let error = Elevation::from_png(b"not a png").unwrap_err().to_string();
        assert!(error.contains("elevation"), "{error}");
    }
}
