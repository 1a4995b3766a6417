//! The Foxglove live view: `rover demo --foxglove` serves the Foxglove WebSocket protocol; a client
//! speaking it (subprotocol `foxglove.sdk.v1`) finds the map and plan channels among the
//! advertised ones, subscribes, and decodes their messages as the graph's `nav_msgs/OccupancyGrid`
//! and `nav_msgs/Path` until the map shows mapped ground and the plan has poses.

mod support;

use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use futures::{SinkExt, StreamExt};
use rover_msgs::RosMessage;
use rover_msgs::nav_msgs::{OccupancyGrid, Path};
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use tokio_tungstenite::tungstenite::http::HeaderValue;

/// The subprotocol of Foxglove's WebSocket protocol (the SDK's name for version 1: inline schemas).
const SUBPROTOCOL: &str = "foxglove.sdk.v1";
/// Opcode of a binary message carrying a subscribed channel's message.
const MESSAGE_DATA: u8 = 0x01;
/// The ids this client gives its subscriptions of the map and of the decision's plan.
const MAP_SUBSCRIPTION: u32 = 7;
const PLAN_SUBSCRIPTION: u32 = 8;

struct Demo(Child);

impl Drop for Demo {
    fn drop(&mut self) {
        rover::processes::graph::send_signal(self.0.id(), nix::sys::signal::Signal::SIGINT);
        let stopped = support::eventually(Duration::from_secs(15), || self.0.try_wait().ok().flatten().is_some());
        if !stopped {
            let _ = self.0.kill();
        }
    }
}

/// The id of the advertised channel of `topic` and its schema name, once advertised.
fn advertised(text: &str, topic: &str) -> Option<(u64, String)> {
    let message: serde_json::Value = serde_json::from_str(text).ok()?;
    (message["op"] == "advertise").then_some(())?;
    let channel = message["channels"].as_array()?.iter().find(|c| c["topic"] == topic)?;
    Some((channel["id"].as_u64()?, channel["schemaName"].as_str()?.to_string()))
}

#[tokio::test(flavor = "multi_thread")]
async fn a_foxglove_client_subscribes_to_the_map_and_the_plan_and_decodes_them() {
    support::assert_isolated();
    let domain = support::Domain::reserve();
    let port = domain.port();
    let out = std::env::temp_dir().join(format!("rover-live-view-{}", std::process::id()));
    let demo = Command::new(support::rover())
        .args(["demo", "--foxglove", "--foxglove-port", &port.to_string(), "--max-sim-seconds", "600"])
        .arg("--out")
        .arg(&out)
        .env("ROS_DOMAIN_ID", domain.id.to_string())
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("start rover demo --foxglove");
    let _demo = Demo(demo);
    support::wait_for_port(port, Duration::from_secs(60));
    let mut request = format!("ws://127.0.0.1:{port}").into_client_request().expect("request");
    request.headers_mut().insert("Sec-WebSocket-Protocol", HeaderValue::from_static(SUBPROTOCOL));
    let (mut socket, response) = tokio_tungstenite::connect_async(request).await.expect("connect to the live view");
    assert_eq!(response.headers().get("Sec-WebSocket-Protocol").and_then(|v| v.to_str().ok()), Some(SUBPROTOCOL));

    let deadline = Instant::now() + Duration::from_secs(90);
    let (mut subscribed, mut grid, mut plan) = (Vec::new(), None::<OccupancyGrid>, None::<Path>);
    while grid.is_none() || plan.is_none() {
        assert!(Instant::now() < deadline, "no map and plan within 90 s (subscribed: {subscribed:?})");
        let next = tokio::time::timeout(Duration::from_secs(30), socket.next()).await;
        let message = next.expect("a message within 30 s").expect("the stream goes on").expect("a message");
        match message {
            Message::Text(text) => {
                for (subscription, topic, type_name) in [
                    (MAP_SUBSCRIPTION, "/map", OccupancyGrid::type_name()),
                    (PLAN_SUBSCRIPTION, "/rover/plan", Path::type_name()),
                ] {
                    if let Some((channel, schema)) = advertised(&text, topic) {
                        assert_eq!(schema, type_name, "{topic}");
                        let subscribe = serde_json::json!({"op": "subscribe", "subscriptions": [{"id": subscription, "channelId": channel}]});
                        socket.send(Message::text(subscribe.to_string())).await.expect("subscribe");
                        subscribed.push(topic);
                    }
                }
            }
            Message::Binary(data) if data.first() == Some(&MESSAGE_DATA) => {
                let (subscription, payload) = (u32::from_le_bytes(data[1..5].try_into().unwrap()), &data[13..]);
                if subscription == MAP_SUBSCRIPTION {
                    let map = rover_runtime::cdr::decode::<OccupancyGrid>(payload).expect("a CDR OccupancyGrid");
                    assert_eq!((map.info.width, map.info.height), (200, 200));
                    grid = grid.or(map.data.contains(&0).then_some(map));
                } else {
                    assert_eq!(subscription, PLAN_SUBSCRIPTION, "one of our subscriptions' ids");
                    let path = rover_runtime::cdr::decode::<Path>(payload).expect("a CDR Path");
                    plan = plan.or((!path.poses.is_empty()).then_some(path));
                }
            }
            _ => {}
        }
    }
    let (grid, plan) = (grid.unwrap(), plan.unwrap());
    assert_eq!(grid.data.len(), 200 * 200, "a whole map, with free cells mapped");
    assert_eq!(plan.header.frame_id, "map");
    let step_m = plan.poses.windows(2).map(|pair| {
        let (a, b) = (&pair[0].pose.position, &pair[1].pose.position);
        (a.x - b.x).hypot(a.y - b.y)
    });
    assert!(step_m.fold(0.0, f64::max) < 1.5, "a plan goes from cell to neighbouring cell");
    let _ = std::fs::remove_dir_all(&out);
}
