//! The seed baseline's evaluation (`tests/python/seed_baseline/eval_baseline.py`) against the
//! `rover` binary under test: 60 simulated seconds on `map_bw.png` and on a procedural world
//! (whose ground truth `rover sim --export-map` writes), checked through its `--json` rows.

mod support;

use std::process::{Command, Stdio};
use std::time::Instant;

use support::number;

/// The Python modules of the baseline driver (drive_baseline.py, perception.py).
const DRIVER_MODULES: [&str; 6] = ["socketio", "engineio", "eventlet", "numpy", "cv2", "PIL"];

/// Simulated seconds per run.
const SIM_SECONDS: f64 = 60.0;

/// Runs eval_baseline.py with `world` (`--map PNG` or `--procedural`) on `seed` for SIM_SECONDS
/// and returns its JSON rows; `None` if Python lacks the driver's modules (a skip).
fn eval_baseline(world: &[&str], seed: u64) -> Option<Vec<serde_json::Value>> {
    let python = support::python_with(&DRIVER_MODULES)?;
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/python/seed_baseline/eval_baseline.py");
    let started = Instant::now();
    let output = Command::new(&python)
        .args(["-W", "ignore", script])
        .args(world)
        .args(["--seeds", &seed.to_string(), "--max-sim-seconds", &SIM_SECONDS.to_string(), "--json"])
        .args(["--run-timeout", "300"])
        .arg("--rover")
        .arg(support::rover())
        .stdin(Stdio::null())
        .stderr(Stdio::inherit())
        .output()
        .unwrap_or_else(|e| panic!("cannot start {}: {e}", python.display()));
    let stdout = String::from_utf8_lossy(&output.stdout);
    eprintln!("eval_baseline.py {world:?} seed {seed}: {:.1} s wall\n{stdout}", started.elapsed().as_secs_f64());
    assert!(output.status.success(), "eval_baseline.py {world:?} failed: {}", output.status);
    let rows: serde_json::Value = serde_json::from_str(&stdout).expect("eval_baseline.py --json prints JSON");
    Some(rows.as_array().expect("a JSON list").clone())
}

/// The number `key` of a result row.
/// Checks the one row of a 60 s run of `seed`: six samples, the whole simulated time, a partial
/// map of the baseline's usual fidelity (~93 %), a frame rate and a home distance.
fn assert_one_plausible_row(rows: &[serde_json::Value], seed: u64) {
    assert_eq!(rows.len(), 1, "one row per seed: {rows:?}");
    let row = &rows[0];
    assert_eq!(row["seed"].as_u64(), Some(seed), "{row}");
    assert_eq!(row["samples"].as_u64(), Some(6), "{row}");
    assert!((number(row, "sim_seconds") - SIM_SECONDS).abs() <= 1.0, "the whole simulated time: {row}");
    let mapped = number(row, "mapped_pct");
    assert!(mapped > 0.0 && mapped < 100.0, "part of the world mapped in 60 s: {row}");
    assert!(number(row, "fidelity_pct") > 50.0, "the baseline maps with ~93 % fidelity: {row}");
    assert!(number(row, "frames_per_second") > 0.0, "{row}");
    assert!(number(row, "home_distance_m").is_finite(), "{row}");
}

#[test]
fn the_baseline_evaluation_scores_a_60_s_run_on_the_udacity_map() {
    let map = support::map_bw_png();
    let Some(rows) = eval_baseline(&["--map", &map], 1) else { return };
    assert_one_plausible_row(&rows, 1);
}

#[test]
fn the_baseline_evaluation_scores_a_60_s_run_on_a_procedural_world_with_its_exported_ground_truth() {
    let Some(rows) = eval_baseline(&["--procedural"], 0) else { return };
    assert_one_plausible_row(&rows, 0);
}
