//! The live runner: source → BASS port → block reader → graph → recorder, with the
//! compute time of every block measured against the block's duration.

use std::path::PathBuf;
use std::str::FromStr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant, SystemTime};

use afe_bass_source::{Feeder, Pacing, Reader, Sample, Source, SynthSpec, WavSource};
pub use afe_core::ExpectedSource;
use afe_core::ParamMap;
use afe_graph::Manager;
use thiserror::Error;

use crate::block_times::BlockTimes;
use crate::recorder::Recorder;
use crate::rss::RssProbe;

/// How long the reader sleeps when the port has no new frame (real-time pacing).
const POLL: Duration = Duration::from_micros(500);

/// Where the audio comes from, as written on the command line.
#[derive(Debug, Clone, PartialEq)]
pub enum SourceSpec {
    /// `wav:FILE`: replay of a WAV file.
    Wav(PathBuf),
    /// `synth:SPEC`: a synthetic signal (see [`SynthSpec`]).
    Synth(SynthSpec),
    /// `alsa:DEVICE`: ALSA capture from a device such as `hw:1,0`.
    Alsa(String),
    /// `zenoh:ENDPOINT[@NAME]`: the raw audio an `afe serve` server publishes, e.g.
    /// `zenoh:tcp/192.168.1.20:7447` (NAME picks a server when several answer).
    Zenoh {
        /// Zenoh endpoint of the server.
        endpoint: String,
        /// The server's name, if given.
        name: Option<String>,
    },
}

impl FromStr for SourceSpec {
    type Err = StreamError;

    /// Parses `wav:FILE`, `synth:SPEC`, `alsa:DEVICE` or `zenoh:ENDPOINT[@NAME]`.
    ///
    /// ```
    /// use afe::stream::SourceSpec;
    /// let s: SourceSpec = "alsa:hw:1,0".parse()?;
    /// assert_eq!(s, SourceSpec::Alsa("hw:1,0".into()));
    /// assert!("mic:0".parse::<SourceSpec>().is_err());
    /// # Ok::<(), afe::stream::StreamError>(())
    /// ```
    fn from_str(text: &str) -> Result<Self, StreamError> {
        let bad = || {
            StreamError::Spec(format!(
                "unknown source '{text}': expected wav:FILE, synth:SPEC, alsa:DEVICE or zenoh:ENDPOINT"
            ))
        };
        let (kind, rest) = text.split_once(':').ok_or_else(bad)?;
        if rest.is_empty() {
            return Err(StreamError::Spec(format!(
                "source '{text}' names no {}",
                match kind {
                    "wav" => "file",
                    "alsa" => "device",
                    "zenoh" => "endpoint",
                    _ => "signal",
                }
            )));
        }
        match kind {
            "wav" => Ok(SourceSpec::Wav(PathBuf::from(rest))),
            "synth" => Ok(SourceSpec::Synth(rest.parse()?)),
            "alsa" => Ok(SourceSpec::Alsa(rest.to_string())),
            "zenoh" => {
                let (endpoint, name) = match rest.rsplit_once('@') {
                    Some((e, n)) => (e, Some(n.to_string())),
                    None => (rest, None),
                };
                Ok(SourceSpec::Zenoh {
                    endpoint: endpoint.to_string(),
                    name,
                })
            }
            _ => Err(bad()),
        }
    }
}

impl SourceSpec {
    /// The pacing a source gets unless told otherwise: files run as fast as possible,
    /// synthesis and capture at real time.
    pub fn default_pacing(&self) -> Pacing {
        match self {
            SourceSpec::Wav(_) => Pacing::Fast,
            SourceSpec::Synth(_) | SourceSpec::Alsa(_) | SourceSpec::Zenoh { .. } => {
                Pacing::Realtime
            }
        }
    }

