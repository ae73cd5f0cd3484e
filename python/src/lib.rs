//! `afe._afe`: the compiled core of the Python package `afe`. The pure-Python layer
//! (`python/afe/__init__.py`) normalises arguments (paths, array-likes, parameter dicts)
//! and documents the API; this module does the work, with the GIL released while
//! processing.

mod batch;
mod interrupt;
mod raa;
mod spatial;
mod wire;

use std::path::PathBuf;
use std::sync::Mutex;

use afe::npy::Dtype;
use afe::{Manager, ParamMap, Recorder, RequestHandle};
use numpy::{
    Complex32, Complex64, PyArray1, PyArrayMethods, PyReadonlyArray2, PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyFileNotFoundError, PyKeyError, PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// Maps a core error to the Python exception a user expects.
fn to_py(e: afe::Error) -> PyErr {
    match e {
        afe::Error::UnknownHandle(_) => PyKeyError::new_err(e.to_string()),
        afe::Error::Interrupted => pyo3::exceptions::PyKeyboardInterrupt::new_err(e.to_string()),
        afe::Error::WholeSignalTooLarge { .. }
        | afe::Error::WholeSignalOverMemory { .. }
        | afe::Error::AllocationFailed { .. }
        | afe::Error::OutputsTooLarge { .. } => {
            pyo3::exceptions::PyMemoryError::new_err(e.to_string())
        }
        afe::Error::WorkerPanicked | afe::Error::Stalled(_) | afe::Error::Scheduler(_) => {
            pyo3::exceptions::PyRuntimeError::new_err(e.to_string())
        }
        _ => PyValueError::new_err(e.to_string()),
    }
}

/// A Python value (a parameter's value, a store's spec) as the JSON-like value the core
/// takes: dicts with string keys, lists, strings, numbers, booleans and `None`.
fn value_of(obj: &Bound<'_, PyAny>) -> PyResult<serde_json::Value> {
    pythonize::depythonize(obj).map_err(|e| PyValueError::new_err(e.to_string()))
}

/// A request's parameters from a dict of AFE names to values (`None`: none).
fn params_of(obj: &Bound<'_, PyAny>) -> PyResult<ParamMap> {
    match value_of(obj) {
        Ok(serde_json::Value::Object(o)) => Ok(o.into_iter().collect()),
        Ok(serde_json::Value::Null) => Ok(ParamMap::new()),
        Ok(other) => Err(PyValueError::new_err(format!(
            "params must be a dict of AFE parameter names to values, not {other}"
        ))),
        Err(e) => Err(PyValueError::new_err(format!(
            "params must be a dict of AFE parameter names to values: {e}"
        ))),
    }
}

/// A description, summary or listing as Python dicts and lists.
fn py_value<'py>(py: Python<'py>, v: &impl serde::Serialize) -> PyResult<Bound<'py, PyAny>> {
    pythonize::pythonize(py, v).map_err(|e| PyValueError::new_err(e.to_string()))
}

/// Columns of a `[samples, channels]` float64 array, as owned per-ear signals.
fn columns(x: &PyReadonlyArray2<'_, f64>) -> Vec<Vec<f64>> {
    let shape = x.shape();
    let (n, ch) = (shape[0], shape[1]);
    let view = x.as_array();
    (0..ch)
        .map(|c| (0..n).map(|t| view[[t, c]]).collect())
        .collect()
}

/// A numpy array of `shape` from row-major `data`: float64, or complex128 when the
/// signal is `complex` (`data` then holds `(real, imaginary)` pairs; with no rows the
/// array is still complex128).
fn array<'py>(
    py: Python<'py>,
    shape: &[usize],
    data: &[f64],
    complex: bool,
) -> PyResult<Bound<'py, PyAny>> {
    if complex {
        let values: Vec<Complex64> = data
            .chunks_exact(2)
            .map(|c| Complex64::new(c[0], c[1]))
            .collect();
        let flat = PyArray1::from_vec(py, values);
        return Ok(flat.reshape(shape.to_vec())?.into_any());
    }
    let flat = PyArray1::from_slice(py, data);
    Ok(flat.reshape(shape.to_vec())?.into_any())
}

