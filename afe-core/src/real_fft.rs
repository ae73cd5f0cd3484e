//! The DFT of a real sequence of even length `N = 2M`, by an `M`-point complex FFT of the
//! sequence taken in pairs and a split pass that separates the two halves' spectra: the
//! operations of `realfft`'s forward transform, so its values bit for bit, with a faster
//! split pass. `realfft`'s is compiled for the baseline SSE2 and runs one complex value
//! at a time (8 % of issue 11's whole set on the AVX2 path); here it has a version per
//! vector width and works on the real and imaginary parts as separate arrays, so that
//! the pairs `(k, M − k)`, the second running backwards, vectorise. The `autocorrelation`
//! request (with its filterbank and hair cells) takes about 5 % less time with it there.
//!
//! With `Z = FFT_M(x[2m] + i·x[2m + 1])`, the spectrum is, for `0 < k < M`,
//! `X[k] = ½(Z[k] + Z̄[M − k]) − ½i·e^{−2πik/N}·(Z[k] − Z̄[M − k])`, and
//! `X[0] = Re Z[0] + Im Z[0]`, `X[M] = Re Z[0] − Im Z[0]`.
//!
//! [`RealIfft`] is the inverse, `realfft`'s complex-to-real transform bit for bit with its
//! merge pass vectorised the same way: the pairs `(k, M − k)` of the spectrum merged into
//! the `M`-point sequence whose inverse complex FFT holds the real output in pairs.

use std::f64::consts::PI;
use std::sync::Arc;

use afe_fft::Fft;
use num_complex::Complex64;

/// At most the `f64` values a planned transform of `n` points here holds ([`RealFft`],
/// [`RealIfft`], and the processors' even inverse built on them): its buffers, scratch and the FFT
/// plan's own twiddles, for the processors' working-memory bounds.
pub fn transform_values(n: usize) -> usize {
    n.saturating_mul(6)
}

/// The smallest length from `n` on of the form `2^k`, `3·2^k`, `5·2^k` or `7·2^k`, which
/// these transforms run fastest: for a linear correlation, any length beyond its lags
/// gives the same values (1792 for 20 ms at 44.1 kHz, about 12 % faster than the AFE's
/// 2048).
pub fn fast_len(n: usize) -> usize {
    [1, 3, 5, 7]
        .into_iter()
        .map(|m| m * n.div_ceil(m).next_power_of_two())
        .min()
        .unwrap_or(n)
}

/// The complex FFT of `n/2` points (forward or inverse) for a real transform of `n`
/// values (even, at least 2), and `cos θ_k`, `sin θ_k` for `θ_k = −2πk/n`,
/// `0 < k < ⌈n/4⌉`, which each direction scales its own way.
///
/// # Panics
/// If `n` is odd or below 2.
fn half_length_plan(n: usize, inverse: bool) -> (Arc<dyn Fft<f64>>, Vec<f64>, Vec<f64>) {
    assert!(
        n >= 2 && n.is_multiple_of(2),
        "an even length of at least 2, not {n}"
    );
    let fft = match inverse {
        true => afe_fft::inverse(n / 2),
        false => afe_fft::forward(n / 2),
    };
    let step = -2.0 * PI / n as f64;
    let (cos, sin) = (1..n.div_ceil(4))
        .map(|k| {
            let angle = step * k as f64;
            (angle.cos(), angle.sin())
        })
        .unzip();
    (fft, cos, sin)
}

/// A planned forward transform of `N` real values, with its buffers.
pub struct RealFft {
    fft: Arc<dyn Fft<f64>>,
    /// `½·e^{−2πik/N}` for `0 < k < ⌈N/4⌉`, real and imaginary parts.
    twiddle_re: Vec<f64>,
    twiddle_im: Vec<f64>,
    /// The real input, in pairs `(x[2m], x[2m + 1])`; then the FFT's output `Z`.
    pairs: Vec<Complex64>,
    z: Vec<Complex64>,
    scratch: Vec<Complex64>,
}

impl std::fmt::Debug for RealFft {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RealFft")
            .field("points", &self.points())
            .finish_non_exhaustive()
    }
}

