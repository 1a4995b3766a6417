//! One simulator step: physics, camera render, JPEG encode and the telemetry JSON, as the simulator
//! does per command, while driving around the Unity world and a procedural one. Baseline in the
//! same run: the JPEG encode alone of the same frames.
//!
//! Run: `cargo bench --bench sim_step`.

use std::time::{Duration, Instant};

use rover_sim::sim::{SimConfig, Simulator};
use rover_sim::unity_world::{UnityFiles, unity_world};
use rover_sim::wire::command::Command;
use rover_sim::world::World;

const STEPS: usize = 3000;

fn median(mut samples: Vec<Duration>) -> f64 {
    samples.sort();
    samples[samples.len() / 2].as_secs_f64() * 1000.0
}

/// Drives in long arcs, braking and turning in place now and then, so frames have motion, pitch and roll.
fn command(step: usize) -> Command {
    match step % 400 {
        0..=299 => Command::Drive {
            steering_deg: if (step / 150).is_multiple_of(2) { 6.0 } else { -9.0 },
            throttle: 0.6,
            brake: 0.0,
        },
        300..=339 => Command::Drive { steering_deg: 0.0, throttle: 0.0, brake: 10.0 },
        _ => Command::Drive { steering_deg: 15.0, throttle: 0.0, brake: 0.0 },
    }
}

/// Times `STEPS` steps of the simulator in `world`; prints and returns the step's median, ms.
fn measure(name: &str, world: World) -> f64 {
    let mut simulator = Simulator::new(world, SimConfig::default());
    let (mut steps, mut physics, mut telemetries, mut encodes) = (vec![], vec![], vec![], vec![]);
    for step in 0..STEPS {
        let started = Instant::now();
        simulator.step(command(step));
        let stepped = started.elapsed();
        let telemetry = simulator.telemetry();
        let total = started.elapsed();
        steps.push(total);
        physics.push(stepped);
        telemetries.push(total - stepped);
        std::hint::black_box(telemetry);
        let image = simulator.render().clone();
        let started = Instant::now();
        std::hint::black_box(rover_imaging::encode_jpeg(&image, 75).expect("encode"));
        encodes.push(started.elapsed());
    }
    let report = simulator.report();
    let (step_ms, jpeg_ms) = (median(steps), median(encodes));
    println!(
        "{name:<22} step median {step_ms:.3} ms (physics {:.3}, telemetry: render + JPEG + JSON {:.3}; the JPEG alone {jpeg_ms:.3}); the step takes {:.2}x the JPEG encode alone   ({:.0} m driven, {} collisions)",
        median(physics),
        median(telemetries),
        step_ms / jpeg_ms,
        report.distance_m,
        report.collisions
    );
    step_ms
}

fn shared(path: &str) -> Vec<u8> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared").join(path);
    std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn main() {
    let (map, floor) = (shared("udacity/calibration_images/map_bw.png"), shared("udacity-world/floor_flat.png"));
    let (elevation, rocks) = (shared("udacity-world/elevation_cm.png"), shared("udacity-world/rocks.json"));
    let files = UnityFiles {
        map_png: &map,
        floor_png: Some(&floor),
        elevation_png: Some(&elevation),
        rocks_json: Some(&rocks),
    };
    println!("simulator step = physics + render + JPEG (q75, 4:2:0) + telemetry JSON, {STEPS} steps each");
    let unity = measure("surveyed Unity world (seed 1)", unity_world(&files, 1).expect("map"));
    let procedural = measure("procedural (seed 1)", rover_sim::procgen::procedural_world(1));
    let worst = unity.max(procedural);
    println!("target: median <= 2.5 ms: {}", if worst <= 2.5 { "met" } else { "MISSED" });
}
