//! The `afe` command line: list the representations, extract them from WAV files.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use std::time::Instant;

use afe::extract::{run_with, Job};
use afe::wav::{read_wav, Audio};
use afe::{requests, Manager, ParamMap};
use clap::{Parser, Subcommand};
use serde_json::{json, Value};

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
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Compute representations of a WAV file and save them as float64 arrays in an .npz.
    Extract {
        /// Input WAV file (mono or two-channel binaural).
        input: PathBuf,
        /// Requests, comma-separated (e.g. ratemap,ild,itd,ic).
        #[arg(short = 'r', long = "requests", value_delimiter = ',', required = true)]
        requests: Vec<String>,
        /// An AFE parameter, NAME=VALUE (VALUE is JSON, or a bare string). Repeatable.
        #[arg(short = 'p', long = "param", value_name = "NAME=VALUE")]
        params: Vec<String>,
        /// A JSON object of AFE parameter names to values (-p entries override it).
        #[arg(long = "params", value_name = "FILE.json")]
        params_file: Option<PathBuf>,
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
        /// Requests, comma-separated.
        #[arg(short = 'r', long = "requests", value_delimiter = ',', required = true)]
        requests: Vec<String>,
        /// An AFE parameter, NAME=VALUE. Repeatable.
        #[arg(short = 'p', long = "param", value_name = "NAME=VALUE")]
        params: Vec<String>,
        /// A JSON object of AFE parameter names to values.
        #[arg(long = "params", value_name = "FILE.json")]
        params_file: Option<PathBuf>,
        /// Feed the input in chunks of N samples (default: one call).
        #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
        chunk: Option<u64>,
        #[command(flatten)]
        threads: Threads,
        /// Number of timed runs (the median is reported).
        #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u64).range(1..))]
        repeat: u64,
        /// Print the result as one JSON object.
        #[arg(long)]
        json: bool,
    },
}

/// The executor choice shared by `extract` and `bench`.
#[derive(clap::Args)]
struct Threads {
    /// Worker threads of the concurrent scheduler (default: the number of cores;
    /// 0 = the sequential executor). Every choice gives the same numbers.
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
    let cli = Cli::parse();
    let result = match cli.command {
        Command::List { json } => {
            list(json);
            Ok(())
        }
        Command::Extract {
            input,
            requests,
            params,
            params_file,
            chunk,
            all,
            threads,
            trace,
            output,
        } => load_params(params_file.as_deref(), &params).and_then(|p| {
            let job = Job {
                requests: clean(requests),
                params: p,
                chunk: chunk.map(|n| n as usize),
                all,
                threads: threads.count(),
            };
            extract(&input, job, trace.as_deref(), &output)
        }),
        Command::Bench {
            input,
            requests,
            params,
            params_file,
            chunk,
            threads,
            repeat,
            json,
        } => load_params(params_file.as_deref(), &params).and_then(|p| {
            let job = Job {
                requests: clean(requests),
                params: p,
                chunk: chunk.map(|n| n as usize),
                all: false,
                threads: threads.count(),
            };
            bench(&input, &job, repeat as usize, json)
        }),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(msg) => {
            eprintln!("error: {msg}");
            ExitCode::FAILURE
        }
    }
}

/// The chain of request names from `name` down to `time`.
fn chain(name: &str) -> Vec<&'static str> {
    let mut out = Vec::new();
    let mut cur = afe::find_request(name).ok();
    while let Some(def) = cur {
        out.push(def.name);
        cur = afe::find_request(def.dependency).ok();
    }
    out
}

fn list(as_json: bool) {
    let entries: Vec<Value> = requests()
        .iter()
        .map(|r| {
            let defaults = (r.defaults)();
            let params: Vec<Value> = r
                .params
                .iter()
                .map(|p| {
                    json!({
                        "name": p.name,
                        "type": p.kind.type_name(),
                        "accepts": p.kind.describe(),
                        "default": defaults.get(p.name).cloned().unwrap_or(Value::Null),
                        "unit": p.unit,
                        "description": p.description,
                    })
                })
                .collect();
            json!({
                "name": r.name,
                "depends_on": r.dependency,
                "chain": chain(r.name),
                "binaural": r.ears == afe_processors::Ears::Binaural,
                "description": r.description,
                "unit": r.output_unit,
                "parameters": params,
            })
        })
        .collect();
    if as_json {
        println!("{}", Value::Array(entries));
        return;
    }
    for e in &entries {
        println!(
            "{}  ({}; from {})\n    {}",
            e["name"].as_str().unwrap_or_default(),
            if e["binaural"] == json!(true) {
                "binaural"
            } else {
                "per ear"
            },
            e["depends_on"].as_str().unwrap_or_default(),
            e["description"].as_str().unwrap_or_default()
        );
        for p in e["parameters"].as_array().into_iter().flatten() {
            let default = match &p["default"] {
                Value::Null => "[]".to_string(),
                v => v.to_string(),
            };
            let unit = p["unit"].as_str().unwrap_or_default();
            println!(
                "    {:<24} {:<10} {:<7} {}",
                p["name"].as_str().unwrap_or_default(),
                default,
                if unit.is_empty() { "-" } else { unit },
                p["description"].as_str().unwrap_or_default()
            );
        }
        println!();
    }
}

