//! Typed node parameters: declaration with type, default, range and description; loading from
//! `--params-file` YAML (`node: ros__parameters: ...`) and `-p` overrides; clear errors.
//!
//! Nodes declare their parameters once with [`node_params!`](crate::node_params), which yields a
//! plain struct the algorithms use and the specs the runtime needs for loading, validation,
//! `--help`, and the ROS 2 parameter services.

use std::collections::BTreeMap;
use std::path::Path;

pub use ros2_client::parameters::ParameterValue;

/// Declaration of one parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamSpec {
    /// Parameter name, e.g. `reply_deadline_ms`.
    pub name: &'static str,
    /// One-line description (from the doc comment).
    pub description: &'static str,
    /// Default value; its variant is the parameter's type.
    pub default: ParameterValue,
    /// Inclusive numeric range, for integer and double parameters.
    pub range: Option<(f64, f64)>,
    /// The node reads it only when it starts: the parameter services refuse to set it (ROS's
    /// read-only parameters).
    pub read_at_start: bool,
}

/// A parameter value type: conversion to and from [`ParameterValue`].
pub trait ParamType: Sized {
    /// Human-readable type name used in error messages and `--help`.
    const TYPE_NAME: &'static str;
    /// Converts into the ROS representation.
    fn into_value(self) -> ParameterValue;
    /// Converts from the ROS representation, if the variant fits.
    fn from_value(value: &ParameterValue) -> Option<Self>;
}

macro_rules! param_types {
    ($($rust:ty => $variant:ident, $name:literal);* $(;)?) => {$(
        impl ParamType for $rust {
            const TYPE_NAME: &'static str = $name;
            fn into_value(self) -> ParameterValue { ParameterValue::$variant(self) }
            fn from_value(value: &ParameterValue) -> Option<Self> {
                match value { ParameterValue::$variant(v) => Some(v.clone()), _ => None }
            }
        }
    )*};
}

param_types! {
    bool => Boolean, "a boolean";
    i64 => Integer, "an integer";
    f64 => Double, "a number";
    String => String, "a string";
    Vec<f64> => DoubleArray, "a list of numbers";
    Vec<i64> => IntegerArray, "a list of integers";
    Vec<String> => StringArray, "a list of strings";
}

/// A node's parameter set, declared with [`node_params!`](crate::node_params).
pub trait NodeParams: Clone + Send + Sync + 'static {
    /// Every parameter of the node.
    fn specs() -> Vec<ParamSpec>;
    /// Builds the struct from values already checked against [`NodeParams::specs`].
    fn from_values(values: &ParamValues) -> Self;
}

/// Parameter values by name.
pub type ParamValues = BTreeMap<String, ParameterValue>;

/// Errors while loading or setting parameters.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ParamError {
    /// A parameter file could not be read or parsed.
    #[error("parameter file {path}: {reason}")]
    File {
        /// The file.
        path: String,
        /// What went wrong.
        reason: String,
    },
    /// A parameter the node does not declare.
    #[error("node `{node}`: unknown parameter `{name}` (from {source_name}); known parameters: {known}")]
    Unknown {
        /// Node name.
        node: String,
        /// Parameter name.
        name: String,
        /// Where it came from.
        source_name: String,
        /// Declared names.
        known: String,
    },
    /// A value of the wrong type or out of range.
    #[error("node `{node}`: parameter `{name}` (from {source_name}) {reason}")]
    Invalid {
        /// Node name.
        node: String,
        /// Parameter name.
        name: String,
        /// Where it came from.
        source_name: String,
        /// What is wrong.
        reason: String,
    },
}

/// Name of the parameter every ROS 2 node has.
pub const USE_SIM_TIME: &str = "use_sim_time";

/// The parameter every ROS 2 node has: stamp with the simulated time of `/clock`.
pub(crate) fn use_sim_time_spec() -> ParamSpec {
    ParamSpec {
        name: USE_SIM_TIME,
        description: "Stamp messages with the simulated time of /clock instead of the wall clock.",
        default: ParameterValue::Boolean(false),
        range: None,
        read_at_start: true,
    }
}

