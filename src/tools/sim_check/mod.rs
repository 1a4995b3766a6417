//! `rover sim-check`: how closely the simulated world resembles the real one. The simulator renders
//! the camera at every logged pose of recorded datasets; the rover's own perception classifies the
//! real and the simulated image, and their bird's-eye masks are compared pixel by pixel, frame by
//! frame, summed up per dataset, per 8 m square of the map ([`squares`]) and per kind of surface
//! ([`bands`]).

mod bands;
pub mod squares;

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use rover_bridge::convert::{rep103_roll_rad, wrapped_rad};
use rover_imaging::{RgbImage, UNITY_JPEG_QUALITY};
use rover_perception::Perception;
use rover_perception::classify::Class;
use rover_perception::params::PerceptionParams;
use rover_sim::camera::{BodyPose, CameraModel};
use rover_sim::cli::WorldArgs;
use rover_sim::render::{RenderOptions, Renderer};
use rover_sim::world::World;
use serde::Serialize;

use self::bands::BandTally;
pub use self::bands::{BANDS, BandColours, ColourSummary, band_of};
use self::squares::{SquareSummary, is_held_out, square_of, square_summaries};
use crate::tools::dataset::{ReadReport, RecordedFrame, read_log};

/// Options of `rover sim-check`.
#[derive(Debug, Clone, clap::Args)]
pub struct SimCheckArgs {
    /// Recorded datasets: folders with robot_log.csv and IMG/ (e.g. ../shared/udacity/test_dataset),
    /// or the logs themselves, as the simulator wrote them on any machine.
    #[arg(required = true, num_args = 1.., value_name = "DATASET")]
    pub datasets: Vec<PathBuf>,
    /// The world the datasets were recorded in.
    #[command(flatten)]
    pub world: WorldArgs,
    /// Print one JSON object (summaries, squares, colours and every frame) instead of tables.
    #[arg(long)]
    pub json: bool,
    /// Write one side-by-side PNG per frame into this folder (a subfolder per dataset when there are
    /// several): real | simulated | masks (white: both navigable, red: only the real one, blue:
    /// only the simulated one, grey: both not navigable).
    #[arg(long, value_name = "DIR")]
    pub images: Option<PathBuf>,
    /// Write a picture of the map, each 8 m square with frames coloured by their mean navigable
    /// IoU, to this PNG.
    #[arg(long, value_name = "PNG")]
    pub squares_picture: Option<PathBuf>,
}

/// How one frame's simulated view compares with the real one.
#[derive(Debug, Clone, Serialize, PartialEq, Default)]
pub struct FrameCheck {
    /// The real image's file name.
    pub image: String,
    /// Where it was taken: x, metres.
    pub x_m: f64,
    /// y, metres.
    pub y_m: f64,
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

/// The figures of a set of frames: all of them, and split into those taken in the squares the
/// look was calibrated on and in those kept aside.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct SplitSummary {
    /// Every frame.
    pub all: CheckSummary,
    /// The frames of the squares used to calibrate the look.
    pub calibration: CheckSummary,
    /// The frames of the squares kept aside ([`squares::is_held_out`]).
    pub held_out: CheckSummary,
}

impl SplitSummary {
    fn of(frames: &[FrameCheck]) -> Self {
        let held_out = |f: &&FrameCheck| is_held_out(square_of(f.x_m, f.y_m));
        let (aside, calibration): (Vec<FrameCheck>, Vec<FrameCheck>) =
            frames.iter().cloned().partition(|f| held_out(&f));
        SplitSummary { all: summarize(frames), calibration: summarize(&calibration), held_out: summarize(&aside) }
    }
}

/// The check of one dataset.
#[derive(Debug, Clone, Serialize)]
pub struct DatasetCheck {
    /// The dataset as given.
    pub dataset: PathBuf,
    /// How its log was read.
    pub read: ReadReport,
    /// Its figures.
    pub summary: SplitSummary,
    /// Its frames by 8 m square.
    pub squares: Vec<SquareSummary>,
    /// One entry per frame, in the log's order.
    pub frames: Vec<FrameCheck>,
}

