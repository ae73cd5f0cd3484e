//! The request manager: the public face of a processor graph. It places and edits
//! requests (resolved by [`crate::resolve`]) between chunks, and runs the graph chunk by
//! chunk on the sequential or the concurrent executor (spec 00-overview §3–§6).

use afe_core::{Block, CancelToken, Error, ParamMap, Result, SignalInfo};
use afe_processors::Registry;
use serde_json::Value;

use crate::block_input::BlockInput;
use crate::engine::Engine;
use crate::graph::{Channel, Graph, OutputRef};
use crate::resolve::chain_of;

mod chunks;
mod clocks;
mod editing;
mod signals;
mod whole_signal;

use clocks::FrameClock;
pub use signals::Signal;

/// Highest input sampling rate accepted, in Hz.
pub const MAX_FS: f64 = 1_000_000.0;

/// Handle of a placed request, returned by [`Manager::add_request`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct RequestHandle(usize);

impl RequestHandle {
    /// The handle's number (for bindings that pass handles as integers).
    pub fn index(self) -> usize {
        self.0
    }

    /// The handle numbered `index`; a manager rejects numbers it did not hand out.
    pub fn from_index(index: usize) -> Self {
        RequestHandle(index)
    }
}

struct Request {
    outputs: Vec<OutputRef>,
    params: ParamMap,
}

/// Resolves requests into a processor graph shared between them and runs it.
///
/// ```
/// use afe_graph::Manager;
/// let mut mgr = Manager::new(16000.0, 2)?;
/// let ild = mgr.add_request("ild", &Default::default())?;
/// let left = vec![0.1; 1600];
/// let right = vec![0.2; 1600];
/// mgr.process_signal(&[&left, &right])?;
/// let out = &mgr.request_signals(ild)?[0];
/// assert_eq!(out.key(), "ild_mono");
/// assert_eq!(out.new.frames(), 9); // 100 ms, 20-ms windows every 10 ms
/// # Ok::<(), afe_core::Error>(())
/// ```
pub struct Manager {
    fs: f64,
    ears: usize,
    graph: Graph,
    /// Placed requests by handle; `None` once removed.
    requests: Vec<Option<Request>>,
    /// The concurrent executor, or `None` for the sequential one.
    engine: Option<Engine>,
    /// Chunks processed by the sequential executor and not yet collected (0 or 1).
    pending: u64,
    /// Samples per ear submitted since construction or the last reset: error messages
    /// name a bad sample by its position in the stream.
    position: u64,
    /// Whole-signal outputs of the last [`Manager::process_signal`] run in blocks, per
    /// node and output (`None` where not kept): what the signals show while
    /// `whole_shown` (until the next chunk or edit). Kept allocated for the next call.
    whole: Vec<Vec<Option<Block>>>,
    whole_shown: bool,
    /// Whether `process_signal` keeps every intermediate signal, not only the requested.
    keep_all: bool,
    /// Samples per ear submitted since construction (never reset): the stream clock.
    stream_pos: u64,
    /// The stream clock at the last reset (or whole-signal run): where the processors'
    /// time, and the head pose's, starts.
    reset_pos: u64,
    /// Where each node's outputs stand in the stream, per node and output.
    clocks: Vec<Vec<FrameClock>>,
    /// The stop request its whole-signal calls watch.
    cancel: CancelToken,
    /// The requests it can place.
    registry: Registry,
}

/// Where a streamed whole-signal call hands each block of an output
/// ([`Manager::process_signal_streaming`]).
pub type BlockSink<'a> = dyn FnMut(OutputRef, &Block) + 'a;

/// Largest amplitude accepted (full scale is 1.0) of the input times the gain of its
/// pre-processing (level scaling, pre-emphasis, middle-ear filter): far above any real
/// recording (raw 32-bit PCM counts are 2.1e9), and low enough that every representation
/// stays finite, the spectral features of the square-law hair cell's ratemap (the 16th
/// power of the input) and the STFT, stored in single precision as the AFE stores it,
/// among them: at 1e18 the DRNL's spectral features were Inf, at 1e22 the gammatone's
/// kurtosis NaN.
pub const MAX_AMPLITUDE: f64 = 1e15;

/// Block length in samples in which a whole signal goes through a chunk-invariant graph:
/// bit-identical to one call, and the intermediate signals stay in cache.
pub const WHOLE_SIGNAL_BLOCK: usize = 1024;

/// Largest chunk (samples) [`Manager::prepare`] sizes buffers for: 10 s at 96 kHz.
pub const MAX_PREPARED_CHUNK: usize = 960_000;

/// Most silence [`Manager::prepare`] runs, in seconds of audio: far more than the first
/// frames of the default windows need (`amsFeatures`' 32 ms takes more than two 10-ms
/// chunks).
pub const PREPARE_SECONDS_MAX: f64 = 2.0;

/// Chunks longer than this (samples) go through a chunk-invariant graph in blocks of
/// [`WHOLE_SIGNAL_BLOCK`].
const LONG_CHUNK: usize = 4 * WHOLE_SIGNAL_BLOCK;

