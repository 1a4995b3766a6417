//! `rover bag`: a short demo mission recorded with `rover demo --record`, read back by rosbags and
//! rclpy (`tests/python/bag_check.py`) and played into a fresh mapping node, which must end with
//! the recorded map statistics; the Udacity test dataset turned into a bag and played through
//! perception and mapping, which must score as `rover replay` does. Recordings killed or stopped
//! by a full disk stay bags of what was written; hostile bag folders and playback rates are refused
//! with errors that name them, never a hang or a panic.

mod support;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use rover_bag::{BagReader, BagWriter, MessageTime, QosProfile, TopicInfo};
use rover_msgs::RosMessage;
use rover_msgs::msg::MapStats;
use rover_msgs::sensor_msgs::CompressedImage;
use rover_runtime::topics;
use support::{Domain, Latest, Process, eventually, map_bw_png, rover, start_process, test_dataset_dir, test_runtime};

/// Simulated seconds of the recorded mission.
const MISSION_SIM_SECONDS: &str = "40";
/// How long the mapping node waits after its last scan before it publishes.
const PUBLISH_DELAY_MS: &str = "publish_max_delay_ms:=100.0";
/// How long without new map statistics, after the end of playback, means the final ones came.
const STATS_QUIET: Duration = Duration::from_secs(1);
/// How long after the end of playback the final map statistics may take.
const FINAL_STATS_TIMEOUT: Duration = Duration::from_secs(30);
/// How long the mapping node may take to subscribe to `rover/terrain`.
const SUBSCRIBER_WAIT: Duration = Duration::from_secs(30);
/// How long a `rover` run that must end on its own may take.
const QUICK_EXIT: Duration = Duration::from_secs(30);
/// How long the test publishes into a recorder before killing it.
const RECORD_BEFORE_KILL: Duration = Duration::from_millis(3500);
/// The test publisher's period.
const PUBLISH_PERIOD: Duration = Duration::from_millis(10);
/// The file size limit (`ulimit -f`, KiB) that stands for a full disk.
const FULL_DISK_KIB: u32 = 512;
/// Time for the other participants to match the mapping node's reader once the test's writer has
/// (discovery runs in every participant at once).
const MATCH_WAIT: Duration = Duration::from_secs(1);

fn scratch_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rover-test-bag-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create the test folder");
    dir
}

/// A topic as the recorder's summary lists it: type and message count.
type Reported = BTreeMap<String, (String, u64)>;

/// The topic lines of a bag summary (`  /topic  pkg/msg/Type  count`).
fn reported_topics(summary: &str) -> Reported {
    summary
        .lines()
        .filter_map(|line| {
            let fields: Vec<&str> = line.split_whitespace().collect();
            match fields[..] {
                [topic, type_name, count] if line.starts_with("  /") => {
                    Some((topic.to_string(), (type_name.to_string(), count.parse().ok()?)))
                }
                _ => None,
            }
        })
        .collect()
}

/// The recorded mission: the bag, what the recorder reported and the mapping node's log.
struct Recorded {
    bag: PathBuf,
    reported: Reported,
    mapping_log: PathBuf,
}

/// The frames a mapping node's log says it mapped (its last line: `mapping: N frames mapped, ...`).
fn frames_mapped(log: &str) -> Option<u64> {
    log.lines().rev().find_map(|line| line.split("mapping: ").nth(1)?.split(" frames mapped").next()?.parse().ok())
}

/// Records a short mission on `map_bw.png` once for the tests of this file.
fn recorded_mission() -> &'static Recorded {
    static RECORDED: OnceLock<Recorded> = OnceLock::new();
    RECORDED.get_or_init(|| record_mission("mission"))
}

