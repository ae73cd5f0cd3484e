//! `adaptation`: a chain of non-linear adaptation loops per IHC channel (Dau et al.
//! 1996/1997 and variants), with optional overshoot limitation (spec 14-adaptation).
//!
//! Each loop divides the signal by its own low-passed output, which compresses
//! stationary input and passes fast changes: the output is in model units, 0 at the
//! level floor. Exactly chunk-invariant: the loop states carry over between chunks.

use afe_core::descriptor::{request_def, Built, Descriptor, Ears, RequestDef};
use afe_core::erb::linspace;
use afe_core::{Block, DrawAs, Error, Params, Processor, Result, SignalInfo};

use crate::exp::exp;

afe_core::choices! {
    /// A named parameter preset of the AFE (`adpt_model`), which overrides `adpt_lim`,
    /// `adpt_mindB` and `adpt_tau`.
    pub enum AdaptationModel {
        /// No preset: the three parameters as given.
        None = "",
        /// Dau et al. (1996): limitation 10, floor 0 dB SPL, the five standard time constants.
        Dau = "adt_dau",
        /// Püschel (1988): no limitation, time constants evenly spaced from 5 to 500 ms.
        Puschel = "adt_puschel",
        /// Breebaart et al. (2001): limitation 10, time constants evenly spaced from 5 to 500 ms.
        Breebaart = "adt_breebaart",
        /// van Dorp Schuitman (2009): no limitation, standard time constants, and a floor per
        /// channel at the absolute threshold of hearing of its centre frequency.
        VanDorpSchuitman = "adt_vandorpschuitman",
    }
}

afe_core::params! {
    /// Parameters of the adaptation loops, under their AFE names.
    pub struct AdaptationParams / AdaptationNames {
        /// overshoot limitation factor (at most 1: no limitation)
        #[afe = "adpt_lim"]
        pub lim: f64 = 10.0,
        /// lowest signal level, the floor of the input
        #[afe = "adpt_mindB", unit = "dB SPL"]
        pub min_db_spl: f64 = 0.0,
        /// time constant of each adaptation loop
        #[afe = "adpt_tau", unit = "s"]
        pub tau_sec: Vec<f64> = DAU_TAU_SEC.to_vec(),
        /// preset overriding adpt_lim, adpt_mindB and adpt_tau ('' for none)
        #[afe = "adpt_model"]
        pub model: AdaptationModel = AdaptationModel::None,
    }
}

/// The five time constants of Dau et al., in s.
const DAU_TAU_SEC: [f64; 5] = [0.005, 0.05, 0.129, 0.253, 0.5];

/// `linspace(0.005, 0.5, 5)`, the time constants of the Püschel and Breebaart presets.
fn spaced_tau_sec() -> Vec<f64> {
    linspace(0.005, 0.5, 5)
}

impl AdaptationParams {
    /// The parameters after the AFE's verification: a preset replaces `adpt_lim`,
    /// `adpt_mindB` and `adpt_tau` by its own values (the model name is kept).
    pub fn with_preset(&self) -> Self {
        let (lim, tau) = match self.model {
            AdaptationModel::None => return self.clone(),
            AdaptationModel::Dau => (10.0, DAU_TAU_SEC.to_vec()),
            AdaptationModel::Puschel => (0.0, spaced_tau_sec()),
            AdaptationModel::Breebaart => (10.0, spaced_tau_sec()),
            AdaptationModel::VanDorpSchuitman => (0.0, DAU_TAU_SEC.to_vec()),
        };
        AdaptationParams {
            lim,
            min_db_spl: 0.0,
            tau_sec: tau,
            model: self.model,
        }
    }
}

/// Absolute threshold of hearing in dB SPL at `f_hz` (the van Dorp Schuitman floor).
fn threshold_of_hearing_db(f_hz: f64) -> f64 {
    let f = f_hz / 1000.0;
    3.64 * f.powf(-0.8) - 6.5 * (-0.6 * (f - 3.3) * (f - 3.3)).exp() + 1e-3 * f.powi(4)
}

