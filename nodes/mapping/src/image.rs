//! The Udacity-style map inset: north up, navigable blue, obstacles red, rocks white, the ground
//! truth faintly in green where known, and a band of statistics below.

use rover_imaging::RgbImage;
use rover_imaging::text::draw_text;
use rover_msgs::map_grid::{CELLS, OCCUPANCY_FREE, OCCUPANCY_OCCUPIED, SIDE_CELLS, cell_xy};

/// Height of the statistics band under the map, pixels.
const BAND_PX: usize = 24;

/// The numbers printed under the map.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct InsetStats {
    /// Time since the mapping node started, seconds.
    pub time_s: f64,
    /// Mapped %, if a ground truth is known.
    pub mapped_pct: Option<f64>,
    /// Fidelity %, if a ground truth is known.
    pub fidelity_pct: Option<f64>,
    /// Rocks located.
    pub rocks_located: usize,
    /// Samples collected.
    pub collected: usize,
}

/// Draws the inset of the map whose cells are `occupancy` (row = y).
pub(crate) fn map_inset(
    occupancy: &[i8],
    ground_truth: Option<&[bool]>,
    rocks: &[(f64, f64)],
    stats: &InsetStats,
) -> RgbImage {
    let mut image = RgbImage::new(SIDE_CELLS, SIDE_CELLS + BAND_PX);
    for (cell, &value) in occupancy.iter().enumerate().take(CELLS) {
        let (x, y) = cell_xy(cell);
        let truth = ground_truth.is_some_and(|t| t[cell]);
        let rgb = match value {
            OCCUPANCY_FREE => [0, if truth { 40 } else { 0 }, 255],
            OCCUPANCY_OCCUPIED => [255, if truth { 40 } else { 0 }, 0],
            _ if truth => [0, 45, 0],
            _ => [0, 0, 0],
        };
        image.set_pixel(x, SIDE_CELLS - 1 - y, rgb);
    }
    for &(x, y) in rocks {
        for (dx, dy) in [(0i64, 0i64), (1, 0), (-1, 0), (0, 1), (0, -1)] {
            let (px, py) = (x as i64 + dx, y as i64 + dy);
            if (0..SIDE_CELLS as i64).contains(&px) && (0..SIDE_CELLS as i64).contains(&py) {
                image.set_pixel(px as usize, SIDE_CELLS - 1 - py as usize, [255, 255, 255]);
            }
        }
    }
    let percent = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.1}%"));
    let first = format!("T {:.0}S M {} F {}", stats.time_s, percent(stats.mapped_pct), percent(stats.fidelity_pct));
    let second = format!("ROCKS {} COLLECTED {}", stats.rocks_located, stats.collected);
    draw_text(&mut image, 2, SIDE_CELLS + 2, &first, 2, [255, 255, 255]);
    draw_text(&mut image, 2, SIDE_CELLS + 13, &second, 2, [255, 255, 255]);
    image
}

#[cfg(test)]
mod tests {
    use rover_msgs::map_grid::{OCCUPANCY_UNKNOWN, cell_at};

    use super::*;

    #[test]
    fn draws_cells_truth_rocks_and_text() {
        let mut occupancy = vec![OCCUPANCY_UNKNOWN; CELLS];
        occupancy[cell_at(10, 20)] = OCCUPANCY_FREE;
        occupancy[cell_at(11, 20)] = OCCUPANCY_OCCUPIED;
        let mut truth = vec![false; CELLS];
        truth[0] = true;
        truth[cell_at(10, 20)] = true;
        let stats = InsetStats {
            time_s: 12.0,
            mapped_pct: Some(50.0),
            fidelity_pct: Some(90.0),
            rocks_located: 2,
            collected: 1,
        };
        let image = map_inset(&occupancy, Some(&truth), &[(100.5, 100.5)], &stats);
        assert_eq!((image.width, image.height), (200, 224));
        assert_eq!(image.pixel(0, 199), [0, 45, 0], "ground truth of cell (0, 0) at the bottom left");
        assert_eq!(image.pixel(10, 179), [0, 40, 255], "navigable where the truth is navigable");
        assert_eq!(image.pixel(11, 179), [255, 0, 0], "an obstacle");
        assert_eq!(image.pixel(12, 179), [0, 0, 0], "unknown");
        assert_eq!(image.pixel(100, 99), [255, 255, 255], "rock, north up");
        assert!((200..224).any(|y| (0..200).any(|x| image.pixel(x, y) == [255, 255, 255])), "text band");
    }
}
