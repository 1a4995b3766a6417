//! Camera perception of the rover: the calibrated bird's-eye warp as a lookup table ([`warp`]),
//! colour classification ([`classify`]) and the rover-frame terrain scan ([`scan`]).
//!
//! Nothing is warped per frame: the table built once from the calibration lists, for each warped
//! pixel inside the camera's view, the source pixels and weights OpenCV's `warpPerspective` would
//! use; a frame is decoded, and each entry is classified from the colour tests of its four source
//! pixels where they decide it, else from its interpolated colour, and that is all.

pub mod classify;
mod homography;
pub mod node;
pub mod params;
pub mod scan;
mod warp;

use rover_imaging::{ImageError, RgbImage};

use crate::classify::{Class, ColourBits, Thresholds};
use crate::homography::Matrix3;
use crate::warp::{BorderedImage, Tap, WarpTable};

/// The calibration of the warp (the Udacity starter's values by default).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Calibration {
    /// Corners of the 1 m grid cell in the camera image: near left, near right, far right, far left.
    pub source_px: [[f32; 2]; 4],
    /// Half the side of that cell in the warped image, pixels (10 px per metre gives 5).
    pub destination_half_size_px: f32,
    /// Rows between the bottom of the warped image and the cell's near edge.
    pub bottom_offset_px: f32,
    /// Warped pixels per metre.
    pub pixels_per_metre: f32,
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// Distance from the rover's reported position to the cell's near edge, metres (the camera's
    /// offset ahead, [`rover_msgs::body::CameraMount::forward_m`], + 0.3992 m, unity-sim-spec 4.2).
    pub near_edge_ahead_m: f64,
}

/// [`Calibration::near_edge_ahead_m`] in Unity: 0.4287 m
/// ([`rover_msgs::body::CameraMount::forward_m`]) + 0.3992 m, rounded to the 0.1 mm of its parts.
pub const UNITY_NEAR_EDGE_AHEAD_M: f64 = 0.8279;

impl Default for Calibration {
    fn default() -> Self {
        Calibration {
            source_px: [[14.0, 140.0], [301.0, 140.0], [200.0, 96.0], [118.0, 96.0]],
            destination_half_size_px: 5.0,
            bottom_offset_px: 6.0,
            pixels_per_metre: 10.0,
            width: 320,
            height: 160,
            near_edge_ahead_m: UNITY_NEAR_EDGE_AHEAD_M,
        }
    }
}

impl Calibration {
    /// The destination points of the starter: a square at the bottom centre of the warped image.
    pub fn destination_px(&self) -> [[f32; 2]; 4] {
        let (w, h) = (self.width as f32, self.height as f32);
        let (d, bottom) = (self.destination_half_size_px, self.bottom_offset_px);
        [
            [w / 2.0 - d, h - bottom],
            [w / 2.0 + d, h - bottom],
            [w / 2.0 + d, h - 2.0 * d - bottom],
            [w / 2.0 - d, h - 2.0 * d - bottom],
        ]
    }

    /// The homography from camera pixels to warped pixels.
    pub fn homography(&self) -> Option<Matrix3> {
        homography::perspective_transform(&self.source_px, &self.destination_px())
    }

    /// Rover-frame position (x forward, y left, metres from the reported position) of warped pixel (x, y).
    pub fn rover_position(&self, warped_x: f64, warped_y: f64) -> (f64, f64) {
        let near_edge_row = self.height as f64 - self.bottom_offset_px as f64;
        let ppm = self.pixels_per_metre as f64;
        (self.near_edge_ahead_m + (near_edge_row - warped_y) / ppm, (self.width as f64 / 2.0 - warped_x) / ppm)
    }
}

/// Errors of the perception pipeline.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PerceptionError {
    /// The calibration points do not define a perspective transform.
    #[error("the calibration points are degenerate (three of them on a line?)")]
    DegenerateCalibration,
    /// The image could not be decoded or has the wrong size.
    #[error(transparent)]
    Image(#[from] ImageError),
}

/// Perception of one camera: the table, the thresholds and reusable buffers.
pub struct Perception {
    calibration: Calibration,
    thresholds: Thresholds,
    colour_bits: Option<ColourBits>,
    table: WarpTable,
    image: RgbImage,
    source: BorderedImage,
    classes: Vec<Class>,
}

