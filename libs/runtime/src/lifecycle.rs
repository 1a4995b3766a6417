//! Managed nodes: the ROS 2 lifecycle (unconfigured, inactive, active, finalized) with its
//! standard services (`<node>/get_state`, `change_state`, `get_available_states`,
//! `get_available_transitions`, `get_transition_graph`) and `<node>/transition_event` topic, so
//! that `ros2 lifecycle` and Nav2-style managers drive the nodes. The services run in a task of
//! their own; a change of state goes to the node's loop ([`Lifecycle::next_request`]), which
//! makes it and answers.

use std::sync::{Arc, Mutex};

use anyhow::Context as _;
use futures::StreamExt as _;
use ros2_client::service::Server;
use ros2_client::{MessageTypeName, Name, Node};
use rover_msgs::lifecycle_msgs as msgs;
use tokio::sync::{mpsc, oneshot};

use crate::services;
use crate::sync::lock;

/// A primary state of the lifecycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum State {
    /// Created: no subscriptions, no publishers of data.
    Unconfigured,
    /// Configured, publishing nothing that moves the rover.
    Inactive,
    /// Running.
    Active,
    /// Shut down for good.
    Finalized,
}

/// A transition a user can ask for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Transition {
    /// Unconfigured to inactive.
    Configure,
    /// Inactive to unconfigured.
    Cleanup,
    /// Inactive to active.
    Activate,
    /// Active to inactive.
    Deactivate,
    /// Any primary state but finalized to finalized.
    Shutdown,
}

const PRIMARY_STATES: [State; 4] = [State::Unconfigured, State::Inactive, State::Active, State::Finalized];

impl State {
    /// The state's id in `lifecycle_msgs/msg/State`.
    fn id(self) -> u8 {
        match self {
            State::Unconfigured => 1,
            State::Inactive => 2,
            State::Active => 3,
            State::Finalized => 4,
        }
    }

    /// The state's label, as `ros2 lifecycle get` prints it.
    pub fn label(self) -> &'static str {
        match self {
            State::Unconfigured => "unconfigured",
            State::Inactive => "inactive",
            State::Active => "active",
            State::Finalized => "finalized",
        }
    }

    fn message(self) -> msgs::State {
        msgs::State { id: self.id(), label: self.label().to_string() }
    }

    /// The transitions available from this state, each with the state it leads to.
    fn transitions(self) -> &'static [(Transition, State)] {
        match self {
            State::Unconfigured => {
                &[(Transition::Configure, State::Inactive), (Transition::Shutdown, State::Finalized)]
            }
            State::Inactive => &[
                (Transition::Cleanup, State::Unconfigured),
                (Transition::Activate, State::Active),
                (Transition::Shutdown, State::Finalized),
            ],
            State::Active => &[(Transition::Deactivate, State::Inactive), (Transition::Shutdown, State::Finalized)],
            State::Finalized => &[],
        }
    }

    /// The state `transition` leads to from this one, if it is available here.
    pub fn after(self, transition: Transition) -> Option<State> {
        self.transitions().iter().find(|(t, _)| *t == transition).map(|&(_, state)| state)
    }
}

impl Transition {
    const ALL: [Transition; 5] = [
        Transition::Configure,
        Transition::Cleanup,
        Transition::Activate,
        Transition::Deactivate,
        Transition::Shutdown,
    ];

    /// The transition's id from `start` in `lifecycle_msgs/msg/Transition` (shutdown has one per
    /// start state).
    fn id_from(self, start: State) -> u8 {
        match (self, start) {
            (Transition::Configure, _) => 1,
            (Transition::Cleanup, _) => 2,
            (Transition::Activate, _) => 3,
            (Transition::Deactivate, _) => 4,
            (Transition::Shutdown, State::Unconfigured) => 5,
            (Transition::Shutdown, State::Inactive) => 6,
            (Transition::Shutdown, _) => 7,
        }
    }

