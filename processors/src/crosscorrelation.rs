//! `crosscorrelation`: normalised interaural cross-correlation per channel and frame over
//! lags −maxLag..maxLag (spec 18-crosscorrelation): by dot products over even and odd
//! samples for short lag ranges, by zero-padded real FFTs for long ones.

use std::ops::Range;
use std::sync::Arc;

use afe_core::cpu::has_avx512;
use afe_core::descriptor::{request_def, Built, Descriptor, Ears, RequestDef};
use afe_core::framing::Frame;
use afe_core::lanes::vector_start;
use afe_core::window::{window, WINDOW_NAMES};
use afe_core::{Block, Error, ParamKind, ParamSpec, Params, Part, Processor, Result, SignalInfo};
use realfft::num_complex::Complex64;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use serde::{Deserialize, Serialize};

use crate::framed::{check_framing, check_work, EarFrames};

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
    /// The channels it outputs: all (`None`) or, as a part of a split, this range.
    part: Option<Range<usize>>,
}

/// How the lags are computed: the choice depends only on the configuration.
enum Engine {
    /// Dot products per lag (a two-parallel fast FIR), eight channels per SIMD vector:
    /// fastest for short lag ranges such as the default 99 lags.
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

/// Window, polyphase frames and accumulators of the direct method, for one group of
/// `LANES` channels at a time (see [`vector_start`]; with fewer channels, the unused
/// lanes stay zero).
///
/// The correlation `acc[i] = Σ_n L[n+i]·r[n]` (`L`: the left frame after `maxLag` zero
/// rows, `r`: the right frame, `i = ℓ + maxLag`) is split over even and odd samples, a
/// two-parallel fast FIR: with `X(a, b)[k] = Σ_m a[m+k]·b[m]` over half frames,
/// `E = X(L_even, r_even)`, `O = X(L_odd, r_odd)` and
/// `D = X(L_odd − L_even[·+1], r_even − r_odd)`,
///
/// ```text
/// acc[2k] = E[k] + O[k]        acc[2k+1] = D[k] + O[k] + E[k+1]
/// ```
///
/// three half-length correlations of about half the lags each: three quarters of the
/// multiply-adds of the plain sum. It equals the plain sum to rounding (spec N17): `D`
/// correlates the differences of neighbouring samples, small for the smooth IHC envelopes,
/// so nothing cancels (the sums of Karatsuba's form would, by ~1e-15).
struct Direct {
    win: Vec<f64>,
    max_lag: usize,
    /// Lags computed per pass (accumulators held in registers): 8 to 12 with AVX-512,
    /// else 4 or 5.
    lag_block: usize,
    /// First channel of each group.
    starts: Vec<usize>,
    /// Lags of each half-length correlation: `maxLag + 1`, rounded up to `lag_block`.
    half_lags: usize,
    /// The current group's left polyphase rows (each group in turn, so that they stay
    /// in cache for the dot products): `L_even`, `L_odd` and
    /// `L_odd − L_even[·+1]`, `W/2 + half_lags` rows each, zero outside the frame.
    left: Vec<Lanes>,
    /// The current group's right rows: `r_even`, `r_odd` and `r_even − r_odd`, `W/2` rows each.
    right: Vec<Lanes>,
    /// `E`, `O` and `D` of one group, `half_lags` rows each.
    acc: Vec<Lanes>,
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
            input.channels(),
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
            // found by fuzzing: 1.4 GB for a long window when it kept every group's rows
            // (one group of channels at a time, few lags: the window is what counts)
            check_work(
                ("cc_wSizeSec", params.w_size_sec),
                direct_work(w, max_lag),
                &format!("this window of {w} samples"),
                "shorten the window",
            )?;
            Engine::Direct(Direct::new(win, max_lag, nc))
        } else {
            Engine::Fft(Box::new(FftEngine::new(win, max_lag)))
        };
        let cc = Crosscorrelation {
            frames: EarFrames::new(nc, w, h),
            engine,
            part: None,
        };
        let lags_s = (0..=2 * max_lag)
            .map(|i| (i as f64 - max_lag as f64) / fs)
            .collect();
        let info = input
            .correlation(1.0 / params.h_size_sec, lags_s)
            .with_unit(Self::OUTPUT_UNIT)
            .with_window_s(params.w_size_sec);
        Ok((cc, info))
    }
}

