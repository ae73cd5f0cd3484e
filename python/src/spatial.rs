//! `afe.locate`, `afe.render` and `afe.heads`: head models and localisation
//! (`afe-spatial`) on numpy arrays.

use afe_spatial::{Head, HeadYaw, LocaliserParams, Neck, SpatialError, TrackerParams};
use numpy::{
    Complex64, PyArray1, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods,
};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::columns;

fn value_error(e: SpatialError) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// The sources of the `[samples, 2]` signal `x` at `fs` Hz as `head` hears them: a dict
/// of `sources` (a list of dicts with `azimuth_deg` and `salience`), per frame `t_s`,
/// `active`, `azimuth_deg` and `yaw_deg` (arrays), and the score grid `azimuths_deg`
/// with the active frames' `mean_score`; in the world with the `[points, 2]` track
/// `head_yaw` of `(t_s, yaw_deg)`; with `track`, the sources tracked over time
/// (`tracked`: a list of dicts of `t_s`, `yaw_deg`, `tracks` (each a dict of `id`,
/// `azimuth_deg`, `uncertainty_deg`, `mass`, `velocity_deg_s`, `seen_s` and `resolved`)
/// and `suggested_turn` (`None` or a dict of `turn_deg`, `target_yaw_deg`, `why` and the
/// track `ids` or `id`, for a neck turning ±90 deg)).
#[pyfunction]
#[pyo3(signature = (x, fs, head, sources, head_yaw, track))]
pub fn locate<'py>(
    py: Python<'py>,
    x: PyReadonlyArray2<'py, f64>,
    fs: f64,
    head: &str,
    sources: Option<usize>,
    head_yaw: Option<PyReadonlyArray2<'py, f64>>,
    track: bool,
) -> PyResult<Bound<'py, PyDict>> {
    if x.shape()[1] != 2 {
        return Err(PyValueError::new_err(format!(
            "x has {} channel(s): locating needs two (left ear, right ear)",
            x.shape()[1]
        )));
    }
    let head = Head::parse(head).map_err(value_error)?;
    let yaw = match &head_yaw {
        Some(track) => {
            let [t, yaw]: [Vec<f64>; 2] = columns(track).try_into().map_err(|c: Vec<_>| {
                PyValueError::new_err(format!(
                    "head_yaw has {} column(s): rows of (t_s, yaw_deg)",
                    c.len()
                ))
            })?;
            let points: Vec<(f64, f64)> = t.into_iter().zip(yaw).collect();
            Some(HeadYaw::new(&points).map_err(value_error)?)
        }
        None => None,
    };
    let ears = columns(&x);
    let found = py
        .allow_threads(|| {
            afe_spatial::locate(
                &head,
                [&ears[0], &ears[1]],
                fs,
                &LocaliserParams::default(),
                sources,
                yaw.as_ref(),
            )
        })
        .map_err(value_error)?;
    let tracked = match track {
        true => Some(
            py.allow_threads(|| {
                afe_spatial::track(&found, &TrackerParams::default(), &Neck::default())
            })
            .map_err(value_error)?,
        ),
        false => None,
    };
    let out = PyDict::new(py);
    out.set_item("head", head.name())?;
    let list = PyList::empty(py);
    for s in &found.sources {
        let d = PyDict::new(py);
        d.set_item("azimuth_deg", s.azimuth_deg)?;
        d.set_item("salience", s.salience)?;
        list.append(d)?;
    }
    out.set_item("sources", list)?;
    let frames = &found.frames;
    let column = |f: fn(&afe_spatial::locate::Frame) -> f64| frames.iter().map(f).collect();
    out.set_item("t_s", PyArray1::from_vec(py, column(|f| f.t_s)))?;
    out.set_item(
        "azimuth_deg",
        PyArray1::from_vec(py, column(|f| f.azimuth_deg)),
    )?;
    out.set_item("yaw_deg", PyArray1::from_vec(py, column(|f| f.yaw_deg)))?;
    let active: Vec<bool> = frames.iter().map(|f| f.active).collect();
    out.set_item("active", PyArray1::from_vec(py, active))?;
    out.set_item("azimuths_deg", PyArray1::from_vec(py, found.azimuths_deg))?;
    if let Some(tracked) = tracked {
        out.set_item("tracked", crate::py_value(py, &tracked)?)?;
    }
    out.set_item("mean_score", PyArray1::from_vec(py, found.mean_score))?;
    Ok(out)
}

/// The mono `x` at `fs` Hz as the two ears of `head` hear it from `azimuth_deg`:
/// `[samples, 2]`.
#[pyfunction]
pub fn render<'py>(
    py: Python<'py>,
    x: PyReadonlyArray1<'py, f64>,
    fs: f64,
    head: &str,
    azimuth_deg: f64,
) -> PyResult<Bound<'py, PyAny>> {
    let head = Head::parse(head).map_err(value_error)?;
    let mono = x.as_slice()?.to_vec();
    if let Some(t) = mono.iter().position(|v| !v.is_finite()) {
        return Err(PyValueError::new_err(format!("sample {t} is NaN or Inf")));
    }
    let [l, r] = py
        .allow_threads(|| head.render(azimuth_deg, &mono, fs))
        .map_err(value_error)?;
    let data: Vec<f64> = l.iter().zip(&r).flat_map(|(a, b)| [*a, *b]).collect();
    Ok(PyArray1::from_vec(py, data)
        .reshape(vec![l.len(), 2])?
        .into_any())
}

/// The transfer functions of `head` to the left and the right ear from `azimuth_deg`
/// at each of `freqs_hz`, relative to the free field at the head's centre, in the DFT's
/// sign convention (a delay τ is `e^{−iωτ}`): complex `[freqs, 2]`.
#[pyfunction]
pub fn transfer<'py>(
    py: Python<'py>,
    freqs_hz: PyReadonlyArray1<'py, f64>,
    head: &str,
    azimuth_deg: f64,
) -> PyResult<Bound<'py, PyAny>> {
    let head = Head::parse(head).map_err(value_error)?;
    let freqs = freqs_hz.as_slice()?.to_vec();
    let top = head.max_frequency_hz();
    if let Some(f) = freqs
        .iter()
        .find(|f| !(f.is_finite() && **f >= 0.0 && **f <= top))
    {
        return Err(PyValueError::new_err(format!(
            "frequency {f} Hz: the head {} has transfer functions from 0 to {top} Hz",
            head.name()
        )));
    }
    if !azimuth_deg.is_finite() {
        return Err(PyValueError::new_err(format!(
            "azimuth {azimuth_deg} deg is not finite"
        )));
    }
    let h = py.allow_threads(|| head.transfer(azimuth_deg, &freqs));
    let data: Vec<Complex64> = h
        .iter()
        .flatten()
        .map(|c| Complex64::new(c.re, c.im))
        .collect();
    Ok(PyArray1::from_vec(py, data)
        .reshape(vec![freqs.len(), 2])?
        .into_any())
}

/// The heads named without a file: `(name, description)` pairs.
#[pyfunction]
pub fn heads() -> Vec<(&'static str, &'static str)> {
    afe_spatial::head::BUILT_IN.to_vec()
}
