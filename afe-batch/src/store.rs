//! The corpus store: a Zarr v3 hierarchy (one group per file id, one float64 or
//! complex128 array per output, or float32 or complex64 rounded from them, written chunk
//! by chunk as the output comes), or a folder of per-file `.npz` files in the `afe
//! extract` layout. Its root records the requests, the parameters and their hash and the
//! stored type, so a second run with others is refused.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use afe_core::{CancelToken, ParamMap};
use afe_graph::{Manager, OutputRef, Signal};
use serde_json::{json, Value};
use zarrs::array::codec::CodecOptions;
use zarrs::array::{Array, ArrayBuilder, DataType, FillValue};
use zarrs::filesystem::FilesystemStore;
use zarrs::group::GroupBuilder;

use super::group::read_file_group;
use super::inputs::{check_id, fnv1a, InputFile};
use super::ledger::LOG_DIR;
use super::locks::{active_runs, StoreLock, LOCK_FILE};
use super::verify::read_json;
use super::BatchError;
use afe::bounded_read::read_text;
use afe::extract::Sink;
use afe::npy::Dtype;
use afe::output::OutputFile;
use afe::Recorder;

/// Most bytes in a chunk of an output array (1 MiB: a few seconds of a full-rate
/// filterbank, minutes of a ratemap); a shorter output is one chunk of its own length.
/// Chunks are stored uncompressed: the outputs are float64 noise to a compressor (gzip
/// saved under 1 % on ratemaps and cost time).
pub(crate) const CHUNK_BYTES: usize = 1 << 20;

/// Largest store metadata file read, bytes (the spec holds requests and parameters).
pub(crate) const META_MAX_BYTES: u64 = 16 << 20;

/// The metadata file of an npz store (a zarr store keeps it in its root's attributes).
const NPZ_META: &str = "afe-batch.json";

/// How a store keeps its arrays.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// A Zarr v3 hierarchy.
    Zarr,
    /// One `.npz` per file, as `afe extract` writes it.
    Npz,
}

impl Format {
    /// The name used on the command line and in the store's metadata.
    pub fn as_str(self) -> &'static str {
        match self {
            Format::Zarr => "zarr",
            Format::Npz => "npz",
        }
    }
}

impl std::str::FromStr for Format {
    type Err = BatchError;

    fn from_str(s: &str) -> Result<Self, BatchError> {
        match s {
            "zarr" => Ok(Format::Zarr),
            "npz" => Ok(Format::Npz),
            _ => Err(BatchError::Usage(format!(
                "unknown store format '{s}': use zarr or npz"
            ))),
        }
    }
}

/// What a store holds: the requests, their parameters and the layout.
#[derive(Debug, Clone, PartialEq)]
pub struct StoreSpec {
    /// AFE request names.
    pub requests: Vec<String>,
    /// AFE parameters shared by the requests.
    pub params: ParamMap,
    /// The layout.
    pub format: Format,
    /// How the values are stored: float64 as computed, or rounded to float32.
    pub dtype: Dtype,
}

impl StoreSpec {
    /// A hash of the requests (as a set) and the parameters, in hex: equal for runs that
    /// compute the same arrays.
    pub fn param_hash(&self) -> String {
        let mut requests = self.requests.clone();
        requests.sort();
        requests.dedup();
        let canonical = json!({ "requests": requests, "params": self.params }).to_string();
        format!("{:016x}", fnv1a(canonical.as_bytes()))
    }

    fn to_json(&self) -> Value {
        json!({
            "format": self.format.as_str(),
            "afe_version": env!("CARGO_PKG_VERSION"),
            "requests": self.requests,
            "params": self.params,
            "param_hash": self.param_hash(),
            "dtype": self.dtype.name(false),
        })
    }

    fn from_json(v: &Value) -> Option<StoreSpec> {
        Some(StoreSpec {
            requests: v
                .get("requests")?
                .as_array()?
                .iter()
                .map(|r| r.as_str().map(str::to_string))
                .collect::<Option<_>>()?,
            params: v
                .get("params")?
                .as_object()?
                .iter()
                .map(|(k, v)| (k.clone(), v.clone()))
                .collect(),
            format: v.get("format")?.as_str()?.parse().ok()?,
            // stores written before float32 existed hold float64
            dtype: match v.get("dtype").and_then(Value::as_str) {
                None | Some("float64") => Dtype::Float64,
                Some("float32") => Dtype::Float32,
                Some(_) => return None,
            },
        })
    }
}

