//! Locks shared by a node's tasks.

use std::sync::{Mutex, MutexGuard};

/// Locks `mutex`, carrying on with its value if a thread panicked while holding it: the values
/// kept under the project's locks are whole at every point, so a panic elsewhere must not take
/// the node's loop down with it.
pub fn lock<T>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    mutex.lock().unwrap_or_else(|e| e.into_inner())
}