    /// The transition's label, as `ros2 lifecycle set` takes it.
    pub fn label(self) -> &'static str {
        match self {
            Transition::Configure => "configure",
            Transition::Cleanup => "cleanup",
            Transition::Activate => "activate",
            Transition::Deactivate => "deactivate",
            Transition::Shutdown => "shutdown",
        }
    }

    fn message_from(self, start: State) -> msgs::Transition {
        msgs::Transition { id: self.id_from(start), label: self.label().to_string() }
    }

    /// The intermediate state while the transition runs (`configuring`, ...).
    fn running_state(self) -> msgs::State {
        let (id, label) = match self {
            Transition::Configure => (10, "configuring"),
            Transition::Cleanup => (11, "cleaningup"),
            Transition::Shutdown => (12, "shuttingdown"),
            Transition::Activate => (13, "activating"),
            Transition::Deactivate => (14, "deactivating"),
        };
        msgs::State { id, label: label.to_string() }
    }

    /// The transition that `request` names from `start`: by id, or by label when the id is 0.
    fn requested(request: &msgs::Transition, start: State) -> Option<Transition> {
        let by_id = |t: &&Transition| t.id_from(start) == request.id;
        let by_label = |t: &&Transition| request.id == 0 && t.label() == request.label;
        Transition::ALL.iter().find(|t| by_id(t) || by_label(t)).copied()
    }
}

/// The descriptions of the transitions available from `state`, as `get_available_transitions`
/// gives them: each from the state to its intermediate state.
fn transitions_from(state: State) -> Vec<msgs::TransitionDescription> {
    state
        .transitions()
        .iter()
        .map(|&(transition, _)| msgs::TransitionDescription {
            transition: transition.message_from(state),
            start_state: state.message(),
            goal_state: transition.running_state(),
        })
        .collect()
}

/// A request to change the node's state, for the node's loop to carry out.
#[derive(Debug)]
pub struct ChangeRequest {
    /// The transition asked for (available from the state the node was in).
    pub transition: Transition,
    reply: oneshot::Sender<bool>,
}

/// A node's lifecycle: its state, the requests to change it, and the `transition_event` topic.
pub struct Lifecycle {
    state: Arc<Mutex<State>>,
    requests: mpsc::UnboundedReceiver<ChangeRequest>,
    events: ros2_client::Publisher<msgs::TransitionEvent>,
}

impl Lifecycle {
    /// Serves the lifecycle services of `node`, which starts unconfigured.
    pub(crate) fn serve(node: &Arc<Mutex<Node>>) -> anyhow::Result<Self> {
        let state = Arc::new(Mutex::new(State::Unconfigured));
        let (sender, requests) = mpsc::unbounded_channel();
        let (servers, events) = {
            let node = &mut lock(node);
            let servers = Servers {
                get_state: services::node_server(node, "lifecycle_msgs", "GetState")?,
                change_state: services::node_server(node, "lifecycle_msgs", "ChangeState")?,
                available_states: services::node_server(node, "lifecycle_msgs", "GetAvailableStates")?,
                available_transitions: services::node_server(node, "lifecycle_msgs", "GetAvailableTransitions")?,
                transition_graph: services::node_server(node, "lifecycle_msgs", "GetTransitionGraph")?,
            };
            (servers, event_publisher(node)?)
        };
        let shared = Arc::clone(&state);
        tokio::spawn(async move { serve(&servers, &shared, &sender).await });
        Ok(Lifecycle { state, requests, events })
    }

    /// The node's state.
    pub fn state(&self) -> State {
        *lock(&self.state)
    }

    /// The next request to change state; pending forever once the services have stopped.
    pub async fn next_request(&mut self) -> ChangeRequest {
        match self.requests.recv().await {
            Some(request) => request,
            None => std::future::pending().await,
        }
    }

    /// Records the outcome of `request`'s transition, answers it and publishes the event.
    pub fn finish(&mut self, request: ChangeRequest, succeeded: bool) {
        if succeeded {
            self.record(request.transition);
        }
        let _ = request.reply.send(succeeded);
    }

    /// Moves the node along `transition`, asked by the node itself (autostart), and publishes the
    /// event; a transition not available from the current state is an error.
    pub fn record(&mut self, transition: Transition) {
        let start = self.state();
        let Some(goal) = start.after(transition) else {
            tracing::error!("lifecycle: {} is not available from {}", transition.label(), start.label());
            return;
        };
        *lock(&self.state) = goal;
        tracing::info!("lifecycle: {} -> {}", start.label(), goal.label());
        let event = msgs::TransitionEvent {
            timestamp: unix_nanos(),
            transition: transition.message_from(start),
            start_state: start.message(),
            goal_state: goal.message(),
        };
        if let Err(e) = self.events.publish(event) {
            tracing::warn!("cannot publish the lifecycle transition event: {e}");
        }
    }
}