/// Name of the parameter every node of the graph has: configure and activate itself at start.
pub const AUTOSTART: &str = "autostart";

/// The parameter every node of the graph (a managed node) has.
pub(crate) fn autostart_spec() -> ParamSpec {
    ParamSpec {
        name: AUTOSTART,
        description: "Configure and activate the node at start; false leaves it unconfigured for a \
                      lifecycle manager or `ros2 lifecycle set`.",
        default: ParameterValue::Boolean(true),
        range: None,
        read_at_start: true,
    }
}

/// Checks `value` against `spec` and returns it with integers widened to doubles where needed.
pub fn check_value(spec: &ParamSpec, value: &ParameterValue) -> Result<ParameterValue, String> {
    let value = coerce(&spec.default, value)
        .ok_or_else(|| format!("expects {}, got {}", type_description(&spec.default), describe_value(value)))?;
    if let (Some((lo, hi)), Some(number)) = (spec.range, as_number(&value))
        && !(lo..=hi).contains(&number)
    {
        return Err(format!("= {number} is outside the allowed range [{lo}, {hi}]"));
    }
    Ok(value)
}

fn coerce(default: &ParameterValue, value: &ParameterValue) -> Option<ParameterValue> {
    use ParameterValue as V;
    match (default, value) {
        (V::Double(_), V::Integer(i)) => Some(V::Double(*i as f64)),
        (V::DoubleArray(_), V::IntegerArray(items)) => Some(V::DoubleArray(items.iter().map(|&i| i as f64).collect())),
        (V::DoubleArray(_) | V::IntegerArray(_) | V::StringArray(_), V::StringArray(items)) if items.is_empty() => {
            Some(default_empty(default))
        }
        (V::Double(_), V::Double(d)) if !d.is_finite() => None,
        _ if std::mem::discriminant(default) == std::mem::discriminant(value) => Some(value.clone()),
        _ => None,
    }
}

fn default_empty(default: &ParameterValue) -> ParameterValue {
    match default {
        ParameterValue::DoubleArray(_) => ParameterValue::DoubleArray(Vec::new()),
        ParameterValue::IntegerArray(_) => ParameterValue::IntegerArray(Vec::new()),
        _ => ParameterValue::StringArray(Vec::new()),
    }
}

fn as_number(value: &ParameterValue) -> Option<f64> {
    match value {
        ParameterValue::Integer(i) => Some(*i as f64),
        ParameterValue::Double(d) => Some(*d),
        _ => None,
    }
}

/// Describes the type of a parameter from its default value, e.g. "a number".
pub fn type_description(default: &ParameterValue) -> &'static str {
    match default {
        ParameterValue::Boolean(_) => bool::TYPE_NAME,
        ParameterValue::Integer(_) => i64::TYPE_NAME,
        ParameterValue::Double(_) => "a finite number",
        ParameterValue::String(_) => String::TYPE_NAME,
        ParameterValue::DoubleArray(_) => <Vec<f64>>::TYPE_NAME,
        ParameterValue::IntegerArray(_) => <Vec<i64>>::TYPE_NAME,
        ParameterValue::StringArray(_) => <Vec<String>>::TYPE_NAME,
        _ => "an unsupported type",
    }
}

/// Formats a value for messages and `--help`, e.g. `4567`, `"127.0.0.1"`, `[1.0, 2.0]`; a long one
/// is clipped (see [`crate::rejections::clipped`]).
pub fn describe_value(value: &ParameterValue) -> String {
    let described = match value {
        ParameterValue::NotSet => "nothing".to_string(),
        ParameterValue::Boolean(b) => b.to_string(),
        ParameterValue::Integer(i) => i.to_string(),
        ParameterValue::Double(d) => format!("{d:?}"),
        ParameterValue::String(s) => format!("{s:?}"),
        ParameterValue::ByteArray(v) => format!("{v:?}"),
        ParameterValue::BooleanArray(v) => format!("{v:?}"),
        ParameterValue::IntegerArray(v) => format!("{v:?}"),
        ParameterValue::DoubleArray(v) => format!("{v:?}"),
        ParameterValue::StringArray(v) => format!("{v:?}"),
    };
    crate::rejections::clipped(&described).into_owned()
}

