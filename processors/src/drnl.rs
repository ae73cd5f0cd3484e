//! `filterbank` with `fb_type = 'drnl'`: the dual-resonance non-linear basilar-membrane
//! filterbank (spec 12-drnl), per channel the sum of a linear path and a compressive
//! non-linear path, each a cascade of second-order sections run as DF2T in f64 with the
//! reference's operation order. Two parameter sets: CASP (Jepsen et al. 2008, default)
//! and MAP 1.14h. The request and the grid are [`crate::filterbank`]'s.
//!
//! Reproduced as the AFE computes them: the gammatone-like sections take the low-pass
//! cut-offs as centre frequencies, CASP's compression constants jump at 1000 Hz, MAP
//! scales its input by 20 (`20e−5·10^5`). The non-linear path's gain is `fb_mocIpsi[c] ·
//! fb_mocContra[c]` per channel, replaceable at run time ([`Drnl::set_moc`]).

use std::f64::consts::{LN_2, PI, SQRT_2};

use afe_core::filter::Df2t;
use afe_core::lanes::vector_start;
use afe_core::{Block, ParamMap, Processor, Result, SignalInfo};
use serde::{Deserialize, Serialize};
use serde_json::json;

use crate::filterbank::{invalid, FilterbankParams};

/// DRNL parameter set (AFE `fb_model`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum DrnlModel {
    /// Lopez-Poveda & Meddis (2001) as used in CASP (Jepsen et al. 2008): low-pass
    /// sections on both paths, broken-stick compression.
    #[serde(rename = "CASP")]
    Casp,
    /// MAP 1.14h: middle-ear (tympanic membrane and stapes) stage, no low-pass sections,
    /// compression above a threshold.
    #[serde(rename = "MAP")]
    Map,
}

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

/// `values` as one value per channel: one value repeated, or exactly `n`.
fn per_channel(name: &str, values: &[f64], n: usize) -> Result<Vec<f64>> {
    match values.len() {
        1 => Ok(vec![values[0]; n]),
        len if len == n => Ok(values.to_vec()),
        len => Err(invalid(
            name,
            values,
            format!("expected one value or {n} (one per channel), got {len}"),
        )),
    }
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
/// to 1e−9 (its error is multiplied by `delta`). Vectorises, unlike `powf`: CASP's
/// exponent is 1/4 − 5e−9, and rounding it to 1/4 would move the compressed values by
/// up to 1e−7 relative.
#[inline(always)]
fn pow_quarter_plus(x: f64, delta: f64) -> f64 {
    let t = delta * ln_rough(x);
    x.sqrt().sqrt() * (1.0 + t * (1.0 + 0.5 * t))
}

/// `ln x` for `x ≥ 0` within 1e−9 for normal `x` (finite for 0, subnormals and ∞):
/// exponent and mantissa from the bits, the mantissa brought into [√½, √2), and
/// `ln m = 2·atanh((m − 1)/(m + 1))` by its series to the 9th power.
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
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    let series = 1.0 + s2 * (1.0 / 3.0 + s2 * (0.2 + s2 * (1.0 / 7.0 + s2 * (1.0 / 9.0))));
    e * LN_2 + 2.0 * s * series
}

