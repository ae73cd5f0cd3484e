//! `crosscorrelation`: normalised interaural cross-correlation per channel and frame over
//! lags −maxLag..maxLag (spec 18-crosscorrelation), computed by zero-padded real FFTs.

use std::sync::Arc;

use afe_core::framing::Frame;
use afe_core::lanes::vector_start;
use afe_core::window::{window, WINDOW_NAMES};
use afe_core::{
    Block, Error, ParamKind, ParamSpec, Params, Processor, Result, SignalInfo, SignalKind,
};
use realfft::num_complex::Complex64;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use serde::{Deserialize, Serialize};

use crate::cpu::has_avx512;
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

/// How the lags are computed: the choice depends only on the configuration.
enum Engine {
    /// Dot products per lag, eight channels per SIMD vector: fastest for short lag
    /// ranges such as the default 99 lags.
    Direct(Direct),
    /// Zero-padded real FFTs per channel: fastest for long lag ranges.
    Fft(Box<FftEngine>),
}

/// Channels per vector of the direct method.
const LANES: usize = 8;

/// One value per channel of a group, aligned to a cache line so that a vector load
/// never straddles two lines.
#[derive(Debug, Clone, Copy, Default)]
#[repr(align(64))]
struct Lanes([f64; LANES]);

/// Window, zero-padded frames and accumulators of the direct method, per group of
/// `LANES` channels (see [`vector_start`]; with fewer channels, the unused lanes stay zero).
struct Direct {
    win: Vec<f64>,
    max_lag: usize,
    /// Lags computed per pass (accumulators held in registers): 8 to 12 with AVX-512,
    /// else 4 or 5.
    lag_block: usize,
    /// Windowed left frame, row `p` holding sample `p − maxLag`, zero outside the
    /// frame; `W + lags − 1` rows per group, `lags` rounded up to `lag_block`.
    left: Vec<Lanes>,
    /// Windowed right frame, `W` rows per group.
    right: Vec<Lanes>,
    /// One row per computed lag.
    acc: Vec<Lanes>,
    /// Energies of the current frames, per group.
    energy: Vec<Energy>,
}

