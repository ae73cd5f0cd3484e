//! `crosscorrelation`: normalised interaural cross-correlation per channel and frame over
//! lags −maxLag..maxLag (spec 18-crosscorrelation), computed by zero-padded real FFTs.

use std::sync::Arc;

use afe_core::window::{window, WINDOW_NAMES};
use afe_core::{
    Block, Error, ParamKind, ParamSpec, Params, Processor, Result, SignalInfo, SignalKind,
};
use realfft::num_complex::Complex64;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use serde::{Deserialize, Serialize};

use crate::framed::{check_framing, EarFrames};

/// Parameters of the cross-correlation, under their AFE names.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CrosscorrelationParams {
    /// Window name (AFE `cc_wname`).
    #[serde(rename = "cc_wname")]
    pub wname: String,
    /// Window length in s (AFE `cc_wSizeSec`).
    #[serde(rename = "cc_wSizeSec")]
    pub w_size_sec: f64,
    /// Hop in s (AFE `cc_hSizeSec`).
    #[serde(rename = "cc_hSizeSec")]
    pub h_size_sec: f64,
    /// Largest lag in s (AFE `cc_maxDelaySec`).
    #[serde(rename = "cc_maxDelaySec")]
    pub max_delay_sec: f64,
}

impl Default for CrosscorrelationParams {
    fn default() -> Self {
        CrosscorrelationParams {
            wname: "hann".into(),
            w_size_sec: 0.02,
            h_size_sec: 0.01,
            max_delay_sec: 0.0011,
        }
    }
}

impl Params for CrosscorrelationParams {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec {
            name: "cc_wname",
            kind: ParamKind::Choice(WINDOW_NAMES),
            unit: "",
            description: "window applied to each frame",
        },
        ParamSpec {
            name: "cc_wSizeSec",
            kind: ParamKind::Number,
            unit: "s",
            description: "window length",
        },
        ParamSpec {
            name: "cc_hSizeSec",
            kind: ParamKind::Number,
            unit: "s",
            description: "hop between frames",
        },
        ParamSpec {
            name: "cc_maxDelaySec",
            kind: ParamKind::Number,
            unit: "s",
            description: "largest interaural lag computed",
        },
    ];
}

/// The cross-correlation: left and right IHC in, `[frame][channel][lag]` out.
pub struct Crosscorrelation {
    frames: EarFrames,
    engine: Engine,
}

/// FFT plans, window and scratch of the per-channel correlation.
struct Engine {
    win: Vec<f64>,
    max_lag: usize,
    fft: Arc<dyn RealToComplex<f64>>,
    ifft: Arc<dyn ComplexToReal<f64>>,
    time_l: Vec<f64>,
    time_r: Vec<f64>,
    spec_l: Vec<Complex64>,
    spec_r: Vec<Complex64>,
    scratch: Vec<Complex64>,
}

impl std::fmt::Debug for Crosscorrelation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Crosscorrelation")
            .field("window", &self.engine.win.len())
            .field("max_lag", &self.engine.max_lag)
            .finish_non_exhaustive()
    }
}

impl Crosscorrelation {
    /// Builds the cross-correlation for the IHC signal `input` (the same for both ears).
    pub fn new(params: &CrosscorrelationParams, input: &SignalInfo) -> Result<(Self, SignalInfo)> {
        let fs = input.fs_hz;
        let (w, h) = check_framing(
            ("cc_wSizeSec", params.w_size_sec),
            ("cc_hSizeSec", params.h_size_sec),
            fs,
        )?;
        let max_lag = (params.max_delay_sec * fs).ceil();
        if params.max_delay_sec < 0.0 || max_lag > w as f64 {
            return Err(Error::InvalidParameter {
                name: "cc_maxDelaySec".into(),
                value: params.max_delay_sec.to_string(),
                reason: format!(
                    "must be ≥ 0 s and at most the window ({} s): longer lags are all zero",
                    params.w_size_sec
                ),
            });
        }
        let max_lag = max_lag as usize;
        // The AFE transforms 2^nextpow2(2W − 1) points; only lags up to L = min(maxLag,
        // W − 1) are kept, and a circular correlation of N ≥ W + L points has no wrap-around
        // there, so the smaller transform gives the same values (to rounding) at half the cost.
        let nfft = (w + max_lag.min(w - 1)).next_power_of_two();
        let mut planner = RealFftPlanner::<f64>::new();
        let fft = planner.plan_fft_forward(nfft);
        let ifft = planner.plan_fft_inverse(nfft);
        let scratch_len = fft.get_scratch_len().max(ifft.get_scratch_len());
        let nc = input.channels();
        let engine = Engine {
            win: window(&params.wname, w, "cc_wname")?,
            max_lag,
            time_l: fft.make_input_vec(),
            time_r: fft.make_input_vec(),
            spec_l: fft.make_output_vec(),
            spec_r: fft.make_output_vec(),
            scratch: vec![Complex64::new(0.0, 0.0); scratch_len],
            fft,
            ifft,
        };
        let cc = Crosscorrelation {
            frames: EarFrames::new(nc, w, h),
            engine,
        };
        let lags_s = (0..=2 * max_lag)
            .map(|i| (i as f64 - max_lag as f64) / fs)
            .collect();
        let info = SignalInfo {
            kind: SignalKind::Correlation,
            fs_hz: 1.0 / params.h_size_sec,
            cf_hz: input.cf_hz.clone(),
            lags_s,
            audio_fs_hz: input.audio_fs_hz,
        };
        Ok((cc, info))
    }
}