/// At most the `f64` values of the direct engine's buffers for a `w`-sample window and
/// lags up to `max_lag`: for one group of channels, three rows of half a window per ear,
/// and three of the lags (padded by at most 11) for the left frame's shifts and the sums.
fn direct_work(w: usize, max_lag: usize) -> usize {
    LANES * 3 * (2 * (w / 2) + 2 * (max_lag + 12))
}

/// Whether dot products beat the FFT for a `w`-sample window and lags up to `max_lag`:
/// the direct method costs `3·(w/2)·(maxLag+1)` multiply-adds per channel, eight channels
/// at a time, the FFT about three transforms per channel. At 44.1 kHz (882-sample window)
/// this picks dot products for 99 and 443 lags, the FFT for 883 and beyond, which is
/// where the plain dot products measured faster and slower (`afe bench -r
/// crosscorrelation -p cc_maxDelaySec=…`, one core); the fast FIR moves the crossover
/// further out, not below.
fn prefer_direct(w: usize, max_lag: usize) -> bool {
    let nfft = (w + max_lag.min(w - 1)).next_power_of_two() as f64;
    let direct = (3 * (w / 2) * (max_lag + 1)) as f64 / LANES as f64;
    let fft = 3.0 * nfft * nfft.log2();
    direct <= fft
}

impl Direct {
    fn new(win: Vec<f64>, max_lag: usize, nc: usize) -> Self {
        // As many accumulators as the registers hold (32 AVX-512 registers, 16 AVX2 ones,
        // two per vector), the count that pads the lags least: 10 for the default 50
        // lags per half-length correlation.
        let blocks = if has_avx512() { 8..=12 } else { 4..=5 };
        let best = blocks
            .rev()
            .min_by_key(|b| (max_lag + 1).next_multiple_of(*b));
        Self::with_lag_block(win, max_lag, nc, best.unwrap_or(4))
    }

    fn with_lag_block(win: Vec<f64>, max_lag: usize, nc: usize, lag_block: usize) -> Self {
        assert!(
            matches!(lag_block, 4 | 5 | 8..=12),
            "no dot-product kernel for {lag_block} lags per pass"
        );
        assert!(
            win.len().is_multiple_of(2),
            "the AFE's windows have an even length"
        );
        let starts = (0..nc.div_ceil(LANES))
            .map(|g| vector_start(g, LANES, nc))
            .collect();
        Self::for_groups(win, max_lag, lag_block, starts)
    }

    /// The buffers for the groups whose first channels are `starts`.
    fn for_groups(win: Vec<f64>, max_lag: usize, lag_block: usize, starts: Vec<usize>) -> Self {
        let half_lags = (max_lag + 1).next_multiple_of(lag_block);
        let half = win.len() / 2;
        Direct {
            starts,
            left: vec![Lanes::default(); 3 * (half + half_lags)],
            right: vec![Lanes::default(); 3 * half],
            acc: vec![Lanes::default(); 3 * half_lags],
            win,
            max_lag,
            lag_block,
            half_lags,
        }
    }

    /// The same computation for groups `groups` only (their lanes compute what they
    /// compute here, so a part's channels get the same values bit for bit).
    fn part(&self, groups: Range<usize>) -> Direct {
        let starts = self.starts[groups].to_vec();
        Self::for_groups(self.win.clone(), self.max_lag, self.lag_block, starts)
    }

