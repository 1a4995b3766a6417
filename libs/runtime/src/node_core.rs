//! What a node of the graph does, apart from how its messages travel: a [`NodeCore`] takes the
//! messages of the topics it reads and writes messages into an [`Outbox`]. The DDS adapter
//! ([`crate::run_node`]) and the in-process executor ([`crate::executor::Executor`]) run the same
//! cores, so the graph is wired once: by the graph table and each core's [`Inputs`].

use std::any::Any;
use std::time::Instant;

use rover_msgs::RosMessage;
use rover_msgs::builtin_interfaces::Time;
use rover_msgs::std_msgs::Header;

use crate::NodeParams;
use crate::commands::{Action, ActionReport, Commands, GoalEnd, GoalId};
use crate::ports::{Named, Ports};
use crate::topics::Topic;

/// A node's behaviour: built from its parameters, driven by its input messages.
pub trait NodeCore: Sized + 'static {
    /// The node's parameters.
    type Params: NodeParams;
    /// The node's default name: its entry of the graph table.
    const NAME: &'static str;
    /// Whether, once asked to stop, the node still handles the messages already sent to it
    /// (a map should include every scan the rover drove on).
    const DRAINS_ON_STOP: bool = false;
    /// Whether the core is built, with its subscriptions and publishers, when the node starts and
    /// kept in every lifecycle state until shutdown, so that it handles its work from outside the
    /// graph and its timer even while unconfigured (the bridge publishes the simulator's frames,
    /// which it answers with the brake until active, and its diagnostics); configure and cleanup
    /// then only mark the state.
    const BUILT_AT_START: bool = false;

    /// The handler of each topic the node reads: exactly the graph table's reads of the node.
    fn inputs() -> Inputs<Self>;

    /// The handlers of the topics the node still answers while inactive (lifecycle), such as a
    /// brake for each frame; the other messages are dropped while inactive.
    fn inactive_inputs() -> Inputs<Self> {
        Inputs::new()
    }

    /// The commands (services and actions of [`crate::commands`]) the node serves: exactly the
    /// graph table's serves of the node. Only an active core gets their calls; the adapter
    /// refuses them for it otherwise.
    fn commands() -> Commands<Self> {
        Commands::new()
    }

    /// Called once when the node first becomes active, e.g. to publish a latched topic's first
    /// value.
    fn start(&mut self, _out: &mut Outbox) {}

    /// Called when the node becomes active (`true`) and when it stops being active (`false`:
    /// deactivated, cleaned up or shut down).
    fn set_active(&mut self, _active: bool) {}

    /// Takes parameters set while the node runs.
    fn set_params(&mut self, params: Self::Params);

    /// When the core next wants [`NodeCore::on_timer`], if at all (the wall clock: only the DDS
    /// adapter has timers; the in-process executor runs in lock step).
    fn timer_due(&self) -> Option<Instant> {
        None
    }

    /// The timer of [`NodeCore::timer_due`] went off.
    fn on_timer(&mut self, _out: &mut Outbox) {}

    /// Called once when the node stops, after the drained messages: final publications, snapshots
    /// and the summary log line.
    fn stop(&mut self, _out: &mut Outbox) {}
}

/// A core built from its parameters alone: every core but the bridge's, which shares the
/// simulator's connection with its Socket.IO server.
pub trait FromParams: NodeCore {
    /// The core, configured by `params`.
    fn new(params: Self::Params) -> anyhow::Result<Self>;
}

/// Work for a core from outside the graph (the bridge's simulator frames), run by the adapter
/// on the configured core like a message.
pub type Work<C> = Box<dyn FnOnce(&mut C, &mut Outbox) + Send>;

/// The type-erased handler of one input topic of core `C`.
pub(crate) trait InputPort<C>: Named {
    /// Subscribes `node` to the topic: a stream of its messages.
    fn subscribe(&self, node: &mut crate::RosNode) -> anyhow::Result<futures::stream::BoxStream<'static, Received>>;
    /// Hands `message`, which must be of the topic's type, to the core.
    fn deliver(&self, core: &mut C, message: &dyn Any, out: &mut Outbox);
}

/// One received message: its topic's name and the message, of the topic's type.
pub(crate) type Received = (&'static str, Box<dyn Any + Send>);

/// A handler of messages of type `M`.
type Handler<C, M> = fn(&mut C, &M, &mut Outbox);

struct Port<C, M: 'static> {
    topic: &'static Topic<M>,
    handler: Handler<C, M>,
}

impl<C, M> Named for Port<C, M> {
    fn name(&self) -> &'static str {
        self.topic.name
    }
}

