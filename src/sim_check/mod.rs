//! `rover sim-check`: how closely the simulated world resembles the real one. The simulator renders
//! the camera at every logged pose of a recorded dataset; the rover's own perception classifies the
//! real and the simulated image, and their bird's-eye masks are compared pixel by pixel.

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use rover_imaging::{RgbImage, UNITY_JPEG_QUALITY};
use rover_perception::Perception;
use rover_perception::classify::{Class, Thresholds};
use rover_perception::params::PerceptionParams;
use rover_sim::camera::{BodyPose, CameraModel};
use rover_sim::cli::WorldArgs;
use rover_sim::render::{Hit, RenderOptions, Renderer, Surface};
use rover_sim::world::World;
use serde::Serialize;

use crate::dataset::{RecordedFrame, read_log};

/// Options of `rover sim-check`.
#[derive(Debug, Clone, clap::Args)]
pub struct SimCheckArgs {
    /// Dataset folder with robot_log.csv and IMG/ (e.g. ../shared/udacity/test_dataset).
    pub dataset: PathBuf,
    /// The world the dataset was recorded in.
    #[command(flatten)]
    pub world: WorldArgs,
    /// Print one JSON object (summary and frames) instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Write one side-by-side PNG per frame into this folder: real | simulated | masks (white: both
    /// navigable, red: only the real one, blue: only the simulated one, grey: both not navigable).
    #[arg(long, value_name = "DIR")]
    pub images: Option<PathBuf>,
}

/// How one frame's simulated view compares with the real one.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct FrameCheck {
    /// The real image's file name.
    pub image: String,
    /// Intersection over union of the navigable bird's-eye pixels.
    pub nav_iou: f64,
    /// Intersection over union of the obstacle bird's-eye pixels.
    pub obstacle_iou: f64,
    /// Fraction of in-view bird's-eye pixels with the same class.
    pub agreement: f64,
    /// Mean absolute difference of the camera images, per channel, 0..255.
    pub colour_difference: f64,
    /// Navigable bird's-eye pixels in the real image.
    pub real_navigable_px: usize,
    /// Navigable bird's-eye pixels in the simulated image.
    pub sim_navigable_px: usize,
}

/// The whole dataset in figures.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct CheckSummary {
    /// Frames compared.
    pub frames: usize,
    /// Mean navigable IoU.
    pub nav_iou_mean: f64,
    /// Median navigable IoU.
    pub nav_iou_median: f64,
    /// 10th percentile of the navigable IoU.
    pub nav_iou_p10: f64,
    /// Mean obstacle IoU.
    pub obstacle_iou_mean: f64,
    /// Mean pixel agreement.
    pub agreement_mean: f64,
    /// Mean colour difference, 0..255.
    pub colour_difference_mean: f64,
}

/// The report of a check: the summary, the colours by band and every frame.
#[derive(Debug, Clone, Serialize)]
pub struct CheckReport {
    /// The summary.
    pub summary: CheckSummary,
    /// Real and simulated colours where the simulator drew each kind of surface.
    pub bands: Vec<BandColours>,
    /// One entry per frame, in the dataset's order.
    pub frames: Vec<FrameCheck>,
}

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
struct BandTally {
    real: ColourTally,
    sim: ColourTally,
    pixels: Vec<u64>,
}

impl BandTally {
    fn new() -> Self {
        BandTally { real: ColourTally::new(), sim: ColourTally::new(), pixels: vec![0; BANDS.len()] }
    }

    fn add(&mut self, hits: &[Hit], real: &RgbImage, simulated: &RgbImage, thresholds: &Thresholds) {
        for (index, hit) in hits.iter().enumerate() {
            let Some(band) = band_of(hit) else { continue };
            let (x, y) = (index % real.width, index / real.width);
            self.real.add(band, real.pixel(x, y), thresholds);
            self.sim.add(band, simulated.pixel(x, y), thresholds);
            self.pixels[band] += 1;
        }
    }

