//! Analytic signal by FFT over the whole input, as MATLAB's `hilbert` (spec 01-P5).

use std::sync::Arc;

use afe_fft::Fft;
use num_complex::Complex64;

/// The forward and inverse transforms of one length.
struct Plans {
    n: usize,
    forward: Arc<dyn Fft<f64>>,
    inverse: Arc<dyn Fft<f64>>,
}

/// Computes analytic signals of arbitrary lengths, reusing plans and buffers.
pub struct Hilbert {
    /// The plans of the last length.
    plans: Option<Plans>,
    buf: Vec<Complex64>,
    scratch: Vec<Complex64>,
}

impl std::fmt::Debug for Hilbert {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Hilbert").finish_non_exhaustive()
    }
}

impl Default for Hilbert {
    fn default() -> Self {
        Self::new()
    }
}

impl Hilbert {
    /// A transformer with no plan yet.
    pub fn new() -> Self {
        Hilbert {
            plans: None,
            buf: Vec::new(),
            scratch: Vec::new(),
        }
    }

    /// The analytic signal of `x` (no padding): `ifft(fft(x)·h)`. The result stays valid
    /// until the next call.
    pub fn analytic(&mut self, x: impl ExactSizeIterator<Item = f64>) -> &[Complex64] {
        let n = x.len();
        self.buf.clear();
        self.buf.extend(x.map(|v| Complex64::new(v, 0.0)));
        if n == 0 {
            return &self.buf;
        }
        let plans = match self.plans.take() {
            Some(plans) if plans.n == n => plans,
            _ => Plans {
                n,
                forward: afe_fft::forward(n),
                inverse: afe_fft::inverse(n),
            },
        };
        let (fwd, inv) = (&plans.forward, &plans.inverse);
        let need = fwd
            .get_inplace_scratch_len()
            .max(inv.get_inplace_scratch_len());
        self.scratch.resize(need, Complex64::new(0.0, 0.0));
        fwd.process_with_scratch(&mut self.buf, &mut self.scratch);
        // h: 1 at DC (and at n/2 for even n), 2 on positive frequencies, 0 on negative ones.
        let positive_end = n.div_ceil(2);
        for v in &mut self.buf[1..positive_end] {
            *v *= 2.0;
        }
        let zero_from = n / 2 + 1;
        for v in &mut self.buf[zero_from.min(n)..] {
            *v = Complex64::new(0.0, 0.0);
        }
        inv.process_with_scratch(&mut self.buf, &mut self.scratch);
        self.plans = Some(plans);
        let scale = 1.0 / n as f64;
        for v in &mut self.buf {
            *v *= scale;
        }
        &self.buf
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn envelope_of_a_whole_period_cosine_is_flat() {
        let n = 64;
        let x: Vec<f64> = (0..n)
            .map(|i| (2.0 * PI * 4.0 * i as f64 / n as f64).cos())
            .collect();
        let mut h = Hilbert::new();
        let a = h.analytic(x.iter().copied());
        for (i, v) in a.iter().enumerate() {
            assert!((v.re - x[i]).abs() < 1e-12);
            assert!((v.norm() - 1.0).abs() < 1e-12);
        }
        // odd length too
        let a = h.analytic([1.0, 2.0, 3.0].into_iter());
        assert!((a[0].re - 1.0).abs() < 1e-12 && (a[2].re - 3.0).abs() < 1e-12);
    }
}
