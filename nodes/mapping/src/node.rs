//! The mapping node (`rover mapping`): terrain scans in; the map, its image, statistics and the
//! located rocks out: [`MappingCore`] with its publications and its snapshot file.

use std::time::{Duration, Instant};

use rover_imaging::message::rgb8_message;
use rover_msgs::frame_ids;
use rover_msgs::geometry_msgs::{Point, Pose as PoseMsg, PoseArray, Quaternion};
use rover_msgs::map_grid::SIDE_CELLS;
use rover_msgs::msg::TerrainScan;
use rover_msgs::nav_msgs::{MapMetaData, OccupancyGrid};
use rover_msgs::std_msgs::Header;
use rover_runtime::node_core::{FromParams, Inputs, NodeCore, Outbox};
use rover_runtime::snapshot::SnapshotFile;
use rover_runtime::topics;

use crate::image::{InsetStats, map_inset};
use crate::mapper::{MapPublication, MappingCore};
use crate::markers::sample_markers;
use crate::params::MappingParams;
use crate::score::ground_truth_from_png;
use crate::snapshot;

/// The ground truth that `params` name, if any.
fn ground_truth(params: &MappingParams) -> anyhow::Result<Option<Vec<bool>>> {
    if params.ground_truth_png.is_empty() {
        return Ok(None);
    }
    let path = std::path::Path::new(&params.ground_truth_png);
    let png = rover_files::read_at_most(path, rover_imaging::MAX_IMAGE_FILE_BYTES)
        .map_err(|e| anyhow::anyhow!("parameter ground_truth_png = {:?}: {e}", params.ground_truth_png))?;
    let truth = ground_truth_from_png(&png).map_err(|e| anyhow::anyhow!("parameter ground_truth_png: {e}"))?;
    Ok(Some(truth))
}

/// The node's snapshot file and what the last snapshot held: frames mapped, samples collected,
/// whether home was known.
struct Snapshots {
    file: SnapshotFile,
    written: (u64, u32, bool),
}

impl Snapshots {
    fn new(state_dir: &str) -> Self {
        Snapshots { file: SnapshotFile::new(state_dir, snapshot::FILE_NAME), written: (0, 0, false) }
    }

    /// Carries `mapping` on from the snapshot, if there is one.
    fn restore(&mut self, mapping: &mut MappingCore) {
        if let Some(memory) = self.file.load(snapshot::decode) {
            mapping.restore(memory);
            let (navigable, obstacle) = mapping.map().cell_counts();
            tracing::info!(
                "restored the map from {}: {navigable} navigable and {obstacle} obstacle cells, home {:?}, {} samples collected",
                self.file.path().map_or_else(String::new, |p| p.display().to_string()),
                mapping.home().map(|h| (h.x_m, h.y_m)),
                mapping.samples_collected()
            );
        }
        self.written = Self::held(mapping);
    }

    fn held(mapping: &MappingCore) -> (u64, u32, bool) {
        (mapping.frames_mapped(), mapping.samples_collected(), mapping.home().is_some())
    }

    /// Writes the snapshot if the map changed and `every` has passed since the last one.
    fn write_if_due(&mut self, mapping: &MappingCore, every: Duration) {
        if self.file.due(every) {
            self.write(mapping);
        }
    }

    /// Writes the snapshot now if the collected count or home changed since the last one (see
    /// [`MappingNode::publish`]).
    fn write_if_mission_changed(&mut self, mapping: &MappingCore) {
        let ((_, collected, home_known), (_, written_collected, written_home_known)) =
            (Self::held(mapping), self.written);
        if (collected, home_known) != (written_collected, written_home_known) {
            self.write(mapping);
        }
    }

    /// Writes the snapshot if the map changed since the last one.
    fn write(&mut self, mapping: &MappingCore) {
        let now = Self::held(mapping);
        if now != self.written {
            self.file.save(&snapshot::encode(&mapping.memory()));
            self.written = now;
        }
    }
}

/// What the node publishes of the samples: the located rocks and where samples were collected,
/// world metres.
#[derive(Debug, Clone, PartialEq)]
struct SampleView {
    rocks: Vec<(f64, f64)>,
    collected_at: Vec<(f64, f64)>,
}

/// The mapping node: every terrain scan into the world map; the map, its image, statistics and
/// the located rocks published every few scans, and at the latest `publish_max_delay_ms` after a
/// scan.
pub struct MappingNode {
    mapping: MappingCore,
    snapshots: Snapshots,
    /// The rocks and the places of the collected samples last published; `None` until the first
    /// publication, so that the latched topics say "none yet" from the start.
    last_samples: Option<SampleView>,
    published_at: Instant,
    /// When the node started (the map image shows the time since).
    started: Instant,
}

impl NodeCore for MappingNode {
    type Params = MappingParams;
    const NAME: &'static str = "mapping";
    const DRAINS_ON_STOP: bool = true;

    fn inputs() -> Inputs<Self> {
        Inputs::new()
            .on(&topics::TERRAIN, Self::on_scan)
            .on(&topics::SAMPLE_TRUTH, |node, samples, _| node.mapping.set_samples_truth(samples))
    }

    fn start(&mut self, out: &mut Outbox) {
        self.publish(out.header(frame_ids::MAP), out);
    }

    fn set_params(&mut self, params: MappingParams) {
        self.mapping.set_params(params);
    }

    fn timer_due(&self) -> Option<Instant> {
        let delay = Duration::from_secs_f64(self.mapping.params().publish_max_delay_ms / 1000.0);
        self.mapping.has_unpublished_scans().then_some(self.published_at + delay)
    }

