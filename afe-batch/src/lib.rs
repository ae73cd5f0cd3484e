//! Corpus extraction: the same requests over many files into one store, with every core
//! busy, memory bounded by the files in flight, progress, failures recorded and skipped,
//! resume after a crash at file granularity (each file checked on disk), shards for
//! independent jobs, and runs that share a store without losing a file ([`locks`]).
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
pub mod locks;
mod progress;
mod store;
mod verify;

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use afe_core::CancelToken;
use afe_graph::Manager;
use serde_json::{json, Value};

use afe::extract::{run_into, Job};
use afe::wav::open_input;

pub use group::{
    check_group, is_saved_group, read_group, read_group_until, write_group, ArrayOnDisk,
    ElementType, SavedArray,
};
pub use inputs::{discover, shard, InputFile};
pub use ledger::{Ledger, LedgerView, Record, Status};
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
    /// An id that nests with one the store holds already: one would be a folder of the
    /// other's group, and redoing the outer file would delete the inner one.
    #[error("file id '{id}' nests with '{stored}', which the store '{}' holds already ('{outer}' would be a folder of '{inner}', and redoing '{outer}' would delete '{inner}'): give '{id}' another id (a manifest: id<TAB>path), or another store", store.display())]
    NestsInStore {
        /// The id of this run's inputs.
        id: String,
        /// The id the store holds.
        stored: String,
        /// The one of them that is a folder of the other.
        outer: String,
        /// The one under it.
        inner: String,
        /// The store.
        store: PathBuf,
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
    /// `--overwrite` while another run writes the store.
    #[error("another run is writing the store '{}' ({runs}): --overwrite would delete its files under it; wait for it to end (or stop it), then overwrite", path.display())]
    Busy {
        /// The store.
        path: PathBuf,
        /// The runs holding it, as `pid N on HOST`.
        runs: String,
    },
    /// The store could not be written (a full disk, a quota, a file size limit, lost
    /// permissions): the run stopped, and the files not written are left to resume.
    #[error("cannot write the store '{}': {reason}; stopped after {done} file(s) of this run: the files not written are left to resume, free space (or fix the store) and run the same command again", path.display())]
    StoreWrite {
        /// The store or the file in it.
        path: PathBuf,
        /// What the system or zarr said.
        reason: String,
        /// Files this run finished.
        done: usize,
    },
    /// A saved group, or a file of a store, whose arrays are not whole on disk or declare
    /// more than their files hold.
    #[error("'{}' is damaged: {reason}; save it again (a file of a batch store: run the batch again)", path.display())]
    Damaged {
        /// The group.
        path: PathBuf,
        /// What is wrong, naming the array and chunk.
        reason: String,
    },
    /// Reading would take more memory than is available.
    #[error("reading '{}' takes {:.2} GB of memory, more than {}: read it where there is more memory", path.display(), needed_bytes / 1e9, available_text(*available_bytes))]
    TooLarge {
        /// The group.
        path: PathBuf,
        /// Bytes the values take once read.
        needed_bytes: f64,
        /// Bytes of memory available, where known (else the allocation failed).
        available_bytes: Option<f64>,
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

/// The memory available, for [`BatchError::TooLarge`].
fn available_text(bytes: Option<f64>) -> String {
    match bytes {
        Some(b) => format!(
            "the {:.2} GB available (MemAvailable, a cgroup's limit, ulimit -v or AFE_MEMORY_AVAILABLE_GB)",
            b / 1e9
        ),
        None => "the system could allocate".into(),
    }
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
    /// Stops the run as a signal to the process does (Python's Ctrl-C of this call).
    pub cancel: CancelToken,
}

impl Default for BatchOptions {
    fn default() -> Self {
        BatchOptions {
            workers: 0,
            shard: None,
            on_error: OnError::Skip,
            progress: ProgressMode::None,
            overwrite: false,
            cancel: CancelToken::new(),
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
    /// Done meanwhile by another run sharing the store (found done once this run could
    /// claim them).
    pub done_elsewhere: usize,
    /// Recorded as done by an earlier run but found incomplete in the store (a group,
    /// array or chunk missing or cut short): id and what was wrong. They are among the
    /// files this run computes.
    pub incomplete: Vec<(String, String)>,
    /// Lines of the store's logs that could not be read, skipped.
    pub warnings: Vec<String>,
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
            "done_elsewhere": self.done_elsewhere,
            "incomplete": self.incomplete.iter().map(|(id, e)| json!({"id": id, "error": e})).collect::<Vec<_>>(),
            "warnings": self.warnings,
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
            "{} file(s): {} done now, {} done before, {}{} failed{}; {:.2} h of audio in {:.1} s ({:.0}x real time)",
            self.files,
            self.done,
            self.already_done,
            if self.done_elsewhere > 0 {
                format!("{} done by another run, ", self.done_elsewhere)
            } else {
                String::new()
            },
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
        for (id, e) in &self.incomplete {
            s.push_str(&format!(
                "\n  recorded as done but incomplete in the store, computed again: {id}: {e}"
            ));
        }
        for (id, e) in &self.failed {
            s.push_str(&format!("\n  failed: {id}: {e}"));
        }
        for w in &self.warnings {
            s.push_str(&format!("\n  warning: {w}"));
        }
        s
    }
}

/// What a run over a store has to do.
#[derive(Debug)]
pub struct Plan {
    /// The store, open to be written (its lock held shared).
    pub store: Store,
    /// The files to compute, longest first.
    pub files: Vec<InputFile>,
    /// Files of the inputs the store holds whole already.
    pub already_done: usize,
    /// Files recorded as done but incomplete on disk (id, what is wrong): in `files`.
    pub incomplete: Vec<(String, String)>,
    /// The store's logs as read.
    pub ledger: LedgerView,
}

/// The files of `inputs` (sharded) that `store` does not hold whole yet, longest first:
/// those without a record of being done, and those recorded as done whose output on disk
/// is missing or cut short ([`Store::verify`]). Creates the store if needed (see
/// [`Store::create`]).
pub fn plan(
    inputs: &[PathBuf],
    root: &Path,
    spec: &StoreSpec,
    options: &BatchOptions,
) -> Result<Plan, BatchError> {
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
    let mut ledger = LedgerView::default();
    ledger
        .refresh(root)
        .map_err(|e| BatchError::store(root, &e))?;
    inputs::check_nesting(&files, ledger.records(), root)?;
    let before = files.len();
    let mut incomplete = Vec::new();
    files.retain(|f| match ledger.get(&f.id) {
        Some(r) if r.status == Status::Done => match store.verify(&f.id) {
            Ok(()) => false,
            Err(why) => {
                incomplete.push((f.id.clone(), why));
                true
            }
        },
        _ => true,
    });
    let already_done = before - files.len();
    files.sort_by(|a, b| {
        b.audio_s
            .total_cmp(&a.audio_s)
            .then_with(|| a.id.cmp(&b.id))
    });
    Ok(Plan {
        store,
        files,
        already_done,
        incomplete,
        ledger,
    })
}

/// Refuses unknown requests and parameters before any file is touched.
fn check_spec(spec: &StoreSpec) -> Result<(), BatchError> {
    if spec.requests.is_empty() {
        return Err(BatchError::Usage("no request given".into()));
    }
    let registry = afe::Registry::default();
    for r in &spec.requests {
        registry.find(r)?;
    }
    registry.check_parameter_names(spec.params.keys())?;
    Ok(())
}

/// How one file of a run ended.
#[derive(Debug)]
enum Outcome {
    /// Computed (or failed) by this run: its record, appended to the log.
    Recorded(Record),
    /// Found done by another run once claimed: that run's record.
    Elsewhere(Record),
    /// Another run holds its claim (and the caller would not wait).
    Busy,
    /// Not computed: the run is interrupted or stopping.
    Stopped,
}

/// How often a run that waits for a file another run holds looks again.
const CLAIM_POLL: std::time::Duration = std::time::Duration::from_millis(50);

/// Computes `inputs` into the store at `root`: the files it does not hold whole yet,
/// longest first, `options.workers` at a time. Each file is claimed first (see
/// [`locks`]): a file another run holds is put aside and waited for once the others are
/// done, then computed only if that run did not finish it, so runs sharing a store share
/// its files. A store that cannot be written stops the run with
/// [`BatchError::StoreWrite`], the files not written left to the next run.
pub fn run(
    inputs: &[PathBuf],
    root: &Path,
    spec: &StoreSpec,
    options: &BatchOptions,
) -> Result<Summary, BatchError> {
    let start = Instant::now();
    let Plan {
        store,
        files,
        already_done,
        incomplete,
        ledger: view,
    } = plan(inputs, root, spec, options)?;
    let warnings = view.warnings();
    let view = Mutex::new(view);
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
        already_done,
    ));
    let summary = Mutex::new(Summary {
        files: files.len() + already_done,
        already_done,
        incomplete,
        warnings,
        ..Summary::default()
    });
    let next = AtomicUsize::new(0);
    let stop = Stop {
        failed: AtomicBool::new(false),
        cancel: &options.cancel,
    };
    let deferred: Mutex<Vec<&InputFile>> = Mutex::new(Vec::new());
    let store_error = Mutex::new(None);
    // a shared queue in longest-first order: each worker takes the next file when free;
    // files held by another run are put aside, then waited for
    std::thread::scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|| {
                let mut waiting = false;
                while !stop.now() {
                    let file = if waiting {
                        lock(&deferred).pop()
                    } else {
                        files.get(next.fetch_add(1, Ordering::Relaxed))
                    };
                    let Some(file) = file else {
                        if waiting {
                            break;
                        }
                        waiting = true;
                        continue;
                    };
                    let outcome = process(&store, &ledger, &view, file, threads, waiting, &stop);
                    let record = match outcome {
                        Ok(Outcome::Recorded(r)) => r,
                        Ok(Outcome::Elsewhere(r)) => {
                            lock(&summary).done_elsewhere += 1;
                            lock(&progress).file(&r, true);
                            continue;
                        }
                        Ok(Outcome::Busy) => {
                            lock(&deferred).push(file);
                            continue;
                        }
                        Ok(Outcome::Stopped) => break,
                        Err(e) => {
                            stop.failed.store(true, Ordering::Relaxed);
                            lock(&store_error).get_or_insert(e);
                            break;
                        }
                    };
                    let mut s = lock(&summary);
                    match &record.error {
                        None => {
                            s.done += 1;
                            s.audio_s += record.audio_s;
                        }
                        Some(e) => {
                            s.failed.push((record.id.clone(), e.clone()));
                            if options.on_error == OnError::Stop {
                                stop.failed.store(true, Ordering::Relaxed);
                            }
                        }
                    }
                    drop(s);
                    lock(&progress).file(&record, false);
                }
            });
        }
    });
    let mut summary = summary
        .into_inner()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    summary.wall_s = start.elapsed().as_secs_f64();
    summary.not_started = files
        .len()
        .saturating_sub(summary.done + summary.done_elsewhere + summary.failed.len());
    summary.failed.sort();
    lock(&progress).finish(&summary);
    if let Some(e) = lock(&store_error).take() {
        let (path, reason) = match e {
            BatchError::Store { path, reason } => (path, reason),
            other => (root.to_path_buf(), other.to_string()),
        };
        return Err(BatchError::StoreWrite {
            path,
            reason,
            done: summary.done,
        });
    }
    if options.cancel.is_cancelled() {
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

/// Why a run's workers stop taking files: a store that cannot be written or a failed
/// file (`--on-error stop`), or the caller's stop request.
struct Stop<'a> {
    failed: AtomicBool,
    cancel: &'a CancelToken,
}

