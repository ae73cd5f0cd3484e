//! The precedence model's state and its per-frame steps: step A (windowing, cumulative
//! autocorrelations, the lead/lag estimate) per ear, steps B and C (the LLAR mode, each
//! channel's correlation, ITD and ILD) per frame pair. Apart from the processor, which
//! frames the input and hands each frame pair to [`Model::frame`].

use std::ops::Range;

use afe_core::framing::Frame;
use afe_core::real_fft::{RealFft, RealIfft};

use super::kernels::{
    accumulate_power, dot, even_lags, frame_xcorr, lag_products, short_xcorr, transform,
    window_columns, xcorr,
};
use super::lag_removal::{peak_ratio, LagRemoval, TAPS};
use crate::crosscorrelation::{above_subnormal_band, in_subnormal_band};
use crate::even_inverse::EvenInverse;

/// Rows of a frame pair scanned between two looks at whether every channel's maxima
/// already lie above the subnormal band.
const ROWS_PER_CHECK: usize = 8;

/// Lag-removal variants and which one each ear uses in each LLAR mode (spec step B):
/// `false` = `S` (short), `true` = `L` (long).
const MODES: [(bool, bool); 4] = [(false, false), (true, true), (false, true), (true, false)];

/// One frame's outputs: ITD and ILD per channel, and the cross-correlation.
type Cues<'a> = (&'a mut [f64], &'a mut [f64], &'a mut [f64]);

/// Everything but the framing: constants, FFT plans, cumulative state and scratch.
pub(super) struct Model {
    /// Each ear's largest magnitude per channel of the current frame (the subnormal
    /// band's test).
    pub(super) tail_peaks: [Vec<f64>; 2],
    pub(super) win: Vec<f64>,
    pub(super) nc: usize,
    pub(super) max_lag: usize,
    pub(super) ac_lag: usize,
    pub(super) main_peak_width: usize,
    pub(super) cc_lag: usize,
    pub(super) fs: f64,
    /// `a(τ)`, the decay weight of the lag, at index `τ − 1`.
    pub(super) decay: Vec<f64>,
    /// `1/max(cf, 100)` per channel: the weight of each autocorrelation.
    pub(super) ac_weight: Vec<f64>,
    /// The frequency weight `w_n` of each channel's correlation.
    pub(super) cc_weight: Vec<f64>,
    /// The forward and inverse transforms of `nfft` samples, `nfft/2 + 1` bins (their
    /// spectra as real and imaginary parts, so that the passes around them vectorise).
    pub(super) fft: RealFft,
    pub(super) ifft: RealIfft,
    /// The inverse of the real, even power spectra (the autocorrelations), at half the
    /// cost.
    pub(super) even: EvenInverse,
    pub(super) ears: [Ear; 2],
    /// Whether the next frame is the first since construction or reset.
    pub(super) first: bool,
    /// Cumulative summary cross-correlation of each mode, `2·ccLag + 1` lags.
    pub(super) cc_modes: [Vec<f64>; 4],
    /// The frames' cross-correlation over lags `−(W−1)..W−1`.
    pub(super) xcorr: Vec<f64>,
    /// One channel's (or the summary's) correlation, `2·max(maxLag, ccLag) + 1` lags.
    pub(super) icc: Vec<f64>,
}

/// What one ear keeps and computes per frame.
#[derive(Debug, Clone)]
pub(super) struct Ear {
    /// Windowed frame, `[channel][time]`.
    pub(super) cols: Vec<f64>,
    /// Spectra of the windowed frame's channels, `[channel][bin]`.
    pub(super) spectra: Spectra,
    /// Cumulative weighted power spectra (the transforms of the cumulative
    /// autocorrelations), `[channel][bin]`.
    pub(super) power: Vec<f64>,
    /// Spectrum of the summary autocorrelation (real).
    pub(super) summary: Vec<f64>,
    /// Largest windowed value of each channel, then largest value of each
    /// autocorrelation row.
    pub(super) peaks: Vec<f64>,
    /// Autocorrelation rows for the per-channel normalisation, `[channel][lag]`, lags
    /// `0..=acLag`: the rows are even, and only their maximum (at lag 0) and the lags
    /// from `mainPeakWidth` on are read, so the negative half is left out.
    pub(super) rows: Vec<f64>,
    /// Summary autocorrelation, lags `0..=acLag`.
    pub(super) sacf: Vec<f64>,
    /// Sum of the windowed frame over the channels, and its spectrum.
    pub(super) sum: Vec<f64>,
    pub(super) sum_spectrum: Spectra,
    /// Summary `S` and `L` signals (`W + 5·acLag` samples at most).
    pub(super) sum_short: Vec<f64>,
    pub(super) sum_long: Vec<f64>,
    /// The lag-removed signal of each channel used by a direct correlation,
    /// `[channel][time]`, `W + 5·acLag` samples per channel at most.
    pub(super) variant: Vec<f64>,
    /// Energy of each channel's selected signal.
    pub(super) energy: Vec<f64>,
    /// The lead/lag analysis of the current frame.
    pub(super) lag: LagRemoval,
}

