//! The peak of a cross-correlation function, read by the binaural cues built on it: the
//! ITD takes its lag, the IC its height (spec 19-itd, 20-ic).

use afe_core::{Result, SignalInfo, SignalKind};

/// Peak of a correlation function: `(index, δ)` with the first maximum (NaN ignored, as
/// MATLAB's `max`) and the parabolic offset δ (0 at the lag-range edges).
pub(crate) fn parabolic_peak(y: &[f64]) -> (usize, f64, f64) {
    // The largest non-NaN value (f64::max skips NaN), then its first position; all-NaN
    // gives index 0.
    let top = y.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let i = y.iter().position(|v| *v == top).unwrap_or(0);
    if i > 0 && i + 1 < y.len() {
        let (yl, yc, yu) = (y[i - 1], y[i], y[i + 1]);
        let delta = 0.5 * (yl - yu) / (yl - 2.0 * yc + yu);
        (i, delta, yc - 0.25 * (yl - yu) * delta)
    } else {
        (i, 0.0, y[i])
    }
}

/// Checks that a binaural cue is built on a correlation signal.
pub(crate) fn correlation_input(input: &SignalInfo, what: &str) -> Result<()> {
    if input.kind != SignalKind::Correlation || input.lags_s().is_empty() {
        return Err(afe_core::Error::InvalidInput(format!(
            "{what} needs a cross-correlation input"
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parabola_vertex_and_edges() {
        let (i, d, v) = parabolic_peak(&[0.0, 1.0, 0.5]);
        assert_eq!(i, 1);
        // parabola through (−1, 0), (0, 1), (1, 0.5): δ = 0.5·(−0.5)/(−1.5) = 1/6
        assert!((d - 1.0 / 6.0).abs() < 1e-15);
        assert!((v - (1.0 + 0.25 * 0.5 / 6.0)).abs() < 1e-15);
        assert_eq!(parabolic_peak(&[3.0, 1.0, 2.0]), (0, 0.0, 3.0));
        assert_eq!(parabolic_peak(&[f64::NAN, 1.0, 2.0]).0, 2);
        assert!(parabolic_peak(&[0.0, 1.0, 1.0, 1.0, 0.0]).1.is_finite());
        assert!(parabolic_peak(&[1.0, 1.0, 1.0]).0 == 0);
    }
}