impl Stop<'_> {
    fn now(&self) -> bool {
        self.failed.load(Ordering::Relaxed) || self.cancel.is_cancelled()
    }
}

/// Claims `file` (`wait`: until the run holding it lets go, else [`Outcome::Busy`]), and
/// unless another run has done it meanwhile, computes it and appends its record while the
/// claim is held. An error is the store's (it cannot be written): the run stops.
fn process(
    store: &Store,
    ledger: &Ledger,
    view: &Mutex<LedgerView>,
    file: &InputFile,
    threads: usize,
    wait: bool,
    stop: &Stop<'_>,
) -> Result<Outcome, BatchError> {
    let root = store.root();
    let _claim = loop {
        match locks::try_claim(root, &file.id).map_err(|e| BatchError::store(root, &e))? {
            Some(claim) => break claim,
            None if !wait => return Ok(Outcome::Busy),
            None if stop.now() => return Ok(Outcome::Stopped),
            None => std::thread::sleep(CLAIM_POLL),
        }
    };
    // whole on disk and recorded as done since this run's plan: another run did it (a
    // whole group without a record, left by a run killed before its record, is redone)
    if store.verify(&file.id).is_ok() {
        let mut view = lock(view);
        view.refresh(root)
            .map_err(|e| BatchError::store(root, &e))?;
        if let Some(r) = view.get(&file.id).filter(|r| r.status == Status::Done) {
            return Ok(Outcome::Elsewhere(r.clone()));
        }
    }
    let Some(record) = compute(store, file, threads, stop.cancel)? else {
        return Ok(Outcome::Stopped);
    };
    ledger
        .append(&record)
        .map_err(|e| BatchError::store(ledger.path(), &e))?;
    Ok(Outcome::Recorded(record))
}