/// Complex spectra as their real and imaginary parts.
#[derive(Debug, Clone)]
pub(super) struct Spectra {
    re: Vec<f64>,
    im: Vec<f64>,
}

impl Spectra {
    pub(super) fn zeros(len: usize) -> Self {
        Spectra {
            re: vec![0.0; len],
            im: vec![0.0; len],
        }
    }

    /// Bins `bins` of the parts (one channel's spectrum of several).
    pub(super) fn bins(&self, bins: Range<usize>) -> (&[f64], &[f64]) {
        (&self.re[bins.clone()], &self.im[bins])
    }

    /// The transform of `x` (zero-padded) into bins `bins` of the parts.
    pub(super) fn transform(&mut self, fft: &mut RealFft, x: &[f64], bins: Range<usize>) {
        transform(fft, x, (&mut self.re[bins.clone()], &mut self.im[bins]));
    }
}

/// The first largest value and its index, skipping NaN (MATLAB's `max`); `(NaN, 0)`
/// when every value is NaN.
fn first_max(x: &[f64]) -> (f64, usize) {
    let mut best = (f64::NAN, 0);
    for (i, &v) in x.iter().enumerate() {
        if v > best.0 || (best.0.is_nan() && !v.is_nan()) {
            best = (v, i);
        }
    }
    best
}

impl Model {
    /// Bins of each spectrum, `nfft/2 + 1`.
    fn bins(&self) -> usize {
        self.fft.points() / 2 + 1
    }

    /// Step A for ear `e`: windows frame `x`, updates the cumulative autocorrelations
    /// and estimates the lag's delay and amplitude ratio.
    fn analyse(&mut self, e: usize, x: Frame<'_>) {
        let (nc, w, first) = (self.nc, self.win.len(), self.first);
        let (nfft, bins) = (self.fft.points(), self.bins());
        let ear = &mut self.ears[e];
        window_columns(&self.win, x, &mut ear.cols, &mut ear.peaks);
        // Active bandwidth: channels whose peak is within 12 dB of the frame's.
        let top = ear.peaks.iter().fold(f64::NAN, |a, &b| a.max(b));
        let top_db = 20.0 * top.abs().log10();
        let bandwidth = ear
            .peaks
            .iter()
            .filter(|p| 20.0 * p.abs().log10() - top_db > -12.0)
            .count();
        let per_channel = bandwidth <= 5;

        ear.summary.fill(0.0);
        for c in 0..nc {
            let own = c * bins..(c + 1) * bins;
            let col = &ear.cols[c * w..(c + 1) * w];
            ear.spectra.transform(&mut self.fft, col, own.clone());
            let power = &mut ear.power[own.clone()];
            let spec = ear.spectra.bins(own);
            accumulate_power(spec, power, &mut ear.summary, self.ac_weight[c], first);
        }
        let nl = self.ac_lag + 1;
        let scale = 1.0 / nfft as f64;
        if per_channel {
            // Per-channel rows (the raw autocorrelation on the first frame), each scaled
            // by its maximum in turn while it is within 60 dB of the whole array's.
            for c in 0..nc {
                let (re, im) = ear.spectra.bins(c * bins..(c + 1) * bins);
                let power = &ear.power[c * bins..(c + 1) * bins];
                let row = &mut ear.rows[c * nl..(c + 1) * nl];
                if first {
                    let (raw, _) = self.ifft.spectrum();
                    for ((s, r), i) in raw.iter_mut().zip(re).zip(im) {
                        *s = r * r + i * i;
                    }
                    even_lags(&mut self.even, raw, scale, row);
                } else {
                    even_lags(&mut self.even, power, scale, row);
                }
            }
            for (row, peak) in ear.rows.chunks_exact(nl).zip(ear.peaks.iter_mut()) {
                *peak = first_max(row).0;
            }
            for c in 0..nc {
                let whole = ear.peaks.iter().fold(f64::NAN, |a, &b| a.max(b));
                let row = &mut ear.rows[c * nl..(c + 1) * nl];
                let m = ear.peaks[c];
                if 20.0 * (m / whole).log10() > -60.0 {
                    row.iter_mut().for_each(|v| *v /= m);
                } else {
                    row.fill(0.0);
                }
                ear.peaks[c] = first_max(row).0;
            }
            ear.sacf.fill(0.0);
            for row in ear.rows.chunks_exact(nl) {
                for (s, v) in ear.sacf.iter_mut().zip(row) {
                    *s += v;
                }
            }
        } else {
            even_lags(&mut self.even, &ear.summary, scale, &mut ear.sacf);
        }
        let total = first_max(&ear.sacf).0;
        let (side, j) = first_max(&ear.sacf[self.main_peak_width..]);
        let tau = (self.main_peak_width + j).min(self.decay.len());
        let b = peak_ratio(side / total).min(0.9);
        ear.lag = LagRemoval::new(tau, b, self.decay[tau - 1]);
    }

