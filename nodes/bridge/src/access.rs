//! Who may connect to the simulator's Socket.IO server, decided on each HTTP request before
//! Engine.IO sees it: a peer from an allowed address, within the connection cap, opening the
//! websocket transport (as the Unity client does), without a browser's `Origin` unless it is
//! allowed, and with the shared token when one is set. A web page or a LAN peer could otherwise
//! become "the simulator" and drive the rover.

use std::fmt;
use std::net::IpAddr;

use axum::http::{HeaderMap, StatusCode, Uri, header};
use rover_runtime::IpNetwork;

/// What precedes a simulator's token in its `Authorization` header (`Authorization: Bearer TOKEN`).
const BEARER_PREFIX: &str = "Bearer ";

/// The rules of [`AccessPolicy::check`].
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct AccessPolicy {
    /// `Origin` header values accepted (a request carrying any other is refused).
    pub allowed_origins: Vec<String>,
    /// The token a simulator must present; `None`: none asked.
    pub token: Option<String>,
    /// Networks a peer may connect from; empty: any.
    pub allowed_networks: Vec<IpNetwork>,
    /// Open connections at most (the one being checked included).
    pub max_connections: usize,
}

/// Why a request was refused; its kind counts it in the bridge's problems.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Refusal {
    /// The peer's address is in none of the allowed networks.
    Address,
    /// This many connections are open, over the cap.
    TooManyConnections(usize),
    /// Not a websocket upgrade of the websocket transport (e.g. an Engine.IO polling request).
    NotWebsocket,
    /// A browser's `Origin` that is not allowed.
    Origin(String),
    /// No token, or not the expected one.
    Token {
        /// Whether the request presented a token at all.
        presented: bool,
    },
}

impl Refusal {
    /// The problem kind under which the bridge counts refusals of this sort.
    pub(crate) fn kind(&self) -> &'static str {
        match self {
            Refusal::Address => "refused_address",
            Refusal::TooManyConnections(_) => "refused_too_many_connections",
            Refusal::NotWebsocket => "refused_not_websocket",
            Refusal::Origin(_) => "refused_origin",
            Refusal::Token { .. } => "refused_token",
        }
    }

    /// The HTTP status the refusal is answered with.
    pub(crate) fn status(&self) -> StatusCode {
        match self {
            Refusal::Address | Refusal::Origin(_) => StatusCode::FORBIDDEN,
            Refusal::TooManyConnections(_) => StatusCode::SERVICE_UNAVAILABLE,
            Refusal::NotWebsocket => StatusCode::BAD_REQUEST,
            Refusal::Token { .. } => StatusCode::UNAUTHORIZED,
        }
    }
}

/// What was wrong and what was expected, naming the parameter that decides it.
impl fmt::Display for Refusal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Refusal::Address => f.write_str("its address is not in parameter allowed_addresses"),
            Refusal::TooManyConnections(open) => {
                write!(f, "{open} connections are open, more than parameter max_connections")
            }
            Refusal::NotWebsocket => f.write_str(
                "not a websocket upgrade with transport=websocket: only the websocket transport is served, \
                 as the Unity simulator uses",
            ),
            Refusal::Origin(origin) => write!(
                f,
                "it carries Origin {:?}, so it comes from a web page in a browser; a simulator sends no Origin \
                 (parameter allowed_origins lists accepted ones)",
                rover_runtime::rejections::clipped(origin)
            ),
            Refusal::Token { presented: false } => {
                f.write_str("no `Authorization: Bearer` token, expected the one of parameter simulator_token")
            }
            Refusal::Token { presented: true } => f.write_str("its token is not the one of parameter simulator_token"),
        }
    }
}

impl AccessPolicy {
    /// Whether a request for `uri` with `headers` from `peer`, while `open_connections` are open
    /// (its own included), may go on to Engine.IO; the first rule it breaks if not.
    pub(crate) fn check(
        &self,
        peer: IpAddr,
        open_connections: usize,
        uri: &Uri,
        headers: &HeaderMap,
    ) -> Result<(), Refusal> {
        if !self.allows_address(peer) {
            return Err(Refusal::Address);
        }
        if open_connections > self.max_connections {
            return Err(Refusal::TooManyConnections(open_connections));
        }
        if !is_websocket_transport(uri, headers) {
            return Err(Refusal::NotWebsocket);
        }
        if let Some(origin) = headers.get(header::ORIGIN) {
            let origin = String::from_utf8_lossy(origin.as_bytes());
            if !self.allowed_origins.iter().any(|allowed| *allowed == origin) {
                return Err(Refusal::Origin(origin.into_owned()));
            }
        }
        match (&self.token, presented_token(headers)) {
            (None, _) => Ok(()),
            (Some(expected), Some(token)) if same_secret(expected.as_bytes(), token) => Ok(()),
            (Some(_), token) => Err(Refusal::Token { presented: token.is_some() }),
        }
    }

    fn allows_address(&self, peer: IpAddr) -> bool {
        self.allowed_networks.is_empty() || self.allowed_networks.iter().any(|network| network.contains(peer))
    }
}

/// Whether the request opens the websocket transport: `transport=websocket` in the query and an
/// `Upgrade: websocket` header.
fn is_websocket_transport(uri: &Uri, headers: &HeaderMap) -> bool {
    let websocket_query = uri.query().is_some_and(|query| query.split('&').any(|pair| pair == "transport=websocket"));
    let upgrade = headers.get(header::UPGRADE).is_some_and(|value| value.as_bytes().eq_ignore_ascii_case(b"websocket"));
    websocket_query && upgrade
}

