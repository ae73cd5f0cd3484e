//! `autocorrelation`: short-time, centre-clipped, normalised autocorrelation per channel
//! and frame, the correlogram the pitch estimator reads (spec 21-autocorrelation).
//!
//! Each frame is windowed, centre-clipped, and correlated with itself through a
//! zero-padded real FFT (`|X|^K`, the generalised ACF), scaled by the AFE's off-by-one
//! "unbiased" divisor and normalised by lag 0. Chunk-invariant: only un-framed samples
//! carry over.

use afe_core::descriptor::{request_def, Built, Descriptor, Ears, RequestDef};
use afe_core::framing::FrameBuffer;
use afe_core::window::{window, Window};
use afe_core::{Block, Error, Processor, Result, SignalInfo};

use crate::even_inverse::EvenInverse;
use crate::framed::{check_framing, check_work};
use afe_core::real_fft::{fast_len, transform_values, RealFft};

/// Outside these bounds on the ACF's lag 0 (the sum of the spectral powers |X|^K) the
/// powers overflowed or lost their precision in the subnormals: the spectrum is then
/// scaled by its largest magnitude.
const POWER_RANGE: std::ops::RangeInclusive<f64> = 1e-200..=1e200;

/// Frames whose largest magnitude lies in this range keep their scale (`K = 2`): lag 0 (the
/// unnormalised inverse's, `N·Σx²` over the clipped frame) then stays within [`POWER_RANGE`] unless
/// `clc` clipping shrinks the frame, where the rescaling after the fact takes over.
const UNSCALED: std::ops::RangeInclusive<f64> = 1e-90..=1e90;

afe_core::choices! {
    /// How a frame is centre-clipped (AFE `ac_clipMethod`): samples between the thresholds
    /// become 0, the others are kept as below.
    pub enum ClipMethod {
        /// Kept samples are moved towards 0 by the threshold (centre clipping and compression).
        Compress = "clc",
        /// Kept samples keep their value.
        Keep = "clp",
        /// Kept samples become +1 (above) or −1 (below).
        Sign = "sgn",
    }
}

afe_core::params! {
    /// Parameters of the autocorrelation, under their AFE names.
    pub struct AutocorrelationParams / AutocorrelationNames {
        /// window applied to each frame
        #[afe = "ac_wname"]
        pub wname: Window = Window::Hann,
        /// window length
        #[afe = "ac_wSizeSec", unit = "s"]
        pub w_size_sec: f64 = 0.02,
        /// hop between frames
        #[afe = "ac_hSizeSec", unit = "s"]
        pub h_size_sec: f64 = 0.01,
        /// centre clipping: compress ('clc'), keep ('clp') or sign ('sgn')
        #[afe = "ac_clipMethod"]
        pub clip_method: ClipMethod = ClipMethod::Keep,
        /// clipping threshold as a fraction of the frame's extreme values
        #[afe = "ac_clipAlpha"]
        pub clip_alpha: f64 = 0.6,
        /// exponent of the magnitude spectrum (2: plain autocorrelation)
        #[afe = "ac_K"]
        pub spectral_exponent: f64 = 2.0,
    }
}

/// The autocorrelation of one ear: IHC `[time][channel]` in, `[frame][channel][lag]` out
/// over lags `0..W−1` samples.
pub struct Autocorrelation {
    params: AutocorrelationParams,
    win: Vec<f64>,
    frames: FrameBuffer,
    /// `(W − 1)/(W − 1 − j)` per lag `j`: the AFE's unbiased scaling over that of lag 0.
    scale: Vec<f64>,
    /// The forward transform, whose input holds the clipped, zero-padded frame.
    fft: RealFft,
    /// The inverse of the (real, even) power spectrum, at half a full transform's cost.
    inverse: EvenInverse,
    /// Windowed frame, `[channel][time]`.
    columns: Vec<f64>,
    /// Each channel's largest windowed value (the clipping's upper threshold over α).
    peaks: Vec<f64>,
    /// Each channel's smallest windowed value (the lower threshold over −α).
    troughs: Vec<f64>,
    /// The frame's spectrum `X[0..=N/2]`, real and imaginary parts (for `K ≠ 2` and
    /// rescaled spectra; `K = 2` goes from the transform to the inverse in one pass).
    re: Vec<f64>,
    im: Vec<f64>,
    /// The power spectrum's first half (for `K ≠ 2` and rescaled spectra), and the
    /// unnormalised ACF at lags `0..W − 1`.
    power: Vec<f64>,
    acf: Vec<f64>,
}

