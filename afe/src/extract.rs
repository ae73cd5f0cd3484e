//! Running a set of requests over a whole signal, whole or in chunks.

use afe_core::{Block, Error, ParamMap, Result};
use afe_graph::{Manager, OutputRef};

use crate::recorder::Recorder;
use crate::wav::WavBlocks;

pub use afe_graph::WHOLE_SIGNAL_BLOCK;

/// Samples per ear read at a time when a whole signal is gathered for one call. It is not
/// tied to [`WHOLE_SIGNAL_BLOCK`]: reads of 16 blocks (16,384 samples) tripled the page
/// faults of `gabor`'s gathering, mostly in the copies that grow the gathered input.
const GATHER_READ: usize = 1 << 16;

/// What to compute and how to feed the input.
#[derive(Debug, Clone, Default)]
pub struct Job {
    /// AFE request names, all placed with the same parameters.
    pub requests: Vec<String>,
    /// AFE parameter name → value, shared by every request.
    pub params: ParamMap,
    /// Feed the input in chunks of this many samples (`None`: the whole signal, as the
    /// AFE's `processSignal`; run in internal blocks where that is bit-identical).
    pub chunk: Option<usize>,
    /// Record every intermediate signal too.
    pub all: bool,
    /// Worker threads of the concurrent scheduler (0: sequential executor).
    pub threads: usize,
}

/// Computes `job` on `channels` (one slice per ear) at `fs` Hz.
///
/// ```
/// use afe::extract::{run, Job};
/// let x: Vec<f64> = (0..4410).map(|t| (0.2 * t as f64).sin()).collect();
/// let job = Job { requests: vec!["ratemap".into(), "ild".into()], chunk: Some(441), ..Job::default() };
/// let rec = run(&job, 44100.0, &[&x, &x])?;
/// let ild = rec.get("ild_mono").expect("recorded");
/// assert_eq!(ild.shape(), vec![9, 31]);
/// assert!(ild.data.as_slice().iter().all(|v| v.abs() < 1e-9)); // identical ears
/// # Ok::<(), afe::Error>(())
/// ```
pub fn run(job: &Job, fs: f64, channels: &[&[f64]]) -> Result<Recorder> {
    let mut mgr = Manager::with_threads(fs, channels.len(), job.threads)?;
    run_with(&mut mgr, job, channels)
}

/// Computes `job` with an existing manager (e.g. one recording a scheduler trace); the
/// requests of `job` are added to it. Chunks are pipelined: chunk k+1 is submitted before
/// the output of chunk k is collected, so the concurrent scheduler can overlap them.
pub fn run_with(mgr: &mut Manager, job: &Job, channels: &[&[f64]]) -> Result<Recorder> {
    let mut rec = Recorder::new(job.all);
    rec.expect_input(channels.first().map_or(0, |c| c.len() as u64));
    run_slices_into(mgr, job, channels, &mut rec)?;
    Ok(rec)
}

/// As [`run_with`], handing each chunk's output to `sink`.
pub fn run_slices_into<S: Sink>(
    mgr: &mut Manager,
    job: &Job,
    channels: &[&[f64]],
    sink: &mut S,
) -> std::result::Result<(), S::Error> {
    let len = channels.first().map_or(0, |c| c.len());
    if channels.iter().any(|c| c.len() != len) {
        return Err(Error::InvalidInput("the channels have different lengths".into()).into());
    }
    let mut pos = 0;
    run_into(
        mgr,
        job,
        channels.len(),
        |frames, out| {
            let end = pos + frames.min(len - pos);
            for (o, c) in out.iter_mut().zip(channels) {
                o.clear();
                o.extend_from_slice(&c[pos..end]);
            }
            let got = end - pos;
            pos = end;
            Ok(got)
        },
        sink,
    )
}

/// Computes `job` on the WAV file `wav` with `mgr` (made for its rate and channels),
/// decoding it block by block where the graph allows, into outputs sized up front for
/// the file's length (each written once).
pub fn run_wav(mgr: &mut Manager, job: &Job, wav: &mut WavBlocks) -> Result<Recorder> {
    let (ears, frames) = (wav.channels(), wav.frames());
    record_known_length(mgr, job, ears, frames, |n, out| {
        wav.read(n, out)
            .map_err(|e| Error::InvalidInput(e.to_string()))
    })
}

/// As [`run_source`] for an input of `samples` samples in all, recorded into outputs sized
/// for it up front.
fn record_known_length(
    mgr: &mut Manager,
    job: &Job,
    ears: usize,
    samples: u64,
    next: impl FnMut(usize, &mut [Vec<f64>]) -> Result<usize>,
) -> Result<Recorder> {
    let mut rec = Recorder::new(job.all);
    rec.expect_input(samples);
    run_into(mgr, job, ears, next, &mut rec)?;
    Ok(rec)
}

