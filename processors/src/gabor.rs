//! `gabor`: spectro-temporal Gabor filter-bank features (GBFB) of the log-compressed
//! ratemap, normalised per chunk (spec 27-gabor).
//!
//! Every quantity of a chunk (the dB floor, the edge padding, the mean and variance of
//! each feature) comes from that chunk alone, as in the AFE: the output depends on the
//! chunking.

use std::f64::consts::PI;

use afe_core::descriptor::{request_def, Built, Descriptor, Ears, RequestDef};
use afe_core::{Block, Error, Processor, Result, SignalInfo};
use num_complex::Complex64;

afe_core::params! {
    /// Parameters of the Gabor features, under their AFE names.
    pub struct GaborParams / GaborNames {
        /// dynamic range kept below the chunk's maximum before the log
        #[afe = "gb_maxDynamicRangeDB", unit = "dB"]
        pub max_dynamic_range_db: f64 = 80.0,
    }
}

/// Largest modulation frequencies (spectral, temporal), rad per channel / per frame.
const OMEGA_MAX: [f64; 2] = [PI / 2.0, PI / 2.0];
/// Half-waves under the envelope (spectral, temporal).
const NU: [f64; 2] = [3.5, 3.5];
/// Spacing of neighbouring filters (spectral, temporal).
const DISTANCE: [f64; 2] = [0.3, 0.2];
/// Largest temporal filter extent in frames; the spectral one is three times the number of
/// channels.
const SIZE_MAX_TIME: f64 = 40.0;
/// Frames of edge padding on each side of a chunk: `floor(SIZE_MAX_TIME/2)`.
const CONTEXT: usize = 20;

/// One Gabor filter, reduced to what the features need: the real part of the filter (the features
/// are real), the DC-map weights where the AFE subtracts a DC map, and the kept output rows.
#[derive(Debug, Clone)]
struct Filter {
    /// Spectral half-length: taps `−half_k ..= half_k`.
    half_k: usize,
    /// Temporal half-length.
    half_n: usize,
    /// `Re G`, `[2·half_k + 1][2·half_n + 1]`.
    real: Vec<f64>,
    /// `|G|` (same layout; the AFE's `|G|/Σ|G|` up to a scale the map cancels) when the
    /// AFE subtracts a DC map, i.e. when `Re G` has a negative tap.
    dc_weights: Option<Vec<f64>>,
    /// Kept channels and, per channel, the sums of `Re G` and of the DC weights over the
    /// taps that fall on the spectrogram (the all-ones convolutions of the DC map).
    rows: Vec<(usize, f64, f64)>,
}

/// The symmetric Hann envelope of width `w`: `0.5·(1 + cos(2πj/w))` for the integers
/// `|j| < w/2` (the zero end points excluded, robustly when `w/2` is an integer).
fn hann_envelope(w: f64) -> Vec<f64> {
    let m = (1..)
        .take_while(|&i| (i as f64) < w / 2.0 - 1e-9 * w)
        .count() as isize;
    (-m..=m)
        .map(|j| 0.5 * (1.0 + (2.0 * PI * j as f64 / w).cos()))
        .collect()
}

/// The modulation frequencies along one axis: `ω_max/s^i` while above `ω_min`.
fn omega_list(d: usize, size_max: f64) -> Vec<f64> {
    let omega_min = PI * NU[d] / size_max;
    let c = DISTANCE[d] * 8.0 / NU[d];
    let s = (1.0 + c / 2.0) / (1.0 - c / 2.0);
    let mut list = vec![OMEGA_MAX[d]];
    let mut i = 1;
    while (OMEGA_MAX[d] / s.powi(i - 1)) / s > omega_min {
        list.push(OMEGA_MAX[d] / s.powi(i));
        i += 1;
    }
    list
}

