//! The Unity simulator's Socket.IO client, byte for byte (unity-sim-spec 1): it opens the websocket
//! transport directly with `EIO=4`, never sends `40`, emits telemetry when the websocket opens and
//! again on the `0{...}` packet, pings once and then every 25 s after each pong, answers `2` with
//! `3`, fragments messages over 1016 bytes, and reconnects whenever the connection drops.

use std::time::Duration;

use futures::{SinkExt, StreamExt};
use tokio::net::TcpStream;
use tokio::time::Instant;
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use tokio_tungstenite::tungstenite::http::HeaderValue;
use tokio_tungstenite::tungstenite::protocol::frame::Frame;
use tokio_tungstenite::tungstenite::protocol::frame::coding::{Data, OpCode};
use tokio_tungstenite::tungstenite::{self, Message};
use tokio_tungstenite::{MaybeTlsStream, WebSocketStream};

use super::command::{Command, CommandError, parse_command};
use super::packet::{self, Inbound};

/// websocket-sharp splits outgoing messages into frames of this many bytes.
pub const FRAGMENT_BYTES: usize = 1016;
/// How long a closing client waits for the server to close its side.
const CLOSE_WAIT: Duration = Duration::from_secs(1);

/// The URL the Unity client connects to on `host:port`.
pub fn unity_url(host: &str, port: u16) -> String {
    format!("ws://{host}:{port}/socket.io/?EIO=4&transport=websocket")
}

/// Errors of the websocket connection.
#[derive(Debug, thiserror::Error)]
pub enum WireError {
    /// The URL is not a websocket URL.
    #[error("bad websocket URL {url:?}: {reason}")]
    BadUrl {
        /// The URL.
        url: String,
        /// What is wrong.
        reason: String,
    },
    /// The websocket failed.
    #[error("websocket: {0}")]
    Websocket(#[from] tungstenite::Error),
}

/// One websocket connection speaking the Unity client's framing.
pub struct Connection {
    socket: WebSocketStream<MaybeTlsStream<TcpStream>>,
}

impl Connection {
    /// Opens the websocket transport directly (no polling handshake), as websocket-sharp does.
    pub async fn open(url: &str) -> Result<Connection, WireError> {
        Connection::open_with_token(url, None).await
    }

    /// [`Connection::open`], presenting `token` (if any) as `Authorization: Bearer TOKEN`, for a
    /// bridge that asks for one (its parameter `simulator_token`; Unity cannot send one).
    pub async fn open_with_token(url: &str, token: Option<&str>) -> Result<Connection, WireError> {
        let bad_url = |reason: String| WireError::BadUrl { url: url.to_string(), reason };
        let mut request = url.into_client_request().map_err(|e| bad_url(e.to_string()))?;
        request.headers_mut().insert("User-Agent", HeaderValue::from_static("websocket-sharp/1.0"));
        if let Some(token) = token {
            let bearer = HeaderValue::from_str(&format!("Bearer {token}"))
                .map_err(|_| bad_url("the token is not valid in an HTTP header (printable ASCII expected)".into()))?;
            request.headers_mut().insert("Authorization", bearer);
        }
        let (socket, _response) = tokio_tungstenite::connect_async(request).await?;
        Ok(Connection { socket })
    }

    /// Sends a text message, split into 1016-byte fragments when longer (websocket-sharp behaviour).
    pub async fn send_text(&mut self, text: &str) -> Result<(), WireError> {
        let bytes = text.as_bytes();
        if bytes.len() <= FRAGMENT_BYTES {
            self.socket.send(Message::text(text)).await?;
            return Ok(());
        }
        let chunks: Vec<&[u8]> = bytes.chunks(FRAGMENT_BYTES).collect();
        let last = chunks.len() - 1;
        for (index, chunk) in chunks.into_iter().enumerate() {
            let opcode = if index == 0 { OpCode::Data(Data::Text) } else { OpCode::Data(Data::Continue) };
            self.socket.feed(Message::Frame(Frame::message(chunk.to_vec(), opcode, index == last))).await?;
        }
        self.socket.flush().await?;
        Ok(())
    }

