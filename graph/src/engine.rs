//! The concurrent executor: `threads` computing threads, the caller and a fixed pool of
//! `threads − 1` workers, run the graph's nodes through the token protocol of
//! [`crate::protocol`] (Ready → Process → Wait → Release), with vertical concurrency (a
//! parent computes chunk k+1 while its children read chunk k) and horizontal concurrency
//! (siblings run at once). Each worker takes first the nodes whose home it is (see
//! [`crate::placement`]), so that a chain of nodes stays in one core's cache.
//!
//! The calling thread also plays two roles of its own: it is the source (it publishes
//! each input chunk into node 0) and the sink (it copies the other nodes' outputs of a
//! chunk that it reads into blocks of its own, then returns its reader tokens; a whole
//! signal's joined outputs the nodes keep themselves, see [`Engine::lend_kept`]). While
//! it waits for a chunk or a free input slot it runs ready nodes like a worker, so that
//! `threads` threads share `threads` cores without a third thread to wake per chunk.
//! Workers never lock, allocate (beyond what a processor's first chunks of a new size
//! need, and a kept whole output growing past the length it was sized for) or free: the
//! node table is built and dropped by the caller, and swapped only while the pool is idle.

mod layout;

use std::cell::UnsafeCell;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::AtomicUsize;
use std::sync::Arc;
use std::thread::{self, JoinHandle, Thread};
use std::time::{Duration, Instant};

use afe_core::denormals::FlushDenormals;
use afe_core::framing::FrameBuffer;
use afe_core::{Block, Error, Processor, Result};

use crate::compile::{compile, Compiled, NodeShape};
use crate::graph::{Graph, OutputRef, MAX_INPUTS};
use crate::placement;
use crate::protocol::{consumed, is_ready, next_chunk, release, Links, NodeSync};
use crate::sync::{AtomicBool, AtomicU64, Ordering};
use crate::trace::{TraceEvent, Tracer};
use crate::wakeup::{ReadySet, Wakeup, WAIT_CHUNK, WAIT_IDLE, WAIT_SOURCE};
use layout::{mark_readers, node_runtimes, part_runtimes, split_nodes};

/// How long an idle worker (or the waiting caller, itself a computing thread) spins before
/// parking: long enough to bridge the gaps between the nodes of a chunk without a futex
/// round trip.
const SPIN: Duration = Duration::from_micros(50);
/// Safety net for a missed unpark: parked threads re-check this often.
const PARK_TIMEOUT: Duration = Duration::from_millis(2);

/// Largest pool: one bit per worker in the idle mask.
pub const MAX_THREADS: usize = 64;

