//! `rover live-view`: the graph's topics live in Foxglove. A WebSocket server of the `foxglove`
//! crate (Foxglove's WebSocket protocol) gets one channel per topic below; each message goes out as
//! the CDR bytes ros2-client sent, with the topic's `ros2msg` schema, as a bag stores it, so that
//! Foxglove decodes camera, map, odometry, TF, rocks, the decision's mode and its planned path with
//! its own ROS 2 readers. A client may publish goals and teleoperation ([`client_publish`]).
//! The server listens on loopback; clients reach it through [`client_cap`], which caps how many
//! are connected, and each client's backlog is small, its oldest messages dropped when it lags.

mod client_cap;
mod client_publish;

use std::net::{Ipv4Addr, SocketAddr};
use std::sync::Arc;
use std::time::Duration;

use foxglove::websocket::{Capability, ServerListener, ShutdownHandle};
use foxglove::{ChannelBuilder, Context, PartialMetadata, RawChannel, Schema, WebSocketServer};
use rover_bag::schema::{SCHEMA_ENCODING, schema_text};
use rover_msgs::RosMessage;
use rover_runtime::topics::{self, Topic, TopicVisitor, visit_all};
use rover_runtime::{MessageInfo, NoParams, RosNode, Runtime, spawn_subscriber_with_info};
use tokio::task::JoinHandle;

use crate::tools::bag::record::message_time;
use client_cap::{CapConfig, ClientCap};

/// Foxglove's default port for a live connection.
pub const DEFAULT_PORT: u16 = 8765;
/// The address served by default: this machine only.
const DEFAULT_HOST: &str = "127.0.0.1";
/// The web origin allowed by default: Foxglove's own web app.
const FOXGLOVE_WEB_ORIGIN: &str = "https://app.foxglove.dev";
/// Clients connected at once by default (a person or two watching).
const DEFAULT_MAX_CLIENTS: u16 = 4;
/// Messages queued per client by default, about a second of the camera, odometry and transforms.
const DEFAULT_CLIENT_BACKLOG: u16 = 128;
/// A client that has not sent its handshake request after this long is closed.
const CLIENT_HANDSHAKE_TIMEOUT: Duration = Duration::from_secs(5);
/// The smallest backlog: a client's first messages (server info, one advertisement per topic)
/// share the queue's size, and a client whose control messages overflow it is disconnected.
const MIN_CLIENT_BACKLOG: i64 = 32;
/// The message encoding of every channel: ROS 2's CDR.
const MESSAGE_ENCODING: &str = "cdr";
/// The topics served (names of the topic table).
pub const LIVE_TOPICS: [&str; 11] = [
    topics::CAMERA_COMPRESSED.name,
    topics::CAMERA_INFO.name,
    topics::ODOM.name,
    topics::TF.name,
    topics::TF_STATIC.name,
    topics::MAP.name,
    topics::ROCKS.name,
    topics::SAMPLE_MARKERS.name,
    topics::MODE.name,
    topics::PLAN.name,
    topics::TELEMETRY.name,
];

/// Options of `rover live-view` (and `rover demo --foxglove`).
#[derive(Debug, Clone, clap::Args)]
pub struct LiveViewArgs {
    /// Address to serve on: 127.0.0.1 (this machine only) by default. Another address lets any
    /// peer that reaches it watch the graph and publish goals and teleoperation.
    #[arg(long, default_value = DEFAULT_HOST, value_name = "HOST")]
    pub host: String,
    /// Port to serve on (Foxglove's default 8765; 0 picks a free one).
    #[arg(long, default_value_t = DEFAULT_PORT, value_name = "PORT")]
    pub port: u16,
    /// Clients connected at once at most; a further one is refused (HTTP 503) and logged.
    #[arg(long, default_value_t = DEFAULT_MAX_CLIENTS, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    pub max_clients: u16,
    /// Messages queued for each client at most; a client that lags behind loses the oldest ones
    /// (logged at most every 30 s) instead of the queue growing with it.
    #[arg(long, default_value_t = DEFAULT_CLIENT_BACKLOG, value_name = "MESSAGES",
          value_parser = clap::value_parser!(u16).range(MIN_CLIENT_BACKLOG..))]
    pub client_backlog: u16,
    /// A web page that may connect (its Origin, e.g. https://app.foxglove.dev); repeat for more,
    /// or give * for any. Pages from other origins are refused (HTTP 403), since a client may
    /// publish goals and drive; clients that are not web pages send no Origin and connect.
    #[arg(long = "allowed-origin", value_name = "ORIGIN", default_value = FOXGLOVE_WEB_ORIGIN)]
    pub allowed_origins: Vec<String>,
}

