//! The atomics the scheduler's token protocol is written against. `tests/loom.rs`
//! includes `protocol.rs` with its own `sync` module re-exporting loom's atomics, so the
//! model checker explores the same protocol code the engine runs.

pub(crate) use std::sync::atomic::{fence, AtomicBool, AtomicU32, AtomicU64, Ordering};
