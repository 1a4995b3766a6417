//! The TCP side of the simulator's server: each accepted connection is counted while it is open
//! (for the connection cap) and closed unless a request on it is admitted by the
//! [`AccessPolicy`] within the handshake timeout, so that a peer that opens connections and sends
//! nothing cannot hold them. [`admit`] applies the policy to each HTTP request.

use std::future::Future as _;
use std::io;
use std::net::SocketAddr;
use std::pin::Pin;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::task::{Context, Poll};
use std::time::Duration;

use axum::extract::connect_info::Connected;
use axum::extract::{ConnectInfo, Request, State};
use axum::http::header;
use axum::middleware::Next;
use axum::response::{IntoResponse as _, Response};
use axum::serve::IncomingStream;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::{TcpListener, TcpStream};
use tokio::time::Sleep;

use crate::access::{AccessPolicy, Refusal};
use crate::stats::BridgeStats;

/// The problem kind of connections closed for want of a handshake.
const HANDSHAKE_TIMEOUT_KIND: &str = "refused_handshake_timeout";

/// The access rules and the count of open connections, shared by the listener and [`admit`].
pub(crate) struct Gate {
    policy: AccessPolicy,
    handshake_timeout: Duration,
    open_connections: AtomicUsize,
    stats: Arc<BridgeStats>,
}

impl Gate {
    /// A gate applying `policy`, closing connections not admitted within `handshake_timeout`,
    /// counting refusals in `stats`.
    pub(crate) fn new(policy: AccessPolicy, handshake_timeout: Duration, stats: Arc<BridgeStats>) -> Arc<Gate> {
        Arc::new(Gate { policy, handshake_timeout, open_connections: AtomicUsize::new(0), stats })
    }

    /// Counts and logs (rate-limited) the refusal of a request from `peer`; the response saying why.
    fn refuse(&self, peer: SocketAddr, refusal: &Refusal) -> Response {
        self.stats.warn_problem(refusal.kind(), format_args!("refused a connection from {peer}: {refusal}"));
        (refusal.status(), [(header::CONNECTION, "close")], format!("{refusal}\n")).into_response()
    }
}

/// A TCP listener whose connections pass through a [`Gate`].
pub(crate) struct GatedListener {
    listener: TcpListener,
    gate: Arc<Gate>,
}

impl GatedListener {
    /// Listens on `address`.
    pub(crate) async fn bind(address: SocketAddr, gate: Arc<Gate>) -> io::Result<GatedListener> {
        Ok(GatedListener { listener: TcpListener::bind(address).await?, gate })
    }
}

impl axum::serve::Listener for GatedListener {
    type Io = GatedStream;
    type Addr = SocketAddr;

    async fn accept(&mut self) -> (GatedStream, SocketAddr) {
        let (stream, peer) = axum::serve::Listener::accept(&mut self.listener).await;
        self.gate.open_connections.fetch_add(1, Ordering::Relaxed);
        let connection = Arc::new(OpenConnection { gate: self.gate.clone(), peer, admitted: AtomicBool::new(false) });
        let deadline = Box::pin(tokio::time::sleep(self.gate.handshake_timeout));
        (GatedStream { stream, connection, handshake: Handshake::Pending(deadline) }, peer)
    }

    fn local_addr(&self) -> io::Result<SocketAddr> {
        self.listener.local_addr()
    }
}

/// One accepted connection, counted as open while it lives.
struct OpenConnection {
    gate: Arc<Gate>,
    peer: SocketAddr,
    admitted: AtomicBool,
}

impl Drop for OpenConnection {
    fn drop(&mut self) {
        self.gate.open_connections.fetch_sub(1, Ordering::Relaxed);
    }
}

/// Where a connection is in its handshake.
enum Handshake {
    /// No request admitted yet: the connection is closed at this deadline.
    Pending(Pin<Box<Sleep>>),
    /// A request was admitted: no deadline.
    Admitted,
    /// The deadline passed: every read fails.
    TimedOut,
}

/// The stream of an accepted connection: a TCP stream whose reads fail once the handshake
/// deadline passes before a request is admitted.
pub(crate) struct GatedStream {
    stream: TcpStream,
    connection: Arc<OpenConnection>,
    handshake: Handshake,
}

impl GatedStream {
    /// Fails once the handshake deadline has passed without an admitted request (logging it the
    /// first time); otherwise wakes the task at the deadline.
    fn check_handshake(&mut self, cx: &mut Context<'_>) -> io::Result<()> {
        if let Handshake::Pending(deadline) = &mut self.handshake {
            if self.connection.admitted.load(Ordering::Relaxed) {
                self.handshake = Handshake::Admitted;
            } else if deadline.as_mut().poll(cx).is_ready() {
                self.handshake = Handshake::TimedOut;
                let gate = &self.connection.gate;
                gate.stats.warn_problem(
                    HANDSHAKE_TIMEOUT_KIND,
                    format_args!(
                        "closed the connection from {}: no admitted websocket handshake within {:.1} s \
                         (parameter handshake_timeout_s)",
                        self.connection.peer,
                        gate.handshake_timeout.as_secs_f64()
                    ),
                );
            }
        }
        match self.handshake {
            Handshake::TimedOut => Err(io::Error::new(io::ErrorKind::TimedOut, "no websocket handshake in time")),
            _ => Ok(()),
        }
    }
}

impl AsyncRead for GatedStream {
    fn poll_read(mut self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &mut ReadBuf<'_>) -> Poll<io::Result<()>> {
        if let Err(timed_out) = self.check_handshake(cx) {
            return Poll::Ready(Err(timed_out));
        }
        Pin::new(&mut self.stream).poll_read(cx, buf)
    }
}

impl AsyncWrite for GatedStream {
    fn poll_write(mut self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &[u8]) -> Poll<io::Result<usize>> {
        Pin::new(&mut self.stream).poll_write(cx, buf)
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.stream).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.stream).poll_shutdown(cx)
    }

    fn poll_write_vectored(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[io::IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        Pin::new(&mut self.stream).poll_write_vectored(cx, bufs)
    }

    fn is_write_vectored(&self) -> bool {
        self.stream.is_write_vectored()
    }
}

/// The connection a request came on, as the request's `ConnectInfo`.
#[derive(Clone)]
pub(crate) struct Peer(Arc<OpenConnection>);

impl Peer {
    /// The peer's address.
    pub(crate) fn address(&self) -> SocketAddr {
        self.0.peer
    }
}

impl Connected<IncomingStream<'_, GatedListener>> for Peer {
    fn connect_info(stream: IncomingStream<'_, GatedListener>) -> Self {
        Peer(stream.io().connection.clone())
    }
}

/// Passes a request on to Engine.IO if the gate's policy admits it (its connection then has no
/// handshake deadline any more); answers it with the refusal's status otherwise.
pub(crate) async fn admit(
    State(gate): State<Arc<Gate>>,
    ConnectInfo(peer): ConnectInfo<Peer>,
    request: Request,
    next: Next,
) -> Response {
    let open = gate.open_connections.load(Ordering::Relaxed);
    match gate.policy.check(peer.address().ip(), open, request.uri(), request.headers()) {
        Ok(()) => {
            peer.0.admitted.store(true, Ordering::Relaxed);
            next.run(request).await
        }
        Err(refusal) => gate.refuse(peer.address(), &refusal),
    }
}
