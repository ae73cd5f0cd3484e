//! What an output array's axes mean, as JSON: its kind, rates, centre frequencies, lags,
//! feature names, and (for a whole description) its framing and the parameters it was
//! computed with. Python's signal objects, the `.npz` metadata entry and the corpus
//! store's array attributes use it.

use afe_core::{Axis, SignalInfo, SignalKind};
use afe_graph::{Manager, Signal};
use serde_json::{json, Map, Value};

/// The kind's name in this JSON (`time-frequency`, `correlation`, ...).
pub fn kind_name(kind: SignalKind) -> &'static str {
    match kind {
        SignalKind::TimeDomain => "time-domain",
        SignalKind::TimeFrequency => "time-frequency",
        SignalKind::Correlation => "correlation",
        SignalKind::Modulation => "modulation",
        SignalKind::Feature => "feature",
        SignalKind::Spectrum => "spectrum",
        SignalKind::BinaryMask => "binary-mask",
        SignalKind::DuetHistogram => "duet-histogram",
    }
}

/// `info` as a JSON object: kind, AFE class, axes, dtype, rates in Hz, centre frequencies
/// in Hz, lags in seconds, modulation frequencies, feature names, DUET bins, frame shape,
/// and what the signal says of itself: `unit` of the values (empty where the AFE has
/// none), `window_s` and `hop_s` of framed signals (`null` for sample-rate ones) and
/// `display`, how it is best drawn (`{"draw": "signed"}`, `{"draw": "power-decibels",
/// "range_db": 60.0}`, ...).
///
/// ```
/// let info = afe::SignalInfo::time_frequency(16000.0, vec![100.0, 200.0]);
/// let v = afe::metadata::info_json(&info);
/// assert_eq!(v["kind"], "time-frequency");
/// assert_eq!(v["frame_shape"], serde_json::json!([2]));
/// ```
pub fn info_json(info: &SignalInfo) -> Value {
    let values = |name: &str| info.axis(name).and_then(Axis::values).unwrap_or_default();
    json!({
        "kind": kind_name(info.kind),
        "afe_class": info.kind.afe_class(),
        "axes": info.axis_names(),
        "dtype": if info.is_complex() { "complex128" } else { "float64" },
        "fs_hz": info.fs_hz,
        "audio_fs_hz": info.audio_fs_hz,
        "cf_hz": info.cf_hz(),
        "lags_s": info.lags_s(),
        "mod_cf_hz": info.mod_cf_hz(),
        "features": info.features(),
        "alpha": values("alpha"),
        "delta_samples": values("delta"),
        "frame_axes": info.axes,
        "frame_shape": info.frame_shape(),
        "unit": info.unit,
        "window_s": info.window_s,
        "hop_s": info.hop_s(),
        "display": info.display,
        "plan": info.plan(),
    })
}

/// Everything known about signal `s` of `manager`, as JSON: [`info_json`]'s fields plus
/// `key`, `name`, `ear`, `instance`, `first_frame` and `first_time_s` (where its rows
/// start in the stream: row `k` is at `first_time_s + k / fs_hz`), `n_channels`,
/// `processors` (the chain's request names, nearest first, each once) and `parameters`
/// (the whole chain's effective parameters, derived ones such as `fb_delaySec` included).
///
/// ```
/// let mut mgr = afe::Manager::new(16000.0, 2)?;
/// mgr.add_request("ild", &afe::ParamMap::new())?;
/// mgr.process_chunk(&[&[0.0; 1600], &[0.0; 1600]])?;
/// let s = &mgr.signals(false)[0];
/// let d = afe::metadata::describe(&mgr, s);
/// assert_eq!(d["key"], "ild_mono");
/// assert_eq!(d["unit"], "dB");
/// assert_eq!(d["window_s"], 0.02);
/// assert_eq!(d["hop_s"], 0.01);
/// assert_eq!(d["parameters"]["fb_nChannels"], 31);
/// assert_eq!(d["processors"], serde_json::json!(["ild", "innerhaircell", "filterbank", "time"]));
/// # Ok::<(), afe::Error>(())
/// ```
pub fn describe(manager: &Manager, s: &Signal<'_>) -> Value {
    let chain = manager.signal_chain(s.source);
    let mut parameters = Map::new();
    for (_, params) in chain.iter().rev() {
        parameters.extend(params.iter().map(|(k, v)| (k.clone(), v.clone())));
    }
    let mut processors: Vec<&str> = Vec::new();
    for (name, _) in &chain {
        if !processors.contains(name) {
            processors.push(name);
        }
    }
    let mut d = info_json(s.info);
    if let Value::Object(m) = &mut d {
        m.extend([
            ("key".to_string(), json!(s.key())),
            ("name".to_string(), json!(s.name)),
            ("ear".to_string(), json!(s.channel.as_str())),
            ("instance".to_string(), json!(s.instance)),
            ("first_frame".to_string(), json!(s.first_frame)),
            ("first_time_s".to_string(), json!(s.first_time_s)),
            ("n_channels".to_string(), json!(s.info.cf_hz().len())),
            ("processors".to_string(), json!(processors)),
            ("parameters".to_string(), Value::Object(parameters)),
            ("nan_where".to_string(), json!(s.info.nan_where)),
        ]);
    }
    d
}
