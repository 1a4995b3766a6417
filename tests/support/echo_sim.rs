//! A fake simulator for the bridge tests and benchmark: it sends recorded frames in the Unity
//! dialect and, with the echo node answering, checks which telemetry each reply answers.

use std::collections::VecDeque;
use std::path::Path;
use std::time::{Duration, Instant};

use rover_msgs::unity::ReportedState;
use rover_sim::wire::client::{ClientConfig, ClientStats, Simulation, run_client};
use rover_sim::wire::command::Command;
use rover_sim::wire::telemetry::TelemetryValues;

use rover::tools::dataset::{RecordedFrame, read_log};

use super::test_dataset_dir;

/// Positions cycle through 1..=997 so that the echo node's throttle (x / 1000) names the telemetry.
const POSITION_CYCLE: u64 = 997;

/// A recorded frame with its JPEG loaded.
pub(crate) struct LoadedFrame {
    /// The row of `robot_log.csv`.
    pub frame: RecordedFrame,
    /// The camera image.
    pub jpeg: Vec<u8>,
}

/// The 283 recorded frames with their images.
pub(crate) fn recorded_frames() -> Vec<LoadedFrame> {
    let frames = read_log(Path::new(&test_dataset_dir())).expect("the recorded dataset").frames;
    frames.into_iter().map(|frame| LoadedFrame { jpeg: frame.jpeg().expect("a recorded JPEG"), frame }).collect()
}

/// The telemetry JSON of `loaded` as the Unity client writes it, with the rover at `x_m`.
pub(crate) fn telemetry_json(loaded: &LoadedFrame, x_m: f64) -> String {
    let frame = &loaded.frame;
    TelemetryValues {
        state: ReportedState { x_m, ..frame.state },
        near_sample: false,
        picking_up: false,
        samples: &[(97.44, 74.65), (122.28, 51.66)],
        image_jpeg: &loaded.jpeg,
    }
    .to_json()
}

/// One reply as the fake simulator saw it.
#[derive(Debug, Clone)]
pub(crate) struct SeenReply {
    /// The reply's throttle.
    pub throttle: f64,
    /// The reply's brake.
    pub brake: f64,
    /// From the telemetry it answers (or the oldest one outstanding) to the reply.
    pub latency: Duration,
    /// When it came.
    pub at: Instant,
}

/// A fake simulator that sends recorded frames and checks which telemetry each reply answers.
pub(crate) struct EchoCheckingSimulator {
    /// The recorded frames, sent in turn.
    pub frames: Vec<LoadedFrame>,
    /// Telemetry sent so far.
    pub sent: u64,
    /// Telemetry not answered yet: its number and when it left.
    pub outstanding: VecDeque<(u64, Instant)>,
    /// Every drive reply.
    pub replies: Vec<SeenReply>,
    /// The telemetry each echoed reply answered, with the reply's brake.
    pub fresh_matches: Vec<(u64, f64)>,
    /// Replies that echo no outstanding telemetry.
    pub unmatched: Vec<SeenReply>,
    /// Events other than drive replies.
    pub other_events: u64,
    /// The run ends after this many replies.
    pub limit: usize,
    /// Called with the number of replies after each one.
    pub on_reply: Box<dyn FnMut(usize) + Send>,
}

impl EchoCheckingSimulator {
    /// A simulator that ends after `limit` replies.
    pub(crate) fn new(limit: usize) -> Self {
        EchoCheckingSimulator {
            frames: recorded_frames(),
            sent: 0,
            outstanding: VecDeque::new(),
            replies: Vec::new(),
            fresh_matches: Vec::new(),
            unmatched: Vec::new(),
            other_events: 0,
            limit,
            on_reply: Box::new(|_| {}),
        }
    }

    fn position_of(k: u64) -> u64 {
        1 + k % POSITION_CYCLE
    }
}

impl Simulation for EchoCheckingSimulator {
    fn telemetry_json(&mut self) -> String {
        self.sent += 1;
        let k = self.sent;
        self.outstanding.push_back((k, Instant::now()));
        let frame = &self.frames[k as usize % self.frames.len()];
        telemetry_json(frame, Self::position_of(k) as f64)
    }

    fn apply(&mut self, command: Command) {
        let Command::Drive { throttle, brake, .. } = command else {
            self.other_events += 1;
            return;
        };
        let now = Instant::now();
        let position = (throttle * 1000.0).round() as u64;
        let answered = self.outstanding.iter().position(|&(k, _)| Self::position_of(k) == position && throttle > 0.0);
        let latency = match answered {
            Some(index) => {
                let (k, sent_at) = self.outstanding.remove(index).expect("index in range");
                self.fresh_matches.push((k, brake));
                now - sent_at
            }
            None => {
                let (_, sent_at) = self.outstanding.pop_front().expect("a reply without outstanding telemetry");
                now - sent_at
            }
        };
        let reply = SeenReply { throttle, brake, latency, at: now };
        if answered.is_none() {
            self.unmatched.push(reply.clone());
        }
        self.replies.push(reply);
        (self.on_reply)(self.replies.len());
    }

    fn finished(&self) -> bool {
        self.replies.len() >= self.limit
    }
}

/// Runs the fake simulator against a bridge on `port` until it has seen its replies.
pub(crate) async fn run_fake_unity(simulation: &mut EchoCheckingSimulator, port: u16) -> ClientStats {
    let config = ClientConfig::unity("127.0.0.1", port);
    tokio::time::timeout(Duration::from_secs(300), run_client(simulation, &config, std::future::pending()))
        .await
        .expect("the fake simulator finished within 5 minutes")
}
