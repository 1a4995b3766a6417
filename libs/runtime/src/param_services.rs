//! The ROS 2 parameter services of a node (`~/get_parameters`, `~/set_parameters`,
//! `~/list_parameters`, ...), answered from the node's declared parameters so that `ros2 param`
//! lists, gets, sets and describes them. Values live in the `ros2-client` node, which checks a new
//! value with the node's validator and publishes the change on `/parameter_events`.

use std::sync::{Arc, Mutex};

use futures::StreamExt;
use ros2_client::parameters::raw;
use ros2_client::rcl_interfaces as rcl;
use ros2_client::service::Server;
use ros2_client::{Node, Parameter, ParameterValue};

use crate::params::{self, ParamSpec};
use crate::services;
use crate::sync::lock;

/// Separator of the parts of a parameter name (`a.b.c`).
const NAME_SEPARATOR: char = '.';

/// The six servers of one node.
struct Servers {
    get: Server<rcl::GetParametersRequest, rcl::GetParametersResponse>,
    types: Server<rcl::GetParameterTypesRequest, rcl::GetParameterTypesResponse>,
    set: Server<rcl::SetParametersRequest, rcl::SetParametersResponse>,
    set_atomically: Server<rcl::SetParametersRequest, rcl::SetParametersAtomicallyResponse>,
    list: Server<rcl::ListParametersRequest, rcl::ListParametersResponse>,
    describe: Server<rcl::DescribeParametersRequest, rcl::DescribeParametersResponse>,
}

/// Creates the parameter services of `node`, whose parameters are `specs`, and answers them in a
/// task of the current tokio runtime for as long as the process runs.
pub(crate) fn start(node: &Arc<Mutex<Node>>, specs: Vec<ParamSpec>) -> anyhow::Result<()> {
    let servers = {
        let node = &mut lock(node);
        Servers {
            get: services::node_server(node, "rcl_interfaces", "GetParameters")?,
            types: services::node_server(node, "rcl_interfaces", "GetParameterTypes")?,
            set: services::node_server(node, "rcl_interfaces", "SetParameters")?,
            set_atomically: services::node_server(node, "rcl_interfaces", "SetParametersAtomically")?,
            list: services::node_server(node, "rcl_interfaces", "ListParameters")?,
            describe: services::node_server(node, "rcl_interfaces", "DescribeParameters")?,
        }
    };
    let table =
        Table { node: Arc::clone(node), specs: std::iter::once(params::use_sim_time_spec()).chain(specs).collect() };
    tokio::spawn(async move { serve(&servers, &table).await });
    Ok(())
}

/// Answers the requests of `servers` from `table` until every request stream ends.
async fn serve(servers: &Servers, table: &Table) {
    let mut get = servers.get.receive_request_stream();
    let mut types = servers.types.receive_request_stream();
    let mut set = servers.set.receive_request_stream();
    let mut set_atomically = servers.set_atomically.receive_request_stream();
    let mut list = servers.list.receive_request_stream();
    let mut describe = servers.describe.receive_request_stream();
    loop {
        tokio::select! {
            Some(request) = get.next() => services::answer(&servers.get, request, |r| table.get(r)).await,
            Some(request) = types.next() => services::answer(&servers.types, request, |r| table.types(r)).await,
            Some(request) = set.next() => services::answer(&servers.set, request, |r| table.set(r)).await,
            Some(request) = set_atomically.next() => {
                services::answer(&servers.set_atomically, request, |r| table.set_atomically(r)).await
            }
            Some(request) = list.next() => services::answer(&servers.list, request, |r| table.list(r)).await,
            Some(request) = describe.next() => services::answer(&servers.describe, request, |r| table.describe(r)).await,
            else => return,
        }
    }
}

/// The parameters of one node: their declarations and the node that holds their values.
struct Table {
    node: Arc<Mutex<Node>>,
    specs: Vec<ParamSpec>,
}

impl Table {
    fn value(&self, name: &str) -> Option<ParameterValue> {
        lock(&self.node).get_parameter(name)
    }

    fn get(&self, request: rcl::GetParametersRequest) -> rcl::GetParametersResponse {
        let value = |name: &String| self.value(name).unwrap_or(ParameterValue::NotSet).into();
        rcl::GetParametersResponse { values: request.names.iter().map(value).collect() }
    }

    fn types(&self, request: rcl::GetParameterTypesRequest) -> rcl::GetParameterTypesResponse {
        let type_of = |name: &String| self.value(name).map_or(raw::ParameterType::NOT_SET, |v| type_code(&v));
        rcl::GetParameterTypesResponse { values: request.names.iter().map(type_of).collect() }
    }

    fn set(&self, request: rcl::SetParametersRequest) -> rcl::SetParametersResponse {
        let results = request.parameter.into_iter().map(|p| result(self.set_one(Parameter::from(p)))).collect();
        rcl::SetParametersResponse { results }
    }

