//! The wire format of `afe serve`'s messages, decoded by afe-net's own reader for
//! Python's Zenoh client (`afe.remote`), which only carries the bytes.

use afe_net::wire::{self, Header};
use numpy::{IntoPyArray, PyArray1};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// A header as Python's client reads it: `(seq, first_input_frame, input_frames, count,
/// t_ns)`.
type HeaderTuple = (u64, u64, u32, u32, u64);

fn header_tuple(h: &Header) -> HeaderTuple {
    (h.seq, h.first_input_frame, h.input_frames, h.count, h.t_ns)
}

fn to_py(e: wire::WireError) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// An audio message: its header and its samples, interleaved (`[frames * count]`).
/// ValueError for a message that does not follow the wire format.
#[pyfunction]
pub fn wire_read_audio<'py>(
    py: Python<'py>,
    data: &[u8],
) -> PyResult<(HeaderTuple, Bound<'py, PyArray1<f64>>)> {
    let (h, samples) = wire::read_audio(data).map_err(to_py)?;
    Ok((header_tuple(&h), samples.into_pyarray(py)))
}

/// A frames message: its header and, per signal, `(first_frame, rows, width, values)`
/// with the values time-major (`[rows * width]`). ValueError for a message that does not
/// follow the wire format.
#[pyfunction]
#[allow(clippy::type_complexity)]
pub fn wire_read_frames<'py>(
    py: Python<'py>,
    data: &[u8],
) -> PyResult<(
    HeaderTuple,
    Vec<(u64, usize, usize, Bound<'py, PyArray1<f64>>)>,
)> {
    let (h, parts) = wire::read_frames(data).map_err(to_py)?;
    let parts = parts
        .into_iter()
        .map(|p| (p.first_frame, p.rows, p.width, p.values.into_pyarray(py)))
        .collect();
    Ok((header_tuple(&h), parts))
}
