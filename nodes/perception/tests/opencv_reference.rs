//! The lookup table against OpenCV itself (the `opencv` crate on the system's OpenCV): on all 283
//! recorded frames, decoded once and fed to both, `warpPerspective` (INTER_LINEAR, black border)
//! plus the thresholds gives exactly the navigable, obstacle and rock masks of the table.
#![cfg(feature = "opencv-reference")]

use std::path::PathBuf;

use opencv::core::{self, Mat, Point2f, Scalar, Size, Vector};
use opencv::imgproc;
use opencv::prelude::*;
use rover_imaging::RgbImage;
use rover_perception::classify::{Class, RockRule, Thresholds, rgb_to_hsv};
use rover_perception::{Calibration, Perception};

fn dataset() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/udacity/test_dataset/IMG")
}

fn frames() -> Vec<RgbImage> {
    let mut files: Vec<PathBuf> =
        std::fs::read_dir(dataset()).expect("test_dataset/IMG").map(|e| e.unwrap().path()).collect();
    files.sort();
    let Calibration { width, height, .. } = Calibration::default();
    files.iter().map(|f| rover_imaging::decode_jpeg(&std::fs::read(f).unwrap(), width, height).unwrap()).collect()
}

fn points(p: &[[f32; 2]; 4]) -> Vector<Point2f> {
    p.iter().map(|q| Point2f::new(q[0], q[1])).collect()
}

fn opencv_matrix(calibration: &Calibration) -> Mat {
    imgproc::get_perspective_transform(
        &points(&calibration.source_px),
        &points(&calibration.destination_px()),
        core::DECOMP_LU,
    )
    .expect("getPerspectiveTransform")
}

fn warp(image: &Mat, matrix: &Mat, size: Size) -> Mat {
    let mut warped = Mat::default();
    imgproc::warp_perspective(
        image,
        &mut warped,
        matrix,
        size,
        imgproc::INTER_LINEAR,
        core::BORDER_CONSTANT,
        Scalar::all(0.0),
    )
    .expect("warpPerspective");
    warped
}

fn to_mat(image: &RgbImage) -> Mat {
    let flat = Mat::from_slice(&image.data).expect("wrap the pixels");
    flat.reshape(3, image.height as i32).expect("reshape").try_clone().expect("own the pixels")
}

#[test]
fn the_matrix_is_bit_identical_to_opencv() {
    let calibration = Calibration::default();
    let ours = calibration.homography().unwrap();
    let theirs = opencv_matrix(&calibration);
    for row in 0..3 {
        for col in 0..3 {
            let value = *theirs.at_2d::<f64>(row, col).unwrap();
            assert_eq!(value.to_bits(), ours[(row * 3 + col) as usize].to_bits(), "M[{row}][{col}]: {value} vs ours");
        }
    }
}

/// Masks of one frame: navigable, obstacle and rock, per warped pixel.
fn reference_masks(warped: &Mat, view: &Mat, thresholds: &Thresholds) -> Vec<(bool, bool, bool)> {
    let bytes = warped.data_bytes().unwrap();
    let view = view.data_bytes().unwrap();
    (0..view.len())
        .map(|i| {
            let rgb = [bytes[i * 3], bytes[i * 3 + 1], bytes[i * 3 + 2]];
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

fn compare(thresholds: Thresholds) {
    let calibration = Calibration::default();
    let matrix = opencv_matrix(&calibration);
    let size = Size::new(calibration.width as i32, calibration.height as i32);
    let ones = Mat::new_rows_cols_with_default(size.height, size.width, core::CV_8UC1, Scalar::all(1.0)).unwrap();
    let view = warp(&ones, &matrix, size);
    let mut perception = Perception::new(calibration, thresholds).unwrap();
    let frames = frames();
    assert_eq!(frames.len(), 283);
    let (mut pixels, mut navigable, mut rocks) = (0usize, 0usize, 0usize);
    for (index, frame) in frames.iter().enumerate() {
        let warped = warp(&to_mat(frame), &matrix, size);
        perception.process_rgb(frame).unwrap();
        let ours = perception.warped_image();
        assert_eq!(ours.data, warped.data_bytes().unwrap(), "frame {index}: warped bytes differ");
        let reference = reference_masks(&warped, &view, &thresholds);
        let table = table_masks(&perception, reference.len(), calibration.width);
        assert_eq!(table, reference, "frame {index}: masks differ");
        pixels += reference.len();
        navigable += reference.iter().filter(|m| m.0).count();
        rocks += reference.iter().filter(|m| m.2).count();
    }
    eprintln!(
        "283 frames, {pixels} warped pixels: {navigable} navigable and {rocks} rock pixels, all identical to OpenCV"
    );
}

#[test]
fn rgb_masks_match_opencv_on_all_recorded_frames() {
    compare(Thresholds::default());
}

#[test]
fn hsv_rock_masks_match_opencv_on_all_recorded_frames() {
    let hsv =
        Thresholds { rock: RockRule::Hsv { lower: [0, 120, 120], upper: [40, 255, 255] }, ..Thresholds::default() };
    compare(hsv);
}

#[test]
fn hsv_conversion_matches_opencv_for_every_colour() {
    let mut all = Vec::with_capacity(256 * 256 * 256 * 3);
    for r in 0..=255u8 {
        for g in 0..=255u8 {
            for b in 0..=255u8 {
                all.extend_from_slice(&[r, g, b]);
            }
        }
    }
    let image = to_mat(&RgbImage { width: 4096, height: 4096, data: all.clone() });
    let mut hsv = Mat::default();
    imgproc::cvt_color(&image, &mut hsv, imgproc::COLOR_RGB2HSV, 0).unwrap();
    let theirs = hsv.data_bytes().unwrap();
    for (i, rgb) in all.chunks_exact(3).enumerate() {
        let ours = rgb_to_hsv([rgb[0], rgb[1], rgb[2]]);
        assert_eq!(ours, theirs[i * 3..i * 3 + 3], "RGB {rgb:?}");
    }
}
