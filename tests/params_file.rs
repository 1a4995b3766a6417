//! `launch_scripts/rover_params.yaml` against the parameters the nodes declare: the file lists
//! exactly the declared parameters of every node with their declared defaults and loads through
//! the runtime's `--params-file` path; unknown and ill-typed parameters stop each node with a
//! message naming them.
//!
//! Regenerate the file after changing a declaration:
//! `ROVER_WRITE_PARAMS_YAML=1 cargo test --test params_file`.

mod support;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

use rover::processes::nodes::Node;
use rover_runtime::params::{self, ParamSpec, ParameterValue};
use rover_runtime::ros_args::Remap;
use rover_runtime::{RosArgs, resolve_params};

/// The nodes of the graph with their declared parameters, in launch order.
fn declared_nodes() -> Vec<(&'static str, Vec<ParamSpec>)> {
    Node::ALL.into_iter().map(|node| (node.name(), node.param_specs())).collect()
}

fn params_file() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("launch_scripts/rover_params.yaml")
}

const HEADER: &str = "\
# Parameters of every node of the rover graph, with their default values.
# Use: rover NODE --ros-args --params-file launch_scripts/rover_params.yaml [-r __ns:=/NAMESPACE]
# (launch_scripts/rover.launch.py and launch_scripts/rover-graph pass it to every node).
# The `/**/NODE` keys apply to the node of that name in any namespace.
# Each parameter's comment gives its type, its allowed range, whether the node reads it only when it
# starts (`ros2 param set` refuses those) and what it does; `rover NODE --help` prints the same
# table. Generated from the nodes' declarations, and tests/params_file.rs fails when the two
# differ. Regenerate: ROVER_WRITE_PARAMS_YAML=1 cargo test --test params_file
";

/// Width at which the description comments wrap.
const COMMENT_WIDTH: usize = 100;

/// The text the parameter file must have, generated from the declarations.
fn expected_yaml() -> String {
    let mut out = String::from(HEADER);
    for (node, specs) in declared_nodes() {
        out.push_str(&format!("\n/**/{node}:\n  ros__parameters:\n"));
        for spec in &specs {
            let at_start = if spec.read_at_start { ", read at start" } else { "" };
            let comment = format!("{}{at_start}. {}", type_and_range(spec), spec.description);
            for line in wrap(&comment, COMMENT_WIDTH - 6) {
                out.push_str(&format!("    # {line}\n"));
            }
            out.push_str(&format!("    {}: {}\n", spec.name, yaml_value(&spec.default)));
        }
    }
    out
}

/// The ROS type name of a parameter and its range, e.g. `integer in [1, 65535]`.
fn type_and_range(spec: &ParamSpec) -> String {
    let type_name = match spec.default {
        ParameterValue::Boolean(_) => "bool",
        ParameterValue::Integer(_) => "integer",
        ParameterValue::Double(_) => "double",
        ParameterValue::String(_) => "string",
        ParameterValue::DoubleArray(_) => "double_array",
        ParameterValue::IntegerArray(_) => "integer_array",
        ParameterValue::StringArray(_) => "string_array",
        ref other => panic!("parameter {} has an unsupported type: {other:?}", spec.name),
    };
    match spec.range {
        Some((lo, hi)) => format!("{type_name} in [{lo}, {hi}]"),
        None => type_name.to_string(),
    }
}

/// Splits `text` into lines of at most `width` characters at spaces.
fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines: Vec<String> = Vec::new();
    for word in text.split_whitespace() {
        match lines.last_mut() {
            Some(line) if line.len() + 1 + word.len() <= width => {
                line.push(' ');
                line.push_str(word);
            }
            _ => lines.push(word.to_string()),
        }
    }
    lines
}

