//! The node graph as separate processes: each node is the `rover` executable with its subcommand,
//! started on one DDS domain with the same ROS arguments, its log in a file of its own. Used by
//! `rover demo`, `rover eval` and the tests that need the whole graph.

use std::fs::File;
use std::io::Write as _;
use std::path::PathBuf;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use nix::sys::signal::Signal;
use nix::unistd::Pid;

use crate::processes::nodes::node_names;

/// How a graph is started.
#[derive(Debug, Clone)]
pub struct GraphConfig {
    /// The `rover` executable.
    pub rover: PathBuf,
    /// `ROS_DOMAIN_ID` of every node (`None`: inherit the environment's).
    pub domain_id: Option<u16>,
    /// TCP port of the bridge's Socket.IO server.
    pub port: u16,
    /// ROS arguments given to every node after `--ros-args` (e.g. `--params-file`, `-r __ns:=/a`).
    pub ros_args: Vec<String>,
    /// Folder of the log files, one per node, and of the nodes' state (`state/`).
    pub log_dir: PathBuf,
    /// Start a node that dies again, after a back-off (see [`Graph::respawn_dead`]).
    pub respawn: bool,
    /// Nodes started on another host (`None`: all on this one).
    pub remote: Option<RemoteNodes>,
    /// Environment variables every node gets besides this process's (e.g. `ROS_SECURITY_ENABLE`).
    pub env: Vec<(String, String)>,
}

/// Nodes that run on another host, each started through a command prefix that runs a program
/// there (e.g. `ip netns exec base`, as `tools/two-hosts` does).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RemoteNodes {
    /// The nodes' names, e.g. `mapping`.
    pub nodes: Vec<String>,
    /// The command prefix; the node's own command line follows it.
    pub exec: Vec<String>,
}

impl GraphConfig {
    /// A graph of this very executable (`rover`), logging into `log_dir`.
    pub fn of_current_exe(port: u16, log_dir: PathBuf) -> anyhow::Result<Self> {
        let rover = std::env::current_exe().context("cannot find the rover executable")?;
        let (ros_args, env) = (Vec::new(), Vec::new());
        Ok(GraphConfig { rover, domain_id: None, port, ros_args, log_dir, respawn: true, remote: None, env })
    }

    /// The folder where the nodes keep what a restarted node carries on from (the mapping and
    /// decision nodes' snapshots): one per graph, so a new graph starts afresh.
    pub fn state_dir(&self) -> PathBuf {
        self.log_dir.join("state")
    }

    /// The log file of node `name`.
    pub fn log_file(&self, name: &str) -> PathBuf {
        self.log_dir.join(format!("{name}.log"))
    }
}

/// One node process (or, through [`NodeProcess::spawn`], any child process, as the tests start);
/// interrupted (SIGINT) when dropped, killed if it does not stop.
#[derive(Debug)]
pub struct NodeProcess {
    /// The process's name: a node's subcommand, e.g. `decision`.
    pub name: String,
    /// The log file (stderr of the process).
    pub log: PathBuf,
    child: Child,
}

impl NodeProcess {
    /// Starts `rover NAME --ros-args ...` as `config` says, with a new log file.
    pub fn start(config: &GraphConfig, name: &str) -> anyhow::Result<Self> {
        let log = Self::log_path(config, name)?;
        let file = File::create(&log).with_context(|| format!("cannot create {}", log.display()))?;
        Self::spawn_logging_to(name, Self::command(config, name), log, file)
    }

