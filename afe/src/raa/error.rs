//! What can keep the RAA from computing its predictors.

use thiserror::Error;

/// Why [`super::raa`] refused its input or could not finish. Each message names what is
/// wrong and what is accepted.
#[derive(Debug, Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum RaaError {
    /// The input does not have exactly two channels.
    #[error("the RAA needs a binaural input, two channels (left, right): got {0}")]
    NotBinaural(usize),
    /// The input has no samples.
    #[error("the input signal is empty")]
    Empty,
    /// The two ears have different lengths.
    #[error("the ears have different lengths: {left} samples left, {right} right")]
    UnequalLengths {
        /// Samples of the left ear.
        left: usize,
        /// Samples of the right ear.
        right: usize,
    },
    /// A sample is NaN or infinite.
    #[error("sample {index} of the {ear} ear is {value}: the RAA needs finite samples")]
    NotFinite {
        /// `"left"` or `"right"`.
        ear: &'static str,
        /// 0-based index of the first such sample.
        index: usize,
        /// The sample.
        value: f64,
    },
    /// A sampling rate at which the RAA's filters do not fit below the Nyquist frequency.
    #[error(
        "sampling rate {0} Hz: the RAA needs more than {min} Hz and at most 1 MHz (its \
         headphone filter's low-pass is at {lp} Hz, its highest band at {top} Hz)",
        min = 2.0 * super::headphone::LOW_PASS_HZ,
        lp = super::headphone::LOW_PASS_HZ,
        top = super::FB_HIGH_FREQ_HZ
    )]
    SampleRate(f64),
    /// Too short for two ITD frames, which the ITD fluctuations need.
    #[error(
        "the signal has {samples} samples ({seconds:.4} s): the RAA needs at least {needed} \
         ({needed_s:.4} s), two ITD frames of 50 ms with a hop of 25 ms, for its ITD \
         fluctuations"
    )]
    TooShort {
        /// Samples per ear.
        samples: usize,
        /// Their duration in s.
        seconds: f64,
        /// Samples needed.
        needed: usize,
        /// Their duration in s.
        needed_s: f64,
    },
    /// A band of one ear has no sample of Psi at or above the peak threshold, or none at or
    /// below the dip threshold: the AFE's `afeRAA` fails there too (an empty index group).
    #[error(
        "no sample of Psi in the {ear} ear's band {band} ({cf_hz:.1} Hz) is {side} its \
         {kind} threshold {constant} x mean|adaptation| = {threshold:.6e} MU (the AFE's \
         afeRAA fails on this too): give {constant} a {fix} value (now {value})"
    )]
    NoPeakOrDip {
        /// `"left"` or `"right"`.
        ear: &'static str,
        /// 0-based band index.
        band: usize,
        /// Centre frequency of the band, Hz.
        cf_hz: f64,
        /// `"peak"` or `"dip"`.
        kind: &'static str,
        /// `"at or above"` or `"at or below"`.
        side: &'static str,
        /// `"mu_psi"` or `"mu_psi_dip"`.
        constant: &'static str,
        /// The constant's value.
        value: f64,
        /// The threshold in model units.
        threshold: f64,
        /// `"lower"` (peak) or `"higher"` (dip): the change that admits samples.
        fix: &'static str,
    },
    /// A name that is not one of the RAA's constants.
    #[error(
        "unknown RAA constant '{name}'{hint} (the constants: {known})",
        hint = closest.as_ref().map(|c| format!(" (did you mean '{c}'?)")).unwrap_or_default(),
        known = super::RaaConstants::names().collect::<Vec<_>>().join(", ")
    )]
    UnknownConstant {
        /// The name as given.
        name: String,
        /// The constant it most likely misspells.
        closest: Option<String>,
    },
    /// The signal is too long for the memory available: the RAA holds six `[sample,
    /// band]` arrays of Psi and its streams at once.
    #[error(
        "the RAA of {seconds:.1} s of signal would take about {need} of memory (Psi and its \
         direct and reverberant streams, 16 bands per ear, are kept whole), more than the \
         {available} available: analyse an excerpt of at most {max_seconds} s, or free memory"
    )]
    TooLarge {
        /// Length of the signal, s.
        seconds: f64,
        /// Memory it would take, e.g. `7.9 GB`.
        need: String,
        /// Memory available, e.g. `2.0 GB`.
        available: String,
        /// The longest signal that would fit, whole seconds.
        max_seconds: f64,
    },
    /// A constant outside the range where the predictors are finite (see
    /// [`super::RaaConstants::check`]).
    #[error(
        "RAA constant {name} = {}: the predictors are finite for {accepted} (the AFE's \
         value: {})",
        super::constants::compact(*value),
        super::constants::compact(*default)
    )]
    ConstantOutOfRange {
        /// The constant's AFE name.
        name: &'static str,
        /// Its value.
        value: f64,
        /// The values accepted, e.g. `values from 0 up to 1e9`.
        accepted: String,
        /// The AFE's value.
        default: f64,
    },
    /// A predictor came out NaN or infinite: the input (silent, or beyond the model's
    /// range) or the constants leave it undefined.
    #[error(
        "the RAA's {name} is {value} ({formula}): the input (silent, or beyond the model's \
         range) or the constants {constants} leave it undefined; check the input's level, \
         or bring those constants nearer the AFE's values"
    )]
    UndefinedPredictor {
        /// `afeRAA`'s name of the predictor, e.g. `pClar`.
        name: &'static str,
        /// Its value.
        value: f64,
        /// How it is computed, e.g. `FL/BL with BL = 0`.
        formula: String,
        /// The constants it depends on.
        constants: &'static str,
    },
    /// A constant's value, or the AFE processing under the RAA (its parameters, an
    /// interrupt, memory).
    #[error(transparent)]
    Afe(#[from] afe_core::Error),
}
