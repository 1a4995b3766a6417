//! The perception lookup table against OpenCV itself (`cv2` of the opencv-python wheel, as a
//! student's Python pipeline uses it): on all 283 recorded frames, decoded once here and fed to
//! both, `warpPerspective` (INTER_LINEAR, black border) plus the thresholds gives exactly the
//! navigable, obstacle and rock masks of the table; the perspective matrix and the HSV of every
//! RGB colour are bit for bit OpenCV's.

mod support;

use std::path::{Path, PathBuf};
use std::process::Command;

use rover_imaging::RgbImage;
use rover_perception::classify::{Class, RockRule, Thresholds, rgb_to_hsv};
use rover_perception::{Calibration, Perception};

/// What OpenCV computed, read back from `tests/python/opencv_reference.py`'s files.
struct OpenCv {
    matrix: [f64; 9],
    /// Every frame warped, one after the other.
    warped: Vec<u8>,
    /// The warp of an all-ones image: 1 where a warped pixel comes from the camera's view.
    view: Vec<u8>,
    /// HSV of every RGB colour, R outermost, B innermost.
    hsv: Vec<u8>,
}

fn frames() -> Vec<RgbImage> {
    let dir = support::shared_dir().join("udacity/test_dataset/IMG");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("read {}: {e}", dir.display()))
        .map(|entry| entry.expect("a directory entry").path())
        .collect();
    files.sort();
    let Calibration { width, height, .. } = Calibration::default();
    files.iter().map(|f| rover_imaging::decode_jpeg(&std::fs::read(f).unwrap(), width, height).unwrap()).collect()
}

fn points_text(points: &[[f32; 2]; 4]) -> String {
    points.iter().flatten().map(|v| v.to_string()).collect::<Vec<_>>().join(",")
}

/// Runs OpenCV on `frames` with the calibration's points.
fn opencv(python: &Path, calibration: &Calibration, frames: &[RgbImage]) -> OpenCv {
    let dir = std::env::temp_dir().join(format!("rover-opencv-reference-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temporary folder");
    let frames_path = dir.join("frames.rgb");
    std::fs::write(&frames_path, frames.iter().flat_map(|f| f.data.iter().copied()).collect::<Vec<u8>>()).unwrap();
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/python/opencv_reference.py");
    let status = Command::new(python)
        .args(["-W", "ignore", script])
        .args([calibration.width.to_string(), calibration.height.to_string()])
        .args([points_text(&calibration.source_px), points_text(&calibration.destination_px())])
        .args([&frames_path, &dir])
        .status()
        .expect("run the OpenCV script");
    assert!(status.success(), "opencv_reference.py failed: {status}");
    let read = |name: &str| std::fs::read(dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
    let matrix_bytes = read("matrix.f64");
    let matrix = std::array::from_fn(|i| f64::from_le_bytes(matrix_bytes[i * 8..i * 8 + 8].try_into().unwrap()));
    let opencv = OpenCv { matrix, warped: read("warped.rgb"), view: read("view.u8"), hsv: read("hsv.u8") };
    let _ = std::fs::remove_dir_all(&dir);
    opencv
}

/// Masks of one warped frame by the thresholds alone: navigable, obstacle and rock, per pixel.
fn reference_masks(warped: &[u8], view: &[u8], thresholds: &Thresholds) -> Vec<(bool, bool, bool)> {
    (0..view.len())
        .map(|i| {
            let rgb = [warped[i * 3], warped[i * 3 + 1], warped[i * 3 + 2]];
            let navigable = thresholds.is_navigable(rgb);
            let rock = match thresholds.rock {
                RockRule::Rgb { .. } => thresholds.is_rock(rgb),
                RockRule::Hsv { lower, upper } => {
                    let hsv = rgb_to_hsv(rgb);
                    (0..3).all(|k| lower[k] <= hsv[k] && hsv[k] <= upper[k])
                }
            };
            (navigable, view[i] == 1 && !navigable, rock)
        })
        .collect()
}

fn table_masks(perception: &Perception, count: usize, width: usize) -> Vec<(bool, bool, bool)> {
    let mut masks = vec![(false, false, false); count];
    let warped = perception.warped_image();
    for (entry, class) in perception.table().entries.iter().zip(perception.classes()) {
        let i = entry.y as usize * width + entry.x as usize;
        let rgb = warped.pixel(entry.x as usize, entry.y as usize);
        let navigable = *class == Class::Navigable || (*class == Class::Rock && rgb.iter().all(|&c| c > 160));
        masks[i] = (navigable, entry.in_view && !navigable, *class == Class::Rock);
    }
    masks
}

fn every_colour() -> impl Iterator<Item = [u8; 3]> {
    (0..=255u8).flat_map(|r| (0..=255u8).flat_map(move |g| (0..=255u8).map(move |b| [r, g, b])))
}

#[test]
fn the_table_the_matrix_and_hsv_are_opencvs_on_all_recorded_frames() {
    let Some(python) = support::python_with(&["cv2", "numpy"]) else { return };
    let calibration = Calibration::default();
    let frames = frames();
    assert_eq!(frames.len(), 283, "the recorded dataset");
    let opencv = opencv(&python, &calibration, &frames);

    let ours = calibration.homography().expect("a perspective matrix");
    for (i, theirs) in opencv.matrix.iter().enumerate() {
        assert_eq!(theirs.to_bits(), ours[i].to_bits(), "M[{}][{}]: {theirs} there, {} here", i / 3, i % 3, ours[i]);
    }

    let hsv_rule = RockRule::Hsv { lower: [0, 120, 120], upper: [40, 255, 255] };
    for thresholds in [Thresholds::default(), Thresholds { rock: hsv_rule, ..Thresholds::default() }] {
        let mut perception = Perception::new(calibration, thresholds).unwrap();
        let frame_bytes = calibration.width * calibration.height * 3;
        let (mut navigable, mut rocks) = (0usize, 0usize);
        for (index, frame) in frames.iter().enumerate() {
            let warped = &opencv.warped[index * frame_bytes..(index + 1) * frame_bytes];
            perception.process_rgb(frame).unwrap();
            assert!(perception.warped_image().data == warped, "frame {index}: warped bytes differ from OpenCV's");
            let reference = reference_masks(warped, &opencv.view, &thresholds);
            assert_eq!(table_masks(&perception, reference.len(), calibration.width), reference, "frame {index}");
            navigable += reference.iter().filter(|m| m.0).count();
            rocks += reference.iter().filter(|m| m.2).count();
        }
        eprintln!("{:?}: 283 frames, {navigable} navigable and {rocks} rock pixels as OpenCV's", thresholds.rock);
        assert!(navigable > 0 && rocks > 0, "the frames show floor and rocks");
    }

    for (i, rgb) in every_colour().enumerate() {
        assert_eq!(rgb_to_hsv(rgb), opencv.hsv[i * 3..i * 3 + 3], "HSV of RGB {rgb:?}");
    }
}
