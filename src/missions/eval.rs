//! `rover eval`: one full mission per seed, scored against the simulator's true world, as a table
//! or JSON.

use std::collections::BTreeMap;
use std::ops::RangeInclusive;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use rover_decision::machine::Mode;
use rover_runtime::{Runtime, Shutdown};
use rover_sim::sim::{SimConfig, SimReport};
use serde::Serialize;

use crate::missions::chaos::Chaos;
use crate::missions::in_graph::run_graph_mission;
use crate::missions::in_process::{NodeSettings, Progress, Replies, run_in_process};
use crate::missions::picture::{MissionMap, write_mission_png};
use crate::missions::time_by_mode::{self, TimeByMode};
use crate::missions::timeline::Timeline;
use crate::processes::cpu::{CpuMeter, ms_per_frame};
use crate::processes::graph::{GraphConfig, RemoteNodes, free_port, log_dir};
use crate::processes::nodes::Node;

/// Options of `rover eval`.
#[derive(Debug, Clone, clap::Args)]
pub struct EvalArgs {
    /// The world: --map PNG, or --procedural for the procedural world of each seed.
    #[command(flatten)]
    pub world: rover_sim::cli::WorldArgs,
    /// Procedural worlds, one per seed (instead of --map).
    #[arg(long)]
    pub procedural: bool,
    /// Seeds, e.g. 0..9 (inclusive) or 4.
    #[arg(long, default_value = "0..9", value_parser = parse_seeds)]
    pub seeds: RangeInclusive<u64>,
    /// Print one JSON list instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Run every node as a library in this process (no DDS, no sockets): the fast development loop.
    #[arg(long)]
    pub in_process: bool,
    /// End a mission after this much simulated time, seconds.
    #[arg(long, default_value_t = 1200.0, value_name = "SECONDS")]
    pub max_sim_seconds: f64,
    /// Write each run's picture (the final map, path, samples and scores) as PNG into this folder.
    #[arg(long, value_name = "DIR")]
    pub maps: Option<PathBuf>,
    /// Kill a random node (SIGKILL) every CHAOS_PERIOD_S simulated seconds; the graph starts it
    /// again and the mission must go on.
    #[arg(long, conflicts_with_all = ["in_process", "no_respawn"])]
    pub chaos: bool,
    /// Simulated seconds between two kills of --chaos.
    #[arg(long, default_value_t = 60.0, value_name = "SECONDS", requires = "chaos")]
    pub chaos_period_s: f64,
    /// End a mission when a node dies, instead of starting the node again.
    #[arg(long, conflicts_with = "in_process")]
    pub no_respawn: bool,
    /// Start these nodes on another host through --remote-exec, e.g. mapping,decision,pickup
    /// (`tools/two-hosts` does).
    #[arg(long, value_name = "NODES", value_delimiter = ',', requires = "remote_exec", conflicts_with = "in_process")]
    pub remote_nodes: Vec<String>,
    /// The command that runs a program on the other host, e.g. "ip netns exec base".
    #[arg(long, value_name = "COMMAND", requires = "remote_nodes")]
    pub remote_exec: Option<String>,
}

impl EvalArgs {
    /// The nodes to start on another host, checked against the graph's node names.
    fn remote_nodes(&self) -> anyhow::Result<Option<RemoteNodes>> {
        let Some(exec) = &self.remote_exec else { return Ok(None) };
        let names: Vec<&str> = Node::ALL.iter().map(|n| n.name()).collect();
        if let Some(unknown) = self.remote_nodes.iter().find(|n| !names.contains(&n.as_str())) {
            anyhow::bail!("--remote-nodes {unknown:?}: expected some of {}", names.join(", "));
        }
        let exec: Vec<String> = exec.split_whitespace().map(str::to_string).collect();
        anyhow::ensure!(!exec.is_empty(), "--remote-exec is empty: expected a command such as \"ip netns exec base\"");
        Ok(Some(RemoteNodes { nodes: self.remote_nodes.clone(), exec }))
    }
}

