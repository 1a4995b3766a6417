//! Goals given from outside, as Nav2's `navigate_to_pose` and RViz's `goal_pose` give them: the
//! checks a goal pose must pass, the error codes of a goal given up, and the feedback on one that
//! runs; and the feedback and score of the whole mission as the `sample_return` action gives them.

use rover_msgs::builtin_interfaces::Duration;
use rover_msgs::frame_ids;
use rover_msgs::geometry_msgs::{Point, Pose, PoseStamped, Quaternion};
use rover_msgs::msg::{MapStats, Telemetry};
use rover_msgs::nav2_msgs::{NavigateToPoseFeedback, NavigateToPoseResult};
use rover_msgs::sample_return::{SampleReturnFeedback, SampleReturnResult};
use rover_msgs::std_msgs::Header;

use crate::machine::{GoalFailure, Mode, NavigationProgress, Status};

/// The point on the map a goal pose asks for; a pose in another frame than `map`, with a
/// coordinate that is not finite or with an orientation that is no rotation is refused with
/// the result that says why.
pub(crate) fn goal_point(goal: &PoseStamped) -> Result<(f64, f64), NavigateToPoseResult> {
    let frame = goal.header.frame_id.trim_start_matches('/');
    if frame != frame_ids::MAP {
        let why = format!("goal in frame '{}': the rover takes goals in '{}'", goal.header.frame_id, frame_ids::MAP);
        return Err(NavigateToPoseResult::error(NavigateToPoseResult::TF_ERROR, why));
    }
    let Point { x, y, z } = goal.pose.position;
    if ![x, y, z].iter().all(|v| v.is_finite()) {
        let why = format!("goal position ({x}, {y}, {z}) is not finite");
        return Err(NavigateToPoseResult::error(NavigateToPoseResult::UNKNOWN, why));
    }
    let Quaternion { x: qx, y: qy, z: qz, w: qw } = goal.pose.orientation;
    let norm = (qx * qx + qy * qy + qz * qz + qw * qw).sqrt();
    if !norm.is_finite() || norm < 1e-6 {
        let why = format!("goal orientation ({qx}, {qy}, {qz}, {qw}) is no rotation: give a unit quaternion (w: 1.0)");
        return Err(NavigateToPoseResult::error(NavigateToPoseResult::UNKNOWN, why));
    }
    Ok((x, y))
}

/// The result of a goal given up for `failure`.
pub(crate) fn failure_result(failure: GoalFailure, goal: (f64, f64)) -> NavigateToPoseResult {
    let code = match failure {
        GoalFailure::OutsideMap => NavigateToPoseResult::GOAL_OUTSIDE_MAP,
        GoalFailure::Occupied => NavigateToPoseResult::GOAL_OCCUPIED,
        GoalFailure::NoPath => NavigateToPoseResult::NO_VALID_PATH,
        GoalFailure::NoProgress => NavigateToPoseResult::UNKNOWN,
    };
    NavigateToPoseResult::error(code, failure.message(goal))
}

/// The feedback on a navigation at the frame of `telemetry`: the rover's pose in `map`, the time
/// since the goal came and the time left at the rover's speed (at least `least_speed_mps`).
pub(crate) fn feedback(
    progress: &NavigationProgress,
    telemetry: &Telemetry,
    frame_period_s: f64,
    least_speed_mps: f64,
) -> NavigateToPoseFeedback {
    let header = Header { frame_id: frame_ids::MAP.to_string(), ..telemetry.header.clone() };
    let position = Point { x: telemetry.x_m, y: telemetry.y_m, z: 0.0 };
    let pose = Pose { position, orientation: Quaternion::from_yaw(telemetry.yaw_rad as f64) };
    let speed_mps = (telemetry.speed_mps as f64).abs().max(least_speed_mps);
    NavigateToPoseFeedback {
        current_pose: PoseStamped { header, pose },
        navigation_time: Duration::from_secs_f64(progress.frames as f64 * frame_period_s),
        estimated_time_remaining: Duration::from_secs_f64(progress.distance_remaining_m / speed_mps),
        number_of_recoveries: progress.recoveries.min(i16::MAX as u32) as i16,
        distance_remaining: progress.distance_remaining_m as f32,
    }
}

/// How the mission goes: its mode and time, and the mapping node's latest statistics.
pub(crate) fn mission_feedback(status: &Status, stats: &MapStats, mission_time_s: f64) -> SampleReturnFeedback {
    SampleReturnFeedback {
        mode: status.mode.name().to_string(),
        mapped_pct: stats.mapped_pct,
        fidelity_pct: stats.fidelity_pct,
        samples_located: stats.rocks_located,
        samples_collected: status.samples_collected,
        mission_time_s,
    }
}