impl RealFft {
    /// Plans the transform of `n` real values (even, at least 2).
    ///
    /// # Panics
    /// If `n` is odd or below 2.
    pub fn new(n: usize) -> Self {
        let (fft, cos, sin) = half_length_plan(n, false);
        RealFft {
            twiddle_re: cos.iter().map(|c| 0.5 * c).collect(),
            twiddle_im: sin.iter().map(|s| 0.5 * s).collect(),
            pairs: vec![Complex64::default(); n / 2],
            z: vec![Complex64::default(); n / 2],
            scratch: vec![Complex64::default(); fft.get_outofplace_scratch_len()],
            fft,
        }
    }

    /// `N`, the number of real values transformed.
    pub fn points(&self) -> usize {
        2 * self.pairs.len()
    }

    /// The `N` real values to transform. The transforms leave them unspecified: write
    /// all of them before each run.
    pub fn input(&mut self) -> &mut [f64] {
        bytemuck::cast_slice_mut(&mut self.pairs)
    }

    /// The half-length FFT `Z[0..M]` of the input's pairs, without the split pass, for
    /// callers that fuse the split with what they do next; and the split's twiddles
    /// `½·e^{−2πik/N}`, `0 < k < ⌈N/4⌉` (from `k = 1`), real and imaginary parts.
    #[inline(always)]
    pub fn transform(&mut self) -> (&[Complex64], (&[f64], &[f64])) {
        self.fft
            .process_outofplace_with_scratch(&mut self.pairs, &mut self.z, &mut self.scratch);
        (&self.z, (&self.twiddle_re, &self.twiddle_im))
    }

    /// Writes the spectrum `X[0..=M]` of the input, real parts into `re` and imaginary
    /// parts into `im`. Inlined so that its first pass gets the caller's vector width.
    ///
    /// # Panics
    /// If `re` or `im` does not hold `M + 1` values.
    #[inline(always)]
    pub fn run(&mut self, re: &mut [f64], im: &mut [f64]) {
        let m = self.pairs.len();
        assert!(
            re.len() == m + 1 && im.len() == m + 1,
            "the spectrum's first half, M + 1 values"
        );
        let (z, _) = self.transform();
        for ((r, i), z) in re.iter_mut().zip(im.iter_mut()).zip(z) {
            (*r, *i) = (z.re, z.im);
        }
        let (z0_re, z0_im) = (re[0], im[0]);
        (re[0], im[0]) = (z0_re + z0_im, 0.0);
        (re[m], im[m]) = (z0_re - z0_im, 0.0);
        // pairs (k, M − k) for 0 < k < M/2, and with M even X[M/2] = Z̄[M/2]
        let pairs = (m - 1) / 2;
        let (re_low, re_high) = re[1..m].split_at_mut(pairs);
        let (im_low, im_high) = im[1..m].split_at_mut(pairs);
        let middle = re_high.len() - pairs;
        if middle == 1 {
            im_high[0] = -im_high[0];
        }
        let (re_high, im_high) = (&mut re_high[middle..], &mut im_high[middle..]);
        split::<false>(
            (re_low, im_low),
            (re_high, im_high),
            (&self.twiddle_re[..pairs], &self.twiddle_im[..pairs]),
        );
    }
}

/// A planned inverse transform to `N` real values from the spectrum's first half, with
/// its buffers.
pub struct RealIfft {
    fft: Arc<dyn Fft<f64>>,
    /// `e^{2πik/N}` for `0 < k < ⌈N/4⌉`, real and imaginary parts.
    twiddle_re: Vec<f64>,
    twiddle_im: Vec<f64>,
    /// The spectrum `X[0..=M]`, real and imaginary parts; the merge pass overwrites it.
    re: Vec<f64>,
    im: Vec<f64>,
    /// The merged sequence, then the output in pairs `(x[2m], x[2m + 1])`.
    merged: Vec<Complex64>,
    pairs: Vec<Complex64>,
    scratch: Vec<Complex64>,
}

impl std::fmt::Debug for RealIfft {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RealIfft")
            .field("len", &(2 * self.pairs.len()))
            .finish_non_exhaustive()
    }
}

impl RealIfft {
    /// Plans the inverse to `n` real values (even, at least 2).
    ///
    /// # Panics
    /// If `n` is odd or below 2.
    pub fn new(n: usize) -> Self {
        let (fft, cos, sin) = half_length_plan(n, true);
        let m = n / 2;
        RealIfft {
            twiddle_re: cos,
            twiddle_im: sin.iter().map(|s| -s).collect(),
            re: vec![0.0; m + 1],
            im: vec![0.0; m + 1],
            merged: vec![Complex64::default(); m],
            pairs: vec![Complex64::default(); m],
            scratch: vec![Complex64::default(); fft.get_outofplace_scratch_len()],
            fft,
        }
    }

