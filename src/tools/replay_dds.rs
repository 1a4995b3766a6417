//! `rover replay --via-dds`: the recorded frames published as the bridge would publish them,
//! one at a time, each waiting for its terrain scan from the perception node (and sent again while
//! none comes); the map statistics of the mapping node are read once it has gone quiet after the
//! last frame.

use std::time::{Duration, Instant};

use futures::StreamExt;
use rover_bridge::convert::{FrameMessages, PinholeCamera};
use rover_msgs::builtin_interfaces::Time;
use rover_msgs::msg::MapStats;
use rover_runtime::{NoParams, Runtime, messages, topics};

use crate::tools::dataset::RecordedFrame;
use crate::tools::replay::ReplayReport;

/// How long to wait for the terrain scan of a frame.
const SCAN_TIMEOUT: Duration = Duration::from_secs(5);
/// A frame without a terrain scan after this long is sent again with the same stamp: a node that
/// has just been discovered may miss the first samples. The mapping node skips a second scan of a
/// frame it has mapped (it comes no later than the last scan taken).
const RESEND_AFTER: Duration = Duration::from_secs(1);
/// How long to wait for the nodes to appear.
const DISCOVERY_TIMEOUT: Duration = Duration::from_secs(20);
/// After the last frame, the mapping node has mapped every scan once it publishes no statistics for
/// this long (it publishes while scans are left unpublished, at least every `publish_max_delay_ms`,
/// 500 ms by default).
const MAPPING_QUIET: Duration = Duration::from_millis(1500);
/// The longest wait for the mapping node to go quiet after the last frame.
const MAPPING_DONE_TIMEOUT: Duration = Duration::from_secs(30);

/// Replays `frames` through the running perception and mapping nodes.
pub(super) async fn replay_over_dds(frames: &[RecordedFrame], runtime: &Runtime) -> anyhow::Result<ReplayReport> {
    let (mut node, _) = runtime.node::<NoParams>("replay")?;
    let telemetry = node.publisher(&topics::TELEMETRY)?;
    let camera = node.publisher(&topics::CAMERA_COMPRESSED)?;
    let terrain_subscription = node.subscription(&topics::TERRAIN)?;
    let stats_subscription = node.subscription(&topics::MAP_STATS)?;
    let discovered = async {
        node.subscription_matched(&camera).await;
        node.subscription_matched(&telemetry).await;
        node.publisher_matched(&terrain_subscription).await;
        node.publisher_matched(&stats_subscription).await;
    };
    tokio::time::timeout(DISCOVERY_TIMEOUT, discovered)
        .await
        .map_err(|_| anyhow::anyhow!("no perception and mapping nodes answered within {DISCOVERY_TIMEOUT:?}"))?;
    let mut scans = std::pin::pin!(messages(terrain_subscription));
    let mut stats = std::pin::pin!(messages(stats_subscription));
    let (mut round_trips, mut lost, mut latest) = (Vec::new(), 0usize, None::<MapStats>);
    for (index, frame) in frames.iter().enumerate() {
        let number = index as u64 + 1;
        let messages =
            FrameMessages::new(&frame.sim_telemetry(frame.jpeg()?), number, Time::now(), &PinholeCamera::rover());
        let started = Instant::now();
        let answered = tokio::time::timeout(SCAN_TIMEOUT, async {
            loop {
                camera
                    .publish(messages.compressed.clone())
                    .map_err(|e| anyhow::anyhow!("cannot publish the camera frame: {e:?}"))?;
                telemetry
                    .publish(messages.telemetry.clone())
                    .map_err(|e| anyhow::anyhow!("cannot publish telemetry: {e:?}"))?;
                let resend = tokio::time::sleep(RESEND_AFTER);
                tokio::pin!(resend);
                loop {
                    tokio::select! {
                        Some(scan) = scans.next() => if scan.telemetry.frame == number { return anyhow::Ok(true) },
                        Some(s) = stats.next() => latest = Some(s),
                        () = &mut resend => break,
                        else => return Ok(false),
                    }
                }
                tracing::info!("no terrain scan for frame {number} within {RESEND_AFTER:?}: sending it again");
            }
        })
        .await
        .unwrap_or(Ok(false))?;
        if answered {
            round_trips.push(started.elapsed());
        } else {
            lost += 1;
            tracing::warn!("no terrain scan for frame {number} within {SCAN_TIMEOUT:?}");
        }
    }
    let until_quiet = async {
        while let Ok(Some(s)) = tokio::time::timeout(MAPPING_QUIET, stats.next()).await {
            latest = Some(s);
        }
    };
    let _ = tokio::time::timeout(MAPPING_DONE_TIMEOUT, until_quiet).await;
    let final_stats = latest.ok_or_else(|| anyhow::anyhow!("the mapping node published no statistics"))?;
    round_trips.sort();
    let median = round_trips.get(round_trips.len() / 2).map_or(0.0, |d| d.as_secs_f64() * 1000.0);
    let finite = |v: f32| v.is_finite().then_some((v as f64 * 10.0).round() / 10.0);
    Ok(ReplayReport {
        frames: frames.len(),
        frames_mapped: None,
        frames_skipped_tilt: None,
        frames_rejected: lost,
        mapped_pct: finite(final_stats.mapped_pct),
        fidelity_pct: finite(final_stats.fidelity_pct),
        floor_fidelity_pct: None,
        rocks_located: final_stats.rocks_located as usize,
        navigable_cells: final_stats.navigable_cells as usize,
        perception_ms_median: median,
        mapping_ms_median: None,
    })
}
