//! Two hosts on this machine: two network namespaces joined by a veth pair, the way
//! `tools/two-hosts` joins them, for tests of what crosses a network.

use std::process::Command;

use super::{Domain, Process};

/// The address of each host on the link between them.
pub(crate) const ADDRESSES: [&str; 2] = ["10.78.0.1", "10.78.0.2"];

/// Two network namespaces joined by a veth pair with addresses, multicast routed over the link
/// (unless made without); removed on drop.
pub(crate) struct TwoHosts {
    names: [String; 2],
}

impl TwoHosts {
    pub(crate) fn new(tag: &str) -> Self {
        Self::joined(tag, true)
    }

    /// Two hosts whose link carries no multicast, as on networks that drop it.
    pub(crate) fn without_multicast(tag: &str) -> Self {
        Self::joined(tag, false)
    }

    fn joined(tag: &str, multicast: bool) -> Self {
        let pid = std::process::id();
        let pair = TwoHosts { names: ["a", "b"].map(|host| format!("host-{tag}-{host}-{pid}")) };
        let ends = ["a", "b"].map(|host| format!("{}{host}{}", &tag[..tag.len().min(4)], pid % 100_000));
        ip(&["link", "add", &ends[0], "type", "veth", "peer", "name", &ends[1]]);
        let addresses = [(ADDRESSES[0], ADDRESSES[1]), (ADDRESSES[1], ADDRESSES[0])];
        for ((host, end), (address, peer)) in pair.names.iter().zip(&ends).zip(addresses) {
            ip(&["netns", "add", host]);
            ip(&["link", "set", end, "netns", host, "name", "link0"]);
            ip(&["-n", host, "link", "set", "lo", "up"]);
            ip(&["-n", host, "addr", "add", address, "peer", peer, "dev", "link0"]);
            ip(&["-n", host, "link", "set", "link0", "multicast", if multicast { "on" } else { "off" }, "up"]);
            if multicast {
                ip(&["-n", host, "route", "add", "224.0.0.0/4", "dev", "link0"]);
            }
        }
        pair
    }

    /// Starts `rover args` on host `host` (0 or 1) on `domain`, with the environment `env`.
    pub(crate) fn start(
        &self,
        host: usize,
        args: &[&str],
        env: &[(&str, &str)],
        domain: &Domain,
        name: &str,
    ) -> Process {
        let log = std::env::temp_dir().join(format!("rover-test-{}-{name}-{}.log", domain.id, std::process::id()));
        let mut command = Command::new("ip");
        command.args(["netns", "exec", &self.names[host]]).arg(super::rover()).args(args);
        command.env("ROS_DOMAIN_ID", domain.id.to_string()).env("RUST_LOG", "info").envs(env.iter().copied());
        Process::spawn(name, command, log).unwrap_or_else(|e| panic!("{e:#}"))
    }

    /// Runs `program args` on host `host` to its end; panics with what it printed unless it
    /// succeeds.
    pub(crate) fn run(&self, host: usize, program: &str, args: &[&str]) -> String {
        let output = Command::new("ip").args(["netns", "exec", &self.names[host], program]).args(args).output();
        let output = output.unwrap_or_else(|e| panic!("run {program}: {e}"));
        let printed = format!("{}{}", String::from_utf8_lossy(&output.stdout), String::from_utf8_lossy(&output.stderr));
        assert!(output.status.success(), "{program} {}: {printed}", args.join(" "));
        printed
    }
}

impl Drop for TwoHosts {
    fn drop(&mut self) {
        for name in &self.names {
            let _ = Command::new("ip").args(["netns", "del", name]).status();
        }
    }
}

fn ip(args: &[&str]) {
    let output = Command::new("ip").args(args).output().expect("run ip (iproute2)");
    assert!(output.status.success(), "ip {}: {}", args.join(" "), String::from_utf8_lossy(&output.stderr));
}
