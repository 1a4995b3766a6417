//! The DDS side of every node of the graph, written once: [`run_node`] runs a [`NodeCore`] as a
//! managed node. Configured, it is subscribed to the topics it reads and has publishers for the
//! topics the graph table says it writes; active, it gets each message, parameter change and
//! timer; inactive, only the messages it answers while inactive; it stops on shutdown.

use std::any::Any;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use futures::StreamExt as _;
use rover_msgs::RosMessage;
use tracing::Instrument as _;

use crate::commands::Commands;
use crate::graph::node_topics;
use crate::lifecycle::{State, Transition};
use crate::node_core::{FromParams, Inputs, NodeCore, Outbox, Received, Sent, Work};
use crate::topics::{Topic, TopicVisitor, visit_all};
use crate::{Params, Publisher, RosNode, Runtime};

/// Once asked to stop, a draining node still handles the messages already sent to it until none
/// has come for this long.
const DRAIN_QUIET: Duration = Duration::from_millis(100);
/// Once asked to stop, a draining node handles messages for at most this long.
const DRAIN_LIMIT: Duration = Duration::from_secs(1);
/// A stopping node waits at most this long for the results of its goals to go out (each waits
/// for its client to ask for it).
const RESULTS_LIMIT: Duration = Duration::from_secs(1);

/// Runs the node whose core is `C` until shutdown: a managed node, configured and activated at
/// start unless its `autostart` parameter is false, whose state `ros2 lifecycle` can change.
pub async fn run_node<C: FromParams>(runtime: &Runtime) -> anyhow::Result<()> {
    run_node_with::<C>(runtime, Box::new(|_, params| C::new(params)), futures::stream::pending()).await
}

/// Builds the core of a node from the node and its parameters, at each configure.
pub type Build<C> = Box<dyn Fn(&RosNode, <C as NodeCore>::Params) -> anyhow::Result<C> + Send>;

/// [`run_node`] for a core that `build` makes, which also gets the `work` that comes from
/// outside the graph (in any state it is configured in; dropped while it is not).
pub async fn run_node_with<C: NodeCore>(
    runtime: &Runtime,
    build: Build<C>,
    work: impl futures::Stream<Item = Work<C>>,
) -> anyhow::Result<()> {
    let (mut node, params) = runtime.node::<C::Params>(C::NAME)?;
    let span = node.span();
    let (inputs, inactive_inputs) = (C::inputs(), C::inactive_inputs());
    check_inputs_are_the_tables::<C>(&inputs.ports.names())?;
    let mut lifecycle = node.lifecycle()?;
    let commands = C::commands();
    check_commands_are_the_tables::<C>(&commands.ports.names())?;
    let (mut calls, reports, unsent) = serve_commands(&node, &commands)?;
    let mut managed = Managed::<C> { build, configured: None, out: Outbox::new(node.now(), Vec::new()), reports };
    let mut work = std::pin::pin!(work);
    let mut changes = params.watch();
    let shutdown = runtime.shutdown();
    if C::BUILT_AT_START {
        managed.configured = Some(configure(&mut node, &inputs, &params, &managed.build)?);
    }
    async {
        let autostart = if node.autostarts() { &[Transition::Configure, Transition::Activate][..] } else { &[] };
        for &transition in autostart {
            if managed.change(transition, &mut node, &inputs, &params) {
                lifecycle.record(transition);
            }
        }
        loop {
            let timer = managed.timer_due(lifecycle.state());
            tokio::select! {
                () = shutdown.wait() => break,
                request = lifecycle.next_request() => {
                    let succeeded = managed.change(request.transition, &mut node, &inputs, &params);
                    lifecycle.finish(request, succeeded);
                }
                Some((name, call)) = calls.next() => managed.command(&commands, name, call, lifecycle.state(), &node),
                Some((topic, message)) = managed.next_message() => {
                    let handlers = if lifecycle.state() == State::Active { &inputs } else { &inactive_inputs };
                    managed.deliver(handlers, topic, &*message, &node);
                }
                () = sleep_until(timer), if timer.is_some() => managed.with_core(&node, |core, out| core.on_timer(out)),
                Some(job) = work.next() => managed.with_core(&node, job),
                Ok(()) = changes.changed() => managed.set_params(changes.borrow_and_update().clone()),
            }
        }
        if lifecycle.state() == State::Active && C::DRAINS_ON_STOP {
            managed.drain(&inputs, &node).await;
        }
        if lifecycle.state() != State::Finalized {
            managed.change(Transition::Shutdown, &mut node, &inputs, &params);
        }
        results_sent(&unsent).await;
    }
    .instrument(span)
    .await;
    Ok(())
}