impl Perception {
    /// Builds the lookup table for `calibration`.
    pub fn new(calibration: Calibration, thresholds: Thresholds) -> Result<Self, PerceptionError> {
        let matrix = calibration.homography().ok_or(PerceptionError::DegenerateCalibration)?;
        let table = WarpTable::new(&matrix, calibration.width, calibration.height)
            .ok_or(PerceptionError::DegenerateCalibration)?;
        let classes = vec![Class::Unknown; table.entries.len()];
        Ok(Perception {
            calibration,
            thresholds,
            colour_bits: ColourBits::of(&thresholds),
            table,
            image: RgbImage::default(),
            source: BorderedImage::default(),
            classes,
        })
    }

    /// The calibration.
    pub fn calibration(&self) -> &Calibration {
        &self.calibration
    }

    /// The warp table.
    pub fn table(&self) -> &WarpTable {
        &self.table
    }

    /// The classes of the last frame, one per table entry.
    pub fn classes(&self) -> &[Class] {
        &self.classes
    }

    /// Decodes a camera JPEG of the calibration's size and classifies it; a JPEG of another size
    /// is rejected from its header. Only the rows the warp reads are decoded
    /// ([`WarpTable::source_rows`]): the same classes as from the whole image, for less work.
    pub fn process_jpeg(&mut self, jpeg: &[u8]) -> Result<&[Class], PerceptionError> {
        let (width, height, rows) = (self.calibration.width, self.calibration.height, &self.table.source_rows);
        rover_imaging::decode_jpeg_rows_into(jpeg, width, height, rows.clone(), &mut self.image)?;
        self.source.fill(&self.image.data, (width, height), rows.clone(), self.colour_bits.as_ref());
        self.classify();
        Ok(&self.classes)
    }

    /// Classifies an already decoded image.
    pub fn process_rgb(&mut self, image: &RgbImage) -> Result<&[Class], PerceptionError> {
        if (image.width, image.height) != (self.calibration.width, self.calibration.height) {
            return Err(self.wrong_size(image.width, image.height));
        }
        let rows = self.table.source_rows.clone();
        self.source.fill(&image.data, (image.width, image.height), rows, self.colour_bits.as_ref());
        self.classify();
        Ok(&self.classes)
    }

    fn wrong_size(&self, width: usize, height: usize) -> PerceptionError {
        PerceptionError::Image(ImageError::WrongSize {
            width,
            height,
            expected_width: self.calibration.width,
            expected_height: self.calibration.height,
        })
    }

    /// Classifies every table entry: from the colour bits of its taps when they decide it, else
    /// from its interpolated colour (the same class either way, see [`ColourBits`]).
    fn classify(&mut self) {
        let (table, source) = (&self.table, &self.source);
        let interpolated = |tap: Tap| self.thresholds.classify(table.sample(tap, source), tap.in_view());
        if self.colour_bits.is_some() {
            for (class, &tap) in self.classes.iter_mut().zip(&table.taps) {
                *class = source.decided_class(tap).unwrap_or_else(|| interpolated(tap));
            }
        } else {
            for (class, &tap) in self.classes.iter_mut().zip(&table.taps) {
                *class = interpolated(tap);
            }
        }
    }

    /// The warped colour image of the last frame (the full `warpPerspective` output), for checks.
    pub fn warped_image(&self) -> RgbImage {
        let mut warped = RgbImage::new(self.calibration.width, self.calibration.height);
        for (entry, &tap) in self.table.entries.iter().zip(&self.table.taps) {
            warped.set_pixel(entry.x as usize, entry.y as usize, self.table.sample(tap, &self.source));
        }
        warped
    }
}

#[cfg(test)]
mod tests {
    use rover_msgs::body::CameraMount;

    use super::*;

    #[test]
    fn the_near_edge_is_the_camera_offset_plus_the_camera_to_cell_distance() {
        assert!((UNITY_NEAR_EDGE_AHEAD_M - (CameraMount::UNITY.forward_m + 0.3992)).abs() < 1e-12);
    }

    /// The class of every entry from its interpolated colour alone.
    fn interpolated_classes(perception: &Perception, thresholds: &Thresholds) -> Vec<Class> {
        let warped = perception.warped_image();
        let table = perception.table();
        table.entries.iter().map(|e| thresholds.classify(warped.pixel(e.x as usize, e.y as usize), e.in_view)).collect()
    }