/// Default bound (MB) on the intermediate signals a whole-signal call may hold beyond the
/// requested outputs (e.g. the joined filterbank output under the Hilbert IHC); the
/// environment variable `AFE_WHOLE_SIGNAL_LIMIT_MB` replaces it.
pub const WHOLE_SIGNAL_LIMIT_MB: u64 = 2048;

impl std::fmt::Debug for Manager {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Manager")
            .field("fs", &self.fs)
            .field("ears", &self.ears)
            .field("nodes", &self.graph.nodes.len())
            .field("threads", &self.threads())
            .finish()
    }
}

impl Manager {
    /// A manager for input at `fs` Hz with `ears` channels (1 = mono, 2 = binaural).
    pub fn new(fs: f64, ears: usize) -> Result<Self> {
        if !(fs.is_finite() && fs > 0.0 && fs <= MAX_FS) {
            return Err(Error::InvalidSampleRate(fs));
        }
        if !(1..=2).contains(&ears) {
            return Err(Error::InvalidInput(format!(
                "{ears} input channels: expected 1 (mono) or 2 (left, right)"
            )));
        }
        Ok(Manager {
            fs,
            ears,
            graph: Graph::new(fs, ears),
            requests: Vec::new(),
            engine: None,
            pending: 0,
            position: 0,
            whole: Vec::new(),
            whole_shown: false,
            keep_all: false,
            stream_pos: 0,
            reset_pos: 0,
            clocks: Vec::new(),
            cancel: CancelToken::new(),
            registry: Registry::default(),
        })
    }

    /// The head's yaw over time as this manager's processors read it (the `tracking`
    /// request turns the localisation's head-relative azimuths into the world's by it):
    /// a shared feed, so a clone given to a motor controller's thread feeds it live.
    /// Times are s since the processors started: the stream's first sample, or the last
    /// reset (a whole-signal run starts at 0).
    pub fn head_pose(&self) -> &afe_core::HeadPose {
        &self.graph.context.head_pose
    }

    /// Reads the head's yaw from `pose`, a feed shared with whoever reports it, instead of
    /// its own; refused once a request is placed (its nodes read the feed they were built
    /// with).
    pub fn set_head_pose(&mut self, pose: afe_core::HeadPose) -> Result<()> {
        if self.requests.iter().any(Option::is_some) {
            return Err(Error::InvalidInput(
                "the head pose is set before the first request is placed".into(),
            ));
        }
        self.graph.context.head_pose = pose;
        Ok(())
    }

    /// Reports the head's yaw `yaw_deg` (deg, positive to the left) at `t_s` (s since the
    /// processors started, after the last point's time).
    pub fn set_head_yaw(&self, t_s: f64, yaw_deg: f64) -> Result<()> {
        self.head_pose().push(t_s, yaw_deg)
    }

    /// The requests this manager can place: the built-in ones unless
    /// [`Manager::set_registry`] gave others.
    pub fn registry(&self) -> &Registry {
        &self.registry
    }

    /// Places requests from `registry` from now on (e.g. the built-in ones and a
    /// processor of the program's own); refused once a request is placed.
    pub fn set_registry(&mut self, registry: Registry) -> Result<()> {
        if self.requests.iter().any(Option::is_some) {
            return Err(Error::InvalidInput(
                "the registry is set before the first request is placed".into(),
            ));
        }
        self.registry = registry;
        Ok(())
    }

    /// A manager that runs its graph on `threads` threads, the calling one and a pool of
    /// `threads − 1` workers (the concurrent scheduler); `threads = 0` selects the
    /// sequential executor. Outputs are the same, bit for bit, whatever the choice.
    pub fn with_threads(fs: f64, ears: usize, threads: usize) -> Result<Self> {
        Self::with_engine(fs, ears, threads, 0)
    }

    /// This manager's stop request: cancelling it (from any thread, through a clone)
    /// stops its whole-signal calls at their next block or node with
    /// [`Error::Interrupted`] until it is cleared. Other managers run on; a signal to the
    /// process ([`afe_core::interrupt::request`]) stops them all.
    pub fn cancel_token(&self) -> &CancelToken {
        &self.cancel
    }

    /// Watches `token` instead of its own stop request (one token for the managers of a
    /// batch).
    pub fn set_cancel_token(&mut self, token: CancelToken) {
        self.cancel = token;
    }

    /// As [`Manager::with_threads`], recording up to `trace_capacity` scheduler events per
    /// worker for [`Manager::trace`].
    pub fn with_engine(
        fs: f64,
        ears: usize,
        threads: usize,
        trace_capacity: usize,
    ) -> Result<Self> {
        let mut m = Self::new(fs, ears)?;
        if threads > 0 {
            let mut engine = Engine::new(threads, trace_capacity)?;
            engine.install(&mut m.graph);
            m.engine = Some(engine);
        }
        Ok(m)
    }

    /// With the concurrent scheduler: fail with a dump of every node's state, instead of
    /// waiting longer than `timeout` for a chunk (default 30 s).
    pub fn set_stall_timeout(&mut self, timeout: std::time::Duration) {
        if let Some(e) = self.engine.as_mut() {
            e.set_stall_timeout(timeout);
        }
    }