/// What a configured node has: its core, its subscriptions and its publishers.
struct Configured<C> {
    core: C,
    messages: futures::stream::SelectAll<futures::stream::BoxStream<'static, Received>>,
    publishers: Publishers,
    started: bool,
}

/// A managed node's core and its connections, as its lifecycle state has them.
struct Managed<C: NodeCore> {
    build: Build<C>,
    /// Present from configure to cleanup or shutdown.
    configured: Option<Configured<C>>,
    out: Outbox,
    /// Where the core's reports on its actions' goals go, in every state.
    reports: Publishers,
}

impl<C: NodeCore> Managed<C> {
    /// Carries out `transition`; whether it succeeded. Configure builds the core, subscribes
    /// and creates the publishers; activate starts the core the first time; cleanup and
    /// shutdown stop the core and drop them all (a core [`NodeCore::BUILT_AT_START`] is only
    /// deactivated at cleanup).
    fn change(
        &mut self,
        transition: Transition,
        node: &mut RosNode,
        inputs: &Inputs<C>,
        params: &Params<C::Params>,
    ) -> bool {
        match transition {
            Transition::Configure if C::BUILT_AT_START => true,
            Transition::Configure => match configure(node, inputs, params, &self.build) {
                Ok(configured) => {
                    self.configured = Some(configured);
                    true
                }
                Err(e) => {
                    tracing::error!("cannot configure: {e:#}");
                    false
                }
            },
            Transition::Activate => {
                if let Some(configured) = self.configured.as_mut().filter(|c| !c.started) {
                    configured.started = true;
                    self.with_core(node, |core, out| core.start(out));
                }
                self.with_core(node, |core, _| core.set_active(true));
                true
            }
            Transition::Deactivate => {
                self.with_core(node, |core, _| core.set_active(false));
                true
            }
            Transition::Cleanup if C::BUILT_AT_START => {
                self.with_core(node, |core, _| core.set_active(false));
                true
            }
            Transition::Cleanup | Transition::Shutdown => {
                self.with_core(node, |core, out| {
                    core.set_active(false);
                    core.stop(out);
                });
                self.configured = None;
                true
            }
        }
    }

    /// The next message of a configured node's subscriptions; pending while unconfigured.
    async fn next_message(&mut self) -> Option<Received> {
        match self.configured.as_mut() {
            Some(configured) => configured.messages.next().await,
            None => std::future::pending().await,
        }
    }

    /// Hands `message` of `topic` to the core's handler in `handlers`, if it has one, and sends
    /// what the core writes.
    fn deliver(&mut self, handlers: &Inputs<C>, topic: &str, message: &dyn Any, node: &RosNode) {
        if let Some(port) = handlers.ports.find(topic) {
            self.with_core(node, |core, out| port.deliver(core, message, out));
        }
    }

    /// Hands `call` of the command `name` to the active core, or refuses it for the core in any
    /// other state.
    fn command(&mut self, commands: &Commands<C>, name: &str, call: Box<dyn Any + Send>, state: State, node: &RosNode) {
        let Some(port) = commands.ports.find(name) else { return };
        if state == State::Active && self.configured.is_some() {
            self.with_core(node, |core, out| port.deliver(core, call, out));
            return;
        }
        let who = node.identity().fully_qualified();
        let why =
            format!("{who} is {}: it takes commands once active (ros2 lifecycle set {who} activate)", state.label());
        crate::rejections::request_problem("refused_call", &format_args!("refused a call of {name}: {why}"));
        port.refuse(call, &why, &mut self.out);
        let refusals = self.out.take();
        self.reports.send(refusals, None);
    }

