//! `duet`: the DUET histogram (Yilmaz & Rickard 2004) of interaural attenuation and
//! delay estimates from the STFTs of both pre-processed ears, one 2-D histogram per block
//! of STFT frames (spec 33-duet).
//!
//! Each STFT cell gives the ratio `ρ = (R + ε)/(L + ε)` of the right and left spectra
//! (`ε = 2^−52`); the symmetric attenuation `α = |ρ| − 1/|ρ|` and the delay
//! `δ = −arg(ρ)/ω` (in samples) pick a bin, weighted by `(|L|·|R|)²·ω²`. A block's
//! histogram is smoothed by a cubic five-point Savitzky–Golay filter along both axes,
//! clipped at 0 and normalised to a maximum of 1 (all NaN when the block is silent, as
//! in the AFE).
//!
//! **Chunking.** The MATLAB AFE refills the right ear's sample buffer from the *left*
//! input after each chunk, so from the second chunk on its right-ear STFT starts with
//! left-ear samples and chunked output differs from one call. afe buffers each ear from
//! its own input instead: any chunking gives the output of one call, bit for bit, and
//! one call gives the AFE's output.

use std::f64::consts::PI;
use std::sync::Arc;

use afe_core::descriptor::{request_def, Built, Descriptor, Ears, RequestDef};
use afe_core::framing::{window_samples, FrameBuffer};
use afe_core::sgolay::SavitzkyGolay;
use afe_core::window::hamming_periodic;
use afe_core::{Axis, Block, Error, ParamKind, Processor, Result, SignalInfo, SignalKind};
use afe_fft::RealToComplex;
use num_complex::Complex64;

use crate::framed::{EarFrames, MAX_WINDOW};

afe_core::params! {
    /// Parameters of the DUET histogram, under their AFE names.
    pub struct DuetParams / DuetNames {
        /// STFT window length (the STFT hop is half of it)
        #[afe = "duet_wSTFTSec", unit = "s"]
        pub w_stft_sec: f64 = 0.02,
        /// histogram block length
        #[afe = "duet_wDUETSec", unit = "s"]
        pub w_duet_sec: f64 = 0.5,
        /// hop between histogram blocks
        #[afe = "duet_hDUETSec", unit = "s"]
        pub h_duet_sec: f64 = 1.0 / 6.0,
        /// number of attenuation bins (at least 5)
        #[afe = "duet_binsAlpha", kind = ParamKind::Count]
        pub bins_alpha: usize = 35,
        /// number of delay bins (at least 5)
        #[afe = "duet_binsDelta", kind = ParamKind::Count]
        pub bins_delta: usize = 51,
        /// largest symmetric attenuation |α| counted
        #[afe = "duet_maxAlpha"]
        pub max_alpha: f64 = 0.7,
        /// largest delay |δ| counted
        #[afe = "duet_maxDelta", unit = "samples"]
        pub max_delta: f64 = 3.6,
    }
}

/// Most histogram cells per block (`binsAlpha·binsDelta`); beyond is a mistake.
const MAX_CELLS: usize = 1 << 22;

/// The `ε = 2^−52` the AFE adds (as a real number) to both spectra before dividing.
const EPS: f64 = f64::EPSILON;

/// The DUET histogram: left and right time signals `[time][1]` in, one
/// `[alpha bin][delta bin]` histogram per block out.
pub struct Duet {
    win: Vec<f64>,
    stft_frames: EarFrames,
    fft: Arc<dyn RealToComplex<f64>>,
    time: Vec<f64>,
    spec_l: Vec<Complex64>,
    spec_r: Vec<Complex64>,
    scratch: Vec<Complex64>,
    /// `ω_k = k·2π/NFFT` for the bins `k = 1..=NFFT/2`.
    omega: Vec<f64>,
    /// One row per STFT frame: per bin `k = 1..=NFFT/2`, its histogram cell
    /// (`alpha·binsDelta + delta`) and its weight, doubled below Nyquist for the
    /// conjugate bin `NFFT − k`, which falls in the same cell; a bin outside the
    /// histogram's range has cell 0 and weight 0.
    cells: FrameBuffer,
    /// The rows of the STFT frames completed in this chunk.
    new_cells: Vec<f64>,
    hist: Vec<f64>,
    smoothed: Vec<f64>,
    sgolay: SavitzkyGolay,
    bins_alpha: usize,
    bins_delta: usize,
    max_alpha: f64,
    max_delta: f64,
}

