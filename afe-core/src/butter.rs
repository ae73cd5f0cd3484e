//! Digital Butterworth design by the bilinear transform (spec 01-P2), as MATLAB's `butter`.

use std::f64::consts::PI;

use rustfft::num_complex::Complex64;

/// The response type of a Butterworth design.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ButterType {
    /// Low-pass, one cut-off.
    Low,
    /// High-pass, one cut-off.
    High,
    /// Band-pass between two cut-offs (order doubles).
    BandPass,
    /// Band-stop between two cut-offs (order doubles).
    BandStop,
}

/// Transfer-function coefficients `(b, a)` of an `order`-th Butterworth filter.
///
/// `wn` holds the cut-off(s) normalised to Nyquist, each in (0, 1): one value for
/// low/high-pass, two increasing values for band-pass/stop. The gain is exactly unity at
/// DC (low-pass, band-stop), Nyquist (high-pass) or the band centre (band-pass).
///
/// # Panics
/// If `order` is 0 or `wn` has the wrong length; callers validate user input first.
pub fn butter(order: usize, wn: &[f64], kind: ButterType) -> (Vec<f64>, Vec<f64>) {
    assert!(order > 0, "Butterworth order must be positive");
    let n = order;
    let warp = |w: f64| 4.0 * (PI * w / 2.0).tan();
    let proto: Vec<Complex64> = (1..=n)
        .map(|k| {
            let angle = PI * (2 * k + n - 1) as f64 / (2 * n) as f64;
            Complex64::new(angle.cos(), angle.sin())
        })
        .collect();
    let one = Complex64::new(1.0, 0.0);
    let (poles, zeros, w_norm): (Vec<Complex64>, Vec<Complex64>, f64) = match kind {
        ButterType::Low => {
            assert_eq!(wn.len(), 1);
            let u = warp(wn[0]);
            (proto.iter().map(|p| p * u).collect(), vec![-one; n], 0.0)
        }
        ButterType::High => {
            assert_eq!(wn.len(), 1);
            let u = warp(wn[0]);
            (proto.iter().map(|p| u / p).collect(), vec![one; n], PI)
        }
        ButterType::BandPass | ButterType::BandStop => {
            assert_eq!(wn.len(), 2);
            let (u1, u2) = (warp(wn[0]), warp(wn[1]));
            let wo = (u1 * u2).sqrt();
            let bw = u2 - u1;
            let mut poles = Vec::with_capacity(2 * n);
            for p in &proto {
                let q = if kind == ButterType::BandPass {
                    p * bw
                } else {
                    bw / p
                };
                let r = (q * q - 4.0 * wo * wo).sqrt();
                poles.push((q + r) / 2.0);
                poles.push((q - r) / 2.0);
            }
            if kind == ButterType::BandPass {
                let mut zeros = vec![one; n];
                zeros.extend(std::iter::repeat_n(-one, n));
                (poles, zeros, 2.0 * (wo / 4.0).atan())
            } else {
                let zpos = bilinear(Complex64::new(0.0, wo));
                let mut zeros = vec![zpos; n];
                zeros.extend(std::iter::repeat_n(zpos.conj(), n));
                (poles, zeros, 0.0)
            }
        }
    };
    let zpoles: Vec<Complex64> = poles.into_iter().map(bilinear).collect();
    let a = real_poly(&zpoles);
    let b0 = real_poly(&zeros);
    // Unity gain at w_norm: Re(A/B0) there, evaluated from the roots (∏(1 − r·e^{−iw})),
    // which stays accurate where the expanded polynomial cancels (clustered poles at DC).
    let e = Complex64::new(0.0, -w_norm).exp();
    let from_roots = |roots: &[Complex64]| {
        roots
            .iter()
            .fold(Complex64::new(1.0, 0.0), |acc, r| acc * (1.0 - r * e))
    };
    let gain = (from_roots(&zpoles) / from_roots(&zeros)).re;
    (b0.iter().map(|v| v * gain).collect(), a)
}

/// The bilinear map `z = (4 + s)/(4 − s)` (sampling period 1/2).
fn bilinear(s: Complex64) -> Complex64 {
    (4.0 + s) / (4.0 - s)
}

/// Real part of the monic polynomial with the given roots, highest power first.
fn real_poly(roots: &[Complex64]) -> Vec<f64> {
    let mut c = vec![Complex64::new(1.0, 0.0)];
    for r in roots {
        c.push(Complex64::new(0.0, 0.0));
        for k in (1..c.len()).rev() {
            let prev = c[k - 1];
            c[k] -= r * prev;
        }
    }
    c.into_iter().map(|v| v.re).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn response(b: &[f64], a: &[f64], w: f64) -> f64 {
        let e = Complex64::new(0.0, -w).exp();
        let ev = |c: &[f64]| {
            c.iter()
                .rev()
                .fold(Complex64::new(0.0, 0.0), |acc, &v| acc * e + v)
        };
        (ev(b) / ev(a)).norm()
    }

    #[test]
    fn lowpass_is_half_power_at_cutoff() {
        let (b, a) = butter(2, &[1000.0 / 22050.0], ButterType::Low);
        assert!((response(&b, &a, 0.0) - 1.0).abs() < 1e-12);
        let wc = PI * 1000.0 / 22050.0;
        assert!((response(&b, &a, wc) - 0.5f64.sqrt()).abs() < 1e-9);
    }

    #[test]
    fn highpass_and_bands_have_unity_gain_where_promised() {
        let (b, a) = butter(4, &[20.0 / 22050.0], ButterType::High);
        assert!((response(&b, &a, PI) - 1.0).abs() < 1e-12);
        // 4th order at half the cut-off: 1/sqrt(1 + 2^8) (bilinear warping is negligible
        // this far below Nyquist; evaluating clustered coefficients near DC costs digits)
        let r = response(&b, &a, 2.0 * PI * 10.0 / 44100.0);
        assert!((r - 1.0 / 257f64.sqrt()).abs() < 1e-4, "{r}");
        let (b, a) = butter(3, &[0.1, 0.3], ButterType::BandPass);
        assert_eq!(a.len(), 7);
        assert!(response(&b, &a, 0.0) < 1e-12 && response(&b, &a, PI) < 1e-12);
        let (b, a) = butter(2, &[0.1, 0.3], ButterType::BandStop);
        assert!((response(&b, &a, 0.0) - 1.0).abs() < 1e-12);
        assert!((response(&b, &a, PI) - 1.0).abs() < 1e-9);
    }
}
