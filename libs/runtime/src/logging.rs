//! Logging through `tracing`: console output filtered by `RUST_LOG` (or `--log-level`) and capped
//! in size, and every event of the project's own crates also published on `/rosout` by the node it
//! belongs to. `--log-level NODE:=LEVEL` sets one node's level, up or down; the console and
//! `/rosout` can each be turned off ([`LogArgs`]).

use std::io::Write;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, OnceLock};

use ros2_client::log::LogLevel;
use ros2_client::rosout::{NodeLoggingHandle, RosoutRaw};
use tracing::field::{Field, Visit};
use tracing::{Event, Subscriber};
use tracing_subscriber::layer::{Context, SubscriberExt};
use tracing_subscriber::registry::LookupSpan;
use tracing_subscriber::util::SubscriberInitExt;
use tracing_subscriber::{EnvFilter, Layer};

use crate::ros_args::LogArgs;
use crate::sync::lock;

/// Directives that mute the DDS and Socket.IO stacks' chatter; `RUST_LOG` or `--log-level` come after
/// them and can override each one.
pub const QUIET_DEPENDENCIES: &str = "rustdds=warn,rustdds::network::udp_sender=error,rustdds::rtps=error,\
rustdds::dds::participant=error,ros2_client=warn,ros2_client::rosout=off,ros2_client::distributions=error,\
socketioxide=warn,engineioxide=warn";

/// Most bytes a process writes to its console (which launchers keep in log files): past it one
/// line says so and the rest are dropped, so that no flood of lines fills a disk. `/rosout` still
/// gets every event.
const MAX_CONSOLE_BYTES: u64 = 64 << 20;

/// What the console of this process has written so far.
static CONSOLE_WRITTEN: LogBudget = LogBudget::new(MAX_CONSOLE_BYTES);

/// Bytes a log may still take.
struct LogBudget {
    max_bytes: u64,
    written_bytes: AtomicU64,
}

impl LogBudget {
    const fn new(max_bytes: u64) -> Self {
        LogBudget { max_bytes, written_bytes: AtomicU64::new(0) }
    }
}

/// A writer that passes lines on to `inner` while `budget` lasts; the line that exhausts it is
/// replaced by a notice, and later ones are dropped.
struct Capped<'a, W> {
    inner: W,
    budget: &'a LogBudget,
}