    /// One frame pair's cues into `(itd, ild, cc)`.
    #[inline(always)]
    pub(super) fn frame(&mut self, left: Frame<'_>, right: Frame<'_>, out: Cues<'_>) {
        self.analyse(0, left);
        self.analyse(1, right);
        self.cues(out.0, out.1, out.2);
        self.first = false;
    }

    /// [`Model::frame`] in IEEE arithmetic, for a frame pair whose products sink into
    /// the subnormals where the thread flushes them: the decay after digital silence,
    /// whose ITD and ILD the AFE still computes from them.
    #[cold]
    #[inline(never)]
    pub(super) fn frame_ieee(&mut self, left: Frame<'_>, right: Frame<'_>, out: Cues<'_>) {
        let (itd, ild, cc) = out;
        {
            let _ieee = afe_core::denormals::GradualUnderflow::enable();
            self.frame(left, right, (&mut *itd, &mut *ild, &mut *cc));
        }
        for o in [itd, ild, cc] {
            afe_core::denormals::flush_subnormals(o);
        }
    }

    /// Whether some channel's largest magnitudes in the two frames lie where flushing
    /// subnormals would change the cues (the cross-correlation's `in_subnormal_band`).
    /// The maxima only grow row by row, and their products with them: the scan stops
    /// once every channel's lies above the band (a speech frame's first rows), the answer
    /// the whole frame gives.
    pub(super) fn in_subnormal_band(&mut self, left: Frame<'_>, right: Frame<'_>) -> bool {
        let [l, r] = &mut self.tail_peaks;
        l.fill(0.0);
        r.fill(0.0);
        for (n, (row_l, row_r)) in left.rows().zip(right.rows()).enumerate() {
            for (p, v) in l.iter_mut().zip(row_l).chain(r.iter_mut().zip(row_r)) {
                *p = p.max(v.abs());
            }
            let checkpoint = (n + 1).is_multiple_of(ROWS_PER_CHECK);
            if checkpoint
                && l.iter()
                    .zip(r.iter())
                    .all(|(&a, &b)| above_subnormal_band(a, b))
            {
                return false;
            }
        }
        l.iter()
            .zip(r.iter())
            .any(|(&a, &b)| in_subnormal_band(a, b))
    }

