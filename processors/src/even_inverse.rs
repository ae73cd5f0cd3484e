//! The inverse DFT of a real, even spectrum (a type-I cosine transform) by a real FFT of
//! half the length: the autocorrelation's second transform at half the cost of a full
//! complex-to-real one.
//!
//! For a spectrum `P[k] = P[N − k]` of even length `N = 2M`, the unnormalised inverse
//! `S[m] = Σₖ P[k]·e^{2πikm/N}` is real and equals `2·C[m]`, with
//! `C[m] = ½P[0] + ½(−1)^m P[M] + Σ_{j=1}^{M−1} P[j]·cos(πjm/M)`. With
//! `v[j] = P[j] + P[M − j]`, `w[j] = P[j] − P[M − j]` and `u[j] = ½v[j] + sin(πj/M)·w[j]`
//! (`j < M`), the `M`-point DFT `U` of `u` gives the even terms, `C[2k] = Re U[k]`, and the
//! differences of the odd ones, `C[2k + 1] − C[2k − 1] = Im U[k]`, from `C[1]` (the
//! definition at `m = 1`): `v` is symmetric about `M/2` and `sin(πj/M)·w[j]`
//! antisymmetric, so each lands in one part of `U`.

use std::f64::consts::PI;

use num_complex::Complex64;

use afe_core::real_fft::{split_pair, RealFft};

/// A planned inverse of length `N` for real, even spectra, with its buffers.
pub struct EvenInverse {
    /// The real FFT of length `M`, whose input holds `u`.
    fft: RealFft,
    /// `sin(πj/M)` and `cos(πj/M)`, `j < M`.
    sin: Vec<f64>,
    cos: Vec<f64>,
    /// `U`'s real and imaginary parts.
    re: Vec<f64>,
    im: Vec<f64>,
}

impl std::fmt::Debug for EvenInverse {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EvenInverse")
            .field("len", &(2 * self.fft.points()))
            .finish_non_exhaustive()
    }
}

impl EvenInverse {
    /// Plans the inverse of length `n`, a multiple of 4 (so that the real FFT of half the
    /// length has an even length as well).
    ///
    /// # Panics
    /// If `n` is not a positive multiple of 4.
    pub fn new(n: usize) -> Self {
        assert!(
            n >= 4 && n.is_multiple_of(4),
            "a positive multiple of 4, not {n}"
        );
        let m = n / 2;
        let angle = |j: usize| PI * j as f64 / m as f64;
        EvenInverse {
            sin: (0..m).map(|j| angle(j).sin()).collect(),
            cos: (0..m).map(|j| angle(j).cos()).collect(),
            re: vec![0.0; m / 2 + 1],
            im: vec![0.0; m / 2 + 1],
            fft: RealFft::new(m),
        }
    }

    /// From `p`, the spectrum's first half `P[0..=M]` (`M = N/2`; the rest is its mirror
    /// image), writes `S[m] = Σₖ P[k]·e^{2πikm/N}` for `m < out.len()` (at most `M + 1`),
    /// unnormalised as a complex-to-real FFT's output. Inlined so that its loops get the
    /// caller's vector width.
    ///
    /// # Panics
    /// If `p` does not hold `M + 1` values or `out` more than `M + 1`.
    #[inline(always)]
    pub fn run(&mut self, p: &[f64], out: &mut [f64]) {
        let m = self.fft.points();
        assert_eq!(p.len(), m + 1, "the spectrum's first half, M + 1 values");
        assert!(out.len() <= m + 1, "at most M + 1 values of the inverse");
        // `P[M − j]` for `j < M`: `p[1..]` backwards.
        let mirrored = p[..m].iter().zip(p[1..].iter().rev());
        for ((u, (&a, &b)), s) in self.fft.input().iter_mut().zip(mirrored).zip(&self.sin) {
            *u = 0.5 * (a + b) + s * (a - b);
        }
        // C[1] by its definition.
        let c1 = 0.5 * (p[0] - p[m]) + dot(&p[1..m], &self.cos[1..]);
        self.finish(c1, out);
    }

