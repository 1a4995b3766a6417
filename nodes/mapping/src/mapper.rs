//! What the mapping node does with each message, as a plain type that the node and the in-process
//! mission both run: scans ordered by stamp then frame, home taken from the telemetry of the first
//! scan, the samples picked up counted from the scans' telemetry and their rocks forgotten, the
//! statistics of `rover/map_stats`, and the memory a snapshot keeps.

use rover_msgs::builtin_interfaces::Time;
use rover_msgs::geometry_msgs::PoseArray;
use rover_msgs::msg::{MapStats, Telemetry, TerrainScan};
use rover_msgs::std_msgs::Header;
use rover_msgs::tally::SampleTally;
use rover_runtime::{Rejections, topics};

use crate::map::{ScanGrid, Update, WorldMap, arm_point};
use crate::params::MappingParams;
use crate::projection::Pose;
use crate::score::{occupancy_counts, occupancy_scores, samples_located};
use crate::snapshot::{Home, Memory};

/// Where a scan stands in time: its stamp (seconds, nanoseconds), then its frame. Scans come in
/// this order; a restarted bridge numbers frames from 1 again, but its stamps go on.
type ScanOrder = (i32, u32, u64);

/// Where a message of `frame` stamped in `header` stands among the scans.
fn order_of(header: &Header, frame: u64) -> ScanOrder {
    (header.stamp.sec, header.stamp.nanosec, frame)
}

/// At most this many places of collected samples are kept (a world has a handful of samples; a
/// telemetry that keeps counting pickups cannot grow the list further).
const MAX_COLLECTED_PLACES: usize = u8::MAX as usize;

/// The mapping node's state: the map, home, the samples collected and what it rejected.
#[derive(Debug, Clone)]
pub(crate) struct MappingCore {
    map: WorldMap,
    params: MappingParams,
    ground_truth: Option<Vec<bool>>,
    samples_truth: Option<Vec<(f64, f64)>>,
    tally: SampleTally,
    home: Option<Home>,
    last_scan: Option<ScanOrder>,
    /// Rocks picked up, to forget before the scan after the one whose telemetry shows the pickup:
    /// the pickup's place in time and the rover's pose (x, y, yaw).
    picked: Vec<(ScanOrder, [f64; 3])>,
    /// Where the samples were picked up, world metres.
    collected_at: Vec<(f64, f64)>,
    rejections: Rejections,
    frames_mapped: u64,
    tilted_frames: u64,
    unpublished_scans: u64,
    last_scan_frame: u64,
}

impl MappingCore {
    /// An empty map with `params`, scored against `ground_truth` (navigable per cell) if given.
    pub(crate) fn new(params: MappingParams, ground_truth: Option<Vec<bool>>) -> Self {
        MappingCore {
            map: WorldMap::new(params.map_config()),
            params,
            ground_truth,
            samples_truth: None,
            tally: SampleTally::default(),
            home: None,
            last_scan: None,
            picked: Vec::new(),
            collected_at: Vec::new(),
            rejections: Rejections::default(),
            frames_mapped: 0,
            tilted_frames: 0,
            unpublished_scans: 0,
            last_scan_frame: 0,
        }
    }

    /// Maps one terrain scan received at `now` (the node's clock) and follows the telemetry it
    /// carries, unless it fails its checks, is stamped ahead of `now`, or comes before the last
    /// scan taken.
    pub(crate) fn add_scan(&mut self, scan: &TerrainScan, now: &Time) {
        self.unpublished_scans += 1;
        self.last_scan_frame = scan.telemetry.frame;
        if !self.rejections.accept(topics::TERRAIN.name, scan) || !self.stamped_by_now(&scan.header, now) {
            return;
        }
        self.restart_order_if_time_went_back(now);
        let order = order_of(&scan.header, scan.telemetry.frame);
        if self.in_order(order) {
            self.forget_rocks_picked_before(order);
            self.map_scan(scan);
            self.follow_telemetry(&scan.telemetry, order);
        }
    }

    /// Maps `scan` as if received at the time it is stamped.
    #[cfg(test)]
    pub(crate) fn add_scan_at_its_stamp(&mut self, scan: &TerrainScan) {
        self.add_scan(scan, &scan.header.stamp.clone());
    }

