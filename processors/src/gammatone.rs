//! `filterbank` with `fb_type = 'gammatone'`: complex all-pole gammatone filters on an
//! ERB-spaced grid (spec 11-gammatone), each run as one order-n DF2T filter in complex f64.
//!
//! The coefficients follow the reference recipe operation by operation (component-wise
//! division by fs, convolution as `a[k] + (−p)·a[k−1]`, textbook complex products, no FMA):
//! the expanded polynomial is ill-conditioned at low centre frequencies, and this recipe
//! reproduces the MATLAB AFE bit for bit.

use std::f64::consts::PI;

use afe_core::erb::{colon_range, erb2freq, freq2erb, linspace};
use afe_core::lanes::vector_start;
use afe_core::{
    Block, Error, ParamKind, ParamMap, ParamSpec, Params, Processor, Result, SignalInfo,
};
use serde::{Deserialize, Serialize};
use serde_json::{json, Value};

use crate::cpu::has_avx512;

use crate::registry::{request_def, Built, Descriptor, Ears, RequestDef};

/// Parameters of the gammatone filterbank, under their AFE names.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GammatoneParams {
    /// Filterbank type (AFE `fb_type`); only `'gammatone'` is implemented.
    #[serde(rename = "fb_type")]
    pub fb_type: String,
    /// Lowest centre frequency in Hz (AFE `fb_lowFreqHz`).
    #[serde(rename = "fb_lowFreqHz")]
    pub low_freq_hz: f64,
    /// Highest requested centre frequency in Hz (AFE `fb_highFreqHz`).
    #[serde(rename = "fb_highFreqHz")]
    pub high_freq_hz: f64,
    /// Channel spacing in ERBs (AFE `fb_nERBs`).
    #[serde(rename = "fb_nERBs")]
    pub n_erbs: f64,
    /// Number of channels; overrides the spacing when given (AFE `fb_nChannels`).
    #[serde(rename = "fb_nChannels")]
    pub n_channels: Option<u32>,
    /// Explicit centre frequencies in Hz; highest priority when given (AFE `fb_cfHz`).
    #[serde(rename = "fb_cfHz")]
    pub cf_hz: Vec<f64>,
    /// Gammatone order (AFE `fb_nGamma`).
    #[serde(rename = "fb_nGamma")]
    pub n_gamma: u32,
    /// Bandwidth in ERBs (AFE `fb_bwERBs`).
    #[serde(rename = "fb_bwERBs")]
    pub bw_erbs: f64,
    /// Phase-align the impulse responses (AFE `fb_bAlign`).
    #[serde(rename = "fb_bAlign")]
    pub align: bool,
}

impl Default for GammatoneParams {
    fn default() -> Self {
        GammatoneParams {
            fb_type: "gammatone".into(),
            low_freq_hz: 80.0,
            high_freq_hz: 8000.0,
            n_erbs: 1.0,
            n_channels: None,
            cf_hz: Vec::new(),
            n_gamma: 4,
            bw_erbs: 1.018,
            align: false,
        }
    }
}

impl Params for GammatoneParams {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec {
            name: "fb_type",
            kind: ParamKind::Choice(&["gammatone"]),
            unit: "",
            description: "filterbank type",
        },
        ParamSpec {
            name: "fb_lowFreqHz",
            kind: ParamKind::Number,
            unit: "Hz",
            description: "lowest centre frequency",
        },
        ParamSpec {
            name: "fb_highFreqHz",
            kind: ParamKind::Number,
            unit: "Hz",
            description: "highest requested centre frequency",
        },
        ParamSpec {
            name: "fb_nERBs",
            kind: ParamKind::Number,
            unit: "ERB",
            description: "channel spacing on the ERB-number scale",
        },
        ParamSpec {
            name: "fb_nChannels",
            kind: ParamKind::Count,
            unit: "",
            description: "number of channels (overrides fb_nERBs; [] = derive from the spacing)",
        },
        ParamSpec {
            name: "fb_cfHz",
            kind: ParamKind::Numbers,
            unit: "Hz",
            description: "explicit centre frequencies (overrides everything; [] = derive)",
        },
        ParamSpec {
            name: "fb_nGamma",
            kind: ParamKind::Count,
            unit: "",
            description: "gammatone filter order",
        },
        ParamSpec {
            name: "fb_bwERBs",
            kind: ParamKind::Number,
            unit: "ERB",
            description: "filter bandwidth in ERBs",
        },
        ParamSpec {
            name: "fb_bAlign",
            kind: ParamKind::Flag,
            unit: "",
            description: "phase-align the channels' impulse responses",
        },
    ];
}