impl LiveViewArgs {
    /// The default options, serving on loopback port `port`.
    pub fn local(port: u16) -> Self {
        LiveViewArgs {
            host: DEFAULT_HOST.to_string(),
            port,
            max_clients: DEFAULT_MAX_CLIENTS,
            client_backlog: DEFAULT_CLIENT_BACKLOG,
            allowed_origins: vec![FOXGLOVE_WEB_ORIGIN.to_string()],
        }
    }
}

/// A running live view: the subscriptions of its node and the WebSocket server.
pub struct LiveView {
    /// Holds the channels: they close when their context is dropped.
    _context: Arc<Context>,
    _node: RosNode,
    subscribers: Vec<JoinHandle<()>>,
    server: foxglove::WebSocketServerHandle,
    clients: ClientCap,
}

impl LiveView {
    /// Starts the server on `args.host:args.port` and subscribes to the live topics with a node
    /// `live_view` on `runtime`.
    pub async fn start(runtime: &Runtime, args: &LiveViewArgs) -> anyhow::Result<Self> {
        let context = Context::new();
        let (mut node, _) = runtime.node::<NoParams>("live_view")?;
        let client_topics = Arc::new(client_publish::ClientTopics::new(&mut node)?);
        let (server, clients) = serve(&context, args, client_topics).await?;
        let mut forward = Forward { node: &mut node, context: &context, subscribers: Vec::new() };
        visit_all(&mut forward)?;
        let subscribers = std::mem::take(&mut forward.subscribers);
        tracing::info!(
            "Foxglove live view on ws://{}:{} ({} topics): in Foxglove, Open connection, Foxglove WebSocket",
            args.host,
            clients.port(),
            subscribers.len()
        );
        Ok(LiveView { _context: context, _node: node, subscribers, server, clients })
    }

    /// Ends the subscriptions and closes the server's connections.
    pub async fn stop(self) {
        for subscriber in &self.subscribers {
            subscriber.abort();
        }
        self.clients.stop();
        let refused = self.clients.refused_origins();
        if refused > 0 {
            tracing::info!("live view: refused {refused} web pages from origins not allowed");
        }
        let shutdown: ShutdownHandle = self.server.stop();
        shutdown.wait().await;
    }
}

/// The Foxglove server of `context` on loopback, reached through the client cap on the address
/// of `args`; `listener` takes what clients publish.
async fn serve(
    context: &Arc<Context>,
    args: &LiveViewArgs,
    listener: Arc<dyn ServerListener>,
) -> anyhow::Result<(foxglove::WebSocketServerHandle, ClientCap)> {
    let server = WebSocketServer::new()
        .name("rover")
        .bind(Ipv4Addr::LOCALHOST.to_string(), 0)
        .context(context)
        .capabilities([Capability::ClientPublish])
        .supported_encodings(client_publish::ENCODINGS)
        .listener(listener)
        .message_backlog_size(usize::from(args.client_backlog))
        .start()
        .await
        .map_err(|e| anyhow::anyhow!("cannot start the Foxglove server on loopback: {e}"))?;
    let config = CapConfig {
        server: SocketAddr::from((Ipv4Addr::LOCALHOST, server.port())),
        max_clients: usize::from(args.max_clients),
        handshake_timeout: CLIENT_HANDSHAKE_TIMEOUT,
        allowed_origins: args.allowed_origins.iter().cloned().collect(),
        refused_origins: Arc::default(),
    };
    let clients = ClientCap::start(&args.host, args.port, config).await?;
    Ok((server, clients))
}

