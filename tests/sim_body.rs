//! The simulated body sways in turns as the real rover's does: on the flat floor, its roll in a
//! turn matches the roll that the recorded Unity logs show at the same sideways acceleration.

mod support;

use std::path::Path;

use rover::tools::dataset::{RecordedFrame, read_log};
use rover_bridge::convert::wrapped_rad;
use rover_sim::elevation::Elevation;
use rover_sim::sim::{SimConfig, Simulator};
use rover_sim::wire::command::Command;
use rover_sim::world::{StartPose, WORLD_SIZE, World};
use support::{shared_dir, test_dataset_dir};

/// Turns this hard and harder, m/s^2: the sway has settled at its limit in the logs.
const HARD_TURN_MPS2: (f64, f64) = (1.5, 3.5);
/// Ground within this distance of the rover lower than this is flat floor, metres.
const FLAT_WITHIN_M: f64 = 1.5;
const FLAT_BELOW_M: f64 = 0.01;
/// Frames this many either side of a frame give its yaw rate...
const SPAN_FRAMES: usize = 2;
/// ...when they are less than this far apart, seconds (farther, the log has a gap there).
const MAX_SPAN_S: f64 = 0.5;
/// The simulated roll is within this of the logs' median, degrees.
const TOLERANCE_DEG: f64 = 0.25;

/// Throttles of the simulated turns at full lock (the speed settles where the throttle holds it).
const TURN_THROTTLES: [f64; 3] = [0.5, 0.6, 0.7];
/// A simulated turn is measured after this long, seconds.
const SETTLE_S: f64 = 15.0;

fn surveyed_ground() -> Elevation {
    let path = shared_dir().join("udacity-world/elevation_cm.png");
    Elevation::from_png(&std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))).unwrap()
}

fn on_flat_floor(ground: &Elevation, frame: &RecordedFrame) -> bool {
    let (x, y) = (frame.state.x_m, frame.state.y_m);
    let offsets = [-FLAT_WITHIN_M, 0.0, FLAT_WITHIN_M];
    offsets.iter().all(|dx| offsets.iter().all(|dy| (ground.height_at(x + dx, y + dy) as f64) < FLAT_BELOW_M))
}

/// The sideways acceleration (speed times yaw rate, m/s^2) and the absolute roll (degrees) of each
/// frame of `log` on the flat floor.
fn logged_turns(log: &Path, ground: &Elevation) -> Vec<(f64, f64)> {
    let frames = read_log(log).unwrap_or_else(|e| panic!("{}: {e:#}", log.display())).frames;
    let times: Vec<f64> = frames.iter().map(|f| f.time_ns().expect("a time in the image name") as f64 * 1e-9).collect();
    (SPAN_FRAMES..frames.len().saturating_sub(SPAN_FRAMES))
        .filter(|&i| on_flat_floor(ground, &frames[i]))
        .filter_map(|i| {
            let (before, after) = (&frames[i - SPAN_FRAMES].state, &frames[i + SPAN_FRAMES].state);
            let dt = times[i + SPAN_FRAMES] - times[i - SPAN_FRAMES];
            (dt > 0.0 && dt < MAX_SPAN_S).then(|| {
                let yaw_rate = wrapped_rad(after.yaw_deg - before.yaw_deg) / dt;
                (frames[i].state.speed_mps * yaw_rate, wrapped_rad(frames[i].state.roll_deg).abs().to_degrees())
            })
        })
        .collect()
}

/// The median absolute roll of the `turns` with a sideways acceleration in [`HARD_TURN_MPS2`].
fn median_roll_in_hard_turns(turns: &[(f64, f64)]) -> (f64, usize) {
    let mut rolls: Vec<f64> = turns
        .iter()
        .filter(|(accel, _)| (HARD_TURN_MPS2.0..=HARD_TURN_MPS2.1).contains(&accel.abs()))
        .map(|&(_, roll)| roll)
        .collect();
    rolls.sort_by(f64::total_cmp);
    (rolls.get(rolls.len() / 2).copied().unwrap_or(f64::NAN), rolls.len())
}

/// The simulated rover's sideways acceleration (m/s^2) and absolute roll (degrees) in a steady
/// turn at full lock and `throttle`, on open flat ground.
fn simulated_turn(throttle: f64) -> (f64, f64) {
    let world = World::open(vec![true; WORLD_SIZE * WORLD_SIZE], StartPose { x_m: 100.0, y_m: 100.0, yaw_deg: 0.0 });
    let config = SimConfig::default();
    let mut sim = Simulator::new(world, config);
    let steps = (SETTLE_S / config.step_s) as usize;
    let drive = Command::Drive { steering_deg: 15.0, throttle, brake: 0.0 };
    for _ in 1..steps {
        sim.step(drive);
    }
    let before = sim.pose();
    sim.step(drive);
    let now = sim.pose();
    let speed_mps = (now.x_m - before.x_m).hypot(now.y_m - before.y_m) / config.step_s;
    let yaw_rate = wrapped_rad(now.yaw_deg - before.yaw_deg) / config.step_s;
    (speed_mps * yaw_rate, now.roll_deg.abs())
}

#[test]
fn in_hard_turns_the_simulated_body_rolls_as_the_recorded_ones_do() {
    let ground = surveyed_ground();
    let logs = [
        Path::new(&test_dataset_dir()).join("robot_log.csv"),
        shared_dir().join("udacity/recordings/tzyhpcom-2018-03-03/robot_log.csv"),
    ];
    let simulated = TURN_THROTTLES.map(|throttle| (throttle, simulated_turn(throttle)));
    for (throttle, (accel, _)) in simulated {
        assert!((HARD_TURN_MPS2.0..=HARD_TURN_MPS2.1).contains(&accel.abs()), "throttle {throttle}: {accel} m/s^2");
    }
    for log in &logs {
        let (logged_roll, frames) = median_roll_in_hard_turns(&logged_turns(log, &ground));
        assert!(frames >= 10, "{}: only {frames} frames in hard turns on the flat floor", log.display());
        for (_, (accel, roll)) in simulated {
            assert!(
                (roll - logged_roll).abs() <= TOLERANCE_DEG,
                "at {accel:.2} m/s^2 the simulated body rolls {roll:.2} degrees, the rover of {} {logged_roll:.2} \
                 (median of {frames} frames)",
                log.display()
            );
        }
    }
}
