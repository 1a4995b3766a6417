//! The process runtime (one DDS context per process) and ROS nodes built on it.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use anyhow::Context as _;
use futures::StreamExt;
use ros2_client::{Context, MessageInfo, MessageTypeName, Name, NodeName, NodeOptions, Publisher, Subscription};
use rover_msgs::RosMessage;
use rover_msgs::builtin_interfaces::Time;
use rover_msgs::std_msgs::Header;
use tokio::sync::watch;

use crate::discovery::Discovery;
use crate::graph::NodeTopics;
use crate::matching::Matches;
use crate::names::NodeIdentity;
use crate::params::{self, AUTOSTART, Assignment, NodeParams, ParamSpec, ParamValues, USE_SIM_TIME};
use crate::ros_args::RosArgs;
use crate::rtps_ports::MAX_DOMAIN_ID;
use crate::security;
use crate::shutdown::Shutdown;
use crate::sync::lock;
use crate::topics::{self, Topic};

/// How long a new participant waits before it creates any endpoint. RustDDS 0.15.1 sends its first
/// SPDP announcement 100 ms after the participant is created, but already answers the SPDP of peers
/// that reach it earlier with SEDP data. A Fast DDS peer (rclpy, a `ros2` daemon) drops SEDP data of
/// a participant it does not know yet; if endpoints created later reach it after it has learnt the
/// participant but before the repair of the dropped ones, it never takes those in, although it
/// acknowledges them: the node's `ros_discovery_info` writer, `/rosout`, `/parameter_events` and
/// parameter services stay unknown to it (issue 17). With no endpoint before the first
/// announcement (plus a margin for a loaded machine), every peer receives them in order.
const FIRST_ANNOUNCEMENT_WAIT: Duration = Duration::from_millis(250);

/// Reads `ROS_DOMAIN_ID` (default 0), with a clear error for a bad value.
pub fn domain_id_from_env() -> anyhow::Result<u16> {
    match std::env::var("ROS_DOMAIN_ID") {
        Err(_) => Ok(0),
        Ok(text) if text.trim().is_empty() => Ok(0),
        Ok(text) => text.trim().parse::<u16>().ok().filter(|&id| id <= MAX_DOMAIN_ID).ok_or_else(|| {
            anyhow::anyhow!("ROS_DOMAIN_ID={text:?} is not a whole number between 0 and {MAX_DOMAIN_ID}")
        }),
    }
}

/// What every node of a process shares: the DDS context, what its endpoints have matched, the ROS
/// arguments and the shutdown flag.
///
/// The nodes run without `ros2-client`'s spinner, whose `/clock` reader has the wrong type
/// (`builtin_interfaces/msg/Time`): the runtime answers the parameter services itself
/// ([`crate::param_services`]), follows `/clock` as `rosgraph_msgs/msg/Clock` in nodes that use
/// simulated time, and reads the participant's match events once for all nodes
/// ([`crate::matching`]).
#[derive(Clone)]
pub struct Runtime {
    context: Context,
    matches: Matches,
    ros_args: Arc<RosArgs>,
    shutdown: Shutdown,
}

impl Runtime {
    /// Creates the DDS context on `ROS_DOMAIN_ID`. Must run inside a tokio runtime.
    pub fn new(ros_args: RosArgs, shutdown: Shutdown) -> anyhow::Result<Self> {
        Self::on_domain(domain_id_from_env()?, ros_args, shutdown)
    }