/// Parses `NAME=VALUE`: VALUE as JSON when it is JSON, else as a plain string.
fn parse_param(arg: &str) -> Result<(String, Value), String> {
    let (name, value) = arg
        .split_once('=')
        .ok_or_else(|| format!("parameter '{arg}' is not of the form NAME=VALUE"))?;
    let value = serde_json::from_str(value).unwrap_or_else(|_| Value::String(value.to_string()));
    Ok((name.trim().to_string(), value))
}

fn load_params(file: Option<&Path>, args: &[String]) -> Result<ParamMap, String> {
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
                ))
            }
            Err(e) => {
                return Err(format!(
                    "parameter file '{}' is not valid JSON: {e}",
                    path.display()
                ))
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

/// Reads a WAV file that afe can process: mono or two channels, not empty.
fn read_input(input: &Path) -> Result<Audio, String> {
    let audio = read_wav(input).map_err(|e| e.to_string())?;
    if audio.channels.len() > 2 {
        return Err(format!(
            "'{}' has {} channels: afe takes mono or two-channel (left, right) input",
            input.display(),
            audio.channels.len()
        ));
    }
    if audio.channels[0].is_empty() {
        return Err(format!("'{}' holds no samples", input.display()));
    }
    Ok(audio)
}

fn extract(input: &Path, job: Job, trace: Option<&Path>, output: &Path) -> Result<(), String> {
    if trace.is_some() && job.threads == 0 {
        return Err("--trace records the concurrent scheduler: use --threads 1 or more".into());
    }
    let audio = read_input(input)?;
    let refs: Vec<&[f64]> = audio.channels.iter().map(Vec::as_slice).collect();
    let capacity = if trace.is_some() { 1 << 20 } else { 0 };
    let mut mgr = Manager::with_engine(audio.fs, refs.len(), job.threads, capacity)
        .map_err(|e| e.to_string())?;
    let rec = run_with(&mut mgr, &job, &refs).map_err(|e| e.to_string())?;
    let arrays: Vec<(String, Vec<usize>, &[f64])> = rec
        .signals()
        .iter()
        .map(|s| (s.key.clone(), s.shape(), s.data.as_slice()))
        .collect();
    write_atomically(output, |file| afe::npy::write_npz(file, &arrays))?;
    if let Some(path) = trace {
        let t = mgr.trace().map_err(|e| e.to_string())?.unwrap_or_default();
        write_atomically(path, |mut file| {
            std::io::Write::write_all(&mut file, t.to_string().as_bytes())
        })?;
    }
    eprintln!(
        "wrote {} array(s) to {}: {}",
        arrays.len(),
        output.display(),
        arrays
            .iter()
            .map(|(k, s, _)| format!("{k} {s:?}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    Ok(())
}

/// Writes `path` through a temporary file renamed into place, so that a failure leaves
/// no partial output.
fn write_atomically(
    path: &Path,
    write: impl FnOnce(std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<(), String> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".partial");
    let tmp = PathBuf::from(tmp);
    let result = std::fs::File::create(&tmp)
        .and_then(|f| write(std::io::BufWriter::new(f)))
        .and_then(|()| std::fs::rename(&tmp, path));
    result.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        format!("cannot write '{}': {e}", path.display())
    })
}

fn bench(input: &Path, job: &Job, repeat: usize, as_json: bool) -> Result<(), String> {
    let audio = read_input(input)?;
    let refs: Vec<&[f64]> = audio.channels.iter().map(Vec::as_slice).collect();
    let seconds = refs[0].len() as f64 / audio.fs;
    let mut times = Vec::with_capacity(repeat);
    for _ in 0..repeat {
        let mut mgr =
            Manager::with_threads(audio.fs, refs.len(), job.threads).map_err(|e| e.to_string())?;
        for r in &job.requests {
            mgr.add_request(r, &job.params).map_err(|e| e.to_string())?;
        }
        let start = Instant::now();
        let rec = run_with(
            &mut mgr,
            &Job {
                requests: Vec::new(),
                ..job.clone()
            },
            &refs,
        )
        .map_err(|e| e.to_string())?;
        times.push(start.elapsed().as_secs_f64());
        std::hint::black_box(rec);
    }
    times.sort_by(f64::total_cmp);
    let median = times[times.len() / 2];
    let result = json!({
        "input": input.display().to_string(),
        "requests": job.requests,
        "audio_seconds": seconds,
        "wall_seconds_median": median,
        "wall_seconds_min": times[0],
        "x_realtime": seconds / median,
        "threads": job.threads,
        "chunk": job.chunk,
        "repeat": repeat,
    });
    if as_json {
        println!("{result}");
    } else {
        println!(
            "{:.3} s of audio in {:.4} s (median of {repeat}): {:.1}x real time, threads {}, chunk {}",
            seconds,
            median,
            seconds / median,
            job.threads,
            job.chunk.map_or("whole signal".to_string(), |c| format!("{c} samples"))
        );
    }
    Ok(())
}
