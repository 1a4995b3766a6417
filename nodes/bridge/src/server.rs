//! The Socket.IO server the simulator connects to. The Unity client asks for `EIO=4` yet speaks
//! Engine.IO 3 and Socket.IO protocol 4 without ever sending the namespace CONNECT, and it sends
//! its first telemetry the moment the websocket opens. The server is therefore `engineioxide` with
//! its `v3` feature behind an `EIO=4` -> `EIO=3` rewrite, plus the small protocol-v4 layer of
//! [`crate::sio`]: every message is handled in arrival order from the first byte on.
//!
//! One simulator is served at a time: a second connection is refused (or, when configured,
//! replaces the first), so that two simulators never share the lock-step frame numbers. Only the
//! websocket transport is served, each request passes the [`crate::gate`] first, and a served
//! simulator that falls silent is closed after the idle timeout, freeing its slot.

use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use axum::http::{Request, Uri};
use bytes::Bytes;
use engineioxide::handler::EngineIoHandler;
use engineioxide::sid::Sid;
use engineioxide::socket::{DisconnectReason, Socket};
use engineioxide::{Str, TransportType, config::EngineIoConfig, layer::EngineIoLayer};
use rover_runtime::rejections::worth_logging;
use rover_runtime::sync::lock;
use tokio::sync::mpsc::error::TrySendError;
use tokio::sync::oneshot;
use tower::util::MapRequestLayer;

use crate::access::AccessPolicy;
use crate::gate::{self, Gate, GatedListener, Peer};
use crate::insets::InsetsSent;
use crate::lockstep::{FrameSink, InFlight, LockStep};
use crate::reply::{DataEvent, Reply};
use crate::sio::{self, Packet};
use crate::stats::BridgeStats;
use crate::telemetry::check_size;

/// Settings of the Socket.IO server.
#[derive(Debug, Clone)]
pub(crate) struct ServerConfig {
    /// Address to listen on.
    pub address: SocketAddr,
    /// Largest websocket message accepted by the transport (larger ones close the connection).
    pub max_message_bytes: usize,
    /// A new simulator connection replaces the one being served instead of being refused.
    pub replace_connected_simulator: bool,
    /// Who may connect.
    pub access: AccessPolicy,
    /// A connection with no admitted websocket handshake by then is closed.
    pub handshake_timeout: Duration,
    /// A served simulator that sends nothing for this long is closed.
    pub idle_timeout: Duration,
}