fn invalid(name: &str, value: impl std::fmt::Debug, reason: impl Into<String>) -> Error {
    // Debug prints a float in its shortest form, 1e308 rather than 309 digits
    Error::InvalidParameter {
        name: name.into(),
        value: format!("{value:?}"),
        reason: reason.into(),
    }
}

/// Highest `fb_highFreqHz` accepted, Hz: far above any sampling rate's Nyquist frequency,
/// low enough that the ERB grid up to it stays countable.
const MAX_HIGH_FREQ_HZ: f64 = 1e7;

/// The centre-frequency grid and derived values of a parameter set (the AFE's verify step).
#[derive(Debug, Clone, PartialEq)]
pub struct GammatoneGrid {
    /// Centre frequencies in Hz.
    pub cf_hz: Vec<f64>,
    /// Envelope-peak delay per channel in s, `3/(2π·bw)` (informational).
    pub delay_s: Vec<f64>,
    /// The parameter map as the AFE reports it after verification.
    pub map: ParamMap,
}

/// Largest filterbank: more channels than this is a parameter mistake, not a use case.
pub const MAX_CHANNELS: usize = 1024;

impl GammatoneParams {
    /// Checks the parameters and derives the grid (priority `fb_cfHz` > `fb_nChannels` >
    /// `fb_nERBs`), as the AFE's verify step does.
    pub fn grid(&self) -> Result<GammatoneGrid> {
        if self.bw_erbs <= 0.0 {
            return Err(invalid("fb_bwERBs", self.bw_erbs, "must be > 0"));
        }
        let (cf, n_erbs, low, high): (Vec<f64>, Value, f64, f64) = if !self.cf_hz.is_empty() {
            if let Some(bad) = self.cf_hz.iter().find(|f| **f <= 0.0) {
                return Err(invalid("fb_cfHz", bad, "centre frequencies must be > 0 Hz"));
            }
            if self.cf_hz.len() > MAX_CHANNELS {
                return Err(invalid(
                    "fb_cfHz",
                    format_args!("[{} values]", self.cf_hz.len()),
                    format!("at most {MAX_CHANNELS} channels are supported"),
                ));
            }
            let cf = self.cf_hz.clone();
            let (lo, hi) = (cf[0], cf[cf.len() - 1]);
            (cf, json!("n/a"), lo, hi)
        } else {
            if self.low_freq_hz <= 0.0 {
                return Err(invalid("fb_lowFreqHz", self.low_freq_hz, "must be > 0 Hz"));
            }
            if self.high_freq_hz.is_nan() || self.high_freq_hz > MAX_HIGH_FREQ_HZ {
                return Err(invalid(
                    "fb_highFreqHz",
                    self.high_freq_hz,
                    "must be a frequency in Hz below the Nyquist frequency of the input",
                ));
            }
            if self.high_freq_hz < self.low_freq_hz {
                return Err(invalid(
                    "fb_highFreqHz",
                    self.high_freq_hz,
                    format!("must be ≥ fb_lowFreqHz ({} Hz)", self.low_freq_hz),
                ));
            }
            let (elo, ehi) = (freq2erb(self.low_freq_hz), freq2erb(self.high_freq_hz));
            match self.n_channels {
                Some(0) => return Err(invalid("fb_nChannels", 0, "must be at least 1")),
                Some(n) if n as usize > MAX_CHANNELS => {
                    return Err(invalid(
                        "fb_nChannels",
                        n,
                        format!("at most {MAX_CHANNELS} channels are supported"),
                    ))
                }
                Some(n) => {
                    let e = linspace(elo, ehi, n as usize);
                    let spacing = (e[e.len() - 1] - e[0]) / f64::from(n);
                    let cf = e.into_iter().map(erb2freq).collect();
                    (cf, json!(spacing), self.low_freq_hz, self.high_freq_hz)
                }
                None => {
                    let count = (ehi - elo) / self.n_erbs;
                    if self.n_erbs <= 0.0 || count >= MAX_CHANNELS as f64 {
                        return Err(invalid(
                            "fb_nERBs",
                            self.n_erbs,
                            format!(
                                "must be > 0 and give at most {MAX_CHANNELS} channels between fb_lowFreqHz and fb_highFreqHz"
                            ),
                        ));
                    }
                    let cf: Vec<f64> = colon_range(elo, self.n_erbs, ehi)
                        .into_iter()
                        .map(erb2freq)
                        .collect();
                    (cf, json!(self.n_erbs), self.low_freq_hz, self.high_freq_hz)
                }
            }
        };
        let delay_s: Vec<f64> = cf
            .iter()
            .map(|f| 3.0 / (2.0 * PI * (self.bw_erbs * (24.7 + 0.108 * f))))
            .collect();
        let mut map = self.to_map();
        map.insert("fb_cfHz".into(), json!(cf));
        map.insert("fb_nChannels".into(), json!(cf.len()));
        map.insert("fb_nERBs".into(), n_erbs);
        map.insert("fb_lowFreqHz".into(), json!(low));
        map.insert("fb_highFreqHz".into(), json!(high));
        map.insert("fb_delaySec".into(), json!(delay_s));
        Ok(GammatoneGrid {
            cf_hz: cf,
            delay_s,
            map,
        })
    }
}

