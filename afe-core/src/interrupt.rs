//! Stopping long work cleanly on request: the CLI's SIGINT/SIGTERM handler, or Python's
//! signal check, raises one process-wide flag. A whole signal then stops at the next
//! block or node with [`crate::Error::Interrupted`] (and an extraction writes nothing); a
//! stream ends as if its source had, so what it computed can be saved; a batch stops
//! taking files and leaves the file it was computing unrecorded, for the next run to redo.

use std::sync::atomic::{AtomicBool, Ordering};

static REQUESTED: AtomicBool = AtomicBool::new(false);

/// Asks the running work to stop.
pub fn request() {
    REQUESTED.store(true, Ordering::SeqCst);
}

/// Whether a stop was asked for.
pub fn requested() -> bool {
    REQUESTED.load(Ordering::Relaxed)
}

/// Withdraws the request, once the interrupted work has returned (Python: the next call
/// must run).
pub fn clear() {
    REQUESTED.store(false, Ordering::SeqCst);
}
