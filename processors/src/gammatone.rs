//! `filterbank` with `fb_type = 'gammatone'`: complex all-pole gammatone filters on an
//! ERB-spaced grid (spec 11-gammatone), each run as one order-n DF2T filter in complex f64.
//!
//! The coefficients follow the reference recipe operation by operation (component-wise
//! division by fs, convolution as `a[k] + (−p)·a[k−1]`, textbook complex products, no FMA):
//! the expanded polynomial is ill-conditioned at low centre frequencies, and this recipe
//! reproduces the MATLAB AFE bit for bit. The request is [`crate::filterbank`]'s, the
//! parameters and the grid [`crate::filterbank_params`]'s.

use std::f64::consts::PI;

use afe_core::cpu::has_avx512;
use afe_core::lanes::vector_start;
use afe_core::{Block, Error, ParamMap, Processor, Result, SignalInfo};
use serde_json::json;

use crate::filterbank_params::{CfGrid, FilterbankParams};

/// The gammatone's verified parameters (the AFE's verify step): the grid, order,
/// bandwidth, alignment and the informational per-channel delay `fb_delaySec`.
pub(crate) fn verified(params: &FilterbankParams) -> Result<ParamMap> {
    let (grid, delay_s) = grid_and_delays(params)?;
    let mut map = ParamMap::new();
    grid.insert_into(&mut map);
    map.insert("fb_nGamma".into(), json!(params.n_gamma));
    map.insert("fb_bwERBs".into(), json!(params.bw_erbs));
    map.insert("fb_bAlign".into(), json!(params.align));
    map.insert("fb_delaySec".into(), json!(delay_s));
    Ok(map)
}

