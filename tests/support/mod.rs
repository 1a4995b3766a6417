//! Shared helpers of the integration tests: isolation check, DDS domains, child processes,
//! the real Udacity frames and a DDS observer.
#![allow(dead_code)]

pub(crate) mod echo_sim;
pub(crate) mod launched;
pub(crate) mod ros2;
pub(crate) mod two_hosts;

use std::fs::File;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Fails unless the test runs in a network namespace whose only interface is `lo`
/// (`tools/isolated`), so no DDS discovery traffic leaves the machine.
pub(crate) fn assert_isolated() {
    let devices = std::fs::read_to_string("/proc/net/dev").expect("read /proc/net/dev");
    let interfaces: Vec<&str> = devices.lines().skip(2).filter_map(|l| l.split(':').next()).map(str::trim).collect();
    assert_eq!(
        interfaces,
        vec!["lo"],
        "DDS tests must run in a loopback-only network namespace: run them through tools/isolated (see README)"
    );
}

/// The shared data folder (`../shared` beside the repository, or `ROVER_SHARED`).
pub(crate) fn shared_dir() -> PathBuf {
    std::env::var_os("ROVER_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared"))
}

/// The path of `path` inside the shared data folder, as a command-line argument.
pub(crate) fn shared_path(path: &str) -> String {
    shared_dir().join(path).display().to_string()
}

/// `map_bw.png`, the ground truth of the Udacity world.
pub(crate) fn map_bw_png() -> String {
    shared_path("udacity/calibration_images/map_bw.png")
}

/// The options of the surveyed Unity world: `map_bw.png` with the surveyed ground and rocks.
pub(crate) fn surveyed_world_args() -> Vec<String> {
    ["--map", &map_bw_png(), "--elevation", &shared_path("udacity-world/elevation_cm.png")]
        .into_iter()
        .map(String::from)
        .chain(["--rocks".into(), shared_path("udacity-world/rocks.json")])
        .collect()
}

/// The 283 recorded Udacity frames (`robot_log.csv` and `IMG/`).
pub(crate) fn test_dataset_dir() -> String {
    shared_path("udacity/test_dataset")
}

/// The number at `key` of a JSON object, or a panic naming the key and the object.
pub(crate) fn number(value: &serde_json::Value, key: &str) -> f64 {
    value[key].as_f64().unwrap_or_else(|| panic!("no number {key} in {value}"))
}

/// A bridge on `domain` listening on the domain's port, with parameters `extra` (`name:=value`)
/// and /diagnostics every 100 ms; returns once the port accepts connections.
pub(crate) fn start_bridge(domain: &Domain, extra: &[&str]) -> Process {
    let port = format!("port:={}", domain.port());
    let mut args = vec!["bridge", "--ros-args", "-p", &port, "-p", "diagnostics_period_ms:=100.0"];
    for param in extra {
        args.extend(["-p", param]);
    }
    let bridge = start_process(&rover(), &args, domain, "bridge");
    wait_for_port(domain.port(), Duration::from_secs(20));
    bridge
}

/// A graph of the test's `rover` binary on `domain` and its port, logging into `log_dir`, all on
/// this host, without respawning.
pub(crate) fn graph_config(domain: &Domain, log_dir: PathBuf) -> rover::processes::graph::GraphConfig {
    rover::processes::graph::GraphConfig {
        rover: rover(),
        domain_id: Some(domain.id),
        port: domain.port(),
        ros_args: Vec::new(),
        log_dir,
        respawn: false,
        remote: None,
        env: Vec::new(),
    }
}

/// A new DDS Security keystore named after `name` (`tools/keystore create-keystore`): one CA and
/// an enclave per node.
pub(crate) fn keystore(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rover-keystore-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/keystore");
    let status = Command::new(script).arg("create-keystore").arg(&dir).status().expect("run tools/keystore");
    assert!(status.success(), "tools/keystore create-keystore {} failed", dir.display());
    dir
}