/// Where a parameter value comes from, for error messages.
#[derive(Debug, Clone)]
pub struct Assignment {
    /// Parameter name.
    pub name: String,
    /// Value.
    pub value: ParameterValue,
    /// Source, e.g. `-p port:=x` or `params.yaml`.
    pub source_name: String,
}

/// Resolves a node's parameter values: defaults, then files, then `-p` overrides.
pub fn resolve_values(node: &str, specs: &[ParamSpec], assignments: &[Assignment]) -> Result<ParamValues, ParamError> {
    let mut values: ParamValues = specs.iter().map(|s| (s.name.to_string(), s.default.clone())).collect();
    let use_sim_time = use_sim_time_spec();
    for assignment in assignments {
        let spec =
            std::iter::once(&use_sim_time).chain(specs).find(|s| s.name == assignment.name).ok_or_else(|| {
                ParamError::Unknown {
                    node: node.to_string(),
                    name: assignment.name.clone(),
                    source_name: assignment.source_name.clone(),
                    known: specs.iter().map(|s| s.name).collect::<Vec<_>>().join(", "),
                }
            })?;
        let value = check_value(spec, &assignment.value).map_err(|reason| ParamError::Invalid {
            node: node.to_string(),
            name: assignment.name.clone(),
            source_name: assignment.source_name.clone(),
            reason,
        })?;
        values.insert(assignment.name.clone(), value);
    }
    Ok(values)
}

/// Reads the assignments for node `fully_qualified` (e.g. `/rover1/bridge`) from a YAML parameter file.
///
/// Sections named `/**`, the node's base name, its fully qualified name, or `/**/name` apply.
pub fn assignments_from_file(path: &Path, fully_qualified: &str) -> Result<Vec<Assignment>, ParamError> {
    let file_error = |reason: String| ParamError::File { path: path.display().to_string(), reason };
    let text = std::fs::read_to_string(path).map_err(|e| file_error(format!("cannot read it: {e}")))?;
    assignments_from_yaml(&text, &path.display().to_string(), fully_qualified).map_err(file_error)
}

/// Like [`assignments_from_file`], on YAML text; `source_name` names it in messages.
pub fn assignments_from_yaml(text: &str, source_name: &str, fully_qualified: &str) -> Result<Vec<Assignment>, String> {
    let root: serde_yaml_ng::Value = serde_yaml_ng::from_str(text).map_err(|e| format!("invalid YAML: {e}"))?;
    let serde_yaml_ng::Value::Mapping(sections) = root else {
        return Err("expected a mapping of node names to `ros__parameters`".to_string());
    };
    let base_name = fully_qualified.rsplit('/').next().unwrap_or(fully_qualified);
    let mut assignments = Vec::new();
    for (key, section) in &sections {
        let key = key.as_str().ok_or_else(|| format!("section key {key:?} is not a string"))?;
        if !section_applies(key, base_name, fully_qualified) {
            continue;
        }
        let params = section
            .get("ros__parameters")
            .ok_or_else(|| format!("section `{key}` has no `ros__parameters` mapping"))?;
        flatten_yaml("", params, source_name, &mut assignments)?;
    }
    Ok(assignments)
}

fn section_applies(key: &str, base_name: &str, fully_qualified: &str) -> bool {
    key == "/**" || key == base_name || key == fully_qualified || key.strip_prefix("/**/") == Some(base_name)
}