/// Designed coefficients of one channel: `H(z) = b0 / (1 − p z⁻¹)^n`.
#[derive(Debug, Clone, PartialEq)]
struct ChannelDesign {
    /// Numerator (complex when aligned), `(re, im)`.
    b0: (f64, f64),
    /// Denominator `a[1..=n]`, `(re, im)` each (`a[0] = 1`).
    a: Vec<(f64, f64)>,
}

fn design_channel(cf: f64, bw_erbs: f64, n: usize, fs: f64, align: bool) -> ChannelDesign {
    let bw = bw_erbs * (24.7 + 0.108 * cf);
    let re = -((2.0 * PI) * bw) / fs;
    let im = -((2.0 * PI) * cf) / fs;
    let mag = re.exp();
    let p = (mag * im.cos(), mag * im.sin());
    let neg_p = (-p.0, -p.1);
    let mut a: Vec<(f64, f64)> = vec![(1.0, 0.0)];
    for _ in 0..n {
        let mut next = Vec::with_capacity(a.len() + 1);
        for k in 0..=a.len() {
            let cur = if k < a.len() { a[k] } else { (0.0, 0.0) };
            let prev = if k > 0 { a[k - 1] } else { (0.0, 0.0) };
            let prod = (
                neg_p.0 * prev.0 - neg_p.1 * prev.1,
                neg_p.0 * prev.1 + neg_p.1 * prev.0,
            );
            next.push((cur.0 + prod.0, cur.1 + prod.1));
        }
        a = next;
    }
    let step = 1.0 - re.exp();
    let mut g = 1.0;
    for _ in 0..n {
        g *= step;
    }
    let b0 = if align {
        let tau = 3.0 / (2.0 * PI * bw);
        let phase = 2.0 * PI * cf * tau;
        (g * phase.cos(), g * phase.sin())
    } else {
        (g, 0.0)
    };
    ChannelDesign {
        b0,
        a: a[1..].to_vec(),
    }
}