/// As [`array`], taking the values over: a float64 array is handed to numpy without a copy.
fn owned_array<'py>(
    py: Python<'py>,
    shape: &[usize],
    data: Vec<f64>,
    complex: bool,
) -> PyResult<Bound<'py, PyAny>> {
    if complex {
        return array(py, shape, &data, true);
    }
    Ok(PyArray1::from_vec(py, data)
        .reshape(shape.to_vec())?
        .into_any())
}

/// A run's recorded outputs, moved into numpy arrays of `dtype` (float32 arrays are
/// rounded one output at a time, each float64 history freed once converted), and their
/// descriptions.
fn recorded<'py>(
    py: Python<'py>,
    rec: afe::Recorder,
    dtype: Dtype,
) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyAny>)> {
    rec.check_dtype(dtype).map_err(to_py)?;
    let meta = py_value(py, &rec.metadata_as(dtype))?;
    let d = PyDict::new(py);
    for r in rec.into_signals() {
        let (shape, complex) = (r.shape(), r.info.is_complex());
        let values = r.data.into_vec();
        let a = match dtype {
            Dtype::Float64 => owned_array(py, &shape, values, complex)?,
            Dtype::Float32 if complex => {
                let pairs = values.chunks_exact(2);
                let v: Vec<Complex32> = pairs
                    .map(|c| Complex32::new(c[0] as f32, c[1] as f32))
                    .collect();
                PyArray1::from_vec(py, v).reshape(shape)?.into_any()
            }
            Dtype::Float32 => {
                let v: Vec<f32> = values.iter().map(|&x| x as f32).collect();
                drop(values);
                PyArray1::from_vec(py, v).reshape(shape)?.into_any()
            }
        };
        d.set_item(r.key, a)?;
    }
    Ok((d, meta))
}

/// Before a whole signal is computed: a `ResourceWarning` when its outputs would take
/// more than half of the memory available, a `MemoryError` when more than all of it
/// (see `afe::memory`).
fn check_memory(
    py: Python<'_>,
    mgr: &mut Manager,
    samples: u64,
    all: bool,
    dtype: Dtype,
) -> PyResult<()> {
    let bytes = afe::memory::output_bytes(mgr, samples, all, dtype);
    if let Some(warning) = afe::memory::check(bytes).map_err(to_py)? {
        let category = py.get_type::<pyo3::exceptions::PyResourceWarning>();
        let text = std::ffi::CString::new(warning).unwrap_or_default();
        PyErr::warn(py, &category, &text, 2)?;
    }
    Ok(())
}

/// The `dtype` asked for from Python: `"float64"` or `"float32"`.
pub(crate) fn stored_type(dtype: &str) -> PyResult<Dtype> {
    match dtype {
        "float64" => Ok(Dtype::Float64),
        "float32" => Ok(Dtype::Float32),
        other => Err(PyValueError::new_err(format!(
            "dtype = {other:?}: expected \"float64\" (as computed) or \"float32\" (rounded, half the memory)"
        ))),
    }
}

/// One output as handed to Python: its key, array shape, values and whether complex.
type Output = (String, Vec<usize>, Vec<f64>, bool);

fn signals_dict<'py, 'a>(
    py: Python<'py>,
    items: impl Iterator<Item = &'a Output>,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (key, shape, data, complex) in items {
        d.set_item(key, array(py, shape, data, *complex)?)?;
    }
    Ok(d)
}

/// What a Python `Manager` holds.
struct State {
    manager: Manager,
    /// Everything computed since creation, the last reset or `process_signal`.
    history: Recorder,
    keep_history: bool,
    /// Seconds of each output the history keeps (`None`: all).
    history_seconds: Option<f64>,
}

impl State {
    /// A fresh history, bounded as asked.
    fn new_history(&self) -> Recorder {
        let mut r = Recorder::new(false);
        r.keep_last(self.history_seconds);
        r
    }
}

impl State {
    /// The new output of the requested signals after the last chunk, as owned arrays.
    fn new_output(&self) -> Vec<Output> {
        self.manager
            .signals(false)
            .iter()
            .map(|s| {
                let mut shape = vec![s.new.frames()];
                shape.extend(s.info.frame_shape());
                (
                    s.key(),
                    shape,
                    s.new.as_slice().to_vec(),
                    s.info.is_complex(),
                )
            })
            .collect()
    }
}