/// A default value in YAML that ROS tools and the runtime read back with the same type.
fn yaml_value(value: &ParameterValue) -> String {
    let list = |items: Vec<String>| format!("[{}]", items.join(", "));
    match value {
        ParameterValue::Boolean(b) => b.to_string(),
        ParameterValue::Integer(i) => i.to_string(),
        ParameterValue::Double(d) => yaml_double(*d),
        ParameterValue::String(s) => serde_json::to_string(s).expect("a string serialises"),
        ParameterValue::DoubleArray(items) => list(items.iter().map(|d| yaml_double(*d)).collect()),
        ParameterValue::IntegerArray(items) => list(items.iter().map(i64::to_string).collect()),
        ParameterValue::StringArray(items) => {
            list(items.iter().map(|s| serde_json::to_string(s).expect("a string serialises")).collect())
        }
        other => panic!("unsupported default {other:?}"),
    }
}

/// A double with a decimal point and, if in exponent form, a signed exponent (`1.0e+20`), so that
/// YAML 1.1 readers such as PyYAML see a float too.
fn yaml_double(d: f64) -> String {
    let text = format!("{d:?}");
    match text.split_once('e') {
        None => text,
        Some((mantissa, exponent)) => {
            let mantissa = if mantissa.contains('.') { mantissa.to_string() } else { format!("{mantissa}.0") };
            let exponent = if exponent.starts_with('-') { exponent.to_string() } else { format!("+{exponent}") };
            format!("{mantissa}e{exponent}")
        }
    }
}

/// The assignments the runtime reads from `path` for the node `/NAMESPACE/node`, by name.
fn file_values(path: &Path, fully_qualified: &str) -> BTreeMap<String, ParameterValue> {
    params::assignments_from_file(path, fully_qualified)
        .unwrap_or_else(|e| panic!("{e}"))
        .into_iter()
        .map(|a| (a.name, a.value))
        .collect()
}

#[test]
fn the_params_file_is_the_one_generated_from_the_declarations() {
    let path = params_file();
    let expected = expected_yaml();
    if std::env::var_os("ROVER_WRITE_PARAMS_YAML").is_some() {
        std::fs::write(&path, &expected).expect("write the parameter file");
    }
    let actual = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        actual == expected,
        "{} differs from the nodes' declarations; regenerate it with \
         ROVER_WRITE_PARAMS_YAML=1 cargo test --test params_file. Expected text:\n{expected}",
        path.display()
    );
}

#[test]
fn the_params_file_lists_exactly_the_declared_parameters_with_their_defaults() {
    for namespace in ["", "/rover1"] {
        for (node, specs) in declared_nodes() {
            let values = file_values(&params_file(), &format!("{namespace}/{node}"));
            let declared: Vec<&str> = specs.iter().map(|s| s.name).collect();
            let listed: Vec<&str> = values.keys().map(String::as_str).collect();
            let mut declared_sorted = declared.clone();
            declared_sorted.sort_unstable();
            assert_eq!(listed, declared_sorted, "parameters of {node} in the file vs. declared");
            for spec in &specs {
                assert_eq!(values[spec.name], spec.default, "default of {node}.{}", spec.name);
            }
        }
    }
}

#[test]
fn the_params_file_loads_through_the_runtime_into_the_defaults() {
    let ros_args = RosArgs {
        params_files: vec![params_file()],
        remaps: vec![Remap { node: None, from: "__ns".into(), to: "/rover1".into() }],
        ..RosArgs::default()
    };
    assert_eq!(resolve_params::<rover_bridge::node::BridgeParams>("bridge", &ros_args).unwrap(), Default::default());
    assert_eq!(
        resolve_params::<rover_perception::params::PerceptionParams>("perception", &ros_args).unwrap(),
        Default::default()
    );
    assert_eq!(
        resolve_params::<rover_mapping::params::MappingParams>("mapping", &ros_args).unwrap(),
        Default::default()
    );
    assert_eq!(
        resolve_params::<rover_decision::params::DecisionParams>("decision", &ros_args).unwrap(),
        Default::default()
    );
    assert_eq!(resolve_params::<rover_pickup::PickupParams>("pickup", &ros_args).unwrap(), Default::default());
}