/// Samples filtered per pass over the groups, so that a long input's output rows stay
/// in cache while every group writes its lanes of them (a 32-channel block is 128 KiB).
const TIME_BLOCK: usize = 512;
/// Largest supported `fb_nGamma` (the expanded polynomial is numerically useless beyond).
pub const MAX_ORDER: usize = 8;

/// Coefficients and state of `W` channels, lane-major so that every operation of the
/// recursion runs across the channels (unused lanes of the last group have zero
/// coefficients and produce zeros that are never written out).
#[derive(Debug, Clone)]
struct Group<const W: usize> {
    b_re: [f64; W],
    b_im: [f64; W],
    /// `a[1..=order]`.
    a_re: [[f64; W]; MAX_ORDER],
    a_im: [[f64; W]; MAX_ORDER],
    z_re: [[f64; W]; MAX_ORDER],
    z_im: [[f64; W]; MAX_ORDER],
}

/// The channel groups of a filterbank, `W` channels per group.
#[derive(Debug, Clone)]
struct Bank<const W: usize> {
    groups: Vec<Group<W>>,
    /// First channel of each group. With `W` channels or more, the last group ends at
    /// the last channel, overlapping its neighbour when the count is not a multiple of
    /// `W`: an overlapped channel is then computed twice, identically, and written twice.
    starts: Vec<usize>,
    /// Full-width output rows of a bank narrower than `W` channels (`TIME_BLOCK` × `W`,
    /// copied out in part; empty otherwise).
    partial: Vec<f64>,
}

impl<const W: usize> Bank<W> {
    fn new(designs: &[ChannelDesign]) -> Self {
        let empty = Group {
            b_re: [0.0; W],
            b_im: [0.0; W],
            a_re: [[0.0; W]; MAX_ORDER],
            a_im: [[0.0; W]; MAX_ORDER],
            z_re: [[0.0; W]; MAX_ORDER],
            z_im: [[0.0; W]; MAX_ORDER],
        };
        let nc = designs.len();
        let starts: Vec<usize> = (0..nc.div_ceil(W))
            .map(|g| vector_start(g, W, nc))
            .collect();
        let mut groups = vec![empty; starts.len()];
        for (g, &c0) in groups.iter_mut().zip(&starts) {
            for (l, d) in designs[c0..].iter().take(W).enumerate() {
                g.b_re[l] = d.b0.0;
                g.b_im[l] = d.b0.1;
                for (k, ak) in d.a.iter().enumerate() {
                    g.a_re[k][l] = ak.0;
                    g.a_im[k][l] = ak.1;
                }
            }
        }
        let partial = if nc < W {
            vec![0.0; TIME_BLOCK * W]
        } else {
            Vec::new()
        };
        Bank {
            groups,
            starts,
            partial,
        }
    }

    fn filter(&mut self, order: usize, x: &[f64], out: &mut [f64], nc: usize) {
        let run = match order {
            1 => run_group::<1, W>,
            2 => run_group::<2, W>,
            3 => run_group::<3, W>,
            4 => run_group::<4, W>,
            5 => run_group::<5, W>,
            6 => run_group::<6, W>,
            7 => run_group::<7, W>,
            _ => run_group::<8, W>,
        };
        for (x, out) in x.chunks(TIME_BLOCK).zip(out.chunks_mut(TIME_BLOCK * nc)) {
            for (g, &c0) in self.groups.iter_mut().zip(&self.starts) {
                if nc >= W {
                    run(g, x, &mut out[c0..], nc);
                } else {
                    let rows = &mut self.partial[..x.len() * W];
                    run(g, x, rows, W);
                    for (o, r) in out.chunks_exact_mut(nc).zip(rows.chunks_exact(W)) {
                        o.copy_from_slice(&r[..nc]);
                    }
                }
            }
        }
    }

    fn reset(&mut self) {
        for g in &mut self.groups {
            g.z_re = [[0.0; W]; MAX_ORDER];
            g.z_im = [[0.0; W]; MAX_ORDER];
        }
    }
}

