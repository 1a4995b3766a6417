//! What a mission's observer hears from the graph, the same whether the nodes run in processes of
//! their own or in this one: telemetry, the map, the rocks, the mode and the bridge's diagnostics,
//! scored against the simulator's true world.

use std::time::Instant;

use rover_bridge::stats::{DEADLINE_MISSES_KEY, REPLY_P50_KEY, REPLY_P99_KEY, SILENCE_BRAKES_KEY};
use rover_decision::machine::Mode;
use rover_mapping::score::{LocatedSamples, occupancy_scores};
use rover_msgs::diagnostic_msgs::DiagnosticArray;
use rover_msgs::frames::MissionFrames;
use rover_msgs::geometry_msgs::PoseArray;
use rover_msgs::msg::{DecisionState, Telemetry};
use rover_msgs::nav_msgs::OccupancyGrid;
use rover_runtime::node_core::Sent;
use rover_runtime::topics;
use rover_sim::sim::Simulator;
use rover_sim::world::World;

use crate::missions::in_process::{Progress, Replies};
use crate::missions::picture::{MissionMap, sample_marks};
use crate::missions::time_by_mode::{ModeClock, TimeByMode, activity_of};
use crate::missions::timeline::Timeline;

/// What the evaluator has heard from the graph.
#[derive(Debug)]
pub(crate) struct Evaluator {
    samples: usize,
    located: LocatedSamples,
    progress: Progress,
    /// When the last telemetry came (a stalled graph sends none).
    pub(crate) last_frame_at: Instant,
    frames: MissionFrames,
    clock: ModeClock,
    /// The world's open floor, for the fidelity against it.
    open_floor: Vec<bool>,
    /// The map, path and start so far; the samples are filled in at the end.
    mission_map: MissionMap,
}

impl Evaluator {
    pub(crate) fn new(world: &World) -> Self {
        let samples = world.samples.iter().map(|s| (s.x_m, s.y_m)).collect::<Vec<_>>();
        let progress = Progress {
            sim_seconds: 0.0,
            mapped_pct: 0.0,
            fidelity_pct: 0.0,
            floor_fidelity_pct: 0.0,
            located: 0,
            collected: 0,
            mode: "starting".to_string(),
            time_by_mode: TimeByMode::default(),
            timeline: Timeline::default(),
            replies: Replies::default(),
        };
        let mission_map = MissionMap {
            ground_truth: world.ground_truth().to_vec(),
            home_m: (world.start.x_m, world.start.y_m),
            ..MissionMap::default()
        };
        Evaluator {
            samples: samples.len(),
            located: LocatedSamples::new(samples),
            progress,
            last_frame_at: Instant::now(),
            frames: MissionFrames::default(),
            clock: ModeClock::default(),
            open_floor: world.open_floor(),
            mission_map,
        }
    }

    /// The progress so far, with the time by activity.
    pub(crate) fn snapshot(&self) -> Progress {
        Progress { time_by_mode: self.clock.times().clone(), ..self.progress.clone() }
    }

    pub(crate) fn on_map(&mut self, map: &OccupancyGrid) {
        let scores = occupancy_scores(&map.data, &self.mission_map.ground_truth);
        self.progress.mapped_pct = scores.mapped_pct;
        self.progress.fidelity_pct = scores.fidelity_pct;
        self.progress.floor_fidelity_pct = occupancy_scores(&map.data, &self.open_floor).fidelity_pct;
        self.mission_map.occupancy.clone_from(&map.data);
    }

    pub(crate) fn on_rocks(&mut self, rocks: &PoseArray) {
        let cells = rocks
            .poses
            .iter()
            .filter(|p| p.position.x >= 0.0 && p.position.y >= 0.0)
            .map(|p| (p.position.x as usize, p.position.y as usize))
            .collect::<Vec<_>>();
        self.located.update(&cells);
        self.progress.located = self.located.count();
    }

    /// Takes the decision node's state; whether it reports this mission done.
    pub(crate) fn on_mode(&mut self, state: &DecisionState) -> bool {
        let done = state.mode == Mode::Done.name() && answers_a_frame_seen(self.frames.last(), state.frame);
        self.progress.mode.clone_from(&state.mode);
        done
    }