    fn colours(&self) -> Vec<BandColours> {
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

/// Intersection over union of two masks; two empty masks agree fully.
fn iou(a: impl Iterator<Item = bool>, b: impl Iterator<Item = bool>) -> f64 {
    let (mut both, mut either) = (0usize, 0usize);
    for (a, b) in a.zip(b) {
        both += (a && b) as usize;
        either += (a || b) as usize;
    }
    if either == 0 { 1.0 } else { both as f64 / either as f64 }
}

/// Compares the classes of the real and the simulated image over the in-view bird's-eye pixels.
pub fn compare_classes(real: &[Class], simulated: &[Class]) -> (f64, f64, f64) {
    let in_view = || real.iter().zip(simulated).filter(|(r, _)| **r != Class::Unknown);
    let navigable = |c: &Class| *c == Class::Navigable;
    let nav_iou = iou(in_view().map(|(r, _)| navigable(r)), in_view().map(|(_, s)| navigable(s)));
    let obstacle = |c: &Class| *c == Class::Obstacle;
    let obstacle_iou = iou(in_view().map(|(r, _)| obstacle(r)), in_view().map(|(_, s)| obstacle(s)));
    let total = in_view().count();
    let same = in_view().filter(|(r, s)| r == s).count();
    let agreement = if total == 0 { 1.0 } else { same as f64 / total as f64 };
    (nav_iou, obstacle_iou, agreement)
}

/// Mean absolute difference of two images of the same size, per channel.
pub fn colour_difference(a: &RgbImage, b: &RgbImage) -> f64 {
    let total: u64 = a.data.iter().zip(&b.data).map(|(x, y)| x.abs_diff(*y) as u64).sum();
    total as f64 / a.data.len().max(1) as f64
}

/// The value below which `fraction` of the sorted `values` lie (nearest rank).
fn percentile(sorted: &[f64], fraction: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let rank = ((fraction * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    sorted[rank - 1]
}

fn mean(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, count) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    if count == 0 { 0.0 } else { sum / count as f64 }
}

/// The summary of per-frame checks.
pub fn summarize(frames: &[FrameCheck]) -> CheckSummary {
    let mut nav: Vec<f64> = frames.iter().map(|f| f.nav_iou).collect();
    nav.sort_by(f64::total_cmp);
    CheckSummary {
        frames: frames.len(),
        nav_iou_mean: mean(nav.iter().copied()),
        nav_iou_median: percentile(&nav, 0.5),
        nav_iou_p10: percentile(&nav, 0.1),
        obstacle_iou_mean: mean(frames.iter().map(|f| f.obstacle_iou)),
        agreement_mean: mean(frames.iter().map(|f| f.agreement)),
        colour_difference_mean: mean(frames.iter().map(|f| f.colour_difference)),
    }
}

/// The simulator's body pose for a logged frame (Unity angles in 0..360; the log's roll is
/// positive left side down, the renderer's positive right side down), resting on the ground at
/// `ground_m` above the floor.
pub fn body_pose(frame: &RecordedFrame, ground_m: f64) -> BodyPose {
    let signed = |deg: f64| if deg > 180.0 { deg - 360.0 } else { deg };
    BodyPose {
        x_m: frame.state.x_m,
        y_m: frame.state.y_m,
        yaw_deg: frame.state.yaw_deg,
        pitch_deg: signed(frame.state.pitch_deg),
        roll_deg: -signed(frame.state.roll_deg),
        ground_m,
    }
}

/// Renders, classifies and compares every frame of the dataset in the world of `args`.
pub fn check(args: &SimCheckArgs, perception: &PerceptionParams) -> anyhow::Result<CheckReport> {
    let frames = read_log(&args.dataset)?;
    anyhow::ensure!(!frames.is_empty(), "{} has no frames", args.dataset.display());
    check_world(&frames, &args.world.world(0)?, perception, args.images.as_deref())
}

/// Renders `world` at every pose of `frames`, classifies and compares; writes the side-by-side
/// pictures into `images` if given.
pub fn check_world(
    frames: &[RecordedFrame],
    world: &World,
    perception: &PerceptionParams,
    images: Option<&Path>,
) -> anyhow::Result<CheckReport> {
    let options = RenderOptions { record_hits: true, ..RenderOptions::default() };
    let mut renderer = Renderer::new(world, CameraModel::rover(), options);
    let (mut real_view, _) = perception.pipeline()?;
    let (mut sim_view, _) = perception.pipeline()?;
    let (width, height) = (real_view.calibration().width, real_view.calibration().height);
    if let Some(dir) = images {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    let (mut rendered, mut jpeg) = (RgbImage::default(), Vec::new());
    let thresholds = perception.thresholds()?;
    let mut bands = BandTally::new();
    let mut checks = Vec::with_capacity(frames.len());
    for (index, frame) in frames.iter().enumerate() {
        let real = rover_imaging::decode_jpeg(&frame.jpeg()?, width, height)
            .with_context(|| frame.image.display().to_string())?;
        let pose = body_pose(frame, world.ground_height(frame.state.x_m, frame.state.y_m) as f64);
        renderer.render(world, &[], &pose, &mut rendered);
        rover_imaging::encode_jpeg_into(&rendered, UNITY_JPEG_QUALITY, &mut jpeg)?;
        let simulated = rover_imaging::decode_jpeg(&jpeg, rendered.width, rendered.height)?;
        bands.add(renderer.hits(), &real, &simulated, &thresholds);
        let real_classes = real_view.process_rgb(&real)?.to_vec();
        let sim_classes = sim_view.process_rgb(&simulated)?;
        let (nav_iou, obstacle_iou, agreement) = compare_classes(&real_classes, sim_classes);
        let count = |classes: &[Class]| classes.iter().filter(|c| **c == Class::Navigable).count();
        let name = frame.image.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        if let Some(dir) = images {
            let picture = side_by_side(&real, &simulated, &real_view, &real_classes, sim_classes);
            write_png(&dir.join(Path::new(&name).with_extension("png")), &picture)?;
        }
        checks.push(FrameCheck {
            nav_iou,
            obstacle_iou,
            agreement,
            colour_difference: colour_difference(&real, &simulated),
            real_navigable_px: count(&real_classes),
            sim_navigable_px: count(sim_classes),
            image: name,
        });
        if (index + 1) % 50 == 0 {
            tracing::info!("{} of {} frames checked", index + 1, frames.len());
        }
    }
    Ok(CheckReport { summary: summarize(&checks), bands: bands.colours(), frames: checks })
}

/// Pixels of the side-by-side picture per image pixel.
const PICTURE_SCALE: usize = 2;

/// Real | simulated | the two navigable masks in the bird's-eye view, each enlarged.
fn side_by_side(
    real: &RgbImage,
    simulated: &RgbImage,
    perception: &Perception,
    real_classes: &[Class],
    sim_classes: &[Class],
) -> RgbImage {
    let (width, height) = (real.width, real.height);
    let mut picture = RgbImage::new(3 * width * PICTURE_SCALE, height * PICTURE_SCALE);
    let mut put = |x: usize, y: usize, rgb: [u8; 3]| {
        for dy in 0..PICTURE_SCALE {
            for dx in 0..PICTURE_SCALE {
                picture.set_pixel(x * PICTURE_SCALE + dx, y * PICTURE_SCALE + dy, rgb);
            }
        }
    };
    for y in 0..height {
        for x in 0..width {
            put(x, y, real.pixel(x, y));
            put(width + x, y, simulated.pixel(x, y));
        }
    }
    let entries = &perception.table().entries;
    for ((entry, real), simulated) in entries.iter().zip(real_classes).zip(sim_classes) {
        let colour = match (*real == Class::Navigable, *simulated == Class::Navigable) {
            _ if *real == Class::Unknown => [0, 0, 0],
            (true, true) => [255, 255, 255],
            (true, false) => [230, 40, 40],
            (false, true) => [60, 90, 255],
            (false, false) => [90, 90, 90],
        };
        put(2 * width + entry.x as usize, entry.y as usize, colour);
    }
    picture
}

fn write_png(path: &Path, image: &RgbImage) -> anyhow::Result<()> {
    std::fs::write(path, rover_imaging::encode_png(image)?).with_context(|| format!("cannot write {}", path.display()))
}

/// The report as tables: the summary, then the colours by band.
pub fn table(report: &CheckReport) -> String {
    let summary = &report.summary;
    let mut text = format!(
        "frames                 {:>8}\n\
         nav IoU mean           {:>8.3}\n\
         nav IoU median         {:>8.3}\n\
         nav IoU p10            {:>8.3}\n\
         obstacle IoU mean      {:>8.3}\n\
         pixel agreement mean   {:>8.3}\n\
         colour difference mean {:>8.1}\n",
        summary.frames,
        summary.nav_iou_mean,
        summary.nav_iou_median,
        summary.nav_iou_p10,
        summary.obstacle_iou_mean,
        summary.agreement_mean,
        summary.colour_difference_mean
    );
    text += "\nband                        pixels   real median      sim median       real nav  sim nav\n";
    for band in &report.bands {
        let rgb = |c: [u8; 3]| format!("{:>3} {:>3} {:>3}", c[0], c[1], c[2]);
        text += &format!(
            "{:<26} {:>9}   {}      {}      {:>7.3}  {:>7.3}\n",
            band.band,
            band.pixels,
            rgb(band.real.median_rgb),
            rgb(band.sim.median_rgb),
            band.real.navigable,
            band.sim.navigable
        );
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;
    use rover_msgs::unity::ReportedState;

    #[test]
    fn iou_counts_only_in_view_pixels_and_empty_masks_agree() {
        use Class::*;
        let real = [Navigable, Navigable, Obstacle, Obstacle, Unknown];
        let simulated = [Navigable, Obstacle, Obstacle, Obstacle, Navigable];
        let (nav, obstacle, agreement) = compare_classes(&real, &simulated);
        assert_eq!(nav, 0.5);
        assert!((obstacle - 2.0 / 3.0).abs() < 1e-12);
        assert_eq!(agreement, 0.75);
        assert_eq!(compare_classes(&[Obstacle], &[Obstacle]).0, 1.0, "no navigable pixel in either");
    }

    #[test]
    fn the_summary_has_the_mean_median_and_tenth_percentile() {
        let frame = |nav_iou: f64| FrameCheck {
            image: String::new(),
            nav_iou,
            obstacle_iou: 0.5,
            agreement: 0.9,
            colour_difference: 10.0,
            real_navigable_px: 0,
            sim_navigable_px: 0,
        };
        let frames: Vec<FrameCheck> = (1..=10).map(|i| frame(i as f64 / 10.0)).collect();
        let summary = summarize(&frames);
        assert!((summary.nav_iou_mean - 0.55).abs() < 1e-12);
        assert_eq!((summary.nav_iou_median, summary.nav_iou_p10), (0.5, 0.1));
        assert!((summary.agreement_mean - 0.9).abs() < 1e-12);
    }

    #[test]
    fn logged_angles_become_signed_body_angles() {
        let state =
            ReportedState { x_m: 1.0, y_m: 2.0, pitch_deg: 359.5, yaw_deg: 30.0, roll_deg: 2.0, ..Default::default() };
        let frame = RecordedFrame { image: PathBuf::new(), state };
        let pose = body_pose(&frame, 0.1);
        assert!((pose.pitch_deg + 0.5).abs() < 1e-9 && (pose.roll_deg + 2.0).abs() < 1e-9);
        assert_eq!((pose.x_m, pose.y_m, pose.yaw_deg, pose.ground_m), (1.0, 2.0, 30.0, 0.1));
    }
}
