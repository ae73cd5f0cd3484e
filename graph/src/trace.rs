//! Per-node, per-chunk timing of the concurrent scheduler, and its export in the Chrome
//! trace-event format (opens in Perfetto or chrome://tracing).

use std::cell::UnsafeCell;

use serde_json::{json, Value};

use crate::sync::{AtomicU64, Ordering};

/// When one node went through the states of one chunk, in ns since the engine started.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TraceEvent {
    /// Node index in the graph.
    pub node: u32,
    /// Chunk index.
    pub chunk: u64,
    /// Claimed by the scheduler (READY: parents published, own slot free).
    pub ready_ns: u64,
    /// Started processing on a worker (PROCESS).
    pub start_ns: u64,
    /// Finished processing (WAIT is folded into READY by the double-buffered slots, so
    /// the node goes straight on to RELEASE).
    pub end_ns: u64,
    /// Published its output and handed out tokens (RELEASE done).
    pub released_ns: u64,
}

/// Preallocated per-worker event logs: a worker appends only to its own, within capacity.
pub(crate) struct Tracer {
    logs: Box<[UnsafeCell<Vec<TraceEvent>>]>,
    capacity: usize,
    dropped: AtomicU64,
}

impl Tracer {
    pub(crate) fn new(workers: usize, capacity: usize) -> Self {
        Tracer {
            logs: (0..workers)
                .map(|_| UnsafeCell::new(Vec::with_capacity(capacity)))
                .collect(),
            capacity,
            dropped: AtomicU64::new(0),
        }
    }

    /// Appends an event to worker `w`'s log (no allocation: full logs drop events).
    pub(crate) fn record(&self, w: usize, ev: TraceEvent) {
        if self.capacity == 0 {
            return;
        }
        // SAFETY: only worker `w` writes log `w`; the caller reads logs only while the
        // pool is quiescent.
        #[allow(unsafe_code)]
        let log = unsafe { &mut *self.logs[w].get() };
        if log.len() < self.capacity {
            log.push(ev);
        } else {
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// Events that did not fit in the preallocated logs.
    pub(crate) fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }

    /// Every recorded event with its worker.
    pub(crate) fn events(&self) -> Vec<(usize, TraceEvent)> {
        let mut out = Vec::new();
        for (w, log) in self.logs.iter().enumerate() {
            // SAFETY: called by the caller while the pool is quiescent.
            #[allow(unsafe_code)]
            let log = unsafe { &*log.get() };
            out.extend(log.iter().map(|e| (w, *e)));
        }
        out
    }
}

/// The events as a Chrome trace: one track per worker with a slice per node and chunk,
/// plus the time each node spent claimed but waiting for a worker.
/// `dropped` counts the events that did not fit in the preallocated logs (recorded in the
/// trace's metadata so that a truncated trace says so).
pub fn chrome_trace(labels: &[String], events: &[(usize, TraceEvent)], dropped: u64) -> Value {
    let us = |ns: u64| ns as f64 / 1000.0;
    let mut out: Vec<Value> = Vec::with_capacity(2 * events.len() + labels.len());
    for (w, e) in events {
        let name = labels.get(e.node as usize).cloned().unwrap_or_default();
        out.push(json!({
            "name": name, "cat": "process", "ph": "X", "pid": 1, "tid": w,
            "ts": us(e.start_ns), "dur": us(e.end_ns - e.start_ns),
            "args": {"chunk": e.chunk, "release_us": us(e.released_ns - e.end_ns)},
        }));
        if e.ready_ns > 0 && e.ready_ns < e.start_ns {
            out.push(json!({
                "name": format!("{name} ready"), "cat": "ready", "ph": "X", "pid": 2,
                "tid": e.node, "ts": us(e.ready_ns), "dur": us(e.start_ns - e.ready_ns),
                "args": {"chunk": e.chunk},
            }));
        }
    }
    let workers = events.iter().map(|(w, _)| *w).max().map_or(0, |m| m + 1);
    for w in 0..workers {
        out.push(json!({"name": "thread_name", "ph": "M", "pid": 1, "tid": w,
                         "args": {"name": format!("worker {w}")}}));
    }
    for (n, label) in labels.iter().enumerate() {
        out.push(json!({"name": "thread_name", "ph": "M", "pid": 2, "tid": n,
                         "args": {"name": format!("{label} (queued)")}}));
    }
    json!({"traceEvents": out, "displayTimeUnit": "ms", "metadata": {"dropped_events": dropped}})
}
