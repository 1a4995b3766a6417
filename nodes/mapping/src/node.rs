//! The mapping node (`rover mapping`): terrain scans in; the map, its image, statistics and the
//! located rocks out.

use std::time::{Duration, Instant};

use futures::StreamExt;
use rover_msgs::geometry_msgs::{Point, Pose as PoseMsg, PoseArray, Quaternion};
use rover_msgs::map_grid::SIDE_CELLS;
use rover_msgs::msg::{MapStats, Telemetry, TerrainScan};
use rover_msgs::nav_msgs::{MapMetaData, OccupancyGrid};
use rover_msgs::sensor_msgs::Image;
use rover_msgs::std_msgs::Header;
use rover_msgs::tally::SampleTally;
use rover_node::snapshot::SnapshotFile;
use rover_node::{Publisher, Rejections, Runtime, messages, topics};
use tracing::Instrument as _;

use crate::image::{InsetStats, map_inset};
use crate::map::{ScanGrid, Update, WorldMap};
use crate::params::MappingParams;
use crate::projection::Pose;
use crate::score::{ground_truth_from_png, samples_located};
use crate::snapshot::{self, Home, Memory};

/// Where a scan stands in time: its stamp (seconds, nanoseconds), then its frame. Scans come in
/// this order; a restarted bridge numbers frames from 1 again, but its stamps go on.
type ScanOrder = (i32, u32, u64);

/// The mapping node's state: the map and what it knows about samples.
struct Mapping {
    map: WorldMap,
    params: MappingParams,
    ground_truth: Option<Vec<bool>>,
    samples_truth: Option<Vec<(f64, f64)>>,
    tally: SampleTally,
    home: Option<Home>,
    last_scan: Option<ScanOrder>,
    rejections: Rejections,
    tilted_frames: u64,
    started: Instant,
    frames: u64,
    unpublished_scans: u64,
}

impl Mapping {
    fn new(params: MappingParams) -> anyhow::Result<Self> {
        let ground_truth = if params.ground_truth_png.is_empty() {
            None
        } else {
            let png = std::fs::read(&params.ground_truth_png)
                .map_err(|e| anyhow::anyhow!("parameter ground_truth_png = {:?}: {e}", params.ground_truth_png))?;
            Some(ground_truth_from_png(&png).map_err(|e| anyhow::anyhow!("parameter ground_truth_png: {e}"))?)
        };
        Ok(Mapping {
            map: WorldMap::new(params.map_config()),
            params,
            ground_truth,
            samples_truth: None,
            tally: SampleTally::default(),
            home: None,
            last_scan: None,
            rejections: Rejections::default(),
            tilted_frames: 0,
            started: Instant::now(),
            frames: 0,
            unpublished_scans: 0,
        })
    }

    fn add_scan(&mut self, scan: &TerrainScan) {
        self.unpublished_scans += 1;
        if !self.rejections.accept(topics::TERRAIN.name, scan) {
            return;
        }
        let order = (scan.header.stamp.sec, scan.header.stamp.nanosec, scan.frame);
        if let Some(last) = self.last_scan.filter(|&last| order <= last) {
            let problem = format_args!("skipped a terrain scan: frame {} arrived after frame {}", scan.frame, last.2);
            self.rejections.reject("out_of_order", &problem);
            return;
        }
        self.last_scan = Some(order);
        match self.map.update(&ScanGrid::of(scan), Pose::of_scan(scan)) {
            Update::Used(_) => self.frames += 1,
            Update::SkippedTilt => self.tilted_frames += 1,
            Update::Malformed => {
                let problem =
                    format_args!("skipped a terrain scan: {} cells for {}x{}", scan.cells.len(), scan.rows, scan.cols);
                self.rejections.reject("malformed", &problem);
            }
        }
    }

    fn on_telemetry(&mut self, telemetry: &Telemetry) {
        if !self.rejections.accept(topics::TELEMETRY.name, telemetry) {
            return;
        }
        self.home.get_or_insert(Home { frame: telemetry.frame, x_m: telemetry.x_m, y_m: telemetry.y_m });
        if self.tally.update(telemetry.samples_remaining) > 0 {
            self.map.forget_picked_rock(telemetry.x_m, telemetry.y_m, telemetry.yaw_rad as f64);
        }
    }