/// The filter for modulation frequencies `(omega_k, omega_n)` over `channels` channels.
fn design(mut omega_k: f64, mut omega_n: f64, channels: usize) -> Filter {
    let size_max_k = 3.0 * channels as f64;
    let width = |omega: f64, d: usize| (2.0 * PI / omega.abs()) * NU[d] / 2.0;
    let mut w_n = width(omega_n, 1);
    if w_n > SIZE_MAX_TIME {
        w_n = SIZE_MAX_TIME;
        omega_n = 0.0;
    }
    let mut w_k = width(omega_k, 0);
    if w_k > size_max_k {
        w_k = size_max_k;
        omega_k = 0.0;
    }
    let (h_k, h_n) = (hann_envelope(w_k), hann_envelope(w_n));
    let (lk, ln) = (h_k.len(), h_n.len());
    let (half_k, half_n) = (lk / 2, ln / 2);
    let envelope: Vec<f64> = h_k
        .iter()
        .flat_map(|a| h_n.iter().map(move |b| a * b))
        .collect();
    let mut g: Vec<Complex64> = envelope
        .iter()
        .enumerate()
        .map(|(i, e)| {
            let k = (i / ln) as f64 - half_k as f64;
            let n = (i % ln) as f64 - half_n as f64;
            e * Complex64::new(0.0, omega_n * n + omega_k * k).exp()
        })
        .collect();
    // The pure DC filter (both frequencies 0) becomes `G + iG` in spec 27: that changes
    // only its imaginary part, which neither its features (real) nor its DC test (its
    // real part, the envelope, is positive) read, so only the other filters change here.
    if omega_n != 0.0 || omega_k != 0.0 {
        let count = g.len() as f64;
        let mean_e = envelope.iter().sum::<f64>() / count;
        let mean_g = g.iter().sum::<Complex64>() / count;
        for (v, e) in g.iter_mut().zip(&envelope) {
            *v -= (e / mean_e) * mean_g;
        }
    }
    // Spec 27 divides G by the largest modulus of its 2-D DFT. That scales every feature
    // of the filter by one positive factor, which the per-chunk normalisation (step 8)
    // removes again, and leaves the sign test and the DC weights as they are: skipped.
    let real: Vec<f64> = g.iter().map(|v| v.re).collect();
    // Spec 27 weighs the DC map by `|G|/Σ|G|`; the map divides by the same weights'
    // all-ones convolution, so their scale cancels and `|G|` serves.
    let dc_weights = real
        .iter()
        .any(|v| *v < 0.0)
        .then(|| g.iter().map(|v| v.norm()).collect::<Vec<f64>>());
    let step = (lk / 4).max(1);
    let rows = ((channels / 2) % step..channels)
        .step_by(step)
        .map(|r| {
            // Taps a with 0 ≤ r + half_k − a < channels fall on the spectrogram; every
            // temporal tap does (the padding is wider than any filter).
            let first = (r + half_k + 1).saturating_sub(channels);
            let last = (r + half_k).min(lk - 1);
            let sum = |taps: &[f64]| -> f64 {
                (first..=last)
                    .flat_map(|a| taps[a * ln..(a + 1) * ln].iter())
                    .sum()
            };
            let dc = dc_weights.as_deref().map_or(0.0, sum);
            (r, sum(&real), dc)
        })
        .collect();
    Filter {
        half_k,
        half_n,
        real,
        dc_weights,
        rows,
    }
}

/// The Gabor features of one ear: ratemap `[frame][channel]` in, `[frame][feature]` out.
#[derive(Debug, Clone)]
pub struct Gabor {
    range_db: f64,
    channels: usize,
    filters: Vec<Filter>,
    features: usize,
    /// Log spectrogram with edge padding, `[channel][CONTEXT + frames + CONTEXT]`.
    spectrogram: Vec<f64>,
    /// Features before the transpose, `[feature][frame]`.
    rows: Vec<f64>,
    acc_real: Vec<f64>,
    acc_dc: Vec<f64>,
}

