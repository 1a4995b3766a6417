//! `rover demo`: the simulator and the whole graph, each node in its own process, headless; one
//! live progress line, then a summary table, the mission's picture as PNG and the JSON report.

use std::io::{IsTerminal as _, Write as _};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use rover_runtime::Runtime;
use rover_sim::sim::{SimConfig, SimReport};
use serde::Serialize;

use crate::missions::eval::{RunResult, table};
use crate::missions::in_graph::run_graph_mission;
use crate::missions::in_process::Progress;
use crate::missions::picture::write_mission_png;
use crate::processes::graph::{GraphConfig, free_port};
use crate::tools::bag::record::Recorder;
use crate::tools::bag::summary;
use crate::tools::live_view::{self, LiveView, LiveViewArgs};

/// Without a terminal, a progress line is printed every this many simulated seconds.
const LINE_EVERY_SIM_S: f64 = 50.0;
/// How long the recorder goes on after the graph has stopped, for the messages still on their way.
const LAST_MESSAGES_GRACE: Duration = Duration::from_millis(500);

/// Options of `rover demo`.
#[derive(Debug, Clone, clap::Args)]
pub struct DemoArgs {
    /// The world (default: the built-in procedural world of --seed).
    #[command(flatten)]
    pub world: rover_sim::cli::WorldArgs,
    /// Seed of the world, the sample choice and the start yaw.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// End the mission after this much simulated time, seconds.
    #[arg(long, default_value_t = 1200.0, value_name = "SECONDS")]
    pub max_sim_seconds: f64,
    /// Pace the simulation to the wall clock (default: as fast as the graph answers).
    #[arg(long)]
    pub realtime: bool,
    /// Folder for the mission's picture (map.png: the final map over the true world, the path,
    /// the samples and the scores), the JSON report (report.json) and the node logs.
    #[arg(long, default_value = "rover-demo", value_name = "DIR")]
    pub out: PathBuf,
    /// End the mission when a node dies, instead of starting the node again.
    #[arg(long)]
    pub no_respawn: bool,
    /// Record every topic of the graph into this new rosbag2 bag folder (as `rover bag record -a`).
    #[arg(long, value_name = "DIR")]
    pub record: Option<PathBuf>,
    /// Serve the mission live to Foxglove on ws://127.0.0.1:8765 (as `rover live-view`); with
    /// --realtime it plays at the speed a person watches.
    #[arg(long)]
    pub foxglove: bool,
    /// Port of --foxglove.
    #[arg(long, default_value_t = live_view::DEFAULT_PORT, value_name = "PORT", requires = "foxglove")]
    pub foxglove_port: u16,
}

/// The JSON report of a demo run.
#[derive(Debug, Serialize)]
struct DemoReport<'a> {
    result: &'a RunResult,
    complete: bool,
    simulator: &'a SimReport,
}

/// Runs the demo mission; `ros_args` go to every node.
pub async fn run_demo(args: &DemoArgs, runtime: &Runtime, ros_args: &[String]) -> anyhow::Result<RunResult> {
    std::fs::create_dir_all(&args.out).with_context(|| format!("cannot create {}", args.out.display()))?;
    let world = args.world.world(args.seed)?;
    let samples = world.samples.len();
    let mut config = GraphConfig::of_current_exe(free_port()?, args.out.join("logs"))?;
    config.ros_args = ros_args.to_vec();
    config.respawn = !args.no_respawn;
    eprintln!(
        "rover demo: {} (seed {}), {samples} samples; node logs in {}; Ctrl-C stops",
        args.world.describe(),
        args.seed,
        config.log_dir.display()
    );
    let sim_config =
        SimConfig { realtime: args.realtime, max_sim_seconds: Some(args.max_sim_seconds), ..SimConfig::default() };
    let recording = match &args.record {
        Some(dir) => Some((Recorder::start(runtime, dir, &[])?, dir)),
        None => None,
    };
    let live_view = if args.foxglove {
        let view_args = LiveViewArgs::local(args.foxglove_port);
        Some(LiveView::start(runtime, &view_args).await?)
    } else {
        None
    };
    let started = Instant::now();
    let mut line = ProgressLine::new(samples);
    let outcome = run_graph_mission(runtime, config, world, sim_config, |p, _| line.show(p)).await;
    if let Ok(outcome) = &outcome {
        line.finish(&outcome.progress);
    }
    if let Some((recorder, dir)) = recording {
        finish_recording(recorder, dir).await?;
    }
    if let Some(view) = live_view {
        view.stop().await;
    }
    let outcome = outcome?;
    let wall_seconds = started.elapsed().as_secs_f64();
    let result = RunResult::of(args.seed, samples, &outcome.report, &outcome.progress, wall_seconds, &outcome.cpu);
    print!("{}", table(std::slice::from_ref(&result)));
    let path = args.out.join("map.png");
    write_mission_png(&path, &outcome.mission_map, &result)?;
    println!("map: {}", path.display());
    let report = DemoReport { result: &result, complete: result.complete(), simulator: &outcome.report };
    let path = args.out.join("report.json");
    std::fs::write(&path, serde_json::to_string_pretty(&report)?)
        .with_context(|| format!("cannot write {}", path.display()))?;
    println!("report: {}", path.display());
    if !outcome.unclean_nodes.is_empty() {
        tracing::warn!("nodes that did not stop cleanly: {}", outcome.unclean_nodes.join(", "));
    }
    Ok(result)
}

/// Ends the recording of the mission into `dir` once the last messages of the stopped nodes
/// (the mapping node's final map) have arrived, and prints the bag's summary.
async fn finish_recording(recorder: Recorder, dir: &Path) -> anyhow::Result<()> {
    tokio::time::sleep(LAST_MESSAGES_GRACE).await;
    let metadata = recorder.finish().await?;
    print!("{}", summary(dir, &metadata));
    Ok(())
}

/// The live progress line: rewritten in place on a terminal, one line per 50 sim seconds otherwise.
struct ProgressLine {
    samples: usize,
    terminal: bool,
    next_line_s: f64,
}

impl ProgressLine {
    fn new(samples: usize) -> Self {
        ProgressLine { samples, terminal: std::io::stderr().is_terminal(), next_line_s: 0.0 }
    }

    fn text(&self, p: &Progress) -> String {
        format!(
            "sim {:>6.1} s | mapped {:>5.1} % | fidelity {:>5.1} % | samples located {} collected {} of {} | {}",
            p.sim_seconds, p.mapped_pct, p.fidelity_pct, p.located, p.collected, self.samples, p.mode
        )
    }

    fn show(&mut self, p: &Progress) {
        if self.terminal {
            eprint!("\r\x1b[K{}", self.text(p));
            let _ = std::io::stderr().flush();
        } else if p.sim_seconds >= self.next_line_s {
            eprintln!("{}", self.text(p));
            self.next_line_s += LINE_EVERY_SIM_S;
        }
    }

    fn finish(&mut self, p: &Progress) {
        if self.terminal {
            eprintln!("\r\x1b[K{}", self.text(p));
        } else {
            eprintln!("{}", self.text(p));
        }
    }
}
