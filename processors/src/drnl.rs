//! `filterbank` with `fb_type = 'drnl'`: the dual-resonance non-linear basilar-membrane
//! filterbank (spec 12-drnl), per channel the sum of a linear path and a compressive
//! non-linear path, each a cascade of second-order sections run as DF2T in f64 with the
//! reference's operation order. Two parameter sets: CASP (Jepsen et al. 2008, default)
//! and MAP 1.14h. The request is [`crate::filterbank`]'s, the parameters and the grid
//! [`crate::filterbank_params`]'s.
//!
//! Reproduced as the AFE computes them: the gammatone-like sections take the low-pass
//! cut-offs as centre frequencies, CASP's compression constants jump at 1000 Hz, MAP
//! scales its input by 20 (`20e−5·10^5`). The non-linear path's gain is `fb_mocIpsi[c] ·
//! fb_mocContra[c]` per channel, replaceable at run time ([`Drnl::set_moc`]).

use std::f64::consts::{LN_2, PI, SQRT_2};

use afe_core::filter::Df2t;
use afe_core::lanes::vector_start;
use afe_core::params::per_channel;
use afe_core::{Block, Error, ParamMap, Processor, Result, SignalInfo};
use serde_json::json;

pub use crate::filterbank_params::DrnlModel;
use crate::filterbank_params::FilterbankParams;

/// The DRNL's verified parameters (the AFE's map after preparation): the grid, the model
/// and both MOC gains expanded to one per channel.
pub(crate) fn verified(params: &FilterbankParams) -> Result<ParamMap> {
    let grid = params.grid()?;
    let n = grid.cf_hz.len();
    let mut map = ParamMap::new();
    grid.insert_into(&mut map);
    map.insert("fb_model".into(), json!(params.model));
    map.insert(
        "fb_mocIpsi".into(),
        json!(per_channel("fb_mocIpsi", &params.moc_ipsi, n)?),
    );
    map.insert(
        "fb_mocContra".into(),
        json!(per_channel("fb_mocContra", &params.moc_contra, n)?),
    );
    Ok(map)
}

/// A second-order section `(b0 + b1 z⁻¹ + b2 z⁻²) / (1 + a1 z⁻¹ + a2 z⁻²)`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Biquad {
    b: [f64; 3],
    /// `a1, a2` (`a0 = 1`).
    a: [f64; 2],
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
fn exp10(x: f64) -> f64 {
    10f64.powf(x)
}

/// CASP's compression exponent `10^(−0.60206)`, 5e−9 below 1/4.
fn casp_exponent() -> f64 {
    exp10(-0.60206)
}

/// MAP's compression threshold `ctBM = 1e−9·10^(25/20)` (b = 25 dB re 1 nm).
fn map_threshold() -> f64 {
    1e-9 * exp10(25.0 / 20.0)
}

/// One channel's design.
#[derive(Debug, Clone, Copy, PartialEq)]
struct ChannelDesign {
    lin_gain: f64,
    gt_lin: Biquad,
    /// CASP only.
    lp_lin: Option<Biquad>,
    gt_nl: Biquad,
    /// CASP only.
    lp_nl: Option<Biquad>,
    /// Compression: CASP `(a, b)` of `min(a·|u|, b·|u|^c)`; MAP `(a, CtS)`, the linear
    /// gain and the threshold below which it applies.
    compression: (f64, f64),
}