/// Makes a channel for each live topic and forwards its messages.
struct Forward<'a> {
    node: &'a mut RosNode,
    context: &'a Arc<Context>,
    subscribers: Vec<JoinHandle<()>>,
}

impl TopicVisitor for Forward<'_> {
    fn visit<M: RosMessage>(&mut self, topic: &Topic<M>) -> anyhow::Result<()> {
        if !LIVE_TOPICS.contains(&topic.name) {
            return Ok(());
        }
        let channel = channel::<M>(self.context, &self.node.identity().resolve_topic(topic.name)?)?;
        let handler = move |message: M, info: MessageInfo| match rover_runtime::cdr::encode(&message) {
            Ok(data) => channel.log_with_meta(&data, PartialMetadata { log_time: Some(message_time(&info).log_ns) }),
            Err(e) => tracing::warn!("{e:#}"),
        };
        let subscription = self.node.subscription(topic)?;
        self.subscribers.push(spawn_subscriber_with_info(subscription, self.node.span(), handler));
        Ok(())
    }
}

/// The channel of topic `name` carrying messages of type `M` in CDR.
fn channel<M: RosMessage>(context: &Arc<Context>, name: &str) -> anyhow::Result<Arc<RawChannel>> {
    let schema = Schema::new(M::type_name(), SCHEMA_ENCODING, schema_text(&M::definitions()).into_bytes());
    ChannelBuilder::new(name)
        .message_encoding(MESSAGE_ENCODING)
        .schema(schema)
        .context(context)
        .build_raw()
        .map_err(|e| anyhow::anyhow!("cannot make the Foxglove channel {name}: {e}"))
}

/// Runs `rover live-view` until shutdown.
pub async fn run(args: &LiveViewArgs, runtime: &Runtime) -> anyhow::Result<()> {
    let view = LiveView::start(runtime, args).await?;
    runtime.shutdown().wait().await;
    view.stop().await;
    Ok(())
}

#[cfg(test)]
mod tests {
    use std::time::Instant;

    use futures::{SinkExt as _, StreamExt as _};
    use rover_msgs::std_msgs::Header;
    use tokio::net::TcpSocket;
    use tokio_tungstenite::tungstenite::client::IntoClientRequest as _;
    use tokio_tungstenite::tungstenite::http::HeaderValue;
    use tokio_tungstenite::tungstenite::{self, Message};
    use tokio_tungstenite::{WebSocketStream, client_async};

    use super::*;

    /// Foxglove's WebSocket subprotocol.
    const SUBPROTOCOL: &str = "foxglove.sdk.v1";
    /// Opcode of a binary message carrying a subscribed channel's message; its payload starts
    /// after the opcode, the subscription id and the log time.
    const MESSAGE_DATA: u8 = 0x01;
    const PAYLOAD_OFFSET: usize = 13;
    /// The kernel receive buffer of a test client, bytes: small, so that a client that does not
    /// read holds little in its socket.
    const CLIENT_RECEIVE_BUFFER_BYTES: u32 = 16 * 1024;

    struct NoPublishing;

    impl ServerListener for NoPublishing {}

    fn options(max_clients: u16, client_backlog: u16) -> LiveViewArgs {
        LiveViewArgs { port: 0, max_clients, client_backlog, ..LiveViewArgs::local(0) }
    }

    async fn connect(port: u16) -> Result<WebSocketStream<tokio::net::TcpStream>, tungstenite::Error> {
        let socket = TcpSocket::new_v4()?;
        socket.set_recv_buffer_size(CLIENT_RECEIVE_BUFFER_BYTES)?;
        let stream = socket.connect(SocketAddr::from((Ipv4Addr::LOCALHOST, port))).await?;
        let mut request = format!("ws://127.0.0.1:{port}").into_client_request()?;
        request.headers_mut().insert("Sec-WebSocket-Protocol", HeaderValue::from_static(SUBPROTOCOL));
        Ok(client_async(request, stream).await?.0)
    }