/// Computes one file of a distributed run (a Dask task: see `afe.batch`) into the store
/// at `root` and records it in this process's log: as [`run`] does for each of its files,
/// under the store's lock and the file's claim, waiting while another run holds it.
/// Returns its record (a failed file is a record) and `false`, or the record of the run
/// that did it meanwhile and `true`. `Err`: the store cannot be written, or an interrupt.
pub fn compute_one(root: &Path, file: &InputFile) -> Result<(Record, bool), BatchError> {
    let store = Store::open_to_write(root)?;
    let ledger = Ledger::open(root).map_err(|e| BatchError::store(root, &e))?;
    let view = Mutex::new(LedgerView::default());
    // one file per executor task: the executor's workers share the cores
    match process(
        &store,
        &ledger,
        &view,
        file,
        0,
        true,
        &Stop {
            failed: AtomicBool::new(false),
            cancel: &CancelToken::new(),
        },
    )? {
        Outcome::Recorded(r) => Ok((r, false)),
        Outcome::Elsewhere(r) => Ok((r, true)),
        Outcome::Busy | Outcome::Stopped => Err(BatchError::Afe(afe_core::Error::Interrupted)),
    }
}

/// Computes one file into `store` (first removing what a killed run left of it) and
/// returns its record, for the caller to append to a ledger; failures of the file are in
/// the record. `Ok(None)`: interrupted (see [`afe::interrupt`]), nothing to record.
/// `Err`: the store cannot be written (a full disk...): nothing is recorded, the file is
/// left to the next run. `threads`: of the concurrent scheduler, the caller among them
/// (0: the sequential executor).
fn compute(
    store: &Store,
    file: &InputFile,
    threads: usize,
    cancel: &CancelToken,
) -> Result<Option<Record>, BatchError> {
    let start = Instant::now();
    let result = compute_file(store, file, threads, cancel);
    if result.is_err() {
        // a failed file leaves nothing half-written behind
        let _ = store.clear(&file.id);
    }
    match result {
        Err(BatchError::Afe(afe_core::Error::Interrupted)) => Ok(None),
        Err(e @ BatchError::Store { .. }) => Err(e),
        result => Ok(Some(Record::now(
            &file.id,
            &file.path,
            result.map_err(|e| e.to_string()),
            file.audio_s,
            start.elapsed().as_secs_f64(),
        ))),
    }
}

