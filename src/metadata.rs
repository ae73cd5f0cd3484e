//! What an output array's axes mean, as JSON: its kind, rates, centre frequencies, lags,
//! feature names. Python's signal info and the corpus store's array attributes use it.

use afe_core::{SignalInfo, SignalKind};
use serde_json::{json, Value};

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
/// in Hz, lags in seconds, modulation frequencies, feature names, DUET bins, frame shape.
///
/// ```
/// let info = afe::SignalInfo::time_frequency(16000.0, vec![100.0, 200.0]);
/// let v = afe::metadata::info_json(&info);
/// assert_eq!(v["kind"], "time-frequency");
/// assert_eq!(v["frame_shape"], serde_json::json!([2]));
/// ```
pub fn info_json(info: &SignalInfo) -> Value {
    json!({
        "kind": kind_name(info.kind),
        "afe_class": info.kind.afe_class(),
        "axes": info.kind.axes(),
        "dtype": if info.is_complex() { "complex128" } else { "float64" },
        "fs_hz": info.fs_hz,
        "audio_fs_hz": info.audio_fs_hz,
        "cf_hz": info.cf_hz,
        "lags_s": info.lags_s,
        "mod_cf_hz": info.mod_cf_hz,
        "features": info.features,
        "alpha": info.alpha,
        "delta_samples": info.delta_samples,
        "frame_shape": info.frame_shape(),
    })
}