fn flatten_yaml(
    prefix: &str,
    value: &serde_yaml_ng::Value,
    source_name: &str,
    out: &mut Vec<Assignment>,
) -> Result<(), String> {
    let serde_yaml_ng::Value::Mapping(map) = value else {
        return Err(format!("`ros__parameters` must be a mapping, found {}", yaml_kind(value)));
    };
    for (key, item) in map {
        let key = key.as_str().ok_or_else(|| format!("parameter name {key:?} is not a string"))?;
        let name = if prefix.is_empty() { key.to_string() } else { format!("{prefix}.{key}") };
        if matches!(item, serde_yaml_ng::Value::Mapping(_)) {
            flatten_yaml(&name, item, source_name, out)?;
        } else {
            let value = yaml_to_value(item).map_err(|reason| format!("parameter `{name}`: {reason}"))?;
            out.push(Assignment { name, value, source_name: source_name.to_string() });
        }
    }
    Ok(())
}

/// Parses the value of a `-p name:=value` override the way ROS does (as YAML).
pub fn parse_override(text: &str) -> Result<ParameterValue, String> {
    let value: serde_yaml_ng::Value =
        serde_yaml_ng::from_str(text).map_err(|e| format!("invalid value {text:?}: {e}"))?;
    yaml_to_value(&value)
}

fn yaml_to_value(value: &serde_yaml_ng::Value) -> Result<ParameterValue, String> {
    use serde_yaml_ng::Value as Y;
    Ok(match value {
        Y::Bool(b) => ParameterValue::Boolean(*b),
        Y::Number(n) if n.is_i64() => ParameterValue::Integer(n.as_i64().unwrap_or_default()),
        Y::Number(n) => ParameterValue::Double(n.as_f64().unwrap_or(f64::NAN)),
        Y::String(s) => ParameterValue::String(s.clone()),
        Y::Null => ParameterValue::String(String::new()),
        Y::Sequence(items) => sequence_to_value(items)?,
        other => return Err(format!("unsupported value of kind {}", yaml_kind(other))),
    })
}

fn sequence_to_value(items: &[serde_yaml_ng::Value]) -> Result<ParameterValue, String> {
    use serde_yaml_ng::Value as Y;
    if items.iter().all(|i| matches!(i, Y::Number(n) if n.is_i64())) && !items.is_empty() {
        return Ok(ParameterValue::IntegerArray(items.iter().filter_map(Y::as_i64).collect()));
    }
    if items.iter().all(|i| matches!(i, Y::Number(_))) && !items.is_empty() {
        return Ok(ParameterValue::DoubleArray(items.iter().filter_map(Y::as_f64).collect()));
    }
    if items.iter().all(|i| matches!(i, Y::Bool(_))) && !items.is_empty() {
        return Ok(ParameterValue::BooleanArray(items.iter().filter_map(Y::as_bool).collect()));
    }
    items
        .iter()
        .map(|i| i.as_str().map(str::to_string).ok_or_else(|| "lists must hold items of one type".to_string()))
        .collect::<Result<Vec<_>, _>>()
        .map(ParameterValue::StringArray)
}

fn yaml_kind(value: &serde_yaml_ng::Value) -> &'static str {
    match value {
        serde_yaml_ng::Value::Null => "null",
        serde_yaml_ng::Value::Bool(_) => "a boolean",
        serde_yaml_ng::Value::Number(_) => "a number",
        serde_yaml_ng::Value::String(_) => "a string",
        serde_yaml_ng::Value::Sequence(_) => "a list",
        serde_yaml_ng::Value::Mapping(_) => "a mapping",
        serde_yaml_ng::Value::Tagged(_) => "a tagged value",
    }
}

/// Formats the parameter table for `--help`.
pub fn help_table(specs: &[ParamSpec]) -> String {
    let mut out = String::from("Parameters (set with --ros-args -p NAME:=VALUE or --params-file FILE):\n");
    for spec in specs {
        let range = spec.range.map(|(lo, hi)| format!(", range [{lo}, {hi}]")).unwrap_or_default();
        let at_start = if spec.read_at_start { ", read at start" } else { "" };
        out.push_str(&format!(
            "  {} ({}{range}, default {}{at_start})\n      {}\n",
            spec.name,
            type_description(&spec.default),
            describe_value(&spec.default),
            spec.description
        ));
    }
    out
}