    /// Steps B and C on the analysed frame pair: the LLAR mode, then each channel's
    /// correlation (into `cc`, `[channel][lag]`), ITD (s) and ILD (dB).
    fn cues(&mut self, itd: &mut [f64], ild: &mut [f64], cc: &mut [f64]) {
        let (nc, w) = (self.nc, self.win.len());
        for ear in &mut self.ears {
            ear.sum.fill(0.0);
            for col in ear.cols.chunks_exact(w) {
                for (s, v) in ear.sum.iter_mut().zip(col) {
                    *s += v;
                }
            }
            let bins = 0..ear.sum_spectrum.re.len();
            ear.sum_spectrum.transform(&mut self.fft, &ear.sum, bins);
            let lag = ear.lag;
            let short = &mut ear.sum_short[..lag.len(false, w)];
            lag.apply(false, &ear.sum, short);
            let long = &mut ear.sum_long[..lag.len(true, w)];
            lag.apply(true, &ear.sum, long);
        }
        let ncc = 2 * self.cc_lag + 1;
        for (m, &(long_l, long_r)) in MODES.iter().enumerate() {
            let [l, r] = &self.ears;
            let left = if long_l {
                &l.sum_long[..l.lag.len(true, w)]
            } else {
                &l.sum_short[..l.lag.len(false, w)]
            };
            let right = if long_r {
                &r.sum_long[..r.lag.len(true, w)]
            } else {
                &r.sum_short[..r.lag.len(false, w)]
            };
            let out = &mut self.icc[..ncc];
            if m == 0 {
                let all = 0..l.sum_spectrum.re.len();
                let (fl, fr) = (l.sum_spectrum.bins(all.clone()), r.sum_spectrum.bins(all));
                frame_xcorr(&mut self.ifft, fl, fr, &mut self.xcorr);
                short_xcorr(&self.xcorr, &l.lag, &r.lag, out);
            } else {
                xcorr(left, right, out);
            }
            let acc = &mut self.cc_modes[m];
            for (a, v) in acc.iter_mut().zip(&*out) {
                *a = if self.first { *v } else { *a + v };
            }
        }
        let mut mode = 0;
        let mut best = f64::NAN;
        for (m, acc) in self.cc_modes.iter().enumerate() {
            let v = first_max(acc).0;
            if v > best || (best.is_nan() && !v.is_nan()) {
                (best, mode) = (v, m);
            }
        }
        let (long_l, long_r) = MODES[mode];
        let nl = 2 * self.max_lag + 1;
        if !long_l && !long_r {
            self.short_pair(cc);
        } else {
            self.direct_pair(long_l, long_r, cc);
        }
        let len_l = self.ears[0].lag.len(long_l, w) as f64;
        let len_r = self.ears[1].lag.len(long_r, w) as f64;
        for c in 0..nc {
            let (el, er) = (self.ears[0].energy[c], self.ears[1].energy[c]);
            let row = &mut cc[c * nl..(c + 1) * nl];
            let norm = f64::EPSILON + (el * er).sqrt();
            let weight = self.cc_weight[c];
            for v in row.iter_mut() {
                *v = weight * (*v / norm);
            }
            let (_, i) = first_max(row);
            itd[c] = (i as f64 - self.max_lag as f64) / self.fs;
            let (rms_l, rms_r) = ((el / len_l).sqrt(), (er / len_r).sqrt());
            let (level, en) = if rms_l > 0.0 && rms_r > 0.0 {
                (20.0 * (rms_r / rms_l).log10(), rms_l * rms_r)
            } else {
                (0.0, 0.0)
            };
            ild[c] = level * en / en;
        }
    }

    /// Mode 1 (`S` on both ears): each channel's correlation over `±maxLag` into `cc`
    /// and the energies of its `S` signals, from the frames' cross- and
    /// autocorrelations: `xcorr(S_l, S_r)[m] = Σ_{q,p} c_q·d_p·R[m − qτ_l + pτ_r]`.
    fn short_pair(&mut self, cc: &mut [f64]) {
        let (nc, w) = (self.nc, self.win.len());
        let bins = self.bins();
        let nl = 2 * self.max_lag + 1;
        let (ll, lr) = (self.ears[0].lag, self.ears[1].lag);
        for ear in &mut self.ears {
            let lag = ear.lag;
            for (c, col) in ear.cols.chunks_exact(w).enumerate() {
                let r = lag_products(col, lag.tau);
                let mut energy = 0.0;
                for q in 0..TAPS {
                    for p in 0..TAPS {
                        energy += lag.short[q] * lag.short[p] * r[q.abs_diff(p)];
                    }
                }
                ear.energy[c] = energy;
            }
        }
        let [left, right] = &self.ears;
        for (c, out) in cc.chunks_exact_mut(nl).enumerate().take(nc) {
            let bins = c * bins..(c + 1) * bins;
            let (sl, sr) = (left.spectra.bins(bins.clone()), right.spectra.bins(bins));
            frame_xcorr(&mut self.ifft, sl, sr, &mut self.xcorr);
            short_xcorr(&self.xcorr, &ll, &lr, out);
        }
    }

    /// Modes with an `L` signal: each channel's selected signals are built and
    /// correlated directly, into `cc`, with their energies.
    fn direct_pair(&mut self, long_l: bool, long_r: bool, cc: &mut [f64]) {
        let w = self.win.len();
        let longest = w + 5 * self.ac_lag;
        let nl = 2 * self.max_lag + 1;
        for (ear, long) in self.ears.iter_mut().zip([long_l, long_r]) {
            let lag = ear.lag;
            let n = lag.len(long, w);
            for (c, col) in ear.cols.chunks_exact(w).enumerate() {
                let v = &mut ear.variant[c * longest..c * longest + n];
                lag.apply(long, col, v);
                ear.energy[c] = dot(v, v);
            }
        }
        let [left, right] = &self.ears;
        let (n_l, n_r) = (left.lag.len(long_l, w), right.lag.len(long_r, w));
        for (c, out) in cc.chunks_exact_mut(nl).enumerate() {
            let a = &left.variant[c * longest..c * longest + n_l];
            let b = &right.variant[c * longest..c * longest + n_r];
            xcorr(a, b, out);
        }
    }
}