impl Gabor {
    /// Builds the feature extractor for the ratemap `input`.
    pub fn new(params: &GaborParams, input: &SignalInfo) -> Result<(Self, SignalInfo)> {
        if params.max_dynamic_range_db <= 0.0 {
            return Err(Error::invalid(
                GaborParams::NAMES.max_dynamic_range_db,
                params.max_dynamic_range_db,
                "must be > 0 dB",
            ));
        }
        let channels = input.channels();
        if channels == 0 {
            return Err(Error::InvalidInput(
                "gabor needs a ratemap with at least one channel".into(),
            ));
        }
        let spectral = omega_list(0, 3.0 * channels as f64);
        let temporal = omega_list(1, SIZE_MAX_TIME);
        let omega_n: Vec<f64> = std::iter::once(0.0)
            .chain(temporal.iter().rev().copied())
            .collect();
        let omega_k: Vec<f64> = spectral
            .iter()
            .map(|v| -v)
            .chain(std::iter::once(0.0))
            .chain(spectral.iter().rev().copied())
            .collect();
        let filters: Vec<Filter> = omega_n
            .iter()
            .flat_map(|n| omega_k.iter().map(move |k| (*k, *n)))
            .filter(|(k, n)| !(*k < 0.0 && *n == 0.0))
            .map(|(k, n)| design(k, n, channels))
            .collect();
        let features = filters.iter().map(|f| f.rows.len()).sum();
        let names = (1..=features).map(|i| i.to_string()).collect();
        let gabor = Gabor {
            range_db: params.max_dynamic_range_db,
            channels,
            filters,
            features,
            spectrogram: Vec::new(),
            rows: Vec::new(),
            acc_real: Vec::new(),
            acc_dc: Vec::new(),
        };
        let info = SignalInfo {
            window_s: input.window_s,
            ..SignalInfo::feature(input.fs_hz, input.audio_fs_hz, names)
        }
        .with_unit(Self::OUTPUT_UNIT)
        .nan_where(
            "(or ±Inf) in a chunk whose features do not vary (silence, or a chunk of one \
             frame): the per-chunk normalisation divides by a variance of 0, as in the AFE; \
             and with ihc_method 'none' and rm_scaling 'magnitude' (the log of a signed \
             ratemap)",
        );
        Ok((gabor, info))
    }

    /// The padded log spectrogram of a chunk of `frames` ratemap rows.
    fn log_spectrogram(&mut self, input: &[f64], frames: usize) {
        let k = self.channels;
        let padded = frames + 2 * CONTEXT;
        let peak = input.iter().fold(f64::NAN, |m, v| m.max(*v));
        let floor = 10f64.powf(-(self.range_db - 10.0 * peak.log10()) / 10.0);
        self.spectrogram.resize(k * padded, 0.0);
        for (c, row) in self.spectrogram.chunks_exact_mut(padded).enumerate() {
            for (t, v) in row[CONTEXT..CONTEXT + frames].iter_mut().enumerate() {
                *v = 10.0 * (input[t * k + c] + floor).log10();
            }
            let (first, last) = (row[CONTEXT], row[CONTEXT + frames - 1]);
            row[..CONTEXT].fill(first);
            row[CONTEXT + frames..].fill(last);
        }
    }
}

afe_core::simd_kernel!(
    fma,
    /// Kept row `r` of filter `f`'s 'same' convolution over the padded log spectrogram of
    /// `k`
    /// channels, for `acc_real.len()` frames: `out[t] = Σ G[a, b]·S[r + half_k − a, t +
    /// half_n − b]`
    /// with `Re G` into `acc_real` and, where the filter has them, the DC weights into
    /// `acc_dc`.
    fn convolve_row(
        spectrogram: &[f64],
        k: usize,
        f: &Filter,
        r: usize,
        acc_real: &mut [f64],
        acc_dc: &mut [f64],
    ) {
        let frames = acc_real.len();
        let padded = spectrogram.len() / k;
        let ln = 2 * f.half_n + 1;
        acc_real.fill(0.0);
        acc_dc.fill(0.0);
        for a in 0..2 * f.half_k + 1 {
            let Some(src) = (r + f.half_k)
                .checked_sub(a)
                .filter(|s| *s < k)
                .map(|s| &spectrogram[s * padded..(s + 1) * padded])
            else {
                continue;
            };
            let taps = &f.real[a * ln..(a + 1) * ln];
            let dc = f.dc_weights.as_ref().map(|w| &w[a * ln..(a + 1) * ln]);
            // Four taps per pass over the frames, the sums held in registers between them:
            // each sum still adds its terms tap by tap, with a quarter of the accumulator loads
            // and stores.
            let mut b = 0;
            while b + 4 <= ln {
                let start = CONTEXT + f.half_n - b;
                let x: [&[f64]; 4] = std::array::from_fn(|i| &src[start - i..start - i + frames]);
                let g: [f64; 4] = std::array::from_fn(|i| taps[b + i]);
                let xs = x[0].iter().zip(x[1]).zip(x[2].iter().zip(x[3]));
                match dc {
                    Some(dc) => {
                        let w: [f64; 4] = std::array::from_fn(|i| dc[b + i]);
                        let accs = acc_real.iter_mut().zip(acc_dc.iter_mut());
                        for ((ar, ad), ((x0, x1), (x2, x3))) in accs.zip(xs) {
                            *ar = (((*ar + g[0] * x0) + g[1] * x1) + g[2] * x2) + g[3] * x3;
                            *ad = (((*ad + w[0] * x0) + w[1] * x1) + w[2] * x2) + w[3] * x3;
                        }
                    }
                    None => {
                        for (ar, ((x0, x1), (x2, x3))) in acc_real.iter_mut().zip(xs) {
                            *ar = (((*ar + g[0] * x0) + g[1] * x1) + g[2] * x2) + g[3] * x3;
                        }
                    }
                }
                b += 4;
            }
            for b in b..ln {
                let start = CONTEXT + f.half_n - b;
                let s = &src[start..start + frames];
                let g = taps[b];
                match dc {
                    Some(dc) => {
                        let w = dc[b];
                        for ((ar, ad), x) in acc_real.iter_mut().zip(acc_dc.iter_mut()).zip(s) {
                            *ar += g * x;
                            *ad += w * x;
                        }
                    }
                    None => {
                        for (ar, x) in acc_real.iter_mut().zip(s) {
                            *ar += g * x;
                        }
                    }
                }
            }
        }
    }
);

