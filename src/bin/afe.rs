//! The `afe` command line: list the representations, extract them from WAV files.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use afe::extract::{run, Job};
use afe::wav::read_wav;
use afe::{requests, ParamMap};
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
        /// Output .npz file.
        #[arg(short = 'o', long = "output", value_name = "OUT.npz")]
        output: PathBuf,
    },
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
            output,
        } => extract(
            &input,
            requests,
            &params,
            params_file.as_deref(),
            chunk,
            all,
            &output,
        ),
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

fn extract(
    input: &Path,
    request_names: Vec<String>,
    param_args: &[String],
    params_file: Option<&Path>,
    chunk: Option<u64>,
    all: bool,
    output: &Path,
) -> Result<(), String> {
    let params = load_params(params_file, param_args)?;
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
    let job = Job {
        requests: request_names
            .iter()
            .map(|r| r.trim().to_string())
            .filter(|r| !r.is_empty())
            .collect(),
        params,
        chunk: chunk.map(|n| n as usize),
        all,
    };
    let refs: Vec<&[f64]> = audio.channels.iter().map(Vec::as_slice).collect();
    let rec = run(&job, audio.fs, &refs).map_err(|e| e.to_string())?;
    let arrays: Vec<(String, Vec<usize>, &[f64])> = rec
        .signals()
        .iter()
        .map(|s| (s.key.clone(), s.shape(), s.data.as_slice()))
        .collect();
    let mut tmp = output.as_os_str().to_owned();
    tmp.push(".partial");
    let tmp = PathBuf::from(tmp);
    let write = || -> std::io::Result<()> {
        let file = std::fs::File::create(&tmp)?;
        afe::npy::write_npz(std::io::BufWriter::new(file), &arrays)?;
        std::fs::rename(&tmp, output)
    };
    write().map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        format!("cannot write '{}': {e}", output.display())
    })?;
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
