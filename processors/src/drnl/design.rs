//! The DRNL's per-channel design (spec 12-drnl): the two section types, the CASP and
//! MAP parameter sets and the constants they share. Apart from the filterbank because
//! it is computed once, at construction, and checked against the spec's formulas on its
//! own; the filterbank only copies its coefficients into lanes.

use std::f64::consts::{PI, SQRT_2};

/// A second-order section `(b0 + b1 z⁻¹ + b2 z⁻²) / (1 + a1 z⁻¹ + a2 z⁻²)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Biquad {
    pub(super) b: [f64; 3],
    /// `a1, a2` (`a0 = 1`).
    pub(super) a: [f64; 2],
}

/// The DRNL "gammatone" resonator `GT(cf, bw)` at rate `fs` (spec 12-drnl): two poles, one
/// zero, unity gain at `cf`.
fn gt_section(cf: f64, bw: f64, fs: f64) -> Biquad {
    let theta = 2.0 * PI * cf / fs;
    let phi = 2.0 * PI * bw / fs;
    let alpha = -(-phi).exp() * theta.cos();
    let a1 = 2.0 * alpha;
    let a2 = (-2.0 * phi).exp();
    // |1 + a1·e^{−iθ} + a2·e^{−2iθ}| / |1 + α·e^{−iθ}|
    let (c1, s1) = (theta.cos(), theta.sin());
    let (c2, s2) = ((2.0 * theta).cos(), (2.0 * theta).sin());
    let num = (1.0 + a1 * c1 + a2 * c2).hypot(-(a1 * s1) - a2 * s2);
    let den = (1.0 + alpha * c1).hypot(-(alpha * s1));
    let g0 = num / den;
    Biquad {
        b: [g0, g0 * alpha, 0.0],
        a: [a1, a2],
    }
}

/// The second-order Butterworth low-pass `LP(fc)` at rate `fs` (bilinear, `K = cot(π·fc/fs)`).
fn lp_section(fc: f64, fs: f64) -> Biquad {
    let k = 1.0 / (PI * fc / fs).tan();
    let c = 1.0 / (1.0 + SQRT_2 * k + k * k);
    let d = 2.0 * c * (1.0 - k * k);
    let e = c * (1.0 - SQRT_2 * k + k * k);
    Biquad {
        b: [c, 2.0 * c, c],
        a: [d, e],
    }
}

/// `10^x`, evaluated as the AFE does (a power of 10, not `exp(x·ln 10)`).
pub(super) fn exp10(x: f64) -> f64 {
    10f64.powf(x)
}

/// CASP's compression exponent `10^(−0.60206)`, 5e−9 below 1/4.
pub(super) fn casp_exponent() -> f64 {
    exp10(-0.60206)
}

/// MAP's compression threshold `ctBM = 1e−9·10^(25/20)` (b = 25 dB re 1 nm).
pub(super) fn map_threshold() -> f64 {
    1e-9 * exp10(25.0 / 20.0)
}

/// One channel's design.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct ChannelDesign {
    pub(super) lin_gain: f64,
    pub(super) gt_lin: Biquad,
    /// CASP only.
    pub(super) lp_lin: Option<Biquad>,
    pub(super) gt_nl: Biquad,
    /// CASP only.
    pub(super) lp_nl: Option<Biquad>,
    /// Compression: CASP `(a, b)` of `min(a·|u|, b·|u|^c)`; MAP `(a, CtS)`, the linear
    /// gain and the threshold below which it applies.
    pub(super) compression: (f64, f64),
}