/// An open store.
#[derive(Debug)]
pub struct Store {
    root: PathBuf,
    spec: StoreSpec,
    zarr: Option<Arc<FilesystemStore>>,
    /// The store's lock, held shared by a store opened to be written.
    _lock: Option<StoreLock>,
}

/// How long a run waits between looks while another run creates the store.
const CREATE_POLL: Duration = Duration::from_millis(20);

impl Store {
    /// Opens the store at `root` for `spec` to be written, creating it if `root` is
    /// missing or an empty folder; the store's lock is held shared until the store is
    /// dropped (see [`crate::locks`]). A store made for other requests, parameters or
    /// format is refused, or with `overwrite` emptied first, which is refused while
    /// another run writes it; a folder that is not a store is never touched.
    pub fn create(root: &Path, spec: &StoreSpec, overwrite: bool) -> Result<Store, BatchError> {
        if root.exists() && !root.is_dir() {
            return Err(BatchError::NotAStore {
                path: root.to_path_buf(),
                reason: "it is a file".into(),
            });
        }
        // nothing (not even the lock) is made in a folder holding other files
        if root.exists() && read_spec(root)?.is_none() && !holds_only_logs(root) {
            return Err(foreign(root));
        }
        std::fs::create_dir_all(root).map_err(|e| BatchError::store(root, &e))?;
        loop {
            let shared = StoreLock::shared(root).map_err(|e| BatchError::store(root, &e))?;
            let found = read_spec(root)?;
            match &found {
                Some(f) if same(f, spec) => return Store::with(root, f.clone(), Some(shared)),
                Some(f) if !overwrite => return Err(other_params(root, f, spec)),
                None if !holds_only_logs(root) => return Err(foreign(root)),
                _ => {}
            }
            // made or emptied under the exclusive lock, then opened again shared (another
            // run may make or replace it in between: the loop looks again)
            drop(shared);
            match StoreLock::try_exclusive(root).map_err(|e| BatchError::store(root, &e))? {
                Some(exclusive) => {
                    Store::make(root, spec, overwrite)?;
                    drop(exclusive);
                }
                None if found.is_some() => {
                    return Err(BatchError::Busy {
                        path: root.to_path_buf(),
                        runs: describe_runs(root),
                    })
                }
                None if afe::interrupt::requested() => {
                    return Err(BatchError::Interrupted { done: 0 })
                }
                None => std::thread::sleep(CREATE_POLL),
            }
        }
    }