    /// The synthetic head that turns (`synth:...,turn=DEG`), which reports its own yaw to
    /// the stream's head pose; `None` for any other source.
    pub fn turning_head(&self) -> Option<afe_bass_source::Placed> {
        match self {
            SourceSpec::Synth(s) => s.placed.filter(|p| p.turn_deg != 0.0),
            _ => None,
        }
    }
}

/// What to compute, and how to run the stream.
#[derive(Debug, Clone)]
pub struct StreamJob {
    /// AFE request names, all placed with the same parameters.
    pub requests: Vec<String>,
    /// AFE parameter name → value, shared by every request.
    pub params: ParamMap,
    /// Block fed to the graph per step, in ms: `round(block_ms · fs / 1000)` frames.
    pub block_ms: f64,
    /// Stop after this many seconds of audio (`None`: at the end of the source).
    pub duration_s: Option<f64>,
    /// Real time, or as fast as the graph goes.
    pub pacing: Pacing,
    /// Worker threads of the concurrent scheduler (0: sequential executor).
    pub threads: usize,
    /// Keep the outputs (for saving them).
    pub record: bool,
    /// With `record`: every intermediate signal too.
    pub all: bool,
    /// Replay WAV files from the start again after their end.
    pub looping: bool,
    /// ALSA capture rate in Hz.
    pub alsa_rate: u32,
    /// Ask for real-time scheduling and locked memory ([`crate::realtime`]); this changes
    /// the calling thread's scheduling for good. Real-time pacing only.
    pub rt: bool,
    /// The channels and rate the source must have (a robot's platform descriptor's):
    /// another source is refused before the stream starts.
    pub expect: Option<ExpectedSource>,
    /// The requests the stream's manager can place (the built-in ones by default; a
    /// program adds its own processors to it).
    pub registry: crate::Registry,
    /// The head's yaw over time its processors read (`tracking`): a feed whose clones
    /// the caller fills, from a CSV track or as a motor controller reports (times in s
    /// of the stream).
    pub head_pose: crate::HeadPose,
}

impl Default for StreamJob {
    fn default() -> Self {
        StreamJob {
            requests: Vec::new(),
            params: ParamMap::new(),
            block_ms: 10.0,
            duration_s: None,
            pacing: Pacing::Fast,
            threads: 0,
            record: false,
            all: false,
            looping: false,
            alsa_rate: 44_100,
            rt: false,
            expect: None,
            registry: crate::Registry::default(),
            head_pose: crate::HeadPose::new(),
        }
    }
}

/// Everything that can stop a stream.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum StreamError {
    /// The port, the reader or the source failed (file, synth spec, ALSA device).
    #[error(transparent)]
    Source(#[from] afe_bass_source::Error),
    /// The graph refused a request, a parameter or the input.
    #[error(transparent)]
    Afe(#[from] afe_core::Error),
    /// A source specification or stream setting that cannot work.
    #[error("{0}")]
    Spec(String),
}

/// The numbers of a stream, so far or at its end (serialised as `afe stream --json`
/// shows it).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct StreamReport {
    /// Frames processed by the graph.
    pub frames: u64,
    /// Frames the source published that the graph never got: lost by the reader when it
    /// fell more than the port's length behind, plus the partial block before each gap.
    pub lost_frames: u64,
    /// Blocks processed.
    pub blocks: u64,
    /// Blocks whose compute time exceeded their duration.
    pub deadline_misses: u64,
    /// Median compute time per block, in ms (within 2.3 % above, see
    /// [`crate::block_times`]).
    pub compute_ms_p50: f64,
    /// 99th-percentile compute time per block, in ms (as the median).
    pub compute_ms_p99: f64,
    /// Longest compute time of a block, in ms.
    pub compute_ms_max: f64,
    /// Index (from 0) of the block that took `compute_ms_max`.
    pub slowest_block: u64,
    /// Indices of the first blocks that missed their deadline (at most
    /// [`crate::block_times::MISSED_KEPT`]).
    pub missed_blocks: Vec<u64>,
    /// Compute times: (upper bin edge in ms, blocks) of the non-empty bins, fastest first.
    pub compute_ms_histogram: Vec<(f64, u64)>,
    /// Duration of a full block, in ms: the compute budget.
    pub budget_ms: f64,
    /// Audio duration processed over total compute time: how many times faster than
    /// real time the graph runs (0 before the first block).
    pub x_realtime: f64,
    /// Device overruns of the source (ALSA), whose frames never reached the port.
    pub device_overruns: u64,
    /// Sampling rate of the stream, in Hz.
    pub fs: f64,
    /// Frames per full block.
    pub block_frames: usize,
    /// Whether the stream was stopped by [`crate::interrupt`] before its end (what was
    /// computed until then is complete and can be saved).
    pub interrupted: bool,
    /// What [`StreamJob::rt`] obtained (`None` without it); serialised as `rt` (its
    /// description) and `rt_complete`.
    #[serde(skip)]
    pub realtime: Option<crate::realtime::Realtime>,
    /// Resident memory in MiB after the first 60 s of audio (sampled each second of
    /// audio; `None` for shorter streams or without `/proc`).
    pub rss_mib_at_60s: Option<f64>,
    /// Largest resident memory in MiB sampled after the first 60 s.
    pub rss_mib_max_after_60s: Option<f64>,
    /// Resident memory in MiB at the last sample.
    pub rss_mib_end: Option<f64>,
}

