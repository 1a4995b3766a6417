//! The bird's-eye warp as a lookup table: for every warped pixel whose source neighbourhood touches
//! the camera image, the source pixels and the fixed-point bilinear weights that OpenCV's
//! `warpPerspective` (INTER_LINEAR, constant black border) would use, so that interpolating only
//! these entries gives the same bytes as warping the whole image.
//!
//! The source coordinates come from the inverse homography evaluated in double precision in blocks
//! of 64x16 warped pixels (the row terms are computed at the block's first column), scaled to
//! 1/32 pixel and rounded half to even. Weights are 15-bit products of the 1/32 fractions; the
//! whole-pixel entry keeps OpenCV's 32767 + 1 split, which is invisible on 8-bit images.

use std::ops::Range;

use crate::classify::{Class, ColourBits};
use crate::homography::{Matrix3, invert};

/// Sub-pixel resolution of the source coordinates (OpenCV's INTER_BITS).
const INTER_BITS: u32 = 5;
const INTER_TAB_SIZE: i32 = 1 << INTER_BITS;
/// Fixed-point scale of the weights (OpenCV's INTER_REMAP_COEF_BITS).
pub(crate) const WEIGHT_BITS: u32 = 15;
/// OpenCV's warp block: 64 columns by 16 rows.
const BLOCK_COLUMNS: usize = 64;
const BLOCK_ROWS: usize = 16;

/// One warped pixel: where it is, and how it is interpolated from the camera image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WarpEntry {
    /// Column in the warped image.
    pub x: u16,
    /// Row in the warped image.
    pub y: u16,
    /// Index of the top-left tap among the pixels of the black-bordered source (see
    /// [`BorderedImage`]); the others are the pixel to its right and the two below them.
    pub tap: u32,
    /// The source position's fraction of a pixel, in 1/32 px: `fy * 32 + fx`, which picks the
    /// four taps' weights ([`WarpEntry::weights`]).
    pub fraction: u16,
    /// The warped pixel is inside the camera's field of view (the warped all-ones mask is 1).
    pub in_view: bool,
}

/// The warp of a `width` x `height` image onto a warped image of the same size.
#[derive(Debug, Clone)]
pub struct WarpTable {
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// Warped pixels that see any of the image, in row-major order of the warped image.
    pub entries: Vec<WarpEntry>,
    /// Pixels per row of the black-bordered source.
    pub stride_px: usize,
    /// The rows of the image that the entries' taps read (the others never matter).
    pub source_rows: Range<usize>,
    /// Each entry's taps, fraction and in-view flag in four bytes: all that classifying an entry
    /// reads, where [`WarpEntry`] takes twelve.
    pub taps: Vec<Tap>,
}

/// A warped pixel's top-left tap among the pixels of the bordered source (the low 21 bits), its
/// fraction of a pixel (the next 10) and whether it is in view (the top bit), in one `u32`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Tap(u32);

impl Tap {
    const INDEX_BITS: u32 = 21;
    const INDEX_MASK: u32 = (1 << Self::INDEX_BITS) - 1;
    const IN_VIEW: u32 = 1 << 31;

    fn of(entry: &WarpEntry) -> Self {
        let in_view = if entry.in_view { Self::IN_VIEW } else { 0 };
        Tap(entry.tap | (entry.fraction as u32) << Self::INDEX_BITS | in_view)
    }

    /// Index of the top-left tap in the bordered source.
    #[inline]
    pub fn index(self) -> usize {
        (self.0 & Self::INDEX_MASK) as usize
    }

    /// The fixed-point weights of the four taps.
    #[inline]
    pub fn weights(self) -> [u16; 4] {
        WEIGHTS[((self.0 & !Self::IN_VIEW) >> Self::INDEX_BITS) as usize]
    }

    /// The warped pixel is inside the camera's field of view.
    #[inline]
    pub fn in_view(self) -> bool {
        self.0 & Self::IN_VIEW != 0
    }
}

impl WarpEntry {
    /// Fixed-point weights of the four taps (sum 2^15): top-left, top-right, bottom-left, bottom-right.
    pub fn weights(&self) -> [u16; 4] {
        WEIGHTS[self.fraction as usize]
    }
}

