//! The Room Acoustic Analyzer (RAA) of the Two!Ears AFE, `afeRAA`: van Dorp Schuitman's
//! (2011) model of room-acoustic perception, built on the AFE's processors. From a
//! binaural recording it predicts reverberance, clarity, apparent source width (ASW) and
//! listener envelopment (LEV), unscaled and scaled by sigmoids to [0, 1].
//!
//! The chain, as `afeRAA` runs it:
//! 1. the headphone filter ([`headphone`]: 1 kHz high-pass, 4 kHz low-pass);
//! 2. the AFE request `adaptation` with level scaling, 16 gammatone bands from 167.7924
//!    to 1836.4 Hz, the `breebart` hair cell and the `adt_vandorpschuitman` loops without
//!    overshoot limit ([`adaptation_params`]), on the whole signal;
//! 3. the ITD per 50-ms frame and band from the adaptation output ([`itd`]);
//! 4. Psi, the adaptation output low-passed with a 20-ms time constant, split per ear and
//!    band into a direct and a reverberant stream by its peaks and dips ([`streams`]);
//! 5. the predictors from the streams' levels and the ITD's fluctuations.
//!
//! References: van Dorp Schuitman, J. (2011), *Auditory modelling for assessing room
//! acoustics*, PhD thesis, TU Delft; van Dorp Schuitman, de Vries and Lindau (2013),
//! JASA 133, 1572–1585.

mod constants;
mod error;
pub mod headphone;
pub mod itd;
mod predictors;
pub mod streams;

use afe_core::filter::Df2t;
use afe_core::{Block, ParamMap};
use afe_graph::{Channel, Manager};
use afe_processors::adaptation::{AdaptationModel, AdaptationParams};
use afe_processors::filterbank::{FbType, FilterbankParams};
use afe_processors::ihc::{IhcParams, Method};
use afe_processors::pre_proc::PreProcParams;
use serde::Serialize;
use serde_json::{json, Value};

pub use constants::RaaConstants;
pub use error::RaaError;

/// Lowest centre frequency of the RAA's gammatone bands, Hz (`fb_lowFreqHz`).
pub const FB_LOW_FREQ_HZ: f64 = 167.7924;
/// Highest centre frequency of the RAA's gammatone bands, Hz (`fb_highFreqHz`).
pub const FB_HIGH_FREQ_HZ: f64 = 1836.4;
/// Number of gammatone bands (`fb_nChannels`).
pub const FB_N_CHANNELS: usize = 16;
/// Time constant of the low-pass that turns the adaptation output into Psi, s.
const ENVELOPE_TAU_S: f64 = 0.02;

