//! Test support shared by the processors' tests: feeding a processor its input in
//! chunks as a stream would, deterministic noise, and a plain DFT to check FFTs against.

use afe_core::{Block, Processor};
use num_complex::Complex64;
use std::f64::consts::PI;

/// Runs `p` over `x` (rows of `width` values) cut into chunks of the row counts that
/// `chunks` yields, until the input is used up (a chunk may be empty), and returns its
/// outputs (`out_width` values per row) joined.
pub(crate) fn feed<P: Processor>(
    p: &mut P,
    x: &[f64],
    width: usize,
    out_width: usize,
    chunks: impl IntoIterator<Item = usize>,
) -> Vec<f64> {
    let rows = x.len() / width;
    let mut out = vec![Block::new(out_width)];
    let mut all = Vec::new();
    let mut start = 0;
    for n in chunks {
        if start >= rows {
            break;
        }
        let end = start.saturating_add(n).min(rows);
        let block = Block::from_vec(x[start * width..end * width].to_vec(), width);
        p.process(&[&block], &mut out);
        all.extend_from_slice(out[0].as_slice());
        start = end;
    }
    all
}

/// Deterministic white noise in [−0.5, 0.5): `len` values of a xorshift generator whose
/// state starts from `seed` (any seed, 0 included, gives a full-period sequence).
pub(crate) fn noise(len: usize, seed: u64) -> Vec<f64> {
    let mut state = seed.wrapping_mul(6_364_136_223_846_793_005) | 1;
    (0..len)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        })
        .collect()
}

/// The `nfft`-point DFT of the real `x` (zero-padded, `x.len() ≤ nfft`), each bin summed
/// term by term from exactly reduced phases: a slow reference that shares nothing with
/// an FFT library. The Nyquist bin is exactly real, as a real FFT gives it.
pub(crate) fn plain_dft(x: &[f64], nfft: usize) -> Vec<Complex64> {
    assert!(
        x.len() <= nfft,
        "{} samples do not fit {nfft} points",
        x.len()
    );
    let mut spectrum: Vec<Complex64> = (0..nfft)
        .map(|k| {
            x.iter()
                .enumerate()
                .map(|(n, &v)| {
                    let phase = -2.0 * PI * ((k * n) % nfft) as f64 / nfft as f64;
                    Complex64::from_polar(v, phase)
                })
                .sum()
        })
        .collect();
    if nfft.is_multiple_of(2) {
        spectrum[nfft / 2].im = 0.0;
    }
    spectrum
}
