//! The live view's listening socket: it relays each client to the Foxglove server (which listens
//! on loopback only) while at most `max_clients` are connected; a further client is answered
//! HTTP 503 and closed, with a rate-limited log line and a count. The `foxglove` crate has no cap
//! of its own, and every client costs a message backlog and the encoding of every message. A
//! client must send its handshake request within a timeout, so that connections that send
//! nothing cannot hold the cap, and a web page may connect only from an allowed origin (HTTP 403
//! otherwise), since clients may publish goals and drive.

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use rover_runtime::Rejections;
use tokio::io::{AsyncReadExt as _, AsyncWriteExt as _};
use tokio::net::{TcpListener, TcpSocket, TcpStream};
use tokio::task::{JoinHandle, JoinSet};

/// The kind under which refused clients are counted and logged.
const REFUSED: &str = "Foxglove client over the cap";
/// The answer to a client over the cap.
const SERVICE_UNAVAILABLE: &[u8] =
    b"HTTP/1.1 503 Service Unavailable\r\nConnection: close\r\nContent-Length: 0\r\nRetry-After: 5\r\n\r\n";
/// The answer to a web page from an origin not allowed.
const FORBIDDEN: &[u8] = b"HTTP/1.1 403 Forbidden\r\nConnection: close\r\nContent-Length: 0\r\n\r\n";
/// The allowed origin that stands for any.
const ANY_ORIGIN: &str = "*";
/// How long a refused client gets to take its answer.
const REFUSAL_WRITE_TIMEOUT: Duration = Duration::from_secs(1);
/// The kernel's receive buffer of each relay's connection to the Foxglove server, bytes: small, so
/// that what waits for a slow client stays in the server's backlog (where the oldest is dropped)
/// rather than piling up in socket buffers.
const RELAY_RECEIVE_BUFFER_BYTES: u32 = 256 * 1024;
/// Pause after a failed accept (e.g. out of file descriptors) before the next one.
const ACCEPT_RETRY_PAUSE: Duration = Duration::from_millis(100);
/// Longest handshake request accepted, bytes (a browser's takes about 1 KiB).
const MAX_REQUEST_HEAD_BYTES: usize = 16 * 1024;
/// The end of an HTTP request's head.
const END_OF_HEAD: &[u8] = b"\r\n\r\n";

/// Where and how many clients are served, and from which web origins.
#[derive(Debug, Clone)]
pub(super) struct CapConfig {
    /// The Foxglove server the clients are relayed to.
    pub server: SocketAddr,
    /// Clients connected at once at most.
    pub max_clients: usize,
    /// A client that has not sent its whole handshake request by then is closed.
    pub handshake_timeout: Duration,
    /// The web origins allowed (`*`: any); a client with no Origin header is not a web page.
    pub allowed_origins: Arc<[String]>,
    /// Clients refused for their origin so far.
    pub refused_origins: Arc<AtomicU64>,
}

/// The listening socket and its relays; dropping it (or [`ClientCap::stop`]) closes them all.
pub(super) struct ClientCap {
    local_addr: SocketAddr,
    accepting: JoinHandle<()>,
    refused_origins: Arc<AtomicU64>,
}

impl ClientCap {
    /// Listens on `host:port` and relays clients as `config` says.
    pub(super) async fn start(host: &str, port: u16, config: CapConfig) -> anyhow::Result<ClientCap> {
        let listener = TcpListener::bind((host, port))
            .await
            .map_err(|e| anyhow::anyhow!("cannot serve Foxglove on {host}:{port}: {e}"))?;
        let local_addr = listener.local_addr()?;
        let refused_origins = config.refused_origins.clone();
        let accepting = tokio::spawn(accept_clients(listener, config));
        Ok(ClientCap { local_addr, accepting, refused_origins })
    }

    /// The port clients connect to.
    pub(super) fn port(&self) -> u16 {
        self.local_addr.port()
    }

    /// Web pages refused for their origin so far.
    pub(super) fn refused_origins(&self) -> u64 {
        self.refused_origins.load(Ordering::Relaxed)
    }

    /// Stops accepting and closes every relayed connection.
    pub(super) fn stop(&self) {
        self.accepting.abort();
    }
}

impl Drop for ClientCap {
    fn drop(&mut self) {
        self.stop();
    }
}