thread_local! {
    static IS_WORKER: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// True on the scheduler's worker threads (used by allocation-counting tests).
pub fn is_worker_thread() -> bool {
    IS_WORKER.with(std::cell::Cell::get)
}

/// One short spin of an idle computing thread, idle since `idle_since` (set now if
/// unset); false, without spinning, once it has been idle for [`SPIN`] and should park.
fn spin_idle(idle_since: &mut Option<Instant>) -> bool {
    if idle_since.get_or_insert_with(Instant::now).elapsed() >= SPIN {
        return false;
    }
    for _ in 0..64 {
        std::hint::spin_loop();
    }
    true
}

/// One node as the pool sees it.
struct NodeRt {
    label: String,
    /// `None` for the source (node 0).
    processor: UnsafeCell<Option<Box<dyn Processor>>>,
    /// Output blocks of chunk `k` live in `slots[k % 2]`.
    slots: [UnsafeCell<Vec<Block>>; 2],
    inputs: Box<[OutputRef]>,
    /// The feedback output this node takes from the previous chunk (see
    /// [`crate::protocol`]).
    feedback: Option<OutputRef>,
    /// Where the node's processor is split: the table entries of its parts (after the
    /// graph's nodes), whose outputs it joins (see [`afe_core::ChannelSplit`]).
    parts: Box<[usize]>,
    /// Whether the node takes each chunk with [`afe_core::WholeSignal::absorb`] (a whole signal's
    /// node that finishes once at its end) rather than processing it.
    absorbs: bool,
    /// Per output: a whole signal's buffer that the node appends each chunk's output to
    /// itself, right after computing it (see [`Engine::lend_kept`]).
    kept: UnsafeCell<Vec<Option<Block>>>,
    /// Whether it keeps its outputs by writing them straight into their buffers, with no
    /// copy: set by [`Engine::lend_kept`] where no processor in the pool reads them.
    kept_in_place: bool,
    /// Whether a processor in the pool reads its outputs (a child with a processor, or a
    /// feedback target).
    read: bool,
    /// Frames of each kept output in chunk `k`, in `kept_frames[k % 2]` (read by the
    /// caller as its slot).
    kept_frames: [UnsafeCell<Vec<usize>>; 2],
    claimed_at_ns: AtomicU64,
    /// Whether a child that reads its outputs has its home on another thread: the node
    /// then claims its output's cache lines before writing them (see [`claim_lines`]).
    claims: bool,
}

impl NodeRt {
    /// An entry running `processor` on `inputs`, its two slots given (see `slots`): not
    /// split, no feedback, nothing kept, read by no one until the table says so.
    fn new(
        label: String,
        processor: Option<Box<dyn Processor>>,
        slots: [Vec<Block>; 2],
        inputs: &[OutputRef],
    ) -> NodeRt {
        let [now, last] = slots;
        NodeRt {
            label,
            processor: UnsafeCell::new(processor),
            slots: [UnsafeCell::new(now), UnsafeCell::new(last)],
            inputs: inputs.into(),
            feedback: None,
            parts: Box::new([]),
            absorbs: false,
            kept: UnsafeCell::new(Vec::new()),
            kept_in_place: false,
            read: false,
            kept_frames: Default::default(),
            claimed_at_ns: AtomicU64::new(0),
            claims: false,
        }
    }
}

/// Most parts a heavy node is split into (its join reads them beside its inputs).
const MAX_PARTS: usize = 4;

/// The compiled graph: synchronisation state, links, processors and slots.
struct Table {
    sync: Vec<NodeSync>,
    links: Vec<Links>,
    rt: Vec<NodeRt>,
    ready: ReadySet,
    /// Per worker, the entries it takes first (see [`crate::placement`]).
    homes: Vec<Box<[u64]>>,
}

impl Table {
    /// A ready node for computing thread `id`: one whose home it is first, else any.
    fn take(&self, id: usize) -> Option<usize> {
        self.ready.pop(self.homes.get(id).map_or(&[], |m| m))
    }
}

struct Shared {
    table: UnsafeCell<Table>,
    /// Set by the caller while it swaps the table; workers stay out.
    swapping: AtomicBool,
    /// Workers currently using the table.
    active: AtomicUsize,
    /// What the parked caller and the parked workers wait for.
    wakeup: Wakeup,
    shutdown: AtomicBool,
    poisoned: AtomicBool,
    workers: std::sync::OnceLock<Box<[Thread]>>,
    caller: UnsafeCell<Thread>,
    epoch: Instant,
    tracer: Tracer,
}

// SAFETY: the `UnsafeCell`s are accessed under the token protocol: a node's processor
// and its slot `k % 2` only by the holder of its claim while `readers_left[k % 2] == 0`;
// a published slot only by its readers while their consumed-token is pending; the table
// and the caller handle only by the caller while `swapping` is set and `active == 0`.
#[allow(unsafe_code)]
unsafe impl Sync for Shared {}

impl Shared {
    fn now_ns(&self) -> u64 {
        self.epoch.elapsed().as_nanos() as u64
    }

    fn caller(&self) -> &Thread {
        // SAFETY: replaced only while no worker is active (see `Engine::adopt_caller`).
        #[allow(unsafe_code)]
        unsafe {
            &*self.caller.get()
        }
    }

    /// Offers node `n` to the scheduler (see [`Wakeup::offer`]). Returns whether it was
    /// queued.
    fn offer(&self, table: &Table, n: usize) -> bool {
        self.wakeup.offer(
            &table.sync,
            &table.links,
            &table.ready,
            n,
            || self.caller(),
            || {
                table.rt[n]
                    .claimed_at_ns
                    .store(self.now_ns(), Ordering::Relaxed);
            },
        )
    }

    /// Unparks the caller if it waits for `what`.
    fn wake_caller_if(&self, what: u64) {
        self.wakeup.wake_caller_if(what, || self.caller());
    }

    /// Wakes up to `count` parked workers.
    fn wake(&self, count: usize) {
        if let Some(workers) = self.workers.get() {
            self.wakeup.wake(count, workers);
        }
    }

    fn worker_loop(&self, id: usize) {
        IS_WORKER.with(|w| w.set(true));
        // for the thread's life, so that `run`'s own guard only reads the setting
        let _flush = FlushDenormals::enable();
        while !self.shutdown.load(Ordering::Acquire) {
            self.active.fetch_add(1, Ordering::SeqCst);
            if self.swapping.load(Ordering::SeqCst) {
                self.active.fetch_sub(1, Ordering::SeqCst);
                thread::park_timeout(PARK_TIMEOUT);
                continue;
            }
            // SAFETY: `active > 0` and `swapping` unset: the caller does not touch the table.
            #[allow(unsafe_code)]
            let table = unsafe { &*self.table.get() };
            let mut idle_since: Option<Instant> = None;
            loop {
                if let Some(n) = table.take(id) {
                    self.run(table, n, id);
                    idle_since = None;
                } else if !spin_idle(&mut idle_since) {
                    break;
                }
            }
            let nothing = self.wakeup.going_idle(id, &table.ready);
            self.active.fetch_sub(1, Ordering::SeqCst);
            if nothing {
                self.wake_caller_if(WAIT_IDLE);
            }
            if nothing && !self.shutdown.load(Ordering::Acquire) {
                thread::park_timeout(PARK_TIMEOUT);
            }
            self.wakeup.awake(id);
        }
    }

    /// Process and Release of one claimed node.
    fn run(&self, table: &Table, n: usize, worker: usize) {
        let _flush = FlushDenormals::enable();
        let k = next_chunk(&table.sync, n);
        let slot = (k % 2) as usize;
        let rt = &table.rt[n];
        let ready = rt.claimed_at_ns.load(Ordering::Relaxed);
        let start = self.now_ns();
        // SAFETY: we hold the claim of `n`, so its processor and its slot `k % 2` (free:
        // READY checked `readers_left == 0`) are ours alone; every parent (the parts of a
        // split node among them) has published chunk `k` into its slot `k % 2`, and a
        // feedback source its chunk `k − 1` into its slot `(k + 1) % 2`, each untouched
        // until we return our consumed-token in `release` below.
        #[allow(unsafe_code)]
        let ok = unsafe {
            let feedback = rt
                .feedback
                .map(|f| &(&*table.rt[f.node].slots[1 - slot].get())[f.output]);
            let first = rt.inputs[0];
            let first_block = &(&*table.rt[first.node].slots[slot].get())[first.output];
            let mut inputs: [&Block; MAX_INPUTS] = [first_block; MAX_INPUTS];
            for (dst, p) in inputs.iter_mut().zip(rt.inputs.iter()).skip(1) {
                *dst = &(&*table.rt[p.node].slots[slot].get())[p.output];
            }
            let outputs = &mut *rt.slots[slot].get();
            let processor = &mut *rt.processor.get();
            let mut parts: [&[Block]; MAX_PARTS] = [&[]; MAX_PARTS];
            for (dst, &p) in parts.iter_mut().zip(rt.parts.iter()) {
                *dst = &*table.rt[p].slots[slot].get();
            }
            let kept = &mut *rt.kept.get();
            let kept_frames = &mut *rt.kept_frames[slot].get();
            if rt.kept_in_place {
                // the kept buffer stands in for the slot, showing only what is new (and
                // goes back below even if the processor panics)
                for (out, acc) in outputs.iter_mut().zip(kept.iter_mut()) {
                    if let Some(acc) = acc {
                        std::mem::swap(out, acc);
                        out.seal();
                    }
                }
            }
            let ok = catch_unwind(AssertUnwindSafe(|| {
                if rt.claims {
                    claim_lines(outputs);
                }
                if let Some(p) = processor.as_mut() {
                    if let (Some(f), Some(to)) = (feedback.filter(|f| !f.is_empty()), p.feedback())
                    {
                        to.receive_feedback(f);
                    }
                    let inputs = &inputs[..rt.inputs.len()];
                    match rt.parts.len() {
                        _ if rt.absorbs => {
                            if let Some(whole) = p.whole_signal() {
                                whole.absorb(inputs);
                            }
                        }
                        0 => p.process(inputs, outputs),
                        n => {
                            if let Some(split) = p.channel_split() {
                                split.join(inputs, &parts[..n], outputs);
                            }
                        }
                    }
                }
            }))
            .is_ok();
            let outs = outputs.iter_mut().zip(kept.iter_mut());
            for ((out, acc), frames) in outs.zip(kept_frames.iter_mut()) {
                if let Some(acc) = acc {
                    *frames = out.frames();
                    if rt.kept_in_place {
                        std::mem::swap(out, acc);
                    } else if ok {
                        acc.extend_from(out);
                    }
                }
            }
            ok
        };
        if !ok {
            self.poisoned.store(true, Ordering::SeqCst);
            self.caller().unpark();
            return;
        }
        let end = self.now_ns();
        let mut queued = 0;
        release(&table.sync, &table.links, n, k, |x| {
            queued += usize::from(self.offer(table, x));
        });
        // This worker takes one of the newly ready nodes itself; wake others for the rest.
        self.wake(queued.saturating_sub(1));
        self.wakeup
            .chunk_published(&table.sync, &table.links, n, k, || self.caller());
        self.tracer.record(
            worker,
            TraceEvent {
                node: n as u32,
                chunk: k,
                ready_ns: ready,
                start_ns: start,
                end_ns: end,
                released_ns: self.now_ns(),
            },
        );
    }
}

/// Writes a zero into each cache line of the outputs' previous content (chunk k − 2, read
/// by every reader already), which the node then replaces. Readers on another core hold
/// copies of those lines, and a node whose stores depend on each other (a recursive
/// filter) would wait for the ownership of each line in turn: these independent stores
/// take them all at once (on an AVX2 host, the hair cell's low-pass ran 4x slower without).
fn claim_lines(outputs: &mut [Block]) {
    for block in outputs {
        for x in block.as_mut_slice().iter_mut().step_by(8) {
            *x = 0.0;
        }
    }
}

/// The worker pool and the graph it runs.
pub struct Engine {
    shared: Arc<Shared>,
    handles: Vec<JoinHandle<()>>,
    /// Chunks published into the source.
    submitted: u64,
    /// Chunks collected by the caller.
    collected: u64,
    /// The caller's copy of the last collected chunk's outputs that it reads (`copied`).
    views: Vec<Vec<Block>>,
    /// Per node and output: whether [`Engine::collect`] copies it (all by default).
    copied: Vec<Vec<bool>>,
    /// Per node and output: whether the node appends it to a buffer of its own (see
    /// [`Engine::lend_kept`]), so that [`Engine::collect`] does not copy it.
    kept: Vec<Vec<bool>>,
    /// Frames of every output in the last collected chunk, copied or not.
    frames: Vec<Vec<usize>>,
    stall_timeout: Duration,
}

impl std::fmt::Debug for Engine {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Engine")
            .field("threads", &self.threads())
            .field("submitted", &self.submitted)
            .field("collected", &self.collected)
            .finish()
    }
}

