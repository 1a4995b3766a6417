//! The rover-frame terrain scan of a frame: the classified warped pixels as a grid (x forward,
//! y left), summaries for steering, and the classified bird's-eye image for the simulator inset.

use rover_imaging::RgbImage;
use rover_msgs::frame_ids;
use rover_msgs::msg::{Telemetry, TerrainScan};
use rover_msgs::std_msgs::Header;

use crate::Calibration;
use crate::classify::Class;
use crate::warp::WarpTable;

/// Partial sums of [`ScanGeometry::summarize`], one for the entries of each place modulo this
/// many, so that an addition need not wait for the one before. The `f64` sums may differ from one
/// running sum in their last bits, which the `f32` means almost never show (they did not on any
/// recorded frame the tests check).
const PARTIAL_SUMS: usize = 4;

/// Where the table entries fall in the rover-frame grid.
#[derive(Debug, Clone)]
pub struct ScanGeometry {
    /// Grid rows (forward bins).
    pub rows: usize,
    /// Grid columns (lateral bins).
    pub cols: usize,
    /// Cell size, metres.
    pub resolution_m: f64,
    /// x of the grid's near edge, metres ahead of the rover position.
    pub origin_x_m: f64,
    /// y of the grid's right edge, metres (left positive).
    pub origin_y_m: f64,
    /// The first table entry within the range limit: the entries are in the order of the warped
    /// image's rows, from the farthest, so those from this one on are all in range.
    pub first_in_range: usize,
    /// Grid cell of each table entry from [`ScanGeometry::first_in_range`] on.
    pub cell_of_entry: Vec<u32>,
    /// Bearing (radians, positive left) and distance (metres) of each table entry from the rover.
    pub polar_of_entry: Vec<(f32, f32)>,
}

impl ScanGeometry {
    /// The grid for `table`, keeping entries up to `max_range_m` ahead.
    pub fn new(calibration: &Calibration, table: &WarpTable, max_range_m: f64) -> Self {
        let resolution_m = 1.0 / calibration.pixels_per_metre as f64;
        let (w, h) = (calibration.width, calibration.height);
        let (near_x, right_y) = calibration.rover_position((w - 1) as f64, (h - 1) as f64);
        let rows = (((max_range_m - near_x) / resolution_m).floor() as usize + 1).min(h);
        let polar_of_entry = (table.entries.iter())
            .map(|entry| {
                let (x, y) = calibration.rover_position(entry.x as f64, entry.y as f64);
                (y.atan2(x) as f32, x.hypot(y) as f32)
            })
            .collect();
        let first_in_range = table.entries.partition_point(|entry| h - 1 - entry.y as usize >= rows);
        let cell_of_entry = (table.entries[first_in_range..].iter())
            .map(|entry| ((h - 1 - entry.y as usize) * w + w - 1 - entry.x as usize) as u32)
            .collect();
        ScanGeometry {
            rows,
            cols: w,
            resolution_m,
            origin_x_m: near_x - resolution_m / 2.0,
            origin_y_m: right_y - resolution_m / 2.0,
            first_in_range,
            cell_of_entry,
            polar_of_entry,
        }
    }

    /// Writes the class codes of a frame into `cells` (rows * cols, row-major).
    pub fn fill(&self, classes: &[Class], cells: &mut Vec<u8>) {
        cells.clear();
        cells.resize(self.rows * self.cols, Class::Unknown as u8);
        for (&class, &cell) in classes[self.first_in_range..].iter().zip(&self.cell_of_entry) {
            cells[cell as usize] = class as u8;
        }
    }

    /// Summaries of a frame for steering: the mean bearing and distance of the navigable pixels,
    /// and the bearing and distance of the nearest rock pixel (the foot of the rock: the rest of
    /// it stands up from the ground and projects beyond).
    pub fn summarize(&self, classes: &[Class]) -> ScanSummary {
        let mut summary = ScanSummary::default();
        let mut sums = [[0.0f64; 2]; PARTIAL_SUMS];
        let mut add = |sum: &mut [f64; 2], class: Class, (bearing, distance): (f32, f32)| match class {
            Class::Navigable => {
                summary.navigable_count += 1;
                sum[0] += bearing as f64;
                sum[1] += distance as f64;
            }
            Class::Rock if summary.rock.is_none_or(|(_, nearest)| distance < nearest) => {
                summary.rock = Some((bearing, distance));
            }
            _ => {}
        };
        let (classes, polar) = (classes.chunks_exact(PARTIAL_SUMS), self.polar_of_entry.chunks_exact(PARTIAL_SUMS));
        let rest = classes.remainder().iter().zip(polar.remainder());
        for (classes, polar) in classes.zip(polar) {
            for ((sum, &class), &polar) in sums.iter_mut().zip(classes).zip(polar) {
                add(sum, class, polar);
            }
        }
        for (&class, &polar) in rest {
            add(&mut sums[0], class, polar);
        }
        let [bearing_sum, distance_sum] =
            sums.iter().fold([0.0; 2], |total, sum| [total[0] + sum[0], total[1] + sum[1]]);
        if summary.navigable_count > 0 {
            summary.navigable_bearing_rad = (bearing_sum / summary.navigable_count as f64) as f32;
            summary.navigable_distance_m = (distance_sum / summary.navigable_count as f64) as f32;
        }
        summary
    }