/// Rewrites `EIO=4` to `EIO=3` in the query, so the Unity client gets the Engine.IO 3 behaviour it speaks.
pub(crate) fn rewrite_engine_io_version<B>(mut request: Request<B>) -> Request<B> {
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
pub(crate) async fn serve<S: FrameSink>(
    core: Arc<LockStep<S>>,
    config: ServerConfig,
    shutdown: impl std::future::Future<Output = ()> + Send + 'static,
) -> anyhow::Result<()> {
    let engine_config = EngineIoConfig::builder()
        .req_path("/socket.io")
        .transports([TransportType::Websocket])
        .ping_interval(Duration::from_secs(25))
        .ping_timeout(Duration::from_secs(60))
        .max_payload(config.max_message_bytes as u64)
        .ws_max_message_size(config.max_message_bytes)
        .ws_max_frame_size(config.max_message_bytes)
        .max_buffer_size(1024)
        .build();
    let handler = Arc::new(SimulatorLink {
        core,
        served: Arc::default(),
        replies: Arc::default(),
        insets_sent: Arc::default(),
        replace_connected: config.replace_connected_simulator,
        idle_timeout: config.idle_timeout,
    });
    let gate = Gate::new(config.access, config.handshake_timeout, handler.core.shared_stats());
    let app = axum::Router::new()
        .layer(EngineIoLayer::from_config(handler, engine_config))
        .layer(axum::middleware::from_fn_with_state(gate.clone(), gate::admit))
        .layer(MapRequestLayer::new(rewrite_engine_io_version));
    let listener = GatedListener::bind(config.address, gate)
        .await
        .with_context(|| format!("cannot listen on {} (is another bridge running?)", config.address))?;
    tracing::info!("waiting for the simulator on ws://{}/socket.io/", config.address);
    axum::serve(listener, app.into_make_service_with_connect_info::<Peer>())
        .with_graceful_shutdown(shutdown)
        .await
        .context("Socket.IO server failed")
}

/// What becomes of a new simulator connection.
#[derive(Debug, PartialEq)]
enum Admission<T> {
    /// No simulator was being served: the new one is.
    Served,
    /// The new one is served instead of this one (its id and connection), which is to be closed.
    Replacing(Sid, T),
    /// The simulator with this id is being served: the new one is refused.
    Refused(Sid),
}

/// The one simulator connection the bridge serves (`T` is the connection, a socket in the server),
/// with when it was last heard from.
#[derive(Debug)]
struct ServedSimulator<T> {
    current: Mutex<Option<Served<T>>>,
}

#[derive(Debug)]
struct Served<T> {
    sid: Sid,
    connection: T,
    last_heard: Instant,
}

impl<T> Default for ServedSimulator<T> {
    fn default() -> Self {
        ServedSimulator { current: Mutex::new(None) }
    }
}

impl<T> ServedSimulator<T> {
    /// Decides on connection `sid`, heard from at `now`: served if none is, else refused, or
    /// served in place of the current one when `replace`.
    fn admit(&self, sid: Sid, connection: T, replace: bool, now: Instant) -> Admission<T> {
        let mut current = self.current();
        if let Some(served) = current.as_ref().filter(|_| !replace) {
            return Admission::Refused(served.sid);
        }
        match current.replace(Served { sid, connection, last_heard: now }) {
            None => Admission::Served,
            Some(old) => Admission::Replacing(old.sid, old.connection),
        }
    }

    /// Notes that connection `sid` sent something at `now`; returns whether it is the one served.
    fn heard(&self, sid: Sid, now: Instant) -> bool {
        let mut current = self.current();
        let served = current.as_mut().filter(|served| served.sid == sid);
        served.map(|served| served.last_heard = now).is_some()
    }

    /// How long connection `sid` has been silent at `now`; `None` if it is not the one served.
    fn silent_for(&self, sid: Sid, now: Instant) -> Option<Duration> {
        let current = self.current();
        current
            .as_ref()
            .filter(|served| served.sid == sid)
            .map(|served| now.saturating_duration_since(served.last_heard))
    }

    /// Forgets connection `sid` if it is the one served; returns whether it was.
    fn release(&self, sid: Sid) -> bool {
        self.current().take_if(|served| served.sid == sid).is_some()
    }

    fn current(&self) -> std::sync::MutexGuard<'_, Option<Served<T>>> {
        lock(&self.current)
    }
}

/// Keeps the replies in the order of their frames, although frames wait for their drive commands
/// side by side: the simulator applies commands in the order they come, and two frames in flight
/// whose replies swapped would leave the rover with the older command.
#[derive(Default)]
struct ReplyOrder {
    previous_sent: Mutex<Option<oneshot::Receiver<()>>>,
}

impl ReplyOrder {
    /// The next reply's turn: it waits for the first (the reply before it was sent, or its task
    /// ended), and fires the second once it is sent itself.
    fn next_turn(&self) -> (Option<oneshot::Receiver<()>>, oneshot::Sender<()>) {
        let (sent, next_waits_for) = oneshot::channel();
        (lock(&self.previous_sent).replace(next_waits_for), sent)
    }
}

/// The Engine.IO handler: one per server; it serves one simulator connection at a time.
struct SimulatorLink<S> {
    core: Arc<LockStep<S>>,
    served: Arc<ServedSimulator<Arc<Socket<()>>>>,
    replies: Arc<ReplyOrder>,
    insets_sent: Arc<InsetsSent<Sid>>,
    replace_connected: bool,
    idle_timeout: Duration,
}

