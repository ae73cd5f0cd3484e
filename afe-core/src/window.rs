//! Window functions by MATLAB name (spec 01-P3): symmetric, built as a first half mirrored.

use std::f64::consts::PI;

crate::choices! {
    /// A window accepted by the `*_wname` parameters, by its MATLAB name.
    pub enum Window {
        /// Raised cosine with zero ends.
        Hann = "hann",
        /// MATLAB's `hanning`: the Hann window without its zero ends.
        Hanning = "hanning",
        /// Raised cosine on a 0.08 pedestal.
        Hamming = "hamming",
        /// All ones.
        Rectwin = "rectwin",
        /// Three-term cosine window with zero ends.
        Blackman = "blackman",
        /// Triangle without zero ends.
        Triang = "triang",
        /// Triangle with zero ends.
        Bartlett = "bartlett",
    }
}

/// The symmetric window `shape` of length `n`.
pub fn window(shape: Window, n: usize) -> Vec<f64> {
    let half_mirrored = |f: &dyn Fn(f64) -> f64| {
        let half = n.div_ceil(2);
        let mut w: Vec<f64> = (0..half).map(|k| f(k as f64)).collect();
        let mirror: Vec<f64> = w[..n / 2].iter().rev().copied().collect();
        w.extend(mirror);
        w
    };
    let denom = (n as f64 - 1.0).max(1.0);
    match shape {
        _ if n == 1 && shape != Window::Hanning => vec![1.0],
        Window::Rectwin => vec![1.0; n],
        Window::Hann => half_mirrored(&|k| 0.5 - 0.5 * (2.0 * PI * (k / denom)).cos()),
        Window::Hanning => {
            half_mirrored(&|k| 0.5 * (1.0 - (2.0 * PI * (k + 1.0) / (n as f64 + 1.0)).cos()))
        }
        Window::Hamming => half_mirrored(&|k| 0.54 - 0.46 * (2.0 * PI * (k / denom)).cos()),
        Window::Blackman => half_mirrored(&|k| {
            let x = k / denom;
            0.42 - 0.5 * (2.0 * PI * x).cos() + 0.08 * (4.0 * PI * x).cos()
        }),
        Window::Triang => half_mirrored(&|k| {
            if n % 2 == 1 {
                2.0 * (k + 1.0) / (n as f64 + 1.0)
            } else {
                (2.0 * k + 1.0) / n as f64
            }
        }),
        Window::Bartlett => half_mirrored(&|k| 1.0 - (2.0 * k / denom - 1.0).abs()),
    }
}

/// The periodic Hamming window of length `n` (MATLAB `hamming(n, 'periodic')`, spec
/// zz-numerics N5): the first `n` samples of the symmetric window of length `n + 1`,
/// `0.54 − 0.46·cos(2πk/n)`, its second half mirrored from the first as MATLAB builds it.
pub fn hamming_periodic(n: usize) -> Vec<f64> {
    (0..n)
        .map(|k| 0.54 - 0.46 * (2.0 * PI * (k.min(n - k) as f64 / n as f64)).cos())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hann_has_zero_ends_and_is_symmetric() {
        let w = window(Window::Hann, 8);
        assert_eq!(w.len(), 8);
        assert_eq!(w[0], 0.0);
        assert_eq!(w[7], 0.0);
        for k in 0..8 {
            assert_eq!(w[k], w[7 - k]);
            let f = 0.5 * (1.0 - (2.0 * PI * k as f64 / 7.0).cos());
            assert!((w[k] - f).abs() < 1e-15);
        }
    }

    #[test]
    fn odd_lengths_and_other_shapes() {
        let w = window(Window::Triang, 5);
        assert_eq!(w, vec![1.0 / 3.0, 2.0 / 3.0, 1.0, 2.0 / 3.0, 1.0 / 3.0]);
        let w = window(Window::Bartlett, 5);
        assert_eq!(w, vec![0.0, 0.5, 1.0, 0.5, 0.0]);
        let w = window(Window::Hanning, 3);
        assert!((w[0] - 0.5).abs() < 1e-15 && (w[1] - 1.0).abs() < 1e-15);
        assert_eq!(window(Window::Hamming, 1), vec![1.0]);
    }

    /// MATLAB's values, from the definitions (spec 01-P3) evaluated by hand.
    #[test]
    fn blackman_hamming_and_even_lengths_have_matlabs_values() {
        let cases: [(Window, usize, &[f64]); 5] = [
            (
                Window::Blackman,
                7,
                &[0.0, 0.13, 0.63, 1.0, 0.63, 0.13, 0.0],
            ),
            (Window::Hamming, 5, &[0.08, 0.54, 1.0, 0.54, 0.08]),
            (Window::Triang, 4, &[0.25, 0.75, 0.75, 0.25]),
            (Window::Bartlett, 4, &[0.0, 2.0 / 3.0, 2.0 / 3.0, 0.0]),
            (Window::Rectwin, 3, &[1.0, 1.0, 1.0]),
        ];
        for (name, n, want) in cases {
            let w = window(name, n);
            assert_eq!(w.len(), n, "{name}");
            for (k, (v, x)) in w.iter().zip(want).enumerate() {
                assert!((v - x).abs() < 1e-15, "{name}({n})[{k}] = {v}, want {x}");
            }
        }
    }

    #[test]
    fn periodic_hamming_is_the_symmetric_one_of_length_n_plus_1_truncated() {
        for n in [1, 2, 7, 882] {
            let w = hamming_periodic(n);
            let s = window(Window::Hamming, n + 1);
            assert_eq!(w[..], s[..n], "length {n}");
            for (k, v) in w.iter().enumerate() {
                let f = 0.54 - 0.46 * (2.0 * PI * k as f64 / n as f64).cos();
                assert!((v - f).abs() < 1e-15);
            }
        }
    }
}
