//! The RAA's outer- and middle-ear stage, van Dorp Schuitman's headphone filter (the AFE's
//! `headphonefilter_Dorp2011`): a first-order Butterworth high-pass at 1 kHz, then a
//! first-order low-pass at 4 kHz, each scaled by the square root of the inverse of the
//! pair's peak gain, so that the cascade peaks at unity.

use afe_core::butter::{butter, ButterType};
use afe_core::filter::Df2t;

/// Cut-off of the high-pass, Hz.
pub const HIGH_PASS_HZ: f64 = 1000.0;
/// Cut-off of the low-pass, Hz.
pub const LOW_PASS_HZ: f64 = 4000.0;

/// Points of the frequency grid on which the peak gain is taken: MATLAB's `freqz`
/// default, `k·π/512` rad/sample for k = 0 … 511 (Nyquist excluded).
const GRID_POINTS: usize = 512;

/// The two filters `(b, a)`, high-pass first, scaled as the AFE scales them, at `fs` Hz
/// (above `2 · LOW_PASS_HZ`, which the caller checks).
pub fn design(fs: f64) -> [(Vec<f64>, Vec<f64>); 2] {
    let nyquist = fs / 2.0;
    let (b1, a1) = butter(1, &[HIGH_PASS_HZ / nyquist], ButterType::High);
    let (b2, a2) = butter(1, &[LOW_PASS_HZ / nyquist], ButterType::Low);
    let peak = (0..GRID_POINTS)
        .map(|k| {
            let w = std::f64::consts::PI * k as f64 / GRID_POINTS as f64;
            magnitude(&b1, &a1, w) * magnitude(&b2, &a2, w)
        })
        .fold(0.0, f64::max);
    let scale = (1.0 / peak).sqrt();
    let scaled = |b: Vec<f64>| b.into_iter().map(|v| v * scale).collect();
    [(scaled(b1), a1), (scaled(b2), a2)]
}

/// `|B(e^{iw}) / A(e^{iw})|` of the filter `(b, a)` at `w` rad/sample.
fn magnitude(b: &[f64], a: &[f64], w: f64) -> f64 {
    let at = |p: &[f64]| {
        let (re, im) = p.iter().enumerate().fold((0.0, 0.0), |(re, im), (k, c)| {
            let phase = w * k as f64;
            (re + c * phase.cos(), im - c * phase.sin())
        });
        re.hypot(im)
    };
    at(b) / at(a)
}

/// `left` and `right` through the filters of [`design`], as MATLAB's `filter` runs them
/// (transposed direct form II, zero initial state): the two ears, `[left, right]`.
pub fn apply(fs: f64, left: &[f64], right: &[f64]) -> [Vec<f64>; 2] {
    let mut rows: Vec<f64> = left.iter().zip(right).flat_map(|(l, r)| [*l, *r]).collect();
    for (b, a) in design(fs) {
        Df2t::new(&b, &a, 2).process(&mut rows);
    }
    [
        rows.iter().step_by(2).copied().collect(),
        rows.iter().skip(1).step_by(2).copied().collect(),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cascade_peaks_at_unity_and_passes_the_band_between_the_cut_offs() {
        let fs = 16000.0;
        let [(b1, a1), (b2, a2)] = design(fs);
        let gain = |f: f64| {
            let w = 2.0 * std::f64::consts::PI * f / fs;
            magnitude(&b1, &a1, w) * magnitude(&b2, &a2, w)
        };
        let peak = (0..GRID_POINTS)
            .map(|k| gain(k as f64 * fs / 2.0 / GRID_POINTS as f64))
            .fold(0.0, f64::max);
        assert!((peak - 1.0).abs() < 1e-12, "peak {peak}");
        // first order: about -3 dB re the peak near each cut-off, far lower outside
        assert!(gain(2000.0) > 0.9);
        assert!(gain(50.0) < 0.1 && gain(7900.0) < 0.2);
        // both filters take the same scale, the square root of the inverse peak
        let s1 = b1[0] / butter(1, &[0.125], ButterType::High).0[0];
        let s2 = b2[0] / butter(1, &[0.5], ButterType::Low).0[0];
        assert!((s1 - s2).abs() < 1e-14, "{s1} {s2}");
    }

    #[test]
    fn apply_filters_each_ear_alone() {
        let fs = 16000.0;
        let x: Vec<f64> = (0..400).map(|t| (0.7 * t as f64).sin()).collect();
        let zero = vec![0.0; 400];
        let [l, r] = apply(fs, &x, &zero);
        assert!(r.iter().all(|v| *v == 0.0));
        let [l2, _] = apply(fs, &x, &x);
        assert_eq!(l, l2);
    }
}
