//! The runtime's own ROS 2 services (parameters, lifecycle): creating a node's servers and the
//! clients of another node's, and answering requests, written once.

use anyhow::Context as _;
use ros2_client::service::{Client, Server};
use ros2_client::{Message, Name, Node, ServiceMapping, ServiceTypeName};

/// What a service's request and response must be for the runtime to serve and call it.
pub(crate) trait ServiceMessage: Message + Clone + 'static {}

impl<T: Message + Clone + 'static> ServiceMessage for T {}

/// The server, on `node`, of one of the services every node of its kind offers (e.g. `GetState` of
/// `lifecycle_msgs`): named, as ROS 2 names them, after its type in snake case (`get_state`) under
/// the node's name.
pub(crate) fn node_server<Req: ServiceMessage, Resp: ServiceMessage>(
    node: &mut Node,
    package: &str,
    type_name: &str,
) -> anyhow::Result<Server<Req, Resp>> {
    let name = service_name(&node.fully_qualified_name(), &snake_case(type_name))?;
    server(node, &name, package, type_name)
}

/// The server, on `node`, of the service named `name`, whose type is `<package>/srv/<type_name>`.
pub(crate) fn server<Req: ServiceMessage, Resp: ServiceMessage>(
    node: &mut Node,
    name: &Name,
    package: &str,
    type_name: &str,
) -> anyhow::Result<Server<Req, Resp>> {
    let (qos, type_name) = (crate::qos::services(), ServiceTypeName::new(package, type_name));
    node.create_server(ServiceMapping::Enhanced, name, &type_name, qos.clone(), qos)
        .with_context(|| format!("cannot create the service {name}"))
}

/// A client, created on `on`, of the service of type `<package>/srv/<type_name>` that node `node`
/// (fully qualified) offers as every node of its kind does (see [`node_server`]).
pub(crate) fn node_client<Req: ServiceMessage, Resp: ServiceMessage>(
    on: &mut Node,
    node: &str,
    package: &str,
    type_name: &str,
) -> anyhow::Result<Client<Req, Resp>> {
    let name = service_name(node, &snake_case(type_name))?;
    let (qos, type_name) = (crate::qos::services(), ServiceTypeName::new(package, type_name));
    on.create_client(ServiceMapping::Enhanced, &name, &type_name, qos.clone(), qos)
        .with_context(|| format!("cannot create a client of {name}"))
}

/// `GetAvailableStates` as `get_available_states`.
fn snake_case(type_name: &str) -> String {
    let mut snake = String::with_capacity(type_name.len() + 4);
    for (i, c) in type_name.chars().enumerate() {
        if c.is_ascii_uppercase() && i > 0 {
            snake.push('_');
        }
        snake.push(c.to_ascii_lowercase());
    }
    snake
}

/// The name of service `service` of node `node` (fully qualified): `<node>/<service>`.
fn service_name(node: &str, service: &str) -> anyhow::Result<Name> {
    Name::new(node, service).map_err(|e| anyhow::anyhow!("{node}/{service}: {e}"))
}

/// Sends `handle`'s response to a request of `server`; a request that could not be read, or a
/// response that could not be sent, is logged.
pub(crate) async fn answer<Req: ServiceMessage, Resp: ServiceMessage>(
    server: &Server<Req, Resp>,
    request: ros2_client::ReadResult<(ros2_client::RmwRequestId, Req)>,
    handle: impl FnOnce(Req) -> Resp,
) {
    match request {
        Ok((id, request)) => {
            if let Err(e) = server.async_send_response(id, handle(request)).await {
                crate::rejections::request_problem(
                    "unanswered_request",
                    &format_args!("cannot answer a service request: {e:?}"),
                );
            }
        }
        Err(e) => crate::rejections::request_problem(
            "malformed_request",
            &format_args!("dropped a malformed service request: {e:?}"),
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::snake_case;

    #[test]
    fn a_service_type_names_its_service_in_snake_case() {
        assert_eq!(snake_case("GetAvailableTransitions"), "get_available_transitions");
        assert_eq!(snake_case("GetState"), "get_state");
        assert_eq!(snake_case("DescribeParameters"), "describe_parameters");
    }
}