    /// Keeps the first true sample positions received (for scoring the located rocks).
    fn set_samples_truth(&mut self, samples: &PoseArray) {
        if self.rejections.accept(topics::SAMPLE_TRUTH.name, samples) {
            self.samples_truth
                .get_or_insert_with(|| samples.poses.iter().map(|p| (p.position.x, p.position.y)).collect());
        }
    }

    /// Whether enough scans came in since the last publication to publish again.
    fn publication_due(&self) -> bool {
        self.unpublished_scans >= self.params.publish_every_scans as u64
    }

    fn rocks(&self) -> Vec<(f64, f64)> {
        self.map.rocks(self.params.rock_merge_m)
    }

    /// What a snapshot keeps.
    fn memory(&self) -> Memory {
        Memory { evidence: self.map.gathered(), home: self.home, tally: self.tally }
    }

    /// Carries on from `memory`, an earlier node's snapshot.
    fn restore(&mut self, memory: Memory) {
        self.map = WorldMap::with_evidence(self.params.map_config(), memory.evidence);
        self.home = memory.home;
        self.tally = memory.tally;
    }

    fn stats(&self, header: Header) -> MapStats {
        let (navigable_cells, obstacle_cells) = self.map.cell_counts();
        let scores = self.ground_truth.as_deref().map(|truth| self.map.scores(truth));
        let rocks_located = match &self.samples_truth {
            Some(samples) => samples_located(&self.map.rock_cells(), samples),
            None => self.rocks().len(),
        };
        MapStats {
            header,
            navigable_cells: navigable_cells as u32,
            obstacle_cells: obstacle_cells as u32,
            mapped_pct: scores.map_or(f32::NAN, |s| s.mapped_pct as f32),
            fidelity_pct: scores.map_or(f32::NAN, |s| s.fidelity_pct as f32),
            rocks_located: rocks_located as u32,
            home_frame: self.home.map_or(0, |h| h.frame),
            home_x_m: self.home.map_or(f64::NAN, |h| h.x_m),
            home_y_m: self.home.map_or(f64::NAN, |h| h.y_m),
            samples_collected: self.tally.collected(),
        }
    }
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
    fn restore(&mut self, mapping: &mut Mapping) {
        if let Some(memory) = self.file.load(snapshot::decode) {
            mapping.restore(memory);
            let (navigable, obstacle) = mapping.map.cell_counts();
            tracing::info!(
                "restored the map from {}: {navigable} navigable and {obstacle} obstacle cells, home {:?}, {} samples collected",
                self.file.path().map_or_else(String::new, |p| p.display().to_string()),
                mapping.home.map(|h| (h.x_m, h.y_m)),
                mapping.tally.collected()
            );
        }
        self.written = Self::held(mapping);
    }

    fn held(mapping: &Mapping) -> (u64, u32, bool) {
        (mapping.frames, mapping.tally.collected(), mapping.home.is_some())
    }

    /// Writes the snapshot if the map changed and `every` has passed since the last one.
    fn write_if_due(&mut self, mapping: &Mapping, every: Duration) {
        if self.file.due(every) {
            self.write(mapping);
        }
    }

    /// Writes the snapshot if the map changed since the last one.
    fn write(&mut self, mapping: &Mapping) {
        let now = Self::held(mapping);
        if now != self.written {
            self.file.save(&snapshot::encode(&mapping.memory()));
            self.written = now;
        }
    }
}

struct Outputs {
    map: Publisher<OccupancyGrid>,
    image: Publisher<Image>,
    stats: Publisher<MapStats>,
    rocks: Publisher<PoseArray>,
    /// The rocks last published; `None` until the first publication, so that the latched topic
    /// says "no rocks yet" from the start.
    last_rocks: Option<Vec<(f64, f64)>>,
    published_at: Instant,
}