/// The groups in the width that suits the CPU, detected once at construction: 16
/// channels (two AVX-512 registers) or 8 (two AVX2 registers, or plain SSE2). Both give
/// the same numbers; only the register pressure differs.
#[derive(Debug, Clone)]
enum Banks {
    Wide(Bank<16>),
    Narrow(Bank<8>),
}

/// The gammatone filterbank of one ear: time-domain in, `[time][channel]` out.
#[derive(Debug, Clone)]
pub struct Gammatone {
    channels: usize,
    order: usize,
    banks: Banks,
}

impl Gammatone {
    /// Designs the filterbank for input rate `fs` Hz; returns it with its output signal.
    /// (The verified parameter map is [`GammatoneParams::grid`]'s.)
    pub fn new(params: &GammatoneParams, fs: f64) -> Result<(Self, SignalInfo)> {
        Self::with_width(params, fs, has_avx512())
    }

    /// [`Gammatone::new`] with the group width chosen by the caller (`wide`: 16 lanes).
    fn with_width(params: &GammatoneParams, fs: f64, wide: bool) -> Result<(Self, SignalInfo)> {
        let grid = params.grid()?;
        if let Some(bad) = grid.cf_hz.iter().find(|f| **f >= fs / 2.0) {
            let nyquist = fs / 2.0;
            return Err(if params.cf_hz.is_empty() {
                let default = GammatoneParams::default().high_freq_hz;
                let which = if params.high_freq_hz == default {
                    " (the default)"
                } else {
                    ""
                };
                invalid(
                    "fb_highFreqHz",
                    params.high_freq_hz,
                    format!(
                        "{}{which} puts centre frequencies up to {bad:.0} Hz, above the Nyquist \
                         frequency ({nyquist} Hz) of the {fs} Hz input: set fb_highFreqHz below \
                         {nyquist} Hz",
                        params.high_freq_hz
                    ),
                )
            } else {
                invalid(
                    "fb_cfHz",
                    bad,
                    format!(
                        "centre frequencies must lie below the Nyquist frequency ({nyquist} Hz) \
                         of the {fs} Hz input"
                    ),
                )
            });
        }
        let order = params.n_gamma as usize;
        if order > MAX_ORDER {
            return Err(invalid(
                "fb_nGamma",
                order,
                format!("orders up to {MAX_ORDER} are supported"),
            ));
        }
        let designs: Vec<ChannelDesign> = grid
            .cf_hz
            .iter()
            .map(|&cf| design_channel(cf, params.bw_erbs, order, fs, params.align))
            .collect();
        let banks = if wide {
            Banks::Wide(Bank::new(&designs))
        } else {
            Banks::Narrow(Bank::new(&designs))
        };
        let gammatone = Gammatone {
            channels: designs.len(),
            order,
            banks,
        };
        Ok((gammatone, SignalInfo::time_frequency(fs, grid.cf_hz)))
    }

    /// Filters `x` (time-domain) into `out` (`x.len()` rows of one value per channel).
    pub fn filter(&mut self, x: &[f64], out: &mut [f64]) {
        let (order, nc) = (self.order, self.channels);
        match &mut self.banks {
            Banks::Wide(b) => b.filter(order, x, out, nc),
            Banks::Narrow(b) => b.filter(order, x, out, nc),
        }
    }
}

