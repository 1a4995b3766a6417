//! The decision node's parameters: every threshold of the state machine.

use crate::local::FreeSpaceRays;

rover_runtime::node_params! {
    /// Parameters of the decision node.
    pub struct DecisionParams {
        /// Cruising speed on open ground, m/s (Unity caps it at 5).
        max_speed_mps: f64 [0.1, 5.0] = 3.5,
        /// Least speed of the last metres to a sample (faster before, as braking at
        /// `stop_decel_mps2` allows to stop with the sample in the arm's reach), and the speed of
        /// creeping on where the camera sees no free lane, m/s.
        approach_speed_mps: f64 [0.1, 3.0] = 0.5,
        /// Throttle per m/s of speed error.
        throttle_gain: f64 [0.0, 10.0] = 0.8,
        /// Brake value for stops (at least 1: a stop always brakes).
        brake: f64 [1.0, 100.0] = 10.0,
        /// Steering degrees per degree of bearing to the chosen direction.
        steer_gain: f64 [0.0, 10.0] = 1.0,
        /// A direction is taken only with this much free ground ahead, metres.
        clearance_m: f64 [0.3, 10.0] = 1.2,
        /// Short of free ground ahead, the speed is one from which braking at this rate stops the
        /// rover with `clearance_m` to spare, m/s^2.
        stop_decel_mps2: f64 [0.1, 5.0] = 1.5,
        /// In a turn, the speed keeps the sideways acceleration below this, m/s^2: the sharper the
        /// steering, the slower.
        turn_accel_mps2: f64 [0.1, 10.0] = 1.5,
        /// Beyond this bearing the rover stops and turns in place, degrees (short of it, it turns
        /// on the move at up to full lock).
        turn_in_place_deg: f64 [10.0, 180.0] = 65.0,
        /// A turn in place ends below this bearing, degrees (the rest is turned on the move while
        /// speeding up).
        turn_done_deg: f64 [1.0, 90.0] = 25.0,
        /// Half width of the lanes checked for free ground, metres.
        lane_half_width_m: f64 [0.1, 2.0] = 0.5,
        /// Lookahead of the path follower, metres.
        lookahead_m: f64 [0.5, 20.0] = 2.5,
        /// Farther along the path, up to this far, the follower steers straight toward the
        /// farthest point that a line clear of walls leads to, metres (no farther than
        /// `lookahead_m`: off).
        max_lookahead_m: f64 [0.5, 30.0] = 2.5,
        /// Frames between replans.
        replan_frames: i64 [1, 10000] = 12,
        /// A replan due at most this many frames before the next map is expected (as long after
        /// the last map as that one after the map before) waits for it, as the new map is planned
        /// on anyway (0: never waits).
        replan_waits_for_map_frames: i64 [0, 100] = 3,
        /// A frontier target counts as reached within this distance, metres.
        frontier_reached_m: f64 [0.5, 20.0] = 2.0,
        /// A frontier cell needs this many unexplored cells in its 5x5 neighbourhood.
        frontier_min_unknown: i64 [1, 25] = 6,
        /// Cells up to this far in front of the camera count as inspected, metres.
        inspect_range_m: f64 [0.5, 20.0] = 5.0,
        /// Cells up to this angle either side of the heading count as inspected, degrees (the
        /// camera's horizontal field of view is 108.9 degrees, 54 either side).
        inspect_half_angle_deg: f64 [1.0, 90.0] = 52.0,
        /// Extra cost, metres, of a frontier straight behind the rover (scaled by the turn).
        turn_penalty_m: f64 [0.0, 100.0] = 8.0,
        /// Choose each new frontier target as the first stop of a tour through the frontier
        /// clusters that ends at home (false: the cheapest frontier).
        frontier_tour: bool = true,
        /// Extra path cost of unknown cells.
        unknown_cost: f64 [0.0, 100.0] = 1.5,
        /// Extra path cost of cells next to obstacles.
        near_wall_cost: f64 [0.0, 100.0] = 4.0,
        /// Give up a frontier target not reached in this time plus its way at cruising speed,
        /// seconds.
        target_timeout_s: f64 [1.0, 10000.0] = 40.0,
        /// Throttle without motion for this long means stuck, seconds.
        stuck_s: f64 [0.1, 60.0] = 1.5,
        /// Moving less than 1 m in this long, turns in place included, means stalled: recover,
        /// seconds.
        stall_s: f64 [1.0, 600.0] = 12.0,
        /// Recovery: reverse throttle while backing up.
        recover_throttle: f64 [0.1, 1.0] = 0.8,
        /// Recovery: backing up, seconds.
        recover_back_s: f64 [0.0, 60.0] = 1.0,
        /// Recovery: turning towards open ground, seconds.
        recover_turn_s: f64 [0.0, 60.0] = 1.5,
        /// Pitch or roll beyond this means tilted: recover, degrees.
        tilt_limit_deg: f64 [1.0, 90.0] = 12.0,
        /// Chase a seen sample up to this distance, metres (as projected on the ground: a sample
        /// on the foot of a wall projects farther than it is).
        sample_sight_m: f64 [0.5, 20.0] = 12.0,
        /// Go for a sample, seen or remembered, up to this path cost on the map (an approach whose
        /// route turns out dearer is left for later); at any cost once the map holds every missing
        /// sample.
        sample_detour_cost: f64 [0.0, 1000.0] = 60.0,
        /// Give up a sample not reached in this time plus its way at cruising speed, seconds.
        sample_timeout_s: f64 [1.0, 1000.0] = 30.0,
        /// A sample given up after failed approaches is tried again after this long, seconds.
        sample_retry_s: f64 [1.0, 10000.0] = 90.0,
        /// Give up waiting for the arm after this long stopped next to a sample, seconds.
        pickup_wait_s: f64 [0.5, 100.0] = 4.0,
        /// Stop at home within this distance of the start, metres.
        home_tolerance_m: f64 [0.2, 10.0] = 1.5,
        /// A goal of `navigate_to_pose` or `goal_pose` counts as reached within this distance,
        /// metres.
        goal_tolerance_m: f64 [0.2, 10.0] = 1.0,
        /// A goal that the map shows inside an obstacle is given up once the rover is this close
        /// to it, metres (from farther off the map may be wrong there).
        goal_seen_m: f64 [0.5, 20.0] = 3.0,
        /// A goal of `navigate_to_pose` or `goal_pose` is given up (aborted) after this many
        /// recoveries on the way.
        goal_max_recoveries: f64 [0.0, 100.0] = 6.0,
        /// Start the sample-return mission at the first frame (false: the rover holds still
        /// until the `start_mission` service, and takes goals meanwhile).
        start_mission: bool = true,
        /// Be home by this mission time even if not done, seconds.
        mission_deadline_s: f64 [10.0, 100000.0] = 1150.0,
        /// Speed assumed when estimating the way home, as a fraction of the cruising speed.
        return_speed_fraction: f64 [0.1, 1.0] = 0.6,
        /// Simulated time per frame, seconds (converts the times above to frames).
        frame_period_s: f64 [0.001, 1.0] = rover_msgs::unity::FRAME_PERIOD_S,
        /// Folder of the node's snapshot (`decision.snapshot`: what the exploration learnt, the
        /// rocks given up on, the stage of the mission, its time), read at start so that a
        /// restarted node carries on, and written while it runs; empty: none. The launchers give
        /// each launch a folder of its own.
        state_dir: String = "",
        /// Write the snapshot at most this often, ms.
        snapshot_every_ms: f64 [100.0, 600000.0] = 1000.0,
    }
    read_at_start: [state_dir]
}

impl DecisionParams {
    /// Frames in `seconds`.
    pub fn frames(&self, seconds: f64) -> u64 {
        (seconds / self.frame_period_s).round().max(1.0) as u64
    }

    /// Frames allowed for a way of path cost `way_m`: `allowance_s` plus the way at cruising
    /// speed.
    pub fn frames_for_way(&self, allowance_s: f64, way_m: f64) -> u64 {
        self.frames(allowance_s + way_m / self.max_speed_mps)
    }

    /// The free-space rays the decision steers by, in lanes of `lane_half_width_m`.
    pub fn free_space_rays(&self) -> FreeSpaceRays {
        FreeSpaceRays::for_decision(self.lane_half_width_m)
    }
}