/// FFT plans, window and scratch of the per-channel correlation.
struct FftEngine {
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
        let (method, w, max_lag) = match &self.engine {
            Engine::Direct(d) => ("direct", d.win.len(), d.max_lag),
            Engine::Fft(f) => ("fft", f.win.len(), f.max_lag),
        };
        f.debug_struct("Crosscorrelation")
            .field("method", &method)
            .field("window", &w)
            .field("max_lag", &max_lag)
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
        let win = window(&params.wname, w, "cc_wname")?;
        let nc = input.channels();
        let engine = if prefer_direct(w, max_lag) {
            Engine::Direct(Direct::new(win, max_lag, nc))
        } else {
            Engine::Fft(Box::new(FftEngine::new(win, max_lag)))
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

/// Whether dot products beat the FFT for a `w`-sample window and lags up to `max_lag`:
/// the direct method costs `w·(2·maxLag+1)` multiply-adds per channel, eight channels
/// at a time, the FFT about three transforms per channel. Measured at 44.1 kHz (882-sample
/// window, one core, `afe bench -r crosscorrelation -p cc_maxDelaySec=…`): direct is
/// faster at 99 lags (1.1 ms) and 443 (5 ms), the FFT at 883 (10 ms) and beyond.
fn prefer_direct(w: usize, max_lag: usize) -> bool {
    let nfft = (w + max_lag.min(w - 1)).next_power_of_two() as f64;
    let direct = (w * (2 * max_lag + 1)) as f64 / LANES as f64;
    let fft = 3.0 * nfft * nfft.log2();
    direct <= fft
}

impl Direct {
    fn new(win: Vec<f64>, max_lag: usize, nc: usize) -> Self {
        // As many accumulators as the registers hold (32 AVX-512 registers, 16 AVX2 ones,
        // two per vector), the count that pads the lags least: 11 for the default 99.
        let blocks = if has_avx512() { 8..=12 } else { 4..=5 };
        let nl = 2 * max_lag + 1;
        let best = blocks.rev().min_by_key(|b| nl.next_multiple_of(*b));
        Self::with_lag_block(win, max_lag, nc, best.unwrap_or(4))
    }

    fn with_lag_block(win: Vec<f64>, max_lag: usize, nc: usize, lag_block: usize) -> Self {
        assert!(
            matches!(lag_block, 4 | 5 | 8..=12),
            "no dot-product kernel for {lag_block} lags per pass"
        );
        let lags = (2 * max_lag + 1).next_multiple_of(lag_block);
        let w = win.len();
        let groups = nc.div_ceil(LANES);
        Direct {
            left: vec![Lanes::default(); groups * (w + lags - 1)],
            right: vec![Lanes::default(); groups * w],
            acc: vec![Lanes::default(); lags],
            energy: vec![([0.0; LANES], [0.0; LANES]); groups],
            win,
            max_lag,
            lag_block,
        }
    }

    /// Correlates every channel of one frame pair (`[time][channel]`) into `out`
    /// (`[channel][lag]`).
    fn correlate(&mut self, frame_l: Frame<'_>, frame_r: Frame<'_>, nc: usize, out: &mut [f64]) {
        let w = self.win.len();
        let nl = 2 * self.max_lag + 1;
        let shape = (nc, self.max_lag);
        let (left, right, energy) = (&mut self.left[..], &mut self.right[..], &mut self.energy);
        window_frames(&self.win, (frame_l, frame_r), shape, left, right, energy);
        let dot = match self.lag_block {
            5 => dot_lags::<5>,
            8 => dot_lags::<8>,
            9 => dot_lags::<9>,
            10 => dot_lags::<10>,
            11 => dot_lags::<11>,
            12 => dot_lags::<12>,
            _ => dot_lags::<4>,
        };
        let rows_l = self.left.len() / self.energy.len();
        let groups = self
            .left
            .chunks_exact(rows_l)
            .zip(self.right.chunks_exact(w));
        for (g, ((left, right), (el, er))) in groups.zip(&self.energy).enumerate() {
            dot(left, right, &mut self.acc);
            let c0 = vector_start(g, LANES, nc);
            for l in 0..LANES.min(nc) {
                let norm = f64::EPSILON + (el[l] * er[l]).sqrt();
                let o = &mut out[(c0 + l) * nl..(c0 + l + 1) * nl];
                for (v, a) in o.iter_mut().zip(&self.acc) {
                    *v = a.0[l] / norm;
                }
            }
        }
    }
}

/// Per-group energies `Σ (win·x)²` of the left and right frames.
type Energy = ([f64; LANES], [f64; LANES]);

/// Writes the windowed frame pair (`[time][channel]`, `nc` wide) into the lanes of the
/// groups of `left` (after `maxLag` zero rows) and `right` (see [`vector_start`]), row by
/// row so that each frame row is read once; then their energies into `energy`, group by
/// group with the sums in registers.
#[multiversion::multiversion(targets("x86_64+avx512f+avx512vl", "x86_64+avx2"))]
fn window_frames<'a>(
    win: &[f64],
    (frame_l, frame_r): (Frame<'a>, Frame<'a>),
    (nc, max_lag): (usize, usize),
    left: &mut [Lanes],
    right: &mut [Lanes],
    energy: &mut [Energy],
) {
    let (w, groups) = (win.len(), energy.len());
    let rows_l = left.len() / groups;
    let parts = [(frame_l.head, frame_r.head), (frame_l.tail, frame_r.tail)];
    let rows = parts
        .into_iter()
        .flat_map(|(l, r)| l.chunks_exact(nc).zip(r.chunks_exact(nc)));
    for (n, ((row_l, row_r), &wn)) in rows.zip(win).enumerate() {
        for g in 0..groups {
            let c0 = vector_start(g, LANES, nc);
            let (pl, pr) = (&mut left[g * rows_l + max_lag + n], &mut right[g * w + n]);
            if nc >= LANES {
                let mut x = [[0.0; LANES]; 2];
                x[0].copy_from_slice(&row_l[c0..c0 + LANES]);
                x[1].copy_from_slice(&row_r[c0..c0 + LANES]);
                for ear in &mut x {
                    for v in ear.iter_mut() {
                        *v *= wn;
                    }
                }
                (pl.0, pr.0) = (x[0], x[1]);
            } else {
                for l in 0..nc {
                    (pl.0[l], pr.0[l]) = (wn * row_l[c0 + l], wn * row_r[c0 + l]);
                }
            }
        }
    }
    let frames = left.chunks_exact(rows_l).zip(right.chunks_exact(w));
    for ((pl, pr), (el, er)) in frames.zip(energy.iter_mut()) {
        let (mut sl, mut sr) = ([0.0; LANES], [0.0; LANES]);
        for (vl, vr) in pl[max_lag..max_lag + w].iter().zip(pr) {
            for l in 0..LANES {
                sl[l] += vl.0[l] * vl.0[l];
                sr[l] += vr.0[l] * vr.0[l];
            }
        }
        (*el, *er) = (sl, sr);
    }
}

/// `acc[i] = Σ_n left[n + i] · right[n]` for every row `i` of `acc`, lanes apart, with
/// `B` accumulators in registers per pass. Fused multiply-adds: one rounding per term,
/// the same on every machine (a library call where the CPU lacks FMA).
#[multiversion::multiversion(targets("x86_64+avx512f+avx512vl+fma", "x86_64+avx2+fma"))]
fn dot_lags<const B: usize>(left: &[Lanes], right: &[Lanes], acc: &mut [Lanes]) {
    let w = right.len();
    for (j, out) in acc.chunks_exact_mut(B).enumerate() {
        let rows = &left[j * B..j * B + w + B - 1];
        let mut a = [Lanes::default(); B];
        // Two samples per step share B − 1 of their B + 1 left rows (fewer loads); each
        // accumulator still adds its terms in sample order.
        let pairs = right.chunks_exact(2);
        let odd = pairs.remainder();
        for (n, r) in pairs.enumerate() {
            let win = &rows[2 * n..2 * n + B + 1];
            for i in 0..B {
                for l in 0..LANES {
                    let t = win[i].0[l].mul_add(r[0].0[l], a[i].0[l]);
                    a[i].0[l] = win[i + 1].0[l].mul_add(r[1].0[l], t);
                }
            }
        }
        if let [r] = odd {
            let win = &rows[w - 1..w - 1 + B];
            for i in 0..B {
                for l in 0..LANES {
                    a[i].0[l] = win[i].0[l].mul_add(r.0[l], a[i].0[l]);
                }
            }
        }
        out.copy_from_slice(&a);
    }
}

impl FftEngine {
    fn new(win: Vec<f64>, max_lag: usize) -> Self {
        let w = win.len();
        // The AFE transforms 2^nextpow2(2W − 1) points; only lags up to L = min(maxLag,
        // W − 1) are kept, and a circular correlation of N ≥ W + L points has no wrap-around
        // there, so the smaller transform gives the same values (to rounding) at half the cost.
        let nfft = (w + max_lag.min(w - 1)).next_power_of_two();
        let mut planner = RealFftPlanner::<f64>::new();
        let fft = planner.plan_fft_forward(nfft);
        let ifft = planner.plan_fft_inverse(nfft);
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

    /// Correlates channel `c` of the current frames into `out` (one value per lag).
    fn correlate(&mut self, frame_l: Frame<'_>, frame_r: Frame<'_>, c: usize, out: &mut [f64]) {
        let w = self.win.len();
        let nfft = self.time_l.len();
        let (mut el, mut er) = (0.0, 0.0);
        let rows = frame_l.rows().zip(frame_r.rows());
        for (n, (rl, rr)) in rows.enumerate() {
            let l = self.win[n] * rl[c];
            let r = self.win[n] * rr[c];
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
        let ears = (inputs[0].as_slice(), inputs[1].as_slice());
        let n = self.frames.available(ears.0, ears.1);
        let max_lag = match &self.engine {
            Engine::Direct(d) => d.max_lag,
            Engine::Fft(f) => f.max_lag,
        };
        let nl = 2 * max_lag + 1;
        let out = outputs[0].resize_to(n);
        for (k, out) in out.chunks_exact_mut(nc * nl).enumerate() {
            let (fl, fr) = self.frames.frame(ears, k);
            match &mut self.engine {
                Engine::Direct(d) => d.correlate(fl, fr, nc, out),
                Engine::Fft(f) => {
                    for (c, o) in out.chunks_exact_mut(nl).enumerate() {
                        f.correlate(fl, fr, c, o);
                    }
                }
            }
        }
        self.frames.advance(ears.0, ears.1, n);
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
    fn direct_and_fft_engines_agree() {
        // 11 channels: a full group and a partial one; lags up to and beyond the window.
        let (w, nc) = (40, 11);
        let x = |seed: usize| -> Vec<f64> {
            (0..w * nc)
                .map(|i| ((i * 7919 + seed) % 1013) as f64 / 1013.0)
                .collect()
        };
        let (fl, fr) = (x(1), x(5));
        for max_lag in [0, 3, 17, 39, 40] {
            let win = window("hann", w, "").expect("hann");
            let nl = 2 * max_lag + 1;
            let framing = afe_core::framing::FrameBuffer::new(nc, w, w);
            let (fl, fr) = (framing.frame(&fl, 0), framing.frame(&fr, 0));
            let mut fft = FftEngine::new(win.clone(), max_lag);
            let mut b = vec![0.0; nc * nl];
            for (c, o) in b.chunks_exact_mut(nl).enumerate() {
                fft.correlate(fl, fr, c, o);
            }
            assert!(b.iter().any(|v| *v > 0.1));
            for lag_block in [4, 5, 8, 9, 10, 11, 12] {
                let mut direct = Direct::with_lag_block(win.clone(), max_lag, nc, lag_block);
                let mut a = vec![0.0; nc * nl];
                direct.correlate(fl, fr, nc, &mut a);
                for (i, (u, v)) in a.iter().zip(&b).enumerate() {
                    let (c, lag) = (i / nl, i % nl);
                    assert!(
                        (u - v).abs() < 1e-13,
                        "{lag}/{max_lag}, channel {c}: {u} vs {v}"
                    );
                }
            }
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
