//! The cross-correlation's FFT engine: one zero-padded real transform per channel and
//! ear, for long lag ranges. Apart from the processor, which only frames the input and
//! picks an engine by the cost model, as the direct engine is.

use std::sync::Arc;

use afe_core::framing::Frame;
use afe_fft::{ComplexToReal, RealToComplex};
use num_complex::Complex64;

use super::in_subnormal_band;

/// FFT plans, window and scratch of the per-channel correlation.
pub(super) struct FftEngine {
    pub(super) win: Vec<f64>,
    pub(super) max_lag: usize,
    fft: Arc<dyn RealToComplex<f64>>,
    ifft: Arc<dyn ComplexToReal<f64>>,
    time_l: Vec<f64>,
    time_r: Vec<f64>,
    spec_l: Vec<Complex64>,
    spec_r: Vec<Complex64>,
    scratch: Vec<Complex64>,
}

impl FftEngine {
    pub(super) fn new(win: Vec<f64>, max_lag: usize) -> Self {
        let w = win.len();
        // The AFE transforms 2^nextpow2(2W − 1) points; only lags up to L = min(maxLag,
        // W − 1) are kept, and a circular correlation of N ≥ W + L points has no wrap-around
        // there, so the smaller transform gives the same values (to rounding) at half the cost.
        let nfft = (w + max_lag.min(w - 1)).next_power_of_two();
        let fft = afe_fft::real_forward(nfft);
        let ifft = afe_fft::real_inverse(nfft);
        let scratch_len = fft.get_scratch_len().max(ifft.get_scratch_len());
        FftEngine {
            win,
            max_lag,
            time_l: fft.make_input_vec(),
            time_r: fft.make_input_vec(),
            spec_l: fft.make_output_vec(),
            spec_r: fft.make_output_vec(),
            scratch: vec![Complex64::new(0.0, 0.0); scratch_len],
            fft,
            ifft,
        }
    }

    /// Correlates column `c` of the current frames into `out` (one value per lag).
    pub(super) fn correlate(
        &mut self,
        frame_l: Frame<'_>,
        frame_r: Frame<'_>,
        c: usize,
        out: &mut [f64],
    ) {
        let (ml, mr) = self.correlate_column(frame_l, frame_r, c, out);
        if in_subnormal_band(ml, mr) {
            self.correlate_column_ieee(frame_l, frame_r, c, out);
        }
    }

    /// [`FftEngine::correlate_column`] in IEEE arithmetic (see [`in_subnormal_band`]).
    #[cold]
    #[inline(never)]
    fn correlate_column_ieee(&mut self, fl: Frame<'_>, fr: Frame<'_>, c: usize, out: &mut [f64]) {
        let _ieee = afe_core::denormals::GradualUnderflow::enable();
        self.correlate_column(fl, fr, c, out);
    }

    /// Correlates column `c` into `out`; returns its largest windowed magnitudes, left
    /// and right.
    fn correlate_column(
        &mut self,
        frame_l: Frame<'_>,
        frame_r: Frame<'_>,
        c: usize,
        out: &mut [f64],
    ) -> (f64, f64) {
        let w = self.win.len();
        let nfft = self.time_l.len();
        let (mut el, mut er) = (0.0, 0.0);
        let (mut ml, mut mr) = (0.0f64, 0.0f64);
        let rows = frame_l.rows().zip(frame_r.rows());
        for (n, (rl, rr)) in rows.enumerate() {
            let l = self.win[n] * rl[c];
            let r = self.win[n] * rr[c];
            self.time_l[n] = l;
            self.time_r[n] = r;
            el += l * l;
            er += r * r;
            ml = ml.max(l.abs());
            mr = mr.max(r.abs());
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
        (ml, mr)
    }
}
