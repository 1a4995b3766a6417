//! The bridge node (`rover bridge`): wires the lock-step core and the Socket.IO server to the topics.

use std::net::{IpAddr, SocketAddr};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use anyhow::Context as _;
use base64::Engine as _;
use rover_imaging::message::{rgb_image_from_message, rgb8_message};
use rover_msgs::body::CameraMount;
use rover_msgs::frame_ids;
use rover_msgs::geometry_msgs::PoseArray;
use rover_msgs::msg::Telemetry;
use rover_msgs::nav_msgs::Odometry;
use rover_msgs::rosgraph_msgs::Clock;
use rover_msgs::sensor_msgs::{CameraInfo, CompressedImage, Image};
use rover_msgs::std_msgs::Header;
use rover_msgs::tf2_msgs::TFMessage;
use rover_runtime::lifecycle::{State, Transition};
use rover_runtime::sync::lock;
use rover_runtime::{Publisher, RosNode, Runtime, publish_or_warn, spawn_subscriber, topics};
use tracing::Instrument as _;

use crate::access::AccessPolicy;
use crate::clock::SimClock;
use crate::convert::{self, FrameMessages, PinholeCamera};
use crate::lockstep::{FrameSink, LockStep, LockStepConfig};
use crate::reply::ReplyPolicy;
use crate::server::{self, ServerConfig};
use crate::telemetry::SimTelemetry;
use crate::teleop::TeleopGains;

rover_runtime::node_params! {
    /// Parameters of the bridge node.
    pub struct BridgeParams {
        /// Address the Socket.IO server listens on.
        host: String = "127.0.0.1",
        /// TCP port the Socket.IO server listens on (the Unity simulator always uses 4567).
        port: i64 [1, 65535] = 4567,
        /// How long to wait for the drive command of a frame before answering with the last one, ms
        /// (at most 250: the simulator drives on meanwhile, up to 1.25 m at its top speed).
        reply_deadline_ms: f64 [0.0, 250.0] = 50.0,
        /// After this long without any drive command the rover is told to brake, ms (at least the
        /// longest reply deadline, at most 2000: 10 m driven blind at the top speed).
        silence_limit_ms: f64 [250.0, 2000.0] = 1000.0,
        /// Brake value sent when braking on silence, on a rejected frame or on a bad cmd_vel (at
        /// least 1, which decelerates 3.6 m/s^2; 10 locks the wheels).
        brake: f64 [1.0, 100.0] = 10.0,
        /// Largest accepted packet from the simulator (a telemetry event with its payload), bytes;
        /// a larger one is not parsed but answered with a brake.
        max_payload_bytes: i64 [1024, 16777216] = 1048576,
        /// Width of the simulator's camera image, pixels.
        image_width: i64 [1, 4096] = 320,
        /// Height of the simulator's camera image, pixels.
        image_height: i64 [1, 4096] = 160,
        /// Also publish the decoded camera image on camera/image_raw (rgb8).
        publish_raw_image: bool = false,
        /// How long a cmd_vel twist overrides the decision node, ms (at most 2000: a teleop tool
        /// that stops publishing drives the rover that long).
        teleop_timeout_ms: f64 [0.0, 2000.0] = 500.0,
        /// Teleoperation throttle per m/s of speed error.
        teleop_throttle_per_mps: f64 [0.0, 10.0] = 0.5,
        /// Period of the /diagnostics message, ms.
        diagnostics_period_ms: f64 [10.0, 60000.0] = 1000.0,
        /// JPEG quality of the inset images sent to the simulator.
        inset_jpeg_quality: i64 [1, 100] = 60,
        /// A new simulator connection replaces the one being served instead of being refused.
        replace_connected_simulator: bool = false,
        /// Simulated time per telemetry frame, s: /clock advances by it each frame, as the
        /// simulator sends no time (the headless simulator steps 0.04 s).
        frame_period_s: f64 [0.001, 1.0] = rover_msgs::unity::FRAME_PERIOD_S,
        /// Browser origins (the Origin header, e.g. "http://localhost:8080") allowed to connect; a
        /// request with any other Origin is refused (403), so that no web page in a browser can
        /// become the simulator. Simulators send no Origin.
        allowed_origins: Vec<String> = Vec::new(),
        /// Token a simulator must present as `Authorization: Bearer TOKEN` (`rover sim --token`);
        /// empty: none asked. The Unity simulator cannot send one: set it only for rover sim.
        simulator_token: String = "",
        /// Addresses or networks (e.g. "192.168.1.20", "10.0.0.0/8") a simulator may connect from;
        /// empty: any. Others are refused (403) before anything else is read.
        allowed_addresses: Vec<String> = Vec::new(),
        /// Open connections to the Socket.IO server at most (one simulator is served; the rest are
        /// reconnects and refusals in passing); more are refused (503).
        max_connections: i64 [1, 1024] = 8,
        /// A connection that has not completed an accepted websocket handshake after this long is
        /// closed, s, so that idle connections cannot hold the connection cap.
        handshake_timeout_s: f64 [0.1, 60.0] = 5.0,
        /// A served simulator that sends nothing for this long is disconnected and the next one
        /// served, s. Simulators send telemetry every frame (Unity at its frame rate, 25 Hz or
        /// more), so silence means it is gone; the Engine.IO heartbeat alone keeps it 85 s.
        simulator_idle_timeout_s: f64 [0.5, 600.0] = 5.0,
    }
    read_at_start: [
        host,
        port,
        max_payload_bytes,
        image_width,
        image_height,
        publish_raw_image,
        diagnostics_period_ms,
        inset_jpeg_quality,
        replace_connected_simulator,
        frame_period_s,
        allowed_origins,
        simulator_token,
        allowed_addresses,
        max_connections,
        handshake_timeout_s,
        simulator_idle_timeout_s,
    ]
}