/// Compute times and counts of a running stream, in constant memory.
#[derive(Debug, Clone)]
pub struct Timing {
    fs: f64,
    block_frames: usize,
    times: BlockTimes,
    frames: u64,
    lost: u64,
    last_compute_s: f64,
    last_frames: usize,
    rss: RssTrack,
    /// When the feeder of a source paced at real time started (before its first frame),
    /// and the frames it publishes at once.
    paced_from: Option<(SystemTime, u64)>,
    /// When the last block was complete on the reader's side.
    ready: SystemTime,
}

/// Resident memory sampled once per second of audio.
#[derive(Debug, Clone, Default)]
struct RssTrack {
    probe: RssProbe,
    next_sample: u64,
    at_60s_kib: Option<u64>,
    max_after_kib: Option<u64>,
    last_kib: Option<u64>,
}

impl Timing {
    fn new(fs: f64, block_frames: usize) -> Self {
        Timing {
            fs,
            block_frames,
            times: BlockTimes::default(),
            frames: 0,
            lost: 0,
            last_compute_s: 0.0,
            last_frames: 0,
            rss: RssTrack::default(),
            paced_from: None,
            ready: SystemTime::UNIX_EPOCH,
        }
    }

    fn block(&mut self, frames: usize, compute_s: f64) {
        self.frames += frames as u64;
        self.last_frames = frames;
        self.last_compute_s = compute_s;
        self.times.record(compute_s, frames as f64 / self.fs);
        let audio = self.frames + self.lost;
        if audio >= self.rss.next_sample {
            self.rss.next_sample = audio + self.fs as u64;
            let Some(kib) = self.rss.probe.read_kib() else {
                return;
            };
            self.rss.last_kib = Some(kib);
            if audio as f64 >= 60.0 * self.fs {
                match self.rss.at_60s_kib {
                    None => self.rss.at_60s_kib = Some(kib),
                    Some(_) => {
                        self.rss.max_after_kib =
                            Some(self.rss.max_after_kib.map_or(kib, |m| m.max(kib)));
                    }
                }
            }
        }
    }

    /// Frames processed so far.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// Frames lost so far (the reader fell behind the port).
    pub fn lost_frames(&self) -> u64 {
        self.lost
    }

    /// Sampling rate of the stream, Hz.
    pub fn fs(&self) -> f64 {
        self.fs
    }

    /// Frames per full block.
    pub fn block_frames(&self) -> usize {
        self.block_frames
    }

    /// Frames in the last block (a finite source's last one may be short).
    pub fn last_block_frames(&self) -> usize {
        self.last_frames
    }

