//! The `afe` command line: list the representations, extract them from WAV files,
//! stream them from a live source.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use std::io::{IsTerminal, Write as _};
use std::time::{Duration, Instant};

use afe::bass_source::Pacing;
use afe::extract::{run_slices_into, run_wav, run_with, Discard, Job};
use afe::output::OutputFile;
use afe::stream::{SourceSpec, StreamJob, StreamReport};
use afe::wav::{Audio, WavBlocks};
use afe::{Manager, ParamMap};
use clap::{Parser, Subcommand};
use serde_json::{json, Value};

/// `println!` that ends quietly when stdout's reader went away (`afe ... | head`), where
/// `println!` would panic.
macro_rules! outln {
    ($($arg:tt)*) => {
        out(&format!("{}\n", format_args!($($arg)*)))
    };
}

/// Real-time binaural Auditory Front-End (the Two!Ears AFE representations).
#[derive(Parser)]
#[command(name = "afe", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// List every request with its parameters, defaults, units and meaning.
    List {
        /// A request (its whole processing chain, as the AFE's parameterHelper shows
        /// it) or one parameter (its processor, type, accepted values, default, unit).
        name: Option<String>,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Compute representations of a WAV file and save them as float64 arrays in an .npz.
    Extract {
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
        /// Write the scheduler's per-node, per-chunk timing as a Chrome trace (Perfetto).
        #[arg(long, value_name = "trace.json")]
        trace: Option<PathBuf>,
        /// Output .npz file.
        #[arg(short = 'o', long = "output", value_name = "OUT.npz")]
        output: PathBuf,
    },
    /// Measure processing speed on a WAV file: median wall time of K runs.
    Bench {
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
    },
    /// Draw representations of a WAV file: one panel per signal, axes in s and Hz, colour
    /// bars with units (PNG or SVG, by the output's extension).
    #[cfg(feature = "plot")]
    Plot {
        /// Input WAV file (mono or two-channel binaural).
        input: PathBuf,
        #[command(flatten)]
        requests: Requests,
        /// Time (s) at which correlations, modulation spectra and DUET histograms are
        /// drawn (default: the middle of the signal).
        #[arg(long, value_name = "S")]
        at: Option<f64>,
        /// Figure width in pixels.
        #[arg(long, default_value_t = 1000, value_parser = clap::value_parser!(u32).range(300..=10_000))]
        width: u32,
        /// Output figure, .png or .svg.
        #[arg(short = 'o', long = "output", value_name = "FIG.png")]
        output: PathBuf,
    },
    /// Compute representations of many WAV files into one store (Zarr v3, or one .npz per
    /// file): longest files first on every core, progress, failed files recorded and
    /// skipped, and a second run resumes where a killed one stopped.
    #[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
    Batch {
        #[command(subcommand)]
        status: Option<BatchCommand>,
        /// Folders (searched for .wav files), glob patterns, WAV files, or manifests
        /// (one `id<TAB>path` per line). A file's id is its path relative to its input.
        #[arg(required = true, value_name = "INPUT")]
        inputs: Vec<PathBuf>,
        #[command(flatten)]
        requests: Option<Requests>,
        /// The store: a folder, created if missing.
        #[arg(short = 'o', long = "output", value_name = "STORE", required = true)]
        store: Option<PathBuf>,
        #[command(flatten)]
        args: BatchArgs,
    },
    /// List the ALSA capture devices (needs a build with `--features alsa`).
    Devices,
    /// Run requests on a live stream (BASS port and block reader): WAV replay, a
    /// synthetic signal or ALSA capture; report compute time per block against its budget.
    Stream {
        /// wav:FILE, synth:SPEC (e.g. synth:fs=44100,tone=440,noise=0.1,itd_ms=0.4,
        /// ild_db=-6,seed=1; keys fs, tone, amp, noise, seed, itd_ms, ild_db, silence) or
        /// alsa:DEVICE (e.g. alsa:hw:1,0; see `afe devices`).
        #[arg(long, value_name = "wav:FILE|synth:SPEC|alsa:DEVICE")]
        source: String,
        #[command(flatten)]
        requests: Requests,
        /// Block fed to the graph per step, in ms (round(M·fs/1000) frames): the compute
        /// budget of each block.
        #[arg(long, value_name = "M", default_value_t = 10.0)]
        block_ms: f64,
        /// Stop after SECONDS of audio (required for synth and alsa sources, and with
        /// --loop; a wav file plays once by default).
        #[arg(long = "for", value_name = "SECONDS")]
        duration: Option<f64>,
        /// Publish the source at real time (default for synth and alsa).
        #[arg(long, conflicts_with = "fast")]
        realtime: bool,
        /// As fast as the graph computes (default for wav; with alsa, the device is read
        /// between blocks, in the processing thread).
        #[arg(long)]
        fast: bool,
        /// Replay a wav file from its start again after its end.
        #[arg(long = "loop")]
        looping: bool,
        /// Real-time scheduling (SCHED_FIFO) for the processing threads and locked
        /// memory; says what it could not get (it needs root, or CAP_SYS_NICE and
        /// CAP_IPC_LOCK). Real-time pacing only.
        #[arg(long)]
        rt: bool,
        /// ALSA capture rate in Hz (default 44100).
        #[arg(long, value_name = "HZ")]
        rate: Option<u32>,
        #[command(flatten)]
        threads: Threads,
        /// With -o: also save every intermediate signal.
        #[arg(long)]
        all: bool,
        /// Print the final report as one JSON object (and no status line).
        #[arg(long)]
        json: bool,
        /// Save what was computed, as `afe extract` does.
        #[arg(short = 'o', long = "output", value_name = "OUT.npz")]
        output: Option<PathBuf>,
        /// Serve the live web view of the stream on this address (e.g. 127.0.0.1:8080).
        #[cfg(feature = "view")]
        #[arg(long, value_name = "ADDR")]
        view: Option<std::net::SocketAddr>,
    },
    /// Subscribe to requests on an `afe serve` server over Zenoh and report what arrives:
    /// blocks, frames lost, and the latency from the server's port.
    #[cfg(feature = "remote")]
    Subscribe {
        /// Zenoh endpoint of the server.
        #[arg(long, value_name = "ENDPOINT", default_value = afe::remote::DEFAULT_LISTEN)]
        connect: String,
        /// The server's name, when several answer at the endpoint.
        #[arg(long, value_name = "NAME")]
        name: Option<String>,
        #[command(flatten)]
        requests: Requests,
        /// Stop after SECONDS of the server's audio (default: until the server goes or
        /// Ctrl-C).
        #[arg(long = "for", value_name = "SECONDS")]
        duration: Option<f64>,
        /// Print the report as one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Serve a live source at real time until stopped (Ctrl-C) or --for, to remote
    /// clients over Zenoh (--listen) and to the live web view on --http, which shows the
    /// representations as they are computed; pages can add and remove requests, change
    /// parameters and listen.
    #[cfg(feature = "view")]
    Serve {
        /// wav:FILE (replayed in a loop), synth:SPEC or alsa:DEVICE, as for `afe stream`.
        #[arg(long, value_name = "wav:FILE|synth:SPEC|alsa:DEVICE")]
        source: String,
        #[command(flatten)]
        requests: ServeRequests,
        /// Serve the live web view on this address, e.g. 127.0.0.1:8080 (keep it on
        /// loopback: the page can edit the graph, and it has no authentication).
        #[arg(long, value_name = "ADDR")]
        http: Option<std::net::SocketAddr>,
        /// Zenoh endpoint the server listens on for remote clients (repeatable); loopback
        /// unless told otherwise.
        #[cfg(feature = "remote")]
        #[arg(long, value_name = "ENDPOINT", default_value = afe::remote::DEFAULT_LISTEN)]
        listen: Vec<String>,
        /// The server's name: its Zenoh keys are afe/NAME/...
        #[cfg(feature = "remote")]
        #[arg(long, value_name = "NAME", default_value = afe::remote::DEFAULT_NAME)]
        name: String,
        /// A Zenoh configuration file (JSON5) to start from, e.g. with user-password
        /// authentication (transport/auth/usrpwd); --listen overrides its endpoints.
        #[cfg(feature = "remote")]
        #[arg(long, value_name = "FILE.json5")]
        zenoh_config: Option<PathBuf>,
        /// Block fed to the graph per step, in ms.
        #[arg(long, value_name = "M", default_value_t = 10.0)]
        block_ms: f64,
        /// Stop after SECONDS of audio (default: run until stopped).
        #[arg(long = "for", value_name = "SECONDS")]
        duration: Option<f64>,
        /// ALSA capture rate in Hz (default 44100).
        #[arg(long, value_name = "HZ")]
        rate: Option<u32>,
        #[command(flatten)]
        threads: Threads,
        /// Print the final report as one JSON object (and no status line).
        #[arg(long)]
        json: bool,
    },
}

/// Everything the CLI reports: each error as the crate that found it says it, or a
/// usage error of the command line itself.
#[derive(Debug, thiserror::Error)]
enum CliError {
    #[error(transparent)]
    Afe(#[from] afe::Error),
    #[error(transparent)]
    Batch(#[from] afe::batch::BatchError),
    #[error(transparent)]
    Stream(#[from] afe::stream::StreamError),
    #[error(transparent)]
    Output(#[from] afe::output::OutputError),
    #[error(transparent)]
    Wav(#[from] afe::wav::WavError),
    #[error(transparent)]
    Source(#[from] afe::bass_source::Error),
    #[cfg(feature = "view")]
    #[error(transparent)]
    View(#[from] afe::view::ViewError),
    #[cfg(feature = "plot")]
    #[error(transparent)]
    Plot(#[from] afe::plot::PlotError),
    #[cfg(feature = "remote")]
    #[error(transparent)]
    Remote(#[from] afe::remote::RemoteError),
    #[error("{0}")]
    Message(String),
}

impl From<String> for CliError {
    fn from(msg: String) -> Self {
        CliError::Message(msg)
    }
}

impl From<&str> for CliError {
    fn from(msg: &str) -> Self {
        CliError::Message(msg.to_string())
    }
}

/// `afe batch status STORE`.
#[derive(Subcommand)]
enum BatchCommand {
    /// Show what a store holds: its requests and parameters, files done and failed.
    Status {
        /// The store.
        store: PathBuf,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
}

/// The requests and their AFE parameters, shared by `extract`, `bench`, `stream` and `batch`.
#[derive(clap::Args)]
struct Requests {
    /// Requests, comma-separated (e.g. ratemap,ild,itd,ic).
    #[arg(
        short = 'r',
        long = "requests",
        value_name = "REQ,...",
        value_delimiter = ',',
        required = true
    )]
    names: Vec<String>,
    /// An AFE parameter, NAME=VALUE (VALUE is JSON, or a bare string). Repeatable.
    #[arg(short = 'p', long = "param", value_name = "NAME=VALUE")]
    params: Vec<String>,
    /// A JSON object of AFE parameter names to values (-p entries override it).
    #[arg(long = "params", value_name = "FILE.json")]
    params_file: Option<PathBuf>,
}

/// `afe serve`'s requests: optional, since remote clients subscribe to their own.
#[cfg(feature = "view")]
#[derive(clap::Args)]
struct ServeRequests {
    /// Requests computed from the start, comma-separated (clients add their own).
    #[arg(
        short = 'r',
        long = "requests",
        value_name = "REQ,...",
        value_delimiter = ','
    )]
    names: Vec<String>,
    /// An AFE parameter, NAME=VALUE (VALUE is JSON, or a bare string). Repeatable.
    #[arg(short = 'p', long = "param", value_name = "NAME=VALUE")]
    params: Vec<String>,
    /// A JSON object of AFE parameter names to values (-p entries override it).
    #[arg(long = "params", value_name = "FILE.json")]
    params_file: Option<PathBuf>,
}

#[cfg(feature = "view")]
impl ServeRequests {
    /// The request names (possibly none) and the merged parameters.
    fn load(self) -> Result<(Vec<String>, ParamMap), CliError> {
        let params = load_params(self.params_file.as_deref(), &self.params)?;
        Ok((clean(self.names), params))
    }
}

impl Requests {
    /// The request names (trimmed, empty ones dropped) and the merged parameters.
    fn load(self) -> Result<(Vec<String>, ParamMap), CliError> {
        let params = load_params(self.params_file.as_deref(), &self.params)?;
        let names = clean(self.names);
        if names.is_empty() {
            return Err("no request given: -r takes request names, e.g. -r ratemap,ild".into());
        }
        Ok((names, params))
    }
}

/// The executor choice shared by `extract`, `bench` and `stream`.
#[derive(clap::Args)]
struct Threads {
    /// Threads of the concurrent scheduler, the calling one among them (default: the
    /// number of cores; 0 = the sequential executor). Every choice gives the same numbers.
    #[arg(long, value_name = "N")]
    threads: Option<usize>,
}

impl Threads {
    fn count(&self) -> usize {
        self.threads.unwrap_or_else(|| {
            std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get)
        })
    }
}

fn main() -> ExitCode {
    // argument errors exit with 1 like every other error (clap's own code is 2); help
    // and version print to stdout and exit with 0
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            return if e.use_stderr() {
                ExitCode::FAILURE
            } else {
                ExitCode::SUCCESS
            };
        }
    };
    if let Command::Bench { .. } = cli.command {
        // the runs after the first reuse the memory of the outputs the one before freed,
        // instead of having the kernel zero it afresh; before any thread starts (the
        // interrupt handler's too), so that every thread shares the main heap
        afe_core::memory_reuse::keep_freed_memory();
    }
    install_interrupt_handler();
    let result = match cli.command {
        Command::List { name, json } => list(name.as_deref(), json),
        Command::Extract {
            input,
            requests,
            chunk,
            all,
            threads,
            trace,
            output,
        } => requests.load().and_then(|(requests, params)| {
            let job = Job {
                requests,
                params,
                chunk: chunk.map(|n| n as usize),
                all,
                threads: threads.count(),
            };
            extract(&input, job, trace.as_deref(), &output)
        }),
        #[cfg(feature = "plot")]
        Command::Plot {
            input,
            requests,
            at,
            width,
            output,
        } => requests.load().and_then(|(requests, params)| {
            let job = Job {
                requests,
                params,
                ..Job::default()
            };
            plot(&input, &job, at, width, &output)
        }),
        Command::Bench {
            input,
            requests,
            chunk,
            threads,
            repeat,
            discard,
            json,
        } => requests.load().and_then(|(requests, params)| {
            let job = Job {
                requests,
                params,
                chunk: chunk.map(|n| n as usize),
                all: false,
                threads: threads.count(),
            };
            bench(&input, &job, repeat as usize, discard, json)
        }),
        Command::Devices => devices(),
        Command::Batch {
            status: Some(BatchCommand::Status { store, json }),
            ..
        } => batch_status(&store, json),
        Command::Batch {
            status: None,
            inputs,
            requests,
            store,
            args,
        } => match (requests, store) {
            (Some(requests), Some(store)) => requests
                .load()
                .and_then(|(requests, params)| batch(&inputs, &store, requests, params, args)),
            _ => Err("afe batch needs -r REQ,... and -o STORE".into()),
        },
        Command::Stream {
            source,
            requests,
            block_ms,
            duration,
            realtime,
            fast,
            looping,
            rt,
            rate,
            threads,
            all,
            json,
            output,
            #[cfg(feature = "view")]
            view,
        } => requests.load().and_then(|(requests, params)| {
            let job = StreamJob {
                requests,
                params,
                block_ms,
                duration_s: duration,
                // --realtime, --fast, or the source's default: set in `stream`
                pacing: Pacing::Fast,
                // under --rt the sequential executor unless --threads says otherwise: at
                // 10-ms blocks it is faster (no hand-offs) and never waits on a wake-up
                threads: match (rt, threads.threads) {
                    (true, None) => 0,
                    _ => threads.count(),
                },
                record: output.is_some(),
                all,
                looping,
                alsa_rate: rate.unwrap_or(44_100),
                rt,
            };
            let pacing = match (realtime, fast) {
                (true, _) => Some(Pacing::Realtime),
                (_, true) => Some(Pacing::Fast),
                _ => None,
            };
            let run = StreamRun {
                source: &source,
                pacing,
                rate_given: rate.is_some(),
                as_json: json,
                output: output.as_deref(),
                #[cfg(feature = "view")]
                view,
                #[cfg(feature = "remote")]
                serve: None,
                endless: false,
            };
            stream(job, &run)
        }),
        #[cfg(feature = "remote")]
        Command::Subscribe {
            connect,
            name,
            requests,
            duration,
            json,
        } => requests.load().and_then(|(requests, params)| {
            subscribe(
                &connect,
                name.as_deref(),
                &requests,
                &params,
                duration,
                json,
            )
        }),
        #[cfg(feature = "view")]
        Command::Serve {
            source,
            requests,
            http,
            #[cfg(feature = "remote")]
            listen,
            #[cfg(feature = "remote")]
            name,
            #[cfg(feature = "remote")]
            zenoh_config,
            block_ms,
            duration,
            rate,
            threads,
            json,
        } => requests.load().and_then(|(requests, params)| {
            let job = StreamJob {
                requests,
                params,
                block_ms,
                duration_s: duration,
                pacing: Pacing::Realtime,
                // the sequential executor unless --threads says otherwise: at 10-ms blocks it
                // gives remote clients the lowest latency (no hand-offs between threads)
                threads: threads.threads.unwrap_or(0),
                looping: source.starts_with("wav:"),
                alsa_rate: rate.unwrap_or(44_100),
                ..StreamJob::default()
            };
            let run = StreamRun {
                source: &source,
                pacing: Some(Pacing::Realtime),
                rate_given: rate.is_some(),
                as_json: json,
                output: None,
                view: http,
                #[cfg(feature = "remote")]
                serve: Some(afe::remote::ServeOptions {
                    listen,
                    name,
                    config_file: zenoh_config,
                }),
                endless: true,
            };
            stream(job, &run)
        }),
    };
    // 130: the shells' code for a command stopped by SIGINT
    let interrupted = afe::interrupt::requested();
    match result {
        Ok(()) if interrupted => ExitCode::from(130),
        Ok(()) => ExitCode::SUCCESS,
        Err(msg) => {
            eprintln!("error: {msg}");
            ExitCode::from(if interrupted { 130 } else { 1 })
        }
    }
}

/// SIGINT, SIGTERM or SIGHUP: the first asks the running work to stop cleanly (see
/// `afe::interrupt`: no half-written output, a stream saves what it computed, a batch
/// keeps its finished files), a second one quits at once.
fn install_interrupt_handler() {
    let installed = ctrlc::set_handler(|| {
        if afe::interrupt::requested() {
            std::process::exit(130);
        }
        afe::interrupt::request();
        eprintln!("\ninterrupted: stopping cleanly (again to quit at once)");
    });
    if let Err(e) = installed {
        eprintln!("warning: no clean stop on Ctrl-C ({e})");
    }
}

fn list(name: Option<&str>, as_json: bool) -> Result<(), CliError> {
    let listing = afe::catalog::listing();
    let mut text = String::new();
    let mut entries = listing.as_array().cloned().unwrap_or_default();
    if let Some(name) = name {
        let by_name = |n: &str| entries.iter().find(|e| e["name"] == n).cloned();
        if let Some(request) = by_name(name) {
            // the request's chain, from the request down to the time-domain input
            entries = request["chain"]
                .as_array()
                .into_iter()
                .flatten()
                .filter_map(|n| n.as_str().and_then(by_name))
                .collect();
        } else {
            let found = entries.iter().find_map(|e| {
                e["parameters"]
                    .as_array()?
                    .iter()
                    .find(|p| p["name"] == name)
                    .map(|p| (e["name"].clone(), p.clone()))
            });
            let Some((processor, mut p)) = found else {
                return Err(format!(
                    "'{name}' is neither a request nor a parameter: `afe list` shows them all"
                )
                .into());
            };
            p["processor"] = processor;
            if as_json {
                out(&format!("{p}\n"));
            } else {
                for key in [
                    "name",
                    "processor",
                    "type",
                    "accepts",
                    "default",
                    "unit",
                    "description",
                ] {
                    let v = match &p[key] {
                        Value::String(s) => s.clone(),
                        Value::Null => "[]".into(),
                        v => v.to_string(),
                    };
                    text.push_str(&format!("{key:<12} {v}\n"));
                }
            }
            out(&text);
            return Ok(());
        }
    }
    if as_json {
        out(&format!("{}\n", Value::Array(entries)));
        return Ok(());
    }
    for e in &entries {
        text.push_str(&format!(
            "{}  ({}; from {})\n    {}\n",
            e["name"].as_str().unwrap_or_default(),
            if e["binaural"] == json!(true) {
                "binaural"
            } else {
                "per ear"
            },
            e["depends_on"].as_str().unwrap_or_default(),
            e["description"].as_str().unwrap_or_default()
        ));
        for p in e["parameters"].as_array().into_iter().flatten() {
            let default = match &p["default"] {
                Value::Null => "[]".to_string(),
                v => v.to_string(),
            };
            let unit = p["unit"].as_str().unwrap_or_default();
            text.push_str(&format!(
                "    {:<24} {:<10} {:<7} {}\n",
                p["name"].as_str().unwrap_or_default(),
                default,
                if unit.is_empty() { "-" } else { unit },
                p["description"].as_str().unwrap_or_default()
            ));
        }
        text.push('\n');
    }
    out(&text);
    Ok(())
}

/// Prints `text` to stdout; a reader that went away (`afe list | head`) ends it quietly.
fn out(text: &str) {
    let mut stdout = std::io::stdout().lock();
    let _ = stdout
        .write_all(text.as_bytes())
        .and_then(|()| stdout.flush());
}

/// Parses `NAME=VALUE`: VALUE as JSON when it is JSON, else as a plain string.
fn parse_param(arg: &str) -> Result<(String, Value), CliError> {
    let (name, value) = arg
        .split_once('=')
        .ok_or_else(|| format!("parameter '{arg}' is not of the form NAME=VALUE"))?;
    if value.trim().is_empty() {
        return Err(format!(
            "parameter '{arg}' has no value: give NAME=VALUE (leave the parameter out for \
             its default)"
        )
        .into());
    }
    let value = serde_json::from_str(value).unwrap_or_else(|_| Value::String(value.to_string()));
    Ok((name.trim().to_string(), value))
}

fn load_params(file: Option<&Path>, args: &[String]) -> Result<ParamMap, CliError> {
    let mut map = ParamMap::new();
    if let Some(path) = file {
        let text = std::fs::read_to_string(path)
            .map_err(|e| format!("cannot read parameter file '{}': {e}", path.display()))?;
        match serde_json::from_str::<Value>(&text) {
            Ok(Value::Object(obj)) => map.extend(obj),
            Ok(_) => {
                return Err(format!(
                    "parameter file '{}' must hold a JSON object of AFE parameter names to values",
                    path.display()
                )
                .into())
            }
            Err(e) => {
                return Err(
                    format!("parameter file '{}' is not valid JSON: {e}", path.display()).into(),
                )
            }
        }
    }
    for a in args {
        let (k, v) = parse_param(a)?;
        map.insert(k, v);
    }
    Ok(map)
}

fn clean(requests: Vec<String>) -> Vec<String> {
    requests
        .iter()
        .map(|r| r.trim().to_string())
        .filter(|r| !r.is_empty())
        .collect()
}

/// Opens a WAV file that afe can process: mono or two channels, not empty.
fn open_input(input: &Path) -> Result<WavBlocks, CliError> {
    Ok(afe::wav::open_input(input)?)
}

/// Reads a whole WAV file that afe can process.
fn read_input(input: &Path) -> Result<Audio, CliError> {
    Ok(open_input(input)?.read_all()?)
}

fn extract(input: &Path, job: Job, trace: Option<&Path>, output: &Path) -> Result<(), CliError> {
    if trace.is_some() && job.threads == 0 {
        return Err("--trace records the concurrent scheduler: use --threads 1 or more".into());
    }
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
    // trace events preallocated per worker (48 bytes each): 12 MiB, ~5000 chunks of 11 nodes
    let capacity = if trace.is_some() { 1 << 18 } else { 0 };
    let mut mgr = Manager::with_engine(wav.fs(), wav.channels(), job.threads, capacity)?;
    let rec = run_wav(&mut mgr, &job, &mut wav).map_err(|e| match e {
        afe::Error::Interrupted => CliError::Message(format!("{e}: nothing was written")),
        e => e.into(),
    })?;
    let events = match &trace {
        Some(_) => Some(mgr.trace()?.unwrap_or_default()),
        None => None,
    };
    save(&rec, &output)?;
    if let (Some(t), Some(events)) = (trace, events) {
        t.write(|file| file.write_all(events.to_string().as_bytes()))?;
    }
    Ok(())
}

/// Checks `path` as an output of a run reading `input` (see [`OutputFile::check`]).
fn checked_output(path: &Path, input: &Path) -> Result<OutputFile, CliError> {
    let out = OutputFile::check(path)?;
    out.check_not_input(input)?;
    Ok(out)
}

/// Saves every recorded signal as a float64 array `<request>_<ear>` in an .npz, with
/// their descriptions in its `afe_metadata` entry.
fn save(rec: &afe::Recorder, output: &OutputFile) -> Result<(), CliError> {
    output.write(|file| rec.write_npz(file))?;
    eprintln!(
        "wrote {} array(s) to {}: {}",
        rec.signals().len(),
        output.path().display(),
        rec.signals()
            .iter()
            .map(|s| format!("{} {:?}", s.key, s.shape()))
            .collect::<Vec<_>>()
            .join(", ")
    );
    Ok(())
}

/// The options of `afe batch` as given.
#[derive(clap::Args)]
struct BatchArgs {
    /// Files computed at once (default: the number of cores).
    #[arg(short = 'j', long = "jobs", value_name = "N", value_parser = clap::value_parser!(u64).range(1..=1024))]
    jobs: Option<u64>,
    /// Compute only shard I of N (0-based), chosen by a hash of the file ids, so N
    /// independent jobs fill one store together.
    #[arg(long, value_name = "I/N")]
    shard: Option<String>,
    /// What a file that fails does: recorded and skipped, or stops the run.
    #[arg(long, value_name = "skip|stop", default_value = "skip")]
    on_error: String,
    /// Progress display: a bar on stderr, JSON lines on stdout, or none.
    #[arg(long, value_name = "bar|jsonl|none", default_value = "bar")]
    progress: String,
    /// Store layout: Zarr v3, or one .npz per file (as `afe extract` writes it).
    #[arg(long, value_name = "zarr|npz", default_value = "zarr")]
    format: String,
    /// Replace the contents of a store made with other requests or parameters.
    #[arg(long)]
    overwrite: bool,
}

fn batch(
    inputs: &[PathBuf],
    store: &Path,
    requests: Vec<String>,
    params: ParamMap,
    args: BatchArgs,
) -> Result<(), CliError> {
    use afe::batch::{run, BatchOptions, StoreSpec};
    let shard = match args.shard.as_deref() {
        None => None,
        Some(text) => Some(
            text.split_once('/')
                .and_then(|(i, n)| Some((i.trim().parse().ok()?, n.trim().parse().ok()?)))
                .ok_or_else(|| format!("--shard '{text}': give I/N, e.g. 0/4"))?,
        ),
    };
    let spec = StoreSpec {
        requests,
        params,
        format: args.format.parse()?,
    };
    let options = BatchOptions {
        workers: args.jobs.map_or(0, |j| j as usize),
        shard,
        on_error: args.on_error.parse()?,
        progress: args.progress.parse()?,
        overwrite: args.overwrite,
    };
    let summary = run(inputs, store, &spec, &options)?;
    if options.progress == afe::batch::ProgressMode::None {
        eprintln!("{}", summary.text());
    }
    // with --on-error skip, failed files are an outcome (listed, recorded), not an error
    Ok(())
}

fn batch_status(store: &Path, as_json: bool) -> Result<(), CliError> {
    use afe::batch::Status;
    let (spec, records) = afe::batch::status(store)?;
    let done: Vec<_> = records
        .iter()
        .filter(|r| r.status == Status::Done)
        .collect();
    let failed: Vec<_> = records
        .iter()
        .filter(|r| r.status == Status::Failed)
        .collect();
    let audio_s: f64 = done.iter().map(|r| r.audio_s).sum();
    if as_json {
        let v = json!({
            "store": store.to_string_lossy(),
            "format": spec.format.as_str(),
            "requests": spec.requests,
            "params": spec.params,
            "param_hash": spec.param_hash(),
            "done": done.len(),
            "audio_s": audio_s,
            "failed": failed.iter().map(|r| r.to_json()).collect::<Vec<_>>(),
        });
        outln!("{v}");
        return Ok(());
    }
    outln!(
        "{}: {} store of {} with {} (hash {})",
        store.display(),
        spec.format.as_str(),
        spec.requests.join(","),
        serde_json::to_string(&spec.params).unwrap_or_default(),
        spec.param_hash()
    );
    outln!(
        "{} file(s) done ({:.2} h of audio), {} failed",
        done.len(),
        audio_s / 3600.0,
        failed.len()
    );
    for r in failed {
        outln!(
            "  failed: {} ({}): {}",
            r.id,
            r.path.display(),
            r.error.as_deref().unwrap_or("")
        );
    }
    Ok(())
}

#[cfg(feature = "plot")]
fn plot(
    input: &Path,
    job: &Job,
    at: Option<f64>,
    width: u32,
    output: &Path,
) -> Result<(), CliError> {
    let format = afe::plot::Format::of(output)?;
    let output = checked_output(output, input)?;
    let mut wav = open_input(input)?;
    let mut mgr = Manager::new(wav.fs(), wav.channels())?;
    let rec = run_wav(&mut mgr, job, &mut wav)?;
    let layout = afe::plot::Layout {
        width,
        at_s: at,
        ..afe::plot::Layout::default()
    };
    let figure = afe::plot::render(&rec, format, &layout)?;
    output.write(|file| file.write_all(&figure))?;
    outln!(
        "drew {} panel(s) to {}",
        rec.signals().len(),
        output.path().display()
    );
    Ok(())
}

fn bench(
    input: &Path,
    job: &Job,
    repeat: usize,
    discard: bool,
    as_json: bool,
) -> Result<(), CliError> {
    let audio = read_input(input)?;
    let refs: Vec<&[f64]> = audio.channels.iter().map(Vec::as_slice).collect();
    let seconds = refs[0].len() as f64 / audio.fs;
    let mut times = Vec::with_capacity(repeat);
    let mut values = 0;
    for _ in 0..repeat {
        let mut mgr = Manager::with_threads(audio.fs, refs.len(), job.threads)?;
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
    }
    let first = times[0];
    times.sort_by(f64::total_cmp);
    let median = times[times.len() / 2];
    let outputs = if discard { "discarded" } else { "kept" };
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
    });
    if as_json {
        outln!("{result}");
    } else {
        outln!(
            "{:.3} s of audio in {:.4} s (median of {repeat}; first run {first:.4} s): {:.1}x real time, threads {}, chunk {}, {values} output values {outputs}",
            seconds,
            median,
            seconds / median,
            job.threads,
            job.chunk.map_or("whole signal".to_string(), |c| format!("{c} samples"))
        );
    }
    Ok(())
}

#[cfg(feature = "alsa")]
fn devices() -> Result<(), CliError> {
    let list = afe::bass_source::list_devices()?;
    if list.is_empty() {
        outln!("no ALSA capture device found");
    }
    for d in list {
        outln!("{:<24} {}", d.name, d.description);
    }
    Ok(())
}

#[cfg(not(feature = "alsa"))]
fn devices() -> Result<(), CliError> {
    Err(afe::stream::ALSA_OFF.into())
}

/// `afe subscribe`: receives a subscription's blocks until `duration_s` of audio, the
/// server's departure or Ctrl-C, and prints the tally.
#[cfg(feature = "remote")]
fn subscribe(
    endpoint: &str,
    name: Option<&str>,
    requests: &[String],
    params: &ParamMap,
    duration_s: Option<f64>,
    as_json: bool,
) -> Result<(), CliError> {
    let client = afe::remote::Client::connect(endpoint, name)?;
    let list: Vec<(&str, ParamMap)> = requests
        .iter()
        .map(|r| (r.as_str(), params.clone()))
        .collect();
    let mut sub = client.subscribe(&list)?;
    if !as_json {
        eprintln!(
            "subscribed to '{}': {}",
            client.name(),
            sub.keys().join(", ")
        );
    }
    let limit = duration_s.map(|d| (d * client.fs()).round() as u64);
    let mut tally = afe::remote::Tally::default();
    while !afe::interrupt::requested() && limit.is_none_or(|l| tally.input_frames() < l) {
        match sub.recv(std::time::Duration::from_millis(200)) {
            Ok(Some(frames)) => tally.add(&frames),
            Ok(None) => {}
            Err(afe::remote::RemoteError::ServerGone(_)) => break,
            Err(e) => return Err(e.into()),
        }
    }
    let report = tally.report(&sub);
    if as_json {
        outln!("{report}");
    } else {
        outln!(
            "{} blocks ({:.2} s), {} lost; latency from the server's port p50 {:.3} ms, p99 {:.3} ms, max {:.3} ms",
            report["messages"],
            tally.input_frames() as f64 / client.fs(),
            report["lost_messages"],
            report["latency_ms_p50"].as_f64().unwrap_or(0.0),
            report["latency_ms_p99"].as_f64().unwrap_or(0.0),
            report["latency_ms_max"].as_f64().unwrap_or(0.0),
        );
    }
    Ok(())
}

/// How `afe stream` and `afe serve` run a stream, beyond its job.
struct StreamRun<'a> {
    source: &'a str,
    /// `--realtime` or `--fast` if given.
    pacing: Option<Pacing>,
    rate_given: bool,
    as_json: bool,
    output: Option<&'a Path>,
    /// Serve the live view on this address.
    #[cfg(feature = "view")]
    view: Option<std::net::SocketAddr>,
    /// Serve the stream to remote clients over Zenoh.
    #[cfg(feature = "remote")]
    serve: Option<afe::remote::ServeOptions>,
    /// Runs until stopped (`afe serve`): no `--for` needed.
    endless: bool,
}

/// What sees each block of a CLI stream: the status line, and the live view's tap.
struct CliObserver<'a> {
    status: &'a mut Status,
    #[cfg(feature = "view")]
    tap: Option<afe::view::Tap>,
    #[cfg(feature = "remote")]
    remote: Option<afe::remote::ServeTap>,
}

