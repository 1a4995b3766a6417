//! The commands nodes serve besides their topics, declared once like the topics: services (a
//! request and its answer) and actions (a goal, feedback while it runs, and its result). A core
//! handles them like its input messages ([`Commands`]); the DDS adapter serves them
//! ([`crate::run_node`]) and answers for a core that is not active.

use std::any::Any;
use std::marker::PhantomData;

use rover_msgs::RosMessage;
use rover_msgs::nav2_msgs::{NavigateToPoseFeedback, NavigateToPoseGoal, NavigateToPoseResult};
use rover_msgs::sample_return::{SampleReturnFeedback, SampleReturnGoal, SampleReturnResult};
use rover_msgs::std_srvs::{TriggerRequest, TriggerResponse};

use crate::node_core::Outbox;
use crate::ports::{Named, Ports};

/// A service: its name (relative, or `~/` for one under the node's name) and its type.
pub struct Service<Req, Resp> {
    /// The name as the node uses it, before namespacing and remapping.
    pub name: &'static str,
    /// The package of the type, e.g. `std_srvs`.
    pub package: &'static str,
    /// The type's name in its package, e.g. `Trigger`.
    pub type_name: &'static str,
    types: PhantomData<fn(Req) -> Resp>,
}

impl Service<TriggerRequest, TriggerResponse> {
    /// A `std_srvs/srv/Trigger` service named `name`.
    const fn trigger(name: &'static str) -> Self {
        Service { name, package: "std_srvs", type_name: "Trigger", types: PhantomData }
    }
}

/// An action: its name and its type; `G` is the goal, `R` the result and `F` the feedback.
pub struct Action<G, R, F> {
    /// The name as the node uses it, before namespacing and remapping.
    pub name: &'static str,
    /// The package of the type, e.g. `nav2_msgs`.
    pub package: &'static str,
    /// The type's name in its package, e.g. `NavigateToPose`.
    pub type_name: &'static str,
    types: PhantomData<fn(G) -> (R, F)>,
}

/// Starts the sample-return mission (when the `start_mission` parameter held it back).
pub static START_MISSION: Service<TriggerRequest, TriggerResponse> = Service::trigger("~/start_mission");
/// Brakes and holds the mission where it is.
pub static PAUSE_MISSION: Service<TriggerRequest, TriggerResponse> = Service::trigger("~/pause_mission");
/// Carries a paused mission on from where it was.
pub static RESUME_MISSION: Service<TriggerRequest, TriggerResponse> = Service::trigger("~/resume_mission");
/// Ends exploring and drives home now.
pub static RETURN_HOME: Service<TriggerRequest, TriggerResponse> = Service::trigger("~/return_home");
/// Drives to a pose in `map`, Nav2's interface.
pub static NAVIGATE_TO_POSE: Action<NavigateToPoseGoal, NavigateToPoseResult, NavigateToPoseFeedback> =
    Action { name: "navigate_to_pose", package: "nav2_msgs", type_name: "NavigateToPose", types: PhantomData };

/// The whole sample-return mission: started by the goal, its score the result.
pub static SAMPLE_RETURN: Action<SampleReturnGoal, SampleReturnResult, SampleReturnFeedback> =
    Action { name: "sample_return", package: "rover_msgs", type_name: "SampleReturn", types: PhantomData };

/// The name of every command of this table.
pub fn all_names() -> [&'static str; 6] {
    [
        START_MISSION.name,
        PAUSE_MISSION.name,
        RESUME_MISSION.name,
        RETURN_HOME.name,
        NAVIGATE_TO_POSE.name,
        SAMPLE_RETURN.name,
    ]
}

/// The answer the adapter gives for a core that cannot take a command (it is not active).
pub trait Refusal {
    /// The answer that refuses a command for the reason `why`.
    fn refused(why: &str) -> Self;
}

impl Refusal for TriggerResponse {
    fn refused(why: &str) -> Self {
        TriggerResponse { success: false, message: why.to_string() }
    }
}

impl Refusal for SampleReturnResult {
    fn refused(why: &str) -> Self {
        SampleReturnResult::ended_early(why)
    }
}

impl Refusal for NavigateToPoseResult {
    fn refused(why: &str) -> Self {
        NavigateToPoseResult::error(NavigateToPoseResult::UNKNOWN, why)
    }
}

/// The id of an action's goal, as its client chose it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct GoalId(pub u128);

/// How a goal ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GoalEnd {
    /// Reached.
    Succeeded,
    /// Given up by the node (its result says why).
    Aborted,
    /// Given up at the client's request.
    Canceled,
}

/// What a core reports on one of its goals, through its [`Outbox`].
#[derive(Debug, Clone, PartialEq)]
pub enum ActionReport<R, F> {
    /// Feedback on a running goal.
    Feedback(GoalId, F),
    /// The end of a goal, with its result.
    Finish(GoalId, GoalEnd, R),
}

/// A call of an action by a client, for the core.
pub(crate) enum ActionCall<G> {
    /// A new goal, accepted and running.
    Goal(GoalId, G),
    /// The client asks to cancel a running goal.
    Cancel(GoalId),
}

/// A call of a service, for the core: the request and where its answer goes.
pub(crate) struct ServiceCall<Req, Resp> {
    pub(crate) request: Req,
    pub(crate) reply: tokio::sync::oneshot::Sender<Resp>,
}

