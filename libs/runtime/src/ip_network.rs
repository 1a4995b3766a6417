//! IP networks as users write them (`10.0.0.0/8`, `192.168.1.20`, `fd00::/8`), for the lists of
//! peers a server or a firewall lets in.

use std::net::IpAddr;

/// An IP network: an address and the number of its leading bits that matter (`10.0.0.0/8`; a
/// bare address is the network of that address alone).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct IpNetwork {
    address: IpAddr,
    prefix_bits: u32,
}

impl IpNetwork {
    /// The network of `address` alone.
    pub fn host(address: IpAddr) -> Self {
        IpNetwork { address, prefix_bits: if address.is_ipv4() { 32 } else { 128 } }
    }

    /// Whether the network is an IPv4 one.
    pub fn is_ipv4(&self) -> bool {
        self.address.is_ipv4()
    }

    /// Whether `peer` is in the network (an IPv4 peer seen as an IPv4-mapped IPv6 address counts
    /// as the IPv4 one).
    pub fn contains(&self, peer: IpAddr) -> bool {
        match (self.address, peer.to_canonical()) {
            (IpAddr::V4(network), IpAddr::V4(peer)) => {
                same_prefix(network.to_bits().into(), peer.to_bits().into(), 32, self.prefix_bits)
            }
            (IpAddr::V6(network), IpAddr::V6(peer)) => {
                same_prefix(network.to_bits(), peer.to_bits(), 128, self.prefix_bits)
            }
            _ => false,
        }
    }
}

/// Whether the first `prefix_bits` of two addresses `width` bits wide are equal.
fn same_prefix(a: u128, b: u128, width: u32, prefix_bits: u32) -> bool {
    let ignored_bits = width - prefix_bits;
    ignored_bits >= width || (a ^ b) >> ignored_bits == 0
}

impl std::str::FromStr for IpNetwork {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let expected = || format!("{text:?} is not an IP address or network, expected e.g. 192.168.1.20 or 10.0.0.0/8");
        let (address, prefix) = match text.trim().split_once('/') {
            Some((address, prefix)) => (address, Some(prefix)),
            None => (text.trim(), None),
        };
        let address: IpAddr = address.parse().map_err(|_| expected())?;
        let width = IpNetwork::host(address).prefix_bits;
        let prefix_bits = match prefix {
            None => width,
            Some(prefix) => prefix.parse().ok().filter(|&bits| bits <= width).ok_or_else(expected)?,
        };
        Ok(IpNetwork { address, prefix_bits })
    }
}

impl std::fmt::Display for IpNetwork {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.address, self.prefix_bits)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn networks_parse_and_contain_their_addresses() {
        let network: IpNetwork = "10.1.0.0/16".parse().unwrap();
        assert!(network.contains("10.1.200.3".parse().unwrap()));
        assert!(network.contains("::ffff:10.1.0.9".parse().unwrap()), "IPv4-mapped IPv6 peers count as IPv4");
        assert!(!network.contains("10.2.0.1".parse().unwrap()));
        assert!(!network.contains("::1".parse().unwrap()));
        let single: IpNetwork = "192.168.1.7".parse().unwrap();
        assert!(single.contains("192.168.1.7".parse().unwrap()) && !single.contains("192.168.1.8".parse().unwrap()));
        let any: IpNetwork = "0.0.0.0/0".parse().unwrap();
        assert!(any.contains("203.0.113.5".parse().unwrap()));
        let v6: IpNetwork = "fd00::/8".parse().unwrap();
        assert!(v6.contains("fd12::1".parse().unwrap()) && !v6.contains("fe80::1".parse().unwrap()));
        for bad in ["10.0.0.0/33", "lan", "10.0.0/8", "::/129"] {
            let error = bad.parse::<IpNetwork>().unwrap_err();
            assert!(error.contains(&format!("{bad:?} is not an IP address or network")), "{error}");
        }
    }

    #[test]
    fn a_network_is_shown_as_written_with_its_prefix() {
        assert_eq!("10.0.0.0/24".parse::<IpNetwork>().unwrap().to_string(), "10.0.0.0/24");
        assert_eq!(IpNetwork::host("fd00::1".parse().unwrap()).to_string(), "fd00::1/128");
    }
}