/// How long a lifecycle client waits for the answer to a transition (configuring may read a
/// snapshot).
const CALL_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(3);
/// How long it waits for a node's state: a request sent before discovery matched the node's
/// server is lost, and the next one should not wait long.
const STATE_TIMEOUT: std::time::Duration = std::time::Duration::from_millis(500);

/// A client of one managed node's `get_state` and `change_state`, for a lifecycle manager.
pub struct LifecycleClient {
    node: String,
    get_state: ros2_client::service::Client<msgs::EmptyRequest, msgs::GetStateResponse>,
    change_state: ros2_client::service::Client<msgs::ChangeStateRequest, msgs::ChangeStateResponse>,
}

impl LifecycleClient {
    /// A client of the managed node `node` (fully qualified, e.g. `/rover1/decision`), created on
    /// `on`.
    pub(crate) fn new(on: &mut Node, node: &str) -> anyhow::Result<Self> {
        Ok(LifecycleClient {
            node: node.to_string(),
            get_state: services::node_client(on, node, "lifecycle_msgs", "GetState")?,
            change_state: services::node_client(on, node, "lifecycle_msgs", "ChangeState")?,
        })
    }

    /// The node's fully qualified name.
    pub fn node(&self) -> &str {
        &self.node
    }

    /// The node's state; none if it does not answer in time (not started, or gone).
    pub async fn state(&self) -> Option<State> {
        let request = msgs::EmptyRequest::default();
        let response = tokio::time::timeout(STATE_TIMEOUT, self.get_state.async_call_service(request)).await;
        let id = response.ok()?.ok()?.current_state.id;
        PRIMARY_STATES.into_iter().find(|state| state.id() == id)
    }

    /// Asks the node, in state `from`, for `transition`; whether it succeeded in time.
    pub async fn change(&self, from: State, transition: Transition) -> bool {
        let request = msgs::ChangeStateRequest { transition: transition.message_from(from) };
        let response = tokio::time::timeout(CALL_TIMEOUT, self.change_state.async_call_service(request)).await;
        matches!(response, Ok(Ok(msgs::ChangeStateResponse { success: true })))
    }
}

/// Nanoseconds since the Unix epoch, the event's timestamp.
fn unix_nanos() -> u64 {
    std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos() as u64)
}

/// The five servers of one node.
struct Servers {
    get_state: Server<msgs::EmptyRequest, msgs::GetStateResponse>,
    change_state: Server<msgs::ChangeStateRequest, msgs::ChangeStateResponse>,
    available_states: Server<msgs::EmptyRequest, msgs::GetAvailableStatesResponse>,
    available_transitions: Server<msgs::EmptyRequest, msgs::GetAvailableTransitionsResponse>,
    transition_graph: Server<msgs::EmptyRequest, msgs::GetAvailableTransitionsResponse>,
}

fn event_publisher(node: &mut Node) -> anyhow::Result<ros2_client::Publisher<msgs::TransitionEvent>> {
    let node_name = node.fully_qualified_name();
    let name = Name::new(&node_name, "transition_event").map_err(|e| anyhow::anyhow!("{node_name}: {e}"))?;
    let type_name = MessageTypeName::new("lifecycle_msgs", "TransitionEvent");
    let topic = node.create_topic(&name, type_name, &crate::qos::reliable(10))?;
    node.create_publisher(&topic, None).with_context(|| format!("cannot create {node_name}/transition_event"))
}