type ServiceHandler<C, Req, Resp> = fn(&mut C, &Req, &mut Outbox) -> Resp;
type GoalHandler<C, G> = fn(&mut C, GoalId, &G, &mut Outbox);
type CancelHandler<C> = fn(&mut C, GoalId, &mut Outbox);

/// The type-erased handler of one command of core `C`.
pub(crate) trait CommandPort<C>: Named {
    /// Serves the command on `node`: its calls, and where the core's reports on them go.
    fn serve(&self, node: &crate::RosNode) -> anyhow::Result<crate::command_servers::Served>;
    /// Hands `call`, a call of this command, to the core.
    fn deliver(&self, core: &mut C, call: Box<dyn Any + Send>, out: &mut Outbox);
    /// Answers `call` for a core that cannot take it, for the reason `why`.
    fn refuse(&self, call: Box<dyn Any + Send>, why: &str, out: &mut Outbox);
}

struct ServicePort<C, Req: 'static, Resp: 'static> {
    service: &'static Service<Req, Resp>,
    handler: ServiceHandler<C, Req, Resp>,
}

impl<C, Req, Resp> Named for ServicePort<C, Req, Resp> {
    fn name(&self) -> &'static str {
        self.service.name
    }
}

impl<C, Req, Resp> CommandPort<C> for ServicePort<C, Req, Resp>
where
    Req: RosMessage,
    Resp: RosMessage + Refusal,
{
    fn serve(&self, node: &crate::RosNode) -> anyhow::Result<crate::command_servers::Served> {
        crate::command_servers::serve_service(node, self.service)
    }

    fn deliver(&self, core: &mut C, call: Box<dyn Any + Send>, out: &mut Outbox) {
        let call = downcast::<ServiceCall<Req, Resp>>(call);
        let _ = call.reply.send((self.handler)(core, &call.request, out));
    }

    fn refuse(&self, call: Box<dyn Any + Send>, why: &str, _out: &mut Outbox) {
        let _ = downcast::<ServiceCall<Req, Resp>>(call).reply.send(Resp::refused(why));
    }
}

struct ActionPort<C, G: 'static, R: 'static, F: 'static> {
    action: &'static Action<G, R, F>,
    on_goal: GoalHandler<C, G>,
    on_cancel: CancelHandler<C>,
}

impl<C, G, R, F> Named for ActionPort<C, G, R, F> {
    fn name(&self) -> &'static str {
        self.action.name
    }
}

impl<C, G, R, F> CommandPort<C> for ActionPort<C, G, R, F>
where
    G: RosMessage,
    R: RosMessage + Refusal,
    F: RosMessage,
{
    fn serve(&self, node: &crate::RosNode) -> anyhow::Result<crate::command_servers::Served> {
        crate::command_servers::serve_action(node, self.action)
    }

    fn deliver(&self, core: &mut C, call: Box<dyn Any + Send>, out: &mut Outbox) {
        match *downcast::<ActionCall<G>>(call) {
            ActionCall::Goal(id, goal) => (self.on_goal)(core, id, &goal, out),
            ActionCall::Cancel(id) => (self.on_cancel)(core, id, out),
        }
    }

    fn refuse(&self, call: Box<dyn Any + Send>, why: &str, out: &mut Outbox) {
        let (id, end) = match *downcast::<ActionCall<G>>(call) {
            ActionCall::Goal(id, _) => (id, GoalEnd::Aborted),
            ActionCall::Cancel(id) => (id, GoalEnd::Canceled),
        };
        out.finish(self.action, id, end, R::refused(why));
    }
}

fn downcast<T: 'static>(call: Box<dyn Any + Send>) -> Box<T> {
    call.downcast().unwrap_or_else(|_| panic!("a call of the command's type: the command table types both"))
}

/// The commands a core serves, each with its handlers.
pub struct Commands<C> {
    pub(crate) ports: Ports<dyn CommandPort<C>>,
}

impl<C: 'static> Commands<C> {
    /// No command yet.
    pub fn new() -> Self {
        Commands { ports: Ports::default() }
    }

    /// Adds `service`, whose requests `handler` answers.
    pub fn service<Req, Resp>(
        mut self,
        service: &'static Service<Req, Resp>,
        handler: ServiceHandler<C, Req, Resp>,
    ) -> Self
    where
        Req: RosMessage,
        Resp: RosMessage + Refusal,
    {
        self.ports.push(Box::new(ServicePort { service, handler }));
        self
    }

    /// Adds `action`: `on_goal` takes each new goal (a new goal may preempt a running one),
    /// `on_cancel` a client's request to cancel one. The core reports on its goals with
    /// [`Outbox::feedback`] and ends each with [`Outbox::finish`].
    pub fn action<G, R, F>(
        mut self,
        action: &'static Action<G, R, F>,
        on_goal: GoalHandler<C, G>,
        on_cancel: CancelHandler<C>,
    ) -> Self
    where
        G: RosMessage,
        R: RosMessage + Refusal,
        F: RosMessage,
    {
        self.ports.push(Box::new(ActionPort { action, on_goal, on_cancel }));
        self
    }
}

impl<C: 'static> Default for Commands<C> {
    fn default() -> Self {
        Self::new()
    }
}