impl<W: Write> Write for Capped<'_, W> {
    fn write(&mut self, line: &[u8]) -> std::io::Result<usize> {
        let before = self.budget.written_bytes.fetch_add(line.len() as u64, Ordering::Relaxed);
        let max_bytes = self.budget.max_bytes;
        if before + line.len() as u64 <= max_bytes {
            self.inner.write_all(line)?;
        } else if before <= max_bytes {
            writeln!(self.inner, "log output reached {max_bytes} bytes: further lines are dropped (/rosout has them)")?;
        }
        Ok(line.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

/// The prefix of the project's own crates' log targets: their events are the nodes' ROS log.
const OWN_TARGETS: &str = "rover";

/// Name of the span that tags events with the node they belong to (field `name`).
pub const NODE_SPAN: &str = "node";

static ROSOUT_HANDLES: OnceLock<Mutex<Vec<(String, NodeLoggingHandle)>>> = OnceLock::new();

fn handles() -> &'static Mutex<Vec<(String, NodeLoggingHandle)>> {
    ROSOUT_HANDLES.get_or_init(|| Mutex::new(Vec::new()))
}

/// Installs the global subscriber: level `info` unless `RUST_LOG` says otherwise, `--log-level`
/// overrides both, and `--log-level NODE:=LEVEL` sets one node's events. Calling it again is harmless.
pub fn init(logs: &LogArgs) {
    let rust_log = std::env::var("RUST_LOG").ok();
    let directives = filter_directives(logs, rust_log.as_deref());
    let filter = EnvFilter::try_new(&directives).unwrap_or_else(|e| {
        eprintln!("ignoring the log filter {rust_log:?}: {e}");
        fallback_filter()
    });
    let ansi = std::io::IsTerminal::is_terminal(&std::io::stderr());
    let console = logs
        .console
        .then(|| tracing_subscriber::fmt::layer().with_writer(capped_stderr).with_target(false).with_ansi(ansi));
    let _ = tracing_subscriber::registry()
        .with(NodeSpans::new(logs, rust_log.as_deref()))
        .with(console)
        .with(logs.rosout.then_some(RosoutLayer))
        .with(filter)
        .try_init();
}

/// The `EnvFilter` directives of `logs` with `RUST_LOG` set to `rust_log`: the dependencies
/// quietened, then the level asked for (`--log-level`, else `RUST_LOG`, else info), then each
/// node's level for the project's events in that node's span (the DDS stack keeps the process's).
fn filter_directives(logs: &LogArgs, rust_log: Option<&str>) -> String {
    let requested = logs.level.map(str::to_string).or_else(|| rust_log.map(str::to_string)).unwrap_or_default();
    let requested = if requested.trim().is_empty() { "info".to_string() } else { requested };
    let mut directives = format!("info,{QUIET_DEPENDENCIES},{requested}");
    for (logger, level) in &logs.node_levels {
        directives.push_str(&format!(",{OWN_TARGETS}[{NODE_SPAN}{{name={}}}]={level}", node_name_pattern(logger)));
    }
    directives
}

/// The pattern of the fully qualified node names a ROS logger name stands for: `rover1.bridge`
/// (or `/rover1/bridge`) is that node, a bare `bridge` the node of that name in any namespace.
fn node_name_pattern(logger: &str) -> String {
    let name = logger_path(logger);
    if name.contains('/') { format!("/{name}") } else { format!(".*/{name}") }
}

/// Whether the fully qualified node name `node` is the one a ROS logger name means.
fn logger_names(logger: &str, node: &str) -> bool {
    let name = logger_path(logger);
    if name.contains('/') {
        node.trim_start_matches('/') == name
    } else {
        node.rsplit('/').next() == Some(name.as_str())
    }
}

/// A ROS logger name (`rover1.bridge`, `/rover1/bridge` or `bridge`) as a node path without the
/// leading slash (`rover1/bridge`, `bridge`).
fn logger_path(logger: &str) -> String {
    logger.trim_start_matches('/').replace('.', "/")
}

/// The filter used when the one asked for does not parse: info, the dependencies quietened.
fn fallback_filter() -> EnvFilter {
    EnvFilter::new(format!("info,{QUIET_DEPENDENCIES}"))
}

fn capped_stderr() -> Capped<'static, std::io::Stderr> {
    Capped { inner: std::io::stderr(), budget: &CONSOLE_WRITTEN }
}

/// Registers the `/rosout` publisher of the node with fully qualified name `node`.
pub(crate) fn register_rosout(node: &str, handle: NodeLoggingHandle) {
    lock(handles()).push((node.to_string(), handle));
}

/// Removes the `/rosout` publisher of `node` (when the node is dropped).
pub(crate) fn unregister_rosout(node: &str) {
    lock(handles()).retain(|(name, _)| name != node);
}

/// The fully qualified name of the node a span belongs to, kept in the span's extensions.
struct NodeName(String);

/// Tags each node span with its node's name, and holds to `--log-level NODE:=LEVEL` the events
/// of a node it names: the project's at that level, up or down, the DDS stack's at the process's
/// (the filter lets in all that a louder level may need).
struct NodeSpans {
    node_levels: Vec<(String, &'static str)>,
    process: EnvFilter,
}

impl NodeSpans {
    fn new(logs: &LogArgs, rust_log: Option<&str>) -> Self {
        let process_only = LogArgs { node_levels: Vec::new(), ..logs.clone() };
        let process =
            EnvFilter::try_new(filter_directives(&process_only, rust_log)).unwrap_or_else(|_| fallback_filter());
        NodeSpans { node_levels: logs.node_levels.clone(), process }
    }
}

impl<S: Subscriber + for<'a> LookupSpan<'a>> Layer<S> for NodeSpans {
    fn on_new_span(&self, attrs: &tracing::span::Attributes<'_>, id: &tracing::span::Id, ctx: Context<'_, S>) {
        if attrs.metadata().name() != NODE_SPAN {
            return;
        }
        let mut visitor = MessageVisitor::default();
        attrs.record(&mut visitor);
        if let (Some(span), Some(name)) = (ctx.span(id), visitor.fields.into_iter().find(|(k, _)| k == "name")) {
            span.extensions_mut().insert(NodeName(name.1));
        }
    }