impl BridgeParams {
    fn lockstep_config(&self) -> LockStepConfig {
        LockStepConfig {
            policy: ReplyPolicy {
                deadline: Duration::from_secs_f64(self.reply_deadline_ms / 1000.0),
                silence_limit: Duration::from_secs_f64(self.silence_limit_ms / 1000.0),
                brake: self.brake as f32,
            },
            max_payload_bytes: self.max_payload_bytes as usize,
            image_size: (self.image_width as usize, self.image_height as usize),
            teleop_timeout: Duration::from_secs_f64(self.teleop_timeout_ms / 1000.0),
            teleop_gains: TeleopGains { throttle_per_mps: self.teleop_throttle_per_mps, brake: self.brake },
        }
    }

    fn server_config(&self) -> anyhow::Result<ServerConfig> {
        let ip: IpAddr =
            self.host.parse().with_context(|| format!("parameter host = {:?} is not an IP address", self.host))?;
        Ok(ServerConfig {
            address: SocketAddr::new(ip, self.port as u16),
            max_message_bytes: self.max_payload_bytes as usize * 4,
            replace_connected_simulator: self.replace_connected_simulator,
            access: self.access_policy()?,
            handshake_timeout: Duration::from_secs_f64(self.handshake_timeout_s),
            idle_timeout: Duration::from_secs_f64(self.simulator_idle_timeout_s),
        })
    }

    fn access_policy(&self) -> anyhow::Result<AccessPolicy> {
        let allowed_networks = self
            .allowed_addresses
            .iter()
            .map(|text| text.parse().map_err(|e: String| anyhow::anyhow!("parameter allowed_addresses: {e}")))
            .collect::<anyhow::Result<_>>()?;
        Ok(AccessPolicy {
            allowed_origins: self.allowed_origins.clone(),
            token: Some(self.simulator_token.clone()).filter(|token| !token.is_empty()),
            allowed_networks,
            max_connections: self.max_connections as usize,
        })
    }
}