fn empty_table() -> Table {
    Table {
        sync: Vec::new(),
        links: Vec::new(),
        rt: Vec::new(),
        ready: ReadySet::new(0),
        homes: Vec::new(),
    }
}

impl Engine {
    /// Starts `threads − 1` workers, the caller being the last of `threads` (1..=64)
    /// computing threads, with an empty graph; `trace_capacity` events per computing
    /// thread are preallocated for tracing (0 = no tracing).
    pub fn new(threads: usize, trace_capacity: usize) -> Result<Self> {
        if !(1..=MAX_THREADS).contains(&threads) {
            return Err(Error::InvalidInput(format!(
                "{threads} worker threads: choose between 1 and {MAX_THREADS} (0 selects the sequential executor)"
            )));
        }
        let shared = Arc::new(Shared {
            table: UnsafeCell::new(empty_table()),
            swapping: AtomicBool::new(false),
            active: AtomicUsize::new(0),
            wakeup: Wakeup::new(),
            shutdown: AtomicBool::new(false),
            poisoned: AtomicBool::new(false),
            workers: std::sync::OnceLock::new(),
            caller: UnsafeCell::new(thread::current()),
            epoch: Instant::now(),
            tracer: Tracer::new(threads, trace_capacity),
        });
        let mut engine = Engine {
            shared,
            handles: Vec::with_capacity(threads),
            submitted: 0,
            collected: 0,
            views: Vec::new(),
            copied: Vec::new(),
            kept: Vec::new(),
            frames: Vec::new(),
            stall_timeout: Duration::from_secs(30),
        };
        for id in 0..threads - 1 {
            let s = Arc::clone(&engine.shared);
            // On failure `engine` is dropped, which stops and joins the workers started.
            let h = thread::Builder::new()
                .name(format!("afe-worker-{id}"))
                .spawn(move || s.worker_loop(id))
                .map_err(|e| Error::Scheduler(format!("cannot start a worker thread: {e}")))?;
            engine.handles.push(h);
        }
        let threads_list: Box<[Thread]> =
            engine.handles.iter().map(|h| h.thread().clone()).collect();
        let _ = engine.shared.workers.set(threads_list);
        Ok(engine)
    }