/// The parameters of the AFE request `adaptation` under the RAA, as `afeRAA` sets them.
pub fn adaptation_params() -> ParamMap {
    [
        (PreProcParams::NAMES.level_scaling, json!(true)),
        (FilterbankParams::NAMES.fb_type, json!(FbType::Gammatone)),
        (FilterbankParams::NAMES.low_freq_hz, json!(FB_LOW_FREQ_HZ)),
        (FilterbankParams::NAMES.high_freq_hz, json!(FB_HIGH_FREQ_HZ)),
        (FilterbankParams::NAMES.n_channels, json!(FB_N_CHANNELS)),
        (IhcParams::NAMES.method, json!(Method::Breebart)),
        (
            AdaptationParams::NAMES.model,
            json!(AdaptationModel::VanDorpSchuitman),
        ),
        (AdaptationParams::NAMES.lim, json!(0)),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect()
}

/// The predictors, `afeRAA`'s `par`, under its field names. MU = model units, the scale
/// of the AFE's adaptation loops. ITD fluctuations are in the AFE's ITD unit (see
/// [`RaaPsi::itd`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RaaPar {
    /// Level of the background (reverberant) stream, `L_REV`, MU; also the unscaled
    /// reverberance.
    #[serde(rename = "BL")]
    pub bl: f64,
    /// Reverberance, scaled to [0, 1].
    #[serde(rename = "sREV")]
    pub s_rev: f64,
    /// Level of the foreground (direct) stream, `L_DIR`, MU.
    #[serde(rename = "FL")]
    pub fl: f64,
    /// Clarity, unscaled: `FL / BL`, 1.
    #[serde(rename = "pClar")]
    pub p_clar: f64,
    /// Clarity, scaled to [0, 1].
    #[serde(rename = "sClar")]
    pub s_clar: f64,
    /// Level of the low-frequency bands (168 to 387 Hz) of both ears, `L_LOW`, MU.
    #[serde(rename = "Llow")]
    pub l_low: f64,
    /// ITD fluctuation of the foreground, `σ_ITD,DIR`: the standard deviation over frames
    /// of the direct ITD, averaged over the bands from 387 Hz to 1836.4 Hz; ITD unit.
    #[serde(rename = "ITDf")]
    pub itd_f: f64,
    /// Apparent source width, unscaled: `mu_ASW·Llow + log10(1 + nu_ASW·ITDf·1e3)`, 1.
    #[serde(rename = "pASW")]
    pub p_asw: f64,
    /// Apparent source width, scaled to [0, 1].
    #[serde(rename = "sASW")]
    pub s_asw: f64,
    /// ITD fluctuation of the background, `σ_ITD,REV`, as `ITDf` of the reverberant ITD;
    /// ITD unit.
    #[serde(rename = "ITDb")]
    pub itd_b: f64,
    /// Listener envelopment, unscaled: `mu_LEV·BL + log10(1 + nu_LEV·ITDb·1e3)`, 1.
    #[serde(rename = "pLEV")]
    pub p_lev: f64,
    /// Listener envelopment, scaled to [0, 1].
    #[serde(rename = "sLEV")]
    pub s_lev: f64,
}

/// One predictor's name, value, unit and meaning (see [`RaaPar::fields`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParField {
    /// `afeRAA`'s field name, e.g. `sREV`.
    pub name: &'static str,
    /// The value.
    pub value: f64,
    /// `MU`, `1`, or `ITD unit` (see [`RaaPsi::itd`]).
    pub unit: &'static str,
    /// What it is.
    pub description: &'static str,
}

impl RaaPar {
    /// Every predictor in `afeRAA`'s order, with its unit and meaning.
    pub fn fields(&self) -> [ParField; 12] {
        let f = |name, value, unit, description| ParField {
            name,
            value,
            unit,
            description,
        };
        [
            f(
                "BL",
                self.bl,
                "MU",
                "level of the background (reverberant) stream",
            ),
            f("sREV", self.s_rev, "1", "reverberance, scaled"),
            f(
                "FL",
                self.fl,
                "MU",
                "level of the foreground (direct) stream",
            ),
            f("pClar", self.p_clar, "1", "clarity, unscaled (FL/BL)"),
            f("sClar", self.s_clar, "1", "clarity, scaled"),
            f(
                "Llow",
                self.l_low,
                "MU",
                "level of the bands from 168 to 387 Hz",
            ),
            f(
                "ITDf",
                self.itd_f,
                ITD_UNIT,
                "ITD fluctuation of the foreground",
            ),
            f("pASW", self.p_asw, "1", "apparent source width, unscaled"),
            f("sASW", self.s_asw, "1", "apparent source width, scaled"),
            f(
                "ITDb",
                self.itd_b,
                ITD_UNIT,
                "ITD fluctuation of the background",
            ),
            f("pLEV", self.p_lev, "1", "listener envelopment, unscaled"),
            f("sLEV", self.s_lev, "1", "listener envelopment, scaled"),
        ]
    }
}

/// The unit of the RAA's ITD: the lag in samples times the frame hop, 25 ms (the AFE's
/// `afeRAA` divides the lag by the frame rate, not by the sampling rate).
pub const ITD_UNIT: &str = "samples x 0.025 s";