/// Streaming front-end: requests placed by name, chunks in, numpy arrays out. The state
/// sits behind a mutex (Python objects may be shared between threads); it is locked
/// only while a call runs, with the GIL released. Its stop request sits outside, so that
/// another thread can cancel the call that holds the lock.
#[pyclass(name = "Manager", module = "afe._afe")]
struct PyManager {
    state: Mutex<State>,
    cancel: afe::interrupt::CancelToken,
    /// The head's yaw feed its processors read: fed without the state's lock, so that a
    /// motor controller's thread reports while a whole signal runs.
    head_pose: afe::HeadPose,
}

impl PyManager {
    /// Runs `f` on the state with the GIL released.
    fn with<R: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&mut State) -> afe::Result<R> + Send,
    ) -> PyResult<R> {
        py.allow_threads(|| self.locked(f))
    }

    /// Runs `f` on the state (the GIL is not needed).
    fn locked<R>(&self, f: impl FnOnce(&mut State) -> afe::Result<R>) -> PyResult<R> {
        let mut st = self.state.lock().map_err(|_| {
            PyValueError::new_err("this Manager was left broken by an earlier error")
        })?;
        f(&mut st).map_err(to_py)
    }

    /// Processes `x` as the next chunk, or (`whole`) as a whole signal from a fresh
    /// state; records it and returns the new output of every request.
    fn process<'py>(
        &self,
        py: Python<'py>,
        x: PyReadonlyArray2<'py, f64>,
        whole: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        let ears = columns(&x);
        let run = |st: &mut State| {
            let refs: Vec<&[f64]> = ears.iter().map(Vec::as_slice).collect();
            if whole {
                st.manager.process_signal(&refs)?;
                st.history = st.new_history();
            } else {
                st.manager.process_chunk(&refs)?;
            }
            if st.keep_history {
                st.history.record(&st.manager);
            }
            Ok(st.new_output())
        };
        let out = if whole {
            // a request to stop made before this call is not this call's, nor one made by
            // this call's Ctrl-C or cancel() the next call's
            self.cancel.clear();
            let out = interrupt::interruptible(py, &self.cancel, || self.locked(run));
            self.cancel.clear();
            out??
        } else {
            self.with(py, run)?
        };
        signals_dict(py, out.iter())
    }
}

#[pymethods]
impl PyManager {
    #[new]
    #[pyo3(signature = (fs, channels, threads, keep_history, history_seconds))]
    fn new(
        fs: f64,
        channels: usize,
        threads: usize,
        keep_history: bool,
        history_seconds: Option<f64>,
    ) -> PyResult<Self> {
        let mut history = Recorder::new(false);
        history.keep_last(history_seconds);
        let manager = Manager::with_threads(fs, channels, threads).map_err(to_py)?;
        Ok(PyManager {
            cancel: manager.cancel_token().clone(),
            head_pose: manager.head_pose().clone(),
            state: Mutex::new(State {
                manager,
                history,
                keep_history,
                history_seconds,
            }),
        })
    }

    /// Stops this manager's whole-signal call that runs now, from any thread: it raises
    /// KeyboardInterrupt; other managers run on. Without such a call, nothing happens.
    fn cancel(&self) {
        self.cancel.cancel();
    }

    /// Reports the head's yaw `yaw_deg` (deg, positive to the left) at `t_s` (s since the
    /// processors started), from any thread.
    fn set_head_yaw(&self, t_s: f64, yaw_deg: f64) -> PyResult<()> {
        self.head_pose.push(t_s, yaw_deg).map_err(to_py)
    }

    #[getter]
    fn fs(&self, py: Python<'_>) -> PyResult<f64> {
        self.with(py, |st| Ok(st.manager.fs()))
    }

    #[getter]
    fn channels(&self, py: Python<'_>) -> PyResult<usize> {
        self.with(py, |st| Ok(st.manager.ears()))
    }

    #[getter]
    fn threads(&self, py: Python<'_>) -> PyResult<usize> {
        self.with(py, |st| Ok(st.manager.threads()))
    }

    fn add_request(
        &self,
        py: Python<'_>,
        name: &str,
        params: &Bound<'_, PyAny>,
    ) -> PyResult<usize> {
        let params = params_of(params)?;
        self.with(py, |st| {
            let h = st.manager.add_request(name, &params)?;
            st.history.follow_edit(&st.manager, &[]);
            Ok(h.index())
        })
    }

    fn remove_request(&self, py: Python<'_>, handle: usize) -> PyResult<()> {
        self.with(py, |st| {
            st.manager
                .remove_request(RequestHandle::from_index(handle))?;
            // the other requests' histories go on; the removed one's rows are kept
            st.history.follow_edit(&st.manager, &[]);
            Ok(())
        })
    }

