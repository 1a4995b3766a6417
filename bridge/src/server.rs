//! The Socket.IO server the simulator connects to. The Unity client asks for `EIO=4` yet speaks
//! Engine.IO 3 and Socket.IO protocol 4 without ever sending the namespace CONNECT, and it sends
//! its first telemetry the moment the websocket opens. The server is therefore `engineioxide` with
//! its `v3` feature behind an `EIO=4` -> `EIO=3` rewrite, plus the small protocol-v4 layer of
//! [`crate::sio`]: every message is handled in arrival order from the first byte on.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use anyhow::Context as _;
use axum::http::{Request, Uri};
use bytes::Bytes;
use engineioxide::handler::EngineIoHandler;
use engineioxide::socket::{DisconnectReason, Socket};
use engineioxide::{Str, config::EngineIoConfig, layer::EngineIoLayer};
use tokio::sync::mpsc::error::TrySendError;
use tower::util::MapRequestLayer;

use crate::lockstep::{FrameSink, InFlight, LockStep};
use crate::reply::{DataEvent, Reply};
use crate::sio::{self, Packet};
use crate::stats::BridgeStats;

/// Settings of the Socket.IO server.
#[derive(Debug, Clone, Copy)]
pub struct ServerConfig {
    /// Address to listen on.
    pub address: SocketAddr,
    /// Largest websocket message accepted by the transport (larger ones close the connection).
    pub max_message_bytes: usize,
}

/// Rewrites `EIO=4` to `EIO=3` in the query, so the Unity client gets the Engine.IO 3 behaviour it speaks.
pub fn rewrite_engine_io_version<B>(mut request: Request<B>) -> Request<B> {
    let uri = request.uri();
    if let Some(query) = uri.query().filter(|q| q.split('&').any(|p| p == "EIO=4")) {
        let query: Vec<&str> = query.split('&').map(|p| if p == "EIO=4" { "EIO=3" } else { p }).collect();
        let path_and_query = format!("{}?{}", uri.path(), query.join("&"));
        let mut parts = uri.clone().into_parts();
        if let Ok(path_and_query) = path_and_query.parse() {
            parts.path_and_query = Some(path_and_query);
            if let Ok(rewritten) = Uri::from_parts(parts) {
                *request.uri_mut() = rewritten;
            }
        }
    }
    request
}

/// Serves the simulator until `shutdown` resolves.
pub async fn serve<S: FrameSink>(
    core: Arc<LockStep<S>>,
    config: ServerConfig,
    shutdown: impl std::future::Future<Output = ()> + Send + 'static,
) -> anyhow::Result<()> {
    let engine_config = EngineIoConfig::builder()
        .req_path("/socket.io")
        .ping_interval(Duration::from_secs(25))
        .ping_timeout(Duration::from_secs(60))
        .max_payload(config.max_message_bytes as u64)
        .ws_max_message_size(config.max_message_bytes)
        .ws_max_frame_size(config.max_message_bytes)
        .max_buffer_size(1024)
        .build();
    let handler = Arc::new(SimulatorLink { core });
    let app = axum::Router::new()
        .layer(EngineIoLayer::from_config(handler, engine_config))
        .layer(MapRequestLayer::new(rewrite_engine_io_version));
    let listener = tokio::net::TcpListener::bind(config.address)
        .await
        .with_context(|| format!("cannot listen on {} (is another bridge running?)", config.address))?;
    tracing::info!("waiting for the simulator on ws://{}/socket.io/", config.address);
    axum::serve(listener, app).with_graceful_shutdown(shutdown).await.context("Socket.IO server failed")
}

/// The Engine.IO handler: one per server, shared by all simulator connections.
struct SimulatorLink<S> {
    core: Arc<LockStep<S>>,
}

impl<S> Clone for SimulatorLink<S> {
    fn clone(&self) -> Self {
        SimulatorLink { core: self.core.clone() }
    }
}

impl<S> std::fmt::Debug for SimulatorLink<S> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("SimulatorLink")
    }
}

impl<S: FrameSink> EngineIoHandler for SimulatorLink<S> {
    type Data = ();

    fn on_connect(self: Arc<Self>, socket: Arc<Socket<()>>) {
        tracing::info!(sid = %socket.id, "simulator connected");
        self.core.stats().client_connected();
        if socket.emit(sio::CONNECT).is_err() {
            tracing::warn!(sid = %socket.id, "cannot send the namespace CONNECT");
        }
    }

