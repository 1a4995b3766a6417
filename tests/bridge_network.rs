//! The bridge's Socket.IO server on a real network: only the websocket transport, no browser
//! origins, an optional token and address allow-list, handshake and idle timeouts and a cap on
//! connections, each against the real `rover bridge` process over raw TCP.

mod support;

use std::io::{Read as _, Write as _};
use std::net::TcpStream;
use std::time::{Duration, Instant};

use rover_sim::wire::client::{Connection, unity_url};
use rover_sim::wire::packet::Inbound;
use support::echo_sim::{recorded_frames, telemetry_json};
use support::{Domain, Latest, Process, diagnostic_value, eventually, start_bridge};

/// A websocket upgrade to the Unity client's URL, as websocket-sharp sends it, plus `extra_headers`
/// (each ending in CRLF).
fn websocket_upgrade(port: u16, extra_headers: &str) -> String {
    format!(
        "GET /socket.io/?EIO=4&transport=websocket HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\
         User-Agent: websocket-sharp/1.0\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n\
         Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n{extra_headers}\r\n"
    )
}

/// Sends `request` on a new connection to `port`; the connection and the response's status code.
fn send_request(port: u16, request: &str) -> (TcpStream, u16) {
    let mut stream = TcpStream::connect(("127.0.0.1", port)).expect("connect to the bridge");
    stream.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    stream.write_all(request.as_bytes()).expect("send the request");
    let mut head = Vec::new();
    let mut byte = [0u8; 1];
    while !head.ends_with(b"\r\n") {
        assert_eq!(stream.read(&mut byte).expect("a response within 5 s"), 1, "the bridge closed without a response");
        head.push(byte[0]);
    }
    let status_line = String::from_utf8_lossy(&head).into_owned();
    let status = status_line.split(' ').nth(1).and_then(|code| code.parse().ok());
    (stream, status.unwrap_or_else(|| panic!("not an HTTP status line: {status_line:?}")))
}

fn status_of(port: u16, request: &str) -> u16 {
    send_request(port, request).1
}

/// The status the bridge on `port` answers a websocket upgrade with `extra_headers` with.
fn upgrade_status(port: u16, extra_headers: &str) -> u16 {
    status_of(port, &websocket_upgrade(port, extra_headers))
}

/// Whether the peer closes `stream` within `timeout` (whatever it sends before).
fn closed_within(stream: &mut TcpStream, timeout: Duration) -> bool {
    let deadline = Instant::now() + timeout;
    let mut buffer = [0u8; 4096];
    while Instant::now() < deadline {
        stream
            .set_read_timeout(Some(deadline.saturating_duration_since(Instant::now()).max(Duration::from_millis(1))))
            .unwrap();
        match stream.read(&mut buffer) {
            Ok(0) => return true,
            Ok(_) => continue,
            Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {
                return false;
            }
            Err(_) => return true,
        }
    }
    false
}

fn bridge_with(extra: &[&str]) -> (Domain, Process) {
    support::assert_isolated();
    let domain = Domain::reserve();
    let bridge = start_bridge(&domain, extra);
    (domain, bridge)
}

fn log_contains(bridge: &Process, needle: &str) -> bool {
    eventually(Duration::from_secs(5), || bridge.log_text().contains(needle))
}

#[test]
fn an_engine_io_polling_handshake_is_refused() {
    let (domain, bridge) = bridge_with(&[]);
    let polling =
        format!("GET /socket.io/?EIO=4&transport=polling HTTP/1.1\r\nHost: 127.0.0.1:{}\r\n\r\n", domain.port());
    assert_eq!(status_of(domain.port(), &polling), 400, "only the websocket transport is served");
    assert!(log_contains(&bridge, "only the websocket transport"), "{}", bridge.log_text());
}

#[tokio::test(flavor = "multi_thread")]
async fn a_browser_origin_is_refused_and_counted_and_a_request_without_origin_connects() {
    let (domain, bridge) = bridge_with(&[]);
    let runtime = support::test_runtime(&domain);
    let (mut node, _) = runtime.node::<rover_runtime::NoParams>("observer").unwrap();
    let diagnostics = Latest::subscribe(&mut node, &rover_runtime::topics::DIAGNOSTICS);
    let port = domain.port();
    assert_eq!(upgrade_status(port, "Origin: http://evil.example\r\n"), 403);
    assert!(log_contains(&bridge, "\"http://evil.example\""), "{}", bridge.log_text());
    let counted = || diagnostic_value(&diagnostics, "problem_refused_origin").as_deref() == Some("1");
    assert!(eventually(Duration::from_secs(10), counted), "not counted: {:?}", diagnostics.last());
    assert_eq!(upgrade_status(port, ""), 101, "websocket-sharp sends no Origin");
}