    fn on_timer(&mut self, out: &mut Outbox) {
        self.publish(out.header(frame_ids::MAP), out);
    }

    fn stop(&mut self, out: &mut Outbox) {
        self.snapshots.write(&self.mapping);
        self.publish(out.header(frame_ids::MAP), out);
        tracing::info!(
            "mapping: {} frames mapped, {} skipped while tilted, rejected {}",
            self.mapping.frames_mapped(),
            self.mapping.tilted_frames(),
            self.mapping.rejections()
        );
    }
}

impl FromParams for MappingNode {
    fn new(settings: MappingParams) -> anyhow::Result<Self> {
        let truth = ground_truth(&settings)?;
        let mut mapping = MappingCore::new(settings, truth);
        let mut snapshots = Snapshots::new(&mapping.params().state_dir);
        snapshots.restore(&mut mapping);
        Ok(MappingNode {
            mapping,
            snapshots,
            last_samples: None,
            published_at: Instant::now(),
            started: Instant::now(),
        })
    }
}

impl MappingNode {
    fn on_scan(&mut self, scan: &TerrainScan, out: &mut Outbox) {
        self.mapping.add_scan(scan, &out.now());
        if self.mapping.publication_due() {
            // Stamped as the scan, so that the decision node knows which frame the map includes.
            self.publish(Header::at(frame_ids::MAP, scan.header.stamp.clone()), out);
            let every = Duration::from_secs_f64(self.mapping.params().snapshot_every_ms / 1000.0);
            self.snapshots.write_if_due(&self.mapping, every);
        }
    }

    /// Publishes the map, its image, statistics and rocks, stamped with `header`. A new collected
    /// count or home goes into the snapshot first: a count goes out on `rover/map_stats` only once
    /// it is on disk, so a node started again after a kill never publishes a smaller one.
    fn publish(&mut self, header: Header, out: &mut Outbox) {
        let mapping = &mut self.mapping;
        self.snapshots.write_if_mission_changed(mapping);
        mapping.mark_published();
        self.published_at = Instant::now();
        let MapPublication { occupancy, stats, rocks, collected_at } = mapping.publication(header.clone());
        if out.wanted(&topics::MAP_IMAGE) {
            let inset = InsetStats {
                time_s: self.started.elapsed().as_secs_f64(),
                mapped_pct: stats.mapped_pct.is_finite().then_some(stats.mapped_pct as f64),
                fidelity_pct: stats.fidelity_pct.is_finite().then_some(stats.fidelity_pct as f64),
                rocks_located: stats.rocks_located as usize,
                collected: mapping.samples_collected() as usize,
            };
            let image = map_inset(&occupancy, mapping.ground_truth(), &rocks, &inset);
            out.publish(&topics::MAP_IMAGE, rgb8_message(image, header.clone()));
        }
        out.publish(&topics::MAP, occupancy_grid(occupancy, header.clone()));
        out.publish(&topics::MAP_STATS, stats);
        let samples = SampleView { rocks, collected_at };
        let last = self.last_samples.replace(samples.clone());
        if last.as_ref().map(|l| &l.rocks) != Some(&samples.rocks) {
            out.publish(&topics::ROCKS, PoseArray::of_points(header.clone(), &samples.rocks));
        }
        if last.as_ref() != Some(&samples) {
            out.publish(&topics::SAMPLE_MARKERS, sample_markers(&header, &samples.rocks, &samples.collected_at));
        }
    }
}

/// The map grid as an `OccupancyGrid` stamped with `header`.
fn occupancy_grid(occupancy: Vec<i8>, header: Header) -> OccupancyGrid {
    OccupancyGrid {
        info: MapMetaData {
            map_load_time: header.stamp.clone(),
            resolution: 1.0,
            width: SIDE_CELLS as u32,
            height: SIDE_CELLS as u32,
            origin: PoseMsg { position: Point::default(), orientation: Quaternion::from_yaw(0.0) },
        },
        header,
        data: occupancy,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mapper::test_scans::{rock_scan, with_samples};

    #[test]
    fn a_new_collected_count_is_on_disk_before_it_is_published() {
        let dir = std::env::temp_dir().join(format!("rover-mapping-snapshots-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let state_dir = dir.to_str().expect("a UTF-8 temporary folder");
        let mut mapping = MappingCore::new(MappingParams::default(), None);
        let mut snapshots = Snapshots::new(state_dir);
        mapping.add_scan_at_its_stamp(&rock_scan(1, 1, (100.0, 100.0)));
        mapping.add_scan_at_its_stamp(&with_samples(rock_scan(2, 2, (100.0, 100.0)), 5));
        assert_eq!(mapping.samples_collected(), 1);
        let written = mapping.memory();
        snapshots.write_if_mission_changed(&mapping);
        let restored = || {
            let mut restarted = MappingCore::new(MappingParams::default(), None);
            Snapshots::new(state_dir).restore(&mut restarted);
            restarted
        };
        let restarted = restored();
        assert_eq!(restarted.samples_collected(), 1, "the new count is on disk");
        assert!(restarted.memory() == written, "the snapshot holds the memory of the count's scan");
        mapping.add_scan_at_its_stamp(&with_samples(rock_scan(3, 3, (100.0, 100.0)), 5));
        snapshots.write_if_mission_changed(&mapping);
        assert!(mapping.memory() != written, "the scan added to the map");
        assert!(restored().memory() == written, "a scan that changes only the map waits for the periodic write");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