    /// Starts node `name` again, its log appended to the earlier process's.
    pub fn start_again(config: &GraphConfig, name: &str) -> anyhow::Result<Self> {
        let log = Self::log_path(config, name)?;
        let mut file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&log)
            .with_context(|| format!("cannot open {}", log.display()))?;
        writeln!(file, "---- {name} started again ----").with_context(|| format!("cannot write {}", log.display()))?;
        Self::spawn_logging_to(name, Self::command(config, name), log, file)
    }

    fn log_path(config: &GraphConfig, name: &str) -> anyhow::Result<PathBuf> {
        std::fs::create_dir_all(&config.log_dir)
            .with_context(|| format!("cannot create the log folder {}", config.log_dir.display()))?;
        Ok(config.log_file(name))
    }

    fn command(config: &GraphConfig, name: &str) -> Command {
        let remote = config.remote.as_ref().filter(|r| r.nodes.iter().any(|n| n == name));
        let mut command = match remote.and_then(|r| r.exec.split_first()) {
            Some((program, prefix)) => {
                let mut command = Command::new(program);
                command.args(prefix).arg(&config.rover);
                command
            }
            None => Command::new(&config.rover),
        };
        command.arg(name).arg("--ros-args").args(&config.ros_args);
        // Its own DDS Security enclave, used when ROS_SECURITY_ENABLE=true.
        command.args(["--enclave", &crate::processes::nodes::enclave_of(name)]);
        // Aimed at one node each, so they also reach the nodes of `rover all`; the others ignore them.
        command.args(["-p", &format!("bridge:port:={}", config.port)]);
        for node in ["mapping", "decision"] {
            command.args(["-p", &format!("{node}:state_dir:={}", config.state_dir().display())]);
        }
        if let Some(id) = config.domain_id {
            command.env("ROS_DOMAIN_ID", id.to_string());
        }
        command.envs(config.env.iter().map(|(name, value)| (name, value)));
        command
    }

    /// Starts `command` as the process called `name`, stdin and stdout closed, stderr into the
    /// new file `log`.
    pub fn spawn(name: &str, command: Command, log: PathBuf) -> anyhow::Result<Self> {
        let file = File::create(&log).with_context(|| format!("cannot create {}", log.display()))?;
        Self::spawn_logging_to(name, command, log, file)
    }

    fn spawn_logging_to(name: &str, mut command: Command, log: PathBuf, stderr: File) -> anyhow::Result<Self> {
        let child = command
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(stderr)
            .spawn()
            .with_context(|| format!("cannot start {} for {name}", command.get_program().display()))?;
        Ok(NodeProcess { name: name.to_string(), log, child })
    }

    /// The process id.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// The exit status, if the process has ended.
    pub fn exited(&mut self) -> Option<ExitStatus> {
        self.child.try_wait().ok().flatten()
    }

    /// Waits up to `timeout` for the process to exit; its exit status if it did.
    pub fn wait_for_exit(&mut self, timeout: Duration) -> Option<ExitStatus> {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(status) = self.exited() {
                return Some(status);
            }
            if Instant::now() >= deadline {
                return None;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Sends SIGINT (unless the process has exited) and waits up to `timeout` for the exit status.
    pub fn interrupt(&mut self, timeout: Duration) -> Option<ExitStatus> {
        if let Some(status) = self.exited() {
            return Some(status);
        }
        send_signal(self.pid(), Signal::SIGINT);
        self.wait_for_exit(timeout)
    }

    /// Kills the process at once (a crash, as far as the other nodes can tell).
    pub fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }

    /// The log written so far.
    pub fn log_text(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }
}

impl Drop for NodeProcess {
    fn drop(&mut self) {
        if self.interrupt(Duration::from_secs(5)).is_none() {
            self.kill();
        }
    }
}

/// A free TCP port on the loopback, e.g. for a bridge.
pub fn free_port() -> anyhow::Result<u16> {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").context("cannot find a free TCP port")?;
    Ok(listener.local_addr()?.port())
}

/// Sends `signal` to the process `pid`; a process that has already gone is no error.
pub fn send_signal(pid: u32, signal: Signal) {
    if let Ok(pid) = i32::try_from(pid) {
        let _ = nix::sys::signal::kill(Pid::from_raw(pid), signal);
    }
}

/// First wait before a dead node starts again; it doubles with each death soon after a start.
const RESPAWN_FIRST_DELAY: Duration = Duration::from_millis(250);
/// A node that ran this long before it died starts again after the first delay.
const RESPAWN_STABLE_AFTER: Duration = Duration::from_secs(10);
/// A node that died this many times in a row soon after its start is not started again.
const RESPAWN_MAX_QUICK_DEATHS: u32 = 6;

/// The running node processes of one graph.
#[derive(Debug)]
pub struct Graph {
    config: GraphConfig,
    nodes: Vec<NodeProcess>,
    back_offs: Vec<BackOff>,
}

/// When a node last started and when it may start again after dying.
#[derive(Debug)]
struct BackOff {
    name: String,
    started_at: Instant,
    quick_deaths: u32,
    restart_at: Option<Instant>,
    restarts: u32,
}

impl BackOff {
    fn new(name: &str) -> Self {
        BackOff { name: name.to_string(), started_at: Instant::now(), quick_deaths: 0, restart_at: None, restarts: 0 }
    }