    /// The scheduler trace recorded so far, in the Chrome trace-event format (`None` for
    /// the sequential executor). Finishes the chunks in flight first.
    pub fn trace(&mut self) -> Result<Option<Value>> {
        let Some(e) = self.engine.as_mut() else {
            return Ok(None);
        };
        e.quiesce()?;
        let (labels, events, dropped) = e.trace();
        Ok(Some(crate::trace::chrome_trace(&labels, &events, dropped)))
    }

    /// Computing threads of the concurrent scheduler, the caller among them (0: sequential
    /// executor).
    pub fn threads(&self) -> usize {
        self.engine.as_ref().map_or(0, Engine::threads)
    }

    /// Whether output `r` is read after each chunk: requested, kept by
    /// [`Manager::set_keep_all`], or fed back (the executors pass it on between tables).
    fn is_read(&self, r: OutputRef) -> bool {
        (self.keep_all && r.node > 0)
            || self.graph.nodes[r.node].infos[r.output].feedback
            || self.is_requested(r)
    }

    /// Whether output `r` is an output of a placed request.
    fn is_requested(&self, r: OutputRef) -> bool {
        self.requests
            .iter()
            .flatten()
            .any(|q| q.outputs.contains(&r))
    }

    /// Bytes of `len` input samples' worth of the signal `info` describes.
    fn signal_bytes(&self, info: &SignalInfo, len: usize) -> f64 {
        len as f64 * info.fs_hz / self.fs * info.width() as f64 * 8.0
    }

    /// Tells the concurrent executor which outputs to copy after each chunk: those read.
    fn sync_copied(&mut self) {
        let mask = self
            .graph
            .nodes
            .iter()
            .enumerate()
            .map(|(node, n)| {
                (0..n.outputs.len())
                    .map(|output| self.is_read(OutputRef { node, output }))
                    .collect()
            })
            .collect();
        if let Some(e) = self.engine.as_mut() {
            e.set_copied(mask);
        }
    }

    /// Input sampling rate in Hz.
    pub fn fs(&self) -> f64 {
        self.fs
    }

    /// Number of input channels (1 or 2).
    pub fn ears(&self) -> usize {
        self.ears
    }

    /// Handles of the requests in place, in the order they were added.
    pub fn handles(&self) -> impl Iterator<Item = RequestHandle> + '_ {
        self.requests
            .iter()
            .enumerate()
            .filter(|(_, r)| r.is_some())
            .map(|(i, _)| RequestHandle(i))
    }

    /// Whether every processor gives the same output for any chunking (false with the
    /// Hilbert-based IHC methods or the AGC, whose output depends on chunk boundaries).
    pub fn is_chunk_invariant(&self) -> bool {
        self.graph.invariant_nodes().iter().all(|i| *i)
    }

    /// How a whole signal may be fed in chunks and still give one call's output (see
    /// [`Manager::process_signal`]): `Some(n)` when any chunking does once the first
    /// chunk holds at least `n` input samples or the whole signal (`n` = 0 for a
    /// chunk-invariant graph; with the AGC, its seeding time), `None` when some
    /// processor needs its whole input in one call.
    pub fn one_call_prefix(&self) -> Option<usize> {
        self.graph.one_call_prefix()
    }

    /// Number of processor instances in the graph (the input node excluded).
    pub fn processor_count(&self) -> usize {
        self.graph.nodes.len() - 1
    }

    /// The graph's work estimate in values per second of signal, checked against
    /// [`crate::work::work_limit`] when a request is placed (see [`crate::work`]).
    pub fn work_per_second(&self) -> f64 {
        self.graph.work_per_second()
    }

    /// Whether every intermediate signal is kept for [`Manager::signals`]`(true)` after
    /// each chunk and after [`Manager::process_signal`] (`true`), or only the requested
    /// ones (`false`, the default: less memory and time, and the concurrent executor
    /// copies only what is asked for).
    pub fn set_keep_all(&mut self, keep: bool) {
        self.keep_all = keep;
        self.sync_copied();
    }

    /// Returns every processor to its initial state (chunks in flight are finished and
    /// dropped first).
    pub fn reset(&mut self) -> Result<()> {
        self.edit(|m| {
            m.graph.reset();
            m.position = 0;
            m.reset_pos = m.stream_pos;
            for n in 0..m.clocks.len() {
                m.restart_clocks(n);
            }
            Ok(())
        })
    }
}

/// A parameter map of `pairs`, for the tests.
#[cfg(test)]
fn params(pairs: &[(&str, serde_json::Value)]) -> ParamMap {
    pairs
        .iter()
        .map(|(k, v)| (k.to_string(), v.clone()))
        .collect()
}

/// The output keys of request `h` of `m`.
#[cfg(test)]
fn output_keys(m: &Manager, h: RequestHandle) -> Vec<String> {
    let signals = m.request_signals(h).expect("a placed request");
    signals.iter().map(Signal::key).collect()
}
