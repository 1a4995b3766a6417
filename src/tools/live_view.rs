//! `rover live-view`: the graph's topics live in Foxglove. A WebSocket server of the `foxglove`
//! crate (Foxglove's WebSocket protocol) gets one channel per topic below; each message goes out as
//! the CDR bytes ros2-client sent, with the topic's `ros2msg` schema, as a bag stores it, so that
//! Foxglove decodes camera, map, odometry, TF, rocks, the decision's mode and its planned path with
//! its own ROS 2 readers.

use std::sync::Arc;

use foxglove::websocket::ShutdownHandle;
use foxglove::{ChannelBuilder, Context, PartialMetadata, RawChannel, Schema, WebSocketServer};
use rover_bag::schema::{SCHEMA_ENCODING, schema_text};
use rover_msgs::RosMessage;
use rover_runtime::topics::{self, Topic, TopicVisitor, visit_all};
use rover_runtime::{MessageInfo, NoParams, RosNode, Runtime, spawn_subscriber_with_info};
use tokio::task::JoinHandle;

use crate::tools::bag::record::message_time;

/// Foxglove's default port for a live connection.
pub const DEFAULT_PORT: u16 = 8765;
/// The message encoding of every channel: ROS 2's CDR.
const MESSAGE_ENCODING: &str = "cdr";
/// The topics served (names of the topic table).
const LIVE_TOPICS: [&str; 10] = [
    topics::CAMERA_COMPRESSED.name,
    topics::CAMERA_INFO.name,
    topics::ODOM.name,
    topics::TF.name,
    topics::TF_STATIC.name,
    topics::MAP.name,
    topics::ROCKS.name,
    topics::MODE.name,
    topics::PLAN.name,
    topics::TELEMETRY.name,
];

/// Options of `rover live-view` (and `rover demo --foxglove`).
#[derive(Debug, Clone, clap::Args)]
pub struct LiveViewArgs {
    /// Address to serve on; keep 127.0.0.1 unless Foxglove runs on another machine.
    #[arg(long, default_value = "127.0.0.1", value_name = "HOST")]
    pub host: String,
    /// Port to serve on (Foxglove's default 8765; 0 picks a free one).
    #[arg(long, default_value_t = DEFAULT_PORT, value_name = "PORT")]
    pub port: u16,
}

/// A running live view: the subscriptions of its node and the WebSocket server.
pub struct LiveView {
    /// Holds the channels: they close when their context is dropped.
    _context: Arc<Context>,
    _node: RosNode,
    subscribers: Vec<JoinHandle<()>>,
    server: foxglove::WebSocketServerHandle,
}

impl LiveView {
    /// Starts the server on `args.host:args.port` and subscribes to the live topics with a node
    /// `live_view` on `runtime`.
    pub async fn start(runtime: &Runtime, args: &LiveViewArgs) -> anyhow::Result<Self> {
        let context = Context::new();
        let server = WebSocketServer::new()
            .name("rover")
            .bind(args.host.clone(), args.port)
            .context(&context)
            .start()
            .await
            .map_err(|e| anyhow::anyhow!("cannot serve Foxglove on {}:{}: {e}", args.host, args.port))?;
        let (mut node, _) = runtime.node::<NoParams>("live_view")?;
        let mut forward = Forward { node: &mut node, context: &context, subscribers: Vec::new() };
        visit_all(&mut forward)?;
        let subscribers = std::mem::take(&mut forward.subscribers);
        tracing::info!(
            "Foxglove live view on ws://{}:{} ({} topics): in Foxglove, Open connection, Foxglove WebSocket",
            args.host,
            server.port(),
            subscribers.len()
        );
        Ok(LiveView { _context: context, _node: node, subscribers, server })
    }

    /// Ends the subscriptions and closes the server's connections.
    pub async fn stop(self) {
        for subscriber in &self.subscribers {
            subscriber.abort();
        }
        let shutdown: ShutdownHandle = self.server.stop();
        shutdown.wait().await;
    }
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
