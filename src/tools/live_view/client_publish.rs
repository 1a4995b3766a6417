//! What a Foxglove user sends the rover from the live view: a goal pose ("2D goal pose" of the
//! 3D panel, or a Publish panel) on `goal_pose` and teleoperation on `cmd_vel` (the Teleop panel).
//! A client advertises a channel on one of those topics, in CDR or JSON, and its messages are
//! published on the graph; anything else is refused with a rate-limited log line.

use std::sync::Mutex;

use foxglove::websocket::{Client, ClientChannel, ServerListener};
use rover_msgs::RosMessage;
use rover_msgs::geometry_msgs::{Point, Pose, PoseStamped, Quaternion, Twist, Vector3};
use rover_msgs::std_msgs::Header;
use rover_runtime::sync::lock;
use rover_runtime::topics::{self, Topic};
use rover_runtime::{Publisher, Rejections, RosNode, publish_or_warn};
use serde_json::Value;

/// The encodings a client may publish in.
pub(super) const ENCODINGS: [&str; 2] = ["cdr", "json"];
/// A client's message larger than this is refused, bytes (a pose or a twist takes under 100).
const MAX_MESSAGE_BYTES: usize = 4096;
/// The kind under which refused client messages are counted and logged.
const REFUSED: &str = "Foxglove client message";

/// The publishers of the topics a Foxglove client may publish on, with their resolved names.
pub(super) struct ClientTopics {
    goal_pose: (String, Publisher<PoseStamped>),
    cmd_vel: (String, Publisher<Twist>),
    rejections: Mutex<Rejections>,
}

impl ClientTopics {
    /// Publishers on `goal_pose` and `cmd_vel` of `node`.
    pub(super) fn new(node: &mut RosNode) -> anyhow::Result<Self> {
        let goal_pose = (node.identity().resolve_topic(topics::GOAL_POSE.name)?, node.publisher(&topics::GOAL_POSE)?);
        let cmd_vel = (node.identity().resolve_topic(topics::CMD_VEL.name)?, node.publisher(&topics::CMD_VEL)?);
        Ok(ClientTopics { goal_pose, cmd_vel, rejections: Mutex::new(Rejections::default()) })
    }

    /// Publishes `payload` of `channel` on its topic, or says why not.
    fn forward(&self, channel: &ClientChannel, payload: &[u8]) -> Result<(), String> {
        if payload.len() > MAX_MESSAGE_BYTES {
            return Err(format!("{} bytes on {}: at most {MAX_MESSAGE_BYTES} expected", payload.len(), channel.topic));
        }
        let topic = format!("/{}", channel.topic.trim_start_matches('/'));
        if topic == self.goal_pose.0 {
            let goal = decode(channel, payload, &topics::GOAL_POSE, pose_from_json)?;
            publish_or_warn(&self.goal_pose.1, &topics::GOAL_POSE, goal);
        } else if topic == self.cmd_vel.0 {
            let twist = decode(channel, payload, &topics::CMD_VEL, twist_from_json)?;
            publish_or_warn(&self.cmd_vel.1, &topics::CMD_VEL, twist);
        } else {
            return Err(format!("{topic}: clients may publish on {} and {} only", self.goal_pose.0, self.cmd_vel.0));
        }
        Ok(())
    }
}

impl ServerListener for ClientTopics {
    fn on_message_data(&self, _client: Client, channel: &ClientChannel, payload: &[u8]) {
        if let Err(problem) = self.forward(channel, payload) {
            lock(&self.rejections).reject(REFUSED, &problem);
        }
    }

    fn on_client_advertise(&self, _client: Client, channel: &ClientChannel) {
        tracing::info!(
            "a Foxglove client publishes on {} ({}, {})",
            channel.topic,
            channel.schema_name,
            channel.encoding
        );
    }
}

/// The message of `topic` in `payload`, decoded by the channel's encoding: CDR, or JSON read by
/// `from_json`.
fn decode<M: RosMessage>(
    channel: &ClientChannel,
    payload: &[u8],
    topic: &Topic<M>,
    from_json: fn(&Value) -> M,
) -> Result<M, String> {
    match channel.encoding.as_str() {
        "cdr" => rover_runtime::cdr::decode::<M>(payload).map_err(|e| format!("{}: {e:#}", topic.name)),
        "json" => serde_json::from_slice::<Value>(payload)
            .map(|json| from_json(&json))
            .map_err(|e| format!("{}: not JSON: {e}", topic.name)),
        other => Err(format!("{}: encoding {other:?}, expected one of {ENCODINGS:?}", topic.name)),
    }
}

/// The number at `pointer` of `json` (a missing field is 0, as in a default message).
fn number(json: &Value, pointer: &str) -> f64 {
    json.pointer(pointer).and_then(Value::as_f64).unwrap_or(0.0)
}

/// A `geometry_msgs/PoseStamped` from Foxglove's JSON (fields missing: their defaults; no
/// orientation: none, which the decision node refuses).
fn pose_from_json(json: &Value) -> PoseStamped {
    let frame_id = json.pointer("/header/frame_id").and_then(Value::as_str).unwrap_or_default();
    let at = |axis: &str| number(json, &format!("/pose/position/{axis}"));
    let turn = |axis: &str| number(json, &format!("/pose/orientation/{axis}"));
    let pose = Pose {
        position: Point { x: at("x"), y: at("y"), z: at("z") },
        orientation: Quaternion { x: turn("x"), y: turn("y"), z: turn("z"), w: turn("w") },
    };
    PoseStamped { header: Header { frame_id: frame_id.to_string(), ..Header::default() }, pose }
}

/// A `geometry_msgs/Twist` from Foxglove's JSON (fields missing: 0).
fn twist_from_json(json: &Value) -> Twist {
    let vector = |part: &str| Vector3 {
        x: number(json, &format!("/{part}/x")),
        y: number(json, &format!("/{part}/y")),
        z: number(json, &format!("/{part}/z")),
    };
    Twist { linear: vector("linear"), angular: vector("angular") }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_json_goal_pose_becomes_the_pose_and_missing_fields_their_defaults() {
        let json = serde_json::json!({
            "header": {"frame_id": "map", "stamp": {"sec": 1, "nsec": 5}},
            "pose": {"position": {"x": 12.5, "y": 80.0}, "orientation": {"w": 1.0}}
        });
        let pose = pose_from_json(&json);
        assert_eq!(pose.header.frame_id, "map");
        assert_eq!((pose.pose.position.x, pose.pose.position.y, pose.pose.position.z), (12.5, 80.0, 0.0));
        assert_eq!(pose.pose.orientation, Quaternion::IDENTITY);
        let bare = pose_from_json(&serde_json::json!({"pose": {"position": {"x": "far"}}}));
        assert_eq!((bare.pose.position.x, bare.pose.orientation.w, bare.header.frame_id.as_str()), (0.0, 0.0, ""));
    }

    #[test]
    fn a_json_twist_keeps_its_linear_and_angular_parts() {
        let twist = twist_from_json(&serde_json::json!({"linear": {"x": 1.5}, "angular": {"z": -0.5}}));
        assert_eq!((twist.linear.x, twist.linear.y, twist.angular.z), (1.5, 0.0, -0.5));
    }
}