impl std::fmt::Debug for Autocorrelation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Autocorrelation")
            .field("params", &self.params)
            .field("fft_len", &self.fft.points())
            .finish_non_exhaustive()
    }
}

impl Autocorrelation {
    /// Builds the autocorrelation for the IHC signal `input`.
    pub fn new(params: &AutocorrelationParams, input: &SignalInfo) -> Result<(Self, SignalInfo)> {
        let fs = input.fs_hz;
        let (w, h) = check_framing(
            (AutocorrelationParams::NAMES.w_size_sec, params.w_size_sec),
            (AutocorrelationParams::NAMES.h_size_sec, params.h_size_sec),
            fs,
            input.channels(),
        )?;
        if !(0.0..=1.0).contains(&params.clip_alpha) {
            return Err(Error::invalid(
                AutocorrelationParams::NAMES.clip_alpha,
                params.clip_alpha,
                "must be between 0 and 1 (a fraction of the frame's extreme values)",
            ));
        }
        // (within 1e-12 of 1, α·max rounds to max itself)
        if params.clip_method == ClipMethod::Compress && params.clip_alpha >= 1.0 - 1e-12 {
            return Err(Error::invalid(
                AutocorrelationParams::NAMES.clip_alpha,
                params.clip_alpha,
                "with ac_clipMethod 'clc' a threshold of 1 clips every sample to 0 and \
                         the autocorrelation is NaN: give a value below 1 − 1e-12",
            ));
        }
        if params.spectral_exponent <= 0.0 {
            return Err(Error::invalid(
                AutocorrelationParams::NAMES.spectral_exponent,
                params.spectral_exponent,
                "must be > 0 (2 gives the plain autocorrelation)",
            ));
        }
        let win = window(params.wname, w);
        let nc = input.channels();
        // The AFE's transform length is 2^nextpow2(2W − 1). For K = 2 the ACF is a linear
        // correlation, which any length from 2W − 2 on gives without wrap-around up to
        // lag W − 2: a faster one, a multiple of 4 for the even inverse (1792 for 20 ms
        // at 44.1 kHz). Other exponents sample |X|^K, so they keep the AFE's length.
        let nfft = if params.spectral_exponent == 2.0 {
            4 * fast_len((2 * w - 2).div_ceil(4))
        } else {
            (2 * w - 1).next_power_of_two()
        };
        // the transforms' buffers, beside the columns, spectra and lags (found by fuzzing:
        // a window of minutes over one channel asked for gigabytes of transform buffers)
        check_work(
            (AutocorrelationParams::NAMES.w_size_sec, params.w_size_sec),
            nc * (w + 2) + 2 * w + 3 * (nfft / 2 + 1) + 2 * transform_values(nfft),
            &format!("this window over {nc} channels"),
            "shorten the window or use fewer channels",
        )?;
        let top = (w - 1) as f64;
        let ac = Autocorrelation {
            params: params.clone(),
            frames: FrameBuffer::new(nc, w, h),
            scale: (0..w - 1).map(|j| top / (top - j as f64)).collect(),
            columns: vec![0.0; nc * w],
            peaks: vec![0.0; nc],
            troughs: vec![0.0; nc],
            re: vec![0.0; nfft / 2 + 1],
            im: vec![0.0; nfft / 2 + 1],
            power: vec![0.0; nfft / 2 + 1],
            acf: vec![0.0; w - 1],
            inverse: EvenInverse::new(nfft),
            fft: RealFft::new(nfft),
            win,
        };
        let lags_s = (0..w - 1).map(|k| k as f64 / fs).collect();
        let info = input
            .correlation(1.0 / params.h_size_sec, lags_s)
            .with_unit(Self::OUTPUT_UNIT)
            .with_window_s(params.w_size_sec)
            .nan_where(
                "at every lag of a frame whose input is all zero (digital silence, or a channel \
                 the hair cell rectified to 0): 0/0, as in the AFE; and of a frame whose lag 0 \
                 underflows to 0 in the AFE's arithmetic (a filter's decay, or a large ac_K)",
            );
        Ok((ac, info))
    }