/// The bilinear weights of OpenCV's 32x32 interpolation table for fractions (fx, fy) in 1/32 px.
const fn weights(fx: i32, fy: i32) -> [i32; 4] {
    let one = 1 << WEIGHT_BITS;
    let scale = one / (INTER_TAB_SIZE * INTER_TAB_SIZE);
    let (gx, gy) = (INTER_TAB_SIZE - fx, INTER_TAB_SIZE - fy);
    let w = [gy * gx * scale, gy * fx * scale, fy * gx * scale, fy * fx * scale];
    if w[0] == one { [one - 1, 0, 0, 1] } else { w }
}

/// [`weights`] of every fraction `fy * 32 + fx`.
const WEIGHTS: [[u16; 4]; (INTER_TAB_SIZE * INTER_TAB_SIZE) as usize] = {
    let mut table = [[0; 4]; (INTER_TAB_SIZE * INTER_TAB_SIZE) as usize];
    let mut fraction = 0;
    while fraction < table.len() {
        let w = weights(fraction as i32 % INTER_TAB_SIZE, fraction as i32 / INTER_TAB_SIZE);
        table[fraction] = [w[0] as u16, w[1] as u16, w[2] as u16, w[3] as u16];
        fraction += 1;
    }
    table
};

/// Rounds half to even and saturates to `i32`, like OpenCV's `saturate_cast<int>(double)`.
fn round_to_int(value: f64) -> i32 {
    value.clamp(i32::MIN as f64, i32::MAX as f64).round_ties_even() as i32
}

impl WarpTable {
    /// Builds the table of the warp by `matrix` (source to warped) for `width` x `height` images;
    /// `None` if the matrix cannot be inverted or the images are too large for the table's
    /// 16-bit columns and rows and 21-bit tap indices.
    pub fn new(matrix: &Matrix3, width: usize, height: usize) -> Option<Self> {
        let too_large =
            width.max(height) > u16::MAX as usize || (width + 2) * (height + 2) > Tap::INDEX_MASK as usize + 1;
        if too_large {
            return None;
        }
        let m = invert(matrix)?;
        let stride_px = width + 2;
        let mut entries = Vec::new();
        let mut rows: Vec<Vec<WarpEntry>> = vec![Vec::new(); height];
        for block_y in (0..height).step_by(BLOCK_ROWS) {
            for block_x in (0..width).step_by(BLOCK_COLUMNS) {
                let columns = BLOCK_COLUMNS.min(width - block_x);
                for (y, row) in rows.iter_mut().enumerate().skip(block_y).take(BLOCK_ROWS) {
                    let (bx, fy) = (block_x as f64, y as f64);
                    let x0 = m[0] * bx + m[1] * fy + m[2];
                    let y0 = m[3] * bx + m[4] * fy + m[5];
                    let w0 = m[6] * bx + m[7] * fy + m[8];
                    for column in 0..columns {
                        let c = column as f64;
                        let w = w0 + m[6] * c;
                        let w = if w != 0.0 { INTER_TAB_SIZE as f64 / w } else { 0.0 };
                        let sx_fixed = round_to_int((x0 + m[0] * c) * w);
                        let sy_fixed = round_to_int((y0 + m[3] * c) * w);
                        let entry =
                            Self::entry((block_x + column, y), (sx_fixed, sy_fixed), (width, height), stride_px);
                        row.extend(entry);
                    }
                }
            }
        }
        for mut row in rows {
            row.sort_by_key(|e| e.x);
            entries.extend(row);
        }
        let source_rows = Self::rows_read(&entries, stride_px, height);
        let taps = entries.iter().map(Tap::of).collect();
        Some(WarpTable { width, height, entries, stride_px, source_rows, taps })
    }

    /// The image rows that the taps of `entries` read: each reads its top-left tap's row of the
    /// bordered source and the row below, the bordered rows being the image's one lower.
    fn rows_read(entries: &[WarpEntry], stride_px: usize, height: usize) -> Range<usize> {
        let bordered_rows = entries.iter().map(|e| e.tap as usize / stride_px);
        let (top, bottom) = bordered_rows.fold((usize::MAX, 0), |(top, bottom), row| (top.min(row), bottom.max(row)));
        if top > bottom {
            return 0..0;
        }
        top.saturating_sub(1)..(bottom + 1).min(height)
    }