impl afe::stream::Observer for CliObserver<'_> {
    fn block(&mut self, timing: &afe::stream::Timing, mgr: &mut Manager, input: &[Vec<f64>]) {
        self.status.update(timing);
        #[cfg(feature = "view")]
        if let Some(tap) = &mut self.tap {
            tap.block(timing, mgr, input);
        }
        #[cfg(feature = "remote")]
        if let Some(tap) = &mut self.remote {
            tap.block(timing, mgr, input);
        }
        #[cfg(not(feature = "view"))]
        let _ = (mgr, input);
    }
}

fn stream(mut job: StreamJob, run: &StreamRun<'_>) -> Result<(), CliError> {
    let source = run.source;
    let (pacing, rate_given, as_json, output) =
        (run.pacing, run.rate_given, run.as_json, run.output);
    let spec: SourceSpec = source.parse()?;
    match &spec {
        SourceSpec::Wav(_) if job.looping && job.duration_s.is_none() && !run.endless => {
            return Err("--loop replays the file forever: give --for SECONDS".into())
        }
        SourceSpec::Synth(_) | SourceSpec::Alsa(_) if job.duration_s.is_none() && !run.endless => {
            return Err(format!("'{source}' never ends: give --for SECONDS").into())
        }
        SourceSpec::Synth(_) | SourceSpec::Alsa(_) | SourceSpec::Zenoh { .. } if job.looping => {
            return Err("--loop replays wav files only".into())
        }
        SourceSpec::Wav(_) | SourceSpec::Synth(_) | SourceSpec::Zenoh { .. } if rate_given => {
            return Err(
                "--rate sets the ALSA capture rate (synth: fs= in the spec; wav: the file's rate; zenoh: the server's)"
                    .into(),
            )
        }
        _ => {}
    }
    let output = match (output, &spec) {
        (Some(o), SourceSpec::Wav(input)) => Some(checked_output(o, input)?),
        (Some(o), _) => Some(OutputFile::check(o)?),
        (None, _) => None,
    };
    job.pacing = pacing.unwrap_or_else(|| spec.default_pacing());
    #[cfg(feature = "view")]
    let (view, tap) = match run.view {
        Some(addr) => {
            let (view, tap) = afe::view::View::start(addr, job.block_ms)?;
            if !addr.ip().is_loopback() {
                eprintln!(
                    "warning: the live view on {addr} is open to the network, without \
                     authentication: anyone reaching it can edit the graph"
                );
            }
            eprintln!("live view: http://{}/", view.addr());
            (Some(view), Some(tap))
        }
        None => (None, None),
    };
    #[cfg(feature = "remote")]
    let (server, remote) = match &run.serve {
        Some(options) => {
            let (server, tap) = afe::remote::Server::start(options)?;
            for endpoint in options
                .listen
                .iter()
                .filter(|e| !afe::remote::is_loopback(e))
            {
                if !server.authenticated() {
                    eprintln!(
                        "warning: Zenoh listens on {endpoint}, open to the network, without \
                         authentication: anyone reaching it can subscribe (give --zenoh-config \
                         with transport/auth/usrpwd)"
                    );
                }
            }
            eprintln!(
                "zenoh: '{}' on {}",
                server.name(),
                options.listen.join(", ")
            );
            (Some(server), Some(tap))
        }
        None => (None, None),
    };
    let mut status = Status::new(!as_json && std::io::stderr().is_terminal());
    let observer = CliObserver {
        status: &mut status,
        #[cfg(feature = "view")]
        tap,
        #[cfg(feature = "remote")]
        remote,
    };
    // the tap goes with the observer at the end of the stream: pages are told
    let out = afe::stream::run_spec(&spec, &job, observer)?;
    status.finish();
    #[cfg(feature = "view")]
    drop(view);
    #[cfg(feature = "remote")]
    drop(server);
    if let Some(path) = &output {
        save(&out.recorded, path)?;
    }
    let r = &out.report;
    if let Some(rt) = &r.realtime {
        if rt.complete() {
            eprintln!("real time: {}", rt.describe());
        } else {
            eprintln!("warning: --rt: {}", rt.describe());
        }
    }
    if as_json {
        let mut result = serde_json::to_value(r).map_err(|e| e.to_string())?;
        let extra = json!({
            "source": source,
            "requests": job.requests,
            "pacing": if job.pacing == Pacing::Realtime { "realtime" } else { "fast" },
            "threads": job.threads,
            "seconds": r.frames as f64 / r.fs,
            "rt": r.realtime.as_ref().map(afe::realtime::Realtime::describe),
            "rt_complete": r.realtime.as_ref().map(afe::realtime::Realtime::complete),
        });
        if let (Some(all), Value::Object(extra)) = (result.as_object_mut(), extra) {
            all.extend(extra);
        }
        outln!("{result}");
    } else {
        outln!(
            "{} frames ({:.2} s at {} Hz) in {} blocks of {} frames: compute per block p50 {:.3} ms, \
             p99 {:.3} ms, max {:.3} ms (block {}), budget {:.2} ms ({:.1}x real time); \
             {} deadline miss(es){}; {} frame(s) lost{}{}",
            r.frames,
            r.frames as f64 / r.fs,
            r.fs,
            r.blocks,
            r.block_frames,
            r.compute_ms_p50,
            r.compute_ms_p99,
            r.compute_ms_max,
            r.slowest_block,
            r.budget_ms,
            r.x_realtime,
            r.deadline_misses,
            match r.missed_blocks.as_slice() {
                [] => String::new(),
                m => format!(
                    " (blocks {}{})",
                    m.iter().map(u64::to_string).collect::<Vec<_>>().join(", "),
                    if r.deadline_misses > m.len() as u64 { ", ..." } else { "" }
                ),
            },
            r.lost_frames,
            if r.device_overruns > 0 {
                format!("; {} device overrun(s)", r.device_overruns)
            } else {
                String::new()
            },
            if r.interrupted {
                "; interrupted: what was computed until then is reported (and saved with -o)"
            } else {
                ""
            }
        );
    }
    Ok(())
}

/// The status line of `afe stream` on a terminal: rewritten in place at most 4 times a
/// second.
struct Status {
    shown: bool,
    enabled: bool,
    last: Option<Instant>,
}

impl Status {
    const PERIOD: Duration = Duration::from_millis(250);

    fn new(enabled: bool) -> Self {
        Status {
            shown: false,
            enabled,
            last: None,
        }
    }

    fn update(&mut self, timing: &afe::stream::Timing) {
        if !self.enabled || self.last.is_some_and(|t| t.elapsed() < Self::PERIOD) {
            return;
        }
        self.last = Some(Instant::now());
        self.shown = true;
        eprint!("\r{}\x1b[K", status_line(&timing.report()));
    }

    fn finish(&self) {
        if self.shown {
            eprintln!();
        }
    }
}

fn status_line(r: &StreamReport) -> String {
    format!(
        "{} frames ({:.1} s) | {:.1}x real time | compute p50 {:.2} ms p99 {:.2} ms / {:.2} ms | misses {} | lost {}",
        r.frames,
        r.frames as f64 / r.fs,
        r.x_realtime,
        r.compute_ms_p50,
        r.compute_ms_p99,
        r.budget_ms,
        r.deadline_misses,
        r.lost_frames
    )
}