/// The adaptation loops of one ear: IHC `[time][channel]` in, the same shape out.
#[derive(Debug, Clone)]
pub struct Adaptation {
    /// Loop feedback coefficient `a1 = exp(−1/(τ·fs))` and input gain `1 − a1`, per loop.
    a1: Vec<f64>,
    b0: Vec<f64>,
    /// Frequency channels; the per-channel vectors below have `lanes` entries per row,
    /// the channels padded to whole SIMD steps with neutral values.
    channels: usize,
    lanes: usize,
    /// Per channel: the floor, and the output offset and scale `(v − corr)·mult`.
    min_level: Vec<f64>,
    corr: Vec<f64>,
    mult: Vec<f64>,
    /// Initial loop states `minLevel^(1/2^j)`, `[loop][channel]`.
    initial: Vec<f64>,
    /// Overshoot limitation constants, `None` when the limitation is off.
    limit: Option<Limit>,
    /// Loop states, `[loop][channel]`.
    state: Vec<f64>,
    /// The sample entering the first loop, one value per lane (padding lanes hold 1).
    row: Vec<f64>,
    /// What each loop gave at the last step, `[loop][lane]` (see [`adapt`]).
    stages: Vec<f64>,
}

/// Channels per SIMD step of [`adapt`].
const STEP: usize = 8;

/// `values`, rows of `channels` entries, with each row padded to `lanes` by `fill`.
fn padded(values: &[f64], channels: usize, lanes: usize, fill: f64) -> Vec<f64> {
    values
        .chunks(channels.max(1))
        .flat_map(|row| {
            row.iter()
                .copied()
                .chain(std::iter::repeat_n(fill, lanes - row.len()))
        })
        .collect()
}

/// Largest `adpt_lim` accepted: the limitation's constants are products of it, which overflowed
/// near 1.8e308.
const MAX_LIM: f64 = 1e100;

/// Lowest level floor accepted, dB SPL (amplitude 10^-15): the loops divide by the
/// floor's roots, and a floor that reaches 0 (below about −6000 dB) gave NaN.
const MIN_FLOOR_DB: f64 = -200.0;

