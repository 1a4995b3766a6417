//! A minimal node for tests and benchmarks: answers every `rover/telemetry` frame at once with a
//! `rover/drive_cmd` for the same frame. The command encodes what it answers, so a test can check
//! which telemetry a reply belongs to: throttle = x_m / 1000, brake = frame number, steering 0.
//!
//! Usage: `echo_node [--ros-args ...]` (node name `echo`).

use rover_msgs::frame_ids;
use rover_msgs::msg::DriveCommand;
use rover_msgs::std_msgs::Header;
use rover_runtime::{NoParams, Runtime, Shutdown, logging, publish_or_warn, spawn_subscriber, split_ros_args, topics};

fn main() -> anyhow::Result<()> {
    let (own, ros_args) = split_ros_args(std::env::args().collect())?;
    if own.iter().skip(1).any(|a| a == "--help" || a == "-h") {
        println!(
            "echo_node: answers each rover/telemetry frame with a rover/drive_cmd for the same frame\n(throttle = x_m / 1000, brake = frame). Accepts --ros-args."
        );
        return Ok(());
    }
    logging::init(&ros_args.logs);
    tokio::runtime::Runtime::new()?.block_on(async move {
        let runtime = Runtime::new(ros_args, Shutdown::on_signals())?;
        let (mut node, _params) = runtime.node::<NoParams>("echo")?;
        let drive = node.publisher(&topics::DRIVE_CMD)?;
        spawn_subscriber(node.subscription(&topics::TELEMETRY)?, node.span(), move |telemetry| {
            let command = DriveCommand {
                header: Header::now(frame_ids::BASE_LINK),
                frame: telemetry.frame,
                throttle: (telemetry.x_m / 1000.0) as f32,
                brake: telemetry.frame as f32,
                steering_angle_deg: 0.0,
            };
            publish_or_warn(&drive, &topics::DRIVE_CMD, command);
        });
        runtime.shutdown().wait().await;
        anyhow::Ok(())
    })
}