    /// The normalised ACF of channel `c`'s windowed frame into `out` (`W − 1` lags); inlined into
    /// [`correlate_frames`] so that its loops get that function's vector width.
    #[inline(always)]
    fn correlate(&mut self, c: usize, out: &mut [f64]) {
        // the windowed frame's largest magnitude; sign clipping makes every sample ±1
        let top = self.peaks[c].abs().max(self.troughs[c].abs());
        let method = self.params.clip_method;
        // An all-zero frame gives 0/0 = NaN at every lag, as in the AFE (after digital
        // silence most frames are such: no transform for them).
        if top == 0.0 && method != ClipMethod::Sign {
            out.fill(f64::NAN);
            return;
        }
        self.load(c);
        let w = self.win.len();
        // the clipped frame's largest magnitude: the windowed one's where kept samples keep
        // their value, 1 where they become ±1
        let clipped_top = match method {
            ClipMethod::Keep => top,
            ClipMethod::Sign => 1.0,
            ClipMethod::Compress => (self.fft.input()[..w].iter()).fold(0.0, |m, v| v.abs().max(m)),
        };
        let k = self.params.spectral_exponent;
        match tail_regime(clipped_top, w, k) {
            Tail::Underflows => return out.fill(f64::NAN),
            Tail::Subnormal => return self.ieee_acf(out),
            Tail::Normal => {}
        }
        if k == 2.0 {
            // A frame far from 1 (the decay after digital silence) is brought near it by a
            // power of two, which changes no bit of the normalised ACF and keeps lag 0 in
            // range, where one transform does.
            if !UNSCALED.contains(&top) && method != ClipMethod::Sign {
                to_unit(&mut self.fft.input()[..w], top);
            }
            self.inverse
                .run_squares(self.fft.transform(), &mut self.acf);
        } else {
            self.powers(k);
        }
        // W ≥ 2 (check_framing), so there is a lag 0
        let lag0 = self.acf[0];
        let lag0 = if POWER_RANGE.contains(&lag0) {
            lag0
        } else {
            self.rescaled_acf(c, k)
        };
        let inv = 1.0 / lag0;
        for ((o, v), s) in out.iter_mut().zip(&self.acf).zip(&self.scale) {
            *o = v * s * inv;
        }
    }

    /// The unnormalised ACF of the clipped frame in the transform's input through
    /// `|X|^K` (by magnitude and power per bin), into `self.acf`.
    #[inline(always)]
    fn powers(&mut self, k: f64) {
        self.fft.run(&mut self.re, &mut self.im);
        let power = self.power.iter_mut().zip(self.re.iter().zip(&self.im));
        power.for_each(|(p, (re, im))| *p = re.hypot(*im).powf(k));
        self.inverse.run(&self.power, &mut self.acf);
    }

    /// The normalised ACF of the clipped frame in the transform's input as the AFE's
    /// arithmetic gives it where its powers sink into the subnormals: the powers and
    /// their inverse in IEEE arithmetic (subnormals kept, whatever the thread's
    /// flushing), then the AFE's divisions: the inverse's `1/N`, `a[j] = c[j]/(W − 1 − j)`
    /// and `a[j]/a[0]`. Where lag 0 underflows to 0 the AFE divides by it (±Inf at the lags
    /// that did not underflow, NaN at the others): such a frame has no ACF, and is NaN at
    /// every lag, as a frame whose every power underflows.
    #[cold]
    #[inline(never)]
    fn ieee_acf(&mut self, out: &mut [f64]) {
        let _ieee = afe_core::denormals::GradualUnderflow::enable();
        let k = self.params.spectral_exponent;
        if k == 2.0 {
            self.inverse
                .run_squares(self.fft.transform(), &mut self.acf);
        } else {
            self.powers(k);
        }
        // the inverse transform's 1/N, where the AFE's lag 0 underflows first
        let n = self.fft.points() as f64;
        let top = (self.win.len() - 1) as f64;
        let a0 = self.acf[0] / n / top;
        if a0 == 0.0 {
            out.fill(f64::NAN);
            return;
        }
        for (j, (o, v)) in out.iter_mut().zip(&self.acf).enumerate() {
            *o = (v / n / (top - j as f64)) / a0;
        }
        afe_core::denormals::flush_subnormals(out);
    }