impl std::fmt::Debug for Duet {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Duet")
            .field("window", &self.win.len())
            .field("nfft", &self.time.len())
            .field("bins", &(self.bins_alpha, self.bins_delta))
            .finish_non_exhaustive()
    }
}

impl Duet {
    /// Builds the histogram for the pre-processed time signal `input` (both ears alike).
    ///
    /// STFT: `Ws = 2·round(wSTFTSec·fs/2)`, hop `Ws/2`, periodic Hamming, full FFT of
    /// length `2^nextpow2(2·Ws − 1)`. Blocks: `floor(wDUETSec·2/wSTFTSec)` STFT frames
    /// every `floor(hDUETSec·2/wSTFTSec)`, at `(2/wSTFTSec)/hop` blocks per second.
    pub fn new(p: &DuetParams, input: &SignalInfo) -> Result<(Self, SignalInfo)> {
        let fs = input.fs_hz;
        let ws = window_samples(p.w_stft_sec, fs);
        if p.w_stft_sec <= 0.0 || !(2..=MAX_WINDOW).contains(&ws) {
            return Err(Error::invalid(
                DuetParams::NAMES.w_stft_sec,
                p.w_stft_sec,
                format!("the STFT window must span between 2 and {MAX_WINDOW} samples at {fs} Hz"),
            ));
        }
        let fs_stft = 2.0 / p.w_stft_sec;
        let frames_of = |sec: f64| (sec * fs_stft).floor();
        let wd = frames_of(p.w_duet_sec);
        let hd = frames_of(p.h_duet_sec);
        let max_frames = (MAX_WINDOW / (ws / 2)) as f64;
        if !(1.0..=max_frames).contains(&wd) {
            return Err(Error::invalid(
                DuetParams::NAMES.w_duet_sec,
                p.w_duet_sec,
                format!(
                    "a block must span between 1 and {max_frames} STFT frames of {} s",
                    p.w_stft_sec / 2.0
                ),
            ));
        }
        if !(1.0..=max_frames).contains(&hd) {
            return Err(Error::invalid(
                DuetParams::NAMES.h_duet_sec,
                p.h_duet_sec,
                format!(
                    "the block hop must span between 1 and {max_frames} STFT frames of {} s",
                    p.w_stft_sec / 2.0
                ),
            ));
        }
        let sgolay = SavitzkyGolay::new(3, 5)?;
        for (name, bins) in [
            (DuetParams::NAMES.bins_alpha, p.bins_alpha),
            (DuetParams::NAMES.bins_delta, p.bins_delta),
        ] {
            if bins < sgolay.frame() {
                return Err(Error::invalid(
                    name,
                    bins,
                    format!(
                        "the histogram is smoothed over {} bins: at least {} are needed",
                        sgolay.frame(),
                        sgolay.frame()
                    ),
                ));
            }
        }
        let n_cells = p.bins_alpha.saturating_mul(p.bins_delta);
        if n_cells > MAX_CELLS {
            // named after the larger of the two: the one to bring down
            let (name, value) = if p.bins_delta > p.bins_alpha {
                (DuetParams::NAMES.bins_delta, p.bins_delta)
            } else {
                (DuetParams::NAMES.bins_alpha, p.bins_alpha)
            };
            return Err(Error::invalid(
                name,
                value,
                format!("duet_binsAlpha·duet_binsDelta must be at most {MAX_CELLS}"),
            ));
        }
        for (name, max) in [
            (DuetParams::NAMES.max_alpha, p.max_alpha),
            (DuetParams::NAMES.max_delta, p.max_delta),
        ] {
            if max <= 0.0 {
                return Err(Error::invalid(name, max, "the range limit must be above 0"));
            }
        }
        let nfft = (2 * ws - 1).next_power_of_two();
        let half = nfft / 2;
        let fft = afe_fft::real_forward(nfft);
        let (wd, hd) = (wd as usize, hd as usize);
        let duet = Duet {
            win: hamming_periodic(ws),
            stft_frames: EarFrames::new(1, ws, ws / 2),
            time: fft.make_input_vec(),
            spec_l: fft.make_output_vec(),
            spec_r: fft.make_output_vec(),
            scratch: fft.make_scratch_vec(),
            fft,
            omega: (1..=half)
                .map(|k| k as f64 * (2.0 * PI / nfft as f64))
                .collect(),
            cells: FrameBuffer::new(2 * half, wd, hd),
            new_cells: Vec::new(),
            hist: vec![0.0; n_cells],
            smoothed: vec![0.0; n_cells],
            sgolay,
            bins_alpha: p.bins_alpha,
            bins_delta: p.bins_delta,
            max_alpha: p.max_alpha,
            max_delta: p.max_delta,
        };
        let centres = |bins: usize, max: f64| -> Vec<f64> {
            (0..bins)
                .map(|i| -max + 2.0 * max * i as f64 / (bins - 1) as f64)
                .collect()
        };
        let info = SignalInfo {
            kind: SignalKind::DuetHistogram,
            fs_hz: fs_stft / hd as f64,
            axes: vec![
                Axis::Attenuation(centres(p.bins_alpha, p.max_alpha)),
                Axis::Delay(centres(p.bins_delta, p.max_delta)),
            ],
            audio_fs_hz: input.audio_fs_hz,
            unit: Self::OUTPUT_UNIT,
            window_s: Some(p.w_duet_sec),
            nan_where: Some(
                "in a block of silence: the histogram is divided by its largest bin, 0 there",
            ),
            ..SignalInfo::default()
        };
        Ok((duet, info))
    }