    /// Whether `header` is stamped at most `max_stamp_ahead_s` after `now`: a scan from the future
    /// (a peer's, or from a host whose clock is ahead) would hold back every scan until its stamp.
    fn stamped_by_now(&mut self, header: &Header, now: &Time) -> bool {
        let ahead_s = header.stamp.as_secs_f64() - now.as_secs_f64();
        if ahead_s <= self.params.max_stamp_ahead_s {
            return true;
        }
        let problem = format_args!(
            "skipped a terrain scan stamped {ahead_s:.1} s after this node's clock, more than \
             max_stamp_ahead_s = {} s: a peer's scan, or hosts whose clocks disagree",
            self.params.max_stamp_ahead_s
        );
        self.rejections.reject("stamped_ahead", &problem);
        false
    }

    /// Orders scans afresh when `now` is more than `max_stamp_ahead_s` behind the last scan
    /// taken: time started again, as the simulated time of a respawned bridge does.
    fn restart_order_if_time_went_back(&mut self, now: &Time) {
        let Some((sec, nanosec, frame)) = self.last_scan else { return };
        let last_s = Time { sec, nanosec }.as_secs_f64();
        if last_s - now.as_secs_f64() > self.params.max_stamp_ahead_s {
            tracing::warn!(
                "time went back from {last_s:.2} s (frame {frame}) to {:.2} s: ordering scans afresh",
                now.as_secs_f64()
            );
            self.last_scan = None;
        }
    }

    /// Whether a scan at `order` comes after the last scan taken; it becomes the last.
    fn in_order(&mut self, order: ScanOrder) -> bool {
        if let Some(last) = self.last_scan.filter(|&last| order <= last) {
            let problem = format_args!("skipped a terrain scan: frame {} arrived after frame {}", order.2, last.2);
            self.rejections.reject("out_of_order", &problem);
            return false;
        }
        self.last_scan = Some(order);
        true
    }

    fn map_scan(&mut self, scan: &TerrainScan) {
        match self.map.update(&ScanGrid::of(scan), Pose::of_scan(scan)) {
            Update::Used(_) => self.frames_mapped += 1,
            Update::SkippedTilt => self.tilted_frames += 1,
            Update::Malformed => {
                let problem =
                    format_args!("skipped a terrain scan: {} cells for {}x{}", scan.cells.len(), scan.rows, scan.cols);
                self.rejections.reject("malformed", &problem);
            }
        }
    }

    /// Follows the telemetry of the scan at `order`: the first is home; a drop of
    /// `samples_remaining` is a sample picked up, whose rock evidence in front of the arm is
    /// forgotten before the next scan is mapped.
    fn follow_telemetry(&mut self, telemetry: &Telemetry, order: ScanOrder) {
        self.home.get_or_insert(Home { frame: telemetry.frame, x_m: telemetry.x_m, y_m: telemetry.y_m });
        if self.tally.update(telemetry.samples_remaining) > 0 {
            let yaw_rad = telemetry.yaw_rad as f64;
            self.picked.push((order, [telemetry.x_m, telemetry.y_m, yaw_rad]));
            if self.collected_at.len() < MAX_COLLECTED_PLACES {
                self.collected_at.push(arm_point(telemetry.x_m, telemetry.y_m, yaw_rad));
            }
        }
    }

    /// Forgets the rocks picked up before `order` (a scan's).
    fn forget_rocks_picked_before(&mut self, order: ScanOrder) {
        let map = &mut self.map;
        self.picked.retain(|&(picked_at, [x_m, y_m, yaw_rad])| {
            let due = picked_at < order;
            if due {
                map.forget_picked_rock(x_m, y_m, yaw_rad);
            }
            !due
        });
    }

    /// Keeps the first true sample positions received (for scoring the located rocks).
    pub(crate) fn set_samples_truth(&mut self, samples: &PoseArray) {
        if self.rejections.accept(topics::SAMPLE_TRUTH.name, samples) {
            self.samples_truth.get_or_insert_with(|| samples.points());
        }
    }

    /// The parameters.
    pub(crate) fn params(&self) -> &MappingParams {
        &self.params
    }

    /// Replaces the parameters; the map keeps its evidence and decides by the new ones at once.
    pub(crate) fn set_params(&mut self, params: MappingParams) {
        self.map.set_config(params.map_config());
        self.params = params;
    }

    /// Whether to publish after the last scan: its frame is a multiple of `publish_every_scans`
    /// (so that the maps hold the same scans however many of the first frames this node missed
    /// while the graph came up), or that many scans came in since the last publication.
    pub(crate) fn publication_due(&self) -> bool {
        let every = self.params.publish_every_scans as u64;
        self.unpublished_scans > 0 && (self.last_scan_frame.is_multiple_of(every) || self.unpublished_scans >= every)
    }