impl Processor for Gabor {
    fn process(&mut self, inputs: &[&Block], outputs: &mut [Block]) {
        let frames = inputs[0].frames();
        if frames == 0 {
            outputs[0].reset_to(0);
            return;
        }
        self.log_spectrogram(inputs[0].as_slice(), frames);
        let k = self.channels;
        self.rows.resize(self.features * frames, 0.0);
        self.acc_real.resize(frames, 0.0);
        self.acc_dc.resize(frames, 0.0);
        let mut feature = 0;
        for f in &self.filters {
            for &(r, sum_real, sum_dc) in &f.rows {
                let (acc_real, acc_dc) = (&mut self.acc_real, &mut self.acc_dc);
                convolve_row(&self.spectrogram, k, f, r, acc_real, acc_dc);
                let row = &mut self.rows[feature * frames..(feature + 1) * frames];
                if f.dc_weights.is_some() {
                    for ((o, g), d) in row.iter_mut().zip(&self.acc_real).zip(&self.acc_dc) {
                        *o = g - d / sum_dc * sum_real;
                    }
                } else {
                    row.copy_from_slice(&self.acc_real);
                }
                feature += 1;
            }
        }
        let out = outputs[0].resize_to(frames);
        let n = frames as f64;
        for (j, row) in self.rows.chunks_exact(frames).enumerate() {
            let mean = row.iter().sum::<f64>() / n;
            let var = row.iter().map(|x| x * x).sum::<f64>() / n - mean * mean;
            let sd = var.sqrt();
            for (t, x) in row.iter().enumerate() {
                out[t * self.features + j] = (x - mean) / sd;
            }
        }
    }

    fn reset(&mut self) {}
}

impl Descriptor for Gabor {
    type Params = GaborParams;
    const NAME: &'static str = "gabor";
    const DEPENDENCY: &'static str = "ratemap";
    const EARS: Ears = Ears::PerEar;
    const DESCRIPTION: &'static str =
        "spectro-temporal Gabor filter-bank features of the log ratemap, normalised per chunk";
    const OUTPUT_UNIT: &'static str = "";

    fn build(params: &GaborParams, inputs: &[SignalInfo]) -> Result<Built> {
        let (p, out) = Gabor::new(params, &inputs[0])?;
        Ok(Built::new(p, vec![out]))
    }

    /// The dB floor, padding and normalisation come from each chunk, as in the AFE.
    fn chunk_invariant(_: &GaborParams) -> bool {
        false
    }
}

/// The registry entry of `gabor`.
pub static REQUEST: RequestDef = request_def::<Gabor>();

#[cfg(test)]
mod tests {
    use super::*;

