//! The perception node (`rover perception`): camera JPEGs and telemetry in, terrain scans and the
//! classified bird's-eye view out.

use rover_imaging::message::rgb8_message;
use rover_msgs::builtin_interfaces::Time;
use rover_msgs::msg::Telemetry;
use rover_msgs::sensor_msgs::CompressedImage;
use rover_runtime::node_core::{FromParams, Inputs, NodeCore, Outbox};
use rover_runtime::pairing::Pairer;
use rover_runtime::{Rejections, topics};

use crate::Perception;
use crate::params::PerceptionParams;
use crate::scan::{ScanGeometry, vision_image};

/// How many unmatched camera frames or telemetry messages are kept while waiting for a partner.
const PAIRING_BACKLOG: usize = 16;

/// The perception node: each camera frame, with the telemetry of the same stamp, classified and
/// projected into a terrain scan.
pub struct PerceptionNode {
    /// The classifier of camera images.
    perception: Perception,
    /// Where each classified pixel lies around the rover.
    geometry: ScanGeometry,
    settings: PerceptionParams,
    /// Camera frames and telemetry waiting for their partner of the same stamp.
    pairs: Pairer<Time, CompressedImage, Telemetry>,
    /// Frames classified so far.
    frames: u64,
    /// Inputs refused as invalid.
    rejections: Rejections,
}

impl NodeCore for PerceptionNode {
    type Params = PerceptionParams;
    const NAME: &'static str = "perception";

    fn inputs() -> Inputs<Self> {
        Inputs::new().on(&topics::CAMERA_COMPRESSED, Self::on_camera).on(&topics::TELEMETRY, Self::on_telemetry)
    }

    /// Every parameter of perception is read at start: a new value takes effect when the node
    /// starts again.
    fn set_params(&mut self, _params: PerceptionParams) {}

    fn stop(&mut self, _out: &mut Outbox) {
        tracing::info!(
            "perception: {} frames, rejected {}, {} unpaired",
            self.frames,
            self.rejections,
            self.pairs.dropped()
        );
    }
}

impl FromParams for PerceptionNode {
    fn new(settings: PerceptionParams) -> anyhow::Result<Self> {
        let (perception, geometry) = settings.pipeline()?;
        Ok(PerceptionNode {
            perception,
            geometry,
            settings,
            pairs: Pairer::new(PAIRING_BACKLOG),
            frames: 0,
            rejections: Rejections::default(),
        })
    }
}

impl PerceptionNode {
    fn on_camera(&mut self, image: &CompressedImage, out: &mut Outbox) {
        if let Some((image, pose)) = self.pairs.push_first(image.header.stamp.clone(), image.clone()) {
            self.handle(&image, pose, out);
        }
    }

    fn on_telemetry(&mut self, pose: &Telemetry, out: &mut Outbox) {
        if let Some((image, pose)) = self.pairs.push_second(pose.header.stamp.clone(), pose.clone()) {
            self.handle(&image, pose, out);
        }
    }

    fn handle(&mut self, image: &CompressedImage, pose: Telemetry, out: &mut Outbox) {
        if !self.rejections.accept(topics::TELEMETRY.name, &pose) {
            return;
        }
        if let Err(e) = self.perception.process_jpeg(&image.data) {
            let problem = format_args!("rejected the camera image of frame {}: {e}", pose.frame);
            self.rejections.reject(topics::CAMERA_COMPRESSED.name, &problem);
            return;
        }
        self.frames += 1;
        let scan = self.geometry.terrain_scan(self.perception.classes(), &pose, image.header.clone());
        out.publish(&topics::TERRAIN, scan);
        let every = self.settings.vision_every_frames as u64;
        if every > 0 && self.frames.is_multiple_of(every) && out.wanted(&topics::VISION) {
            let view = vision_image(self.perception.table(), self.perception.classes());
            out.publish(&topics::VISION, rgb8_message(view, image.header.clone()));
        }
    }
}
