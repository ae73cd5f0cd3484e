//! The atomics and thread handles the scheduler's token protocol and wake-up path are
//! written against. `tests/loom.rs` and `tests/loom_wakeup.rs` include `protocol.rs` (and
//! `wakeup.rs`) with their own `sync` module re-exporting loom's, so the model checker
//! explores the same code the engine runs.

pub(crate) use std::sync::atomic::{fence, AtomicBool, AtomicU32, AtomicU64, Ordering};
pub(crate) use std::thread::Thread;
