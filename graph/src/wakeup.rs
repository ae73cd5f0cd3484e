//! The wake-up and parking path of the concurrent scheduler: the ready set the workers
//! take claimed nodes from, the word in which the parked caller says what it waits for,
//! and the idle mask through which parked workers are woken. `tests/loom_wakeup.rs`
//! includes this file, like `protocol.rs`, against loom's atomics and threads.
//!
//! Memory-ordering rules. Every wake-up is a store-buffering pattern: one side publishes
//! its own state, then reads the other's, with a SeqCst fence in between on *both* sides,
//! so that at least one of them sees the other: either the sleeper sees the work (and does
//! not park) or the waker sees the sleeper (and unparks it). An unpark that comes before
//! the park is not lost (the thread's park token). The pairs are:
//! - a worker going idle sets its idle bit, then checks the ready set; whoever queues a
//!   node pushes it, then reads the idle mask ([`Wakeup::going_idle`], [`Wakeup::wake`]);
//! - the caller stores what it waits for, then re-checks it; a worker makes it come
//!   true, then reads the wait word ([`Wakeup::park_unless`], [`Wakeup::wake_caller_if`]).
//!
//! The first waker takes the caller's wait (compare-exchange to [`NOT_WAITING`]), so the
//! caller is unparked once per wait, and only once the awaited condition holds: an unpark
//! costs the waker ~70 µs on the development machine.

use crate::protocol::{try_claim, Links, NodeSync};
use crate::sync::{fence, AtomicU64, Ordering, Thread};

/// The caller is not parked.
pub(crate) const NOT_WAITING: u64 = 0;
/// The caller waits for the source's next slot to be free.
pub(crate) const WAIT_SOURCE: u64 = 1;
/// The caller waits for the pool to go idle.
pub(crate) const WAIT_IDLE: u64 = u64::MAX;
/// The caller waits for chunk `c` to complete: `WAIT_CHUNK + c`.
pub(crate) const WAIT_CHUNK: u64 = 2;

/// Lock-free set of claimed nodes waiting for a worker: one bit per node.
pub(crate) struct ReadySet {
    words: Box<[AtomicU64]>,
}

impl ReadySet {
    /// Empty, with room for `nodes` nodes.
    pub(crate) fn new(nodes: usize) -> Self {
        ReadySet {
            words: (0..nodes.div_ceil(64)).map(|_| AtomicU64::new(0)).collect(),
        }
    }

    /// Queues node `n` (whose claim the caller holds).
    pub(crate) fn push(&self, n: usize) {
        self.words[n / 64].fetch_or(1 << (n % 64), Ordering::AcqRel);
    }

    /// Takes the deepest ready node among those marked in `home` (one bit per node, see
    /// [`crate::placement`]), else the deepest of all (children before parents drains the
    /// pipeline and frees slots first).
    pub(crate) fn pop(&self, home: &[u64]) -> Option<usize> {
        self.pop_masked(|w| home.get(w).copied().unwrap_or(0))
            .or_else(|| self.pop_masked(|_| u64::MAX))
    }

    /// Takes the highest ready node whose bit is set in `mask(word)`.
    fn pop_masked(&self, mask: impl Fn(usize) -> u64) -> Option<usize> {
        for (w, word) in self.words.iter().enumerate().rev() {
            let m = mask(w);
            let mut bits = word.load(Ordering::Acquire) & m;
            while bits != 0 {
                let b = 63 - bits.leading_zeros() as usize;
                let prev = word.fetch_and(!(1 << b), Ordering::AcqRel);
                if prev & (1 << b) != 0 {
                    return Some(w * 64 + b);
                }
                bits = prev & m & !(1 << b);
            }
        }
        None
    }

    /// No node is queued.
    pub(crate) fn is_empty(&self) -> bool {
        self.words.iter().all(|w| w.load(Ordering::Acquire) == 0)
    }
}

/// What the parked caller and the parked workers wait for.
#[derive(Debug)]
pub(crate) struct Wakeup {
    /// What the parked caller waits for: [`NOT_WAITING`], [`WAIT_SOURCE`], [`WAIT_IDLE`],
    /// or `WAIT_CHUNK + c` for chunk `c` to complete.
    wait: AtomicU64,
    /// One bit per worker that is idle (parked, or about to park).
    idle: AtomicU64,
}