    fn entry(
        (x, y): (usize, usize),
        (sx_fixed, sy_fixed): (i32, i32),
        (width, height): (usize, usize),
        stride_px: usize,
    ) -> Option<WarpEntry> {
        let sx = (sx_fixed >> INTER_BITS).clamp(i16::MIN as i32, i16::MAX as i32);
        let sy = (sy_fixed >> INTER_BITS).clamp(i16::MIN as i32, i16::MAX as i32);
        let (w, h) = (width as i32, height as i32);
        if sx >= w || sx + 1 < 0 || sy >= h || sy + 1 < 0 {
            return None;
        }
        let (fx, fy) = (sx_fixed & (INTER_TAB_SIZE - 1), sy_fixed & (INTER_TAB_SIZE - 1));
        let weights = weights(fx, fy);
        let positions = [(sx, sy), (sx + 1, sy), (sx, sy + 1), (sx + 1, sy + 1)];
        let inside = positions.map(|(px, py)| px >= 0 && py >= 0 && px < w && py < h);
        let coverage: i32 = (0..4).filter(|&i| inside[i]).map(|i| weights[i]).sum();
        let in_view = (coverage + (1 << (WEIGHT_BITS - 1))) >> WEIGHT_BITS >= 1;
        let tap = ((sy + 1) as usize * stride_px + (sx + 1) as usize) as u32;
        let fraction = (fy * INTER_TAB_SIZE + fx) as u16;
        Some(WarpEntry { x: x as u16, y: y as u16, tap, fraction, in_view })
    }

    /// Interpolates the warped pixel of `tap` from the black-bordered source.
    #[inline]
    pub fn sample(&self, tap: Tap, source: &BorderedImage) -> [u8; 3] {
        let (at, stride) = (tap.index() * 3, self.stride_px * 3);
        let top: &[u8; 6] = source.data[at..at + 6].try_into().expect("six bytes");
        let bottom: &[u8; 6] = source.data[at + stride..at + stride + 6].try_into().expect("six bytes");
        let [w0, w1, w2, w3] = tap.weights();
        let (w0, w1, w2, w3) = (w0 as u32, w1 as u32, w2 as u32, w3 as u32);
        let channel = |k: usize| {
            let sum = (1 << (WEIGHT_BITS - 1))
                + top[k] as u32 * w0
                + top[k + 3] as u32 * w1
                + bottom[k] as u32 * w2
                + bottom[k + 3] as u32 * w3;
            (sum >> WEIGHT_BITS).min(255) as u8
        };
        [channel(0), channel(1), channel(2)]
    }
}

/// A plane value of [`BorderedImage`]'s decided classes: the taps do not decide the class.
const UNDECIDED: u8 = u8::MAX;
const OBSTACLE: u8 = Class::Obstacle as u8;
/// The classes by their codes, which the decided plane holds (any other value is undecided).
const DECIDED_CLASSES: [Class; 4] = [Class::Unknown, Class::Navigable, Class::Obstacle, Class::Rock];

/// An RGB image inside a one-pixel black border: the taps of OpenCV's constant border that fall
/// outside the image read black, without any test in the loop. With [`ColourBits`], also the
/// class that each block of two by two pixels decides for a warped pixel in view whose top-left
/// tap it starts at, in a plane of the same layout. The buffers are kept from one frame to the
/// next: only the rows filled change.
#[derive(Debug, Clone, Default)]
pub struct BorderedImage {
    data: Vec<u8>,
    bits: Vec<u8>,
    decided: Vec<u8>,
    /// Width, height and the colour bits of black of the buffers' layout.
    layout: Option<(usize, usize, Option<u8>)>,
    /// The image rows that the last fill copied.
    filled: Range<usize>,
}

