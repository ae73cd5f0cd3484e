//! The SIMD kernels of the precedence model: the transforms, products and correlations
//! its frames go through, each a free function compiled per instruction set by
//! `simd_kernel!`. Apart from the model, which calls them, so that the code that needs a
//! version per vector width stands on its own.

use afe_core::framing::Frame;
use afe_core::real_fft::{RealFft, RealIfft};

use super::lag_removal::{LagRemoval, TAPS};
use crate::even_inverse::EvenInverse;

afe_core::simd_kernel!(
    /// The transform of `x` (zero-padded) into `re` and `im`: a function of its own so
    /// that the copies around the FFT get a version per vector width.
    pub(super) fn transform(fft: &mut RealFft, x: &[f64], (re, im): (&mut [f64], &mut [f64])) {
        let input = fft.input();
        input[..x.len()].copy_from_slice(x);
        input[x.len()..].fill(0.0);
        fft.run(re, im);
    }
);

/// `Σ a[i]·b[i]` with eight partial sums (vectorised).
#[inline(always)]
fn dot_lanes(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for l in 0..8 {
            acc[l] += x[l] * y[l];
        }
    }
    let tail: f64 = ra.iter().zip(rb).map(|(x, y)| x * y).sum();
    acc.iter().sum::<f64>() + tail
}

afe_core::simd_kernel!(
    /// `Σ a[i]·b[i]` over the shorter length.
    pub(super) fn dot(a: &[f64], b: &[f64]) -> f64 {
        dot_lanes(a, b)
    }
);

afe_core::simd_kernel!(
    /// The frame's autocorrelation at lags `k·τ`, `k = 0..5` (0 from lag `len(x)` on).
    pub(super) fn lag_products(x: &[f64], tau: usize) -> [f64; TAPS] {
        let mut r = [0.0; TAPS];
        for (k, rk) in r.iter_mut().enumerate() {
            let d = k * tau;
            if d < x.len() {
                *rk = dot_lanes(&x[d..], &x[..x.len() - d]);
            }
        }
        r
    }
);

afe_core::simd_kernel!(
    /// `out[m + maxLag] = Σ_j a[j + m]·b[j]` for `m = −maxLag..maxLag`, `out` being
    /// `2·maxLag + 1` long (calcXCorr with `'none'` scaling; zero where the signals do not
    /// overlap).
    pub(super) fn xcorr(a: &[f64], b: &[f64], out: &mut [f64]) {
        let max_lag = (out.len() / 2) as isize;
        let (la, lb) = (a.len() as isize, b.len() as isize);
        for (i, o) in out.iter_mut().enumerate() {
            let m = i as isize - max_lag;
            let lo = (-m).max(0);
            let hi = lb.min(la - m);
            *o = if hi > lo {
                dot_lanes(
                    &a[(lo + m) as usize..(hi + m) as usize],
                    &b[lo as usize..hi as usize],
                )
            } else {
                0.0
            };
        }
    }
);

afe_core::simd_kernel!(
    /// Windows the frame (`[time][channel]`, `nc` wide) into `cols` (`[channel][time]`) and
    /// each channel's largest windowed value into `peaks` (NaN ignored, as MATLAB's `max`).
    pub(super) fn window_columns<'a>(
        win: &[f64],
        frame: Frame<'a>,
        cols: &mut [f64],
        peaks: &mut [f64],
    ) {
        frame.window_columns(win, cols, Some(peaks), None);
    }
);

afe_core::simd_kernel!(
    /// Adds a channel's power spectrum `|x|²` to its cumulative weighted one
    /// (`power += |x|²·weight`, or `=` on the first frame) and to the summary spectrum
    /// (the raw power on the first frame, the cumulative weighted one after).
    pub(super) fn accumulate_power(
        (re, im): (&[f64], &[f64]),
        power: &mut [f64],
        summary: &mut [f64],
        weight: f64,
        first: bool,
    ) {
        let n = power.len().min(summary.len()).min(re.len()).min(im.len());
        let (power, summary, re, im) = (&mut power[..n], &mut summary[..n], &re[..n], &im[..n]);
        if first {
            for k in 0..n {
                let pw = re[k] * re[k] + im[k] * im[k];
                power[k] = pw * weight;
                summary[k] += pw;
            }
        } else {
            for k in 0..n {
                let pw = re[k] * re[k] + im[k] * im[k];
                power[k] += pw * weight;
                summary[k] += power[k];
            }
        }
    }
);

afe_core::simd_kernel!(
    /// The inverse transform of the real, even spectrum whose first half is `p`, scaled
    /// by `scale`, at lags `0..out.len()` into `out`.
    pub(super) fn even_lags(even: &mut EvenInverse, p: &[f64], scale: f64, out: &mut [f64]) {
        even.run(p, out);
        out.iter_mut().for_each(|o| *o *= scale);
    }
);