    /// Runs `act` on the configured core at the node's time and sends what the core writes;
    /// nothing while unconfigured.
    fn with_core(&mut self, node: &RosNode, act: impl FnOnce(&mut C, &mut Outbox)) {
        if let Some(configured) = self.configured.as_mut() {
            self.out.set_now(node.now());
            act(&mut configured.core, &mut self.out);
            self.reports.send(self.out.take(), Some(&configured.publishers));
        }
    }

    /// When the core wants its timer: an active core, or one built at start in any state.
    fn timer_due(&self, state: State) -> Option<Instant> {
        let runs = state == State::Active || C::BUILT_AT_START;
        self.configured.as_ref().filter(|_| runs).and_then(|c| c.core.timer_due())
    }

    fn set_params(&mut self, params: C::Params) {
        if let Some(configured) = self.configured.as_mut() {
            configured.core.set_params(params);
        }
    }

    /// Handles the messages still arriving after shutdown (see [`DRAIN_QUIET`] and [`DRAIN_LIMIT`]).
    async fn drain(&mut self, inputs: &Inputs<C>, node: &RosNode) {
        let stopped_at = Instant::now();
        let mut quiet_until = stopped_at + DRAIN_QUIET;
        loop {
            tokio::select! {
                Some((topic, message)) = self.next_message() => {
                    self.deliver(inputs, topic, &*message, node);
                    quiet_until = Instant::now() + DRAIN_QUIET;
                }
                () = tokio::time::sleep_until(quiet_until.min(stopped_at + DRAIN_LIMIT).into()) => break,
            }
        }
    }
}

/// The core built by `build` from the node's current parameters, subscribed to its inputs, with a
/// publisher for each topic the graph table says the node writes.
fn configure<C: NodeCore>(
    node: &mut RosNode,
    inputs: &Inputs<C>,
    params: &Params<C::Params>,
    build: &Build<C>,
) -> anyhow::Result<Configured<C>> {
    let publishers = Publishers::of(node, C::NAME)?;
    let streams = inputs.ports.iter().map(|port| port.subscribe(node)).collect::<anyhow::Result<Vec<_>>>()?;
    let core = build(node, params.get())?;
    Ok(Configured { core, messages: futures::stream::select_all(streams), publishers, started: false })
}

async fn sleep_until(timer: Option<Instant>) {
    if let Some(at) = timer {
        tokio::time::sleep_until(at.into()).await;
    }
}

/// The calls of a node's commands, one stream.
type Calls = futures::stream::SelectAll<futures::stream::BoxStream<'static, Received>>;

/// Serves every command of `commands` on `node`: their calls, where the reports on their goals
/// go, and the counts of results not sent yet.
fn serve_commands<C: NodeCore>(
    node: &RosNode,
    commands: &Commands<C>,
) -> anyhow::Result<(Calls, Publishers, Vec<Arc<AtomicUsize>>)> {
    let mut reports = Publishers { by_topic: Vec::new() };
    let (mut calls, mut unsent) = (Vec::new(), Vec::new());
    for port in commands.ports.iter() {
        let served = port.serve(node)?;
        calls.push(served.calls);
        if let Some((sink, count)) = served.reports {
            reports.by_topic.push((port.name(), sink));
            unsent.push(count);
        }
    }
    Ok((futures::stream::select_all(calls), reports, unsent))
}