    /// Index on the port of the frame after the last block (frames processed plus lost).
    pub fn input_end(&self) -> u64 {
        self.frames + self.lost
    }

    /// Unix time in ns at which the last block's last frame was published on the port, or
    /// a bound below it: for a source paced at real time, when the port chunk holding that
    /// frame was due, counted from just before the feeder started (so never after the true
    /// time); otherwise when the reader had the whole block.
    pub fn block_end_unix_ns(&self) -> u64 {
        let at = match self.paced_from {
            Some((t0, chunk)) => {
                let published = self.input_end().div_ceil(chunk.max(1)) * chunk.max(1);
                t0 + Duration::from_secs_f64(published as f64 / self.fs)
            }
            None => self.ready,
        };
        at.duration_since(SystemTime::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos() as u64)
    }

    /// Compute time of the last block in ms, and its budget (the block's duration) in ms.
    pub fn last_block_ms(&self) -> (f64, f64) {
        (
            self.last_compute_s * 1e3,
            self.block_frames as f64 / self.fs * 1e3,
        )
    }

    /// The report so far.
    pub fn report(&self) -> StreamReport {
        let t = &self.times;
        StreamReport {
            frames: self.frames,
            lost_frames: self.lost,
            blocks: t.blocks(),
            deadline_misses: t.misses(),
            compute_ms_p50: t.quantile_s(0.50) * 1e3,
            compute_ms_p99: t.quantile_s(0.99) * 1e3,
            compute_ms_max: t.max_s() * 1e3,
            slowest_block: t.slowest_block(),
            missed_blocks: t.missed_blocks().to_vec(),
            compute_ms_histogram: t.histogram_ms(),
            budget_ms: self.block_frames as f64 / self.fs * 1e3,
            x_realtime: if t.total_s() > 0.0 {
                self.frames as f64 / self.fs / t.total_s()
            } else {
                0.0
            },
            device_overruns: 0,
            fs: self.fs,
            block_frames: self.block_frames,
            interrupted: false,
            realtime: None,
            rss_mib_at_60s: self.rss.at_60s_kib.map(|k| k as f64 / 1024.0),
            rss_mib_max_after_60s: self.rss.max_after_kib.map(|k| k as f64 / 1024.0),
            rss_mib_end: self.rss.last_kib.map(|k| k as f64 / 1024.0),
        }
    }
}

/// What sees each block once the graph has computed it: the timing, the graph (its
/// signals' new output) and the block's input, one vector per ear. It may edit the graph
/// before the next block (add or remove requests, change parameters), as the live view
/// does. A closure of the timing alone is one.
pub trait Observer {
    /// Called after every block.
    fn block(&mut self, timing: &Timing, mgr: &mut Manager, input: &[Vec<f64>]);
}

impl<F: FnMut(&Timing)> Observer for F {
    fn block(&mut self, timing: &Timing, _mgr: &mut Manager, _input: &[Vec<f64>]) {
        self(timing);
    }
}

/// An [`Observer`] made of a closure that sees the whole block: the timing, the graph and
/// the block's input.
pub struct Blocks<F>(pub F);

impl<F: FnMut(&Timing, &mut Manager, &[Vec<f64>])> Observer for Blocks<F> {
    fn block(&mut self, timing: &Timing, mgr: &mut Manager, input: &[Vec<f64>]) {
        (self.0)(timing, mgr, input);
    }
}

/// The result of a stream: its report and, if asked, its outputs.
#[derive(Debug, Clone)]
pub struct Streamed {
    /// Counts and compute times.
    pub report: StreamReport,
    /// The outputs (empty unless [`StreamJob::record`]), as [`crate::extract::run`] gives them.
    pub recorded: Recorder,
}

