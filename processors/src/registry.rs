//! Request names → processors: dependency, ear handling, parameters, constructor.

use afe_core::{Error, ParamMap, ParamSpec, Params, Processor, Result, SignalInfo};

use crate::adaptation::{Adaptation, AdaptationParams};
use crate::autocorrelation::{Autocorrelation, AutocorrelationParams};
use crate::butterworth::{Butterworth, ButterworthParams};
use crate::crosscorrelation::{Crosscorrelation, CrosscorrelationParams};
use crate::gammatone::{Gammatone, GammatoneParams};
use crate::ic::Ic;
use crate::ihc::{Ihc, IhcParams};
use crate::ild::{Ild, IldParams};
use crate::itd::Itd;
use crate::pitch::{Pitch, PitchParams};
use crate::pre_proc::{PreProc, PreProcParams};
use crate::ratemap::{Ratemap, RatemapParams};

/// How a processor relates to the ears (the AFE's binaural flag).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ears {
    /// One instance takes every ear and has one output per ear (preProc, flag 2).
    All,
    /// One instance per ear (flag 0).
    PerEar,
    /// One instance combining the left and right parents, or the single binaural parent
    /// (flag 1).
    Binaural,
}

/// A processor made for a graph node: the processor, its outputs and its parameters.
pub struct Built {
    /// The processor, ready to run.
    pub processor: Box<dyn Processor>,
    /// One description per output (one per ear for preProc, one otherwise).
    pub outputs: Vec<SignalInfo>,
}

/// Everything the graph needs to know about one request name.
pub struct RequestDef {
    /// The AFE request name, e.g. `ratemap`.
    pub name: &'static str,
    /// The request this one is computed from (`input` for the raw ear signals).
    pub dependency: &'static str,
    /// Ear handling.
    pub ears: Ears,
    /// One-line meaning, for listings.
    pub description: &'static str,
    /// Unit of the output values, for listings.
    pub output_unit: &'static str,
    /// The parameters this processor declares.
    pub params: &'static [ParamSpec],
    /// The AFE defaults of those parameters.
    pub defaults: fn() -> ParamMap,
    /// The processor's own parameters after defaults and verification; two nodes with
    /// equal maps (and equal parents) compute the same thing and are shared.
    pub canonical: fn(&ParamMap) -> Result<ParamMap>,
    /// Builds the processor for parent outputs `inputs` (one per ear for preProc).
    pub build: fn(&ParamMap, &[SignalInfo]) -> Result<Built>,
    /// Whether, with these request parameters, any chunking gives the output of one call
    /// (false where the AFE itself depends on chunk boundaries).
    pub chunk_invariant: fn(&ParamMap) -> bool,
}

impl std::fmt::Debug for RequestDef {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RequestDef")
            .field("name", &self.name)
            .finish_non_exhaustive()
    }
}

fn canonical<P: Params>(map: &ParamMap) -> Result<ParamMap> {
    Ok(P::from_map(map)?.to_map())
}

fn defaults<P: Params>() -> ParamMap {
    P::default().to_map()
}

fn built(processor: impl Processor + 'static, outputs: Vec<SignalInfo>) -> Built {
    Built {
        processor: Box::new(processor),
        outputs,
    }
}

fn build_time(map: &ParamMap, inputs: &[SignalInfo]) -> Result<Built> {
    let (p, outs) = PreProc::new(
        &PreProcParams::from_map(map)?,
        inputs[0].fs_hz,
        inputs.len(),
    )?;
    Ok(built(p, outs))
}

fn build_butterworth(map: &ParamMap, inputs: &[SignalInfo]) -> Result<Built> {
    let (p, out) = Butterworth::new(&ButterworthParams::from_map(map)?, inputs[0].fs_hz)?;
    Ok(built(p, vec![out]))
}

fn canonical_filterbank(map: &ParamMap) -> Result<ParamMap> {
    Ok(GammatoneParams::from_map(map)?.grid()?.map)
}

fn build_filterbank(map: &ParamMap, inputs: &[SignalInfo]) -> Result<Built> {
    let (p, out) = Gammatone::new(&GammatoneParams::from_map(map)?, inputs[0].fs_hz)?;
    Ok(built(p, vec![out]))
}

fn build_ihc(map: &ParamMap, inputs: &[SignalInfo]) -> Result<Built> {
    let (p, out) = Ihc::new(&IhcParams::from_map(map)?, &inputs[0])?;
    Ok(built(p, vec![out]))
}