    /// Whether any scan came in since the last publication.
    pub(crate) fn has_unpublished_scans(&self) -> bool {
        self.unpublished_scans > 0
    }

    /// Notes that the map was just published: scans count towards the next publication.
    pub(crate) fn mark_published(&mut self) {
        self.unpublished_scans = 0;
    }

    /// The map.
    pub(crate) fn map(&self) -> &WorldMap {
        &self.map
    }

    /// The ground truth the map is scored against, if any.
    pub(crate) fn ground_truth(&self) -> Option<&[bool]> {
        self.ground_truth.as_deref()
    }

    /// Where the rover started, once a telemetry frame came in.
    pub(crate) fn home(&self) -> Option<Home> {
        self.home
    }

    /// Samples picked up in the mission.
    pub(crate) fn samples_collected(&self) -> u32 {
        self.tally.collected()
    }

    /// Scans that added to the map.
    pub(crate) fn frames_mapped(&self) -> u64 {
        self.frames_mapped
    }

    /// Scans skipped because the body was tilted.
    pub(crate) fn tilted_frames(&self) -> u64 {
        self.tilted_frames
    }

    /// The inputs rejected so far, by kind.
    pub(crate) fn rejections(&self) -> &Rejections {
        &self.rejections
    }

    /// The located rocks, world metres.
    #[cfg(test)]
    fn rocks(&self) -> Vec<(f64, f64)> {
        self.rocks_on(&self.map.occupancy())
    }

    /// The located rocks of the map whose cells are `occupancy`.
    fn rocks_on(&self, occupancy: &[i8]) -> Vec<(f64, f64)> {
        self.map.rocks(occupancy, self.params.rock_merge_m)
    }

    /// What a snapshot keeps.
    pub(crate) fn memory(&self) -> Memory {
        Memory {
            evidence: self.map.gathered(),
            home: self.home,
            tally: self.tally,
            collected_at: self.collected_at.clone(),
        }
    }

    /// Carries on from `memory`, an earlier node's snapshot.
    pub(crate) fn restore(&mut self, memory: Memory) {
        self.map = WorldMap::with_evidence(self.params.map_config(), memory.evidence);
        self.home = memory.home;
        self.tally = memory.tally;
        self.collected_at = memory.collected_at;
    }

    /// What a publication of the map shows, stamped with `header`: the map's cells classified
    /// once, for the occupancy grid, the statistics and the inset alike.
    pub(crate) fn publication(&self, header: Header) -> MapPublication {
        let occupancy = self.map.occupancy();
        let rocks = self.rocks_on(&occupancy);
        let stats = self.stats(&occupancy, &rocks, header);
        MapPublication { occupancy, stats, rocks, collected_at: self.collected_at.clone() }
    }

    /// The statistics of `rover/map_stats` of the map whose cells are `occupancy` and whose rocks
    /// are `rocks`; the scores are NaN without a ground truth.
    fn stats(&self, occupancy: &[i8], rocks: &[(f64, f64)], header: Header) -> MapStats {
        let (navigable_cells, obstacle_cells) = occupancy_counts(occupancy);
        let scores = self.ground_truth.as_deref().map(|truth| occupancy_scores(occupancy, truth));
        MapStats {
            header,
            navigable_cells: navigable_cells as u32,
            obstacle_cells: obstacle_cells as u32,
            mapped_pct: scores.map_or(f32::NAN, |s| s.mapped_pct as f32),
            fidelity_pct: scores.map_or(f32::NAN, |s| s.fidelity_pct as f32),
            rocks_located: self.rocks_located(rocks) as u32,
            home_frame: self.home.map_or(0, |h| h.frame),
            home_x_m: self.home.map_or(f64::NAN, |h| h.x_m),
            home_y_m: self.home.map_or(f64::NAN, |h| h.y_m),
            samples_collected: self.tally.collected(),
        }
    }

    /// True samples with a rock on the map, once they are known; the located `rocks` until then.
    fn rocks_located(&self, rocks: &[(f64, f64)]) -> usize {
        match &self.samples_truth {
            Some(samples) => samples_located(&self.map.rock_cells(), samples),
            None => rocks.len(),
        }
    }
}

/// One publication of the map (see [`MappingCore::publication`]).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct MapPublication {
    /// The occupancy grid's cells (row = y).
    pub occupancy: Vec<i8>,
    /// The statistics.
    pub stats: MapStats,
    /// The located rocks, world metres.
    pub rocks: Vec<(f64, f64)>,
    /// Where the samples were collected, world metres.
    pub collected_at: Vec<(f64, f64)>,
}