    /// Creates the DDS context on `domain_id`, ignoring `ROS_DOMAIN_ID`, discovering others as far
    /// as `ROS_AUTOMATIC_DISCOVERY_RANGE` and `ROS_STATIC_PEERS` (or `ROS_LOCALHOST_ONLY`) say. Blocks for
    /// [`FIRST_ANNOUNCEMENT_WAIT`] so that the participant has announced itself before its first
    /// endpoint exists.
    pub fn on_domain(domain_id: u16, ros_args: RosArgs, shutdown: Shutdown) -> anyhow::Result<Self> {
        let discovery = Discovery::from_env()?;
        let enclave = security::enclave_from(|name| std::env::var(name).ok(), ros_args.enclave.as_deref())?;
        discovery.spawn_relay(domain_id);
        let builder = discovery.participant(domain_id);
        let builder = match &enclave {
            Some(enclave) => {
                tracing::info!("DDS Security on: enclave {}", enclave.dir.display());
                enclave.secure(builder)
            }
            None => builder,
        };
        let participant =
            builder.build().with_context(|| format!("cannot create the DDS participant on domain {domain_id}"))?;
        std::thread::sleep(FIRST_ANNOUNCEMENT_WAIT);
        let matches = Matches::follow(&participant);
        let context = Context::from_domain_participant(participant)
            .with_context(|| format!("cannot create the ROS context on domain {domain_id}"))?;
        tracing::debug!(domain_id, "DDS participant created");
        Ok(Runtime { context, matches, ros_args: Arc::new(ros_args), shutdown })
    }

    /// The parameters of node `P` (default name `default_name`) as this process's ROS arguments
    /// set them, before the node exists.
    pub fn params<P: NodeParams>(&self, default_name: &str) -> anyhow::Result<P> {
        resolve_params(default_name, &self.ros_args)
    }

    /// The shutdown flag of the process.
    pub fn shutdown(&self) -> Shutdown {
        self.shutdown.clone()
    }

    /// Creates the node whose default name is `default_name`, with its parameters `P` resolved from
    /// the defaults, `--params-file` files and `-p` overrides, its parameter services answered and,
    /// with `use_sim_time`, its clock following `/clock`.
    pub fn node<P: NodeParams>(&self, default_name: &str) -> anyhow::Result<(RosNode, Params<P>)> {
        let identity = NodeIdentity::resolve(default_name, &self.ros_args)?;
        let specs = declared_specs::<P>(default_name);
        let values = resolve_param_values(default_name, &specs, &identity, &self.ros_args)?;
        let (params, options) = Params::<P>::with_values(values);
        let node_name = NodeName::new(&identity.namespace, &identity.name)
            .map_err(|e| anyhow::anyhow!("node name {}: {e}", identity.fully_qualified()))?;
        let node = self
            .context
            .new_node(node_name, options)
            .with_context(|| format!("cannot create node {}", identity.fully_qualified()))?;
        crate::logging::register_rosout(&identity.fully_qualified(), node.logging_handle());
        let node = Arc::new(Mutex::new(node));
        crate::param_services::start(&node, specs)?;
        let topics = crate::graph::node_topics(default_name);
        let mut node = RosNode { node, identity, topics, matches: self.matches.clone(), sim_time: None };
        if node.uses_sim_time() {
            node.follow_clock()?;
        }
        Ok((node, params))
    }
}

/// The parameters node `default_name` declares: those of `P`, and `autostart` for a managed node
/// (a node of the graph).
fn declared_specs<P: NodeParams>(default_name: &str) -> Vec<ParamSpec> {
    let managed = crate::graph::node_topics(default_name).map(|_| params::autostart_spec());
    P::specs().into_iter().chain(managed).collect()
}

fn resolve_param_values(
    default_name: &str,
    specs: &[ParamSpec],
    identity: &NodeIdentity,
    ros_args: &RosArgs,
) -> anyhow::Result<ParamValues> {
    let mut assignments = Vec::new();
    for file in &ros_args.params_files {
        assignments.extend(params::assignments_from_file(file, &identity.fully_qualified())?);
    }
    for p in ros_args.params_for(default_name) {
        let value = params::parse_override(&p.value)
            .map_err(|reason| anyhow::anyhow!("-p {}:={}: {reason}", p.name, p.value))?;
        assignments.push(Assignment {
            name: p.name.clone(),
            value,
            source_name: format!("-p {}:={}", p.name, p.value),
        });
    }
    Ok(params::resolve_values(&identity.fully_qualified(), specs, &assignments)?)
}

/// The parameters of the node whose default name is `default_name`, from the ROS arguments alone
/// (no DDS), for tools that run a node's library offline.
pub fn resolve_params<P: NodeParams>(default_name: &str, ros_args: &RosArgs) -> anyhow::Result<P> {
    let identity = NodeIdentity::resolve(default_name, ros_args)?;
    let specs = declared_specs::<P>(default_name);
    Ok(P::from_values(&resolve_param_values(default_name, &specs, &identity, ros_args)?))
}

