//! The DDS servers of the commands of [`crate::commands`]: each runs as a task that turns its
//! requests into calls for the node's loop and carries the core's answers and reports back.

use std::any::Any;
use std::collections::HashMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use anyhow::Context as _;
use futures::channel::mpsc;
use futures::{SinkExt as _, StreamExt as _};
use ros2_client::action::{AsyncActionServer, ExecutingGoalHandle, GoalEndStatus};
use ros2_client::{ActionTypeName, ServiceMapping};
use rover_msgs::RosMessage;

use crate::adapter::AnyPublisher;
use crate::commands::{Action, ActionCall, ActionReport, GoalEnd, GoalId, Service, ServiceCall};
use crate::node_core::Received;
use crate::{RosNode, qos};

/// Calls not yet taken by the node's loop, per command; a client that sends faster waits.
const CALL_BACKLOG: usize = 8;

/// A command being served: its calls for the node's loop, and where the core's reports on them
/// go with how many results are still on their way (actions only).
pub(crate) struct Served {
    pub(crate) calls: futures::stream::BoxStream<'static, Received>,
    pub(crate) reports: Option<(Box<dyn AnyPublisher>, Arc<AtomicUsize>)>,
}

/// Serves `service` on `node`: each request becomes a [`ServiceCall`], answered when the node's
/// loop replies.
pub(crate) fn serve_service<Req, Resp>(node: &RosNode, service: &'static Service<Req, Resp>) -> anyhow::Result<Served>
where
    Req: RosMessage,
    Resp: RosMessage,
{
    let name = node.resolved_name(service.name)?;
    let server = node
        .with_inner(|inner| crate::services::server::<Req, Resp>(inner, &name, service.package, service.type_name))?;
    let (mut calls, received) = mpsc::channel::<Received>(CALL_BACKLOG);
    tokio::spawn(async move {
        loop {
            let (id, request) = match server.async_receive_request().await {
                Ok(request) => request,
                Err(e) => {
                    let problem = format_args!("dropped a malformed request of {}: {e:?}", service.name);
                    crate::rejections::request_problem("malformed_request", &problem);
                    continue;
                }
            };
            let (reply, answer) = tokio::sync::oneshot::channel();
            if calls.send((service.name, Box::new(ServiceCall { request, reply }))).await.is_err() {
                break;
            }
            let Ok(response) = answer.await else { continue };
            if let Err(e) = server.async_send_response(id, response).await {
                crate::rejections::request_problem(
                    "unanswered_request",
                    &format_args!("cannot answer a request of {}: {e:?}", service.name),
                );
            }
        }
    });
    Ok(Served { calls: received.boxed(), reports: None })
}

/// Serves `action` on `node`: every goal is accepted and handed to the core as an
/// [`ActionCall`]; the core's reports become feedback and results.
pub(crate) fn serve_action<G, R, F>(node: &RosNode, action: &'static Action<G, R, F>) -> anyhow::Result<Served>
where
    G: RosMessage,
    R: RosMessage,
    F: RosMessage,
{
    let name = node.resolved_name(action.name)?;
    let type_name = ActionTypeName::new(action.package, action.type_name);
    let policies = ros2_client::action::ActionServerQosPolicies {
        goal_service: qos::services(),
        result_service: qos::services(),
        cancel_service: qos::services(),
        feedback_publisher: qos::reliable(10),
        status_publisher: qos::latched(),
    };
    let server = node
        .with_inner(|inner| {
            inner.create_action_server::<G, R, F>(ServiceMapping::Enhanced, &name, &type_name, policies)
        })
        .with_context(|| format!("cannot serve the action {}", action.name))?;
    let (calls, received) = mpsc::channel::<Received>(CALL_BACKLOG);
    let (reports, report_queue) = tokio::sync::mpsc::unbounded_channel::<ActionReport<R, F>>();
    let unsent = Arc::new(AtomicUsize::new(0));
    let server = Arc::new(AsyncActionServer::new(server));
    let goals = GoalServer { server, name: action.name, executing: HashMap::new(), unsent: Arc::clone(&unsent) };
    tokio::spawn(goals.run(calls, report_queue));
    let sender = ReportSender { reports, unsent: Arc::clone(&unsent) };
    Ok(Served { calls: received.boxed(), reports: Some((Box::new(sender), unsent)) })
}

/// Forwards a core's reports on an action's goals to the action's task, counting the results.
struct ReportSender<R, F> {
    reports: tokio::sync::mpsc::UnboundedSender<ActionReport<R, F>>,
    unsent: Arc<AtomicUsize>,
}

impl<R: RosMessage, F: RosMessage> AnyPublisher for ReportSender<R, F> {
    fn publish(&self, message: Box<dyn Any + Send>) {
        let report = message.downcast::<ActionReport<R, F>>().expect("a report of the action's types");
        if matches!(*report, ActionReport::Finish(..)) {
            self.unsent.fetch_add(1, Ordering::SeqCst);
        }
        let _ = self.reports.send(*report);
    }
}

/// An action's server and the goals it runs.
struct GoalServer<G, R, F>
where
    G: RosMessage,
    R: RosMessage,
    F: RosMessage,
{
    server: Arc<AsyncActionServer<G, R, F>>,
    name: &'static str,
    executing: HashMap<GoalId, ExecutingGoalHandle<G>>,
    /// Results reported by the core and not sent yet.
    unsent: Arc<AtomicUsize>,
}

impl<G: RosMessage, R: RosMessage, F: RosMessage> GoalServer<G, R, F> {
    /// Accepts goals and cancel requests for the node's loop, and sends the core's reports,
    /// until the node's loop is gone.
    async fn run(
        mut self,
        mut calls: mpsc::Sender<Received>,
        mut reports: tokio::sync::mpsc::UnboundedReceiver<ActionReport<R, F>>,
    ) {
        let server = Arc::clone(&self.server);
        loop {
            let new_calls: Vec<ActionCall<G>> = tokio::select! {
                goal = server.receive_new_goal() => match goal {
                    Ok(handle) => self.start(handle).await.into_iter().collect(),
                    Err(e) => {
                        crate::rejections::request_problem("malformed_goal", &format_args!("dropped a malformed goal of {}: {e:?}", self.name));
                        Vec::new()
                    }
                },
                cancel = server.receive_cancel_request() => match cancel {
                    Ok(handle) => {
                        let goals: Vec<_> = handle.goals().collect();
                        if let Err(e) = server.respond_to_cancel_requests(&handle, goals.iter().copied()).await {
                            let problem = format_args!("cannot answer a cancel request of {}: {e:?}", self.name);
                            crate::rejections::request_problem("unanswered_cancel", &problem);
                        }
                        goals.iter().map(|goal| ActionCall::Cancel(GoalId(goal.uuid.as_u128()))).collect()
                    }
                    Err(e) => {
                        let problem = format_args!("dropped a malformed cancel request of {}: {e:?}", self.name);
                        crate::rejections::request_problem("malformed_cancel", &problem);
                        Vec::new()
                    }
                },
                Some(report) = reports.recv() => {
                    self.report(report).await;
                    Vec::new()
                }
            };
            for call in new_calls {
                if calls.send((self.name, Box::new(call))).await.is_err() {
                    return;
                }
            }
        }
    }

    /// Accepts and starts the new goal of `handle`: the call for the core.
    async fn start(&mut self, handle: ros2_client::action::NewGoalHandle<G>) -> Option<ActionCall<G>> {
        let goal = self.server.get_new_goal(handle.clone())?;
        let accepted = self.server.accept_goal(handle).await.ok()?;
        let executing = self.server.start_executing_goal(accepted).await.ok()?;
        let id = GoalId(executing.goal_id().uuid.as_u128());
        self.executing.insert(id, executing);
        Some(ActionCall::Goal(id, goal))
    }

    /// Publishes a feedback, or sends a goal's result once its client asks for it.
    async fn report(&mut self, report: ActionReport<R, F>) {
        match report {
            ActionReport::Feedback(id, feedback) => {
                if let Some(handle) = self.executing.get(&id).cloned()
                    && let Err(e) = self.server.publish_feedback(handle, feedback).await
                {
                    tracing::debug!("cannot publish feedback of {}: {}", self.name, goal_error(&e));
                }
            }
            ActionReport::Finish(id, end, result) => {
                let Some(handle) = self.executing.remove(&id) else {
                    self.unsent.fetch_sub(1, Ordering::SeqCst);
                    return;
                };
                let (server, name, unsent) = (Arc::clone(&self.server), self.name, Arc::clone(&self.unsent));
                tokio::spawn(async move {
                    if let Err(e) = server.send_result_response(handle, end_status(end), result).await {
                        crate::rejections::request_problem(
                            "unsent_result",
                            &format_args!("cannot send the result of a goal of {name}: {e:?}"),
                        );
                    }
                    unsent.fetch_sub(1, Ordering::SeqCst);
                });
            }
        }
    }
}

fn end_status(end: GoalEnd) -> GoalEndStatus {
    match end {
        GoalEnd::Succeeded => GoalEndStatus::Succeeded,
        GoalEnd::Aborted => GoalEndStatus::Aborted,
        GoalEnd::Canceled => GoalEndStatus::Canceled,
    }
}

/// What went wrong with a goal, for the log.
fn goal_error<T>(error: &ros2_client::action::GoalError<T>) -> &'static str {
    use ros2_client::action::GoalError;
    match error {
        GoalError::NoSuchGoal => "no such goal",
        GoalError::WrongGoalState => "the goal is not running",
        GoalError::DDSReadError(_) => "DDS read error",
        GoalError::DDSWriteError(_) => "DDS write error",
    }
}