#[cfg(test)]
pub(crate) mod test_scans {
    use rover_msgs::builtin_interfaces::Time;

    use super::*;

    /// A scan of frame `frame` stamped `sec`, taken at (x, y) facing +x with 6 samples on the
    /// ground, that sees floor from 0.5 m ahead of the rover and rock on the 1.5 m beyond it.
    pub(crate) fn rock_scan(frame: u64, sec: i32, position: (f64, f64)) -> TerrainScan {
        let (rows, cols) = (4, 4);
        TerrainScan {
            header: Header { stamp: Time { sec, nanosec: 0 }, frame_id: String::new() },
            telemetry: telemetry(frame, position, 6),
            resolution_m: 0.5,
            origin_x_m: 0.5,
            origin_y_m: -1.0,
            rows,
            cols,
            cells: (0..rows * cols)
                .map(|i| if i < cols { TerrainScan::NAVIGABLE } else { TerrainScan::ROCK })
                .collect(),
            ..TerrainScan::default()
        }
    }

    /// Telemetry of frame `frame` at (x, y) facing +x with `samples_remaining` on the ground.
    pub(crate) fn telemetry(frame: u64, (x_m, y_m): (f64, f64), samples_remaining: u8) -> Telemetry {
        Telemetry { frame, x_m, y_m, samples_remaining, ..Telemetry::default() }
    }

    /// `scan` with `samples_remaining` samples on the ground.
    pub(crate) fn with_samples(scan: TerrainScan, samples_remaining: u8) -> TerrainScan {
        TerrainScan { telemetry: Telemetry { samples_remaining, ..scan.telemetry }, ..scan }
    }
}

#[cfg(test)]
mod tests {
    use rover_msgs::body::ARM_REACH_M;

    use super::test_scans::{rock_scan, with_samples};
    use super::*;

    fn core() -> MappingCore {
        MappingCore::new(MappingParams::default(), None)
    }

    /// The frames mapped and the scans rejected as out of order after the scans `(frame, stamp
    /// seconds)` in this order, all taken at one place.
    fn mapped_and_out_of_order(scans: &[(u64, i32)]) -> (u64, u64) {
        let mut mapping = core();
        for &(frame, sec) in scans {
            mapping.add_scan(&rock_scan(frame, sec, (100.0, 100.0)), &Time { sec, nanosec: 0 });
        }
        (mapping.frames_mapped(), mapping.rejections().count("out_of_order"))
    }

    #[test]
    fn scans_out_of_order_are_skipped_and_counted() {
        assert_eq!(mapped_and_out_of_order(&[(10, 5), (9, 5), (10, 5), (11, 4)]), (1, 3));
    }

    #[test]
    fn a_new_bridge_numbering_frames_from_one_again_is_mapped() {
        assert_eq!(mapped_and_out_of_order(&[(5000, 200), (1, 201), (2, 201)]), (3, 0));
    }

    #[test]
    fn a_scan_stamped_ahead_of_the_clock_is_skipped_and_holds_nothing_back() {
        let mut mapping = core();
        let at = |sec| Time { sec, nanosec: 0 };
        mapping.add_scan(&rock_scan(1, 10, (100.0, 100.0)), &at(10));
        mapping.add_scan(&rock_scan(2, 1_000_000, (100.0, 100.0)), &at(10));
        mapping.add_scan(&rock_scan(3, 14, (100.0, 100.0)), &at(11));
        mapping.add_scan(&rock_scan(4, 11, (100.0, 100.0)), &at(11));
        assert_eq!(mapping.frames_mapped(), 2, "frames 1 and 3: {}", mapping.rejections());
        assert_eq!(mapping.rejections().count("stamped_ahead"), 1);
        assert_eq!(mapping.rejections().count("out_of_order"), 1, "frame 4 came after frame 3");
    }

    #[test]
    fn scans_after_the_clock_starts_again_are_mapped_in_their_new_order() {
        let mut mapping = core();
        let at = |sec| Time { sec, nanosec: 0 };
        mapping.add_scan(&rock_scan(7000, 300, (100.0, 100.0)), &at(300));
        for frame in 1..=3 {
            mapping.add_scan(&rock_scan(frame, frame as i32, (100.0, 100.0)), &at(frame as i32));
        }
        mapping.add_scan(&rock_scan(2, 2, (100.0, 100.0)), &at(3));
        assert_eq!(mapping.frames_mapped(), 4, "{}", mapping.rejections());
        assert_eq!(mapping.rejections().count("out_of_order"), 1, "a repeated frame of the new time");
    }

