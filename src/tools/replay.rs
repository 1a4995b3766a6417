//! `rover replay`: a recorded Udacity dataset through perception and mapping, scored the Udacity way.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use rover_bridge::convert::{rep103_roll_rad, wrapped_rad};
use rover_mapping::map::{ScanGrid, Update, WorldMap};
use rover_mapping::params::MappingParams;
use rover_mapping::projection::Pose;
use rover_mapping::score::{ground_truth_from_png, occupancy_counts, occupancy_scores};
use rover_perception::params::PerceptionParams;
use rover_perception::scan::ScanGeometry;
use serde::Serialize;

use crate::tools::dataset::{RecordedFrame, read_log};

/// Options of `rover replay`.
#[derive(Debug, Clone, clap::Args)]
pub struct ReplayArgs {
    /// Recorded dataset: a folder with robot_log.csv and IMG/ (e.g. ../shared/udacity/test_dataset),
    /// or the log itself, as the simulator wrote it on any machine.
    pub dataset: PathBuf,
    /// Ground-truth map for the scores (200x200 PNG, navigable > 0).
    #[arg(long, value_name = "MAP_PNG")]
    pub ground_truth: Option<PathBuf>,
    /// Where the floor really is, for a second fidelity against it: a PNG like the ground truth
    /// (e.g. ../shared/udacity-world/floor_flat.png, which also holds the floor at the foot of
    /// the walls that map_bw.png leaves out).
    #[arg(long, value_name = "FLOOR_PNG")]
    pub floor: Option<PathBuf>,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Publish the frames over DDS as the bridge would and score the map of the running
    /// perception and mapping nodes (start mapping with -p ground_truth_png:=MAP for the scores).
    #[arg(long, conflicts_with_all = ["ground_truth", "floor"])]
    pub via_dds: bool,
}

/// What a replay measured.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ReplayReport {
    /// Frames in the dataset.
    pub frames: usize,
    /// Frames the map used (unknown over DDS: the mapping node does not publish its count).
    pub frames_mapped: Option<usize>,
    /// Frames skipped for pitch or roll (unknown over DDS).
    pub frames_skipped_tilt: Option<usize>,
    /// Frames whose image could not be used (over DDS: frames without a terrain scan).
    pub frames_rejected: usize,
    /// Udacity mapped %, if a ground truth was given.
    pub mapped_pct: Option<f64>,
    /// Udacity fidelity %, if a ground truth was given.
    pub fidelity_pct: Option<f64>,
    /// Fidelity % against the floor image, if one was given.
    pub floor_fidelity_pct: Option<f64>,
    /// Distinct rocks located.
    pub rocks_located: usize,
    /// Navigable cells of the map.
    pub navigable_cells: usize,
    /// Median time of perception per frame (JPEG decode, table, classes, scan grid), ms.
    pub perception_ms_median: f64,
    /// Median time of a map update per frame, ms (not timed over DDS).
    pub mapping_ms_median: Option<f64>,
}

fn median_ms(mut samples: Vec<Duration>) -> f64 {
    if samples.is_empty() {
        return 0.0;
    }
    samples.sort();
    samples[samples.len() / 2].as_secs_f64() * 1000.0
}

/// The bird's-eye grid of `geometry` holding the class codes `cells`, as the map takes it.
pub fn scan_grid<'a>(geometry: &ScanGeometry, cells: &'a [u8]) -> ScanGrid<'a> {
    ScanGrid {
        rows: geometry.rows,
        cols: geometry.cols,
        resolution_m: geometry.resolution_m,
        origin_x_m: geometry.origin_x_m,
        origin_y_m: geometry.origin_y_m,
        cells,
    }
}

/// The pose of a recorded frame in REP-103 angles, converted like the bridge converts telemetry.
pub fn frame_pose(frame: &RecordedFrame) -> Pose {
    Pose {
        x_m: frame.state.x_m,
        y_m: frame.state.y_m,
        yaw_rad: wrapped_rad(frame.state.yaw_deg),
        pitch_rad: wrapped_rad(frame.state.pitch_deg),
        roll_rad: rep103_roll_rad(frame.state.roll_deg),
    }
}