/// Parses `A..B` (inclusive) or a single seed.
pub fn parse_seeds(text: &str) -> Result<RangeInclusive<u64>, String> {
    let number = |s: &str| s.trim().parse::<u64>().map_err(|_| format!("{s:?} is not a seed number"));
    match text.split_once("..") {
        Some((a, b)) => {
            let (a, b) = (number(a)?, number(b.trim_start_matches('='))?);
            if a > b {
                return Err(format!("seeds {text:?}: the first must not exceed the last"));
            }
            Ok(a..=b)
        }
        None => number(text).map(|n| n..=n),
    }
}

/// One mission's result.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct RunResult {
    /// Seed of the world and the samples.
    pub seed: u64,
    /// Udacity mapped %, against the simulator's true world.
    pub mapped_pct: f64,
    /// Udacity fidelity %.
    pub fidelity_pct: f64,
    /// Fidelity % against the world's open floor (flat, no rock) instead of the ground truth,
    /// whose conservative edge leaves out the floor at the foot of the walls.
    pub floor_fidelity_pct: f64,
    /// Samples located on the map.
    pub located: usize,
    /// Samples picked up.
    pub collected: usize,
    /// Samples in the world.
    pub samples: usize,
    /// Final distance to the start, metres.
    pub home_distance_m: f64,
    /// Simulated time, seconds.
    pub sim_seconds: f64,
    /// Wall-clock time, seconds.
    pub wall_seconds: f64,
    /// Frames per wall-clock second, end to end.
    pub frames_per_second: f64,
    /// CPU time a frame took, all processes together (user and system), milliseconds.
    pub cpu_ms_per_frame: f64,
    /// The same by process: `simulator` (with its Unity client and the evaluator) and each node,
    /// or `in_process` for a mission in one process.
    pub cpu_ms_per_frame_by_process: BTreeMap<String, f64>,
    /// The decision's final mode.
    pub final_mode: String,
    /// Distance driven, metres.
    pub distance_m: f64,
    /// Simulated seconds by activity: the decision's modes, and picking up, turning in place and
    /// standing still apart from them.
    pub time_by_mode_s: TimeByMode,
    /// When samples were collected and how the mapped share grew.
    #[serde(flatten)]
    pub timeline: Timeline,
    /// How the bridge answered (all zero in process): late frames change the course of a graph
    /// mission on a loaded machine or a slow link.
    #[serde(flatten)]
    pub replies: Replies,
}

impl RunResult {
    /// Whether the run meets the mission targets: mapped >= 90 %, fidelity >= 85 %, every sample
    /// collected, stopped within 3 m of the start, within 1,200 simulated seconds.
    pub fn complete(&self) -> bool {
        self.mapped_pct >= 90.0
            && self.fidelity_pct >= 85.0
            && self.collected == self.samples
            && self.home_distance_m <= 3.0
            && self.sim_seconds <= 1200.0
            && self.final_mode == Mode::Done.name()
    }

    /// The result of the mission of `seed` in a world with `samples` samples, whose processes
    /// used the CPU times `cpu`.
    pub fn of(
        seed: u64,
        samples: usize,
        report: &SimReport,
        progress: &Progress,
        wall_seconds: f64,
        cpu: &BTreeMap<String, Duration>,
    ) -> Self {
        let cpu_ms_per_frame_by_process = ms_per_frame(cpu, report.frames);
        RunResult {
            seed,
            mapped_pct: progress.mapped_pct,
            fidelity_pct: progress.fidelity_pct,
            floor_fidelity_pct: progress.floor_fidelity_pct,
            located: progress.located,
            collected: report.samples_collected,
            samples,
            home_distance_m: report.final_distance_to_start_m,
            sim_seconds: report.sim_seconds,
            wall_seconds,
            frames_per_second: report.frames as f64 / wall_seconds.max(1e-9),
            cpu_ms_per_frame: cpu_ms_per_frame_by_process.values().sum(),
            cpu_ms_per_frame_by_process,
            final_mode: progress.mode.clone(),
            distance_m: report.distance_m,
            time_by_mode_s: progress.time_by_mode.clone(),
            timeline: progress.timeline.clone(),
            replies: progress.replies,
        }
    }
}

