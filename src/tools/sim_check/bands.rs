//! Colours by kind of surface: where the simulator drew each kind (sky, floor by distance, wall
//! foot by height, walls and rocks by how they face the sun), the real and the simulated colours
//! of those pixels, so that a person sees which surface looks wrong.

use rover_imaging::RgbImage;
use rover_perception::classify::Thresholds;
use rover_sim::render::{Hit, Surface};
use serde::Serialize;

/// The kinds of simulated surface in which colours are compared, with their names.
pub const BANDS: [&str; 16] = [
    "sky",
    "floor 0-1.5 m away",
    "floor 1.5-3 m away",
    "floor 3-6 m away",
    "floor 6-10 m away",
    "floor 10+ m away",
    "floor fading into rock",
    "wall foot 0-10 cm high",
    "wall foot 10-30 cm high",
    "wall 0.3-1.5 m high",
    "wall in shade",
    "wall half lit",
    "wall in sun",
    "boulder in shade",
    "boulder half lit",
    "boulder in sun",
];

/// The band of a simulated pixel, an index into [`BANDS`] (none for samples).
pub fn band_of(hit: &Hit) -> Option<usize> {
    let by_depth = |depth: f32| [1.5, 3.0, 6.0, 10.0].iter().take_while(|&&limit| depth >= limit).count();
    let by_sun = |sun: f32| {
        if sun < 0.35 {
            0
        } else if sun < 0.7 {
            1
        } else {
            2
        }
    };
    match hit.surface {
        Surface::Sky => Some(0),
        Surface::Sample => None,
        Surface::Boulder => Some(13 + by_sun(hit.sun)),
        Surface::Floor | Surface::Rock if hit.height_m < 0.02 && hit.rock < 0.05 => Some(1 + by_depth(hit.depth_m)),
        Surface::Floor | Surface::Rock if hit.height_m < 0.02 => Some(6),
        Surface::Floor | Surface::Rock if hit.height_m < 0.1 => Some(7),
        Surface::Floor | Surface::Rock if hit.height_m < 0.3 => Some(8),
        Surface::Floor | Surface::Rock if hit.height_m < 1.5 => Some(9),
        Surface::Floor | Surface::Rock => Some(10 + by_sun(hit.sun)),
    }
}

/// Real and simulated colours of one band.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct BandColours {
    /// The band's name.
    pub band: String,
    /// Pixels in the band over all frames.
    pub pixels: u64,
    /// The real pixels.
    pub real: ColourSummary,
    /// The simulated pixels.
    pub sim: ColourSummary,
}

/// The colours of one band in one kind of image.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct ColourSummary {
    /// Median colour.
    pub median_rgb: [u8; 3],
    /// Fraction of the pixels that the perception's colour rule calls navigable.
    pub navigable: f64,
}

/// Colour histograms of the bands of one kind of image (real or simulated), filled frame by frame.
struct ColourTally {
    histograms: Vec<[[u64; 256]; 3]>,
    navigable: Vec<u64>,
}

impl ColourTally {
    fn new() -> Self {
        ColourTally { histograms: vec![[[0; 256]; 3]; BANDS.len()], navigable: vec![0; BANDS.len()] }
    }

    fn add(&mut self, band: usize, rgb: [u8; 3], thresholds: &Thresholds) {
        for (k, &channel) in rgb.iter().enumerate() {
            self.histograms[band][k][channel as usize] += 1;
        }
        self.navigable[band] += thresholds.is_navigable(rgb) as u64;
    }

    /// The summary of band `band`, which holds `pixels` pixels.
    fn summary(&self, band: usize, pixels: u64) -> ColourSummary {
        let median = [0, 1, 2].map(|k| {
            let mut running = 0;
            self.histograms[band][k]
                .iter()
                .position(|&n| {
                    running += n;
                    running * 2 >= pixels
                })
                .unwrap_or(0) as u8
        });
        ColourSummary { median_rgb: median, navigable: self.navigable[band] as f64 / pixels as f64 }
    }
}

/// The colours of the bands in the real and the simulated images.
pub(super) struct BandTally {
    real: ColourTally,
    sim: ColourTally,
    pixels: Vec<u64>,
}

impl BandTally {
    pub(super) fn new() -> Self {
        BandTally { real: ColourTally::new(), sim: ColourTally::new(), pixels: vec![0; BANDS.len()] }
    }

    pub(super) fn add(&mut self, hits: &[Hit], real: &RgbImage, simulated: &RgbImage, thresholds: &Thresholds) {
        for (index, hit) in hits.iter().enumerate() {
            let Some(band) = band_of(hit) else { continue };
            let (x, y) = (index % real.width, index / real.width);
            self.real.add(band, real.pixel(x, y), thresholds);
            self.sim.add(band, simulated.pixel(x, y), thresholds);
            self.pixels[band] += 1;
        }
    }

    pub(super) fn colours(&self) -> Vec<BandColours> {
        (0..BANDS.len())
            .filter(|&b| self.pixels[b] > 0)
            .map(|b| BandColours {
                band: BANDS[b].to_string(),
                pixels: self.pixels[b],
                real: self.real.summary(b, self.pixels[b]),
                sim: self.sim.summary(b, self.pixels[b]),
            })
            .collect()
    }
}