/// Replays `frames` through the perception and mapping libraries.
pub fn replay_frames(
    frames: &[RecordedFrame],
    perception: &PerceptionParams,
    mapping: &MappingParams,
    ground_truth: Option<&[bool]>,
    floor: Option<&[bool]>,
) -> anyhow::Result<(ReplayReport, WorldMap)> {
    let (mut pipeline, geometry) = perception.pipeline()?;
    let mut map = WorldMap::new(mapping.map_config());
    let (mut perception_times, mut mapping_times) = (Vec::new(), Vec::new());
    let (mut mapped, mut skipped, mut rejected) = (0, 0, 0);
    let mut cells = Vec::new();
    for frame in frames {
        let jpeg = frame.jpeg()?;
        let started = Instant::now();
        let classes = match pipeline.process_jpeg(&jpeg) {
            Ok(classes) => classes,
            Err(e) => {
                tracing::warn!("{}: {e}", frame.image.display());
                rejected += 1;
                continue;
            }
        };
        geometry.fill(classes, &mut cells);
        perception_times.push(started.elapsed());
        let started = Instant::now();
        let update = map.update(&scan_grid(&geometry, &cells), frame_pose(frame));
        mapping_times.push(started.elapsed());
        match update {
            Update::Used(_) => mapped += 1,
            Update::SkippedTilt => skipped += 1,
            Update::Malformed => rejected += 1,
        }
    }
    let occupancy = map.occupancy();
    let scores = ground_truth.map(|truth| occupancy_scores(&occupancy, truth));
    let report = ReplayReport {
        frames: frames.len(),
        frames_mapped: Some(mapped),
        frames_skipped_tilt: Some(skipped),
        frames_rejected: rejected,
        mapped_pct: scores.map(|s| s.mapped_pct),
        fidelity_pct: scores.map(|s| s.fidelity_pct),
        floor_fidelity_pct: floor.map(|floor| occupancy_scores(&occupancy, floor).fidelity_pct),
        rocks_located: map.rocks(&occupancy, mapping.rock_merge_m).len(),
        navigable_cells: occupancy_counts(&occupancy).0,
        perception_ms_median: median_ms(perception_times),
        mapping_ms_median: Some(median_ms(mapping_times)),
    };
    Ok((report, map))
}

/// Reads a ground-truth (or floor) PNG.
pub fn read_ground_truth(path: &Path) -> anyhow::Result<Vec<bool>> {
    let png = rover_files::read_at_most(path, rover_imaging::MAX_IMAGE_FILE_BYTES)?;
    ground_truth_from_png(&png).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
}

/// Runs `rover replay` offline (the libraries in this process) and prints the report.
pub fn run(args: &ReplayArgs, perception: &PerceptionParams, mapping: &MappingParams) -> anyhow::Result<ReplayReport> {
    let frames = read_log(&args.dataset)?.frames;
    let truth = args.ground_truth.as_deref().map(read_ground_truth).transpose()?;
    let floor = args.floor.as_deref().map(read_ground_truth).transpose()?;
    let (report, _) = replay_frames(&frames, perception, mapping, truth.as_deref(), floor.as_deref())?;
    print_report(args, &report)?;
    Ok(report)
}

/// Runs `rover replay --via-dds` against the running nodes and prints the report.
pub async fn run_via_dds(args: &ReplayArgs, runtime: &rover_runtime::Runtime) -> anyhow::Result<ReplayReport> {
    let frames = read_log(&args.dataset)?.frames;
    let report = crate::tools::replay_dds::replay_over_dds(&frames, runtime).await?;
    print_report(args, &report)?;
    Ok(report)
}

fn print_report(args: &ReplayArgs, report: &ReplayReport) -> anyhow::Result<()> {
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print_table(report);
    }
    Ok(())
}

fn print_table(report: &ReplayReport) {
    let percent = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.1} %"));
    let count = |v: Option<usize>| v.map_or("-".to_string(), |v| v.to_string());
    println!(
        "frames                {:>8}  (mapped {}, skipped for tilt {}, rejected {})",
        report.frames,
        count(report.frames_mapped),
        count(report.frames_skipped_tilt),
        report.frames_rejected
    );
    println!("mapped                {:>8}", percent(report.mapped_pct));
    println!("fidelity              {:>8}", percent(report.fidelity_pct));
    println!("fidelity on the floor {:>8}", percent(report.floor_fidelity_pct));
    println!("rocks located         {:>8}", report.rocks_located);
    println!("navigable cells       {:>8}", report.navigable_cells);
    println!(
        "perception per frame  {:>6.3} ms (median; over DDS: camera out to terrain scan back)",
        report.perception_ms_median
    );
    let mapping_ms = report.mapping_ms_median.map_or("-".to_string(), |ms| format!("{ms:.3} ms"));
    println!("map update per frame  {mapping_ms:>9} (median)");
}
