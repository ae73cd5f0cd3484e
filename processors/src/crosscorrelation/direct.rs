//! The cross-correlation's direct engine: the two-parallel fast FIR, eight channels per
//! vector, with its buffers and its two SIMD kernels (windowing into polyphase rows, dot
//! products over blocks of lags). Apart from the processor, which only frames the input
//! and picks an engine by the cost model, as the FFT engine is.

use std::ops::Range;

use afe_core::cpu::has_avx512;
use afe_core::framing::Frame;
use afe_core::lanes::vector_start;

use super::in_subnormal_band;

/// Channels per vector of the direct method.
pub(super) const LANES: usize = 8;

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
pub(super) struct Direct {
    pub(super) win: Vec<f64>,
    pub(super) max_lag: usize,
    /// Lags computed per pass (accumulators held in registers): 8 to 12 with AVX-512,
    /// else 4 or 5.
    lag_block: usize,
    /// First channel of each group.
    pub(super) starts: Vec<usize>,
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

/// At most the `f64` values of the direct engine's buffers for a `w`-sample window and
/// lags up to `max_lag`: for one group of channels, three rows of half a window per ear,
/// and three of the lags (padded by at most 11) for the left frame's shifts and the sums.
pub(super) fn direct_work(w: usize, max_lag: usize) -> usize {
    LANES * 3 * (2 * (w / 2) + 2 * (max_lag + 12))
}

impl Direct {
    pub(super) fn new(win: Vec<f64>, max_lag: usize, nc: usize) -> Self {
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
    pub(super) fn part(&self, groups: Range<usize>) -> Direct {
        let starts = self.starts[groups].to_vec();
        Self::for_groups(self.win.clone(), self.max_lag, self.lag_block, starts)
    }

    /// Correlates the channels of its groups of one frame pair (`[time][channel]`, over
    /// the frames' columns) into `out` (`[channel][lag]`, from their first column on).
    pub(super) fn correlate(&mut self, frame_l: Frame<'_>, frame_r: Frame<'_>, out: &mut [f64]) {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::crosscorrelation::fft::FftEngine;
    use crate::framed::EarFrames;
    use afe_core::window::{window, Window};

    #[test]
    fn the_working_memory_bound_holds_every_buffer() {
        for (w, max_lag) in [(40, 0), (40, 11), (42, 12), (882, 49), (882, 882)] {
            let win = window(Window::Hann, w);
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
            .flat_map(|c| [(c, Window::Hann), (c, Window::Hamming)])
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
                let win = window(wname, w);
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
}
