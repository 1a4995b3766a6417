//! Checks the hand-declared standard messages field for field against the `.msg` files of an
//! installed ROS 2 distribution (the PyPI wheels that `tools/test-all` installs).
//! `tf2_msgs/TFMessage` has no wheel on PyPI and is not checked here.

use std::path::PathBuf;

use rover_msgs::RosMessage;
use rover_msgs::builtin_interfaces::{Duration, Time};
use rover_msgs::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus, KeyValue};
use rover_msgs::geometry_msgs::*;
use rover_msgs::nav_msgs::{MapMetaData, OccupancyGrid, Odometry};
use rover_msgs::rosgraph_msgs::Clock;
use rover_msgs::sensor_msgs::{CameraInfo, CompressedImage, Image, RegionOfInterest};
use rover_msgs::std_msgs::Header;

/// The `.msg` file of `package/name` in the first prefix of `AMENT_PREFIX_PATH` that has it.
fn installed_msg(package: &str, name: &str) -> Option<PathBuf> {
    let prefixes = std::env::var("AMENT_PREFIX_PATH").ok()?;
    prefixes
        .split(':')
        .map(|prefix| PathBuf::from(prefix).join("share").join(package).join("msg").join(format!("{name}.msg")))
        .find(|path| path.exists())
}

fn check<M: RosMessage>(checked: &mut Vec<String>) {
    let Some(path) = installed_msg(M::PACKAGE, M::NAME) else {
        panic!("{} not found under AMENT_PREFIX_PATH", M::type_name());
    };
    let text = std::fs::read_to_string(&path).unwrap();
    let spec = rover_msgs::idl::parse_msg(M::PACKAGE, &text).unwrap();
    let installed: Vec<(String, String)> = spec.fields.into_iter().map(|f| (f.name, f.ros_type)).collect();
    let ours: Vec<(String, String)> = M::fields().into_iter().map(|(n, t)| (n.to_string(), t)).collect();
    assert_eq!(ours, installed, "{} differs from {}", M::type_name(), path.display());
    checked.push(M::type_name());
}

#[test]
fn standard_messages_match_the_installed_definitions() {
    if std::env::var_os("AMENT_PREFIX_PATH").is_none() {
        assert!(
            std::env::var_os("ROVER_REQUIRE_ROS").is_none(),
            "AMENT_PREFIX_PATH is not set: run through tools/test-all, which installs the ROS 2 wheels"
        );
        eprintln!("skipped: no ROS 2 installation (AMENT_PREFIX_PATH unset); tools/test-all runs this check");
        return;
    }
    let mut checked = Vec::new();
    check::<Time>(&mut checked);
    check::<Duration>(&mut checked);
    check::<Header>(&mut checked);
    check::<Point>(&mut checked);
    check::<Vector3>(&mut checked);
    check::<Quaternion>(&mut checked);
    check::<Pose>(&mut checked);
    check::<PoseArray>(&mut checked);
    check::<Twist>(&mut checked);
    check::<PoseWithCovariance>(&mut checked);
    check::<TwistWithCovariance>(&mut checked);
    check::<Transform>(&mut checked);
    check::<TransformStamped>(&mut checked);
    check::<Odometry>(&mut checked);
    check::<MapMetaData>(&mut checked);
    check::<OccupancyGrid>(&mut checked);
    check::<CompressedImage>(&mut checked);
    check::<Image>(&mut checked);
    check::<RegionOfInterest>(&mut checked);
    check::<CameraInfo>(&mut checked);
    check::<KeyValue>(&mut checked);
    check::<DiagnosticStatus>(&mut checked);
    check::<DiagnosticArray>(&mut checked);
    check::<Clock>(&mut checked);
    eprintln!("checked {} standard messages: {}", checked.len(), checked.join(", "));
}