/// The environment that secures a process with `keystore`, enforced.
pub(crate) fn security_env(keystore: &Path) -> Vec<(String, String)> {
    let keystore = keystore.display().to_string();
    [
        ("ROS_SECURITY_ENABLE", "true"),
        ("ROS_SECURITY_KEYSTORE", keystore.as_str()),
        ("ROS_SECURITY_STRATEGY", "Enforce"),
    ]
    .map(|(name, value)| (name.to_string(), value.to_string()))
    .to_vec()
}

/// A DDS domain id (and a TCP port derived from it) reserved for one test.
pub(crate) struct Domain {
    /// `ROS_DOMAIN_ID` of the test's processes.
    pub id: u16,
    lock: PathBuf,
}

impl Domain {
    /// Reserves a domain no other running test uses.
    pub(crate) fn reserve() -> Domain {
        let dir = std::env::temp_dir().join("rover-test-domains");
        std::fs::create_dir_all(&dir).expect("create the domain lock folder");
        for id in 1..=200u16 {
            let lock = dir.join(format!("{id}"));
            if File::create_new(&lock).is_ok() {
                stop_ros2_daemon_on(id);
                return Domain { id, lock };
            }
        }
        panic!("no free DDS domain id; remove {} if no test is running", dir.display());
    }

    /// A TCP port for this test's bridge.
    pub(crate) fn port(&self) -> u16 {
        30000 + self.id * 10
    }
}

impl Drop for Domain {
    fn drop(&mut self) {
        stop_ros2_daemon_on(self.id);
        let _ = std::fs::remove_file(&self.lock);
    }
}

/// Stops the `ros2` daemon of domain `id` if one runs: `ros2` commands start one when none runs,
/// and a daemon left by an earlier test would show that test's participants to the next one.
fn stop_ros2_daemon_on(id: u16) {
    let daemon = std::net::SocketAddr::from(([127, 0, 0, 1], 11511 + id));
    if std::net::TcpStream::connect_timeout(&daemon, Duration::from_millis(200)).is_ok() {
        let _ = Command::new("timeout")
            .args(["--kill-after=5", "15", &ros2_cli().to_string_lossy(), "daemon", "stop"])
            .env("ROS_DOMAIN_ID", id.to_string())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status();
    }
}

/// A child process of a test: interrupted (SIGINT) when dropped, its stderr in a log file.
pub(crate) type Process = rover::processes::graph::NodeProcess;

/// How long a test process gets to exit after SIGINT.
pub(crate) const STOP_TIMEOUT: Duration = Duration::from_secs(5);

/// What the runtime logs when a node's lifecycle reaches `active` (its endpoints exist).
pub(crate) const ACTIVATED_LOG_LINE: &str = "lifecycle: inactive -> active";

/// Starts `program` with `args` on `domain`, logging to a temporary file named after `name`.
pub(crate) fn start_process(program: &Path, args: &[&str], domain: &Domain, name: &str) -> Process {
    let log = std::env::temp_dir().join(format!("rover-test-{}-{name}-{}.log", domain.id, std::process::id()));
    let mut command = Command::new(program);
    command
        .args(args)
        .env("ROS_DOMAIN_ID", domain.id.to_string())
        .env("RUST_LOG", std::env::var("RUST_LOG").unwrap_or_else(|_| "info".into()));
    Process::spawn(name, command, log).unwrap_or_else(|e| panic!("{e:#}"))
}

/// The `rover` binary under test.
pub(crate) fn rover() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_rover"))
}

/// The echo node, a test helper (`tests/helpers/echo_node.rs`).
pub(crate) fn echo_node() -> PathBuf {
    helper("echo_node")
}

/// The link emulator of `tools/two-hosts`, a test helper (`tests/helpers/link_emulator.rs`).
pub(crate) fn link_emulator() -> PathBuf {
    helper("link_emulator")
}