/// The mission's score at the frame of `telemetry`: complete when the rover is done at home with
/// no sample left on the ground.
pub(crate) fn mission_result(
    status: &Status,
    stats: &MapStats,
    telemetry: &Telemetry,
    mission_time_s: f64,
) -> SampleReturnResult {
    let feedback = mission_feedback(status, stats, mission_time_s);
    let home_distance_m = status.home.map_or(f64::NAN, |(x, y)| (telemetry.x_m - x).hypot(telemetry.y_m - y));
    let complete = status.mode == Mode::Done && telemetry.samples_remaining == 0;
    let message = match (complete, status.mode) {
        (true, _) => "every sample collected and home".to_string(),
        (false, Mode::Done) => format!("home with {} samples left on the ground", telemetry.samples_remaining),
        (false, mode) => format!("ended in mode {}", mode.name()),
    };
    SampleReturnResult {
        complete,
        mapped_pct: feedback.mapped_pct,
        fidelity_pct: feedback.fidelity_pct,
        samples_located: feedback.samples_located,
        samples_collected: feedback.samples_collected,
        samples_remaining: telemetry.samples_remaining,
        home_distance_m: home_distance_m as f32,
        mission_time_s,
        message,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn goal(frame_id: &str, x: f64, y: f64, orientation: Quaternion) -> PoseStamped {
        let pose = Pose { position: Point { x, y, z: 0.0 }, orientation };
        PoseStamped { header: Header { frame_id: frame_id.to_string(), ..Header::default() }, pose }
    }

    #[test]
    fn a_goal_in_map_gives_its_point_and_bad_goals_say_what_is_wrong() {
        assert_eq!(goal_point(&goal("map", 12.5, 80.0, Quaternion::IDENTITY)), Ok((12.5, 80.0)));
        assert_eq!(goal_point(&goal("/map", 1.0, 2.0, Quaternion::from_yaw(1.0))), Ok((1.0, 2.0)));
        let odom = goal_point(&goal("odom", 1.0, 2.0, Quaternion::IDENTITY)).unwrap_err();
        assert_eq!(odom.error_code, NavigateToPoseResult::TF_ERROR);
        assert!(odom.error_msg.contains("'odom'"), "{}", odom.error_msg);
        let nan = goal_point(&goal("map", f64::NAN, 2.0, Quaternion::IDENTITY)).unwrap_err();
        assert!(nan.error_code == NavigateToPoseResult::UNKNOWN && nan.error_msg.contains("not finite"));
        let zero = Quaternion { w: 0.0, ..Quaternion::IDENTITY };
        let no_rotation = goal_point(&goal("map", 1.0, 2.0, zero)).unwrap_err();
        assert!(no_rotation.error_msg.contains("no rotation"), "{}", no_rotation.error_msg);
    }

    #[test]
    fn feedback_counts_time_in_frames_and_estimates_the_rest_at_the_rovers_speed() {
        let progress = NavigationProgress { goal: (0.0, 0.0), distance_remaining_m: 20.0, frames: 50, recoveries: 2 };
        let telemetry = Telemetry { x_m: 3.0, y_m: 4.0, speed_mps: 2.0, ..Telemetry::default() };
        let fed_back = feedback(&progress, &telemetry, 0.04, 0.5);
        assert_eq!(fed_back.navigation_time, Duration { sec: 2, nanosec: 0 });
        assert_eq!(fed_back.estimated_time_remaining, Duration { sec: 10, nanosec: 0 });
        assert_eq!((fed_back.number_of_recoveries, fed_back.distance_remaining), (2, 20.0));
        assert_eq!(fed_back.current_pose.header.frame_id, "map");
        assert_eq!((fed_back.current_pose.pose.position.x, fed_back.current_pose.pose.position.y), (3.0, 4.0));
        let standing = Telemetry { speed_mps: 0.0, ..telemetry };
        assert_eq!(feedback(&progress, &standing, 0.04, 0.5).estimated_time_remaining.sec, 40);
    }

    #[test]
    fn a_mission_is_complete_when_done_with_no_sample_left() {
        let stats = MapStats { mapped_pct: 97.5, fidelity_pct: 96.0, rocks_located: 6, ..MapStats::default() };
        let done = Status {
            mode: Mode::Done,
            reason: "home".to_string(),
            target: None,
            samples_collected: 6,
            home: Some((3.0, 0.0)),
        };
        let at_home = Telemetry { samples_remaining: 0, ..Telemetry::default() };
        let result = mission_result(&done, &stats, &at_home, 512.0);
        assert!(result.complete, "{result:?}");
        assert_eq!((result.samples_collected, result.samples_located, result.home_distance_m), (6, 6, 3.0));
        assert_eq!((result.mapped_pct, result.mission_time_s), (97.5, 512.0));
        let one_left = Telemetry { samples_remaining: 1, ..at_home.clone() };
        assert!(!mission_result(&done, &stats, &one_left, 512.0).complete);
        let exploring = Status { mode: Mode::Explore, ..done };
        let ended = mission_result(&exploring, &stats, &at_home, 100.0);
        assert!(!ended.complete && ended.message.contains("explore"), "{ended:?}");
        assert_eq!(mission_feedback(&exploring, &stats, 100.0).mode, "explore");
    }

    #[test]
    fn a_failure_has_nav2s_code_and_names_the_goal() {
        let result = failure_result(GoalFailure::OutsideMap, (250.0, 3.0));
        assert_eq!(result.error_code, NavigateToPoseResult::GOAL_OUTSIDE_MAP);
        assert!(result.error_msg.contains("250.00"), "{}", result.error_msg);
        assert_eq!(failure_result(GoalFailure::NoPath, (1.0, 1.0)).error_code, NavigateToPoseResult::NO_VALID_PATH);
    }
}
