//! Bridge health counters and their `/diagnostics` message.

use std::collections::{BTreeMap, VecDeque};
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use rover_msgs::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus, KeyValue};
use rover_msgs::std_msgs::Header;
use rover_runtime::rejections::worth_logging;
use rover_runtime::sync::lock;

use crate::reply::{CommandSource, Reply};

/// Number of recent reply latencies kept for the percentiles.
const LATENCY_WINDOW: usize = 2000;

/// `/diagnostics` key: replies without a fresh command (held or silence brake).
pub const DEADLINE_MISSES_KEY: &str = "deadline_misses";
/// `/diagnostics` key: replies braking after the silence limit.
pub const SILENCE_BRAKES_KEY: &str = "replies_silence_brake";
/// `/diagnostics` key: the reply latency's median over the window, milliseconds.
pub const REPLY_P50_KEY: &str = "reply_latency_p50_ms";
/// `/diagnostics` key: the reply latency's 99th percentile over the window, milliseconds.
pub const REPLY_P99_KEY: &str = "reply_latency_p99_ms";

/// Where a frame's time went, from the bridge's clock: its own work on the way in (parse, check,
/// publish), the graph (published to drive command in) and its own work on the way out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LoopHops {
    /// Telemetry received to its messages published.
    pub bridge_in: Duration,
    /// Messages published to the frame's drive command received.
    pub graph: Duration,
    /// Drive command received to reply decided.
    pub bridge_out: Duration,
}

/// The hops of [`LoopHops`] as `/diagnostics` names them (`hop_NAME_p50_ms`, `hop_NAME_p99_ms`).
pub const HOP_NAMES: [&str; 3] = ["bridge_in", "graph", "bridge_out"];

/// The latest durations of one kind, for percentiles.
#[derive(Debug)]
struct LatencyWindow(Mutex<VecDeque<f64>>);

impl Default for LatencyWindow {
    fn default() -> Self {
        LatencyWindow(Mutex::new(VecDeque::with_capacity(LATENCY_WINDOW)))
    }
}

impl LatencyWindow {
    fn record(&self, duration: Duration) {
        let mut window = lock(&self.0);
        if window.len() == LATENCY_WINDOW {
            window.pop_front();
        }
        window.push_back(duration.as_secs_f64() * 1000.0);
    }

    fn summary(&self) -> LatencySummary {
        let mut values: Vec<f64> = lock(&self.0).iter().copied().collect();
        if values.is_empty() {
            return LatencySummary::default();
        }
        values.sort_by(f64::total_cmp);
        let at = |q: f64| values[((values.len() - 1) as f64 * q).round() as usize];
        LatencySummary { p50_ms: at(0.5), p99_ms: at(0.99), samples: values.len() }
    }
}

/// Counters of the bridge, shared by the socket handlers and the diagnostics publisher.
#[derive(Debug)]
pub struct BridgeStats {
    started: Instant,
    frames: AtomicU64,
    connected: AtomicU64,
    connections: AtomicU64,
    replies_fresh: AtomicU64,
    replies_held: AtomicU64,
    replies_silence_brake: AtomicU64,
    replies_teleop: AtomicU64,
    replies_rejected: AtomicU64,
    replies_inactive: AtomicU64,
    replies_pickup: AtomicU64,
    replies_manual: AtomicU64,
    problems: Mutex<BTreeMap<String, u64>>,
    latencies: LatencyWindow,
    hops: [LatencyWindow; 3],
    last_rate: Mutex<(Instant, u64)>,
}

impl Default for BridgeStats {
    fn default() -> Self {
        let now = Instant::now();
        BridgeStats {
            started: now,
            frames: AtomicU64::new(0),
            connected: AtomicU64::new(0),
            connections: AtomicU64::new(0),
            replies_fresh: AtomicU64::new(0),
            replies_held: AtomicU64::new(0),
            replies_silence_brake: AtomicU64::new(0),
            replies_teleop: AtomicU64::new(0),
            replies_rejected: AtomicU64::new(0),
            replies_inactive: AtomicU64::new(0),
            replies_pickup: AtomicU64::new(0),
            replies_manual: AtomicU64::new(0),
            problems: Mutex::new(BTreeMap::new()),
            latencies: LatencyWindow::default(),
            hops: Default::default(),
            last_rate: Mutex::new((now, 0)),
        }
    }
}

/// Percentiles of recent reply latencies, milliseconds.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LatencySummary {
    /// Median.
    pub p50_ms: f64,
    /// 99th percentile.
    pub p99_ms: f64,
    /// Samples in the window.
    pub samples: usize,
}

impl BridgeStats {
    /// Counts a telemetry frame received.
    pub fn frame_received(&self) {
        self.frames.fetch_add(1, Ordering::Relaxed);
    }