/// CASP's broken-stick non-linearity `sign(u)·min(a·|u|, b·|u|^c)`, `c = 1/4 + delta`.
#[inline(always)]
fn casp_compress(u: f64, a: f64, b: f64, delta: f64) -> f64 {
    let au = u.abs();
    (a * au).min(b * pow_quarter_plus(au, delta)).copysign(u)
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

/// One section's coefficients across `W` channels.
#[derive(Debug, Clone, Copy)]
struct LaneBiquad<const W: usize> {
    b0: [f64; W],
    b1: [f64; W],
    b2: [f64; W],
    a1: [f64; W],
    a2: [f64; W],
}

impl<const W: usize> LaneBiquad<W> {
    const ZERO: Self = LaneBiquad {
        b0: [0.0; W],
        b1: [0.0; W],
        b2: [0.0; W],
        a1: [0.0; W],
        a2: [0.0; W],
    };

    fn set(&mut self, lane: usize, s: &Biquad) {
        self.b0[lane] = s.b[0];
        self.b1[lane] = s.b[1];
        self.b2[lane] = s.b[2];
        self.a1[lane] = s.a[0];
        self.a2[lane] = s.a[1];
    }

    /// One DF2T step of every lane on `v`, in place (spec 01-P1 operation order:
    /// `y = z0 + b0·x`, `z0 = (z1 − a1·y) + b1·x`, `z1 = b2·x − a2·y`).
    #[inline(always)]
    fn step(&self, z: &mut [[f64; W]; 2], v: &mut [f64; W]) {
        for l in 0..W {
            let x = v[l];
            let y = z[0][l] + self.b0[l] * x;
            z[0][l] = (z[1][l] - self.a1[l] * y) + self.b1[l] * x;
            z[1][l] = self.b2[l] * x - self.a2[l] * y;
            v[l] = y;
        }
    }
}

/// Coefficients and state of `W` channels, lane-major (unused lanes of a narrow bank
/// have zero coefficients and compute zeros that are never written out).
#[derive(Debug, Clone)]
struct Group<const W: usize> {
    lin_gain: [f64; W],
    /// Non-linear path input gain `mocIpsi·mocContra`.
    moc: [f64; W],
    gt_lin: LaneBiquad<W>,
    lp_lin: LaneBiquad<W>,
    gt_nl: LaneBiquad<W>,
    lp_nl: LaneBiquad<W>,
    /// The per-channel compression constants (see [`ChannelDesign::compression`]).
    comp: [[f64; W]; 2],
    z: [[[f64; W]; 2]; STATES],
}

/// CASP: `lin = LP⁴(GT²(g·x))`, `nlin = LP(GT²(compress(GT²(moc·x))))`, out `lin + nlin`,
/// for one group over a chunk, `stride` values per output row. Compiled for AVX-512 and
/// AVX2 too, chosen at run time; every lane does the scalar operations in order, so the
/// numbers do not depend on the instruction set or the lane.
#[multiversion::multiversion(targets("x86_64+avx512f+avx512vl", "x86_64+avx2"))]
fn run_casp<const W: usize>(
    g: &mut Group<W>,
    delta: f64,
    x: &[f64],
    out: &mut [f64],
    stride: usize,
) {
    let mut z = g.z;
    let (gt_lin, lp_lin, gt_nl, lp_nl) = (&g.gt_lin, &g.lp_lin, &g.gt_nl, &g.lp_nl);
    let [ca, cb] = g.comp;
    for (t, &xin) in x.iter().enumerate() {
        let mut lin = [0.0; W];
        let mut nl = [0.0; W];
        for l in 0..W {
            lin[l] = g.lin_gain[l] * xin;
            nl[l] = g.moc[l] * xin;
        }
        for zs in &mut z[0..2] {
            gt_lin.step(zs, &mut lin);
        }
        for zs in &mut z[2..6] {
            lp_lin.step(zs, &mut lin);
        }
        for zs in &mut z[6..8] {
            gt_nl.step(zs, &mut nl);
        }
        for l in 0..W {
            nl[l] = casp_compress(nl[l], ca[l], cb[l], delta);
        }
        for zs in &mut z[8..10] {
            gt_nl.step(zs, &mut nl);
        }
        lp_nl.step(&mut z[10], &mut nl);
        let row = &mut out[t * stride..t * stride + W];
        for l in 0..W {
            row[l] = lin[l] + nl[l];
        }
    }
    g.z = z;
}

/// MAP: `lin = GT³(500·x)`, `nlin = GT³(compress(GT³(moc·x)))`, out `lin + nlin`, for
/// one group over a chunk of the middle-ear output (see [`run_casp`]).
#[multiversion::multiversion(targets("x86_64+avx512f+avx512vl", "x86_64+avx2"))]
fn run_map<const W: usize>(
    g: &mut Group<W>,
    ct_bm: f64,
    x: &[f64],
    out: &mut [f64],
    stride: usize,
) {
    let mut z = g.z;
    let (gt_lin, gt_nl) = (&g.gt_lin, &g.gt_nl);
    let [ca, cts] = g.comp;
    for (t, &xin) in x.iter().enumerate() {
        let mut lin = [0.0; W];
        let mut nl = [0.0; W];
        for l in 0..W {
            lin[l] = g.lin_gain[l] * xin;
            nl[l] = g.moc[l] * xin;
        }
        for zs in &mut z[0..3] {
            gt_lin.step(zs, &mut lin);
        }
        for zs in &mut z[3..6] {
            gt_nl.step(zs, &mut nl);
        }
        for l in 0..W {
            nl[l] = map_compress(nl[l], ca[l], cts[l], ct_bm);
        }
        for zs in &mut z[6..9] {
            gt_nl.step(zs, &mut nl);
        }
        let row = &mut out[t * stride..t * stride + W];
        for l in 0..W {
            row[l] = lin[l] + nl[l];
        }
    }
    g.z = z;
}

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

/// Samples per pass over the groups: a long input's output rows stay in cache while
/// every group writes its lanes of them, and MAP's middle-ear output fits a fixed buffer.
const TIME_BLOCK: usize = 512;
/// Channels per group: two AVX2 registers (one AVX-512 register) per operation. Wider
/// groups only spill the eleven sections' states.
const LANES: usize = 8;

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
    /// Full-width rows of a bank narrower than `LANES` channels (empty otherwise).
    partial: Vec<f64>,
    moc_ipsi: Vec<f64>,
    moc_contra: Vec<f64>,
}

impl Drnl {
    /// Designs the DRNL for input rate `fs` Hz from the DRNL's parameters of `params`
    /// (grid, `fb_model`, `fb_mocIpsi`, `fb_mocContra`); returns it with its output
    /// signal.
    pub fn new(params: &FilterbankParams, fs: f64) -> Result<(Self, SignalInfo)> {
        let grid = params.grid()?;
        grid.check_below_nyquist(params, fs)?;
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
            gt_lin: LaneBiquad::ZERO,
            lp_lin: LaneBiquad::ZERO,
            gt_nl: LaneBiquad::ZERO,
            lp_nl: LaneBiquad::ZERO,
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
            partial: if nc < LANES {
                vec![0.0; TIME_BLOCK * LANES]
            } else {
                Vec::new()
            },
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
                return Err(invalid(
                    name,
                    v,
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
                    run(g, konst, input, &mut out[c0..], nc);
                } else {
                    let rows = &mut self.partial[..input.len() * LANES];
                    run(g, konst, input, rows, LANES);
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
    /// across a reset, spec zz N16; a fresh state is what a reset promises).
    fn reset(&mut self) {
        for g in &mut self.groups {
            g.z = [[[0.0; LANES]; 2]; STATES];
        }
        if let Some(me) = &mut self.middle_ear {
            me.reset();
        }
    }
}
