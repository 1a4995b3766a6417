//! ROS 2's discovery range across two hosts: two network namespaces joined by a veth pair, the way
//! `tools/two-hosts` joins them. A bridge node started unconfigured on host A is brought up by a
//! `rover lifecycle-manager` only when they discover each other: with `SUBNET` (the default) from
//! host B; with `LOCALHOST` or `ROS_LOCALHOST_ONLY=1` from host A but never from B; with `OFF`
//! from nowhere, not even host A. Over a link without multicast, only `ROS_STATIC_PEERS` lets them
//! discover each other.

mod support;

use std::time::{Duration, Instant};

use support::two_hosts::TwoHosts;
use support::{Domain, Process};

/// How long the managers that should discover their bridge get: announcements go out every 10 s,
/// and the first may come before the static peers' relay listens.
const DISCOVERY_LIMIT: Duration = Duration::from_secs(45);
/// How long a manager that does not discover the node is given, once every manager that should
/// have discovered its node has done so.
const UNDISCOVERED_GRACE: Duration = Duration::from_secs(6);

/// Environment variables of a process: (name, value).
type Env<'a> = &'a [(&'a str, &'a str)];

/// One case: a bridge on host A with `env`, a manager on host `manager_host`; whether the manager
/// should bring the bridge up.
struct Case {
    name: &'static str,
    bridge: Process,
    _manager: Process,
    _hosts: TwoHosts,
    discovered: bool,
}

impl Case {
    fn start(name: &'static str, env: &[(&str, &str)], manager_host: usize, discovered: bool) -> Self {
        Self::start_on(TwoHosts::new(name), name, (env, &[]), manager_host, discovered)
    }

    /// A case on `hosts`, the bridge's environment and the manager's in `env`.
    fn start_on(hosts: TwoHosts, name: &'static str, env: (Env, Env), manager_host: usize, discovered: bool) -> Self {
        let domain = Domain::reserve();
        let port = format!("port:={}", domain.port());
        let bridge_args = ["bridge", "--ros-args", "-p", "autostart:=false", "-p", &port];
        let bridge = hosts.start(0, &bridge_args, env.0, &domain, &format!("{name}-bridge"));
        let manager = hosts.start(manager_host, &["lifecycle-manager"], env.1, &domain, &format!("{name}-manager"));
        Case { name, bridge, _manager: manager, _hosts: hosts, discovered }
    }

    fn brought_up(&self) -> bool {
        self.bridge.log_text().contains("unconfigured -> inactive")
    }
}

/// Each host names the other as its static peer.
const A_PEER: (&str, &str) = ("ROS_STATIC_PEERS", support::two_hosts::ADDRESSES[1]);
const B_PEER: (&str, &str) = ("ROS_STATIC_PEERS", support::two_hosts::ADDRESSES[0]);

#[test]
fn a_node_is_discovered_as_far_as_its_discovery_range_says() {
    support::assert_isolated();
    let cases = [
        Case::start("subnet", &[], 1, true),
        Case::start("localhost", &[("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")], 1, false),
        Case::start("localonly", &[("ROS_LOCALHOST_ONLY", "1")], 1, false),
        Case::start("samehost", &[("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")], 0, true),
        Case::start("off", &[("ROS_AUTOMATIC_DISCOVERY_RANGE", "OFF")], 0, false),
        Case::start_on(TwoHosts::without_multicast("nomc"), "nomulticast", (&[], &[]), 1, false),
        Case::start_on(TwoHosts::without_multicast("peer"), "staticpeers", (&[A_PEER], &[B_PEER]), 1, true),
    ];
    let started = Instant::now();
    let expected_up = || cases.iter().filter(|case| case.discovered).all(Case::brought_up);
    assert!(support::eventually(DISCOVERY_LIMIT, expected_up), "{}", report(&cases));
    let discovered_after = started.elapsed();
    std::thread::sleep(UNDISCOVERED_GRACE);
    for case in &cases {
        assert_eq!(case.brought_up(), case.discovered, "case {}: {}", case.name, report(&cases));
    }
    println!("discovered within {discovered_after:?}; undiscovered for {UNDISCOVERED_GRACE:?} more");
}

/// Each case's outcome and its bridge's log, for a failure message.
fn report(cases: &[Case]) -> String {
    let lines = cases.iter().map(|case| {
        format!(
            "{} (expected up: {}): up {}\n{}",
            case.name,
            case.discovered,
            case.brought_up(),
            case.bridge.log_text()
        )
    });
    lines.collect::<Vec<_>>().join("\n")
}