    /// Takes the messages of the graph that an evaluator listens to; whether the decision node
    /// reported this mission done among them.
    pub(crate) fn observe(&mut self, messages: &[Sent]) -> bool {
        let mut done = false;
        for sent in messages {
            if let Some(map) = sent.on(&topics::MAP) {
                self.on_map(map);
            } else if let Some(rocks) = sent.on(&topics::ROCKS) {
                self.on_rocks(rocks);
            } else if let Some(state) = sent.on(&topics::MODE) {
                done |= self.on_mode(state);
            }
        }
        done
    }

    /// The final progress and mission map, once `simulator` has stopped.
    pub(crate) fn finish(&mut self, simulator: &Simulator) -> (Progress, MissionMap) {
        let report = simulator.report();
        self.progress.sim_seconds = report.sim_seconds;
        self.progress.collected = report.samples_collected;
        self.note_timeline();
        let mission_map = MissionMap { samples: sample_marks(simulator), ..std::mem::take(&mut self.mission_map) };
        (self.snapshot(), mission_map)
    }

    /// Adds the progress so far to the timeline.
    fn note_timeline(&mut self) {
        let Progress { sim_seconds, mapped_pct, collected, .. } = self.progress;
        self.progress.timeline.note(sim_seconds, mapped_pct, collected);
    }

    pub(crate) fn on_diagnostics(&mut self, diagnostics: &DiagnosticArray) {
        let replies = &mut self.progress.replies;
        update_from(&mut replies.deadline_misses, diagnostics, DEADLINE_MISSES_KEY);
        update_from(&mut replies.silence_brakes, diagnostics, SILENCE_BRAKES_KEY);
        update_from(&mut replies.reply_p50_ms, diagnostics, REPLY_P50_KEY);
        update_from(&mut replies.reply_p99_ms, diagnostics, REPLY_P99_KEY);
    }

    pub(crate) fn on_telemetry(&mut self, telemetry: &Telemetry, step_s: f64) {
        let frame = self.frames.of(telemetry.frame);
        self.progress.sim_seconds = frame as f64 * step_s;
        self.clock.on_frame(frame, activity_of(&self.progress.mode, telemetry), step_s);
        self.progress.collected = self.samples.saturating_sub(telemetry.samples_remaining as usize);
        self.note_timeline();
        self.mission_map.path.record(telemetry.x_m, telemetry.y_m);
        self.last_frame_at = Instant::now();
    }
}

/// Sets `value` from the number under `key` in `diagnostics`, when there is one.
fn update_from<T: std::str::FromStr>(value: &mut T, diagnostics: &DiagnosticArray, key: &str) {
    if let Some(number) = diagnostics.value(key).and_then(|text| text.parse().ok()) {
        *value = number;
    }
}

/// How many frames a decision state may be ahead of the last telemetry the evaluator saw (the two
/// travel separately).
const MODE_AHEAD_FRAMES: u64 = 25;

/// True if a decision state of bridge frame `frame` belongs to this mission: the evaluator has seen
/// telemetry (`last`: bridge frame, mission frame) up to shortly before it. A latched `done` of the
/// previous mission's graph, still being stopped when this evaluator subscribed, has a frame far
/// ahead of a new mission's first frames, or comes before any.
fn answers_a_frame_seen(last: Option<(u64, u64)>, frame: u64) -> bool {
    last.is_some_and(|(bridge_frame, _)| frame <= bridge_frame + MODE_AHEAD_FRAMES)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_done_from_an_earlier_mission_is_not_this_missions_done() {
        assert!(!answers_a_frame_seen(None, 10), "no telemetry seen yet");
        assert!(!answers_a_frame_seen(Some((40, 40)), 26_300), "the last frame of a 1052 s mission");
        assert!(answers_a_frame_seen(Some((26_290, 26_290)), 26_300), "its own frame, a little ahead");
        assert!(answers_a_frame_seen(Some((500, 9_000)), 480), "after a bridge restart, in bridge frames");
    }
}
