//! The bridge against a fake Unity client that speaks the simulator's dialect byte for byte
//! (`rover_sim::wire`), with real recorded frames, real DDS and the bridge in its own process.

mod support;

use std::collections::HashSet;
use std::time::{Duration, Instant};

use ros2_client::dds::rustdds::DomainParticipant;
use ros2_client::parameters::{Parameter, ParameterValue};
use ros2_client::rcl_interfaces::{SetParametersRequest, SetParametersResponse};
use ros2_client::{Client, Context, Name, NodeName, NodeOptions, ServiceMapping, ServiceTypeName};
use rover_msgs::geometry_msgs::{Twist, Vector3};
use rover_runtime::Publisher;
use rover_sim::wire::client::{Connection, unity_url};
use rover_sim::wire::packet::Inbound;
use support::echo_sim::{EchoCheckingSimulator, SeenReply, recorded_frames, run_fake_unity, telemetry_json};
use support::{
    Domain, Latest, Process, STOP_TIMEOUT, diagnostic_value, echo_node, eventually, rover, start_bridge, start_process,
    test_runtime, wait_for_port,
};
use tokio_tungstenite::tungstenite::Message;

#[tokio::test(flavor = "multi_thread")]
async fn a_thousand_frames_each_get_exactly_one_reply_with_the_command_for_that_frame() {
    support::assert_isolated();
    let domain = Domain::reserve();
    let _bridge = start_bridge(&domain, &[]);
    let _echo = start_process(&echo_node(), &[], &domain, "echo");
    let mut simulation = EchoCheckingSimulator::new(1000);
    let stats = run_fake_unity(&mut simulation, domain.port()).await;

    assert_eq!(stats.connections, 1);
    assert_eq!(stats.commands_dropped, 0, "every reply parsed: all values were JSON strings");
    assert_eq!(simulation.other_events, 0);
    assert_eq!(simulation.replies.len(), 1000);
    assert_eq!(
        stats.telemetry_sent as usize,
        simulation.replies.len() + simulation.outstanding.len(),
        "every telemetry but the ones still in flight got exactly one reply"
    );
    assert!(simulation.outstanding.len() <= 2, "at most the two connect loops are in flight");
    let answered: HashSet<u64> = simulation.fresh_matches.iter().map(|&(k, _)| k).collect();
    assert_eq!(answered.len(), simulation.fresh_matches.len(), "no telemetry was answered twice");
    for &(k, frame) in &simulation.fresh_matches {
        assert_eq!(frame, k as f64, "the reply to telemetry {k} carries the command for frame {k}");
    }
    let order: Vec<u64> = simulation.fresh_matches.iter().map(|&(k, _)| k).collect();
    assert!(order.is_sorted(), "replies come in the order of their telemetry (the simulator applies them so)");
    let first_fresh = simulation.replies.iter().position(|r| r.throttle > 0.0).expect("the echo node answered");
    let misses = simulation.unmatched.iter().filter(|r| r.at > simulation.replies[first_fresh].at).count();
    assert!(misses <= 5, "{misses} replies missed their command after the echo node was discovered");
    assert!(simulation.fresh_matches.len() >= 950, "only {} fresh replies", simulation.fresh_matches.len());
}