/// The report of a check: the figures of all datasets together, by square and by kind of
/// surface, and each dataset's.
#[derive(Debug, Clone, Serialize)]
pub struct CheckReport {
    /// All frames of all datasets.
    pub summary: SplitSummary,
    /// All frames by 8 m square.
    pub squares: Vec<SquareSummary>,
    /// Real and simulated colours where the simulator drew each kind of surface.
    pub bands: Vec<BandColours>,
    /// Each dataset, in the order given.
    pub datasets: Vec<DatasetCheck>,
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
pub(crate) fn percentile(sorted: &[f64], fraction: f64) -> f64 {
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
    BodyPose {
        x_m: frame.state.x_m,
        y_m: frame.state.y_m,
        yaw_deg: frame.state.yaw_deg,
        pitch_deg: wrapped_rad(frame.state.pitch_deg).to_degrees(),
        roll_deg: rep103_roll_rad(frame.state.roll_deg).to_degrees(),
        ground_m,
    }
}

/// Renders, classifies and compares every frame of the datasets in the world of `args`, and
/// writes the pictures asked for.
pub fn check(args: &SimCheckArgs, perception: &PerceptionParams) -> anyhow::Result<CheckReport> {
    let recordings = args.datasets.iter().map(|dataset| read_log(dataset)).collect::<anyhow::Result<Vec<_>>>()?;
    if let Some(empty) = recordings.iter().find(|r| r.frames.is_empty()) {
        anyhow::bail!("{} has no frames", empty.report.log.display());
    }
    let world = args.world.world(0)?;
    let mut checker = Checker::new(&world, perception)?;
    let mut datasets = Vec::with_capacity(args.datasets.len());
    for (index, (dataset, recording)) in args.datasets.iter().zip(recordings).enumerate() {
        let images = args.images.as_ref().map(|dir| match args.datasets.len() {
            1 => dir.clone(),
            _ => dir.join(format!("{}-{}", index + 1, dataset_name(dataset))),
        });
        let frames = checker.check_frames(&recording.frames, images.as_deref())?;
        let (summary, squares) = (SplitSummary::of(&frames), square_summaries(&frames));
        datasets.push(DatasetCheck { dataset: dataset.clone(), read: recording.report, summary, squares, frames });
    }
    let all: Vec<FrameCheck> = datasets.iter().flat_map(|d| d.frames.iter().cloned()).collect();
    let report = CheckReport {
        summary: SplitSummary::of(&all),
        squares: square_summaries(&all),
        bands: checker.bands.colours(),
        datasets,
    };
    if let Some(path) = &args.squares_picture {
        write_png(path, &squares::picture(&report.squares, world.ground_truth()))?;
    }
    Ok(report)
}

/// A short name of a dataset for folder names: its folder's name.
fn dataset_name(dataset: &Path) -> String {
    let folder = if dataset.is_dir() { Some(dataset) } else { dataset.parent() };
    folder.and_then(Path::file_name).map_or_else(|| "dataset".into(), |n| n.to_string_lossy().into_owned())
}

/// Renders `world` at every pose of `frames`, classifies and compares; writes the side-by-side
/// pictures into `images` if given.
pub fn check_world(
    frames: &[RecordedFrame],
    world: &World,
    perception: &PerceptionParams,
    images: Option<&Path>,
) -> anyhow::Result<(SplitSummary, Vec<FrameCheck>)> {
    let frames = Checker::new(world, perception)?.check_frames(frames, images)?;
    Ok((SplitSummary::of(&frames), frames))
}

/// What checking frames in one world keeps from frame to frame: the renderer, the two
/// perception pipelines and the colour tallies.
struct Checker<'w> {
    world: &'w World,
    renderer: Renderer,
    real_view: Perception,
    sim_view: Perception,
    thresholds: rover_perception::classify::Thresholds,
    bands: BandTally,
    rendered: RgbImage,
    jpeg: Vec<u8>,
}

impl<'w> Checker<'w> {
    fn new(world: &'w World, perception: &PerceptionParams) -> anyhow::Result<Self> {
        let options = RenderOptions { record_hits: true, ..RenderOptions::default() };
        Ok(Checker {
            world,
            renderer: Renderer::new(world, CameraModel::rover(), options),
            real_view: perception.pipeline()?.0,
            sim_view: perception.pipeline()?.0,
            thresholds: perception.thresholds()?,
            bands: BandTally::new(),
            rendered: RgbImage::default(),
            jpeg: Vec::new(),
        })
    }

    /// Checks every frame, with a progress line every [`PROGRESS_EVERY`].
    fn check_frames(&mut self, frames: &[RecordedFrame], images: Option<&Path>) -> anyhow::Result<Vec<FrameCheck>> {
        if let Some(dir) = images {
            std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        }
        let mut progress = std::time::Instant::now();
        let mut checks = Vec::with_capacity(frames.len());
        for (index, frame) in frames.iter().enumerate() {
            checks.push(self.check_frame(frame, images)?);
            if progress.elapsed() >= PROGRESS_EVERY {
                tracing::info!("{} of {} frames checked", index + 1, frames.len());
                progress = std::time::Instant::now();
            }
        }
        Ok(checks)
    }

