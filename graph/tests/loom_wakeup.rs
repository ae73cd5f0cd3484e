//! Model check (loom) of the engine's wake-up and parking path: the very `wakeup.rs` (the
//! ready set, the caller's wait word, the idle mask) and `protocol.rs` the engine runs,
//! compiled here against loom's atomics and threads, driven the way `engine.rs` drives
//! them. Two workers and the caller run a source with two children over three chunks,
//! with at most one preemption (loom's bound) per execution.
//!
//! The caller plays the engine's caller: it submits each chunk into the source (waiting
//! for the source's slot), keeps at most two chunks in flight, collects each chunk
//! (waiting for it to complete, then returning its reader tokens), waits for the pool to
//! go idle, and shuts the pool down. While it waits it runs ready nodes itself, as the
//! engine's caller does, and parks only when none is ready. Workers take nodes from the ready set, run them,
//! release them (offering the nodes that may have become ready, waking idle workers for
//! the extra ones and the caller when its chunk is complete), and when the ready set is
//! empty go idle and park. Both park with loom's plain `park` (the engine's
//! `park_timeout` is only a safety net), so a lost wake-up leaves a thread parked for
//! ever, which loom reports as a deadlock. Loom also fails on a data race on a slot and
//! the caller on a wrong value.
//!
//! Not modelled: the engine's `active` count and table swap, spinning before parking,
//! tracing and panics.

#![allow(dead_code, unsafe_code)]

mod sync {
    pub(crate) use loom::sync::atomic::{fence, AtomicBool, AtomicU32, AtomicU64, Ordering};
    pub(crate) use loom::thread::Thread;
}

#[path = "../src/protocol.rs"]
mod protocol;

mod model;

#[path = "../src/wakeup.rs"]
mod wakeup;

use std::sync::OnceLock;

use loom::cell::UnsafeCell;
use loom::sync::atomic::{AtomicBool, Ordering};
use loom::sync::Arc;
use loom::thread::Thread;
use protocol::{consumed, next_chunk, release, Links, NodeSync};
use wakeup::{ReadySet, Wakeup, WAIT_CHUNK, WAIT_IDLE, WAIT_SOURCE};

/// Worker threads.
const WORKERS: usize = 2;
/// Chunks through the graph: the third reuses the source's first slot.
const CHUNKS: u64 = 3;

/// The engine's shared state, reduced to what the wake-up path touches.
struct Model {
    sync: Vec<NodeSync>,
    links: Vec<Links>,
    /// Each node's two output slots (the source's are written by the caller).
    slots: Vec<[UnsafeCell<u64>; 2]>,
    ready: ReadySet,
    wakeup: Wakeup,
    shutdown: AtomicBool,
    /// Set once the workers are spawned, as in the engine.
    workers: OnceLock<Box<[Thread]>>,
    caller: Thread,
    /// Whether the caller runs ready nodes while it waits, as the engine's does.
    helps: bool,
}

impl Model {
    /// The graph of `parents` (node 0 is the source), as `Engine::install` links it: every
    /// node but the source has the caller as an extra reader.
    fn new(parents: &[&[usize]], helps: bool) -> Self {
        let n = parents.len();
        Model {
            sync: (0..n).map(|_| NodeSync::new()).collect(),
            links: model::links(parents, true),
            slots: (0..n)
                .map(|_| [UnsafeCell::new(0), UnsafeCell::new(0)])
                .collect(),
            ready: ReadySet::new(n),
            wakeup: Wakeup::new(),
            shutdown: AtomicBool::new(false),
            workers: OnceLock::new(),
            caller: loom::thread::current(),
            helps,
        }
    }

    /// `Shared::offer`.
    fn offer(&self, n: usize) -> bool {
        self.wakeup.offer(
            &self.sync,
            &self.links,
            &self.ready,
            n,
            || &self.caller,
            || (),
        )
    }

    /// `Shared::wake`.
    fn wake(&self, count: usize) {
        if let Some(workers) = self.workers.get() {
            self.wakeup.wake(count, workers);
        }
    }

    /// What node `n` must hold for chunk `k` (see [`model::expected`]).
    fn expected(&self, n: usize, k: u64) -> u64 {
        model::expected(&self.links, n, k)
    }

    /// `Shared::worker_loop`, without the spinning.
    fn worker_loop(&self, id: usize) {
        while !self.shutdown.load(Ordering::Acquire) {
            while let Some(n) = self.ready.pop(&[1 << (id + 1)]) {
                self.run(n);
            }
            let nothing = self.wakeup.going_idle(id, &self.ready);
            if nothing {
                self.wakeup.wake_caller_if(WAIT_IDLE, || &self.caller);
            }
            if nothing && !self.shutdown.load(Ordering::Acquire) {
                loom::thread::park();
            }
            self.wakeup.awake(id);
        }
    }