    /// Under the exclusive lock: writes the metadata of a new store, or empties a store
    /// of other contents first (`overwrite`), keeping the lock file.
    fn make(root: &Path, spec: &StoreSpec, overwrite: bool) -> Result<(), BatchError> {
        match read_spec(root)? {
            Some(found) if same(&found, spec) => return Ok(()),
            Some(found) if !overwrite => return Err(other_params(root, &found, spec)),
            Some(_) => empty(root)?,
            None if !holds_only_logs(root) => return Err(foreign(root)),
            None => {}
        }
        // written whole under a temporary name and renamed: a run killed here leaves no
        // torn metadata that every later run would refuse
        let (name, meta) = match spec.format {
            Format::Zarr => (
                "zarr.json",
                json!({ "zarr_format": 3, "node_type": "group", "attributes": { "afe": spec.to_json() } }),
            ),
            Format::Npz => (NPZ_META, spec.to_json()),
        };
        let file = OutputFile::check(&root.join(name)).map_err(|e| BatchError::store(root, &e))?;
        file.write(|f| f.write_all(meta.to_string().as_bytes()))
            .map_err(|e| BatchError::store(root, &e))?;
        // an overwrite into the other format: the old metadata goes last, so that the
        // folder is a store at every moment
        for old in ["zarr.json", NPZ_META].iter().filter(|&&n| n != name) {
            match std::fs::remove_file(root.join(old)) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                    return Err(BatchError::store(root, &e))
                }
                _ => {}
            }
        }
        Ok(())
    }

    /// Opens an existing store to read it (no lock is taken: a run may be writing it).
    pub fn open(root: &Path) -> Result<Store, BatchError> {
        match read_spec(root)? {
            Some(spec) => Store::with(root, spec, None),
            None => Err(not_a_store(root)),
        }
    }

    /// Opens an existing store to write files into it, holding its lock shared until
    /// dropped (one file of a distributed run: see [`crate::compute_one`]).
    pub fn open_to_write(root: &Path) -> Result<Store, BatchError> {
        if read_spec(root)?.is_none() {
            return Err(not_a_store(root));
        }
        let lock = StoreLock::shared(root).map_err(|e| BatchError::store(root, &e))?;
        // read again under the lock: an overwrite may have replaced it meanwhile
        match read_spec(root)? {
            Some(spec) => Store::with(root, spec, Some(lock)),
            None => Err(not_a_store(root)),
        }
    }

    fn with(root: &Path, spec: StoreSpec, lock: Option<StoreLock>) -> Result<Store, BatchError> {
        let zarr = match spec.format {
            Format::Zarr => Some(Arc::new(
                FilesystemStore::new(root).map_err(|e| BatchError::store(root, &e))?,
            )),
            Format::Npz => None,
        };
        Ok(Store {
            root: root.to_path_buf(),
            spec,
            zarr,
            _lock: lock,
        })
    }

    /// The store's folder.
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// What the store holds.
    pub fn spec(&self) -> &StoreSpec {
        &self.spec
    }

    /// Where file `id`'s output lives: its group's folder, or its `.npz`.
    pub fn file_path(&self, id: &str) -> PathBuf {
        match self.spec.format {
            Format::Zarr => self.root.join(id),
            Format::Npz => self.root.join(format!("{id}.npz")),
        }
    }

    /// Removes what a run that died left of file `id`; refuses (and removes nothing) when
    /// its folder holds the group of another file, whose id nests in `id`.
    pub fn clear(&self, id: &str) -> Result<(), BatchError> {
        let path = self.file_path(id);
        if let Some(child) = nested_group(&path, id) {
            return Err(BatchError::IdIsFolder {
                id: id.to_string(),
                child,
            });
        }
        let removed = if path.is_dir() {
            std::fs::remove_dir_all(&path)
        } else {
            std::fs::remove_file(&path)
        };
        match removed {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(BatchError::store(&path, &e)),
            _ => Ok(()),
        }
    }

    /// A writer of `file`'s outputs. Its folders' groups are written now; its own group,
    /// with the file's facts and its arrays' names, is written last by
    /// [`FileWriter::finish`], so that a group with metadata is a whole one.
    pub fn writer(
        &self,
        file: &InputFile,
        fs: f64,
        channels: usize,
    ) -> Result<FileWriter<'_>, BatchError> {
        match &self.zarr {
            Some(z) => {
                let mut path = String::new();
                let parts: Vec<&str> = file.id.split('/').collect();
                for part in &parts[..parts.len() - 1] {
                    path.push('/');
                    path.push_str(part);
                    // a folder that is another file's group: that file's redo would delete
                    // this one
                    if is_file_group(&self.root.join(&path[1..])) {
                        return Err(BatchError::IdIsFolder {
                            id: path[1..].to_string(),
                            child: file.id.clone(),
                        });
                    }
                    if is_group(&self.root.join(&path[1..])) {
                        continue;
                    }
                    GroupBuilder::new()
                        .build(z.clone(), &path)
                        .map_err(|e| BatchError::store(&self.root, &e))?
                        .store_metadata()
                        .map_err(|e| BatchError::store(&self.root, &e))?;
                }
                Ok(FileWriter::Zarr(ZarrFile {
                    store: z.clone(),
                    group: format!("/{}", file.id),
                    facts: json!({
                        "path": file.path.to_string_lossy(),
                        "fs_hz": fs,
                        "channels": channels,
                        "duration_s": file.audio_s,
                    }),
                    root: &self.root,
                    audio_s: file.audio_s,
                    dtype: self.spec.dtype,
                    arrays: Vec::new(),
                }))
            }
            None => Ok(FileWriter::Npz {
                rec: Recorder::new(false),
                path: self.file_path(&file.id),
                dtype: self.spec.dtype,
            }),
        }
    }
}