/// The intermediate representations, `afeRAA`'s `psi`. Time-frequency arrays are
/// `[sample][band]`, ITD arrays `[frame][band]`.
#[derive(Debug, Clone, PartialEq)]
pub struct RaaPsi {
    /// Left ear: the adaptation output low-passed (first order, 20 ms), MU (`PsiL`).
    pub psi_l: Block,
    /// Right ear, as [`RaaPsi::psi_l`] (`PsiR`).
    pub psi_r: Block,
    /// Direct stream of the left ear: `PsiL` on its direct segments, 0 elsewhere, MU
    /// (`PsiLdir`).
    pub psi_l_dir: Block,
    /// Direct stream of the right ear, MU (`PsiRdir`).
    pub psi_r_dir: Block,
    /// Reverberant stream of the left ear: `PsiL − PsiLdir`, MU (`PsiLrev`).
    pub psi_l_rev: Block,
    /// Reverberant stream of the right ear, MU (`PsiRrev`).
    pub psi_r_rev: Block,
    /// Interaural time difference per frame and band, positive when the right ear leads,
    /// in the AFE's unit: the lag in samples times the hop, 0.025 s, i.e. `fs/40` times
    /// the delay in seconds (400× at 16 kHz) (`ITD`).
    pub itd: Block,
    /// The direct part of the ITD: `ITD` times the share of the ears (0, ½ or 1) whose
    /// stream is direct at the frame's centre (`ITDdir`).
    pub itd_dir: Block,
    /// The reverberant part: `ITD − ITDdir` (`ITDrev`).
    pub itd_rev: Block,
    /// Centre frequency of each band, Hz (`f`).
    pub f: Vec<f64>,
    /// Time of each sample of Psi, s: `(1..=N)/fs`, from `1/fs` (`t_psi`).
    pub t_psi: Vec<f64>,
    /// Start of each ITD frame, s: `k · 0.025` (`t_itd`).
    pub t_itd: Vec<f64>,
    /// Sampling rate, Hz (`fs`).
    pub fs: f64,
    /// Samples per ear (`numSamples`).
    pub num_samples: usize,
    /// Bands (`numBands`).
    pub num_bands: usize,
    /// ITD frames (`itdNumFrames`).
    pub itd_num_frames: usize,
}

impl RaaPsi {
    /// The arrays under `afeRAA`'s field names with their shapes, row-major.
    pub fn arrays(&self) -> Vec<(&'static str, Vec<usize>, &[f64])> {
        vec![
            block("PsiL", &self.psi_l),
            block("PsiR", &self.psi_r),
            block("PsiLdir", &self.psi_l_dir),
            block("PsiRdir", &self.psi_r_dir),
            block("PsiLrev", &self.psi_l_rev),
            block("PsiRrev", &self.psi_r_rev),
            block("ITD", &self.itd),
            block("ITDdir", &self.itd_dir),
            block("ITDrev", &self.itd_rev),
            vector("f", &self.f),
            vector("t_psi", &self.t_psi),
            vector("t_itd", &self.t_itd),
        ]
    }

    /// As [`RaaPsi::arrays`], the arrays moved out rather than borrowed (a caller that
    /// hands them on, as Python does to numpy, then holds each once).
    pub fn into_arrays(self) -> Vec<(&'static str, Vec<usize>, Vec<f64>)> {
        let block = |name, b: Block| {
            let shape = vec![b.frames(), b.width()];
            (name, shape, b.into_vec())
        };
        let vector = |name, v: Vec<f64>| (name, vec![v.len()], v);
        vec![
            block("PsiL", self.psi_l),
            block("PsiR", self.psi_r),
            block("PsiLdir", self.psi_l_dir),
            block("PsiRdir", self.psi_r_dir),
            block("PsiLrev", self.psi_l_rev),
            block("PsiRrev", self.psi_r_rev),
            block("ITD", self.itd),
            block("ITDdir", self.itd_dir),
            block("ITDrev", self.itd_rev),
            vector("f", self.f),
            vector("t_psi", self.t_psi),
            vector("t_itd", self.t_itd),
        ]
    }

    /// The scalars under `afeRAA`'s field names: `fs`, `numSamples`, `numBands`,
    /// `itdNumFrames`.
    pub fn scalars_json(&self) -> Value {
        json!({
            "fs": self.fs,
            "numSamples": self.num_samples,
            "numBands": self.num_bands,
            "itdNumFrames": self.itd_num_frames,
        })
    }
}

/// A named `[rows, columns]` array of [`RaaPsi::arrays`].
fn block<'a>(name: &'static str, b: &'a Block) -> (&'static str, Vec<usize>, &'a [f64]) {
    (name, vec![b.frames(), b.width()], b.as_slice())
}

