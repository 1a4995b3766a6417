//! The bridge node (`rover bridge`): wires the lock-step core and the Socket.IO server to the topics.

use std::net::{IpAddr, SocketAddr};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use base64::Engine as _;
use rover_imaging::message::{rgb_image_from_message, rgb8_message};
use rover_msgs::body::CameraMount;
use rover_msgs::frame_ids;
use rover_msgs::sensor_msgs::Image;
use rover_msgs::std_msgs::Header;
use rover_runtime::node_core::{Inputs, NodeCore, Outbox, Work};
use rover_runtime::{Build, RosNode, Runtime, run_node_with, topics};
use tokio::sync::mpsc;
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

/// How many accepted frames may wait for the bridge node's core; a frame beyond is dropped
/// (the lock-step core counts and logs it) rather than queued without bound behind a stalled
/// node.
const FRAME_QUEUE_LENGTH: usize = 64;

/// Hands each accepted frame to the bridge node's core, which the adapter runs.
struct FrameQueue(mpsc::Sender<Work<BridgeNode>>);

impl FrameSink for FrameQueue {
    fn publish_frame(&self, frame: u64, telemetry: SimTelemetry) -> bool {
        let publish: Work<BridgeNode> = Box::new(move |core, out| core.publish_frame(frame, &telemetry, out));
        self.0.try_send(publish).is_ok()
    }
}

/// The bridge node's core: publishes the topics of each frame the lock-step core accepted, and
/// hands it the commands and insets that come over DDS.
struct BridgeNode {
    link: Arc<LockStep<FrameQueue>>,
    clock: SimClock,
    camera: PinholeCamera,
    publish_raw_image: bool,
    inset_jpeg_quality: u8,
    /// The sample positions last published on `sim/sample_truth`.
    last_samples: Option<Vec<(f64, f64)>>,
    /// The node's name, as `/diagnostics` reports it.
    name: String,
    diagnostics_period: Duration,
    next_diagnostics: Instant,
}

impl NodeCore for BridgeNode {
    type Params = BridgeParams;
    const NAME: &'static str = "bridge";
    const BUILT_AT_START: bool = true;

    fn inputs() -> Inputs<Self> {
        Inputs::<Self>::new()
            .on(&topics::DRIVE_CMD, |core, cmd, _| {
                core.link.on_drive_command(cmd.frame, cmd.throttle, cmd.brake, cmd.steering_angle_deg)
            })
            .on(&topics::PICKUP, |core, _, _| core.link.on_pickup_request())
            .on(&topics::CMD_VEL, |core, twist, _| core.link.on_teleop(twist.clone()))
            .on(&topics::MAP_IMAGE, |core, image, _| core.set_inset(image, Inset::Map))
            .on(&topics::VISION, |core, image, _| core.set_inset(image, Inset::Vision))
    }

    fn start(&mut self, out: &mut Outbox) {
        let header = Header::at(frame_ids::MAP, self.clock.now());
        out.publish(&topics::TF_STATIC, convert::static_transforms_message(&CameraMount::UNITY, &header));
    }

    fn set_active(&mut self, active: bool) {
        self.link.set_active(active);
    }

    fn set_params(&mut self, params: BridgeParams) {
        self.link.set_config(params.lockstep_config());
    }

    fn timer_due(&self) -> Option<Instant> {
        Some(self.next_diagnostics)
    }

    fn on_timer(&mut self, out: &mut Outbox) {
        self.next_diagnostics = Instant::now() + self.diagnostics_period;
        let header = Header::at("", self.clock.now());
        out.publish(&topics::DIAGNOSTICS, self.link.stats().diagnostics(&self.name, header));
    }

    fn stop(&mut self, _out: &mut Outbox) {
        tracing::info!("bridge: {}", self.link.stats().summary());
    }
}

/// The two inset images the bridge sends the simulator.
#[derive(Debug, Clone, Copy)]
enum Inset {
    Map,
    Vision,
}

impl BridgeNode {
    fn new(link: Arc<LockStep<FrameQueue>>, node: &RosNode, params: &BridgeParams) -> Self {
        BridgeNode {
            link,
            clock: SimClock::new(params.frame_period_s, node.uses_sim_time()),
            camera: PinholeCamera::of_size(params.image_width as u32, params.image_height as u32),
            publish_raw_image: params.publish_raw_image,
            inset_jpeg_quality: params.inset_jpeg_quality as u8,
            last_samples: None,
            name: node.identity().fully_qualified(),
            diagnostics_period: Duration::from_secs_f64(params.diagnostics_period_ms / 1000.0),
            next_diagnostics: Instant::now(),
        }
    }