    /// The spectrum `X[0..=M]` to invert, real and imaginary parts (the imaginary parts
    /// of `X[0]` and `X[M]` are taken as 0). [`RealIfft::run`] leaves them unspecified:
    /// write all of them before each run.
    pub fn spectrum(&mut self) -> (&mut [f64], &mut [f64]) {
        (&mut self.re, &mut self.im)
    }

    /// The `N` real values of the inverse (unnormalised, as `realfft`'s: `N` times the
    /// inverse DFT). Inlined so that its passes get the caller's vector width.
    #[inline(always)]
    pub fn run(&mut self) -> &[f64] {
        let m = self.pairs.len();
        let (re, im) = (&mut self.re, &mut self.im);
        (im[0], im[m]) = (0.0, 0.0);
        let (sum_re, sum_im) = (re[0] + re[m], im[0] + im[m]);
        let (diff_re, diff_im) = (re[0] - re[m], im[0] - im[m]);
        (re[0], im[0]) = (sum_re - sum_im, diff_re - diff_im);
        // pairs (k, M − k) for 0 < k < M/2, and with M even X[M/2] doubled and conjugated
        let pairs = (m - 1) / 2;
        if m.is_multiple_of(2) && m >= 2 {
            let c = m / 2;
            (re[c], im[c]) = (re[c] + re[c], -(im[c] + im[c]));
        }
        let (re_low, re_high) = re[1..m].split_at_mut(pairs);
        let (im_low, im_high) = im[1..m].split_at_mut(pairs);
        let middle = re_high.len() - pairs;
        split::<true>(
            (re_low, im_low),
            (&mut re_high[middle..], &mut im_high[middle..]),
            (&self.twiddle_re[..pairs], &self.twiddle_im[..pairs]),
        );
        for ((z, r), i) in self.merged.iter_mut().zip(&re[..m]).zip(&im[..m]) {
            *z = Complex64::new(*r, *i);
        }
        self.fft.process_outofplace_with_scratch(
            &mut self.merged,
            &mut self.pairs,
            &mut self.scratch,
        );
        bytemuck::cast_slice(&self.pairs)
    }
}

crate::simd_kernel!(
    fma,
    /// The split pass (forward) or merge pass (`INVERSE`) over the pairs `(k, M − k)`,
    /// `0 < k < M/2`, in `realfft`'s order of operations: `low` holds the values of
    /// `k = 1` on, `high` those of `M − k` ending at `k = 1`, as real and imaginary parts,
    /// and both get the results in their place (the inverse's signs are the forward's
    /// negated, which changes no bit). A function of its own, with a version per vector
    /// width, so that its slices are known apart and the loop vectorises although `high`
    /// runs backwards.
    fn split<const INVERSE: bool>(
        (re_low, im_low): (&mut [f64], &mut [f64]),
        (re_high, im_high): (&mut [f64], &mut [f64]),
        (tw_re, tw_im): (&[f64], &[f64]),
    ) {
        let pairs = re_high.len();
        let (re_low, im_low) = (&mut re_low[..pairs], &mut im_low[..pairs]);
        let (im_high, tw_re, tw_im) = (&mut im_high[..pairs], &tw_re[..pairs], &tw_im[..pairs]);
        for i in 0..pairs {
            let j = pairs - 1 - i;
            let (x, y) = ((re_low[i], im_low[i]), (re_high[j], im_high[j]));
            let (low, high) = split_pair::<INVERSE>(x, y, (tw_re[i], tw_im[i]));
            ((re_low[i], im_low[i]), (re_high[j], im_high[j])) = (low, high);
        }
    }
);