    /// The status of the HTTP response refusing a websocket handshake.
    fn refusal_status(connected: Result<WebSocketStream<tokio::net::TcpStream>, tungstenite::Error>) -> Option<u16> {
        match connected {
            Err(tungstenite::Error::Http(response)) => Some(response.status().as_u16()),
            _ => None,
        }
    }

    #[tokio::test(flavor = "multi_thread")]
    async fn clients_over_the_cap_are_refused_until_one_leaves() {
        let context = Context::new();
        let (_server, clients) = serve(&context, &options(2, 32), Arc::new(NoPublishing)).await.unwrap();
        let first = connect(clients.port()).await.expect("the first client connects");
        let _second = connect(clients.port()).await.expect("the second client connects");
        assert_eq!(refusal_status(connect(clients.port()).await), Some(503), "a third client is refused");
        drop(first);
        let deadline = Instant::now() + Duration::from_secs(3);
        while connect(clients.port()).await.is_err() {
            assert!(Instant::now() < deadline, "no client connects after the first left");
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    }

    /// The sequence number in a message of the test channel.
    fn sequence(data: &[u8]) -> Option<u64> {
        (data.first() == Some(&MESSAGE_DATA)).then_some(())?;
        Some(u64::from_le_bytes(data.get(PAYLOAD_OFFSET..PAYLOAD_OFFSET + 8)?.try_into().ok()?))
    }

    /// Subscribes `client` to the channel advertised as `topic`.
    async fn subscribe(client: &mut WebSocketStream<tokio::net::TcpStream>, topic: &str) {
        while let Some(Ok(message)) = client.next().await {
            let Message::Text(text) = message else { continue };
            let advertised: serde_json::Value = serde_json::from_str(&text).unwrap();
            let channels = advertised["channels"].as_array().cloned().unwrap_or_default();
            if let Some(channel) = channels.iter().find(|channel| channel["topic"] == topic) {
                let request =
                    serde_json::json!({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": channel["id"]}]});
                client.send(Message::text(request.to_string())).await.unwrap();
                return;
            }
        }
        panic!("{topic} was never advertised");
    }

    #[tokio::test(flavor = "multi_thread")]
    async fn a_client_that_does_not_read_loses_the_oldest_messages_not_the_newest() {
        let context = Context::new();
        let (_server, clients) = serve(&context, &options(4, 32), Arc::new(NoPublishing)).await.unwrap();
        let channel = channel::<Header>(&context, "/lagging").unwrap();
        let mut client = connect(clients.port()).await.unwrap();
        subscribe(&mut client, "/lagging").await;
        let message = |sequence: u64| [sequence.to_le_bytes().to_vec(), vec![0; 32 * 1024]].concat();
        let subscribed = async {
            loop {
                channel.log(&message(0));
                if let Ok(Some(Ok(Message::Binary(data)))) =
                    tokio::time::timeout(Duration::from_millis(50), client.next()).await
                {
                    break sequence(&data);
                }
            }
        };
        assert_eq!(tokio::time::timeout(Duration::from_secs(5), subscribed).await.expect("subscribed"), Some(0));
        const PUBLISHED: u64 = 2000;
        for sequence in 1..=PUBLISHED {
            channel.log(&message(sequence));
        }
        let mut received = Vec::new();
        while received.last() != Some(&PUBLISHED) {
            let next = tokio::time::timeout(Duration::from_secs(2), client.next()).await;
            let Ok(Some(Ok(Message::Binary(data)))) = next else { panic!("message {PUBLISHED} never came") };
            received.extend(sequence(&data).filter(|&s| s > 0));
        }
        assert!(received.is_sorted(), "messages keep their order");
        assert!(
            (received.len() as u64) < PUBLISHED / 2,
            "{} of {PUBLISHED} messages were kept for a client that did not read",
            received.len()
        );
    }
}