    /// Sets every parameter of the request or none: all are checked before the first is set.
    fn set_atomically(&self, request: rcl::SetParametersRequest) -> rcl::SetParametersAtomicallyResponse {
        let parameters: Vec<Parameter> = request.parameter.into_iter().map(Parameter::from).collect();
        let checked = parameters.iter().try_for_each(|p| settable_value(&self.specs, p).map(|_| ()));
        let outcome = checked.and_then(|()| parameters.into_iter().try_for_each(|p| self.set_one(p)));
        rcl::SetParametersAtomicallyResponse { result: result(outcome) }
    }

    fn list(&self, request: rcl::ListParametersRequest) -> rcl::ListParametersResponse {
        let names: Vec<&str> = self.specs.iter().map(|s| s.name).collect();
        rcl::ListParametersResponse { result: list(&names, &request.prefixes, request.depth) }
    }

    fn describe(&self, request: rcl::DescribeParametersRequest) -> rcl::DescribeParametersResponse {
        rcl::DescribeParametersResponse { values: request.names.iter().map(|n| describe(&self.specs, n)).collect() }
    }

    fn set_one(&self, parameter: Parameter) -> Result<(), String> {
        let value = settable_value(&self.specs, &parameter)?;
        lock(&self.node).set_parameter(&parameter.name, value)
    }
}

/// The value `parameter` would be set to (integers widened where a number is declared), if it
/// may be set: declared in `specs`, not read only when the node starts, of its type, within its
/// range.
fn settable_value(specs: &[ParamSpec], parameter: &Parameter) -> Result<ParameterValue, String> {
    let spec = specs.iter().find(|s| s.name == parameter.name);
    let spec = spec.ok_or_else(|| format!("unknown parameter `{}`", parameter.name))?;
    if spec.read_at_start {
        let name = spec.name;
        return Err(format!("{name} is read when the node starts: start it with -p {name}:=VALUE"));
    }
    params::check_value(spec, &parameter.value).map_err(|reason| format!("{} {reason}", parameter.name))
}

fn result(outcome: Result<(), String>) -> raw::SetParametersResult {
    match outcome {
        Ok(()) => raw::SetParametersResult { successful: true, reason: String::new() },
        Err(reason) => raw::SetParametersResult { successful: false, reason },
    }
}

/// The `rcl_interfaces/ParameterType` code of `value`.
fn type_code(value: &ParameterValue) -> u8 {
    value.to_parameter_type() as u8
}

/// The parameters among `names` that a `list_parameters` request for `prefixes` (none: all) and
/// `depth` (0: any) asks for, and the prefixes of those with nested names. A name is `depth`
/// deep when it has fewer than `depth` separators after the prefix.
fn list(names: &[&str], prefixes: &[String], depth: u64) -> rcl::ListParametersResult {
    let shallow = |rest: &str| depth == 0 || (rest.matches(NAME_SEPARATOR).count() as u64) < depth;
    let under = |name: &str, prefix: &str| {
        name == prefix || name.strip_prefix(prefix).and_then(|r| r.strip_prefix(NAME_SEPARATOR)).is_some_and(shallow)
    };
    let wanted = |name: &str| {
        if prefixes.is_empty() { shallow(name) } else { prefixes.iter().any(|prefix| under(name, prefix)) }
    };
    let names: Vec<String> = names.iter().filter(|name| wanted(name)).map(|name| name.to_string()).collect();
    let mut nested: Vec<String> =
        names.iter().filter_map(|n| n.rsplit_once(NAME_SEPARATOR).map(|(prefix, _)| prefix.to_string())).collect();
    nested.sort();
    nested.dedup();
    rcl::ListParametersResult { names, prefixes: nested }
}

