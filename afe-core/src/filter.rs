//! Direct-form II transposed IIR filtering over time-major multichannel blocks.
//!
//! The recursion and its evaluation order are those of the reference (spec 01-P1):
//! `y = z0 + b0·x`, `z[i] = (z[i+1] − a[i+1]·y) + b[i+1]·x`, `z[m−1] = b[m]·x − a[m]·y`.
//! The order matters bit for bit on pole-clustered designs, so keep it.

/// A real DF2T filter applied independently to every channel of a time-major block.
#[derive(Debug, Clone, PartialEq)]
pub struct Df2t {
    b: Vec<f64>,
    a: Vec<f64>,
    channels: usize,
    /// State, `[order][channels]` so that the inner loop runs across channels.
    z: Vec<f64>,
}

impl Df2t {
    /// A filter with numerator `b` and denominator `a` (normalised by `a[0]`), for
    /// `channels` independent channels, with zero initial state.
    ///
    /// # Panics
    /// If `b` or `a` is empty or `a[0]` is zero.
    pub fn new(b: &[f64], a: &[f64], channels: usize) -> Self {
        assert!(
            !b.is_empty() && !a.is_empty() && a[0] != 0.0,
            "invalid filter"
        );
        let m = b.len().max(a.len());
        let mut bn = vec![0.0; m];
        let mut an = vec![0.0; m];
        for (d, s) in bn.iter_mut().zip(b) {
            *d = s / a[0];
        }
        for (d, s) in an.iter_mut().zip(a) {
            *d = s / a[0];
        }
        Df2t {
            b: bn,
            a: an,
            channels,
            z: vec![0.0; (m - 1) * channels],
        }
    }

    /// Filter order (number of states per channel).
    pub fn order(&self) -> usize {
        self.b.len() - 1
    }

    /// Filters `data` (time-major, `channels` values per row) in place, carrying state.
    pub fn process(&mut self, data: &mut [f64]) {
        let nc = self.channels;
        let m = self.order();
        let b = &self.b;
        let a = &self.a;
        for row in data.chunks_exact_mut(nc) {
            if m == 0 {
                for x in row.iter_mut() {
                    *x *= b[0];
                }
                continue;
            }
            for (c, x) in row.iter_mut().enumerate() {
                let xin = *x;
                let y = self.z[c] + b[0] * xin;
                for i in 0..m - 1 {
                    self.z[i * nc + c] = (self.z[(i + 1) * nc + c] - a[i + 1] * y) + b[i + 1] * xin;
                }
                self.z[(m - 1) * nc + c] = b[m] * xin - a[m] * y;
                *x = y;
            }
        }
    }

    /// Zeroes the state.
    pub fn reset(&mut self) {
        self.z.fill(0.0);
    }

    /// Sets every channel's first state to `value` (the other states are zeroed); used to
    /// seed one-pole smoothers.
    pub fn set_first_state(&mut self, channel: usize, value: f64) {
        for i in 0..self.order() {
            self.z[i * self.channels + channel] = 0.0;
        }
        if self.order() > 0 {
            self.z[channel] = value;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Direct evaluation of the difference equation, as an independent check.
    fn difference_equation(b: &[f64], a: &[f64], x: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; x.len()];
        for n in 0..x.len() {
            let mut acc = 0.0;
            for (k, bk) in b.iter().enumerate() {
                if n >= k {
                    acc += bk * x[n - k];
                }
            }
            for (k, ak) in a.iter().enumerate().skip(1) {
                if n >= k {
                    acc -= ak * y[n - k];
                }
            }
            y[n] = acc / a[0];
        }
        y
    }

    #[test]
    fn matches_difference_equation_and_is_chunk_invariant() {
        let b = [0.2, 0.3, -0.1];
        let a = [1.0, -0.5, 0.25];
        let x: Vec<f64> = (0..50).map(|i| ((i * 7919) % 13) as f64 - 6.0).collect();
        let want = difference_equation(&b, &a, &x);
        // two channels: the second carries the same signal scaled by 2
        let mut data: Vec<f64> = x.iter().flat_map(|v| [*v, 2.0 * v]).collect();
        let mut f = Df2t::new(&b, &a, 2);
        let (first, second) = data.split_at_mut(2 * 17);
        f.process(first);
        f.process(second);
        for (n, w) in want.iter().enumerate() {
            assert!((data[2 * n] - w).abs() < 1e-12);
            assert!((data[2 * n + 1] - 2.0 * w).abs() < 1e-12);
        }
    }

    #[test]
    fn reset_restores_zero_state() {
        let mut f = Df2t::new(&[1.0], &[1.0, -0.9], 1);
        let mut x = vec![1.0, 0.0, 0.0];
        f.process(&mut x);
        f.reset();
        let mut y = vec![1.0, 0.0, 0.0];
        f.process(&mut y);
        assert_eq!(y, vec![1.0, 0.9, 0.9 * 0.9]);
    }
}
