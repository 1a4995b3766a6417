use crate::RosMessage;
use crate::msg::*;

fn msg_file_fields(name: &str) -> Vec<(String, String)> {
    let path = format!("{}/msg/{name}.msg", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let spec = crate::idl::parse_msg("rover_msgs", &text).unwrap();
    spec.fields.into_iter().map(|f| (f.name, f.ros_type)).collect()
}

fn rust_fields<M: RosMessage>() -> Vec<(String, String)> {
    M::fields().into_iter().map(|(name, ty)| (name.to_string(), ty)).collect()
}

#[test]
fn generated_types_match_their_msg_files() {
    assert_eq!(rust_fields::<Telemetry>(), msg_file_fields("Telemetry"));
    assert_eq!(rust_fields::<DriveCommand>(), msg_file_fields("DriveCommand"));
    assert_eq!(rust_fields::<PickupRequest>(), msg_file_fields("PickupRequest"));
    assert_eq!(rust_fields::<TerrainScan>(), msg_file_fields("TerrainScan"));
    assert_eq!(rust_fields::<MapStats>(), msg_file_fields("MapStats"));
    assert_eq!(rust_fields::<DecisionState>(), msg_file_fields("DecisionState"));
}

#[test]
fn every_msg_file_has_a_rust_type() {
    let mut files: Vec<String> = std::fs::read_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/msg"))
        .unwrap()
        .map(|e| e.unwrap().path().file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    files.sort();
    let mut types = vec![
        Telemetry::NAME,
        DriveCommand::NAME,
        PickupRequest::NAME,
        TerrainScan::NAME,
        MapStats::NAME,
        DecisionState::NAME,
    ];
    types.sort();
    assert_eq!(files, types);
}

#[test]
fn constants_are_generated() {
    assert_eq!(TerrainScan::UNKNOWN, 0);
    assert_eq!(TerrainScan::NAVIGABLE, 1);
    assert_eq!(TerrainScan::OBSTACLE, 2);
    assert_eq!(TerrainScan::ROCK, 3);
}

#[test]
fn type_names_follow_ros_conventions() {
    assert_eq!(Telemetry::type_name(), "rover_msgs/msg/Telemetry");
    assert_eq!(crate::sensor_msgs::CameraInfo::type_name(), "sensor_msgs/msg/CameraInfo");
    let camera_fields = crate::sensor_msgs::CameraInfo::fields();
    assert!(camera_fields.contains(&("k", "float64[9]".to_string())));
    assert!(camera_fields.contains(&("d", "float64[]".to_string())));
}

#[test]
fn yaw_quaternion_is_a_unit_rotation_about_z() {
    let q = crate::geometry_msgs::Quaternion::from_yaw(std::f64::consts::FRAC_PI_2);
    assert!((q.z - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-12);
    assert!((q.w - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-12);
    assert_eq!((q.x, q.y), (0.0, 0.0));
}

#[test]
fn diagnostic_values_are_found_by_key_in_the_first_status_that_has_them() {
    use crate::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus, KeyValue};
    let status = |name: &str, pairs: &[(&str, &str)]| DiagnosticStatus {
        name: name.into(),
        values: pairs.iter().map(|&(key, value)| KeyValue { key: key.into(), value: value.into() }).collect(),
        ..DiagnosticStatus::default()
    };
    let array = DiagnosticArray {
        status: vec![status("a", &[("frames", "3")]), status("b", &[("frames", "4"), ("late", "1")])],
        ..DiagnosticArray::default()
    };
    assert_eq!((array.value("frames"), array.value("late"), array.value("none")), (Some("3"), Some("1"), None));
    assert_eq!(array.status[1].value("frames"), Some("4"));
}

#[test]
fn definitions_list_the_type_then_each_nested_type_once_depth_first() {
    let names: Vec<String> =
        crate::nav_msgs::Odometry::definitions().into_iter().map(|definition| definition.type_name).collect();
    assert_eq!(
        names,
        [
            "nav_msgs/Odometry",
            "std_msgs/Header",
            "builtin_interfaces/Time",
            "geometry_msgs/PoseWithCovariance",
            "geometry_msgs/Pose",
            "geometry_msgs/Point",
            "geometry_msgs/Quaternion",
            "geometry_msgs/TwistWithCovariance",
            "geometry_msgs/Twist",
            "geometry_msgs/Vector3",
        ]
    );
    assert_eq!(Telemetry::definitions()[0].fields, Telemetry::fields());
}

#[test]
fn points_become_poses_without_rotation_and_back() {
    use crate::geometry_msgs::{PoseArray, Quaternion};
    let header = crate::std_msgs::Header { frame_id: "map".into(), ..Default::default() };
    let poses = PoseArray::of_points(header, &[(97.4, 74.6), (122.3, 51.7)]);
    assert_eq!(poses.header.frame_id, "map");
    assert!(poses.poses.iter().all(|pose| pose.orientation == Quaternion::IDENTITY && pose.position.z == 0.0));
    assert_eq!(poses.points(), [(97.4, 74.6), (122.3, 51.7)]);
}

#[test]
fn the_sample_return_types_match_the_action_file() {
    use crate::sample_return::{SampleReturnFeedback, SampleReturnResult};
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/action/SampleReturn.action");
    let text = std::fs::read_to_string(path).unwrap();
    let parts: Vec<&str> = text.split("\n---\n").collect();
    assert_eq!(parts.len(), 3, "goal, result and feedback");
    let fields = |part: &str| -> Vec<(String, String)> {
        let spec = crate::idl::parse_msg("rover_msgs", part).unwrap();
        spec.fields.into_iter().map(|f| (f.name, f.ros_type)).collect()
    };
    assert!(fields(parts[0]).is_empty(), "a goal without fields");
    assert_eq!(rust_fields::<SampleReturnResult>(), fields(parts[1]));
    assert_eq!(rust_fields::<SampleReturnFeedback>(), fields(parts[2]));
}