    /// Counts a simulator connection.
    pub fn client_connected(&self) {
        self.connected.fetch_add(1, Ordering::Relaxed);
        self.connections.fetch_add(1, Ordering::Relaxed);
    }

    /// Counts a simulator disconnection and its reason; returns how many of that reason there
    /// were so far.
    pub fn client_disconnected(&self, reason: &str) -> u64 {
        self.connected.fetch_sub(1, Ordering::Relaxed);
        self.problem(&format!("disconnect_{reason}"))
    }

    /// Counts a problem of kind `kind` (a rejected frame, a disconnect, a bad command...); returns
    /// how many of its kind there were so far.
    pub fn problem(&self, kind: &str) -> u64 {
        let mut problems = lock(&self.problems);
        let count = problems.entry(kind.to_string()).or_default();
        *count += 1;
        *count
    }

    /// Counts a problem of kind `kind` and logs `message` as a warning, with the count so far, when
    /// that count is worth logging (the first, then at each power of two).
    pub fn warn_problem(&self, kind: &str, message: std::fmt::Arguments) {
        let count = self.problem(kind);
        if worth_logging(count) {
            tracing::warn!("{message} ({count} such so far)");
        }
    }

    /// Counts one reply and records how long the frame took from arrival to reply, and where
    /// the time went when a drive command answered it.
    pub fn replied(&self, reply: &Reply, latency: Duration, hops: Option<LoopHops>) {
        let counter = match reply {
            Reply::Data(_, CommandSource::Fresh) => &self.replies_fresh,
            Reply::Data(_, CommandSource::Held) => &self.replies_held,
            Reply::Data(_, CommandSource::SilenceBrake) => &self.replies_silence_brake,
            Reply::Data(_, CommandSource::Teleop) => &self.replies_teleop,
            Reply::Data(_, CommandSource::RejectedFrame) => &self.replies_rejected,
            Reply::Data(_, CommandSource::Inactive) => &self.replies_inactive,
            Reply::Pickup => &self.replies_pickup,
            Reply::Manual => &self.replies_manual,
        };
        counter.fetch_add(1, Ordering::Relaxed);
        self.latencies.record(latency);
        if let Some(LoopHops { bridge_in, graph, bridge_out }) = hops {
            for (window, duration) in self.hops.iter().zip([bridge_in, graph, bridge_out]) {
                window.record(duration);
            }
        }
    }

    /// Frames received so far.
    pub fn frames(&self) -> u64 {
        self.frames.load(Ordering::Relaxed)
    }

    /// Replies sent with the fresh command of their frame.
    pub fn fresh_replies(&self) -> u64 {
        self.replies_fresh.load(Ordering::Relaxed)
    }

    /// Replies without a fresh command: held last command or silence brake (deadline misses).
    pub fn deadline_misses(&self) -> u64 {
        self.replies_held.load(Ordering::Relaxed) + self.replies_silence_brake.load(Ordering::Relaxed)
    }

    /// Count of problems of kind `kind`.
    #[cfg(test)]
    pub fn problem_count(&self, kind: &str) -> u64 {
        lock(&self.problems).get(kind).copied().unwrap_or(0)
    }

    /// Percentiles of the recent reply latencies.
    pub fn latency(&self) -> LatencySummary {
        self.latencies.summary()
    }

    /// Percentiles of the recent frames' hops, in the order of [`HOP_NAMES`].
    pub fn hops(&self) -> [LatencySummary; 3] {
        self.hops.each_ref().map(LatencyWindow::summary)
    }

    /// Telemetry frames per second since the previous call.
    fn rate_hz(&self) -> f64 {
        let now = Instant::now();
        let frames = self.frames();
        let mut last = lock(&self.last_rate);
        let elapsed = now.duration_since(last.0).as_secs_f64();
        let rate = if elapsed > 0.0 { (frames - last.1) as f64 / elapsed } else { 0.0 };
        *last = (now, frames);
        rate
    }

    /// One line for the log: frames, replies by source, deadline misses, latency and problems.
    pub fn summary(&self) -> String {
        let count = |counter: &AtomicU64| counter.load(Ordering::Relaxed);
        let latency = self.latency();
        let problems = lock(&self.problems);
        format!(
            "{} frames; replies: {} fresh, {} held, {} silence brakes, {} teleop, {} rejected frames, {} inactive brakes, \
             {} pickups, {} manual; {} deadline misses; reply latency p50 {:.2} ms, p99 {:.2} ms; problems {:?}",
            self.frames(),
            self.fresh_replies(),
            count(&self.replies_held),
            count(&self.replies_silence_brake),
            count(&self.replies_teleop),
            count(&self.replies_rejected),
            count(&self.replies_inactive),
            count(&self.replies_pickup),
            count(&self.replies_manual),
            self.deadline_misses(),
            latency.p50_ms,
            latency.p99_ms,
            *problems
        )
    }