fn compute_file(
    store: &Store,
    file: &InputFile,
    threads: usize,
    cancel: &CancelToken,
) -> Result<(), BatchError> {
    store.clear(&file.id)?;
    let mut wav = open_input(&file.path)?;
    let spec = store.spec();
    let job = Job {
        requests: spec.requests.clone(),
        params: spec.params.clone(),
        ..Job::default()
    };
    let mut mgr = Manager::with_threads(wav.fs(), wav.channels(), threads)?;
    mgr.set_cancel_token(cancel.clone());
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

/// What a store holds, as [`status`] finds it.
#[derive(Debug, Clone)]
pub struct StoreStatus {
    /// Its requests, parameters and layout.
    pub spec: StoreSpec,
    /// The latest record of every file, by id; a file recorded as done whose output is
    /// not whole on disk has [`Status::Missing`] and what is wrong as its error.
    pub records: Vec<Record>,
    /// Lines of the logs that could not be read, skipped.
    pub warnings: Vec<String>,
}

/// A store's state: its spec and the latest record of every file, each done one checked
/// on disk ([`Store::verify`]: metadata read, chunk sizes compared, no value decoded).
pub fn status(root: &Path) -> Result<StoreStatus, BatchError> {
    let store = Store::open(root)?;
    let (records, warnings) = ledger::read(root).map_err(|e| BatchError::store(root, &e))?;
    let mut records: Vec<Record> = records
        .into_values()
        .map(|mut r| {
            if r.status == Status::Done {
                if let Err(why) = store.verify(&r.id) {
                    r.status = Status::Missing;
                    r.error = Some(why);
                }
            }
            r
        })
        .collect();
    records.sort_by(|a, b| a.id.cmp(&b.id));
    Ok(StoreStatus {
        spec: store.spec().clone(),
        records,
        warnings,
    })
}