    /// The `rover_msgs/TerrainScan` of a frame's classes, carrying the frame's `telemetry`.
    pub fn terrain_scan(&self, classes: &[Class], telemetry: &Telemetry, header: Header) -> TerrainScan {
        let summary = self.summarize(classes);
        let mut cells = Vec::new();
        self.fill(classes, &mut cells);
        let (rock_bearing_rad, rock_distance_m) = summary.rock.unwrap_or((0.0, 0.0));
        TerrainScan {
            header: Header { frame_id: frame_ids::BASE_LINK.to_string(), ..header },
            telemetry: telemetry.clone(),
            resolution_m: self.resolution_m as f32,
            origin_x_m: self.origin_x_m as f32,
            origin_y_m: self.origin_y_m as f32,
            rows: self.rows as u32,
            cols: self.cols as u32,
            cells,
            navigable_count: summary.navigable_count,
            navigable_bearing_rad: summary.navigable_bearing_rad,
            navigable_distance_m: summary.navigable_distance_m,
            rock_seen: summary.rock.is_some(),
            rock_bearing_rad,
            rock_distance_m,
        }
    }
}

/// What a frame shows, in a few numbers.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ScanSummary {
    /// Navigable pixels in view.
    pub navigable_count: u32,
    /// Their mean bearing, radians, positive left.
    pub navigable_bearing_rad: f32,
    /// Their mean distance, metres.
    pub navigable_distance_m: f32,
    /// Bearing (radians, positive left) and distance (m) of the nearest rock pixel, if any.
    pub rock: Option<(f32, f32)>,
}

/// The classified bird's-eye view: obstacles red, rocks white, navigable blue (the starter's inset).
pub fn vision_image(table: &WarpTable, classes: &[Class]) -> RgbImage {
    let mut image = RgbImage::new(table.width, table.height);
    for (entry, class) in table.entries.iter().zip(classes) {
        let rgb = match class {
            Class::Unknown => continue,
            Class::Navigable => [0, 0, 255],
            Class::Obstacle => [255, 0, 0],
            Class::Rock => [255, 255, 255],
        };
        image.set_pixel(entry.x as usize, entry.y as usize, rgb);
    }
    image
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Perception;
    use crate::classify::Thresholds;

    #[test]
    fn geometry_puts_the_calibration_cell_0_83_m_ahead() {
        let calibration = Calibration::default();
        let (x, y) = calibration.rover_position(160.0, 154.0);
        assert!((x - 0.8279).abs() < 1e-9 && y.abs() < 1e-9);
        let perception = Perception::new(calibration, Thresholds::default()).unwrap();
        let geometry = ScanGeometry::new(&calibration, perception.table(), 8.0);
        assert_eq!(geometry.cols, 320);
        assert!((geometry.origin_x_m - (0.3279 - 0.05)).abs() < 1e-9, "{}", geometry.origin_x_m);
        let last_row_x = geometry.origin_x_m + (geometry.rows as f64 - 0.5) * geometry.resolution_m;
        assert!(last_row_x <= 8.0 + 1e-9 && last_row_x > 7.85, "{last_row_x}");
        let entries = &perception.table().entries;
        let in_range = geometry.cell_of_entry.len();
        assert!(in_range > 5000 && in_range < entries.len(), "{in_range}");
        assert_eq!(geometry.first_in_range + in_range, entries.len());
        let in_range_row = |entry: &crate::warp::WarpEntry| 159 - (entry.y as usize) < geometry.rows;
        assert!(entries[geometry.first_in_range..].iter().all(in_range_row));
        assert!(!entries[..geometry.first_in_range].iter().any(in_range_row));
    }

    #[test]
    fn all_white_ground_is_navigable_straight_ahead() {
        let calibration = Calibration::default();
        let mut perception = Perception::new(calibration, Thresholds::default()).unwrap();
        let mut white = RgbImage::new(320, 160);
        white.data.fill(230);
        let classes = perception.process_rgb(&white).unwrap().to_vec();
        let geometry = ScanGeometry::new(&calibration, perception.table(), 100.0);
        let summary = geometry.summarize(&classes);
        assert!(summary.navigable_count > 30_000, "{summary:?}");
        assert!(summary.navigable_bearing_rad.abs() < 0.01, "{summary:?}");
        assert!(summary.rock.is_none());
        let mut cells = Vec::new();
        geometry.fill(&classes, &mut cells);
        assert_eq!(cells.len(), geometry.rows * geometry.cols);
        assert!(cells.iter().filter(|&&c| c == Class::Navigable as u8).count() > 30_000);
    }
}
