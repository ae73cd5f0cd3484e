//! Digital Butterworth design by the bilinear transform (spec 01-P2), as MATLAB's `butter`.

use std::f64::consts::PI;

use num_complex::Complex64;

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
    let (zeros, zpoles, w_norm) = butter_zpk(order, wn, kind);
    let a = real_poly(&zpoles);
    let b0 = real_poly(&zeros);
    // Unity gain at w_norm: Re(A/B0) there, evaluated from the roots (∏(1 − r·e^{−iw})),
    // which stays accurate where the expanded polynomial cancels (clustered poles at DC).
    let gain = (response_from_roots(&zpoles, w_norm) / response_from_roots(&zeros, w_norm)).re;
    (b0.iter().map(|v| v * gain).collect(), a)
}

/// [`butter`]'s design as filters `(b, a)` to run in series: its transfer function
/// alone where that is stable and accurate, its second-order sections ([`butter_sos`])
/// elsewhere.
///
/// The transfer function is the AFE's form (MATLAB runs `filter(b, a)`; the oracle's
/// DC-removal high-pass, 4th order at 20 Hz, is reproduced by it and the DF2T to a few
/// 1e−7, spec zz-numerics N3). Its expanded denominator loses clustered poles to
/// round-off: a 4th-order high-pass at 1 Hz (44.1 kHz) has computed roots outside the
/// unit circle. It is kept when its computed denominator has every root within half
/// the designed poles' distance to the unit circle (Schur–Cohn,
/// [`crate::filter::roots_within`]), which holds for the AFE's designs at the usual
/// rates; the sections, which keep each pole pair in its own quadratic, replace it
/// otherwise.
pub fn butter_filters(order: usize, wn: &[f64], kind: ButterType) -> Vec<(Vec<f64>, Vec<f64>)> {
    let (b, a) = butter(order, wn, kind);
    let (_, poles, _) = butter_zpk(order, wn, kind);
    let rho = (1.0 + radius(&poles)) / 2.0;
    let denominator: Vec<Complex64> = a[1..].iter().map(|v| Complex64::new(*v, 0.0)).collect();
    if crate::filter::roots_within(&denominator, rho) {
        return vec![(b, a)];
    }
    butter_sos(order, wn, kind)
        .into_iter()
        .map(|(b, a)| (b.to_vec(), a.to_vec()))
        .collect()
}

/// `∏(1 − r·e^{−iw})` over `roots`: a monic polynomial's response at `w` rad/sample.
fn response_from_roots(roots: &[Complex64], w: f64) -> Complex64 {
    let e = Complex64::new(0.0, -w).exp();
    roots
        .iter()
        .fold(Complex64::new(1.0, 0.0), |acc, r| acc * (1.0 - r * e))
}

/// One second-order section `(b0, b1, b2)`, `(1, a1, a2)` (a first-order one has zero
/// `b2` and `a2`).
pub type Biquad = ([f64; 3], [f64; 3]);