impl Adaptation {
    /// Builds the loops for the IHC signal `input` (its `cf_hz` gives the van Dorp
    /// Schuitman floor); `params` are taken after their preset (see
    /// [`AdaptationParams::with_preset`]).
    pub fn new(params: &AdaptationParams, input: &SignalInfo) -> Result<(Self, SignalInfo)> {
        let p = params.with_preset();
        let fs = input.fs_hz;
        if p.tau_sec.is_empty() || p.tau_sec.iter().any(|t| *t <= 0.0) {
            return Err(Error::invalid(
                AdaptationParams::NAMES.tau_sec,
                format!("{:?}", p.tau_sec),
                "needs at least one time constant, each > 0 s",
            ));
        }
        let floor_db: Vec<f64> = match p.model {
            AdaptationModel::VanDorpSchuitman => input
                .cf_hz()
                .iter()
                .map(|&f| threshold_of_hearing_db(f))
                .collect(),
            _ => vec![p.min_db_spl; input.channels()],
        };
        if let Some(db) = floor_db
            .iter()
            .find(|db| db.is_nan() || **db >= 100.0 || **db < MIN_FLOOR_DB)
        {
            let (name, value) = match p.model {
                AdaptationModel::VanDorpSchuitman => (
                    AdaptationParams::NAMES.model,
                    "\"adt_vandorpschuitman\"".to_string(),
                ),
                _ => (AdaptationParams::NAMES.min_db_spl, p.min_db_spl.to_string()),
            };
            return Err(Error::invalid(name, value, format!(
                    "the level floor ({db} dB SPL) must be below 100 dB SPL (amplitude 1) and \
                     at least {MIN_FLOOR_DB} dB SPL (the loops divide by it: lower floors reach \
                     0 and give NaN); the van Dorp Schuitman floor exceeds 100 dB above about 17.8 kHz"
                )));
        }
        let loops = p.tau_sec.len();
        let a1: Vec<f64> = p.tau_sec.iter().map(|t| (-1.0 / (t * fs)).exp()).collect();
        let b0 = a1.iter().map(|a| 1.0 - a).collect();
        let min_level: Vec<f64> = floor_db
            .iter()
            .map(|db| 10f64.powf((db - 100.0) / 20.0))
            .collect();
        let initial: Vec<f64> = (1..=loops)
            .flat_map(|j| {
                let e = 1.0 / 2f64.powi(j as i32);
                min_level.iter().map(move |m| m.powf(e))
            })
            .collect();
        let corr: Vec<f64> = min_level
            .iter()
            .map(|m| m.powf(1.0 / 2f64.powi(loops as i32)))
            .collect();
        let mult: Vec<f64> = corr.iter().map(|c| 100.0 / (1.0 - c)).collect();
        if p.lim > MAX_LIM {
            return Err(Error::invalid(
                AdaptationParams::NAMES.lim,
                p.lim,
                format!(
                    "must be at most {MAX_LIM:e}: larger factors overflow the limitation's \
                     constants (NaN); a factor that large limits nothing: use at most 1 to \
                     disable the limitation"
                ),
            ));
        }
        let limit = if p.lim > 1.0 {
            let constants: Vec<[f64; 3]> = initial
                .iter()
                .map(|s0| {
                    let m = (1.0 - s0 * s0) * p.lim - 1.0;
                    [2.0 * m, -2.0 / m, m - 1.0]
                })
                .collect();
            if constants.iter().any(|[f, _, _]| f.is_nan() || *f <= 0.0) {
                return Err(Error::invalid(
                    AdaptationParams::NAMES.lim,
                    p.lim,
                    "above 1, the limitation factor must exceed 1/(1 − s0²) of every \
                             loop's initial state s0 (use at most 1 to disable it)",
                ));
            }
            Some(Limit {
                f: constants.iter().map(|c| c[0]).collect(),
                ex: constants.iter().map(|c| c[1]).collect(),
                off: constants.iter().map(|c| c[2]).collect(),
            })
        } else {
            None
        };
        let nc = input.channels();
        let lanes = nc.max(1).next_multiple_of(STEP);
        // Padding lanes hold 1: divided by a state of 1 they stay 1, below the limitation.
        let pad = |v: &[f64], fill| padded(v, nc, lanes, fill);
        let initial = pad(&initial, 1.0);
        let adaptation = Adaptation {
            a1,
            b0,
            channels: nc,
            lanes,
            min_level: pad(&min_level, 1.0),
            corr: pad(&corr, 0.0),
            mult: pad(&mult, 1.0),
            state: initial.clone(),
            initial,
            limit: limit.map(|l| Limit {
                f: pad(&l.f, 0.0),
                ex: pad(&l.ex, 0.0),
                off: pad(&l.off, 0.0),
            }),
            row: vec![1.0; lanes],
            stages: vec![1.0; loops * lanes],
        };
        let info = input
            .clone()
            .with_unit(Self::OUTPUT_UNIT)
            .drawn_as(DrawAs::AmplitudeDecibels { range_db: 60.0 });
        Ok((adaptation, info))
    }
}

impl Processor for Adaptation {
    fn process(&mut self, inputs: &[&Block], outputs: &mut [Block]) {
        let input = inputs[0];
        let out = outputs[0].resize_to(input.frames());
        adapt(self, input.as_slice(), out);
    }

    fn reset(&mut self) {
        self.state.copy_from_slice(&self.initial);
    }
}

/// Overshoot limitation constants per `[loop][channel]`: above 1, a loop's output `v`
/// becomes `f / (1 + exp(ex·(v − 1))) − off`.
#[derive(Debug, Clone)]
struct Limit {
    f: Vec<f64>,
    ex: Vec<f64>,
    off: Vec<f64>,
}

