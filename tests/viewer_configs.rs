//! The viewer configurations users open, `config/rover.rviz` and `config/rover.foxglove-layout.json`,
//! name only topics the graph publishes, with the types their displays draw: RViz's displays and
//! goal tool against the topic table, Foxglove's panels against what `rover live-view` serves.

use std::collections::BTreeMap;
use std::path::Path;

use rover_msgs::RosMessage;
use rover_msgs::msg::Telemetry;
use rover_runtime::topics::{Topic, TopicVisitor, visit_all};

/// The ROS type of each topic of the table, by absolute name.
fn topic_types() -> BTreeMap<String, String> {
    struct Types(BTreeMap<String, String>);

    impl TopicVisitor for Types {
        fn visit<M: RosMessage>(&mut self, topic: &Topic<M>) -> anyhow::Result<()> {
            let name = format!("/{}", topic.name.trim_start_matches('/'));
            self.0.insert(name, format!("{}/msg/{}", M::PACKAGE, M::NAME));
            Ok(())
        }
    }

    let mut types = Types(BTreeMap::new());
    visit_all(&mut types).expect("the table's topics");
    types.0
}

fn config(name: &str) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("config").join(name);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The message type an RViz display class draws.
fn rviz_display_type(class: &str) -> Option<&'static str> {
    Some(match class {
        "rviz_default_plugins/Map" => "nav_msgs/msg/OccupancyGrid",
        "rviz_default_plugins/Path" => "nav_msgs/msg/Path",
        "rviz_default_plugins/MarkerArray" => "visualization_msgs/msg/MarkerArray",
        "rviz_default_plugins/PoseArray" => "geometry_msgs/msg/PoseArray",
        "rviz_default_plugins/Odometry" => "nav_msgs/msg/Odometry",
        "rviz_default_plugins/Image" => "sensor_msgs/msg/Image",
        "rviz_default_plugins/SetGoal" => "geometry_msgs/msg/PoseStamped",
        _ => return None,
    })
}

#[test]
fn rviz_shows_the_graphs_topics_with_their_types_and_sends_goals_on_goal_pose() {
    let rviz: serde_yaml_ng::Value = serde_yaml_ng::from_str(&config("rover.rviz")).expect("rover.rviz is YAML");
    let manager = &rviz["Visualization Manager"];
    assert_eq!(manager["Global Options"]["Fixed Frame"], "map");
    let types = topic_types();
    let entries = manager["Displays"]
        .as_sequence()
        .into_iter()
        .flatten()
        .chain(manager["Tools"].as_sequence().into_iter().flatten());
    let mut shown = Vec::new();
    for entry in entries {
        let class = entry["Class"].as_str().expect("every display and tool has a class");
        let Some(topic) = entry["Topic"]["Value"].as_str() else { continue };
        let drawn = rviz_display_type(class).unwrap_or_else(|| panic!("{class} on {topic}: a display this test knows"));
        assert_eq!(types.get(topic).map(String::as_str), Some(drawn), "{class} on {topic}");
        shown.push(topic);
    }
    for topic in ["/map", "/rover/plan", "/rover/sample_markers", "/odom", "/camera/image_raw", "/goal_pose"] {
        assert!(shown.contains(&topic), "rover.rviz lacks {topic}: {shown:?}");
    }
}

#[test]
fn the_foxglove_layout_uses_only_what_the_live_view_serves() {
    let layout: serde_json::Value =
        serde_json::from_str(&config("rover.foxglove-layout.json")).expect("the layout is JSON");
    let panels = layout["configById"].as_object().expect("panels by id");
    let served: Vec<String> =
        rover::tools::live_view::LIVE_TOPICS.iter().map(|t| format!("/{}", t.trim_start_matches('/'))).collect();
    let mut used = Vec::new();
    for (id, panel) in panels {
        used.extend(panel["topics"].as_object().into_iter().flat_map(|topics| topics.keys().cloned()));
        used.extend(panel["imageMode"]["imageTopic"].as_str().map(String::from));
        used.extend(panel["topicPath"].as_str().map(String::from));
        for path in panel["paths"].as_array().into_iter().flatten() {
            let (topic, field) =
                path["value"].as_str().and_then(|p| p.split_once('.')).expect("a plot path TOPIC.FIELD");
            assert_eq!(topic, "/rover/telemetry", "{id}");
            assert!(Telemetry::fields().iter().any(|(name, _)| *name == field), "{id}: no field {field}");
            used.push(topic.to_string());
        }
    }
    for topic in &used {
        assert!(served.contains(topic), "the layout uses {topic}, which rover live-view does not serve: {served:?}");
    }
    assert!(used.len() >= 6, "{used:?}");
    let layout_ids = layout["layout"].to_string();
    assert!(panels.keys().all(|id| layout_ids.contains(id.as_str())), "every panel is placed: {layout_ids}");
}
