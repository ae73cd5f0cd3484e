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

use crate::real_fft::RealFft;

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
            .field("len", &(2 * self.fft.len()))
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
        assert!(n >= 4 && n % 4 == 0, "a positive multiple of 4, not {n}");
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
        let m = self.fft.len();
        assert_eq!(p.len(), m + 1, "the spectrum's first half, M + 1 values");
        assert!(out.len() <= m + 1, "at most M + 1 values of the inverse");
        // `P[M − j]` for `j < M`: `p[1..]` backwards.
        let mirrored = p[..m].iter().zip(p[1..].iter().rev());
        for ((u, (&a, &b)), s) in self.fft.input().iter_mut().zip(mirrored).zip(&self.sin) {
            *u = 0.5 * (a + b) + s * (a - b);
        }
        // C[1] by its definition.
        let c1 = 0.5 * (p[0] - p[m]) + dot(&p[1..m], &self.cos[1..]);
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
    use realfft::num_complex::Complex64;
    use realfft::RealFftPlanner;

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

    #[test]
    fn agrees_with_a_complex_to_real_fft() {
        let n = 2048;
        let p = noise(n / 2 + 1, 7);
        let ifft = RealFftPlanner::<f64>::new().plan_fft_inverse(n);
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