    /// Writes channel `c`'s windowed frame, centre-clipped and zero-padded, into the transform's
    /// input.
    #[inline(always)]
    fn load(&mut self, c: usize) {
        let w = self.win.len();
        let f = &self.columns[c * w..(c + 1) * w];
        let alpha = self.params.clip_alpha;
        let thresholds = (alpha * self.peaks[c].abs(), alpha * self.troughs[c].abs());
        let time = self.fft.input();
        clip(f, self.params.clip_method, thresholds, &mut time[..w]);
        time[w..].fill(0.0);
    }

    /// The ACF of channel `c` again from its spectrum over the spectrum's largest
    /// magnitude, where |X|^K overflowed or sank into the subnormals (K far from 2, or a
    /// frame that clipping brought near 0): the normalisation by lag 0 cancels the scale,
    /// and an all-zero frame stays all zero. Returns the new lag 0.
    #[cold]
    fn rescaled_acf(&mut self, c: usize, k: f64) -> f64 {
        self.load(c);
        self.fft.run(&mut self.re, &mut self.im);
        let m = (self.re.iter().zip(&self.im)).fold(0.0f64, |m, (re, im)| m.max(re.hypot(*im)));
        if m > 0.0 {
            let power = self.power.iter_mut().zip(self.re.iter().zip(&self.im));
            power.for_each(|(p, (re, im))| *p = (re.hypot(*im) / m).powf(k));
            self.inverse.run(&self.power, &mut self.acf);
        }
        self.acf[0]
    }
}

/// Where a clipped frame's ACF stands against the AFE's arithmetic, which computes the
/// powers `|X|^K` of its spectrum in IEEE double precision.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Tail {
    /// Every power underflows to 0 in the AFE (`|X| ≤ W·max|g|`, and
    /// `(W·max|g|)^K < 2^−1075`): its ACF is 0/0 = NaN at every lag.
    Underflows,
    /// Some powers may be subnormal, none can overflow: the AFE's result is its
    /// arithmetic's, computed so.
    Subnormal,
    /// The AFE's powers are exact to well below the tolerance (or could overflow, where
    /// the rescaled computation keeps the output finite).
    Normal,
}

/// log2 of the smallest power `|X|^K` that the AFE computes to well below the tolerance
/// (1e−300: a subnormal's error, 2^−1075, is below 1e−10 of a lag 0 that large).
const EXACT_POWER_LOG2: f64 = -996.5;

/// The regime of a clipped frame whose largest magnitude is `top` (> 0), over a window of
/// `w` samples, with spectral exponent `k`: the AFE's arithmetic where the frame only
/// holds a decay whose powers sink into the subnormals; a frame whose powers could also
/// overflow (a large `k`) keeps the rescaled computation (conformance: "Non-finite").
fn tail_regime(top: f64, w: usize, k: f64) -> Tail {
    // log2 of a bound on every power, (W·top)^K, and of the largest sample's own power
    let bound = k * (w as f64 * top).log2();
    let own = k * top.log2();
    if bound < -1075.0 {
        Tail::Underflows
    } else if own < EXACT_POWER_LOG2 && bound < -EXACT_POWER_LOG2 {
        Tail::Subnormal
    } else {
        Tail::Normal
    }
}

/// Multiplies `x`, whose largest magnitude is `top` (> 0), by the power of two that brings
/// `top` near [0.5, 1) (`log2` may round it into [0.25, 0.5)): exact, unless `x` holds
/// subnormals or the scaling makes some. A non-finite `top` leaves `x` as it is.
#[inline(always)]
fn to_unit(x: &mut [f64], top: f64) {
    if !top.is_finite() {
        return;
    }
    // top = f·2^e with f in [0.5, 1); 2^−e in steps that stay finite
    let mut e = top.log2().floor() as i32 + 1;
    while e != 0 {
        let step = e.clamp(-1000, 1000);
        let factor = 2f64.powi(-step);
        x.iter_mut().for_each(|v| *v *= factor);
        e -= step;
    }
}

