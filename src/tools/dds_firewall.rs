//! `rover dds-firewall`: an nftables ruleset that lets DDS traffic of one domain (UDP to its RTPS
//! ports) in from this host and the allowed peers only. RustDDS listens on every interface
//! whatever the discovery range, and allocates what a fragment header claims before any fragment
//! arrives, so a host that can reach its ports can make a node allocate gigabytes with one packet;
//! these rules keep such packets out.

use rover_runtime::IpNetwork;
use rover_runtime::rtps_ports::{MAX_DOMAIN_ID, domain_ports};

/// Options of `rover dds-firewall`.
#[derive(Debug, clap::Args)]
pub struct DdsFirewallArgs {
    /// The DDS domain whose ports the rules cover (default: ROS_DOMAIN_ID, else 0).
    #[arg(long, value_name = "ID", value_parser = clap::value_parser!(u16).range(..=i64::from(MAX_DOMAIN_ID)))]
    pub domain: Option<u16>,
    /// A host or network let in besides this host, as an address or ADDRESS/BITS; repeat for
    /// more. Default: the addresses of ROS_STATIC_PEERS (semicolon-separated hosts).
    #[arg(long = "allow", value_name = "ADDRESS[/BITS]")]
    pub allow: Vec<String>,
}

/// The ruleset for `domain` letting in `allowed` besides the loopback interface; applying it
/// again replaces it.
fn ruleset(domain: u16, allowed: &[IpNetwork]) -> String {
    let ports = domain_ports(domain);
    let ports = format!("{}-{}", ports.start(), ports.end());
    let table = format!("inet rover_dds_{domain}");
    let mut rules =
        vec!["type filter hook input priority filter; policy accept;".to_string(), "iif \"lo\" accept".to_string()];
    for (family, v4) in [("ip", true), ("ip6", false)] {
        let sources: Vec<String> = allowed.iter().filter(|a| a.is_ipv4() == v4).map(|a| a.to_string()).collect();
        if !sources.is_empty() {
            rules.push(format!("{family} saddr {{ {} }} udp dport {ports} accept", sources.join(", ")));
        }
    }
    rules.push(format!("udp dport {ports} counter drop"));
    let body: Vec<String> = rules.iter().map(|rule| format!("\t\t{rule}")).collect();
    format!(
        "# DDS domain {domain}: RTPS ports {ports} open to this host{}only\ntable {table}\ndelete table {table}\n\
         table {table} {{\n\tchain input {{\n{}\n\t}}\n}}\n",
        if allowed.is_empty() { " " } else { " and the allowed peers " },
        body.join("\n")
    )
}

/// Prints the ruleset that `args` describe.
pub fn run(args: &DdsFirewallArgs) -> anyhow::Result<()> {
    let domain = match args.domain {
        Some(domain) => domain,
        None => rover_runtime::domain_id_from_env()?,
    };
    let allowed: Vec<IpNetwork> = if args.allow.is_empty() {
        rover_runtime::StaticPeers::from_env()?.addresses().iter().copied().map(IpNetwork::host).collect()
    } else {
        let parse = |text: &String| text.parse().map_err(|e: String| anyhow::anyhow!("--allow {e}"));
        args.allow.iter().map(parse).collect::<anyhow::Result<_>>()?
    };
    print!("{}", ruleset(domain, &allowed));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rules_cover_the_domains_ports_and_let_in_loopback_and_the_allowed() {
        let rules = ruleset(7, &["10.78.0.2".parse().unwrap(), "fd00::/8".parse().unwrap()]);
        assert!(rules.contains("udp dport 9150-9399 counter drop"), "{rules}");
        assert!(rules.contains("iif \"lo\" accept"), "{rules}");
        assert!(rules.contains("ip saddr { 10.78.0.2/32 } udp dport 9150-9399 accept"), "{rules}");
        assert!(rules.contains("ip6 saddr { fd00::/8 } udp dport 9150-9399 accept"), "{rules}");
        assert!(!ruleset(0, &[]).contains("saddr"), "only loopback when nothing is allowed");
    }
}