impl EvalArgs {
    fn world(&self, seed: u64) -> anyhow::Result<rover_sim::world::World> {
        anyhow::ensure!(
            self.world.map.is_some() != self.procedural,
            "give either --map PNG or --procedural (one procedural world per seed)"
        );
        self.world.world(seed)
    }
}

/// The name the CPU time of a mission in one process goes by.
const IN_PROCESS: &str = "in_process";

/// Runs every seed in-process and returns the results; a `shutdown` request (Ctrl-C) ends the run
/// with an error naming the seed.
pub fn run_in_process_eval(
    args: &EvalArgs,
    settings: &NodeSettings,
    shutdown: &Shutdown,
) -> anyhow::Result<Vec<RunResult>> {
    let mut results = Vec::new();
    for seed in args.seeds.clone() {
        let world = args.world(seed)?;
        let samples = world.samples.len();
        let this_process = [(IN_PROCESS, std::process::id())];
        let cpu_meter = CpuMeter::start(this_process);
        let progress_every_frames = (PROGRESS_EVERY_SIM_S / settings.decision.frame_period_s).round() as u64;
        let outcome = run_in_process(world, settings, args.max_sim_seconds, progress_every_frames, shutdown, |p| {
            print_progress(seed, p)
        })
        .with_context(|| format!("seed {seed}"))?;
        let report = &outcome.report;
        let cpu = cpu_meter.used(this_process);
        let result = RunResult::of(seed, samples, report, &outcome.progress, report.wall_seconds, &cpu);
        if let Some(dir) = &args.maps {
            save_picture(dir, &outcome.mission_map, &result)?;
        }
        results.push(result);
    }
    Ok(results)
}

/// Runs every seed with each node in its own process (started from this executable with the ROS
/// arguments `ros_args`), the evaluator on `runtime`, and returns the results.
pub async fn run_graph_eval(args: &EvalArgs, runtime: &Runtime, ros_args: &[String]) -> anyhow::Result<Vec<RunResult>> {
    let mut results = Vec::new();
    for seed in args.seeds.clone() {
        let world = args.world(seed)?;
        let samples = world.samples.len();
        let mut config = GraphConfig::of_current_exe(free_port()?, log_dir("eval").join(format!("seed{seed}")))?;
        config.ros_args = ros_args.to_vec();
        config.respawn = !args.no_respawn;
        config.remote = args.remote_nodes()?;
        let sim_config = SimConfig { max_sim_seconds: Some(args.max_sim_seconds), ..SimConfig::default() };
        let started = Instant::now();
        let mut next_line_s = PROGRESS_EVERY_SIM_S;
        let mut chaos = args.chaos.then(|| Chaos::every(args.chaos_period_s, args.max_sim_seconds, seed));
        let mut kills = Vec::new();
        let outcome = run_graph_mission(runtime, config, world, sim_config, |p, graph| {
            if let Some(chaos) = chaos.as_mut() {
                kills.extend(chaos.act(p.sim_seconds, graph).into_iter().map(|node| node.name()));
            }
            if p.sim_seconds >= next_line_s {
                print_progress(seed, p);
                next_line_s += PROGRESS_EVERY_SIM_S;
            }
        })
        .await?;
        if args.chaos {
            eprintln!("seed {seed}: chaos killed {} nodes: {}", kills.len(), kills.join(", "));
        }
        if runtime.shutdown().is_requested() {
            anyhow::bail!("interrupted during seed {seed}");
        }
        let wall_seconds = started.elapsed().as_secs_f64();
        let result = RunResult::of(seed, samples, &outcome.report, &outcome.progress, wall_seconds, &outcome.cpu);
        if let Some(dir) = &args.maps {
            save_picture(dir, &outcome.mission_map, &result)?;
        }
        results.push(result);
    }
    Ok(results)
}

