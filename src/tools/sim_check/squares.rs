//! The map in 8 m squares: the agreement of the frames taken in each square, the squares kept
//! aside from calibrating the simulator's look, and a picture of the map coloured by agreement so
//! that a person sees where the simulated world is still wrong.

use rover_imaging::RgbImage;
use rover_imaging::shapes::fill_rect;
use rover_imaging::text::{draw_text, text_height_px, text_width_px};
use rover_sim::world::WORLD_SIZE;
use serde::Serialize;

use super::{FrameCheck, percentile};

/// Side of a square, metres.
pub const SQUARE_M: f64 = 8.0;
/// Squares along each side of the world.
const SQUARES_A_SIDE: usize = WORLD_SIZE / SQUARE_M as usize;
/// Pixels of the picture per metre.
const PX_PER_M: usize = 4;
/// Font pixel size of the picture's text, pixels.
const TEXT_SCALE: usize = 2;
/// Height of the legend under the map, pixels.
const LEGEND_PX: usize = 64;

/// A square: its column and row (0 at the west and south edges).
pub type Square = (usize, usize);

/// The square holding (x, y), metres.
pub fn square_of(x_m: f64, y_m: f64) -> Square {
    let index = |v: f64| ((v / SQUARE_M).floor().max(0.0) as usize).min(SQUARES_A_SIDE - 1);
    (index(x_m), index(y_m))
}

/// True for the squares kept aside: the simulator's look was calibrated on the frames of the
/// other squares only, so these tell whether it holds where it was not tuned. Every third square
/// along each diagonal, which spreads them over the whole map.
pub fn is_held_out((column, row): Square) -> bool {
    (column + row) % 3 == 0
}

/// The frames of one square in figures.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct SquareSummary {
    /// West edge, metres.
    pub x_m: f64,
    /// South edge, metres.
    pub y_m: f64,
    /// Whether the square was kept aside from calibration.
    pub held_out: bool,
    /// Frames taken in the square.
    pub frames: usize,
    /// Their mean navigable IoU.
    pub nav_iou_mean: f64,
    /// The 10th percentile of their navigable IoU.
    pub nav_iou_p10: f64,
}

/// One summary per square that holds frames, south to north, west to east.
pub fn square_summaries(frames: &[FrameCheck]) -> Vec<SquareSummary> {
    let mut by_square = std::collections::BTreeMap::<(usize, usize), Vec<f64>>::new();
    for frame in frames {
        let (column, row) = square_of(frame.x_m, frame.y_m);
        by_square.entry((row, column)).or_default().push(frame.nav_iou);
    }
    by_square
        .into_iter()
        .map(|((row, column), mut ious)| {
            ious.sort_by(f64::total_cmp);
            SquareSummary {
                x_m: column as f64 * SQUARE_M,
                y_m: row as f64 * SQUARE_M,
                held_out: is_held_out((column, row)),
                frames: ious.len(),
                nav_iou_mean: ious.iter().sum::<f64>() / ious.len() as f64,
                nav_iou_p10: percentile(&ious, 0.1),
            }
        })
        .collect()
}

/// The colour of a navigable IoU: red at 0, yellow at 0.5, green at 1.
fn iou_colour(iou: f64) -> [u8; 3] {
    let t = iou.clamp(0.0, 1.0);
    let (red, green) = if t < 0.5 { (1.0, t * 2.0) } else { (2.0 - t * 2.0, 1.0) };
    [(red * 230.0) as u8, (green * 200.0) as u8, 40]
}

/// The map (`ground_truth`: navigable cells, row = y) north up, each square with frames
/// coloured by its mean navigable IoU (its ground bright, the rest dark) and labelled with it in
/// hundredths, the squares kept aside framed in white; a legend below.
pub fn picture(squares: &[SquareSummary], ground_truth: &[bool]) -> RgbImage {
    let side_px = WORLD_SIZE * PX_PER_M;
    let mut image = RgbImage::new(side_px, side_px + LEGEND_PX);
    let square_at = |x: usize, y: usize| {
        let (column, row) = square_of(x as f64, y as f64);
        squares.iter().find(|s| square_of(s.x_m, s.y_m) == (column, row))
    };
    for y in 0..WORLD_SIZE {
        for x in 0..WORLD_SIZE {
            let ground = ground_truth[y * WORLD_SIZE + x];
            let rgb = match (square_at(x, y), ground) {
                (Some(square), true) => iou_colour(square.nav_iou_mean),
                (Some(square), false) => iou_colour(square.nav_iou_mean).map(|c| c / 4),
                (None, true) => [110, 110, 110],
                (None, false) => [25, 25, 25],
            };
            fill_rect(&mut image, x * PX_PER_M, (WORLD_SIZE - 1 - y) * PX_PER_M, PX_PER_M, PX_PER_M, rgb);
        }
    }
    let square_px = SQUARE_M as usize * PX_PER_M;
    for square in squares {
        let (left, top) = (square.x_m as usize * PX_PER_M, side_px - square.y_m as usize * PX_PER_M - square_px);
        if square.held_out {
            for (x, y, w, h) in [
                (0, 0, square_px, 2),
                (0, square_px - 2, square_px, 2),
                (0, 0, 2, square_px),
                (square_px - 2, 0, 2, square_px),
            ] {
                fill_rect(&mut image, left + x, top + y, w, h, [255, 255, 255]);
            }
        }
        let label = format!("{:.0}", square.nav_iou_mean * 100.0);
        let (width, height) = (text_width_px(&label, TEXT_SCALE), text_height_px(TEXT_SCALE));
        let (x, y) = (left + (square_px - width) / 2, top + (square_px - height) / 2);
        fill_rect(&mut image, x - 2, y - 2, width + 4, height + 4, iou_colour(square.nav_iou_mean));
        draw_text(&mut image, x, y, &label, TEXT_SCALE, [0, 0, 0]);
    }
    draw_legend(&mut image, side_px + 12);
    image
}