/// Whether `dir` holds a folder group's whole metadata: a run killed while writing it
/// leaves it empty or torn, and the next file in that folder then writes it again.
fn is_group(dir: &Path) -> bool {
    read_text(&dir.join("zarr.json"), META_MAX_BYTES)
        .is_ok_and(|t| serde_json::from_str::<Value>(&t).is_ok())
}

/// Whether `dir` holds the group metadata of a file (its facts: `afe.path`).
fn is_file_group(dir: &Path) -> bool {
    read_json(&dir.join("zarr.json"))
        .is_ok_and(|v| v["node_type"] == "group" && v["attributes"]["afe"].get("path").is_some())
}

/// The id of a group found under the folder `dir` of file `id` (another file's, or a
/// folder of other files): a file's folder holds only its arrays. Arrays' folders are
/// not searched.
fn nested_group(dir: &Path, id: &str) -> Option<String> {
    let entries = std::fs::read_dir(dir).ok()?;
    entries.filter_map(Result::ok).find_map(|e| {
        let name = e.file_name().to_string_lossy().into_owned();
        let path = e.path();
        if !e.file_type().is_ok_and(|t| t.is_dir()) {
            return None;
        }
        match read_json(&path.join("zarr.json")).map(|v| v["node_type"].clone()) {
            Ok(kind) if kind == "array" => None,
            Ok(kind) if kind == "group" => Some(format!("{id}/{name}")),
            // an array whose metadata a kill tore holds only its chunks ('c')
            _ if name == "c" => None,
            _ => nested_group(&path, &format!("{id}/{name}")),
        }
    })
}

/// Whether two specs make the same store.
fn same(a: &StoreSpec, b: &StoreSpec) -> bool {
    a.param_hash() == b.param_hash() && a.format == b.format && a.dtype == b.dtype
}

fn other_params(root: &Path, found: &StoreSpec, wanted: &StoreSpec) -> BatchError {
    BatchError::OtherParams {
        path: root.to_path_buf(),
        found: describe(found),
        wanted: describe(wanted),
    }
}

fn foreign(root: &Path) -> BatchError {
    BatchError::NotAStore {
        path: root.to_path_buf(),
        reason: "it is a folder holding other files: give a new or empty folder".into(),
    }
}

fn not_a_store(root: &Path) -> BatchError {
    BatchError::NotAStore {
        path: root.to_path_buf(),
        reason: "it holds no afe batch metadata".into(),
    }
}

/// Whether the folder `root` holds nothing but what making a store puts there first: the
/// logs folder and the root metadata being written under a temporary name.
fn holds_only_logs(root: &Path) -> bool {
    std::fs::read_dir(root).is_ok_and(|entries| {
        entries.filter_map(Result::ok).all(|e| {
            let name = e.file_name();
            let name = name.to_string_lossy();
            name == LOG_DIR
                || (name.ends_with(".partial")
                    && (name.starts_with(".zarr.json.") || name.starts_with(".afe-batch.json.")))
        })
    })
}

/// Removes everything in the store but its metadata (the folder stays a store for other
/// runs looking at it; the new metadata replaces it) and its lock file (other runs wait
/// on that very file: a new one would be another lock).
fn empty(root: &Path) -> Result<(), BatchError> {
    let remove = |path: &Path| -> Result<(), BatchError> {
        let removed = if path.is_dir() {
            std::fs::remove_dir_all(path)
        } else {
            std::fs::remove_file(path)
        };
        removed.map_err(|e| BatchError::store(path, &e))
    };
    for entry in std::fs::read_dir(root).map_err(|e| BatchError::store(root, &e))? {
        let path = entry.map_err(|e| BatchError::store(root, &e))?.path();
        if path.ends_with("zarr.json") || path.ends_with(NPZ_META) {
            continue;
        }
        if !path.ends_with(LOG_DIR) {
            remove(&path)?;
            continue;
        }
        for inner in std::fs::read_dir(&path).map_err(|e| BatchError::store(&path, &e))? {
            let inner = inner.map_err(|e| BatchError::store(&path, &e))?.path();
            if !inner.ends_with(LOCK_FILE) {
                remove(&inner)?;
            }
        }
    }
    Ok(())
}

/// The other runs holding the store's lock, for a message.
fn describe_runs(root: &Path) -> String {
    let runs = active_runs(root);
    if runs.is_empty() {
        "a run whose entry is not visible here".into()
    } else {
        runs.join(", ")
    }
}

