//! `rover bag play`: a typed publisher per topic of the bag that is in the topic table, each
//! message deserialized and published at its log time relative to the first, divided by the rate;
//! a gap of more than [`MAX_GAP`] between messages is skipped, so that a bad stamp cannot stall
//! the playback for years.

use std::collections::HashMap;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use futures::future::BoxFuture;
use rover_bag::{BagMessage, BagReader, TopicInfo};
use rover_msgs::RosMessage;
use rover_runtime::rejections::worth_logging;
use rover_runtime::topics::{Topic, TopicVisitor, visit_all};
use rover_runtime::{NoParams, Publisher, RosNode, Runtime, Shutdown};

use super::{check_known, resolve_names};

/// The player's node name (as `ros2 bag play`'s).
const PLAYER_NODE: &str = "rosbag2_player";
/// How long `--wait-for` waits for a subscriber.
const SUBSCRIBER_WAIT: Duration = Duration::from_secs(30);
/// How long the player stays after the last message, so reliable readers get the last ones.
const DELIVERY_GRACE: Duration = Duration::from_secs(1);
/// How often the progress line is printed.
const PROGRESS_PERIOD: Duration = Duration::from_secs(5);
/// The slowest and fastest `--rate`.
const RATE_RANGE: std::ops::RangeInclusive<f64> = 0.001..=1000.0;
/// The longest gap in log time between consecutive messages that is played as recorded; a longer
/// one is skipped (with a warning).
const MAX_GAP: Duration = Duration::from_secs(60);
/// The latest a message is ever played after the start: later than any playback ends.
const MAX_OFFSET: Duration = Duration::from_secs(100 * 365 * 86_400);

/// Options of `rover bag play`.
#[derive(Debug, Clone, clap::Args)]
pub struct PlayArgs {
    /// The bag folder (with metadata.yaml).
    #[arg(value_name = "DIR")]
    pub bag: PathBuf,
    /// Play this many times faster than recorded (0.5: half as fast), from 0.001 to 1000. A gap of
    /// more than 60 s between consecutive messages (log time) is skipped, with a warning.
    #[arg(long, default_value_t = 1.0, value_parser = positive_rate, value_name = "R")]
    pub rate: f64,
    /// Play only these topics of the bag (default: every topic of the bag that is in the graph's
    /// topic table).
    #[arg(long, num_args = 1.., value_name = "TOPIC")]
    pub topics: Vec<String>,
    /// Before playing, wait (up to 30 s) until TOPIC has a subscriber; name a topic N times to
    /// wait for N subscribers.
    #[arg(long = "wait-for", value_name = "TOPIC")]
    pub wait_for: Vec<String>,
}

/// A `--rate` in [`RATE_RANGE`].
fn positive_rate(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(rate) if RATE_RANGE.contains(&rate) => Ok(rate),
        _ => Err(format!(
            "{text:?} is not a positive number from {} to {} (times as fast as recorded)",
            RATE_RANGE.start(),
            RATE_RANGE.end()
        )),
    }
}

/// The bag time played so far: log time since the first message, without the gaps skipped.
#[derive(Debug, Default)]
struct BagClock {
    /// The latest log time seen, nanoseconds.
    latest_ns: Option<u64>,
    /// Bag time played up to `latest_ns`, nanoseconds.
    played_ns: u64,
    /// Gaps skipped so far.
    skipped_gaps: u64,
}

impl BagClock {
    /// The bag time at which the message logged at `log_ns` is played: as recorded after the
    /// previous one, at once if logged earlier, right after it if more than [`MAX_GAP`] later.
    fn played_ns(&mut self, log_ns: u64) -> u64 {
        let gap_ns = self.latest_ns.map_or(0, |latest| log_ns.saturating_sub(latest));
        if gap_ns > duration_ns(MAX_GAP) {
            self.skipped_gaps += 1;
            if worth_logging(self.skipped_gaps) {
                tracing::warn!(
                    "skipped {:.1} s without messages in the bag before the message logged at {log_ns} ns: gaps over \
                     {MAX_GAP:?} are not played ({} such so far)",
                    gap_ns as f64 / 1e9,
                    self.skipped_gaps
                );
            }
        } else {
            self.played_ns = self.played_ns.saturating_add(gap_ns);
        }
        self.latest_ns = Some(self.latest_ns.map_or(log_ns, |latest| latest.max(log_ns)));
        self.played_ns
    }
}