/// Simulated seconds between two progress lines of a graph run.
const PROGRESS_EVERY_SIM_S: f64 = 100.0;

fn print_progress(seed: u64, p: &Progress) {
    eprintln!(
        "seed {seed}: {:>6.0} s  mapped {:>5.1} %  fidelity {:>5.1} %  located {}  collected {}  {}",
        p.sim_seconds, p.mapped_pct, p.fidelity_pct, p.located, p.collected, p.mode
    );
}

/// Writes the picture of the mission that gave `result` into `dir` as `map_seedN.png`.
fn save_picture(dir: &Path, mission: &MissionMap, result: &RunResult) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    write_mission_png(&dir.join(format!("map_seed{}.png", result.seed)), mission, result)
}

/// The results as a table.
pub fn table(results: &[RunResult]) -> String {
    let mut out = String::from(
        "seed  mapped %  fidelity %  on floor %  located  collected  home m  sim s   wall s  frames/s  CPU ms/frame  mode         complete\n",
    );
    for r in results {
        out += &format!(
            "{:>4}  {:>8.1}  {:>10.1}  {:>10.1}  {:>7}  {:>9}  {:>6.1}  {:>6.0}  {:>7.1}  {:>8.0}  {:>12.2}  {:<12} {}\n",
            r.seed,
            r.mapped_pct,
            r.fidelity_pct,
            r.floor_fidelity_pct,
            r.located,
            format!("{}/{}", r.collected, r.samples),
            r.home_distance_m,
            r.sim_seconds,
            r.wall_seconds,
            r.frames_per_second,
            r.cpu_ms_per_frame,
            r.final_mode,
            if r.complete() { "yes" } else { "no" }
        );
    }
    let complete = results.iter().filter(|r| r.complete()).count();
    out += &format!("{complete} of {} complete\n", results.len());
    out += &cpu_line(results);
    out += "\n";
    out += &time_table(results);
    out
}

/// The CPU time a frame took in each process, the mean over the runs it was measured in, as one
/// line (none for missions in one process).
fn cpu_line(results: &[RunResult]) -> String {
    let mut sums: BTreeMap<&str, (f64, usize)> = BTreeMap::new();
    for (name, ms) in results.iter().flat_map(|r| &r.cpu_ms_per_frame_by_process) {
        let (sum, runs) = sums.entry(name).or_default();
        (*sum, *runs) = (*sum + ms, *runs + 1);
    }
    if sums.len() < 2 {
        return String::new();
    }
    let parts: Vec<String> =
        sums.iter().map(|(name, (sum, runs))| format!("{name} {:.2}", sum / *runs as f64)).collect();
    format!("CPU ms a frame by process (mean of the runs): {}\n", parts.join(", "))
}

/// The activities of the time table, with their column titles.
const ACTIVITIES: [(&str, &str); 7] = [
    (Mode::Explore.name(), "explore"),
    (Mode::ApproachSample.name(), "approach"),
    (time_by_mode::PICKUP, "pickup"),
    (Mode::Recover.name(), "recover"),
    (Mode::ReturnHome.name(), "home"),
    (time_by_mode::TURNING_IN_PLACE, "turning"),
    (time_by_mode::STOPPED, "stopped"),
];

/// Where each mission's time went, simulated seconds by activity, when the last sample was
/// collected, the distance driven, and the frames whose drive command came too late for the bridge.
pub fn time_table(results: &[RunResult]) -> String {
    let mut out = String::from("seed");
    for (_, title) in ACTIVITIES {
        out += &format!("  {title:>8}");
    }
    out += "  last sample s  distance m  late frames  brakes  reply p50 ms  p99 ms\n";
    for r in results {
        out += &format!("{:>4}", r.seed);
        for (activity, _) in ACTIVITIES {
            out += &format!("  {:>8.0}", r.time_by_mode_s.seconds(activity));
        }
        let replies = &r.replies;
        let last_sample = r.timeline.collected_at_s.last().map_or("-".to_string(), |s| format!("{s:.0}"));
        out += &format!(
            "  {last_sample:>13}  {:>10.0}  {:>11}  {:>6}  {:>12.2}  {:>6.2}\n",
            r.distance_m, replies.deadline_misses, replies.silence_brakes, replies.reply_p50_ms, replies.reply_p99_ms
        );
    }
    out
}

