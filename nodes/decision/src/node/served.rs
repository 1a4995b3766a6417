//! The decision node's commands: the mission's action `sample_return`, the goals of
//! `navigate_to_pose` and `goal_pose`, and the mission's services, with their feedback and
//! results.

use rover_msgs::geometry_msgs::PoseStamped;
use rover_msgs::msg::Telemetry;
use rover_msgs::nav2_msgs::{NavigateToPoseGoal, NavigateToPoseResult};
use rover_msgs::sample_return::{SampleReturnGoal, SampleReturnResult};
use rover_msgs::std_srvs::{TriggerRequest, TriggerResponse};
use rover_runtime::commands::{self, GoalEnd, GoalId};
use rover_runtime::node_core::Outbox;
use rover_runtime::topics;

use super::DecisionNode;
use crate::goals;
use crate::machine::{CommandAnswer, Mode, NavigationEnd};

/// A running goal gets feedback every this many frames.
const FEEDBACK_EVERY_FRAMES: u64 = 10;
/// The mission's action gets feedback every this many frames.
const MISSION_FEEDBACK_EVERY_FRAMES: u64 = 25;

/// A goal the machine drives to: from `navigate_to_pose` (its id) or from `goal_pose` (none).
pub(super) struct RunningGoal {
    id: Option<GoalId>,
    point: (f64, f64),
}

/// The answer of a mission command as `std_srvs/Trigger` gives it.
pub(super) fn answer(answer: CommandAnswer) -> TriggerResponse {
    match answer {
        Ok(message) => TriggerResponse { success: true, message: message.to_string() },
        Err(message) => TriggerResponse { success: false, message: message.to_string() },
    }
}

impl DecisionNode {
    /// A goal of `sample_return`: the mission starts (or goes on, from a pause too) and the goal
    /// follows it to its end, in place of an earlier one.
    pub(super) fn on_mission_goal(&mut self, id: GoalId, _goal: &SampleReturnGoal, out: &mut Outbox) {
        if let Some(earlier) = self.mission_goal.replace(id) {
            let preempted = SampleReturnResult::ended_early("preempted by a new goal");
            out.finish(&commands::SAMPLE_RETURN, earlier, GoalEnd::Aborted, preempted);
        }
        let _ = self.machine.start_mission();
        let _ = self.machine.resume_after_pause();
        tracing::info!("sample_return: following the mission");
    }

    /// The client cancels the mission's goal: the mission pauses (the rover brakes and holds).
    pub(super) fn on_mission_cancel(&mut self, id: GoalId, out: &mut Outbox) {
        if self.mission_goal == Some(id) {
            self.mission_goal = None;
            let _ = self.machine.pause();
        }
        let canceled = SampleReturnResult::ended_early("canceled: the mission is paused");
        out.finish(&commands::SAMPLE_RETURN, id, GoalEnd::Canceled, canceled);
    }

    /// Ends the mission's goal with the score once the rover is done, else gives feedback every
    /// second.
    pub(super) fn report_on_mission(&mut self, telemetry: &Telemetry, out: &mut Outbox) {
        let Some(id) = self.mission_goal else { return };
        let status = self.machine.status();
        let time_s =
            self.mission_frames.last().map_or(0, |(_, mission)| mission) as f64 * self.machine.params().frame_period_s;
        if status.mode == Mode::Done {
            self.mission_goal = None;
            let result = goals::mission_result(status, &self.map_stats, telemetry, time_s);
            tracing::info!("sample_return: {}", result.message);
            out.finish(&commands::SAMPLE_RETURN, id, GoalEnd::Succeeded, result);
        } else if telemetry.frame.is_multiple_of(MISSION_FEEDBACK_EVERY_FRAMES) {
            out.feedback(&commands::SAMPLE_RETURN, id, goals::mission_feedback(status, &self.map_stats, time_s));
        }
    }

    /// A new goal of `navigate_to_pose`, in place of the goal that runs.
    pub(super) fn on_navigate_goal(&mut self, id: GoalId, goal: &NavigateToPoseGoal, out: &mut Outbox) {
        self.start_goal(Some(id), &goal.pose, out);
    }