/// Publishes the topics of each accepted telemetry frame.
struct DdsSink {
    /// Held, never read: while it lives, late subscribers still get the latched transforms.
    _tf_static: Publisher<TFMessage>,
    telemetry: Publisher<Telemetry>,
    compressed: Publisher<CompressedImage>,
    camera_info: Publisher<CameraInfo>,
    odom: Publisher<Odometry>,
    tf: Publisher<TFMessage>,
    clock_publisher: Publisher<Clock>,
    clock: Arc<SimClock>,
    sample_truth: Publisher<PoseArray>,
    raw: Option<Publisher<Image>>,
    camera: PinholeCamera,
    last_samples: Mutex<Option<Vec<(f64, f64)>>>,
}

impl DdsSink {
    fn new(node: &mut RosNode, params: &BridgeParams, clock: Arc<SimClock>) -> anyhow::Result<Self> {
        let camera = PinholeCamera::of_size(params.image_width as u32, params.image_height as u32);
        let tf_static = node.publisher(&topics::TF_STATIC)?;
        let static_transforms =
            convert::static_transforms_message(&CameraMount::UNITY, &Header::at(frame_ids::MAP, clock.now()));
        publish_or_warn(&tf_static, &topics::TF_STATIC, static_transforms);
        Ok(DdsSink {
            _tf_static: tf_static,
            telemetry: node.publisher(&topics::TELEMETRY)?,
            compressed: node.publisher(&topics::CAMERA_COMPRESSED)?,
            camera_info: node.publisher(&topics::CAMERA_INFO)?,
            odom: node.publisher(&topics::ODOM)?,
            tf: node.publisher(&topics::TF)?,
            clock_publisher: node.publisher(&topics::CLOCK)?,
            clock,
            sample_truth: node.publisher(&topics::SAMPLE_TRUTH)?,
            raw: if params.publish_raw_image { Some(node.publisher(&topics::CAMERA_RAW)?) } else { None },
            camera,
            last_samples: Mutex::new(None),
        })
    }

    fn publish_raw(&self, publisher: &Publisher<Image>, jpeg: &[u8], header: Header) {
        match rover_imaging::decode_jpeg(jpeg, self.camera.width as usize, self.camera.height as usize) {
            Ok(image) => publish_or_warn(publisher, &topics::CAMERA_RAW, rgb8_message(image, header)),
            Err(e) => tracing::warn!("camera/image_raw not published: {e}"),
        }
    }

    fn publish_sample_truth(&self, telemetry: &SimTelemetry, header: Header) {
        let mut last = lock(&self.last_samples);
        if last.as_ref() != Some(&telemetry.samples) {
            *last = Some(telemetry.samples.clone());
            let message =
                convert::sample_truth_message(telemetry, Header { frame_id: frame_ids::MAP.into(), ..header });
            publish_or_warn(&self.sample_truth, &topics::SAMPLE_TRUTH, message);
        }
    }
}

impl FrameSink for DdsSink {
    fn publish_frame(&self, frame: u64, telemetry: &SimTelemetry) {
        publish_or_warn(&self.clock_publisher, &topics::CLOCK, self.clock.clock_message(frame));
        let messages = FrameMessages::new(telemetry, frame, self.clock.stamp_frame(frame), &self.camera);
        let (odom_header, camera_header) = (messages.telemetry.header.clone(), messages.compressed.header.clone());
        publish_or_warn(&self.telemetry, &topics::TELEMETRY, messages.telemetry);
        publish_or_warn(&self.compressed, &topics::CAMERA_COMPRESSED, messages.compressed);
        publish_or_warn(&self.camera_info, &topics::CAMERA_INFO, messages.camera_info);
        publish_or_warn(&self.odom, &topics::ODOM, messages.odom);
        publish_or_warn(&self.tf, &topics::TF, messages.tf);
        if let Some(raw) = &self.raw {
            self.publish_raw(raw, &telemetry.image_jpeg, camera_header);
        }
        self.publish_sample_truth(telemetry, odom_header);
    }
}