#[tokio::test(flavor = "multi_thread")]
async fn without_a_decision_node_replies_keep_their_deadline_and_brake_after_the_silence_limit() {
    support::assert_isolated();
    let domain = Domain::reserve();
    let _bridge = start_bridge(&domain, &["reply_deadline_ms:=50.0", "silence_limit_ms:=600.0"]);
    let echo = std::sync::Arc::new(std::sync::Mutex::new(Some(start_process(&echo_node(), &[], &domain, "echo"))));
    let mut simulation = EchoCheckingSimulator::new(400);
    let killed_at = std::sync::Arc::new(std::sync::Mutex::new(None));
    let (echo_for_kill, killed_for_sim) = (echo.clone(), killed_at.clone());
    let fresh_seen = std::sync::Arc::new(std::sync::atomic::AtomicUsize::new(0));
    simulation.on_reply = Box::new(move |_| {
        let fresh = fresh_seen.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        if fresh == 150
            && let Some(mut process) = echo_for_kill.lock().unwrap().take()
        {
            process.kill();
            *killed_for_sim.lock().unwrap() = Some(Instant::now());
        }
    });
    run_fake_unity(&mut simulation, domain.port()).await;

    let killed_at = killed_at.lock().unwrap().expect("the echo node was killed");
    let after: Vec<&SeenReply> =
        simulation.replies.iter().filter(|r| r.at > killed_at + Duration::from_millis(100)).collect();
    assert!(after.len() > 50, "replies kept coming after the decision node died");
    for reply in &after {
        assert!(reply.latency < Duration::from_millis(50 + 150), "a reply took {:?}", reply.latency);
    }
    let held: Vec<_> = after.iter().filter(|r| r.throttle > 0.0).collect();
    let braking: Vec<_> = after.iter().filter(|r| r.throttle == 0.0 && r.brake == 10.0).collect();
    assert!(!held.is_empty(), "the last command is held for a while");
    assert!(!braking.is_empty(), "then the rover is told to brake");
    let first_brake = braking[0].at - killed_at;
    assert!(
        first_brake >= Duration::from_millis(500) && first_brake <= Duration::from_millis(1500),
        "braking started {first_brake:?} after the decision node died"
    );
    assert!(braking.iter().all(|r| r.at >= braking[0].at), "no command came back after braking started");
    assert!(after.iter().skip_while(|r| r.throttle > 0.0).all(|r| r.throttle == 0.0), "braking lasts");
}

/// A connection that reads the handshake and then exchanges single telemetry frames.
struct RawClient {
    connection: Connection,
}

impl RawClient {
    async fn connect(port: u16) -> RawClient {
        let connection = Connection::open(&unity_url("127.0.0.1", port)).await.expect("connect to the bridge");
        RawClient { connection }
    }

    async fn send_text(&mut self, text: &str) {
        self.connection.send_text(text).await.expect("send");
    }

    /// Waits for the next event; `None` if the connection closed or nothing came within 3 s.
    async fn next_event(&mut self) -> Option<(String, Option<serde_json::Value>)> {
        let deadline = tokio::time::Instant::now() + Duration::from_secs(3);
        loop {
            match tokio::time::timeout_at(deadline, self.connection.receive()).await.ok()?? {
                Inbound::Event { name, data } => return Some((name, data)),
                Inbound::Close => return None,
                _ => continue,
            }
        }
    }

    async fn exchange(&mut self, telemetry_argument: &str) -> Option<(String, Option<serde_json::Value>)> {
        self.send_text(&format!("42[\"telemetry\",{telemetry_argument}]")).await;
        self.next_event().await
    }

    /// Whether the bridge closes the connection within 3 s without sending an event.
    async fn closed_without_an_event(&mut self) -> bool {
        let deadline = tokio::time::Instant::now() + Duration::from_secs(3);
        loop {
            match tokio::time::timeout_at(deadline, self.connection.receive()).await {
                Ok(None | Some(Inbound::Close)) => return true,
                Ok(Some(Inbound::Event { .. })) | Err(_) => return false,
                Ok(Some(_)) => continue,
            }
        }
    }
}

fn valid_telemetry() -> serde_json::Value {
    serde_json::from_str(&telemetry_json(&recorded_frames()[10], 42.0)).unwrap()
}

struct BadInputCase {
    domain: Domain,
    bridge: Process,
    diagnostics: Latest<rover_msgs::diagnostic_msgs::DiagnosticArray>,
    telemetry: Latest<rover_msgs::msg::Telemetry>,
    _runtime: rover_runtime::Runtime,
    node: rover_runtime::RosNode,
}

impl BadInputCase {
    fn start(extra: &[&str]) -> BadInputCase {
        support::assert_isolated();
        let domain = Domain::reserve();
        let bridge = start_bridge(&domain, extra);
        let runtime = test_runtime(&domain);
        let (mut node, _) = runtime.node::<rover_runtime::NoParams>("observer").unwrap();
        let diagnostics = Latest::subscribe(&mut node, &rover_runtime::topics::DIAGNOSTICS);
        let telemetry = Latest::subscribe(&mut node, &rover_runtime::topics::TELEMETRY);
        BadInputCase { domain, bridge, diagnostics, telemetry, _runtime: runtime, node }
    }