/// The store's spec, if `root` is a store.
fn read_spec(root: &Path) -> Result<Option<StoreSpec>, BatchError> {
    let zarr = root.join("zarr.json");
    let npz = root.join(NPZ_META);
    let (path, meta) = if zarr.is_file() {
        let text = read_text(&zarr, META_MAX_BYTES).map_err(|e| BatchError::store(&zarr, &e))?;
        let v: Value = serde_json::from_str(&text).map_err(|e| BatchError::store(&zarr, &e))?;
        (zarr, v["attributes"]["afe"].clone())
    } else if npz.is_file() {
        let text = read_text(&npz, META_MAX_BYTES).map_err(|e| BatchError::store(&npz, &e))?;
        (
            npz.clone(),
            serde_json::from_str(&text).map_err(|e| BatchError::store(&npz, &e))?,
        )
    } else {
        return Ok(None);
    };
    match StoreSpec::from_json(&meta) {
        Some(spec) => Ok(Some(spec)),
        None => Err(BatchError::NotAStore {
            path,
            reason: "a zarr hierarchy without afe's batch metadata".into(),
        }),
    }
}

fn describe(spec: &StoreSpec) -> String {
    format!(
        "{} as {} of {} with {} (hash {})",
        spec.requests.join(","),
        spec.format.as_str(),
        spec.dtype.name(false),
        serde_json::to_string(&spec.params).unwrap_or_default(),
        spec.param_hash()
    )
}

/// Writes one file's outputs as they are computed.
#[derive(Debug)]
pub enum FileWriter<'a> {
    /// Into the file's zarr group, chunk by chunk.
    Zarr(ZarrFile<'a>),
    /// Into memory, then one `.npz`.
    Npz {
        /// The outputs so far.
        rec: Recorder,
        /// The file written at the end.
        path: PathBuf,
        /// How its values are stored.
        dtype: Dtype,
    },
}

impl FileWriter<'_> {
    /// Sizes an `.npz`'s outputs for a file of `samples` samples per ear (as the header
    /// declares), so that each is written once instead of growing.
    pub fn expect_input(&mut self, samples: u64) {
        if let FileWriter::Npz { rec, .. } = self {
            rec.expect_input(samples);
        }
    }

    /// Writes what is left and the arrays' final shapes.
    pub fn finish(self) -> Result<(), BatchError> {
        match self {
            FileWriter::Zarr(z) => z.finish(),
            FileWriter::Npz { rec, path, dtype } => {
                if let Some(dir) = path.parent() {
                    std::fs::create_dir_all(dir).map_err(|e| BatchError::store(dir, &e))?;
                }
                let out = OutputFile::check(&path).map_err(|e| BatchError::store(&path, &e))?;
                out.write(|f| rec.write_npz_as(f, dtype))
                    .map_err(|e| BatchError::store(&path, &e))
            }
        }
    }
}

impl Sink for FileWriter<'_> {
    type Error = BatchError;

    fn chunk(&mut self, manager: &Manager) -> Result<(), BatchError> {
        match self {
            FileWriter::Zarr(z) => z.push_all(manager),
            FileWriter::Npz { rec, .. } => Ok(rec.chunk(manager)?),
        }
    }

    fn whole(&mut self, manager: &mut Manager) -> Result<(), BatchError> {
        match self {
            // copied from the manager as shown: a signal taken out of it (take_whole) is no
            // longer listed by `signals`, so its array would never be made
            FileWriter::Zarr(z) => z.push_all(manager),
            FileWriter::Npz { rec, .. } => Ok(rec.whole(manager)?),
        }
    }

    fn keeps_whole(&self) -> Option<u64> {
        match self {
            FileWriter::Zarr(_) => None,
            FileWriter::Npz { rec, .. } => rec.keeps_whole(),
        }
    }
}

/// A file's zarr group being written.
#[derive(Debug)]
pub struct ZarrFile<'a> {
    store: Arc<FilesystemStore>,
    group: String,
    /// The file's facts (`afe` attributes of its group), written with the array names.
    facts: Value,
    root: &'a Path,
    /// The file's duration in seconds, to size the chunks.
    audio_s: f64,
    /// How the values are stored.
    dtype: Dtype,
    arrays: Vec<ArrayOut>,
}

