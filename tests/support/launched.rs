//! A launched graph seen from the test: a DDS watcher of its topics, the launcher process with
//! its output in a file, and the processes it started.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::Duration;

use nix::sys::signal::Signal;
use rover::processes::graph::send_signal;
use rover_msgs::msg::{DecisionState, DriveCommand, Telemetry};
use rover_runtime::ros_args::Remap;
use rover_runtime::{RosArgs, RosNode, Runtime, Shutdown, topics};

use super::{Domain, Latest, eventually};

/// A subscriber in namespace `namespace` of the test's domain.
pub(crate) struct Watcher {
    pub telemetry: Latest<Telemetry>,
    pub drive: Latest<DriveCommand>,
    pub mode: Latest<DecisionState>,
    _node: RosNode,
    /// Its tasks go before the DDS participant they use.
    _tokio: tokio::runtime::Runtime,
    _runtime: Runtime,
}

impl Watcher {
    pub(crate) fn start(domain: &Domain, namespace: &str) -> Watcher {
        let tokio = tokio::runtime::Runtime::new().expect("a tokio runtime");
        let _entered = tokio.enter();
        let remap = Remap { node: None, from: "__ns".into(), to: namespace.into() };
        let ros_args = RosArgs { remaps: vec![remap], ..RosArgs::default() };
        let runtime = Runtime::on_domain(domain.id, ros_args, Shutdown::new()).expect("the test's DDS participant");
        let (mut node, _) = runtime.node::<rover_runtime::NoParams>("launch_watcher").expect("create the watcher node");
        let telemetry = Latest::subscribe(&mut node, &topics::TELEMETRY);
        let drive = Latest::subscribe(&mut node, &topics::DRIVE_CMD);
        let mode = Latest::subscribe(&mut node, &topics::MODE);
        Watcher { telemetry, drive, mode, _node: node, _runtime: runtime, _tokio: tokio }
    }

    /// Waits until frames flow and the decision node answers them.
    pub(crate) fn graph_runs(&self) -> bool {
        eventually(Duration::from_secs(45), || self.telemetry.count() >= 30 && self.drive.count() >= 10)
    }

    /// Waits up to `limit` for the first sample collected, as the decision node reports it.
    pub(crate) fn collects_a_sample(&self, limit: Duration) -> bool {
        eventually(limit, || self.mode.last().is_some_and(|state| state.samples_collected >= 1))
    }

    /// Waits up to `limit` for the decision node to report `done`, then checks that the mission
    /// is complete: no sample left and the rover within [`HOME_RADIUS_M`] of its start. Returns
    /// how it ended, or what is missing.
    pub(crate) fn mission_completes(&self, limit: Duration) -> Result<MissionEnd, String> {
        let done = || self.mode.last().is_some_and(|state| state.mode == "done");
        if !eventually(limit, done) {
            let mode = self.mode.last().map(|state| format!("{} ({})", state.mode, state.reason));
            return Err(format!("no `done` after {limit:?}; last mode {mode:?}, {} frames", self.telemetry.count()));
        }
        let state = self.mode.last().expect("a done state");
        let last = self.telemetry.last().ok_or("no telemetry")?;
        let end = MissionEnd {
            samples_collected: state.samples_collected,
            samples_left: last.samples_remaining,
            home_distance_m: (last.x_m - state.home_x_m).hypot(last.y_m - state.home_y_m),
            frames: self.telemetry.count(),
        };
        let complete = end.samples_left == 0 && end.home_distance_m <= HOME_RADIUS_M;
        complete.then_some(end.clone()).ok_or_else(|| format!("done but not complete: {end:?}"))
    }
}

/// How near its start the rover must end a complete mission, metres (as `rover eval` counts it).
pub(crate) const HOME_RADIUS_M: f64 = 3.0;

/// How a launched mission ended, as the watcher saw it.
#[derive(Clone, Debug)]
pub(crate) struct MissionEnd {
    pub samples_collected: u32,
    pub samples_left: u8,
    pub home_distance_m: f64,
    pub frames: usize,
}