/// Accepts clients until aborted; the relays end with it.
async fn accept_clients(listener: TcpListener, config: CapConfig) {
    let mut relays = JoinSet::new();
    let mut refusals = Rejections::default();
    loop {
        let (client, peer) = match listener.accept().await {
            Ok(accepted) => accepted,
            Err(e) => {
                refusals.reject("live view accept", &format_args!("cannot accept a Foxglove client: {e}"));
                tokio::time::sleep(ACCEPT_RETRY_PAUSE).await;
                continue;
            }
        };
        while relays.try_join_next().is_some() {}
        if relays.len() >= config.max_clients {
            let problem = format_args!(
                "refused Foxglove client {peer}: {} clients are connected, the most --max-clients allows",
                relays.len()
            );
            refusals.reject(REFUSED, &problem);
            tokio::spawn(refuse(client));
        } else {
            tracing::info!("Foxglove client {peer} connected ({} of at most {})", relays.len() + 1, config.max_clients);
            relays.spawn(relay(client, peer, config.clone()));
        }
    }
}

/// Answers `client` HTTP 503 and closes it.
async fn refuse(client: TcpStream) {
    refuse_with(client, SERVICE_UNAVAILABLE).await;
}

/// Answers `client` with `response` and closes it.
async fn refuse_with(mut client: TcpStream, response: &[u8]) {
    let _ = tokio::time::timeout(REFUSAL_WRITE_TIMEOUT, client.write_all(response)).await;
}

/// The value of the Origin header of the request whose head is `head`, if it has one.
fn request_origin(head: &[u8]) -> Option<String> {
    let head = String::from_utf8_lossy(head);
    let headers = head.split("\r\n").skip(1).take_while(|line| !line.is_empty());
    let mut origins =
        headers.filter_map(|line| line.split_once(':')).filter(|(name, _)| name.trim().eq_ignore_ascii_case("origin"));
    origins.next().map(|(_, value)| value.trim().to_string())
}

/// Whether a web page from `origin` may connect.
fn origin_allowed(allowed: &[String], origin: &str) -> bool {
    allowed.iter().any(|allowed| allowed == ANY_ORIGIN || allowed.trim_end_matches('/') == origin)
}

/// Waits for the client's handshake request, then copies bytes both ways between `client` and
/// the Foxglove server until either side closes.
async fn relay(mut client: TcpStream, peer: SocketAddr, config: CapConfig) {
    let head = match tokio::time::timeout(config.handshake_timeout, read_request_head(&mut client)).await {
        Ok(Ok(head)) => head,
        Ok(Err(e)) => return tracing::warn!("closed Foxglove client {peer}: {e}"),
        Err(_) => {
            let waited_s = config.handshake_timeout.as_secs_f64();
            return tracing::warn!("closed Foxglove client {peer}: no handshake request within {waited_s:.1} s");
        }
    };
    if let Some(origin) = request_origin(&head).filter(|origin| !origin_allowed(&config.allowed_origins, origin)) {
        let refused = config.refused_origins.fetch_add(1, Ordering::Relaxed) + 1;
        if rover_runtime::rejections::worth_logging(refused) {
            let origin = rover_runtime::rejections::clipped(&origin).into_owned();
            tracing::warn!(
                "refused Foxglove client {peer}: a web page from {origin:?}, not an --allowed-origin ({refused} such so far)"
            );
        }
        return refuse_with(client, FORBIDDEN).await;
    }
    let connected = async {
        let socket = if config.server.is_ipv4() { TcpSocket::new_v4()? } else { TcpSocket::new_v6()? };
        socket.set_recv_buffer_size(RELAY_RECEIVE_BUFFER_BYTES)?;
        let mut upstream = socket.connect(config.server).await?;
        upstream.write_all(&head).await?;
        Ok::<_, std::io::Error>(upstream)
    };
    match connected.await {
        Ok(mut upstream) => {
            let _ = tokio::io::copy_bidirectional(&mut client, &mut upstream).await;
            tracing::info!("Foxglove client {peer} disconnected");
        }
        Err(e) => tracing::warn!("cannot relay Foxglove client {peer} to the server at {}: {e}", config.server),
    }
}

