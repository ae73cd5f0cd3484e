//! `afe batch`: many WAV files into one store, and `afe batch status`.

use std::path::{Path, PathBuf};

use afe::ParamMap;
use clap::Subcommand;
use serde_json::json;

use crate::args::Requests;
use crate::error::CliError;
use crate::extract::StoredType;
use crate::outln;

/// `afe batch INPUT... -r ... -o STORE`, or `afe batch status STORE`.
#[derive(clap::Args)]
pub(crate) struct BatchArgs {
    #[command(subcommand)]
    status: Option<BatchCommand>,
    /// Folders (searched for .wav files), glob patterns, WAV files, or manifests
    /// (one `id<TAB>path` per line). A file's id is its path relative to its input.
    #[arg(required = true, value_name = "INPUT")]
    inputs: Vec<PathBuf>,
    #[command(flatten)]
    requests: Requests,
    /// The store: a folder, created if missing.
    #[arg(short = 'o', long = "output", value_name = "STORE", required = true)]
    store: Option<PathBuf>,
    #[command(flatten)]
    options: BatchFlags,
}

/// `afe batch status STORE`.
#[derive(Subcommand)]
enum BatchCommand {
    /// Show what a store holds: its requests and parameters, files done, failed, and
    /// recorded as done but missing on disk (each done file checked: metadata and chunk
    /// sizes).
    Status {
        /// The store.
        store: PathBuf,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
}

impl BatchArgs {
    pub(crate) fn run(self) -> Result<(), CliError> {
        if let Some(BatchCommand::Status { store, json }) = self.status {
            return batch_status(&store, json);
        }
        let Some(store) = self.store else {
            return Err("afe batch needs -r REQ,... and -o STORE".into());
        };
        let (requests, params) = self.requests.load()?;
        batch(&self.inputs, &store, requests, params, self.options)
    }
}

/// The options of `afe batch` as given.
#[derive(clap::Args)]
struct BatchFlags {
    /// Files computed at once (default: the number of cores). Cores left free are shared
    /// by each file's concurrent scheduler (`-j 1` on two cores: each file on both).
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
    /// How the values are stored: f64 as computed, or f32 (each value rounded; half the
    /// disk). A store keeps one type: a run with the other is refused.
    #[arg(long, value_enum, default_value_t = StoredType::F64)]
    dtype: StoredType,
    /// Replace the contents of a store made with other requests, parameters or type
    /// (refused while another run writes the store).
    #[arg(long)]
    overwrite: bool,
}

fn batch(
    inputs: &[PathBuf],
    store: &Path,
    requests: Vec<String>,
    params: ParamMap,
    args: BatchFlags,
) -> Result<(), CliError> {
    use afe_batch::{run, BatchOptions, StoreSpec};
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
        dtype: args.dtype.into(),
    };
    let options = BatchOptions {
        workers: args.jobs.map_or(0, |j| j as usize),
        shard,
        on_error: args.on_error.parse()?,
        progress: args.progress.parse()?,
        overwrite: args.overwrite,
        ..BatchOptions::default()
    };
    let summary = run(inputs, store, &spec, &options)?;
    if options.progress == afe_batch::ProgressMode::None {
        eprintln!("{}", summary.text());
    }
    // with --on-error skip, failed files are an outcome (listed, recorded), not an error
    Ok(())
}

fn batch_status(store: &Path, as_json: bool) -> Result<(), CliError> {
    use afe_batch::Status;
    let status = afe_batch::status(store)?;
    let spec = &status.spec;
    let with = |want: Status| -> Vec<&afe_batch::Record> {
        status.records.iter().filter(|r| r.status == want).collect()
    };
    let (done, failed, missing) = (
        with(Status::Done),
        with(Status::Failed),
        with(Status::Missing),
    );
    // a fold from +0: an empty f64 sum is -0, printed as "-0.00 h"
    let audio_s = done.iter().fold(0.0, |sum, r| sum + r.audio_s);
    if as_json {
        let v = json!({
            "store": store.to_string_lossy(),
            "format": spec.format.as_str(),
            "requests": spec.requests,
            "params": spec.params,
            "param_hash": spec.param_hash(),
            "dtype": spec.dtype.name(false),
            "done": done.len(),
            "audio_s": audio_s,
            "failed": failed.iter().map(|r| r.to_json()).collect::<Vec<_>>(),
            "missing": missing.iter().map(|r| r.to_json()).collect::<Vec<_>>(),
            "warnings": status.warnings,
        });
        outln!("{v}");
        return Ok(());
    }
    outln!(
        "{}: {} store of {} ({}) with {} (hash {})",
        store.display(),
        spec.format.as_str(),
        spec.requests.join(","),
        spec.dtype.name(false),
        serde_json::to_string(&spec.params).unwrap_or_default(),
        spec.param_hash()
    );
    outln!(
        "{} file(s) done ({:.2} h of audio), {} failed, {} missing",
        done.len(),
        audio_s / 3600.0,
        failed.len(),
        missing.len()
    );
    for r in failed {
        outln!(
            "  failed: {} ({}): {}",
            r.id,
            r.path.display(),
            r.error.as_deref().unwrap_or("")
        );
    }
    for r in missing {
        outln!(
            "  missing: {} ({}): recorded as done, but {}: the next run computes it again",
            r.id,
            r.path.display(),
            r.error.as_deref().unwrap_or("")
        );
    }
    for w in &status.warnings {
        outln!("  warning: {w}");
    }
    Ok(())
}