impl<S> Clone for SimulatorLink<S> {
    fn clone(&self) -> Self {
        SimulatorLink {
            core: self.core.clone(),
            served: self.served.clone(),
            replies: self.replies.clone(),
            insets_sent: self.insets_sent.clone(),
            replace_connected: self.replace_connected,
            idle_timeout: self.idle_timeout,
        }
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
        match self.served.admit(socket.id, socket.clone(), self.replace_connected, Instant::now()) {
            Admission::Refused(served) => return self.refuse(&socket, served),
            Admission::Replacing(old_sid, old) => {
                tracing::warn!(sid = %socket.id, "a new simulator connection replaces simulator {old_sid}");
                self.core.stats().client_disconnected("replaced");
                old.close(DisconnectReason::ClosingServer);
            }
            Admission::Served => {}
        }
        tracing::info!(sid = %socket.id, "simulator connected from {}", peer_of(&socket));
        self.core.stats().client_connected();
        if socket.emit(sio::CONNECT).is_err() {
            tracing::warn!(sid = %socket.id, "cannot send the namespace CONNECT");
        }
        self.close_when_silent(socket);
    }

    fn on_disconnect(&self, socket: Arc<Socket<()>>, reason: DisconnectReason) {
        if self.served.release(socket.id) {
            log_disconnect(&socket, &reason, self.core.stats());
        }
    }

    fn on_message(self: &Arc<Self>, message: Str, socket: Arc<Socket<()>>) {
        if !self.served.heard(socket.id, Instant::now()) {
            return;
        }
        let in_flight = match self.packet(&message) {
            Ok(Packet::Event { name, args }) if name == "telemetry" => self.core.receive(args.first()),
            Ok(Packet::Event { name, .. }) => {
                tracing::debug!(sid = %socket.id, "ignored event {name:?}");
                return;
            }
            Ok(_) => return,
            Err((kind, problem)) => self.core.receive_garbage(kind, &problem),
        };
        self.spawn_reply(in_flight, socket);
    }

    fn on_binary(self: &Arc<Self>, data: Bytes, socket: Arc<Socket<()>>) {
        if !self.served.heard(socket.id, Instant::now()) {
            return;
        }
        let problem = format!("binary websocket message of {} bytes (the simulator only sends text)", data.len());
        let in_flight = self.core.receive_garbage("binary_message", &problem);
        self.spawn_reply(in_flight, socket);
    }
}

impl<S: FrameSink> SimulatorLink<S> {
    /// Closes a connection that arrived while simulator `served` is being served; its frames
    /// never reach the lock-step core.
    fn refuse(&self, socket: &Socket<()>, served: Sid) {
        let message = format_args!(
            "refused a second simulator connection ({} from {}): simulator {served} is connected and served \
             (parameter replace_connected_simulator lets a new one take over)",
            socket.id,
            peer_of(socket)
        );
        self.core.stats().warn_problem("simulator_refused", message);
        socket.close(DisconnectReason::ClosingServer);
    }

    /// Closes the served connection `socket` once it has sent nothing for the idle timeout, so
    /// that a simulator that vanished without closing frees the slot for the next one.
    fn close_when_silent(&self, socket: Arc<Socket<()>>) {
        let (served, core, idle_timeout) = (self.served.clone(), self.core.clone(), self.idle_timeout);
        tokio::spawn(async move {
            while let Some(silent_for) = served.silent_for(socket.id, Instant::now()) {
                if silent_for < idle_timeout {
                    tokio::time::sleep(idle_timeout - silent_for).await;
                } else if served.release(socket.id) {
                    let count = core.stats().client_disconnected("idle");
                    if worth_logging(count) {
                        tracing::warn!(
                            sid = %socket.id,
                            "closed the connection of the simulator at {}: nothing received for {:.1} s \
                             (parameter simulator_idle_timeout_s); the next simulator to connect is served \
                             ({count} such so far)",
                            peer_of(&socket),
                            silent_for.as_secs_f64()
                        );
                    }
                    socket.close(DisconnectReason::HeartbeatTimeout);
                }
            }
        });
    }