fn inset_base64(message: Image, quality: u8) -> Result<String, String> {
    let image = rgb_image_from_message(message)?;
    let jpeg = rover_imaging::encode_jpeg(&image, quality).map_err(|e| e.to_string())?;
    Ok(base64::engine::general_purpose::STANDARD.encode(jpeg))
}

/// Runs the bridge node until shutdown.
pub async fn run(runtime: &Runtime) -> anyhow::Result<()> {
    let (mut node, params) = runtime.node::<BridgeParams>("bridge")?;
    let span = node.span();
    let initial = params.get();
    let clock = Arc::new(SimClock::new(initial.frame_period_s, node.uses_sim_time()));
    let sink = DdsSink::new(&mut node, &initial, clock.clone())?;
    let core = Arc::new(LockStep::new(initial.lockstep_config(), sink));
    subscribe_commands(&mut node, &core, &span)?;
    subscribe_insets(&mut node, &core, &span, initial.inset_jpeg_quality as u8)?;
    let diagnostics = node.publisher(&topics::DIAGNOSTICS)?;
    let name = node.identity().fully_qualified();
    let period = Duration::from_secs_f64(initial.diagnostics_period_ms / 1000.0);
    let diagnostics_core = core.clone();
    tokio::spawn(
        async move {
            let mut ticks = tokio::time::interval(period);
            loop {
                ticks.tick().await;
                let message = diagnostics_core.stats().diagnostics(&name, Header::at("", clock.now()));
                publish_or_warn(&diagnostics, &topics::DIAGNOSTICS, message);
            }
        }
        .instrument(span.clone()),
    );
    let mut changes = params.watch();
    let config_core = core.clone();
    tokio::spawn(async move {
        while changes.changed().await.is_ok() {
            let updated = changes.borrow_and_update().lockstep_config();
            config_core.set_config(updated);
        }
    });
    manage(&node, core.clone(), &span)?;
    let shutdown = runtime.shutdown();
    let served = server::serve(core.clone(), initial.server_config()?, async move { shutdown.wait().await })
        .instrument(span.clone())
        .await;
    span.in_scope(|| tracing::info!("bridge: {}", core.stats().summary()));
    served
}

/// Makes the bridge a managed node, configured and active from the start unless its `autostart`
/// parameter is false: while it is not active, it answers the simulator with the brake.
fn manage(node: &RosNode, core: Arc<LockStep<DdsSink>>, span: &tracing::Span) -> anyhow::Result<()> {
    let mut lifecycle = node.lifecycle()?;
    if node.autostarts() {
        lifecycle.record(Transition::Configure);
        lifecycle.record(Transition::Activate);
    }
    core.set_active(lifecycle.state() == State::Active);
    tokio::spawn(
        async move {
            loop {
                let request = lifecycle.next_request().await;
                let goal = lifecycle.state().after(request.transition);
                core.set_active(goal == Some(State::Active));
                lifecycle.finish(request, true);
            }
        }
        .instrument(span.clone()),
    );
    Ok(())
}

fn subscribe_commands(node: &mut RosNode, core: &Arc<LockStep<DdsSink>>, span: &tracing::Span) -> anyhow::Result<()> {
    let drive = core.clone();
    spawn_subscriber(node.subscription(&topics::DRIVE_CMD)?, span.clone(), move |cmd| {
        drive.on_drive_command(cmd.frame, cmd.throttle, cmd.brake, cmd.steering_angle_deg)
    });
    let pickup = core.clone();
    spawn_subscriber(node.subscription(&topics::PICKUP)?, span.clone(), move |_| pickup.on_pickup_request());
    let teleop = core.clone();
    spawn_subscriber(node.subscription(&topics::CMD_VEL)?, span.clone(), move |twist| teleop.on_teleop(twist));
    Ok(())
}

