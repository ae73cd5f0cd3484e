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

use std::f64::consts::PI;

use afe_core::filter::Df2t;
use afe_core::lanes::vector_start;
use afe_core::params::per_channel;
use afe_core::{Block, Error, Feedback, ParamMap, Processor, Result, SignalInfo};
use serde_json::json;

pub use crate::filterbank_params::DrnlModel;
use crate::filterbank_params::FilterbankParams;

mod compression;
mod design;
mod kernels;

use design::{casp_channel, casp_exponent, exp10, map_channel, map_threshold, ChannelDesign};
use kernels::{run_casp, run_map, Group, LaneGt, LaneLp, Paths, STATES};

/// The DRNL's verified parameters (the AFE's map after preparation): the grid, the model
/// and both MOC gains expanded to one per channel.
pub(crate) fn verified(params: &FilterbankParams) -> Result<ParamMap> {
    let grid = params.grid()?;
    let n = grid.cf_hz.len();
    let mut map = ParamMap::new();
    grid.insert_into(&mut map);
    map.insert(FilterbankParams::NAMES.model.into(), json!(params.model));
    map.insert(
        FilterbankParams::NAMES.moc_ipsi.into(),
        json!(per_channel(
            FilterbankParams::NAMES.moc_ipsi,
            &params.moc_ipsi,
            n
        )?),
    );
    map.insert(
        FilterbankParams::NAMES.moc_contra.into(),
        json!(per_channel(
            FilterbankParams::NAMES.moc_contra,
            &params.moc_contra,
            n
        )?),
    );
    Ok(map)
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
                (
                    FilterbankParams::NAMES.low_freq_hz,
                    params.low_freq_hz.to_string(),
                )
            } else {
                (FilterbankParams::NAMES.cf_hz, format!("{:?}", params.cf_hz))
            };
            return Err(Error::invalid(
                name,
                value,
                format!("the DRNL needs centre frequencies above 0 Hz, and one is {f} Hz"),
            ));
        }
        let nc = grid.cf_hz.len();
        let moc_ipsi = per_channel(FilterbankParams::NAMES.moc_ipsi, &params.moc_ipsi, nc)?;
        let moc_contra = per_channel(FilterbankParams::NAMES.moc_contra, &params.moc_contra, nc)?;
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
        for (name, v) in [
            (FilterbankParams::NAMES.moc_ipsi, ipsi),
            (FilterbankParams::NAMES.moc_contra, contra),
        ] {
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

    fn feedback(&mut self) -> Option<&mut dyn Feedback> {
        Some(self)
    }
}

impl Feedback for Drnl {
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
    use super::compression::{casp_compress, map_compress};
    use super::design::Biquad;
    use super::*;
    use crate::testing::feed;
    use afe_core::Params;
    use proptest::prelude::*;
    use serde_json::Value;

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