    /// The full spectrum of one windowed frame into `spec` (bins `0..=NFFT/2`).
    fn spectrum(
        fft: &dyn RealToComplex<f64>,
        win: &[f64],
        frame: afe_core::framing::Frame<'_>,
        time: &mut [f64],
        spec: &mut [Complex64],
        scratch: &mut [Complex64],
    ) {
        for ((t, w), x) in time.iter_mut().zip(win).zip(frame.rows()) {
            *t = w * x[0];
        }
        time[win.len()..].fill(0.0);
        // The buffers come from the plan, so their lengths match and this cannot fail.
        let _ = fft.process_with_scratch(time, spec, scratch);
    }

    /// The histogram cell and weight of every bin `1..=NFFT/2` of one STFT frame pair,
    /// as pairs into `row`.
    fn frame_cells(&self, row: &mut [f64]) {
        let half = self.omega.len();
        let (a1, d1) = ((self.bins_alpha - 1) as f64, (self.bins_delta - 1) as f64);
        let (ma, md) = (self.max_alpha, self.max_delta);
        for (k, pair) in row.chunks_exact_mut(2).enumerate() {
            let (l, r) = (self.spec_l[k + 1], self.spec_r[k + 1]);
            let omega = self.omega[k];
            let rho = divide(r + EPS, l + EPS);
            let a = rho.re.hypot(rho.im);
            let alpha = a - 1.0 / a;
            pair[0] = 0.0;
            pair[1] = 0.0;
            // The bin decisions use |ρ| and arg ρ as the AFE computes them (hypot, atan2);
            // the weight `(|L|·|R|)²`, which decides nothing, is taken from the squared
            // moduli without square roots (the same value to a few ulps).
            if alpha.abs() < ma {
                let delta = -rho.im.atan2(rho.re) / omega;
                if delta.abs() < md {
                    let ia = (1.0 + a1 * (alpha + ma) / (2.0 * ma)).round();
                    let id = (1.0 + d1 * (delta + md) / (2.0 * md)).round();
                    let ia = (ia as usize).clamp(1, self.bins_alpha) - 1;
                    let id = (id as usize).clamp(1, self.bins_delta) - 1;
                    let w = (l.norm_sqr() * r.norm_sqr()) * (omega * omega);
                    pair[0] = (ia * self.bins_delta + id) as f64;
                    pair[1] = if k + 1 < half { 2.0 * w } else { w };
                }
            }
        }
    }
}