/// The colour ramp and what the picture shows, from row `top` down.
fn draw_legend(image: &mut RgbImage, top: usize) {
    let white = [255, 255, 255];
    for k in 0..=100 {
        fill_rect(image, 12 + k * 2, top, 2, 14, iou_colour(k as f64 / 100.0));
    }
    let below = top + 20;
    draw_text(image, 12, below, "0", TEXT_SCALE, white);
    draw_text(image, 12 + 100 - text_width_px("50", TEXT_SCALE) / 2, below, "50", TEXT_SCALE, white);
    draw_text(image, 12 + 200 - text_width_px("100", TEXT_SCALE), below, "100", TEXT_SCALE, white);
    let lines = ["NAVIGABLE IOU PER 8 M SQUARE, IN HUNDREDTHS", "WHITE FRAME: KEPT ASIDE FROM CALIBRATION"];
    for (k, line) in lines.iter().enumerate() {
        draw_text(image, 240, top + k * (text_height_px(TEXT_SCALE) + 8), line, TEXT_SCALE, white);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(x_m: f64, y_m: f64, nav_iou: f64) -> FrameCheck {
        FrameCheck { image: String::new(), x_m, y_m, nav_iou, ..FrameCheck::default() }
    }

    #[test]
    fn frames_are_summed_up_by_the_square_they_were_taken_in() {
        let frames = [frame(1.0, 1.0, 0.2), frame(7.9, 0.5, 0.4), frame(8.0, 0.5, 0.9), frame(100.0, 17.0, 0.5)];
        let squares = square_summaries(&frames);
        assert_eq!(squares.len(), 3);
        assert_eq!((squares[0].x_m, squares[0].y_m, squares[0].frames), (0.0, 0.0, 2));
        assert!((squares[0].nav_iou_mean - 0.3).abs() < 1e-12 && squares[0].held_out);
        assert_eq!((squares[1].x_m, squares[1].held_out), (8.0, false));
        assert_eq!((squares[2].x_m, squares[2].y_m), (96.0, 16.0));
        assert_eq!(square_of(-3.0, 250.0), (0, 24), "positions off the map fall in its edge squares");
    }

    #[test]
    fn a_third_of_the_squares_are_kept_aside_in_every_row() {
        for row in 0..SQUARES_A_SIDE {
            let kept = (0..SQUARES_A_SIDE).filter(|&column| is_held_out((column, row))).count();
            assert!((8..=9).contains(&kept), "row {row}: {kept}");
        }
    }

    #[test]
    fn the_picture_colours_the_squares_by_their_agreement() {
        let squares = square_summaries(&[frame(4.0, 4.0, 0.95), frame(20.0, 4.0, 0.1)]);
        let ground = vec![true; WORLD_SIZE * WORLD_SIZE];
        let image = picture(&squares, &ground);
        assert_eq!((image.width, image.height), (800, 800 + LEGEND_PX));
        let at = |x_m: f64, y_m: f64| image.pixel((x_m * 4.0) as usize, ((200.0 - y_m) * 4.0) as usize);
        assert_eq!(at(0.1, 6.0), [255, 255, 255], "the held-out square's frame");
        assert_eq!(at(2.5, 2.5), iou_colour(0.95));
        assert_eq!(at(18.5, 2.5), iou_colour(0.1));
        assert_eq!(at(50.0, 50.0), [110, 110, 110], "ground without frames");
        assert!(iou_colour(0.1)[0] > iou_colour(0.1)[1] && iou_colour(0.95)[1] > iou_colour(0.95)[0]);
    }
}