afe_core::simd_kernel!(
    fma,
    /// Runs the loops over `input` (`[time][channel]`) into `out`, eight lanes at a time so that
    /// the divisions, state updates and the overshoot limitation (computed for the eight lanes
    /// where one of them is above 1, kept where the value is) vectorise.
    ///
    /// The loops are staggered: at step `t`, loop `j` works on sample `t − j`, taking what
    /// loop `j − 1` gave at step `t − 1`. The loops of one step are then independent, so
    /// their divisions and limitations overlap instead of each waiting on the one before;
    /// every sample still sees the same operations in the same order.
    fn adapt(a: &mut Adaptation, input: &[f64], out: &mut [f64]) {
        let (nc, lanes, loops) = (a.channels.max(1), a.lanes, a.a1.len());
        let n = input.len() / nc;
        for t in 0..(n + loops).saturating_sub(1) {
            if let Some(x) = input.get(t * nc..(t + 1) * nc) {
                for ((v, &x), &m) in a.row.iter_mut().zip(x).zip(&a.min_level) {
                    *v = x.max(m);
                }
            }
            // last loop first, so that each reads its predecessor's value of the step before
            for j in (0..loops).rev().filter(|j| (*j..n + j).contains(&t)) {
                let (before, from_j) = a.stages.split_at_mut(j * lanes);
                let src = if j == 0 {
                    &a.row[..]
                } else {
                    &before[(j - 1) * lanes..]
                };
                let (a1, b0) = (a.a1[j], a.b0[j]);
                for (k, (src, dst)) in src
                    .chunks_exact(STEP)
                    .zip(from_j[..lanes].chunks_exact_mut(STEP))
                    .enumerate()
                {
                    let at = j * lanes + k * STEP..j * lanes + (k + 1) * STEP;
                    let (mut v, mut s) = ([0.0; STEP], [0.0; STEP]);
                    v.copy_from_slice(src);
                    s.copy_from_slice(&a.state[at.clone()]);
                    for (v, s) in v.iter_mut().zip(&s) {
                        *v /= s;
                    }
                    if let Some(l) = &a.limit {
                        if v.iter().fold(false, |any, v| any | (*v > 1.0)) {
                            let (mut f, mut ex, mut off) = ([0.0; STEP], [0.0; STEP], [0.0; STEP]);
                            f.copy_from_slice(&l.f[at.clone()]);
                            ex.copy_from_slice(&l.ex[at.clone()]);
                            off.copy_from_slice(&l.off[at.clone()]);
                            for (v, ((f, ex), off)) in v.iter_mut().zip(f.iter().zip(&ex).zip(&off))
                            {
                                let limited = f / (1.0 + exp(ex * (*v - 1.0))) - off;
                                *v = if *v > 1.0 { limited } else { *v };
                            }
                        }
                    }
                    for (s, v) in s.iter_mut().zip(&v) {
                        *s = a1 * *s + b0 * v;
                    }
                    a.state[at].copy_from_slice(&s);
                    dst.copy_from_slice(&v);
                }
            }
            // the last loop has just finished sample t − (loops − 1)
            if let Some(y) = (t + 1)
                .checked_sub(loops)
                .and_then(|s| out.get_mut(s * nc..(s + 1) * nc))
            {
                let last = &a.stages[(loops - 1) * lanes..];
                for (((y, v), c), m) in y.iter_mut().zip(last).zip(&a.corr).zip(&a.mult) {
                    *y = (v - c) * m;
                }
            }
        }
    }
);

impl Descriptor for Adaptation {
    type Params = AdaptationParams;
    const NAME: &'static str = "adaptation";
    const DEPENDENCY: &'static str = "innerhaircell";
    const EARS: Ears = Ears::PerEar;
    const DESCRIPTION: &'static str =
        "adaptation loops: compressed IHC envelope per frequency channel";
    const OUTPUT_UNIT: &'static str = "model units";

    fn build(params: &AdaptationParams, inputs: &[SignalInfo]) -> Result<Built> {
        let (p, out) = Adaptation::new(params, &inputs[0])?;
        Ok(Built::new(p, vec![out]))
    }