/// Waits, up to [`RESULTS_LIMIT`], until every result reported is sent: a goal that a stopping
/// core ended reaches its client before the process exits.
async fn results_sent(unsent: &[Arc<AtomicUsize>]) {
    let stopped_at = Instant::now();
    while unsent.iter().any(|count| count.load(Ordering::SeqCst) > 0) && stopped_at.elapsed() < RESULTS_LIMIT {
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
}

/// Refuses a core whose commands are not the graph table's serves of its node.
fn check_commands_are_the_tables<C: NodeCore>(commands: &[&'static str]) -> anyhow::Result<()> {
    let listed = node_topics(C::NAME).map_or(&[][..], |entry| entry.serves);
    check_same_names(C::NAME, ("serves", "serves"), listed, commands)
}

/// Refuses a core whose inputs are not the graph table's reads of its node.
pub(crate) fn check_inputs_are_the_tables<C: NodeCore>(inputs: &[&'static str]) -> anyhow::Result<()> {
    let entry = node_topics(C::NAME)
        .ok_or_else(|| anyhow::anyhow!("node {} is not in the graph table (libs/runtime/src/graph.rs)", C::NAME))?;
    check_same_names(C::NAME, ("handles", "reads"), entry.reads, inputs)
}

/// Refuses `handled`, what node `node`'s core does (`verbs.0`), unless it is the table's `listed`
/// (`verbs.1`), in any order.
fn check_same_names(
    node: &str,
    verbs: (&str, &str),
    listed: &[&'static str],
    handled: &[&'static str],
) -> anyhow::Result<()> {
    let (mut listed, mut handled) = (listed.to_vec(), handled.to_vec());
    listed.sort_unstable();
    handled.sort_unstable();
    anyhow::ensure!(
        listed == handled,
        "node {node} {} {handled:?} but the graph table (libs/runtime/src/graph.rs) says it {} {listed:?}",
        verbs.0,
        verbs.1
    );
    Ok(())
}

/// A publisher whose message type is known only to itself.
pub(crate) trait AnyPublisher {
    fn publish(&self, message: Box<dyn Any + Send>);
}

struct TypedPublisher<M: RosMessage> {
    publisher: Publisher<M>,
    topic: &'static str,
}

impl<M: RosMessage> AnyPublisher for TypedPublisher<M> {
    fn publish(&self, message: Box<dyn Any + Send>) {
        let message = message.downcast::<M>().expect("a message of the topic's type: the topic table types both");
        if let Err(e) = self.publisher.publish(*message) {
            tracing::warn!("cannot publish on {}: {e}", self.topic);
        }
    }
}

/// The publishers of every topic a node writes, by topic name.
struct Publishers {
    by_topic: Vec<(&'static str, Box<dyn AnyPublisher>)>,
}

impl Publishers {
    /// Publishers for the topics the graph table says node `name` writes.
    fn of(node: &mut RosNode, name: &str) -> anyhow::Result<Self> {
        let writes = node_topics(name).map_or(&[][..], |entry| entry.writes);
        let mut visitor = Creator { node, writes, by_topic: Vec::new() };
        visit_all(&mut visitor)?;
        Ok(Publishers { by_topic: visitor.by_topic })
    }

    /// Sends each message with its publisher here, else with its publisher in `others`.
    fn send(&self, messages: Vec<Sent>, others: Option<&Publishers>) {
        for sent in messages {
            let publisher = self.find(sent.topic).or_else(|| others.and_then(|others| others.find(sent.topic)));
            match publisher {
                Some(publisher) => publisher.publish(sent.into_message()),
                None => tracing::error!(
                    "dropped a message on {}: the graph table does not let this node write it",
                    sent.topic
                ),
            }
        }
    }
}

impl Publishers {
    fn find(&self, topic: &str) -> Option<&dyn AnyPublisher> {
        self.by_topic.iter().find(|(name, _)| *name == topic).map(|(_, publisher)| &**publisher)
    }
}

struct Creator<'a> {
    node: &'a mut RosNode,
    writes: &'static [&'static str],
    by_topic: Vec<(&'static str, Box<dyn AnyPublisher>)>,
}

impl TopicVisitor for Creator<'_> {
    fn visit<M: RosMessage>(&mut self, topic: &Topic<M>) -> anyhow::Result<()> {
        if self.writes.contains(&topic.name) {
            let publisher = self.node.publisher(topic)?;
            self.by_topic.push((topic.name, Box::new(TypedPublisher { publisher, topic: topic.name })));
        }
        Ok(())
    }
}
