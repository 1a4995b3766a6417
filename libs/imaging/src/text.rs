//! A tiny 3x5 pixel font for the statistics and legends drawn on map pictures.

use crate::RgbImage;

/// Glyph rows, 3 bits each (bit 2 = left column), top to bottom.
fn glyph(c: char) -> [u8; 5] {
    match c.to_ascii_uppercase() {
        '0' => [7, 5, 5, 5, 7],
        '1' => [2, 6, 2, 2, 7],
        '2' => [7, 1, 7, 4, 7],
        '3' => [7, 1, 7, 1, 7],
        '4' => [5, 5, 7, 1, 1],
        '5' => [7, 4, 7, 1, 7],
        '6' => [7, 4, 7, 5, 7],
        '7' => [7, 1, 1, 2, 2],
        '8' => [7, 5, 7, 5, 7],
        '9' => [7, 5, 7, 1, 7],
        'A' => [2, 5, 7, 5, 5],
        'B' => [6, 5, 6, 5, 6],
        'C' => [7, 4, 4, 4, 7],
        'D' => [6, 5, 5, 5, 6],
        'E' => [7, 4, 6, 4, 7],
        'F' => [7, 4, 6, 4, 4],
        'G' => [7, 4, 5, 5, 7],
        'H' => [5, 5, 7, 5, 5],
        'I' => [7, 2, 2, 2, 7],
        'J' => [1, 1, 1, 5, 7],
        'K' => [5, 5, 6, 5, 5],
        'L' => [4, 4, 4, 4, 7],
        'M' => [5, 7, 7, 5, 5],
        'N' => [6, 5, 5, 5, 5],
        'O' => [7, 5, 5, 5, 7],
        'P' => [7, 5, 7, 4, 4],
        'Q' => [2, 5, 5, 6, 3],
        'R' => [6, 5, 6, 5, 5],
        'S' => [7, 4, 7, 1, 7],
        'T' => [7, 2, 2, 2, 2],
        'U' => [5, 5, 5, 5, 7],
        'V' => [5, 5, 5, 5, 2],
        'W' => [5, 5, 7, 7, 5],
        'X' => [5, 5, 2, 5, 5],
        'Y' => [5, 5, 2, 2, 2],
        'Z' => [7, 1, 2, 4, 7],
        '.' => [0, 0, 0, 0, 2],
        ',' => [0, 0, 0, 2, 4],
        ':' => [0, 2, 0, 2, 0],
        '/' => [1, 1, 2, 4, 4],
        '%' => [5, 1, 2, 4, 5],
        '-' => [0, 0, 7, 0, 0],
        '(' => [1, 2, 2, 2, 1],
        ')' => [4, 2, 2, 2, 4],
        _ => [0; 5],
    }
}

/// Height of a line of text at `scale`, pixels.
pub const fn text_height_px(scale: usize) -> usize {
    5 * scale
}

/// Width of `text` at `scale`, pixels (glyphs 3 font pixels wide, 1 apart).
pub fn text_width_px(text: &str, scale: usize) -> usize {
    (text.chars().count() * 4).saturating_sub(1) * scale
}

/// Draws `text` with its top-left corner at (x, y), each font pixel `scale` pixels wide; glyphs
/// outside the image are clipped. Unknown characters are blank.
pub fn draw_text(image: &mut RgbImage, x: usize, y: usize, text: &str, scale: usize, rgb: [u8; 3]) {
    for (index, c) in text.chars().enumerate() {
        let left = x + index * 4 * scale;
        for (row, bits) in glyph(c).iter().enumerate() {
            for col in 0..3 {
                if bits & (4 >> col) == 0 {
                    continue;
                }
                for dy in 0..scale {
                    for dx in 0..scale {
                        let (px, py) = (left + col * scale + dx, y + row * scale + dy);
                        if px < image.width && py < image.height {
                            image.set_pixel(px, py, rgb);
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_clipped_glyphs() {
        let mut image = RgbImage::new(20, 10);
        draw_text(&mut image, 0, 0, "1%", 1, [255, 255, 255]);
        assert_eq!(image.pixel(1, 0), [255, 255, 255], "top of the 1");
        assert_eq!(image.pixel(0, 0), [0, 0, 0]);
        assert_eq!(image.pixel(4, 0), [255, 255, 255], "top left of the %");
        draw_text(&mut image, 18, 8, "8", 2, [1, 2, 3]);
        assert_eq!(image.pixel(19, 9), [1, 2, 3]);
    }

    #[test]
    fn every_letter_and_digit_has_a_glyph() {
        for c in ('A'..='Z').chain('0'..='9') {
            assert_ne!(glyph(c), [0; 5], "{c}");
        }
    }

    #[test]
    fn text_size_counts_glyphs_and_the_gaps_between_them() {
        assert_eq!((text_width_px("AB", 3), text_height_px(3)), (21, 15));
        assert_eq!(text_width_px("", 3), 0);
    }
}
