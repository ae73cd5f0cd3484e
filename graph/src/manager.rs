//! The request manager: the public face of a processor graph. It places and edits
//! requests (resolved by [`crate::resolve`]) between chunks, and runs the graph chunk by
//! chunk on the sequential or the concurrent executor (spec 00-overview §3–§6).

use afe_core::{Block, CancelToken, Error, ParamMap, Result, SignalInfo};
use afe_processors::requests;
use serde_json::Value;

use crate::block_input::BlockInput;
use crate::engine::Engine;
use crate::graph::{Channel, Graph, OutputRef};
use crate::resolve::chain_of;

mod whole_signal;

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

/// One output signal of the graph, as seen after the last processed chunk.
#[derive(Debug, Clone, Copy)]
pub struct Signal<'a> {
    /// Index of the first new frame among all the frames this output has given (it
    /// keeps counting across `reset` and `modify_parameter`).
    pub first_frame: u64,
    /// Time of the first new frame in seconds from the start of the stream: an output
    /// whose framing (re)started at input sample `s` (when it was placed, reset or
    /// rebuilt by `modify_parameter`) has its frame `k` at `s / fs + k / fs_hz`, the
    /// AFE's time axis (first frame at the start).
    pub first_time_s: f64,
    /// Name of the signal: the request's, e.g. `ratemap`, or the output's own where a
    /// processor has several (`precedence_itd`, `precedence_ild`, `precedence_cc`).
    pub name: &'static str,
    /// 1-based instance among the signals of the same name (requests with different
    /// parameters make several instances).
    pub instance: usize,
    /// Ear of the signal.
    pub channel: Channel,
    /// Rate, channel centre frequencies and lags.
    pub info: &'a SignalInfo,
    /// The new values computed by the last `process_chunk` / `process_signal`,
    /// time-major (`[frame][channel]` or `[frame][channel][lag]`).
    pub new: &'a Block,
    /// Where the signal lives in the graph.
    pub source: OutputRef,
}

impl Signal<'_> {
    /// The output name used by the CLI and Python: `<name>_<channel>`, or
    /// `<name>_<k>_<channel>` for the k-th instance (k ≥ 2), as in the AFE oracle.
    pub fn key(&self) -> String {
        if self.instance > 1 {
            format!("{}_{}_{}", self.name, self.instance, self.channel.as_str())
        } else {
            format!("{}_{}", self.name, self.channel.as_str())
        }
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
    /// Where each node's outputs stand in the stream, per node and output.
    clocks: Vec<Vec<FrameClock>>,
    /// The stop request its whole-signal calls watch.
    cancel: CancelToken,
}

/// Where a streamed whole-signal call hands each block of an output
/// ([`Manager::process_signal_streaming`]).
pub type BlockSink<'a> = dyn FnMut(OutputRef, &Block) + 'a;

/// The frame count of one output, for the index and time of each chunk's first frame.
#[derive(Debug, Clone, Copy, Default)]
struct FrameClock {
    /// Input sample (stream clock) at which the output's framing (re)started.
    start: u64,
    /// Frames since then.
    since: u64,
    /// Frames given in all.
    given: u64,
    /// `since` and `given` before the last chunk: its first frame.
    first_since: u64,
    first_given: u64,
}

impl FrameClock {
    /// A clock (re)started at input sample `start`, after `given` frames in all.
    fn started_at(start: u64, given: u64) -> Self {
        FrameClock {
            start,
            given,
            first_given: given,
            ..FrameClock::default()
        }
    }

    fn advance(&mut self, frames: u64) {
        self.first_since = self.since;
        self.first_given = self.given;
        self.since += frames;
        self.given += frames;
    }
}

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