    fn ratemap(channels: usize) -> SignalInfo {
        SignalInfo::time_frequency(
            44100.0,
            (0..channels).map(|c| 100.0 * (c + 1) as f64).collect(),
        )
        .framed(100.0)
    }

    #[test]
    fn feature_counts_match_the_gbfb() {
        for (k, n) in [(23, 311), (16, 221), (31, 455), (32, 464), (64, 923)] {
            let (g, info) = Gabor::new(&GaborParams::default(), &ratemap(k)).expect("valid");
            assert_eq!((g.features, info.width()), (n, n), "K = {k}");
            assert_eq!(info.features()[0], "1");
        }
    }

    #[test]
    fn modulation_axes_follow_the_spec() {
        let n = omega_list(1, SIZE_MAX_TIME);
        let expect = [PI / 2.0, 0.9863, 0.6193, 0.3889];
        assert_eq!(n.len(), 4);
        for (a, b) in n.iter().zip(expect) {
            assert!((a - b).abs() < 1e-4, "{n:?}");
        }
        assert_eq!(omega_list(0, 69.0).len(), 4);
        assert_eq!(omega_list(0, 48.0).len(), 3);
    }

    #[test]
    fn hann_envelope_excludes_exact_end_points() {
        // w = 8: |j| < 4, 7 taps; w = 8.5: |j| ≤ 4, 9 taps.
        assert_eq!(hann_envelope(8.0).len(), 7);
        assert_eq!(hann_envelope(8.5).len(), 9);
        // Spec N12: a half-width within 1e-9·w above an integer counts as that integer.
        assert_eq!(hann_envelope(8.0 + 2e-9).len(), 7);
        assert_eq!(hann_envelope(8.0 + 2e-6).len(), 9);
        // 0.5·(1 + cos(2πj/8)): 1, ½ ± √2/4, ½ and the first and last ½ − √2/4.
        let (hi, lo) = (0.5 + 2f64.sqrt() / 4.0, 0.5 - 2f64.sqrt() / 4.0);
        let want = [lo, 0.5, hi, 1.0, hi, 0.5, lo];
        for (h, w) in hann_envelope(8.0).iter().zip(want) {
            assert!((h - w).abs() < 1e-15, "{h} vs {w}");
        }
    }

    #[test]
    fn features_are_normalised_per_chunk() {
        let k = 16;
        let (mut g, info) = Gabor::new(&GaborParams::default(), &ratemap(k)).expect("valid");
        let frames = 50;
        let x: Vec<f64> = (0..frames * k)
            .map(|i| {
                let (t, c) = ((i / k) as f64, (i % k) as f64);
                1e-3 * (1.5 + (0.3 * t + 0.5 * c).sin()) * (1.0 + 0.1 * c)
            })
            .collect();
        let mut out = vec![Block::new(info.width())];
        g.process(&[&Block::from_vec(x, k)], &mut out);
        assert_eq!(out[0].frames(), frames);
        for j in 0..info.width() {
            let col: Vec<f64> = out[0].rows().map(|r| r[j]).collect();
            let mean = col.iter().sum::<f64>() / frames as f64;
            let var = col.iter().map(|v| v * v).sum::<f64>() / frames as f64;
            assert!(mean.abs() < 1e-9 && (var - 1.0).abs() < 1e-9, "feature {j}");
        }
        g.process(&[&Block::new(k)], &mut out);
        assert!(out[0].is_empty());
    }

    /// Each chunk is processed on its own (floor, padding, normalisation from the chunk):
    /// two chunks give what two fresh extractors give on each, not the one-call output.
    #[test]
    fn each_chunk_stands_alone() {
        let k = 8;
        let x: Vec<f64> = (0..60 * k)
            .map(|i| 1e-2 * (2.0 + (0.2 * (i / k) as f64 + (i % k) as f64).cos()))
            .collect();
        let info = ratemap(k);
        let p = GaborParams::default();
        let run = |rows: &[f64]| {
            let (mut g, out_info) = Gabor::new(&p, &info).expect("valid");
            let mut out = vec![Block::new(out_info.width())];
            g.process(&[&Block::from_vec(rows.to_vec(), k)], &mut out);
            out.remove(0).into_vec()
        };
        let (mut g, out_info) = Gabor::new(&p, &info).expect("valid");
        let mut out = vec![Block::new(out_info.width())];
        let mut chunked = Vec::new();
        for part in [&x[..25 * k], &x[25 * k..]] {
            g.process(&[&Block::from_vec(part.to_vec(), k)], &mut out);
            chunked.extend_from_slice(out[0].as_slice());
        }
        let mut separate = run(&x[..25 * k]);
        separate.extend(run(&x[25 * k..]));
        assert_eq!(chunked, separate);
        assert_ne!(chunked, run(&x));
    }

