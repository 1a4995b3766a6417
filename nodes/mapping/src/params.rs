//! The mapping node's parameters and the configuration they give.

use crate::map::MapConfig;

rover_runtime::node_params! {
    /// Parameters of the mapping node.
    pub struct MappingParams {
        /// Scan cells farther than this from the rover are ignored, metres.
        max_range_m: f64 [0.5, 20.0] = 8.0,
        /// Frames whose pitch or roll exceeds this are skipped, degrees.
        max_tilt_deg: f64 [0.0, 45.0] = 3.0,
        /// Re-project scan cells through the tilted camera (pitch and roll correction).
        correct_tilt: bool = true,
        /// A cell becomes navigable after this many frames saw it navigable...
        min_navigable_hits: i64 [1, 1000] = 1,
        /// ...and when its navigable evidence is at least this many times its obstacle evidence.
        navigable_ratio: f64 [0.0, 100.0] = 0.2,
        /// A frame that sees a cell within this range weighs fully as evidence; farther, it weighs
        /// (this range / its range) squared, metres.
        full_weight_range_m: f64 [0.1, 20.0] = 3.0,
        /// Obstacle cells this far beyond the nearest obstacle of their bearing (1 degree bins) are
        /// not evidence: behind a wall the camera sees the wall's face, which the flat-floor
        /// projection throws onto the ground beyond it, metres (20: every obstacle cell counts).
        shadow_margin_m: f64 [0.0, 20.0] = 1.5,
        /// A cell that is not navigable becomes an obstacle after this many obstacle frames.
        min_obstacle_hits: i64 [1, 1000] = 2,
        /// A cell holds a rock after this many rock frames.
        min_rock_hits: i64 [1, 1000] = 2,
        /// Rock cells closer than this are one rock, metres (a sample seen from afar lands up to
        /// 3 m beyond where it lies; no two sample places of the Unity world are closer than 7 m).
        rock_merge_m: f64 [0.1, 20.0] = 3.5,
        /// A scan stamped more than this after the node's clock is skipped, and a clock this far
        /// behind the last scan mapped means time started again (a respawned bridge's simulated
        /// time), so scans are ordered afresh, seconds. Hosts' clocks must agree within it.
        max_stamp_ahead_s: f64 [0.1, 3600.0] = 5.0,
        /// Ground-truth map (200x200 PNG, navigable > 0) for the Udacity scores; empty: none.
        ground_truth_png: String = "",
        /// Publish map, map/image, rover/map_stats and rover/rocks after each terrain scan whose
        /// frame is a multiple of this (simulated time, so a mission plays out alike however fast
        /// the graph runs), or after this many scans since the last publication.
        publish_every_scans: i64 [1, 100000] = 25,
        /// Also publish scans not yet published after this long, ms (when the scans stop).
        publish_max_delay_ms: f64 [10.0, 60000.0] = 500.0,
        /// Folder of the node's snapshot (`mapping.snapshot`: evidence, home, collected count),
        /// read at start so that a restarted node carries on where the last one stopped, and
        /// written while the map changes and at shutdown; empty: none. The launchers give each
        /// launch a folder of its own.
        state_dir: String = "",
        /// Write the snapshot at most this often, ms (wall clock: a graph running ten times
        /// faster than real time maps ten times as much ground in it, all of it lost in a crash).
        snapshot_every_ms: f64 [100.0, 600000.0] = 250.0,
    }
    read_at_start: [ground_truth_png, state_dir]
}

impl MappingParams {
    /// The map configuration these parameters describe.
    pub fn map_config(&self) -> MapConfig {
        MapConfig {
            max_range_m: self.max_range_m,
            max_tilt_deg: self.max_tilt_deg,
            correct_tilt: self.correct_tilt,
            min_navigable_hits: self.min_navigable_hits as u16,
            navigable_ratio: self.navigable_ratio as f32,
            full_weight_range_m: self.full_weight_range_m,
            shadow_margin_m: self.shadow_margin_m,
            min_obstacle_hits: self.min_obstacle_hits as u16,
            min_rock_hits: self.min_rock_hits as u16,
        }
    }
}
