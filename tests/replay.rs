//! Perception and mapping on the 283 recorded Udacity frames: the scores of the libraries, the same
//! scores from the real nodes over DDS, and the nodes' handling of bad input.

mod support;

use std::time::{Duration, Instant};

use rover_msgs::builtin_interfaces::Time;
use rover_msgs::msg::{MapStats, Telemetry, TerrainScan};
use rover_msgs::sensor_msgs::CompressedImage;
use rover_msgs::std_msgs::Header;
use rover_runtime::{Publisher, RosNode, Runtime, topics};
use support::{
    Domain, Latest, Process, STOP_TIMEOUT, eventually, map_bw_png, rover, start_process, test_dataset_dir, test_runtime,
};

fn replay_json(args: &[&str], domain: Option<&Domain>) -> serde_json::Value {
    let mut command = std::process::Command::new(rover());
    command.arg("replay").arg(test_dataset_dir()).args(args).arg("--json");
    if let Some(domain) = domain {
        command.env("ROS_DOMAIN_ID", domain.id.to_string());
    }
    let output = command.output().expect("run rover replay");
    assert!(output.status.success(), "rover replay failed: {}", String::from_utf8_lossy(&output.stderr));
    serde_json::from_slice(&output.stdout).expect("one JSON object")
}

#[test]
fn the_libraries_map_the_test_dataset_with_at_least_85_percent_fidelity_and_20_percent_mapped() {
    let report = replay_json(&["--ground-truth", &map_bw_png()], None);
    eprintln!("{report}");
    assert_eq!(report["frames"], 283);
    let (mapped, fidelity) = (report["mapped_pct"].as_f64().unwrap(), report["fidelity_pct"].as_f64().unwrap());
    assert!(fidelity >= 85.0, "fidelity {fidelity}");
    assert!(mapped >= 20.0, "mapped {mapped}");
    assert!(report["perception_ms_median"].as_f64().unwrap() > 0.0);
    assert!(report["rocks_located"].as_u64().is_some());
}

fn start_perception(domain: &Domain) -> Process {
    start_process(&rover(), &["perception"], domain, "perception")
}

fn start_mapping(domain: &Domain) -> Process {
    start_process(
        &rover(),
        &[
            "mapping",
            "--ros-args",
            "-p",
            &format!("ground_truth_png:={}", map_bw_png()),
            "-p",
            "publish_max_delay_ms:=100.0",
        ],
        domain,
        "mapping",
    )
}

fn start_nodes(domain: &Domain) -> (Process, Process) {
    (start_perception(domain), start_mapping(domain))
}

#[test]
fn the_nodes_over_dds_give_the_same_map_as_the_libraries() {
    support::assert_isolated();
    let offline = replay_json(&["--ground-truth", &map_bw_png()], None);
    let domain = Domain::reserve();
    let (_perception, _mapping) = start_nodes(&domain);
    let over_dds = replay_json(&["--via-dds"], Some(&domain));
    eprintln!("offline {offline}\nover DDS {over_dds}");
    assert_eq!(over_dds["frames_rejected"], 0, "every frame got its terrain scan");
    assert_eq!(over_dds["mapped_pct"], offline["mapped_pct"]);
    assert_eq!(over_dds["fidelity_pct"], offline["fidelity_pct"]);
    assert_eq!(over_dds["navigable_cells"], offline["navigable_cells"]);
}

fn stamp(sec: i32) -> Header {
    Header { stamp: Time { sec, nanosec: 0 }, frame_id: "odom".into() }
}

fn telemetry(frame: u64, sec: i32, x_m: f64) -> Telemetry {
    Telemetry { header: stamp(sec), frame, x_m, y_m: 85.6, yaw_rad: 1.0, ..Telemetry::default() }
}

/// The test's own node: it sends camera frames and telemetry to perception, sees the terrain scans
/// that perception publishes, sends scans of its own to mapping and sees its statistics.
struct Tester {
    camera: Publisher<CompressedImage>,
    telemetry: Publisher<Telemetry>,
    scans_out: Publisher<TerrainScan>,
    scans: Latest<TerrainScan>,
    stats: Latest<MapStats>,
    /// The node the publishers and subscriptions belong to, kept alive.
    _node: RosNode,
}

impl Tester {
    fn new(runtime: &Runtime) -> Self {
        let (mut node, _) = runtime.node::<rover_runtime::NoParams>("tester").unwrap();
        Tester {
            camera: node.publisher(&topics::CAMERA_COMPRESSED).unwrap(),
            telemetry: node.publisher(&topics::TELEMETRY).unwrap(),
            scans_out: node.publisher(&topics::TERRAIN).unwrap(),
            scans: Latest::subscribe(&mut node, &topics::TERRAIN),
            stats: Latest::subscribe(&mut node, &topics::MAP_STATS),
            _node: node,
        }
    }

    /// Sends frame `frame`, stamped `sec`: its camera image and its telemetry at `x_m`.
    fn send(&self, sec: i32, frame: u64, jpeg: Vec<u8>, x_m: f64) {
        self.camera.publish(CompressedImage { header: stamp(sec), format: "jpeg".into(), data: jpeg }).unwrap();
        self.telemetry.publish(telemetry(frame, sec, x_m)).unwrap();
    }

