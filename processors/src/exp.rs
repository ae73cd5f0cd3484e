//! `eˣ` in straight-line arithmetic (no call, no branch), so that a loop over SIMD lanes
//! that needs it still vectorises; within 2 ulp of `f64::exp`.
//!
//! `eˣ = 2ⁿ·eʳ` with `n` the integer nearest `x/ln 2` and `r = x − n·ln 2` (Cody and
//! Waite's two-part `ln 2`, so that `n·ln 2` is subtracted without rounding), `|r| ≤ ½ln 2`;
//! `eʳ` by its Taylor series to degree 12 (the rest is below 2e−16 of it) in Estrin's
//! scheme, and `2ⁿ` built in the exponent bits.
//!
//! The products are fused multiply-adds: one rounding each, and a dependency chain about
//! half as long, which is what bounds the adaptation loops' overshoot limitation (10–15 %
//! faster there). Its only caller, the adaptation loops, has versions for AVX-512 and for
//! AVX2 + FMA, and aarch64 always has FMA; on an x86-64 CPU with neither, the fallback
//! version gets the same values from the slower library `fma`.

use std::f64::consts::LOG2_E;

/// `ln 2` split so that its high part times any `|n| ≤ 2¹¹` is exact.
const LN2_HI: f64 = 6.931_471_803_691_238_164_9e-1;
const LN2_LO: f64 = 1.908_214_929_270_587_700_0e-10;

/// `1.5·2⁵²`: added to a double below `2⁵¹` in size, it leaves the nearest integer in
/// the low bits of the mantissa.
const SHIFTER: f64 = 6_755_399_441_055_744.0;

/// Below this `eˣ` is subnormal; the result is 0 there.
const MIN_ARG: f64 = -708.0;
/// Above this `eˣ` overflows; the argument is clamped to it.
const MAX_ARG: f64 = 709.0;

/// `eˣ`, within 2 ulp of `f64::exp` for `−708 ≤ x ≤ 709`; 0 below `−708` (where `eˣ` is
/// below 4e−308), `e⁷⁰⁹` above 709, NaN for NaN.
#[inline(always)]
pub fn exp(x: f64) -> f64 {
    let c = x.clamp(MIN_ARG, MAX_ARG);
    let shifted = c.mul_add(LOG2_E, SHIFTER);
    let n = shifted - SHIFTER;
    let r = (-n).mul_add(LN2_LO, (-n).mul_add(LN2_HI, c));
    // 1 + r + r²·t(r), with t's eleven terms in Estrin's scheme (pairs, then pairs of
    // pairs) so that its dependency chain is a few multiply-adds deep instead of eleven.
    let c = &INV_FACTORIAL;
    let r2 = r * r;
    let r4 = r2 * r2;
    let pair = |k: usize| c[k + 1].mul_add(r, c[k]);
    let t = pair(8)
        .mul_add(r2, pair(6))
        .mul_add(r4, pair(4).mul_add(r2, pair(2)))
        + c[12].mul_add(r2, pair(10)) * (r4 * r4);
    let e_r = 1.0 + r2.mul_add(t, r);
    // n + 1023 into the exponent field: the low bits of `shifted` hold n
    let two_n = f64::from_bits(shifted.to_bits().wrapping_add(1023) << 52);
    let y = e_r * two_n;
    if x < MIN_ARG {
        0.0
    } else {
        y
    }
}

/// `1/k!` for `k ≤ 12`.
const INV_FACTORIAL: [f64; 13] = [
    1.0,
    1.0,
    1.0 / 2.0,
    1.0 / 6.0,
    1.0 / 24.0,
    1.0 / 120.0,
    1.0 / 720.0,
    1.0 / 5_040.0,
    1.0 / 40_320.0,
    1.0 / 362_880.0,
    1.0 / 3_628_800.0,
    1.0 / 39_916_800.0,
    1.0 / 479_001_600.0,
];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::noise;

    /// Distance in units in the last place of `want`.
    fn ulps(got: f64, want: f64) -> f64 {
        let ulp = f64::from_bits(want.to_bits() + 1) - want;
        (got - want).abs() / ulp
    }

    #[test]
    fn within_two_ulp_of_std_over_the_whole_range() {
        let small = noise(20_000, 1).into_iter().map(|u| 4.0 * u);
        let wide = noise(20_000, 2).into_iter().map(|u| 1416.0 * u);
        let edges = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            MIN_ARG,
            MAX_ARG,
            0.5 * LN2_HI,
            -708.0 + 1e-9,
        ];
        let mut worst: f64 = 0.0;
        for x in small.chain(wide).chain(edges) {
            let u = ulps(exp(x), x.exp());
            assert!(u <= 2.0, "exp({x}): {} vs {} ({u} ulp)", exp(x), x.exp());
            worst = worst.max(u);
        }
        assert!(worst > 0.0, "a polynomial cannot be exact everywhere");
    }

    #[test]
    fn ends_of_the_range() {
        assert_eq!(exp(0.0), 1.0);
        assert_eq!(exp(-709.0), 0.0);
        assert_eq!(exp(f64::NEG_INFINITY), 0.0);
        assert_eq!(exp(1e6), exp(MAX_ARG));
        assert!(exp(MAX_ARG).is_finite() && exp(MAX_ARG) > 8e307);
        assert!(exp(f64::NAN).is_nan());
    }
}
