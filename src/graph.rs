//! The node graph as separate processes: each node is the `rover` executable with its subcommand,
//! started on one DDS domain with the same ROS arguments, its log in a file of its own. Used by
//! `rover demo`, `rover eval` and the tests that need the whole graph.

use std::fs::File;
use std::path::PathBuf;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use nix::sys::signal::Signal;
use nix::unistd::Pid;

use crate::nodes::node_names;

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
    /// Folder of the log files, one per node.
    pub log_dir: PathBuf,
}

impl GraphConfig {
    /// A graph of this very executable (`rover`), logging into `log_dir`.
    pub fn of_current_exe(port: u16, log_dir: PathBuf) -> anyhow::Result<Self> {
        let rover = std::env::current_exe().context("cannot find the rover executable")?;
        Ok(GraphConfig { rover, domain_id: None, port, ros_args: Vec::new(), log_dir })
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
    /// Starts `rover NAME --ros-args ...` as `config` says.
    pub fn start(config: &GraphConfig, name: &str) -> anyhow::Result<Self> {
        std::fs::create_dir_all(&config.log_dir)
            .with_context(|| format!("cannot create the log folder {}", config.log_dir.display()))?;
        let mut command = Command::new(&config.rover);
        command.arg(name).arg("--ros-args").args(&config.ros_args);
        // Aimed at the bridge node, so it also reaches the bridge of `rover all`; the other nodes ignore it.
        command.args(["-p", &format!("bridge:port:={}", config.port)]);
        if let Some(id) = config.domain_id {
            command.env("ROS_DOMAIN_ID", id.to_string());
        }
        Self::spawn(name, command, config.log_dir.join(format!("{name}.log")))
    }

    /// Starts `command` as the process called `name`, stdin and stdout closed, stderr into the
    /// file `log`.
    pub fn spawn(name: &str, mut command: Command, log: PathBuf) -> anyhow::Result<Self> {
        let stderr = File::create(&log).with_context(|| format!("cannot create {}", log.display()))?;
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

/// The running node processes of one graph.
#[derive(Debug)]
pub struct Graph {
    config: GraphConfig,
    nodes: Vec<NodeProcess>,
}

impl Graph {
    /// Starts every node of [`crate::nodes::Node::ALL`].
    pub fn start(config: GraphConfig) -> anyhow::Result<Self> {
        Self::start_nodes(config, &node_names().collect::<Vec<_>>())
    }

    /// Starts the nodes `names` (subcommands of `rover`).
    pub fn start_nodes(config: GraphConfig, names: &[&str]) -> anyhow::Result<Self> {
        let nodes = names.iter().map(|name| NodeProcess::start(&config, name)).collect::<anyhow::Result<_>>()?;
        Ok(Graph { config, nodes })
    }

    /// How the graph was started.
    pub fn config(&self) -> &GraphConfig {
        &self.config
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

    /// Starts node `name` again (after [`Graph::kill`]).
    pub fn restart(&mut self, name: &str) -> anyhow::Result<()> {
        self.kill(name);
        self.nodes.push(NodeProcess::start(&self.config, name)?);
        Ok(())
    }

    /// The nodes that have exited, with their status.
    pub fn exited(&mut self) -> Vec<(String, ExitStatus)> {
        self.nodes.iter_mut().filter_map(|n| n.exited().map(|s| (n.name.clone(), s))).collect()
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