    /// Checks the log line, the diagnostics counter, and that a valid frame from `client` (the one
    /// simulator the bridge serves) still gets a reply.
    async fn assert_handled(&self, client: &mut RawClient, log_needle: &str, counter: &str) {
        assert!(
            eventually(Duration::from_secs(5), || self.bridge.log_text().contains(log_needle)),
            "no log line containing {log_needle:?} in:\n{}",
            self.bridge.log_text()
        );
        let count = |s: &Self| diagnostic_value(&s.diagnostics, counter).and_then(|v| v.parse::<u64>().ok());
        assert!(
            eventually(Duration::from_secs(10), || count(self).is_some_and(|c| c >= 1)),
            "/diagnostics has no {counter} >= 1; last: {:?}",
            self.diagnostics.last()
        );
        let reply = client.exchange(&valid_telemetry().to_string()).await;
        assert_eq!(reply.map(|r| r.0).as_deref(), Some("data"), "the loop goes on after the bad input");
    }
}

fn assert_brake(reply: Option<(String, Option<serde_json::Value>)>) {
    let (name, data) = reply.expect("a reply to the bad frame");
    assert_eq!(name, "data");
    let data = data.expect("data has an argument");
    assert_eq!((data["throttle"].as_str(), data["brake"].as_str()), (Some("0"), Some("10")), "{data}");
}

async fn rejected_with_brake(client: &mut RawClient, argument: &str) {
    assert_brake(client.exchange(argument).await);
}

/// One telemetry frame with `argument` gets a brake; then [`BadInputCase::assert_handled`].
async fn rejected_and_handled(case: &BadInputCase, argument: &str, log_needle: &str, counter: &str) {
    let mut client = RawClient::connect(case.domain.port()).await;
    rejected_with_brake(&mut client, argument).await;
    case.assert_handled(&mut client, log_needle, counter).await;
}

fn with_field(field: &str, value: serde_json::Value) -> String {
    let mut telemetry = valid_telemetry();
    telemetry[field] = value;
    telemetry.to_string()
}

#[tokio::test(flavor = "multi_thread")]
async fn invalid_json_is_rejected_with_a_brake() {
    let case = BadInputCase::start(&[]);
    let mut client = RawClient::connect(case.domain.port()).await;
    client.send_text("42[\"telemetry\",{\"speed\":\"1.0\",]").await;
    assert_brake(client.next_event().await);
    case.assert_handled(&mut client, "unparseable Socket.IO packet", "problem_unparseable_packet").await;
}

#[tokio::test(flavor = "multi_thread")]
async fn missing_fields_are_rejected_with_a_brake() {
    let case = BadInputCase::start(&[]);
    let mut telemetry = valid_telemetry();
    telemetry.as_object_mut().unwrap().remove("yaw");
    rejected_and_handled(&case, &telemetry.to_string(), "telemetry field `yaw` is missing", "problem_missing_field")
        .await;
}

#[tokio::test(flavor = "multi_thread")]
async fn non_numeric_and_nan_values_are_rejected_with_a_brake() {
    let case = BadInputCase::start(&[]);
    let mut client = RawClient::connect(case.domain.port()).await;
    rejected_with_brake(&mut client, &with_field("speed", "fast".into())).await;
    rejected_with_brake(&mut client, &with_field("pitch", "nan".into())).await;
    rejected_with_brake(&mut client, &with_field("throttle", serde_json::json!(0.5))).await;
    for (log_needle, counter) in [
        ("telemetry field `speed` = \"fast\" is not a number", "problem_not_a_number"),
        ("telemetry field `pitch` = \"nan\" is not finite", "problem_not_finite"),
        ("telemetry field `throttle` is a number, expected a string", "problem_not_a_string"),
    ] {
        case.assert_handled(&mut client, log_needle, counter).await;
    }
}