fn build_ratemap(map: &ParamMap, inputs: &[SignalInfo]) -> Result<Built> {
    let (p, out) = Ratemap::new(&RatemapParams::from_map(map)?, &inputs[0])?;
    Ok(built(p, vec![out]))
}

fn build_ild(map: &ParamMap, inputs: &[SignalInfo]) -> Result<Built> {
    let (p, out) = Ild::new(&IldParams::from_map(map)?, &inputs[0])?;
    Ok(built(p, vec![out]))
}

fn build_crosscorrelation(map: &ParamMap, inputs: &[SignalInfo]) -> Result<Built> {
    let (p, out) = Crosscorrelation::new(&CrosscorrelationParams::from_map(map)?, &inputs[0])?;
    Ok(built(p, vec![out]))
}

fn build_itd(_: &ParamMap, inputs: &[SignalInfo]) -> Result<Built> {
    let (p, out) = Itd::new(&inputs[0])?;
    Ok(built(p, vec![out]))
}

fn build_ic(_: &ParamMap, inputs: &[SignalInfo]) -> Result<Built> {
    let (p, out) = Ic::new(&inputs[0])?;
    Ok(built(p, vec![out]))
}

/// The adaptation's own parameters after its preset (the AFE applies presets when it
/// verifies parameters, so two requests reaching the same values share the node).
fn canonical_adaptation(map: &ParamMap) -> Result<ParamMap> {
    Ok(AdaptationParams::from_map(map)?.with_preset().to_map())
}

fn build_adaptation(map: &ParamMap, inputs: &[SignalInfo]) -> Result<Built> {
    let (p, out) = Adaptation::new(&AdaptationParams::from_map(map)?, &inputs[0])?;
    Ok(built(p, vec![out]))
}

fn build_autocorrelation(map: &ParamMap, inputs: &[SignalInfo]) -> Result<Built> {
    let (p, out) = Autocorrelation::new(&AutocorrelationParams::from_map(map)?, &inputs[0])?;
    Ok(built(p, vec![out]))
}

fn build_pitch(map: &ParamMap, inputs: &[SignalInfo]) -> Result<Built> {
    let (p, out) = Pitch::new(&PitchParams::from_map(map)?, &inputs[0])?;
    Ok(built(p, vec![out]))
}

/// The AFE's pitch thresholds and smooths per chunk.
fn never(_: &ParamMap) -> bool {
    false
}

fn no_params(_: &ParamMap) -> Result<ParamMap> {
    Ok(ParamMap::new())
}

fn always(_: &ParamMap) -> bool {
    true
}

/// The AGC seeds its running mean from the first chunk.
fn time_chunk_invariant(map: &ParamMap) -> bool {
    PreProcParams::from_map(map).is_ok_and(|p| !p.normalize_rms)
}

/// The Hilbert-based IHC methods transform each chunk on its own.
fn ihc_chunk_invariant(map: &ParamMap) -> bool {
    IhcParams::from_map(map)
        .is_ok_and(|p| !matches!(p.method.as_str(), "hilbert" | "joergensen" | "bernstein"))
}