#[cfg(test)]
impl RunResult {
    /// A run for tests: seed 3, 725 s, five of six samples, the last collected at 700 s.
    pub(crate) fn example() -> Self {
        RunResult {
            seed: 3,
            mapped_pct: 91.5,
            fidelity_pct: 88.0,
            floor_fidelity_pct: 99.5,
            located: 6,
            collected: 5,
            samples: 6,
            home_distance_m: 1.2,
            sim_seconds: 725.0,
            wall_seconds: 60.0,
            frames_per_second: 300.0,
            cpu_ms_per_frame: 3.5,
            cpu_ms_per_frame_by_process: BTreeMap::from([
                ("simulator".to_string(), 2.5),
                ("perception".to_string(), 1.0),
            ]),
            final_mode: Mode::Done.name().to_string(),
            distance_m: 900.0,
            time_by_mode_s: TimeByMode::default(),
            timeline: Timeline {
                collected_at_s: vec![40.0, 180.0, 320.0, 510.0, 700.0],
                mapped_pct_by_100_s: vec![20.0, 35.0, 50.0, 62.0, 75.0, 84.0, 91.0],
            },
            replies: Replies::default(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_time_table_shows_when_the_last_sample_came() {
        let run = RunResult::example();
        let none = RunResult { timeline: Timeline::default(), seed: 4, ..run.clone() };
        let table = time_table(&[run, none]);
        let row = |seed: &str| table.lines().find(|l| l.split_whitespace().next() == Some(seed)).unwrap().to_string();
        assert!(table.lines().next().unwrap().contains("last sample s"), "{table}");
        assert_eq!(row("3").split_whitespace().nth(8), Some("700"), "{table}");
        assert_eq!(row("4").split_whitespace().nth(8), Some("-"), "{table}");
    }

    #[test]
    fn the_table_shows_the_cpu_of_a_frame_in_all_and_by_process() {
        let run = RunResult::example();
        let other = RunResult {
            seed: 4,
            cpu_ms_per_frame: 5.0,
            cpu_ms_per_frame_by_process: BTreeMap::from([
                ("simulator".to_string(), 3.5),
                ("perception".to_string(), 1.0),
                ("decision".to_string(), 0.5),
            ]),
            ..run.clone()
        };
        let table = table(&[run.clone(), other]);
        let header = table.lines().next().unwrap();
        let row = table.lines().find(|l| l.split_whitespace().next() == Some("4")).unwrap();
        let column = header.split("  ").filter(|t| !t.is_empty()).position(|t| t.trim() == "CPU ms/frame").unwrap();
        assert_eq!(row.split_whitespace().nth(column), Some("5.00"), "{table}");
        assert!(
            table.contains(
                "CPU ms a frame by process (mean of the runs): decision 0.50, perception 1.00, simulator 3.00"
            ),
            "{table}"
        );
        let in_process =
            RunResult { cpu_ms_per_frame_by_process: BTreeMap::from([(IN_PROCESS.to_string(), 3.0)]), ..run };
        assert!(!super::table(&[in_process]).contains("by process"), "one process has no split");
    }

    #[test]
    fn seed_ranges() {
        assert_eq!(parse_seeds("0..9"), Ok(0..=9));
        assert_eq!(parse_seeds("4"), Ok(4..=4));
        assert_eq!(parse_seeds("2..=3"), Ok(2..=3));
        assert!(parse_seeds("5..1").unwrap_err().contains("must not exceed"));
        assert!(parse_seeds("a..3").unwrap_err().contains("\"a\""));
    }
}
