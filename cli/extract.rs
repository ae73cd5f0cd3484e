//! `afe extract`: a WAV file's representations into an .npz.

use std::path::{Path, PathBuf};

use afe::extract::{run_wav, Job};
use afe::npy::Dtype;
use afe::Manager;

use crate::args::{Requests, Threads};
use crate::error::CliError;
use crate::files::{checked_output, open_input, report_saved};

/// `afe extract IN.wav -r ... -o OUT.npz`.
#[derive(clap::Args)]
pub(crate) struct ExtractArgs {
    /// Input WAV file (mono or two-channel binaural).
    input: PathBuf,
    #[command(flatten)]
    requests: Requests,
    /// Feed the input in chunks of N samples instead of one call.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    chunk: Option<u64>,
    /// Also save every intermediate signal (time, filterbank, innerhaircell, ...).
    #[arg(long)]
    all: bool,
    #[command(flatten)]
    threads: Threads,
    /// How the values are stored: f64 as computed, or f32 (each value rounded; half the
    /// memory and disk).
    #[arg(long, value_enum, default_value_t = StoredType::F64)]
    dtype: StoredType,
    /// Write the scheduler's per-node, per-chunk timing as a Chrome trace (Perfetto).
    #[arg(long, value_name = "trace.json")]
    trace: Option<PathBuf>,
    /// Output .npz file.
    #[arg(short = 'o', long = "output", value_name = "OUT.npz")]
    output: PathBuf,
}

impl ExtractArgs {
    pub(crate) fn run(self) -> Result<(), CliError> {
        let job = self
            .requests
            .job(self.chunk, self.all, self.threads.count())?;
        let dtype = self.dtype.into();
        extract(&self.input, job, dtype, self.trace.as_deref(), &self.output)
    }
}

/// The `--dtype` choices.
#[derive(Clone, Copy, clap::ValueEnum)]
pub(crate) enum StoredType {
    /// float64 (complex128), as computed.
    F64,
    /// float32 (complex64), rounded.
    F32,
}

impl From<StoredType> for Dtype {
    fn from(t: StoredType) -> Self {
        match t {
            StoredType::F64 => Dtype::Float64,
            StoredType::F32 => Dtype::Float32,
        }
    }
}

/// Trace events preallocated per worker (48 bytes each, one per node and chunk): 12 MiB,
/// 23 000 chunks of 11 nodes on one worker.
pub(crate) const TRACE_EVENTS: usize = 1 << 18;

/// Refuses `--trace` with the sequential executor (`--threads 0`), which records none.
pub(crate) fn check_trace_threads(traced: bool, threads: usize) -> Result<(), CliError> {
    if traced && threads == 0 {
        return Err("--trace records the concurrent scheduler: use --threads 1 or more".into());
    }
    Ok(())
}

fn extract(
    input: &Path,
    job: Job,
    dtype: Dtype,
    trace: Option<&Path>,
    output: &Path,
) -> Result<(), CliError> {
    check_trace_threads(trace.is_some(), job.threads)?;
    // every output is checked before the computation, so that none is found unwritable
    // after it (or written while another is not)
    let output = checked_output(output, input)?;
    let trace = match trace {
        Some(t) => {
            let t = checked_output(t, input)?;
            t.check_distinct(&output)?;
            Some(t)
        }
        None => None,
    };
    let mut wav = open_input(input)?;
    let capacity = if trace.is_some() { TRACE_EVENTS } else { 0 };
    let mut mgr = Manager::with_engine(wav.fs(), wav.channels(), job.threads, capacity)?;
    for r in &job.requests {
        mgr.add_request(r, &job.params)?;
    }
    // before the computation: outputs that would not fit the memory
    let bytes = afe::memory::output_bytes(&mut mgr, wav.frames(), job.all, dtype);
    if let Some(warning) = afe::memory::check(bytes)? {
        eprintln!("warning: {warning}");
    }
    let job = Job {
        requests: Vec::new(),
        ..job
    };
    let rec = run_wav(&mut mgr, &job, &mut wav).map_err(|e| match e {
        afe::Error::Interrupted => CliError::Message(format!("{e}: nothing was written")),
        e => e.into(),
    })?;
    let events = match &trace {
        Some(_) => Some(mgr.trace()?.unwrap_or_default()),
        None => None,
    };
    rec.check_dtype(dtype)?;
    // both outputs or neither: a trace that cannot be written leaves no .npz either
    let mut staged = vec![output.stage_unless_interrupted(|file| rec.write_npz_as(file, dtype))?];
    if let (Some(t), Some(events)) = (&trace, events) {
        staged.push(
            t.stage_unless_interrupted(|file| file.write_all(events.to_string().as_bytes()))?,
        );
    }
    afe::output::commit_all(staged)?;
    report_saved(&rec, &output);
    Ok(())
}