impl BorderedImage {
    /// Copies rows `rows` of the `width` x `height` RGB pixels `rgb` into the bordered buffer
    /// (the others, and those `rgb` is too short for, read black); when `colour_bits` are given,
    /// also the classes that their blocks of two by two pixels decide
    /// ([`ColourBits::class_of_taps`]) for the blocks whose top-left pixel lies in the bordered
    /// rows `rows.start..=rows.end`, which hold every top-left tap of a table whose
    /// [`WarpTable::source_rows`] are `rows` (the other blocks are undecided, or keep their class
    /// when neither of their rows changed).
    pub fn fill(
        &mut self,
        rgb: &[u8],
        (width, height): (usize, usize),
        rows: Range<usize>,
        colour_bits: Option<&ColourBits>,
    ) {
        let stride_px = width + 2;
        let black_bits = colour_bits.map(|bits| bits.of_pixel([0, 0, 0]));
        self.lay_out((width, height, black_bits));
        let rows_given = rgb.len() / (width * 3).max(1);
        let end = rows.end.min(height).min(rows_given);
        let rows = rows.start.min(end)..end;
        self.blacken_rows_not_in(&rows, stride_px, width, black_bits);
        self.filled = rows.clone();
        let image_rows = || rgb.chunks_exact(width * 3).enumerate().skip(rows.start).take(rows.len());
        for (row, pixels) in image_rows() {
            let start = ((row + 1) * stride_px + 1) * 3;
            self.data[start..start + width * 3].copy_from_slice(pixels);
        }
        if let Some(colour_bits) = colour_bits {
            for (row, pixels) in image_rows() {
                let start = (row + 1) * stride_px + 1;
                for (bits, pixel) in self.bits[start..start + width].iter_mut().zip(pixels.chunks_exact(3)) {
                    *bits = colour_bits.of_pixel([pixel[0], pixel[1], pixel[2]]);
                }
            }
            self.decide_blocks(stride_px, rows.start..(rows.end + 1).min(height + 1));
        }
    }

    /// Makes the rows of the last fill that are not in `rows` black again, and the blocks over
    /// them undecided.
    fn blacken_rows_not_in(&mut self, rows: &Range<usize>, stride_px: usize, width: usize, black_bits: Option<u8>) {
        for row in self.filled.clone().filter(|row| !rows.contains(row)) {
            let start = (row + 1) * stride_px + 1;
            self.data[start * 3..(start + width) * 3].fill(0);
            if let Some(black) = black_bits {
                self.bits[start..start + width].fill(black);
                self.decided[start - 1 - stride_px..start - 1 + stride_px].fill(UNDECIDED);
            }
        }
    }

    /// Black buffers for `layout` (width, height, colour bits of black) unless they have it.
    fn lay_out(&mut self, layout: (usize, usize, Option<u8>)) {
        if self.layout == Some(layout) {
            return;
        }
        let (width, height, black_bits) = layout;
        let pixels = (width + 2) * (height + 2);
        self.data = vec![0; pixels * 3];
        self.bits = black_bits.map_or_else(Vec::new, |black| vec![black; pixels]);
        self.decided = vec![UNDECIDED; self.bits.len()];
        self.filled = 0..0;
        self.layout = Some(layout);
    }

    /// The class of the warped pixel whose top-left tap is `tap` where the colour bits of its
    /// four taps decide it (see [`BorderedImage::fill`]), else `None`.
    #[inline]
    pub fn decided_class(&self, tap: Tap) -> Option<Class> {
        let code = self.decided[tap.index()];
        let out_of_view = code == OBSTACLE && !tap.in_view();
        DECIDED_CLASSES.get(code as usize).map(|&class| if out_of_view { Class::Unknown } else { class })
    }