static REQUESTS: &[RequestDef] = &[
    RequestDef {
        name: "time",
        dependency: "input",
        ears: Ears::All,
        description: "pre-processed ear signals (DC removal, pre-emphasis, AGC, level, middle ear)",
        output_unit: "",
        params: PreProcParams::SPECS,
        defaults: defaults::<PreProcParams>,
        canonical: canonical::<PreProcParams>,
        build: build_time,
        chunk_invariant: time_chunk_invariant,
    },
    RequestDef {
        name: "butterworth",
        dependency: "time",
        ears: Ears::PerEar,
        description: "Butterworth-filtered ear signals (not in the AFE)",
        output_unit: "",
        params: ButterworthParams::SPECS,
        defaults: defaults::<ButterworthParams>,
        canonical: canonical::<ButterworthParams>,
        build: build_butterworth,
        chunk_invariant: always,
    },
    RequestDef {
        name: "filterbank",
        dependency: "time",
        ears: Ears::PerEar,
        description: "gammatone filterbank output per frequency channel",
        output_unit: "",
        params: GammatoneParams::SPECS,
        defaults: defaults::<GammatoneParams>,
        canonical: canonical_filterbank,
        build: build_filterbank,
        chunk_invariant: always,
    },
    RequestDef {
        name: "innerhaircell",
        dependency: "filterbank",
        ears: Ears::PerEar,
        description: "inner-hair-cell envelope per frequency channel",
        output_unit: "",
        params: IhcParams::SPECS,
        defaults: defaults::<IhcParams>,
        canonical: canonical::<IhcParams>,
        build: build_ihc,
        chunk_invariant: ihc_chunk_invariant,
    },
    RequestDef {
        name: "ratemap",
        dependency: "innerhaircell",
        ears: Ears::PerEar,
        description: "auditory spectrogram: smoothed IHC envelope per frame and channel",
        output_unit: "",
        params: RatemapParams::SPECS,
        defaults: defaults::<RatemapParams>,
        canonical: canonical::<RatemapParams>,
        build: build_ratemap,
        chunk_invariant: always,
    },
    RequestDef {
        name: "ild",
        dependency: "innerhaircell",
        ears: Ears::Binaural,
        description: "interaural level difference, right re left, per frame and channel",
        output_unit: "dB",
        params: IldParams::SPECS,
        defaults: defaults::<IldParams>,
        canonical: canonical::<IldParams>,
        build: build_ild,
        chunk_invariant: always,
    },
    RequestDef {
        name: "crosscorrelation",
        dependency: "innerhaircell",
        ears: Ears::Binaural,
        description: "normalised interaural cross-correlation per frame, channel and lag",
        output_unit: "",
        params: CrosscorrelationParams::SPECS,
        defaults: defaults::<CrosscorrelationParams>,
        canonical: canonical::<CrosscorrelationParams>,
        build: build_crosscorrelation,
        chunk_invariant: always,
    },
    RequestDef {
        name: "itd",
        dependency: "crosscorrelation",
        ears: Ears::Binaural,
        description: "interaural time difference per frame and channel (positive: right leads)",
        output_unit: "s",
        params: &[],
        defaults: ParamMap::new,
        canonical: no_params,
        build: build_itd,
        chunk_invariant: always,
    },
    RequestDef {
        name: "ic",
        dependency: "crosscorrelation",
        ears: Ears::Binaural,
        description: "interaural coherence per frame and channel",
        output_unit: "",
        params: &[],
        defaults: ParamMap::new,
        canonical: no_params,
        build: build_ic,
        chunk_invariant: always,
    },
    RequestDef {
        name: "adaptation",
        dependency: "innerhaircell",
        ears: Ears::PerEar,
        description: "adaptation loops: compressed IHC envelope per frequency channel",
        output_unit: "model units",
        params: AdaptationParams::SPECS,
        defaults: defaults::<AdaptationParams>,
        canonical: canonical_adaptation,
        build: build_adaptation,
        chunk_invariant: always,
    },
    RequestDef {
        name: "autocorrelation",
        dependency: "innerhaircell",
        ears: Ears::PerEar,
        description: "centre-clipped normalised autocorrelation per frame, channel and lag",
        output_unit: "",
        params: AutocorrelationParams::SPECS,
        defaults: defaults::<AutocorrelationParams>,
        canonical: canonical::<AutocorrelationParams>,
        build: build_autocorrelation,
        chunk_invariant: always,
    },
    RequestDef {
        name: "pitch",
        dependency: "autocorrelation",
        ears: Ears::PerEar,
        description: "pitch per frame from the summary autocorrelation, raw pitch and confidence",
        output_unit: "Hz",
        params: PitchParams::SPECS,
        defaults: defaults::<PitchParams>,
        canonical: canonical::<PitchParams>,
        build: build_pitch,
        chunk_invariant: never,
    },
];

/// Every request this build knows, in dependency order.
pub fn requests() -> &'static [RequestDef] {
    REQUESTS
}

/// The definition of request `name`, or an error listing the known names.
pub fn find_request(name: &str) -> Result<&'static RequestDef> {
    REQUESTS
        .iter()
        .find(|r| r.name == name)
        .ok_or_else(|| Error::UnknownRequest {
            name: name.to_string(),
            known: REQUESTS
                .iter()
                .map(|r| r.name)
                .collect::<Vec<_>>()
                .join(", "),
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_dependency_resolves_and_parameter_names_are_unique() {
        let mut names = std::collections::BTreeSet::new();
        for r in requests() {
            assert!(r.dependency == "input" || find_request(r.dependency).is_ok());
            for p in r.params {
                assert!(names.insert(p.name), "{} declared twice", p.name);
            }
            assert!((r.canonical)(&(r.defaults)()).is_ok());
        }
    }

    #[test]
    fn unknown_request_lists_the_known_ones() {
        let e = find_request("ratemapp").unwrap_err().to_string();
        assert!(
            e.contains("'ratemapp'") && e.contains("ratemap, ild"),
            "{e}"
        );
    }
}