    /// [`EvenInverse::run`] of the power spectrum `P[k] = |X[k]|²` of a real transform of
    /// `N` points, from that transform's half-length output `z` (`Z[0..M]`) and its split
    /// twiddles ([`RealFft::transform`]): the split, the powers and the fold into `u` in one
    /// pass over the pairs `(k, M − k)`, with `P` never stored. `P` and `u` are those of
    /// the forward transform's spectrum bit for bit (for powers below `f64::MAX/2`);
    /// `C[1]` sums the same terms in another order.
    ///
    /// # Panics
    /// If `z` does not hold `M` values or `out` more than `M + 1`.
    #[inline(always)]
    pub fn run_squares(
        &mut self,
        (z, (tw_re, tw_im)): (&[Complex64], (&[f64], &[f64])),
        out: &mut [f64],
    ) {
        let m = self.fft.points();
        assert_eq!(z.len(), m, "the forward transform's M values");
        assert!(out.len() <= m + 1, "at most M + 1 values of the inverse");
        let z: &[f64] = bytemuck::cast_slice(z);
        let (sin, cos) = (&self.sin[..m], &self.cos[..m]);
        let u = &mut self.fft.input()[..m];
        // X[0] and X[M] are real; with M even, X[M/2] = Z̄[M/2]
        let (p0, pm) = ((z[0] + z[1]) * (z[0] + z[1]), (z[0] - z[1]) * (z[0] - z[1]));
        u[0] = 0.5 * (p0 + pm) + sin[0] * (p0 - pm);
        let c = m / 2;
        let pc = z[2 * c] * z[2 * c] + z[2 * c + 1] * z[2 * c + 1];
        // ½(P + P) + sin·(P − P), exactly, for a finite P below f64::MAX/2
        u[c] = pc;
        // pairs (k, M − k), 0 < k < M/2: `low` from k = 1 up, `high` from M − 1 down
        let pairs = c - 1;
        let (u_low, u_rest) = u[1..].split_at_mut(pairs);
        let high_start = u_rest.len() - pairs;
        let mut fold = Fold {
            z_low: &z[2..2 + 2 * pairs],
            z_high: &z[2 * (m - pairs)..],
            tw: (&tw_re[..pairs], &tw_im[..pairs]),
            sin: (&sin[1..1 + pairs], &sin[m - pairs..]),
            cos: (&cos[1..1 + pairs], &cos[m - pairs..]),
            u_low,
            u_high: &mut u_rest[high_start..],
        };
        // a vector's worth of pairs at a time, the rest one by one
        let mut sums = [0.0; FOLD];
        let whole = pairs - pairs % FOLD;
        for i0 in (0..whole).step_by(FOLD) {
            fold.pairs(i0, &mut sums);
        }
        let mut rest = [0.0];
        for i in whole..pairs {
            fold.pairs(i, &mut rest);
        }
        let c1 = 0.5 * (p0 - pm) + pc * cos[c] + (sums.iter().sum::<f64>() + rest[0]);
        self.finish(c1, out);
    }

    /// From `u` in the real FFT's input and `C[1]`, writes `S[m]` for `m < out.len()`.
    #[inline(always)]
    fn finish(&mut self, c1: f64, out: &mut [f64]) {
        self.fft.run(&mut self.re, &mut self.im);
        for (o, u) in out.iter_mut().step_by(2).zip(&self.re) {
            *o = 2.0 * u;
        }
        // C[2k + 1] = C[1] + Σ_{0 < i ≤ k} Im U[i], in blocks summed side by side; U[0] is
        // real (its imaginary part an exact 0), so the sums may start at i = 0.
        let odd = out.len() / 2;
        let step = odd.div_ceil(BLOCKS).max(1);
        let mut start = [0.0; BLOCKS];
        start[0] = c1;
        for b in 1..BLOCKS {
            let terms = self.im.get((b - 1) * step..(b * step).min(odd));
            let sum: f64 = terms.unwrap_or_default().iter().sum();
            start[b] = start[b - 1] + sum;
        }
        for i in 0..step {
            for (b, acc) in start.iter_mut().enumerate() {
                let k = b * step + i;
                if k < odd {
                    *acc += self.im[k];
                    out[2 * k + 1] = 2.0 * *acc;
                }
            }
        }
    }
}