    fn publish_frame(&mut self, frame: u64, telemetry: &SimTelemetry, out: &mut Outbox) {
        out.publish(&topics::CLOCK, self.clock.clock_message(frame));
        let messages = FrameMessages::new(telemetry, frame, self.clock.stamp_frame(frame), &self.camera);
        let (odom_header, camera_header) = (messages.telemetry.header.clone(), messages.compressed.header.clone());
        out.publish(&topics::TELEMETRY, messages.telemetry);
        out.publish(&topics::CAMERA_COMPRESSED, messages.compressed);
        out.publish(&topics::CAMERA_INFO, messages.camera_info);
        out.publish(&topics::ODOM, messages.odom);
        out.publish(&topics::TF, messages.tf);
        if self.publish_raw_image {
            self.publish_raw(&telemetry.image_jpeg, camera_header, out);
        }
        self.publish_sample_truth(telemetry, odom_header, out);
    }

    fn publish_raw(&self, jpeg: &[u8], header: Header, out: &mut Outbox) {
        match rover_imaging::decode_jpeg(jpeg, self.camera.width as usize, self.camera.height as usize) {
            Ok(image) => out.publish(&topics::CAMERA_RAW, rgb8_message(image, header)),
            Err(e) => tracing::warn!("camera/image_raw not published: {e}"),
        }
    }

    /// Publishes the true sample positions when they changed (a sample was picked up).
    fn publish_sample_truth(&mut self, telemetry: &SimTelemetry, header: Header, out: &mut Outbox) {
        if self.last_samples.as_ref() != Some(&telemetry.samples) {
            self.last_samples = Some(telemetry.samples.clone());
            let message =
                convert::sample_truth_message(telemetry, Header { frame_id: frame_ids::MAP.into(), ..header });
            out.publish(&topics::SAMPLE_TRUTH, message);
        }
    }

    /// Encodes `image` as the `inset` JPEG for the next replies, on a blocking thread: the
    /// node's task also carries the frames and the drive commands.
    fn set_inset(&mut self, image: &Image, inset: Inset) {
        let (link, image, quality) = (self.link.clone(), image.clone(), self.inset_jpeg_quality);
        let span = tracing::Span::current();
        tokio::task::spawn_blocking(move || match inset_base64(image, quality) {
            Ok(jpeg) => match inset {
                Inset::Map => link.set_map_inset(jpeg),
                Inset::Vision => link.set_vision_inset(jpeg),
            },
            Err(e) => span.in_scope(|| tracing::warn!("ignored an inset image ({inset:?}): {e}")),
        });
    }
}

fn inset_base64(message: Image, quality: u8) -> Result<String, String> {
    let image = rgb_image_from_message(message)?;
    let jpeg = rover_imaging::encode_jpeg(&image, quality).map_err(|e| e.to_string())?;
    Ok(base64::engine::general_purpose::STANDARD.encode(jpeg))
}

/// Runs the bridge node until shutdown: the Socket.IO server from the start, and the managed
/// node whose core publishes its frames and takes its commands. Until the node is active the
/// lock-step core answers every frame with the brake.
pub async fn run(runtime: &Runtime) -> anyhow::Result<()> {
    let initial: BridgeParams = runtime.params(BridgeNode::NAME)?;
    let (frames, mut queued) = mpsc::channel(FRAME_QUEUE_LENGTH);
    let link = Arc::new(LockStep::new(initial.lockstep_config(), FrameQueue(frames)));
    link.set_active(false);
    let server_link = link.clone();
    let build: Build<BridgeNode> = Box::new(move |node, params| Ok(BridgeNode::new(link.clone(), node, &params)));
    let shutdown = runtime.shutdown();
    let served = server::serve(server_link, initial.server_config()?, async move { shutdown.wait().await });
    let frames = futures::stream::poll_fn(move |context| queued.poll_recv(context));
    let (served, ran) =
        tokio::join!(served.instrument(tracing::info_span!("bridge")), run_node_with(runtime, build, frames));
    served.and(ran)
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
    fn frames_beyond_the_queue_are_dropped_and_counted_not_queued() {
        let (frames, mut queued) = mpsc::channel(1);
        let params = BridgeParams { image_width: 64, image_height: 32, ..BridgeParams::default() };
        let link = LockStep::new(params.lockstep_config(), FrameQueue(frames));
        let payload = crate::lockstep::tests::payload(false);
        link.receive(Some(&payload));
        link.receive(Some(&payload));
        assert_eq!(link.stats().problem_count("frame_not_published"), 1);
        assert!(queued.try_recv().is_ok(), "the first frame waits for the core");
        assert!(queued.try_recv().is_err(), "the second was dropped");
    }

    #[test]
    fn no_reply_deadline_outlasts_the_silence_limit() {
        let (_, longest_deadline_ms) = spec("reply_deadline_ms").range.unwrap();
        let (shortest_silence_ms, _) = spec("silence_limit_ms").range.unwrap();
        assert!(longest_deadline_ms <= shortest_silence_ms);
    }
}
