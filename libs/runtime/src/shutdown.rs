//! Process shutdown on SIGINT or SIGTERM, shared by every node of the process.

use tokio::signal::unix::{Signal, SignalKind, signal};
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

    /// A flag that is also set on SIGINT (Ctrl-C) or SIGTERM. Needs a tokio runtime. The handlers
    /// are in place when it returns, so a signal that arrives at once is not lost (a process started
    /// in the background of a shell inherits an ignored SIGINT until then).
    pub fn on_signals() -> Self {
        let shutdown = Self::new();
        let on_signal = shutdown.clone();
        match Signals::install() {
            Ok(mut signals) => {
                tokio::spawn(async move {
                    let signal = signals.next().await;
                    tracing::info!("received {signal}, shutting down");
                    on_signal.request();
                });
            }
            Err(e) => tracing::warn!("cannot install signal handlers ({e}); Ctrl-C will kill the process abruptly"),
        }
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

/// The SIGINT and SIGTERM streams of the process.
struct Signals {
    interrupt: Signal,
    terminate: Signal,
}

impl Signals {
    /// Installs the handlers of both signals.
    fn install() -> std::io::Result<Self> {
        Ok(Signals { interrupt: signal(SignalKind::interrupt())?, terminate: signal(SignalKind::terminate())? })
    }

    /// The name of the next signal that arrives.
    async fn next(&mut self) -> &'static str {
        tokio::select! {
            _ = self.interrupt.recv() => "SIGINT",
            _ = self.terminate.recv() => "SIGTERM",
        }
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

    #[tokio::test]
    async fn a_sigint_at_once_after_the_handlers_are_made_requests_shutdown() {
        let shutdown = Shutdown::on_signals();
        nix::sys::signal::raise(nix::sys::signal::Signal::SIGINT).expect("raise SIGINT");
        tokio::time::timeout(std::time::Duration::from_secs(2), shutdown.wait()).await.expect("shutdown requested");
    }
}