/// A named vector of [`RaaPsi::arrays`].
fn vector<'a>(name: &'static str, v: &'a [f64]) -> (&'static str, Vec<usize>, &'a [f64]) {
    (name, vec![v.len()], v)
}

/// `afeRAA`'s two outputs.
#[derive(Debug, Clone, PartialEq)]
pub struct Raa {
    /// The predictors.
    pub par: RaaPar,
    /// The intermediate representations.
    pub psi: RaaPsi,
}

impl Raa {
    /// `{"par": {...}, "psi": {scalars}}`: every predictor and the scalars of `psi`, under
    /// `afeRAA`'s names (what `afe raa --json` prints).
    pub fn to_json(&self) -> Value {
        json!({ "par": self.par, "psi": self.psi.scalars_json() })
    }
}

/// The RAA of the binaural signal `ears` (`[left, right]`, full scale 1) at `fs` Hz with
/// `constants`: `afeRAA(earSignals, fs, parConf)`.
///
/// ```no_run
/// use afe::raa::{raa, RaaConstants};
/// let audio = afe::wav::read_wav(std::path::Path::new("data/raa_speech_16k.wav"))?;
/// let [left, right] = &audio.channels[..] else { unreachable!() };
/// let out = raa(&[left, right], audio.fs, &RaaConstants::default())?;
/// println!("reverberance {:.3}, clarity {:.3}", out.par.s_rev, out.par.s_clar);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn raa(ears: &[&[f64]], fs: f64, constants: &RaaConstants) -> Result<Raa, RaaError> {
    constants.check()?;
    let [left, right] = check_input(ears, fs)?;
    check_memory(left.len(), fs)?;
    let [left, right] = headphone::apply(fs, left, right);
    let (adapt_l, adapt_r, f) = adaptation(fs, &left, &right)?;
    drop((left, right));

    let itd = itd::itd(&adapt_l, &adapt_r, fs);
    // each band's mean |adaptation output| sets its thresholds; Psi then takes the
    // adaptation output's place
    let (level_l, level_r) = (
        streams::mean_levels(&adapt_l),
        streams::mean_levels(&adapt_r),
    );
    let psi_l = envelope(adapt_l, fs);
    let psi_r = envelope(adapt_r, fs);
    let segment = |ear, psi: &Block, levels: &[f64]| {
        streams::Segmentation {
            constants,
            fs,
            ear,
            cf_hz: &f,
        }
        .direct_mask(psi, levels)
    };
    let mask_l = segment("left", &psi_l, &level_l)?;
    let mask_r = segment("right", &psi_r, &level_r)?;

    let (itd_dir, itd_rev) = itd::split(&itd, &mask_l, &mask_r, fs);
    let num_samples = psi_l.frames();
    let itd_num_frames = itd.frames();
    let frame_rate = 1.0 / itd::HOP_S;
    let psi = RaaPsi {
        psi_l_dir: streams::masked(&psi_l, &mask_l, true)?,
        psi_r_dir: streams::masked(&psi_r, &mask_r, true)?,
        psi_l_rev: streams::masked(&psi_l, &mask_l, false)?,
        psi_r_rev: streams::masked(&psi_r, &mask_r, false)?,
        psi_l,
        psi_r,
        itd,
        itd_dir,
        itd_rev,
        t_psi: (1..=num_samples).map(|t| t as f64 / fs).collect(),
        t_itd: (0..itd_num_frames).map(|k| k as f64 / frame_rate).collect(),
        num_bands: f.len(),
        f,
        fs,
        num_samples,
        itd_num_frames,
    };
    let par = predictors::predictors(&psi, constants);
    predictors::check_finite(&par)?;
    Ok(Raa { par, psi })
}

/// Bytes the RAA of `samples` samples per ear holds at its peak: the six `[sample, band]`
/// arrays of Psi and its streams, the two direct-stream masks, `t_psi`, and the input
/// four times over (the caller's two ears and the headphone filter's output), with a
/// twentieth more and 64 MB for the rest (measured: 1.60 GB for 120 s at 16 kHz, of
/// 1.61 GB counted so).
pub fn memory_bytes(samples: usize) -> f64 {
    let bands = FB_N_CHANNELS as f64;
    let counted = samples as f64 * (6.0 * 8.0 * bands + 2.0 * bands + 8.0 + 4.0 * 8.0);
    1.05 * counted + 64e6
}