fn subscribe_insets(
    node: &mut RosNode,
    core: &Arc<LockStep<DdsSink>>,
    span: &tracing::Span,
    quality: u8,
) -> anyhow::Result<()> {
    let map = core.clone();
    spawn_subscriber(node.subscription(&topics::MAP_IMAGE)?, span.clone(), move |image| {
        match inset_base64(image, quality) {
            Ok(inset) => map.set_map_inset(inset),
            Err(e) => tracing::warn!("ignored a map/image message: {e}"),
        }
    });
    let vision = core.clone();
    spawn_subscriber(node.subscription(&topics::VISION)?, span.clone(), move |image| {
        match inset_base64(image, quality) {
            Ok(inset) => vision.set_vision_inset(inset),
            Err(e) => tracing::warn!("ignored a rover/vision message: {e}"),
        }
    });
    Ok(())
}

#[cfg(test)]
mod tests {
    use rover_runtime::NodeParams as _;
    use rover_runtime::params::{self, ParameterValue};

    use super::*;

    fn spec(name: &str) -> params::ParamSpec {
        BridgeParams::specs().into_iter().find(|spec| spec.name == name).expect("a bridge parameter")
    }

    /// Why the parameter services refuse `value` for bridge parameter `name`.
    fn refusal(name: &str, value: f64) -> String {
        params::check_value(&spec(name), &ParameterValue::Double(value)).expect_err("refused")
    }

    #[test]
    fn unsafe_values_of_the_safety_parameters_are_refused_with_their_range() {
        assert_eq!(refusal("brake", 0.0), "= 0 is outside the allowed range [1, 100]");
        assert_eq!(refusal("silence_limit_ms", 600000.0), "= 600000 is outside the allowed range [250, 2000]");
        assert_eq!(refusal("reply_deadline_ms", 1000.0), "= 1000 is outside the allowed range [0, 250]");
        assert_eq!(refusal("teleop_timeout_ms", 10000.0), "= 10000 is outside the allowed range [0, 2000]");
    }

    #[test]
    fn a_parameter_file_with_brake_0_is_refused_at_start() {
        let yaml = "bridge:\n  ros__parameters:\n    brake: 0.0\n";
        let assignments = params::assignments_from_yaml(yaml, "unsafe.yaml", "/bridge").unwrap();
        let error = params::resolve_values("/bridge", &BridgeParams::specs(), &assignments).unwrap_err();
        assert_eq!(
            error.to_string(),
            "node `/bridge`: parameter `brake` (from unsafe.yaml) = 0 is outside the allowed range [1, 100]"
        );
    }

    #[test]
    fn a_bad_allowed_address_is_refused_naming_it() {
        let params =
            BridgeParams { allowed_addresses: vec!["10.0.0.0/8".into(), "lan".into()], ..BridgeParams::default() };
        let error = params.server_config().unwrap_err().to_string();
        assert_eq!(
            error,
            "parameter allowed_addresses: \"lan\" is not an IP address or network, expected e.g. 192.168.1.20 or 10.0.0.0/8"
        );
    }

    #[test]
    fn an_empty_token_asks_for_none() {
        assert_eq!(BridgeParams::default().access_policy().unwrap().token, None);
        let params = BridgeParams { simulator_token: "s3cret".into(), ..BridgeParams::default() };
        assert_eq!(params.access_policy().unwrap().token.as_deref(), Some("s3cret"));
    }

    #[test]
    fn no_reply_deadline_outlasts_the_silence_limit() {
        let (_, longest_deadline_ms) = spec("reply_deadline_ms").range.unwrap();
        let (shortest_silence_ms, _) = spec("silence_limit_ms").range.unwrap();
        assert!(longest_deadline_ms <= shortest_silence_ms);
    }
}