    /// The decided class of every block of two by two pixels whose top-left pixel lies in the
    /// bordered rows `rows`, from the bits all four pixels have and those any of them has (but for
    /// the range's last pixel; a block at the end of another row takes the next row's first pixel
    /// for its right ones, harmless as no tap starts in the last column).
    fn decide_blocks(&mut self, stride_px: usize, rows: Range<usize>) {
        let (start, end) = (rows.start * stride_px, rows.end * stride_px);
        let (top, bottom) = (&self.bits[start..end], &self.bits[start + stride_px..end + stride_px]);
        let blocks = top.windows(2).zip(bottom.windows(2));
        for (decided, (top, bottom)) in self.decided[start..end].iter_mut().zip(blocks) {
            let (all, any) = (top[0] & top[1] & bottom[0] & bottom[1], top[0] | top[1] | bottom[0] | bottom[1]);
            *decided = ColourBits::class_of_taps(all, any).map_or(UNDECIDED, |class| class as u8);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::classify::Thresholds;
    use crate::homography::perspective_transform;

    #[test]
    fn weights_are_exact_bilinear_with_the_whole_pixel_quirk() {
        assert_eq!(weights(0, 0), [32767, 0, 0, 1]);
        assert_eq!(weights(16, 0), [16384, 16384, 0, 0]);
        assert_eq!(weights(8, 24), [6144, 2048, 18432, 6144]);
        for fx in 0..32 {
            for fy in 0..32 {
                assert_eq!(weights(fx, fy).iter().sum::<i32>(), 32768);
            }
        }
    }

    #[test]
    fn each_tap_carries_its_entrys_index_weights_and_view() {
        let table = WarpTable::new(&crate::Calibration::default().homography().unwrap(), 320, 160).unwrap();
        let fractions: std::collections::HashSet<u16> = table.entries.iter().map(|e| e.fraction).collect();
        assert!(fractions.len() > 500, "{} fractions", fractions.len());
        assert!(table.entries.iter().any(|e| !e.in_view) && table.entries.iter().any(|e| e.in_view));
        for (entry, &tap) in table.entries.iter().zip(&table.taps) {
            assert_eq!(
                (tap.index(), tap.weights(), tap.in_view()),
                (entry.tap as usize, entry.weights(), entry.in_view)
            );
        }
        let too_many_pixels = WarpTable::new(&identity_matrix(), 2048, 1024);
        assert!(too_many_pixels.is_none(), "2050 x 1026 bordered pixels need more than 21 bits");
    }

    /// The homography that leaves every point where it is.
    fn identity_matrix() -> Matrix3 {
        let corners = [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]];
        perspective_transform(&corners, &corners).unwrap()
    }

    /// The table of the identity warp of 20 x 10 images.
    fn identity_table() -> WarpTable {
        WarpTable::new(&identity_matrix(), 20, 10).unwrap()
    }

    #[test]
    fn rows_filled_before_but_not_now_read_black_again_and_blocks_over_both_are_undecided() {
        let table = identity_table();
        let bits = ColourBits::of(&Thresholds::default()).unwrap();
        let white = vec![255u8; 20 * 10 * 3];
        let mut source = BorderedImage::default();
        source.fill(&white, (20, 10), 0..10, Some(&bits));
        source.fill(&white, (20, 10), 4..7, Some(&bits));
        for (entry, &tap) in table.entries.iter().zip(&table.taps) {
            let white_row = (4..7).contains(&(entry.y as usize));
            assert_eq!(table.sample(tap, &source), if white_row { [255; 3] } else { [0; 3] }, "{entry:?}");
            let decided = source.decided_class(tap);
            match entry.y {
                4 | 5 if entry.x < 19 => assert_eq!(decided, Some(Class::Navigable), "{entry:?}"),
                _ => assert_eq!(decided, None, "{entry:?}: white and black taps, or rows no longer filled"),
            }
        }
        source.fill(&white[..20 * 5 * 3], (20, 10), 0..10, Some(&bits));
        for (entry, &tap) in table.entries.iter().zip(&table.taps) {
            let expected = if entry.y < 5 { [255; 3] } else { [0; 3] };
            assert_eq!(table.sample(tap, &source), expected, "{entry:?}: the rows of a short image read black");
        }
    }

    #[test]
    fn an_identity_warp_copies_the_image() {
        let table = identity_table();
        assert_eq!(table.entries.len(), 200);
        assert_eq!(table.source_rows, 0..10);
        let rgb: Vec<u8> = (0..600).map(|i| (i * 7 % 256) as u8).collect();
        let mut source = BorderedImage::default();
        source.fill(&rgb, (20, 10), table.source_rows.clone(), None);
        for (entry, &tap) in table.entries.iter().zip(&table.taps) {
            let at = (entry.y as usize * 20 + entry.x as usize) * 3;
            assert_eq!(table.sample(tap, &source), [rgb[at], rgb[at + 1], rgb[at + 2]]);
            assert!(entry.in_view);
        }
    }
}
