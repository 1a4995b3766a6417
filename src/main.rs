//! `rover`: the autonomy stack of the Udacity rover as a ROS 2 node graph, one subcommand per role.

use std::process::ExitCode;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};
use rover::processes::nodes::{Group, Node, ROS_ARGS_HELP, processes, run_together};
use rover::tools::bag::{BagArgs, BagCommand};
use rover_runtime::params::help_table;
use rover_runtime::{Runtime, Shutdown, logging, split_ros_args};

/// The rover autonomy stack: Socket.IO bridge to the simulator and ROS 2 nodes over DDS.
#[derive(Parser)]
#[command(name = "rover", version, after_help = ROS_ARGS_HELP)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    #[command(flatten)]
    Node(Node),
    /// Run every node (the list of `rover nodes`) in this one process, on one DDS participant.
    /// Aim parameters at a node with -p NODE:NAME:=VALUE or a params file.
    #[command(after_help = ROS_ARGS_HELP)]
    All,
    /// Run the chosen nodes in this one process, on one DDS participant, as a ROS component
    /// container does: e.g. `rover container bridge perception` beside `rover container mapping
    /// decision pickup`. Aim parameters at a node with -p NODE:NAME:=VALUE or a params file.
    #[command(after_help = ROS_ARGS_HELP)]
    Container {
        /// The nodes to run, by name (`rover nodes` lists them).
        #[arg(required = true, value_name = "NODE")]
        nodes: Vec<Node>,
    },
    /// Print the name of every node, one a line, in start order (the launchers read this list);
    /// with --group, one process a line: its nodes, space-separated.
    Nodes {
        /// Run these nodes in one process, e.g. --group bridge,perception; repeatable; every other
        /// node runs alone.
        #[arg(long = "group", value_name = "NODE,NODE...")]
        groups: Vec<Group>,
    },
    /// Bring the graph's nodes, started with -p autostart:=false, up in start order (configure,
    /// then activate), as Nav2's lifecycle manager does; then bring up any node that comes back
    /// unconfigured (respawned), until Ctrl-C.
    #[command(name = "lifecycle-manager", after_help = ROS_ARGS_HELP)]
    LifecycleManager,
    /// Replay a recorded dataset (robot_log.csv + IMG/) through perception and mapping and print
    /// the Udacity scores. Parameters: -p perception:NAME:=VALUE, -p mapping:NAME:=VALUE.
    #[command(after_help = ROS_ARGS_HELP)]
    Replay(rover::tools::replay::ReplayArgs),
    /// Run the demo: the simulator on the built-in procedural world and the whole graph, each node
    /// in its own process, headless; a live progress line, then a summary table, the mission's
    /// picture (PNG: map, path, samples, scores) and the JSON report. Ctrl-C stops everything.
    #[command(after_help = ROS_ARGS_HELP)]
    Demo(rover::missions::demo::DemoArgs),
    /// Run one full mission per seed and print a table of the scores (mapped and fidelity against
    /// the simulator's true world, samples, distance home, time, frames per second, CPU time a frame).
    #[command(after_help = ROS_ARGS_HELP)]
    Eval(rover::missions::eval::EvalArgs),
    /// Compare the simulated world with a recorded one: render the simulator at every logged pose,
    /// classify the real and the simulated image with the perception pipeline, and report how far
    /// their bird's-eye masks agree. Parameters: -p perception:NAME:=VALUE.
    #[command(name = "sim-check", after_help = ROS_ARGS_HELP)]
    SimCheck(rover::tools::sim_check::SimCheckArgs),
    /// Run the headless simulator: connects to the bridge as the Unity simulator does, renders the
    /// camera, simulates the rover and prints a report at the end (or on Ctrl-C).
    Sim(rover_sim::cli::SimArgs),
    /// Record and play rosbag2 bags (MCAP storage) of the graph's topics, as `ros2 bag` does, and
    /// turn a recorded dataset into a bag.
    Bag(rover::tools::bag::BagArgs),
    /// Serve the graph's camera and its calibration, map, odometry, TF, rocks, mode, plan and
    /// telemetry live to Foxglove
    /// (Open connection, Foxglove WebSocket, ws://127.0.0.1:8765) until Ctrl-C.
    #[command(name = "live-view", after_help = ROS_ARGS_HELP)]
    LiveView(rover::tools::live_view::LiveViewArgs),
    /// Print nftables rules that let a DDS domain's traffic in from this host and the allowed
    /// peers only (apply with `rover dds-firewall | sudo nft -f -`): the DDS library listens on
    /// every interface, so without them any host that reaches its ports can send a node packets
    /// that make it allocate gigabytes.
    #[command(name = "dds-firewall")]
    DdsFirewall(rover::tools::dds_firewall::DdsFirewallArgs),
}

/// The command line, with each node's parameter table in its long help.
fn cli_command() -> clap::Command {
    Node::ALL.into_iter().fold(Cli::command(), |command, node| {
        command.mut_subcommand(node.name(), |c| c.after_long_help(node_help(node)))
    })
}

fn node_help(node: Node) -> String {
    format!("{}\n{ROS_ARGS_HELP}", help_table(&node.param_specs()))
}