    /// Correlates the channels of its groups of one frame pair (`[time][channel]`, over
    /// the frames' columns) into `out` (`[channel][lag]`, from their first column on).
    fn correlate(&mut self, frame_l: Frame<'_>, frame_r: Frame<'_>, out: &mut [f64]) {
        for g in 0..self.starts.len() {
            let (ml, mr) = self.correlate_group(frame_l, frame_r, g, out);
            let lanes = LANES.min(frame_l.width());
            if (0..lanes).any(|l| in_subnormal_band(ml[l], mr[l])) {
                self.correlate_group_ieee(frame_l, frame_r, g, out);
            }
        }
    }

    /// [`Direct::correlate_group`] in IEEE arithmetic, for a group whose products sink
    /// into the subnormals where the thread flushes them (see [`in_subnormal_band`]).
    #[cold]
    #[inline(never)]
    fn correlate_group_ieee(&mut self, fl: Frame<'_>, fr: Frame<'_>, g: usize, out: &mut [f64]) {
        let _ieee = afe_core::denormals::GradualUnderflow::enable();
        self.correlate_group(fl, fr, g, out);
    }

    /// Correlates group `g`'s channels of one frame pair into their rows of `out`;
    /// returns each lane's largest windowed magnitudes, left and right.
    #[inline(always)]
    fn correlate_group(
        &mut self,
        frame_l: Frame<'_>,
        frame_r: Frame<'_>,
        g: usize,
        out: &mut [f64],
    ) -> ([f64; LANES], [f64; LANES]) {
        let (nc, first) = (frame_l.width(), frame_l.first_column());
        let half = self.win.len() / 2;
        let (rows_l, k) = (half + self.half_lags, self.half_lags);
        let dot = match self.lag_block {
            5 => dot_lags::<5>,
            8 => dot_lags::<8>,
            9 => dot_lags::<9>,
            10 => dot_lags::<10>,
            11 => dot_lags::<11>,
            12 => dot_lags::<12>,
            _ => dot_lags::<4>,
        };
        let nl = 2 * self.max_lag + 1;
        let window = if nc < LANES {
            window_frames::<false>
        } else {
            window_frames::<true>
        };
        let c0 = self.starts[g];
        let (left, right) = (&mut self.left, &mut self.right);
        let (el, er, ml, mr) = window(&self.win, (frame_l, frame_r), self.max_lag, c0, left, right);
        let phases = left.chunks_exact(rows_l).zip(right.chunks_exact(half));
        for ((l, r), acc) in phases.zip(self.acc.chunks_exact_mut(k)) {
            dot(l, r, acc);
        }
        let (e, rest) = self.acc.split_at(k);
        let (o, d) = rest.split_at(k);
        for l in 0..LANES.min(nc) {
            let norm = f64::EPSILON + (el[l] * er[l]).sqrt();
            let c = c0 + l - first;
            let out = &mut out[c * nl..(c + 1) * nl];
            for (i, v) in out.iter_mut().enumerate() {
                let j = i / 2;
                let sum = if i % 2 == 0 {
                    e[j].0[l] + o[j].0[l]
                } else {
                    d[j].0[l] + o[j].0[l] + e[j + 1].0[l]
                };
                *v = sum / norm;
            }
        }
        (ml, mr)
    }
}

/// Whether a frame pair whose largest windowed magnitudes are `left` and `right` has
/// products that flushing subnormals to zero would change beyond the round-off (it
/// drops them whole) while IEEE arithmetic, the AFE's, keeps them: the decay after
/// digital silence, 300 dB and more below the signal, whose correlation's shape (its
/// peak, the ITD) the AFE still computes. Not where every product underflows to 0 in
/// IEEE arithmetic too (below 2^−1076), nor where the thread keeps subnormals.
pub(crate) fn in_subnormal_band(left: f64, right: f64) -> bool {
    // log2 of the largest product (the product itself could flush)
    let product = left.log2() + right.log2();
    left > 0.0
        && right > 0.0
        && (-1076.0..SUBNORMAL_PRODUCT_LOG2).contains(&product)
        && afe_core::denormals::flushing()
}