/// The complex DF2T recursion of one channel group of order `M` over a chunk, state in
/// registers. Per channel, the operations and their order are the reference's
/// (`y = z0 + b0·x`, `z[k] = z[k+1] − a[k+1]·y`, textbook complex products, no FMA,
/// output `2·Re y`), so the output is bit-identical to a channel-by-channel evaluation,
/// signed zeros and subnormals included. Compiled for AVX-512 and AVX2 too, chosen at
/// run time.
#[multiversion::multiversion(targets("x86_64+avx512f+avx512vl", "x86_64+avx2"))]
fn run_group<const M: usize, const W: usize>(
    g: &mut Group<W>,
    x: &[f64],
    out: &mut [f64],
    stride: usize,
) {
    let mut zr = [[0.0; W]; M];
    let mut zi = [[0.0; W]; M];
    let mut ar = [[0.0; W]; M];
    let mut ai = [[0.0; W]; M];
    zr.copy_from_slice(&g.z_re[..M]);
    zi.copy_from_slice(&g.z_im[..M]);
    ar.copy_from_slice(&g.a_re[..M]);
    ai.copy_from_slice(&g.a_im[..M]);
    let (br, bi) = (g.b_re, g.b_im);
    for (t, &xin) in x.iter().enumerate() {
        let mut yr = [0.0; W];
        let mut yi = [0.0; W];
        for l in 0..W {
            yr[l] = zr[0][l] + br[l] * xin;
            yi[l] = zi[0][l] + bi[l] * xin;
        }
        for k in 0..M - 1 {
            for l in 0..W {
                zr[k][l] = zr[k + 1][l] - (ar[k][l] * yr[l] - ai[k][l] * yi[l]);
                zi[k][l] = zi[k + 1][l] - (ar[k][l] * yi[l] + ai[k][l] * yr[l]);
            }
        }
        for l in 0..W {
            zr[M - 1][l] = -(ar[M - 1][l] * yr[l] - ai[M - 1][l] * yi[l]);
            zi[M - 1][l] = -(ar[M - 1][l] * yi[l] + ai[M - 1][l] * yr[l]);
        }
        for y in &mut yr {
            *y *= 2.0;
        }
        out[t * stride..t * stride + W].copy_from_slice(&yr);
    }
    g.z_re[..M].copy_from_slice(&zr);
    g.z_im[..M].copy_from_slice(&zi);
}

impl Processor for Gammatone {
    fn process(&mut self, inputs: &[&Block], outputs: &mut [Block]) {
        let x = inputs[0].as_slice();
        let out = outputs[0].resize_to(x.len());
        self.filter(x, out);
    }

    fn reset(&mut self) {
        match &mut self.banks {
            Banks::Wide(b) => b.reset(),
            Banks::Narrow(b) => b.reset(),
        }
    }
}

impl Descriptor for Gammatone {
    type Params = GammatoneParams;
    const NAME: &'static str = "filterbank";
    const DEPENDENCY: &'static str = "time";
    const EARS: Ears = Ears::PerEar;
    const DESCRIPTION: &'static str = "gammatone filterbank output per frequency channel";
    const OUTPUT_UNIT: &'static str = "";
    /// The channel grid, which every representation above is laid out on.
    const FIXED: &'static [&'static str] = &[
        "fb_type",
        "fb_lowFreqHz",
        "fb_highFreqHz",
        "fb_nERBs",
        "fb_cfHz",
    ];

    fn build(params: &GammatoneParams, inputs: &[SignalInfo]) -> Result<Built> {
        let (p, out) = Gammatone::new(params, inputs[0].fs_hz)?;
        Ok(Built::new(p, vec![out]))
    }

    /// The resolved channel grid (equal grids from different parameter sets are shared).
    fn canonical(params: &GammatoneParams) -> Result<ParamMap> {
        Ok(params.grid()?.map)
    }
}