/// The same design as [`butter`] as a cascade of second-order sections, designed as
/// scipy's `zpk2sos` does: stable at any order, where the expanded transfer function
/// of a narrow band or a low cut-off at high order is not (its coefficients lose the
/// poles to round-off).
///
/// Each section holds a conjugate pole pair (or two real poles, or a lone real one) and
/// the zeros nearest to them, taken by the poles closest to the unit circle first; the
/// sections run in the order of their poles' radius, the closest to the circle last;
/// each has unit gain where the whole filter has it (DC, Nyquist or the band centre).
/// Pairing the zeros with their nearest poles keeps every section's gain near the
/// filter's. Sections that each took one zero at DC and one at Nyquist (the pairing
/// before issue 44) had, in a wide band-pass, large gains near one band edge and small
/// ones near the other, and their product amplified the round-off of the first
/// sections: the output of [20, 20000] Hz at order 12 peaked at 2.4e4 where scipy's
/// sections give 0.46, [1, 22049] Hz at order 32 at 1.2e92.
pub fn butter_sos(order: usize, wn: &[f64], kind: ButterType) -> Vec<Biquad> {
    let (zeros, poles, w_norm) = butter_zpk(order, wn, kind);
    let whole = response_from_roots(&poles, w_norm) / response_from_roots(&zeros, w_norm);
    let mut poles = pairs(poles);
    poles.sort_by(|a, b| radius(a).total_cmp(&radius(b)));
    let mut zeros_left = zeros;
    let mut zeros: Vec<Vec<Complex64>> = vec![Vec::new(); poles.len()];
    for (p, z) in poles.iter().zip(&mut zeros).rev() {
        while z.len() < p.len() && !zeros_left.is_empty() {
            let nearest = (0..zeros_left.len())
                .min_by(|&i, &j| {
                    (zeros_left[i] - p[0])
                        .norm()
                        .total_cmp(&(zeros_left[j] - p[0]).norm())
                })
                .expect("a zero is left");
            let zero = zeros_left.swap_remove(nearest);
            if !is_real(&zero) {
                let conj = (0..zeros_left.len())
                    .min_by(|&i, &j| {
                        (zeros_left[i] - zero.conj())
                            .norm()
                            .total_cmp(&(zeros_left[j] - zero.conj()).norm())
                    })
                    .expect("complex zeros come in conjugate pairs");
                z.push(zeros_left.swap_remove(conj));
            }
            z.push(zero);
        }
    }
    // the sections' unit gains multiply to ±1 where the whole filter is +1 ([`butter`])
    let sign = if whole.re < 0.0 { -1.0 } else { 1.0 };
    zeros
        .iter()
        .zip(&poles)
        .enumerate()
        .map(|(k, (z, p))| {
            let gain = (response_from_roots(p, w_norm) / response_from_roots(z, w_norm)).norm();
            let gain = if k == 0 { sign * gain } else { gain };
            let (b, a) = (quadratic(z), quadratic(p));
            ([b[0] * gain, b[1] * gain, b[2] * gain], a)
        })
        .collect()
}

/// How much a cascade of `sections` can amplify the round-off of its intermediate
/// signals, relative to its peak gain: the largest, over the points between two
/// sections, of `max|P(w)|·max|S(w)|` (`P` the sections before the point, `S` those
/// after, maxima over 0, π, the cut-offs `wn` (normalised to Nyquist) and 200
/// log-spaced frequencies from 1e−7·π to π), divided by the cascade's `max|H(w)|`.
///
/// Round-off of relative size ε (2⁻⁵³) in an intermediate signal reaches the output at
/// up to ε times this figure. Low- and high-passes and band-passes stay below 1e6 at
/// every order up to 32; wide or high-order band-stops reach 1e88 (their sections
/// normalised at DC have gains near Nyquist that differ by 20 orders of magnitude).
pub fn round_off_gain(sections: &[Biquad], wn: &[f64]) -> f64 {
    let mut w: Vec<f64> = (0..200)
        .map(|k| PI * 10f64.powf(-7.0 + 7.0 * k as f64 / 199.0))
        .collect();
    w.extend([0.0, PI]);
    w.extend(wn.iter().map(|v| PI * v));
    let gains: Vec<Vec<f64>> = sections
        .iter()
        .map(|(b, a)| {
            w.iter()
                .map(|&w| {
                    let e = Complex64::new(0.0, -w).exp();
                    let ev = |c: &[f64; 3]| c[0] + e * (c[1] + e * c[2]);
                    (ev(b) / ev(a)).norm()
                })
                .collect()
        })
        .collect();
    let product = |range: &[Vec<f64>]| -> f64 {
        (0..w.len())
            .map(|i| range.iter().map(|g| g[i]).product::<f64>())
            .fold(0.0, f64::max)
    };
    let peak = product(&gains);
    (1..gains.len())
        .map(|k| product(&gains[..k]) * product(&gains[k..]))
        .fold(1.0, f64::max)
        / peak
}

/// The largest modulus of `roots`.
fn radius(roots: &[Complex64]) -> f64 {
    roots.iter().fold(0.0, |m, r| m.max(r.norm()))
}

/// Whether `r` is real up to an imaginary part of 1e-12 relative to its norm (or 1).
fn is_real(r: &Complex64) -> bool {
    r.im.abs() <= 1e-12 * r.norm().max(1.0)
}

/// Groups conjugate-symmetric `roots` into pairs: each complex root with its conjugate,
/// the real ones smallest with largest (a lone real root last, on its own).
fn pairs(roots: Vec<Complex64>) -> Vec<Vec<Complex64>> {
    let (mut real, complex): (Vec<Complex64>, Vec<Complex64>) =
        roots.into_iter().partition(is_real);
    let mut out: Vec<Vec<Complex64>> = complex
        .iter()
        .filter(|r| r.im > 0.0)
        .map(|r| vec![*r, r.conj()])
        .collect();
    real.sort_by(|a, b| a.re.total_cmp(&b.re));
    while real.len() >= 2 {
        let (lo, hi) = (real.remove(0), real.remove(real.len() - 1));
        out.push(vec![lo, hi]);
    }
    out.extend(real.into_iter().map(|r| vec![r]));
    out
}

