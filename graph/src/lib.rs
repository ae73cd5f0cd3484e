//! Request resolution and execution for `afe`: the [`Manager`] turns AFE requests into
//! a DAG of processors shared between requests, and runs it chunk by chunk. The
//! sequential executor here is the reference for every scheduler.

mod block_input;
mod compile;
mod engine;
mod graph;
mod manager;
mod placement;
mod protocol;
mod resolve;
#[cfg(test)]
mod stress;
mod sync;
mod trace;
mod wakeup;
mod whole_run;
pub mod work;

pub use block_input::BlockSource;
pub use engine::{is_worker_thread, MAX_THREADS};
pub use graph::{Channel, OutputRef};
pub use manager::{
    BlockSink, Manager, RequestHandle, Signal, MAX_PREPARED_CHUNK, PREPARE_SECONDS_MAX,
    WHOLE_SIGNAL_BLOCK, WHOLE_SIGNAL_LIMIT_MB,
};
pub use trace::{chrome_trace, TraceEvent};