/// Answers the lifecycle requests until every request stream ends.
async fn serve(servers: &Servers, state: &Mutex<State>, changes: &mpsc::UnboundedSender<ChangeRequest>) {
    let mut get_state = servers.get_state.receive_request_stream();
    let mut change_state = servers.change_state.receive_request_stream();
    let mut available_states = servers.available_states.receive_request_stream();
    let mut available_transitions = servers.available_transitions.receive_request_stream();
    let mut transition_graph = servers.transition_graph.receive_request_stream();
    let current = || *lock(state);
    loop {
        tokio::select! {
            Some(request) = get_state.next() => {
                services::answer(&servers.get_state, request, |_| msgs::GetStateResponse { current_state: current().message() }).await;
            }
            Some(request) = change_state.next() => {
                let (id, request) = match request {
                    Ok(request) => request,
                    Err(e) => {
                        crate::rejections::request_problem("malformed_request", &format_args!("dropped a malformed lifecycle request: {e:?}"));
                        continue;
                    }
                };
                let success = change(current(), &request.transition, changes).await;
                if let Err(e) = servers.change_state.async_send_response(id, msgs::ChangeStateResponse { success }).await {
                    crate::rejections::request_problem("unanswered_request", &format_args!("cannot answer a lifecycle request: {e:?}"));
                }
            }
            Some(request) = available_states.next() => {
                let available_states = PRIMARY_STATES.iter().map(|s| s.message()).collect();
                services::answer(&servers.available_states, request, |_| msgs::GetAvailableStatesResponse { available_states }).await;
            }
            Some(request) = available_transitions.next() => {
                let available_transitions = transitions_from(current());
                services::answer(&servers.available_transitions, request, |_| msgs::GetAvailableTransitionsResponse { available_transitions }).await;
            }
            Some(request) = transition_graph.next() => {
                let available_transitions = PRIMARY_STATES.into_iter().flat_map(transitions_from).collect();
                services::answer(&servers.transition_graph, request, |_| msgs::GetAvailableTransitionsResponse { available_transitions }).await;
            }
            else => return,
        }
    }
}

/// Hands a `change_state` request from `start` to the node's loop and waits for the outcome; a
/// transition not available from `start` fails at once.
async fn change(start: State, requested: &msgs::Transition, changes: &mpsc::UnboundedSender<ChangeRequest>) -> bool {
    let Some(transition) = Transition::requested(requested, start).filter(|t| start.after(*t).is_some()) else {
        let problem = format_args!(
            "lifecycle: refused transition {} [{}]: not available from {}",
            requested.label,
            requested.id,
            start.label()
        );
        crate::rejections::request_problem("refused_transition", &problem);
        return false;
    };
    let (reply, outcome) = oneshot::channel();
    changes.send(ChangeRequest { transition, reply }).is_ok() && outcome.await.unwrap_or(false)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_standard_transitions_lead_where_ros_2_says() {
        assert_eq!(State::Unconfigured.after(Transition::Configure), Some(State::Inactive));
        assert_eq!(State::Inactive.after(Transition::Activate), Some(State::Active));
        assert_eq!(State::Active.after(Transition::Deactivate), Some(State::Inactive));
        assert_eq!(State::Inactive.after(Transition::Cleanup), Some(State::Unconfigured));
        assert_eq!(State::Active.after(Transition::Shutdown), Some(State::Finalized));
        assert_eq!(State::Active.after(Transition::Configure), None);
        assert_eq!(State::Finalized.after(Transition::Activate), None);
    }

    #[test]
    fn a_request_names_its_transition_by_id_or_else_by_label() {
        let by =
            |id: u8, label: &str, start| Transition::requested(&msgs::Transition { id, label: label.into() }, start);
        assert_eq!(by(4, "", State::Active), Some(Transition::Deactivate));
        assert_eq!(by(7, "", State::Active), Some(Transition::Shutdown));
        assert_eq!(by(5, "", State::Unconfigured), Some(Transition::Shutdown));
        assert_eq!(by(0, "activate", State::Inactive), Some(Transition::Activate));
        assert_eq!(by(9, "activate", State::Inactive), None, "an unknown id is not read as its label");
    }

    #[test]
    fn available_transitions_go_to_the_intermediate_states() {
        let from_active = transitions_from(State::Active);
        let listed: Vec<(u8, &str, &str)> = from_active
            .iter()
            .map(|d| (d.transition.id, d.transition.label.as_str(), d.goal_state.label.as_str()))
            .collect();
        assert_eq!(listed, [(4, "deactivate", "deactivating"), (7, "shutdown", "shuttingdown")]);
        assert!(from_active.iter().all(|d| d.start_state == State::Active.message()));
        assert!(transitions_from(State::Finalized).is_empty());
    }
}
