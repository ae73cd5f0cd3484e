//! Stopping long work cleanly on request. Each piece of work (a `Manager`, a batch, a
//! Python call) watches its own [`CancelToken`]; a signal to the process (the CLI's
//! SIGINT/SIGTERM handler calls [`request`]) stops them all. A whole signal then stops at
//! the next block or node with [`crate::Error::Interrupted`] (and an extraction writes
//! nothing); a stream ends as if its source had, so what it computed can be saved; a
//! batch stops taking files and leaves the file it was computing unrecorded, for the
//! next run to redo.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;

/// Set by a signal to the process: every token reads as cancelled.
static REQUESTED: AtomicBool = AtomicBool::new(false);

/// The stop request of one piece of work; its clones share it, so that another thread
/// (Python's `Manager.cancel`, a Ctrl-C watcher) can stop the work without touching
/// anything else that runs. It also reads as cancelled once the process was asked to
/// stop ([`request`]).
#[derive(Debug, Clone, Default)]
pub struct CancelToken(Arc<AtomicBool>);

impl CancelToken {
    /// A token of its own, not cancelled.
    pub fn new() -> CancelToken {
        CancelToken::default()
    }

    /// Asks the work that watches this token to stop.
    pub fn cancel(&self) {
        self.0.store(true, Ordering::SeqCst);
    }

    /// Whether this token was cancelled or the process asked to stop.
    pub fn is_cancelled(&self) -> bool {
        self.0.load(Ordering::Relaxed) || requested()
    }

    /// Withdraws this token's request, once the work it stopped has returned (the next
    /// call must run); a request of the process stays.
    pub fn clear(&self) {
        self.0.store(false, Ordering::SeqCst);
    }
}

/// Threads now blocked in a wait on outside input that no flag check can cut short.
static WAITING: AtomicUsize = AtomicUsize::new(0);

/// Marks a wait on outside input that may block for ever and that no check of the flag
/// can cut short (opening a FIFO before its writer comes, reading a device): while it
/// lives, [`waiting_on_input`] is true, and the CLI's handler quits at once on the first
/// signal (nothing can have been written).
#[derive(Debug)]
pub struct InputWait(());

impl InputWait {
    /// Starts the wait; it ends when the value is dropped.
    pub fn start() -> InputWait {
        WAITING.fetch_add(1, Ordering::SeqCst);
        InputWait(())
    }
}

impl Drop for InputWait {
    fn drop(&mut self) {
        WAITING.fetch_sub(1, Ordering::SeqCst);
    }
}

/// Whether a thread is now blocked in an [`InputWait`].
pub fn waiting_on_input() -> bool {
    WAITING.load(Ordering::SeqCst) > 0
}

/// Asks all the running work of the process to stop (a signal handler's call).
pub fn request() {
    REQUESTED.store(true, Ordering::SeqCst);
}

/// Whether the process was asked to stop.
pub fn requested() -> bool {
    REQUESTED.load(Ordering::Relaxed)
}

#[cfg(test)]
mod tests {
    use super::CancelToken;

    /// Clones share one request; a token of its own does not see it; clearing withdraws
    /// it for every clone.
    #[test]
    fn a_token_is_shared_by_its_clones_and_by_no_other() {
        let token = CancelToken::new();
        let clone = token.clone();
        let other = CancelToken::new();
        assert!(!token.is_cancelled());
        clone.cancel();
        assert!(token.is_cancelled() && clone.is_cancelled());
        assert!(!other.is_cancelled());
        token.clear();
        assert!(!clone.is_cancelled());
    }
}
