//! The pickup node (`rover pickup`): telemetry in, pickup requests out.

use futures::StreamExt;
use rover_msgs::msg::{PickupRequest, Telemetry};
use rover_msgs::std_msgs::Header;
use rover_node::{Rejections, Runtime, messages, topics};
use tracing::Instrument as _;

use crate::{ArmInput, Pickup, PickupParams};

/// Runs the pickup node until shutdown.
pub async fn run(runtime: &Runtime) -> anyhow::Result<()> {
    let (mut node, params) = runtime.node::<PickupParams>("pickup")?;
    let span = node.span();
    let requests = node.publisher(&topics::PICKUP)?;
    let telemetry_subscription = node.subscription(&topics::TELEMETRY)?;
    let mut telemetry = std::pin::pin!(messages(&telemetry_subscription));
    let mut changes = params.watch();
    let mut settings = params.get();
    let mut pickup = Pickup::default();
    let mut rejections = Rejections::default();
    let shutdown = runtime.shutdown();
    async {
        loop {
            tokio::select! {
                () = shutdown.wait() => break,
                Some(t) = telemetry.next() => {
                    if rejections.accept(topics::TELEMETRY.name, &t) && pickup.on_telemetry(&arm_input(&t), &settings) {
                        tracing::info!(frame = t.frame, "sample within reach and rover stopped: requesting a pickup");
                        let request = PickupRequest { header: Header { frame_id: "base_link".to_string(), ..t.header }, frame: t.frame };
                        if let Err(e) = requests.publish(request) {
                            tracing::warn!("cannot publish rover/pickup: {e:?}");
                        }
                    }
                }
                Ok(()) = changes.changed() => settings = changes.borrow_and_update().clone(),
            }
        }
        tracing::info!(
            "pickup: {} requests, {} samples collected, rejected {rejections}",
            pickup.requests,
            pickup.collected()
        );
    }
    .instrument(span)
    .await;
    Ok(())
}

fn arm_input(telemetry: &Telemetry) -> ArmInput {
    ArmInput {
        frame: telemetry.frame,
        speed_mps: telemetry.speed_mps as f64,
        near_sample: telemetry.near_sample,
        picking_up: telemetry.picking_up,
        samples_remaining: telemetry.samples_remaining,
    }
}
