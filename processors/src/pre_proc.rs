//! `time` (preProc): DC removal, pre-emphasis, RMS normalisation (AGC), level scaling and
//! middle-ear filtering, in that order (spec 10-preProc). All off by default (identity).
//!
//! One instance serves both ears, because the AGC can link their gains.

use afe_core::butter::{butter_filters, ButterType};
use afe_core::descriptor::{request_def, Built, Descriptor, Ears, RequestDef};
use afe_core::filter::Df2t;
use afe_core::{Block, DrawAs, Error, ParamMap, Params, Processor, Result, SignalInfo};

use crate::filterbank_params::{fb_type_of, FbType};
use crate::middle_ear::{self, MiddleEarModel};

afe_core::params! {
    /// Parameters of the pre-processor, under their AFE names.
    pub struct PreProcParams / PreProcNames {
        /// remove DC with a 4th-order Butterworth high-pass
        #[afe = "pp_bRemoveDC"]
        pub remove_dc: bool = false,
        /// cut-off of the DC-removal high-pass
        #[afe = "pp_cutoffHzDC", unit = "Hz"]
        pub cutoff_hz_dc: f64 = 20.0,
        /// apply the pre-emphasis FIR y[n] = x[n] − |c|·x[n−1]
        #[afe = "pp_bPreEmphasis"]
        pub pre_emphasis: bool = false,
        /// pre-emphasis coefficient c
        #[afe = "pp_coefPreEmphasis"]
        pub coef_pre_emphasis: f64 = 0.97,
        /// normalise by the running RMS (AGC)
        #[afe = "pp_bNormalizeRMS"]
        pub normalize_rms: bool = false,
        /// link the AGC gains of both ears
        #[afe = "pp_bBinauralRMS"]
        pub binaural_rms: bool = true,
        /// AGC integration time constant
        #[afe = "pp_intTimeSecRMS", unit = "s"]
        pub int_time_sec_rms: f64 = 0.5,
        /// scale the input by 10^((100 − pp_refSPLdB)/20) (see pp_refSPLdB)
        #[afe = "pp_bLevelScaling"]
        pub level_scaling: bool = false,
        /// level reference: the input is multiplied by 10^((100 − pp_refSPLdB)/20) as the AFE's
        /// code does, so 80 amplifies by 20 dB (the AFE calls it the dB SPL of RMS 1, which its
        /// code inverts; the models take RMS 1 as 100 dB SPL); one value, or [left, right]
        #[afe = "pp_refSPLdB", unit = "dB"]
        pub ref_spl_db: Vec<f64> = vec![100.0],
        /// apply the middle-ear FIR
        #[afe = "pp_bMiddleEarFiltering"]
        pub middle_ear_filtering: bool = false,
        /// middle-ear filter model
        #[afe = "pp_middleEarModel"]
        pub middle_ear_model: MiddleEarModel = MiddleEarModel::Jepsen,
        /// compensate the middle-ear filter to a 0 dB peak
        #[afe = "pp_bUnityComp"]
        pub unity_comp: bool = true,
    }
}

/// Lowest sampling rate in Hz at which the middle-ear designs have data to work from.
const MIN_MIDDLE_EAR_FS: f64 = 2000.0;

/// The per-ear state of the pre-processor.
#[derive(Debug, Clone)]
struct Ear {
    /// The DC-removal high-pass, filters in series (none when off).
    dc: Vec<Df2t>,
    emphasis: Option<Df2t>,
    agc: Df2t,
    agc_seeded: bool,
    level_gain: f64,
    middle_ear: Option<Df2t>,
}

/// The pre-processor of both ears (or the single ear of a mono input).
#[derive(Debug, Clone)]
pub struct PreProc {
    params: PreProcParams,
    ears: Vec<Ear>,
    /// AGC: α and the number of seeding samples `round(τ·fs)`.
    alpha: f64,
    seed_len: usize,
    middle_ear_gain: f64,
    /// The most the processing raises the input's amplitude (see `Built::input_gain`).
    amplitude_gain: f64,
    /// Per-ear normaliser scratch.
    norm: [Vec<f64>; 2],
}