/// The bytes `client` sends up to the end of its request's head (and any after it in the same
/// reads); an error if it closes first or the head is longer than [`MAX_REQUEST_HEAD_BYTES`].
async fn read_request_head(client: &mut TcpStream) -> std::io::Result<Vec<u8>> {
    let mut head = Vec::with_capacity(1024);
    let mut chunk = [0u8; 1024];
    while !head.windows(END_OF_HEAD.len()).any(|window| window == END_OF_HEAD) {
        if head.len() > MAX_REQUEST_HEAD_BYTES {
            let problem = format!("a handshake request over {MAX_REQUEST_HEAD_BYTES} bytes");
            return Err(std::io::Error::new(std::io::ErrorKind::InvalidData, problem));
        }
        let read = client.read(&mut chunk).await?;
        if read == 0 {
            return Err(std::io::Error::new(std::io::ErrorKind::UnexpectedEof, "closed before its handshake request"));
        }
        head.extend_from_slice(&chunk[..read]);
    }
    Ok(head)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cap of `max_clients` in front of a server listening on loopback, and that server.
    async fn cap_in_front(
        max_clients: usize,
        handshake_timeout: Duration,
        origins: &[&str],
    ) -> (ClientCap, TcpListener) {
        let server = TcpListener::bind("127.0.0.1:0").await.unwrap();
        let config = CapConfig {
            server: server.local_addr().unwrap(),
            max_clients,
            handshake_timeout,
            allowed_origins: origins.iter().map(|origin| origin.to_string()).collect(),
            refused_origins: Arc::default(),
        };
        (ClientCap::start("127.0.0.1", 0, config).await.unwrap(), server)
    }

    #[tokio::test]
    async fn a_client_without_a_handshake_is_closed_and_frees_its_place() {
        let (cap, server) = cap_in_front(1, Duration::from_millis(200), &[]).await;
        let mut silent = TcpStream::connect(("127.0.0.1", cap.port())).await.unwrap();
        let closed = tokio::time::timeout(Duration::from_secs(2), silent.read(&mut [0u8; 1])).await;
        assert!(matches!(closed, Ok(Ok(0) | Err(_))), "a client that sends nothing is closed: {closed:?}");
        let request = b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n";
        let mut client = TcpStream::connect(("127.0.0.1", cap.port())).await.unwrap();
        client.write_all(request).await.unwrap();
        let (mut relayed, _) = tokio::time::timeout(Duration::from_secs(2), server.accept())
            .await
            .expect("the next client is relayed")
            .unwrap();
        let mut received = vec![0u8; request.len()];
        relayed.read_exact(&mut received).await.unwrap();
        assert_eq!(received, request, "the server gets the request as sent");
    }

    #[test]
    fn the_origin_is_read_from_the_request_head_and_checked() {
        let head = b"GET / HTTP/1.1\r\nHost: x\r\norigin:  https://app.foxglove.dev \r\n\r\n";
        assert_eq!(request_origin(head).as_deref(), Some("https://app.foxglove.dev"));
        assert_eq!(request_origin(b"GET / HTTP/1.1\r\nHost: x\r\n\r\nOrigin: late"), None, "after the head");
        let allowed = ["https://app.foxglove.dev/".to_string()];
        assert!(origin_allowed(&allowed, "https://app.foxglove.dev"));
        assert!(!origin_allowed(&allowed, "http://evil.example"));
        assert!(origin_allowed(&["*".to_string()], "http://evil.example"));
    }

    #[tokio::test]
    async fn a_web_page_from_an_origin_not_allowed_is_refused_403() {
        let (cap, server) = cap_in_front(4, Duration::from_secs(2), &["https://app.foxglove.dev"]).await;
        let mut page = TcpStream::connect(("127.0.0.1", cap.port())).await.unwrap();
        page.write_all(b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nOrigin: http://evil.example\r\n\r\n").await.unwrap();
        let mut answer = String::new();
        tokio::time::timeout(Duration::from_secs(2), page.read_to_string(&mut answer)).await.unwrap().unwrap();
        assert!(answer.starts_with("HTTP/1.1 403"), "{answer}");
        assert_eq!(cap.refused_origins(), 1);
        let mut foxglove = TcpStream::connect(("127.0.0.1", cap.port())).await.unwrap();
        foxglove.write_all(b"GET / HTTP/1.1\r\nOrigin: https://app.foxglove.dev\r\n\r\n").await.unwrap();
        let relayed = tokio::time::timeout(Duration::from_secs(2), server.accept()).await;
        assert!(relayed.is_ok(), "Foxglove's web app is relayed to the server");
    }
}