/// Declares a node's parameters: a struct with one field per parameter and its [`NodeParams`] impl.
/// The parameters listed after `read_at_start` (or all of them, with `read_at_start: all`) are read
/// only when the node starts (a name that is not a field does not compile).
///
/// ```
/// rover_runtime::node_params! {
///     /// Parameters of an example node.
///     pub struct ExampleParams {
///         /// TCP port to listen on.
///         port: i64 [1, 65535] = 4567,
///         /// Host to bind.
///         host: String = "127.0.0.1",
///         /// Seconds to wait for an answer.
///         timeout_s: f64 [0.0, 60.0] = 1.0,
///     }
///     read_at_start: [port, host]
/// }
/// ```
///
/// A name in `read_at_start` that is not a parameter does not compile:
///
/// ```compile_fail
/// rover_runtime::node_params! {
///     /// Parameters with a misspelt start-only one.
///     pub struct MisspeltParams {
///         /// TCP port to listen on.
///         port: i64 [1, 65535] = 4567,
///     }
///     read_at_start: [prot]
/// }
/// ```
#[macro_export]
macro_rules! node_params {
    (
        $(#[$meta:meta])*
        pub struct $name:ident {
            $(
                $(#[doc = $doc:literal])+
                $field:ident : $ty:ty $([$lo:literal, $hi:literal])? = $default:expr
            ),* $(,)?
        }
        $(read_at_start: $start:tt)?
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, PartialEq)]
        pub struct $name {
            $( $(#[doc = $doc])+ pub $field: $ty, )*
        }

        impl $crate::params::NodeParams for $name {
            #[allow(unused_variables, reason = "a struct without fields has no parameter to look up")]
            fn specs() -> Vec<$crate::params::ParamSpec> {
                let read_at_start: &[&str] = $crate::node_params!(@names [$($field),*] $($start)?);
                vec![$(
                    $crate::params::ParamSpec {
                        name: stringify!($field),
                        description: concat!($($doc),+).trim_ascii(),
                        default: <$ty as $crate::params::ParamType>::into_value(<$ty>::from($default)),
                        range: $crate::node_params!(@range $($lo, $hi)?),
                        read_at_start: read_at_start.contains(&stringify!($field)),
                    }
                ),*]
            }

            #[allow(unused_variables, reason = "a struct without fields reads no value")]
            fn from_values(values: &$crate::params::ParamValues) -> Self {
                $name {$(
                    $field: values
                        .get(stringify!($field))
                        .and_then(<$ty as $crate::params::ParamType>::from_value)
                        .unwrap_or_else(|| <$ty>::from($default)),
                )*}
            }
        }

        impl Default for $name {
            fn default() -> Self {
                $name { $( $field: <$ty>::from($default), )* }
            }
        }

        $crate::node_params!(@fields_exist $name $($start)?);
    };
    (@names [$($field:ident),*]) => { &[] };
    (@names [$($field:ident),*] all) => { &[$(stringify!($field)),*] };
    (@names [$($field:ident),*] [$($start:ident),* $(,)?]) => { &[$(stringify!($start)),*] };
    (@fields_exist $name:ident $(all)?) => {};
    (@fields_exist $name:ident [$($start:ident),* $(,)?]) => {
        const _: fn(&$name) = |_params| {
            $(let _ = &_params.$start;)*
        };
    };
    (@range $lo:literal, $hi:literal) => { Some(($lo as f64, $hi as f64)) };
    (@range) => { None };
}

crate::node_params! {
    /// The parameters of a node that has none of its own (besides `use_sim_time`).
    pub struct NoParams {}
}

#[cfg(test)]
mod tests;