    /// Number of computing threads: the workers and the caller.
    pub fn threads(&self) -> usize {
        self.handles.len() + 1
    }

    /// Fails with a dump of every node's state instead of waiting longer than this.
    pub fn set_stall_timeout(&mut self, timeout: Duration) {
        self.stall_timeout = timeout;
    }

    fn table(&self) -> &Table {
        // SAFETY: the caller only reads the table's shared parts here; it is replaced only
        // through `&mut self` in `swap_table`.
        #[allow(unsafe_code)]
        unsafe {
            &*self.shared.table.get()
        }
    }

    /// Per output of node `n`: rows of room in its two pool slots and in the caller's
    /// copy (the pool quiescent). A test reads it to see that an output was not copied.
    #[cfg(test)]
    pub(crate) fn rooms(&self, n: usize) -> Vec<(usize, usize, usize)> {
        let rt = &self.table().rt[n];
        // SAFETY: the pool is quiescent: no worker holds a slot.
        #[allow(unsafe_code)]
        let (a, b) = unsafe { (&*rt.slots[0].get(), &*rt.slots[1].get()) };
        (a.iter().zip(b).zip(&self.views[n]))
            .map(|((a, b), v)| (a.room(), b.room(), v.room()))
            .collect()
    }

    /// Waits (parked) until `done` holds, failing on a poisoned pool or a stall. `code`
    /// tells the workers what the caller waits for, so that they wake it only then.
    fn wait_until(
        &self,
        what: &str,
        code: u64,
        mut done: impl FnMut(&Table) -> bool,
    ) -> Result<()> {
        let began = Instant::now();
        let mut idle_since: Option<Instant> = None;
        loop {
            if self.shared.poisoned.load(Ordering::SeqCst) {
                return Err(Error::WorkerPanicked);
            }
            if done(self.table()) {
                return Ok(());
            }
            if began.elapsed() > self.stall_timeout {
                return Err(Error::Stalled(format!(
                    "waited for {what} beyond the watchdog:\n{}",
                    self.dump()
                )));
            }
            if self.help() {
                idle_since = None;
                continue;
            }
            if spin_idle(&mut idle_since) {
                continue;
            }
            idle_since = None;
            if self.shared.wakeup.park_unless(
                code,
                || done(self.table()),
                || thread::park_timeout(PARK_TIMEOUT),
            ) {
                return Ok(());
            }
        }
    }