/// Refuses a signal of `samples` samples per ear at `fs` Hz whose RAA would not fit the
/// memory available ([`afe_graph::work::memory_available`]), before anything is
/// computed.
fn check_memory(samples: usize, fs: f64) -> Result<(), RaaError> {
    let need = memory_bytes(samples);
    match afe_graph::work::memory_available()? {
        Some(available) if need > available => Err(RaaError::TooLarge {
            seconds: samples as f64 / fs,
            need: afe_graph::work::size(need),
            available: afe_graph::work::size(available),
            max_seconds: ((available - memory_bytes(0)) / (memory_bytes(1) - memory_bytes(0)) / fs)
                .floor()
                .max(0.0),
        }),
        _ => Ok(()),
    }
}

/// The two ears of `ears` once checked: two channels, as long as each other, not empty,
/// finite, long enough for two ITD frames, at a rate where the filters fit.
fn check_input<'a>(ears: &[&'a [f64]], fs: f64) -> Result<[&'a [f64]; 2], RaaError> {
    let &[left, right] = ears else {
        return Err(RaaError::NotBinaural(ears.len()));
    };
    if !(fs.is_finite() && fs > 2.0 * headphone::LOW_PASS_HZ && fs <= 1e6) {
        return Err(RaaError::SampleRate(fs));
    }
    if left.len() != right.len() {
        return Err(RaaError::UnequalLengths {
            left: left.len(),
            right: right.len(),
        });
    }
    if left.is_empty() {
        return Err(RaaError::Empty);
    }
    for (ear, x) in [("left", left), ("right", right)] {
        if let Some(index) = x.iter().position(|v| !v.is_finite()) {
            return Err(RaaError::NotFinite {
                ear,
                index,
                value: x[index],
            });
        }
    }
    let framing = itd::Framing::at(fs);
    let needed = framing.size + framing.hop;
    if left.len() < needed {
        return Err(RaaError::TooShort {
            samples: left.len(),
            seconds: left.len() as f64 / fs,
            needed,
            needed_s: needed as f64 / fs,
        });
    }
    Ok([left, right])
}

/// The adaptation outputs of both ears (`[sample][band]`, MU) and the bands' centre
/// frequencies (Hz), computed by the AFE request `adaptation` on the whole signal.
fn adaptation(fs: f64, left: &[f64], right: &[f64]) -> Result<(Block, Block, Vec<f64>), RaaError> {
    let mut mgr = Manager::new(fs, 2)?;
    let handle = mgr.add_request("adaptation", &adaptation_params())?;
    mgr.process_signal(&[left, right])?;
    let signals: Vec<_> = (mgr.request_signals(handle)?.iter())
        .map(|s| (s.channel, s.source, s.info.cf_hz().to_vec()))
        .collect();
    // each ear's whole output moves out of the manager rather than being copied
    let mut ear = |channel| {
        let found = signals.iter().find(|s| s.0 == channel);
        found
            .and_then(|(_, source, cf)| Some((mgr.take_whole(*source)?, cf.clone())))
            .ok_or_else(|| {
                afe_core::Error::InvalidInput(format!(
                    "the adaptation request gave no {} signal",
                    channel.as_str()
                ))
            })
    };
    let ((l, f), (r, _)) = (ear(Channel::Left)?, ear(Channel::Right)?);
    Ok((l, r, f))
}

/// Psi: `adaptation` (`[sample][band]`) through the first-order low-pass of time constant
/// [`ENVELOPE_TAU_S`], `y[n] = (1 − e)·x[n] + e·y[n−1]` with `e = exp(−1/(τ·fs))`.
/// The adaptation output is filtered in place.
fn envelope(mut adaptation: Block, fs: f64) -> Block {
    let e = (-1.0 / (ENVELOPE_TAU_S * fs)).exp();
    Df2t::new(&[1.0 - e], &[1.0, -e], adaptation.width()).process(adaptation.as_mut_slice());
    adaptation
}
