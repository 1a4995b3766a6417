//! The Socket.IO server the simulator connects to, built on `socketioxide` with the protocol-v4
//! (Engine.IO 3) layer. The Unity client asks for `EIO=4` yet speaks Engine.IO 3 and never sends
//! the namespace CONNECT, so the query is rewritten to `EIO=3` before `socketioxide` sees it.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use anyhow::Context as _;
use axum::http::{Request, Uri};
use serde_json::value::RawValue;
use socketioxide::SocketIo;
use socketioxide::extract::{SocketRef, TryData};
use socketioxide::socket::DisconnectReason;
use tower::util::MapRequestLayer;

use crate::lockstep::{FrameSink, LockStep};
use crate::reply::{DataEvent, Reply};

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
        let query: Vec<&str> = query
            .split('&')
            .map(|p| if p == "EIO=4" { "EIO=3" } else { p })
            .collect();
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
    let (layer, io) = SocketIo::builder()
        .ping_interval(Duration::from_secs(25))
        .ping_timeout(Duration::from_secs(60))
        .max_payload(config.max_message_bytes as u64)
        .ws_max_message_size(config.max_message_bytes)
        .ws_max_frame_size(config.max_message_bytes)
        .max_buffer_size(1024)
        .build_layer();
    io.ns("/", move |socket: SocketRef| {
        let core = core.clone();
        async move { on_connect(socket, core) }
    });
    let app = axum::Router::new()
        .layer(layer)
        .layer(MapRequestLayer::new(rewrite_engine_io_version));
    let listener = tokio::net::TcpListener::bind(config.address)
        .await
        .with_context(|| {
            format!(
                "cannot listen on {} (is another bridge running?)",
                config.address
            )
        })?;
    tracing::info!(
        "waiting for the simulator on ws://{}/socket.io/",
        config.address
    );
    axum::serve(listener, app)
        .with_graceful_shutdown(shutdown)
        .await
        .context("Socket.IO server failed")
}

fn on_connect<S: FrameSink>(socket: SocketRef, core: Arc<LockStep<S>>) {
    tracing::info!(sid = %socket.id, "simulator connected");
    core.stats().client_connected();
    let on_telemetry = core.clone();
    socket.on(
        "telemetry",
        move |socket: SocketRef, TryData(payload): TryData<Box<RawValue>>| {
            let core = on_telemetry.clone();
            async move {
                let payload = payload.ok();
                let reply = core.answer(payload.as_deref().map(RawValue::get)).await;
                send_reply(&socket, &core, &reply);
            }
        },
    );
    socket.on_fallback(|socket: SocketRef| async move {
        tracing::debug!(sid = %socket.id, "ignored an unknown event");
    });
    let on_disconnect = core.clone();
    socket.on_disconnect(move |socket: SocketRef, reason: DisconnectReason| {
        let on_disconnect = on_disconnect.clone();
        async move { log_disconnect(&socket, &reason, on_disconnect.stats()) }
    });
}

fn log_disconnect(
    socket: &SocketRef,
    reason: &DisconnectReason,
    stats: &crate::stats::BridgeStats,
) {
    let kind = disconnect_kind(reason);
    if matches!(
        reason,
        DisconnectReason::TransportClose | DisconnectReason::ClosingServer
    ) {
        tracing::info!(sid = %socket.id, "simulator disconnected: {reason}");
    } else {
        tracing::warn!(sid = %socket.id, "simulator connection lost ({kind}): {reason}; waiting for it to reconnect");
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
        DisconnectReason::ClientNSDisconnect => "client_disconnect",
        DisconnectReason::ServerNSDisconnect => "server_disconnect",
        DisconnectReason::ClosingServer => "server_closing",
    }
}

fn send_reply<S: FrameSink>(socket: &SocketRef, core: &LockStep<S>, reply: &Reply) {
    let empty = serde_json::Map::new();
    let sent = match reply {
        Reply::Data(values, _) => {
            let insets = core.insets();
            socket.emit(
                "data",
                &DataEvent::new(*values, &insets.map, &insets.vision),
            )
        }
        Reply::Pickup => socket.emit("pickup", &empty),
        Reply::Manual => socket.emit("manual", &empty),
    };
    if let Err(e) = sent {
        tracing::warn!(sid = %socket.id, "cannot send the reply: {e}");
        core.stats().problem("reply_not_sent");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_eio_4_is_rewritten() {
        let request = Request::get("/socket.io/?EIO=4&transport=websocket")
            .body(())
            .unwrap();
        assert_eq!(
            rewrite_engine_io_version(request).uri(),
            "/socket.io/?EIO=3&transport=websocket"
        );
        let request = Request::get("/socket.io/?transport=websocket&EIO=3")
            .body(())
            .unwrap();
        assert_eq!(
            rewrite_engine_io_version(request).uri(),
            "/socket.io/?transport=websocket&EIO=3"
        );
        let request = Request::get("/socket.io/?EIO=40").body(()).unwrap();
        assert_eq!(
            rewrite_engine_io_version(request).uri(),
            "/socket.io/?EIO=40"
        );
    }
}