    /// Runs one ready node on the calling thread, the pool's last computing thread;
    /// returns whether there was one.
    fn help(&self) -> bool {
        let table = self.table();
        let me = self.handles.len();
        let Some(n) = table.take(me) else {
            return false;
        };
        let was_worker = IS_WORKER.with(|w| w.replace(true));
        self.shared.run(table, n, me);
        IS_WORKER.with(|w| w.set(was_worker));
        true
    }

    /// Every node's protocol state, for stall reports.
    pub fn dump(&self) -> String {
        let t = self.table();
        t.sync
            .iter()
            .zip(&t.rt)
            .enumerate()
            .map(|(i, (s, rt))| {
                format!(
                    "  node {i} {}: produced {} readers_left {:?} claimed {} ready {}",
                    rt.label,
                    s.produced.load(Ordering::SeqCst),
                    [
                        s.readers_left[0].load(Ordering::SeqCst),
                        s.readers_left[1].load(Ordering::SeqCst)
                    ],
                    s.claimed.load(Ordering::SeqCst),
                    is_ready(&t.sync, &t.links, i)
                )
            })
            .collect::<Vec<_>>()
            .join("\n")
    }

    /// Makes the current thread the one workers wake (the manager may move threads).
    /// Chunks in flight need not be collected: the swap waits only for the workers to
    /// step out of the table.
    fn adopt_caller(&mut self) -> Result<()> {
        if self.shared.caller().id() == thread::current().id() {
            return Ok(());
        }
        self.with_table_swapped(|shared| {
            // SAFETY: no worker is active (`with_table_swapped`).
            #[allow(unsafe_code)]
            unsafe {
                *shared.caller.get() = thread::current();
            }
        });
        Ok(())
    }