#[tokio::test(flavor = "multi_thread")]
async fn comma_decimals_are_read_as_decimals() {
    let case = BadInputCase::start(&[]);
    let mut telemetry = valid_telemetry();
    telemetry["position"] = "12,5000;85,5890".into();
    telemetry["speed"] = "1,2500".into();
    let mut client = RawClient::connect(case.domain.port()).await;
    let deadline = Instant::now() + Duration::from_secs(10);
    let parsed = |t: &rover_msgs::msg::Telemetry| t.x_m == 12.5 && t.y_m == 85.589 && t.speed_mps == 1.25;
    while !case.telemetry.all().iter().any(parsed) && Instant::now() < deadline {
        let (name, _) = client.exchange(&telemetry.to_string()).await.expect("a reply");
        assert_eq!(name, "data");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    assert!(
        case.telemetry.all().iter().any(parsed),
        "rover/telemetry carries x 12.5 and speed 1.25: {:?}",
        case.telemetry.last()
    );
}

#[tokio::test(flavor = "multi_thread")]
async fn corrupt_base64_is_rejected_with_a_brake() {
    let case = BadInputCase::start(&[]);
    let argument = with_field("image", "/9j/4AAQ***not base64***".into());
    rejected_and_handled(&case, &argument, "telemetry field `image` is not valid base64", "problem_bad_base64").await;
}

#[tokio::test(flavor = "multi_thread")]
async fn corrupt_jpeg_is_rejected_with_a_brake() {
    use base64::Engine as _;
    let case = BadInputCase::start(&[]);
    let mut jpeg = recorded_frames()[10].jpeg.clone();
    jpeg.truncate(jpeg.len() / 2);
    let image = base64::engine::general_purpose::STANDARD.encode(&jpeg);
    let argument = with_field("image", image.into());
    rejected_and_handled(&case, &argument, "telemetry field `image`: truncated JPEG", "problem_bad_image").await;
}

#[tokio::test(flavor = "multi_thread")]
async fn a_payload_over_the_size_limit_is_rejected_with_a_brake() {
    let case = BadInputCase::start(&["max_payload_bytes:=65536"]);
    let argument = with_field("image", "A".repeat(100_000).into());
    rejected_and_handled(&case, &argument, "exceeds the limit of 65536 bytes", "problem_too_large").await;
}

#[tokio::test(flavor = "multi_thread")]
async fn a_binary_frame_is_rejected_with_a_brake() {
    let case = BadInputCase::start(&[]);
    let mut client = RawClient::connect(case.domain.port()).await;
    client.connection.send_message(Message::binary(vec![0x04, 0xFF, 0x00, 0x42])).await.expect("send binary");
    assert_brake(client.next_event().await);
    case.assert_handled(&mut client, "binary websocket message of 3 bytes", "problem_binary_message").await;
}

#[tokio::test(flavor = "multi_thread")]
async fn an_abrupt_disconnect_is_followed_by_a_working_reconnect() {
    let case = BadInputCase::start(&[]);
    let mut client = RawClient::connect(case.domain.port()).await;
    client.connection.send_text(&format!("42[\"telemetry\",{}]", valid_telemetry())).await.expect("send");
    drop(client);
    let lost = || case.bridge.log_text().contains("simulator connection lost");
    assert!(eventually(Duration::from_secs(5), lost), "the bridge frees its simulator slot when the connection drops");
    let mut reconnected = RawClient::connect(case.domain.port()).await;
    case.assert_handled(&mut reconnected, "simulator connection lost", "problem_disconnect_transport_error").await;
}

#[tokio::test(flavor = "multi_thread")]
async fn raw_images_insets_params_file_and_clean_shutdown() {
    let params = std::env::temp_dir().join(format!("rover-bridge-params-{}.yaml", std::process::id()));
    std::fs::write(&params, "bridge:\n  ros__parameters:\n    publish_raw_image: true\n    inset_jpeg_quality: 50\n")
        .unwrap();
    support::assert_isolated();
    let domain = Domain::reserve();
    let port = format!("port:={}", domain.port());
    let mut bridge = start_process(
        &rover(),
        &["bridge", "--ros-args", "-p", &port, "--params-file", params.to_str().unwrap()],
        &domain,
        "bridge",
    );
    wait_for_port(domain.port(), Duration::from_secs(20));
    let runtime = test_runtime(&domain);
    let (mut node, _) = runtime.node::<rover_runtime::NoParams>("observer").unwrap();
    let raw = Latest::subscribe(&mut node, &rover_runtime::topics::CAMERA_RAW);
    let map_image = node.publisher(&rover_runtime::topics::MAP_IMAGE).unwrap();
    let inset = rover_msgs::sensor_msgs::Image {
        header: rover_msgs::std_msgs::Header::now("map"),
        height: 20,
        width: 40,
        encoding: "rgb8".into(),
        is_bigendian: 0,
        step: 120,
        data: vec![200; 40 * 20 * 3],
    };
    let mut client = RawClient::connect(domain.port()).await;
    let deadline = Instant::now() + Duration::from_secs(15);
    let mut inset_seen = false;
    while Instant::now() < deadline && !(inset_seen && raw.last().is_some()) {
        map_image.publish(inset.clone()).unwrap();
        let (_, data) = client.exchange(&valid_telemetry().to_string()).await.expect("a reply");
        inset_seen |= data.as_ref().and_then(|d| d["inset_image1"].as_str()).is_some_and(|s| s.starts_with("/9j/"));
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    assert!(inset_seen, "map/image came back as a base64 JPEG in inset_image1");
    tokio::time::sleep(Duration::from_millis(300)).await;
    client.exchange(&valid_telemetry().to_string()).await.expect("a reply");
    let map_inset = |data: Option<serde_json::Value>| data.and_then(|d| d["inset_image1"].as_str().map(str::to_string));
    let (_, data) = client.exchange(&valid_telemetry().to_string()).await.expect("a reply");
    assert_eq!(map_inset(data).as_deref(), Some(""), "an inset the simulator was sent is not sent again");
    drop(client);
    let lost = || bridge.log_text().contains("simulator connection lost");
    assert!(eventually(Duration::from_secs(5), lost), "the bridge frees its simulator slot when the connection drops");
    let mut client = RawClient::connect(domain.port()).await;
    let (_, data) = client.exchange(&valid_telemetry().to_string()).await.expect("a reply");
    assert!(map_inset(data).is_some_and(|s| s.starts_with("/9j/")), "a new connection is sent the inset it lacks");
    let image = raw.last().expect("camera/image_raw was published");
    assert_eq!((image.width, image.height, image.encoding.as_str(), image.step), (320, 160, "rgb8", 960));
    assert_eq!(image.data.len(), 320 * 160 * 3);
    let status = bridge.interrupt(STOP_TIMEOUT).expect("the bridge stops on SIGINT");
    assert!(status.success(), "clean exit on SIGINT: {status}");
    let _ = std::fs::remove_file(params);
}

/// The standard error of a bridge started with `-p parameter`, which must stop it at once (one
/// that runs is interrupted after 20 s).
fn refused_at_start(parameter: &str) -> String {
    support::assert_isolated();
    let output = std::process::Command::new("timeout")
        .args(["--signal=INT", "--kill-after=5", "20"])
        .arg(rover())
        .args(["bridge", "--ros-args", "-p", parameter])
        .output()
        .expect("run rover bridge");
    assert!(!output.status.success(), "the bridge started with -p {parameter}");
    String::from_utf8_lossy(&output.stderr).into_owned()
}

#[test]
fn a_bad_parameter_stops_the_bridge_with_a_message_naming_it() {
    let stderr = refused_at_start("reply_deadline_ms:=soon");
    assert!(
        stderr.contains(
            "parameter `reply_deadline_ms` (from -p reply_deadline_ms:=soon) expects a finite number, got \"soon\""
        ),
        "{stderr}"
    );
}

#[test]
fn an_unsafe_brake_stops_the_bridge_at_start() {
    let stderr = refused_at_start("brake:=0.0");
    assert!(
        stderr.contains("parameter `brake` (from -p brake:=0.0) = 0 is outside the allowed range [1, 100]"),
        "{stderr}"
    );
}

/// A client of the bridge's `set_parameters` service (rcl_interfaces), the one `ros2 param set` calls.
struct ParameterClient {
    _node: ros2_client::Node,
    client: Client<SetParametersRequest, SetParametersResponse>,
}

impl ParameterClient {
    async fn of_bridge(domain: &Domain) -> ParameterClient {
        let participant = DomainParticipant::new(domain.id).expect("a DDS participant");
        let context = Context::from_domain_participant(participant).expect("a ROS context");
        let name = NodeName::new("/", "parameter_client").unwrap();
        let mut node = context.new_node(name, NodeOptions::new()).expect("a node");
        tokio::spawn(node.spinner().expect("a spinner").spin());
        let service = Name::new("/bridge", "set_parameters").unwrap();
        let service_type = ServiceTypeName::new("rcl_interfaces", "SetParameters");
        let qos = rover_runtime::qos::reliable(1);
        let client = node
            .create_client(ServiceMapping::Enhanced, &service, &service_type, qos.clone(), qos)
            .expect("a service client");
        tokio::time::timeout(Duration::from_secs(20), client.wait_for_service(&node))
            .await
            .expect("the bridge's set_parameters service is discovered");
        ParameterClient { _node: node, client }
    }

    /// Sets double parameter `name` to `value`: whether it was taken, and the reason if not.
    async fn set_double(&self, name: &str, value: f64) -> (bool, String) {
        let parameter = Parameter { name: name.to_string(), value: ParameterValue::Double(value) };
        let request = SetParametersRequest { parameter: vec![parameter.into()] };
        for _attempt in 0..5 {
            let call = self.client.async_call_service(request.clone());
            if let Ok(Ok(response)) = tokio::time::timeout(Duration::from_secs(2), call).await {
                let result = response.results.into_iter().next().expect("one result per parameter");
                return (result.successful, result.reason);
            }
        }
        panic!("no answer from /bridge/set_parameters to {name} := {value}");
    }
}

#[tokio::test(flavor = "multi_thread")]
async fn the_parameter_service_refuses_unsafe_values_and_parameters_read_at_start_with_a_reason() {
    support::assert_isolated();
    let domain = Domain::reserve();
    let _bridge = start_bridge(&domain, &[]);
    let parameters = ParameterClient::of_bridge(&domain).await;
    for (name, value, range) in [
        ("brake", 0.0, "[1, 100]"),
        ("silence_limit_ms", 600000.0, "[250, 2000]"),
        ("reply_deadline_ms", 1000.0, "[0, 250]"),
        ("teleop_timeout_ms", 10000.0, "[0, 2000]"),
    ] {
        let (taken, reason) = parameters.set_double(name, value).await;
        assert!(!taken, "{name} := {value} was taken");
        assert!(reason.contains(&format!("is outside the allowed range {range}")), "{name} := {value}: {reason:?}");
    }
    let (taken, reason) = parameters.set_double("frame_period_s", 0.05).await;
    assert!(!taken, "frame_period_s, read when the bridge starts, was taken");
    assert!(reason.contains("frame_period_s is read when the node starts"), "{reason:?}");
    let (taken, reason) = parameters.set_double("brake", 20.0).await;
    assert!(taken, "a safe brake is taken: {reason:?}");
}

fn twist_forward(linear_mps: f64) -> Twist {
    Twist { linear: Vector3 { x: linear_mps, ..Vector3::default() }, ..Twist::default() }
}

/// Publishes `twist` on cmd_vel and exchanges a telemetry frame, every 50 ms for up to 10 s, until
/// a reply's `data` satisfies `wanted`; that reply's data.
async fn reply_under_teleop(
    client: &mut RawClient,
    cmd_vel: &Publisher<Twist>,
    twist: Twist,
    wanted: impl Fn(&serde_json::Value) -> bool,
) -> Option<serde_json::Value> {
    let deadline = Instant::now() + Duration::from_secs(10);
    while Instant::now() < deadline {
        cmd_vel.publish(twist.clone()).expect("publish cmd_vel");
        if let Some((_, Some(data))) = client.exchange(&valid_telemetry().to_string()).await
            && wanted(&data)
        {
            return Some(data);
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    None
}

#[tokio::test(flavor = "multi_thread")]
async fn a_nan_cmd_vel_brakes_the_rover_instead_of_releasing_the_brake() {
    let mut case = BadInputCase::start(&[]);
    let cmd_vel = case.node.publisher(&rover_runtime::topics::CMD_VEL).unwrap();
    let mut client = RawClient::connect(case.domain.port()).await;
    let throttle = |data: &serde_json::Value| data["throttle"].as_str().and_then(|t| t.parse::<f64>().ok());
    let driving = reply_under_teleop(&mut client, &cmd_vel, twist_forward(1.0), |d| throttle(d) > Some(0.0)).await;
    assert!(driving.is_some(), "cmd_vel drives the rover (no decision node runs, so only teleop gives throttle)");
    let nan = reply_under_teleop(&mut client, &cmd_vel, twist_forward(f64::NAN), |d| throttle(d) == Some(0.0)).await;
    let nan = nan.expect("a NaN cmd_vel takes over from the forward one");
    assert_eq!(nan["brake"].as_str(), Some("10"), "a NaN cmd_vel brakes: {nan}");
    case.assert_handled(&mut client, "cmd_vel field `linear.x` = NaN", "problem_bad_teleop").await;
}

/// A telemetry argument no recorded frame has: its speed marks the frames of one client.
fn marked_telemetry(speed: &str) -> String {
    with_field("speed", speed.into())
}

fn speed_seen(case: &BadInputCase, speed_mps: f32) -> bool {
    case.telemetry.all().iter().any(|t| t.speed_mps == speed_mps)
}

/// Sends `client`'s frames marked `speed` (each answered) every 50 ms, for up to 10 s, until the
/// observer has seen one on rover/telemetry (the first frames may go out before the bridge's
/// writer knows the observer's reader); whether it was seen.
async fn exchange_until_seen(case: &BadInputCase, client: &mut RawClient, speed: &str, speed_mps: f32) -> bool {
    let deadline = Instant::now() + Duration::from_secs(10);
    while Instant::now() < deadline {
        let reply = client.exchange(&marked_telemetry(speed)).await;
        assert_eq!(reply.map(|r| r.0).as_deref(), Some("data"), "the simulator is served");
        if speed_seen(case, speed_mps) {
            return true;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    false
}

#[tokio::test(flavor = "multi_thread")]
async fn a_second_simulator_is_refused_while_the_first_keeps_being_served() {
    let case = BadInputCase::start(&[]);
    let mut first = RawClient::connect(case.domain.port()).await;
    assert!(
        exchange_until_seen(&case, &mut first, "1,1100", 1.11).await,
        "the first simulator's frames reach the topics"
    );
    let mut second = RawClient::connect(case.domain.port()).await;
    let _ = second.connection.send_text(&format!("42[\"telemetry\",{}]", marked_telemetry("2,2200"))).await;
    assert!(second.closed_without_an_event().await, "the second simulator is disconnected without a reply");
    assert!(
        exchange_until_seen(&case, &mut first, "3,3300", 3.33).await,
        "the first simulator is still served and its frames reach the topics"
    );
    assert!(!speed_seen(&case, 2.22), "a frame of the refused simulator reached rover/telemetry");
    case.assert_handled(&mut first, "refused a second simulator connection", "problem_simulator_refused").await;
}

#[tokio::test(flavor = "multi_thread")]
async fn with_replacement_a_new_simulator_takes_over_from_the_first() {
    let case = BadInputCase::start(&["replace_connected_simulator:=true"]);
    let mut first = RawClient::connect(case.domain.port()).await;
    assert_eq!(first.exchange(&valid_telemetry().to_string()).await.map(|r| r.0).as_deref(), Some("data"));
    let mut second = RawClient::connect(case.domain.port()).await;
    assert!(first.closed_without_an_event().await, "the replaced simulator is disconnected");
    case.assert_handled(&mut second, "a new simulator connection replaces simulator", "problem_disconnect_replaced")
        .await;
}
