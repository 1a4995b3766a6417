//! What the Udacity fidelity counts as wrongly mapped ground is floor: `map_bw.png` leaves out the
//! floor at the foot of the walls, which real frames and the surveyed world both show. So the
//! fidelity against the floor (`floor_fidelity_pct`) stays near 100 % where the Udacity fidelity
//! stays near 90 %.

mod support;

use std::process::Command;

use support::{map_bw_png, number, rover, shared_path, surveyed_world_args, test_dataset_dir};

/// Runs `rover` with `args` and `--json`; its JSON output.
fn rover_json(args: &[String]) -> serde_json::Value {
    let output = Command::new(rover()).args(args).arg("--json").output().expect("run rover");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "rover {args:?} failed: {stderr}");
    serde_json::from_slice(&output.stdout).unwrap_or_else(|e| panic!("{e}: {stderr}"))
}

/// Asserts that nearly all the ground of a map is floor while the Udacity fidelity is lower.
fn assert_wrong_ground_is_floor(what: &str, report: &serde_json::Value) {
    let (fidelity, on_floor) = (number(report, "fidelity_pct"), number(report, "floor_fidelity_pct"));
    assert!(on_floor >= 97.0, "{what}: {on_floor} % of the mapped ground is floor");
    assert!(on_floor - fidelity >= 3.0, "{what}: fidelity {fidelity} %, on the floor {on_floor} %");
}

#[test]
fn the_real_frames_map_floor_where_map_bw_scores_them_wrong() {
    let recording = shared_path("udacity/recordings/tzyhpcom-2018-03-03");
    for dataset in [test_dataset_dir(), recording] {
        let args = [
            "replay",
            &dataset,
            "--ground-truth",
            &map_bw_png(),
            "--floor",
            &shared_path("udacity-world/floor_flat.png"),
        ];
        let report = rover_json(&args.map(String::from));
        assert_wrong_ground_is_floor(&dataset, &report);
    }
}

#[test]
fn a_mission_on_the_surveyed_world_maps_floor_where_map_bw_scores_it_wrong() {
    let mut args = ["eval", "--in-process", "--seeds", "0", "--max-sim-seconds", "150"].map(String::from).to_vec();
    args.extend(surveyed_world_args());
    let results = rover_json(&args);
    assert_wrong_ground_is_floor("surveyed world, seed 0, 150 s", &results[0]);
}