    /// Publishes the next input chunk (one slice per ear) into the source node, waiting
    /// while the source's previous use of that slot is still being read.
    ///
    /// At most two chunks may be in flight (each node double-buffers its output):
    /// collect the oldest before submitting a third.
    pub fn submit(&mut self, chunk: &[&[f64]]) -> Result<()> {
        if self.in_flight() >= 2 {
            return Err(Error::Scheduler(
                "two chunks are in flight already: collect one before submitting the next".into(),
            ));
        }
        self.adopt_caller()?;
        let k = self.submitted;
        let slot = (k % 2) as usize;
        self.wait_until("the input slot", WAIT_SOURCE, |t| {
            t.sync[0].readers_left[slot].load(Ordering::Acquire) == 0
        })?;
        let table = self.table();
        // SAFETY: the source's slot `k % 2` has no reader left, and only the caller
        // writes the source.
        #[allow(unsafe_code)]
        let outputs = unsafe { &mut *table.rt[0].slots[slot].get() };
        for (block, ear) in outputs.iter_mut().zip(chunk) {
            block.resize_to(ear.len()).copy_from_slice(ear);
        }
        let mut queued = 0;
        release(&table.sync, &table.links, 0, k, |x| {
            queued += usize::from(self.shared.offer(table, x));
        });
        self.shared.wake(queued);
        self.submitted += 1;
        Ok(())
    }

    /// Chunks submitted and not yet collected.
    pub fn in_flight(&self) -> u64 {
        self.submitted - self.collected
    }

    /// Moves the buffers that `whole` holds (per node and output) for the `nodes` marked
    /// into those nodes, which from the next chunk on append each chunk's output to them
    /// on the worker that computed it, while it is still in that core's cache and in
    /// parallel with the other nodes, instead of the caller copying it after
    /// [`Engine::collect`] (which no longer copies them for [`Engine::block`]). The pool
    /// must be quiescent; [`Engine::return_kept`] gives them back. The source (node 0),
    /// which the caller fills, keeps its buffers.
    pub(crate) fn lend_kept(&mut self, whole: &mut [Vec<Option<Block>>], nodes: &[bool]) {
        debug_assert_eq!(self.in_flight(), 0, "lending needs a quiescent pool");
        let lends = |n: usize| n > 0 && nodes.get(n).copied().unwrap_or(false);
        self.kept = (whole.iter().enumerate())
            .map(|(n, outputs)| outputs.iter().map(|o| lends(n) && o.is_some()).collect())
            .collect();
        self.with_table_swapped(|shared| {
            // SAFETY: no worker is active and the pool is quiescent.
            #[allow(unsafe_code)]
            let table = unsafe { &mut *shared.table.get() };
            for (n, (rt, outputs)) in table.rt.iter_mut().zip(whole).enumerate() {
                let kept = rt.kept.get_mut();
                kept.clear();
                if lends(n) {
                    kept.extend(outputs.iter_mut().map(Option::take));
                }
                rt.kept_in_place = lends(n) && !rt.read;
                for frames in &mut rt.kept_frames {
                    frames.get_mut().clear();
                    frames.get_mut().resize(kept.len(), 0);
                }
            }
        });
    }

    /// Finishes the chunks in flight ([`Engine::quiesce`]) and gives the buffers of
    /// [`Engine::lend_kept`] back to `whole`, holding every chunk's output collected
    /// since: after a processor's panic too, but not after a stall (a worker may never let
    /// go of the table). Collects copy every output again afterwards.
    pub(crate) fn return_kept(&mut self, whole: &mut [Vec<Option<Block>>]) -> Result<()> {
        let idle = self.quiesce();
        self.kept.clear();
        if matches!(idle, Err(Error::Stalled(_))) {
            return idle;
        }
        self.with_table_swapped(|shared| {
            // SAFETY: no worker is active and the pool is quiescent.
            #[allow(unsafe_code)]
            let table = unsafe { &mut *shared.table.get() };
            for (rt, outputs) in table.rt.iter_mut().zip(whole) {
                for (acc, kept) in outputs.iter_mut().zip(rt.kept.get_mut().drain(..)) {
                    if let Some(mut kept) = kept {
                        kept.unseal();
                        *acc = Some(kept);
                    }
                }
                rt.kept_in_place = false;
            }
        });
        idle
    }