/// Opens the source `spec` names and streams it: see [`run`].
pub fn run_spec(
    spec: &SourceSpec,
    job: &StreamJob,
    on_block: impl Observer,
) -> Result<Streamed, StreamError> {
    match spec {
        SourceSpec::Wav(path) => match afe_bass_source::open_wav(path, job.looping)? {
            WavSource::Int(replay) => run(replay, job, on_block),
            WavSource::Float(replay) => run(replay, job, on_block),
        },
        SourceSpec::Synth(s) => {
            let synth = afe_bass_source::Synth::new(s.clone());
            match spec.turning_head() {
                Some(placed) => {
                    if !job.head_pose.is_empty() {
                        return Err(StreamError::Spec(format!(
                            "synth turn={}: the synthetic head reports its own yaw; a head-yaw \
                             track is not given with it",
                            placed.turn_deg
                        )));
                    }
                    let turning =
                        crate::turning::Turning::new(synth, placed, job.head_pose.clone())?;
                    run(turning, job, on_block)
                }
                None => run(synth, job, on_block),
            }
        }
        SourceSpec::Alsa(device) => alsa(device, job, on_block),
        SourceSpec::Zenoh { endpoint, name } => zenoh(endpoint, name.as_deref(), job, on_block),
    }
}

/// A `zenoh:` source is opened by the network crate (`afe_net::run_spec`), which this
/// library does not depend on.
fn zenoh(
    _endpoint: &str,
    _name: Option<&str>,
    _job: &StreamJob,
    _on_block: impl Observer,
) -> Result<Streamed, StreamError> {
    Err(StreamError::Spec(ZENOH_OFF.into()))
}

/// What `afe` says about a `zenoh:` source when built without the network crate.
pub const ZENOH_OFF: &str = "this afe was built without Zenoh: rebuild it with \
`cargo build --release --features remote` (or `robot`)";

#[cfg(feature = "alsa")]
fn alsa(device: &str, job: &StreamJob, on_block: impl Observer) -> Result<Streamed, StreamError> {
    let config = afe_bass_source::AlsaConfig {
        device: device.to_string(),
        format: afe_bass_source::PortFormat::bass_timing(job.alsa_rate, 2),
    };
    run(
        afe_bass_source::AlsaSource::acquire(&config)?,
        job,
        on_block,
    )
}

#[cfg(not(feature = "alsa"))]
fn alsa(
    _device: &str,
    _job: &StreamJob,
    _on_block: impl Observer,
) -> Result<Streamed, StreamError> {
    Err(StreamError::Spec(ALSA_OFF.into()))
}

/// What `afe` says about ALSA when built without it.
pub const ALSA_OFF: &str = "this afe was built without ALSA support: rebuild it with \
`cargo build --release --features alsa` (needs the ALSA headers, e.g. libasound2-dev)";

