//! `rover sim`: runs the headless simulator against a bridge, as the Unity simulator would.

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use rover_msgs::unity::FRAME_PERIOD_S;

use crate::look::Look;
use crate::procgen::procedural_world;
use crate::sim::{SimConfig, SimReport, Simulator};
use crate::unity_world::unity_world;
use crate::wire::client::{ClientConfig, run_client};
use crate::world::World;

/// Which world to simulate: the options every command that builds a world shares.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct WorldArgs {
    /// World map: a 200x200 PNG, navigable pixels > 0 (row = y, column = x), e.g.
    /// ../shared/udacity/calibration_images/map_bw.png. Default: a procedural world.
    #[arg(long, value_name = "PNG")]
    pub map: Option<PathBuf>,
    /// Where the terrain is flat floor: a 200x200 PNG like the map, white where the floor is,
    /// containing the map's navigable cells (e.g. ../shared/udacity-world/floor_flat.png for
    /// map_bw.png). Default: the map widened by one cell. Only with --map.
    #[arg(long, value_name = "PNG", requires = "map")]
    pub floor: Option<PathBuf>,
    /// Appearance seed: 0 is the look calibrated against the real Unity frames; other seeds vary
    /// the sun, colours and texture within what those frames show.
    #[arg(long, default_value_t = 0, value_name = "N")]
    pub appearance_seed: u64,
}

impl WorldArgs {
    /// The world these options describe for `seed` (the procedural world's layout, the sample
    /// choice and the start yaw).
    pub fn world(&self, seed: u64) -> anyhow::Result<World> {
        let world = match &self.map {
            None => procedural_world(seed),
            Some(map) => {
                let read = |path: &Path| std::fs::read(path).with_context(|| format!("cannot read {}", path.display()));
                let floor = self.floor.as_deref().map(read).transpose()?;
                unity_world(&read(map)?, floor.as_deref(), seed).with_context(|| match &self.floor {
                    Some(floor) => format!("map {} with floor {}", map.display(), floor.display()),
                    None => format!("map {}", map.display()),
                })?
            }
        };
        Ok(world.with_look(Look::from_seed(self.appearance_seed)))
    }

    /// A short description of the world, for logs.
    pub fn describe(&self) -> String {
        let mut text = self.map.as_ref().map_or("a procedural world".to_string(), |p| p.display().to_string());
        if let Some(floor) = &self.floor {
            text += &format!(" (floor {})", floor.display());
        }
        if self.appearance_seed != 0 {
            text += &format!(", appearance seed {}", self.appearance_seed);
        }
        text
    }
}

/// Options of `rover sim`.
#[derive(Debug, Clone, clap::Args)]
pub struct SimArgs {
    /// The world.
    #[command(flatten)]
    pub world: WorldArgs,
    /// Seed of the procedural world, the sample choice and the start yaw.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Host of the bridge.
    #[arg(long, default_value = "127.0.0.1")]
    pub host: String,
    /// Port of the bridge (the Unity simulator always uses 4567).
    #[arg(long, default_value_t = 4567)]
    pub port: u16,
    /// Simulated time per command, seconds.
    #[arg(long, default_value_t = FRAME_PERIOD_S, value_name = "SECONDS")]
    pub step_seconds: f64,
    /// Pace the simulation to the wall clock (default: as fast as the graph answers).
    #[arg(long)]
    pub realtime: bool,
    /// End the run after this much simulated time.
    #[arg(long, value_name = "SECONDS")]
    pub max_sim_seconds: Option<f64>,
    /// Draw the 1 m calibration grid on the floor.
    #[arg(long)]
    pub grid: bool,
    /// Also write the final report as JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub report: Option<PathBuf>,
    /// Write the world's ground-truth map (navigable white, as map_bw.png) to this PNG and exit,
    /// e.g. to look at a procedural world or to score it with other tools.
    #[arg(long, value_name = "PNG")]
    pub export_map: Option<PathBuf>,
}

impl SimArgs {
    fn config(&self) -> anyhow::Result<SimConfig> {
        anyhow::ensure!(
            self.step_seconds > 0.0 && self.step_seconds <= 1.0,
            "--step-seconds {} must be in (0, 1]",
            self.step_seconds
        );
        if let Some(limit) = self.max_sim_seconds {
            anyhow::ensure!(limit > 0.0, "--max-sim-seconds {limit} must be positive");
        }
        Ok(SimConfig {
            step_s: self.step_seconds,
            realtime: self.realtime,
            max_sim_seconds: self.max_sim_seconds,
            grid: self.grid,
        })
    }
}

/// Runs the simulator until its time limit or until `stop` resolves; prints and returns the report.
/// With `--export-map`, writes the world's map instead and returns `None`.
pub async fn run(args: &SimArgs, stop: impl std::future::Future<Output = ()>) -> anyhow::Result<Option<SimReport>> {
    let world = args.world.world(args.seed)?;
    if let Some(path) = &args.export_map {
        let png = world.ground_truth_png()?;
        std::fs::write(path, png).with_context(|| format!("cannot write the map to {}", path.display()))?;
        println!("wrote the ground-truth map of the world to {}", path.display());
        return Ok(None);
    }
    let config = args.config()?;
    let mut simulator = Simulator::new(world, config);
    tracing::info!(
        "simulating {} (seed {}), start ({:.2}, {:.2}) yaw {:.1} deg, {} samples",
        args.world.describe(),
        args.seed,
        simulator.world().start.x_m,
        simulator.world().start.y_m,
        simulator.world().start.yaw_deg,
        simulator.samples().len()
    );
    let client = ClientConfig::unity(&args.host, args.port);
    let stats = run_client(&mut simulator, &client, stop).await;
    let report = simulator.report();
    tracing::info!(
        "{} connections, {} commands dropped, {} events ignored",
        stats.connections,
        stats.commands_dropped,
        stats.events_ignored
    );
    println!("{report}");
    if let Some(path) = &args.report {
        let json = serde_json::to_string_pretty(&report)?;
        std::fs::write(path, json).with_context(|| format!("cannot write the report to {}", path.display()))?;
    }
    Ok(Some(report))
}
