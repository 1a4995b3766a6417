//! `rover bag play`: a typed publisher per topic of the bag that is in the topic table, each
//! message deserialized and published at its log time relative to the first, divided by the rate.

use std::collections::HashMap;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use futures::future::BoxFuture;
use rover_bag::{BagMessage, BagReader, TopicInfo};
use rover_msgs::RosMessage;
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

/// Options of `rover bag play`.
#[derive(Debug, Clone, clap::Args)]
pub struct PlayArgs {
    /// The bag folder (with metadata.yaml).
    #[arg(value_name = "DIR")]
    pub bag: PathBuf,
    /// Play this many times faster than recorded (0.5: half as fast).
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

fn positive_rate(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(rate) if rate.is_finite() && rate > 0.0 => Ok(rate),
        _ => Err(format!("{text:?} is not a positive number")),
    }
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
    /// Bag time covered, seconds (log time of the last message played minus the first's).
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
    let (started, mut first_ns, mut played) = (tokio::time::Instant::now(), None, Played::default());
    let mut next_progress = Instant::now() + PROGRESS_PERIOD;
    for message in bag.messages() {
        let BagMessage { topic, time, data } = message?;
        let Some(publisher) = publishers.get(&topic) else { continue };
        let first = *first_ns.get_or_insert(time.log_ns);
        let bag_seconds = time.log_ns.saturating_sub(first) as f64 / 1e9;
        tokio::select! {
            () = tokio::time::sleep_until(started + Duration::from_secs_f64(bag_seconds / rate)) => {}
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