/// Records a short mission on `map_bw.png` with `rover demo --record` in the folder `name`.
fn record_mission(name: &str) -> Recorded {
    support::assert_isolated();
    let domain = Domain::reserve();
    let dir = scratch_dir(name);
    let bag = dir.join("mission_bag");
    let output = Command::new(rover())
        .args(["demo", "--map", &map_bw_png(), "--max-sim-seconds", MISSION_SIM_SECONDS, "--no-respawn"])
        .arg("--out")
        .arg(dir.join("demo"))
        .arg("--record")
        .arg(&bag)
        .args(["--ros-args", "-p", &format!("mapping:ground_truth_png:={}", map_bw_png())])
        .args(["-p", &format!("mapping:{PUBLISH_DELAY_MS}")])
        .env("ROS_DOMAIN_ID", domain.id.to_string())
        .output()
        .expect("run rover demo --record");
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(output.status.success(), "rover demo failed:\n{stdout}\n{}", String::from_utf8_lossy(&output.stderr));
    eprintln!("{stdout}");
    Recorded { bag, reported: reported_topics(&stdout), mapping_log: dir.join("demo/logs/mapping.log") }
}

/// The last message of type `M` on `topic` in the bag `dir`.
fn last_in_bag<M: rover_msgs::RosMessage>(dir: &Path, topic: &str) -> M {
    let bag = BagReader::open(dir).expect("open the bag");
    let last = bag.messages().map(|m| m.expect("read the bag")).filter(|m| m.topic == topic).last();
    rover_runtime::cdr::decode(&last.unwrap_or_else(|| panic!("no {topic} in the bag")).data).expect("decode")
}

#[test]
fn the_recorder_reports_every_topic_of_the_table_and_the_mission_traffic() {
    let recorded = recorded_mission();
    assert_eq!(recorded.reported.len(), rover_runtime::topics::all_names().len(), "{:?}", recorded.reported);
    let count = |topic: &str| recorded.reported[topic].1;
    let frames = count("/rover/telemetry");
    assert!(frames >= 900, "{frames} telemetry frames for {MISSION_SIM_SECONDS} sim s");
    // The recorder's reader of each topic matches the bridge's writer on its own, so the first
    // frame or two may be recorded on some of these topics and not on others.
    for topic in ["/camera/image_raw/compressed", "/camera/camera_info", "/odom", "/tf", "/clock"] {
        let messages = count(topic);
        assert!(
            messages.abs_diff(frames) <= 3,
            "{topic}: {messages} messages for {frames} frames, one per frame expected"
        );
    }
    // The frames still in flight when the simulator stops may go unanswered (and, as above, the
    // first frames may reach the recorder's telemetry reader late).
    for topic in ["/rover/terrain", "/rover/drive_cmd"] {
        let answers = count(topic);
        assert!((frames - 3..=frames + 3).contains(&answers), "{topic}: {answers} answers to {frames} frames");
    }
    // Each map goes out with its statistics, but the recorder's two readers match the mapping
    // node's writers one at a time, so either may miss the first few (a late map reader still
    // gets the latched map); which one matches first varies with the machine's load.
    let (maps, statistics) = (count("/map"), count("/rover/map_stats"));
    assert!(statistics >= 30 && maps.abs_diff(statistics) <= 3, "{maps} maps and {statistics} statistics");
    assert_eq!(count("/tf_static"), 1);
    assert_eq!(recorded.reported["/rover/terrain"].0, "rover_msgs/msg/TerrainScan");
}

#[test]
fn rosbags_and_rclpy_read_every_message_of_the_recorded_mission() {
    let Some(python) = support::python_with(&["rosbags.rosbag2", "rclpy", "rosidl_runtime_py", "rover_msgs.msg"])
    else {
        return;
    };
    let recorded = recorded_mission();
    let expected: serde_json::Map<String, serde_json::Value> = recorded
        .reported
        .iter()
        .map(|(topic, (type_name, count))| (topic.clone(), serde_json::json!({"type": type_name, "count": count})))
        .collect();
    let output = Command::new(python)
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/python/bag_check.py"))
        .arg(&recorded.bag)
        .arg(serde_json::Value::Object(expected).to_string())
        .output()
        .expect("run bag_check.py");
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(output.status.success(), "bag_check.py: {}\n{stdout}", String::from_utf8_lossy(&output.stderr));
    let result: serde_json::Value = serde_json::from_str(&stdout).expect("one JSON object");
    eprintln!("{result}");
    let total: u64 = recorded.reported.values().map(|(_, count)| count).sum();
    assert_eq!(result["decoded"], total, "every message decoded by rclpy and by rosbags");
    let stats: MapStats = last_in_bag(&recorded.bag, "/rover/map_stats");
    assert_eq!(result["last_map_stats"]["navigable_cells"], stats.navigable_cells);
    assert!((result["last_map_stats"]["mapped_pct"].as_f64().unwrap() - stats.mapped_pct as f64).abs() < 1e-4);
}