/// log2 of the largest product below which a frame pair is correlated in IEEE
/// arithmetic (1e−280: its products a window's edge away, 1e−10 smaller, stay normal).
const SUBNORMAL_PRODUCT_LOG2: f64 = -930.1;

/// A group's energies `Σ (win·x)²` of the left and right frames, and their largest
/// windowed magnitudes.
type Energy = ([f64; LANES], [f64; LANES], [f64; LANES], [f64; LANES]);

afe_core::simd_kernel!(
    /// Windows the frame pair (`[time][channel]`) into the polyphase rows of the group
    /// whose first input channel is `start` (`left` and `right` laid out as in [`Direct`]),
    /// and returns the frames' energies, summed in time order in registers, and their
    /// largest windowed magnitudes. Row `n` of the
    /// left frame is row `p = n + maxLag` of `L`: row `p / 2` of `L_even` or `L_odd`, and of
    /// the differences with its neighbour (`L[p−1] − L[p]` at row `p/2 − 1` for an even `p`,
    /// `r[n−1] − r[n]` at row `n / 2` for an odd `n`). `WIDE`: at least `LANES` channels
    /// (else the frame's channels fill the first lanes, the others stay zero).
    fn window_frames<'a, const WIDE: bool>(
        win: &[f64],
        (frame_l, frame_r): (Frame<'a>, Frame<'a>),
        max_lag: usize,
        start: usize,
        left: &mut [Lanes],
        right: &mut [Lanes],
    ) -> Energy {
        let (rows_l, half) = (left.len() / 3, right.len() / 3);
        let (mut el, mut er) = ([0.0; LANES], [0.0; LANES]);
        let (mut ml, mut mr) = ([0.0f64; LANES], [0.0f64; LANES]);
        // the previous row (zero before the frame)
        let (mut prev_l, mut prev_r) = ([0.0; LANES], [0.0; LANES]);
        let (nc, first) = (frame_l.width(), frame_l.first_column());
        let mut n = 0;
        let segments = frame_l.segments().into_iter().zip(frame_r.segments());
        for ((part_l, stride, at), (part_r, _, _)) in segments {
            let rows = part_l.chunks_exact(stride).zip(part_r.chunks_exact(stride));
            for ((row_l, row_r), &w) in rows.zip(&win[n..]) {
                let p = n + max_lag;
                let (mut xl, mut xr) = ([0.0; LANES], [0.0; LANES]);
                if WIDE {
                    let c0 = at + start - first;
                    xl.copy_from_slice(&row_l[c0..c0 + LANES]);
                    xr.copy_from_slice(&row_r[c0..c0 + LANES]);
                } else {
                    xl[..nc].copy_from_slice(&row_l[at..at + nc]);
                    xr[..nc].copy_from_slice(&row_r[at..at + nc]);
                }
                for l in 0..LANES {
                    xl[l] *= w;
                    xr[l] *= w;
                    el[l] += xl[l] * xl[l];
                    er[l] += xr[l] * xr[l];
                    ml[l] = ml[l].max(xl[l].abs());
                    mr[l] = mr[l].max(xr[l].abs());
                }
                left[(p % 2) * rows_l + p / 2].0 = xl;
                right[(n % 2) * half + n / 2].0 = xr;
                if p.is_multiple_of(2) && p >= 2 {
                    let s = &mut left[2 * rows_l + p / 2 - 1].0;
                    for l in 0..LANES {
                        s[l] = prev_l[l] - xl[l];
                    }
                }
                if n % 2 == 1 {
                    let s = &mut right[2 * half + n / 2].0;
                    for l in 0..LANES {
                        s[l] = prev_r[l] - xr[l];
                    }
                }
                (prev_l, prev_r) = (xl, xr);
                n += 1;
            }
        }
        // a last row of odd parity: its difference with the zero after the frame (row `p`)
        let p = n + max_lag;
        if p.is_multiple_of(2) {
            left[2 * rows_l + p / 2 - 1].0 = prev_l;
        }
        (el, er, ml, mr)
    }
);