/// The CASP design of the channel at `f` Hz (spec 12-drnl, logs base 10). The GT
/// sections take the low-pass cut-offs as centre frequencies, as the AFE builds them.
pub(super) fn casp_channel(f: f64, fs: f64) -> ChannelDesign {
    let lf = f.log10();
    let lin_fc = exp10(-0.06762 + 1.01 * lf);
    let lin_bw = exp10(0.03728 + 0.75 * lf);
    let nl_fc = exp10(-0.05252 + 1.01 * lf);
    let nl_bw = exp10(-0.03193 + 0.70 * lf);
    // a and b follow f up to 1000 Hz, then jump to their 1500-Hz values
    let lab = if f <= 1000.0 { lf } else { 1500f64.log10() };
    ChannelDesign {
        lin_gain: exp10(4.20405 - 0.47909 * lf),
        gt_lin: gt_section(lin_fc, lin_bw, fs),
        lp_lin: Some(lp_section(lin_fc, fs)),
        gt_nl: gt_section(nl_fc, nl_bw, fs),
        lp_nl: Some(lp_section(nl_fc, fs)),
        compression: (
            exp10(1.40298 + 0.81916 * lab),
            exp10(1.61912 - 0.81867 * lab),
        ),
    }
}

/// MAP's linear gain, compression gain `a` and exponent.
const MAP_LIN_GAIN: f64 = 500.0;
const MAP_A: f64 = 4000.0;