/// Centre-clips frame `f` into `g` (spec step 2) with the thresholds `(hi, lo)`,
/// `α·|max f|` and `α·|min f|`: samples at or above `hi` and at or below `−lo` are kept
/// (per `method`), the others become 0; a sample in both sets (zero, when both
/// thresholds are 0) is treated as below.
#[inline(always)]
fn clip(f: &[f64], method: ClipMethod, (hi, lo): (f64, f64), g: &mut [f64]) {
    let pairs = g.iter_mut().zip(f);
    // One loop per method, each branch-free, so that it vectorises.
    match method {
        ClipMethod::Keep => pairs.for_each(|(y, &x)| {
            *y = if x <= -lo || x >= hi { x } else { 0.0 };
        }),
        ClipMethod::Compress => pairs.for_each(|(y, &x)| {
            let above = if x >= hi { x - hi } else { 0.0 };
            *y = if x <= -lo { x + lo } else { above };
        }),
        ClipMethod::Sign => pairs.for_each(|(y, &x)| {
            let above = if x >= hi { 1.0 } else { 0.0 };
            *y = if x <= -lo { -1.0 } else { above };
        }),
    }
}

afe_core::simd_kernel!(
    fma,
    /// Windows each complete frame of `input` into columns and correlates every channel,
    /// into `out` (`[frame][channel][lag]`).
    fn correlate_frames(ac: &mut Autocorrelation, input: &Block, out: &mut [f64]) {
        let nc = input.width();
        let w = ac.win.len();
        for (k, frame_out) in out.chunks_exact_mut((nc * (w - 1)).max(1)).enumerate() {
            let frame = ac.frames.frame(input.as_slice(), k);
            frame.window_columns(
                &ac.win,
                &mut ac.columns,
                Some(&mut ac.peaks),
                Some(&mut ac.troughs),
            );
            for (c, o) in frame_out.chunks_exact_mut(w - 1).enumerate() {
                ac.correlate(c, o);
            }
        }
    }
);

impl Processor for Autocorrelation {
    fn process(&mut self, inputs: &[&Block], outputs: &mut [Block]) {
        let n = self.frames.available(inputs[0].as_slice());
        let out = outputs[0].resize_to(n);
        correlate_frames(self, inputs[0], out);
        self.frames.advance(inputs[0].as_slice(), n);
    }

    fn reset(&mut self) {
        self.frames.reset();
    }
}

impl Descriptor for Autocorrelation {
    type Params = AutocorrelationParams;
    const NAME: &'static str = "autocorrelation";
    const DEPENDENCY: &'static str = "innerhaircell";
    const EARS: Ears = Ears::PerEar;
    const DESCRIPTION: &'static str =
        "centre-clipped normalised autocorrelation per frame, channel and lag";
    const OUTPUT_UNIT: &'static str = "";

    fn build(params: &AutocorrelationParams, inputs: &[SignalInfo]) -> Result<Built> {
        let (p, out) = Autocorrelation::new(params, &inputs[0])?;
        Ok(Built::new(p, vec![out]))
    }
}