/// What `describe_parameters` says of `name`: its type, description and range, or that it is
/// not declared.
fn describe(specs: &[ParamSpec], name: &str) -> raw::ParameterDescriptor {
    let spec = specs.iter().find(|s| s.name == name);
    let (mut integer_range, mut floating_point_range) = (Vec::new(), Vec::new());
    match spec.map(|s| (s.range, &s.default)) {
        Some((Some((from, to)), ParameterValue::Integer(_))) => {
            integer_range.push(raw::IntegerRange { from_value: from as i64, to_value: to as i64, step: 0 });
        }
        Some((Some((from_value, to_value)), _)) => {
            floating_point_range.push(raw::FloatingPointRange { from_value, to_value, step: 0.0 });
        }
        _ => {}
    }
    raw::ParameterDescriptor {
        name: name.to_string(),
        r#type: spec.map_or(raw::ParameterType::NOT_SET, |s| type_code(&s.default)),
        description: spec.map_or("not declared by this node", |s| s.description).to_string(),
        additional_constraints: String::new(),
        read_only: spec.is_none_or(|s| s.read_at_start),
        dynamic_typing: false,
        floating_point_range,
        integer_range,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ros_args::tests::strings;

    #[test]
    fn a_list_request_selects_by_prefix_and_depth() {
        let names = ["port", "limits.speed", "limits.turn.rate", "limits_other"];
        let all = list(&names, &[], 0);
        assert_eq!(all.names, strings(&names));
        assert_eq!(all.prefixes, strings(&["limits", "limits.turn"]));
        assert_eq!(list(&names, &[], 1).names, strings(&["port", "limits_other"]), "no separator at depth 1");
        let limits = list(&names, &strings(&["limits"]), 0);
        assert_eq!(limits.names, strings(&["limits.speed", "limits.turn.rate"]), "not limits_other");
        assert_eq!(list(&names, &strings(&["limits"]), 1).names, strings(&["limits.speed"]));
        assert!(list(&names, &strings(&["nothing"]), 0).names.is_empty());
    }

    fn spec(name: &'static str, default: ParameterValue, range: Option<(f64, f64)>) -> ParamSpec {
        ParamSpec { name, description: "what it does", default, range, read_at_start: false }
    }

    #[test]
    fn a_parameter_read_at_start_is_refused_and_described_read_only() {
        let specs = [
            ParamSpec { read_at_start: true, ..spec("port", ParameterValue::Integer(4567), Some((1.0, 65535.0))) },
            spec("deadline_ms", ParameterValue::Double(50.0), Some((0.0, 250.0))),
        ];
        let set = |name: &str, value| settable_value(&specs, &Parameter { name: name.into(), value });
        assert_eq!(
            set("port", ParameterValue::Integer(80)),
            Err("port is read when the node starts: start it with -p port:=VALUE".to_string())
        );
        assert_eq!(set("deadline_ms", ParameterValue::Integer(20)), Ok(ParameterValue::Double(20.0)), "widened");
        assert!(set("deadline_ms", ParameterValue::Double(300.0)).unwrap_err().contains("outside the allowed range"));
        assert!(describe(&specs, "port").read_only);
        assert!(!describe(&specs, "deadline_ms").read_only);
        assert!(describe(&specs, "missing").read_only, "not declared");
    }

    #[test]
    fn a_described_parameter_has_its_type_description_and_range() {
        let specs = [
            spec("deadline_ms", ParameterValue::Double(50.0), Some((0.0, 250.0))),
            spec("every", ParameterValue::Integer(10), Some((0.0, 100.0))),
            spec("rule", ParameterValue::String("rgb".into()), None),
        ];
        let deadline = describe(&specs, "deadline_ms");
        assert_eq!((deadline.r#type, deadline.description.as_str()), (raw::ParameterType::DOUBLE, "what it does"));
        assert_eq!(deadline.floating_point_range[0].to_value, 250.0);
        assert!(deadline.integer_range.is_empty() && !deadline.read_only);
        let every = describe(&specs, "every");
        assert_eq!((every.r#type, every.integer_range[0].to_value), (raw::ParameterType::INTEGER, 100));
        let rule = describe(&specs, "rule");
        assert!(rule.integer_range.is_empty() && rule.floating_point_range.is_empty());
        assert_eq!(describe(&specs, "missing").r#type, raw::ParameterType::NOT_SET);
    }

    /// Fuzz target: parameters as a peer sends them (any type code, any fields) are set or
    /// refused with a reason, never a panic, and a value set is within its declared range.
    mod fuzz {
        use proptest::prelude::*;

        use super::*;

        fn raw_value() -> impl Strategy<Value = raw::ParameterValue> {
            let scalars = (any::<u8>(), any::<bool>(), any::<i64>(), any::<f64>(), "\\PC{0,12}");
            let arrays = proptest::collection::vec(any::<f64>(), 0..4);
            (scalars, arrays).prop_map(|((ptype, boolean_value, int_value, double_value, string_value), doubles)| {
                raw::ParameterValue {
                    ptype: ptype % 12,
                    boolean_value,
                    int_value,
                    double_value,
                    string_value,
                    byte_array: vec![ptype],
                    bool_array: vec![boolean_value],
                    int_array: vec![int_value],
                    double_array: doubles,
                    string_array: vec!["x".into()],
                }
            })
        }

        proptest! {
            #[test]
            fn fuzz_param_service_raw_requests(name in "(deadline_ms|every|rule|\\PC{0,8})", value in raw_value()) {
                let specs = [
                    spec("deadline_ms", ParameterValue::Double(50.0), Some((0.0, 250.0))),
                    spec("every", ParameterValue::Integer(10), Some((0.0, 100.0))),
                    spec("rule", ParameterValue::String("rgb".into()), None),
                ];
                let parameter = Parameter::from(raw::Parameter { name: name.clone(), value });
                match settable_value(&specs, &parameter) {
                    Ok(ParameterValue::Double(v)) => prop_assert!((0.0..=250.0).contains(&v), "{name} = {v}"),
                    Ok(ParameterValue::Integer(v)) => prop_assert!((0..=100).contains(&v), "{name} = {v}"),
                    Ok(other) => prop_assert!(matches!(other, ParameterValue::String(_)), "{name} = {other:?}"),
                    Err(reason) => prop_assert!(!reason.is_empty()),
                }
                let _ = describe(&specs, &name);
                let _ = list(&["deadline_ms", "every", "rule"], &[name], u64::from(parameter.name.len() as u8));
            }
        }
    }
}
