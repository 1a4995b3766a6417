//! `rover sim`: runs the headless simulator against a bridge, as the Unity simulator would.

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use rover_msgs::unity::FRAME_PERIOD_S;

use crate::look::Look;
use crate::procgen::procedural_world;
use crate::sim::{SimConfig, SimReport, Simulator};
use crate::start::{random_start, starting_at};
use crate::unity_world::{UnityFiles, unity_world};
use crate::wire::client::{ClientConfig, run_client};
use crate::world::{StartPose, World};

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
    /// The ground's height every 0.5 m: a 401x401 16-bit greyscale PNG in centimetres above the
    /// floor (e.g. ../shared/udacity-world/elevation_cm.png for map_bw.png). Without --floor, the
    /// floor is where it is below 0.5 m. Default: walls rising from the floor as the measured
    /// profile of the Unity walls does. Only with --map.
    #[arg(long, value_name = "PNG", requires = "map")]
    pub elevation: Option<PathBuf>,
    /// The rock obstacles' shapes: a survey of the lowest and highest rock surface over a grid of
    /// cells per rock (e.g. ../shared/udacity-world/rocks.json for map_bw.png). Default: the 16
    /// floor rocks of the Unity scene as faceted boulders fitted to the map. Only with --map.
    #[arg(long, value_name = "JSON", requires = "map")]
    pub rocks: Option<PathBuf>,
    /// Appearance seed: 0 is the look calibrated against the real Unity frames; other seeds vary
    /// the sun, colours and texture within what those frames show.
    #[arg(long, default_value_t = 0, value_name = "N")]
    pub appearance_seed: u64,
    /// Where the rover starts, instead of the world's start: X,Y,YAW in metres and degrees
    /// counter-clockwise from +x, on drivable ground (e.g. 60.5,100.5,180). The start is home.
    #[arg(long, value_name = "X,Y,YAW", allow_hyphen_values = true, conflicts_with = "random_start")]
    pub start: Option<StartPose>,
    /// Start at a pose drawn for the seed: anywhere on the floor reachable from the world's
    /// start, clear of walls, rocks and samples, facing any way. The start is home.
    #[arg(long)]
    pub random_start: bool,
}

impl WorldArgs {
    /// The world these options describe for `seed` (the procedural world's layout, the sample
    /// choice and the start yaw).
    pub fn world(&self, seed: u64) -> anyhow::Result<World> {
        let world = match &self.map {
            None => procedural_world(seed),
            Some(map) => {
                let read = |path: &Path| {
                    rover_files::read_at_most(path, rover_imaging::MAX_IMAGE_FILE_BYTES)
                        .context("cannot read a world file")
                };
                let read_optional = |path: &Option<PathBuf>| path.as_deref().map(read).transpose();
                let (map_png, floor_png) = (read(map)?, read_optional(&self.floor)?);
                let (elevation_png, rocks_json) = (read_optional(&self.elevation)?, read_optional(&self.rocks)?);
                let files = UnityFiles {
                    map_png: &map_png,
                    floor_png: floor_png.as_deref(),
                    elevation_png: elevation_png.as_deref(),
                    rocks_json: rocks_json.as_deref(),
                };
                unity_world(&files, seed).with_context(|| format!("the world of {}", self.describe()))?
            }
        };
        let world = world.with_look(Look::from_seed(self.appearance_seed));
        let start = match self.start {
            Some(start) => Some(start),
            None if self.random_start => Some(random_start(&world, seed)?),
            None => None,
        };
        Ok(match start {
            Some(start) => starting_at(world, start)?,
            None => world,
        })
    }

    /// A short description of the world, for logs.
    pub fn describe(&self) -> String {
        let mut text = self.map.as_ref().map_or("a procedural world".to_string(), |p| p.display().to_string());
        for (what, path) in [("floor", &self.floor), ("elevation", &self.elevation), ("rocks", &self.rocks)] {
            if let Some(path) = path {
                text += &format!(", {what} {}", path.display());
            }
        }
        if self.appearance_seed != 0 {
            text += &format!(", appearance seed {}", self.appearance_seed);
        }
        if let Some(start) = self.start {
            text += &format!(", start ({}, {}) yaw {} deg", start.x_m, start.y_m, start.yaw_deg);
        } else if self.random_start {
            text += ", a random start per seed";
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
    /// Token to present to the bridge, as `Authorization: Bearer TOKEN`: the bridge's parameter
    /// simulator_token, when set (the Unity simulator presents none).
    #[arg(long, value_name = "TOKEN")]
    pub token: Option<String>,
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
    /// Write where the rover can drive (white: cells without boulder or steep ground) to this PNG
    /// and exit, e.g. to draw goals or starts on the floor.
    #[arg(long, value_name = "PNG")]
    pub export_drivable: Option<PathBuf>,
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
    let exports = [
        (&args.export_map, "ground-truth map", world.ground_truth()),
        (&args.export_drivable, "drivable cells", &world.drivable_cells()),
    ];
    let wanted: Vec<_> =
        exports.iter().filter_map(|(path, what, cells)| path.as_ref().map(|path| (path, what, cells))).collect();
    for &(path, what, cells) in &wanted {
        std::fs::write(path, World::cells_png(cells)?)
            .with_context(|| format!("cannot write the {what} to {}", path.display()))?;
        println!("wrote the {what} of the world to {}", path.display());
    }
    if !wanted.is_empty() {
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
    let client = ClientConfig { token: args.token.clone(), ..ClientConfig::unity(&args.host, args.port) };
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