    #[test]
    fn maps_are_published_at_the_same_frames_whichever_scans_came_first() {
        let every = MappingParams::default().publish_every_scans as u64;
        let published_after = |frames: std::ops::RangeInclusive<u64>| {
            let mut mapping = core();
            let mut published = Vec::new();
            for frame in frames {
                mapping.add_scan_at_its_stamp(&rock_scan(frame, frame as i32, (100.0, 100.0)));
                if mapping.publication_due() {
                    mapping.mark_published();
                    published.push(frame);
                }
            }
            published
        };
        assert_eq!(published_after(1..=3 * every), [every, 2 * every, 3 * every]);
        assert_eq!(published_after(3..=3 * every), [every, 2 * every, 3 * every], "the first two missed");
        let renumbered = published_after(5 * every + 1..=7 * every + 1);
        assert_eq!(renumbered, [6 * every, 7 * every], "frames go on where a count of scans would drift");
    }

    #[test]
    fn home_is_where_the_first_scan_was_taken() {
        let mut mapping = core();
        assert_eq!(mapping.publication(Header::default()).stats.home_frame, 0, "no home before any scan");
        mapping.add_scan_at_its_stamp(&rock_scan(3, 3, (99.0, 85.0)));
        mapping.add_scan_at_its_stamp(&rock_scan(4, 4, (120.0, 90.0)));
        assert_eq!(mapping.home(), Some(Home { frame: 3, x_m: 99.0, y_m: 85.0 }));
        let stats = mapping.publication(Header::default()).stats;
        assert_eq!((stats.home_frame, stats.home_x_m, stats.home_y_m), (3, 99.0, 85.0));
    }

    #[test]
    fn a_pickup_counts_a_sample_and_forgets_the_rock_in_front_of_the_arm() {
        let (picked, other) = ((100.0, 100.0), (150.0, 150.0));
        let mut mapping = core();
        for (frame, position) in [(1, picked), (2, picked), (3, other), (4, other)] {
            mapping.add_scan_at_its_stamp(&rock_scan(frame, frame as i32, position));
        }
        assert_eq!((mapping.samples_collected(), mapping.rocks().len()), (0, 2), "the first frame sets the count");
        mapping.add_scan_at_its_stamp(&with_samples(rock_scan(5, 5, picked), 5));
        assert_eq!(mapping.samples_collected(), 1);
        assert_eq!(mapping.rocks().len(), 2, "not forgotten before the next scan");
        mapping.add_scan_at_its_stamp(&with_samples(rock_scan(6, 6, other), 5));
        let rocks = mapping.rocks();
        assert_eq!(rocks.len(), 1, "{rocks:?}");
        assert!((rocks[0].0 - other.0).hypot(rocks[0].1 - other.1) < 3.0, "the other rock stays: {rocks:?}");
        let publication = mapping.publication(Header::default());
        assert_eq!(publication.stats.samples_collected, 1);
        let [(x_m, y_m)] = publication.collected_at[..] else { panic!("{:?}", publication.collected_at) };
        assert!((x_m - picked.0 - ARM_REACH_M).abs() < 1e-9 && (y_m - picked.1).abs() < 1e-9, "in front of the arm");
    }

    #[test]
    fn a_restored_memory_carries_the_map_home_and_count_on() {
        let mut mapping = core();
        mapping.add_scan_at_its_stamp(&rock_scan(1, 1, (100.0, 100.0)));
        mapping.add_scan_at_its_stamp(&with_samples(rock_scan(2, 2, (140.0, 100.0)), 5));
        let mut restarted = core();
        restarted.restore(mapping.memory());
        assert_eq!(restarted.memory(), mapping.memory());
        assert_eq!(restarted.home(), Some(Home { frame: 1, x_m: 100.0, y_m: 100.0 }));
        assert_eq!(restarted.map().occupancy(), mapping.map().occupancy());
        restarted.add_scan_at_its_stamp(&with_samples(rock_scan(3, 3, (140.0, 100.0)), 4));
        assert_eq!(restarted.samples_collected(), 2, "a pickup since the snapshot still counts");
        assert_eq!(restarted.publication(Header::default()).collected_at.len(), 2, "where both were collected");
    }
}
