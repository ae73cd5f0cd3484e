//! Ctrl-C during long calls: Python runs signal handlers only on its main thread between
//! bytecodes, so a call that releases the GIL for minutes would take its
//! KeyboardInterrupt only at the end. Here the work runs on a helper thread while the
//! calling thread waits with the GIL released and checks for signals every 50 ms; on one,
//! the work's own stop request is cancelled (never the process's: other threads' work
//! runs on) and the exception is raised once it has stopped.

use std::sync::{mpsc, Mutex};
use std::time::Duration;

use afe::interrupt::CancelToken;
use pyo3::prelude::*;

/// How often the waiting thread checks for signals.
const CHECK: Duration = Duration::from_millis(50);

/// Runs `work`, which watches `cancel`, interruptibly (see the module): its result, or the
/// signal's exception (KeyboardInterrupt) if one came while it ran (`cancel` is then
/// left cancelled: a token that outlives the call is its owner's to clear).
pub fn interruptible<R: Send>(
    py: Python<'_>,
    cancel: &CancelToken,
    work: impl FnOnce() -> R + Send,
) -> PyResult<R> {
    let (result, signal) = std::thread::scope(|s| {
        let (tx, rx) = mpsc::channel();
        // a receiver is not Sync: the lock lets the GIL-free closure borrow it
        let rx = Mutex::new(rx);
        s.spawn(move || {
            // the receiver outlives the thread inside the scope: a send cannot fail
            let _ = tx.send(work());
        });
        let mut signal = None;
        loop {
            let got = py.allow_threads(|| match rx.lock() {
                Ok(rx) => rx.recv_timeout(CHECK),
                Err(_) => Err(mpsc::RecvTimeoutError::Disconnected),
            });
            match got {
                Ok(r) => break (Some(r), signal),
                Err(mpsc::RecvTimeoutError::Timeout) => {
                    if signal.is_none() {
                        if let Err(e) = py.check_signals() {
                            cancel.cancel();
                            signal = Some(e);
                        }
                    }
                }
                // the work panicked: the scope re-raises the panic when it joins
                Err(mpsc::RecvTimeoutError::Disconnected) => break (None, signal),
            }
        }
    });
    if let Some(e) = signal {
        return Err(e);
    }
    result.ok_or_else(|| pyo3::exceptions::PyRuntimeError::new_err("the computation failed"))
}