/// A ROS 2 node: creates publishers and subscriptions for the graph's [`Topic`]s, with the node's
/// namespace and remaps applied and the topic's QoS.
pub struct RosNode {
    node: Arc<Mutex<ros2_client::Node>>,
    identity: NodeIdentity,
    /// What the graph table lets the node read and write; none for a tool outside the graph.
    topics: Option<&'static NodeTopics>,
    matches: Matches,
    /// The latest `/clock` time, when the node uses simulated time.
    sim_time: Option<Arc<Mutex<Time>>>,
}

impl RosNode {
    /// The node's resolved name and namespace.
    pub fn identity(&self) -> &NodeIdentity {
        &self.identity
    }

    /// A span that tags log events with this node, so they go to `/rosout` under its name.
    pub fn span(&self) -> tracing::Span {
        tracing::info_span!("node", name = %self.identity.fully_qualified())
    }

    /// The node's time: the simulated time of `/clock` when its `use_sim_time` parameter is true
    /// (zero until the first `/clock` message), the wall clock otherwise.
    pub fn now(&self) -> Time {
        match &self.sim_time {
            Some(latest) => lock(latest).clone(),
            None => Time::now(),
        }
    }

    /// A header in `frame_id` stamped with [`RosNode::now`].
    pub fn header(&self, frame_id: &str) -> Header {
        Header::at(frame_id, self.now())
    }

    /// Whether the node configures and activates itself at start: its `autostart` parameter, true
    /// unless set false.
    pub fn autostarts(&self) -> bool {
        self.inner().get_parameter(AUTOSTART) != Some(ros2_client::ParameterValue::Boolean(false))
    }

    /// Whether the node's `use_sim_time` parameter is true.
    pub fn uses_sim_time(&self) -> bool {
        self.inner().get_parameter(USE_SIM_TIME) == Some(ros2_client::ParameterValue::Boolean(true))
    }

    /// Runs `act` on the ros2-client node, e.g. to create a server.
    pub(crate) fn with_inner<T>(&self, act: impl FnOnce(&mut ros2_client::Node) -> T) -> T {
        act(&mut self.inner())
    }