afe_core::simd_kernel!(
    /// The full cross-correlation `R[k] = Σ_j a[j + k]·b[j]` of two frames of `W` samples
    /// from their spectra `fa`, `fb` (real and imaginary parts), into `out` (lags
    /// `−(W−1)..W−1`, `2W − 1` values).
    pub(super) fn frame_xcorr(
        ifft: &mut RealIfft,
        fa: (&[f64], &[f64]),
        fb: (&[f64], &[f64]),
        out: &mut [f64],
    ) {
        conj_product(fa, fb, ifft.spectrum());
        let time = ifft.run();
        let nfft = time.len();
        let scale = 1.0 / nfft as f64;
        let w = out.len().div_ceil(2);
        let (neg, pos) = out.split_at_mut(w - 1);
        for (d, s) in neg.iter_mut().zip(&time[nfft - (w - 1)..]) {
            *d = s * scale;
        }
        for (d, s) in pos.iter_mut().zip(&time[..w]) {
            *d = s * scale;
        }
    }
);

afe_core::simd_kernel!(
    /// `out[k] = fa[k]·conj(fb[k])`: the spectrum of the cross-correlation (each as real
    /// and imaginary parts).
    fn conj_product(
        (a_re, a_im): (&[f64], &[f64]),
        (b_re, b_im): (&[f64], &[f64]),
        (out_re, out_im): (&mut [f64], &mut [f64]),
    ) {
        let n = out_re.len().min(out_im.len());
        let (a_re, a_im, b_re, b_im) = (&a_re[..n], &a_im[..n], &b_re[..n], &b_im[..n]);
        for k in 0..n {
            out_re[k] = a_re[k] * b_re[k] + a_im[k] * b_im[k];
            out_im[k] = a_im[k] * b_re[k] - a_re[k] * b_im[k];
        }
    }
);

afe_core::simd_kernel!(
    /// `xcorr(S_l, S_r)` over lags `±(out.len()/2)` into `out`, from the full
    /// cross-correlation `r` of the frames (lags `−(W−1)..W−1`): as `S` is a sum of shifted
    /// copies of its frame, `xcorr(S_l, S_r)[m] = Σ_{q,p} c_q·d_p·R[m − qτ_l + pτ_r]`.
    pub(super) fn short_xcorr(r: &[f64], ll: &LagRemoval, lr: &LagRemoval, out: &mut [f64]) {
        let span = r.len() as isize;
        // `r` holds 2W − 1 lags, lag 0 at W − 1
        let (half, nl) = (span / 2, out.len() as isize);
        let max_lag = nl / 2;
        out.fill(0.0);
        for q in 0..TAPS {
            for p in 0..TAPS {
                let coef = ll.short[q] * lr.short[p];
                // out[i] += coef·R[i − maxLag − qτ_l + pτ_r], lag k at index k + W − 1
                let shift = half - max_lag - (q * ll.tau) as isize + (p * lr.tau) as isize;
                let lo = (-shift).max(0);
                let hi = nl.min(span - shift);
                if hi > lo {
                    let src = &r[(lo + shift) as usize..(hi + shift) as usize];
                    for (o, v) in out[lo as usize..hi as usize].iter_mut().zip(src) {
                        *o += coef * v;
                    }
                }
            }
        }
    }
);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::precedence::model::Spectra;
    use crate::testing::noise;
    use afe_core::real_fft::fast_len;

    #[test]
    fn short_correlation_from_the_frames_equals_the_direct_one() {
        let w = 64;
        let nfft = fast_len(2 * w - 1);
        let (mut fft, mut ifft) = (RealFft::new(nfft), RealIfft::new(nfft));
        for (tau_l, tau_r, seed) in [(3, 5, 1), (12, 4, 2), (30, 30, 3), (40, 9, 4)] {
            let (xl, xr) = (noise(w, seed), noise(w, seed + 10));
            let (ll, lr) = (
                LagRemoval::new(tau_l, 0.7, 0.9),
                LagRemoval::new(tau_r, 0.4, 1.0),
            );
            let mut spectrum = |x: &[f64]| {
                let mut s = Spectra::zeros(nfft / 2 + 1);
                s.transform(&mut fft, x, 0..nfft / 2 + 1);
                s
            };
            let (fl, fr) = (spectrum(&xl), spectrum(&xr));
            let mut r = vec![0.0; 2 * w - 1];
            let all = 0..nfft / 2 + 1;
            frame_xcorr(&mut ifft, fl.bins(all.clone()), fr.bins(all), &mut r);
            let mut got = vec![0.0; 2 * 20 + 1];
            short_xcorr(&r, &ll, &lr, &mut got);
            let mut sl = vec![0.0; ll.len(false, w)];
            let mut sr = vec![0.0; lr.len(false, w)];
            ll.apply(false, &xl, &mut sl);
            lr.apply(false, &xr, &mut sr);
            let mut want = vec![0.0; got.len()];
            xcorr(&sl, &sr, &mut want);
            let top = want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for (g, v) in got.iter().zip(&want) {
                assert!(
                    (g - v).abs() <= 1e-13 * top,
                    "τ {tau_l}/{tau_r}: {g} vs {v}"
                );
            }
            // and the energies from the frame's autocorrelation at multiples of τ
            let ac = lag_products(&xl, tau_l);
            let mut energy = 0.0;
            for q in 0..TAPS {
                for p in 0..TAPS {
                    energy += ll.short[q] * ll.short[p] * ac[q.abs_diff(p)];
                }
            }
            let direct = dot(&sl, &sl);
            assert!((energy - direct).abs() <= 1e-13 * direct);
        }
    }
}