/// Levels accepted for `pp_refSPLdB`, in dB SPL: a level-scaling gain `10^((100 − L)/20)`
/// within `10^±20`, so that the scaled signal can neither overflow nor vanish.
const REF_SPL_DB_RANGE: (f64, f64) = (-300.0, 500.0);

/// Largest `|pp_coefPreEmphasis|` accepted.
const MAX_PRE_EMPHASIS: f64 = 1e3;

impl PreProc {
    /// Builds the pre-processor for `ears` (1 or 2) input signals at `fs` Hz.
    pub fn new(params: &PreProcParams, fs: f64, ears: usize) -> Result<(Self, Vec<SignalInfo>)> {
        let p = params;
        if p.remove_dc && !(p.cutoff_hz_dc > 0.0 && p.cutoff_hz_dc < fs / 2.0) {
            return Err(Error::invalid(
                PreProcParams::NAMES.cutoff_hz_dc,
                p.cutoff_hz_dc,
                format!(
                    "must lie between 0 and the Nyquist frequency ({} Hz)",
                    fs / 2.0
                ),
            ));
        }
        if p.middle_ear_filtering && fs < MIN_MIDDLE_EAR_FS {
            return Err(Error::invalid(
                PreProcParams::NAMES.middle_ear_filtering,
                "true",
                format!(
                    "the middle-ear data tables start at 50–400 Hz: filtering needs a sampling rate of at least {MIN_MIDDLE_EAR_FS} Hz (the input has {fs} Hz)"
                ),
            ));
        }
        if p.normalize_rms && p.int_time_sec_rms <= 0.0 {
            return Err(Error::invalid(
                PreProcParams::NAMES.int_time_sec_rms,
                p.int_time_sec_rms,
                "must be > 0 s",
            ));
        }
        if !(1..=2).contains(&p.ref_spl_db.len()) {
            return Err(Error::invalid(
                PreProcParams::NAMES.ref_spl_db,
                format!("{:?}", p.ref_spl_db),
                "expected one value or two ([left, right])",
            ));
        }
        let (lo, hi) = REF_SPL_DB_RANGE;
        if let Some(db) = p.ref_spl_db.iter().find(|db| !(lo..=hi).contains(*db)) {
            return Err(Error::invalid(
                PreProcParams::NAMES.ref_spl_db,
                format!("{:?}", p.ref_spl_db),
                format!(
                    "{db} dB would scale the signal by 10^({:.3e}/20): give levels between {lo} and \
                     {hi} dB SPL (a gain within 10^±20), beyond which the output over- or \
                     underflows",
                    100.0 - db
                ),
            ));
        }
        if p.coef_pre_emphasis.is_nan() || p.coef_pre_emphasis.abs() > MAX_PRE_EMPHASIS {
            return Err(Error::invalid(
                PreProcParams::NAMES.coef_pre_emphasis,
                p.coef_pre_emphasis,
                format!(
                    "the pre-emphasis y[n] = x[n] − |c|·x[n−1] takes |c| up to \
                     {MAX_PRE_EMPHASIS} (usually just below 1, AFE default 0.97); larger \
                     values overflow the processing"
                ),
            ));
        }
        let dc: Vec<Df2t> = if p.remove_dc {
            butter_filters(4, &[p.cutoff_hz_dc / (fs / 2.0)], ButterType::High)
                .iter()
                .map(|(b, a)| Df2t::new(b, a, 1))
                .collect()
        } else {
            Vec::new()
        };
        let emphasis = p
            .pre_emphasis
            .then(|| Df2t::new(&[1.0, -p.coef_pre_emphasis.abs()], &[1.0], 1));
        let alpha = (-1.0 / (p.int_time_sec_rms * fs)).exp();
        let mut middle_ear_l1 = 1.0;
        let middle_ear = p.middle_ear_filtering.then(|| {
            let b = match p.middle_ear_model {
                MiddleEarModel::LopezPoveda => middle_ear::lopezpoveda(fs),
                MiddleEarModel::Jepsen => middle_ear::jepsen(fs),
            };
            middle_ear_l1 = b.iter().map(|v| v.abs()).sum();
            Df2t::new(&b, &[1.0], 1)
        });
        let middle_ear_gain = if p.unity_comp {
            10f64.powf(middle_ear::unity_comp_db(p.middle_ear_model) / 20.0)
        } else {
            1.0
        };
        let ear_states: Vec<Ear> = (0..ears)
            .map(|e| Ear {
                dc: dc.clone(),
                emphasis: emphasis.clone(),
                agc: Df2t::new(&[1.0 + (-alpha)], &[1.0, -alpha], 1),
                agc_seeded: false,
                level_gain: 10f64
                    .powf((100.0 - p.ref_spl_db[e.min(p.ref_spl_db.len() - 1)]) / 20.0),
                middle_ear: middle_ear.clone(),
            })
            .collect();
        // the most each stage can raise the amplitude: the level scaling, the
        // pre-emphasis (1 + |c|) and the middle-ear filter (the sum of its taps' magnitudes)
        let level = if p.level_scaling {
            (ear_states.iter()).fold(0.0f64, |m, e| m.max(e.level_gain))
        } else {
            1.0
        };
        let emphasis_gain = if p.pre_emphasis {
            1.0 + p.coef_pre_emphasis.abs()
        } else {
            1.0
        };
        let middle_ear_bound = if p.middle_ear_filtering {
            middle_ear_gain * middle_ear_l1
        } else {
            1.0
        };
        let pre = PreProc {
            params: p.clone(),
            ears: ear_states,
            alpha,
            seed_len: (p.int_time_sec_rms * fs).round().max(0.0) as usize,
            middle_ear_gain,
            amplitude_gain: level * emphasis_gain * middle_ear_bound,
            norm: [Vec::new(), Vec::new()],
        };
        let info = SignalInfo::time_domain(fs)
            .with_unit(Self::OUTPUT_UNIT)
            .drawn_as(DrawAs::AmplitudeDecibels { range_db: 60.0 });
        Ok((pre, vec![info; ears]))
    }