    /// A goal on `goal_pose`, in place of the goal that runs.
    pub(super) fn on_goal_pose(&mut self, pose: &PoseStamped, out: &mut Outbox) {
        self.start_goal(None, pose, out);
    }

    /// The client cancels goal `id`: the rover brakes if it was the running one.
    pub(super) fn on_navigate_cancel(&mut self, id: GoalId, out: &mut Outbox) {
        if self.goal.as_ref().is_some_and(|goal| goal.id == Some(id)) {
            self.goal = None;
            self.machine.cancel_navigation();
            tracing::info!("navigate_to_pose: goal canceled");
        }
        out.finish(&commands::NAVIGATE_TO_POSE, id, GoalEnd::Canceled, NavigateToPoseResult::default());
    }

    /// Ends a running goal, then drives home.
    pub(super) fn on_return_home(&mut self, _request: &TriggerRequest, out: &mut Outbox) -> TriggerResponse {
        let answer = answer(self.machine.return_home_now());
        if answer.success {
            self.end_goal(GoalEnd::Aborted, NavigateToPoseResult::preempted_by("return_home"), out);
        }
        answer
    }

    /// Drives to the goal `pose` (preempting the running goal) for the action goal `id`, or for
    /// `goal_pose` without one; a goal that is refused ends at once, or is logged.
    fn start_goal(&mut self, id: Option<GoalId>, pose: &PoseStamped, out: &mut Outbox) {
        let started = goals::goal_point(pose).and_then(|point| {
            self.machine.navigate_to(point).map(|()| point).map_err(|failure| goals::failure_result(failure, point))
        });
        match started {
            Ok(point) => {
                self.end_goal(GoalEnd::Aborted, NavigateToPoseResult::preempted_by("a new goal"), out);
                tracing::info!("navigating to ({:.2}, {:.2})", point.0, point.1);
                self.goal = Some(RunningGoal { id, point });
            }
            Err(result) => match id {
                Some(id) => {
                    tracing::warn!("navigate_to_pose: refused a goal: {}", result.error_msg);
                    out.finish(&commands::NAVIGATE_TO_POSE, id, GoalEnd::Aborted, result);
                }
                None => self.rejections.reject(topics::GOAL_POSE.name, &result.error_msg),
            },
        }
    }

    /// Ends the running goal, if any, as `end` with `result` (nothing to tell for a `goal_pose`).
    pub(super) fn end_goal(&mut self, end: GoalEnd, result: NavigateToPoseResult, out: &mut Outbox) {
        if let Some(RunningGoal { id: Some(id), .. }) = self.goal.take() {
            out.finish(&commands::NAVIGATE_TO_POSE, id, end, result);
        }
    }

    /// Ends the running goal when the machine's navigation ended, else gives feedback on it now
    /// and then.
    pub(super) fn report_on_goal(&mut self, telemetry: &Telemetry, out: &mut Outbox) {
        let Some(goal) = &self.goal else { return };
        let point = goal.point;
        match self.machine.take_navigation_end() {
            Some(NavigationEnd::Reached) => {
                tracing::info!("navigation: goal ({:.2}, {:.2}) reached", point.0, point.1);
                self.end_goal(GoalEnd::Succeeded, NavigateToPoseResult::default(), out);
            }
            Some(NavigationEnd::Failed(failure)) => {
                let result = goals::failure_result(failure, point);
                tracing::warn!("navigation given up: {}", result.error_msg);
                self.end_goal(GoalEnd::Aborted, result, out);
            }
            None => {
                let Some(id) = goal.id.filter(|_| telemetry.frame.is_multiple_of(FEEDBACK_EVERY_FRAMES)) else {
                    return;
                };
                let Some(progress) = self.machine.navigation_progress() else { return };
                let p = self.machine.params();
                let feedback = goals::feedback(&progress, telemetry, p.frame_period_s, p.approach_speed_mps);
                out.feedback(&commands::NAVIGATE_TO_POSE, id, feedback);
            }
        }
    }
}