/// Streams `source` through the graph of `job`: the source feeds a BASS port (from its
/// own thread at real time, or on demand when fast), a block reader takes blocks of
/// `job.block_ms` from it, and the graph computes each block; `on_block` (an
/// [`Observer`], e.g. a closure of the [`Timing`]) sees every block. When the reader falls behind by more than the port, the frames it
/// lost (and the partial block before the gap) are counted and the graph restarts from
/// a reset state; a finite source's last partial block is processed too.
///
/// ```
/// use afe::stream::{run, StreamJob, Timing};
/// use afe_bass_source::{Pacing, Synth};
/// let job = StreamJob {
///     requests: vec!["ild".into()],
///     duration_s: Some(0.5),
///     pacing: Pacing::Fast,
///     record: true,
///     ..StreamJob::default()
/// };
/// let out = run(Synth::parse("fs=16000,tone=1000,ild_db=-6")?, &job, |_: &Timing| {})?;
/// assert_eq!((out.report.frames, out.report.blocks, out.report.lost_frames), (8000, 50, 0));
/// let ild = out.recorded.get("ild_mono").expect("recorded");
/// assert_eq!(ild.shape(), vec![49, 31]);
/// # Ok::<(), afe::stream::StreamError>(())
/// ```
pub fn run<Src: Source>(
    source: Src,
    job: &StreamJob,
    on_block: impl Observer,
) -> Result<Streamed, StreamError> {
    let format = source.format();
    let fs = f64::from(format.sample_rate);
    if !(job.block_ms.is_finite() && job.block_ms > 0.0 && job.block_ms <= 10_000.0) {
        return Err(StreamError::Spec(format!(
            "block length {} ms: it must be above 0 and at most 10000 ms",
            job.block_ms
        )));
    }
    let block = ((job.block_ms * fs / 1000.0).round() as usize).max(1);
    let limit = match job.duration_s {
        Some(d) if d.is_finite() && d > 0.0 => Some((d * fs).round().max(1.0) as u64),
        Some(d) => {
            return Err(StreamError::Spec(format!(
                "duration {d} s: it must be a number > 0"
            )))
        }
        None => None,
    };
    if let Some(expect) = &job.expect {
        expect
            .check(format.channels, fs)
            .map_err(StreamError::Spec)?;
    }
    if job.rt && job.pacing != Pacing::Realtime {
        return Err(StreamError::Spec(
            "real-time scheduling (--rt) is for streams paced at real time: a fast stream would hold the cores".into(),
        ));
    }
    // before the workers and the feeder start, so that they inherit the policy
    let realtime = job.rt.then(crate::realtime::enable);
    let mut mgr = Manager::with_threads(fs, format.channels, job.threads)?;
    mgr.set_registry(job.registry.clone())?;
    mgr.set_head_pose(job.head_pose.clone())?;
    mgr.set_keep_all(job.all);
    for r in &job.requests {
        mgr.add_request(r, &job.params)?;
    }
    // every buffer sized for a block before the audio starts: nothing allocates on it
    mgr.prepare(block)?;
    let mut feeder = Feeder::new(source, limit)?;
    let mut consumer = Consumer {
        reader: Reader::new(feeder.port(), 0),
        raw: vec![vec![Src::Sample::default(); block]; format.channels],
        input: vec![Vec::with_capacity(block); format.channels],
        filled: 0,
        mgr,
        recorder: Recorder::new(job.all),
        record: job.record,
        timing: Timing::new(fs, block),
        on_block,
    };
    match job.pacing {
        Pacing::Fast => loop {
            if consumer.mgr.cancel_token().is_cancelled() {
                break;
            }
            if consumer.poll()? == 0 {
                if consumer.reader.at_end() {
                    break;
                }
                feeder.pump()?;
            }
        },
        Pacing::Realtime => {
            if feeder.source().clock() == afe_bass_source::Clock::OnDemand {
                // a block is published as soon as it is due, not with its port chunk
                feeder.set_pace(block);
                let pace = block.min(format.frames_per_chunk) as u64;
                consumer.timing.paced_from = Some((SystemTime::now(), pace));
            }
            let stop = AtomicBool::new(false);
            std::thread::scope(|s| {
                let writer = s.spawn(|| feeder.run_realtime(&stop));
                let read = consumer.drain_paced();
                stop.store(true, Ordering::Relaxed);
                let fed = writer
                    .join()
                    .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
                read.and(fed.map_err(StreamError::from))
            })?;
        }
    }
    consumer.flush()?;
    let mut report = consumer.timing.report();
    report.device_overruns = feeder.source().overruns();
    report.interrupted = consumer.mgr.cancel_token().is_cancelled();
    report.realtime = realtime;
    Ok(Streamed {
        report,
        recorded: consumer.recorder,
    })
}

/// The reading side: reader, block assembly, graph, recorder, timing.
struct Consumer<S: Sample, F> {
    reader: Reader<S>,
    /// The block being assembled, as the port stores it.
    raw: Vec<Vec<S>>,
    /// The block as AFE input.
    input: Vec<Vec<f64>>,
    filled: usize,
    mgr: Manager,
    recorder: Recorder,
    record: bool,
    timing: Timing,
    on_block: F,
}

