//! The simulation: world, rover, camera and the run's report, driven one command at a time
//! through the Unity client ([`crate::wire::client::Simulation`]).

use std::time::{Duration, Instant};

use rover_imaging::{RgbImage, UNITY_JPEG_QUALITY};
use rover_msgs::unity::FRAME_PERIOD_S;
use serde::Serialize;

use crate::camera::{BodyPose, CameraModel};
use crate::physics::Rover;
use crate::render::{RenderOptions, Renderer};
use crate::wire::client::Simulation;
use crate::wire::command::Command;
use crate::wire::telemetry::TelemetryValues;
use crate::world::{Sample, World};

/// How often a long run logs its progress.
const PROGRESS_PERIOD: Duration = Duration::from_secs(5);

/// Settings of a run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimConfig {
    /// Simulated time per command, seconds.
    pub step_s: f64,
    /// Pace the run to the wall clock instead of running as fast as the graph answers.
    pub realtime: bool,
    /// End the run after this much simulated time, seconds.
    pub max_sim_seconds: Option<f64>,
    /// Draw the 1 m grid on the floor.
    pub grid: bool,
}

impl Default for SimConfig {
    fn default() -> Self {
        SimConfig { step_s: FRAME_PERIOD_S, realtime: false, max_sim_seconds: None, grid: false }
    }
}

/// What happened in a run.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct SimReport {
    /// Simulated time, seconds.
    pub sim_seconds: f64,
    /// Wall-clock time, seconds.
    pub wall_seconds: f64,
    /// Telemetry frames rendered and sent.
    pub frames: u64,
    /// Commands applied.
    pub commands: u64,
    /// Samples at the start.
    pub samples_total: usize,
    /// Samples picked up.
    pub samples_collected: usize,
    /// Distance driven, metres.
    pub distance_m: f64,
    /// Distance from the final position to the start, metres.
    pub final_distance_to_start_m: f64,
    /// Time with throttle applied but the rover not moving, seconds.
    pub stuck_seconds: f64,
    /// Times the rover ran into a wall, a boulder or a sample.
    pub collisions: u64,
}

impl std::fmt::Display for SimReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "simulation report")?;
        writeln!(f, "  sim time             {:>10.1} s", self.sim_seconds)?;
        writeln!(f, "  wall time            {:>10.1} s", self.wall_seconds)?;
        writeln!(f, "  frames               {:>10}", self.frames)?;
        writeln!(f, "  samples collected    {:>10}", format!("{} / {}", self.samples_collected, self.samples_total))?;
        writeln!(f, "  distance driven      {:>10.1} m", self.distance_m)?;
        writeln!(f, "  distance to start    {:>10.2} m", self.final_distance_to_start_m)?;
        writeln!(f, "  time stuck           {:>10.1} s", self.stuck_seconds)?;
        write!(f, "  collisions           {:>10}", self.collisions)
    }
}

/// A running simulation.
pub struct Simulator {
    world: World,
    config: SimConfig,
    rover: Rover,
    samples: Vec<Sample>,
    renderer: Renderer,
    image: RgbImage,
    jpeg: Vec<u8>,
    report: SimReport,
    started: Instant,
    last_progress: Instant,
}

impl Simulator {
    /// A simulation of `world` with the rover at the world's start pose.
    pub fn new(world: World, config: SimConfig) -> Self {
        let renderer = Renderer::new(
            &world,
            CameraModel::rover(),
            RenderOptions { grid: config.grid, ..RenderOptions::default() },
        );
        let mut rover = Rover::new(world.start.x_m, world.start.y_m, world.start.yaw_deg);
        rover.follow_ground(&world);
        let samples = world.samples.clone();
        let report = SimReport { samples_total: samples.len(), ..SimReport::default() };
        Simulator {
            world,
            config,
            rover,
            samples,
            renderer,
            image: RgbImage::default(),
            jpeg: Vec::new(),
            report,
            started: Instant::now(),
            last_progress: Instant::now(),
        }
    }

    /// The world being simulated.
    pub fn world(&self) -> &World {
        &self.world
    }

    /// Samples still on the ground.
    pub fn samples(&self) -> &[Sample] {
        &self.samples
    }

    /// The report so far.
    pub fn report(&self) -> SimReport {
        let mut report = self.report.clone();
        report.wall_seconds = self.started.elapsed().as_secs_f64();
        report.final_distance_to_start_m =
            (self.rover.x_m - self.world.start.x_m).hypot(self.rover.y_m - self.world.start.y_m);
        report
    }

    /// The body pose of the rover.
    pub fn pose(&self) -> BodyPose {
        BodyPose {
            x_m: self.rover.x_m,
            y_m: self.rover.y_m,
            yaw_deg: self.rover.yaw_deg,
            pitch_deg: self.rover.pitch_deg,
            roll_deg: self.rover.roll_deg,
            ground_m: self.rover.ground_m,
        }
    }

    /// Renders the camera image of the current state.
    pub fn render(&mut self) -> &RgbImage {
        let pose = self.pose();
        self.renderer.render(&self.world, &self.samples, &pose, &mut self.image);
        &self.image
    }

