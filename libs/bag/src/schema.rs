//! The `ros2msg` schema of a message type as rosbag2 stores it in MCAP: the type's fields, then
//! for each nested type a line of 80 `=`, a line `MSG: pkg/Name` and that type's fields.

use rover_msgs::Definition;

/// The schema encoding of ROS 2 message definitions in MCAP.
pub const SCHEMA_ENCODING: &str = "ros2msg";

/// The line between two definitions.
const SEPARATOR: &str = "================================================================================";

/// The schema text of the first of `definitions`, with the nested ones after it (as
/// [`rover_msgs::RosMessage::definitions`] lists them).
pub fn schema_text(definitions: &[Definition]) -> String {
    let mut text = String::new();
    for (index, definition) in definitions.iter().enumerate() {
        if index > 0 {
            text.push_str(&format!("{SEPARATOR}\nMSG: {}\n", definition.type_name));
        }
        for (name, ros_type) in &definition.fields {
            text.push_str(&format!("{ros_type} {name}\n"));
        }
    }
    text
}

#[cfg(test)]
mod tests {
    use rover_msgs::RosMessage;
    use rover_msgs::idl::parse_msg;
    use rover_msgs::msg::{MapStats, TerrainScan};
    use rover_msgs::nav_msgs::Odometry;

    use super::*;

    /// The schema's sections: the root's text, then (type name, text) of each nested type.
    fn sections(text: &str) -> (String, Vec<(String, String)>) {
        let separator = format!("{SEPARATOR}\n");
        let mut parts = text.split(&separator);
        let root = parts.next().unwrap().to_string();
        let nested = parts
            .map(|part| {
                let (first, rest) = part.split_once('\n').unwrap();
                (first.strip_prefix("MSG: ").expect("MSG: line").to_string(), rest.to_string())
            })
            .collect();
        (root, nested)
    }

    fn parsed_fields(package: &str, text: &str) -> Vec<(String, String)> {
        parse_msg(package, text).unwrap().fields.into_iter().map(|f| (f.name, f.ros_type)).collect()
    }

    #[test]
    fn odometry_carries_every_nested_definition_once() {
        let text = schema_text(&Odometry::definitions());
        assert!(text.starts_with("std_msgs/Header header\nstring child_frame_id\n"), "{text}");
        let (_, nested) = sections(&text);
        let names: Vec<&str> = nested.iter().map(|(name, _)| name.as_str()).collect();
        let definitions = Odometry::definitions();
        let nested_types: Vec<&str> = definitions[1..].iter().map(|d| d.type_name.as_str()).collect();
        assert_eq!(names, nested_types, "the nested types, in the order of the definitions");
        assert_eq!(names.len(), 9);
        assert_eq!(names[2], "geometry_msgs/PoseWithCovariance");
        let covariance = &nested[2].1;
        assert_eq!(covariance, "geometry_msgs/Pose pose\nfloat64[36] covariance\n");
        assert!(text.contains(&format!("\n{SEPARATOR}\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n")));
    }

    #[test]
    fn each_section_parses_back_to_its_definition() {
        let definitions = Odometry::definitions();
        let (root, nested) = sections(&schema_text(&definitions));
        assert_eq!(parsed_fields("nav_msgs", &root), definitions[0].fields.iter().map(owned).collect::<Vec<_>>());
        for ((name, text), definition) in nested.iter().zip(&definitions[1..]) {
            let package = name.split('/').next().unwrap();
            let expected: Vec<_> = definition.fields.iter().map(owned).collect();
            assert_eq!(parsed_fields(package, text), expected, "{name}");
        }
    }

    #[test]
    fn rover_messages_match_their_msg_files() {
        for (name, definitions) in [("MapStats", MapStats::definitions()), ("TerrainScan", TerrainScan::definitions())]
        {
            let path = format!("{}/../msgs/msg/{name}.msg", env!("CARGO_MANIFEST_DIR"));
            let msg_file = std::fs::read_to_string(&path).unwrap();
            let (root, nested) = sections(&schema_text(&definitions));
            assert_eq!(parsed_fields("rover_msgs", &root), parsed_fields("rover_msgs", &msg_file), "{name}");
            assert_eq!(nested[0].0, "std_msgs/Header");
        }
    }

    fn owned(field: &(&str, String)) -> (String, String) {
        (field.0.to_string(), field.1.clone())
    }
}