impl<S: Sample, F: Observer> Consumer<S, F> {
    /// Reads what the port has towards the current block, processes the block when it is
    /// complete, and returns the frames read.
    fn poll(&mut self) -> Result<usize, StreamError> {
        let filled = self.filled;
        let mut dest: Vec<&mut [S]> = self.raw.iter_mut().map(|c| &mut c[filled..]).collect();
        let got = self.reader.read(&mut dest)?;
        if got.lost > 0 {
            // The partial block before the gap cannot be continued: drop it with the
            // lost frames, and restart the graph as at the start of a stream.
            self.timing.lost += got.lost + filled as u64;
            for c in &mut self.raw {
                c.copy_within(filled..filled + got.frames, 0);
            }
            self.filled = 0;
            self.mgr.reset()?;
        }
        self.filled += got.frames;
        if self.filled == self.raw[0].len() {
            self.process()?;
        }
        Ok(got.frames)
    }

    /// Reads until the port is closed and read (or a stop is requested), sleeping while
    /// it has nothing new.
    fn drain_paced(&mut self) -> Result<(), StreamError> {
        loop {
            if self.mgr.cancel_token().is_cancelled() {
                return Ok(());
            }
            if self.poll()? == 0 {
                if self.reader.at_end() {
                    return Ok(());
                }
                std::thread::sleep(POLL);
            }
        }
    }

    /// Processes the last, partial block.
    fn flush(&mut self) -> Result<(), StreamError> {
        if self.filled > 0 {
            self.process()?;
        }
        Ok(())
    }