/// The CASP design of the channel at `f` Hz (spec 12-drnl, logs base 10). The GT
/// sections take the low-pass cut-offs as centre frequencies, as the AFE builds them.
fn casp_channel(f: f64, fs: f64) -> ChannelDesign {
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
fn map_channel(f: f64, fs: f64) -> ChannelDesign {
    ChannelDesign {
        lin_gain: MAP_LIN_GAIN,
        gt_lin: gt_section(0.62 * f + 266.0, 0.2 * f + 235.0, fs),
        lp_lin: None,
        gt_nl: gt_section(f, 0.14 * f + 180.0, fs),
        lp_nl: None,
        compression: (MAP_A, map_threshold() / MAP_A),
    }
}

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
fn casp_compress(u: f64, a: f64, b: f64, delta: f64) -> f64 {
    let au = u.abs();
    let (linear, power) = (a * au, b * pow_quarter_plus(au, delta));
    // a plain comparison (one instruction): NaN only comes with a NaN `u`
    if power < linear { power } else { linear }.copysign(u)
}

/// MAP's non-linearity: `a·u` below the threshold `|u| < cts`, else
/// `sign(u)·ctBM·(a·|u|/ctBM)^(1/4)` (the AFE evaluates the power as `exp(c·ln(·))`;
/// `sqrt(sqrt(·))` is within a few ulps of it).
#[inline(always)]
fn map_compress(u: f64, a: f64, cts: f64, ct_bm: f64) -> f64 {
    let au = u.abs();
    let compressed = (ct_bm * ((a * au) / ct_bm).sqrt().sqrt()).copysign(u);
    if au < cts {
        a * u
    } else {
        compressed
    }
}

/// States per channel: CASP lin GT ×2, lin LP ×4, nl GT ×2 + ×2, nl LP ×1; MAP uses 9
/// (GT ×3 on each of the three stages).
const STATES: usize = 11;

/// A [`gt_section`] across `W` channels. Its `b2 = 0`, so the DF2T's `z1 = b2·x − a2·y`
/// is `(−a2)·y`: the same value without the product by zero (only the sign of an exact
/// zero state can differ).
#[derive(Debug, Clone, Copy)]
struct LaneGt<const W: usize> {
    b0: [f64; W],
    b1: [f64; W],
    /// `−a1`, `−a2`: `z + (−a)·y` is `z − a·y` bit for bit.
    na1: [f64; W],
    na2: [f64; W],
}

impl<const W: usize> LaneGt<W> {
    const ZERO: Self = LaneGt {
        b0: [0.0; W],
        b1: [0.0; W],
        na1: [0.0; W],
        na2: [0.0; W],
    };

    fn set(&mut self, lane: usize, s: &Biquad) {
        self.b0[lane] = s.b[0];
        self.b1[lane] = s.b[1];
        self.na1[lane] = -s.a[0];
        self.na2[lane] = -s.a[1];
    }

    /// One sample `x` of lane `l`: DF2T in the reference's order, `y = z0 + b0·x`,
    /// `z0 = (z1 − a1·y) + b1·x`, `z1 = −a2·y`; returns `y`.
    #[inline(always)]
    fn step(&self, z: &mut [[f64; W]; 2], l: usize, x: f64) -> f64 {
        let y = z[0][l] + self.b0[l] * x;
        z[0][l] = (z[1][l] + self.na1[l] * y) + self.b1[l] * x;
        z[1][l] = self.na2[l] * y;
        y
    }

    /// The section over `buf` (rows of `W` channels) in place, state `z` carried.
    #[inline(always)]
    fn run(&self, z: &mut [[f64; W]; 2], buf: &mut [[f64; W]]) {
        self.run_then(z, buf, |_| ());
    }

    /// [`LaneGt::run`], then `then` on each output row in place (in the same pass, so that
    /// its work overlaps the recursion's latency).
    #[inline(always)]
    fn run_then(
        &self,
        z: &mut [[f64; W]; 2],
        buf: &mut [[f64; W]],
        mut then: impl FnMut(&mut [f64; W]),
    ) {
        let mut zs = *z;
        for v in buf.iter_mut() {
            for (l, x) in v.iter_mut().enumerate() {
                *x = self.step(&mut zs, l, *x);
            }
            then(v);
        }
        *z = zs;
    }

    /// The section on `gain·x` (each lane's gain times the one input sample of a row),
    /// written to `buf`: the paths' input scaling in the first section's pass.
    #[inline(always)]
    fn run_from(&self, z: &mut [[f64; W]; 2], x: &[f64], gain: &[f64; W], buf: &mut [[f64; W]]) {
        let mut zs = *z;
        for (v, &xt) in buf.iter_mut().zip(x) {
            for l in 0..W {
                v[l] = self.step(&mut zs, l, gain[l] * xt);
            }
        }
        *z = zs;
    }
}

/// A section given by its one-sample `step` (e.g. [`LaneGt::step`]) over `buf`, writing
/// `other + y` to `W` values at every `stride` of `out` instead of `y` to `buf`: the
/// paths' sum in the last section's pass. State `z` carried.
#[inline(always)]
fn sum_into<const W: usize>(
    z: &mut [[f64; W]; 2],
    buf: &[[f64; W]],
    other: &[[f64; W]],
    out: &mut [f64],
    stride: usize,
    step: impl Fn(&mut [[f64; W]; 2], usize, f64) -> f64,
) {
    let mut zs = *z;
    for (t, (v, o)) in buf.iter().zip(other).enumerate() {
        let row = &mut out[t * stride..t * stride + W];
        for l in 0..W {
            row[l] = o[l] + step(&mut zs, l, v[l]);
        }
    }
    *z = zs;
}

/// An [`lp_section`] across `W` channels. Its numerator is `[C, 2C, C]`, and `(2C)·x` is
/// `C·x + C·x` bit for bit (scaling by 2 is exact), so one product serves all three.
#[derive(Debug, Clone, Copy)]
struct LaneLp<const W: usize> {
    c: [f64; W],
    /// `−a1`, `−a2`.
    na1: [f64; W],
    na2: [f64; W],
}

impl<const W: usize> LaneLp<W> {
    const ZERO: Self = LaneLp {
        c: [0.0; W],
        na1: [0.0; W],
        na2: [0.0; W],
    };

    fn set(&mut self, lane: usize, s: &Biquad) {
        self.c[lane] = s.b[0];
        self.na1[lane] = -s.a[0];
        self.na2[lane] = -s.a[1];
    }

    /// One sample `x` of lane `l` (see [`LaneGt::step`]): `y = z0 + C·x`,
    /// `z0 = (z1 − a1·y) + 2C·x`, `z1 = C·x − a2·y`; returns `y`.
    #[inline(always)]
    fn step(&self, z: &mut [[f64; W]; 2], l: usize, x: f64) -> f64 {
        let cx = self.c[l] * x;
        let y = z[0][l] + cx;
        z[0][l] = (z[1][l] + self.na1[l] * y) + (cx + cx);
        z[1][l] = cx + self.na2[l] * y;
        y
    }

    /// The section over `buf` in place, state `z` carried.
    #[inline(always)]
    fn run(&self, z: &mut [[f64; W]; 2], buf: &mut [[f64; W]]) {
        let mut zs = *z;
        for v in buf.iter_mut() {
            for (l, x) in v.iter_mut().enumerate() {
                *x = self.step(&mut zs, l, *x);
            }
        }
        *z = zs;
    }
}

/// Coefficients and state of `W` channels, lane-major (unused lanes of a narrow bank
/// have zero coefficients and compute zeros that are never written out).
#[derive(Debug, Clone)]
struct Group<const W: usize> {
    lin_gain: [f64; W],
    /// Non-linear path input gain `mocIpsi·mocContra`.
    moc: [f64; W],
    gt_lin: LaneGt<W>,
    lp_lin: LaneLp<W>,
    gt_nl: LaneGt<W>,
    lp_nl: LaneLp<W>,
    /// The per-channel compression constants (see [`ChannelDesign::compression`]).
    comp: [[f64; W]; 2],
    z: [[[f64; W]; 2]; STATES],
}

/// The two paths of a group over one time block, `[time][lane]`.
#[derive(Debug, Clone)]
struct Paths<const W: usize> {
    lin: Vec<[f64; W]>,
    nl: Vec<[f64; W]>,
}

afe_core::simd_kernel!(
    fma,
    /// CASP: `lin = LP⁴(GT²(g·x))`, `nlin = LP(GT²(compress(GT²(moc·x))))`, out `lin + nlin`,
    /// for one group over one time block (at most the paths' length), `stride` values per
    /// output row. Section by section over the block, so that each recursion keeps its
    /// state in registers and the lanes' independent recursions hide each other's latency.
    /// Compiled for AVX-512 and AVX2 + FMA too, chosen at run time; every lane does the
    /// scalar operations in order, so the numbers depend neither on the instruction set nor
    /// on the lane. The filters fuse no multiply-add (they keep the reference's roundings);
    /// only [`ln_rough`] does, whose result is scaled by `delta` (about 5e−9) far below
    /// the output's last bit.
    fn run_casp<const W: usize>(
        g: &mut Group<W>,
        delta: f64,
        x: &[f64],
        paths: &mut Paths<W>,
        out: &mut [f64],
        stride: usize,
    ) {
        let lin = &mut paths.lin[..x.len()];
        let nl = &mut paths.nl[..x.len()];
        let z = &mut g.z;
        g.gt_lin.run_from(&mut z[0], x, &g.lin_gain, lin);
        g.gt_lin.run(&mut z[1], lin);
        for zs in &mut z[2..6] {
            g.lp_lin.run(zs, lin);
        }
        g.gt_nl.run_from(&mut z[6], x, &g.moc, nl);
        let [ca, cb] = g.comp;
        g.gt_nl.run_then(&mut z[7], nl, |v| {
            for l in 0..W {
                v[l] = casp_compress(v[l], ca[l], cb[l], delta);
            }
        });
        for zs in &mut z[8..10] {
            g.gt_nl.run(zs, nl);
        }
        let lp = &g.lp_nl;
        sum_into(&mut z[10], nl, lin, out, stride, |zs, l, x| {
            lp.step(zs, l, x)
        });
    }
);

afe_core::simd_kernel!(
    /// MAP: `lin = GT³(500·x)`, `nlin = GT³(compress(GT³(moc·x)))`, out `lin + nlin`, for
    /// one group over one time block of the middle-ear output (see [`run_casp`]).
    fn run_map<const W: usize>(
        g: &mut Group<W>,
        ct_bm: f64,
        x: &[f64],
        paths: &mut Paths<W>,
        out: &mut [f64],
        stride: usize,
    ) {
        let lin = &mut paths.lin[..x.len()];
        let nl = &mut paths.nl[..x.len()];
        let z = &mut g.z;
        g.gt_lin.run_from(&mut z[0], x, &g.lin_gain, lin);
        for zs in &mut z[1..3] {
            g.gt_lin.run(zs, lin);
        }
        g.gt_nl.run_from(&mut z[3], x, &g.moc, nl);
        g.gt_nl.run(&mut z[4], nl);
        let [ca, cts] = g.comp;
        g.gt_nl.run_then(&mut z[5], nl, |v| {
            for l in 0..W {
                v[l] = map_compress(v[l], ca[l], cts[l], ct_bm);
            }
        });
        for zs in &mut z[6..8] {
            g.gt_nl.run(zs, nl);
        }
        let gt = &g.gt_nl;
        sum_into(&mut z[8], nl, lin, out, stride, |zs, l, x| {
            gt.step(zs, l, x)
        });
    }
);

/// MAP's middle-ear stage shared by all channels: `x1 = 20e−5·10^5·x`, tympanic-membrane
/// one-pole low-pass (50 Hz), stapes one-pole high-pass (1 kHz), times 45e−9.
#[derive(Debug, Clone)]
struct MapMiddleEar {
    scale: f64,
    tm: Df2t,
    stapes: Df2t,
}

impl MapMiddleEar {
    fn new(fs: f64) -> Self {
        let dt = 1.0 / fs;
        let tau = 1.0 / (2.0 * PI * 50.0);
        let a1 = dt / tau - 1.0;
        let t = (PI * 1000.0 * dt).tan();
        let g = 1.0 / (1.0 + t);
        let hc = (1.0 - t) / (1.0 + t);
        MapMiddleEar {
            scale: 20e-5 * exp10(100.0 / 20.0),
            tm: Df2t::new(&[1.0 + a1], &[1.0, a1], 1),
            stapes: Df2t::new(&[g, -g], &[1.0, -hc], 1),
        }
    }

    /// `x` through the stage into `out` (as long).
    fn run(&mut self, x: &[f64], out: &mut [f64]) {
        for (o, v) in out.iter_mut().zip(x) {
            *o = v * self.scale;
        }
        self.tm.process(out);
        self.stapes.process(out);
        for o in out.iter_mut() {
            *o *= 45e-9;
        }
    }

    fn reset(&mut self) {
        self.tm.reset();
        self.stapes.reset();
    }
}

/// Samples per pass over the groups: both paths of a group stay in the L1 cache
/// (2 × 8 KiB) from section to section.
const TIME_BLOCK: usize = 64;
/// Channels per group: four AVX2 registers per operation, whose independent recursions
/// hide each other's latency while a section's state stays in registers (measured
/// against 8 and 32: 8 waits on the recursion, 32 spills the state).
const LANES: usize = 16;

/// The DRNL filterbank of one ear: time-domain in, `[time][channel]` out.
#[derive(Debug, Clone)]
pub struct Drnl {
    model: DrnlModel,
    groups: Vec<Group<LANES>>,
    /// First channel of each group; with `LANES` channels or more the last group ends at
    /// the last channel, overlapping its neighbour (an overlapped channel is computed
    /// twice, identically).
    starts: Vec<usize>,
    channels: usize,
    /// CASP: the exponent's distance from 1/4; MAP: `ctBM`.
    model_constant: f64,
    middle_ear: Option<MapMiddleEar>,
    /// MAP middle-ear output of the current time block.
    stage: Vec<f64>,
    /// Both paths of the group being computed, one time block.
    paths: Paths<LANES>,
    /// Full-width rows of a bank narrower than `LANES` channels (empty otherwise).
    partial: Vec<f64>,
    moc_ipsi: Vec<f64>,
    moc_contra: Vec<f64>,
    /// `fb_mocIpsi` and `fb_mocContra` as the parameters give them, for `reset`.
    moc_given: [Vec<f64>; 2],
}

impl Drnl {
    /// Designs the DRNL for input rate `fs` Hz from the DRNL's parameters of `params`
    /// (grid, `fb_model`, `fb_mocIpsi`, `fb_mocContra`); returns it with its output
    /// signal.
    pub fn new(params: &FilterbankParams, fs: f64) -> Result<(Self, SignalInfo)> {
        let grid = params.grid()?;
        grid.check_below_nyquist(params, fs)?;
        if let Some(&f) = grid.cf_hz.iter().find(|&&f| f <= 0.0) {
            // its bandwidths and gains are powers of log10(cf): NaN at 0 Hz
            let (name, value) = if params.cf_hz.is_empty() {
                ("fb_lowFreqHz", params.low_freq_hz.to_string())
            } else {
                ("fb_cfHz", format!("{:?}", params.cf_hz))
            };
            return Err(Error::invalid(
                name,
                value,
                format!("the DRNL needs centre frequencies above 0 Hz, and one is {f} Hz"),
            ));
        }
        let nc = grid.cf_hz.len();
        let moc_ipsi = per_channel("fb_mocIpsi", &params.moc_ipsi, nc)?;
        let moc_contra = per_channel("fb_mocContra", &params.moc_contra, nc)?;
        let designs: Vec<ChannelDesign> = grid
            .cf_hz
            .iter()
            .map(|&f| match params.model {
                DrnlModel::Casp => casp_channel(f, fs),
                DrnlModel::Map => map_channel(f, fs),
            })
            .collect();
        let starts: Vec<usize> = (0..nc.div_ceil(LANES))
            .map(|g| vector_start(g, LANES, nc))
            .collect();
        let empty = Group {
            lin_gain: [0.0; LANES],
            moc: [0.0; LANES],
            gt_lin: LaneGt::ZERO,
            lp_lin: LaneLp::ZERO,
            gt_nl: LaneGt::ZERO,
            lp_nl: LaneLp::ZERO,
            comp: [[0.0; LANES]; 2],
            z: [[[0.0; LANES]; 2]; STATES],
        };
        let mut groups = vec![empty; starts.len()];
        for (g, &c0) in groups.iter_mut().zip(&starts) {
            for (l, d) in designs[c0..].iter().take(LANES).enumerate() {
                g.lin_gain[l] = d.lin_gain;
                g.gt_lin.set(l, &d.gt_lin);
                g.gt_nl.set(l, &d.gt_nl);
                if let (Some(lin), Some(nl)) = (&d.lp_lin, &d.lp_nl) {
                    g.lp_lin.set(l, lin);
                    g.lp_nl.set(l, nl);
                }
                g.comp[0][l] = d.compression.0;
                g.comp[1][l] = d.compression.1;
            }
        }
        let (model_constant, middle_ear) = match params.model {
            DrnlModel::Casp => (casp_exponent() - 0.25, None),
            DrnlModel::Map => (map_threshold(), Some(MapMiddleEar::new(fs))),
        };
        let mut drnl = Drnl {
            model: params.model,
            groups,
            starts,
            channels: nc,
            model_constant,
            stage: if middle_ear.is_some() {
                vec![0.0; TIME_BLOCK]
            } else {
                Vec::new()
            },
            middle_ear,
            paths: Paths {
                lin: vec![[0.0; LANES]; TIME_BLOCK],
                nl: vec![[0.0; LANES]; TIME_BLOCK],
            },
            partial: if nc < LANES {
                vec![0.0; TIME_BLOCK * LANES]
            } else {
                Vec::new()
            },
            moc_given: [moc_ipsi.clone(), moc_contra.clone()],
            moc_ipsi,
            moc_contra,
        };
        drnl.apply_moc();
        Ok((drnl, SignalInfo::time_frequency(fs, grid.cf_hz)))
    }

    /// The ipsilateral MOC gains, one per channel.
    pub fn moc_ipsi(&self) -> &[f64] {
        &self.moc_ipsi
    }

    /// The contralateral MOC gains, one per channel.
    pub fn moc_contra(&self) -> &[f64] {
        &self.moc_contra
    }

    /// Replaces the MOC gains (one per channel each; the non-linear path's input is
    /// multiplied by `ipsi[c]·contra[c]`) from the next chunk on, keeping every filter
    /// state: the AFE's MOC feedback. Refuses vectors of another length.
    pub fn set_moc(&mut self, ipsi: &[f64], contra: &[f64]) -> Result<()> {
        let nc = self.channels;
        for (name, v) in [("fb_mocIpsi", ipsi), ("fb_mocContra", contra)] {
            if v.len() != nc {
                return Err(Error::invalid(
                    name,
                    format_args!("{v:?}"),
                    format!("expected {nc} values (one per channel), got {}", v.len()),
                ));
            }
        }
        self.moc_ipsi.copy_from_slice(ipsi);
        self.moc_contra.copy_from_slice(contra);
        self.apply_moc();
        Ok(())
    }

    /// Puts `ipsi·contra` of every channel into its lanes.
    fn apply_moc(&mut self) {
        for (g, &c0) in self.groups.iter_mut().zip(&self.starts) {
            for (l, m) in g.moc.iter_mut().enumerate() {
                let c = c0 + l;
                *m = if c < self.channels {
                    self.moc_ipsi[c] * self.moc_contra[c]
                } else {
                    0.0
                };
            }
        }
    }

    /// Filters `x` (time-domain) into `out` (`x.len()` rows of one value per channel).
    pub fn filter(&mut self, x: &[f64], out: &mut [f64]) {
        let nc = self.channels;
        let konst = self.model_constant;
        for (x, out) in x.chunks(TIME_BLOCK).zip(out.chunks_mut(TIME_BLOCK * nc)) {
            let input: &[f64] = match &mut self.middle_ear {
                Some(me) => {
                    let stage = &mut self.stage[..x.len()];
                    me.run(x, stage);
                    stage
                }
                None => x,
            };
            let run = match self.model {
                DrnlModel::Casp => run_casp::<LANES>,
                DrnlModel::Map => run_map::<LANES>,
            };
            for (g, &c0) in self.groups.iter_mut().zip(&self.starts) {
                if nc >= LANES {
                    run(g, konst, input, &mut self.paths, &mut out[c0..], nc);
                } else {
                    let rows = &mut self.partial[..input.len() * LANES];
                    run(g, konst, input, &mut self.paths, rows, LANES);
                    for (o, r) in out.chunks_exact_mut(nc).zip(rows.chunks_exact(LANES)) {
                        o.copy_from_slice(&r[..nc]);
                    }
                }
            }
        }
    }
}

impl Processor for Drnl {
    fn process(&mut self, inputs: &[&Block], outputs: &mut [Block]) {
        let x = inputs[0].as_slice();
        let out = outputs[0].resize_to(x.len());
        self.filter(x, out);
    }

    /// Zeroes every section state, and MAP's middle-ear states too (the AFE keeps those
    /// across a reset, spec zz N16; a fresh state is what a reset promises), and returns
    /// to the MOC gains of the parameters.
    fn reset(&mut self) {
        for g in &mut self.groups {
            g.z = [[[0.0; LANES]; 2]; STATES];
        }
        if let Some(me) = &mut self.middle_ear {
            me.reset();
        }
        let [ipsi, contra] = &self.moc_given;
        self.moc_ipsi.clone_from(ipsi);
        self.moc_contra.clone_from(contra);
        self.apply_moc();
    }

    /// The MOC's feedback (spec 28): row 0 the new `fb_mocIpsi`, row 1 the new
    /// `fb_mocContra`, one value per channel.
    fn receive_feedback(&mut self, feedback: &Block) {
        if feedback.frames() == 2 && feedback.width() == self.channels {
            self.moc_ipsi.copy_from_slice(feedback.row(0));
            self.moc_contra.copy_from_slice(feedback.row(1));
            self.apply_moc();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::feed;
    use afe_core::Params;
    use proptest::prelude::*;
    use realfft::num_complex::Complex64;
    use serde_json::Value;

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

    fn params(model: DrnlModel, n_channels: u32) -> FilterbankParams {
        FilterbankParams {
            model,
            n_channels: Some(n_channels),
            ..Default::default()
        }
    }

    fn signal(len: usize) -> Vec<f64> {
        (0..len)
            .map(|t| {
                0.05 * (((t * 7919) % 1000) as f64 / 500.0 - 1.0) * (1.0 + (t as f64 * 0.003).sin())
            })
            .collect()
    }

    fn run(p: &FilterbankParams, x: &[f64]) -> Vec<f64> {
        let (mut d, info) = Drnl::new(p, 44100.0).expect("valid");
        let mut y = vec![0.0; x.len() * info.channels()];
        d.filter(x, &mut y);
        y
    }

    #[test]
    fn silence_gives_exact_zeros() {
        for model in [DrnlModel::Casp, DrnlModel::Map] {
            let y = run(&params(model, 7), &vec![0.0; 3000]);
            assert!(y.iter().all(|v| *v == 0.0), "{model:?}");
        }
    }

    /// One channel as the spec writes it: generic DF2T sections (spec 01-P1) in series.
    fn reference_channel(d: &ChannelDesign, model: DrnlModel, x: &[f64]) -> Vec<f64> {
        let section = |s: &Biquad, v: &mut Vec<f64>| {
            let mut z = [0.0; 2];
            for x in v.iter_mut() {
                let y = z[0] + s.b[0] * *x;
                z[0] = (z[1] - s.a[0] * y) + s.b[1] * *x;
                z[1] = s.b[2] * *x - s.a[1] * y;
                *x = y;
            }
        };
        let mut lin: Vec<f64> = x.iter().map(|v| d.lin_gain * v).collect();
        let mut nl = x.to_vec();
        let (gts, lps) = if model == DrnlModel::Casp {
            (2, 4)
        } else {
            (3, 0)
        };
        for _ in 0..gts {
            section(&d.gt_lin, &mut lin);
            section(&d.gt_nl, &mut nl);
        }
        for _ in 0..lps {
            section(&d.lp_lin.expect("CASP"), &mut lin);
        }
        let (a, b) = d.compression;
        for v in &mut nl {
            *v = match model {
                DrnlModel::Casp => casp_compress(*v, a, b, casp_exponent() - 0.25),
                DrnlModel::Map => map_compress(*v, a, b, map_threshold()),
            };
        }
        for _ in 0..gts {
            section(&d.gt_nl, &mut nl);
        }
        if let Some(lp) = &d.lp_nl {
            section(lp, &mut nl);
        }
        lin.iter().zip(&nl).map(|(l, n)| l + n).collect()
    }

    /// MAP's input scaling and middle ear as spec 12 writes them: `x1 = 20·x`, the TM
    /// low-pass `y[n] = b0·x1[n] − a1·y[n−1]` and the stapes high-pass
    /// `s[n] = G·y[n] − G·y[n−1] + Hc·s[n−1]`, times 45e−9; in two calls (its states carry
    /// over).
    #[test]
    fn maps_middle_ear_follows_the_spec_equations() {
        for fs in [44100.0, 16000.0] {
            let x = signal(1200);
            let dt = 1.0 / fs;
            let a1 = dt * 2.0 * PI * 50.0 - 1.0;
            let b0 = 1.0 + a1;
            let t = (PI * 1000.0 / fs).tan();
            let (g, hc) = (1.0 / (1.0 + t), (1.0 - t) / (1.0 + t));
            let (mut y_prev, mut s_prev) = (0.0, 0.0);
            let want: Vec<f64> = x
                .iter()
                .map(|v| {
                    let y = b0 * 20.0 * v - a1 * y_prev;
                    let s = g * y - g * y_prev + hc * s_prev;
                    (y_prev, s_prev) = (y, s);
                    45e-9 * s
                })
                .collect();
            let mut me = MapMiddleEar::new(fs);
            let mut got = vec![0.0; x.len()];
            me.run(&x[..500], &mut got[..500]);
            me.run(&x[500..], &mut got[500..]);
            let top = want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for (n, (a, b)) in got.iter().zip(&want).enumerate() {
                assert!((a - b).abs() <= 1e-12 * top, "{fs} Hz, n = {n}: {a} vs {b}");
            }
        }
    }

    #[test]
    fn lanes_compute_the_plain_cascade() {
        let fs = 44100.0;
        let x = signal(2000);
        for model in [DrnlModel::Casp, DrnlModel::Map] {
            for nc in [5u32, 31] {
                let p = params(model, nc);
                let y = run(&p, &x);
                let mut stage = x.clone();
                if model == DrnlModel::Map {
                    MapMiddleEar::new(fs).run(&x, &mut stage);
                }
                for (c, &f) in p.grid().expect("valid").cf_hz.iter().enumerate() {
                    let d = match model {
                        DrnlModel::Casp => casp_channel(f, fs),
                        DrnlModel::Map => map_channel(f, fs),
                    };
                    let want = reference_channel(&d, model, &stage);
                    let nc = nc as usize;
                    for (t, w) in want.iter().enumerate() {
                        assert!(w.abs() > 0.0 || t == 0);
                        assert_eq!(y[t * nc + c], *w, "{model:?} channel {c} t={t}");
                    }
                }
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 32, failure_persistence: None, ..ProptestConfig::default() })]

        /// Any chunking, empty chunks included, gives the output of one call, bit for bit.
        #[test]
        fn chunking_does_not_change_a_bit(
            sizes in prop::collection::vec(prop_oneof![Just(0usize), 1usize..80, 80usize..900], 1..20),
            map in any::<bool>(),
            nc in prop_oneof![Just(3u32), Just(16u32), Just(21u32)],
        ) {
            let model = if map { DrnlModel::Map } else { DrnlModel::Casp };
            let p = params(model, nc);
            let x = signal(3000);
            let whole = run(&p, &x);
            let (mut d, _) = Drnl::new(&p, 44100.0).expect("valid");
            let sizes = sizes.iter().copied().chain([500]).cycle();
            let chunked = feed(&mut d, &x, 1, nc as usize, sizes.take(4000));
            prop_assert_eq!(whole.len(), chunked.len());
            let first = whole.iter().zip(&chunked).position(|(a, b)| a.to_bits() != b.to_bits());
            prop_assert!(first.is_none(), "{:?} {} channels: first difference at {:?}", model, nc, first);
        }
    }

    #[test]
    fn reset_restarts_every_state_including_maps_middle_ear() {
        let x = signal(1500);
        for model in [DrnlModel::Casp, DrnlModel::Map] {
            let p = params(model, 9);
            let (mut d, _) = Drnl::new(&p, 44100.0).expect("valid");
            let mut first = vec![0.0; x.len() * 9];
            d.filter(&x, &mut first);
            d.reset();
            let mut second = vec![0.0; x.len() * 9];
            d.filter(&x, &mut second);
            assert_eq!(first, second, "{model:?}");
        }
    }

    /// The non-linear path's gain is `ipsi·contra` per channel, from parameters or from
    /// [`Drnl::set_moc`] between chunks.
    #[test]
    fn moc_gains_scale_the_non_linear_path() {
        let x = signal(1200);
        let nc = 4;
        let base = params(DrnlModel::Casp, nc as u32);
        let split = FilterbankParams {
            moc_ipsi: vec![0.5],
            moc_contra: vec![2.0, 2.0, 2.0, 2.0],
            ..base.clone()
        };
        assert_eq!(run(&base, &x), run(&split, &x));
        let off = FilterbankParams {
            moc_ipsi: vec![0.0],
            ..base.clone()
        };
        let (mut d, _) = Drnl::new(&base, 44100.0).expect("valid");
        let mut y = vec![0.0; x.len() * nc];
        d.set_moc(&[0.0; 4], &[1.0; 4]).expect("four channels");
        assert_eq!(d.moc_ipsi(), &[0.0; 4]);
        d.filter(&x, &mut y);
        assert_eq!(y, run(&off, &x));
        assert_ne!(y, run(&base, &x));
        let e = d
            .set_moc(&[1.0; 3], &[1.0; 4])
            .expect_err("3 of 4")
            .to_string();
        assert!(
            e.contains("'fb_mocIpsi'") && e.contains("expected 4 values"),
            "{e}"
        );
        // the MOC's feedback (rows: ipsi, contra) sets the same gains; reset restores
        // the parameters' ones
        let (mut d, _) = Drnl::new(&base, 44100.0).expect("valid");
        let mut fed = [0.0; 8];
        fed[4..].fill(1.0);
        d.receive_feedback(&Block::from_vec(fed.to_vec(), 4));
        // anything but two rows of four (no frame from the MOC this chunk, another
        // width) leaves the gains as they are
        for other in [
            Block::new(4),
            Block::from_vec(vec![0.5; 4], 4),
            Block::from_vec(vec![0.5; 8], 2),
        ] {
            d.receive_feedback(&other);
            assert_eq!(
                (d.moc_ipsi(), d.moc_contra()),
                (&[0.0; 4][..], &[1.0; 4][..])
            );
        }
        let mut z = vec![0.0; x.len() * nc];
        d.filter(&x, &mut z);
        assert_eq!(z, y);
        d.reset();
        assert_eq!(
            (d.moc_ipsi(), d.moc_contra()),
            (&[1.0; 4][..], &[1.0; 4][..])
        );
        d.filter(&x, &mut z);
        assert_eq!(z, run(&base, &x));
    }

    fn from_map(pairs: &[(&str, Value)]) -> Result<FilterbankParams> {
        FilterbankParams::from_map(
            &pairs
                .iter()
                .map(|(k, v)| (k.to_string(), v.clone()))
                .collect(),
        )
    }

    #[test]
    fn bad_parameters_are_clear_errors() {
        let e = from_map(&[("fb_type", json!("drnl")), ("fb_model", json!("casp"))])
            .expect_err("unknown model")
            .to_string();
        assert!(
            e.contains("'fb_model'") && e.contains("'CASP', 'MAP'"),
            "{e}"
        );
        let e = from_map(&[("fb_type", json!("dnrl"))])
            .expect_err("unknown type")
            .to_string();
        assert!(
            e.contains("'fb_type'") && e.contains("'gammatone', 'drnl'"),
            "{e}"
        );
        let p = from_map(&[("fb_type", json!("drnl")), ("fb_mocIpsi", json!([1, 1, 1]))])
            .expect("a vector is accepted before the grid is known");
        for e in [
            Drnl::new(&p, 44100.0).expect_err("3 of 31").to_string(),
            verified(&p).expect_err("3 of 31").to_string(),
        ] {
            assert!(
                e.contains("'fb_mocIpsi'")
                    && e.contains("expected one value or 31 (one per channel), got 3"),
                "{e}"
            );
        }
        let e = Drnl::new(&params(DrnlModel::Casp, 8), 15000.0)
            .expect_err("8 kHz at 15 kHz")
            .to_string();
        assert!(
            e.contains("'fb_highFreqHz'") && e.contains("Nyquist"),
            "{e}"
        );
        // a lowest frequency that rounds to a centre frequency of 0 Hz gave NaN
        let p = from_map(&[
            ("fb_type", json!("drnl")),
            ("fb_lowFreqHz", json!(8.8e-16)),
            ("fb_nChannels", json!(4)),
        ])
        .expect("parsed");
        let e = Drnl::new(&p, 44100.0).expect_err("0 Hz").to_string();
        assert!(
            e.contains("'fb_lowFreqHz'")
                && e.contains("the DRNL needs centre frequencies above 0 Hz, and one is 0 Hz"),
            "{e}"
        );
    }

    #[test]
    fn verified_map_expands_the_moc_gains() {
        let map = verified(&FilterbankParams {
            moc_contra: vec![0.5],
            ..Default::default()
        })
        .expect("valid");
        assert_eq!(map["fb_mocContra"], json!(vec![0.5; 31]));
        assert_eq!(map["fb_mocIpsi"], json!(vec![1.0; 31]));
        assert_eq!(map["fb_model"], json!("CASP"));
        let mut keys: Vec<&str> = map.keys().map(String::as_str).collect();
        keys.sort_unstable();
        assert_eq!(
            keys,
            [
                "fb_cfHz",
                "fb_highFreqHz",
                "fb_lowFreqHz",
                "fb_mocContra",
                "fb_mocIpsi",
                "fb_model",
                "fb_nChannels",
                "fb_nERBs"
            ]
        );
    }
}
