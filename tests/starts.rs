//! Missions that start elsewhere than the world's start: a rover put in a dead end of the Unity
//! map facing its wall looks around and drives out; a start off the floor or misspelt is refused,
//! naming it.

mod support;

use std::process::Command;

/// `rover eval --in-process` with `args`: its JSON results, or its stderr when it fails.
fn eval(args: &[&str]) -> Result<serde_json::Value, String> {
    let output = Command::new(support::rover())
        .args(["eval", "--in-process", "--json"])
        .args(args)
        .output()
        .expect("run rover eval");
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    if !output.status.success() {
        return Err(stderr);
    }
    serde_json::from_slice(&output.stdout).map_err(|e| format!("{e}: {stderr}"))
}

fn unity_map_with(start: &str) -> Vec<String> {
    let map = support::map_bw_png();
    let floor = support::shared_path("udacity-world/floor_flat.png");
    ["--map", &map, "--floor", &floor, &format!("--start={start}"), "--seeds", "0"].map(String::from).to_vec()
}

/// Before the look-around, this start ended the mission at 1.2 sim s with 0.2 % mapped, "done";
/// the whole mission from it completes (`rover eval --in-process ... --start=112.5,9.5,270`,
/// docs/mission.md). The test runs its first 90 sim s: the rover has left the dead end.
#[test]
fn a_rover_started_facing_the_wall_of_a_dead_end_looks_around_and_drives_out() {
    let mut args = unity_map_with("112.5,9.5,270");
    args.extend(["--max-sim-seconds", "90"].map(String::from));
    let results = eval(&args.iter().map(String::as_str).collect::<Vec<_>>()).expect("rover eval");
    let run = &results[0];
    let number = |name: &str| run[name].as_f64().unwrap_or_else(|| panic!("no {name} in {run}"));
    assert_ne!(run["final_mode"], "done", "the mission ended in the dead end: {run}");
    assert!(number("sim_seconds") >= 89.0, "{run}");
    assert!(number("distance_m") > 30.0 && number("mapped_pct") > 5.0, "the rover did not drive out: {run}");
}

#[test]
fn a_start_off_the_floor_or_not_x_y_yaw_is_refused_naming_it() {
    let off_floor = eval(&unity_map_with("0,0,90").iter().map(String::as_str).collect::<Vec<_>>()).unwrap_err();
    assert!(off_floor.contains("start (0, 0) is not drivable ground"), "{off_floor}");
    let misspelt = eval(&["--procedural", "--start=100;100;0", "--seeds", "0"]).unwrap_err();
    assert!(misspelt.contains("'100;100;0'") && misspelt.contains("expected X,Y,YAW"), "{misspelt}");
    let both = eval(&["--procedural", "--start=100,100,0", "--random-start", "--seeds", "0"]).unwrap_err();
    assert!(both.contains("--random-start") && both.contains("--start"), "{both}");
}