    /// Computes the AGC normaliser `sqrt(m[n]) + 1e−8` of ear `e` into `self.norm[e]`.
    fn agc_normaliser(&mut self, e: usize, x: &[f64]) {
        let ear = &mut self.ears[e];
        let norm = &mut self.norm[e];
        norm.clear();
        norm.extend(x.iter().map(|v| v * v));
        if !ear.agc_seeded && !x.is_empty() {
            let k = x.len().min(self.seed_len).max(1);
            let ms0 = norm[..k].iter().sum::<f64>() / k as f64;
            ear.agc.set_first_state(0, self.alpha * ms0);
            ear.agc_seeded = true;
        }
        ear.agc.process(norm);
        for v in norm.iter_mut() {
            *v = v.sqrt() + 1e-8;
        }
    }
}

impl Processor for PreProc {
    fn process(&mut self, inputs: &[&Block], outputs: &mut [Block]) {
        let n_ears = self.ears.len();
        for e in 0..n_ears {
            let out = &mut outputs[e];
            out.reset_to(0);
            out.extend_from(inputs[e]);
            let x = out.as_mut_slice();
            let ear = &mut self.ears[e];
            for f in &mut ear.dc {
                f.process(x);
            }
            if let Some(f) = &mut ear.emphasis {
                f.process(x);
            }
            if self.params.normalize_rms {
                self.agc_normaliser(e, x);
            }
        }
        if self.params.normalize_rms {
            if self.params.binaural_rms && n_ears == 2 {
                let [l, r] = &mut self.norm;
                for (a, b) in l.iter_mut().zip(r.iter_mut()) {
                    let m = a.max(*b);
                    *a = m;
                    *b = m;
                }
            }
            for (out, norm) in outputs.iter_mut().zip(&self.norm) {
                for (x, g) in out.as_mut_slice().iter_mut().zip(norm) {
                    *x /= g;
                }
            }
        }
        for (out, ear) in outputs.iter_mut().zip(&mut self.ears) {
            let x = out.as_mut_slice();
            if self.params.level_scaling {
                x.iter_mut().for_each(|v| *v *= ear.level_gain);
            }
            if let Some(f) = &mut ear.middle_ear {
                f.process(x);
                x.iter_mut().for_each(|v| *v *= self.middle_ear_gain);
            }
        }
    }