    fn event_enabled(&self, event: &Event<'_>, ctx: Context<'_, S>) -> bool {
        if self.node_levels.is_empty() {
            return true;
        }
        let Some(node) = node_of(event, &ctx) else { return true };
        let Some((_, level)) = self.node_levels.iter().rev().find(|(logger, _)| logger_names(logger, &node)) else {
            return true;
        };
        let metadata = event.metadata();
        if metadata.target().starts_with(OWN_TARGETS) {
            level.parse::<tracing::Level>().is_ok_and(|max| *metadata.level() <= max)
        } else {
            Layer::<S>::enabled(&self.process, metadata, ctx)
        }
    }
}

/// The fully qualified name of the node whose span `event` happened in, if any.
fn node_of<S: Subscriber + for<'a> LookupSpan<'a>>(event: &Event<'_>, ctx: &Context<'_, S>) -> Option<String> {
    ctx.event_scope(event)
        .and_then(|scope| scope.from_root().find_map(|span| span.extensions().get::<NodeName>().map(|n| n.0.clone())))
}

/// Publishes the project's events on `/rosout`, each by the node it belongs to.
struct RosoutLayer;

impl<S: Subscriber + for<'a> LookupSpan<'a>> Layer<S> for RosoutLayer {
    fn on_event(&self, event: &Event<'_>, ctx: Context<'_, S>) {
        let metadata = event.metadata();
        if !metadata.target().starts_with(OWN_TARGETS) {
            return;
        }
        let node = node_of(event, &ctx);
        let handles = lock(handles());
        let handle = match node {
            Some(node) => handles.iter().find(|(name, _)| *name == node),
            None if handles.len() == 1 => handles.first(),
            None => None,
        };
        let Some((name, handle)) = handle else { return };
        let mut visitor = MessageVisitor::default();
        event.record(&mut visitor);
        handle.rosout_raw(
            ros2_client::builtin_interfaces::Time::now(),
            rosout_level(metadata.level()),
            name.trim_start_matches('/'),
            &visitor.text(),
            metadata.file().unwrap_or_default(),
            metadata.target(),
            metadata.line().unwrap_or_default(),
        );
    }
}

fn rosout_level(level: &tracing::Level) -> LogLevel {
    match *level {
        tracing::Level::ERROR => LogLevel::Error,
        tracing::Level::WARN => LogLevel::Warn,
        tracing::Level::INFO => LogLevel::Info,
        _ => LogLevel::Debug,
    }
}

#[derive(Default)]
struct MessageVisitor {
    message: String,
    fields: Vec<(String, String)>,
}

impl MessageVisitor {
    fn text(&self) -> String {
        let mut text = self.message.clone();
        for (key, value) in &self.fields {
            text.push_str(&format!(" {key}={value}"));
        }
        text
    }
}

impl Visit for MessageVisitor {
    fn record_str(&mut self, field: &Field, value: &str) {
        if field.name() == "message" {
            self.message = value.to_string();
        } else {
            self.fields.push((field.name().to_string(), value.to_string()));
        }
    }

