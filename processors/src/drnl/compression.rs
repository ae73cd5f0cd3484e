//! The DRNL's two non-linearities (CASP's broken stick, MAP's threshold and power) and
//! the vectorisable `x^(1/4 + δ)` and `ln x` behind CASP's. Apart from the kernels that
//! call them because they are scalar numerics with their own accuracy bounds, tested
//! against the literal formulas.

use std::f64::consts::{LN_2, SQRT_2};

/// `x^(1/4 + delta)` for `x ≥ 0` and `|delta| ≲ 1e−8`, within a few ulps of `powf`:
/// `sqrt(sqrt(x))` times `x^delta = exp(delta·ln x)` to second order, with a ln accurate
/// to 4e−8 (its error is multiplied by `delta`). Vectorises, unlike `powf`: CASP's
/// exponent is 1/4 − 5e−9, and rounding it to 1/4 would move the compressed values by
/// up to 1e−7 relative.
#[inline(always)]
fn pow_quarter_plus(x: f64, delta: f64) -> f64 {
    let t = delta * ln_rough(x);
    x.sqrt().sqrt() * (1.0 + t * (1.0 + 0.5 * t))
}

/// Coefficients of `ln(1 + y)` on `y ∈ [√½ − 1, √2 − 1]`, lowest first: the degree-8
/// interpolant at the Chebyshev nodes (maximum error 3.9e−8).
const LN1P: [f64; 9] = [
    2.87670076431255e-08,
    0.9999999600344619,
    -0.5000095634994474,
    0.33334828194380944,
    -0.24950976038480824,
    0.1990183010152832,
    -0.17437085825438994,
    0.16247007808635738,
    -0.09610568068805528,
];

/// `ln x` for `x ≥ 0` within 4e−8 for normal `x` (finite for 0, subnormals and ∞):
/// exponent and mantissa from the bits, the mantissa `m` brought into (√½, √2], and
/// `ln m` by the polynomial [`LN1P`] in `m − 1` (no division: the divider is busy with
/// the square roots), in fused multiply-adds: half the instructions of this, the
/// compression's largest part.
#[inline(always)]
fn ln_rough(x: f64) -> f64 {
    const TWO_52: f64 = 4_503_599_627_370_496.0;
    let bits = x.to_bits();
    // the 11 exponent bits as a float, exactly (2^52 + e, minus 2^52)
    let biased = f64::from_bits(TWO_52.to_bits() | (bits >> 52)) - TWO_52;
    let m = f64::from_bits((bits & 0x000F_FFFF_FFFF_FFFF) | 1f64.to_bits());
    let high = m > SQRT_2;
    let m = if high { 0.5 * m } else { m };
    let e = biased - if high { 1022.0 } else { 1023.0 };
    let y = m - 1.0;
    let mut p = LN1P[8];
    for k in (0..8).rev() {
        p = p.mul_add(y, LN1P[k]);
    }
    e.mul_add(LN_2, p)
}

/// CASP's broken-stick non-linearity `sign(u)·min(a·|u|, b·|u|^c)`, `c = 1/4 + delta`.
#[inline(always)]
pub(super) fn casp_compress(u: f64, a: f64, b: f64, delta: f64) -> f64 {
    let au = u.abs();
    let (linear, power) = (a * au, b * pow_quarter_plus(au, delta));
    // a plain comparison (one instruction): NaN only comes with a NaN `u`
    if power < linear { power } else { linear }.copysign(u)
}

/// MAP's non-linearity: `a·u` below the threshold `|u| < cts`, else
/// `sign(u)·ctBM·(a·|u|/ctBM)^(1/4)` (the AFE evaluates the power as `exp(c·ln(·))`;
/// `sqrt(sqrt(·))` is within a few ulps of it).
#[inline(always)]
pub(super) fn map_compress(u: f64, a: f64, cts: f64, ct_bm: f64) -> f64 {
    let au = u.abs();
    let compressed = (ct_bm * ((a * au) / ct_bm).sqrt().sqrt()).copysign(u);
    if au < cts {
        a * u
    } else {
        compressed
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::drnl::design::{casp_channel, casp_exponent, map_channel, map_threshold};

    /// `|x|^c` within `ulps` of `powf` (relative).
    fn close(got: f64, want: f64, ulps: f64) -> bool {
        (got - want).abs() <= ulps * f64::EPSILON * want.abs()
    }

    #[test]
    fn compressions_match_their_literal_formulas() {
        let c = casp_exponent();
        let delta = c - 0.25;
        let ct_bm = map_threshold();
        let (a, b) = casp_channel(2000.0, 44100.0).compression;
        let (ma, cts) = map_channel(2000.0, 44100.0).compression;
        for k in -300..=40 {
            for u in [1.37f64.powi(k), -(1.29f64.powi(k))] {
                let literal = u.signum() * (a * u.abs()).min(b * u.abs().powf(c));
                let got = casp_compress(u, a, b, delta);
                assert!(
                    close(got, literal, 4.0),
                    "CASP u={u:e}: {got:e} vs {literal:e}"
                );
                let literal = if u.abs() < cts {
                    ma * u
                } else {
                    u.signum() * ct_bm * (0.25 * (ma * u.abs() / ct_bm).ln()).exp()
                };
                let got = map_compress(u, ma, cts, ct_bm);
                assert!(
                    close(got, literal, 8.0),
                    "MAP u={u:e}: {got:e} vs {literal:e}"
                );
            }
        }
        for u in [0.0, -0.0] {
            assert_eq!(casp_compress(u, a, b, delta), 0.0);
            assert_eq!(map_compress(u, ma, cts, ct_bm), 0.0);
        }
        assert!(casp_compress(f64::INFINITY, a, b, delta).is_infinite());
    }
}