#[test]
fn an_allowed_origin_connects() {
    let (domain, _bridge) = bridge_with(&["allowed_origins:=[http://localhost:8080]"]);
    let port = domain.port();
    assert_eq!(upgrade_status(port, "Origin: http://localhost:8080\r\n"), 101);
    assert_eq!(upgrade_status(port, "Origin: http://evil.example\r\n"), 403);
}

#[test]
fn with_a_token_a_missing_or_wrong_one_is_refused() {
    let (domain, bridge) = bridge_with(&["simulator_token:=s3cret"]);
    let port = domain.port();
    assert_eq!(upgrade_status(port, ""), 401);
    assert_eq!(upgrade_status(port, "Authorization: Bearer guess\r\n"), 401);
    assert!(log_contains(&bridge, "simulator_token"), "the refusal names the parameter: {}", bridge.log_text());
    assert_eq!(upgrade_status(port, "Authorization: Bearer s3cret\r\n"), 101);
}

#[tokio::test(flavor = "multi_thread")]
async fn the_simulator_client_with_the_right_token_is_served() {
    let (domain, _bridge) = bridge_with(&["simulator_token:=s3cret"]);
    let url = unity_url("127.0.0.1", domain.port());
    assert!(Connection::open_with_token(&url, Some("guess")).await.is_err(), "a wrong token is refused");
    let mut connection = Connection::open_with_token(&url, Some("s3cret")).await.expect("served with the token");
    connection.send_telemetry(&telemetry_json(&recorded_frames()[10], 42.0)).await.expect("send telemetry");
    let reply = tokio::time::timeout(Duration::from_secs(5), async {
        loop {
            match connection.receive().await {
                Some(Inbound::Event { name, .. }) => return Some(name),
                Some(_) => continue,
                None => return None,
            }
        }
    });
    assert_eq!(reply.await.expect("a reply within 5 s").as_deref(), Some("data"));
}

#[test]
fn an_address_outside_the_allow_list_is_refused() {
    let (domain, bridge) = bridge_with(&["allowed_addresses:=[10.0.0.0/8, 192.168.1.7]"]);
    let port = domain.port();
    assert_eq!(upgrade_status(port, ""), 403, "127.0.0.1 is not in the list");
    assert!(log_contains(&bridge, "allowed_addresses"), "{}", bridge.log_text());
    let (domain, _bridge) = bridge_with(&["allowed_addresses:=[127.0.0.0/8]"]);
    assert_eq!(status_of(domain.port(), &websocket_upgrade(domain.port(), "")), 101, "127.0.0.1 is in 127.0.0.0/8");
}

#[test]
fn a_silent_simulator_is_closed_after_the_idle_timeout_and_a_new_one_is_served() {
    let (domain, bridge) = bridge_with(&["simulator_idle_timeout_s:=1.0"]);
    let port = domain.port();
    let (mut silent, status) = send_request(port, &websocket_upgrade(port, ""));
    assert_eq!(status, 101);
    let started = Instant::now();
    assert!(closed_within(&mut silent, Duration::from_secs(4)), "the silent simulator is still connected");
    let closed_after = started.elapsed();
    assert!(closed_after >= Duration::from_millis(900), "closed after {closed_after:?}, before the idle timeout");
    assert!(log_contains(&bridge, "simulator_idle_timeout_s"), "{}", bridge.log_text());
    let (mut next, status) = send_request(port, &websocket_upgrade(port, ""));
    assert_eq!(status, 101);
    assert!(!closed_within(&mut next, Duration::from_millis(500)), "the next simulator is served, not refused");
    assert!(!bridge.log_text().contains("refused a second simulator"), "{}", bridge.log_text());
}

#[test]
fn a_connection_without_a_handshake_is_closed_after_the_handshake_timeout() {
    let (domain, bridge) = bridge_with(&["handshake_timeout_s:=1.0"]);
    let mut idle = TcpStream::connect(("127.0.0.1", domain.port())).expect("connect");
    idle.write_all(b"GET /socket.io/?EIO=4&transport=websocket HTTP/1.1\r\n").expect("half a request");
    assert!(closed_within(&mut idle, Duration::from_secs(4)), "a half-sent handshake holds its connection");
    assert!(log_contains(&bridge, "handshake_timeout_s"), "{}", bridge.log_text());
}

#[test]
fn connections_over_the_cap_are_refused_until_one_closes() {
    let (domain, bridge) = bridge_with(&["max_connections:=2"]);
    let port = domain.port();
    let open: Vec<TcpStream> = (0..2).map(|_| TcpStream::connect(("127.0.0.1", port)).expect("connect")).collect();
    assert_eq!(upgrade_status(port, ""), 503, "a third connection is refused");
    assert!(log_contains(&bridge, "max_connections"), "{}", bridge.log_text());
    drop(open);
    let served = eventually(Duration::from_secs(3), || upgrade_status(port, "") == 101);
    assert!(served, "once the others closed, a connection is served");
}
