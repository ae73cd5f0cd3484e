//! Middle-ear FIR designs of the preProc (spec 10-preProc): `'jepsen'` (linear phase)
//! and `'lopezpoveda'` (minimum phase), 513 taps, designed with MATLAB's `fir2`.

use std::f64::consts::PI;

use afe_core::fir2::fir2;
use afe_core::hilbert::Hilbert;
use num_complex::Complex64;

afe_core::choices! {
    /// The middle-ear filter's design (spec 10-preProc).
    pub enum MiddleEarModel {
        /// Jepsen et al. (2008): linear phase.
        Jepsen = "jepsen",
        /// Lopez-Poveda & Meddis (2001): minimum phase.
        LopezPoveda = "lopezpoveda",
    }
}

/// FIR order of both designs.
const ORDER: usize = 512;

/// Stapes data of Jepsen et al. (2008): frequency Hz → value (inverted before use).
const JEPSEN: &[(f64, f64)] = &[
    (50.0, 48046.39731),
    (100.0, 24023.19865),
    (200.0, 12011.59933),
    (400.0, 6005.799663),
    (600.0, 3720.406871),
    (800.0, 2866.404385),
    (1000.0, 3363.247811),
    (1200.0, 4379.228921),
    (1400.0, 4804.639731),
    (1600.0, 5732.808769),
    (1800.0, 6228.236688),
    (2000.0, 7206.959596),
    (2200.0, 9172.494031),
    (2400.0, 9554.681282),
    (2600.0, 10779.64042),
    (2800.0, 12011.59933),
    (3000.0, 14013.53255),
    (3500.0, 16015.46577),
    (4000.0, 18017.39899),
    (4500.0, 23852.82136),
    (5000.0, 21020.29882),
    (5500.0, 22931.23508),
    (6000.0, 28027.06509),
    (6500.0, 28745.70779),
    (7000.0, 32098.9),
    (7500.0, 34504.4),
    (8000.0, 36909.9),
    (8500.0, 39315.4),
    (9000.0, 41720.9),
    (9500.0, 44126.4),
    (10000.0, 46531.9),
];

/// Peak-to-peak stapes displacement in µm (Goode et al. 1994, via Lopez-Poveda & Meddis).
const GOODE: &[(f64, f64)] = &[
    (400.0, 0.19953),
    (600.0, 0.22909),
    (800.0, 0.21878),
    (1000.0, 0.15136),
    (1200.0, 0.10000),
    (1400.0, 0.07943),
    (1600.0, 0.05754),
    (1800.0, 0.04365),
    (2000.0, 0.03311),
    (2200.0, 0.02754),
    (2400.0, 0.02188),
    (2600.0, 0.01820),
    (2800.0, 0.01445),
    (3000.0, 0.01259),
    (3500.0, 0.00900),
    (4000.0, 0.00700),
    (4500.0, 0.00457),
    (5000.0, 0.00500),
    (5500.0, 0.00400),
    (6000.0, 0.00300),
    (6500.0, 0.00275),
];

/// Velocities extrapolated below 400 Hz and above 6500 Hz.
const LOPEZ_BELOW: &[(f64, f64)] = &[(100.0, 1.181e-9), (200.0, 2.363e-9)];
const LOPEZ_ABOVE: &[(f64, f64)] = &[
    (7000.0, 8.705e-10),
    (7500.0, 8.000e-10),
    (8000.0, 7.577e-10),
    (8500.0, 7.168e-10),
    (9000.0, 6.781e-10),
    (9500.0, 6.240e-10),
    (10000.0, 6.000e-10),
];

/// Gain in dB that brings each design's peak to about 0 dB (`pp_bUnityComp`).
pub fn unity_comp_db(model: MiddleEarModel) -> f64 {
    match model {
        MiddleEarModel::LopezPoveda => 66.2888,
        MiddleEarModel::Jepsen => 55.9986,
    }
}

/// Magnitude spectrum of `b` by an FFT of its own length (no padding).
fn spectrum(b: &[f64]) -> Vec<Complex64> {
    let mut x: Vec<Complex64> = b.iter().map(|v| Complex64::new(*v, 0.0)).collect();
    afe_fft::forward(x.len()).process(&mut x);
    x
}

/// The `'jepsen'` design at `fs` Hz (513 taps, linear phase, peak ≈ −56 dB).
pub fn jepsen(fs: f64) -> Vec<f64> {
    let rows = JEPSEN.iter().filter(|(f, _)| fs > 20000.0 || *f < fs / 2.0);
    let mut f = vec![0.0];
    let mut m = vec![0.0];
    for (fr, v) in rows {
        f.push(fr * (2.0 / fs));
        m.push(1.0 / v);
    }
    f.push(1.0);
    m.push(0.0);
    let b = fir2(ORDER, &f, &m);
    let peak = spectrum(&b).iter().fold(0.0f64, |a, v| a.max(v.norm()));
    b.iter()
        .map(|v| v / peak * 1e-8 * 10f64.powf(104.0 / 20.0))
        .collect()
}