/// `duration` in nanoseconds, saturated.
fn duration_ns(duration: Duration) -> u64 {
    u64::try_from(duration.as_nanos()).unwrap_or(u64::MAX)
}

/// When the message at bag time `played_ns` is due after the start at `rate`, at most
/// [`MAX_OFFSET`].
fn wall_offset(played_ns: u64, rate: f64) -> Duration {
    Duration::try_from_secs_f64(played_ns as f64 / 1e9 / rate).map_or(MAX_OFFSET, |offset| offset.min(MAX_OFFSET))
}

/// Publishes one topic's messages from their serialized bytes.
trait CdrPublisher: Send {
    /// Deserializes `data` into the topic's message type and publishes it.
    fn publish_cdr(&self, data: &[u8]) -> anyhow::Result<()>;
    /// Resolves once a subscription has matched.
    fn first_subscription<'a>(&'a self, node: &'a RosNode) -> BoxFuture<'a, ()>;
    /// Subscriptions matched so far (known only after the first).
    fn subscriptions(&self, node: &RosNode) -> usize;
}

impl<M: RosMessage> CdrPublisher for Publisher<M> {
    fn publish_cdr(&self, data: &[u8]) -> anyhow::Result<()> {
        let message = rover_runtime::cdr::decode::<M>(data)?;
        self.publish(message).map_err(|e| anyhow::anyhow!("cannot publish a {}: {e}", M::type_name()))
    }

    fn first_subscription<'a>(&'a self, node: &'a RosNode) -> BoxFuture<'a, ()> {
        Box::pin(node.subscription_matched(self))
    }

    fn subscriptions(&self, node: &RosNode) -> usize {
        node.subscription_count(self)
    }
}

/// Creates a publisher for each topic of the table among `wanted`, keyed by resolved name.
struct Publishers<'a> {
    node: &'a mut RosNode,
    wanted: &'a [TopicInfo],
    made: HashMap<String, Box<dyn CdrPublisher>>,
}

impl TopicVisitor for Publishers<'_> {
    fn visit<M: RosMessage>(&mut self, topic: &Topic<M>) -> anyhow::Result<()> {
        let name = self.node.identity().resolve_topic(topic.name)?;
        let Some(info) = self.wanted.iter().find(|t| t.name == name) else {
            return Ok(());
        };
        if info.type_name != M::type_name() {
            tracing::warn!("not playing {name}: the bag has {}, the graph {}", info.type_name, M::type_name());
            return Ok(());
        }
        self.made.insert(name, Box::new(self.node.publisher(topic)?));
        Ok(())
    }
}

/// The bag's topics to play: those named by `--topics` (all when none), checked to be in the bag.
fn wanted_topics(node: &RosNode, bag: &BagReader, requested: &[String]) -> anyhow::Result<Vec<TopicInfo>> {
    let topics = bag.topics();
    if requested.is_empty() {
        return Ok(topics);
    }
    let requested = resolve_names(node.identity(), requested)?;
    let in_bag: Vec<String> = topics.iter().map(|t| t.name.clone()).collect();
    check_known(&requested, &in_bag, "in the bag")?;
    Ok(topics.into_iter().filter(|t| requested.contains(&t.name)).collect())
}