    /// Waits for every node to finish the oldest uncollected chunk, copies the outputs it
    /// reads (readable through [`Engine::block`] until the next collect; not those the
    /// nodes keep, see [`Engine::lend_kept`]) and returns the caller's reader tokens at
    /// once, so that no node waits for the caller.
    pub fn collect(&mut self) -> Result<u64> {
        if self.collected == self.submitted {
            return Err(Error::Scheduler("no chunk in flight to collect".into()));
        }
        self.adopt_caller()?;
        let k = self.collected;
        self.wait_until("the outputs of a chunk", WAIT_CHUNK + k, |t| {
            t.sync
                .iter()
                .all(|s| s.produced.load(Ordering::Acquire) > k)
        })?;
        let slot = (k % 2) as usize;
        let shared = &*self.shared;
        // SAFETY: as in `Engine::table`; the views are a separate field.
        #[allow(unsafe_code)]
        let table = unsafe { &*shared.table.get() };
        let mut queued = 0;
        for (n, view) in self.views.iter_mut().enumerate().skip(1) {
            // SAFETY: node `n` published chunk `k` into slot `k % 2`, and the caller's
            // reader token keeps it there until `consumed` below.
            #[allow(unsafe_code)]
            let published = unsafe { &*table.rt[n].slots[slot].get() };
            let copied = self.copied.get(n).map_or(&[][..], Vec::as_slice);
            let kept = self.kept.get(n).map_or(&[][..], Vec::as_slice);
            // SAFETY: as for the slot: written with it, before it was published.
            #[allow(unsafe_code)]
            let kept_frames = unsafe { &*table.rt[n].kept_frames[slot].get() };
            let frames = &mut self.frames[n];
            for (o, (dst, src)) in view.iter_mut().zip(published).enumerate() {
                dst.clear();
                if kept.get(o).copied().unwrap_or(false) {
                    frames[o] = kept_frames.get(o).copied().unwrap_or(0);
                } else {
                    frames[o] = src.frames();
                    if copied.get(o).copied().unwrap_or(true) {
                        dst.extend_from(src);
                    }
                }
            }
            consumed(&table.sync, n, k, |x| {
                queued += usize::from(shared.offer(table, x));
            });
        }
        shared.wake(queued);
        self.collected += 1;
        Ok(k)
    }

    /// Output `r` of the last collected chunk; `None` for one not copied (see
    /// [`Engine::set_copied`]) or kept by its node (see [`Engine::lend_kept`]).
    pub fn block(&self, r: OutputRef) -> Option<&Block> {
        let flag = |m: &[Vec<bool>], default| {
            let v = m.get(r.node).and_then(|c| c.get(r.output));
            v.copied().unwrap_or(default)
        };
        (flag(&self.copied, true) && !flag(&self.kept, false))
            .then(|| &self.views[r.node][r.output])
    }

    /// Frames of output `r` in the last collected chunk (copied or not).
    pub fn frames(&self, r: OutputRef) -> usize {
        self.frames[r.node][r.output]
    }

    /// Which outputs [`Engine::collect`] copies for the caller, per node and output (an
    /// output not listed is copied): only those read, so that the caller's cost grows
    /// with what is asked for rather than with the graph. Takes effect at the next collect.
    pub fn set_copied(&mut self, copied: Vec<Vec<bool>>) {
        self.copied = copied;
    }

    /// Collects every chunk in flight, gives back the caller's tokens and waits until no
    /// node is claimed: the pool is idle and the table may be swapped.
    pub fn quiesce(&mut self) -> Result<()> {
        while self.in_flight() > 0 {
            self.collect()?;
        }
        let active = &self.shared.active;
        self.wait_until("the pool to go idle", WAIT_IDLE, |t| {
            t.ready.is_empty()
                && t.sync.iter().all(|s| !s.claimed.load(Ordering::Acquire))
                && active.load(Ordering::SeqCst) == 0
        })
    }

    fn with_table_swapped<R>(&mut self, f: impl FnOnce(&Shared) -> R) -> R {
        self.shared.swapping.store(true, Ordering::SeqCst);
        while self.shared.active.load(Ordering::SeqCst) != 0 {
            std::hint::spin_loop();
        }
        let r = f(&self.shared);
        self.shared.swapping.store(false, Ordering::SeqCst);
        r
    }

    /// Moves the processors of `graph` into a freshly compiled table (the pool must be
    /// quiescent: call [`Engine::quiesce`] first). Chunk counting restarts at 0.
    pub(crate) fn install(&mut self, graph: &mut Graph) {
        self.install_absorbing(graph, &[]);
    }