impl Wakeup {
    /// Nobody waits.
    pub(crate) fn new() -> Self {
        Wakeup {
            wait: AtomicU64::new(NOT_WAITING),
            idle: AtomicU64::new(0),
        }
    }

    /// Offers node `n` to the scheduler: claims it if READY and queues it, calling
    /// `claimed` in between (the engine stamps the time for its trace). Returns whether it
    /// was queued. The source (node 0) is the caller's: offering it wakes the caller if it
    /// waits for the source's slot.
    pub(crate) fn offer<'c>(
        &self,
        sync: &[NodeSync],
        links: &[Links],
        ready: &ReadySet,
        n: usize,
        caller: impl FnOnce() -> &'c Thread,
        claimed: impl FnOnce(),
    ) -> bool {
        if n == 0 {
            self.wake_caller_if(WAIT_SOURCE, caller);
            return false;
        }
        if try_claim(sync, links, n) {
            claimed();
            ready.push(n);
            return true;
        }
        false
    }

    /// Unparks the caller if it waits for `what` (once: the first waker clears the wait).
    /// `caller` is called only then, when the caller is parked or about to park (the
    /// engine may replace the caller's handle at other times).
    pub(crate) fn wake_caller_if<'c>(&self, what: u64, caller: impl FnOnce() -> &'c Thread) {
        fence(Ordering::SeqCst);
        if self.wait.load(Ordering::SeqCst) == what
            && self
                .wait
                .compare_exchange(what, NOT_WAITING, Ordering::SeqCst, Ordering::SeqCst)
                .is_ok()
        {
            caller().unpark();
        }
    }

    /// After node `n` published chunk `k`: if `n` is a leaf, wakes the caller if it waits
    /// for a chunk that is now complete (the last node of a chunk to publish is always a
    /// leaf).
    pub(crate) fn chunk_published<'c>(
        &self,
        sync: &[NodeSync],
        links: &[Links],
        n: usize,
        k: u64,
        caller: impl FnOnce() -> &'c Thread,
    ) {
        if !links[n].children.is_empty() {
            return;
        }
        fence(Ordering::SeqCst);
        let w = self.wait.load(Ordering::SeqCst);
        if w == NOT_WAITING || w == WAIT_SOURCE || w == WAIT_IDLE || k < w - WAIT_CHUNK {
            return;
        }
        let c = w - WAIT_CHUNK;
        if sync.iter().all(|s| s.produced.load(Ordering::Acquire) > c) {
            self.wake_caller_if(w, caller);
        }
    }

    /// The caller's side: announces that it waits for `code`, re-checks `done` and parks
    /// with `park` unless `done` holds by then. Returns whether it held; after a park the
    /// caller must check again, as the unpark may be a stale one.
    pub(crate) fn park_unless(
        &self,
        code: u64,
        mut done: impl FnMut() -> bool,
        park: impl FnOnce(),
    ) -> bool {
        self.wait.store(code, Ordering::SeqCst);
        fence(Ordering::SeqCst);
        if done() {
            self.wait.store(NOT_WAITING, Ordering::SeqCst);
            return true;
        }
        park();
        self.wait.store(NOT_WAITING, Ordering::SeqCst);
        false
    }

    /// Unparks up to `count` idle workers of `workers` (after nodes were queued).
    pub(crate) fn wake(&self, mut count: usize, workers: &[Thread]) {
        fence(Ordering::SeqCst);
        let mut idle = self.idle.load(Ordering::Acquire);
        while count > 0 && idle != 0 {
            let w = idle.trailing_zeros() as usize;
            idle &= !(1 << w);
            workers[w].unpark();
            count -= 1;
        }
    }

    /// Worker `id` found the ready set empty: marks it idle and re-checks. Returns whether
    /// the ready set is still empty, so that the worker may park (until [`Wakeup::wake`]
    /// picks it); call [`Wakeup::awake`] after the park either way.
    pub(crate) fn going_idle(&self, id: usize, ready: &ReadySet) -> bool {
        self.idle.fetch_or(1 << id, Ordering::SeqCst);
        // The SeqCst RMW above is no fence for the load below (C++ memory model; loom
        // finds the lost wake-up without this fence).
        fence(Ordering::SeqCst);
        ready.is_empty()
    }

    /// Worker `id` is no longer idle.
    pub(crate) fn awake(&self, id: usize) {
        self.idle.fetch_and(!(1 << id), Ordering::SeqCst);
    }
}