/// One output array: full chunks are written as they fill, the last at the end.
#[derive(Debug)]
struct ArrayOut {
    source: OutputRef,
    array: Array<FilesystemStore>,
    frame_shape: Vec<u64>,
    /// `f64` values per row (two per complex value).
    width: usize,
    /// How the values are stored.
    dtype: Dtype,
    rows_per_chunk: usize,
    buf: Vec<f64>,
    chunks: u64,
    rows: u64,
}

impl ZarrFile<'_> {
    /// Appends what `manager` shows of every requested signal (a chunk's new values, or
    /// a whole signal's).
    fn push_all(&mut self, manager: &Manager) -> Result<(), BatchError> {
        for s in manager.signals(false) {
            self.push(manager, &s, s.new.as_slice())?;
        }
        Ok(())
    }

    fn push(&mut self, manager: &Manager, s: &Signal<'_>, data: &[f64]) -> Result<(), BatchError> {
        let k = match self.arrays.iter().position(|a| a.source == s.source) {
            Some(k) => k,
            None => {
                self.arrays.push(self.create(manager, s)?);
                self.arrays.len() - 1
            }
        };
        let a = &mut self.arrays[k];
        a.buf.extend_from_slice(data);
        let full = a.rows_per_chunk * a.width;
        if full > 0 && a.buf.len() >= full {
            // whole chunks in one pass, the rest kept (a whole signal is many chunks:
            // splitting them off one by one would copy the rest each time)
            let buf = std::mem::take(&mut a.buf);
            let mut chunks = buf.chunks_exact(full);
            for chunk in chunks.by_ref() {
                a.write_chunk(chunk, a.rows_per_chunk)
                    .map_err(|e| BatchError::store(self.root, &e))?;
            }
            a.buf = chunks.remainder().to_vec();
        }
        Ok(())
    }

    fn create(&self, manager: &Manager, s: &Signal<'_>) -> Result<ArrayOut, BatchError> {
        let complex = s.info.is_complex();
        let width = s.info.width();
        let frame_shape: Vec<u64> = s.info.frame_shape().iter().map(|&n| n as u64).collect();
        // zarr stores edge chunks whole: size the chunk to the expected length (from the
        // file's duration, with a margin for framing) so that short files are not padded
        let expected = if self.audio_s > 0.0 {
            (self.audio_s * s.info.fs_hz).ceil() as usize + 2
        } else {
            usize::MAX
        };
        let bytes = match self.dtype {
            Dtype::Float64 => 8,
            Dtype::Float32 => 4,
        };
        let rows_per_chunk = (CHUNK_BYTES / bytes / width.max(1)).clamp(1, expected.max(1));
        let mut shape = vec![0];
        shape.extend(&frame_shape);
        let mut chunk_shape = vec![rows_per_chunk as u64];
        chunk_shape.extend(frame_shape.iter().map(|&n| n.max(1)));
        let (dtype, size) = match (self.dtype, complex) {
            (Dtype::Float64, true) => (DataType::Complex128, 16),
            (Dtype::Float64, false) => (DataType::Float64, 8),
            (Dtype::Float32, true) => (DataType::Complex64, 8),
            (Dtype::Float32, false) => (DataType::Float32, 4),
        };
        let mut described = afe::metadata::describe(manager, s);
        described["dtype"] = Value::from(self.dtype.name(complex));
        let mut attrs = serde_json::Map::new();
        attrs.insert("afe".into(), described);
        let array = ArrayBuilder::new(shape, chunk_shape, dtype, FillValue::new(vec![0; size]))
            .dimension_names(Some(s.info.axis_names()))
            .attributes(attrs)
            .build(self.store.clone(), &format!("{}/{}", self.group, s.key()))
            .map_err(|e| BatchError::store(self.root, &e))?;
        array
            .store_metadata()
            .map_err(|e| BatchError::store(self.root, &e))?;
        Ok(ArrayOut {
            source: s.source,
            array,
            frame_shape,
            width,
            dtype: self.dtype,
            rows_per_chunk,
            buf: Vec::new(),
            chunks: 0,
            rows: 0,
        })
    }

    fn finish(mut self) -> Result<(), BatchError> {
        for a in &mut self.arrays {
            let rows = a.buf.len().checked_div(a.width).unwrap_or(0);
            if rows > 0 {
                let mut chunk = std::mem::take(&mut a.buf);
                chunk.resize(a.rows_per_chunk * a.width, 0.0);
                a.write_chunk(&chunk, rows)
                    .map_err(|e| BatchError::store(self.root, &e))?;
            }
            let mut shape = vec![a.rows];
            shape.extend(&a.frame_shape);
            a.array
                .set_shape(shape)
                .map_err(|e| BatchError::store(self.root, &e))?;
            a.array
                .store_metadata()
                .map_err(|e| BatchError::store(self.root, &e))?;
        }
        // the group's metadata last: it says the file is whole (see `verify`)
        let mut names: Vec<String> = self
            .arrays
            .iter()
            .map(|a| {
                a.array
                    .path()
                    .as_str()
                    .rsplit('/')
                    .next()
                    .unwrap_or_default()
                    .to_string()
            })
            .collect();
        names.sort();
        self.facts["arrays"] = json!(names);
        let mut attrs = serde_json::Map::new();
        attrs.insert("afe".into(), self.facts);
        GroupBuilder::new()
            .attributes(attrs)
            .build(self.store.clone(), &self.group)
            .map_err(|e| BatchError::store(self.root, &e))?
            .store_metadata()
            .map_err(|e| BatchError::store(self.root, &e))
    }
}

