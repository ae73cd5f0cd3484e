//! `afe.raa`: the AFE's Room Acoustic Analyzer (`afeRAA`) on a binaural array.

use afe::raa::{RaaConstants, RaaError};
use numpy::{PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::{PyMemoryError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::{columns, interrupt, owned_array, params_of, to_py};

/// The Python exception for an RAA error: the AFE's own mapping for the processing
/// under it (an interrupt is a KeyboardInterrupt), `ValueError` for the input and the
/// constants.
fn raa_error(e: RaaError) -> PyErr {
    match e {
        RaaError::TooLarge { .. }
        | RaaError::Afe(afe::Error::AllocationFailed { .. })
        | RaaError::Afe(afe::Error::WholeSignalOverMemory { .. }) => {
            PyMemoryError::new_err(e.to_string())
        }
        RaaError::Afe(e) => to_py(e),
        e => PyValueError::new_err(e.to_string()),
    }
}

/// `(par, psi)` of `afeRAA(x, fs, parConf)` for the `[samples, 2]` signal `x` at `fs`
/// Hz, with the constants of the dict `constants` (AFE names) over the AFE's: `par` maps each
/// predictor to a float; `psi` maps each array to a numpy array and `fs` (float),
/// `numSamples`, `numBands`, `itdNumFrames` (ints).
#[pyfunction]
pub fn raa<'py>(
    py: Python<'py>,
    x: PyReadonlyArray2<'py, f64>,
    fs: f64,
    constants: &Bound<'py, PyAny>,
) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyDict>)> {
    let constants = RaaConstants::from_params(&params_of(constants)?).map_err(raa_error)?;
    if x.shape()[1] != 2 {
        return Err(raa_error(RaaError::NotBinaural(x.shape()[1])));
    }
    let ears = columns(&x);
    // the analysis watches no stop request: a signal is raised once it ends
    let out = interrupt::interruptible(py, &afe::interrupt::CancelToken::new(), || {
        let refs: Vec<&[f64]> = ears.iter().map(Vec::as_slice).collect();
        afe::raa::raa(&refs, fs, &constants)
    })?
    .map_err(raa_error)?;
    drop(ears);
    let par = PyDict::new(py);
    for f in out.par.fields() {
        par.set_item(f.name, f.value)?;
    }
    let psi = PyDict::new(py);
    let (fs, samples, bands, frames) = (
        out.psi.fs,
        out.psi.num_samples,
        out.psi.num_bands,
        out.psi.itd_num_frames,
    );
    // each array moves into numpy, not copied: Psi and its streams are held once
    for (name, shape, data) in out.psi.into_arrays() {
        psi.set_item(name, owned_array(py, &shape, data, false)?)?;
    }
    psi.set_item("fs", fs)?;
    psi.set_item("numSamples", samples)?;
    psi.set_item("numBands", bands)?;
    psi.set_item("itdNumFrames", frames)?;
    Ok((par, psi))
}