    /// Resets every filter; the AGC is seeded again from the next chunk (the port's
    /// documented choice, where MATLAB would start a re-used manager's AGC from zero).
    fn reset(&mut self) {
        for ear in &mut self.ears {
            for f in [&mut ear.emphasis, &mut ear.middle_ear]
                .into_iter()
                .flatten()
                .chain(&mut ear.dc)
            {
                f.reset();
            }
            ear.agc.reset();
            ear.agc_seeded = false;
        }
    }
}

impl Descriptor for PreProc {
    type Params = PreProcParams;
    const NAME: &'static str = "time";
    const DEPENDENCY: &'static str = "input";
    const EARS: Ears = Ears::All;
    const DESCRIPTION: &'static str =
        "pre-processed ear signals (DC removal, pre-emphasis, AGC, level, middle ear)";
    const OUTPUT_UNIT: &'static str = "";

    /// With `fb_type = 'drnl'` the middle-ear output is not unity-compensated
    /// (`pp_bUnityComp = false`, spec 12-drnl): the DRNL's coefficients expect the
    /// physical units. The AFE's DRNL sets this in the pre-processor it is prepared on;
    /// here it follows from the request's parameters, which gives a DRNL chain its own
    /// pre-processor, as the AFE's sharing rule does. (A request without a filterbank,
    /// e.g. `stft`, given `fb_type = 'drnl'` is affected too, where the AFE would not be.)
    fn params(map: &ParamMap) -> Result<PreProcParams> {
        let mut params = PreProcParams::from_map(map)?;
        if fb_type_of(map)? == FbType::Drnl {
            params.unity_comp = false;
        }
        Ok(params)
    }

    fn build(params: &PreProcParams, inputs: &[SignalInfo]) -> Result<Built> {
        let (p, outputs) = PreProc::new(params, inputs[0].fs_hz, inputs.len())?;
        let gain = p.amplitude_gain;
        Ok(Built::new(p, outputs).with_input_gain(gain))
    }

    /// The AGC seeds its running mean from the first chunk.
    fn chunk_invariant(params: &PreProcParams) -> bool {
        !params.normalize_rms
    }

    /// The seed is the mean square of the first `round(pp_intTimeSecRMS·fs)` samples of
    /// the first chunk; past that prefix the AGC is a plain recursive filter.
    fn one_call_prefix_s(params: &PreProcParams) -> Option<f64> {
        Some(params.int_time_sec_rms)
    }
}

/// The registry entry of `time`.
pub static REQUEST: RequestDef = request_def::<PreProc>();

#[cfg(test)]
mod tests {
    use super::*;

    fn run(p: &PreProcParams, ears: &[Vec<f64>], fs: f64) -> Vec<Vec<f64>> {
        let (mut pre, _) = PreProc::new(p, fs, ears.len()).expect("valid");
        let inputs: Vec<Block> = ears.iter().map(|x| Block::from_vec(x.clone(), 1)).collect();
        let refs: Vec<&Block> = inputs.iter().collect();
        let mut outs = vec![Block::new(1); ears.len()];
        pre.process(&refs, &mut outs);
        outs.into_iter().map(Block::into_vec).collect()
    }

