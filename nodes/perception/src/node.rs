//! The perception node (`rover perception`): camera JPEGs and telemetry in, terrain scans and the
//! classified bird's-eye view out.

use futures::StreamExt;
use rover_imaging::message::rgb8_message;
use rover_msgs::builtin_interfaces::Time;
use rover_msgs::msg::{Telemetry, TerrainScan};
use rover_msgs::sensor_msgs::{CompressedImage, Image};
use rover_msgs::std_msgs::Header;
use rover_runtime::pairing::Pairer;
use rover_runtime::{Publisher, Rejections, Runtime, publish_or_warn, topics};

use crate::Perception;
use crate::params::PerceptionParams;
use crate::scan::{ScanGeometry, vision_image};

/// How many unmatched camera frames or telemetry messages are kept while waiting for a partner.
const PAIRING_BACKLOG: usize = 16;

/// Runs the perception node until shutdown.
pub async fn run(runtime: &Runtime) -> anyhow::Result<()> {
    let (mut node, params) = runtime.node::<PerceptionParams>("perception")?;
    let span = node.span();
    let settings = params.get();
    let (perception, geometry) = settings.pipeline()?;
    let mut worker = Worker {
        perception,
        geometry,
        terrain: node.publisher(&topics::TERRAIN)?,
        vision: node.publisher(&topics::VISION)?,
        settings,
        frames: 0,
        rejections: Rejections::default(),
    };
    let mut telemetry = std::pin::pin!(node.messages(&topics::TELEMETRY)?);
    let mut camera = std::pin::pin!(node.messages(&topics::CAMERA_COMPRESSED)?);
    let mut pairs: Pairer<Time, CompressedImage, Telemetry> = Pairer::new(PAIRING_BACKLOG);
    let shutdown = runtime.shutdown();
    loop {
        let pair = tokio::select! {
            () = shutdown.wait() => break,
            Some(image) = camera.next() => pairs.push_first(image.header.stamp.clone(), image),
            Some(pose) = telemetry.next() => pairs.push_second(pose.header.stamp.clone(), pose),
            else => break,
        };
        if let Some((image, pose)) = pair {
            let _entered = span.enter();
            worker.handle(image.header, &image.data, pose);
        }
    }
    tracing::info!(parent: &span, "perception: {} frames, rejected {}, {} unpaired", worker.frames, worker.rejections, pairs.dropped());
    Ok(())
}

struct Worker {
    perception: Perception,
    geometry: ScanGeometry,
    terrain: Publisher<TerrainScan>,
    vision: Publisher<Image>,
    settings: PerceptionParams,
    frames: u64,
    rejections: Rejections,
}

impl Worker {
    fn handle(&mut self, header: Header, jpeg: &[u8], pose: Telemetry) {
        if !self.rejections.accept(topics::TELEMETRY.name, &pose) {
            return;
        }
        if let Err(e) = self.perception.process_jpeg(jpeg) {
            let problem = format_args!("rejected the camera image of frame {}: {e}", pose.frame);
            self.rejections.reject(topics::CAMERA_COMPRESSED.name, &problem);
            return;
        }
        self.frames += 1;
        let scan = self.geometry.terrain_scan(self.perception.classes(), &pose, header.clone());
        publish_or_warn(&self.terrain, &topics::TERRAIN, scan);
        let every = self.settings.vision_every_frames as u64;
        if every > 0 && self.frames.is_multiple_of(every) {
            let image = vision_image(self.perception.table(), self.perception.classes());
            let message = rgb8_message(image, header);
            publish_or_warn(&self.vision, &topics::VISION, message);
        }
    }
}