/// A publisher for each wanted topic that the graph knows; topics it does not know are named.
fn publishers(node: &mut RosNode, wanted: &[TopicInfo]) -> anyhow::Result<HashMap<String, Box<dyn CdrPublisher>>> {
    let mut factory = Publishers { node, wanted, made: HashMap::new() };
    visit_all(&mut factory)?;
    let made = factory.made;
    for topic in wanted.iter().filter(|t| !made.contains_key(&t.name)) {
        tracing::warn!("not playing {} ({}): not a topic of the graph's table", topic.name, topic.type_name);
    }
    anyhow::ensure!(!made.is_empty(), "none of the bag's topics is a topic of the graph's table");
    Ok(made)
}

/// Waits until each of `topics` (resolved names of played topics) has as many subscribers as it
/// is named.
async fn wait_for_subscribers(
    node: &RosNode,
    publishers: &HashMap<String, Box<dyn CdrPublisher>>,
    topics: &[String],
) -> anyhow::Result<()> {
    let played: Vec<String> = publishers.keys().cloned().collect();
    check_known(topics, &played, "played")?;
    let wanted = |topic: &String| topics.iter().filter(|t| *t == topic).count();
    let deadline = tokio::time::Instant::now() + SUBSCRIBER_WAIT;
    for topic in topics {
        tokio::time::timeout_at(deadline, publishers[topic].first_subscription(node))
            .await
            .map_err(|_| anyhow::anyhow!("no subscriber on {topic} within {SUBSCRIBER_WAIT:?}"))?;
    }
    while let Some(waiting) = topics.iter().find(|t| publishers[*t].subscriptions(node) < wanted(t)) {
        anyhow::ensure!(
            tokio::time::Instant::now() < deadline,
            "{waiting} has {} of the {} subscribers waited for after {SUBSCRIBER_WAIT:?}",
            publishers[waiting].subscriptions(node),
            wanted(waiting)
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    Ok(())
}

/// What a playback did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Played {
    /// Messages published.
    pub messages: u64,
    /// Bag time covered, seconds (log time of the last message played minus the first's, less the
    /// gaps skipped).
    pub bag_seconds: f64,
    /// Whether shutdown stopped it before the end.
    pub interrupted: bool,
}

/// Publishes the bag's messages of the played topics at their times divided by `rate`.
async fn play_messages(
    bag: &BagReader,
    publishers: &HashMap<String, Box<dyn CdrPublisher>>,
    rate: f64,
    shutdown: &Shutdown,
) -> anyhow::Result<Played> {
    let (started, mut clock, mut played) = (tokio::time::Instant::now(), BagClock::default(), Played::default());
    let mut next_progress = Instant::now() + PROGRESS_PERIOD;
    for message in bag.messages() {
        let BagMessage { topic, time, data } = message?;
        let Some(publisher) = publishers.get(&topic) else { continue };
        let played_ns = clock.played_ns(time.log_ns);
        let bag_seconds = played_ns as f64 / 1e9;
        tokio::select! {
            () = tokio::time::sleep_until(started + wall_offset(played_ns, rate)) => {}
            () = shutdown.wait() => return Ok(Played { interrupted: true, ..played }),
        }
        if let Err(e) = publisher.publish_cdr(&data) {
            tracing::warn!("{topic}: {e:#}");
            continue;
        }
        played = Played { messages: played.messages + 1, bag_seconds, interrupted: false };
        if Instant::now() >= next_progress {
            eprintln!("playing: {:.1} s of the bag, {} messages", played.bag_seconds, played.messages);
            next_progress += PROGRESS_PERIOD;
        }
    }
    Ok(played)
}

/// Runs `rover bag play` until the end of the bag or shutdown.
pub async fn play(args: &PlayArgs, runtime: &Runtime) -> anyhow::Result<Played> {
    let bag = BagReader::open(&args.bag)?;
    let (mut node, _) = runtime.node::<NoParams>(PLAYER_NODE)?;
    let wanted = wanted_topics(&node, &bag, &args.topics)?;
    let publishers = publishers(&mut node, &wanted)?;
    let wait_for = resolve_names(node.identity(), &args.wait_for)?;
    wait_for_subscribers(&node, &publishers, &wait_for).await?;
    let played = play_messages(&bag, &publishers, args.rate, &runtime.shutdown()).await?;
    tokio::time::sleep(DELIVERY_GRACE).await;
    println!(
        "played {} messages of {} topics from {}: {:.1} s of the bag at rate {}{}",
        played.messages,
        publishers.len(),
        args.bag.display(),
        played.bag_seconds,
        args.rate,
        if played.interrupted { " (interrupted)" } else { "" }
    );
    Ok(played)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rates_outside_the_range_or_not_numbers_are_refused_naming_them() {
        assert_eq!(positive_rate("0.5"), Ok(0.5));
        assert_eq!(positive_rate("1000"), Ok(1000.0));
        for bad in ["0", "-1", "1e-300", "0.0009", "1001", "NaN", "inf", "-inf", "fast", ""] {
            let error = positive_rate(bad).unwrap_err();
            assert!(error.contains(&format!("{bad:?}")) && error.contains("from 0.001 to 1000"), "{error}");
        }
    }

    #[test]
    fn extreme_gaps_are_skipped_and_earlier_stamps_played_at_once() {
        let mut clock = BagClock::default();
        let played: Vec<u64> = [u64::MAX / 2, u64::MAX / 2 + 5, 0, u64::MAX / 2 + 7, u64::MAX, u64::MAX, 1]
            .map(|ns| clock.played_ns(ns))
            .to_vec();
        assert_eq!(played, [0, 5, 5, 7, 7, 7, 7]);
        assert_eq!(clock.skipped_gaps, 1);
        let mut clock = BagClock::default();
        let minute_ns = duration_ns(MAX_GAP);
        assert_eq!([0, minute_ns, minute_ns + 1 + minute_ns].map(|ns| clock.played_ns(ns)), [0, minute_ns, minute_ns]);
    }

    #[test]
    fn waits_saturate_instead_of_overflowing() {
        assert_eq!(wall_offset(2_000_000_000, 2.0), Duration::from_secs(1));
        assert_eq!(wall_offset(u64::MAX, *RATE_RANGE.start()), MAX_OFFSET);
        assert_eq!(wall_offset(u64::MAX, f64::MIN_POSITIVE), MAX_OFFSET);
        assert_eq!(wall_offset(u64::MAX, 0.0), MAX_OFFSET);
        assert_eq!(wall_offset(0, f64::NAN), MAX_OFFSET);
        assert!(tokio::time::Instant::now().checked_add(MAX_OFFSET).is_some());
    }

    mod fuzz {
        use proptest::prelude::*;
        use rover_fuzzing::messages::{occupancy_grid, telemetry, terrain_scan};
        use rover_fuzzing::mutation::mutated_bytes;

        use super::*;

        /// Decodes bytes as the message type of every topic of the table, as `rover bag play`
        /// decodes a bag's messages before publishing them.
        struct DecodeAsEveryTopic<'a>(&'a [u8]);

        impl TopicVisitor for DecodeAsEveryTopic<'_> {
            fn visit<M: RosMessage>(&mut self, _topic: &Topic<M>) -> anyhow::Result<()> {
                let _ = rover_runtime::cdr::decode::<M>(self.0);
                Ok(())
            }
        }

        /// The CDR bytes of a hostile telemetry frame, terrain scan or map, as a bag stores them.
        fn bag_message() -> impl Strategy<Value = Vec<u8>> {
            let encoded = |message: anyhow::Result<Vec<u8>>| message.expect("a message encodes");
            prop_oneof![
                telemetry().prop_map(move |m| encoded(rover_runtime::cdr::encode(&m))),
                terrain_scan().prop_map(move |m| encoded(rover_runtime::cdr::encode(&m))),
                occupancy_grid().prop_map(move |m| encoded(rover_runtime::cdr::encode(&m))),
            ]
        }

        proptest! {
            #[test]
            fn fuzz_bag_cdr_decoded_as_every_topic(bytes in bag_message().prop_flat_map(mutated_bytes)) {
                visit_all(&mut DecodeAsEveryTopic(&bytes)).unwrap();
            }
        }
    }
}