impl ArrayOut {
    /// Writes `chunk` (a whole chunk's values) as the next chunk, of which `rows` are data.
    fn write_chunk(
        &mut self,
        chunk: &[f64],
        rows: usize,
    ) -> Result<(), Box<dyn std::error::Error>> {
        let mut shape = vec![(self.chunks + 1) * self.rows_per_chunk as u64];
        shape.extend(&self.frame_shape);
        self.array.set_shape(shape)?;
        let mut indices = vec![self.chunks];
        indices.extend(self.frame_shape.iter().map(|_| 0));
        self.dtype.check(self.array.path().as_str(), chunk)?;
        let bytes: Vec<u8> = match self.dtype {
            Dtype::Float64 => chunk.iter().flat_map(|v| v.to_ne_bytes()).collect(),
            Dtype::Float32 => chunk
                .iter()
                .flat_map(|v| (*v as f32).to_ne_bytes())
                .collect(),
        };
        // a chunk of zeros is stored too (zarr would leave it out), so that every chunk of
        // a whole array is on disk (see `verify`)
        let mut options = CodecOptions::default();
        options.set_store_empty_chunks(true);
        self.array.store_chunk_opt(&indices, bytes, &options)?;
        self.chunks += 1;
        self.rows += rows as u64;
        Ok(())
    }
}

/// One array read back from a store: its shape, values (complex as re, im pairs; float32
/// ones widened, their `info` saying `float32` or `complex64`) and metadata.
#[derive(Debug, Clone, PartialEq)]
pub struct StoredArray {
    /// Output name, e.g. `ratemap_left`.
    pub key: String,
    /// `[frames, ...]`.
    pub shape: Vec<usize>,
    /// Values in C order.
    pub data: Vec<f64>,
    /// Its `afe` attributes ([`afe::metadata::describe`]).
    pub info: Value,
}

impl Store {
    /// The arrays of file `id`, read back (zarr stores only; an npz store's files are
    /// read with numpy or [`afe::npy`]); a signal to the process stops the read.
    pub fn read(&self, id: &str) -> Result<Vec<StoredArray>, BatchError> {
        self.read_until(id, &CancelToken::new())
    }

    /// As [`Store::read`], stopped between chunks also by `cancel`.
    pub fn read_until(
        &self,
        id: &str,
        cancel: &CancelToken,
    ) -> Result<Vec<StoredArray>, BatchError> {
        if self.zarr.is_none() {
            return Err(BatchError::Usage(format!(
                "'{}' is an npz store: read {} with numpy",
                self.root.display(),
                self.file_path(id).display()
            )));
        }
        // an id that is no store path ('../x') names no file of it
        check_id(id).map_err(|_| BatchError::NoSuchFile(id.to_string()))?;
        read_file_group(&self.root, id, cancel)?
            .ok_or_else(|| BatchError::NoSuchFile(id.to_string()))
    }
}