    /// As [`Engine::install`], the nodes marked in `absorbs` taking each chunk with
    /// [`afe_core::WholeSignal::absorb`] (a whole signal run in blocks; see [`Graph::run_whole`]).
    pub(crate) fn install_absorbing(&mut self, graph: &mut Graph, absorbs: &[bool]) {
        // a heavy node whose processor splits runs as parts, one per worker, appended
        // after the graph's nodes; the node joins them
        let split = split_nodes(graph, self.threads().min(MAX_PARTS));
        let shapes: Vec<NodeShape> = graph
            .nodes
            .iter()
            .enumerate()
            .map(|(i, node)| NodeShape {
                label: format!("{}#{}", node.name, node.instance),
                parents: node.parents.clone(),
                feedback_from: node.feedback_from,
                parts: split
                    .iter()
                    .find(|(s, _)| *s == i)
                    .map_or(0, |(_, p)| p.len()),
            })
            .collect();
        let Compiled {
            part_entries,
            links,
            home,
            labels,
        } = compile(&shapes, self.threads());
        let total = links.len();
        let mut rt = node_runtimes(graph, &part_entries, &labels, absorbs);
        for (i, parts) in split {
            rt.extend(part_runtimes(
                &graph.nodes[i],
                parts,
                &part_entries[i],
                &labels,
            ));
        }
        mark_readers(&mut rt, &links, &home);
        let sync: Vec<NodeSync> = (0..total).map(|_| NodeSync::new()).collect();
        for (s, l) in sync.iter().zip(&links) {
            s.readers_left[1].store(l.feedback_to.len() as u32, Ordering::Relaxed);
        }
        let table = Table {
            sync,
            links,
            rt,
            ready: ReadySet::new(total),
            homes: placement::masks(&home, self.threads()),
        };
        let old = self.with_table_swapped(|shared| {
            // SAFETY: no worker is active and the pool is quiescent.
            #[allow(unsafe_code)]
            unsafe {
                std::mem::replace(&mut *shared.table.get(), table)
            }
        });
        drop(old);
        self.views = graph
            .nodes
            .iter()
            .map(|n| n.outputs.iter().map(Block::empty_like).collect())
            .collect();
        self.frames = graph
            .nodes
            .iter()
            .map(|n| vec![0; n.outputs.len()])
            .collect();
        self.submitted = 0;
        self.collected = 0;
        self.kept.clear();
    }

    /// Gives the processors back to `graph` (the pool must be quiescent) and leaves an
    /// empty table.
    pub(crate) fn uninstall(&mut self, graph: &mut Graph) {
        // parts rejoin here, as the processors ran them
        let _flush = FlushDenormals::enable();
        self.kept.clear();
        let old = self.with_table_swapped(|shared| {
            // SAFETY: no worker is active and the pool is quiescent.
            #[allow(unsafe_code)]
            unsafe {
                std::mem::replace(&mut *shared.table.get(), empty_table())
            }
        });
        let sources: Vec<OutputRef> = graph.nodes.iter().filter_map(|n| n.feedback_from).collect();
        let mut rt = old.rt;
        let n = graph.nodes.len().min(rt.len());
        let mut parts: Vec<Option<Box<dyn Processor>>> =
            rt.drain(n..).map(|r| r.processor.into_inner()).collect();
        for (node, rt) in graph.nodes.iter_mut().zip(rt) {
            let mut processor = rt.processor.into_inner();
            let split = processor.as_mut().and_then(|p| p.channel_split());
            if let Some(split) = split.filter(|_| !rt.parts.is_empty()) {
                let mut mine: Vec<Box<dyn Processor>> = rt
                    .parts
                    .iter()
                    .filter_map(|&e| parts.get_mut(e - n)?.take())
                    .collect();
                let shares: Vec<&[FrameBuffer]> = mine
                    .iter_mut()
                    .filter_map(|p| p.channel_split().map(|s| s.part_frames()))
                    .collect();
                split.rejoin(&shares);
            }
            node.processor = processor;
        }
        // the feedback of the last collected chunk is still to be taken: keep it in the
        // graph, where the next table finds it (without a chunk since `install`, the
        // graph still holds what that table was built with)
        if self.collected > 0 {
            for f in sources {
                if let Some(view) = self.views.get(f.node).and_then(|v| v.get(f.output)) {
                    graph.nodes[f.node].outputs[f.output].clone_from(view);
                }
            }
        }
        self.views.clear();
        self.submitted = 0;
        self.collected = 0;
    }

    /// The node labels, the trace recorded so far and the number of events that did not
    /// fit (the pool should be quiescent).
    pub fn trace(&self) -> (Vec<String>, Vec<(usize, TraceEvent)>, u64) {
        let labels = self.table().rt.iter().map(|r| r.label.clone()).collect();
        (
            labels,
            self.shared.tracer.events(),
            self.shared.tracer.dropped(),
        )
    }
}

impl Drop for Engine {
    fn drop(&mut self) {
        let _ = self.quiesce();
        self.shared.shutdown.store(true, Ordering::SeqCst);
        if let Some(ws) = self.shared.workers.get() {
            for w in ws.iter() {
                w.unpark();
            }
        }
        for h in self.handles.drain(..) {
            let _ = h.join();
        }
    }
}