/// `[1, c1, c2]` of the monic polynomial with one or two roots (real, or a conjugate pair).
fn quadratic(roots: &[Complex64]) -> [f64; 3] {
    let c = real_poly(roots);
    [c[0], c[1], c.get(2).copied().unwrap_or(0.0)]
}

/// Zeros, poles (z plane) and the normalised frequency of unit gain of [`butter`]'s
/// design.
fn butter_zpk(order: usize, wn: &[f64], kind: ButterType) -> (Vec<Complex64>, Vec<Complex64>, f64) {
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
    (zeros, poles.into_iter().map(bilinear).collect(), w_norm)
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

    /// The cascade's response at `w` rad/sample.
    fn sos_response(sections: &[Biquad], w: f64) -> f64 {
        sections.iter().map(|(b, a)| response(b, a, w)).product()
    }

    /// The analog prototype's magnitude through the bilinear map, `w` in rad/sample.
    fn ideal(order: usize, wn: &[f64], kind: ButterType, w: f64) -> f64 {
        let warp = |x: f64| 4.0 * (x / 2.0).tan();
        let om = warp(w);
        let (u1, u2) = (warp(PI * wn[0]), wn.get(1).map_or(0.0, |v| warp(PI * v)));
        let ratio = match kind {
            ButterType::Low => om / u1,
            ButterType::High => u1 / om,
            ButterType::BandPass => (om * om - u1 * u2) / (om * (u2 - u1)),
            ButterType::BandStop => (om * (u2 - u1)) / (om * om - u1 * u2),
        };
        1.0 / (1.0 + ratio.abs().powi(2 * order as i32)).sqrt()
    }

    #[test]
    fn sections_give_the_transfer_function_where_it_is_well_conditioned() {
        for (order, wn, kind) in [
            (2, vec![0.05], ButterType::Low),
            (5, vec![0.2], ButterType::High),
            (3, vec![0.1, 0.3], ButterType::BandPass),
            (2, vec![0.1, 0.3], ButterType::BandStop),
        ] {
            let (b, a) = butter(order, &wn, kind);
            let sos = butter_sos(order, &wn, kind);
            let bands = matches!(kind, ButterType::BandPass | ButterType::BandStop);
            assert_eq!(sos.len(), if bands { order } else { order.div_ceil(2) });
            for k in 1..64 {
                let w = PI * k as f64 / 64.0;
                let (tf, cascade) = (response(&b, &a, w), sos_response(&sos, w));
                let want = ideal(order, &wn, kind, w);
                assert!(
                    (cascade - want).abs() <= 1e-12 * want,
                    "{kind:?} {w}: {cascade}"
                );
                // the expanded coefficients lose digits deep in the stop band
                let tol = 1e-12 + 1e-10 * want;
                assert!((tf - cascade).abs() <= tol, "{kind:?} {w}: {tf}");
            }
        }
    }

    /// Issue 13, item 3: designs whose transfer function is unstable in double precision
    /// (a narrow low band, a 10-Hz band stop, an order-8 low cut-off) keep the
    /// Butterworth magnitude as sections, and every section's poles inside the circle.
    #[test]
    fn sections_keep_narrow_and_high_order_designs_stable() {
        let fs = 44100.0;
        for (order, hz, kind) in [
            (4, vec![100.0, 200.0], ButterType::BandPass),
            (4, vec![45.0, 55.0], ButterType::BandStop),
            (8, vec![100.0], ButterType::Low),
        ] {
            let wn: Vec<f64> = hz.iter().map(|f| f / (fs / 2.0)).collect();
            let sos = butter_sos(order, &wn, kind);
            for (_, a) in &sos {
                // a monic quadratic's roots are inside the unit circle iff |a2| < 1 and
                // |a1| < 1 + a2 (the stability triangle)
                assert!(
                    a[2].abs() < 1.0 && a[1].abs() < 1.0 + a[2],
                    "{kind:?}: {a:?}"
                );
            }
            for f in [10.0, 50.0, 80.0, 100.0, 140.0, 200.0, 400.0, 2000.0] {
                let w = 2.0 * PI * f / fs;
                let (got, want) = (sos_response(&sos, w), ideal(order, &wn, kind, w));
                assert!(
                    (got - want).abs() <= 1e-9 * want.max(1e-6),
                    "{kind:?} {f} Hz: {got} vs {want}"
                );
            }
        }
    }

    /// The convention of `∏(1 − r·e^{−iw})`, worked by hand: one root 0.5 at a quarter
    /// turn gives 1 + 0.5i (the designs only use conjugate-symmetric root sets, whose
    /// gains cannot tell `e^{−iw}` from `e^{iw}`).
    #[test]
    fn response_from_roots_evaluates_at_e_to_the_minus_iw() {
        let r = response_from_roots(&[Complex64::new(0.5, 0.0)], PI / 2.0);
        assert!((r - Complex64::new(1.0, 0.5)).norm() < 1e-15, "{r}");
        let two = [Complex64::new(0.0, 0.5), Complex64::new(2.0, 0.0)];
        // (1 − 0.5i·(−i))·(1 − 2·(−i)) = 0.5·(1 + 2i)
        let r = response_from_roots(&two, PI / 2.0);
        assert!((r - Complex64::new(0.5, 1.0)).norm() < 1e-15, "{r}");
    }

    /// Pairs worked by hand: the complex root (positive imaginary part first) with its
    /// conjugate, then the reals smallest with largest, a lone one last. "Real" allows
    /// an imaginary part of 1e-12 relative to a norm above one.
    #[test]
    fn pairs_group_conjugates_then_reals_outside_in() {
        let c = |re, im| Complex64::new(re, im);
        let roots = vec![
            c(0.3, -0.4),
            c(0.9, 0.0),
            c(3.0, 2e-12),
            c(-0.5, 0.0),
            c(0.3, 0.4),
            c(0.2, 0.0),
            c(0.1, 0.0),
        ];
        let want = vec![
            vec![c(0.3, 0.4), c(0.3, -0.4)],
            vec![c(-0.5, 0.0), c(3.0, 2e-12)],
            vec![c(0.1, 0.0), c(0.9, 0.0)],
            vec![c(0.2, 0.0)],
        ];
        assert_eq!(pairs(roots), want);
    }

    /// The transfer function where the oracle uses it (the 20-Hz DC-removal high-pass at
    /// 16 and 44.1 kHz, the IHC low-passes), sections where its computed roots leave the
    /// unit circle: 4th order at 1 Hz and 1 Hz below Nyquist, and an order-12 low-pass
    /// at 50 Hz; those keep the Butterworth magnitude.
    #[test]
    fn filters_keep_the_transfer_function_where_it_is_stable() {
        for (order, wn, kind) in [
            (4, 20.0 / 22050.0, ButterType::High),
            (4, 20.0 / 8000.0, ButterType::High),
            (2, 1000.0 / 22050.0, ButterType::Low),
            (1, 150.0 / 8000.0, ButterType::Low),
        ] {
            assert_eq!(
                butter_filters(order, &[wn], kind),
                vec![butter(order, &[wn], kind)],
                "{order} {wn} {kind:?}"
            );
        }
        for (order, wn, kind) in [
            (4, 1.0 / 22050.0, ButterType::High),
            (4, 22049.0 / 22050.0, ButterType::High),
            (12, 50.0 / 22050.0, ButterType::Low),
        ] {
            let (_, a) = butter(order, &[wn], kind);
            let a: Vec<Complex64> = a[1..].iter().map(|v| Complex64::new(*v, 0.0)).collect();
            assert!(
                !crate::filter::roots_within(&a, 1.0),
                "{order} {wn}: unstable"
            );
            let filters = butter_filters(order, &[wn], kind);
            assert_eq!(filters.len(), order.div_ceil(2));
            let sections: Vec<Biquad> = butter_sos(order, &[wn], kind);
            for (f, s) in filters.iter().zip(&sections) {
                assert_eq!((f.0.as_slice(), f.1.as_slice()), (&s.0[..], &s.1[..]));
            }
            for k in 1..64 {
                let w = PI * k as f64 / 64.0;
                let (got, want) = (sos_response(&sections, w), ideal(order, &[wn], kind, w));
                assert!((got - want).abs() <= 1e-9 * want.max(1e-6), "{w}: {got}");
            }
        }
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
