//! The pickup node (`rover pickup`): telemetry in, pickup requests out.

use rover_msgs::frame_ids;
use rover_msgs::msg::{PickupRequest, Telemetry};
use rover_msgs::std_msgs::Header;
use rover_runtime::node_core::{FromParams, Inputs, NodeCore, Outbox};
use rover_runtime::{Rejections, topics};

use crate::{Pickup, PickupParams, checked_arm_input};

/// The pickup node: one request each time a sample comes within reach of a stopped rover.
pub struct PickupNode {
    /// The arm's state: requests made, samples collected.
    pickup: Pickup,
    params: PickupParams,
    /// Telemetry refused as invalid.
    rejections: Rejections,
}

impl NodeCore for PickupNode {
    type Params = PickupParams;
    const NAME: &'static str = "pickup";

    fn inputs() -> Inputs<Self> {
        Inputs::new().on(&topics::TELEMETRY, Self::on_telemetry)
    }

    fn set_params(&mut self, params: PickupParams) {
        self.params = params;
    }

    fn stop(&mut self, _out: &mut Outbox) {
        tracing::info!(
            "pickup: {} requests, {} samples collected, rejected {}",
            self.pickup.requests,
            self.pickup.collected(),
            self.rejections
        );
    }
}

impl FromParams for PickupNode {
    fn new(params: PickupParams) -> anyhow::Result<Self> {
        Ok(PickupNode { pickup: Pickup::default(), params, rejections: Rejections::default() })
    }
}

impl PickupNode {
    fn on_telemetry(&mut self, telemetry: &Telemetry, out: &mut Outbox) {
        let Some(input) = checked_arm_input(telemetry, &mut self.rejections) else { return };
        if self.pickup.on_telemetry(&input, &self.params) {
            tracing::info!(frame = telemetry.frame, "sample within reach and rover stopped: requesting a pickup");
            let header = Header { frame_id: frame_ids::BASE_LINK.to_string(), ..telemetry.header.clone() };
            out.publish(&topics::PICKUP, PickupRequest { header, frame: telemetry.frame });
        }
    }
}
