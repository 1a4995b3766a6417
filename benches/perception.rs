//! Perception per frame (JPEG decode, lookup-table interpolation and classification, terrain grid
//! and summary) and the map update per frame, on the 283 recorded frames, against the usual Python
//! perception (numpy + opencv-python-headless, benches/python/perception_reference.py) timed in the
//! same run.
//!
//! Run: `tools/setup-ros && source tools/ros-env.sh && cargo bench --bench perception`.

use std::path::PathBuf;
use std::process::Command;
use std::time::{Duration, Instant};

use rover::tools::dataset::read_log;
use rover::tools::replay::{frame_pose, scan_grid};
use rover_mapping::map::WorldMap;
use rover_mapping::params::MappingParams;
use rover_perception::params::PerceptionParams;

const PASSES: usize = 5;

fn median_ms(mut samples: Vec<Duration>) -> f64 {
    samples.sort();
    samples[samples.len() / 2].as_secs_f64() * 1000.0
}

fn python_reference(dataset: &std::path::Path) -> Result<f64, String> {
    let python = std::env::var("ROVER_PYTHON").unwrap_or_else(|_| "python3".to_string());
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/benches/python/perception_reference.py");
    let output = Command::new(&python)
        .args([script, dataset.to_str().unwrap_or_default(), "--passes", &PASSES.to_string()])
        .output()
        .map_err(|e| format!("cannot run {python}: {e}"))?;
    if !output.status.success() {
        return Err(String::from_utf8_lossy(&output.stderr).lines().last().unwrap_or_default().to_string());
    }
    let report: serde_json::Value = serde_json::from_slice(&output.stdout).map_err(|e| e.to_string())?;
    eprintln!("python reference: {report}");
    report["median_ms"].as_f64().ok_or_else(|| "no median_ms".to_string())
}

fn main() -> anyhow::Result<()> {
    let dataset = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/udacity/test_dataset");
    let frames = read_log(&dataset)?.frames;
    let jpegs: Vec<Vec<u8>> = frames.iter().map(|f| f.jpeg()).collect::<anyhow::Result<_>>()?;
    let (mut perception, geometry) = PerceptionParams::default().pipeline()?;
    let mapping = MappingParams::default();
    let (mut perceive, mut map_update) = (Vec::new(), Vec::new());
    let mut cells = Vec::new();
    for _ in 0..PASSES {
        let mut map = WorldMap::new(mapping.map_config());
        for (frame, jpeg) in frames.iter().zip(&jpegs) {
            let started = Instant::now();
            let classes = perception.process_jpeg(jpeg)?;
            let summary = geometry.summarize(classes);
            geometry.fill(classes, &mut cells);
            perceive.push(started.elapsed());
            std::hint::black_box(summary);
            let started = Instant::now();
            std::hint::black_box(map.update(&scan_grid(&geometry, &cells), frame_pose(frame)));
            map_update.push(started.elapsed());
        }
    }
    let (perception_ms, mapping_ms) = (median_ms(perceive), median_ms(map_update));
    println!("{} frames x {PASSES} passes, median per frame", frames.len());
    println!(
        "perception (decode + table + classify + grid): {perception_ms:.3} ms   target <= 1.0 ms: {}",
        verdict(perception_ms <= 1.0)
    );
    println!(
        "map update:                                    {mapping_ms:.3} ms   target <= 0.3 ms: {}",
        verdict(mapping_ms <= 0.3)
    );
    match python_reference(&dataset) {
        Ok(python_ms) => println!(
            "python reference (numpy + opencv):             {python_ms:.3} ms   ratio {:.1}x faster   target >= 4x: {}",
            python_ms / perception_ms,
            verdict(python_ms / perception_ms >= 4.0)
        ),
        Err(e) => println!("python reference unavailable ({e}); run tools/setup-ros and source tools/ros-env.sh"),
    }
    Ok(())
}

fn verdict(ok: bool) -> &'static str {
    if ok { "met" } else { "MISSED" }
}
