//! Arguments that several subcommands share: the requests and their AFE parameters, and
//! the executor's thread count.

use std::path::{Path, PathBuf};

use afe::extract::Job;
use afe::ParamMap;
use serde_json::Value;

use crate::error::CliError;

/// The requests and their AFE parameters, shared by `extract`, `bench`, `stream` and `batch`.
#[derive(clap::Args)]
pub(crate) struct Requests {
    /// Requests, comma-separated (e.g. ratemap,ild,itd,ic).
    #[arg(
        short = 'r',
        long = "requests",
        value_name = "REQ,...",
        value_delimiter = ',',
        required = true
    )]
    names: Vec<String>,
    #[command(flatten)]
    params: Params,
}

/// `afe serve`'s requests: optional, since remote clients subscribe to their own.
#[cfg(feature = "view")]
#[derive(clap::Args)]
pub(crate) struct ServeRequests {
    /// Requests computed from the start, comma-separated (clients add their own).
    #[arg(
        short = 'r',
        long = "requests",
        value_name = "REQ,...",
        value_delimiter = ','
    )]
    names: Vec<String>,
    #[command(flatten)]
    params: Params,
}

/// The AFE parameters of a command's requests: `-p NAME=VALUE` and `--params FILE.json`.
#[derive(clap::Args)]
struct Params {
    /// An AFE parameter, NAME=VALUE (VALUE is JSON, or a bare string). Repeatable.
    #[arg(short = 'p', long = "param", value_name = "NAME=VALUE")]
    params: Vec<String>,
    /// A JSON object of AFE parameter names to values (-p entries override it).
    #[arg(long = "params", value_name = "FILE.json")]
    params_file: Option<PathBuf>,
}

impl Requests {
    /// The request names (trimmed, empty ones dropped) and the merged parameters.
    pub(crate) fn load(self) -> Result<(Vec<String>, ParamMap), CliError> {
        let params = self.params.load()?;
        let names = clean(self.names);
        if names.is_empty() {
            return Err("no request given: -r takes request names, e.g. -r ratemap,ild".into());
        }
        Ok((names, params))
    }
}

impl Requests {
    /// A job over a WAV file of these requests: fed in chunks of `chunk` samples (one
    /// call when `None`), every intermediate signal kept with `all`, on `threads`.
    pub(crate) fn job(
        self,
        chunk: Option<u64>,
        all: bool,
        threads: usize,
    ) -> Result<Job, CliError> {
        let (requests, params) = self.load()?;
        Ok(Job {
            requests,
            params,
            chunk: chunk.map(|n| n as usize),
            all,
            threads,
        })
    }
}

#[cfg(feature = "view")]
impl ServeRequests {
    /// The request names (possibly none) and the merged parameters.
    pub(crate) fn load(self) -> Result<(Vec<String>, ParamMap), CliError> {
        let params = self.params.load()?;
        Ok((clean(self.names), params))
    }
}

impl Params {
    /// The parameter file's object, then each `-p` over it.
    fn load(self) -> Result<ParamMap, CliError> {
        let mut map = match &self.params_file {
            Some(path) => read_params_file(path)?,
            None => ParamMap::new(),
        };
        for a in &self.params {
            let (k, v) = parse_param(a)?;
            map.insert(k, v);
        }
        Ok(map)
    }
}

/// Largest parameter file read, bytes: far above any set of AFE parameters, and a bound
/// on what a wrong path (`/dev/zero`, a WAV file) can make the CLI read.
const PARAMS_FILE_MAX_BYTES: u64 = 1 << 20;

/// The JSON object of parameter names to values in `path`, read up to
/// [`PARAMS_FILE_MAX_BYTES`].
fn read_params_file(path: &Path) -> Result<ParamMap, CliError> {
    let text = afe::bounded_read::read_text(path, PARAMS_FILE_MAX_BYTES).map_err(|e| {
        if e.kind() == std::io::ErrorKind::InvalidData {
            format!(
                "parameter file '{}' is {e}: it should hold one JSON object of AFE parameter \
                 names to values",
                path.display()
            )
        } else {
            format!("cannot read parameter file '{}': {e}", path.display())
        }
    })?;
    match serde_json::from_str::<Value>(&text) {
        Ok(Value::Object(obj)) => Ok(obj.into_iter().collect()),
        Ok(_) => Err(format!(
            "parameter file '{}' must hold a JSON object of AFE parameter names to values",
            path.display()
        )
        .into()),
        Err(e) => Err(format!("parameter file '{}' is not valid JSON: {e}", path.display()).into()),
    }
}

/// Parses `NAME=VALUE`: VALUE as JSON when it is JSON, else as a plain string.
pub(crate) fn parse_param(arg: &str) -> Result<(String, Value), CliError> {
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

/// The request names, trimmed, without empty ones.
fn clean(requests: Vec<String>) -> Vec<String> {
    requests
        .iter()
        .map(|r| r.trim().to_string())
        .filter(|r| !r.is_empty())
        .collect()
}

/// The executor choice shared by `extract`, `bench` and `stream`.
#[derive(clap::Args)]
pub(crate) struct Threads {
    /// Threads of the concurrent scheduler, the calling one among them (default: the
    /// number of cores; 0 = the sequential executor). Every choice gives the same numbers.
    #[arg(long, value_name = "N")]
    pub(crate) threads: Option<usize>,
}

impl Threads {
    /// The thread count asked for, or the machine's cores.
    pub(crate) fn count(&self) -> usize {
        self.threads.unwrap_or_else(|| {
            std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get)
        })
    }
}
