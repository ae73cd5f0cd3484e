//! Corpus extraction: the same requests over many files into one store, with every core
//! busy, memory bounded by the files in flight, progress, failures recorded and skipped,
//! resume after a crash at file granularity, and shards for independent jobs.
//!
//! ```no_run
//! use afe_batch::{run, BatchOptions, Format, StoreSpec};
//! let spec = StoreSpec {
//!     requests: vec!["ratemap".into(), "ild".into()],
//!     params: afe::ParamMap::new(),
//!     format: Format::Zarr,
//!     dtype: afe::npy::Dtype::Float64,
//! };
//! let summary = run(&["corpus/".into()], "features.zarr".as_ref(), &spec, &BatchOptions::default())?;
//! println!("{}", summary.text());
//! # Ok::<(), afe_batch::BatchError>(())
//! ```

mod group;
mod inputs;
mod ledger;
mod progress;
mod store;

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use afe_graph::Manager;
use serde_json::{json, Value};

use afe::extract::{run_into, Job};
use afe::wav::open_input;

pub use group::{is_saved_group, read_group, write_group, ElementType, SavedArray};
pub use inputs::{discover, shard, InputFile};
pub use ledger::{Ledger, Record, Status};
pub use progress::{Progress, ProgressMode};
pub use store::{FileWriter, Format, Store, StoreSpec, StoredArray};

/// Why a batch cannot run (a file that fails is recorded, not an error of the batch).
#[derive(Debug, thiserror::Error)]
pub enum BatchError {
    /// An input that cannot be used.
    #[error("input '{path}': {reason}")]
    Input {
        /// The input as given.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// Two files under one id.
    #[error("two inputs have the id '{id}': '{}' and '{}'; give them distinct ids (a manifest: id<TAB>path)", first.display(), second.display())]
    DuplicateId {
        /// The id.
        id: String,
        /// The first file.
        first: PathBuf,
        /// The second file.
        second: PathBuf,
    },
    /// An id that cannot name a group of the store.
    #[error("file id '{id}' cannot name a store group: {reason}")]
    BadId {
        /// The id.
        id: String,
        /// What is wrong.
        reason: String,
    },
    /// One id is a folder of another.
    #[error("file id '{id}' is also the folder of '{child}': rename one of them")]
    IdIsFolder {
        /// The id that is a prefix.
        id: String,
        /// An id under it.
        child: String,
    },
    /// No input file was found.
    #[error("no input file: {0}")]
    NoInput(String),
    /// A store made for other requests or parameters.
    #[error("the store '{}' holds {found}, not {wanted}: give another store, or --overwrite to replace its contents", path.display())]
    OtherParams {
        /// The store.
        path: PathBuf,
        /// What it holds.
        found: String,
        /// What this run computes.
        wanted: String,
    },
    /// A path that is not a store.
    #[error("'{}' is not an afe store: {reason}", path.display())]
    NotAStore {
        /// The path.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// Reading or writing the store failed.
    #[error("store '{}': {reason}", path.display())]
    Store {
        /// The store or the file in it.
        path: PathBuf,
        /// What the system or zarr said.
        reason: String,
    },
    /// A file id the store does not hold.
    #[error("the store holds no file '{0}'")]
    NoSuchFile(String),
    /// A bad option.
    #[error("{0}")]
    Usage(String),
    /// The graph refused the requests or parameters, or failed on a file.
    #[error(transparent)]
    Afe(#[from] afe_core::Error),
    /// Stopped by [`afe::interrupt`]: the files done so far are kept.
    #[error("interrupted after {done} file(s) of this run: run it again to resume (finished files are kept)")]
    Interrupted {
        /// Files this run finished.
        done: usize,
    },
    /// With `--on-error stop`: the first file that failed.
    #[error("stopped at '{id}': {error}")]
    Stopped {
        /// The file.
        id: String,
        /// Its error.
        error: String,
    },
}

impl BatchError {
    fn input(path: &Path, reason: &str) -> Self {
        BatchError::Input {
            path: path.to_path_buf(),
            reason: reason.to_string(),
        }
    }

    fn store(path: &Path, e: &dyn std::fmt::Display) -> Self {
        BatchError::Store {
            path: path.to_path_buf(),
            reason: e.to_string(),
        }
    }
}

/// What to do when a file fails.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum OnError {
    /// Record it and go on.
    #[default]
    Skip,
    /// Record it, finish the files in flight and stop.
    Stop,
}

impl std::str::FromStr for OnError {
    type Err = BatchError;

    fn from_str(s: &str) -> Result<Self, BatchError> {
        match s {
            "skip" => Ok(OnError::Skip),
            "stop" => Ok(OnError::Stop),
            _ => Err(BatchError::Usage(format!(
                "unknown --on-error '{s}': use skip or stop"
            ))),
        }
    }
}

/// How a batch runs.
#[derive(Debug, Clone)]
pub struct BatchOptions {
    /// Files computed at once (0: one per core). Where they leave cores free, each file
    /// is computed on the concurrent scheduler with its share of them (the same numbers).
    pub workers: usize,
    /// `(I, N)`: compute only shard I of N (0-based).
    pub shard: Option<(u64, u64)>,
    /// What a failed file does.
    pub on_error: OnError,
    /// How progress is shown.
    pub progress: ProgressMode,
    /// Replace a store made with other requests or parameters.
    pub overwrite: bool,
}

impl Default for BatchOptions {
    fn default() -> Self {
        BatchOptions {
            workers: 0,
            shard: None,
            on_error: OnError::Skip,
            progress: ProgressMode::None,
            overwrite: false,
        }
    }
}

/// What a run did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Summary {
    /// Files in this run's inputs (after sharding).
    pub files: usize,
    /// Of them, done by earlier runs and skipped.
    pub already_done: usize,
    /// Computed by this run.
    pub done: usize,
    /// Failed in this run: id and error.
    pub failed: Vec<(String, String)>,
    /// Not started because the run stopped at a failure.
    pub not_started: usize,
    /// Seconds of audio computed by this run.
    pub audio_s: f64,
    /// Wall time of this run in seconds.
    pub wall_s: f64,
}

impl Summary {
    /// The summary as JSON (`--progress jsonl`, Python).
    pub fn to_json(&self) -> Value {
        json!({
            "files": self.files,
            "already_done": self.already_done,
            "done": self.done,
            "failed": self.failed.iter().map(|(id, e)| json!({"id": id, "error": e})).collect::<Vec<_>>(),
            "not_started": self.not_started,
            "audio_s": self.audio_s,
            "wall_s": self.wall_s,
            "x_real_time": self.speed(),
        })
    }