    /// Spec 27 step by step on complex filters: envelope times carrier, DC removal or
    /// `G + iG`, normalisation by the largest modulus of a plain 2-D DFT, `'same'`
    /// convolutions summed over the taps that fall on the padded log spectrogram (the
    /// all-ones ones too), the DC map wherever `Re G` has a negative tap, the kept rows,
    /// the real part, the crop and the per-row normalisation.
    fn reference(x: &[f64], k: usize, range_db: f64) -> Vec<f64> {
        let frames = x.len() / k;
        let peak = x.iter().fold(0.0f64, |m, v| m.max(*v));
        let floor = peak * 10f64.powf(-range_db / 10.0);
        let width = frames + 40;
        let s: Vec<Vec<f64>> = (0..k)
            .map(|c| {
                (0..width)
                    .map(|t| {
                        let t = t.clamp(20, frames + 19) - 20;
                        10.0 * (x[t * k + c] + floor).log10()
                    })
                    .collect()
            })
            .collect();
        let spectral = omega_list(0, 3.0 * k as f64);
        let mut omega_k: Vec<f64> = spectral.iter().map(|v| -v).collect();
        omega_k.push(0.0);
        omega_k.extend(spectral.iter().rev());
        let mut omega_n = vec![0.0];
        omega_n.extend(omega_list(1, 40.0).iter().rev());
        let mut features: Vec<Vec<f64>> = Vec::new();
        for &on in &omega_n {
            for &ok in &omega_k {
                if ok < 0.0 && on == 0.0 {
                    continue;
                }
                let (mut wk, mut wn) = (PI / ok.abs() * 3.5, PI / on.abs() * 3.5);
                let (mut ok, mut on) = (ok, on);
                if wn > 40.0 {
                    (wn, on) = (40.0, 0.0);
                }
                if wk > 3.0 * k as f64 {
                    (wk, ok) = (3.0 * k as f64, 0.0);
                }
                let (hk, hn) = (hann_envelope(wk), hann_envelope(wn));
                let (lk, ln) = (hk.len(), hn.len());
                let (k0, n0) = ((lk + 1) as f64 / 2.0, (ln + 1) as f64 / 2.0);
                let e: Vec<Vec<f64>> = hk
                    .iter()
                    .map(|a| hn.iter().map(|b| a * b).collect())
                    .collect();
                let mut g: Vec<Vec<Complex64>> = (0..lk)
                    .map(|a| {
                        (0..ln)
                            .map(|b| {
                                let phase = on * ((b + 1) as f64 - n0) + ok * ((a + 1) as f64 - k0);
                                e[a][b] * Complex64::from_polar(1.0, phase)
                            })
                            .collect()
                    })
                    .collect();
                let count = (lk * ln) as f64;
                if on != 0.0 || ok != 0.0 {
                    let mean_e = e.iter().flatten().sum::<f64>() / count;
                    let mean_g = g.iter().flatten().sum::<Complex64>() / count;
                    for (gr, er) in g.iter_mut().zip(&e) {
                        for (v, ev) in gr.iter_mut().zip(er) {
                            *v -= ev / mean_e * mean_g;
                        }
                    }
                } else {
                    g.iter_mut()
                        .flatten()
                        .for_each(|v| *v *= Complex64::new(1.0, 1.0));
                }
                let mut top = 0.0f64;
                for u in 0..lk {
                    for v in 0..ln {
                        let mut sum = Complex64::new(0.0, 0.0);
                        for (a, gr) in g.iter().enumerate() {
                            for (b, gv) in gr.iter().enumerate() {
                                let turns = (u * a) as f64 / lk as f64 + (v * b) as f64 / ln as f64;
                                sum += gv * Complex64::from_polar(1.0, -2.0 * PI * turns);
                            }
                        }
                        top = top.max(sum.norm());
                    }
                }
                g.iter_mut().flatten().for_each(|v| *v /= top);
                let total: f64 = g.iter().flatten().map(|v| v.norm()).sum();
                let dc = g.iter().flatten().any(|v| v.re < 0.0);
                // 'same': out[r][t] = Σ G[a][b]·S[r + ⌊Lk/2⌋ − a][t + ⌊Ln/2⌋ − b], zero off S.
                let conv =
                    |r: usize, t: usize, f: &dyn Fn(usize, usize, usize, usize) -> Complex64| {
                        let mut sum = Complex64::new(0.0, 0.0);
                        for a in 0..lk {
                            for b in 0..ln {
                                let (rr, tt) = (
                                    (r + lk / 2) as isize - a as isize,
                                    (t + ln / 2) as isize - b as isize,
                                );
                                if (0..k as isize).contains(&rr)
                                    && (0..width as isize).contains(&tt)
                                {
                                    sum += f(a, b, rr as usize, tt as usize);
                                }
                            }
                        }
                        sum
                    };
                let step = (lk / 4).max(1);
                for r in ((k / 2) % step..k).step_by(step) {
                    let row: Vec<f64> = (20..20 + frames)
                        .map(|t| {
                            let f = conv(r, t, &|a, b, rr, tt| g[a][b] * s[rr][tt]);
                            if !dc {
                                return f.re;
                            }
                            let a_ = |a: usize, b: usize| g[a][b].norm() / total;
                            let sa = conv(r, t, &|a, b, rr, tt| (a_(a, b) * s[rr][tt]).into());
                            let ones_a = conv(r, t, &|a, b, _, _| a_(a, b).into());
                            let ones_g = conv(r, t, &|a, b, _, _| g[a][b]);
                            (f - sa / ones_a * ones_g).re
                        })
                        .collect();
                    features.push(row);
                }
            }
        }
        let n = frames as f64;
        let mut out = vec![0.0; frames * features.len()];
        for (j, row) in features.iter().enumerate() {
            let mean = row.iter().sum::<f64>() / n;
            let sd = (row.iter().map(|v| v * v).sum::<f64>() / n - mean * mean).sqrt();
            for (t, v) in row.iter().enumerate() {
                out[t * features.len() + j] = (v - mean) / sd;
            }
        }
        out
    }

