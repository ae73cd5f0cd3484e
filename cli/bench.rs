//! `afe bench`: the median wall time of repeated runs on a WAV file.

use std::path::{Path, PathBuf};
use std::time::Instant;

use afe::extract::{run_slices_into, run_with, Discard, Job};
use afe::host::Host;
use afe::output::OutputFile;
use afe::Manager;
use serde_json::json;

use crate::args::{Requests, Threads};
use crate::error::CliError;
use crate::extract::{check_trace_threads, TRACE_EVENTS};
use crate::files::{checked_output, read_input};
use crate::outln;

/// `afe bench IN.wav -r ... [--repeat K]`.
#[derive(clap::Args)]
pub(crate) struct BenchArgs {
    /// Input WAV file (mono or two-channel binaural).
    input: PathBuf,
    #[command(flatten)]
    requests: Requests,
    /// Feed the input in chunks of N samples (default: one call).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    chunk: Option<u64>,
    #[command(flatten)]
    threads: Threads,
    /// Number of timed runs (the median is reported, and the first: the runs after it
    /// reuse the memory it freed), at most 100000.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u64).range(1..=100_000))]
    repeat: u64,
    /// Drop each chunk's output once computed, as a live consumer would, instead of
    /// keeping the whole signal's output in memory as `afe extract` does: times the
    /// processing without the first writes to the output's memory.
    #[arg(long)]
    discard: bool,
    /// Print the result as one JSON object.
    #[arg(long)]
    json: bool,
    /// Write the scheduler's per-node, per-chunk timing of the last run as a Chrome
    /// trace (Perfetto), to see where the threads wait (recording adds a little to that
    /// run's time).
    #[arg(long, value_name = "trace.json")]
    trace: Option<PathBuf>,
}

impl BenchArgs {
    pub(crate) fn run(self) -> Result<(), CliError> {
        let job = self.requests.job(self.chunk, false, self.threads.count())?;
        check_trace_threads(self.trace.is_some(), job.threads)?;
        let trace = match &self.trace {
            Some(t) => Some(checked_output(t, &self.input)?),
            None => None,
        };
        bench(
            &self.input,
            &job,
            self.repeat as usize,
            self.discard,
            self.json,
            trace,
        )
    }
}

fn bench(
    input: &Path,
    job: &Job,
    repeat: usize,
    discard: bool,
    as_json: bool,
    trace: Option<OutputFile>,
) -> Result<(), CliError> {
    let audio = read_input(input)?;
    let mut events = None;
    let refs: Vec<&[f64]> = audio.channels.iter().map(Vec::as_slice).collect();
    let seconds = refs[0].len() as f64 / audio.fs;
    let mut times = Vec::with_capacity(repeat);
    let mut values = 0;
    for run in 0..repeat {
        // the last run records the trace (events preallocated per worker, as `afe
        // extract --trace`), the others nothing
        let traced = trace.is_some() && run + 1 == repeat;
        let capacity = if traced { TRACE_EVENTS } else { 0 };
        let mut mgr = Manager::with_engine(audio.fs, refs.len(), job.threads, capacity)?;
        for r in &job.requests {
            mgr.add_request(r, &job.params)?;
        }
        let added = Job {
            requests: Vec::new(),
            ..job.clone()
        };
        let start = Instant::now();
        if discard {
            let mut sink = Discard::default();
            run_slices_into(&mut mgr, &added, &refs, &mut sink)?;
            times.push(start.elapsed().as_secs_f64());
            values = sink.values();
        } else {
            let rec = run_with(&mut mgr, &added, &refs)?;
            times.push(start.elapsed().as_secs_f64());
            values = rec.signals().iter().map(|s| s.data.as_slice().len()).sum();
            std::hint::black_box(rec);
        }
        if traced {
            events = mgr.trace()?;
        }
    }
    let first = times[0];
    times.sort_by(f64::total_cmp);
    let median = times[times.len() / 2];
    let outputs = if discard { "discarded" } else { "kept" };
    let host = Host::detect();
    let result = json!({
        "input": input.display().to_string(),
        "requests": job.requests,
        "audio_seconds": seconds,
        "wall_seconds_median": median,
        "wall_seconds_min": times[0],
        "wall_seconds_first": first,
        "x_realtime": seconds / median,
        "threads": job.threads,
        "chunk": job.chunk,
        "repeat": repeat,
        "outputs": outputs,
        "output_values": values,
        "host": host,
    });
    if as_json {
        outln!("{result}");
    } else {
        outln!(
            "{:.3} s of audio in {:.4} s (median of {repeat}; first run {first:.4} s): {:.1}x real time, threads {}, chunk {}, {values} output values {outputs}; {}",
            seconds,
            median,
            seconds / median,
            job.threads,
            job.chunk.map_or("whole signal".to_string(), |c| format!("{c} samples")),
            host.describe()
        );
    }
    // after the figures, which a trace that cannot be written does not take with it
    if let (Some(t), Some(events)) = (&trace, events) {
        let staged = t.stage(|file| file.write_all(events.to_string().as_bytes()))?;
        afe::output::commit_all(vec![staged])?;
    }
    Ok(())
}