    /// Notes a death now; returns the wait before the next start, `None` when the node keeps
    /// dying and is given up.
    fn died(&mut self) -> Option<Duration> {
        if self.started_at.elapsed() >= RESPAWN_STABLE_AFTER {
            self.quick_deaths = 0;
        }
        if self.given_up() {
            return None;
        }
        let delay = RESPAWN_FIRST_DELAY.saturating_mul(1 << self.quick_deaths);
        self.quick_deaths += 1;
        self.restart_at = (!self.given_up()).then(|| Instant::now() + delay);
        self.restart_at.map(|_| delay)
    }

    fn given_up(&self) -> bool {
        self.quick_deaths >= RESPAWN_MAX_QUICK_DEATHS
    }

    fn started(&mut self) {
        self.started_at = Instant::now();
        self.restart_at = None;
        self.restarts += 1;
    }
}

impl Graph {
    /// Starts every node of [`crate::processes::nodes::Node::ALL`].
    pub fn start(config: GraphConfig) -> anyhow::Result<Self> {
        Self::start_nodes(config, &node_names().collect::<Vec<_>>())
    }

    /// Starts the nodes `names` (subcommands of `rover`), with an empty state folder: a new
    /// graph never carries on from the state of an earlier one.
    pub fn start_nodes(config: GraphConfig, names: &[&str]) -> anyhow::Result<Self> {
        let state_dir = config.state_dir();
        if state_dir.exists() {
            std::fs::remove_dir_all(&state_dir)
                .with_context(|| format!("cannot empty the state folder {}", state_dir.display()))?;
        }
        let nodes = names.iter().map(|name| NodeProcess::start(&config, name)).collect::<anyhow::Result<_>>()?;
        let back_offs = names.iter().map(|name| BackOff::new(name)).collect();
        Ok(Graph { config, nodes, back_offs })
    }

    /// How the graph was started.
    pub fn config(&self) -> &GraphConfig {
        &self.config
    }

    /// The running nodes' names and process ids.
    pub fn processes(&self) -> impl Iterator<Item = (&str, u32)> {
        self.nodes.iter().map(|node| (node.name.as_str(), node.pid()))
    }

    /// The running node called `name`.
    pub fn node_mut(&mut self, name: &str) -> Option<&mut NodeProcess> {
        self.nodes.iter_mut().find(|n| n.name == name)
    }

    /// Kills node `name` at once, as a crash would.
    pub fn kill(&mut self, name: &str) {
        if let Some(index) = self.nodes.iter().position(|n| n.name == name) {
            self.nodes.remove(index).kill();
        }
    }

    /// Kills node `name` and starts it again at once: a new process on a new DDS participant.
    pub fn restart(&mut self, name: &str) -> anyhow::Result<()> {
        self.kill(name);
        self.nodes.push(NodeProcess::start_again(&self.config, name)?);
        Ok(())
    }

    /// Sends SIGKILL to node `name` and leaves it in the graph, as a crash from outside would:
    /// [`Graph::respawn_dead`] finds it dead.
    pub fn crash(&mut self, name: &str) {
        if let Some(node) = self.node_mut(name) {
            send_signal(node.pid(), Signal::SIGKILL);
        }
    }

    /// Times node `name` was started again by [`Graph::respawn_dead`].
    pub fn restarts(&self, name: &str) -> u32 {
        self.back_offs.iter().find(|b| b.name == name).map_or(0, |b| b.restarts)
    }

    fn back_off(&mut self, name: &str) -> Option<&mut BackOff> {
        self.back_offs.iter_mut().find(|b| b.name == name)
    }

    /// The nodes that have exited, with their status.
    pub fn exited(&mut self) -> Vec<(String, ExitStatus)> {
        self.nodes.iter_mut().filter_map(|n| n.exited().map(|s| (n.name.clone(), s))).collect()
    }

    /// The nodes that kept dying soon after their start and are no longer started again.
    pub fn given_up(&self) -> Vec<String> {
        self.back_offs.iter().filter(|b| b.given_up()).map(|b| b.name.clone()).collect()
    }

