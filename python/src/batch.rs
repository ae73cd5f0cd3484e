//! Corpus extraction from Python: a whole run in Rust (`batch_run`), or its plan and one
//! file at a time (`batch_plan`, `batch_compute`) for a Python executor such as Dask to
//! distribute; and reading a store back.

use std::path::PathBuf;

use afe::interrupt::CancelToken;
use afe_batch::{
    BatchError, BatchOptions, ElementType, InputFile, SavedArray, Store, StoreSpec, StoredArray,
};
use pyo3::exceptions::{PyKeyError, PyMemoryError, PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::pybacked::PyBackedBytes;
use pyo3::types::PyDict;

use numpy::{Complex32, PyArray1, PyArrayMethods};

use crate::{array, py_value, stored_type, to_py, value_of};

fn to_py_batch(e: BatchError) -> PyErr {
    match e {
        BatchError::Afe(e) => to_py(e),
        BatchError::Store { .. } | BatchError::StoreWrite { .. } | BatchError::Busy { .. } => {
            PyOSError::new_err(e.to_string())
        }
        BatchError::NoSuchFile(_) => PyKeyError::new_err(e.to_string()),
        BatchError::TooLarge { .. } => PyMemoryError::new_err(e.to_string()),
        BatchError::Stopped { .. } => PyRuntimeError::new_err(e.to_string()),
        _ => PyValueError::new_err(e.to_string()),
    }
}

/// The store's spec from `{"requests": [...], "params": {...}, "format": "zarr"|"npz",
/// "dtype": "float64"|"float32"}`.
fn spec(obj: &Bound<'_, PyAny>) -> PyResult<StoreSpec> {
    let v = value_of(obj)?;
    let requests = v["requests"]
        .as_array()
        .and_then(|r| r.iter().map(|r| r.as_str().map(str::to_string)).collect())
        .ok_or_else(|| PyValueError::new_err("requests must be a list of request names"))?;
    Ok(StoreSpec {
        requests,
        params: match &v["params"] {
            serde_json::Value::Object(o) => o.clone().into_iter().collect(),
            serde_json::Value::Null => afe::ParamMap::new(),
            _ => {
                return Err(PyValueError::new_err(
                    "params must be a dict of AFE parameter names to values",
                ))
            }
        },
        format: v["format"]
            .as_str()
            .unwrap_or("zarr")
            .parse()
            .map_err(to_py_batch)?,
        dtype: stored_type(v["dtype"].as_str().unwrap_or("float64"))?,
    })
}

/// The run's options from `{"jobs": N, "shard": [I, N] | null, "on_error": ...,
/// "progress": ..., "overwrite": bool}`.
fn options(obj: &Bound<'_, PyAny>) -> PyResult<BatchOptions> {
    let v = value_of(obj)?;
    let shard = match &v["shard"] {
        serde_json::Value::Array(a) if a.len() == 2 => Some((
            a[0].as_u64().unwrap_or(u64::MAX),
            a[1].as_u64().unwrap_or(0),
        )),
        serde_json::Value::Null => None,
        other => {
            return Err(PyValueError::new_err(format!(
                "shard must be (index, count), got {other}"
            )))
        }
    };
    Ok(BatchOptions {
        workers: v["jobs"].as_u64().unwrap_or(0) as usize,
        shard,
        on_error: v["on_error"]
            .as_str()
            .unwrap_or("skip")
            .parse()
            .map_err(to_py_batch)?,
        progress: v["progress"]
            .as_str()
            .unwrap_or("none")
            .parse()
            .map_err(to_py_batch)?,
        overwrite: v["overwrite"].as_bool().unwrap_or(false),
        cancel: CancelToken::new(),
    })
}

/// Runs a whole batch in Rust; returns the summary.
#[pyfunction]
pub fn batch_run<'py>(
    py: Python<'py>,
    inputs: Vec<PathBuf>,
    store: PathBuf,
    spec: &Bound<'py, PyAny>,
    options: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    let (spec, options) = (self::spec(spec)?, self::options(options)?);
    let cancel = options.cancel.clone();
    let summary = crate::interrupt::interruptible(py, &cancel, || {
        afe_batch::run(&inputs, &store, &spec, &options)
    })?
    .map_err(to_py_batch)?;
    py_value(py, &summary.to_json())
}

/// One file to compute: id, path, seconds of audio.
type Planned = (String, PathBuf, f64);

/// Creates or checks the store; returns the files still to compute, longest first, and
/// how many the store holds already.
#[pyfunction]
pub fn batch_plan(
    py: Python<'_>,
    inputs: Vec<PathBuf>,
    store: PathBuf,
    spec: &Bound<'_, PyAny>,
    options: &Bound<'_, PyAny>,
) -> PyResult<(Vec<Planned>, usize)> {
    let (spec, options) = (self::spec(spec)?, self::options(options)?);
    let plan = py
        .allow_threads(|| afe_batch::plan(&inputs, &store, &spec, &options))
        .map_err(to_py_batch)?;
    Ok((
        plan.files
            .into_iter()
            .map(|f| (f.id, f.path, f.audio_s))
            .collect(),
        plan.already_done,
    ))
}

/// Computes one file into an existing store and records it in this process's log, under
/// the store's lock and the file's claim (waiting while another run holds it); returns its
/// record (a failed file is a record, not an exception; a file another run
/// did meanwhile, that run's record with `"elsewhere": true`). A store that cannot be
/// written raises `OSError`.
#[pyfunction]
pub fn batch_compute(
    py: Python<'_>,
    store: PathBuf,
    id: String,
    path: PathBuf,
    audio_s: f64,
) -> PyResult<Bound<'_, PyAny>> {
    let (record, elsewhere) = py
        .allow_threads(|| afe_batch::compute_one(&store, &InputFile { id, path, audio_s }))
        .map_err(to_py_batch)?;
    let mut v = record.to_json();
    if elsewhere {
        v["elsewhere"] = true.into();
    }
    py_value(py, &v)
}

