//! The lead/lag analysis of one ear and frame (the end of spec 29's step A): the lag's
//! amplitude ratio and decay weight, and the two inverse filters, `S` and `L`, that remove
//! it. Apart from the model because it is arithmetic on one frame and a few constants,
//! tested on its own against the spec's formulas.

use afe_core::erb::linspace;

/// Copies of the frame summed by either inverse filter (`q = 0..5`).
pub(super) const TAPS: usize = 6;

/// The lead/lag estimate of one ear and frame and its two inverse filters.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct LagRemoval {
    /// Delay of the lag in samples.
    pub(super) tau: usize,
    /// Coefficients of `S`: `S[j] = Σ_q short[q]·x[j − qτ]`, `W + 5τ` samples.
    pub(super) short: [f64; TAPS],
    /// Coefficients of `L`: `L[j] = Σ_q long[q]·x[j + (6 − q)τ]`, `W − τ` samples.
    pub(super) long: [f64; TAPS],
}

impl LagRemoval {
    pub(super) fn new(tau: usize, b: f64, a: f64) -> Self {
        let mut short = [0.0; TAPS];
        let mut long = [0.0; TAPS];
        for q in 0..TAPS {
            short[q] = (-b * a).powi(q as i32);
            let sign = if q % 2 == 0 { -1.0 } else { 1.0 };
            long[q] = sign * b.powi((TAPS - q) as i32) * a.powi((TAPS - 1 - q) as i32);
        }
        LagRemoval { tau, short, long }
    }

    /// Length of the `S` (`long = false`) or `L` signal of a `w`-sample frame.
    pub(super) fn len(&self, long: bool, w: usize) -> usize {
        if long {
            w - self.tau
        } else {
            w + 5 * self.tau
        }
    }

    /// The `S` or `L` signal of frame `x` into `out` (its length).
    pub(super) fn apply(&self, long: bool, x: &[f64], out: &mut [f64]) {
        if long {
            deconv_long(x, self.tau, &self.long, out);
        } else {
            deconv_short(x, self.tau, &self.short, out);
        }
    }
}

/// `S[j] = Σ_q c[q]·x[j − qτ]` over `0 ≤ j < len(x) + 5τ`, summed in the order of `q`.
fn deconv_short(x: &[f64], tau: usize, c: &[f64; TAPS], out: &mut [f64]) {
    out.fill(0.0);
    for (q, &cq) in c.iter().enumerate() {
        let dst = &mut out[q * tau..q * tau + x.len()];
        for (o, v) in dst.iter_mut().zip(x) {
            *o += v * cq;
        }
    }
}

/// `L[j] = Σ_q g[q]·x[j + (6 − q)τ]` over `0 ≤ j < len(x) − τ` (`x` zero beyond its end),
/// summed in the order of `q`.
fn deconv_long(x: &[f64], tau: usize, g: &[f64; TAPS], out: &mut [f64]) {
    out.fill(0.0);
    for (q, &gq) in g.iter().enumerate() {
        let shift = (TAPS - q) * tau;
        if shift < x.len() {
            for (o, v) in out.iter_mut().zip(&x[shift..]) {
                *o += v * gq;
            }
        }
    }
}

/// `peakRatio(q)`: the smallest `b` of the grid `0, 0.01, …, 1` with `b/(1 + b²) ≥ q`,
/// `q` clamped to `[0, 0.5]`; a NaN ratio (silent first frame, where the AFE stops with
/// an error) gives 0.
pub(super) fn peak_ratio(q: f64) -> f64 {
    if q.is_nan() {
        return 0.0;
    }
    let q = q.clamp(0.0, 0.5);
    (0..=100)
        .map(|k| k as f64 * 0.01)
        .find(|b| b / (1.0 + b * b) >= q)
        .unwrap_or(1.0)
}

/// The decay weight table `a(τ)` at index `τ − 1`: 1 up to `6·Fr`, then
/// `linspace(1, 0, 14·Fr)⁴` up to `20·Fr`, then 0, `100·Fr` entries.
pub(super) fn decay_table(fr: usize) -> Vec<f64> {
    let mut a = vec![0.0; 100 * fr];
    a[..6 * fr].fill(1.0);
    for (d, v) in a[6 * fr..20 * fr]
        .iter_mut()
        .zip(linspace(1.0, 0.0, 14 * fr))
    {
        *d = v.powi(4);
    }
    a
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::noise;

    #[test]
    fn peak_ratio_is_the_first_grid_point_reaching_the_ratio() {
        assert_eq!(peak_ratio(0.0), 0.0);
        assert_eq!(peak_ratio(-1.0), 0.0);
        assert_eq!(peak_ratio(f64::NAN), 0.0);
        assert_eq!(peak_ratio(0.5), 1.0);
        assert_eq!(peak_ratio(3.0), 1.0);
        assert_eq!(peak_ratio(0.3), 0.34);
        for i in 1..500 {
            let q = i as f64 / 1000.0;
            let b = peak_ratio(q);
            let k = (b / 0.01).round();
            assert_eq!(b, k * 0.01, "{q}: {b} is on the grid");
            assert!(b / (1.0 + b * b) >= q, "{q}: {b} reaches the ratio");
            let below = (k - 1.0) * 0.01;
            assert!(
                below / (1.0 + below * below) < q,
                "{q}: {below} already does"
            );
        }
    }

    #[test]
    fn deconvolutions_follow_the_direct_formulas() {
        let (d, tau, b, a) = (50, 7, 0.6, 0.8);
        let x = noise(d, 3);
        let lag = LagRemoval::new(tau, b, a);
        // S = x + Σ_{q=1..5} x·(−B·a)^q shifted by qτ
        let mut want = vec![0.0; d + 5 * tau];
        for q in 0..6 {
            for (n, v) in x.iter().enumerate() {
                want[q * tau + n] += v * (-b * a).powi(q as i32);
            }
        }
        let mut got = vec![0.0; lag.len(false, d)];
        lag.apply(false, &x, &mut got);
        assert_eq!(got, want);
        // Y = Σ_{q=0..5} (−1)^(q+1)·x·B^(6−q)·a^(5−q) shifted by qτ; L = Y[6τ..D+5τ)
        let mut y = vec![0.0; d + 5 * tau];
        for q in 0..6 {
            let coef = (-1f64).powi(q as i32 + 1) * b.powi(6 - q as i32) * a.powi(5 - q as i32);
            for (n, v) in x.iter().enumerate() {
                y[q * tau + n] += v * coef;
            }
        }
        let mut got = vec![0.0; lag.len(true, d)];
        lag.apply(true, &x, &mut got);
        assert_eq!(got.len(), d - tau);
        for (g, w) in got.iter().zip(&y[6 * tau..]) {
            assert!((g - w).abs() <= 1e-15, "{g} vs {w}");
        }
    }

    #[test]
    fn decay_weights_fall_from_6_to_20_ms() {
        let a = decay_table(16);
        assert_eq!(a.len(), 1600);
        assert_eq!((a[0], a[6 * 16 - 1], a[6 * 16]), (1.0, 1.0, 1.0));
        assert_eq!((a[20 * 16 - 1], a[20 * 16]), (0.0, 0.0));
        assert!(a[6 * 16..20 * 16].windows(2).all(|p| p[1] < p[0]));
    }
}
