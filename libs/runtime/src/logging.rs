//! Logging through `tracing`: console output filtered by `RUST_LOG` (or `--log-level`) and capped
//! in size, and every event of the project's own crates also published on `/rosout` by the node it
//! belongs to.

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

/// Name of the span that tags events with the node they belong to (field `name`).
pub const NODE_SPAN: &str = "node";

static ROSOUT_HANDLES: OnceLock<Mutex<Vec<(String, NodeLoggingHandle)>>> = OnceLock::new();

fn handles() -> &'static Mutex<Vec<(String, NodeLoggingHandle)>> {
    ROSOUT_HANDLES.get_or_init(|| Mutex::new(Vec::new()))
}

/// Installs the global subscriber: level `info` unless `RUST_LOG` says otherwise, and `log_level`
/// (from `--ros-args --log-level`) overrides both. Calling it again is harmless.
pub fn init(log_level: Option<&str>) {
    let requested = log_level.map(str::to_string).or_else(|| std::env::var("RUST_LOG").ok()).unwrap_or_default();
    let requested = if requested.trim().is_empty() { "info".to_string() } else { requested };
    let filter = EnvFilter::try_new(format!("info,{QUIET_DEPENDENCIES},{requested}")).unwrap_or_else(|e| {
        eprintln!("ignoring the log filter {requested:?}: {e}");
        EnvFilter::new(format!("info,{QUIET_DEPENDENCIES}"))
    });
    let ansi = std::io::IsTerminal::is_terminal(&std::io::stderr());
    let _ = tracing_subscriber::registry()
        .with(tracing_subscriber::fmt::layer().with_writer(capped_stderr).with_target(false).with_ansi(ansi))
        .with(RosoutLayer)
        .with(filter)
        .try_init();
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

struct NodeName(String);

struct RosoutLayer;

impl<S: Subscriber + for<'a> LookupSpan<'a>> Layer<S> for RosoutLayer {
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

    fn on_event(&self, event: &Event<'_>, ctx: Context<'_, S>) {
        let metadata = event.metadata();
        if !metadata.target().starts_with("rover") {
            return;
        }
        let node = ctx.event_scope(event).and_then(|scope| {
            scope.from_root().find_map(|span| span.extensions().get::<NodeName>().map(|n| n.0.clone()))
        });
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
    use super::*;

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
