//! `ROS_STATIC_PEERS`: hosts to discover by unicast, where multicast does not reach (another
//! subnet, a network that drops multicast). RustDDS takes no list of initial peers, but every
//! participant sends its announcements (SPDP) to a few fixed discovery ports of this host as well.
//! A relay listening on the last of those ports forwards the announcements of this host's
//! participants to the discovery ports of each peer; a participant there that hears them answers
//! by unicast, and discovery goes on as usual. One process of the host holds the relay; the others
//! try again now and then, to take over if it ends.

use std::net::{IpAddr, Ipv4Addr, SocketAddr, ToSocketAddrs, UdpSocket};
use std::time::Duration;

use anyhow::Context as _;

use crate::rtps_ports::discovery_port;

/// The environment variable of the static peers.
const PEERS_VARIABLE: &str = "ROS_STATIC_PEERS";
/// The participants of this host that RustDDS announces itself to; the relay listens as the last.
const HOST_PARTICIPANT_SLOTS: u16 = 12;
/// The participants of each peer the announcements are sent to.
const PEER_PARTICIPANTS: u16 = 12;
/// How long a process waits before trying again to hold the relay.
const RELAY_RETRY: Duration = Duration::from_secs(5);

/// The static peers' addresses.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct StaticPeers {
    addresses: Vec<IpAddr>,
}

impl StaticPeers {
    /// The peers `ROS_STATIC_PEERS` names (semicolon-separated host names or addresses).
    pub fn from_env() -> anyhow::Result<Self> {
        Self::parse(&std::env::var(PEERS_VARIABLE).unwrap_or_default())
    }

    /// Reads `peers`; a host is taken at its IPv4 addresses (the relay and RustDDS's transport
    /// speak IPv4), and one with IPv6 addresses only is an error naming it.
    fn parse(peers: &str) -> anyhow::Result<Self> {
        let hosts = peers.split(';').map(str::trim).filter(|host| !host.is_empty());
        let resolve = |host: &str| {
            let addresses =
                (host, 0).to_socket_addrs().with_context(|| format!("{PEERS_VARIABLE}: cannot resolve {host:?}"))?;
            let ipv4: Vec<IpAddr> = addresses.map(|address| address.ip()).filter(IpAddr::is_ipv4).collect();
            anyhow::ensure!(
                !ipv4.is_empty(),
                "{PEERS_VARIABLE}: {host:?} has no IPv4 address; DDS here speaks IPv4 only"
            );
            Ok(ipv4)
        };
        let addresses = hosts.map(resolve).collect::<anyhow::Result<Vec<_>>>()?.concat();
        Ok(StaticPeers { addresses })
    }

    /// The peers' addresses.
    pub fn addresses(&self) -> &[IpAddr] {
        &self.addresses
    }

    /// Whether no peer is named.
    pub(crate) fn is_empty(&self) -> bool {
        self.addresses.is_empty()
    }

    /// The addresses of this host from which it reaches the peers on `domain` (the participant
    /// must announce them for the peers to answer).
    pub(crate) fn local_addresses(&self, domain: u16) -> Vec<IpAddr> {
        let local_to = |peer: &IpAddr| {
            let socket = UdpSocket::bind(SocketAddr::from((Ipv4Addr::UNSPECIFIED, 0))).ok()?;
            socket.connect(SocketAddr::new(*peer, discovery_port(domain, 0))).ok()?;
            socket.local_addr().ok().map(|address| address.ip())
        };
        self.addresses.iter().filter_map(local_to).collect()
    }

    /// Starts the relay of this host's announcements on `domain` to the peers, in the background.
    pub(crate) fn spawn_relay(self, domain: u16) {
        if self.is_empty() {
            return;
        }
        tokio::spawn(async move {
            loop {
                let listen =
                    SocketAddr::from((Ipv4Addr::LOCALHOST, discovery_port(domain, HOST_PARTICIPANT_SLOTS - 1)));
                let sockets =
                    (tokio::net::UdpSocket::bind(listen).await, tokio::net::UdpSocket::bind("0.0.0.0:0").await);
                match sockets {
                    (Ok(announcements), Ok(out)) => {
                        tracing::info!("relaying this host's DDS announcements to {:?} from {listen}", self.addresses);
                        self.relay(&announcements, &out, domain).await;
                    }
                    _ => tokio::time::sleep(RELAY_RETRY).await,
                }
            }
        });
    }

    /// Forwards every RTPS message `announcements` receives to each peer's discovery ports, through
    /// `out` (a socket on loopback sends to loopback only).
    async fn relay(&self, announcements: &tokio::net::UdpSocket, out: &tokio::net::UdpSocket, domain: u16) {
        let mut datagram = vec![0u8; 65_536];
        loop {
            let Ok((length, _)) = announcements.recv_from(&mut datagram).await else { return };
            let message = &datagram[..length];
            if !message.starts_with(b"RTPS") {
                continue;
            }
            for peer in &self.addresses {
                for participant in 0..PEER_PARTICIPANTS {
                    let _ = out.send_to(message, SocketAddr::new(*peer, discovery_port(domain, participant))).await;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn peers_are_read_as_ros_writes_them() {
        let peers = StaticPeers::parse(" 10.0.0.7;;127.0.0.1 ").unwrap();
        assert_eq!(peers.addresses, ["10.0.0.7".parse::<IpAddr>().unwrap(), IpAddr::V4(Ipv4Addr::LOCALHOST)]);
        assert!(StaticPeers::parse("").unwrap().is_empty());
        let error = StaticPeers::parse("no-such-host.invalid").unwrap_err().to_string();
        assert!(error.contains("ROS_STATIC_PEERS") && error.contains("no-such-host.invalid"), "{error}");
        let ipv6 = StaticPeers::parse("10.0.0.7;::1").unwrap_err().to_string();
        assert!(ipv6.contains("\"::1\" has no IPv4 address"), "{ipv6}");
    }

    #[test]
    fn the_relay_listens_on_the_last_port_that_participants_announce_to() {
        assert_eq!(discovery_port(7, HOST_PARTICIPANT_SLOTS - 1), 9150 + 10 + 22);
        assert_eq!(StaticPeers::parse("127.0.0.1").unwrap().local_addresses(0), [IpAddr::V4(Ipv4Addr::LOCALHOST)]);
    }
}