    /// Throughput: seconds of audio per second of wall time.
    pub fn speed(&self) -> f64 {
        if self.wall_s > 0.0 {
            self.audio_s / self.wall_s
        } else {
            0.0
        }
    }

    /// The summary for people, with the failures listed.
    pub fn text(&self) -> String {
        let mut s = format!(
            "{} file(s): {} done now, {} done before, {} failed{}; {:.2} h of audio in {:.1} s ({:.0}x real time)",
            self.files,
            self.done,
            self.already_done,
            self.failed.len(),
            if self.not_started > 0 {
                format!(", {} not started", self.not_started)
            } else {
                String::new()
            },
            self.audio_s / 3600.0,
            self.wall_s,
            self.speed()
        );
        for (id, e) in &self.failed {
            s.push_str(&format!("\n  failed: {id}: {e}"));
        }
        s
    }
}

/// The files of `inputs` (sharded) that `store` does not hold yet, longest first, and how
/// many it holds already. Creates the store if needed (see [`Store::create`]).
pub fn plan(
    inputs: &[PathBuf],
    root: &Path,
    spec: &StoreSpec,
    options: &BatchOptions,
) -> Result<(Store, Vec<InputFile>, usize), BatchError> {
    check_spec(spec)?;
    let mut files = discover(inputs)?;
    if let Some((i, n)) = options.shard {
        if n == 0 || i >= n {
            return Err(BatchError::Usage(format!(
                "shard {i}/{n}: give I/N with 0 <= I < N"
            )));
        }
        files = shard(files, i, n);
    }
    if files.is_empty() && options.shard.is_none() {
        return Err(BatchError::NoInput(format!(
            "no .wav file found in {}",
            inputs
                .iter()
                .map(|p| format!("'{}'", p.display()))
                .collect::<Vec<_>>()
                .join(", ")
        )));
    }
    let store = Store::create(root, spec, options.overwrite)?;
    let records = ledger::read(root).map_err(|e| BatchError::store(root, &e))?;
    let before = files.len();
    files.retain(|f| records.get(&f.id).is_none_or(|r| r.status != Status::Done));
    let already = before - files.len();
    files.sort_by(|a, b| {
        b.audio_s
            .total_cmp(&a.audio_s)
            .then_with(|| a.id.cmp(&b.id))
    });
    Ok((store, files, already))
}

/// Refuses unknown requests and parameters before any file is touched.
fn check_spec(spec: &StoreSpec) -> Result<(), BatchError> {
    if spec.requests.is_empty() {
        return Err(BatchError::Usage("no request given".into()));
    }
    for r in &spec.requests {
        afe::find_request(r)?;
    }
    afe_graph::check_parameter_names(&spec.params)?;
    Ok(())
}

/// Computes `inputs` into the store at `root`: the files it does not hold yet, longest
/// first, `options.workers` at a time.
pub fn run(
    inputs: &[PathBuf],
    root: &Path,
    spec: &StoreSpec,
    options: &BatchOptions,
) -> Result<Summary, BatchError> {
    let start = Instant::now();
    let (store, files, already) = plan(inputs, root, spec, options)?;
    let ledger = Ledger::open(root).map_err(|e| BatchError::store(root, &e))?;
    let workers = match options.workers {
        0 => std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get),
        n => n,
    }
    .min(files.len().max(1));
    let cores = std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get);
    // each file's share of the cores the workers leave free (one: the sequential executor)
    let threads = match cores / workers {
        0 | 1 => 0,
        n => n,
    };
    let audio_s: f64 = files.iter().map(|f| f.audio_s).sum();
    let progress = Mutex::new(Progress::start(
        options.progress,
        files.len(),
        audio_s,
        already,
    ));
    let summary = Mutex::new(Summary {
        files: files.len() + already,
        already_done: already,
        ..Summary::default()
    });
    let next = AtomicUsize::new(0);
    let stop = AtomicBool::new(false);
    let ledger_error = Mutex::new(None);
    // a shared queue in longest-first order: each worker takes the next file when free
    std::thread::scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|| {
                while !stop.load(Ordering::Relaxed) && !afe::interrupt::requested() {
                    let Some(file) = files.get(next.fetch_add(1, Ordering::Relaxed)) else {
                        break;
                    };
                    // an interrupted file is not recorded: the next run redoes it
                    let Some(record) = compute(&store, file, threads) else {
                        break;
                    };
                    if let Err(e) = ledger.append(&record) {
                        stop.store(true, Ordering::Relaxed);
                        *lock(&ledger_error) = Some(BatchError::store(ledger.path(), &e));
                        break;
                    }
                    let mut s = lock(&summary);
                    match &record.error {
                        None => {
                            s.done += 1;
                            s.audio_s += record.audio_s;
                        }
                        Some(e) => {
                            s.failed.push((record.id.clone(), e.clone()));
                            if options.on_error == OnError::Stop {
                                stop.store(true, Ordering::Relaxed);
                            }
                        }
                    }
                    drop(s);
                    lock(&progress).file(&record);
                }
            });
        }
    });
    if let Some(e) = lock(&ledger_error).take() {
        return Err(e);
    }
    let mut summary = summary
        .into_inner()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    summary.wall_s = start.elapsed().as_secs_f64();
    summary.not_started = files
        .len()
        .saturating_sub(summary.done + summary.failed.len());
    summary.failed.sort();
    lock(&progress).finish(&summary);
    if afe::interrupt::requested() {
        return Err(BatchError::Interrupted { done: summary.done });
    }
    if options.on_error == OnError::Stop {
        if let Some((id, error)) = summary.failed.first() {
            return Err(BatchError::Stopped {
                id: id.clone(),
                error: error.clone(),
            });
        }
    }
    Ok(summary)
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Computes one file into `store` (first removing what a killed run left of it) and
/// returns its record, for the caller to append to a ledger; failures are in the record.
/// `None`: interrupted (see [`afe::interrupt`]), nothing to record. `threads`: of the
/// concurrent scheduler, the caller among them (0: the sequential executor).
pub fn compute(store: &Store, file: &InputFile, threads: usize) -> Option<Record> {
    let start = Instant::now();
    let result = compute_file(store, file, threads);
    if result.is_err() {
        // a failed file leaves nothing half-written behind
        let _ = store.clear(&file.id);
    }
    if let Err(BatchError::Afe(afe_core::Error::Interrupted)) = result {
        return None;
    }
    Some(Record::now(
        &file.id,
        &file.path,
        result.map_err(|e| e.to_string()),
        file.audio_s,
        start.elapsed().as_secs_f64(),
    ))
}

fn compute_file(store: &Store, file: &InputFile, threads: usize) -> Result<(), BatchError> {
    store.clear(&file.id)?;
    let mut wav = open_input(&file.path)?;
    let spec = store.spec();
    let job = Job {
        requests: spec.requests.clone(),
        params: spec.params.clone(),
        ..Job::default()
    };
    let mut mgr = Manager::with_threads(wav.fs(), wav.channels(), threads)?;
    let mut writer = store.writer(file, wav.fs(), wav.channels())?;
    writer.expect_input(wav.frames());
    let ears = wav.channels();
    run_into(
        &mut mgr,
        &job,
        ears,
        |frames, out| {
            wav.read(frames, out)
                .map_err(|e| afe_core::Error::InvalidInput(e.to_string()))
        },
        &mut writer,
    )?;
    writer.finish()
}

/// A store's state: its spec and the latest record of every file.
pub fn status(root: &Path) -> Result<(StoreSpec, Vec<Record>), BatchError> {
    let store = Store::open(root)?;
    let mut records: Vec<Record> = ledger::read(root)
        .map_err(|e| BatchError::store(root, &e))?
        .into_values()
        .collect();
    records.sort_by(|a, b| a.id.cmp(&b.id));
    Ok((store.spec().clone(), records))
}