    /// `Shared::run`: Process and Release of one claimed node.
    fn run(&self, n: usize) {
        let k = next_chunk(&self.sync, n);
        let slot = (k % 2) as usize;
        // SAFETY (checked by loom): parents' slots are published and pinned, ours is free.
        let value = self.links[n]
            .parents
            .iter()
            .map(|&p| self.slots[p][slot].with(|v| unsafe { *v }))
            .sum::<u64>()
            + n as u64;
        self.slots[n][slot].with_mut(|v| unsafe { *v = value });
        let mut queued = 0;
        release(&self.sync, &self.links, n, k, |x| {
            queued += usize::from(self.offer(x));
        });
        self.wake(queued.saturating_sub(1));
        self.wakeup
            .chunk_published(&self.sync, &self.links, n, k, || &self.caller);
    }

    /// `Engine::wait_until`, without the stall watchdog and the spinning: a helping caller
    /// runs ready nodes while it waits (`Engine::help`); it parks when there are none.
    fn wait_until(&self, code: u64, mut done: impl FnMut() -> bool) {
        loop {
            if done() {
                return;
            }
            if let Some(n) = self.helps.then(|| self.ready.pop(&[])).flatten() {
                self.run(n);
                continue;
            }
            if self.wakeup.park_unless(code, &mut done, loom::thread::park) {
                return;
            }
        }
    }

    /// `Engine::submit` of chunk `k`.
    fn submit(&self, k: u64) {
        let slot = (k % 2) as usize;
        self.wait_until(WAIT_SOURCE, || {
            self.sync[0].readers_left[slot].load(Ordering::Acquire) == 0
        });
        // SAFETY (checked by loom): the source's slot has no reader left.
        self.slots[0][slot].with_mut(|v| unsafe { *v = k + 1 });
        let mut queued = 0;
        release(&self.sync, &self.links, 0, k, |x| {
            queued += usize::from(self.offer(x));
        });
        self.wake(queued);
    }

    /// `Engine::collect` of chunk `k`: checks every node's output.
    fn collect(&self, k: u64) {
        self.wait_until(WAIT_CHUNK + k, || {
            self.sync
                .iter()
                .all(|s| s.produced.load(Ordering::Acquire) > k)
        });
        let slot = (k % 2) as usize;
        let mut queued = 0;
        for n in 1..self.sync.len() {
            // SAFETY (checked by loom): the caller's reader token pins the slot.
            let got = self.slots[n][slot].with(|v| unsafe { *v });
            assert_eq!(got, self.expected(n, k), "node {n}, chunk {k}");
            consumed(&self.sync, n, k, |x| {
                queued += usize::from(self.offer(x));
            });
        }
        self.wake(queued);
    }

    /// `Engine::quiesce` once every chunk is collected.
    fn quiesce(&self) {
        self.wait_until(WAIT_IDLE, || {
            self.ready.is_empty() && self.sync.iter().all(|s| !s.claimed.load(Ordering::Acquire))
        });
    }
}

fn check(parents: &'static [&'static [usize]], helps: bool) {
    let mut builder = loom::model::Builder::new();
    // One preemption besides the switches at parks and joins: ~10 s; two take over ten
    // minutes with three threads.
    builder.preemption_bound = Some(1);
    builder.check(move || {
        let m = Arc::new(Model::new(parents, helps));
        let handles: Vec<_> = (0..WORKERS)
            .map(|id| {
                let m = Arc::clone(&m);
                loom::thread::spawn(move || m.worker_loop(id))
            })
            .collect();
        let threads: Box<[Thread]> = handles.iter().map(|h| h.thread().clone()).collect();
        assert!(m.workers.set(threads).is_ok());
        // As the manager does: at most two chunks in flight.
        for k in 0..CHUNKS {
            if k >= 2 {
                m.collect(k - 2);
            }
            m.submit(k);
        }
        for k in CHUNKS.saturating_sub(2)..CHUNKS {
            m.collect(k);
        }
        m.quiesce();
        for (n, s) in m.sync.iter().enumerate() {
            assert_eq!(s.produced.load(Ordering::Acquire), CHUNKS, "node {n}");
        }
        // `Engine::drop`.
        m.shutdown.store(true, Ordering::SeqCst);
        for w in m.workers.get().expect("set above").iter() {
            w.unpark();
        }
        for h in handles {
            h.join().expect("worker");
        }
    });
}

/// source → {a, b}: releasing the source queues two nodes, so a worker wakes the other.
#[test]
fn source_with_two_children() {
    check(&[&[], &[0], &[0]], true);
}

/// The same with a caller that only waits (as it does once parked): the workers alone
/// must hand the nodes to each other (without the caller's help, a worker that misses
/// the other's wake-up leaves it parked for ever).
#[test]
fn source_with_two_children_caller_only_waits() {
    check(&[&[], &[0], &[0]], false);
}