    fn process(&mut self) -> Result<(), StreamError> {
        self.timing.ready = SystemTime::now();
        let n = self.filled;
        for (input, raw) in self.input.iter_mut().zip(&self.raw) {
            input.clear();
            input.extend(raw[..n].iter().map(|s| s.to_f64()));
        }
        let refs: Vec<&[f64]> = self.input.iter().map(Vec::as_slice).collect();
        let start = Instant::now();
        self.mgr.submit_chunk(&refs)?;
        self.mgr.collect_chunk()?;
        let compute = start.elapsed().as_secs_f64();
        if self.record {
            self.recorder.record(&self.mgr);
        }
        self.filled = 0;
        self.timing.block(n, compute);
        self.on_block
            .block(&self.timing, &mut self.mgr, &self.input);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use afe_bass_source::Replay;

    fn job(pacing: Pacing) -> StreamJob {
        StreamJob {
            requests: vec!["ratemap".into(), "ild".into()],
            params: [("fb_nChannels".to_string(), serde_json::json!(8))]
                .into_iter()
                .collect(),
            pacing,
            record: true,
            ..StreamJob::default()
        }
    }

    fn signal(frames: usize) -> Vec<Vec<f64>> {
        let l: Vec<f64> = (0..frames).map(|t| (0.07 * t as f64).sin() * 0.3).collect();
        let r = l.iter().map(|v| v * 0.5).collect();
        vec![l, r]
    }

    #[test]
    fn a_stream_computes_what_extract_computes() {
        let x = signal(4321);
        let mut replay = Replay::new(16000, x.clone(), false).expect("replay");
        replay.set_chunking(300, 4).expect("chunking");
        let out = run(replay, &job(Pacing::Fast), |_: &Timing| {}).expect("stream");
        let extract = crate::extract::Job {
            requests: job(Pacing::Fast).requests,
            params: job(Pacing::Fast).params,
            chunk: Some(160),
            ..Default::default()
        };
        let refs: Vec<&[f64]> = x.iter().map(Vec::as_slice).collect();
        let want = crate::extract::run(&extract, 16000.0, &refs).expect("extract");
        assert_eq!(out.report.frames, 4321);
        assert_eq!(out.report.blocks, 28, "27 blocks of 160 and one of 1");
        assert_eq!(out.report.lost_frames, 0);
        assert_eq!(out.recorded.signals().len(), want.signals().len());
        for (a, b) in out.recorded.signals().iter().zip(want.signals()) {
            assert_eq!(a.key, b.key);
            assert_eq!(a.data.as_slice(), b.data.as_slice(), "{}", a.key);
        }
    }

    #[test]
    fn real_time_takes_the_signal_duration_and_loses_nothing() {
        let mut replay = Replay::new(16000, signal(3200), false).expect("replay");
        replay.set_chunking(320, 10).expect("chunking");
        let start = Instant::now();
        let mut calls = 0;
        let out = run(replay, &job(Pacing::Realtime), |_: &Timing| calls += 1).expect("stream");
        assert!(start.elapsed() >= Duration::from_millis(200));
        let r = &out.report;
        assert_eq!(
            (r.frames, r.lost_frames, r.blocks, calls),
            (3200, 0, 20, 20)
        );
        assert_eq!(r.budget_ms, 10.0);
        assert!(r.compute_ms_p50 > 0.0 && r.compute_ms_p50 <= r.compute_ms_p99);
        assert!(r.x_realtime > 1.0, "{r:?}");
    }

    #[test]
    fn a_reader_that_falls_behind_counts_every_lost_frame() {
        // a port of 2 × 100 frames; the reader sleeps 30 ms per 10 ms block
        let mut replay = Replay::new(16000, signal(16000), false).expect("replay");
        replay.set_chunking(100, 2).expect("chunking");
        let mut j = job(Pacing::Realtime);
        j.requests = vec!["ild".into()];
        let out = run(replay, &j, |_: &Timing| {
            std::thread::sleep(Duration::from_millis(30))
        })
        .expect("stream");
        let r = &out.report;
        assert!(r.lost_frames > 0, "{r:?}");
        assert_eq!(r.frames + r.lost_frames, 16000, "{r:?}");
    }

    #[test]
    fn bad_settings_are_clear_errors() {
        let replay = || Replay::new(16000, signal(100), false).expect("replay");
        let mut j = job(Pacing::Fast);
        j.block_ms = 0.0;
        let e = run(replay(), &j, |_: &Timing| {}).expect_err("block");
        assert!(e.to_string().contains("block length 0 ms"), "{e}");
        let mut j = job(Pacing::Fast);
        j.duration_s = Some(-1.0);
        assert!(run(replay(), &j, |_: &Timing| {}).is_err());
        let mut j = job(Pacing::Fast);
        j.requests = vec!["ratemapp".into()];
        let e = run(replay(), &j, |_: &Timing| {}).expect_err("request");
        assert!(e.to_string().contains("unknown request 'ratemapp'"), "{e}");
        let e = "synth:tone=x".parse::<SourceSpec>().expect_err("spec");
        assert!(e.to_string().contains("tone=x"), "{e}");
        assert!("wav:".parse::<SourceSpec>().is_err());
    }

    #[test]
    fn the_afe_reads_back_the_synth_itd_and_ild() {
        let job = StreamJob {
            requests: vec!["itd".into(), "ild".into()],
            duration_s: Some(0.3),
            record: true,
            ..StreamJob::default()
        };
        let synth =
            afe_bass_source::Synth::parse("fs=44100,noise=0.1,itd_ms=0.4,ild_db=-6").expect("spec");
        let out = run(synth, &job, |_: &Timing| {}).expect("stream");
        let last_frame_mean = |key: &str| {
            let s = out.recorded.get(key).expect("recorded");
            let d = s.data.as_slice();
            let w = s.info.cf_hz().len();
            d[d.len() - w..].iter().sum::<f64>() / w as f64
        };
        // 0.4 ms at 44.1 kHz is a delay of 18 samples: 0.408 ms
        let itd = last_frame_mean("itd_mono");
        assert!((itd - 18.0 / 44100.0).abs() < 2e-5, "itd {itd}");
        let ild = last_frame_mean("ild_mono");
        assert!((ild + 6.0).abs() < 0.3, "ild {ild}");
    }
}