    /// Sends any websocket message as is (for tests that send what Unity never would).
    pub async fn send_message(&mut self, message: Message) -> Result<(), WireError> {
        self.socket.send(message).await?;
        Ok(())
    }

    /// Sends a `telemetry` event.
    pub async fn send_telemetry(&mut self, json_object: &str) -> Result<(), WireError> {
        self.send_text(&packet::encode_event("telemetry", json_object)).await
    }

    /// Waits for the next text packet; `None` when the connection is closed.
    /// Binary messages are skipped, as the Unity decoder only reads text.
    pub async fn receive(&mut self) -> Option<Inbound> {
        while let Some(message) = self.socket.next().await {
            match message {
                Ok(Message::Text(text)) => return Some(packet::decode(&text)),
                Ok(Message::Close(_)) | Err(_) => return None,
                Ok(_) => continue,
            }
        }
        None
    }

    /// Closes as Unity does on quit: `41`, then `1`, then the websocket close, and waits (at most
    /// `CLOSE_WAIT`) for the server's close: a socket dropped with a reply still unread is reset,
    /// and the server loses the close packets with it.
    pub async fn close(mut self) {
        let _ = self.send_text(packet::DISCONNECT).await;
        let _ = self.send_text(packet::CLOSE).await;
        let _ = self.socket.close(None).await;
        let drained = async { while let Some(Ok(_)) = self.socket.next().await {} };
        let _ = tokio::time::timeout(CLOSE_WAIT, drained).await;
    }
}

/// The simulation behind the client.
pub trait Simulation {
    /// The telemetry JSON object for the current state (rendered now).
    fn telemetry_json(&mut self) -> String;
    /// Applies one command and advances the simulation by one step.
    fn apply(&mut self, command: Command);
    /// True when the run is over; the client then closes the connection and returns.
    fn finished(&self) -> bool;
    /// When running in real time: the wall-clock instant the next telemetry is due.
    fn due_at(&self) -> Option<std::time::Instant> {
        None
    }
    /// Takes one event of the bridge, its name and JSON argument, as the Unity client does: a
    /// command (`data`, `pickup`, `manual`, `fixed_turn`) is applied, one step; whether it stepped
    /// (an event the client ignores does nothing).
    fn receive_event(&mut self, name: &str, data: Option<&serde_json::Value>) -> Result<bool, CommandError> {
        let Some(command) = parse_command(name, data)? else { return Ok(false) };
        self.apply(command);
        Ok(true)
    }
}

/// Settings of the client loop.
#[derive(Debug, Clone)]
pub struct ClientConfig {
    /// Server URL, see [`unity_url`].
    pub url: String,
    /// Pause between connection attempts while the server is unreachable.
    pub reconnect_delay: Duration,
    /// Pause after a pong before the next ping (25 s in Unity).
    pub ping_interval: Duration,
    /// Token presented to the bridge (its parameter `simulator_token`); Unity sends none.
    pub token: Option<String>,
}

impl ClientConfig {
    /// The Unity client's settings for `host:port`.
    pub fn unity(host: &str, port: u16) -> Self {
        ClientConfig {
            url: unity_url(host, port),
            reconnect_delay: Duration::from_millis(20),
            ping_interval: Duration::from_secs(25),
            token: None,
        }
    }
}

/// What the client did during a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ClientStats {
    /// Connections opened.
    pub connections: u64,
    /// Telemetry events sent.
    pub telemetry_sent: u64,
    /// Commands applied (each answered with one telemetry).
    pub commands_applied: u64,
    /// Commands dropped without telemetry (bad fields, malformed events).
    pub commands_dropped: u64,
    /// Events ignored (unknown names, `get_samples`).
    pub events_ignored: u64,
}

