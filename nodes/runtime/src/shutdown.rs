//! Process shutdown on SIGINT or SIGTERM, shared by every node of the process.

use tokio::sync::watch;

/// A cloneable shutdown flag: [`Shutdown::wait`] resolves once shutdown is requested.
#[derive(Clone, Debug)]
pub struct Shutdown {
    requested: watch::Receiver<bool>,
    trigger: std::sync::Arc<watch::Sender<bool>>,
}

impl Shutdown {
    /// A flag that is only set by [`Shutdown::request`].
    pub fn new() -> Self {
        let (trigger, requested) = watch::channel(false);
        Shutdown { requested, trigger: std::sync::Arc::new(trigger) }
    }

    /// A flag that is also set on SIGINT (Ctrl-C) or SIGTERM. Needs a tokio runtime.
    pub fn on_signals() -> Self {
        let shutdown = Self::new();
        let on_signal = shutdown.clone();
        tokio::spawn(async move {
            let signal = wait_for_signal().await;
            tracing::info!("received {signal}, shutting down");
            on_signal.request();
        });
        shutdown
    }

    /// Requests shutdown.
    pub fn request(&self) {
        self.trigger.send_replace(true);
    }

    /// True once shutdown was requested.
    pub fn is_requested(&self) -> bool {
        *self.requested.borrow()
    }

    /// Resolves when shutdown is requested.
    pub async fn wait(&self) {
        let mut requested = self.requested.clone();
        let _ = requested.wait_for(|&r| r).await;
    }
}

impl Default for Shutdown {
    fn default() -> Self {
        Self::new()
    }
}

async fn wait_for_signal() -> &'static str {
    use tokio::signal::unix::{SignalKind, signal};
    let (Ok(mut interrupt), Ok(mut terminate)) = (signal(SignalKind::interrupt()), signal(SignalKind::terminate()))
    else {
        tracing::warn!("cannot install signal handlers; Ctrl-C will kill the process abruptly");
        return std::future::pending().await;
    };
    tokio::select! {
        _ = interrupt.recv() => "SIGINT",
        _ = terminate.recv() => "SIGTERM",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn request_wakes_every_clone() {
        let shutdown = Shutdown::new();
        let waiter = shutdown.clone();
        let task = tokio::spawn(async move { waiter.wait().await });
        assert!(!shutdown.is_requested());
        shutdown.request();
        tokio::time::timeout(std::time::Duration::from_secs(1), task).await.unwrap().unwrap();
        assert!(shutdown.is_requested());
    }
}