    /// Under a DRNL the middle-ear output is not unity-compensated (spec 12-drnl), and
    /// the node's parameters say so.
    #[test]
    fn drnl_requests_turn_unity_compensation_off() {
        let map = |fb_type: &str| -> afe_core::ParamMap {
            [("fb_type".to_string(), serde_json::json!(fb_type))]
                .into_iter()
                .collect()
        };
        let drnl = <PreProc as Descriptor>::params(&map("drnl")).expect("valid");
        assert!(!drnl.unity_comp);
        let gammatone = <PreProc as Descriptor>::params(&map("gammatone")).expect("valid");
        assert!(gammatone.unity_comp);
        let configured = (REQUEST.configure)(&map("drnl")).expect("valid");
        assert_eq!(
            configured.canonical()["pp_bUnityComp"],
            serde_json::json!(false)
        );
    }

    #[test]
    fn defaults_are_identity() {
        let x = vec![0.1, -0.5, 0.25, 1.0];
        let y = run(&PreProcParams::default(), &[x.clone(), x.clone()], 16000.0);
        assert_eq!(y, vec![x.clone(), x]);
    }

    #[test]
    fn pre_emphasis_and_level_scaling() {
        let p = PreProcParams {
            pre_emphasis: true,
            level_scaling: true,
            ref_spl_db: vec![80.0, 100.0],
            ..Default::default()
        };
        let y = run(&p, &[vec![1.0, 1.0], vec![1.0, 1.0]], 16000.0);
        assert!((y[0][0] - 10.0).abs() < 1e-12 && (y[0][1] - 0.3).abs() < 1e-12);
        assert!((y[1][1] - 0.03).abs() < 1e-15);
    }

    #[test]
    fn agc_brings_a_steady_tone_to_unit_rms() {
        let fs = 8000.0;
        let x: Vec<f64> = (0..16000).map(|t| 0.01 * (0.3 * t as f64).sin()).collect();
        let p = PreProcParams {
            normalize_rms: true,
            ..Default::default()
        };
        let y = run(&p, &[x], fs);
        let tail = &y[0][8000..];
        let rms = (tail.iter().map(|v| v * v).sum::<f64>() / tail.len() as f64).sqrt();
        assert!((rms - 1.0).abs() < 0.02, "{rms}");
    }

    /// RMS of the second half.
    fn tail_rms(y: &[f64]) -> f64 {
        let tail = &y[y.len() / 2..];
        (tail.iter().map(|v| v * v).sum::<f64>() / tail.len() as f64).sqrt()
    }

    #[test]
    fn agc_floor_and_binaural_link() {
        let fs = 8000.0;
        let tone =
            |a: f64| -> Vec<f64> { (0..16000).map(|t| a * (0.3 * t as f64).sin()).collect() };
        let agc = |binaural_rms: bool| PreProcParams {
            normalize_rms: true,
            binaural_rms,
            ..Default::default()
        };
        // The normaliser is RMS + 1e-8: a tone of RMS 1e-8 comes out at RMS 1/2.
        let y = run(&agc(false), &[tone(2f64.sqrt() * 1e-8)], fs);
        assert!((tail_rms(&y[0]) - 0.5).abs() < 0.01, "{}", tail_rms(&y[0]));
        // Linked, both ears share the louder ear's normaliser; unlinked, each its own.
        let ears = [tone(0.01), tone(0.02)];
        let linked = run(&agc(true), &ears, fs);
        let (l, r) = (tail_rms(&linked[0]), tail_rms(&linked[1]));
        assert!((l - 0.5).abs() < 0.02 && (r - 1.0).abs() < 0.02, "{l} {r}");
        let apart = run(&agc(false), &ears, fs);
        let (l, r) = (tail_rms(&apart[0]), tail_rms(&apart[1]));
        assert!((l - 1.0).abs() < 0.02 && (r - 1.0).abs() < 0.02, "{l} {r}");
    }