    fn check_frame(&mut self, frame: &RecordedFrame, images: Option<&Path>) -> anyhow::Result<FrameCheck> {
        let (width, height) = (self.real_view.calibration().width, self.real_view.calibration().height);
        let real = rover_imaging::decode_jpeg(&frame.jpeg()?, width, height)
            .with_context(|| frame.image.display().to_string())?;
        let world = self.world;
        let pose = body_pose(frame, world.ground_height(frame.state.x_m, frame.state.y_m) as f64);
        self.renderer.render(world, &[], &pose, &mut self.rendered);
        rover_imaging::encode_jpeg_into(&self.rendered, UNITY_JPEG_QUALITY, &mut self.jpeg)?;
        let simulated = rover_imaging::decode_jpeg(&self.jpeg, self.rendered.width, self.rendered.height)?;
        self.bands.add(self.renderer.hits(), &real, &simulated, &self.thresholds);
        let real_classes = self.real_view.process_rgb(&real)?.to_vec();
        let sim_classes = self.sim_view.process_rgb(&simulated)?;
        let (nav_iou, obstacle_iou, agreement) = compare_classes(&real_classes, sim_classes);
        let count = |classes: &[Class]| classes.iter().filter(|c| **c == Class::Navigable).count();
        let name = frame.image.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        if let Some(dir) = images {
            let picture = side_by_side(&real, &simulated, &self.real_view, &real_classes, sim_classes);
            write_png(&dir.join(Path::new(&name).with_extension("png")), &picture)?;
        }
        Ok(FrameCheck {
            x_m: frame.state.x_m,
            y_m: frame.state.y_m,
            nav_iou,
            obstacle_iou,
            agreement,
            colour_difference: colour_difference(&real, &simulated),
            real_navigable_px: count(&real_classes),
            sim_navigable_px: count(sim_classes),
            image: name,
        })
    }
}

/// A progress line at most this often.
const PROGRESS_EVERY: std::time::Duration = std::time::Duration::from_secs(2);

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

/// Squares listed as the worst in the table.
const WORST_SQUARES: usize = 8;

/// The report as tables: each dataset's figures (all its frames, those of the squares the look
/// was calibrated on and of those kept aside), all datasets together, the worst squares, then the
/// colours by band.
pub fn table(report: &CheckReport) -> String {
    let mut text = format!(
        "{:<34} {:>6} {:>12} {:>7} {:>6} {:>13} {:>10} {:>12}\n",
        "dataset", "frames", "nav IoU mean", "median", "p10", "obstacle IoU", "agreement", "colour diff"
    );
    let row = |name: &str, s: &CheckSummary| {
        format!(
            "{name:<34} {:>6} {:>12.3} {:>7.3} {:>6.3} {:>13.3} {:>10.3} {:>12.1}\n",
            s.frames,
            s.nav_iou_mean,
            s.nav_iou_median,
            s.nav_iou_p10,
            s.obstacle_iou_mean,
            s.agreement_mean,
            s.colour_difference_mean
        )
    };
    let split = |name: &str, split: &SplitSummary| {
        row(name, &split.all)
            + &row("  squares used for calibration", &split.calibration)
            + &row("  squares kept aside", &split.held_out)
    };
    for dataset in &report.datasets {
        text += &split(&dataset_name(&dataset.dataset), &dataset.summary);
    }
    if report.datasets.len() > 1 {
        text += &split("all datasets", &report.summary);
    }
    let mut worst: Vec<&SquareSummary> = report.squares.iter().collect();
    worst.sort_by(|a, b| a.nav_iou_mean.total_cmp(&b.nav_iou_mean));
    text += "\nworst 8 m squares        frames  nav IoU mean    p10\n";
    for square in worst.iter().take(WORST_SQUARES) {
        let aside = if square.held_out { "  (kept aside)" } else { "" };
        text += &format!(
            "x {:>3}-{:<3} y {:>3}-{:<3}     {:>6} {:>13.3} {:>6.3}{aside}\n",
            square.x_m,
            square.x_m + squares::SQUARE_M,
            square.y_m,
            square.y_m + squares::SQUARE_M,
            square.frames,
            square.nav_iou_mean,
            square.nav_iou_p10
        );
    }
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
            nav_iou,
            obstacle_iou: 0.5,
            agreement: 0.9,
            colour_difference: 10.0,
            ..FrameCheck::default()
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