/// Plays `bag` (`play_args` after the folder) on `domain`, once the mapping node subscribes to
/// `rover/terrain`, and returns the last map statistics that a subscriber of the test got from
/// the nodes. Needs a tokio runtime (the test's node).
fn play_and_read_map_stats(domain: &Domain, bag: &Path, play_args: &[&str]) -> MapStats {
    let runtime = test_runtime(domain);
    let (mut node, _) = runtime.node::<rover_runtime::NoParams>("bag_test").expect("test node");
    let stats = Latest::subscribe(&mut node, &topics::MAP_STATS);
    let terrain = node.publisher(&topics::TERRAIN).expect("a rover/terrain publisher");
    let mapping_ready = eventually(SUBSCRIBER_WAIT, || node.subscription_count(&terrain) >= 1);
    assert!(mapping_ready, "the mapping node subscribes to rover/terrain");
    std::thread::sleep(MATCH_WAIT);
    let mut player =
        start_process(&rover(), &[&["bag", "play", bag.to_str().unwrap()], play_args].concat(), domain, "player");
    let status = player.wait_for_exit(Duration::from_secs(180)).expect("the player ends at the end of the bag");
    assert!(status.success(), "rover bag play failed:\n{}", player.log_text());
    eprintln!("{}", player.log_text());
    final_stats(&stats)
}

/// The last map statistics, once none has come for [`STATS_QUIET`] (the mapping node publishes
/// its last ones shortly after its last scan, later when it is behind).
fn final_stats(stats: &Latest<MapStats>) -> MapStats {
    let (mut count, mut changed_at) = (0, Instant::now());
    let quiet = eventually(FINAL_STATS_TIMEOUT, || {
        let now = stats.all().len();
        if now != count {
            (count, changed_at) = (now, Instant::now());
        }
        count > 0 && changed_at.elapsed() >= STATS_QUIET
    });
    assert!(quiet, "map statistics still coming, or none, {FINAL_STATS_TIMEOUT:?} after playback ({count} received)");
    stats.last().expect("map statistics from the mapping node")
}

fn start_mapping(domain: &Domain) -> Process {
    start_process(
        &rover(),
        &["mapping", "--ros-args", "-p", &format!("ground_truth_png:={}", map_bw_png()), "-p", PUBLISH_DELAY_MS],
        domain,
        "mapping",
    )
}

/// A recorded mission's scans played into a fresh mapping node.
struct Replayed {
    recorded: MapStats,
    played: MapStats,
    /// Frames mapped by the mission's mapping node and by the fresh one.
    frames_mapped: (Option<u64>, Option<u64>),
    /// The scans of the bag and the frames mapped, in words.
    scans: String,
}

/// Plays the scans (each with its frame's telemetry) and sample truth of `recorded` into a fresh
/// mapping node.
fn replay_mission(recorded: &Recorded) -> Replayed {
    let domain = Domain::reserve();
    let mut mapping = start_mapping(&domain);
    let played = play_and_read_map_stats(
        &domain,
        &recorded.bag,
        &[
            "--topics",
            "rover/terrain",
            "sim/sample_truth",
            "--rate",
            "0.5",
            "--wait-for",
            "rover/terrain",
            "--wait-for",
            "sim/sample_truth",
        ],
    );
    mapping.interrupt(support::STOP_TIMEOUT);
    let recorded_log = std::fs::read_to_string(&recorded.mapping_log).unwrap_or_default();
    let frames = (frames_mapped(&recorded_log), frames_mapped(&mapping.log_text()));
    let scans = format!(
        "scans: {} in the bag, {:?} mapped by the mission's mapping node, {:?} by the fresh one",
        recorded.reported["/rover/terrain"].1, frames.0, frames.1
    );
    let stats = last_in_bag(&recorded.bag, "/rover/map_stats");
    eprintln!("recorded {stats:?}\nplayed   {played:?}\n{scans}");
    Replayed { recorded: stats, played, frames_mapped: frames, scans }
}