    fn record_debug(&mut self, field: &Field, value: &dyn std::fmt::Debug) {
        if field.name() == "message" {
            self.message = format!("{value:?}");
        } else {
            self.fields.push((field.name().to_string(), format!("{value:?}")));
        }
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;

    /// The messages of the events that pass a subscriber set up as [`init`] does for `logs`,
    /// each emitted at `level` in the span of node `node`.
    fn passed(logs: &LogArgs, events: &[(&str, tracing::Level)]) -> Vec<String> {
        passed_of(logs, || {
            for (node, level) in events {
                let _span = tracing::info_span!("node", name = %node).entered();
                match *level {
                    tracing::Level::DEBUG => tracing::debug!("{node} debug"),
                    tracing::Level::INFO => tracing::info!("{node} info"),
                    _ => tracing::warn!("{node} warn"),
                }
            }
        })
    }

    /// The messages of the events `emit` makes that pass a subscriber set up as [`init`] does.
    fn passed_of(logs: &LogArgs, emit: impl FnOnce()) -> Vec<String> {
        let seen = Arc::new(Mutex::new(Vec::new()));
        let subscriber = tracing_subscriber::registry()
            .with(NodeSpans::new(logs, None))
            .with(Recorder(seen.clone()))
            .with(EnvFilter::new(filter_directives(logs, None)));
        tracing::subscriber::with_default(subscriber, emit);
        lock(&seen).clone()
    }

    /// Records the message of every event it sees.
    struct Recorder(Arc<Mutex<Vec<String>>>);

    impl<S: Subscriber> Layer<S> for Recorder {
        fn on_event(&self, event: &Event<'_>, _: Context<'_, S>) {
            let mut visitor = MessageVisitor::default();
            event.record(&mut visitor);
            lock(&self.0).push(visitor.text());
        }
    }

    #[test]
    fn a_node_log_level_raises_or_lowers_that_node_only_in_any_namespace_or_one() {
        use tracing::Level;
        let logs = LogArgs {
            node_levels: vec![("bridge".into(), "debug"), ("rover1.mapping".into(), "warn")],
            ..LogArgs::default()
        };
        let events = [
            ("/rover1/bridge", Level::DEBUG),
            ("/perception", Level::DEBUG),
            ("/perception", Level::INFO),
            ("/rover1/mapping", Level::INFO),
            ("/rover1/mapping", Level::WARN),
            ("/rover2/mapping", Level::INFO),
        ];
        let passed = passed(&logs, &events);
        let expected = ["/rover1/bridge debug", "/perception info", "/rover1/mapping warn", "/rover2/mapping info"];
        assert_eq!(passed, expected);
    }

    #[test]
    fn a_louder_node_level_leaves_the_dds_stack_at_the_process_level() {
        let logs = LogArgs { node_levels: vec![("pickup".into(), "debug")], ..LogArgs::default() };
        let passed = passed_of(&logs, || {
            let _span = tracing::info_span!("node", name = "/pickup").entered();
            tracing::debug!(target: "ros2_client::node", "dds debug");
            tracing::warn!(target: "ros2_client::node", "dds warn");
            tracing::debug!("own debug");
        });
        assert_eq!(passed, ["dds warn", "own debug"]);
    }

    #[test]
    fn the_process_log_level_comes_from_log_level_then_rust_log_then_info() {
        let logs = LogArgs { level: Some("warn"), ..LogArgs::default() };
        assert!(filter_directives(&logs, Some("debug")).ends_with(",warn"));
        assert!(filter_directives(&LogArgs::default(), Some("rover_bridge=debug")).ends_with(",rover_bridge=debug"));
        assert!(filter_directives(&LogArgs::default(), Some(" ")).ends_with(",info"));
    }

    #[test]
    fn the_console_log_stops_with_a_notice_once_its_budget_is_spent() {
        let budget = LogBudget::new(30);
        let mut console = Capped { inner: Vec::new(), budget: &budget };
        for line in ["first line\n", "second line\n", "third line!\n", "fourth line\n"] {
            assert_eq!(console.write(line.as_bytes()).unwrap(), line.len(), "every line is taken");
        }
        let written = String::from_utf8(console.inner).unwrap();
        assert_eq!(
            written,
            "first line\nsecond line\nlog output reached 30 bytes: further lines are dropped (/rosout has them)\n"
        );
    }
}