    fn inner(&self) -> std::sync::MutexGuard<'_, ros2_client::Node> {
        lock(&self.node)
    }

    /// Keeps the latest simulated time of `/clock` for [`RosNode::now`].
    fn follow_clock(&mut self) -> anyhow::Result<()> {
        let latest = Arc::new(Mutex::new(Time::default()));
        let clock = Arc::clone(&latest);
        spawn_subscriber(self.subscribe(&topics::CLOCK)?, self.span(), move |message| {
            *lock(&clock) = message.clock;
        });
        self.sim_time = Some(latest);
        Ok(())
    }

    /// Serves the node's lifecycle services; the node starts unconfigured.
    pub fn lifecycle(&self) -> anyhow::Result<crate::lifecycle::Lifecycle> {
        crate::lifecycle::Lifecycle::serve(&self.node)
    }

    /// A client of the lifecycle services of the managed node `node` (fully qualified).
    pub fn lifecycle_client(&self, node: &str) -> anyhow::Result<crate::lifecycle::LifecycleClient> {
        crate::lifecycle::LifecycleClient::new(&mut self.inner(), node)
    }

    /// Creates a publisher on `topic`.
    pub fn publisher<M: RosMessage>(&mut self, topic: &Topic<M>) -> anyhow::Result<Publisher<M>> {
        self.check_in_table(topic.name, "write", |t| t.writes)?;
        let dds_topic = self.dds_topic(topic)?;
        self.inner()
            .create_publisher(&dds_topic, None)
            .with_context(|| format!("cannot create a publisher on {}", topic.name))
    }

    /// Creates a subscription on `topic`.
    pub fn subscription<M: RosMessage>(&mut self, topic: &Topic<M>) -> anyhow::Result<Subscription<M>> {
        self.check_in_table(topic.name, "read", |t| t.reads)?;
        self.subscribe(topic)
    }

    fn subscribe<M: RosMessage>(&mut self, topic: &Topic<M>) -> anyhow::Result<Subscription<M>> {
        let dds_topic = self.dds_topic(topic)?;
        self.inner()
            .create_subscription(&dds_topic, Some(topic.reader_qos()))
            .with_context(|| format!("cannot create a subscription on {}", topic.name))
    }

    /// Refuses a topic that the graph table does not give a node of the graph to `verb`.
    fn check_in_table(
        &self,
        topic: &str,
        verb: &str,
        listed: impl Fn(&NodeTopics) -> &'static [&'static str],
    ) -> anyhow::Result<()> {
        match self.topics {
            Some(entry) if !listed(entry).contains(&topic) => anyhow::bail!(
                "the graph table (libs/runtime/src/graph.rs) does not let node {} {verb} {topic}: add it there",
                entry.node
            ),
            _ => Ok(()),
        }
    }

    /// The messages of `topic` as a stream (see [`messages`]).
    pub fn messages<M: RosMessage>(
        &mut self,
        topic: &Topic<M>,
    ) -> anyhow::Result<impl futures::Stream<Item = M> + Send + 'static> {
        Ok(messages(self.subscription(topic)?))
    }

    /// Resolves once `publisher` has matched a subscription.
    pub async fn subscription_matched<M: RosMessage>(&self, publisher: &Publisher<M>) {
        self.matches.first(publisher.guid()).await;
    }

    /// Resolves once `subscription` has matched a publisher.
    pub async fn publisher_matched<M: RosMessage>(&self, subscription: &Subscription<M>) {
        self.matches.first(subscription.guid()).await;
    }

    /// How many publishers `subscription` has matched.
    pub fn publisher_count<M: RosMessage>(&self, subscription: &Subscription<M>) -> usize {
        self.matches.count(subscription.guid())
    }

    /// How many subscriptions `publisher` has matched.
    pub fn subscription_count<M: RosMessage>(&self, publisher: &Publisher<M>) -> usize {
        self.matches.count(publisher.guid())
    }

    fn dds_topic<M: RosMessage>(&self, topic: &Topic<M>) -> anyhow::Result<ros2_client::dds::rustdds::Topic> {
        let name = self.resolved_name(topic.name)?;
        self.inner()
            .create_topic(&name, MessageTypeName::new(M::PACKAGE, M::NAME), &topic.qos)
            .with_context(|| format!("cannot create topic {name}"))
    }

    /// The absolute name of this node's topic, service or action `name`, namespaced and remapped.
    pub(crate) fn resolved_name(&self, name: &str) -> anyhow::Result<Name> {
        let resolved = self.identity.resolve_topic(name)?;
        Name::parse(&resolved).map_err(|e| anyhow::anyhow!("{resolved}: {e}"))
    }
}

impl Drop for RosNode {
    fn drop(&mut self) {
        crate::logging::unregister_rosout(&self.identity.fully_qualified());
    }
}

/// The messages of `subscription` as a stream that owns it; messages that fail to deserialise are
/// counted, logged (the 1st, 2nd, 4th...) and skipped.
pub fn messages<M: RosMessage>(subscription: Subscription<M>) -> impl futures::Stream<Item = M> + Send + 'static {
    futures::stream::unfold((subscription, 0u64), |(subscription, mut malformed)| async move {
        loop {
            match subscription.async_take().await {
                Ok((message, _info)) => return Some((message, (subscription, malformed))),
                Err(e) => log_malformed::<M>(&mut malformed, &e),
            }
        }
    })
}

/// Counts a message that failed to deserialise in `malformed` and logs the 1st, 2nd, 4th... of a
/// subscription.
fn log_malformed<M: RosMessage>(malformed: &mut u64, error: &dyn std::fmt::Debug) {
    *malformed += 1;
    let count = *malformed;
    if crate::rejections::worth_logging(count) {
        let problem = format!("{error:?}");
        tracing::warn!(
            "dropped a malformed {} message: {} ({count} such so far)",
            M::type_name(),
            crate::rejections::clipped(&problem)
        );
    }
}

