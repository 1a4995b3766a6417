//! Filled rectangles, thick lines, discs and rings on an [`RgbImage`], clipped at its edges; points
//! are in pixels, (0, 0) the top-left corner of the top-left pixel.

use crate::RgbImage;

/// Fills `width_px` x `height_px` pixels from column `x`, row `y`.
pub fn fill_rect(image: &mut RgbImage, x: usize, y: usize, width_px: usize, height_px: usize, rgb: [u8; 3]) {
    for row in y..(y + height_px).min(image.height) {
        for col in x..(x + width_px).min(image.width) {
            image.set_pixel(col, row, rgb);
        }
    }
}

/// Draws the segment from `from` to `to`, `width_px` wide with round ends.
pub fn draw_line(image: &mut RgbImage, from: (f64, f64), to: (f64, f64), width_px: f64, rgb: [u8; 3]) {
    let radius = width_px / 2.0;
    paint_where(image, bounds(&[from, to], radius), rgb, |point| distance_to_segment(point, from, to) <= radius);
}

/// Fills the disc of `radius_px` around `centre`.
pub fn fill_disc(image: &mut RgbImage, centre: (f64, f64), radius_px: f64, rgb: [u8; 3]) {
    paint_where(image, bounds(&[centre], radius_px), rgb, |point| distance(point, centre) <= radius_px);
}

/// Draws the circle of `radius_px` around `centre`, `width_px` wide.
pub fn draw_ring(image: &mut RgbImage, centre: (f64, f64), radius_px: f64, width_px: f64, rgb: [u8; 3]) {
    let half = width_px / 2.0;
    let on_ring = |point| (distance(point, centre) - radius_px).abs() <= half;
    paint_where(image, bounds(&[centre], radius_px + half), rgb, on_ring);
}

/// Pixel columns and rows (half-open ranges) that cover `points` grown by `margin_px`, clipped
/// at zero.
fn bounds(points: &[(f64, f64)], margin_px: f64) -> ((usize, usize), (usize, usize)) {
    let low = |v: f64| (v - margin_px).floor().max(0.0) as usize;
    let high = |v: f64| (v + margin_px).ceil().max(0.0) as usize + 1;
    let (xs, ys): (Vec<f64>, Vec<f64>) = points.iter().copied().unzip();
    let min = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
    let max = |v: &[f64]| v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    ((low(min(&xs)), high(max(&xs))), (low(min(&ys)), high(max(&ys))))
}

/// Sets to `rgb` every pixel within `bounds` whose centre passes `inside`.
fn paint_where(
    image: &mut RgbImage,
    ((x0, x1), (y0, y1)): ((usize, usize), (usize, usize)),
    rgb: [u8; 3],
    inside: impl Fn((f64, f64)) -> bool,
) {
    for y in y0..y1.min(image.height) {
        for x in x0..x1.min(image.width) {
            if inside((x as f64 + 0.5, y as f64 + 0.5)) {
                image.set_pixel(x, y, rgb);
            }
        }
    }
}

fn distance(a: (f64, f64), b: (f64, f64)) -> f64 {
    (a.0 - b.0).hypot(a.1 - b.1)
}

fn distance_to_segment(point: (f64, f64), from: (f64, f64), to: (f64, f64)) -> f64 {
    let (dx, dy) = (to.0 - from.0, to.1 - from.1);
    let length_sq = dx * dx + dy * dy;
    let t = if length_sq == 0.0 {
        0.0
    } else {
        (((point.0 - from.0) * dx + (point.1 - from.1) * dy) / length_sq).clamp(0.0, 1.0)
    };
    distance(point, (from.0 + t * dx, from.1 + t * dy))
}

#[cfg(test)]
mod tests {
    use super::*;

    const WHITE: [u8; 3] = [255, 255, 255];
    const BLACK: [u8; 3] = [0, 0, 0];

    #[test]
    fn a_rect_is_filled_and_clipped() {
        let mut image = RgbImage::new(10, 10);
        fill_rect(&mut image, 8, 1, 5, 2, WHITE);
        assert_eq!((image.pixel(8, 1), image.pixel(9, 2)), (WHITE, WHITE));
        assert_eq!((image.pixel(7, 1), image.pixel(9, 3)), (BLACK, BLACK));
    }

    #[test]
    fn a_line_covers_its_width_between_its_ends() {
        let mut image = RgbImage::new(20, 10);
        draw_line(&mut image, (2.0, 5.0), (17.0, 5.0), 2.0, WHITE);
        assert!((2..17).all(|x| image.pixel(x, 4) == WHITE && image.pixel(x, 5) == WHITE));
        assert_eq!((image.pixel(10, 2), image.pixel(10, 7), image.pixel(19, 5)), (BLACK, BLACK, BLACK));
    }

    #[test]
    fn a_disc_is_full_and_a_ring_is_hollow() {
        let mut image = RgbImage::new(40, 20);
        fill_disc(&mut image, (10.0, 10.0), 5.0, WHITE);
        draw_ring(&mut image, (30.0, 10.0), 5.0, 2.0, WHITE);
        assert_eq!((image.pixel(10, 10), image.pixel(13, 10), image.pixel(16, 10)), (WHITE, WHITE, BLACK));
        assert_eq!((image.pixel(30, 10), image.pixel(34, 10), image.pixel(37, 10)), (BLACK, WHITE, BLACK));
    }
}