/// One pair of the split pass: from `x` at `k`, `y` at `M − k` and the twiddle of `k` (real,
/// imaginary parts), the values at `k` and at `M − k`, in `realfft`'s order of
/// operations (the inverse's signs are the forward's negated, which changes no bit).
#[inline(always)]
pub fn split_pair<const INVERSE: bool>(
    (xr, xi): (f64, f64),
    (yr, yi): (f64, f64),
    (tw_re, tw_im): (f64, f64),
) -> ((f64, f64), (f64, f64)) {
    let (sum_re, sum_im) = (xr + yr, xi + yi);
    let (diff_re, diff_im) = (xr - yr, xi - yi);
    let t_re = sum_im * tw_re + diff_re * tw_im;
    let t_im = sum_im * tw_im - diff_re * tw_re;
    let (a, b, t_re, t_im) = match INVERSE {
        true => (sum_re, diff_im, -t_re, -t_im),
        false => (0.5 * sum_re, 0.5 * diff_im, t_re, t_im),
    };
    ((a + t_re, b + t_im), (a - t_re, t_im - b))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `len` values of a chirp whose start phase is `seed`: every bin non-zero.
    fn chirp(len: usize, seed: u64) -> Vec<f64> {
        (0..len)
            .map(|k| (seed as f64 + 0.37 * k as f64 + 0.011 * (k * k) as f64).sin())
            .collect()
    }

    #[test]
    fn transform_lengths_are_the_smallest_of_four_families() {
        // 2W − 1 at 16, 44.1 and 48 kHz (5·2^7, 7·2^8, 2^11), then 2^10 and 3·2^8
        // exactly, and one above 3·2^8 (7·2^7)
        let cases = [
            (639, 640),
            (1763, 1792),
            (1919, 2048),
            (1024, 1024),
            (768, 768),
            (769, 896),
        ];
        for (n, want) in cases {
            assert_eq!(fast_len(n), want, "{n}");
        }
    }

    fn spectrum(fft: &mut RealFft, x: &[f64]) -> Vec<Complex64> {
        fft.input().copy_from_slice(x);
        let (mut re, mut im) = (
            vec![f64::NAN; x.len() / 2 + 1],
            vec![f64::NAN; x.len() / 2 + 1],
        );
        fft.run(&mut re, &mut im);
        re.iter()
            .zip(&im)
            .map(|(r, i)| Complex64::new(*r, *i))
            .collect()
    }

    #[test]
    fn gives_realffts_spectrum_bit_for_bit() {
        for n in [2, 4, 6, 8, 10, 12, 64, 882, 1024, 2048] {
            let mut ours = RealFft::new(n);
            let theirs = afe_fft::real_forward(n);
            for seed in [n as u64, 1] {
                let x = chirp(n, seed);
                let got = spectrum(&mut ours, &x);
                let mut input = x.clone();
                let mut want = theirs.make_output_vec();
                theirs
                    .process(&mut input, &mut want)
                    .expect("lengths match");
                for (k, (g, w)) in got.iter().zip(&want).enumerate() {
                    assert_eq!(
                        (g.re.to_bits(), g.im.to_bits()),
                        (w.re.to_bits(), w.im.to_bits()),
                        "N = {n}, k = {k}: {g} vs {w}"
                    );
                }
            }
        }
    }

    #[test]
    fn matches_the_definition() {
        let n = 12;
        let x = chirp(n, 3);
        let mut fft = RealFft::new(n);
        assert_eq!(format!("{fft:?}"), "RealFft { points: 12, .. }");
        for (k, g) in spectrum(&mut fft, &x).iter().enumerate() {
            let want: Complex64 = x
                .iter()
                .enumerate()
                .map(|(t, v)| Complex64::from_polar(*v, -2.0 * PI * (k * t) as f64 / n as f64))
                .sum();
            assert!((g - want).norm() < 1e-13, "k = {k}: {g} vs {want}");
        }
    }

    #[test]
    fn inverts_as_realffts_inverse_bit_for_bit() {
        for n in [2, 4, 6, 8, 10, 12, 64, 882, 1792, 2048] {
            let mut ours = RealIfft::new(n);
            let theirs = afe_fft::real_inverse(n);
            for seed in [n as u64, 1] {
                let x = chirp(n + 2, seed);
                let spectrum: Vec<Complex64> = x
                    .chunks_exact(2)
                    .map(|p| Complex64::new(p[0], p[1]))
                    .collect();
                let (re, im) = ours.spectrum();
                for ((r, i), z) in re.iter_mut().zip(im.iter_mut()).zip(&spectrum) {
                    (*r, *i) = (z.re, z.im);
                }
                let got = ours.run().to_vec();
                let mut input = spectrum.clone();
                let mut want = vec![0.0; n];
                // the nonzero imaginary parts at 0 and N/2 are reported, and taken as 0
                let _ = theirs.process(&mut input, &mut want);
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&got), bits(&want), "N = {n}");
            }
        }
    }

    #[test]
    #[should_panic(expected = "an even length")]
    fn an_odd_length_is_refused() {
        RealFft::new(7);
    }
}
