//! Rock detection on the calibration images: the rock in example_rock1/2 is found with a
//! plausible bearing and distance; recorded frames without a rock show none.

use std::path::PathBuf;

use rover_perception::classify::Thresholds;
use rover_perception::scan::{ScanGeometry, ScanSummary};
use rover_perception::{Calibration, Perception};

fn shared(path: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/udacity").join(path)
}

fn summary(perception: &mut Perception, geometry: &ScanGeometry, file: PathBuf) -> ScanSummary {
    let jpeg = std::fs::read(&file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
    let classes = perception.process_jpeg(&jpeg).unwrap().to_vec();
    geometry.summarize(&classes)
}

#[test]
fn the_example_rocks_are_found_ahead() {
    let calibration = Calibration::default();
    let mut perception = Perception::new(calibration, Thresholds::default()).unwrap();
    let geometry = ScanGeometry::new(&calibration, perception.table(), 20.0);
    for file in ["calibration_images/example_rock1.jpg", "calibration_images/example_rock2.jpg"] {
        let found = summary(&mut perception, &geometry, shared(file));
        let (bearing, distance) = found.rock.unwrap_or_else(|| panic!("{file}: no rock found"));
        eprintln!("{file}: rock at bearing {:.1} deg, {distance:.2} m", bearing.to_degrees());
        assert!((1.0..6.0).contains(&distance), "{file}: rock at {distance} m");
        assert!(bearing.abs() < 0.3, "{file}: bearing {bearing}");
    }
}

#[test]
fn frames_without_a_rock_show_none() {
    let calibration = Calibration::default();
    let mut perception = Perception::new(calibration, Thresholds::default()).unwrap();
    let geometry = ScanGeometry::new(&calibration, perception.table(), 20.0);
    let mut files: Vec<PathBuf> =
        std::fs::read_dir(shared("test_dataset/IMG")).unwrap().map(|e| e.unwrap().path()).collect();
    files.sort();
    for file in files.iter().take(60) {
        let found = summary(&mut perception, &geometry, file.clone());
        assert!(found.rock.is_none(), "{}: rock reported at {:?}", file.display(), found.rock);
        assert!(found.navigable_count > 1000, "{}: the floor is seen", file.display());
    }
}
