//! The lock-step core: every telemetry frame gets a number and exactly one reply, the drive command
//! carrying that number if it arrives within the deadline, otherwise the last command, and a brake
//! after a longer silence. Independent of sockets and DDS: frames leave through a [`FrameSink`].

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use rover_msgs::geometry_msgs::Twist;
use rover_msgs::validate::Validate as _;
use rover_runtime::rejections::clipped;
use rover_runtime::sync::lock;
use tokio::sync::oneshot;

use crate::insets::Insets;
use crate::reply::{CommandSource, DriveValues, LastCommand, Reply, ReplyPolicy};
use crate::stats::{BridgeStats, LoopHops};
use crate::telemetry::{SimTelemetry, parse_telemetry_value};
use crate::teleop::{TeleopGains, twist_to_drive};

/// Receives every accepted telemetry frame (the bridge node publishes it on the ROS topics).
pub(crate) trait FrameSink: Send + Sync + 'static {
    /// Called once per accepted frame, before the bridge waits for its drive command; whether
    /// the frame was taken (a sink that cannot keep up drops it).
    fn publish_frame(&self, frame: u64, telemetry: SimTelemetry) -> bool;
}

/// Settings of the lock-step core.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LockStepConfig {
    /// Deadline, silence limit and brake value.
    pub policy: ReplyPolicy,
    /// Largest accepted packet from the simulator (a telemetry event with its payload), bytes;
    /// a larger one is not parsed.
    pub max_payload_bytes: usize,
    /// Expected camera image size (width, height).
    pub image_size: (usize, usize),
    /// How long a `cmd_vel` overrides the decision node.
    pub teleop_timeout: Duration,
    /// Teleoperation controller gains.
    pub teleop_gains: TeleopGains,
}

/// A telemetry frame between its arrival and its reply.
pub(crate) struct InFlight {
    received_at: Instant,
    state: FrameState,
}

enum FrameState {
    Decided(Reply),
    Waiting(Waiting),
}

struct Waiting {
    published_at: Instant,
    receiver: oneshot::Receiver<DriveValues>,
    facts: FrameFacts,
}

/// What the reply to a frame depends on besides its drive command.
#[derive(Debug, Clone, Copy)]
struct FrameFacts {
    frame: u64,
    near_sample: bool,
    picking_up: bool,
    speed_mps: f64,
}

/// The bridge's lock-step state, shared by all simulator connections.
pub(crate) struct LockStep<S> {
    config: Mutex<LockStepConfig>,
    sink: S,
    stats: Arc<BridgeStats>,
    next_frame: AtomicU64,
    waiting: Mutex<HashMap<u64, oneshot::Sender<DriveValues>>>,
    last_command: Mutex<Option<LastCommand>>,
    pickup_requested: AtomicBool,
    braking_on_silence: AtomicBool,
    /// Whether the bridge is active (lifecycle); otherwise every reply is the brake.
    active: AtomicBool,
    teleop: Mutex<Option<(Twist, Instant)>>,
    insets: Mutex<Insets>,
}

impl<S: FrameSink> LockStep<S> {
    /// A core that publishes accepted frames to `sink`.
    pub(crate) fn new(config: LockStepConfig, sink: S) -> Self {
        LockStep {
            config: Mutex::new(config),
            sink,
            stats: Arc::default(),
            next_frame: AtomicU64::new(0),
            waiting: Mutex::new(HashMap::new()),
            last_command: Mutex::new(None),
            pickup_requested: AtomicBool::new(false),
            braking_on_silence: AtomicBool::new(false),
            active: AtomicBool::new(true),
            teleop: Mutex::new(None),
            insets: Mutex::new(Insets::default()),
        }
    }

    /// The current settings.
    pub(crate) fn config(&self) -> LockStepConfig {
        *lock(&self.config)
    }

    /// Replaces the settings (when a parameter changes); frames in flight keep their deadline.
    pub(crate) fn set_config(&self, config: LockStepConfig) {
        *lock(&self.config) = config;
    }