/// The `'lopezpoveda'` design at `fs` Hz (513 taps, minimum phase).
pub fn lopezpoveda(fs: f64) -> Vec<f64> {
    let mut rows: Vec<(f64, f64)> = LOPEZ_BELOW.to_vec();
    rows.extend(GOODE.iter().map(|(f, d)| {
        (
            *f,
            d * 1e-6 * 2.0 * PI * f * 10f64.powf(-104.0 / 20.0) * 2f64.sqrt(),
        )
    }));
    rows.extend_from_slice(LOPEZ_ABOVE);
    let nyq = fs / 2.0;
    if fs <= 20000.0 {
        rows.retain(|(f, _)| *f < nyq);
    } else {
        let extra = ((nyq - 10000.0) / 1000.0).floor() as usize;
        for _ in 0..extra {
            let (f, v) = rows[rows.len() - 1];
            rows.push((f + 1000.0, v / 1.1));
        }
    }
    let (last_f, last_v) = rows[rows.len() - 1];
    if last_f != nyq {
        rows.push((nyq, last_v / (1.0 + (nyq - last_f) * 0.1 / 1000.0)));
    }
    let mut f = vec![0.0];
    let mut m = vec![0.0];
    for (fr, v) in &rows {
        f.push(fr * 2.0 / fs);
        m.push(*v);
    }
    let b: Vec<f64> = fir2(ORDER, &f, &m).iter().map(|v| v / 20e-6).collect();
    // minimum phase: |X|·exp(−i·Im(hilbert(ln|X|)))
    let x = spectrum(&b);
    let log_mag: Vec<f64> = x.iter().map(|v| v.norm().ln()).collect();
    let mut hilbert = Hilbert::new();
    let phase: Vec<f64> = hilbert
        .analytic(log_mag.iter().copied())
        .iter()
        .map(|v| v.im)
        .collect();
    let mut xmin: Vec<Complex64> = x
        .iter()
        .zip(&phase)
        .map(|(v, ph)| Complex64::from_polar(v.norm(), -ph))
        .collect();
    afe_fft::inverse(xmin.len()).process(&mut xmin);
    let n = xmin.len() as f64;
    xmin.iter().map(|v| v.re / n).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn peak_db(b: &[f64]) -> f64 {
        let mut padded = b.to_vec();
        padded.resize(8192, 0.0);
        let peak = spectrum(&padded)
            .iter()
            .fold(0.0f64, |a, v| a.max(v.norm()));
        20.0 * peak.log10()
    }

    #[test]
    fn at_20_khz_jepsen_drops_the_row_at_nyquist() {
        // Up to 20 kHz only rows below Nyquist are kept, so at exactly 20 kHz the 10-kHz
        // row goes: the design is then the limit of the designs just below 20 kHz.
        let at = jepsen(20000.0);
        let below = jepsen(20000.0 * (1.0 - 1e-12));
        let peak = at.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (a, b) in at.iter().zip(&below) {
            assert!((a - b).abs() <= 1e-8 * peak, "{a} vs {b}");
        }
    }

    #[test]
    fn jepsen_peaks_near_minus_56_db_and_is_linear_phase() {
        for fs in [16000.0, 44100.0] {
            let b = jepsen(fs);
            assert_eq!(b.len(), 513);
            for k in 0..513 {
                assert!((b[k] - b[512 - k]).abs() <= 1e-12 * b[256].abs());
            }
            let p = peak_db(&b) + unity_comp_db(MiddleEarModel::Jepsen);
            assert!(p.abs() < 0.05, "fs {fs}: compensated peak {p} dB");
        }
    }

    #[test]
    fn lopezpoveda_is_minimum_phase_with_compensated_peak_near_0_db() {
        let b = lopezpoveda(44100.0);
        assert_eq!(b.len(), 513);
        // minimum phase: energy concentrated at the start
        let e: f64 = b.iter().map(|v| v * v).sum();
        let head: f64 = b[..64].iter().map(|v| v * v).sum();
        assert!(head > 0.9 * e, "{head} of {e}");
        let p = peak_db(&b) + unity_comp_db(MiddleEarModel::LopezPoveda);
        assert!(p.abs() < 1.0, "compensated peak {p} dB");
    }

    /// Both designs at three rates against an independent NumPy reading of the spec
    /// (`tools/make_middle_ear_fixture.py`), to 1e-12 of the largest tap.
    #[test]
    fn designs_match_an_independent_reading_of_the_spec() {
        let text = include_str!("../../data/middle_ear_fir2.json");
        let fixture: serde_json::Value = serde_json::from_str(text).expect("fixture");
        let cases = fixture["middle_ear"]
            .as_array()
            .expect("middle-ear designs");
        assert_eq!(cases.len(), 6);
        for c in cases {
            let fs = c["fs_hz"].as_f64().expect("fs");
            let model = c["model"].as_str().expect("model");
            let want: Vec<f64> = c["taps"]
                .as_array()
                .expect("taps")
                .iter()
                .map(|v| v.as_f64().expect("tap"))
                .collect();
            let got = if model == "jepsen" {
                jepsen(fs)
            } else {
                lopezpoveda(fs)
            };
            let peak = want.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            assert_eq!(got.len(), want.len(), "{model} at {fs} Hz");
            for (k, (g, w)) in got.iter().zip(&want).enumerate() {
                assert!(
                    (g - w).abs() <= 1e-12 * peak,
                    "{model} at {fs} Hz, tap {k}: {g} vs {w}"
                );
            }
        }
    }
}