    /// An image of flat patches of floor, wall and sample colours with noise at their edges.
    fn patchwork(seed: u32) -> RgbImage {
        const COLOURS: [[u8; 3]; 4] = [[200, 180, 165], [110, 100, 90], [170, 140, 20], [161, 161, 161]];
        let mut image = RgbImage::new(320, 160);
        let mut state = seed;
        let mut next = move || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (state >> 24) as u8
        };
        for y in 0..160 {
            for x in 0..320 {
                let colour = COLOURS[(x / 23 + y / 17 + (seed as usize)) % COLOURS.len()];
                let jitter = if x % 23 < 2 || y % 17 < 2 { next() % 7 } else { 0 };
                image.set_pixel(x, y, colour.map(|c| c.saturating_add(jitter)));
            }
        }
        image
    }

    /// The recorded camera frames of `../shared/udacity/test_dataset`, in order.
    fn recorded_frames() -> Vec<std::path::PathBuf> {
        let dataset = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/udacity/test_dataset/IMG");
        let mut frames: Vec<_> = std::fs::read_dir(dataset).unwrap().map(|e| e.unwrap().path()).collect();
        frames.sort();
        frames
    }

    #[test]
    fn a_jpeg_classified_from_the_rows_the_warp_reads_is_classified_as_from_the_whole_image() {
        let mut perception = Perception::new(Calibration::default(), Thresholds::default()).unwrap();
        let rows = perception.table().source_rows.clone();
        assert!(rows.len() < 80, "the warp reads rows {rows:?}, less than half the image");
        let frames = recorded_frames();
        assert_eq!(frames.len(), 283);
        for path in &frames {
            let jpeg = std::fs::read(path).unwrap();
            let classes = perception.process_jpeg(&jpeg).unwrap().to_vec();
            let warped = perception.warped_image();
            let whole = rover_imaging::decode_jpeg(&jpeg, 320, 160).unwrap();
            perception.source.fill(&whole.data, (320, 160), 0..160, perception.colour_bits.as_ref());
            assert_eq!(perception.warped_image(), warped, "{}", path.display());
            perception.classify();
            assert_eq!(perception.classes, classes, "{}", path.display());
        }
    }

    #[test]
    fn the_navigable_means_of_partial_sums_are_those_of_one_running_sum() {
        let calibration = Calibration::default();
        let mut perception = Perception::new(calibration, Thresholds::default()).unwrap();
        let geometry = scan::ScanGeometry::new(&calibration, perception.table(), 8.0);
        for path in recorded_frames().iter().step_by(7) {
            let classes = perception.process_jpeg(&std::fs::read(path).unwrap()).unwrap();
            let summary = geometry.summarize(classes);
            let navigable: Vec<(f32, f32)> = classes
                .iter()
                .zip(&geometry.polar_of_entry)
                .filter(|&(&class, _)| class == Class::Navigable)
                .map(|(_, &polar)| polar)
                .collect();
            let mean = |part: fn(&(f32, f32)) -> f32| {
                (navigable.iter().fold(0.0f64, |sum, polar| sum + part(polar) as f64) / navigable.len() as f64) as f32
            };
            assert_eq!(summary.navigable_count as usize, navigable.len());
            let means = (summary.navigable_bearing_rad, summary.navigable_distance_m);
            assert_eq!(means, (mean(|polar| polar.0), mean(|polar| polar.1)), "{}", path.display());
        }
    }

    #[test]
    fn classes_from_the_taps_colour_bits_are_the_classes_of_the_interpolated_colours() {
        let thresholds = Thresholds::default();
        let mut perception = Perception::new(Calibration::default(), thresholds).unwrap();
        let frames = recorded_frames();
        for path in frames.iter().step_by(7) {
            let classes = perception.process_jpeg(&std::fs::read(path).unwrap()).unwrap().to_vec();
            assert_eq!(classes, interpolated_classes(&perception, &thresholds), "{}", path.display());
        }
        for seed in 0..4 {
            let classes = perception.process_rgb(&patchwork(seed)).unwrap().to_vec();
            assert_eq!(classes, interpolated_classes(&perception, &thresholds), "patchwork {seed}");
            let kinds = [Class::Navigable, Class::Obstacle, Class::Rock].map(|k| classes.contains(&k));
            assert_eq!(kinds, [true; 3], "patchwork {seed} shows every class");
        }
    }
}