    #[test]
    fn only_the_agc_seed_depends_on_the_chunking() {
        assert!(<PreProc as Descriptor>::chunk_invariant(
            &PreProcParams::default()
        ));
        let agc = PreProcParams {
            normalize_rms: true,
            int_time_sec_rms: 0.3,
            ..Default::default()
        };
        assert!(!<PreProc as Descriptor>::chunk_invariant(&agc));
        assert_eq!(<PreProc as Descriptor>::one_call_prefix_s(&agc), Some(0.3));
    }

    /// Issue 44, item 3: a DC-removal cut-off whose 4th-order transfer function is
    /// unstable (1 Hz, and 1 Hz below Nyquist, at 44.1 kHz) runs as second-order
    /// sections: white noise stays bounded, and a 1-Hz high-pass keeps its energy. The
    /// 20-Hz default keeps the AFE's transfer function (one filter).
    #[test]
    fn dc_removal_at_any_cut_off_is_stable() {
        let fs = 44100.0;
        let x = crate::testing::noise(88200, 3);
        let at = |cutoff_hz_dc: f64| PreProcParams {
            remove_dc: true,
            cutoff_hz_dc,
            ..Default::default()
        };
        assert_eq!(
            PreProc::new(&at(20.0), fs, 1).expect("valid").0.ears[0]
                .dc
                .len(),
            1
        );
        for cutoff in [1.0, 22049.0] {
            let (pre, _) = PreProc::new(&at(cutoff), fs, 1).expect("valid");
            assert_eq!(pre.ears[0].dc.len(), 2, "{cutoff} Hz as two sections");
            let y = run(&at(cutoff), std::slice::from_ref(&x), fs).remove(0);
            let peak = y.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            assert!(peak.is_finite() && peak < 2.0, "{cutoff} Hz: peak {peak}");
            if cutoff == 1.0 {
                let energy = |v: &[f64]| v.iter().map(|e| e * e).sum::<f64>();
                let ratio = energy(&y[44100..]) / energy(&x[44100..]);
                assert!(
                    (ratio - 1.0).abs() < 0.01,
                    "a 1-Hz high-pass passes noise: {ratio}"
                );
            }
        }
    }

    #[test]
    fn reset_starts_every_filter_over() {
        let p = PreProcParams {
            remove_dc: true,
            pre_emphasis: true,
            normalize_rms: true,
            ..Default::default()
        };
        let x: Vec<f64> = (0..3000)
            .map(|t| 0.1 + 0.01 * (0.3 * t as f64).sin())
            .collect();
        let (mut pre, _) = PreProc::new(&p, 8000.0, 1).expect("valid");
        let first = crate::testing::feed(&mut pre, &x, 1, 1, [3000]);
        pre.reset();
        assert_eq!(crate::testing::feed(&mut pre, &x, 1, 1, [3000]), first);
    }

    #[test]
    fn agc_seeds_once_from_the_first_samples_whatever_the_chunking() {
        let fs = 8000.0;
        let x: Vec<f64> = (0..16000).map(|t| 0.01 * (0.3 * t as f64).sin()).collect();
        let p = PreProcParams {
            normalize_rms: true,
            ..Default::default()
        };
        let whole = run(&p, std::slice::from_ref(&x), fs);
        // An empty first chunk seeds nothing; the first real chunk covers the seed.
        let (mut pre, _) = PreProc::new(&p, fs, 1).expect("valid");
        let chunked = crate::testing::feed(&mut pre, &x, 1, 1, [0, 5000, 11000]);
        assert_eq!(chunked, whole[0]);
    }