/// `a / b` by Smith's algorithm, as C99 complex division (and so Octave's) computes it
/// for operands of ordinary magnitude.
fn divide(a: Complex64, b: Complex64) -> Complex64 {
    if b.re.abs() < b.im.abs() {
        let ratio = b.re / b.im;
        let denom = b.re * ratio + b.im;
        Complex64::new((a.re * ratio + a.im) / denom, (a.im * ratio - a.re) / denom)
    } else {
        let ratio = b.im / b.re;
        let denom = b.im * ratio + b.re;
        Complex64::new((a.im * ratio + a.re) / denom, (a.im - a.re * ratio) / denom)
    }
}

impl Processor for Duet {
    fn process(&mut self, inputs: &[&Block], outputs: &mut [Block]) {
        let ears = (inputs[0].as_slice(), inputs[1].as_slice());
        let n = self.stft_frames.available(ears.0, ears.1);
        let width = 2 * self.omega.len();
        self.new_cells.resize(n * width, 0.0);
        let mut new_cells = std::mem::take(&mut self.new_cells);
        for (k, row) in new_cells.chunks_exact_mut(width).enumerate() {
            let (left, right) = self.stft_frames.frame(ears, k);
            let fft = self.fft.as_ref();
            Self::spectrum(
                fft,
                &self.win,
                left,
                &mut self.time,
                &mut self.spec_l,
                &mut self.scratch,
            );
            Self::spectrum(
                fft,
                &self.win,
                right,
                &mut self.time,
                &mut self.spec_r,
                &mut self.scratch,
            );
            self.frame_cells(row);
        }
        self.stft_frames.advance(ears.0, ears.1, n);

        let blocks = self.cells.available(&new_cells);
        let out = outputs[0].resize_to(blocks);
        for (j, o) in out.chunks_exact_mut(self.hist.len()).enumerate() {
            self.hist.fill(0.0);
            for row in self.cells.frame(&new_cells, j).rows() {
                for pair in row.chunks_exact(2) {
                    self.hist[pair[0] as usize] += pair[1];
                }
            }
            let cols = self.bins_delta;
            self.sgolay
                .smooth_columns(&self.hist, cols, &mut self.smoothed);
            self.sgolay.smooth_rows(&self.smoothed, cols, o);
            let mut max = 0.0f64;
            for v in o.iter_mut() {
                if *v < 0.0 {
                    *v = 0.0;
                }
                max = max.max(*v);
            }
            // A silent block is all zeros: 0/0 makes it NaN, as in the AFE.
            for v in o.iter_mut() {
                *v /= max;
            }
        }
        self.cells.advance(&new_cells, blocks);
        self.new_cells = new_cells;
    }

    fn reset(&mut self) {
        self.stft_frames.reset();
        self.cells.reset();
    }
}

impl Descriptor for Duet {
    type Params = DuetParams;
    const NAME: &'static str = "duet";
    const DEPENDENCY: &'static str = "time";
    const EARS: Ears = Ears::Binaural;
    const DESCRIPTION: &'static str =
        "DUET histogram of interaural attenuation and delay per block of STFT frames";
    const OUTPUT_UNIT: &'static str = "";

    fn build(params: &DuetParams, inputs: &[SignalInfo]) -> Result<Built> {
        let (p, out) = Duet::new(params, &inputs[0])?;
        Ok(Built::new(p, vec![out]))
    }
}