    /// Sends the recorded frame `good` (frames 1, 2, ...) every 100 ms until perception answers;
    /// the last scan seen by then.
    async fn await_scan(&self, good: &[u8]) -> TerrainScan {
        let deadline = Instant::now() + Duration::from_secs(20);
        let mut sec = 1;
        while self.scans.last().is_none() && Instant::now() < deadline {
            self.send(sec, sec as u64, good.to_vec(), 99.7);
            sec += 1;
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
        self.scans.last().expect("the perception node answers good frames")
    }
}

/// A recorded camera frame of the dataset.
fn good_jpeg() -> Vec<u8> {
    std::fs::read(
        rover::tools::dataset::read_log(std::path::Path::new(&test_dataset_dir())).unwrap().frames[20].image.clone(),
    )
    .unwrap()
}

#[tokio::test(flavor = "multi_thread")]
async fn bad_frames_are_logged_counted_and_skipped() {
    support::assert_isolated();
    let domain = Domain::reserve();
    let (mut perception, mut mapping) = start_nodes(&domain);
    let runtime = test_runtime(&domain);
    let tester = Tester::new(&runtime);
    let good = good_jpeg();
    let small = rover_imaging::encode_jpeg(&rover_imaging::RgbImage::new(64, 32), 75).unwrap();
    tester.await_scan(&good).await;
    let mut truncated = good.clone();
    truncated.truncate(good.len() / 2);
    tester.send(1001, 1001, truncated, 99.7);
    tester.send(1002, 1002, small, 99.7);
    tester.send(1003, 1003, good.clone(), f64::NAN);
    tester.send(1004, 1004, good.clone(), 99.7);
    assert!(
        eventually(Duration::from_secs(10), || tester.scans.all().iter().any(|s| s.telemetry.frame == 1004)),
        "a good frame after the bad ones is processed"
    );
    assert!(
        !tester.scans.all().iter().any(|s| (1001..=1003).contains(&s.telemetry.frame)),
        "bad frames produce no scan"
    );
    let scan = tester.scans.all().into_iter().find(|s| s.telemetry.frame == 1004).unwrap();
    let with_telemetry = |frame, x_m| Telemetry { frame, x_m, ..scan.telemetry.clone() };
    tester.scans_out.publish(TerrainScan { telemetry: with_telemetry(1000, 99.7), ..scan.clone() }).unwrap();
    tester.scans_out.publish(TerrainScan { telemetry: with_telemetry(1005, f64::NAN), ..scan.clone() }).unwrap();
    let malformed = TerrainScan { telemetry: with_telemetry(1006, 99.7), rows: 3, cells: vec![1; 5], ..scan.clone() };
    tester.scans_out.publish(malformed).unwrap();
    let malformed_rejected = "field `cells` = 5 values";
    assert!(
        eventually(Duration::from_secs(10), || mapping.log_text().contains(malformed_rejected)),
        "the mapping node rejects the malformed scan:\n{}",
        mapping.log_text()
    );
    perception.interrupt(STOP_TIMEOUT);
    mapping.interrupt(STOP_TIMEOUT);
    let perception_log = perception.log_text();
    let mapping_log = mapping.log_text();
    assert_log_has(
        "perception",
        &perception_log,
        &[
            "rejected the camera image of frame 1001: truncated JPEG (no FF D9 end-of-image marker)",
            "rejected the camera image of frame 1002: image is 64x32, expected 320x160",
            "rejected a rover/telemetry message: field `x_m` = NaN (expected a number in [-10000, 10000])",
            "rejected 2 camera/image_raw/compressed, 1 rover/telemetry",
        ],
    );
    assert_log_has(
        "mapping",
        &mapping_log,
        &[
            "frame 1000 arrived after frame 1004",
            "rejected a rover/terrain message: field `telemetry.x_m` = NaN",
            "rejected a rover/terrain message: field `cells` = 5 values (expected rows x cols = 960)",
            "rejected 1 out_of_order, 2 rover/terrain",
        ],
    );
}

/// Scans sent to the mapping node right before it is asked to stop (after a first one): fewer than
/// its queue holds.
const SCANS_BEFORE_STOP: u64 = 8;

#[tokio::test(flavor = "multi_thread")]
async fn a_mapping_node_asked_to_stop_first_maps_the_scans_already_sent_to_it() {
    support::assert_isolated();
    let domain = Domain::reserve();
    let runtime = test_runtime(&domain);
    let tester = Tester::new(&runtime);
    let mut perception = start_perception(&domain);
    let scan = tester.await_scan(&good_jpeg()).await;
    perception.interrupt(STOP_TIMEOUT);
    let mut mapping = start_mapping(&domain);
    let scan_of = |frame: u64| TerrainScan {
        header: stamp(frame as i32),
        telemetry: Telemetry { frame, ..scan.telemetry.clone() },
        ..scan.clone()
    };
    // Frame 1 goes out until the node's statistics show it mapped: a reader drops the samples of a
    // writer it has not matched yet, and only then are both sides surely matched. The node skips
    // the repeats (they come no later than the scan it took).
    let deadline = Instant::now() + Duration::from_secs(20);
    let first_mapped = |t: &Tester| t.stats.last().is_some_and(|s| s.home_frame == 1);
    while !first_mapped(&tester) && Instant::now() < deadline {
        tester.scans_out.publish(scan_of(1)).unwrap();
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    assert!(first_mapped(&tester), "the mapping node maps frame 1:\n{}", mapping.log_text());
    for frame in 2..=SCANS_BEFORE_STOP + 1 {
        tester.scans_out.publish(scan_of(frame)).unwrap();
    }
    mapping.interrupt(STOP_TIMEOUT);
    let log = mapping.log_text();
    assert_log_has("mapping", &log, &[&format!("mapping: {} frames mapped", SCANS_BEFORE_STOP + 1)]);
}

fn assert_log_has(node: &str, log: &str, needles: &[&str]) {
    for needle in needles {
        assert!(log.contains(needle), "{node} log lacks {needle:?}:\n{log}");
    }
}