    /// The Socket.IO packet of a websocket message; or why it was refused: too large (then it is
    /// not parsed at all) or not a packet, as a kind for the counters and a message for the log.
    fn packet(&self, message: &str) -> Result<Packet, (&'static str, String)> {
        check_size(message.len(), self.core.config().max_payload_bytes).map_err(|e| (e.kind(), e.to_string()))?;
        sio::decode(message).map_err(|e| ("unparseable_packet", format!("unparseable Socket.IO packet: {e}")))
    }

    fn spawn_reply(&self, in_flight: InFlight, socket: Arc<Socket<()>>) {
        let core = self.core.clone();
        let (previous_sent, sent) = self.replies.next_turn();
        let insets_sent = self.insets_sent.clone();
        tokio::spawn(async move {
            let reply = core.reply(in_flight).await;
            if let Some(previous_sent) = previous_sent {
                let _ = previous_sent.await;
            }
            send_reply(&socket, &core, &insets_sent, &reply);
            let _ = sent.send(());
        });
    }
}

/// The address `socket` connected from, for the logs.
fn peer_of(socket: &Socket<()>) -> String {
    let peer = socket.req_parts.extensions.get::<axum::extract::ConnectInfo<Peer>>();
    peer.map_or_else(|| "an unknown address".to_string(), |info| info.0.address().to_string())
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

fn send_reply<S: FrameSink>(socket: &Socket<()>, core: &LockStep<S>, insets_sent: &InsetsSent<Sid>, reply: &Reply) {
    let empty = serde_json::Map::new();
    let encoded = match reply {
        Reply::Data(values, _) => {
            let insets = insets_sent.next_reply(socket.id, &core.insets());
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

    #[test]
    fn one_simulator_is_served_and_a_second_is_refused_until_it_leaves() {
        let (first, second, now) = (Sid::new(), Sid::new(), Instant::now());
        let served = ServedSimulator::default();
        assert_eq!(served.admit(first, 1, false, now), Admission::Served);
        assert_eq!(served.admit(second, 2, false, now), Admission::Refused(first));
        assert!(served.heard(first, now) && !served.heard(second, now));
        assert!(!served.release(second), "the refused connection was never served");
        assert!(served.release(first));
        assert_eq!(served.admit(second, 2, false, now), Admission::Served);
        assert!(served.heard(second, now));
    }

    #[test]
    fn with_replacement_the_newest_simulator_is_served() {
        let (first, second, now) = (Sid::new(), Sid::new(), Instant::now());
        let served = ServedSimulator::default();
        assert_eq!(served.admit(first, 1, true, now), Admission::Served);
        assert_eq!(served.admit(second, 2, true, now), Admission::Replacing(first, 1));
        assert!(served.heard(second, now) && !served.heard(first, now));
        assert!(!served.release(first), "the replaced connection's close does not free the slot");
        assert!(served.heard(second, now));
    }

    #[test]
    fn silence_is_counted_from_the_last_message_of_the_served_simulator() {
        let (first, second, start) = (Sid::new(), Sid::new(), Instant::now());
        let served = ServedSimulator::default();
        served.admit(first, 1, false, start);
        let later = |ms| start + Duration::from_millis(ms);
        assert_eq!(served.silent_for(first, later(300)), Some(Duration::from_millis(300)));
        served.heard(first, later(400));
        assert_eq!(served.silent_for(first, later(1000)), Some(Duration::from_millis(600)));
        assert_eq!(served.silent_for(second, later(1000)), None, "a connection not served has no silence");
        served.heard(second, later(2000));
        assert_eq!(
            served.silent_for(first, later(2000)),
            Some(Duration::from_millis(1600)),
            "the refused one's messages do not count"
        );
        served.release(first);
        assert_eq!(served.silent_for(first, later(2000)), None);
    }
}