/// The registry entry of `filterbank`.
pub static REQUEST: RequestDef = request_def::<Gammatone>();

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specs_match_struct() {
        afe_core::params::check_param_specs::<GammatoneParams>();
    }

    #[test]
    fn default_grid_has_31_channels_with_the_afe_bits() {
        let grid = GammatoneParams::default().grid().expect("valid");
        assert_eq!(grid.cf_hz.len(), 31);
        assert_eq!(grid.cf_hz[0], 80.00000000000001);
        assert_eq!(grid.cf_hz[1], 115.20010915768904);
        assert_eq!(grid.cf_hz[30], 7641.313909478947);
        assert_eq!(grid.delay_s[0], 0.014067859196599362);
    }

    #[test]
    fn channel_count_mode_spans_both_ends() {
        let p = GammatoneParams {
            n_channels: Some(16),
            low_freq_hz: 100.0,
            ..Default::default()
        };
        let grid = p.grid().expect("valid");
        assert_eq!(grid.cf_hz.len(), 16);
        assert!((grid.cf_hz[0] - 100.0).abs() < 1e-9);
        assert!((grid.cf_hz[15] - 8000.0).abs() < 1e-9);
    }

    #[test]
    fn impulse_response_matches_the_closed_form() {
        // h[t] = 2·g·C(t+n−1, n−1)·r^t·cos(2π·cf·t/fs), r = e^{−β}
        let fs = 16000.0;
        let p = GammatoneParams {
            cf_hz: vec![1000.0],
            ..Default::default()
        };
        let (mut gt, _) = Gammatone::new(&p, fs).expect("valid");
        let n = 200;
        let mut x = vec![0.0; n];
        x[0] = 1.0;
        let mut y = vec![0.0; n];
        gt.filter(&x, &mut y);
        let beta = 2.0 * PI * 1.018 * (24.7 + 0.108 * 1000.0) / fs;
        let g = (1.0 - (-beta).exp()).powi(4);
        for (t, yt) in y.iter().enumerate() {
            let tf = t as f64;
            let binom = (tf + 1.0) * (tf + 2.0) * (tf + 3.0) / 6.0;
            let want = 2.0 * g * binom * (-beta * tf).exp() * (2.0 * PI * 1000.0 * tf / fs).cos();
            assert!((yt - want).abs() < 1e-12, "t={t}: {yt} vs {want}");
        }
    }

    #[test]
    fn unit_gain_at_centre_frequency() {
        let fs = 44100.0;
        let p = GammatoneParams {
            cf_hz: vec![1000.0],
            ..Default::default()
        };
        let (mut gt, _) = Gammatone::new(&p, fs).expect("valid");
        let n = 44100;
        let x: Vec<f64> = (0..n)
            .map(|t| (2.0 * PI * 1000.0 * t as f64 / fs).sin())
            .collect();
        let mut y = vec![0.0; n];
        gt.filter(&x, &mut y);
        let peak = y[n / 2..].iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!((peak - 1.0).abs() < 1e-3, "peak {peak}");
    }

    #[test]
    fn absurd_channel_counts_are_errors_not_allocations() {
        for p in [
            GammatoneParams {
                n_erbs: 1e-9,
                ..Default::default()
            },
            GammatoneParams {
                n_erbs: 1e-300,
                ..Default::default()
            },
            GammatoneParams {
                n_channels: Some(u32::MAX),
                ..Default::default()
            },
        ] {
            let e = p.grid().expect_err("too many channels");
            assert!(e.to_string().contains("at most 1024 channels"), "{e}");
        }
        let p = GammatoneParams {
            n_channels: Some(0),
            ..Default::default()
        };
        let e = p.grid().expect_err("no channel");
        assert!(e.to_string().contains("at least 1"), "{e}");
        let p = GammatoneParams {
            cf_hz: vec![100.0, 900.0],
            ..Default::default()
        };
        let e = Gammatone::new(&p, 1600.0).expect_err("900 Hz above Nyquist");
        assert!(e.to_string().contains("'fb_cfHz'"), "{e}");
    }

    #[test]
    fn both_group_widths_give_the_same_bits() {
        let x: Vec<f64> = (0..3000)
            .map(|t| ((t * 7919 % 1000) as f64 / 500.0 - 1.0) * (1.0 + (t as f64 * 0.01).sin()))
            .collect();
        // 5 channels: both widths take the partial path; 13: partial (16 lanes) against
        // overlapping groups (8); 31: overlapping groups in both.
        for (align, n_channels) in [(false, 5), (false, 13), (false, 31), (true, 31)] {
            let p = GammatoneParams {
                align,
                n_channels: Some(n_channels),
                ..Default::default()
            };
            let mut outs = Vec::new();
            for wide in [false, true] {
                let (mut gt, info) = Gammatone::with_width(&p, 44100.0, wide).expect("valid");
                let nc = info.channels();
                let mut y = vec![0.0; x.len() * nc];
                let mut t = 0;
                for len in [1, 441, 600, 1958] {
                    gt.filter(&x[t..t + len], &mut y[t * nc..(t + len) * nc]);
                    t += len;
                }
                outs.push(y);
            }
            assert!(outs[0].iter().any(|v| *v != 0.0));
            let bits = |v: &Vec<f64>| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
            assert_eq!(
                bits(&outs[0]),
                bits(&outs[1]),
                "{n_channels} channels, align={align}"
            );
        }
    }

    /// The reference recursion of one channel, written plainly (spec 11-gammatone).
    fn reference_channel(d: &ChannelDesign, x: &[f64]) -> Vec<f64> {
        let n = d.a.len();
        let mut z = vec![(0.0f64, 0.0f64); n];
        let mut out = Vec::with_capacity(x.len());
        for &xin in x {
            let y = (z[0].0 + d.b0.0 * xin, z[0].1 + d.b0.1 * xin);
            for k in 0..n {
                let (ar, ai) = d.a[k];
                let prod = (ar * y.0 - ai * y.1, ar * y.1 + ai * y.0);
                let next = if k + 1 < n { z[k + 1] } else { (0.0, 0.0) };
                z[k] = if k + 1 < n {
                    (next.0 - prod.0, next.1 - prod.1)
                } else {
                    (-prod.0, -prod.1)
                };
            }
            out.push(2.0 * y.0);
        }
        out
    }

    #[test]
    fn channels_match_the_plain_recursion_bit_for_bit_through_silence() {
        // A burst, then 1 s of zeros (the state decays into subnormals) and negative zeros.
        let fs = 44100.0;
        let mut x: Vec<f64> = (0..2000)
            .map(|t| (t * 7919 % 1000) as f64 / 500.0 - 1.0)
            .collect();
        x.extend(std::iter::repeat_n(0.0, 44100));
        x.extend(std::iter::repeat_n(-0.0, 100));
        for (align, order, n_channels) in
            [(false, 4, 31), (true, 4, 13), (false, 1, 9), (false, 8, 5)]
        {
            let p = GammatoneParams {
                align,
                n_gamma: order,
                n_channels: Some(n_channels),
                ..Default::default()
            };
            let grid = p.grid().expect("valid");
            for wide in [false, true] {
                let (mut gt, _) = Gammatone::with_width(&p, fs, wide).expect("valid");
                let nc = n_channels as usize;
                let mut y = vec![0.0; x.len() * nc];
                let (head, tail) = x.split_at(1000);
                gt.filter(head, &mut y[..1000 * nc]);
                gt.filter(tail, &mut y[1000 * nc..]);
                for (c, &cf) in grid.cf_hz.iter().enumerate() {
                    let d = design_channel(cf, p.bw_erbs, order as usize, fs, align);
                    let want = reference_channel(&d, &x);
                    for (t, w) in want.iter().enumerate() {
                        let got = y[t * nc + c];
                        assert_eq!(
                            got.to_bits(),
                            w.to_bits(),
                            "channel {c}, t={t}: {got:e} vs {w:e}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn rejects_channels_above_nyquist() {
        let err = Gammatone::new(&GammatoneParams::default(), 8000.0)
            .expect_err("the default grid reaches 7.6 kHz, above the 4 kHz Nyquist frequency");
        // issue 13, item 9: the message names the value the user has (the default) and
        // what to set, not a centre frequency as if it were fb_highFreqHz
        let msg = err.to_string();
        assert!(
            msg.contains("invalid value 8000.0 for parameter 'fb_highFreqHz'"),
            "{msg}"
        );
        assert!(
            msg.contains("(the default)") && msg.contains("below 4000 Hz"),
            "{msg}"
        );
        let p = GammatoneParams {
            high_freq_hz: 1e308,
            n_erbs: 1.0,
            ..Default::default()
        };
        let msg = Gammatone::new(&p, 8000.0).expect_err("absurd").to_string();
        assert!(
            msg.contains("invalid value 1e308 for parameter 'fb_highFreqHz'"),
            "{msg}"
        );
    }
}