    /// Activates or deactivates the bridge: an inactive bridge answers every frame with the brake
    /// at once, whatever drive, pickup or teleoperation commands come.
    pub(crate) fn set_active(&self, active: bool) {
        self.active.store(active, Ordering::Relaxed);
    }

    /// The health counters.
    pub(crate) fn stats(&self) -> &BridgeStats {
        &self.stats
    }

    /// The health counters, for the parts of the server that outlive a borrow of the core.
    pub(crate) fn shared_stats(&self) -> Arc<BridgeStats> {
        self.stats.clone()
    }

    /// The current inset images.
    pub(crate) fn insets(&self) -> Insets {
        lock(&self.insets).clone()
    }

    /// Replaces the world map inset.
    pub(crate) fn set_map_inset(&self, base64_jpeg: String) {
        lock(&self.insets).map = base64_jpeg.into();
    }

    /// Replaces the vision inset.
    pub(crate) fn set_vision_inset(&self, base64_jpeg: String) {
        lock(&self.insets).vision = base64_jpeg.into();
    }

    /// Takes in one telemetry event given its argument (`None` if it had none): parses it, numbers
    /// it, publishes it and registers the wait for its drive command. Call in arrival order;
    /// [`LockStep::reply`] then produces the one reply.
    pub(crate) fn receive(&self, payload: Option<&serde_json::Value>) -> InFlight {
        let received_at = Instant::now();
        let config = self.config();
        self.stats.frame_received();
        let state = match payload.map(parse_telemetry_value) {
            None | Some(Ok(None)) => FrameState::Decided(Reply::Manual),
            Some(Err(e)) => FrameState::Decided(self.reject(&config, e.kind(), &e.to_string())),
            Some(Ok(Some(telemetry))) => {
                let (width, height) = config.image_size;
                match rover_imaging::check_jpeg(&telemetry.image_jpeg, width, height) {
                    Err(e) => {
                        FrameState::Decided(self.reject(&config, "bad_image", &format!("telemetry field `image`: {e}")))
                    }
                    Ok(()) => self.publish(telemetry),
                }
            }
        };
        InFlight { received_at, state }
    }

    /// Takes in a message from the simulator that is not a telemetry event but should have been
    /// (unparseable packet, binary frame): it is answered with a brake, so the loop goes on.
    pub(crate) fn receive_garbage(&self, kind: &str, problem: &str) -> InFlight {
        let config = self.config();
        self.stats.frame_received();
        InFlight { received_at: Instant::now(), state: FrameState::Decided(self.reject(&config, kind, problem)) }
    }

    /// Waits for the drive command of a frame (up to the deadline) and decides the reply.
    pub(crate) async fn reply(&self, in_flight: InFlight) -> Reply {
        let InFlight { received_at, state } = in_flight;
        let (reply, hops) = match state {
            FrameState::Decided(reply) => (reply, None),
            FrameState::Waiting(waiting) => {
                let published_at = waiting.published_at;
                let (reply, command_at) = self.decide(waiting).await;
                let hops = command_at.map(|at| LoopHops {
                    bridge_in: published_at - received_at,
                    graph: at - published_at,
                    bridge_out: at.elapsed(),
                });
                (reply, hops)
            }
        };
        self.stats.replied(&reply, received_at.elapsed(), hops);
        reply
    }

    fn reject(&self, config: &LockStepConfig, kind: &str, problem: &str) -> Reply {
        let problem = clipped(problem);
        self.stats.warn_problem(kind, format_args!("rejected telemetry frame: {problem}; answering with a brake"));
        Reply::Data(DriveValues::brake(config.policy.brake), CommandSource::RejectedFrame)
    }

    fn publish(&self, telemetry: SimTelemetry) -> FrameState {
        let frame = self.next_frame.fetch_add(1, Ordering::Relaxed) + 1;
        let (sender, receiver) = oneshot::channel();
        lock(&self.waiting).insert(frame, sender);
        let facts = FrameFacts {
            frame,
            near_sample: telemetry.near_sample,
            picking_up: telemetry.picking_up,
            speed_mps: telemetry.state.speed_mps,
        };
        if !self.sink.publish_frame(frame, telemetry) {
            let problem = format_args!("frame {frame} was not published: the bridge node is not keeping up");
            self.stats.warn_problem("frame_not_published", problem);
        }
        FrameState::Waiting(Waiting { published_at: Instant::now(), receiver, facts })
    }