/// Publishes `message` with `publisher`, made for `topic`; a failure is logged with the topic's
/// name and the node goes on.
pub fn publish_or_warn<M: RosMessage>(publisher: &Publisher<M>, topic: &Topic<M>, message: M) {
    if let Err(e) = publisher.publish(message) {
        tracing::warn!("cannot publish on {}: {e}", topic.name);
    }
}

/// Spawns a task that calls `handler` for every message of `subscription` until the stream ends.
/// Messages that fail to deserialise are logged and skipped.
pub fn spawn_subscriber<M: RosMessage>(
    subscription: Subscription<M>,
    span: tracing::Span,
    mut handler: impl FnMut(M) + Send + 'static,
) -> tokio::task::JoinHandle<()> {
    spawn_subscriber_with_info(subscription, span, move |message, _info| handler(message))
}

/// [`spawn_subscriber`] whose handler also gets each message's [`MessageInfo`] (source and
/// reception time, publisher).
pub fn spawn_subscriber_with_info<M: RosMessage>(
    subscription: Subscription<M>,
    span: tracing::Span,
    mut handler: impl FnMut(M, MessageInfo) + Send + 'static,
) -> tokio::task::JoinHandle<()> {
    tokio::spawn(tracing::Instrument::instrument(
        async move {
            let mut stream = std::pin::pin!(subscription.async_stream());
            let mut malformed = 0;
            while let Some(received) = stream.next().await {
                match received {
                    Ok((message, info)) => handler(message, info),
                    Err(e) => log_malformed::<M>(&mut malformed, &e),
                }
            }
        },
        span,
    ))
}

/// A node's current parameters; updated when a parameter is set through the ROS 2 parameter services.
#[derive(Clone)]
pub struct Params<P> {
    current: watch::Receiver<P>,
}

impl<P: NodeParams> Params<P> {
    /// A snapshot of the current values.
    pub fn get(&self) -> P {
        self.current.borrow().clone()
    }

    /// A receiver that is notified when a value changes.
    pub fn watch(&self) -> watch::Receiver<P> {
        self.current.clone()
    }

    /// The parameters `values` and the node options that declare them; a value set later (by the
    /// parameter services, which check it first) reaches [`Params::watch`].
    fn with_values(values: ParamValues) -> (Self, NodeOptions) {
        let (sender, current) = watch::channel(P::from_values(&values));
        let mut options = NodeOptions::new().enable_rosout(true).start_parameter_services(false);
        for (name, value) in &values {
            options = options.declare_parameter(name, value.clone());
        }
        let state = Mutex::new(values);
        options = options.parameter_set_action(Box::new(move |name, value| {
            let mut values = lock(&state);
            if name != USE_SIM_TIME && values.get(name) != Some(value) {
                tracing::info!("parameter {name} set to {}", params::describe_value(value));
                values.insert(name.to_string(), value.clone());
                sender.send_replace(P::from_values(&values));
            }
            Ok(())
        }));
        (Params { current }, options)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn values_of(node: &str, args: &[&str]) -> Result<ParamValues, String> {
        let argv = std::iter::once("rover").chain(args.iter().copied()).map(String::from).collect();
        let (_, ros_args) = crate::split_ros_args(argv).map_err(|e| e.to_string())?;
        let identity = NodeIdentity::resolve(node, &ros_args).map_err(|e| e.to_string())?;
        resolve_param_values(node, &declared_specs::<crate::NoParams>(node), &identity, &ros_args)
            .map_err(|e| e.to_string())
    }

    #[test]
    fn every_node_of_the_graph_and_no_tool_has_autostart_true_unless_set() {
        assert_eq!(values_of("pickup", &[]).unwrap().get(AUTOSTART), Some(&ros2_client::ParameterValue::Boolean(true)));
        let off = values_of("pickup", &["--ros-args", "-p", "autostart:=false"]).unwrap();
        assert_eq!(off.get(AUTOSTART), Some(&ros2_client::ParameterValue::Boolean(false)));
        assert_eq!(values_of("evaluator", &[]).unwrap().get(AUTOSTART), None, "a tool is not a managed node");
        let wrong = values_of("pickup", &["--ros-args", "-p", "autostart:=1"]).unwrap_err();
        assert!(wrong.contains("`autostart`") && wrong.contains("a boolean"), "{wrong}");
    }
}