/// A store's spec and the latest record of each file.
#[pyfunction]
pub fn store_status(py: Python<'_>, store: PathBuf) -> PyResult<Bound<'_, PyAny>> {
    let status = py
        .allow_threads(|| afe_batch::status(&store))
        .map_err(to_py_batch)?;
    let (spec, records) = (status.spec, status.records);
    let status = serde_json::json!({
        "format": spec.format.as_str(),
        "requests": spec.requests,
        "params": spec.params,
        "param_hash": spec.param_hash(),
        "dtype": spec.dtype.name(false),
        "files": records.iter().map(afe_batch::Record::to_json).collect::<Vec<_>>(),
        "warnings": status.warnings,
    });
    py_value(py, &status)
}

/// File `id`'s arrays from a zarr store: `({name: array}, {name: metadata})`;
/// Ctrl-C stops the read between chunks (KeyboardInterrupt).
#[pyfunction]
pub fn store_read<'py>(
    py: Python<'py>,
    store: PathBuf,
    id: String,
) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyDict>)> {
    let cancel = CancelToken::new();
    let arrays = crate::interrupt::interruptible(py, &cancel, || {
        Store::open(&store)?.read_until(&id, &cancel)
    })?
    .map_err(to_py_batch)?;
    numpy_dicts(py, arrays)
}

/// `({name: array}, {name: metadata})` of arrays read back, in their order.
fn numpy_dicts<'py>(
    py: Python<'py>,
    arrays: Vec<StoredArray>,
) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyDict>)> {
    let values = PyDict::new(py);
    let infos = PyDict::new(py);
    for a in arrays {
        let value = match a.info["dtype"].as_str() {
            Some("complex128") => array(py, &a.shape, &a.data, true)?,
            Some("float32") => narrow(py, &a.shape, &a.data, false)?,
            Some("complex64") => narrow(py, &a.shape, &a.data, true)?,
            _ => array(py, &a.shape, &a.data, false)?,
        };
        values.set_item(&a.key, value)?;
        infos.set_item(&a.key, py_value(py, &a.info)?)?;
    }
    Ok((values, infos))
}

/// One array for [`save_zarr`]: name, numpy dtype name, shape, raw bytes (C order,
/// native byte order), metadata.
type ToSave = (String, String, Vec<usize>, PyBackedBytes, PyObject);

/// Writes `arrays` as the Zarr group `path` (`afe.save` to a `.zarr` path).
#[pyfunction]
pub fn save_zarr(py: Python<'_>, path: PathBuf, arrays: Vec<ToSave>) -> PyResult<()> {
    let arrays = arrays
        .into_iter()
        .map(|(key, dtype, shape, bytes, info)| {
            let element = ElementType::from_numpy(&dtype).ok_or_else(|| {
                PyValueError::new_err(format!(
                    "'{key}' is {dtype}: a Zarr group of afe.save holds float64, float32, complex128 or complex64"
                ))
            })?;
            let mut info = value_of(info.bind(py))?;
            // the description says what the values are, whatever they were computed as
            if let Some(meta) = info.as_object_mut() {
                meta.insert("dtype".into(), dtype.clone().into());
            }
            Ok(SavedArray {
                key,
                shape,
                element,
                bytes: bytes.to_vec(),
                info,
            })
        })
        .collect::<PyResult<Vec<_>>>()?;
    py.allow_threads(|| afe_batch::write_group(&path, &arrays))
        .map_err(to_py_batch)
}

/// The arrays of a Zarr group written by `afe.save`, as [`store_read`] gives them: a
/// damaged group raises ValueError naming the array and chunk, one larger than the memory
/// available MemoryError; Ctrl-C stops the read between chunks (KeyboardInterrupt).
#[pyfunction]
pub fn load_zarr<'py>(
    py: Python<'py>,
    path: PathBuf,
) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyDict>)> {
    let cancel = CancelToken::new();
    let arrays = crate::interrupt::interruptible(py, &cancel, || {
        afe_batch::read_group_until(&path, &cancel)
    })?
    .map_err(to_py_batch)?;
    numpy_dicts(py, arrays)
}

/// What is wrong with the Zarr group of `afe.save` at `path` (`None`: whole), checked as
/// [`load_zarr`] reads it, without reading a value.
#[pyfunction]
pub fn check_zarr(py: Python<'_>, path: PathBuf) -> PyResult<Option<String>> {
    match py.allow_threads(|| afe_batch::check_group(&path)) {
        Ok(_) => Ok(None),
        Err(e @ BatchError::Damaged { .. }) => Ok(Some(e.to_string())),
        Err(e) => Err(to_py_batch(e)),
    }
}

/// A float32 (or complex64) numpy array of `shape` from the widened values of a float32
/// store, which `f32` holds exactly.
fn narrow<'py>(
    py: Python<'py>,
    shape: &[usize],
    data: &[f64],
    complex: bool,
) -> PyResult<Bound<'py, PyAny>> {
    if complex {
        let values: Vec<Complex32> = data
            .chunks_exact(2)
            .map(|c| Complex32::new(c[0] as f32, c[1] as f32))
            .collect();
        return Ok(PyArray1::from_vec(py, values)
            .reshape(shape.to_vec())?
            .into_any());
    }
    let values: Vec<f32> = data.iter().map(|&v| v as f32).collect();
    Ok(PyArray1::from_vec(py, values)
        .reshape(shape.to_vec())?
        .into_any())
}