impl Outputs {
    fn publish(&mut self, mapping: &mut Mapping) {
        mapping.unpublished_scans = 0;
        self.published_at = Instant::now();
        let header = Header::now("map");
        let grid = OccupancyGrid {
            header: header.clone(),
            info: MapMetaData {
                map_load_time: header.stamp.clone(),
                resolution: 1.0,
                width: SIDE_CELLS as u32,
                height: SIDE_CELLS as u32,
                origin: PoseMsg { position: Point::default(), orientation: Quaternion::from_yaw(0.0) },
            },
            data: mapping.map.occupancy(),
        };
        warn_on_error("map", self.map.publish(grid));
        let stats = mapping.stats(header.clone());
        let rocks = mapping.rocks();
        let inset = InsetStats {
            time_s: mapping.started.elapsed().as_secs_f64(),
            mapped_pct: stats.mapped_pct.is_finite().then_some(stats.mapped_pct as f64),
            fidelity_pct: stats.fidelity_pct.is_finite().then_some(stats.fidelity_pct as f64),
            rocks_located: stats.rocks_located as usize,
            collected: mapping.tally.collected() as usize,
        };
        let image = map_inset(&mapping.map, mapping.ground_truth.as_deref(), &rocks, &inset);
        let message = Image {
            header: header.clone(),
            height: image.height as u32,
            width: image.width as u32,
            encoding: "rgb8".to_string(),
            is_bigendian: 0,
            step: image.width as u32 * 3,
            data: image.data,
        };
        warn_on_error("map/image", self.image.publish(message));
        warn_on_error("rover/map_stats", self.stats.publish(stats));
        if self.last_rocks.as_ref() != Some(&rocks) {
            let poses = rocks
                .iter()
                .map(|&(x, y)| PoseMsg { position: Point { x, y, z: 0.0 }, orientation: Quaternion::from_yaw(0.0) })
                .collect();
            warn_on_error("rover/rocks", self.rocks.publish(PoseArray { header, poses }));
            self.last_rocks = Some(rocks);
        }
    }
}

fn warn_on_error<E: std::fmt::Debug>(topic: &str, result: Result<(), E>) {
    if let Err(e) = result {
        tracing::warn!("cannot publish on {topic}: {e:?}");
    }
}

/// Runs the mapping node until shutdown.
pub async fn run(runtime: &Runtime) -> anyhow::Result<()> {
    let (mut node, params) = runtime.node::<MappingParams>("mapping")?;
    let span = node.span();
    let mut mapping = Mapping::new(params.get())?;
    let mut snapshots = Snapshots::new(&mapping.params.state_dir);
    snapshots.restore(&mut mapping);
    let mut outputs = Outputs {
        map: node.publisher(&topics::MAP)?,
        image: node.publisher(&topics::MAP_IMAGE)?,
        stats: node.publisher(&topics::MAP_STATS)?,
        rocks: node.publisher(&topics::ROCKS)?,
        last_rocks: None,
        published_at: Instant::now(),
    };
    let terrain_subscription = node.subscription(&topics::TERRAIN)?;
    let telemetry_subscription = node.subscription(&topics::TELEMETRY)?;
    let truth_subscription = node.subscription(&topics::SAMPLE_TRUTH)?;
    let mut scans = std::pin::pin!(messages(&terrain_subscription));
    let mut telemetry = std::pin::pin!(messages(&telemetry_subscription));
    let mut truth = std::pin::pin!(messages(&truth_subscription));
    let mut changes = params.watch();
    let shutdown = runtime.shutdown();
    outputs.publish(&mut mapping);
    async {
    loop {
        let flush_at = outputs.published_at + Duration::from_secs_f64(mapping.params.publish_max_delay_ms / 1000.0);
        tokio::select! {
            () = shutdown.wait() => break,
            Some(scan) = scans.next() => {
                mapping.add_scan(&scan);
                if mapping.publication_due() {
                    outputs.publish(&mut mapping);
                    snapshots.write_if_due(&mapping, Duration::from_secs_f64(mapping.params.snapshot_every_ms / 1000.0));
                }
            }
            Some(t) = telemetry.next() => mapping.on_telemetry(&t),
            Some(samples) = truth.next() => mapping.set_samples_truth(&samples),
            () = tokio::time::sleep_until(flush_at.into()), if mapping.unpublished_scans > 0 => outputs.publish(&mut mapping),
            Ok(()) = changes.changed() => {
                let updated = changes.borrow_and_update().clone();
                mapping.map.set_config(updated.map_config());
                mapping.params = updated;
            }
        }
    }
    outputs.publish(&mut mapping);
    snapshots.write(&mapping);
    tracing::info!(
        "mapping: {} frames mapped, {} skipped while tilted, rejected {}",
        mapping.frames,
        mapping.tilted_frames,
        mapping.rejections
    );
    }
    .instrument(span)
    .await;
    Ok(())
}
