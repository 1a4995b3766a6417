//! Inputs a node cannot use: counted by kind (usually the topic) and logged as warnings, the 1st,
//! 2nd, 4th, 8th... of each kind, each quoting at most [`MAX_QUOTED_CHARS`] of the input, so that a
//! stream of bad messages cannot flood the log (or `/rosout`).

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::fmt;
use std::sync::Mutex;

use rover_msgs::validate::Validate;

/// Counts of rejected inputs by kind.
#[derive(Debug, Default, Clone, PartialEq, Eq)]
pub struct Rejections {
    counts: BTreeMap<&'static str, u64>,
}

impl Rejections {
    /// No rejection yet.
    pub const fn new() -> Self {
        Rejections { counts: BTreeMap::new() }
    }

    /// Whether `message`, received on `topic`, passes its checks; one that does not is counted
    /// under the topic's name and logged with the field and value that failed.
    pub fn accept<M: Validate>(&mut self, topic: &'static str, message: &M) -> bool {
        match message.validate() {
            Ok(()) => true,
            Err(invalid) => {
                self.reject(topic, &format_args!("rejected a {topic} message: {invalid}"));
                false
            }
        }
    }

    /// Counts one rejection of `kind` and logs `problem` when it is the 1st, 2nd, 4th... of its kind.
    pub fn reject(&mut self, kind: &'static str, problem: &dyn fmt::Display) {
        let count = self.counts.entry(kind).or_default();
        *count += 1;
        if worth_logging(*count) {
            tracing::warn!("{} ({count} such so far)", clipped(&problem.to_string()));
        }
    }

    /// Rejections of `kind` so far.
    pub fn count(&self, kind: &str) -> u64 {
        self.counts.get(kind).copied().unwrap_or_default()
    }
}

impl fmt::Display for Rejections {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.counts.is_empty() {
            return f.write_str("none");
        }
        let counts: Vec<String> = self.counts.iter().map(|(kind, count)| format!("{count} {kind}")).collect();
        f.write_str(&counts.join(", "))
    }
}

/// Problems with requests from peers on the network (malformed or unanswerable service calls,
/// goals and cancels, refused calls and transitions), counted by kind for the whole process: a
/// peer that floods a node with them costs a few log lines.
static REQUEST_PROBLEMS: Mutex<Rejections> = Mutex::new(Rejections::new());

/// Counts a problem of `kind` with a peer's request and logs `problem` when it is the 1st, 2nd,
/// 4th... of its kind in this process.
pub(crate) fn request_problem(kind: &'static str, problem: &dyn fmt::Display) {
    crate::sync::lock(&REQUEST_PROBLEMS).reject(kind, problem);
}

/// Whether the `count`-th occurrence of a repeated problem is worth a log line: the 1st, 2nd,
/// 4th, 8th... are.
pub fn worth_logging(count: u64) -> bool {
    count.is_power_of_two()
}

/// Longest piece of outside input that a log line quotes, characters.
pub const MAX_QUOTED_CHARS: usize = 200;

/// `text` cut to [`MAX_QUOTED_CHARS`] characters, saying how many bytes were left out: a log line
/// that quotes outside input stays short.
pub fn clipped(text: &str) -> Cow<'_, str> {
    match text.char_indices().nth(MAX_QUOTED_CHARS) {
        None => Cow::Borrowed(text),
        Some((end, _)) => Cow::Owned(format!("{}... ({} more bytes)", &text[..end], text.len() - end)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rover_msgs::msg::TerrainScan;

    #[test]
    fn problems_with_peers_requests_are_counted_for_the_whole_process() {
        let before = crate::sync::lock(&REQUEST_PROBLEMS).count("test_flood");
        let threads: Vec<_> = (0..4)
            .map(|_| std::thread::spawn(|| (0..250).for_each(|_| request_problem("test_flood", &"a flood"))))
            .collect();
        threads.into_iter().for_each(|thread| thread.join().unwrap());
        assert_eq!(crate::sync::lock(&REQUEST_PROBLEMS).count("test_flood") - before, 1000);
    }

    #[test]
    fn long_quotes_are_clipped_on_a_character_boundary() {
        assert_eq!(clipped("short"), "short");
        let long = "é".repeat(1 << 20);
        let clip = clipped(&long);
        assert_eq!(clip.chars().filter(|&c| c == 'é').count(), MAX_QUOTED_CHARS);
        assert!(clip.ends_with(&format!("... ({} more bytes)", 2 * ((1 << 20) - MAX_QUOTED_CHARS))), "{clip}");
    }

    #[test]
    fn invalid_messages_are_counted_by_topic() {
        let mut rejections = Rejections::default();
        let valid = TerrainScan { resolution_m: 0.1, ..TerrainScan::default() };
        assert!(rejections.accept("rover/terrain", &valid));
        assert!(!rejections.accept("rover/terrain", &TerrainScan::default()));
        rejections.reject("out_of_order", &"scan of frame 3 arrived after frame 4");
        assert_eq!(rejections.count("rover/terrain"), 1);
        assert_eq!(rejections.to_string(), "1 out_of_order, 1 rover/terrain");
        assert_eq!(Rejections::default().to_string(), "none");
    }

    #[test]
    fn repeated_problems_are_logged_ever_more_rarely() {
        let logged: Vec<u64> = (1..=100).filter(|&count| worth_logging(count)).collect();
        assert_eq!(logged, vec![1, 2, 4, 8, 16, 32, 64]);
    }
}
