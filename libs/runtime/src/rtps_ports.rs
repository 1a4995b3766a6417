//! The UDP ports that RTPS, DDS's wire protocol, gives a domain (RTPS 2.x, section 9.6.1.1): the
//! static peers' relay sends to them and the DDS firewall filters them.

use std::ops::RangeInclusive;

/// The highest ROS domain id: the ports of a higher one would pass the last UDP port.
pub const MAX_DOMAIN_ID: u16 = 232;

/// Port base, domain gain, participant gain and the unicast discovery offset.
const PORT_BASE: u16 = 7400;
const DOMAIN_GAIN: u16 = 250;
const PARTICIPANT_GAIN: u16 = 2;
const UNICAST_DISCOVERY_OFFSET: u16 = 10;

/// The ports of domain `domain` (at most [`MAX_DOMAIN_ID`]), up to the last UDP port.
pub fn domain_ports(domain: u16) -> RangeInclusive<u16> {
    let first = PORT_BASE + DOMAIN_GAIN * domain;
    first..=first.saturating_add(DOMAIN_GAIN - 1)
}

/// The unicast discovery port of participant `participant` on domain `domain`.
pub fn discovery_port(domain: u16, participant: u16) -> u16 {
    domain_ports(domain).start() + UNICAST_DISCOVERY_OFFSET + PARTICIPANT_GAIN * participant
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_domains_ports_follow_the_rtps_formula() {
        assert_eq!(domain_ports(0), 7400..=7649);
        assert_eq!(domain_ports(7), 9150..=9399);
        assert_eq!(domain_ports(MAX_DOMAIN_ID), 65400..=u16::MAX);
        assert_eq!(discovery_port(0, 0), 7410);
        assert_eq!(discovery_port(7, 11), 9150 + 10 + 22);
    }
}
