//! Peers on the network that mean harm. One floods a node with requests it must refuse: every one
//! is refused, counted, and the node's log grows by a few lines, not one per request. Another, on
//! another host, sends one DATA_FRAG whose header claims half a gigabyte: it reaches the node and
//! costs it that much memory, unless the rules of `rover dds-firewall` keep it out.

mod support;

use std::time::Duration;

use rover_runtime::lifecycle::{State, Transition};
use support::two_hosts::{ADDRESSES, TwoHosts};
use support::{Domain, eventually, start_process, test_runtime};

#[tokio::test(flavor = "multi_thread")]
async fn a_flood_of_refused_transitions_costs_the_node_a_few_log_lines() {
    support::assert_isolated();
    let domain = Domain::reserve();
    let mut pickup =
        start_process(&support::rover(), &["pickup", "--ros-args", "-p", "autostart:=false"], &domain, "pickup");
    let runtime = test_runtime(&domain);
    let (peer, _) = runtime.node::<rover_runtime::NoParams>("flooding_peer").expect("the peer's node");
    let lifecycle = peer.lifecycle_client("/pickup").expect("a client of the pickup's lifecycle");
    let mut state = None;
    for _ in 0..40 {
        state = lifecycle.state().await;
        if state.is_some() {
            break;
        }
    }
    assert_eq!(state, Some(State::Unconfigured), "the pickup node waits unconfigured");
    const REQUESTS: usize = 300;
    for request in 0..REQUESTS {
        let accepted = lifecycle.change(State::Unconfigured, Transition::Activate).await;
        assert!(!accepted, "request {request}: activate from unconfigured was accepted");
    }
    let logged = || pickup.log_text().lines().filter(|line| line.contains("refused transition")).count();
    assert!(
        eventually(Duration::from_secs(5), || pickup.log_text().contains("(256 such so far)")),
        "{}",
        pickup.log_text()
    );
    assert_eq!(logged(), 9, "the 1st, 2nd, 4th ... 256th of {REQUESTS} refusals:\n{}", pickup.log_text());
    assert!(pickup.interrupt(Duration::from_secs(10)).is_some_and(|status| status.success()), "a clean stop");
}

/// What the hostile DATA_FRAG claims its sample holds, bytes.
const CLAIMED_BYTES: u32 = 512 << 20;
/// Most the node's memory may grow when that packet is kept out, kB.
const MAX_GROWTH_BEHIND_FIREWALL_KB: u64 = 20 * 1024;

/// An RTPS message from a stranger (its participant is `sender`): a DATA_FRAG to the participant
/// discovery reader, which takes data from anyone, whose header claims a sample of `claimed_bytes`
/// and which carries its first 1 kB fragment.
fn data_frag_claiming(claimed_bytes: u32, sender: u8) -> Vec<u8> {
    const FRAGMENT_BYTES: u16 = 1024;
    let mut message = b"RTPS\x02\x03\x01\x0f".to_vec();
    message.extend([sender; 12]);
    let mut body = Vec::new();
    body.extend(0u16.to_le_bytes());
    body.extend(28u16.to_le_bytes());
    body.extend([0x00, 0x01, 0x00, 0xc7, 0x00, 0x01, 0x00, 0xc2]);
    body.extend(0i32.to_le_bytes());
    body.extend(1u32.to_le_bytes());
    body.extend(1u32.to_le_bytes());
    body.extend(1u16.to_le_bytes());
    body.extend(FRAGMENT_BYTES.to_le_bytes());
    body.extend(claimed_bytes.to_le_bytes());
    body.extend(vec![0u8; usize::from(FRAGMENT_BYTES)]);
    message.extend([0x16, 0x01]);
    message.extend((body.len() as u16).to_le_bytes());
    message.extend(body);
    message
}

/// The resident memory of process `pid`, kB.
fn resident_kb(pid: u32) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).expect("the process's status");
    let line = status.lines().find(|line| line.starts_with("VmRSS:")).expect("a VmRSS line");
    line.split_whitespace().nth(1).and_then(|kb| kb.parse().ok()).expect("VmRSS in kB")
}

#[test]
fn a_data_frag_claiming_half_a_gigabyte_is_kept_out_by_the_dds_firewall() {
    support::assert_isolated();
    let hosts = TwoHosts::new("frag");
    let domain = Domain::reserve();
    let pickup = hosts.start(0, &["pickup"], &[], &domain, "frag-pickup");
    assert!(eventually(Duration::from_secs(20), || pickup.log_text().contains("-> active")), "{}", pickup.log_text());
    let dir = std::env::temp_dir().join(format!("rover-frag-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let discovery_port = rover_runtime::rtps_ports::discovery_port(domain.id, 0);
    let send_from_host_b = |sender: u8| {
        let packet = dir.join(format!("frag-{sender}.bin"));
        std::fs::write(&packet, data_frag_claiming(CLAIMED_BYTES, sender)).unwrap();
        let script = format!("cat {} > /dev/udp/{}/{discovery_port}", packet.display(), ADDRESSES[0]);
        hosts.run(1, "bash", &["-c", &script]);
        std::thread::sleep(Duration::from_secs(1));
    };
    let before_kb = resident_kb(pickup.pid());
    send_from_host_b(1);
    let grown_kb = || resident_kb(pickup.pid()).saturating_sub(before_kb);
    let reached = eventually(Duration::from_secs(5), || grown_kb() > u64::from(CLAIMED_BYTES) / 1024 / 2);
    let unprotected_kb = grown_kb();
    assert!(reached, "without the firewall the node grew {unprotected_kb} kB: the packet did not reach it");
    let rules = dir.join("rules.nft");
    let printed = std::process::Command::new(support::rover())
        .args(["dds-firewall", "--domain", &domain.id.to_string()])
        .output()
        .expect("rover dds-firewall");
    std::fs::write(&rules, &printed.stdout).unwrap();
    hosts.run(0, "nft", &["-f", &rules.to_string_lossy()]);
    let before_kb = resident_kb(pickup.pid());
    send_from_host_b(2);
    let protected_kb = resident_kb(pickup.pid()).saturating_sub(before_kb);
    println!(
        "a DATA_FRAG claiming {CLAIMED_BYTES} bytes: the node grew {unprotected_kb} kB, {protected_kb} kB behind the firewall"
    );
    assert!(protected_kb < MAX_GROWTH_BEHIND_FIREWALL_KB, "behind the firewall the node grew {protected_kb} kB");
    let counted = hosts.run(0, "nft", &["list", "table", "inet", &format!("rover_dds_{}", domain.id)]);
    assert!(counted.contains("counter packets 1 "), "the firewall dropped the packet:\n{counted}");
    std::fs::remove_dir_all(dir).unwrap();
}
