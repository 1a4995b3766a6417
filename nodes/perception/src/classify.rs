//! Colour classification of warped pixels: navigable ground, rock samples (RGB or HSV rule) and
//! obstacles (in view but not navigable), with the thresholds of the seed reports as defaults.

/// A pixel class, with the codes of `rover_msgs/TerrainScan`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum Class {
    /// Outside the field of view.
    Unknown = 0,
    /// Bright ground.
    Navigable = 1,
    /// In view but not navigable.
    Obstacle = 2,
    /// A yellow rock sample.
    Rock = 3,
}

/// How rock samples are recognised.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RockRule {
    /// R > r, G > g, B < b (the starter notebooks' rule).
    Rgb {
        /// Red must exceed this.
        min_red: u8,
        /// Green must exceed this.
        min_green: u8,
        /// Blue must stay below this.
        max_blue: u8,
    },
    /// OpenCV 8-bit HSV (H in 0..180) within the inclusive bounds, like `cv2.inRange`.
    Hsv {
        /// Lower bounds (H, S, V).
        lower: [u8; 3],
        /// Upper bounds (H, S, V).
        upper: [u8; 3],
    },
}

/// The colour rules.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Thresholds {
    /// Navigable when every channel exceeds its value.
    pub navigable: [u8; 3],
    /// Rock rule.
    pub rock: RockRule,
}

impl Default for Thresholds {
    fn default() -> Self {
        let [min_red, min_green, max_blue] = Thresholds::ROCK_RGB;
        Thresholds { navigable: Thresholds::NAVIGABLE_RGB_MIN, rock: RockRule::Rgb { min_red, min_green, max_blue } }
    }
}

impl Thresholds {
    /// The seed reports' navigable rule: red, green and blue all above these.
    pub const NAVIGABLE_RGB_MIN: [u8; 3] = [160, 160, 160];
    /// The starter notebooks' rock rule: red above, green above, blue below these.
    pub const ROCK_RGB: [u8; 3] = [110, 110, 50];

    /// True if the pixel is navigable ground.
    #[inline]
    pub fn is_navigable(&self, rgb: [u8; 3]) -> bool {
        rgb[0] > self.navigable[0] && rgb[1] > self.navigable[1] && rgb[2] > self.navigable[2]
    }

    /// True if the pixel is a rock sample.
    #[inline]
    pub fn is_rock(&self, rgb: [u8; 3]) -> bool {
        match self.rock {
            RockRule::Rgb { min_red, min_green, max_blue } => {
                rgb[0] > min_red && rgb[1] > min_green && rgb[2] < max_blue
            }
            RockRule::Hsv { lower, upper } => {
                let hsv = rgb_to_hsv(rgb);
                (0..3).all(|k| lower[k] <= hsv[k] && hsv[k] <= upper[k])
            }
        }
    }

    /// The class of a warped pixel: rock first, then navigable, then obstacle if in view.
    #[inline]
    pub fn classify(&self, rgb: [u8; 3], in_view: bool) -> Class {
        if self.is_rock(rgb) {
            Class::Rock
        } else if self.is_navigable(rgb) {
            Class::Navigable
        } else if in_view {
            Class::Obstacle
        } else {
            Class::Unknown
        }
    }
}

/// The colour tests of the RGB rules, one bit each, per channel value: a pixel's bits are the OR of
/// its three channels' entries. Each test compares one channel with a limit, so a bilinear mean of
/// pixels that all pass it passes it, and one of pixels that all fail it fails it (the weights
/// are non-negative and sum to one, and the rounding stays on the same side of a whole-number
/// limit): where the four taps of a warped pixel agree on the tests a rule needs, so does the
/// warped pixel, and the rule's outcome follows without interpolating.
#[derive(Debug, Clone, PartialEq)]
pub struct ColourBits {
    by_channel: [[u8; 256]; 3],
}

/// Bits of [`ColourBits`]: red, green and blue as the rock rule wants them...
const ROCK_BITS: u8 = 0b000_111;
/// ...and the three channels above the navigable limits.
const NAVIGABLE_BITS: u8 = 0b111_000;

impl ColourBits {
    /// The tests of `thresholds`, or none when the rock rule is HSV (hue is no single-channel test).
    pub fn of(thresholds: &Thresholds) -> Option<Self> {
        let RockRule::Rgb { min_red, min_green, max_blue } = thresholds.rock else { return None };
        let rock: [&dyn Fn(u8) -> bool; 3] = [&|v| v > min_red, &|v| v > min_green, &|v| v < max_blue];
        let by_channel = std::array::from_fn(|channel| {
            std::array::from_fn(|value| {
                let value = value as u8;
                (rock[channel](value) as u8) << channel
                    | ((value > thresholds.navigable[channel]) as u8) << (channel + 3)
            })
        });
        Some(ColourBits { by_channel })
    }