/// The registry entry of `duet`.
pub static REQUEST: RequestDef = request_def::<Duet>();

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{noise, plain_dft};
    use afe_core::Params;
    use proptest::prelude::*;

    /// The bin centres along `axis` (`alpha` or `delta`) of a histogram's description.
    fn bins<'a>(info: &'a SignalInfo, axis: &str) -> &'a [f64] {
        info.axis(axis).and_then(Axis::values).expect("a bin axis")
    }

    /// Runs `duet` over the ears in chunks of the given sizes, then the rest; returns
    /// the joined output.
    fn run(duet: &mut Duet, left: &[f64], right: &[f64], chunks: &[usize]) -> Vec<f64> {
        let width = duet.hist.len();
        let mut out = vec![Block::new(width)];
        let mut all = Vec::new();
        let mut start = 0;
        for n in chunks.iter().copied().chain([usize::MAX]) {
            if start >= left.len() {
                break;
            }
            let end = start.saturating_add(n).min(left.len());
            let l = Block::from_vec(left[start..end].to_vec(), 1);
            let r = Block::from_vec(right[start..end].to_vec(), 1);
            duet.process(&[&l, &r], &mut out);
            all.extend_from_slice(out[0].as_slice());
            start = end;
        }
        all
    }

    fn small() -> DuetParams {
        // 16 kHz: Ws = 160, NFFT = 512; blocks of 10 STFT frames every 4.
        DuetParams {
            w_stft_sec: 0.01,
            w_duet_sec: 0.05,
            h_duet_sec: 0.02,
            ..DuetParams::default()
        }
    }

    #[test]
    fn sizes_rates_and_bin_centres_at_44k() {
        let info = SignalInfo::time_domain(44100.0);
        let (duet, out) = Duet::new(&DuetParams::default(), &info).expect("valid");
        assert_eq!((duet.win.len(), duet.time.len()), (882, 2048));
        assert_eq!((duet.cells.window(), out.fs_hz), (50, 6.25));
        assert_eq!(out.frame_shape(), vec![35, 51]);
        assert_eq!(out.kind.afe_class(), "DuetHistogramSignal");
        assert_eq!(
            (
                bins(&out, "alpha")[0],
                bins(&out, "alpha")[17],
                bins(&out, "alpha")[34]
            ),
            (-0.7, 0.0, 0.7)
        );
        assert_eq!(bins(&out, "delta")[25], 0.0);
        assert!((bins(&out, "delta")[1] + 3.6 - 7.2 / 50.0).abs() < 1e-15);
    }

    /// The right ear is the left delayed by one sample and scaled by 0.5: every cell has
    /// ρ ≈ 0.5·e^{−iω} (the window's edges blur it a little), so α = 0.5 − 2 = −1.5 and
    /// δ = 1 sample. The peak is at the bins whose centres are nearest.
    #[test]
    fn a_delayed_attenuated_copy_peaks_at_its_bin() {
        let fs = 16000.0;
        let p = DuetParams {
            max_alpha: 2.0,
            ..small()
        };
        let (mut duet, info) = Duet::new(&p, &SignalInfo::time_domain(fs)).expect("valid");
        let x = noise(4001, 7);
        let left = x[1..].to_vec();
        let right: Vec<f64> = x[..4000].iter().map(|v| 0.5 * v).collect();
        let out = run(&mut duet, &left, &right, &[]);
        let cells = info.width();
        assert!(out.len() >= cells);
        let nearest = |centres: &[f64], v: f64| {
            (0..centres.len())
                .min_by(|&i, &j| (centres[i] - v).abs().total_cmp(&(centres[j] - v).abs()))
                .unwrap_or(0)
        };
        let want = (
            nearest(bins(&info, "alpha"), -1.5),
            nearest(bins(&info, "delta"), 1.0),
        );
        for block in out.chunks_exact(cells) {
            let peak = (0..cells)
                .max_by(|&i, &j| block[i].total_cmp(&block[j]))
                .unwrap_or(0);
            assert_eq!(block[peak], 1.0);
            assert_eq!((peak / p.bins_delta, peak % p.bins_delta), want);
        }
    }

    /// A silent block is NaN everywhere (0/0 after normalisation), as in the AFE.
    #[test]
    fn silence_gives_nan() {
        let (mut duet, info) =
            Duet::new(&small(), &SignalInfo::time_domain(16000.0)).expect("valid");
        let zeros = vec![0.0; 3000];
        let out = run(&mut duet, &zeros, &zeros, &[]);
        assert!(out.len() >= info.width());
        assert!(out.iter().all(|v| v.is_nan()));
    }

    /// The spec's histogram written out: a plain DFT of every frame, all `NFFT − 1`
    /// columns with their signed `ω`, and the spec's bins and weights; smoothed, clipped
    /// and normalised per block. The division is Smith's, checked on its own below.
    fn reference(p: &DuetParams, fs: f64, left: &[f64], right: &[f64]) -> Vec<f64> {
        let ws = 2 * (p.w_stft_sec * fs / 2.0).round() as usize;
        let hs = ws / 2;
        let win: Vec<f64> = (0..ws)
            .map(|n| 0.54 - 0.46 * (2.0 * PI * n as f64 / ws as f64).cos())
            .collect();
        let nfft = (2 * ws - 1).next_power_of_two();
        // Its Nyquist bin is exactly real, as from a real FFT: the sign of that zero
        // decides whether arg ρ is π or −π there.
        let dft = |x: &[f64], start: usize| {
            let frame: Vec<f64> = (0..ws).map(|n| win[n] * x[start + n]).collect();
            plain_dft(&frame, nfft)
        };
        let frames = (left.len() - hs) / hs;
        let stft: Vec<(Vec<Complex64>, Vec<Complex64>)> = (0..frames)
            .map(|f| (dft(left, f * hs), dft(right, f * hs)))
            .collect();
        let wd = (p.w_duet_sec * 2.0 / p.w_stft_sec).floor() as usize;
        let hd = (p.h_duet_sec * 2.0 / p.w_stft_sec).floor() as usize;
        let (na, nd) = (p.bins_alpha, p.bins_delta);
        let (ma, md) = (p.max_alpha, p.max_delta);
        let sgolay = SavitzkyGolay::new(3, 5).expect("valid");
        let mut out = Vec::new();
        let mut start = 0;
        while start + wd <= frames {
            let mut hist = vec![0.0; na * nd];
            for (tl, tr) in &stft[start..start + wd] {
                for k in 1..nfft {
                    let signed = if k <= nfft / 2 {
                        k as f64
                    } else {
                        k as f64 - nfft as f64
                    };
                    let omega = signed * 2.0 * PI / nfft as f64;
                    let rho = divide(tr[k] + EPS, tl[k] + EPS);
                    let alpha = rho.norm() - 1.0 / rho.norm();
                    let delta = -rho.arg() / omega;
                    if alpha.abs() < ma && delta.abs() < md {
                        let ia = (1.0 + (na - 1) as f64 * (alpha + ma) / (2.0 * ma)).round();
                        let id = (1.0 + (nd - 1) as f64 * (delta + md) / (2.0 * md)).round();
                        let w = (tl[k].norm() * tr[k].norm()).powi(2) * omega * omega;
                        hist[(ia as usize - 1) * nd + id as usize - 1] += w;
                    }
                }
            }
            let mut along_alpha = vec![0.0; na * nd];
            let mut both = vec![0.0; na * nd];
            sgolay.smooth_columns(&hist, nd, &mut along_alpha);
            sgolay.smooth_rows(&along_alpha, nd, &mut both);
            let max = both.iter().fold(0.0f64, |m, &v| m.max(v));
            out.extend(both.iter().map(|&v| v.max(0.0) / max));
            start += hd;
        }
        out
    }

    /// Noise in the left ear and, in the right, 0.9 times it one sample later plus some
    /// independent noise: cells spread over many bins around α = −0.2, δ = 1.
    #[test]
    fn matches_the_spec_written_out_with_a_plain_dft() {
        let fs = 16000.0;
        let p = DuetParams {
            bins_alpha: 21,
            bins_delta: 25,
            ..small()
        };
        let x = noise(2401, 5);
        let extra = noise(2400, 9);
        let left = x[1..].to_vec();
        let right: Vec<f64> = x[..2400]
            .iter()
            .zip(&extra)
            .map(|(v, e)| 0.9 * v + 0.3 * e)
            .collect();
        // At 1e-13 the spectra are a few hundred times ε = 2^−52, which then moves ρ.
        for scale in [1.0, 1e-13] {
            let l: Vec<f64> = left.iter().map(|v| v * scale).collect();
            let r: Vec<f64> = right.iter().map(|v| v * scale).collect();
            let want = reference(&p, fs, &l, &r);
            let (mut duet, info) = Duet::new(&p, &SignalInfo::time_domain(fs)).expect("valid");
            let got = run(&mut duet, &l, &r, &[700]);
            assert_eq!(got.len(), want.len());
            assert_eq!(
                got.len(),
                5 * info.width(),
                "blocks of 10 frames every 4 of 29"
            );
            let worst = got
                .iter()
                .zip(&want)
                .map(|(g, w)| (g - w).abs())
                .fold(0.0, f64::max);
            assert!(worst < 1e-13, "scale {scale}: off by {worst}");
            let zeros = got.iter().filter(|&&v| v == 0.0).count();
            assert!(zeros > 0 && zeros < got.len() / 2, "{zeros} clipped cells");
        }
    }

    /// `|α| < maxAlpha` and `|δ| < maxDelta` are strict: a cell exactly at a limit is out.
    #[test]
    fn range_limits_are_exclusive() {
        let info = SignalInfo::time_domain(16000.0);
        let (probe, _) = Duet::new(&small(), &info).expect("valid");
        let delta = PI / probe.omega[0];
        // Bin 1 with `L + ε` and `R + ε` as given (both exact in binary).
        let cell_of = |l: f64, r: f64, max_alpha: f64, max_delta: f64| {
            let p = DuetParams {
                max_alpha,
                max_delta,
                ..small()
            };
            let (mut duet, _) = Duet::new(&p, &info).expect("valid");
            duet.spec_l[1] = Complex64::new(l - EPS, 0.0);
            duet.spec_r[1] = Complex64::new(r - EPS, 0.0);
            assert_eq!((duet.spec_l[1].re + EPS, duet.spec_r[1].re + EPS), (l, r));
            let mut row = vec![f64::NAN; 2 * duet.omega.len()];
            duet.frame_cells(&mut row);
            (row[0], row[1])
        };
        let above = 1.000001;
        // ρ = 2: α = 2 − 1/2 = 1.5, δ = 0.
        assert!(cell_of(1.0, 2.0, 1.5 * above, 1.0).1 > 0.0);
        assert_eq!(cell_of(1.0, 2.0, 1.5, 1.0), (0.0, 0.0));
        // ρ = −1: α = 0, δ = −π/ω₁.
        assert!(cell_of(1.0, -1.0, 1.0, delta * above).1 > 0.0);
        assert_eq!(cell_of(1.0, -1.0, 1.0, delta), (0.0, 0.0));
    }

    #[test]
    fn reset_starts_a_new_stream_and_debug_names_the_sizes() {
        let info = SignalInfo::time_domain(16000.0);
        let (mut duet, _) = Duet::new(&small(), &info).expect("valid");
        let (x, y) = (noise(2000, 4), noise(2000, 8));
        let fresh = run(&mut duet, &x, &y, &[]);
        run(&mut duet, &y, &x, &[]);
        duet.reset();
        let again = run(&mut duet, &x, &y, &[]);
        assert!(!fresh.is_empty());
        assert!(fresh
            .iter()
            .zip(&again)
            .all(|(a, b)| a.to_bits() == b.to_bits()));
        assert_eq!(fresh.len(), again.len());
        let shown = format!("{duet:?}");
        assert!(
            shown.contains("nfft: 512") && shown.contains("(35, 51)"),
            "{shown}"
        );
    }

    /// Smith's division agrees with the textbook one to rounding, on both branches.
    #[test]
    fn smith_division_matches_complex_division() {
        let v = noise(400, 21);
        for q in v.chunks_exact(4) {
            let (a, b) = (Complex64::new(q[0], q[1]), Complex64::new(q[2], q[3]));
            let (got, want) = (divide(a, b), a / b);
            assert!((got - want).norm() <= 1e-13 * want.norm(), "{a} / {b}");
        }
    }

    #[test]
    fn smith_division_is_exact_on_easy_values() {
        let q = divide(Complex64::new(3.0, 4.0), Complex64::new(0.0, 2.0));
        assert_eq!((q.re, q.im), (2.0, -1.5));
        let q = divide(Complex64::new(1.0, 1.0), Complex64::new(2.0, 0.0));
        assert_eq!((q.re, q.im), (0.5, 0.5));
    }

    #[test]
    fn bad_parameters_name_themselves() {
        let info = SignalInfo::time_domain(16000.0);
        let cases: Vec<(&str, DuetParams)> = vec![
            (
                "duet_binsAlpha",
                DuetParams {
                    bins_alpha: 4,
                    ..DuetParams::default()
                },
            ),
            (
                "duet_binsDelta",
                DuetParams {
                    bins_delta: 1,
                    ..DuetParams::default()
                },
            ),
            (
                "duet_maxAlpha",
                DuetParams {
                    max_alpha: 0.0,
                    ..DuetParams::default()
                },
            ),
            (
                "duet_maxDelta",
                DuetParams {
                    max_delta: -1.0,
                    ..DuetParams::default()
                },
            ),
            (
                "duet_wSTFTSec",
                DuetParams {
                    w_stft_sec: 0.0,
                    ..DuetParams::default()
                },
            ),
            (
                "duet_wSTFTSec",
                DuetParams {
                    w_stft_sec: 1e-5,
                    ..DuetParams::default()
                },
            ),
            (
                "duet_wDUETSec",
                DuetParams {
                    w_duet_sec: 0.001,
                    ..DuetParams::default()
                },
            ),
            (
                "duet_hDUETSec",
                DuetParams {
                    h_duet_sec: 0.0,
                    ..DuetParams::default()
                },
            ),
            (
                "duet_hDUETSec",
                DuetParams {
                    h_duet_sec: 1e9,
                    ..DuetParams::default()
                },
            ),
            (
                "duet_binsAlpha",
                DuetParams {
                    bins_alpha: 1 << 20,
                    bins_delta: 1 << 20,
                    ..DuetParams::default()
                },
            ),
        ];
        for (name, p) in cases {
            let e = Duet::new(&p, &info).expect_err(name).to_string();
            assert!(e.contains(name), "{e}");
        }
        // A zero count is refused by the parameter's type, before the constructor.
        let mut map = afe_core::ParamMap::new();
        map.insert("duet_binsAlpha".into(), serde_json::json!(0));
        let e = DuetParams::from_map(&map)
            .expect_err("zero bins")
            .to_string();
        assert!(e.contains("duet_binsAlpha"), "{e}");
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 48, failure_persistence: None, ..ProptestConfig::default() })]

        #[test]
        fn any_chunking_is_bit_identical(
            chunks in prop::collection::vec(prop_oneof![Just(1usize), 1usize..200, 200usize..1500], 1..20),
        ) {
            let x = noise(5000, 3);
            let right: Vec<f64> = noise(5000, 11).iter().zip(&x).map(|(n, v)| 0.7 * v + 0.1 * n).collect();
            let info = SignalInfo::time_domain(16000.0);
            let (mut a, _) = Duet::new(&small(), &info).expect("valid");
            let (mut b, _) = Duet::new(&small(), &info).expect("valid");
            let whole = run(&mut a, &x, &right, &[]);
            let chunked = run(&mut b, &x, &right, &chunks);
            prop_assert!(!whole.is_empty());
            prop_assert_eq!(whole.len(), chunked.len());
            prop_assert!(whole.iter().zip(&chunked).all(|(p, q)| p.to_bits() == q.to_bits()));
        }
    }
}
