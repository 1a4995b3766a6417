//! The runtime's own ROS 2 services (parameters, lifecycle): creating a node's servers and the
//! clients of another node's, and answering requests, written once.

use anyhow::Context as _;
use ros2_client::service::{Client, Server};
use ros2_client::{Message, Name, Node, ServiceMapping, ServiceTypeName};

/// The server of `node`'s service `service` (e.g. `get_state`, under the node's name), whose type
/// is `<package>/srv/<type_name>`.
pub(crate) fn server<Req, Resp>(
    node: &mut Node,
    service: &str,
    package: &str,
    type_name: &str,
) -> anyhow::Result<Server<Req, Resp>>
where
    Req: Message + Clone + 'static,
    Resp: Message + 'static,
{
    let name = service_name(&node.fully_qualified_name(), service)?;
    server_named(node, &name, package, type_name)
}

/// The server, on `node`, of the service named `name`, whose type is `<package>/srv/<type_name>`.
pub(crate) fn server_named<Req, Resp>(
    node: &mut Node,
    name: &Name,
    package: &str,
    type_name: &str,
) -> anyhow::Result<Server<Req, Resp>>
where
    Req: Message + Clone + 'static,
    Resp: Message + 'static,
{
    let (qos, type_name) = (crate::qos::services(), ServiceTypeName::new(package, type_name));
    node.create_server(ServiceMapping::Enhanced, name, &type_name, qos.clone(), qos)
        .with_context(|| format!("cannot create the service {name}"))
}

/// A client, created on `on`, of the service `service` of node `node` (fully qualified), whose
/// type is `<package>/srv/<type_name>`.
pub(crate) fn client<Req, Resp>(
    on: &mut Node,
    node: &str,
    service: &str,
    package: &str,
    type_name: &str,
) -> anyhow::Result<Client<Req, Resp>>
where
    Req: Message + Clone + 'static,
    Resp: Message + 'static,
{
    let name = service_name(node, service)?;
    let (qos, type_name) = (crate::qos::services(), ServiceTypeName::new(package, type_name));
    on.create_client(ServiceMapping::Enhanced, &name, &type_name, qos.clone(), qos)
        .with_context(|| format!("cannot create a client of {node}/{service}"))
}

/// The name of service `service` of node `node` (fully qualified): `<node>/<service>`.
fn service_name(node: &str, service: &str) -> anyhow::Result<Name> {
    Name::new(node, service).map_err(|e| anyhow::anyhow!("{node}/{service}: {e}"))
}

/// Sends `handle`'s response to a request of `server`; a request that could not be read, or a
/// response that could not be sent, is logged.
pub(crate) async fn answer<Req, Resp>(
    server: &Server<Req, Resp>,
    request: ros2_client::ReadResult<(ros2_client::RmwRequestId, Req)>,
    handle: impl FnOnce(Req) -> Resp,
) where
    Req: Message + Clone + 'static,
    Resp: Message + 'static,
{
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
