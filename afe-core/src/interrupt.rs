//! Stopping long work cleanly on request: the CLI's SIGINT/SIGTERM handler, or Python's
//! signal check, raises one process-wide flag. A whole signal then stops at the next
//! block or node with [`crate::Error::Interrupted`] (and an extraction writes nothing); a
//! stream ends as if its source had, so what it computed can be saved; a batch stops
//! taking files and leaves the file it was computing unrecorded, for the next run to redo.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

static REQUESTED: AtomicBool = AtomicBool::new(false);

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
