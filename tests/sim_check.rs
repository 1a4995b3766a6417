//! The simulated world against the real one, with `rover sim-check` as users run it: the simulator
//! renders every logged pose of recorded Unity frames in the surveyed world, the rover's
//! perception classifies both images, and the bird's-eye masks and the colours by kind of surface
//! must agree, also on frames taken where the look was not calibrated.

mod support;

use std::path::{Path, PathBuf};

use support::{number, rover, shared_dir, surveyed_world_args, test_dataset_dir};

fn sim_check(dataset: &Path, extra: &[&str]) -> serde_json::Value {
    sim_check_datasets(&[dataset], extra)
}

fn sim_check_datasets(datasets: &[&Path], extra: &[&str]) -> serde_json::Value {
    let output = std::process::Command::new(rover())
        .arg("sim-check")
        .args(datasets)
        .args(surveyed_world_args())
        .arg("--json")
        .args(extra)
        .output()
        .expect("run rover sim-check");
    assert!(output.status.success(), "rover sim-check failed: {}", String::from_utf8_lossy(&output.stderr));
    serde_json::from_slice(&output.stdout).expect("one JSON object")
}

#[test]
fn the_simulated_world_agrees_with_the_283_real_frames() {
    let report = sim_check(&PathBuf::from(test_dataset_dir()), &[]);
    let summary = &report["summary"]["all"];
    eprintln!("{summary}");
    assert_eq!(summary["frames"], 283);
    assert!(number(summary, "nav_iou_mean") >= 0.80, "navigable IoU mean {summary}");
    assert!(number(summary, "nav_iou_p10") >= 0.50, "navigable IoU 10th percentile {summary}");
    assert!(number(summary, "nav_iou_median") >= 0.80, "navigable IoU median {summary}");
    assert!(number(summary, "obstacle_iou_mean") >= 0.85, "obstacle IoU mean {summary}");
    assert!(number(summary, "agreement_mean") >= 0.90, "pixel agreement {summary}");
    assert!(number(summary, "colour_difference_mean") <= 25.0, "colour difference {summary}");
    assert_eq!(report["datasets"][0]["frames"].as_array().map(Vec::len), Some(283));
    assert_eq!(report["datasets"][0]["read"]["frames"], 283);
}

#[test]
fn each_kind_of_surface_has_the_colour_the_real_camera_sees_there() {
    let report = sim_check(&PathBuf::from(test_dataset_dir()), &[]);
    let bands = report["bands"].as_array().expect("bands");
    let band = |name: &str| bands.iter().find(|b| b["band"] == name).unwrap_or_else(|| panic!("band {name}"));
    let median = |b: &serde_json::Value, image: &str| -> Vec<f64> {
        b[image]["median_rgb"].as_array().unwrap().iter().map(|c| c.as_f64().unwrap()).collect()
    };
    for (name, tolerance) in [
        ("sky", 6.0),
        ("floor 0-1.5 m away", 15.0),
        ("floor 1.5-3 m away", 15.0),
        ("floor 3-6 m away", 15.0),
        ("wall foot 0-10 cm high", 15.0),
        ("wall foot 10-30 cm high", 15.0),
        ("wall in shade", 12.0),
        ("wall half lit", 12.0),
        ("wall in sun", 12.0),
    ] {
        let b = band(name);
        let (real, sim) = (median(b, "real"), median(b, "sim"));
        eprintln!("{name}: real {real:?}, simulated {sim:?}, {} px", b["pixels"]);
        for k in 0..3 {
            assert!((real[k] - sim[k]).abs() <= tolerance, "{name}: real {real:?} against simulated {sim:?}");
        }
    }
    for name in ["floor 0-1.5 m away", "floor 1.5-3 m away"] {
        let b = band(name);
        let (real, sim) = (number(&b["real"], "navigable"), number(&b["sim"], "navigable"));
        assert!(real > 0.9 && sim > 0.9, "{name}: the near floor reads as navigable (real {real}, simulated {sim})");
    }
    for name in ["wall foot 10-30 cm high", "wall in sun", "boulder in sun"] {
        let b = band(name);
        assert!(number(&b["sim"], "navigable") < 0.01, "{name} never reads as navigable");
    }
}