impl Engine {
    /// Correlates channel `c` of the current frames into `out` (one value per lag).
    fn correlate(
        &mut self,
        frame_l: &[f64],
        frame_r: &[f64],
        c: usize,
        nc: usize,
        out: &mut [f64],
    ) {
        let w = self.win.len();
        let nfft = self.time_l.len();
        let (mut el, mut er) = (0.0, 0.0);
        for n in 0..w {
            let l = self.win[n] * frame_l[n * nc + c];
            let r = self.win[n] * frame_r[n * nc + c];
            self.time_l[n] = l;
            self.time_r[n] = r;
            el += l * l;
            er += r * r;
        }
        self.time_l[w..].fill(0.0);
        self.time_r[w..].fill(0.0);
        // Lengths match by construction, so the FFTs cannot fail.
        let _ =
            self.fft
                .process_with_scratch(&mut self.time_l, &mut self.spec_l, &mut self.scratch);
        let _ =
            self.fft
                .process_with_scratch(&mut self.time_r, &mut self.spec_r, &mut self.scratch);
        for (a, b) in self.spec_l.iter_mut().zip(&self.spec_r) {
            *a *= b.conj();
        }
        let last = self.spec_l.len() - 1;
        self.spec_l[0].im = 0.0;
        self.spec_l[last].im = 0.0;
        let _ =
            self.ifft
                .process_with_scratch(&mut self.spec_l, &mut self.time_l, &mut self.scratch);
        let norm = f64::EPSILON + (el * er).sqrt();
        let scale = nfft as f64;
        let m = self.max_lag as isize;
        for (i, o) in out.iter_mut().enumerate() {
            let lag = i as isize - m;
            *o = if lag.unsigned_abs() < w {
                let idx = lag.rem_euclid(nfft as isize) as usize;
                self.time_l[idx] / scale / norm
            } else {
                0.0
            };
        }
    }
}

impl Processor for Crosscorrelation {
    fn process(&mut self, inputs: &[&Block], outputs: &mut [Block]) {
        let nc = inputs[0].width();
        let n = self.frames.push(inputs[0].as_slice(), inputs[1].as_slice());
        let nl = 2 * self.engine.max_lag + 1;
        let out = outputs[0].reset_to(n);
        for k in 0..n {
            let (fl, fr) = self.frames.frame(k);
            for c in 0..nc {
                let start = (k * nc + c) * nl;
                self.engine
                    .correlate(fl, fr, c, nc, &mut out[start..start + nl]);
            }
        }
        self.frames.consume(n);
    }

    fn reset(&mut self) {
        self.frames.reset();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specs_match_struct() {
        afe_core::params::check_param_specs::<CrosscorrelationParams>();
    }

    /// Direct evaluation of `Σ_n l[n+ℓ]·r[n] / (eps + sqrt(Σl²Σr²))`.
    fn direct(l: &[f64], r: &[f64], lag: isize) -> f64 {
        let w = l.len() as isize;
        let mut acc = 0.0;
        for n in 0..w {
            let m = n + lag;
            if (0..w).contains(&m) {
                acc += l[m as usize] * r[n as usize];
            }
        }
        let el: f64 = l.iter().map(|v| v * v).sum();
        let er: f64 = r.iter().map(|v| v * v).sum();
        acc / (f64::EPSILON + (el * er).sqrt())
    }

    #[test]
    fn matches_direct_correlation_and_finds_the_delay() {
        let fs = 1000.0;
        let info = SignalInfo::time_frequency(fs, vec![100.0]);
        let p = CrosscorrelationParams {
            max_delay_sec: 0.005,
            ..Default::default()
        };
        let (mut cc, out_info) = Crosscorrelation::new(&p, &info).expect("valid");
        assert_eq!(out_info.lags_s.len(), 11);
        // right = left delayed by 3 samples: peak at lag −3
        let x: Vec<f64> = (0..60).map(|i| ((i * 37) % 11) as f64).collect();
        let l = Block::from_vec(x[3..43].to_vec(), 1);
        let r = Block::from_vec(x[0..40].to_vec(), 1);
        let mut out = vec![Block::new(11)];
        cc.process(&[&l, &r], &mut out);
        assert_eq!(out[0].frames(), 3);
        let win = window("hann", 20, "").unwrap_or_default();
        let lw: Vec<f64> = (0..20).map(|n| win[n] * l.as_slice()[n]).collect();
        let rw: Vec<f64> = (0..20).map(|n| win[n] * r.as_slice()[n]).collect();
        for (i, v) in out[0].row(0).iter().enumerate() {
            assert!((v - direct(&lw, &rw, i as isize - 5)).abs() < 1e-12);
        }
    }

    #[test]
    fn silent_frames_give_zero_not_nan() {
        let info = SignalInfo::time_frequency(1000.0, vec![100.0]);
        let (mut cc, _) =
            Crosscorrelation::new(&CrosscorrelationParams::default(), &info).expect("valid");
        let z = Block::from_vec(vec![0.0; 40], 1);
        // 1.1 ms at 1 kHz: lags −2..2
        let mut out = vec![Block::new(5)];
        cc.process(&[&z, &z], &mut out);
        assert_eq!(out[0].frames(), 3);
        assert!(out[0].as_slice().iter().all(|v| *v == 0.0));
    }
}