    /// The parameters after the preset (the AFE applies presets when it verifies
    /// parameters, so two requests reaching the same values share the node).
    fn canonical(params: &AdaptationParams) -> Result<afe_core::ParamMap> {
        Ok(params.clone().with_preset().to_map())
    }
}

/// The registry entry of `adaptation`.
pub static REQUEST: RequestDef = request_def::<Adaptation>();

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn ihc(nc: usize) -> SignalInfo {
        SignalInfo::time_frequency(16000.0, (0..nc).map(|c| 200.0 * (c + 1) as f64).collect())
    }

    fn run(p: &AdaptationParams, nc: usize, x: &[f64], chunks: &[usize]) -> Vec<f64> {
        let (mut a, _) = Adaptation::new(p, &ihc(nc)).expect("valid");
        crate::testing::feed(&mut a, x, nc, nc, chunks.iter().copied().cycle())
    }

    #[test]
    fn floor_input_gives_zero_and_constant_input_settles_to_the_closed_form() {
        // No limitation, so that the stationary value is (v0^(1/2^L) − corr)·mult.
        let p = AdaptationParams {
            lim: 0.0,
            ..Default::default()
        };
        let silent = run(&p, 1, &[0.0; 100], &[100]);
        assert!(silent.iter().all(|v| v.abs() < 1e-9), "{silent:?}");
        let v0: f64 = 0.01;
        let y = run(&p, 1, &vec![v0; 160_000], &[160_000]);
        let corr = 1e-5f64.powf(1.0 / 32.0);
        let want = (v0.powf(1.0 / 32.0) - corr) * 100.0 / (1.0 - corr);
        let last = y[y.len() - 1];
        assert!((last - want).abs() < 1e-6 * want, "{last} vs {want}");
    }

    /// The spec's loops written out one channel and one sample at a time, with the
    /// floor `floor_db` (dB SPL) per channel: the reference for the vectorised [`adapt`].
    fn spec_loops(p: &AdaptationParams, floor_db: &[f64], fs: f64, x: &[f64]) -> Vec<f64> {
        let p = p.with_preset();
        let nc = floor_db.len();
        let mut y = vec![0.0; x.len()];
        for (c, db) in floor_db.iter().enumerate() {
            let min_level = 10f64.powf((db - 100.0) / 20.0);
            let loops = p.tau_sec.len() as i32;
            let s0: Vec<f64> = (1..=loops)
                .map(|j| min_level.powf(0.5f64.powi(j)))
                .collect();
            let mut s = s0.clone();
            let corr = min_level.powf(0.5f64.powi(loops));
            for n in 0..x.len() / nc {
                let mut v = x[n * nc + c].max(min_level);
                for (j, tau) in p.tau_sec.iter().enumerate() {
                    let a1 = (-1.0 / (tau * fs)).exp();
                    v /= s[j];
                    if p.lim > 1.0 && v > 1.0 {
                        let m = (1.0 - s0[j] * s0[j]) * p.lim - 1.0;
                        v = 2.0 * m / (1.0 + (-2.0 / m * (v - 1.0)).exp()) - (m - 1.0);
                    }
                    s[j] = a1 * s[j] + (1.0 - a1) * v;
                }
                y[n * nc + c] = (v - corr) * 100.0 / (1.0 - corr);
            }
        }
        y
    }

    #[test]
    fn every_preset_and_parameter_set_follows_the_spec_loops() {
        let fs = 16000.0;
        let cf = [250.0, 1000.0, 4000.0];
        // Terhardt's threshold at the three centre frequencies, worked separately.
        let vds_floor = [11.009935589514262, 3.369066525895342, -3.3875449955780423];
        for (f, db) in cf.iter().zip(vds_floor) {
            assert!((threshold_of_hearing_db(*f) - db).abs() < 1e-12, "{f} Hz");
        }
        let model = |model| AdaptationParams {
            model,
            ..Default::default()
        };
        let custom = AdaptationParams {
            lim: 5.0,
            min_db_spl: 20.0,
            tau_sec: vec![0.01, 0.2],
            model: AdaptationModel::None,
        };
        // 3 channels (one step of eight with padding lanes) and 16 (two whole steps)
        for nc in [3, 16] {
            let cf: Vec<f64> = (0..nc)
                .map(|c| 250.0 * 16f64.powf(c as f64 / (nc - 1) as f64))
                .collect();
            let thresholds: Vec<f64> = cf.iter().map(|f| threshold_of_hearing_db(*f)).collect();
            // Silences (the floor), rises above 1 (the limitation) and slow decays.
            let x: Vec<f64> = (0..2400 * nc)
                .map(|i| {
                    let n = i / nc;
                    let u = ((i * 7919) % 1009) as f64 / 1009.0;
                    if n % 600 < 150 {
                        0.0
                    } else {
                        3.0 * u * u * (1.0 + (i % 3) as f64)
                    }
                })
                .collect();
            let cases = [
                (AdaptationParams::default(), vec![0.0; nc]),
                (model(AdaptationModel::Puschel), vec![0.0; nc]),
                (model(AdaptationModel::Breebaart), vec![0.0; nc]),
                (model(AdaptationModel::VanDorpSchuitman), thresholds),
                (custom.clone(), vec![20.0; nc]),
            ];
            for (p, floor) in cases {
                let info = SignalInfo::time_frequency(fs, cf.clone());
                let (mut a, _) = Adaptation::new(&p, &info).expect("valid");
                let got = crate::testing::feed(&mut a, &x, nc, nc, [700, 1700]);
                let want = spec_loops(&p, &floor, fs, &x);
                assert_eq!(got.len(), want.len());
                for (n, (g, w)) in got.iter().zip(&want).enumerate() {
                    assert!(
                        (g - w).abs() <= 1e-12 * w.abs().max(1.0),
                        "{nc} channels, {p:?} at {n}: {g} vs {w}"
                    );
                }
            }
        }
    }

    #[test]
    fn limitation_bounds_the_onset_overshoot() {
        let x: Vec<f64> = (0..4000).map(|n| if n < 100 { 0.0 } else { 1.0 }).collect();
        let limited = run(&AdaptationParams::default(), 1, &x, &[4000]);
        let free = run(
            &AdaptationParams {
                lim: 1.0,
                ..Default::default()
            },
            1,
            &x,
            &[4000],
        );
        let peak = |y: &[f64]| y.iter().fold(0.0f64, |a, v| a.max(*v));
        assert!(peak(&limited) < peak(&free) / 10.0);
        assert!(peak(&limited) > 0.0);
    }

    #[test]
    fn presets_override_the_other_parameters() {
        let p = AdaptationParams {
            lim: 3.0,
            min_db_spl: 20.0,
            tau_sec: vec![0.1],
            model: AdaptationModel::Puschel,
        }
        .with_preset();
        assert_eq!((p.lim, p.min_db_spl), (0.0, 0.0));
        let want = [0.005, 0.12875, 0.2525, 0.37625, 0.5];
        assert_eq!(p.tau_sec.len(), want.len());
        assert!(p
            .tau_sec
            .iter()
            .zip(want)
            .all(|(t, w)| (t - w).abs() < 1e-15));
        // The node is keyed by the values after the preset: the preset and the same
        // values written out share it.
        let written_out = AdaptationParams {
            lim: 0.0,
            min_db_spl: 0.0,
            tau_sec: linspace(0.005, 0.5, 5),
            model: AdaptationModel::Puschel,
        };
        let preset = AdaptationParams {
            model: AdaptationModel::Puschel,
            ..Default::default()
        };
        let key = <Adaptation as Descriptor>::canonical(&preset).expect("valid");
        assert_eq!(key, written_out.to_map());
        let map: afe_core::ParamMap = [(
            "adpt_model".to_string(),
            serde_json::json!("adt_vandorpschuitman"),
        )]
        .into_iter()
        .collect();
        let p = AdaptationParams::from_map(&map).expect("valid");
        assert_eq!(p.model, AdaptationModel::VanDorpSchuitman);
        // the floor follows the threshold of hearing, so silence gives 0 in every channel
        let y = run(&p, 3, &[0.0; 300], &[100]);
        assert!(y.iter().all(|v| v.abs() < 1e-9));
        let (a, _) = Adaptation::new(&p, &ihc(3)).expect("valid");
        assert!(a.min_level[0] > a.min_level[2]);
    }

    #[test]
    fn bad_parameters_are_errors_naming_them() {
        let cases = [
            (
                AdaptationParams {
                    tau_sec: vec![],
                    ..Default::default()
                },
                "adpt_tau",
            ),
            (
                AdaptationParams {
                    tau_sec: vec![0.01, -0.1],
                    ..Default::default()
                },
                "adpt_tau",
            ),
            (
                AdaptationParams {
                    min_db_spl: 100.0,
                    ..Default::default()
                },
                "adpt_mindB",
            ),
            (
                AdaptationParams {
                    lim: 1.000_001,
                    min_db_spl: 99.0,
                    ..Default::default()
                },
                "adpt_lim",
            ),
            // NaN from finite parameters: a floor that reaches 0, constants that overflow
            (
                AdaptationParams {
                    min_db_spl: -201.0,
                    ..Default::default()
                },
                "adpt_mindB",
            ),
            (
                AdaptationParams {
                    lim: 1.7e308,
                    ..Default::default()
                },
                "adpt_lim",
            ),
        ];
        for (p, name) in cases {
            let e = Adaptation::new(&p, &ihc(2)).expect_err(name).to_string();
            assert!(e.contains(name), "{e}");
        }
        let vds = AdaptationParams {
            model: AdaptationModel::VanDorpSchuitman,
            ..Default::default()
        };
        let high = SignalInfo::time_frequency(44100.0, vec![1000.0, 19000.0]);
        let e = Adaptation::new(&vds, &high).expect_err("floor").to_string();
        assert!(e.contains("adpt_model"), "{e}");
        let map: afe_core::ParamMap = [("adpt_model".to_string(), serde_json::json!("dau"))]
            .into_iter()
            .collect();
        let e = AdaptationParams::from_map(&map)
            .expect_err("model")
            .to_string();
        assert!(e.contains("adpt_model"), "{e}");
    }

    #[test]
    fn reset_restarts_from_the_initial_states() {
        let p = AdaptationParams::default();
        let x: Vec<f64> = (0..600).map(|n| (n as f64 * 0.05).sin().abs()).collect();
        let (mut a, _) = Adaptation::new(&p, &ihc(2)).expect("valid");
        let chunk = Block::from_vec(x, 2);
        let mut first = vec![Block::new(2)];
        a.process(&[&chunk], &mut first);
        a.reset();
        let mut second = vec![Block::new(2)];
        a.process(&[&chunk], &mut second);
        assert_eq!(first, second);
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, failure_persistence: None, ..ProptestConfig::default() })]

        /// Any chunking gives the output of one call, bit for bit.
        #[test]
        fn any_chunking_is_bit_identical(
            seed in 0u64..1000,
            chunks in prop::collection::vec(1usize..300, 1..8),
            limited in any::<bool>(),
        ) {
            let nc = 3;
            let x: Vec<f64> = crate::testing::noise(1500 * nc, seed)
                .iter()
                .enumerate()
                .map(|(i, u)| if i % 97 < 40 { 0.0 } else { (u + 0.5) * (u + 0.5) })
                .collect();
            let p = AdaptationParams { lim: if limited { 10.0 } else { 0.0 }, ..Default::default() };
            let whole = run(&p, nc, &x, &[1500]);
            let chunked = run(&p, nc, &x, &chunks);
            prop_assert_eq!(whole.len(), chunked.len());
            prop_assert!(whole.iter().zip(&chunked).all(|(a, b)| a.to_bits() == b.to_bits()));
        }
    }
}
