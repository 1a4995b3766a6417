//! `rover lifecycle-manager`: brings the graph's managed nodes up in start order (configure, then
//! activate), as Nav2's lifecycle manager does, for a graph started with `-p autostart:=false`;
//! then keeps bringing up any node that comes back unconfigured (a respawned one) until Ctrl-C.
//! A node that a user deactivated stays inactive.

use std::time::Duration;

use rover_runtime::lifecycle::{LifecycleClient, State, Transition};
use rover_runtime::{NoParams, Runtime};

use crate::processes::nodes::node_names;

/// How often the manager asks each node for its state.
const CHECK_PERIOD: Duration = Duration::from_millis(500);

/// Runs the manager until shutdown.
pub async fn run(runtime: &Runtime) -> anyhow::Result<()> {
    let (node, _) = runtime.node::<NoParams>("lifecycle_manager")?;
    let namespace = node.identity().namespace.clone();
    let clients = node_names()
        .map(|name| node.lifecycle_client(&fully_qualified(&namespace, name)))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let shutdown = runtime.shutdown();
    let mut checks = tokio::time::interval(CHECK_PERIOD);
    loop {
        tokio::select! {
            () = shutdown.wait() => return Ok(()),
            _ = checks.tick() => bring_up(&clients).await,
        }
    }
}

/// The fully qualified name of node `name` in `namespace`.
fn fully_qualified(namespace: &str, name: &str) -> String {
    format!("{}/{name}", namespace.trim_end_matches('/'))
}

/// Brings each unconfigured node up to active, in start order. A node that does not answer, or
/// fails a transition, is tried again at the next check, and the nodes after it wait, so that
/// the order holds.
async fn bring_up(clients: &[LifecycleClient]) {
    for client in clients {
        match client.state().await {
            Some(State::Unconfigured) => {
                let configured = client.change(State::Unconfigured, Transition::Configure).await;
                if !configured || !client.change(State::Inactive, Transition::Activate).await {
                    tracing::warn!("{}: could not bring it up; trying again", client.node());
                    return;
                }
                tracing::info!("{}: configured and active", client.node());
            }
            Some(_) => {}
            None => return,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nodes_are_named_in_the_managers_namespace() {
        assert_eq!(fully_qualified("/", "decision"), "/decision");
        assert_eq!(fully_qualified("/rover1", "bridge"), "/rover1/bridge");
    }
}