/// A dataset in a temporary folder named `name`: the log of `source` with its header and every
/// `every`-th row of its first `frames`, byte for byte (line ends too), and its images linked.
fn dataset_part(source: &Path, name: &str, frames: usize, every: usize) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rover-sim-check-{name}-{}", std::process::id()));
    std::fs::create_dir_all(dir.join("IMG")).unwrap();
    let log = std::fs::read_to_string(source.join("robot_log.csv")).unwrap();
    let mut lines = log.split_inclusive('\n');
    let header = lines.next().unwrap();
    let kept: Vec<&str> = lines.take(frames).step_by(every).collect();
    std::fs::write(dir.join("robot_log.csv"), std::iter::once(header).chain(kept.iter().copied()).collect::<String>())
        .unwrap();
    for line in kept {
        let name = line.split(';').next().unwrap().rsplit(['/', '\\']).next().unwrap();
        let link = dir.join("IMG").join(name);
        if !link.exists() {
            std::os::unix::fs::symlink(source.join("IMG").join(name), link).unwrap();
        }
    }
    dir
}

/// A dataset of the first frames of the 283 real ones.
fn small_dataset(frames: usize) -> PathBuf {
    dataset_part(Path::new(&test_dataset_dir()), "small", frames, 1)
}

/// The long recording over most of the map, as the simulator wrote it on a Windows machine.
fn long_recording() -> PathBuf {
    shared_dir().join("udacity/recordings/tzyhpcom-2018-03-03")
}

#[test]
fn a_long_recording_made_elsewhere_is_read_as_it_is_and_checked_square_by_square() {
    let recording = dataset_part(&long_recording(), "long", usize::MAX, 10);
    let log = std::fs::read_to_string(recording.join("robot_log.csv")).unwrap();
    assert!(log.contains("\r\n") && log.contains("C:\\Users\\"), "the part keeps Windows paths and line ends");
    let picture = recording.join("squares.png");
    let test_dataset = PathBuf::from(test_dataset_dir());
    let datasets = [recording.as_path(), test_dataset.as_path()];
    let report = sim_check_datasets(&datasets, &["--squares-picture", &picture.display().to_string()]);
    let long = &report["datasets"][0];
    assert_eq!(long["read"]["frames"], 431);
    assert_eq!(long["read"]["skipped"].as_array().map(Vec::len), Some(0));
    assert_eq!(report["datasets"][1]["summary"]["all"]["frames"], 283);
    assert_eq!(report["summary"]["all"]["frames"], 431 + 283);
    let (calibration, aside) = (&long["summary"]["calibration"], &long["summary"]["held_out"]);
    eprintln!("calibration squares {calibration}\nkept aside {aside}");
    assert!(number(calibration, "frames") > 200.0 && number(aside, "frames") > 100.0);
    assert!(number(&long["summary"]["all"], "nav_iou_mean") >= 0.68, "{}", long["summary"]["all"]);
    assert!(number(&long["summary"]["all"], "nav_iou_p10") >= 0.42, "{}", long["summary"]["all"]);
    let generalises = number(aside, "nav_iou_mean") >= number(calibration, "nav_iou_mean") - 0.03;
    assert!(generalises, "the squares kept aside agree almost as well as those calibrated on");
    let squares = long["squares"].as_array().unwrap();
    assert!(squares.len() >= 50, "the recording covers most of the map's squares: {}", squares.len());
    let image = rover_imaging::decode_png(&std::fs::read(&picture).unwrap()).unwrap();
    assert_eq!(image.width, 800, "the map at 4 pixels a metre");
    std::fs::remove_dir_all(recording).unwrap();
}

#[test]
fn images_show_real_simulated_and_masks_side_by_side() {
    let dataset = small_dataset(3);
    let images = dataset.join("pictures");
    let report = sim_check(&dataset, &["--images", &images.display().to_string()]);
    assert_eq!(report["summary"]["all"]["frames"], 3);
    let mut pictures: Vec<_> = std::fs::read_dir(&images).unwrap().map(|e| e.unwrap().path()).collect();
    pictures.sort();
    assert_eq!(pictures.len(), 3);
    let picture = rover_imaging::decode_png(&std::fs::read(&pictures[0]).unwrap()).unwrap();
    assert_eq!((picture.width, picture.height), (3 * 320 * 2, 160 * 2), "three panels, twice the size");
    let [r, g, b] = picture.pixel(2 * 320 * 2 + 160 * 2, 150 * 2);
    assert!(r == g && g == b && r == 255, "the rover's own ground ahead is navigable in both: {:?}", [r, g, b]);
    std::fs::remove_dir_all(dataset).unwrap();
}

#[test]
fn a_missing_dataset_or_map_is_a_clear_error() {
    let output = std::process::Command::new(rover())
        .args(["sim-check", "/nonexistent/dataset", "--map", "/nonexistent/map.png"])
        .output()
        .expect("run rover sim-check");
    assert!(!output.status.success());
    let error = String::from_utf8_lossy(&output.stderr);
    assert!(error.contains("/nonexistent/dataset") && error.contains("robot_log.csv"), "{error}");
}