    fn modify_parameter(
        &self,
        py: Python<'_>,
        handle: usize,
        name: &str,
        value: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let value =
            value_of(value).map_err(|e| PyValueError::new_err(format!("value of {name}: {e}")))?;
        self.with(py, |st| {
            let h = RequestHandle::from_index(handle);
            st.manager.modify_parameter(h, name, value)?;
            // the edited request's outputs start a new segment (or, reshaped, a new history)
            let edited: Vec<String> = st
                .manager
                .request_signals(h)?
                .iter()
                .map(afe::Signal::key)
                .collect();
            st.history.follow_edit(&st.manager, &edited);
            Ok(())
        })
    }

    fn frames<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let map = self.with(py, |st| {
            let map: serde_json::Map<String, serde_json::Value> = st
                .manager
                .signals(false)
                .iter()
                .map(|s| {
                    let v = serde_json::json!({
                        "first_frame": s.first_frame,
                        "first_time_s": s.first_time_s,
                        "frames": s.new.frames(),
                        "fs_hz": s.info.fs_hz,
                    });
                    (s.key(), v)
                })
                .collect();
            Ok(serde_json::Value::Object(map))
        })?;
        py_value(py, &map)
    }

    fn request_outputs(&self, py: Python<'_>, handle: usize) -> PyResult<Vec<String>> {
        self.with(py, |st| {
            Ok(st
                .manager
                .request_signals(RequestHandle::from_index(handle))?
                .iter()
                .map(afe::Signal::key)
                .collect())
        })
    }

    fn request_parameters<'py>(
        &self,
        py: Python<'py>,
        handle: usize,
    ) -> PyResult<Bound<'py, PyAny>> {
        let used = self.with(py, |st| {
            st.manager
                .request_parameters(RequestHandle::from_index(handle))
        })?;
        py_value(py, &used)
    }

    fn handles(&self, py: Python<'_>) -> PyResult<Vec<usize>> {
        self.with(py, |st| {
            Ok(st.manager.handles().map(|h| h.index()).collect())
        })
    }

    fn process_chunk<'py>(
        &self,
        py: Python<'py>,
        x: PyReadonlyArray2<'py, f64>,
    ) -> PyResult<Bound<'py, PyDict>> {
        self.process(py, x, false)
    }

    fn process_signal<'py>(
        &self,
        py: Python<'py>,
        x: PyReadonlyArray2<'py, f64>,
    ) -> PyResult<Bound<'py, PyDict>> {
        self.process(py, x, true)
    }

    fn prepare(&self, py: Python<'_>, max_chunk: usize) -> PyResult<()> {
        self.with(py, |st| st.manager.prepare(max_chunk))
    }

    fn reset(&self, py: Python<'_>) -> PyResult<()> {
        self.with(py, |st| {
            st.manager.reset()?;
            st.history = st.new_history();
            Ok(())
        })
    }

    /// The history as `{name: array}`, with the arrays' descriptions.
    fn outputs<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyAny>)> {
        let (all, meta) = self.with(py, |st| {
            Ok((
                st.history
                    .signals()
                    .iter()
                    .map(|s| {
                        let data = s.data.as_slice().to_vec();
                        (s.key.clone(), s.shape(), data, s.info.is_complex())
                    })
                    .collect::<Vec<_>>(),
                st.history.metadata(),
            ))
        })?;
        let arrays = signals_dict(py, all.iter())?;
        Ok((arrays, py_value(py, &meta)?))
    }

    /// Each current output's description (`afe::metadata::describe`).
    fn describe<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let map = self.with(py, |st| {
            let map: serde_json::Map<String, serde_json::Value> = st
                .manager
                .signals(false)
                .iter()
                .map(|s| (s.key(), afe::metadata::describe(&st.manager, s)))
                .collect();
            Ok(serde_json::Value::Object(map))
        })?;
        py_value(py, &map)
    }

    fn info<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let map = self.with(py, |st| {
            let map: serde_json::Map<String, serde_json::Value> = st
                .manager
                .signals(false)
                .iter()
                .map(|s| (s.key(), afe::metadata::info_json(s.info)))
                .collect();
            Ok(serde_json::Value::Object(map))
        })?;
        py_value(py, &map)
    }

    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        self.with(py, |st| {
            Ok(format!(
                "afe.Manager(fs={}, channels={}, threads={})",
                st.manager.fs(),
                st.manager.ears(),
                st.manager.threads()
            ))
        })
    }
}