/// The grid and the envelope-peak delay per channel in s, `3/(2π·bw)` (informational,
/// the constant 3 whatever the order, as in the AFE).
fn grid_and_delays(params: &FilterbankParams) -> Result<(CfGrid, Vec<f64>)> {
    if params.bw_erbs <= 0.0 {
        return Err(Error::invalid(
            "fb_bwERBs",
            format_args!("{:?}", params.bw_erbs),
            "must be > 0",
        ));
    }
    let grid = params.grid()?;
    let delay_s = grid
        .cf_hz
        .iter()
        .map(|f| 3.0 / (2.0 * PI * (params.bw_erbs * (24.7 + 0.108 * f))))
        .collect();
    Ok((grid, delay_s))
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
    /// Designs the filterbank for input rate `fs` Hz from the gammatone's parameters of
    /// `params`; returns it with its output signal.
    pub fn new(params: &FilterbankParams, fs: f64) -> Result<(Self, SignalInfo)> {
        Self::with_width(params, fs, has_avx512())
    }

    /// [`Gammatone::new`] with the group width chosen by the caller (`wide`: 16 lanes).
    fn with_width(params: &FilterbankParams, fs: f64, wide: bool) -> Result<(Self, SignalInfo)> {
        let (grid, _) = grid_and_delays(params)?;
        grid.check_below_nyquist(params, fs)?;
        let order = params.n_gamma as usize;
        if order > MAX_ORDER {
            return Err(Error::invalid(
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

afe_core::simd_kernel!(
    /// The complex DF2T recursion of one channel group of order `M` over a chunk, state in
    /// registers. Per channel, the operations and their order are the reference's
    /// (`y = z0 + b0·x`, `z[k] = z[k+1] − a[k+1]·y`, textbook complex products, no FMA,
    /// output `2·Re y`), so the output is bit-identical to a channel-by-channel evaluation,
    /// signed zeros and subnormals included. Compiled for AVX-512 and AVX2 too, chosen at
    /// run time.
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
);

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_delays_have_the_afe_bits() {
        let map = verified(&FilterbankParams::default()).expect("valid");
        assert_eq!(map["fb_delaySec"][0], json!(0.014067859196599362));
        assert_eq!(map["fb_nChannels"], json!(31));
    }

    #[test]
    fn impulse_response_matches_the_closed_form() {
        // h[t] = 2·g·C(t+n−1, n−1)·r^t·cos(2π·cf·t/fs), r = e^{−β}
        let fs = 16000.0;
        let p = FilterbankParams {
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
    fn aligned_impulse_response_matches_the_closed_form() {
        // The pole sits at −cf and the numerator turns by φ = 2π·cf·τ, τ = 3/(2π·bw):
        // h[t] = 2·g·C(t+n−1, n−1)·r^t·cos(2π·cf·t/fs − φ), here of order 3.
        let (fs, cf, bw_erbs) = (16000.0, 1500.0, 1.5);
        let p = FilterbankParams {
            cf_hz: vec![cf],
            n_gamma: 3,
            bw_erbs,
            align: true,
            ..Default::default()
        };
        let (mut gt, _) = Gammatone::new(&p, fs).expect("valid");
        let n = 300;
        let mut x = vec![0.0; n];
        x[0] = 1.0;
        let mut y = vec![0.0; n];
        gt.filter(&x, &mut y);
        let bw = bw_erbs * (24.7 + 0.108 * cf);
        let beta = 2.0 * PI * bw / fs;
        let g = (1.0 - (-beta).exp()).powi(3);
        let phi = 2.0 * PI * cf * 3.0 / (2.0 * PI * bw);
        for (t, yt) in y.iter().enumerate() {
            let tf = t as f64;
            let binom = (tf + 1.0) * (tf + 2.0) / 2.0;
            let carrier = (2.0 * PI * cf * tf / fs - phi).cos();
            let want = 2.0 * g * binom * (-beta * tf).exp() * carrier;
            assert!((yt - want).abs() < 1e-12, "t={t}: {yt} vs {want}");
        }
    }

    #[test]
    fn the_processor_filters_across_chunks_and_reset_starts_over() {
        let (mut gt, _) = Gammatone::new(&FilterbankParams::default(), 16000.0).expect("valid");
        let x: Vec<f64> = (0..1000)
            .map(|t| ((t * 7919 % 1000) as f64) / 500.0 - 1.0)
            .collect();
        let mut whole = vec![0.0; 1000 * 31];
        gt.filter(&x, &mut whole);
        gt.reset();
        let chunked = crate::testing::feed(&mut gt, &x, 1, 31, std::iter::repeat(300));
        assert_eq!(chunked, whole);
    }

    #[test]
    fn unit_gain_at_centre_frequency() {
        let fs = 44100.0;
        let p = FilterbankParams {
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
    fn centre_frequencies_above_nyquist_are_errors() {
        let p = FilterbankParams {
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
            let p = FilterbankParams {
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
            let p = FilterbankParams {
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
        let err = Gammatone::new(&FilterbankParams::default(), 8000.0)
            .expect_err("the default grid reaches 7.6 kHz, above the 4 kHz Nyquist frequency");
        // issue 13, item 9: the message names the value the user has (the default) and
        // what to set, not a centre frequency as if it were fb_highFreqHz
        let msg = err.to_string();
        assert!(
            msg.contains("invalid value 8000.0 for parameter 'fb_highFreqHz'"),
            "{msg}"
        );
        assert!(
            msg.contains("(the default)") && msg.contains("at most 4000 Hz"),
            "{msg}"
        );
        // the channels past Nyquist, 4359 to 7641 Hz of the default grid (spec 11)
        assert!(
            msg.contains("puts 6 centre frequencies, from 4359 Hz up to 7641 Hz, above"),
            "{msg}"
        );
        // one channel past Nyquist: 80 Hz to 4400 Hz at 1 ERB ends at 4359 Hz
        let one = FilterbankParams {
            high_freq_hz: 4400.0,
            ..Default::default()
        };
        let msg = Gammatone::new(&one, 8000.0)
            .expect_err("4359 Hz")
            .to_string();
        assert!(
            msg.contains("4400 puts a centre frequency at 4359 Hz above the Nyquist frequency"),
            "{msg}"
        );
        let p = FilterbankParams {
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