    /// The `/diagnostics` message of the bridge named `name`.
    pub fn diagnostics(&self, name: &str, header: Header) -> DiagnosticArray {
        let connected = self.connected.load(Ordering::Relaxed);
        let latency = self.latency();
        let rate = self.rate_hz();
        let silence = self.replies_silence_brake.load(Ordering::Relaxed);
        let (level, message) = if connected == 0 {
            (DiagnosticStatus::WARN, "no simulator connected".to_string())
        } else if rate > 0.0 && silence > 0 && self.fresh_replies() == 0 {
            (DiagnosticStatus::WARN, "no drive commands: braking".to_string())
        } else {
            (DiagnosticStatus::OK, format!("simulator connected, {rate:.1} frames/s"))
        };
        let mut values = vec![
            key_value("link_up", (connected > 0).to_string()),
            key_value("uptime_s", format!("{:.1}", self.started.elapsed().as_secs_f64())),
            key_value("telemetry_rate_hz", format!("{rate:.1}")),
            key_value("frames", self.frames().to_string()),
            key_value("connections", self.connections.load(Ordering::Relaxed).to_string()),
            key_value(REPLY_P50_KEY, format!("{:.3}", latency.p50_ms)),
            key_value(REPLY_P99_KEY, format!("{:.3}", latency.p99_ms)),
            key_value("replies_fresh", self.fresh_replies().to_string()),
            key_value(DEADLINE_MISSES_KEY, self.deadline_misses().to_string()),
            key_value("replies_held", self.replies_held.load(Ordering::Relaxed).to_string()),
            key_value(SILENCE_BRAKES_KEY, silence.to_string()),
            key_value("replies_teleop", self.replies_teleop.load(Ordering::Relaxed).to_string()),
            key_value("replies_rejected_frame", self.replies_rejected.load(Ordering::Relaxed).to_string()),
            key_value("replies_inactive_brake", self.replies_inactive.load(Ordering::Relaxed).to_string()),
            key_value("replies_pickup", self.replies_pickup.load(Ordering::Relaxed).to_string()),
            key_value("replies_manual", self.replies_manual.load(Ordering::Relaxed).to_string()),
        ];
        for (name, hop) in HOP_NAMES.iter().zip(self.hops()) {
            values.push(key_value(&format!("hop_{name}_p50_ms"), format!("{:.3}", hop.p50_ms)));
            values.push(key_value(&format!("hop_{name}_p99_ms"), format!("{:.3}", hop.p99_ms)));
        }
        for (kind, count) in lock(&self.problems).iter() {
            values.push(key_value(&format!("problem_{kind}"), count.to_string()));
        }
        DiagnosticArray {
            header,
            status: vec![DiagnosticStatus {
                level,
                name: format!("{name}: simulator link"),
                message,
                hardware_id: "rover_simulator".to_string(),
                values,
            }],
        }
    }
}

fn key_value(key: &str, value: String) -> KeyValue {
    KeyValue { key: key.to_string(), value }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reply::DriveValues;

    #[test]
    fn counts_replies_problems_and_latency() {
        let stats = BridgeStats::default();
        stats.client_connected();
        for ms in 1..=100 {
            stats.frame_received();
            stats.replied(&Reply::Data(DriveValues::brake(0.0), CommandSource::Fresh), Duration::from_millis(ms), None);
        }
        stats.replied(&Reply::Data(DriveValues::brake(1.0), CommandSource::Held), Duration::from_millis(50), None);
        stats.problem("not_a_number");
        stats.problem("not_a_number");
        let latency = stats.latency();
        assert_eq!(latency.samples, 101);
        assert!((49.0..=51.0).contains(&latency.p50_ms), "{latency:?}");
        assert!(latency.p99_ms >= 99.0, "{latency:?}");
        let diagnostics = stats.diagnostics("/bridge", Header::default());
        let status = &diagnostics.status[0];
        assert_eq!(status.value("frames"), Some("100"));
        assert_eq!(status.value("hop_graph_p50_ms"), Some("0.000"), "no hops recorded");
        assert_eq!(status.value("deadline_misses"), Some("1"));
        assert_eq!(status.value("problem_not_a_number"), Some("2"));
        assert_eq!(status.value("link_up"), Some("true"));
        let summary = stats.summary();
        assert!(summary.starts_with("100 frames; replies: 100 fresh, 1 held"), "{summary}");
        assert!(summary.contains("1 deadline misses") && summary.contains("\"not_a_number\": 2"), "{summary}");
    }
}