/// The job of `process` and `process_file`: no request of its own (they are placed on the
/// manager first, by [`place`]), the shared parameters for the record.
fn job(
    params: &Bound<'_, PyAny>,
    chunk: Option<usize>,
    threads: usize,
    all: bool,
) -> PyResult<afe::extract::Job> {
    Ok(afe::extract::Job {
        requests: Vec::new(),
        params: params_of(params)?,
        chunk,
        all,
        threads,
    })
}

/// One item of `afe.process`'s requests: its name and its own parameters.
type Item = (String, PyObject);

/// Places each item on `mgr` with the shared `params` under its own. An error about the
/// item (its name, its own parameters, a binaural request on mono input) names it,
/// `requests[i]: ...`; one about a shared parameter names the parameter alone.
fn place(
    py: Python<'_>,
    mgr: &mut Manager,
    items: &[Item],
    params: &afe::ParamMap,
) -> PyResult<()> {
    for (i, (name, own)) in items.iter().enumerate() {
        let own = params_of(own.bind(py))?;
        let mut merged = params.clone();
        merged.extend(own.clone());
        if let Err(e) = mgr.add_request(name, &merged) {
            let shared = match &e {
                afe::Error::UnknownParameter { name, .. }
                | afe::Error::InvalidParameter { name, .. } => {
                    !name.split('/').any(|n| own.contains_key(n))
                }
                _ => false,
            };
            if shared {
                return Err(to_py(e));
            }
            return Err(PyValueError::new_err(format!("requests[{i}]: {e}")));
        }
    }
    Ok(())
}

/// Computes `requests` on a whole signal (`afe extract`'s code path): `{name: array}`
/// and the arrays' descriptions (see `afe::metadata::describe`).
#[pyfunction]
#[pyo3(signature = (x, fs, requests, params, chunk, threads, all, dtype))]
#[allow(clippy::too_many_arguments)]
fn process<'py>(
    py: Python<'py>,
    x: PyReadonlyArray2<'py, f64>,
    fs: f64,
    requests: Vec<Item>,
    params: &Bound<'py, PyAny>,
    chunk: Option<usize>,
    threads: usize,
    all: bool,
    dtype: &str,
) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyAny>)> {
    let dtype = stored_type(dtype)?;
    let job = job(params, chunk, threads, all)?;
    let mut mgr = Manager::with_threads(fs, x.shape()[1], threads).map_err(to_py)?;
    place(py, &mut mgr, &requests, &job.params)?;
    check_memory(py, &mut mgr, x.shape()[0] as u64, all, dtype)?;
    let ears = columns(&x);
    let cancel = mgr.cancel_token().clone();
    let rec = interrupt::interruptible(py, &cancel, || {
        let refs: Vec<&[f64]> = ears.iter().map(Vec::as_slice).collect();
        afe::extract::run_with(&mut mgr, &job, &refs)
    })?
    .map_err(to_py)?;
    drop(ears);
    recorded(py, rec, dtype)
}

/// As [`process`] on the WAV file at `path`, decoded block by block where the graph
/// allows (the file is never held whole), with `fs` (if given) checked against the file's.
#[pyfunction]
#[pyo3(signature = (path, fs, requests, params, chunk, threads, all, dtype))]
#[allow(clippy::too_many_arguments)]
fn process_file<'py>(
    py: Python<'py>,
    path: PathBuf,
    fs: Option<f64>,
    requests: Vec<Item>,
    params: &Bound<'py, PyAny>,
    chunk: Option<usize>,
    threads: usize,
    all: bool,
    dtype: &str,
) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyAny>)> {
    let dtype = stored_type(dtype)?;
    let job = job(params, chunk, threads, all)?;
    let mut wav = afe::wav::WavBlocks::open(&path).map_err(wav_error)?;
    if let Some(fs) = fs.filter(|f| *f != wav.fs()) {
        return Err(PyValueError::new_err(format!(
            "fs = {fs} Hz, but '{}' is sampled at {} Hz",
            path.display(),
            wav.fs()
        )));
    }
    afe::wav::check_input(&path, &wav).map_err(to_py)?;
    let mut mgr = Manager::with_threads(wav.fs(), wav.channels(), threads).map_err(to_py)?;
    place(py, &mut mgr, &requests, &job.params)?;
    check_memory(py, &mut mgr, wav.frames(), all, dtype)?;
    let cancel = mgr.cancel_token().clone();
    let rec = interrupt::interruptible(py, &cancel, || {
        afe::extract::run_wav(&mut mgr, &job, &mut wav)
    })?
    .map_err(to_py)?;
    recorded(py, rec, dtype)
}