    /// The bits of pixel `rgb`.
    #[inline]
    pub fn of_pixel(&self, rgb: [u8; 3]) -> u8 {
        self.by_channel[0][rgb[0] as usize] | self.by_channel[1][rgb[1] as usize] | self.by_channel[2][rgb[2] as usize]
    }

    /// The class of a warped pixel in view whose taps all have the bits `all` and together the
    /// bits `any`, when these decide it: a rule holds if all its tests pass on every tap, fails if
    /// one test fails on every tap, and is open otherwise.
    #[inline]
    pub fn class_of_taps(all: u8, any: u8) -> Option<Class> {
        let holds = |rule: u8| {
            if all & rule == rule {
                Some(true)
            } else if any & rule != rule {
                Some(false)
            } else {
                None
            }
        };
        Some(if holds(ROCK_BITS)? {
            Class::Rock
        } else if holds(NAVIGABLE_BITS)? {
            Class::Navigable
        } else {
            Class::Obstacle
        })
    }
}

const HSV_SHIFT: u32 = 12;

/// OpenCV's 8-bit RGB to HSV (H in 0..180), with its fixed-point division tables.
pub fn rgb_to_hsv(rgb: [u8; 3]) -> [u8; 3] {
    let (r, g, b) = (rgb[0] as i32, rgb[1] as i32, rgb[2] as i32);
    let v = r.max(g).max(b);
    let vmin = r.min(g).min(b);
    let diff = v - vmin;
    let saturation_divisor = if v == 0 { 0 } else { (((255 << HSV_SHIFT) as f64) / v as f64).round_ties_even() as i32 };
    let hue_divisor =
        if diff == 0 { 0 } else { (((180 << HSV_SHIFT) as f64) / (6.0 * diff as f64)).round_ties_even() as i32 };
    let s = (diff * saturation_divisor + (1 << (HSV_SHIFT - 1))) >> HSV_SHIFT;
    let h = if v == r {
        g - b
    } else if v == g {
        b - r + 2 * diff
    } else {
        r - g + 4 * diff
    };
    let mut h = (h * hue_divisor + (1 << (HSV_SHIFT - 1))) >> HSV_SHIFT;
    if h < 0 {
        h += 180;
    }
    [h as u8, s as u8, v as u8]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn starter_rules() {
        let t = Thresholds::default();
        assert_eq!(t.classify([220, 200, 190], true), Class::Navigable);
        assert_eq!(t.classify([160, 200, 190], true), Class::Obstacle);
        assert_eq!(t.classify([160, 200, 190], false), Class::Unknown);
        assert_eq!(t.classify([170, 140, 20], true), Class::Rock);
        assert_eq!(t.classify([30, 20, 15], true), Class::Obstacle);
    }

    #[test]
    fn colour_bits_classify_every_colour_as_the_rules_do() {
        let thresholds = Thresholds::default();
        let bits = ColourBits::of(&thresholds).expect("an RGB rule");
        let near_limits = [0, 49, 50, 51, 109, 110, 111, 159, 160, 161, 255];
        let every = 0..=255u8;
        let red_green = every.clone().flat_map(|r| (0..=255u8).map(move |g| (r, g)));
        let colours = red_green
            .flat_map(|(r, g)| near_limits.map(|b| [r, g, b]))
            .chain(every.flat_map(|b| near_limits.into_iter().flat_map(move |r| near_limits.map(|g| [r, g, b]))));
        for rgb in colours {
            let pixel = bits.of_pixel(rgb);
            assert_eq!(ColourBits::class_of_taps(pixel, pixel), Some(thresholds.classify(rgb, true)), "{rgb:?}");
        }
        let hsv = Thresholds { rock: RockRule::Hsv { lower: [0, 0, 0], upper: [40, 255, 255] }, ..thresholds };
        assert_eq!(ColourBits::of(&hsv), None);
    }

    #[test]
    fn hsv_matches_known_colours() {
        assert_eq!(rgb_to_hsv([255, 0, 0]), [0, 255, 255]);
        assert_eq!(rgb_to_hsv([0, 255, 0]), [60, 255, 255]);
        assert_eq!(rgb_to_hsv([0, 0, 255]), [120, 255, 255]);
        assert_eq!(rgb_to_hsv([128, 128, 128]), [0, 0, 128]);
        let yellow = rgb_to_hsv([170, 140, 20]);
        assert!((20..=30).contains(&yellow[0]), "{yellow:?}");
        let hsv =
            Thresholds { rock: RockRule::Hsv { lower: [0, 120, 120], upper: [40, 255, 255] }, ..Thresholds::default() };
        assert_eq!(hsv.classify([170, 140, 20], true), Class::Rock);
        assert_eq!(hsv.classify([220, 200, 190], true), Class::Navigable);
    }
}