    /// The whole middle-ear stage (design, filtering, unity compensation of spec
    /// 10-preProc step 5) against a direct convolution with the taps of an independent
    /// reading of the spec (`data/middle_ear_fir2.json`) times `10^(peak/20)`.
    #[test]
    fn middle_ear_output_is_the_independent_design_with_its_unity_gain() {
        let text = include_str!("../../data/middle_ear_fir2.json");
        let fixture: serde_json::Value = serde_json::from_str(text).expect("fixture");
        for (model, peak_db) in [
            (MiddleEarModel::Jepsen, 55.9986),
            (MiddleEarModel::LopezPoveda, 66.2888),
        ] {
            let case = fixture["middle_ear"]
                .as_array()
                .expect("designs")
                .iter()
                .find(|c| c["model"] == model.name() && c["fs_hz"] == 16000.0)
                .expect("16 kHz design");
            let gain = 10f64.powf(peak_db / 20.0);
            let taps: Vec<f64> = case["taps"]
                .as_array()
                .expect("taps")
                .iter()
                .map(|v| v.as_f64().expect("tap") * gain)
                .collect();
            let x: Vec<f64> = (0..1500)
                .map(|t| (0.37 * t as f64).sin() + 0.5 * (0.011 * (t * t) as f64).cos())
                .collect();
            let p = PreProcParams {
                middle_ear_filtering: true,
                middle_ear_model: model,
                ..Default::default()
            };
            let y = run(&p, std::slice::from_ref(&x), 16000.0);
            let want: Vec<f64> = (0..x.len())
                .map(|n| {
                    (0..=n.min(taps.len() - 1))
                        .map(|k| taps[k] * x[n - k])
                        .sum()
                })
                .collect();
            let scale = want.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            for (n, (g, w)) in y[0].iter().zip(&want).enumerate() {
                assert!(
                    (g - w).abs() <= 1e-12 * scale,
                    "{model} sample {n}: {g} vs {w}"
                );
            }
        }
    }

    #[test]
    fn middle_ear_needs_a_usable_rate() {
        let p = PreProcParams {
            middle_ear_filtering: true,
            middle_ear_model: MiddleEarModel::LopezPoveda,
            ..Default::default()
        };
        let e = PreProc::new(&p, 100.0, 2).expect_err("no table rows below 50 Hz");
        assert!(e.to_string().contains("at least 2000 Hz"), "{e}");
        assert!(PreProc::new(&p, 16000.0, 2).is_ok());
    }

    #[test]
    fn invalid_ref_spl_is_rejected() {
        let p = PreProcParams {
            ref_spl_db: vec![1.0, 2.0, 3.0],
            ..Default::default()
        };
        let e = PreProc::new(&p, 16000.0, 2).expect_err("three values");
        assert!(e.to_string().contains("pp_refSPLdB"));
    }

    /// Issue 13, item 4: levels and coefficients that would give NaN or all-zero output
    /// are refused, naming the user's value; the ends of the accepted ranges work.
    #[test]
    fn overflowing_levels_and_coefficients_are_refused() {
        for db in [-1e6, 1e6, f64::NAN] {
            let p = PreProcParams {
                level_scaling: true,
                ref_spl_db: vec![db],
                ..Default::default()
            };
            let e = PreProc::new(&p, 16000.0, 2).expect_err("level");
            assert!(e.to_string().contains("pp_refSPLdB"), "{e}");
            assert!(e.to_string().contains(&format!("{db}")), "{e}");
        }
        let p = PreProcParams {
            pre_emphasis: true,
            coef_pre_emphasis: 1e200,
            ..Default::default()
        };
        let e = PreProc::new(&p, 16000.0, 1).expect_err("coefficient");
        assert!(e.to_string().contains("pp_coefPreEmphasis"), "{e}");
        let (lo, hi) = REF_SPL_DB_RANGE;
        for db in [lo, hi] {
            let p = PreProcParams {
                level_scaling: true,
                pre_emphasis: true,
                coef_pre_emphasis: -MAX_PRE_EMPHASIS,
                ref_spl_db: vec![db],
                ..Default::default()
            };
            let (mut pre, _) = PreProc::new(&p, 16000.0, 1).expect("accepted");
            let x = Block::from_vec(vec![1.0, -1.0, 0.5, 0.25], 1);
            let mut out = vec![Block::new(1)];
            pre.process(&[&x], &mut out);
            let y = out[0].as_slice();
            assert!(
                y.iter().all(|v| v.is_finite()) && y.iter().any(|v| *v != 0.0),
                "{y:?}"
            );
        }
    }
}