/// Blocks of the odd outputs' running sum, so that their additions overlap.
const BLOCKS: usize = 4;

/// Running sums of `C[1]`'s terms in the fused pass, one per vector lane.
const FOLD: usize = 8;

/// The slices of [`EvenInverse::run_squares`]'s pass over the pairs `(k, M − k)`: the
/// forward transform's `Z` from `k = 1` up and from `M − 1` down (interleaved real and
/// imaginary parts), its twiddles, `sin` and `cos` at both ends, and `u`.
struct Fold<'a> {
    z_low: &'a [f64],
    z_high: &'a [f64],
    tw: (&'a [f64], &'a [f64]),
    sin: (&'a [f64], &'a [f64]),
    cos: (&'a [f64], &'a [f64]),
    u_low: &'a mut [f64],
    u_high: &'a mut [f64],
}

impl Fold<'_> {
    /// Pairs `i0..i0 + N` (`k = i + 1`): `X[k]` and `X[M − k]` by `realfft`'s split,
    /// their powers folded into `u[k]` and `u[M − k]`; adds their terms of `C[1]` to
    /// `sums`. Over slices of known length, so that the loads run forwards and backwards
    /// without bounds checks and a vector's worth of pairs vectorises.
    #[inline(always)]
    fn pairs<const N: usize>(&mut self, i0: usize, sums: &mut [f64; N]) {
        let j0 = self.u_high.len() - N - i0;
        let (z_low, z_high) = (
            &self.z_low[2 * i0..2 * (i0 + N)],
            &self.z_high[2 * j0..2 * (j0 + N)],
        );
        let (tw_re, tw_im) = (&self.tw.0[i0..i0 + N], &self.tw.1[i0..i0 + N]);
        let (sin_low, sin_high) = (&self.sin.0[i0..i0 + N], &self.sin.1[j0..j0 + N]);
        let (cos_low, cos_high) = (&self.cos.0[i0..i0 + N], &self.cos.1[j0..j0 + N]);
        let (mut u_low, mut u_high) = ([0.0; N], [0.0; N]);
        for l in 0..N {
            let h = N - 1 - l;
            let x = (z_low[2 * l], z_low[2 * l + 1]);
            let y = (z_high[2 * h], z_high[2 * h + 1]);
            let ((lo_re, lo_im), (hi_re, hi_im)) = split_pair::<false>(x, y, (tw_re[l], tw_im[l]));
            let p_low = lo_re * lo_re + lo_im * lo_im;
            let p_high = hi_re * hi_re + hi_im * hi_im;
            u_low[l] = 0.5 * (p_low + p_high) + sin_low[l] * (p_low - p_high);
            u_high[h] = 0.5 * (p_high + p_low) + sin_high[h] * (p_high - p_low);
            sums[l] += p_low * cos_low[l] + p_high * cos_high[h];
        }
        self.u_low[i0..i0 + N].copy_from_slice(&u_low);
        self.u_high[j0..j0 + N].copy_from_slice(&u_high);
    }
}

