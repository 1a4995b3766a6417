//! The pickup node (`rover pickup`): telemetry in, pickup requests out.

use futures::StreamExt;
use rover_msgs::frame_ids;
use rover_msgs::msg::PickupRequest;
use rover_msgs::std_msgs::Header;
use rover_runtime::{Rejections, Runtime, publish_or_warn, topics};
use tracing::Instrument as _;

use crate::{Pickup, PickupParams, checked_arm_input};

/// Runs the pickup node until shutdown.
pub async fn run(runtime: &Runtime) -> anyhow::Result<()> {
    let (mut node, params) = runtime.node::<PickupParams>("pickup")?;
    let span = node.span();
    let requests = node.publisher(&topics::PICKUP)?;
    let mut telemetry = std::pin::pin!(node.messages(&topics::TELEMETRY)?);
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
                    if let Some(input) = checked_arm_input(&t, &mut rejections) && pickup.on_telemetry(&input, &settings) {
                        tracing::info!(frame = t.frame, "sample within reach and rover stopped: requesting a pickup");
                        let request = PickupRequest { header: Header { frame_id: frame_ids::BASE_LINK.to_string(), ..t.header }, frame: t.frame };
                        publish_or_warn(&requests, &topics::PICKUP, request);
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