/// Missions recorded at most until one whose mapping node mapped every scan it was sent and
/// more than [`MIN_MAPPED_PCT`].
const MISSION_ATTEMPTS: usize = 3;
/// A recorded mission's map is worth comparing when more than this is mapped, per cent.
const MIN_MAPPED_PCT: f32 = 5.0;

#[tokio::test(flavor = "multi_thread")]
async fn the_recorded_scans_played_into_a_fresh_mapping_node_give_the_recorded_map() {
    let mut replayed = replay_mission(recorded_mission());
    // On a loaded machine the mission's mapping node can fall more than its reader's history
    // behind and lose scans that the recorder (a deeper history) kept; its map then differs
    // from the bag's through no fault of the bag. Late frames can also send the rover another
    // way, one that maps too little to be worth comparing. Such a mission is recorded again.
    for attempt in 1..MISSION_ATTEMPTS {
        if replayed.frames_mapped.0 == replayed.frames_mapped.1 && replayed.recorded.mapped_pct > MIN_MAPPED_PCT {
            break;
        }
        eprintln!(
            "the mission lost scans or mapped {} % ({}); recording another mission",
            replayed.recorded.mapped_pct, replayed.scans
        );
        replayed = replay_mission(&record_mission(&format!("mission-{attempt}")));
    }
    let Replayed { recorded, played, frames_mapped, scans } = replayed;
    assert!(frames_mapped.0.is_some() && frames_mapped.0 == frames_mapped.1, "{scans}");
    assert!(recorded.mapped_pct > MIN_MAPPED_PCT, "the recorded mission mapped {} %", recorded.mapped_pct);
    assert!(
        (played.mapped_pct - recorded.mapped_pct).abs() <= 0.1,
        "mapped {} vs {}; {scans}",
        played.mapped_pct,
        recorded.mapped_pct
    );
    assert!(
        (played.fidelity_pct - recorded.fidelity_pct).abs() <= 0.1,
        "fidelity {} vs {}; {scans}",
        played.fidelity_pct,
        recorded.fidelity_pct
    );
    assert_eq!(
        (played.navigable_cells, played.obstacle_cells),
        (recorded.navigable_cells, recorded.obstacle_cells),
        "navigable and obstacle cells; {scans}"
    );
}

fn replay_json() -> serde_json::Value {
    let output = Command::new(rover())
        .args(["replay", &test_dataset_dir(), "--ground-truth", &map_bw_png(), "--json"])
        .output()
        .expect("run rover replay");
    assert!(output.status.success(), "rover replay failed: {}", String::from_utf8_lossy(&output.stderr));
    serde_json::from_slice(&output.stdout).expect("one JSON object")
}

#[tokio::test(flavor = "multi_thread")]
async fn the_test_dataset_as_a_bag_plays_through_perception_and_mapping_to_the_replay_scores() {
    support::assert_isolated();
    let dir = scratch_dir("dataset");
    let bag = dir.join("test_dataset_bag");
    let output = Command::new(rover())
        .args(["bag", "from-dataset", &test_dataset_dir(), "-o", bag.to_str().unwrap()])
        .output()
        .expect("run rover bag from-dataset");
    assert!(output.status.success(), "from-dataset failed: {}", String::from_utf8_lossy(&output.stderr));
    let reported = reported_topics(&String::from_utf8_lossy(&output.stdout));
    assert_eq!(reported["/camera/image_raw/compressed"], ("sensor_msgs/msg/CompressedImage".to_string(), 283));
    assert_eq!(reported["/rover/telemetry"].1, 283);
    let domain = Domain::reserve();
    let _perception = start_process(&rover(), &["perception"], &domain, "perception");
    let _mapping = start_mapping(&domain);
    let played = play_and_read_map_stats(
        &domain,
        &bag,
        &["--rate", "2", "--wait-for", "camera/image_raw/compressed", "--wait-for", "rover/telemetry"],
    );
    let offline = replay_json();
    eprintln!("replay {offline}\nplayed {played:?}");
    let rounded = |value: f32| (value as f64 * 10.0).round() / 10.0;
    assert_eq!(rounded(played.mapped_pct), offline["mapped_pct"].as_f64().unwrap());
    assert_eq!(rounded(played.fidelity_pct), offline["fidelity_pct"].as_f64().unwrap());
    assert_eq!(played.navigable_cells as u64, offline["navigable_cells"].as_u64().unwrap());
}