fn main() -> ExitCode {
    let (own_args, ros_args) = match split_ros_args(std::env::args().collect()) {
        Ok(split) => split,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    let matches = cli_command().get_matches_from(own_args);
    let cli = match Cli::from_arg_matches(&matches) {
        Ok(cli) => cli,
        Err(e) => e.exit(),
    };
    // The demo's own log would break its progress line: warnings only, unless asked otherwise.
    let quiet = matches!(cli.command, Command::Demo(_)) && std::env::var_os("RUST_LOG").is_none();
    let mut logs = ros_args.logs.clone();
    if quiet && logs.level.is_none() {
        logs.level = Some("warn");
    }
    logging::init(&logs);
    let runtime = match tokio::runtime::Builder::new_multi_thread().enable_all().build() {
        Ok(runtime) => runtime,
        Err(e) => {
            eprintln!("error: cannot start the async runtime: {e}");
            return ExitCode::FAILURE;
        }
    };
    let mut participant = None;
    let result = runtime.block_on(run(cli.command, ros_args, &mut participant));
    // The tasks that own subscriptions and spinners go first, the DDS participant they use last.
    drop(runtime);
    drop(participant);
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            tracing::error!("{e:#}");
            ExitCode::FAILURE
        }
    }
}

/// The ROS arguments as given on the command line (after `--ros-args`), for child processes.
fn raw_ros_args() -> Vec<String> {
    std::env::args().skip_while(|a| a != "--ros-args").skip(1).collect()
}

/// The DDS runtime of the process, kept in `slot` so that it outlives the async tasks.
fn dds(slot: &mut Option<Runtime>, ros_args: rover_runtime::RosArgs, shutdown: Shutdown) -> anyhow::Result<&Runtime> {
    Ok(slot.insert(Runtime::new(ros_args, shutdown)?))
}

async fn run(
    command: Command,
    ros_args: rover_runtime::RosArgs,
    participant: &mut Option<Runtime>,
) -> anyhow::Result<()> {
    let shutdown = Shutdown::on_signals();
    match command {
        Command::Node(node) => node.run(dds(participant, ros_args, shutdown)?).await,
        Command::All => run_together(dds(participant, ros_args, shutdown)?, &Node::ALL).await,
        Command::Container { nodes } => run_together(dds(participant, ros_args, shutdown)?, &nodes).await,
        Command::LifecycleManager => {
            rover::processes::lifecycle_manager::run(dds(participant, ros_args, shutdown)?).await
        }
        Command::DdsFirewall(args) => rover::tools::dds_firewall::run(&args),
        Command::Nodes { groups } => {
            for process in processes(&groups)? {
                println!("{}", process.iter().map(|node| node.name()).collect::<Vec<_>>().join(" "));
            }
            Ok(())
        }
        Command::Replay(args) if args.via_dds => {
            rover::tools::replay::run_via_dds(&args, dds(participant, ros_args, shutdown)?).await.map(drop)
        }
        Command::Replay(args) => {
            let perception = rover_runtime::resolve_params(Node::Perception.name(), &ros_args)?;
            let mapping = rover_runtime::resolve_params(Node::Mapping.name(), &ros_args)?;
            rover::tools::replay::run(&args, &perception, &mapping).map(drop)
        }
        Command::Eval(args) => {
            let settings = rover::missions::in_process::NodeSettings::resolve(&ros_args)?;
            let results = if args.in_process {
                rover::missions::eval::run_in_process_eval(&args, &settings, &shutdown)?
            } else {
                rover::missions::eval::run_graph_eval(&args, dds(participant, ros_args, shutdown)?, &raw_ros_args())
                    .await?
            };
            if args.json {
                println!("{}", serde_json::to_string_pretty(&results)?);
            } else {
                print!("{}", rover::missions::eval::table(&results));
            }
            Ok(())
        }
        Command::Demo(args) => {
            rover::missions::demo::run_demo(&args, dds(participant, ros_args, shutdown)?, &raw_ros_args())
                .await
                .map(drop)
        }
        Command::SimCheck(args) => {
            let perception = rover_runtime::resolve_params(Node::Perception.name(), &ros_args)?;
            let report = rover::tools::sim_check::check(&args, &perception)?;
            if args.json {
                println!("{}", serde_json::to_string_pretty(&report)?);
            } else {
                print!("{}", rover::tools::sim_check::table(&report));
            }
            Ok(())
        }
        Command::Sim(args) => rover_sim::cli::run(&args, async move { shutdown.wait().await }).await.map(drop),
        Command::Bag(BagArgs { command: BagCommand::Record(args) }) => {
            rover::tools::bag::record::record(&args, dds(participant, ros_args, shutdown)?).await.map(drop)
        }
        Command::Bag(BagArgs { command: BagCommand::Play(args) }) => {
            rover::tools::bag::play::play(&args, dds(participant, ros_args, shutdown)?).await.map(drop)
        }
        Command::Bag(BagArgs { command: BagCommand::FromDataset(args) }) => {
            rover::tools::bag::from_dataset::from_dataset(&args, &ros_args).map(drop)
        }
        Command::Bag(BagArgs { command: BagCommand::Info(args) }) => {
            rover::tools::bag::info::info(&args).map(|text| print!("{text}"))
        }
        Command::LiveView(args) => rover::tools::live_view::run(&args, dds(participant, ros_args, shutdown)?).await,
    }
}