afe_core::simd_kernel!(
    fma,
    /// `acc[i] = Σ_n left[n + i] · right[n]` for every row `i` of `acc`, lanes apart, with
    /// `B` accumulators in registers per pass. Fused multiply-adds: one rounding per term,
    /// the same on every machine (a library call where the CPU lacks FMA).
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
);

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

    /// Correlates column `c` of the current frames into `out` (one value per lag).
    fn correlate(&mut self, frame_l: Frame<'_>, frame_r: Frame<'_>, c: usize, out: &mut [f64]) {
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

impl Crosscorrelation {
    fn max_lag(&self) -> usize {
        match &self.engine {
            Engine::Direct(d) => d.max_lag,
            Engine::Fft(f) => f.max_lag,
        }
    }

    /// Channel ranges of up to `parts` parts over `nc` channels: for the direct method,
    /// whole groups, cut only where a group does not overlap the next (see
    /// [`vector_start`]), so each part's lanes are the groups of one call.
    fn part_ranges(&self, parts: usize, nc: usize) -> Vec<(Range<usize>, Range<usize>)> {
        match &self.engine {
            Engine::Direct(d) => {
                let groups = d.starts.len();
                let parts = parts.min(groups);
                // `p·groups/parts` rises strictly with `p`, from 1 to below `groups`
                let inner = (1..parts)
                    .map(|p| p * groups / parts)
                    .filter(|&g| d.starts[g] == g * LANES);
                let cuts: Vec<usize> = std::iter::once(0)
                    .chain(inner)
                    .chain(std::iter::once(groups))
                    .collect();
                cuts.windows(2)
                    .map(|w| {
                        let end = if w[1] == groups { nc } else { d.starts[w[1]] };
                        (d.starts[w[0]]..end, w[0]..w[1])
                    })
                    .collect()
            }
            Engine::Fft(_) => {
                let parts = parts.min(nc).max(1);
                (0..parts)
                    .map(|p| (p * nc / parts..(p + 1) * nc / parts, 0..0))
                    .collect()
            }
        }
    }
}

impl Processor for Crosscorrelation {
    fn process(&mut self, inputs: &[&Block], outputs: &mut [Block]) {
        let nc = inputs[0].width();
        let ears = (inputs[0].as_slice(), inputs[1].as_slice());
        let n = self.frames.available(ears.0, ears.1);
        let nl = 2 * self.max_lag() + 1;
        let channels = self.part.clone().unwrap_or(0..nc);
        let out = outputs[0].resize_to(n);
        for (k, out) in out.chunks_exact_mut(channels.len() * nl).enumerate() {
            let (fl, fr) = self.frames.frame(ears, k);
            match &mut self.engine {
                Engine::Direct(d) => d.correlate(fl, fr, out),
                Engine::Fft(f) => {
                    for (c, o) in (0..channels.len()).zip(out.chunks_exact_mut(nl)) {
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

    /// Splits the channels (whole groups of the direct method) into up to `parts` ranges.
    fn split(&self, parts: usize) -> Option<Vec<Part>> {
        let nc = self.frames.width();
        let ranges = self.part_ranges(parts, nc);
        if ranges.len() < 2 || self.part.is_some() {
            return None;
        }
        let nl = 2 * self.max_lag() + 1;
        let part = |(channels, groups): (Range<usize>, Range<usize>)| {
            let engine = match &self.engine {
                Engine::Direct(d) => Engine::Direct(d.part(groups)),
                Engine::Fft(f) => Engine::Fft(Box::new(FftEngine::new(f.win.clone(), f.max_lag))),
            };
            Part {
                widths: vec![channels.len() * nl],
                processor: Box::new(Crosscorrelation {
                    frames: self.frames.columns(channels.clone()),
                    engine,
                    part: Some(channels),
                }),
            }
        };
        Some(ranges.into_iter().map(part).collect())
    }

    /// Each output row is the parts' rows side by side. The parts keep the rows of their
    /// channels, so the join only counts rows (what [`Processor::rejoin`] takes back).
    fn join(&mut self, inputs: &[&Block], parts: &[&[Block]], outputs: &mut [Block]) {
        self.frames.count_only();
        let ears = (inputs[0].as_slice(), inputs[1].as_slice());
        let n = self.frames.available(ears.0, ears.1);
        let row_width = outputs[0].width();
        let out = outputs[0].resize_to(n);
        let mut at = 0;
        for part in parts {
            let width = part[0].width();
            for (row, share) in out.chunks_exact_mut(row_width).zip(part[0].rows()) {
                row[at..at + width].copy_from_slice(share);
            }
            at += width;
        }
        self.frames.advance(ears.0, ears.1, n);
    }

    fn part_state(&self) -> Option<&dyn std::any::Any> {
        Some(&self.frames)
    }

    fn rejoin(&mut self, parts: &[&dyn Processor]) {
        let frames: Vec<&EarFrames> = parts
            .iter()
            .filter_map(|p| p.part_state()?.downcast_ref::<EarFrames>())
            .collect();
        if !frames.is_empty() && frames.len() == parts.len() {
            self.frames = EarFrames::joined(&frames);
        }
    }
}

impl Descriptor for Crosscorrelation {
    type Params = CrosscorrelationParams;
    const NAME: &'static str = "crosscorrelation";
    const DEPENDENCY: &'static str = "innerhaircell";
    const EARS: Ears = Ears::Binaural;
    const DESCRIPTION: &'static str =
        "normalised interaural cross-correlation per frame, channel and lag";
    const OUTPUT_UNIT: &'static str = "";

    fn build(params: &CrosscorrelationParams, inputs: &[SignalInfo]) -> Result<Built> {
        let (p, out) = Crosscorrelation::new(params, &inputs[0])?;
        Ok(Built::new(p, vec![out]))
    }
}

/// The registry entry of `crosscorrelation`.
pub static REQUEST: RequestDef = request_def::<Crosscorrelation>();

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::noise;

    /// Parts over channel ranges, joined, give the unsplit output bit for bit, for the
    /// direct method (groups cut where they do not overlap) and the FFT, over chunks
    /// with and without complete frames, and so does the processor after it took its
    /// state back from the parts; where no cut is possible there is no split.
    #[test]
    fn split_parts_joined_equal_one_processor() {
        let direct = CrosscorrelationParams::default();
        // lags as long as a 100-ms window: the FFT method
        let fft = CrosscorrelationParams {
            w_size_sec: 0.1,
            h_size_sec: 0.05,
            max_delay_sec: 0.1,
            ..Default::default()
        };
        let cases = [
            (31, &direct, 2, 2),
            (32, &direct, 3, 3),
            (16, &direct, 2, 2),
            (16, &direct, 3, 2),
            (9, &direct, 2, 0),
            (6, &direct, 2, 0),
            (5, &fft, 2, 2),
        ];
        for (nc, p, parts, expected) in cases {
            let fs = 16000.0;
            let cf = (0..nc).map(|c| 100.0 * (c + 1) as f64).collect();
            let info = SignalInfo::time_frequency(fs, cf);
            let (mut whole, out_info) = Crosscorrelation::new(p, &info).expect("valid");
            let (mut joined, _) = Crosscorrelation::new(p, &info).expect("valid");
            assert_eq!(
                matches!(whole.engine, Engine::Fft(_)),
                std::ptr::eq(p, &fft),
                "{nc}"
            );
            let mut split: Option<Vec<Part>> = None;
            let mut made = 0;
            for (k, len) in [100, 400, 7, 1000, 3333, 1, 900].into_iter().enumerate() {
                let l = Block::from_vec(noise(len * nc, 2 * k as u64), nc);
                let r = Block::from_vec(noise(len * nc, 2 * k as u64 + 1), nc);
                let mut want = vec![Block::new(out_info.width())];
                whole.process(&[&l, &r], &mut want);
                // split after the first chunk, so that the parts start from a state
                if k == 1 {
                    split = joined.split(parts);
                    made = split.as_ref().map_or(0, Vec::len);
                }
                // the parts dropped after four chunks, their state taken back
                if k == 5 {
                    if let Some(split) = split.take() {
                        let shares: Vec<&dyn Processor> =
                            split.iter().map(|p| p.processor.as_ref()).collect();
                        joined.rejoin(&shares);
                    }
                }
                let mut got = vec![Block::new(out_info.width())];
                match split.as_mut() {
                    Some(split) => {
                        let mut shares: Vec<Vec<Block>> = Vec::new();
                        for part in split.iter_mut() {
                            let mut out = vec![Block::new(part.widths[0])];
                            part.processor.process(&[&l, &r], &mut out);
                            shares.push(out);
                        }
                        let views: Vec<&[Block]> = shares.iter().map(Vec::as_slice).collect();
                        joined.join(&[&l, &r], &views, &mut got);
                    }
                    None => joined.process(&[&l, &r], &mut got),
                }
                assert_eq!(
                    got[0].as_slice(),
                    want[0].as_slice(),
                    "{nc} channels, chunk {k}"
                );
            }
            // 9 channels: groups at 0 and 1 overlap; 6: one group
            assert_eq!(made, expected, "{nc} channels");
        }
    }

    #[test]
    fn specs_match_struct() {
        afe_core::params::check_param_specs::<CrosscorrelationParams>();
    }

    /// The cost model's crossover at 44.1 kHz (882-sample window, a 2048-point FFT from
    /// 143 lags on): dot products up to 407 lags each way (3·441·408/8 = 67,473 against
    /// 3·2048·11 = 67,584), the FFT from 408; below 143 lags the FFT has 1024 points.
    #[test]
    fn the_engine_follows_the_cost_model() {
        assert!(prefer_direct(882, 407) && !prefer_direct(882, 408));
        assert!(prefer_direct(882, 49) && !prefer_direct(882, 882));
        let info = SignalInfo::time_frequency(44100.0, vec![500.0; 2]);
        let (cc, _) =
            Crosscorrelation::new(&CrosscorrelationParams::default(), &info).expect("valid");
        assert_eq!(
            format!("{cc:?}"),
            "Crosscorrelation { method: \"direct\", window: 882, max_lag: 49, .. }"
        );
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
    fn the_working_memory_bound_holds_every_buffer() {
        for (w, max_lag) in [(40, 0), (40, 11), (42, 12), (882, 49), (882, 882)] {
            let win = window("hann", w, "").expect("hann");
            for lag_block in [4, 5, 8, 9, 10, 11, 12] {
                let d = Direct::with_lag_block(win.clone(), max_lag, 37, lag_block);
                let held = LANES * (d.left.len() + d.right.len() + d.acc.len());
                assert!(
                    held <= direct_work(w, max_lag),
                    "W {w}, maxLag {max_lag}, {lag_block} lags per pass: {held}"
                );
            }
        }
    }

    #[test]
    fn direct_and_fft_engines_agree() {
        // Channel counts below one group (3), and of two, three and five groups that
        // reuse one buffer, the last one overlapping its neighbour (11, 20, 37); half
        // frames of even and odd length; lags up to and beyond the window, and lag counts
        // that leave 1, 2 or 3 lags of a block of 5, 10 or 11 beyond a multiple of 4;
        // frames that start in rows kept from an earlier chunk; a window that ends in 0
        // (hann) and one that does not (hamming).
        let configs = [(40, 11), (42, 3), (42, 37), (40, 20)];
        for ((w, nc), wname) in configs
            .into_iter()
            .flat_map(|c| [(c, "hann"), (c, "hamming")])
        {
            let x = |seed: usize| -> Vec<f64> {
                (0..w * nc)
                    .map(|i| ((i * 7919 + seed) % 1013) as f64 / 1013.0)
                    .collect()
            };
            let (xl, xr) = (x(1), x(5));
            let mut framing = EarFrames::new(nc, w, w);
            let split = 7 * nc;
            framing.advance(&xl[..split], &xr[..split], 0);
            let (fl, fr) = framing.frame((&xl[split..], &xr[split..]), 0);
            assert_eq!(fl.head.len(), split);
            for max_lag in [0, 3, 4, 9, 10, 17, w - 1, w] {
                let win = window(wname, w, "").expect(wname);
                let nl = 2 * max_lag + 1;
                let mut fft = FftEngine::new(win.clone(), max_lag);
                let mut b = vec![0.0; nc * nl];
                for (c, o) in b.chunks_exact_mut(nl).enumerate() {
                    fft.correlate(fl, fr, c, o);
                    // lags of a window or more have no overlap: exactly 0
                    assert!(o
                        .iter()
                        .enumerate()
                        .all(|(i, v)| i.abs_diff(max_lag) < w || *v == 0.0));
                }
                assert!(b.iter().any(|v| *v > 0.1));
                for lag_block in [4, 5, 8, 9, 10, 11, 12] {
                    let mut direct = Direct::with_lag_block(win.clone(), max_lag, nc, lag_block);
                    let mut a = vec![0.0; nc * nl];
                    direct.correlate(fl, fr, &mut a);
                    for (i, (u, v)) in a.iter().zip(&b).enumerate() {
                        let (c, lag) = (i / nl, i % nl);
                        assert!(
                            (u - v).abs() < 1e-13,
                            "{wname} W {w}, {nc} channels, lag {lag}/{max_lag}, channel {c}: {u} vs {v}"
                        );
                    }
                }
            }
        }
    }

    /// `reset` starts the framing over; taking back the state of no parts keeps it.
    #[test]
    fn reset_and_an_empty_rejoin() {
        let info = SignalInfo::time_frequency(1000.0, vec![100.0, 200.0]);
        let (mut cc, out_info) =
            Crosscorrelation::new(&CrosscorrelationParams::default(), &info).expect("valid");
        let x = |seed: usize| -> Block {
            Block::from_vec((0..70).map(|i| ((i * 31 + seed) % 17) as f64).collect(), 2)
        };
        let (l, r) = (x(1), x(4));
        let run = |cc: &mut Crosscorrelation| {
            let mut out = vec![Block::new(out_info.width())];
            cc.process(&[&l, &r], &mut out);
            out.remove(0)
        };
        let first = run(&mut cc);
        assert_eq!(first.frames(), 2);
        cc.rejoin(&[]);
        let second = run(&mut cc);
        assert_ne!(
            second, first,
            "the kept samples shift the second chunk's frames"
        );
        cc.reset();
        assert_eq!(run(&mut cc), first);
    }

    #[test]
    fn a_window_beyond_the_working_memory_is_refused_naming_what_shrinks_it() {
        // the direct engine holds one group of channels at a time: its memory grows with
        // the window, not with the channels
        let info = SignalInfo::time_frequency(44100.0, vec![500.0]);
        let params = |w_size_sec| CrosscorrelationParams {
            w_size_sec,
            h_size_sec: 1.0,
            max_delay_sec: 0.0,
            ..Default::default()
        };
        let e = Crosscorrelation::new(&params(64.0), &info)
            .expect_err("64 s")
            .to_string();
        assert!(
            e.contains("cc_wSizeSec")
                && e.contains("working memory")
                && e.contains("window of 2822400 samples")
                && e.contains("shorten the window")
                && !e.contains("channels"),
            "{e}"
        );
        assert!(Crosscorrelation::new(&params(30.0), &info).is_ok());
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