/// Where a run's output goes as it is computed: kept in memory ([`Recorder`]) or written
/// out as it comes (the corpus store of `afe-batch`).
pub trait Sink {
    /// What can go wrong in the sink; the graph's own errors convert into it.
    type Error: From<Error>;
    /// Takes the new output of the chunk `manager` just computed.
    fn chunk(&mut self, manager: &Manager) -> std::result::Result<(), Self::Error>;
    /// Takes the output of a whole-signal call ([`Manager::process_signal`]), which it may
    /// move out of `manager`.
    fn whole(&mut self, manager: &mut Manager) -> std::result::Result<(), Self::Error>;
    /// Whether a whole-signal call hands this sink the requested outputs it computes in
    /// blocks as they come ([`Sink::block`], see [`Manager::process_signal_streaming`])
    /// rather than joined, in [`Sink::whole`], with the others.
    fn streams(&self) -> bool {
        false
    }
    /// Takes one block of the requested output `source` during a whole-signal call, where
    /// the sink [`Sink::streams`].
    fn block(&mut self, _source: OutputRef, _block: &Block) {}
    /// Where the sink keeps every output whole in memory (as [`Recorder`] does): the input
    /// samples per ear the run will have, 0 if unknown. A whole signal that runs in blocks
    /// then has its outputs written straight into buffers sized for the whole run
    /// ([`Manager::process_source`]) and handed over in [`Sink::whole`], instead of each
    /// block going to [`Sink::chunk`] to be copied. `None` (the default) for a sink that
    /// hands the output on as it comes.
    fn keeps_whole(&self) -> Option<u64> {
        None
    }
}

impl Sink for Recorder {
    type Error = Error;

    fn chunk(&mut self, manager: &Manager) -> Result<()> {
        self.record(manager);
        Ok(())
    }

    fn whole(&mut self, manager: &mut Manager) -> Result<()> {
        self.record_whole(manager);
        Ok(())
    }

    fn keeps_whole(&self) -> Option<u64> {
        Some(self.expected_input().unwrap_or(0))
    }
}

/// A sink that looks at each chunk's output (and each block streamed from a whole-signal
/// call) and keeps only its size, as a live consumer that hands it on would: what
/// `afe bench --discard` times.
#[derive(Debug, Default)]
pub struct Discard {
    values: usize,
}

impl Discard {
    /// Output values seen so far, over every requested signal.
    pub fn values(&self) -> usize {
        self.values
    }
}

impl Sink for Discard {
    type Error = Error;

    fn chunk(&mut self, manager: &Manager) -> Result<()> {
        for s in manager.signals(false) {
            self.values += std::hint::black_box(s.new.as_slice()).len();
        }
        Ok(())
    }

    fn whole(&mut self, manager: &mut Manager) -> Result<()> {
        self.chunk(manager)
    }

    fn streams(&self) -> bool {
        true
    }

    fn block(&mut self, _source: OutputRef, block: &Block) {
        self.values += std::hint::black_box(block.as_slice()).len();
    }
}

/// Computes `job` on input drawn block by block from `next`, which fills one vector per
/// ear (replacing their content) with up to the asked number of frames and returns how
/// many it gave, 0 at the end. Where the graph is chunk-invariant (or is past a prefix,
/// as with the AGC: see [`Manager::one_call_prefix`]), only one block of input is held at
/// a time; otherwise (and only without `job.chunk`) the whole input is drawn first and
/// processed in one call, as the AFE's `processSignal` does.
pub fn run_source(
    mgr: &mut Manager,
    job: &Job,
    ears: usize,
    next: impl FnMut(usize, &mut [Vec<f64>]) -> Result<usize>,
) -> Result<Recorder> {
    let mut rec = Recorder::new(job.all);
    run_into(mgr, job, ears, next, &mut rec)?;
    Ok(rec)
}