/// The Python exception for a WAV file that cannot be read.
fn wav_error(e: afe::wav::WavError) -> PyErr {
    match &e {
        afe::wav::WavError::Open { source, .. }
            if source.kind() == std::io::ErrorKind::NotFound =>
        {
            PyFileNotFoundError::new_err(e.to_string())
        }
        afe::wav::WavError::Open { .. } => PyOSError::new_err(e.to_string()),
        afe::wav::WavError::Format { .. } => PyValueError::new_err(e.to_string()),
    }
}

/// The catalogue of requests and parameters (`afe list --json`).
#[pyfunction]
fn catalog(py: Python<'_>) -> PyResult<Bound<'_, PyAny>> {
    py_value(py, &afe::catalog::listing())
}

/// The machine and instruction set this runs on (`afe bench`'s `host`).
#[pyfunction]
fn host(py: Python<'_>) -> PyResult<Bound<'_, PyAny>> {
    // the cores' round trip is measured with two threads spinning a few ms
    let host = py.allow_threads(afe::host::Host::detect);
    py_value(py, &host)
}

/// Reads a WAV file: `(samples as a [samples, channels] float64 array, fs in Hz)`.
#[pyfunction]
fn read_wav<'py>(py: Python<'py>, path: PathBuf) -> PyResult<(Bound<'py, PyAny>, f64)> {
    let audio = py
        .allow_threads(|| afe::wav::read_wav(&path))
        .map_err(wav_error)?;
    let ch = audio.channels.len();
    let n = audio.channels.first().map_or(0, Vec::len);
    let mut interleaved = Vec::with_capacity(n * ch);
    for t in 0..n {
        interleaved.extend(audio.channels.iter().map(|c| c[t]));
    }
    Ok((array(py, &[n, ch], &interleaved, false)?, audio.fs))
}

/// The compiled core of the `afe` package.
#[pymodule]
fn _afe(m: &Bound<'_, PyModule>) -> PyResult<()> {
    // load numpy's C API now: loaded lazily, its import fails inside a first call that a
    // pending Ctrl-C interrupts (a PanicException instead of KeyboardInterrupt)
    numpy::PyArray1::<f64>::zeros(m.py(), 0, false);
    m.add_class::<PyManager>()?;
    m.add_function(wrap_pyfunction!(catalog, m)?)?;
    m.add_function(wrap_pyfunction!(host, m)?)?;
    m.add_function(wrap_pyfunction!(process, m)?)?;
    m.add_function(wrap_pyfunction!(process_file, m)?)?;
    m.add_function(wrap_pyfunction!(read_wav, m)?)?;
    m.add_function(wrap_pyfunction!(raa::raa, m)?)?;
    m.add_function(wrap_pyfunction!(spatial::locate, m)?)?;
    m.add_function(wrap_pyfunction!(spatial::render, m)?)?;
    m.add_function(wrap_pyfunction!(spatial::transfer, m)?)?;
    m.add_function(wrap_pyfunction!(spatial::heads, m)?)?;
    m.add_function(wrap_pyfunction!(batch::batch_run, m)?)?;
    m.add_function(wrap_pyfunction!(batch::batch_plan, m)?)?;
    m.add_function(wrap_pyfunction!(batch::batch_compute, m)?)?;
    m.add_function(wrap_pyfunction!(batch::store_status, m)?)?;
    m.add_function(wrap_pyfunction!(batch::store_read, m)?)?;
    m.add_function(wrap_pyfunction!(batch::save_zarr, m)?)?;
    m.add_function(wrap_pyfunction!(batch::load_zarr, m)?)?;
    m.add_function(wrap_pyfunction!(batch::check_zarr, m)?)?;
    m.add_function(wrap_pyfunction!(wire::wire_read_audio, m)?)?;
    m.add_function(wrap_pyfunction!(wire::wire_read_frames, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