impl<C: 'static, M: RosMessage> InputPort<C> for Port<C, M> {
    fn subscribe(&self, node: &mut crate::RosNode) -> anyhow::Result<futures::stream::BoxStream<'static, Received>> {
        use futures::StreamExt as _;
        let name = self.topic.name;
        let messages = node.messages(self.topic)?;
        Ok(messages.map(move |message| -> Received { (name, Box::new(message)) }).boxed())
    }

    fn deliver(&self, core: &mut C, message: &dyn Any, out: &mut Outbox) {
        let message = message.downcast_ref::<M>().expect("a message of the topic's type: the topic table types both");
        (self.handler)(core, message, out);
    }
}

/// The topics a core reads, each with its handler.
pub struct Inputs<C> {
    pub(crate) ports: Ports<dyn InputPort<C>>,
}

impl<C: 'static> Inputs<C> {
    /// No input yet.
    pub fn new() -> Self {
        Inputs { ports: Ports::default() }
    }

    /// Adds `topic`, whose messages go to `handler`.
    pub fn on<M: RosMessage>(mut self, topic: &'static Topic<M>, handler: Handler<C, M>) -> Self {
        self.ports.push(Box::new(Port { topic, handler }));
        self
    }
}

impl<C: 'static> Default for Inputs<C> {
    fn default() -> Self {
        Self::new()
    }
}

/// A message written by a core, not yet sent.
pub struct Sent {
    /// The topic's name, as in the topic table.
    pub topic: &'static str,
    message: Box<dyn Any + Send>,
}

impl Sent {
    pub(crate) fn new(topic: &'static str, message: Box<dyn Any + Send>) -> Self {
        Sent { topic, message }
    }

    /// The message, if it was written on `topic`.
    pub fn on<M: RosMessage>(&self, topic: &Topic<M>) -> Option<&M> {
        if self.topic == topic.name { self.message.downcast_ref() } else { None }
    }

    /// The report, if it is one on a goal of `action`.
    pub fn report<G, R: RosMessage, F: RosMessage>(&self, action: &Action<G, R, F>) -> Option<&ActionReport<R, F>> {
        if self.topic == action.name { self.message.downcast_ref() } else { None }
    }

    pub(crate) fn message(&self) -> &dyn Any {
        &*self.message
    }

    pub(crate) fn into_message(self) -> Box<dyn Any + Send> {
        self.message
    }
}

/// Where a core writes its messages while it handles one input; the runner then sends them.
pub struct Outbox {
    now: Time,
    unread: Vec<&'static str>,
    sent: Vec<Sent>,
}

impl Outbox {
    /// An empty outbox at time `now`; messages on `unread` topics are not wanted by anyone.
    pub(crate) fn new(now: Time, unread: Vec<&'static str>) -> Self {
        Outbox { now, unread, sent: Vec::new() }
    }

    /// The node's time: the stamp for messages that are not stamped by the input they answer.
    pub fn now(&self) -> Time {
        self.now.clone()
    }

    /// A header in `frame_id` stamped [`Outbox::now`].
    pub fn header(&self, frame_id: &str) -> Header {
        Header::at(frame_id, self.now())
    }

    /// Whether anyone reads `topic`: a core may skip building a costly message nobody wants.
    pub fn wanted<M>(&self, topic: &Topic<M>) -> bool {
        !self.unread.contains(&topic.name)
    }

    /// Writes `message` on `topic`.
    pub fn publish<M: RosMessage>(&mut self, topic: &Topic<M>, message: M) {
        self.sent.push(Sent { topic: topic.name, message: Box::new(message) });
    }

    /// Reports `feedback` on the running goal `goal` of `action`.
    pub fn feedback<G, R: RosMessage, F: RosMessage>(&mut self, action: &Action<G, R, F>, goal: GoalId, feedback: F) {
        let report: ActionReport<R, F> = ActionReport::Feedback(goal, feedback);
        self.sent.push(Sent { topic: action.name, message: Box::new(report) });
    }

    /// Ends the goal `goal` of `action` as `end`, with `result`.
    pub fn finish<G, R: RosMessage, F: RosMessage>(
        &mut self,
        action: &Action<G, R, F>,
        goal: GoalId,
        end: GoalEnd,
        result: R,
    ) {
        let report: ActionReport<R, F> = ActionReport::Finish(goal, end, result);
        self.sent.push(Sent { topic: action.name, message: Box::new(report) });
    }

    /// The messages written so far, in order; the outbox is left empty.
    pub(crate) fn take(&mut self) -> Vec<Sent> {
        std::mem::take(&mut self.sent)
    }

    pub(crate) fn set_now(&mut self, now: Time) {
        self.now = now;
    }
}