/// The token of an `Authorization: Bearer TOKEN` header.
fn presented_token(headers: &HeaderMap) -> Option<&[u8]> {
    headers.get(header::AUTHORIZATION)?.as_bytes().strip_prefix(BEARER_PREFIX.as_bytes())
}

/// Whether two secrets are equal, in a time that does not depend on where they first differ.
fn same_secret(expected: &[u8], presented: &[u8]) -> bool {
    let differences = expected.iter().zip(presented).fold(0u8, |acc, (a, b)| acc | (a ^ b));
    expected.len() == presented.len() && differences == 0
}

#[cfg(test)]
mod tests {
    use super::*;

    const WEBSOCKET_URI: &str = "/socket.io/?EIO=3&transport=websocket";
    const PEER: IpAddr = IpAddr::V4(std::net::Ipv4Addr::new(192, 168, 1, 20));

    fn upgrade_headers(extra: &[(header::HeaderName, &str)]) -> HeaderMap {
        let mut headers = HeaderMap::new();
        headers.insert(header::UPGRADE, "websocket".parse().unwrap());
        for (name, value) in extra {
            headers.insert(name, value.parse().unwrap());
        }
        headers
    }

    fn open_policy() -> AccessPolicy {
        AccessPolicy { max_connections: 4, ..AccessPolicy::default() }
    }

    fn check(policy: &AccessPolicy, uri: &str, headers: &HeaderMap) -> Result<(), Refusal> {
        policy.check(PEER, 1, &uri.parse().unwrap(), headers)
    }

    #[test]
    fn a_websocket_upgrade_without_origin_passes_and_polling_does_not() {
        let policy = open_policy();
        assert_eq!(check(&policy, WEBSOCKET_URI, &upgrade_headers(&[])), Ok(()));
        let polling = check(&policy, "/socket.io/?EIO=3&transport=polling", &HeaderMap::new());
        assert_eq!(polling, Err(Refusal::NotWebsocket));
        assert_eq!(polling.unwrap_err().status(), StatusCode::BAD_REQUEST);
        assert_eq!(check(&policy, WEBSOCKET_URI, &HeaderMap::new()), Err(Refusal::NotWebsocket), "no upgrade");
    }

    #[test]
    fn a_browser_origin_is_refused_unless_allowed() {
        let mut policy = open_policy();
        let evil = upgrade_headers(&[(header::ORIGIN, "http://evil.example")]);
        let refusal = check(&policy, WEBSOCKET_URI, &evil).unwrap_err();
        assert_eq!((refusal.status(), refusal.kind()), (StatusCode::FORBIDDEN, "refused_origin"));
        assert!(refusal.to_string().contains("Origin \"http://evil.example\""), "{refusal}");
        policy.allowed_origins = vec!["http://evil.example".to_string()];
        assert_eq!(check(&policy, WEBSOCKET_URI, &evil), Ok(()));
    }

    #[test]
    fn with_a_token_only_the_right_bearer_token_passes() {
        let policy = AccessPolicy { token: Some("s3cret".to_string()), ..open_policy() };
        let bearer = |token: &str| upgrade_headers(&[(header::AUTHORIZATION, &format!("Bearer {token}"))]);
        assert_eq!(check(&policy, WEBSOCKET_URI, &bearer("s3cret")), Ok(()));
        assert_eq!(check(&policy, WEBSOCKET_URI, &bearer("s3cre")), Err(Refusal::Token { presented: true }));
        assert_eq!(check(&policy, WEBSOCKET_URI, &bearer("s3cret!")), Err(Refusal::Token { presented: true }));
        let missing = check(&policy, WEBSOCKET_URI, &upgrade_headers(&[])).unwrap_err();
        assert_eq!(
            (missing.clone(), missing.status()),
            (Refusal::Token { presented: false }, StatusCode::UNAUTHORIZED)
        );
        assert!(missing.to_string().contains("parameter simulator_token"), "{missing}");
    }

    #[test]
    fn only_peers_of_the_allowed_networks_pass() {
        let networks = |list: &[&str]| list.iter().map(|text| text.parse().unwrap()).collect();
        let mut policy = AccessPolicy { allowed_networks: networks(&["10.0.0.0/8", "192.168.1.7"]), ..open_policy() };
        assert_eq!(check(&policy, WEBSOCKET_URI, &upgrade_headers(&[])), Err(Refusal::Address));
        policy.allowed_networks = networks(&["192.168.0.0/16"]);
        assert_eq!(check(&policy, WEBSOCKET_URI, &upgrade_headers(&[])), Ok(()));
    }

    #[test]
    fn connections_over_the_cap_are_refused_first_of_all_but_the_address() {
        let policy = AccessPolicy { max_connections: 2, ..open_policy() };
        let uri = WEBSOCKET_URI.parse().unwrap();
        assert_eq!(policy.check(PEER, 2, &uri, &upgrade_headers(&[])), Ok(()));
        let refusal = policy.check(PEER, 3, &uri, &HeaderMap::new()).unwrap_err();
        assert_eq!(
            (refusal.clone(), refusal.status()),
            (Refusal::TooManyConnections(3), StatusCode::SERVICE_UNAVAILABLE)
        );
    }

    #[test]
    fn secrets_compare_whole() {
        assert!(same_secret(b"abc", b"abc"));
        assert!(!same_secret(b"abc", b"abd") && !same_secret(b"abc", b"ab") && !same_secret(b"", b"a"));
    }
}