/// The registry entry of `autocorrelation`.
pub static REQUEST: RequestDef = request_def::<Autocorrelation>();

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{noise, plain_dft};
    use afe_core::Params;
    use proptest::prelude::*;

    fn ihc(fs: f64, nc: usize) -> SignalInfo {
        SignalInfo::time_frequency(fs, (0..nc).map(|c| 100.0 * (c + 1) as f64).collect())
    }

    fn signal(len: usize, seed: u64) -> Vec<f64> {
        noise(len, seed)
            .iter()
            .enumerate()
            .map(|(i, u)| (i as f64 * 0.3).sin().max(0.0) + 0.2 * (u + 0.5))
            .collect()
    }

    fn run(p: &AutocorrelationParams, nc: usize, x: &[f64], chunks: &[usize]) -> (usize, Vec<f64>) {
        let (mut ac, info) = Autocorrelation::new(p, &ihc(1000.0, nc)).expect("valid");
        let cycled = chunks.iter().copied().cycle();
        let all = crate::testing::feed(&mut ac, x, nc, info.width(), cycled);
        (info.lags_s().len(), all)
    }

    /// Centre-clips frame `f` into `g` with the frame's thresholds.
    fn clip_frame(f: &[f64], method: ClipMethod, alpha: f64, g: &mut [f64]) {
        let max = f.iter().fold(f64::NAN, |m, v| m.max(*v));
        let min = f.iter().fold(f64::NAN, |m, v| m.min(*v));
        clip(f, method, (alpha * max.abs(), alpha * min.abs()), g);
    }

    #[test]
    fn clipping_follows_the_afe() {
        let f = [-2.0, -1.0, 0.0, 1.0, 3.0, 2.0];
        let mut g = [0.0; 6];
        // hi = 0.5·3 = 1.5, lo = 0.5·2 = 1
        clip_frame(&f, ClipMethod::Keep, 0.5, &mut g);
        assert_eq!(g, [-2.0, -1.0, 0.0, 0.0, 3.0, 2.0]);
        clip_frame(&f, ClipMethod::Compress, 0.5, &mut g);
        assert_eq!(g, [-1.0, 0.0, 0.0, 0.0, 1.5, 0.5]);
        clip_frame(&f, ClipMethod::Sign, 0.5, &mut g);
        assert_eq!(g, [-1.0, -1.0, 0.0, 0.0, 1.0, 1.0]);
        // an all-zero frame: every sample is both above and below
        clip_frame(&[0.0; 3], ClipMethod::Sign, 0.6, &mut g[..3]);
        assert_eq!(g[..3], [-1.0; 3]);
        clip_frame(&[0.0; 3], ClipMethod::Keep, 0.6, &mut g[..3]);
        assert_eq!(g[..3], [0.0; 3]);
    }

    /// Windows of 20 and 22 samples: whole groups of four rows, and a remainder of two
    /// (whose small window values only survive the clipping at `α = 0`).
    #[test]
    fn matches_the_direct_sum() {
        let nc = 2;
        let x = signal(60 * nc, 7);
        let methods = [
            (ClipMethod::Keep, 0.6),
            (ClipMethod::Compress, 0.6),
            (ClipMethod::Sign, 0.6),
            (ClipMethod::Keep, 0.0),
        ];
        for ((method, alpha), w) in methods.into_iter().flat_map(|m| [(m, 20), (m, 22)]) {
            let h = w / 2;
            let p = AutocorrelationParams {
                clip_method: method,
                clip_alpha: alpha,
                w_size_sec: w as f64 / 1000.0,
                h_size_sec: h as f64 / 1000.0,
                ..Default::default()
            };
            let (nl, out) = run(&p, nc, &x, &[60]);
            let frames = (60 - w) / h + 1;
            assert_eq!((nl, out.len()), (w - 1, frames * nc * nl));
            let win = window(Window::Hann, w);
            for t in 0..frames {
                for c in 0..nc {
                    let f: Vec<f64> = (0..w).map(|n| win[n] * x[(t * h + n) * nc + c]).collect();
                    let mut g = vec![0.0; w];
                    clip_frame(&f, method, alpha, &mut g);
                    let acf = |j: usize| (0..w - j).map(|n| g[n] * g[n + j]).sum::<f64>();
                    for j in 0..nl {
                        let want = acf(j) / (nl - j) as f64 / (acf(0) / nl as f64);
                        let got = out[(t * nc + c) * nl + j];
                        assert!((got - want).abs() < 1e-12, "{method:?} W {w}: {t} {c} {j}");
                    }
                }
            }
        }
    }

    #[test]
    fn reset_starts_the_framing_over() {
        let nc = 2;
        let x = signal(50 * nc, 5);
        let (mut ac, info) =
            Autocorrelation::new(&AutocorrelationParams::default(), &ihc(1000.0, nc))
                .expect("valid");
        // W = 20: 4·5·2 ≥ 2W − 2 for K = 2; the AFE's 2^nextpow2(2W − 1) for other K
        assert!(format!("{ac:?}").contains("fft_len: 40"));
        let whitened = AutocorrelationParams {
            spectral_exponent: 0.5,
            ..Default::default()
        };
        let (other, _) = Autocorrelation::new(&whitened, &ihc(1000.0, nc)).expect("valid");
        assert!(format!("{other:?}").contains("fft_len: 64"));
        let first = crate::testing::feed(&mut ac, &x, nc, info.width(), [50]);
        ac.reset();
        let again = crate::testing::feed(&mut ac, &x, nc, info.width(), [50]);
        assert!(!first.is_empty());
        assert_eq!(first, again);
    }

    /// `real(ifft(|fft(g, L)|^K))` by plain DFTs, independent of the FFT library (the
    /// inverse of the real, even power spectrum is the real part of its forward DFT / L).
    fn generalised_acf(g: &[f64], l: usize, k: f64) -> Vec<f64> {
        let power: Vec<f64> = plain_dft(g, l).iter().map(|v| v.norm().powf(k)).collect();
        plain_dft(&power, l)
            .iter()
            .map(|v| v.re / l as f64)
            .collect()
    }

    #[test]
    fn other_spectral_exponents_match_direct_transforms() {
        let x = signal(40, 3);
        let win = window(Window::Hann, 20);
        for k in [1.0, 0.5, 3.0] {
            let p = AutocorrelationParams {
                spectral_exponent: k,
                ..Default::default()
            };
            let (nl, out) = run(&p, 1, &x, &[40]);
            let f: Vec<f64> = (0..20).map(|n| win[n] * x[n]).collect();
            let mut g = vec![0.0; 20];
            clip_frame(&f, ClipMethod::Keep, 0.6, &mut g);
            // W = 20: L = 2^nextpow2(39) = 64
            let c = generalised_acf(&g, 64, k);
            for j in 0..nl {
                let want = c[j] / (19 - j) as f64 / (c[0] / 19.0);
                assert!(
                    (out[j] - want).abs() < 1e-11,
                    "K = {k}, lag {j}: {} vs {want}",
                    out[j]
                );
            }
        }
    }

    #[test]
    fn far_from_one_frames_are_rescaled_and_tails_follow_the_afes_arithmetic() {
        let x = signal(40, 3);
        let scaled = |factor: f64| -> Vec<f64> {
            let x2: Vec<f64> = x.iter().map(|v| v * factor).collect();
            run(&AutocorrelationParams::default(), 1, &x2, &[40]).1
        };
        let plain = scaled(1.0);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        // scaled by powers of two down to 1e-135 and up to 1e307 (two steps of scaling),
        // where the AFE's powers keep their precision: the plain frame's ACF bit for bit
        for e in [-450, -300, 600, 990, 1020] {
            let factor = 2f64.powi(e / 2) * 2f64.powi(e - e / 2);
            assert_eq!(bits(&scaled(factor)), bits(&plain), "2^{e}");
        }
        // every power below the smallest subnormal, as the AFE computes them: 0/0
        for factor in [1e-170, 2f64.powi(-1000), 1e-320] {
            assert!(scaled(factor).iter().all(|v| v.is_nan()), "{factor:e}");
        }
        // powers in the subnormals: the AFE's arithmetic, imprecise but finite, whether
        // the thread flushes subnormals (as processors run) or not
        let tail = scaled(3e-160);
        assert!(tail.iter().all(|v| v.is_finite()));
        assert_ne!(bits(&tail), bits(&plain), "the subnormals' round-off");
        let worst = (tail.iter().zip(&plain)).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(worst < 1e-3, "{worst}");
        let flushed = {
            let _flush = afe_core::denormals::FlushDenormals::enable();
            scaled(3e-160)
        };
        assert_eq!(bits(&flushed), bits(&tail));
        // spectral exponents whose powers overflow: rescaled, finite
        for k in [465.0, 5e5, 1e-9] {
            let p = AutocorrelationParams {
                spectral_exponent: k,
                ..Default::default()
            };
            let (_, out) = run(&p, 1, &x, &[40]);
            assert!(
                !out.is_empty() && out.iter().all(|v| v.is_finite()),
                "K = {k}"
            );
            assert!((out[0] - 1.0).abs() < 1e-15, "K = {k}: lag 0 is {}", out[0]);
        }
    }

    #[test]
    fn a_frame_whose_lag_0_underflows_is_nan_never_inf() {
        // K = 45.5 sinks the powers of a frame near 1e-7 into the subnormals, where the
        // AFE's lag 0 can round to 0 while later lags do not (a fuzz case)
        let x = signal(40, 3);
        let p = AutocorrelationParams {
            spectral_exponent: 45.5,
            ..Default::default()
        };
        let mut nan_frames = 0;
        // the subnormal regime from 2.5e-7 to 3.7e-9, in steps of 0.8 in the powers
        for e in 0..900 {
            let factor = 3e-7 * 0.995f64.powi(e);
            let x2: Vec<f64> = x.iter().map(|v| v * factor).collect();
            let (lags, out) = run(&p, 1, &x2, &[40]);
            assert!(out.iter().all(|v| !v.is_infinite()), "{factor:e}");
            for frame in out.chunks(lags) {
                let nan = frame.iter().filter(|v| v.is_nan()).count();
                assert!(nan == 0 || nan == frame.len(), "{factor:e}: {frame:?}");
                nan_frames += usize::from(nan > 0);
            }
        }
        assert!(nan_frames > 0);
    }

    #[test]
    fn the_tail_regimes_follow_the_bound_on_the_powers() {
        // K = 2, W = 882: every power (W·top)^2 below 2^-1075 from top < 1.8e-165
        assert_eq!(tail_regime(1.7e-165, 882, 2.0), Tail::Underflows);
        assert_eq!(tail_regime(1.9e-165, 882, 2.0), Tail::Subnormal);
        assert_eq!(tail_regime(1e-151, 882, 2.0), Tail::Subnormal);
        assert_eq!(tail_regime(1e-149, 882, 2.0), Tail::Normal);
        assert_eq!(tail_regime(1e100, 882, 2.0), Tail::Normal);
        // a large exponent: powers that could overflow keep the rescaled computation
        assert_eq!(tail_regime(0.2, 882, 465.0), Tail::Normal);
        assert_eq!(tail_regime(1e-10, 882, 465.0), Tail::Underflows);
    }

    #[test]
    fn silent_frames_are_nan_except_with_sign_clipping() {
        let (_, out) = run(&AutocorrelationParams::default(), 1, &[0.0; 20], &[20]);
        assert!(!out.is_empty() && out.iter().all(|v| v.is_nan()));
        let p = AutocorrelationParams {
            clip_method: ClipMethod::Sign,
            ..Default::default()
        };
        let (_, out) = run(&p, 1, &[0.0; 20], &[20]);
        assert!(out.iter().all(|v| v.is_finite()));
        assert_eq!(out[0], 1.0);
    }

    #[test]
    fn bad_parameters_are_errors_naming_them() {
        let info = ihc(16000.0, 2);
        let cases = [
            (
                AutocorrelationParams {
                    clip_alpha: 1.5,
                    ..Default::default()
                },
                "ac_clipAlpha",
            ),
            (
                AutocorrelationParams {
                    spectral_exponent: 0.0,
                    ..Default::default()
                },
                "ac_K",
            ),
            // every sample clipped to 0: all NaN
            (
                AutocorrelationParams {
                    clip_method: ClipMethod::Compress,
                    clip_alpha: 1.0,
                    ..Default::default()
                },
                "ac_clipAlpha",
            ),
            (
                AutocorrelationParams {
                    w_size_sec: 0.0,
                    ..Default::default()
                },
                "ac_wSizeSec",
            ),
            (
                AutocorrelationParams {
                    h_size_sec: 0.0,
                    ..Default::default()
                },
                "ac_hSizeSec",
            ),
        ];
        for (p, name) in cases {
            let e = Autocorrelation::new(&p, &info).expect_err(name).to_string();
            assert!(e.contains(name), "{e}");
        }
        let map: afe_core::ParamMap = [("ac_clipMethod".to_string(), serde_json::json!("clip"))]
            .into_iter()
            .collect();
        let e = AutocorrelationParams::from_map(&map)
            .expect_err("method")
            .to_string();
        assert!(e.contains("ac_clipMethod"), "{e}");
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, failure_persistence: None, ..ProptestConfig::default() })]

        /// Any chunking gives the output of one call, bit for bit.
        #[test]
        fn any_chunking_is_bit_identical(
            seed in 0u64..1000,
            chunks in prop::collection::vec(prop_oneof![Just(1usize), 1usize..40, 40usize..200], 1..8),
        ) {
            let nc = 3;
            let x = signal(400 * nc, seed);
            let p = AutocorrelationParams::default();
            let (_, whole) = run(&p, nc, &x, &[400]);
            let (_, chunked) = run(&p, nc, &x, &chunks);
            prop_assert_eq!(whole.len(), chunked.len());
            prop_assert!(whole.iter().zip(&chunked).all(|(a, b)| a.to_bits() == b.to_bits()));
        }
    }
}