    /// Takes the nodes that died out of the graph and starts each again once its back-off has
    /// passed: 0.25 s after its first death, doubling (up to 4 s) while it keeps dying within 10 s
    /// of a start, and not after the sixth such death in a row ([`Graph::given_up`]). Call it
    /// often (e.g. every 100 ms); it never blocks. Returns the nodes it started. A node that
    /// cannot be started is tried again after the next back-off.
    pub fn respawn_dead(&mut self) -> Vec<String> {
        for (name, status) in self.exited() {
            self.kill(&name);
            let log = self.config.log_file(&name);
            match self.back_off(&name).and_then(BackOff::died) {
                Some(delay) => tracing::warn!(
                    "node {name} exited ({status}); starting it again in {:.2} s (see {})",
                    delay.as_secs_f64(),
                    log.display()
                ),
                None => {
                    tracing::error!("node {name} exited ({status}) and keeps dying: given up (see {})", log.display())
                }
            }
        }
        let now = Instant::now();
        let due: Vec<String> = self
            .back_offs
            .iter()
            .filter(|b| b.restart_at.is_some_and(|at| at <= now))
            .map(|b| b.name.clone())
            .collect();
        let mut started = Vec::new();
        for name in due {
            match NodeProcess::start_again(&self.config, &name) {
                Ok(process) => {
                    self.nodes.push(process);
                    if let Some(back_off) = self.back_off(&name) {
                        back_off.started();
                        tracing::info!("node {name} started again (restart {})", back_off.restarts);
                    }
                    started.push(name);
                }
                Err(e) => match self.back_off(&name).and_then(BackOff::died) {
                    Some(delay) => {
                        tracing::warn!("cannot start node {name} again: {e:#}; trying in {:.2} s", delay.as_secs_f64())
                    }
                    None => tracing::error!("cannot start node {name} again: {e:#}; given up"),
                },
            }
        }
        started
    }

    /// Interrupts every node at once and waits up to `timeout` for each; returns the nodes that
    /// did not exit cleanly (killed, or a failure status).
    pub fn stop(mut self, timeout: Duration) -> Vec<String> {
        for node in &self.nodes {
            send_signal(node.pid(), Signal::SIGINT);
        }
        let mut unclean = Vec::new();
        for mut node in self.nodes.drain(..) {
            match node.interrupt(timeout) {
                Some(status) if status.success() => {}
                _ => unclean.push(node.name.clone()),
            }
        }
        unclean
    }
}

/// The log folder of a run: `$TMPDIR/rover-<what>-<pid>`.
pub fn log_dir(what: &str) -> PathBuf {
    std::env::temp_dir().join(format!("rover-{what}-{}", std::process::id()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quick_deaths_double_the_wait_until_the_node_is_given_up() {
        let mut back_off = BackOff::new("decision");
        let delays_ms: Vec<Option<u128>> = (0..7).map(|_| back_off.died().map(|d| d.as_millis())).collect();
        assert_eq!(delays_ms, [Some(250), Some(500), Some(1000), Some(2000), Some(4000), None, None]);
        assert!(back_off.given_up() && back_off.restart_at.is_none());
        let mut stable = BackOff::new("mapping");
        stable.died();
        stable.started_at -= RESPAWN_STABLE_AFTER;
        assert_eq!(stable.died(), Some(RESPAWN_FIRST_DELAY), "a node that ran long enough starts again at once");
    }

    #[test]
    fn remote_nodes_start_through_the_other_hosts_command_and_the_rest_here() {
        let mut config = GraphConfig::of_current_exe(4567, PathBuf::from("/tmp/logs")).expect("exe");
        config.remote = Some(RemoteNodes {
            nodes: vec!["mapping".to_string()],
            exec: ["ip", "netns", "exec", "base"].map(String::from).to_vec(),
        });
        let line = |name: &str| {
            let command = NodeProcess::command(&config, name);
            let args: Vec<String> = command.get_args().map(|a| a.to_string_lossy().into_owned()).collect();
            (command.get_program().to_string_lossy().into_owned(), args)
        };
        let (program, args) = line("mapping");
        assert_eq!(program, "ip");
        assert_eq!(args[..4], ["netns", "exec", "base", &config.rover.to_string_lossy()]);
        assert_eq!(args[4..6], ["mapping", "--ros-args"]);
        let (program, args) = line("bridge");
        assert_eq!(program, config.rover.to_string_lossy());
        assert_eq!(args[..2], ["bridge", "--ros-args"]);
        let enclave = args.iter().position(|arg| arg == "--enclave").map(|i| args[i + 1].as_str());
        assert_eq!(enclave, Some("/rover/bridge"), "each node has its own enclave");
    }
}