/// `Σ a[i]·b[i]` over eight running sums, so that it vectorises.
#[inline(always)]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let (a8, b8) = (a.chunks_exact(8), b.chunks_exact(8));
    let rest: f64 = a8
        .remainder()
        .iter()
        .zip(b8.remainder())
        .map(|(x, y)| x * y)
        .sum();
    let mut acc = [0.0; 8];
    for (x, y) in a8.zip(b8) {
        for ((s, x), y) in acc.iter_mut().zip(x).zip(y) {
            *s += x * y;
        }
    }
    acc.iter().sum::<f64>() + rest
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{noise, plain_dft};
    use num_complex::Complex64;

    /// `S[m]` by its definition: the real part of the plain DFT of the whole mirrored
    /// spectrum (it is even, so its DFT is real).
    fn direct(p: &[f64], count: usize) -> Vec<f64> {
        let n = 2 * (p.len() - 1);
        let full: Vec<f64> = (0..n).map(|k| p[k.min(n - k)]).collect();
        plain_dft(&full, n)[..count].iter().map(|v| v.re).collect()
    }

    #[test]
    fn gives_the_inverse_dft_of_the_mirrored_spectrum() {
        for (n, count) in [
            (2048, 1025),
            (2048, 881),
            (64, 33),
            (64, 32),
            (12, 7),
            (4, 3),
        ] {
            let p = noise(n / 2 + 1, n as u64);
            let mut out = vec![f64::NAN; count];
            EvenInverse::new(n).run(&p, &mut out);
            let want = direct(&p, count);
            let scale = want.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            for (m, (g, w)) in out.iter().zip(&want).enumerate() {
                assert!(
                    (g - w).abs() <= 1e-13 * scale,
                    "N = {n}, m = {m}: {g} vs {w}"
                );
            }
        }
    }

    /// The fused pass from the forward transform gives the inverse of its squared
    /// spectrum, for pair counts with and without a remainder after whole vectors (0 pairs
    /// at N = 4, 1 at 8, 8 at 36, 15 at 64, 511 at 2048).
    #[test]
    fn squares_from_the_forward_transform_equal_the_inverse_of_the_powers() {
        for (n, count) in [
            (4, 3),
            (8, 5),
            (12, 7),
            (36, 19),
            (64, 33),
            (64, 20),
            (2048, 881),
            (2048, 1025),
        ] {
            let x = noise(n, 3 + n as u64);
            let mut fft = RealFft::new(n);
            let (mut re, mut im) = (vec![0.0; n / 2 + 1], vec![0.0; n / 2 + 1]);
            fft.input().copy_from_slice(&x);
            fft.run(&mut re, &mut im);
            let p: Vec<f64> = re.iter().zip(&im).map(|(r, i)| r * r + i * i).collect();
            let mut inverse = EvenInverse::new(n);
            let mut want = vec![f64::NAN; count];
            inverse.run(&p, &mut want);
            fft.input().copy_from_slice(&x);
            let mut got = vec![f64::NAN; count];
            inverse.run_squares(fft.transform(), &mut got);
            for (m, (g, w)) in got.iter().zip(&want).enumerate() {
                // the even lags bit for bit; the odd ones from C[1] summed in another order
                let tolerance = if m % 2 == 0 {
                    0.0
                } else {
                    1e-14 * want[0].abs()
                };
                assert!((g - w).abs() <= tolerance, "N = {n}, m = {m}: {g} vs {w}");
            }
        }
    }

    #[test]
    fn agrees_with_a_complex_to_real_fft() {
        let n = 2048;
        let p = noise(n / 2 + 1, 7);
        let ifft = afe_fft::real_inverse(n);
        let mut full: Vec<Complex64> = p.iter().map(|&v| Complex64::new(v, 0.0)).collect();
        let mut want = ifft.make_output_vec();
        ifft.process(&mut full, &mut want).expect("lengths match");
        let mut out = vec![0.0; n / 2 + 1];
        EvenInverse::new(n).run(&p, &mut out);
        for (m, (g, w)) in out.iter().zip(&want).enumerate() {
            assert!(
                (g - w).abs() <= 1e-12 * want[0].abs(),
                "m = {m}: {g} vs {w}"
            );
        }
    }

    #[test]
    fn debug_names_the_transform_length() {
        assert_eq!(
            format!("{:?}", EvenInverse::new(12)),
            "EvenInverse { len: 12, .. }"
        );
    }

    #[test]
    #[should_panic(expected = "a positive multiple of 4")]
    fn a_length_not_a_multiple_of_4_is_refused() {
        EvenInverse::new(6);
    }
}
