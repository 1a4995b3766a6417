//! ROS 2 name resolution: node namespace, relative and private topic names, remap rules.

use crate::ros_args::RosArgs;

/// Errors in node or topic names.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum NameError {
    /// A name that ROS 2 would reject.
    #[error("invalid {kind} name `{name}`: {reason}")]
    Invalid {
        /// What the name names: node, namespace or topic.
        kind: &'static str,
        /// The bad name.
        name: String,
        /// What is wrong with it.
        reason: &'static str,
    },
}

/// The resolved name and namespace of one node, plus the remap rules that apply to it.
#[derive(Debug, Clone, PartialEq)]
pub struct NodeIdentity {
    /// Node name after `__node` remapping.
    pub name: String,
    /// Absolute namespace after `__ns` remapping, `/` for the root.
    pub namespace: String,
    remaps: Vec<(String, String)>,
}

impl NodeIdentity {
    /// Resolves the identity of the node whose default name is `default_name`.
    pub fn resolve(default_name: &str, ros_args: &RosArgs) -> Result<Self, NameError> {
        let name = ros_args.special_for(default_name, "__node").unwrap_or_else(|| default_name.to_string());
        check_token("node", &name, &name)?;
        let namespace = normalize_namespace(&ros_args.special_for(default_name, "__ns").unwrap_or_default())?;
        let mut identity = NodeIdentity { name, namespace, remaps: Vec::new() };
        for remap in ros_args.remaps_for(default_name).filter(|r| !r.from.starts_with("__")) {
            let from = identity.expand(&remap.from)?;
            let to = identity.expand(&remap.to)?;
            identity.remaps.push((from, to));
        }
        Ok(identity)
    }

    /// Fully qualified node name, e.g. `/rover1/bridge`.
    pub fn fully_qualified(&self) -> String {
        join(&self.namespace, &self.name)
    }

    /// Resolves a topic name as the node sees it: expanded to an absolute name, then remapped.
    pub fn resolve_topic(&self, topic: &str) -> Result<String, NameError> {
        let expanded = self.expand(topic)?;
        let remapped = self.remaps.iter().rev().find(|(from, _)| *from == expanded).map(|(_, to)| to.clone());
        Ok(remapped.unwrap_or(expanded))
    }

    fn expand(&self, topic: &str) -> Result<String, NameError> {
        let expanded = if let Some(private) = topic.strip_prefix("~/") {
            join(&self.fully_qualified(), private)
        } else if topic.starts_with('/') {
            topic.to_string()
        } else {
            join(&self.namespace, topic)
        };
        for token in expanded.trim_start_matches('/').split('/') {
            check_token("topic", topic, token)?;
        }
        Ok(expanded)
    }
}

fn join(namespace: &str, relative: &str) -> String {
    if namespace == "/" { format!("/{relative}") } else { format!("{namespace}/{relative}") }
}

fn normalize_namespace(namespace: &str) -> Result<String, NameError> {
    let trimmed = namespace.trim_end_matches('/');
    if trimmed.is_empty() {
        return Ok("/".to_string());
    }
    let absolute = if trimmed.starts_with('/') { trimmed.to_string() } else { format!("/{trimmed}") };
    for token in absolute[1..].split('/') {
        check_token("namespace", namespace, token)?;
    }
    Ok(absolute)
}

fn check_token(kind: &'static str, name: &str, token: &str) -> Result<(), NameError> {
    let invalid = |reason| Err(NameError::Invalid { kind, name: name.to_string(), reason });
    if token.is_empty() {
        return invalid("it has an empty part (repeated or trailing `/`)");
    }
    if !token.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
        return invalid("only letters, digits, `_` and `/` are allowed");
    }
    if token.starts_with(|c: char| c.is_ascii_digit()) {
        return invalid("a part must not start with a digit");
    }
    if token.contains("__") {
        return invalid("`__` is reserved");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ros_args::split_ros_args;

    fn identity(node: &str, ros: &[&str]) -> NodeIdentity {
        let argv = ["rover", "--ros-args"].iter().chain(ros).map(|s| s.to_string()).collect();
        let (_, args) = split_ros_args(argv).unwrap();
        NodeIdentity::resolve(node, &args).unwrap()
    }

    #[test]
    fn relative_names_follow_the_namespace() {
        let id = identity("bridge", &["-r", "__ns:=/rover1"]);
        assert_eq!(id.fully_qualified(), "/rover1/bridge");
        assert_eq!(id.resolve_topic("rover/telemetry").unwrap(), "/rover1/rover/telemetry");
        assert_eq!(id.resolve_topic("/tf").unwrap(), "/tf");
        assert_eq!(id.resolve_topic("~/status").unwrap(), "/rover1/bridge/status");
    }

    #[test]
    fn remaps_match_expanded_names() {
        let id = identity("bridge", &["-r", "__ns:=/r", "-r", "odom:=/odometry", "-r", "/r/map:=world_map"]);
        assert_eq!(id.resolve_topic("odom").unwrap(), "/odometry");
        assert_eq!(id.resolve_topic("map").unwrap(), "/r/world_map");
        assert_eq!(id.resolve_topic("rover/mode").unwrap(), "/r/rover/mode");
    }

    #[test]
    fn node_rename_and_root_namespace() {
        let id = identity("decision", &["-r", "__node:=brain"]);
        assert_eq!(id.fully_qualified(), "/brain");
        assert_eq!(id.resolve_topic("rover/mode").unwrap(), "/rover/mode");
    }

    #[test]
    fn bad_names_are_rejected_with_the_reason() {
        let (_, args) =
            split_ros_args(vec!["x".into(), "--ros-args".into(), "-r".into(), "__ns:=/9bad".into()]).unwrap();
        let error = NodeIdentity::resolve("bridge", &args).unwrap_err();
        assert!(error.to_string().contains("/9bad"), "{error}");
        let id = identity("bridge", &[]);
        assert!(id.resolve_topic("a//b").is_err());
        assert!(id.resolve_topic("a-b").is_err());
    }
}