/// A launcher process whose output goes to a file.
pub(crate) struct Launcher {
    pub child: Child,
    output: PathBuf,
    /// Whether it leads a process group of its own, which SIGINT then reaches as a whole, as
    /// Ctrl-C in a terminal does (`ros2 run` relies on that to stop its child).
    own_group: bool,
}

impl Launcher {
    /// Starts `command` with SIGINT at its default action (see [`super::with_default_sigint`]).
    pub(crate) fn start(command: &mut Command, what: &str) -> Launcher {
        Self::spawn(command, what, false)
    }

    /// [`Launcher::start`] in a process group of its own, interrupted as a whole.
    pub(crate) fn start_in_own_group(command: &mut Command, what: &str) -> Launcher {
        use std::os::unix::process::CommandExt as _;
        Self::spawn(command.process_group(0), what, true)
    }

    fn spawn(command: &mut Command, what: &str, own_group: bool) -> Launcher {
        let output = std::env::temp_dir().join(format!("rover-launch-{what}-{}.out", std::process::id()));
        let file = std::fs::File::create(&output).expect("create the launcher's output file");
        let stderr = file.try_clone().expect("share the output file");
        let child = super::with_default_sigint(command)
            .stdin(Stdio::null())
            .stdout(file)
            .stderr(stderr)
            .spawn()
            .unwrap_or_else(|e| panic!("start the {what} launcher: {e}"));
        Launcher { child, output, own_group }
    }

    pub(crate) fn output(&self) -> String {
        std::fs::read_to_string(&self.output).unwrap_or_default()
    }

    /// Sends SIGINT and checks that the launcher exits with 0; returns its output.
    pub(crate) fn interrupt_cleanly(&mut self) -> String {
        let status = self.interrupt();
        let output = self.output();
        assert_eq!(
            status.and_then(|s| s.code()),
            Some(0),
            "rover-graph's exit on SIGINT: {status:?}; output:\n{output}"
        );
        output
    }

    /// Sends SIGINT and waits up to 30 s; returns how the launcher exited, if it did.
    pub(crate) fn interrupt(&mut self) -> Option<ExitStatus> {
        self.signal(Signal::SIGINT);
        let exited = eventually(Duration::from_secs(30), || self.child.try_wait().ok().flatten().is_some());
        exited.then(|| self.child.wait().ok()).flatten()
    }
}

impl Launcher {
    /// Sends `signal` to the launcher, or to its whole process group if it has one.
    fn signal(&self, signal: Signal) {
        if self.own_group {
            let group = nix::unistd::Pid::from_raw(i32::try_from(self.child.id()).expect("a pid fits i32"));
            let _ = nix::sys::signal::killpg(group, signal);
        } else {
            send_signal(self.child.id(), signal);
        }
    }
}

impl Drop for Launcher {
    fn drop(&mut self) {
        if self.child.try_wait().ok().flatten().is_none() {
            self.signal(Signal::SIGINT);
            if !eventually(Duration::from_secs(15), || self.child.try_wait().ok().flatten().is_some()) {
                self.signal(Signal::SIGKILL);
                let _ = self.child.wait();
            }
        }
    }
}

pub(crate) fn is_running(pid: u32) -> bool {
    Path::new(&format!("/proc/{pid}")).exists()
}

/// The command line of a running process, its arguments joined by spaces.
pub(crate) fn command_line(pid: u32) -> String {
    std::fs::read(format!("/proc/{pid}/cmdline"))
        .map(|b| String::from_utf8_lossy(&b).replace('\0', " "))
        .unwrap_or_default()
}

/// The `(name, pid)` of every process `ros2 launch` started: its lines
/// `[INFO] [NAME-N]: process started with pid [PID]`.
pub(crate) fn launched_processes(output: &str) -> Vec<(String, u32)> {
    output
        .lines()
        .filter_map(|line| line.strip_prefix("[INFO] ["))
        .filter_map(|rest| rest.split_once("]: process started with pid ["))
        .map(|(name, pid)| {
            let name = name.rsplit_once('-').map_or(name, |(name, _)| name);
            (name.to_string(), pid.trim_end_matches(']').parse().expect("a pid"))
        })
        .collect()
}
