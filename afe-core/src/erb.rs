//! The ERB-number scale of Glasberg & Moore (1990), as the AFE evaluates it.

/// ERB number of frequency `f_hz`: `9.265·ln(1 + f/(24.7·9.265))`.
pub fn freq2erb(f_hz: f64) -> f64 {
    9.265 * (1.0 + f_hz / (24.7 * 9.265)).ln()
}

/// Frequency in Hz of ERB number `erb`: `24.7·9.265·(exp(e/9.265) − 1)`.
pub fn erb2freq(erb: f64) -> f64 {
    24.7 * 9.265 * ((erb / 9.265).exp() - 1.0)
}

/// Equivalent rectangular bandwidth at `f_hz`, in Hz: `24.7 + 0.108·f`.
pub fn erb_bandwidth(f_hz: f64) -> f64 {
    24.7 + 0.108 * f_hz
}

/// `n` points from `a` to `b` inclusive, built symmetrically as Octave 7 does
/// (spec 01-P15); `n = 1` gives `[b]`.
pub fn linspace(a: f64, b: f64, n: usize) -> Vec<f64> {
    if n == 0 {
        return Vec::new();
    }
    if n == 1 {
        return vec![b];
    }
    let delta = (b - a) / (n - 1) as f64;
    let mut y = vec![0.0; n];
    y[0] = a;
    y[n - 1] = b;
    for i in 1..n / 2 {
        y[i] = a + i as f64 * delta;
        y[n - 1 - i] = b - i as f64 * delta;
    }
    if n % 2 == 1 {
        y[n / 2] = if a == -b { 0.0 } else { (a + b) / 2.0 };
    }
    y
}

/// The colon range `a:d:b` evaluated as Octave does: `a + k·d` while `≤ b`
/// (with Octave's few-ulp tolerance on the element count).
pub fn colon_range(a: f64, d: f64, b: f64) -> Vec<f64> {
    if d.is_nan() || d <= 0.0 || b < a {
        return Vec::new();
    }
    let count = ((b - a) / d * (1.0 + 3.0 * f64::EPSILON)).floor() as usize + 1;
    (0..count).map(|k| a + k as f64 * d).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn erb_round_trip() {
        for f in [80.0, 1000.0, 8000.0] {
            assert!((erb2freq(freq2erb(f)) - f).abs() < 1e-9 * f);
        }
        assert!((freq2erb(80.0) - 2.77759).abs() < 1e-5);
    }

    #[test]
    fn linspace_is_symmetric_and_exact_at_ends() {
        let y = linspace(1.0, 2.0, 5);
        assert_eq!(y, vec![1.0, 1.25, 1.5, 1.75, 2.0]);
        assert_eq!(linspace(3.0, 7.0, 1), vec![7.0]);
    }

    #[test]
    fn colon_range_includes_end_within_tolerance() {
        assert_eq!(colon_range(0.0, 0.1, 0.3).len(), 4);
        assert_eq!(colon_range(1.0, 1.0, 3.5), vec![1.0, 2.0, 3.0]);
        assert_eq!(colon_range(0.0, 0.5, 2.0), vec![0.0, 0.5, 1.0, 1.5, 2.0]);
        assert_eq!(colon_range(1.0, 0.5, 1.0), vec![1.0]);
    }

    #[test]
    fn an_empty_colon_range_needs_no_step_or_a_reversed_span() {
        for (a, d, b) in [
            (0.0, f64::NAN, 1.0),
            (0.0, 0.0, 1.0),
            (0.0, -0.5, 1.0),
            (1.0, 0.5, 0.0),
        ] {
            assert!(colon_range(a, d, b).is_empty(), "{a}:{d}:{b}");
        }
    }

    #[test]
    fn bandwidth_is_glasberg_and_moores() {
        assert_eq!(erb_bandwidth(0.0), 24.7);
        assert!((erb_bandwidth(1000.0) - 132.7).abs() < 1e-12);
    }

    #[test]
    fn a_constant_linspace_keeps_its_middle() {
        assert_eq!(linspace(2.0, 2.0, 3), vec![2.0; 3]);
        assert_eq!(linspace(-1.0, 1.0, 3), vec![-1.0, 0.0, 1.0]);
        assert!(linspace(0.0, 1.0, 0).is_empty());
    }
}