#[test]
fn bad_inputs_are_named_without_a_panic() {
    support::assert_isolated();
    let dir = scratch_dir("bad");
    let run = |args: &[&str]| {
        let output = Command::new(rover()).args(args).env("ROS_DOMAIN_ID", "231").output().expect("run rover");
        assert!(!output.status.success(), "rover {args:?} succeeded");
        let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
        assert!(!stderr.contains("panicked"), "{stderr}");
        stderr
    };
    let missing = dir.join("missing");
    assert!(run(&["bag", "play", missing.to_str().unwrap()]).contains("does not exist"));
    assert!(run(&["bag", "play", dir.to_str().unwrap()]).contains("is not a rosbag2 bag"));
    let corrupt = dir.join("corrupt");
    std::fs::create_dir_all(&corrupt).unwrap();
    std::fs::write(
        corrupt.join("metadata.yaml"),
        "rosbag2_bagfile_information:\n  version: 9\n  storage_identifier: mcap\n  relative_file_paths: [corrupt_0.mcap]\n  duration: {nanoseconds: 0}\n  starting_time: {nanoseconds_since_epoch: 0}\n  message_count: 1\n  topics_with_message_count:\n  - topic_metadata: {name: /rover/telemetry, type: rover_msgs/msg/Telemetry, serialization_format: cdr}\n    message_count: 1\n",
    )
    .unwrap();
    std::fs::write(corrupt.join("corrupt_0.mcap"), b"\x89MCAP0\r\n\x01\xff\xff\xff\xff\xff\xff\xff\x7f").unwrap();
    let error = run(&["bag", "play", corrupt.to_str().unwrap()]);
    assert!(error.contains("corrupt_0.mcap"), "{error}");
    let existing = run(&["bag", "from-dataset", &test_dataset_dir(), "-o", dir.to_str().unwrap()]);
    assert!(existing.contains("already exists"), "{existing}");
    assert!(
        run(&["bag", "from-dataset", dir.to_str().unwrap(), "-o", dir.join("x").to_str().unwrap()])
            .contains("robot_log.csv")
    );
    let unknown = run(&["bag", "record", "-o", dir.join("y").to_str().unwrap(), "rover/nothing"]);
    assert!(
        unknown.contains("topic /rover/nothing is not in the graph's topic table")
            && unknown.contains("/rover/telemetry"),
        "{unknown}"
    );
    for rate in ["0", "-1", "1e-300", "NaN", "inf"] {
        let refused = run(&["bag", "play", dir.to_str().unwrap(), &format!("--rate={rate}")]);
        assert!(refused.contains(&format!("\"{rate}\" is not a positive number from 0.001 to 1000")), "{refused}");
    }
}