    /// The reply to a frame, and when its drive command came (`None` if it did not in time).
    async fn decide(&self, waiting: Waiting) -> (Reply, Option<Instant>) {
        let config = self.config();
        let Waiting { receiver, facts, .. } = waiting;
        if !self.active.load(Ordering::Relaxed) {
            lock(&self.waiting).remove(&facts.frame);
            return (Reply::Data(DriveValues::brake(config.policy.brake), CommandSource::Inactive), None);
        }
        let fresh = if config.policy.deadline.is_zero() {
            let mut receiver = receiver;
            receiver.try_recv().ok()
        } else {
            tokio::time::timeout(config.policy.deadline, receiver).await.ok().and_then(Result::ok)
        };
        let command_at = fresh.is_some().then(Instant::now);
        lock(&self.waiting).remove(&facts.frame);
        (self.reply_for(&config, fresh, facts), command_at)
    }

    fn reply_for(&self, config: &LockStepConfig, fresh: Option<DriveValues>, facts: FrameFacts) -> Reply {
        let FrameFacts { frame, near_sample, picking_up, speed_mps } = facts;
        if self.pickup_requested.swap(false, Ordering::Relaxed) {
            if near_sample && !picking_up {
                return Reply::Pickup;
            }
            tracing::warn!(frame, "ignored a pickup request: no sample is within reach or a pickup is running");
            self.stats.problem("pickup_without_sample");
        }
        if let Some(values) = self.teleop_values(config, speed_mps) {
            return Reply::Data(values, CommandSource::Teleop);
        }
        let last = *lock(&self.last_command);
        let reply = config.policy.drive_reply(fresh, last, Instant::now());
        let braking = matches!(reply, Reply::Data(_, CommandSource::SilenceBrake));
        if self.braking_on_silence.swap(braking, Ordering::Relaxed) != braking {
            if braking {
                tracing::warn!(
                    frame,
                    "no drive command for {:?}: braking until one arrives",
                    config.policy.silence_limit
                );
            } else {
                tracing::info!(frame, "drive commands are back");
            }
        }
        reply
    }

    fn teleop_values(&self, config: &LockStepConfig, speed_mps: f64) -> Option<DriveValues> {
        let teleop = lock(&self.teleop);
        let (twist, at) = teleop.as_ref()?;
        (at.elapsed() < config.teleop_timeout).then(|| twist_to_drive(twist, speed_mps, config.teleop_gains))
    }

    /// Handles a drive command from the decision node for frame `frame`.
    pub(crate) fn on_drive_command(&self, frame: u64, throttle: f32, brake: f32, steering_deg: f32) {
        let values = match DriveValues::checked(throttle, brake, steering_deg) {
            Ok(values) => values,
            Err(problem) => {
                let message = format_args!("rejected the drive command of frame {frame}: {problem}");
                self.stats.warn_problem("bad_drive_command", message);
                return;
            }
        };
        *lock(&self.last_command) = Some(LastCommand { values, received_at: Instant::now() });
        if let Some(waiter) = lock(&self.waiting).remove(&frame) {
            let _ = waiter.send(values);
        }
    }

    /// Handles a pickup request: the next reply becomes `pickup` if a sample is within reach.
    pub(crate) fn on_pickup_request(&self) {
        self.pickup_requested.store(true, Ordering::Relaxed);
    }

