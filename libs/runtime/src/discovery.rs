//! How far a participant looks for others, read from the environment as ROS 2 (Jazzy and later)
//! reads it: `ROS_AUTOMATIC_DISCOVERY_RANGE` (`SUBNET`, `LOCALHOST`, `OFF`, `SYSTEM_DEFAULT`),
//! `ROS_STATIC_PEERS` (hosts discovered by unicast, unless the range is `OFF`) and the deprecated
//! `ROS_LOCALHOST_ONLY=1`, which means `LOCALHOST` with no static peers whatever the others say.

use std::net::{IpAddr, Ipv4Addr};

use ros2_client::dds::rustdds::DomainParticipantBuilder;

use crate::static_peers::StaticPeers;

/// The environment variable of the discovery range.
const RANGE_VARIABLE: &str = "ROS_AUTOMATIC_DISCOVERY_RANGE";
/// The deprecated environment variable that limits discovery to this host.
const LOCALHOST_ONLY_VARIABLE: &str = "ROS_LOCALHOST_ONLY";

/// How far a participant discovers others, and the peers it discovers beyond that.
#[derive(Debug)]
pub(crate) struct Discovery {
    range: DiscoveryRange,
    peers: StaticPeers,
}

impl Discovery {
    /// The discovery the environment asks for; a value ROS does not know is an error naming it.
    pub(crate) fn from_env() -> anyhow::Result<Self> {
        let localhost_only = std::env::var(LOCALHOST_ONLY_VARIABLE).is_ok_and(|value| value == "1");
        let range = DiscoveryRange::from_values(std::env::var(RANGE_VARIABLE).ok().as_deref(), localhost_only)?;
        let without_peers = localhost_only || range == DiscoveryRange::Off;
        let peers = if without_peers { StaticPeers::default() } else { StaticPeers::from_env()? };
        Ok(Discovery { range, peers })
    }

    /// A participant builder on `domain_id` that discovers this far and announces the addresses
    /// the static peers reach.
    pub(crate) fn participant(&self, domain_id: u16) -> DomainParticipantBuilder {
        self.range.participant(domain_id, &self.peers.local_addresses(domain_id))
    }

    /// Starts relaying this host's announcements on `domain_id` to the static peers, if any.
    pub(crate) fn spawn_relay(&self, domain_id: u16) {
        self.peers.clone().spawn_relay(domain_id);
    }
}

/// How far a participant discovers others by itself.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum DiscoveryRange {
    /// Every host that multicast reaches (the default).
    Subnet,
    /// This host only: multicast and the locators it announces are on the loopback interface.
    Localhost,
    /// No other participant, not even on this host.
    Off,
}

impl DiscoveryRange {
    /// The range for the value of `ROS_AUTOMATIC_DISCOVERY_RANGE`, or for `ROS_LOCALHOST_ONLY=1`
    /// (`localhost_only`).
    fn from_values(range: Option<&str>, localhost_only: bool) -> anyhow::Result<Self> {
        if localhost_only {
            tracing::warn!(
                "{LOCALHOST_ONLY_VARIABLE}=1 is deprecated (use {RANGE_VARIABLE}=LOCALHOST); discovery stays on \
                 this host"
            );
            return Ok(DiscoveryRange::Localhost);
        }
        match range.unwrap_or_default() {
            "" | "SUBNET" | "SYSTEM_DEFAULT" => Ok(DiscoveryRange::Subnet),
            "LOCALHOST" => Ok(DiscoveryRange::Localhost),
            "OFF" => Ok(DiscoveryRange::Off),
            other => anyhow::bail!(
                "{RANGE_VARIABLE}={other:?} is not a discovery range (expected SUBNET, LOCALHOST, OFF or SYSTEM_DEFAULT)"
            ),
        }
    }

    /// A participant builder on `domain_id` that discovers this far; `LOCALHOST` also announces
    /// `peer_facing` (the addresses static peers reach this host on).
    fn participant(self, domain_id: u16, peer_facing: &[IpAddr]) -> DomainParticipantBuilder {
        let builder = DomainParticipantBuilder::new(domain_id);
        match self {
            DiscoveryRange::Subnet => builder,
            DiscoveryRange::Localhost => {
                builder.with_only_networks([IpAddr::V4(Ipv4Addr::LOCALHOST)].iter().chain(peer_facing).copied())
            }
            DiscoveryRange::Off => builder.with_only_networks(Vec::<IpAddr>::new()).same_host_loopback(false),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_range_is_read_as_ros_reads_it() {
        assert_eq!(DiscoveryRange::from_values(None, false).unwrap(), DiscoveryRange::Subnet);
        assert_eq!(DiscoveryRange::from_values(Some("SYSTEM_DEFAULT"), false).unwrap(), DiscoveryRange::Subnet);
        assert_eq!(DiscoveryRange::from_values(Some("LOCALHOST"), false).unwrap(), DiscoveryRange::Localhost);
        assert_eq!(DiscoveryRange::from_values(Some("OFF"), false).unwrap(), DiscoveryRange::Off);
        assert_eq!(DiscoveryRange::from_values(Some("SUBNET"), true).unwrap(), DiscoveryRange::Localhost);
        let error = DiscoveryRange::from_values(Some("localhost"), false).unwrap_err().to_string();
        assert!(error.contains("ROS_AUTOMATIC_DISCOVERY_RANGE=\"localhost\"") && error.contains("expected"), "{error}");
    }
}