    /// Applies a command and advances the simulation by one step.
    pub fn step(&mut self, command: Command) {
        self.rover.apply(command, &self.samples);
        let (picked, events) = self.rover.step(self.config.step_s, &self.world, &self.samples);
        self.report.commands += 1;
        self.report.sim_seconds = self.report.commands as f64 * self.config.step_s;
        if let Some(index) = picked {
            self.samples.remove(index);
            self.report.samples_collected += 1;
            tracing::info!(
                "sample picked up at {:.1} s ({} of {})",
                self.report.sim_seconds,
                self.report.samples_collected,
                self.report.samples_total
            );
        }
        self.report.distance_m += events.distance_m;
        self.report.collisions += events.collision as u64;
        if events.stuck {
            self.report.stuck_seconds += self.config.step_s;
        }
        if self.last_progress.elapsed() >= PROGRESS_PERIOD {
            self.last_progress = Instant::now();
            let report = self.report();
            tracing::info!(
                "sim {:.1} s, {} frames ({:.0}/s), samples {}/{}, {:.0} m driven",
                report.sim_seconds,
                report.frames,
                report.frames as f64 / report.wall_seconds.max(1e-9),
                report.samples_collected,
                report.samples_total,
                report.distance_m
            );
        }
    }

    /// The telemetry JSON object of the current state, with a freshly rendered camera JPEG.
    pub fn telemetry(&mut self) -> String {
        self.render();
        if let Err(e) = rover_imaging::encode_jpeg_into(&self.image, UNITY_JPEG_QUALITY, &mut self.jpeg) {
            tracing::error!("cannot encode the camera image: {e}");
        }
        self.report.frames += 1;
        let positions: Vec<(f64, f64)> = self.samples.iter().map(|s| (s.x_m, s.y_m)).collect();
        TelemetryValues {
            state: self.rover.reported_state(),
            near_sample: self.rover.near_sample,
            picking_up: self.rover.picking_up,
            samples: &positions,
            image_jpeg: &self.jpeg,
        }
        .to_json()
    }
}

impl Simulation for Simulator {
    fn telemetry_json(&mut self) -> String {
        self.telemetry()
    }

    fn apply(&mut self, command: Command) {
        self.step(command);
    }

    fn finished(&self) -> bool {
        self.config.max_sim_seconds.is_some_and(|limit| self.report.sim_seconds >= limit - 1e-9)
    }

    fn due_at(&self) -> Option<Instant> {
        self.config.realtime.then(|| self.started + Duration::from_secs_f64(self.report.sim_seconds))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_seed_and_commands_give_identical_telemetry() {
        let commands = [
            Command::Drive { steering_deg: 5.0, throttle: 0.6, brake: 0.0 },
            Command::Manual,
            Command::Drive { steering_deg: -15.0, throttle: 0.2, brake: 0.0 },
            Command::Pickup,
            Command::Drive { steering_deg: 0.0, throttle: 0.0, brake: 10.0 },
        ];
        let run = |seed| {
            let mut sim = Simulator::new(crate::procgen::procedural_world(seed), SimConfig::default());
            let mut telemetry = vec![sim.telemetry()];
            for i in 0..60 {
                sim.step(commands[i % commands.len()]);
                telemetry.push(sim.telemetry());
            }
            telemetry
        };
        let first = run(3);
        assert_eq!(first, run(3));
        assert_ne!(first, run(4));
    }

    #[test]
    fn an_event_of_the_bridge_steps_as_its_command() {
        let world = || crate::procgen::procedural_world(5);
        let event = |name: &str, data: serde_json::Value| {
            let mut simulator = Simulator::new(world(), SimConfig::default());
            let stepped = simulator.receive_event(name, Some(&data));
            (stepped, simulator.telemetry())
        };
        let mut by_command = Simulator::new(world(), SimConfig::default());
        by_command.step(Command::Drive { steering_deg: 5.0, throttle: 0.3, brake: 0.7134795 });
        let data = serde_json::json!({"throttle": "0.3", "brake": "0.7134795", "steering_angle": "5"});
        assert_eq!(event("data", data), (Ok(true), by_command.telemetry()));
        assert_eq!(event("get_samples", serde_json::json!({})).0, Ok(false), "ignored, as the Unity client does");
        assert!(event("data", serde_json::json!({"throttle": "fast"})).0.is_err());
    }

    #[test]
    fn a_run_ends_at_the_sim_time_limit_and_reports() {
        let config = SimConfig { max_sim_seconds: Some(1.0), ..SimConfig::default() };
        let mut sim = Simulator::new(crate::procgen::procedural_world(1), config);
        let mut steps = 0;
        while !sim.finished() {
            sim.step(Command::Drive { steering_deg: 0.0, throttle: 1.0, brake: 0.0 });
            steps += 1;
        }
        assert_eq!(steps, 25);
        let report = sim.report();
        assert!((report.sim_seconds - 1.0).abs() < 1e-9);
        assert!(report.distance_m > 0.2 || report.collisions > 0, "{report:?}");
        assert!(report.to_string().contains("samples collected"));
    }
}