/// The example target `name` of this package's build profile: `cargo test` builds the examples,
/// `cargo bench` does not, so a missing one is built here.
fn helper(name: &str) -> PathBuf {
    let profile_dir = rover().parent().expect("the rover binary sits in a profile folder").to_path_buf();
    let path = profile_dir.join("examples").join(name);
    if !path.exists() {
        let mut build = Command::new(env!("CARGO"));
        build.args(["build", "--quiet", "--example", name]).current_dir(env!("CARGO_MANIFEST_DIR"));
        if profile_dir.ends_with("release") {
            build.arg("--release");
        }
        let status = build.status().unwrap_or_else(|e| panic!("cannot run cargo to build {name}: {e}"));
        assert!(status.success(), "cargo build --example {name} failed");
    }
    path
}

/// Waits until a TCP server accepts connections on `port`.
pub(crate) fn wait_for_port(port: u16, timeout: Duration) {
    let deadline = Instant::now() + timeout;
    while Instant::now() < deadline {
        if std::net::TcpStream::connect(("127.0.0.1", port)).is_ok() {
            return;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    panic!("nothing listens on port {port} after {timeout:?}");
}

/// Polls `condition` until it holds or `timeout` passes; returns whether it held.
pub(crate) fn eventually(timeout: Duration, mut condition: impl FnMut() -> bool) -> bool {
    let deadline = Instant::now() + timeout;
    while Instant::now() < deadline {
        if condition() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(25));
    }
    condition()
}

/// A DDS participant inside the test process, on the test's domain.
pub(crate) fn test_runtime(domain: &Domain) -> rover_runtime::Runtime {
    rover_runtime::Runtime::on_domain(domain.id, rover_runtime::RosArgs::default(), rover_runtime::Shutdown::new())
        .expect("create the test's DDS participant")
}

/// Keeps the latest message of a topic, received by a subscription in the test process; a clone
/// sees the same messages.
#[derive(Clone)]
pub(crate) struct Latest<M> {
    latest: std::sync::Arc<std::sync::Mutex<Vec<M>>>,
}

impl<M: rover_msgs::RosMessage> Latest<M> {
    /// Subscribes to `topic` with `node`.
    pub(crate) fn subscribe(node: &mut rover_runtime::RosNode, topic: &rover_runtime::topics::Topic<M>) -> Self {
        let latest = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        let sink = latest.clone();
        rover_runtime::spawn_subscriber(
            node.subscription(topic).expect("subscribe"),
            tracing::Span::none(),
            move |m| sink.lock().unwrap().push(m),
        );
        Latest { latest }
    }

    /// Every message received so far.
    pub(crate) fn all(&self) -> Vec<M> {
        self.latest.lock().unwrap().clone()
    }

    /// How many messages were received so far.
    pub(crate) fn count(&self) -> usize {
        self.latest.lock().unwrap().len()
    }

    /// The last message received, if any.
    pub(crate) fn last(&self) -> Option<M> {
        self.latest.lock().unwrap().last().cloned()
    }
}

/// The value of `key` in the last `/diagnostics` message, if any.
pub(crate) fn diagnostic_value(
    latest: &Latest<rover_msgs::diagnostic_msgs::DiagnosticArray>,
    key: &str,
) -> Option<String> {
    latest.last()?.value(key).map(str::to_string)
}

/// A Python interpreter that can import `modules` (the project's `.venv` under `tools/test-all`).
/// `None` means it is missing, which fails the test when `ROVER_REQUIRE_ROS` is set.
pub(crate) fn python_with(modules: &[&str]) -> Option<PathBuf> {
    let python = std::env::var_os("ROVER_PYTHON").map(PathBuf::from).unwrap_or_else(|| PathBuf::from("python3"));
    let imports = modules.iter().map(|m| format!("import {m}")).collect::<Vec<_>>().join("; ");
    let ok = Command::new(&python)
        .args(["-W", "ignore", "-c", &imports])
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if ok {
        return Some(python);
    }
    assert!(
        std::env::var_os("ROVER_REQUIRE_ROS").is_none(),
        "{} cannot import {modules:?}: run through tools/test-all, which sets up .venv",
        python.display()
    );
    eprintln!("skipped: {} cannot import {modules:?} (tools/test-all sets them up)", python.display());
    None
}

/// A free TCP port on the loopback.
pub(crate) fn free_port() -> u16 {
    rover::processes::graph::free_port().expect("a free port")
}

/// The official `ros2` command line (`ROVER_ROS2`, else `ros2` on the PATH: `.venv/bin/ros2` after
/// `tools/setup-ros` and `source tools/ros-env.sh`).
pub(crate) fn ros2_cli() -> PathBuf {
    std::env::var_os("ROVER_ROS2").map(PathBuf::from).unwrap_or_else(|| PathBuf::from("ros2"))
}

/// A domain for a test of the `ros2` command line, in the isolated namespace; `None` when the test
/// is to be skipped (see [`ros2_cli_or_skip`]).
pub(crate) fn ros2_domain_or_skip() -> Option<Domain> {
    assert_isolated();
    ros2_cli_or_skip().then(Domain::reserve)
}

/// Whether the `ros2` command line runs (`ros2 --help`). Without it the test skips only when its
/// wheels (`../shared/ros2-python`) are absent and `ROVER_REQUIRE_ROS` is unset; otherwise it fails.
fn ros2_cli_or_skip() -> bool {
    let ros2 = ros2_cli();
    let runs = Command::new(&ros2)
        .arg("--help")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if runs {
        return true;
    }
    let wheels = shared_dir().join("ros2-python");
    assert!(
        std::env::var_os("ROVER_REQUIRE_ROS").is_none(),
        "ROVER_REQUIRE_ROS is set but `{} --help` does not run: tools/setup-ros installs it from {}",
        ros2.display(),
        wheels.display()
    );
    assert!(
        !wheels.exists(),
        "`{} --help` does not run although {} is present: run tools/setup-ros and `source tools/ros-env.sh`",
        ros2.display(),
        wheels.display()
    );
    eprintln!("skipped: no `ros2` command line and no {} to install it from", wheels.display());
    false
}

/// Percentiles of durations, milliseconds (NaN when there are none).
pub(crate) struct Percentiles {
    /// Median, ms.
    pub p50_ms: f64,
    /// 99th percentile, ms.
    pub p99_ms: f64,
    /// Largest, ms.
    pub max_ms: f64,
}

/// The median, 99th percentile and maximum of `samples`.
pub(crate) fn percentiles(samples: &[Duration]) -> Percentiles {
    let mut ms: Vec<f64> = samples.iter().map(|d| d.as_secs_f64() * 1000.0).collect();
    ms.sort_by(f64::total_cmp);
    let at = |q: f64| ms.get(((ms.len().max(1) - 1) as f64 * q).round() as usize).copied().unwrap_or(f64::NAN);
    Percentiles { p50_ms: at(0.5), p99_ms: at(0.99), max_ms: at(1.0) }
}

/// Gives `command`'s process SIGINT at its default action, as a terminal does: anything started in
/// the background of a script (such as a test run under `.ci/run &`) inherits SIGINT ignored, and
/// then neither a shell's trap nor Python (`ros2 launch`) sees the Ctrl-C a test sends.
pub(crate) fn with_default_sigint(command: &mut Command) -> &mut Command {
    use std::os::unix::process::CommandExt as _;
    // SAFETY: between fork and exec the child only calls sigaction, which is async-signal-safe.
    unsafe {
        command.pre_exec(|| {
            nix::sys::signal::signal(nix::sys::signal::Signal::SIGINT, nix::sys::signal::SigHandler::SigDfl)
                .map(drop)
                .map_err(std::io::Error::from)
        })
    }
}