/// Checks that every parameter name is declared by some processor.
pub fn check_parameter_names(params: &ParamMap) -> Result<()> {
    let known: Vec<&str> = requests()
        .iter()
        .flat_map(|r| r.params.iter().map(|p| p.name))
        .collect();
    for name in params.keys() {
        if !known.contains(&name.as_str()) {
            return Err(Error::UnknownParameter {
                name: name.clone(),
                hint: afe_core::params::did_you_mean(name, known.iter().copied()),
            });
        }
    }
    Ok(())
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
            clocks: Vec::new(),
            cancel: CancelToken::new(),
        })
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

    /// Applies a change to the graph between chunks: the pool finishes what is in flight,
    /// hands the processors back, and gets the edited graph (unchanged nodes keep their
    /// state; everything is built and freed on this thread).
    fn edit<R>(&mut self, f: impl FnOnce(&mut Self) -> Result<R>) -> Result<R> {
        if let Some(e) = self.engine.as_mut() {
            e.quiesce()?;
            e.uninstall(&mut self.graph);
        }
        self.pending = 0;
        self.whole_shown = false;
        let r = f(self);
        if let Some(e) = self.engine.as_mut() {
            e.install(&mut self.graph);
        }
        self.sync_clocks();
        self.sync_copied();
        r
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

    /// Gives every output of the graph a frame clock: outputs new since the last edit
    /// start at the current input sample.
    fn sync_clocks(&mut self) {
        let now = self.stream_pos;
        self.clocks.resize_with(self.graph.nodes.len(), Vec::new);
        for (clocks, node) in self.clocks.iter_mut().zip(&self.graph.nodes) {
            clocks.resize(node.outputs.len(), FrameClock::started_at(now, 0));
        }
    }

    /// Restarts the framing of `node`'s outputs at the current input sample.
    fn restart_clocks(&mut self, node: usize) {
        let now = self.stream_pos;
        for c in self.clocks.get_mut(node).into_iter().flatten() {
            *c = FrameClock::started_at(now, c.given);
        }
    }

    /// Counts the frames of the chunk just collected (node 0, the input, is no signal).
    fn tick(&mut self) {
        for (n, clocks) in self.clocks.iter_mut().enumerate().skip(1) {
            for (o, c) in clocks.iter_mut().enumerate() {
                let r = OutputRef { node: n, output: o };
                let frames = match &self.engine {
                    Some(e) => e.frames(r),
                    None => self.graph.nodes[n].outputs[o].frames(),
                };
                c.advance(frames as u64);
            }
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

    /// Places request `name` (an AFE request name such as `ratemap`) with the AFE
    /// parameters `params` (absent names take their defaults). Processors whose whole
    /// chain has equal parameters are shared with earlier requests.
    ///
    /// ```
    /// use afe_graph::Manager;
    /// use serde_json::json;
    /// let mut mgr = Manager::new(44100.0, 2)?;
    /// let params = [("fb_nChannels".to_string(), json!(16))].into_iter().collect();
    /// mgr.add_request("ratemap", &params)?;
    /// mgr.add_request("ild", &params)?; // shares time, filterbank and IHC with ratemap
    /// assert_eq!(mgr.processor_count(), 1 + 2 + 2 + 2 + 1);
    /// assert!(mgr.add_request("ratemap", &[("rm_wSizeSecs".to_string(), json!(1))].into_iter().collect()).is_err());
    /// # Ok::<(), afe_core::Error>(())
    /// ```
    pub fn add_request(&mut self, name: &str, params: &ParamMap) -> Result<RequestHandle> {
        check_parameter_names(params)?;
        self.edit(|m| m.add_request_now(name, params))
            .map_err(|e| afe_core::params::unless_set(e, params))
    }

    fn add_request_now(&mut self, name: &str, params: &ParamMap) -> Result<RequestHandle> {
        let chain = chain_of(name)?;
        let rollback = self.graph.nodes.len();
        let placed = self
            .graph
            .resolve(self.ears, &chain, params, name)
            .and_then(|outputs| self.graph.check_work(name, params).map(|()| outputs));
        match placed {
            Ok(outputs) => {
                self.requests.push(Some(Request {
                    outputs,
                    params: params.clone(),
                }));
                Ok(RequestHandle(self.requests.len() - 1))
            }
            Err(e) => {
                self.graph.nodes.truncate(rollback);
                for node in &mut self.graph.nodes {
                    node.feedback_from = node.feedback_from.filter(|f| f.node < rollback);
                }
                Err(e)
            }
        }
    }

    /// The graph's work estimate in values per second of signal, checked against
    /// [`crate::work::work_limit`] when a request is placed (see [`crate::work`]).
    pub fn work_per_second(&self) -> f64 {
        self.graph.work_per_second()
    }

    /// Checks that an input of `channels` channels is one this manager was made for.
    pub fn check_channels(&self, channels: usize) -> Result<()> {
        if channels == self.ears {
            return Ok(());
        }
        Err(Error::InvalidInput(format!(
            "got {channels} channel(s), but this manager was made for {} ({})",
            self.ears,
            if self.ears == 2 {
                "left, right"
            } else {
                "mono"
            }
        )))
    }

    fn check_chunk(&self, chunk: &[&[f64]]) -> Result<()> {
        self.check_channels(chunk.len())?;
        if chunk.iter().any(|c| c.len() != chunk[0].len()) {
            return Err(Error::InvalidInput(format!(
                "left and right have different lengths ({} and {} samples)",
                chunk[0].len(),
                chunk[chunk.len() - 1].len()
            )));
        }
        let names = ["left", "right"];
        let (node, gain) = self.graph.largest_input_gain();
        let limit = MAX_AMPLITUDE / gain;
        for (e, ear) in chunk.iter().enumerate() {
            if let Some(i) = ear.iter().position(|v| v.is_nan() || v.abs() > limit) {
                let which = if self.ears == 2 { names[e] } else { "mono" };
                let at = self.position + i as u64;
                return Err(Error::InvalidInput(if ear[i].is_finite() && gain > 1.0 {
                    format!(
                        "sample {at} of the {which} channel is {:e}: '{node}' raises it by up \
                         to {gain:e} (its level scaling, pre-emphasis and middle-ear filter), \
                         beyond ±{MAX_AMPLITUDE:e}, where the processing overflows: scale the \
                         input down (full scale is 1.0) or lower that gain (pp_refSPLdB)",
                        ear[i]
                    )
                } else if ear[i].is_finite() {
                    format!(
                        "sample {at} of the {which} channel is {:e}: beyond ±{MAX_AMPLITUDE:e} \
                         the processing overflows (full scale is 1.0: scale the input)",
                        ear[i]
                    )
                } else {
                    format!(
                        "sample {at} of the {which} channel is {} (the input must be finite)",
                        ear[i]
                    )
                }));
            }
        }
        Ok(())
    }

    /// Processes the next chunk of a stream (one slice per ear, equal lengths), carrying
    /// every processor's state over from the previous chunk. The new output of every
    /// signal is then available through [`Manager::signals`].
    ///
    /// ```
    /// use afe_graph::Manager;
    /// let mut mgr = Manager::new(16000.0, 1)?;
    /// let h = mgr.add_request("ratemap", &Default::default())?;
    /// let x = vec![0.1; 1600];
    /// let mut frames = 0;
    /// for chunk in x.chunks(160) {
    ///     // 10-ms chunks; the 20-ms window needs two of them before the first frame
    ///     mgr.process_chunk(&[chunk])?;
    ///     frames += mgr.request_signals(h)?[0].new.frames();
    /// }
    /// assert_eq!(frames, 9);
    /// # Ok::<(), afe_core::Error>(())
    /// ```
    pub fn process_chunk(&mut self, chunk: &[&[f64]]) -> Result<()> {
        while self.in_flight() > 0 {
            self.collect_chunk()?;
        }
        let len = chunk.first().map_or(0, |c| c.len());
        if len > LONG_CHUNK && self.is_chunk_invariant() {
            return self.process_long_chunk(chunk);
        }
        self.submit_chunk(chunk)?;
        self.collect_chunk()
    }

    /// A long chunk through a chunk-invariant graph, in blocks (bit-identical), keeping
    /// only the outputs shown ([`Manager::set_keep_all`]): its intermediate signals are
    /// never held whole, so memory does not grow with the chunk's length.
    fn process_long_chunk(&mut self, chunk: &[&[f64]]) -> Result<()> {
        self.check_chunk(chunk)?;
        let before: Vec<Vec<(u64, u64)>> = self
            .clocks
            .iter()
            .map(|c| c.iter().map(|c| (c.since, c.given)).collect())
            .collect();
        let len = chunk[0].len();
        self.run_blocks(BlockInput::Signal(chunk, 0), len, 0, None)?;
        // the chunk's first frame is the first of its first block
        for (clocks, before) in self.clocks.iter_mut().zip(before) {
            for (c, (since, given)) in clocks.iter_mut().zip(before) {
                c.first_since = since;
                c.first_given = given;
            }
        }
        Ok(())
    }

    /// Sizes every output block and every processor's buffers for chunks of up to
    /// `max_chunk` samples before the first chunk, so that no chunk up to that size
    /// allocates on the audio path, the first ones included: silent chunks of that size
    /// run through the processors on this thread (at least two, then until every output
    /// has had frames twice, at most [`PREPARE_SECONDS_MAX`] of audio), which are then
    /// reset. Only before the first chunk (or after [`Manager::reset`]); a request added
    /// later is sized by its first chunks.
    pub fn prepare(&mut self, max_chunk: usize) -> Result<()> {
        if self.position != 0 {
            return Err(Error::InvalidInput(
                "prepare sizes the buffers before the stream starts: call it before the first chunk or after reset".into(),
            ));
        }
        if !(1..=MAX_PREPARED_CHUNK).contains(&max_chunk) {
            return Err(Error::InvalidInput(format!(
                "prepare({max_chunk}): give the largest chunk, 1 to {MAX_PREPARED_CHUNK} samples"
            )));
        }
        let silence = vec![0.0; max_chunk];
        // at least two chunks (the second also meets the rows the first one left for later
        // frames), and until every output has had frames twice: a window longer than two
        // chunks gives its first frame later
        let most = (PREPARE_SECONDS_MAX * self.fs) as usize / max_chunk + 2;
        self.edit(|m| {
            let chunk: Vec<&[f64]> = (0..m.ears).map(|_| silence.as_slice()).collect();
            let mut outputs_seen: Vec<Vec<u8>> = m
                .graph
                .nodes
                .iter()
                .map(|n| vec![0; n.outputs.len()])
                .collect();
            for k in 0..most {
                m.graph.load_input(&chunk);
                m.graph.run_sequential();
                for (seen, node) in outputs_seen.iter_mut().zip(&m.graph.nodes) {
                    for (s, block) in seen.iter_mut().zip(&node.outputs) {
                        *s = s.saturating_add(u8::from(!block.is_empty()));
                    }
                }
                if k >= 1 && outputs_seen.iter().flatten().all(|s| *s >= 2) {
                    break;
                }
            }
            m.graph.reset();
            Ok(())
        })
    }

    /// Starts processing the next chunk without waiting for it: with the concurrent
    /// scheduler, chunk k+1 enters the graph while chunk k is still in its deeper nodes.
    /// Collect each chunk's output, in order, with [`Manager::collect_chunk`]; keep at most
    /// [`Manager::pipeline_depth`] chunks in flight (submitting more is an error).
    ///
    /// ```
    /// use afe_graph::Manager;
    /// let mut mgr = Manager::with_threads(16000.0, 2, 2)?;
    /// mgr.add_request("ild", &Default::default())?;
    /// let (l, r) = (vec![0.1; 1600], vec![0.2; 1600]);
    /// let mut frames = 0;
    /// for (a, b) in l.chunks(160).zip(r.chunks(160)) {
    ///     mgr.submit_chunk(&[a, b])?;
    ///     if mgr.in_flight() == mgr.pipeline_depth() {
    ///         mgr.collect_chunk()?;
    ///         frames += mgr.signals(false)[0].new.frames();
    ///     }
    /// }
    /// while mgr.in_flight() > 0 {
    ///     mgr.collect_chunk()?;
    ///     frames += mgr.signals(false)[0].new.frames();
    /// }
    /// assert_eq!(frames, 9);
    /// # Ok::<(), afe_core::Error>(())
    /// ```
    pub fn submit_chunk(&mut self, chunk: &[&[f64]]) -> Result<()> {
        self.check_chunk(chunk)?;
        self.whole_shown = false;
        let len = chunk.first().map_or(0, |c| c.len() as u64);
        match self.engine.as_mut() {
            Some(e) => {
                e.submit(chunk)?;
                self.position += len;
                self.stream_pos += len;
                Ok(())
            }
            None => {
                if self.pending > 0 {
                    return Err(Error::InvalidInput(
                        "the sequential executor holds one chunk: collect it before submitting the next".into(),
                    ));
                }
                self.graph.load_input(chunk);
                self.graph.run_sequential();
                self.pending = 1;
                self.position += len;
                self.stream_pos += len;
                Ok(())
            }
        }
    }

    /// Waits for the oldest submitted chunk and makes its output the one
    /// [`Manager::signals`] shows.
    pub fn collect_chunk(&mut self) -> Result<()> {
        match self.engine.as_mut() {
            Some(e) => e.collect().map(|_| ())?,
            None if self.pending > 0 => self.pending = 0,
            None => return Err(Error::Scheduler("no chunk in flight to collect".into())),
        }
        self.tick();
        Ok(())
    }

    /// Chunks submitted and not yet collected.
    pub fn in_flight(&self) -> usize {
        match &self.engine {
            Some(e) => e.in_flight() as usize,
            None => self.pending as usize,
        }
    }

    /// How many chunks may usefully be in flight: 1 for the sequential executor, 2 for
    /// the concurrent one (each node double-buffers its output).
    pub fn pipeline_depth(&self) -> usize {
        if self.engine.is_some() {
            2
        } else {
            1
        }
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
            for n in 0..m.clocks.len() {
                m.restart_clocks(n);
            }
            Ok(())
        })
    }

    /// Removes a request. Its processors go when no other request uses them; the others
    /// keep their state.
    pub fn remove_request(&mut self, handle: RequestHandle) -> Result<()> {
        match self.requests.get(handle.0) {
            Some(Some(_)) => {}
            _ => return Err(Error::UnknownHandle(handle.0)),
        }
        self.edit(|m| {
            m.requests[handle.0] = None;
            m.prune();
            Ok(())
        })
    }

    /// Drops the nodes that no remaining request needs, renumbering the others.
    fn prune(&mut self) {
        let needed: Vec<OutputRef> = self
            .requests
            .iter()
            .flatten()
            .flat_map(|r| r.outputs.iter().copied())
            .collect();
        let new_index = self.graph.prune(needed.into_iter());
        let mut clocks = vec![Vec::new(); self.graph.nodes.len()];
        for (old, c) in std::mem::take(&mut self.clocks).into_iter().enumerate() {
            if let Some(slot) = new_index.get(old).and_then(|&i| clocks.get_mut(i)) {
                *slot = c;
            }
        }
        self.clocks = clocks;
        for r in self.requests.iter_mut().flatten() {
            for o in &mut r.outputs {
                o.node = new_index[o.node];
            }
        }
    }

    /// Changes parameter `name` of the processors of request `handle` that declare it,
    /// between chunks, with the AFE's semantics: those processors are rebuilt and reset,
    /// and so is everything computed from them (in every request sharing them). The
    /// parameters that fix the channel grid cannot be changed.
    pub fn modify_parameter(
        &mut self,
        handle: RequestHandle,
        name: &str,
        value: Value,
    ) -> Result<()> {
        let single: ParamMap = [(name.to_string(), value)].into_iter().collect();
        check_parameter_names(&single)?;
        if requests().iter().any(|r| r.fixed.contains(&name)) {
            return Err(Error::InvalidParameter {
                name: name.into(),
                value: single[name].to_string(),
                reason: "this parameter cannot be changed at run time (as in the AFE); place a new request instead".into(),
            });
        }
        let Some(Some(req)) = self.requests.get(handle.0) else {
            return Err(Error::UnknownHandle(handle.0));
        };
        let mut params = req.params.clone();
        params.extend(single);
        let chain = self.graph.ancestors(req.outputs.iter().copied());
        let used = chain.iter().any(|&i| {
            self.graph.nodes[i]
                .def
                .is_some_and(|d| d.params.iter().any(|p| p.name == name))
        });
        if !used {
            return Err(Error::InvalidParameter {
                name: name.into(),
                value: params[name].to_string(),
                reason: format!("no processor of request {} uses this parameter", handle.0),
            });
        }
        self.edit(|m| {
            for n in m.graph.modify(&chain, name, &params[name])? {
                m.restart_clocks(n);
            }
            if let Some(Some(req)) = m.requests.get_mut(handle.0) {
                req.params.insert(name.to_string(), params[name].clone());
            }
            Ok(())
        })
        .map_err(|e| afe_core::params::unless_set(e, &params))
    }

    /// The output signals of a request: one per ear for per-ear representations, one
    /// (`mono`) for binaural cues.
    ///
    /// ```
    /// use afe_graph::Manager;
    /// let mut mgr = Manager::new(16000.0, 2)?;
    /// let h = mgr.add_request("crosscorrelation", &Default::default())?;
    /// mgr.process_signal(&[&[0.1; 800], &[0.2; 800]])?;
    /// let cc = &mgr.request_signals(h)?[0];
    /// assert_eq!(cc.key(), "crosscorrelation_mono");
    /// assert_eq!(cc.info.lags_s.len(), 37); // ±ceil(1.1 ms · 16 kHz) lags
    /// assert_eq!(cc.info.cf_hz.len(), 31);
    /// assert_eq!(cc.new.width(), 31 * 37); // [frame][channel][lag]
    /// # Ok::<(), afe_core::Error>(())
    /// ```
    pub fn request_signals(&self, handle: RequestHandle) -> Result<Vec<Signal<'_>>> {
        let req = self
            .requests
            .get(handle.0)
            .and_then(Option::as_ref)
            .ok_or(Error::UnknownHandle(handle.0))?;
        Ok(req.outputs.iter().filter_map(|r| self.signal(*r)).collect())
    }

    /// Output `k` of request `handle`, as [`Manager::request_signals`] lists them, without
    /// allocating (for the audio path); `None` past the last one or for an unknown handle.
    pub fn request_signal(&self, handle: RequestHandle, k: usize) -> Option<Signal<'_>> {
        let req = self.requests.get(handle.0)?.as_ref()?;
        self.signal(*req.outputs.get(k)?)
    }

    /// The parameters every processor of request `handle`'s chain runs with, defaults
    /// included (the AFE's `getParameterSummary`): e.g. for `ild`, the `ild_*`, `ihc_*`,
    /// `fb_*` and `pp_*` values.
    ///
    /// ```
    /// use afe_graph::Manager;
    /// let mut mgr = Manager::new(16000.0, 2)?;
    /// let params = [("fb_nChannels".to_string(), serde_json::json!(8))].into_iter().collect();
    /// let h = mgr.add_request("ild", &params)?;
    /// let used = mgr.request_parameters(h)?;
    /// assert_eq!(used["fb_nChannels"], 8);
    /// assert_eq!(used["ild_wSizeSec"], 0.02);
    /// assert_eq!(used["ihc_method"], "dau");
    /// # Ok::<(), afe_core::Error>(())
    /// ```
    pub fn request_parameters(&self, handle: RequestHandle) -> Result<ParamMap> {
        let req = self
            .requests
            .get(handle.0)
            .and_then(Option::as_ref)
            .ok_or(Error::UnknownHandle(handle.0))?;
        let mut used = ParamMap::new();
        for (_, params) in self.chain_from(req.outputs.iter().map(|r| r.node)) {
            used.extend(params.iter().map(|(k, v)| (k.clone(), v.clone())));
        }
        Ok(used)
    }

    /// The processors signal `r` is computed through, itself first and then its
    /// ancestors nearest first: each one's request name and effective parameters.
    pub fn signal_chain(&self, r: OutputRef) -> Vec<(&'static str, &ParamMap)> {
        self.chain_from([r.node])
    }

    /// `start` and every node above them, breadth first, each once (the input node,
    /// which has no parameters, left out).
    fn chain_from(&self, start: impl IntoIterator<Item = usize>) -> Vec<(&'static str, &ParamMap)> {
        let mut todo: std::collections::VecDeque<usize> = start.into_iter().collect();
        let mut seen = std::collections::HashSet::new();
        let mut chain = Vec::new();
        while let Some(n) = todo.pop_front() {
            if n == 0 || !seen.insert(n) {
                continue;
            }
            let node = &self.graph.nodes[n];
            chain.push((node.name, &node.params));
            todo.extend(node.parents.iter().map(|p| p.node));
        }
        chain
    }

    /// Signals of the graph: the requested ones, or (`all`) every processor output,
    /// including intermediate ones (time, filterbank, innerhaircell, ...), which are
    /// there only with [`Manager::set_keep_all`] on.
    pub fn signals(&self, all: bool) -> Vec<Signal<'_>> {
        let mut refs: Vec<OutputRef> = if all {
            self.graph
                .nodes
                .iter()
                .enumerate()
                .skip(1)
                .flat_map(|(node, n)| {
                    n.infos
                        .iter()
                        .enumerate()
                        .filter(|(_, info)| !info.feedback)
                        .map(move |(output, _)| OutputRef { node, output })
                })
                .collect()
        } else {
            self.requests
                .iter()
                .flatten()
                .flat_map(|r| r.outputs.clone())
                .collect()
        };
        let mut seen = std::collections::HashSet::new();
        refs.retain(|r| seen.insert(*r));
        refs.into_iter().filter_map(|r| self.signal(r)).collect()
    }

    /// Output `r`'s signal; `None` for an intermediate one not kept (see
    /// [`Manager::set_keep_all`]).
    fn signal(&self, r: OutputRef) -> Option<Signal<'_>> {
        let node = &self.graph.nodes[r.node];
        let clock = self
            .clocks
            .get(r.node)
            .and_then(|c| c.get(r.output))
            .copied()
            .unwrap_or_default();
        let info = &node.infos[r.output];
        Some(Signal {
            first_frame: clock.first_given,
            first_time_s: clock.start as f64 / self.fs + clock.first_since as f64 / info.fs_hz,
            name: node.infos[r.output].name.unwrap_or(node.name),
            instance: node.instance,
            channel: node.channels[r.output],
            info: &node.infos[r.output],
            new: match (self.whole_shown, &self.engine) {
                (true, _) => self.whole[r.node][r.output].as_ref()?,
                (false, _) if !self.is_read(r) => return None,
                (false, Some(e)) => e.block(r)?,
                (false, None) => &node.outputs[r.output],
            },
            source: r,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    /// Chunks of 10 ms with a window change after 0.5 s and a reset after 1 s: the frame
    /// times stay monotonic, the index keeps counting, and each restart's first frame
    /// stands at the input sample where it restarted.
    #[test]
    fn frame_times_follow_the_input_across_edits_and_resets() {
        for threads in [0, 2] {
            let fs = 16000.0;
            let mut m = Manager::with_threads(fs, 2, threads).expect("manager");
            let h = m
                .add_request("ratemap", &params(&[("fb_nChannels", json!(4))]))
                .expect("ratemap");
            let x: Vec<f64> = (0..160).map(|t| (t as f64 * 0.3).sin() * 0.1).collect();
            let mut times: Vec<f64> = Vec::new();
            let mut index = 0;
            let mut restarted: Option<f64> = None;
            for k in 0..150 {
                if k == 50 {
                    m.modify_parameter(h, "rm_hSizeSec", json!(0.02))
                        .expect("modify");
                }
                if k == 100 {
                    m.reset().expect("reset");
                }
                m.submit_chunk(&[&x, &x]).expect("submit");
                m.collect_chunk().expect("collect");
                let s = &m.request_signals(h).expect("signals")[0];
                assert_eq!(s.first_frame, index, "threads {threads}, chunk {k}");
                if s.new.frames() == 0 {
                    continue;
                }
                index += s.new.frames() as u64;
                let hop = 1.0 / s.info.fs_hz;
                for f in 0..s.new.frames() {
                    times.push(s.first_time_s + f as f64 * hop);
                }
                if let Some(t) = restarted.take() {
                    // the first frame after a restart stands where the restart was
                    assert!(
                        (s.first_time_s - t).abs() < 1e-12,
                        "{} vs {t}",
                        s.first_time_s
                    );
                }
            }
            assert!(
                times.windows(2).all(|w| w[1] > w[0]),
                "threads {threads}: not monotonic"
            );
            assert_eq!(times[0], 0.0);
            // 10-ms hops before the change, 20-ms hops after it
            let hops = |t0: f64, t1: f64| -> Vec<f64> {
                times
                    .windows(2)
                    .filter(|w| w[0] >= t0 && w[1] < t1)
                    .map(|w| w[1] - w[0])
                    .collect()
            };
            assert!(hops(0.0, 0.5).iter().all(|h| (h - 0.01).abs() < 1e-12));
            assert!(hops(0.5, 1.0).iter().all(|h| (h - 0.02).abs() < 1e-12));
            assert!(hops(1.0, 1.5).iter().all(|h| (h - 0.02).abs() < 1e-12));
        }
    }

    fn params(pairs: &[(&str, serde_json::Value)]) -> ParamMap {
        pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.clone()))
            .collect()
    }

    /// A processor with several outputs names each (the AFE oracle's names).
    #[test]
    fn multi_output_processors_name_their_outputs() {
        let mut m = Manager::new(16000.0, 2).expect("manager");
        let h = m.add_request("precedence", &ParamMap::new()).expect("ok");
        let left = vec![0.1; 1600];
        m.process_signal(&[&left, &left]).expect("ok");
        let keys: Vec<String> = m
            .request_signals(h)
            .expect("ok")
            .iter()
            .map(Signal::key)
            .collect();
        assert_eq!(
            keys,
            [
                "precedence_itd_mono",
                "precedence_ild_mono",
                "precedence_cc_mono"
            ]
        );
    }

    #[test]
    fn requests_share_their_common_chain() {
        // input ─ time ─┬─ filterbank L ─ ihc L ─┬─ ratemap L
        //               └─ filterbank R ─ ihc R ─┼─ ratemap R
        //                                        ├─ ild
        //                                        └─ crosscorrelation ─┬─ itd
        //                                                             └─ ic
        let mut m = Manager::new(16000.0, 2).expect("valid");
        m.add_request("ratemap", &ParamMap::new()).expect("ok");
        assert_eq!(m.processor_count(), 1 + 2 + 2 + 2);
        m.add_request("ild", &ParamMap::new()).expect("ok");
        m.add_request("itd", &ParamMap::new()).expect("ok");
        m.add_request("ic", &ParamMap::new()).expect("ok");
        assert_eq!(m.processor_count(), 7 + 1 + 1 + 1 + 1);
        // differing only in ild_* keeps the filterbank shared
        m.add_request("ild", &params(&[("ild_wSizeSec", json!(0.04))]))
            .expect("ok");
        assert_eq!(m.processor_count(), 12);
        // a different filterbank duplicates everything above time
        let h = m
            .add_request("ratemap", &params(&[("fb_nChannels", json!(16))]))
            .expect("ok");
        assert_eq!(m.processor_count(), 12 + 6);
        let keys: Vec<String> = m
            .request_signals(h)
            .expect("ok")
            .iter()
            .map(Signal::key)
            .collect();
        assert_eq!(keys, vec!["ratemap_2_left", "ratemap_2_right"]);
    }

    #[test]
    fn a_manager_moves_between_threads_mid_stream_and_bounds_chunks_in_flight() {
        let mut m = Manager::with_threads(16000.0, 2, 2).expect("valid");
        m.set_stall_timeout(std::time::Duration::from_secs(10));
        let h = m.add_request("ild", &ParamMap::new()).expect("ok");
        let x = vec![0.1; 1600];
        m.submit_chunk(&[&x, &x]).expect("first");
        m.submit_chunk(&[&x, &x]).expect("second");
        let e = m.submit_chunk(&[&x, &x]).expect_err("a third in flight");
        assert!(e.to_string().contains("collect one"), "{e}");
        // another thread collects what this one submitted, then goes on streaming
        let m = std::thread::spawn(move || {
            m.collect_chunk().expect("collect on another thread");
            m.collect_chunk().expect("collect on another thread");
            m.process_chunk(&[&x, &x]).expect("stream on");
            m
        })
        .join()
        .expect("thread");
        assert_eq!(m.request_signals(h).expect("ild")[0].new.frames(), 10);
    }

    #[test]
    fn binaural_request_on_mono_input_is_rejected_and_leaves_nothing() {
        let mut m = Manager::new(16000.0, 1).expect("valid");
        let e = m.add_request("itd", &ParamMap::new()).expect_err("mono");
        assert!(matches!(e, Error::BinauralOnMono(ref r) if r == "itd"));
        assert_eq!(m.processor_count(), 0);
        let h = m.add_request("ratemap", &ParamMap::new()).expect("mono ok");
        assert_eq!(m.request_signals(h).expect("ok")[0].key(), "ratemap_mono");
    }

    /// A binaural request on `time` (duet) reads both outputs of the one pre-processor
    /// (flag 2, one output per ear); on a mono input it is refused.
    #[test]
    fn a_binaural_request_on_time_reads_both_preproc_outputs() {
        let mut m = Manager::new(16000.0, 2).expect("valid");
        let h = m.add_request("duet", &ParamMap::new()).expect("ok");
        let duet = m.request_signals(h).expect("ok")[0].source.node;
        let parents: Vec<(&str, usize)> = m.graph.nodes[duet]
            .parents
            .iter()
            .map(|p| (m.graph.nodes[p.node].name, p.output))
            .collect();
        assert_eq!(parents, [("time", 0), ("time", 1)]);
        assert_eq!(m.request_signals(h).expect("ok")[0].key(), "duet_mono");
        let mut mono = Manager::new(16000.0, 1).expect("valid");
        let e = mono
            .add_request("duet", &ParamMap::new())
            .expect_err("mono");
        assert!(matches!(e, Error::BinauralOnMono(ref r) if r == "duet"));
    }

    /// issue 46: a value the request set is never called "(the default)", even when it
    /// equals the default (`fb_highFreqHz = 8000` at 11025 Hz); left unset, it is.
    #[test]
    fn a_value_set_is_not_called_the_default() {
        let mut m = Manager::new(11025.0, 2).expect("valid");
        let e = m
            .add_request("ratemap", &params(&[("fb_highFreqHz", json!(8000))]))
            .expect_err("above Nyquist")
            .to_string();
        assert!(
            e.starts_with("invalid value 8000.0 for parameter 'fb_highFreqHz': 8000 puts "),
            "{e}"
        );
        assert!(!e.contains("the default"), "{e}");
        let e = m
            .add_request("ratemap", &ParamMap::new())
            .expect_err("above Nyquist")
            .to_string();
        assert!(e.contains(": 8000 (the default) puts "), "{e}");
        // modify_parameter too: ams_highFreqHz set to its default at 8 kHz
        let mut m = Manager::new(8000.0, 1).expect("valid");
        let fits = params(&[
            ("fb_highFreqHz", json!(3000)),
            ("ams_highFreqHz", json!(256)),
        ]);
        let h = m.add_request("amsFeatures", &fits).expect("fits");
        let e = m
            .modify_parameter(h, "ams_highFreqHz", json!(1024))
            .expect_err("above Nyquist")
            .to_string();
        assert!(
            e.contains("with ams_highFreqHz = 1024, the modulation band"),
            "{e}"
        );
    }

    #[test]
    fn unknown_names_and_bad_input_are_clear_errors() {
        let mut m = Manager::new(16000.0, 2).expect("valid");
        let e = m
            .add_request("ratemap", &params(&[("rm_wSizeSeconds", json!(0.1))]))
            .expect_err("unknown");
        assert!(e.to_string().contains("did you mean 'rm_wSizeSec'"), "{e}");
        let e = m
            .add_request("ratemapp", &ParamMap::new())
            .expect_err("unknown");
        assert!(e.to_string().contains("unknown request 'ratemapp'"), "{e}");
        let e = m
            .add_request("ratemap", &params(&[("fb_nChannels", json!("many"))]))
            .expect_err("ill-typed");
        assert!(e.to_string().contains("fb_nChannels"), "{e}");
        m.add_request("ratemap", &ParamMap::new()).expect("ok");
        let x = [0.0, f64::NAN];
        let e = m.process_chunk(&[&x, &x]).expect_err("NaN");
        assert!(
            e.to_string()
                .contains("sample 1 of the left channel is NaN"),
            "{e}"
        );
        // later in the stream, the position counts from the start of the stream
        m.process_chunk(&[&[0.0; 3], &[0.0; 3]]).expect("finite");
        let e = m.process_chunk(&[&x, &x]).expect_err("NaN");
        assert!(
            e.to_string().contains("sample 4 of the left channel"),
            "{e}"
        );
        // issue 13, item 4: finite but overflowing input is refused, not turned into NaN
        let huge = [0.0, 1e200];
        let e = m.process_chunk(&[&huge, &huge]).expect_err("overflow");
        let msg = e.to_string();
        assert!(
            msg.contains("sample 4 of the left channel is 1e200"),
            "{msg}"
        );
        assert!(msg.contains("scale the input"), "{msg}");
        m.process_chunk(&[&[MAX_AMPLITUDE; 2], &[-MAX_AMPLITUDE; 2]])
            .expect("the largest accepted amplitude");
        // issue 57, item 5: a level-scaling gain of 1e20 (accepted) lowers the amplitude
        // accepted by as much (float32 noise at 1e18 through it gave an Inf STFT)
        let mut loud = Manager::new(16000.0, 2).expect("manager");
        let params: ParamMap = serde_json::from_value(serde_json::json!({
            "pp_bLevelScaling": true, "pp_refSPLdB": -300.0
        }))
        .expect("params");
        loud.add_request("stft", &params).expect("stft");
        let e = loud
            .process_chunk(&[&[1e-4; 4], &[0.0; 4]])
            .expect_err("1e16 after the gain");
        let msg = e.to_string();
        assert!(msg.contains("'time' raises it by up to 1e20"), "{msg}");
        assert!(msg.contains("pp_refSPLdB"), "{msg}");
        loud.process_chunk(&[&[1e-5; 4], &[-1e-5; 4]])
            .expect("1e15 after the gain");
        let e = m.process_chunk(&[&x]).expect_err("mono chunk");
        assert!(e.to_string().contains("got 1 channel(s)"), "{e}");
        let e = m.process_signal(&[&[], &[]]).expect_err("empty");
        assert!(e.to_string().contains("empty"), "{e}");
        assert!(Manager::new(f64::NAN, 2).is_err());
        assert!(Manager::new(16000.0, 3).is_err());
    }

    /// With `trm_minValuedB` an onset map reads the ratemap beside its onset strength: the
    /// ratemap is the shared one, and a level no frame reaches empties the map.
    #[test]
    fn a_map_reads_the_ratemap_beside_its_strength() {
        let mut m = Manager::new(16000.0, 2).expect("valid");
        let plain = m.add_request("onsetMap", &ParamMap::new()).expect("ok");
        let before = m.processor_count();
        let gated = m
            .add_request("onsetMap", &params(&[("trm_minValuedB", json!(200))]))
            .expect("ratemap wired");
        assert_eq!(m.processor_count(), before + 2, "one new map per ear");
        let map = m.request_signals(gated).expect("ok")[0].source.node;
        let strength = m.request_signals(plain).expect("ok")[0].source.node;
        let parents: Vec<&str> = m.graph.nodes[map]
            .parents
            .iter()
            .map(|p| m.graph.nodes[p.node].name)
            .collect();
        assert_eq!(parents, ["onsetStrength", "ratemap"]);
        assert_eq!(
            m.graph.nodes[map].parents[0].node,
            m.graph.nodes[strength].parents[0].node
        );
        // noise bursts of 0.1 s every 0.3 s: clear onsets
        let mut state = 1u64;
        let x: Vec<f64> = (0..16000)
            .map(|t| {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1);
                let noise = (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
                if t % 4800 < 1600 {
                    noise
                } else {
                    0.0
                }
            })
            .collect();
        m.process_signal(&[&x, &x]).expect("process");
        let ones = |h| -> f64 {
            m.request_signals(h).expect("ok")[0]
                .new
                .as_slice()
                .iter()
                .sum()
        };
        assert!(ones(plain) > 0.0, "the bursts have onsets");
        assert_eq!(ones(gated), 0.0, "no ratemap frame reaches 200 dB");
    }

    /// Every parameter of every registered request turns an ill-typed value into an error
    /// that names the parameter and says what it accepts, and places nothing.
    #[test]
    fn every_parameter_rejects_an_ill_typed_value_by_name() {
        use afe_core::ParamKind;
        for r in requests() {
            for spec in r.params {
                let bad = match spec.kind {
                    ParamKind::Choice(_) | ParamKind::Choices(_) => json!("no-such-choice"),
                    ParamKind::Flag => json!("maybe"),
                    _ => json!("many"),
                };
                let mut m = Manager::new(16000.0, 2).expect("valid");
                let e = m
                    .add_request(r.name, &params(&[(spec.name, bad)]))
                    .expect_err("ill-typed")
                    .to_string();
                assert!(e.contains(spec.name), "{}/{}: {e}", r.name, spec.name);
                assert!(
                    e.contains("expected") || e.contains("one of"),
                    "{}/{}: {e}",
                    r.name,
                    spec.name
                );
                assert_eq!(m.processor_count(), 0, "{}/{}", r.name, spec.name);
            }
        }
    }
}