/// Runs `rover` with `args` on the DDS domain `domain_id`; fails the test if it is still running
/// after [`QUICK_EXIT`] (a hang) or panicked.
fn run_rover_quickly(args: &[&str], domain_id: u16) -> Output {
    let mut child = Command::new(rover())
        .args(args)
        .env("ROS_DOMAIN_ID", domain_id.to_string())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start rover");
    let deadline = Instant::now() + QUICK_EXIT;
    while child.try_wait().expect("wait for rover").is_none() {
        if Instant::now() >= deadline {
            let _ = child.kill();
            let output = child.wait_with_output().expect("rover's output");
            panic!("rover {args:?} still running after {QUICK_EXIT:?}: {}", String::from_utf8_lossy(&output.stderr));
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let output = child.wait_with_output().expect("rover's output");
    assert!(!String::from_utf8_lossy(&output.stderr).contains("panicked"), "rover {args:?} panicked");
    output
}

/// The stderr of a `rover` run that must fail (quickly, without a panic).
fn failure(args: &[&str]) -> String {
    let output = run_rover_quickly(args, 231);
    assert!(!output.status.success(), "rover {args:?} succeeded");
    String::from_utf8_lossy(&output.stderr).into_owned()
}

#[test]
fn storage_paths_outside_the_bag_folder_or_not_regular_files_are_refused_naming_them() {
    support::assert_isolated();
    let dir = scratch_dir("hostile");
    let bag = dir.join("hostile");
    std::fs::create_dir_all(&bag).unwrap();
    std::fs::write(dir.join("x"), b"\x89MCAP0\r\n").unwrap();
    assert!(Command::new("mkfifo").arg(bag.join("fifo.mcap")).status().unwrap().success());
    for (listed, expected) in [
        ("/etc/passwd", "is absolute; expected a file name relative to the bag folder"),
        ("../x", "has a '..' part; expected a file name relative to the bag folder"),
        ("fifo.mcap", "is a FIFO; expected a regular file"),
    ] {
        std::fs::write(bag.join("metadata.yaml"), metadata_listing(listed)).unwrap();
        for command in ["play", "info"] {
            let error = failure(&["bag", command, bag.to_str().unwrap()]);
            assert!(error.contains(&format!("storage file \"{listed}\" {expected}")), "{command} {listed}: {error}");
        }
    }
    std::fs::remove_file(bag.join("metadata.yaml")).unwrap();
    assert!(Command::new("mkfifo").arg(bag.join("metadata.yaml")).status().unwrap().success());
    let error = failure(&["bag", "play", bag.to_str().unwrap()]);
    assert!(error.contains("metadata.yaml") && error.contains("a FIFO (expected a regular file)"), "{error}");
}

/// A `metadata.yaml` of one MapStats message in the storage file `listed`.
fn metadata_listing(listed: &str) -> String {
    format!(
        "rosbag2_bagfile_information:\n  version: 9\n  storage_identifier: mcap\n  relative_file_paths: [{listed:?}]\n  \
         duration: {{nanoseconds: 0}}\n  starting_time: {{nanoseconds_since_epoch: 0}}\n  message_count: 1\n  \
         topics_with_message_count:\n  - topic_metadata: {{name: /rover/map_stats, type: rover_msgs/msg/MapStats, \
         serialization_format: cdr}}\n    message_count: 1\n"
    )
}

#[test]
fn a_bag_with_an_extreme_stamp_gap_plays_at_once_at_the_slowest_rate() {
    support::assert_isolated();
    let domain = Domain::reserve();
    let bag = scratch_dir("gap").join("gap_bag");
    let mut writer = BagWriter::create(&bag).unwrap();
    let info = TopicInfo {
        name: "/rover/map_stats".into(),
        type_name: MapStats::type_name(),
        qos: QosProfile::keep_last(10, true, false),
    };
    let stats = writer.add_topic(info, &rover_bag::schema::schema_text(&MapStats::definitions())).unwrap();
    let data = rover_runtime::cdr::encode(&MapStats::default()).unwrap();
    for log_ns in [1_000, u64::MAX - 1, 2] {
        writer.write(stats, MessageTime { log_ns, publish_ns: log_ns }, &data).unwrap();
    }
    writer.finish().unwrap();
    let output = run_rover_quickly(&["bag", "play", bag.to_str().unwrap(), "--rate", "0.001"], domain.id);
    let (stdout, stderr) = (String::from_utf8_lossy(&output.stdout), String::from_utf8_lossy(&output.stderr));
    assert!(output.status.success() && stdout.contains("played 3 messages"), "{stdout}\n{stderr}");
    assert!(stderr.contains("gaps over 60s are not played"), "{stderr}");
}

/// The messages of each topic that `rover bag info` lists for `bag`, and whether it says the
/// recording was interrupted.
fn bag_info(bag: &Path) -> (Reported, bool) {
    let output = run_rover_quickly(&["bag", "info", bag.to_str().unwrap()], 231);
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(output.status.success(), "rover bag info: {}", String::from_utf8_lossy(&output.stderr));
    eprintln!("{stdout}");
    (reported_topics(&stdout), stdout.contains("unfinished:"))
}

#[tokio::test(flavor = "multi_thread")]
async fn a_recording_killed_midway_is_listed_and_played_up_to_its_last_checkpoint() {
    support::assert_isolated();
    let domain = Domain::reserve();
    let bag = scratch_dir("killed").join("killed_bag");
    let runtime = test_runtime(&domain);
    let (mut node, _) = runtime.node::<rover_runtime::NoParams>("bag_kill_test").expect("test node");
    let stats = node.publisher(&topics::MAP_STATS).expect("a rover/map_stats publisher");
    let mut recorder = start_process(
        &rover(),
        &["bag", "record", "-o", bag.to_str().unwrap(), "rover/map_stats"],
        &domain,
        "recorder",
    );
    assert!(eventually(SUBSCRIBER_WAIT, || node.subscription_count(&stats) >= 1), "the recorder subscribes");
    let (started, mut sent) = (Instant::now(), 0);
    while started.elapsed() < RECORD_BEFORE_KILL {
        stats.publish(MapStats { navigable_cells: sent, ..MapStats::default() }).expect("publish");
        sent += 1;
        std::thread::sleep(PUBLISH_PERIOD);
    }
    recorder.kill();
    let (listed, unfinished) = bag_info(&bag);
    let listed = listed["/rover/map_stats"].1;
    assert!(unfinished, "rover bag info does not say the recording was interrupted");
    assert!(listed >= u64::from(sent) / 4, "{listed} of {sent} messages listed after {RECORD_BEFORE_KILL:?}");
    let read: Vec<u32> = BagReader::open(&bag)
        .expect("open the killed recording")
        .messages()
        .map(|m| rover_runtime::cdr::decode::<MapStats>(&m.expect("read the killed recording").data).unwrap())
        .map(|m| m.navigable_cells)
        .collect();
    assert!(read.len() as u64 >= listed, "{} messages read, {listed} listed", read.len());
    assert_eq!(read, (0..read.len() as u32).collect::<Vec<_>>(), "the messages in the order sent");
    let played = run_rover_quickly(&["bag", "play", bag.to_str().unwrap(), "--rate", "10"], domain.id);
    let stdout = String::from_utf8_lossy(&played.stdout);
    assert!(played.status.success(), "rover bag play: {}", String::from_utf8_lossy(&played.stderr));
    assert!(stdout.contains(&format!("played {} messages", read.len())), "{stdout}");
}

#[tokio::test(flavor = "multi_thread")]
async fn a_recording_stopped_by_a_full_disk_ends_with_an_error_and_keeps_what_it_listed() {
    support::assert_isolated();
    let domain = Domain::reserve();
    let bag = scratch_dir("full").join("full_bag");
    let runtime = test_runtime(&domain);
    let (mut node, _) = runtime.node::<rover_runtime::NoParams>("bag_full_test").expect("test node");
    let camera = node.publisher(&topics::CAMERA_COMPRESSED).expect("a camera publisher");
    // A file size limit, its signal ignored, makes writes past it fail as on a full disk.
    let limited = format!("trap '' XFSZ; ulimit -f {FULL_DISK_KIB}; exec \"$0\" \"$@\"");
    let rover = rover();
    let args = [
        limited.as_str(),
        rover.to_str().unwrap(),
        "bag",
        "record",
        "-o",
        bag.to_str().unwrap(),
        "camera/image_raw/compressed",
    ];
    let mut recorder = start_process(Path::new("bash"), &[&["-c"], &args[..]].concat(), &domain, "full-recorder");
    assert!(eventually(SUBSCRIBER_WAIT, || node.subscription_count(&camera) >= 1), "the recorder subscribes");
    let started = Instant::now();
    for frame in 0u32.. {
        if recorder.exited().is_some() || started.elapsed() > QUICK_EXIT {
            break;
        }
        let image =
            CompressedImage { format: "jpeg".into(), data: vec![frame as u8; 8192], ..CompressedImage::default() };
        camera.publish(image).expect("publish");
        std::thread::sleep(PUBLISH_PERIOD * 5);
    }
    let status = recorder.wait_for_exit(support::STOP_TIMEOUT).expect("the recorder stops when the disk is full");
    let log = recorder.log_text();
    assert!(!status.success(), "{log}");
    assert!(log.contains("File too large") && log.contains("the recording stopped there"), "{log}");
    let reader = BagReader::open(&bag).expect("open the bag of a full disk");
    let listed = reader.metadata().message_count;
    let read = reader.messages().collect::<Result<Vec<_>, _>>().expect("read the bag of a full disk").len() as u64;
    assert!(listed > 0 && read >= listed, "{read} messages read, {listed} listed");
    assert!(log.contains(&format!("metadata.yaml lists the {listed} messages")), "{log}");
}
