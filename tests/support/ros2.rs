//! The official `ros2` command line, run as a user runs it: commands on a test's domain, their
//! output, and the daemon.

use std::process::Command;
use std::time::Duration;

use super::{Domain, ros2_cli};

/// The output (stdout and stderr) of a `ros2` command on `domain`, stopped with SIGINT after
/// `limit`, and whether it exited with status 0.
pub(crate) fn ros2(domain: &Domain, limit: Duration, args: &[&str]) -> (bool, String) {
    ros2_with_env(domain, &[], limit, args)
}

/// [`ros2`] with the environment variables `env` set as well.
pub(crate) fn ros2_with_env(domain: &Domain, env: &[(&str, &str)], limit: Duration, args: &[&str]) -> (bool, String) {
    let output = Command::new("timeout")
        .args(["--signal=INT", "--kill-after=5", &format!("{}", limit.as_secs_f64())])
        .arg(ros2_cli())
        .args(args)
        .env("ROS_DOMAIN_ID", domain.id.to_string())
        .env("PYTHONUNBUFFERED", "1")
        .envs(env.iter().copied())
        .output()
        .expect("run ros2");
    let text = format!("{}{}", String::from_utf8_lossy(&output.stdout), String::from_utf8_lossy(&output.stderr));
    (output.status.success(), text)
}

/// A `ros2` command that must succeed within 30 s; its output.
pub(crate) fn ros2_ok(domain: &Domain, args: &[&str]) -> String {
    let (ok, output) = ros2(domain, Duration::from_secs(30), args);
    assert!(ok, "`ros2 {}` failed:\n{output}", args.join(" "));
    output
}

/// The `ros2` daemon of a domain, stopped when dropped.
pub(crate) struct Daemon<'a> {
    domain: &'a Domain,
}

impl<'a> Daemon<'a> {
    pub(crate) fn start(domain: &'a Domain) -> Daemon<'a> {
        ros2_ok(domain, &["daemon", "start"]);
        let daemon = Daemon { domain };
        assert_contains(&ros2_ok(domain, &["daemon", "status"]), &["The daemon is running"], "ros2 daemon status");
        daemon
    }
}

impl Drop for Daemon<'_> {
    fn drop(&mut self) {
        let _ = ros2(self.domain, Duration::from_secs(15), &["daemon", "stop"]);
    }
}

/// The value of the first `name: value` line of a `ros2 topic echo` output.
pub(crate) fn echoed_value<T: std::str::FromStr>(output: &str, name: &str) -> Option<T> {
    let prefix = format!("{name}: ");
    output.lines().find_map(|line| line.trim().strip_prefix(prefix.as_str())).and_then(|v| v.trim().parse().ok())
}

pub(crate) fn assert_contains(output: &str, expected: &[&str], what: &str) {
    for line in expected {
        assert!(output.contains(line), "{what}: no `{line}` in\n{output}");
    }
}