    /// Handles a `cmd_vel` twist from a teleoperation tool; one with a NaN or infinite component
    /// brakes the rover while it is fresh.
    pub(crate) fn on_teleop(&self, twist: Twist) {
        if let Err(invalid) = twist.validate() {
            self.stats.warn_problem("bad_teleop", format_args!("cmd_vel {invalid}: braking while it is fresh"));
        }
        *lock(&self.teleop) = Some((twist, Instant::now()));
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::telemetry::tests::sample_payload;

    struct ChannelSink(std::sync::mpsc::Sender<u64>);

    impl FrameSink for ChannelSink {
        fn publish_frame(&self, frame: u64, _telemetry: SimTelemetry) -> bool {
            self.0.send(frame).unwrap();
            true
        }
    }

    fn core() -> (Arc<LockStep<ChannelSink>>, std::sync::mpsc::Receiver<u64>) {
        let (sender, receiver) = std::sync::mpsc::channel();
        let config = LockStepConfig {
            policy: ReplyPolicy {
                deadline: Duration::from_millis(50),
                silence_limit: Duration::from_millis(300),
                brake: 10.0,
            },
            max_payload_bytes: 1 << 20,
            image_size: (64, 32),
            teleop_timeout: Duration::from_millis(200),
            teleop_gains: TeleopGains { throttle_per_mps: 0.5, brake: 10.0 },
        };
        (Arc::new(LockStep::new(config, ChannelSink(sender))), receiver)
    }

    /// A telemetry payload with a real JPEG of 64 x 32 pixels.
    pub(crate) fn payload(near_sample: bool) -> serde_json::Value {
        use base64::Engine as _;
        let jpeg = rover_imaging::encode_jpeg(&rover_imaging::RgbImage::new(64, 32), 75).unwrap();
        let mut fields = sample_payload();
        fields.insert("image".into(), base64::engine::general_purpose::STANDARD.encode(jpeg).into());
        fields.insert("near_sample".into(), if near_sample { "1" } else { "0" }.into());
        fields.insert("picking_up".into(), "0".into());
        serde_json::Value::Object(fields)
    }

    /// Sends one frame through `core` on a task of its own; returns that task (its reply) and the
    /// frame's number once published.
    async fn frame_in_flight(
        core: &Arc<LockStep<ChannelSink>>,
        frames: std::sync::mpsc::Receiver<u64>,
    ) -> (tokio::task::JoinHandle<Reply>, u64, std::sync::mpsc::Receiver<u64>) {
        let answering = {
            let core = core.clone();
            tokio::spawn(async move { core.reply(core.receive(Some(&payload(false)))).await })
        };
        let (frame, frames) = tokio::task::spawn_blocking(move || (frames.recv().unwrap(), frames)).await.unwrap();
        (answering, frame, frames)
    }

    #[tokio::test]
    async fn the_command_for_the_frame_is_the_reply() {
        let (core, frames) = core();
        let (answering, frame, _frames) = frame_in_flight(&core, frames).await;
        core.on_drive_command(frame + 1, 1.0, 0.0, 0.0);
        core.on_drive_command(frame, 0.3, 0.0, 5.0);
        let reply = answering.await.unwrap();
        assert_eq!(
            reply,
            Reply::Data(DriveValues { throttle: 0.3, brake: 0.0, steering_deg: 5.0 }, CommandSource::Fresh)
        );
    }

    #[tokio::test]
    async fn a_frames_time_splits_into_the_bridge_in_the_graph_and_the_bridge_out() {
        let (core, frames) = core();
        let (answering, frame, _frames) = frame_in_flight(&core, frames).await;
        tokio::time::sleep(Duration::from_millis(20)).await;
        core.on_drive_command(frame, 0.3, 0.0, 5.0);
        answering.await.unwrap();
        core.reply(core.receive(Some(&payload(false)))).await;
        let [bridge_in, graph, bridge_out] = core.stats().hops();
        assert_eq!([bridge_in.samples, graph.samples, bridge_out.samples], [1, 1, 1], "the held frame has no hops");
        assert!((20.0..50.0).contains(&graph.p50_ms), "the graph took the 20 ms: {graph:?}");
        assert!(bridge_in.p50_ms < 20.0 && bridge_out.p50_ms < 20.0, "{bridge_in:?} {bridge_out:?}");
        let total = core.stats().latency();
        assert!(total.p50_ms >= graph.p50_ms, "{total:?}");
    }

    #[tokio::test]
    async fn silence_holds_then_brakes() {
        let (core, _frames) = core();
        core.on_drive_command(0, 0.4, 0.0, 0.0);
        let held = core.reply(core.receive(Some(&payload(false)))).await;
        assert!(matches!(held, Reply::Data(v, CommandSource::Held) if v.throttle == 0.4), "{held:?}");
        tokio::time::sleep(Duration::from_millis(350)).await;
        let braked = core.reply(core.receive(Some(&payload(false)))).await;
        assert_eq!(braked, Reply::Data(DriveValues::brake(10.0), CommandSource::SilenceBrake));
        assert_eq!(core.stats().deadline_misses(), 2);
    }

    #[tokio::test]
    async fn an_inactive_bridge_brakes_whatever_comes_until_active_again() {
        let (core, frames) = core();
        core.set_active(false);
        let (answering, frame, _frames) = frame_in_flight(&core, frames).await;
        core.on_drive_command(frame, 0.3, 0.0, 5.0);
        core.on_pickup_request();
        assert_eq!(answering.await.unwrap(), Reply::Data(DriveValues::brake(10.0), CommandSource::Inactive));
        core.set_active(true);
        core.on_drive_command(0, 0.4, 0.0, 0.0);
        let reply = core.reply(core.receive(Some(&payload(false)))).await;
        assert!(matches!(reply, Reply::Data(v, CommandSource::Held) if v.throttle == 0.4), "{reply:?}");
        assert!(core.stats().summary().contains("1 inactive brakes"), "{}", core.stats().summary());
    }

    #[tokio::test]
    async fn bad_frames_and_empty_payloads() {
        let (core, _frames) = core();
        assert_eq!(core.reply(core.receive(None)).await, Reply::Manual);
        assert_eq!(core.reply(core.receive(Some(&serde_json::json!({})))).await, Reply::Manual);
        let rejected = core.reply(core.receive(Some(&serde_json::json!({"speed": 1})))).await;
        assert_eq!(rejected, Reply::Data(DriveValues::brake(10.0), CommandSource::RejectedFrame));
        assert_eq!(core.stats().problem_count("missing_field"), 1);
        let mut corrupt = payload(false);
        corrupt["image"] = "/9j/AAAA".into();
        core.reply(core.receive(Some(&corrupt))).await;
        assert_eq!(core.stats().problem_count("bad_image"), 1);
    }

    #[tokio::test]
    async fn pickup_only_when_a_sample_is_near() {
        let (core, _frames) = core();
        core.on_pickup_request();
        assert!(matches!(core.reply(core.receive(Some(&payload(false)))).await, Reply::Data(..)));
        assert_eq!(core.stats().problem_count("pickup_without_sample"), 1);
        core.on_pickup_request();
        assert_eq!(core.reply(core.receive(Some(&payload(true)))).await, Reply::Pickup);
    }

    #[tokio::test]
    async fn teleop_overrides_while_fresh_and_nan_commands_are_rejected() {
        let (core, _frames) = core();
        core.on_drive_command(0, f32::NAN, 0.0, 0.0);
        assert_eq!(core.stats().problem_count("bad_drive_command"), 1);
        assert_eq!(core.stats().deadline_misses(), 0);
        let mut twist = Twist::default();
        twist.linear.x = 2.0;
        core.on_teleop(twist);
        let reply = core.reply(core.receive(Some(&payload(false)))).await;
        assert!(matches!(reply, Reply::Data(_, CommandSource::Teleop)), "{reply:?}");
        tokio::time::sleep(Duration::from_millis(250)).await;
        let reply = core.reply(core.receive(Some(&payload(false)))).await;
        assert!(matches!(reply, Reply::Data(_, CommandSource::SilenceBrake)), "{reply:?}");
    }

    #[tokio::test]
    async fn a_nan_cmd_vel_brakes_the_standing_rover_too() {
        let (core, _frames) = core();
        let mut twist = Twist::default();
        twist.angular.z = f64::NAN;
        core.on_teleop(twist);
        let mut standing = payload(false);
        standing["speed"] = "0.0000".into();
        let reply = core.reply(core.receive(Some(&standing))).await;
        assert_eq!(reply, Reply::Data(DriveValues::brake(10.0), CommandSource::Teleop));
        assert_eq!(core.stats().problem_count("bad_teleop"), 1);
    }
}
