//! The JPEG codec against the Python tools of the Udacity project: the 283 recorded Unity frames
//! and frames of our simulator decode here byte for byte as PIL and OpenCV decode them, so the
//! perception node sees exactly the pixels that a student's Python pipeline sees.

mod support;

use std::path::{Path, PathBuf};
use std::process::Command as Process;

use rover_imaging::{UNITY_JPEG_QUALITY, decode_jpeg, encode_jpeg};
use rover_sim::sim::{SimConfig, Simulator};
use rover_sim::wire::command::Command;

const WIDTH: usize = 320;
const HEIGHT: usize = 160;

/// The recorded frames of `../shared/udacity/test_dataset`, in order.
fn recorded_frames() -> Vec<PathBuf> {
    let dir = support::shared_dir().join("udacity/test_dataset/IMG");
    let mut frames: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("read {}: {e}", dir.display()))
        .map(|entry| entry.expect("a directory entry").path())
        .filter(|path| path.extension().is_some_and(|e| e == "jpg"))
        .collect();
    frames.sort();
    frames
}

/// The RGB bytes of every file of `jpegs` as PIL and as OpenCV decode them.
fn decoded_in_python(python: &Path, jpegs: &[PathBuf], tag: &str) -> (Vec<u8>, Vec<u8>) {
    let out = |tool: &str| std::env::temp_dir().join(format!("rover-jpeg-{tag}-{tool}-{}.rgb", std::process::id()));
    let (pil, opencv) = (out("pil"), out("cv2"));
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/python/decode_jpegs.py");
    let status = Process::new(python)
        .args(["-W", "ignore", script])
        .args([&pil, &opencv])
        .args(jpegs)
        .status()
        .expect("run the Python decoder");
    assert!(status.success(), "decode_jpegs.py failed: {status}");
    let read = |path: &Path| {
        let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("read {}: {e}", path.display()));
        let _ = std::fs::remove_file(path);
        bytes
    };
    (read(&pil), read(&opencv))
}

/// Our decoding of every file of `jpegs`, one after the other.
fn decoded_here(jpegs: &[PathBuf]) -> Vec<u8> {
    jpegs
        .iter()
        .flat_map(|path| decode_jpeg(&std::fs::read(path).expect("read a JPEG"), WIDTH, HEIGHT).expect("decode").data)
        .collect()
}

/// Which frame and byte the first difference is at, for the failure message.
fn first_difference(ours: &[u8], theirs: &[u8]) -> String {
    match ours.iter().zip(theirs).position(|(a, b)| a != b) {
        Some(at) => format!("frame {}, byte {}: {} here, {}", at / (WIDTH * HEIGHT * 3), at, ours[at], theirs[at]),
        None => format!("{} bytes here, {} there", ours.len(), theirs.len()),
    }
}

#[test]
fn the_recorded_frames_decode_as_pil_and_opencv_decode_them() {
    let Some(python) = support::python_with(&["PIL", "cv2", "numpy"]) else { return };
    let frames = recorded_frames();
    assert_eq!(frames.len(), 283, "the recorded dataset");
    let ours = decoded_here(&frames);
    let (pil, opencv) = decoded_in_python(&python, &frames, "recorded");
    assert!(ours == pil, "PIL decodes otherwise: {}", first_difference(&ours, &pil));
    assert!(ours == opencv, "OpenCV decodes otherwise: {}", first_difference(&ours, &opencv));
}

#[test]
fn the_simulators_frames_decode_in_python_as_they_do_here() {
    let Some(python) = support::python_with(&["PIL", "cv2", "numpy"]) else { return };
    let world = rover_sim::procgen::procedural_world(4);
    let mut simulator = Simulator::new(world, SimConfig::default());
    let dir = std::env::temp_dir().join(format!("rover-jpeg-sim-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temporary directory");
    let turn = Command::Drive { steering_deg: 15.0, throttle: 0.0, brake: 0.0 };
    let frames: Vec<PathBuf> = (0..12)
        .map(|i| {
            for _ in 0..20 {
                simulator.step(turn);
            }
            let path = dir.join(format!("frame-{i:02}.jpg"));
            let jpeg = encode_jpeg(simulator.render(), UNITY_JPEG_QUALITY).expect("encode");
            std::fs::write(&path, jpeg).expect("write a frame");
            path
        })
        .collect();
    let ours = decoded_here(&frames);
    let (pil, opencv) = decoded_in_python(&python, &frames, "sim");
    let _ = std::fs::remove_dir_all(&dir);
    assert!(ours == pil, "PIL decodes otherwise: {}", first_difference(&ours, &pil));
    assert!(ours == opencv, "OpenCV decodes otherwise: {}", first_difference(&ours, &opencv));
}