/// Runs the Unity client against the server until the simulation finishes or `stop` resolves,
/// reconnecting whenever the connection drops.
pub async fn run_client<S: Simulation>(
    simulation: &mut S,
    config: &ClientConfig,
    stop: impl std::future::Future<Output = ()>,
) -> ClientStats {
    let mut stats = ClientStats::default();
    let mut stop = std::pin::pin!(stop);
    let mut waiting_logged = false;
    while !simulation.finished() {
        let opened = tokio::select! {
            opened = Connection::open_with_token(&config.url, config.token.as_deref()) => opened,
            () = &mut stop => break,
        };
        let mut connection = match opened {
            Ok(connection) => connection,
            Err(e) => {
                if !std::mem::replace(&mut waiting_logged, true) {
                    tracing::info!("waiting for the server at {}: {e}", config.url);
                }
                tokio::select! {
                    () = tokio::time::sleep(config.reconnect_delay) => continue,
                    () = &mut stop => break,
                }
            }
        };
        waiting_logged = false;
        stats.connections += 1;
        tracing::info!("connected to {}", config.url);
        let over = tokio::select! {
            finished = serve_connection(&mut connection, simulation, config, &mut stats) => finished,
            () = &mut stop => true,
        };
        if over {
            connection.close().await;
            break;
        }
        tracing::warn!("connection to {} lost; reconnecting", config.url);
    }
    stats
}

/// Runs one connection; returns true when the simulation finished, false when the connection dropped.
async fn serve_connection<S: Simulation>(
    connection: &mut Connection,
    simulation: &mut S,
    config: &ClientConfig,
    stats: &mut ClientStats,
) -> bool {
    let mut next_ping: Option<Instant> = None;
    if emit_telemetry(connection, simulation, stats).await.is_err() || connection.send_text(packet::PING).await.is_err()
    {
        return false;
    }
    loop {
        let ping_due = async {
            match next_ping {
                Some(at) => tokio::time::sleep_until(at).await,
                None => std::future::pending().await,
            }
        };
        let inbound = tokio::select! {
            inbound = connection.receive() => inbound,
            () = ping_due => {
                next_ping = None;
                if connection.send_text(packet::PING).await.is_err() { return false; }
                continue;
            }
        };
        let Some(inbound) = inbound else { return false };
        let sent = match inbound {
            Inbound::Open => emit_telemetry(connection, simulation, stats).await,
            Inbound::Ping => connection.send_text(packet::PONG).await,
            Inbound::Pong => {
                next_ping = Some(Instant::now() + config.ping_interval);
                Ok(())
            }
            Inbound::Close => return false,
            Inbound::Event { name, data } => match simulation.receive_event(&name, data.as_ref()) {
                Ok(true) => {
                    stats.commands_applied += 1;
                    if let Some(due) = simulation.due_at() {
                        tokio::time::sleep_until(due.into()).await;
                    }
                    emit_telemetry(connection, simulation, stats).await
                }
                Ok(false) => {
                    stats.events_ignored += 1;
                    Ok(())
                }
                Err(e) => {
                    tracing::warn!("dropped a command: {e}");
                    stats.commands_dropped += 1;
                    Ok(())
                }
            },
            Inbound::Malformed(reason) => {
                tracing::warn!("dropped a malformed event: {reason}");
                stats.commands_dropped += 1;
                Ok(())
            }
            Inbound::Ignored(_) => Ok(()),
        };
        if sent.is_err() {
            return false;
        }
        if simulation.finished() {
            return true;
        }
    }
}

async fn emit_telemetry<S: Simulation>(
    connection: &mut Connection,
    simulation: &mut S,
    stats: &mut ClientStats,
) -> Result<(), WireError> {
    let json = simulation.telemetry_json();
    connection.send_telemetry(&json).await?;
    stats.telemetry_sent += 1;
    Ok(())
}