#[test]
fn a_value_in_the_file_overrides_the_default_and_a_later_p_overrides_the_file() {
    let edited = write_edited_file("override", "mapping", "max_range_m: 8.0", "max_range_m: 6.5");
    let mut ros_args = RosArgs { params_files: vec![edited.clone()], ..RosArgs::default() };
    let from_file = resolve_params::<rover_mapping::params::MappingParams>("mapping", &ros_args).unwrap();
    assert_eq!(from_file.max_range_m, 6.5);
    ros_args.params.push(rover_runtime::ros_args::ParamOverride {
        node: Some("mapping".into()),
        name: "max_range_m".into(),
        value: "5".into(),
    });
    let overridden = resolve_params::<rover_mapping::params::MappingParams>("mapping", &ros_args).unwrap();
    assert_eq!(overridden.max_range_m, 5.0);
    let _ = std::fs::remove_file(edited);
}

/// A copy of the parameter file with `from` replaced by `to` in the section of `node`.
fn write_edited_file(what: &str, node: &str, from: &str, to: &str) -> PathBuf {
    let text = std::fs::read_to_string(params_file()).expect("read the parameter file");
    let section_start = text.find(&format!("/**/{node}:")).expect("the node has a section");
    let offset = text[section_start..].find(from).unwrap_or_else(|| panic!("`{from}` in the {node} section"));
    let at = section_start + offset;
    let edited = format!("{}{to}{}", &text[..at], &text[at + from.len()..]);
    let path = std::env::temp_dir().join(format!("rover-params-{what}-{node}-{}.yaml", std::process::id()));
    std::fs::write(&path, edited).expect("write the edited parameter file");
    path
}

/// The first parameter of `node`'s section and a value of the wrong type for it.
fn ill_typed_assignment(specs: &[ParamSpec]) -> (String, String, &'static str) {
    let spec = &specs[0];
    let current = format!("{}: {}", spec.name, yaml_value(&spec.default));
    let (wrong, expected) = match spec.default {
        ParameterValue::String(_) => ("[1, 2]", "expects a string, got [1, 2]"),
        ParameterValue::Boolean(_) => ("\"yes\"", "expects a boolean, got \"yes\""),
        _ => ("\"soon\"", "got \"soon\""),
    };
    (current, format!("{}: {wrong}", spec.name), expected)
}

#[test]
fn every_node_stops_on_an_unknown_parameter_in_the_file_naming_it_and_the_file() {
    support::assert_isolated();
    for (node, specs) in declared_nodes() {
        let first = format!("{}: {}", specs[0].name, yaml_value(&specs[0].default));
        let file = write_edited_file("unknown", node, &first, &format!("{first}\n    bogus_gain: 1.0"));
        let log = run_node_expecting_failure(node, &file);
        let needle = format!("unknown parameter `bogus_gain` (from {})", file.display());
        assert!(log.contains(&needle), "{node}: no `{needle}` in:\n{log}");
        assert!(log.contains(&format!("known parameters: {}", specs[0].name)), "{node}: {log}");
        let _ = std::fs::remove_file(file);
    }
}

#[test]
fn every_node_stops_on_an_ill_typed_parameter_in_the_file_naming_it_and_the_type() {
    support::assert_isolated();
    for (node, specs) in declared_nodes() {
        let (current, wrong, expected) = ill_typed_assignment(&specs);
        let file = write_edited_file("ill-typed", node, &current, &wrong);
        let log = run_node_expecting_failure(node, &file);
        let needle = format!("parameter `{}` (from {}) ", specs[0].name, file.display());
        assert!(log.contains(&needle) && log.contains(expected), "{node}: no `{needle}...{expected}` in:\n{log}");
        let _ = std::fs::remove_file(file);
    }
}

/// Runs `rover NODE --ros-args --params-file FILE`, which must fail within seconds; returns its log.
fn run_node_expecting_failure(node: &str, file: &Path) -> String {
    let domain = support::Domain::reserve();
    let args = [node, "--ros-args", "--params-file", file.to_str().expect("a UTF-8 path")];
    let mut process = support::start_process(&support::rover(), &args, &domain, &format!("bad-params-{node}"));
    let status = process.wait_for_exit(Duration::from_secs(20));
    let log = process.log_text();
    let status = status.unwrap_or_else(|| panic!("{node} kept running with a bad parameter file:\n{log}"));
    assert!(!status.success(), "{node} accepted a bad parameter file:\n{log}");
    log
}