    fn on_disconnect(&self, socket: Arc<Socket<()>>, reason: DisconnectReason) {
        log_disconnect(&socket, &reason, self.core.stats());
    }

    fn on_message(self: &Arc<Self>, message: Str, socket: Arc<Socket<()>>) {
        let in_flight = match sio::decode(&message) {
            Ok(Packet::Event { name, args }) if name == "telemetry" => self.core.receive(args.first()),
            Ok(Packet::Event { name, .. }) => {
                tracing::debug!(sid = %socket.id, "ignored event {name:?}");
                return;
            }
            Ok(_) => return,
            Err(e) => self.core.receive_garbage("unparseable_packet", &format!("unparseable Socket.IO packet: {e}")),
        };
        self.spawn_reply(in_flight, socket);
    }

    fn on_binary(self: &Arc<Self>, data: Bytes, socket: Arc<Socket<()>>) {
        let problem = format!("binary websocket message of {} bytes (the simulator only sends text)", data.len());
        let in_flight = self.core.receive_garbage("binary_message", &problem);
        self.spawn_reply(in_flight, socket);
    }
}

impl<S: FrameSink> SimulatorLink<S> {
    fn spawn_reply(&self, in_flight: InFlight, socket: Arc<Socket<()>>) {
        let core = self.core.clone();
        tokio::spawn(async move {
            let reply = core.reply(in_flight).await;
            send_reply(&socket, &core, &reply);
        });
    }
}

fn log_disconnect(socket: &Socket<()>, reason: &DisconnectReason, stats: &BridgeStats) {
    let kind = disconnect_kind(reason);
    if matches!(reason, DisconnectReason::TransportClose | DisconnectReason::ClosingServer) {
        tracing::info!(sid = %socket.id, "simulator disconnected ({kind})");
    } else {
        tracing::warn!(sid = %socket.id, "simulator connection lost ({kind}): {reason:?}; waiting for it to reconnect");
    }
    stats.client_disconnected(kind);
}

fn disconnect_kind(reason: &DisconnectReason) -> &'static str {
    match reason {
        DisconnectReason::TransportClose => "closed",
        DisconnectReason::MultipleHttpPollingError => "polling_error",
        DisconnectReason::PacketParsingError => "unparseable_packet",
        DisconnectReason::TransportError => "transport_error",
        DisconnectReason::HeartbeatTimeout => "heartbeat_timeout",
        DisconnectReason::ClosingServer => "server_closing",
    }
}

fn send_reply<S: FrameSink>(socket: &Socket<()>, core: &LockStep<S>, reply: &Reply) {
    let empty = serde_json::Map::new();
    let encoded = match reply {
        Reply::Data(values, _) => {
            let insets = core.insets();
            sio::encode_event("data", &DataEvent::new(*values, &insets.map, &insets.vision))
        }
        Reply::Pickup => sio::encode_event("pickup", &empty),
        Reply::Manual => sio::encode_event("manual", &empty),
    };
    let text = match encoded {
        Ok(text) => text,
        Err(e) => return reply_not_sent(socket, core, &e.to_string()),
    };
    match socket.emit(text) {
        Ok(()) => {}
        Err(TrySendError::Closed(_)) => {
            tracing::debug!(sid = %socket.id, "no reply sent: the simulator has closed the connection")
        }
        Err(e) => reply_not_sent(socket, core, &e.to_string()),
    }
}

fn reply_not_sent<S: FrameSink>(socket: &Socket<()>, core: &LockStep<S>, problem: &str) {
    tracing::warn!(sid = %socket.id, "cannot send the reply: {problem}");
    core.stats().problem("reply_not_sent");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_eio_4_is_rewritten() {
        let request = Request::get("/socket.io/?EIO=4&transport=websocket").body(()).unwrap();
        assert_eq!(rewrite_engine_io_version(request).uri(), "/socket.io/?EIO=3&transport=websocket");
        let request = Request::get("/socket.io/?transport=websocket&EIO=3").body(()).unwrap();
        assert_eq!(rewrite_engine_io_version(request).uri(), "/socket.io/?transport=websocket&EIO=3");
        let request = Request::get("/socket.io/?EIO=40").body(()).unwrap();
        assert_eq!(rewrite_engine_io_version(request).uri(), "/socket.io/?EIO=40");
    }
}