    /// Six channels (spectral filters of 7, 15 and 17 taps, so most reach past the edge
    /// channels), a ratemap spanning 1e-12 to 1e-2 (the 60-dB floor shapes the quiet
    /// part), 37 frames. The features are O(1) and differ by at most about 1e-13 (the
    /// sums run in other orders); the bound is 1e-12.
    #[test]
    fn matches_the_spec_written_out() {
        let (k, frames) = (6, 37);
        let x: Vec<f64> = (0..frames * k)
            .map(|i| {
                let (t, c) = ((i / k) as f64, (i % k) as f64);
                let level = if (i / k) % 9 < 3 { 1e-12 } else { 1e-2 };
                level * (1.2 + (0.4 * t + 0.9 * c).sin()) * (1.0 + 0.3 * c)
            })
            .collect();
        let p = GaborParams {
            max_dynamic_range_db: 60.0,
        };
        let (mut g, info) = Gabor::new(&p, &ratemap(k)).expect("valid");
        let mut out = vec![Block::new(info.width())];
        g.process(&[&Block::from_vec(x.clone(), k)], &mut out);
        let want = reference(&x, k, 60.0);
        assert_eq!(out[0].as_slice().len(), want.len());
        for (i, (a, b)) in out[0].as_slice().iter().zip(&want).enumerate() {
            assert!(
                (a - b).abs() <= 1e-12,
                "value {i} (feature {}): {a} vs {b}",
                i % info.width()
            );
        }
    }

    #[test]
    fn bad_range_names_the_parameter() {
        for v in [0.0, -10.0] {
            let p = GaborParams {
                max_dynamic_range_db: v,
            };
            let e = Gabor::new(&p, &ratemap(8)).unwrap_err().to_string();
            assert!(e.contains("gb_maxDynamicRangeDB"), "{e}");
        }
    }
}