/// As [`run_source`], handing each chunk's output to `sink` instead of recording it, so
/// that a long input streams through in bounded memory where the graph allows.
pub fn run_into<S: Sink>(
    mgr: &mut Manager,
    job: &Job,
    ears: usize,
    mut next: impl FnMut(usize, &mut [Vec<f64>]) -> Result<usize>,
    sink: &mut S,
) -> std::result::Result<(), S::Error> {
    for r in &job.requests {
        mgr.add_request(r, &job.params)?;
    }
    if job.requests.is_empty() && mgr.handles().next().is_none() {
        return Err(Error::InvalidInput("no request given".into()).into());
    }
    if job.chunk == Some(0) {
        return Err(
            Error::InvalidInput("chunk = 0: give a positive number of samples".into()).into(),
        );
    }
    mgr.set_keep_all(job.all);
    let mut buf = vec![Vec::new(); ears];
    let empty = || Error::InvalidInput("the signal is empty".into());
    let (block, mut first) = match (job.chunk, mgr.one_call_prefix()) {
        (Some(n), _) => (n, n),
        // a whole signal: one call where the AFE depends on chunk boundaries
        (None, None) => {
            // the whole length, where known, checked before any of it is gathered; else
            // each part as it grows
            let known = sink.keeps_whole().filter(|n| *n > 0);
            if let Some(samples) = known {
                mgr.check_whole_signal(usize::try_from(samples).unwrap_or(usize::MAX))?;
            }
            let mut part = vec![Vec::new(); ears];
            while next(GATHER_READ, &mut part)? > 0 {
                for (all, p) in buf.iter_mut().zip(&part) {
                    all.try_reserve(p.len())
                        .map_err(|_| Error::AllocationFailed {
                            need: afe_graph::work::size(8.0 * (all.len() + p.len()) as f64),
                            what: "the whole input, gathered for one call".into(),
                        })?;
                    all.extend_from_slice(p);
                }
                if known.is_none() {
                    mgr.check_whole_signal(buf[0].len())?;
                }
                if mgr.cancel_token().is_cancelled() {
                    return Err(Error::Interrupted.into());
                }
            }
            if buf.first().is_none_or(Vec::is_empty) {
                return Err(empty().into());
            }
            let refs: Vec<&[f64]> = buf.iter().map(Vec::as_slice).collect();
            if sink.streams() {
                mgr.process_signal_streaming(&refs, &mut |r, b| sink.block(r, b))?;
            } else {
                mgr.process_signal(&refs)?;
            }
            return sink.whole(mgr);
        }
        // blocks give one call's output, the first holding the AGC's seeding time
        (None, Some(prefix)) => {
            if let Some(samples) = sink.keeps_whole() {
                // written in place into the sink's whole-run outputs (the source fills one
                // vector per ear of the manager's)
                mgr.check_channels(ears)?;
                let samples = usize::try_from(samples).unwrap_or(0);
                let cancel = mgr.cancel_token().clone();
                mgr.process_source(samples, &mut |n, out| {
                    if cancel.is_cancelled() {
                        return Err(Error::Interrupted);
                    }
                    next(n, out)
                })?;
                return sink.whole(mgr);
            }
            mgr.reset()?;
            (WHOLE_SIGNAL_BLOCK, WHOLE_SIGNAL_BLOCK.max(prefix))
        }
    };
    let mut total = 0;
    loop {
        if mgr.cancel_token().is_cancelled() {
            return Err(Error::Interrupted.into());
        }
        let got = next(std::mem::replace(&mut first, block), &mut buf)?;
        if got == 0 {
            break;
        }
        if total == 0 && job.chunk.is_none() {
            // a first block that holds a long seeding time holds every node's output
            mgr.check_whole_signal(got)?;
        }
        total += got;
        let refs: Vec<&[f64]> = buf.iter().map(Vec::as_slice).collect();
        mgr.submit_chunk(&refs)?;
        if mgr.in_flight() >= mgr.pipeline_depth() {
            mgr.collect_chunk()?;
            sink.chunk(mgr)?;
        }
    }
    while mgr.in_flight() > 0 {
        mgr.collect_chunk()?;
        sink.chunk(mgr)?;
    }
    if total == 0 {
        return Err(empty().into());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    /// A whole signal through a graph that runs in blocks (drawn block by block into
    /// [`Manager::process_source`]) is recorded as one `process_signal` gives it, bit for
    /// bit, every intermediate signal included; with the AGC too.
    #[test]
    fn a_whole_signal_is_recorded_as_process_signal_gives_it() {
        let fs = 16000.0;
        let x: Vec<f64> = (0..20_000)
            .map(|t| (0.03 * t as f64).sin() * (1.0 + (t % 900) as f64 / 900.0))
            .collect();
        for agc in [false, true] {
            let mut params = ParamMap::new();
            if agc {
                params.insert("pp_bNormalizeRMS".into(), json!(1));
            }
            let job = Job {
                requests: vec!["ratemap".into(), "ild".into()],
                params: params.clone(),
                all: true,
                ..Job::default()
            };
            let rec = run(&job, fs, &[&x, &x]).expect("run");
            let mut mgr = Manager::new(fs, 2).expect("manager");
            mgr.set_keep_all(true);
            for r in &job.requests {
                mgr.add_request(r, &params).expect("request");
            }
            mgr.process_signal(&[&x, &x]).expect("process");
            let want = mgr.signals(true);
            assert_eq!(rec.signals().len(), want.len(), "agc {agc}");
            for (got, want) in rec.signals().iter().zip(&want) {
                assert_eq!(got.key, want.key());
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(
                    bits(got.data.as_slice()),
                    bits(want.new.as_slice()),
                    "agc {agc}: {}",
                    got.key
                );
            }
        }
    }

    /// A manager made for one ear, given two channels, says so, whether the input is fed
    /// in chunks or drawn whole.
    #[test]
    fn a_channel_count_the_manager_was_not_made_for_is_refused() {
        let x = vec![0.1; 5000];
        for chunk in [None, Some(1000)] {
            let job = Job {
                requests: vec!["ratemap".into()],
                chunk,
                ..Job::default()
            };
            let mut mgr = Manager::new(16000.0, 1).expect("manager");
            let e = run_with(&mut mgr, &job, &[&x, &x]).expect_err("two channels");
            assert!(
                e.to_string()
                    .contains("got 2 channel(s), but this manager was made for 1"),
                "{chunk:?}: {e}"
            );
        }
    }
}