/// The MAP design of the channel at `f` Hz (spec 12-drnl).
pub(super) fn map_channel(f: f64, fs: f64) -> ChannelDesign {
    ChannelDesign {
        lin_gain: MAP_LIN_GAIN,
        gt_lin: gt_section(0.62 * f + 266.0, 0.2 * f + 235.0, fs),
        lp_lin: None,
        gt_nl: gt_section(f, 0.14 * f + 180.0, fs),
        lp_nl: None,
        compression: (MAP_A, map_threshold() / MAP_A),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_complex::Complex64;

    /// `|H(e^{iω})|` of a section at `f` Hz.
    fn gain_at(s: &Biquad, f: f64, fs: f64) -> f64 {
        let w = 2.0 * PI * f / fs;
        let (c1, s1, c2, s2) = (w.cos(), w.sin(), (2.0 * w).cos(), (2.0 * w).sin());
        let num = (s.b[0] + s.b[1] * c1 + s.b[2] * c2).hypot(s.b[1] * s1 + s.b[2] * s2);
        let den = (1.0 + s.a[0] * c1 + s.a[1] * c2).hypot(s.a[0] * s1 + s.a[1] * s2);
        num / den
    }

    /// Asserts `b0, b1, b2, a1, a2` of the section at `f` Hz each within `rel` of `want`.
    fn assert_coefficients(s: &Biquad, want: [f64; 5], rel: f64, f: f64) {
        let got = [s.b[0], s.b[1], s.b[2], s.a[0], s.a[1]];
        for (g, w) in got.iter().zip(want) {
            assert!(
                (g - w).abs() <= rel * w.abs(),
                "{f} Hz: {got:?} vs {want:?}"
            );
        }
    }

    #[test]
    fn gt_sections_have_unity_gain_at_their_centre() {
        for (cf, bw, fs) in [
            (80.0, 50.0, 44100.0),
            (1000.0, 150.0, 16000.0),
            (7000.0, 900.0, 44100.0),
        ] {
            let s = gt_section(cf, bw, fs);
            // Spec 12's coefficients, with g0 from a complex division (2e−13 from the
            // ratio of two hypots at 80 Hz, where the numerator nearly cancels).
            let (theta, phi) = (2.0 * PI * cf / fs, 2.0 * PI * bw / fs);
            let alpha = -(-phi).exp() * theta.cos();
            let (a1, a2) = (2.0 * alpha, (-2.0 * phi).exp());
            let z = Complex64::from_polar(1.0, -theta);
            let g0 = ((1.0 + a1 * z + a2 * z * z) / (1.0 + alpha * z)).norm();
            assert_coefficients(&s, [g0, g0 * alpha, 0.0, a1, a2], 1e-12, cf);
            assert!((gain_at(&s, cf, fs) - 1.0).abs() < 1e-12, "{cf} Hz");
            assert!(gain_at(&s, cf + 3.0 * bw, fs) < 0.5, "{cf} Hz resonates");
            assert_eq!(s.b[2], 0.0);
        }
    }

    #[test]
    fn lp_sections_are_butterworth_low_passes() {
        for (fc, fs) in [(100.0, 44100.0), (1000.0, 16000.0), (7000.0, 44100.0)] {
            let s = lp_section(fc, fs);
            // Spec 12: K = cot(π·fc/fs), C = 1/(1 + √2·K + K²), D = 2C(1 − K²),
            // E = C(1 − √2·K + K²).
            let k = (PI * fc / fs).tan().recip();
            let c = 1.0 / (1.0 + SQRT_2 * k + k * k);
            let (d, e) = (2.0 * c * (1.0 - k * k), c * (1.0 - SQRT_2 * k + k * k));
            assert_coefficients(&s, [c, 2.0 * c, c, d, e], 1e-13, fc);
            assert!((gain_at(&s, 0.0, fs) - 1.0).abs() < 1e-12);
            assert!(
                (gain_at(&s, fc, fs) - SQRT_2.recip()).abs() < 1e-12,
                "{fc} Hz"
            );
            assert!(gain_at(&s, fs / 2.0, fs) < 1e-12);
            assert_eq!((s.b[1], s.b[2]), (2.0 * s.b[0], s.b[0]));
        }
    }

    /// The GT sections resonate at the low-pass cut-offs (the AFE's bug), and a and b
    /// jump to their 1500-Hz values above 1000 Hz.
    #[test]
    fn casp_design_reproduces_the_afe() {
        let fs = 44100.0;
        for f in [250.0, 1000.0, 4000.0] {
            let d = casp_channel(f, fs);
            let lin_fc = 10f64.powf(-0.06762 + 1.01 * f.log10());
            let declared = 10f64.powf(-0.06762 + 1.01679 * f.log10());
            assert!((gain_at(&d.gt_lin, lin_fc, fs) - 1.0).abs() < 1e-12);
            assert!((gain_at(&d.gt_lin, declared, fs) - 1.0).abs() > 1e-6);
            assert_eq!(d.lp_lin, Some(lp_section(lin_fc, fs)));
            let nl_fc = 10f64.powf(-0.05252 + 1.01 * f.log10());
            assert!((gain_at(&d.gt_nl, nl_fc, fs) - 1.0).abs() < 1e-12);
        }
        // Every row of spec 12's CASP table at 500 Hz, and MAP's at 3 kHz.
        let p10 = |x: f64| 10f64.powf(x);
        let lf = 500f64.log10();
        let (lin_fc, nl_fc) = (p10(-0.06762 + 1.01 * lf), p10(-0.05252 + 1.01 * lf));
        let casp = ChannelDesign {
            lin_gain: p10(4.20405 - 0.47909 * lf),
            gt_lin: gt_section(lin_fc, p10(0.03728 + 0.75 * lf), fs),
            lp_lin: Some(lp_section(lin_fc, fs)),
            gt_nl: gt_section(nl_fc, p10(-0.03193 + 0.70 * lf), fs),
            lp_nl: Some(lp_section(nl_fc, fs)),
            compression: (p10(1.40298 + 0.81916 * lf), p10(1.61912 - 0.81867 * lf)),
        };
        assert_eq!(casp_channel(500.0, fs), casp);
        let ct_bm = 1e-9 * p10(25.0 / 20.0);
        let map = ChannelDesign {
            lin_gain: 500.0,
            gt_lin: gt_section(0.62 * 3000.0 + 266.0, 0.2 * 3000.0 + 235.0, fs),
            lp_lin: None,
            gt_nl: gt_section(3000.0, 0.14 * 3000.0 + 180.0, fs),
            lp_nl: None,
            compression: (4000.0, ct_bm / 4000.0),
        };
        assert_eq!(map_channel(3000.0, fs), map);
        assert_eq!(map_threshold(), ct_bm);
        assert!((casp_exponent() - 0.25).abs() < 6e-9 && casp_exponent() != 0.25);
        let below = casp_channel(1000.0, fs).compression;
        let above = casp_channel(1000.001, fs).compression;
        assert!((below.0 - 10f64.powf(1.40298 + 0.81916 * 3.0)).abs() < 1e-9 * below.0);
        assert_eq!(above, casp_channel(5000.0, fs).compression);
        assert!(above.0 / below.0 > 1.39 && below.1 / above.1 > 1.39);
    }
}
