//! What a processor module declares about the request it computes ([`Descriptor`]) and
//! the type-erased entry the graph works with ([`RequestDef`]). The processors crate
//! implements the trait for each processor and lists the entries; nothing here knows a
//! processor by name.
//!
//! A request's parameter map is parsed once, by [`RequestDef::configure`], into the
//! processor's typed parameters behind a [`Configured`]: the graph keeps that value and
//! asks it how to share, build and chunk the node, so no later step parses the map again
//! or can drop a parse error.

use std::fmt;
use std::marker::PhantomData;

use crate::{HeadPose, ParamMap, ParamSpec, Params, Processor, Result, SignalInfo};

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

/// What the graph gives a processor it builds beside its inputs' descriptions: the
/// world the processor hears in.
#[derive(Debug, Clone, Default)]
pub struct BuildContext {
    /// The head's yaw over time, as its manager is told it.
    pub head_pose: HeadPose,
    /// When the node's first frame starts, s since the processors started (the stream's
    /// start or the last reset; later than 0 for a node placed mid-stream). A reset
    /// starts every node at 0.
    pub started_s: f64,
}

/// A processor made for a graph node: the processor, its outputs and its parameters.
pub struct Built {
    /// The processor, ready to run.
    pub processor: Box<dyn Processor>,
    /// One description per output (one per ear for preProc, one otherwise).
    pub outputs: Vec<SignalInfo>,
    /// The largest factor by which the processor can raise the amplitude of the signal
    /// it reads (preProc's level scaling, pre-emphasis and middle-ear gain; 1 for the
    /// others): the graph lowers the input amplitude it accepts by it, so that the
    /// processing stays finite.
    pub input_gain: f64,
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
    /// Parses a request's parameter map into this processor's typed parameters (defaults
    /// filled, values checked, the canonical map derived): the one parse of the map,
    /// whose value the graph node keeps.
    pub configure: fn(&ParamMap) -> Result<Box<dyn Configured>>,
    /// Parameters that cannot change at run time (as in the AFE): they fix what every
    /// representation above is laid out on.
    pub fixed: &'static [&'static str],
    /// The request lower in the chain (same ear) that takes this processor's feedback
    /// output from the next chunk on (the MOC feeds the filterbank), if any.
    pub feeds_back_to: Option<&'static str>,
}

impl fmt::Debug for RequestDef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("RequestDef")
            .field("name", &self.name)
            .finish_non_exhaustive()
    }
}

impl Built {
    /// A built processor with one description per output.
    pub fn new(processor: impl Processor + 'static, outputs: Vec<SignalInfo>) -> Self {
        Built {
            processor: Box::new(processor),
            outputs,
            input_gain: 1.0,
        }
    }

    /// The same, raising its input's amplitude by at most `gain` (see
    /// [`Built::input_gain`]).
    pub fn with_input_gain(self, gain: f64) -> Self {
        Built {
            input_gain: gain,
            ..self
        }
    }
}

/// A request's parameters parsed into one processor's typed parameters (see
/// [`RequestDef::configure`]): everything the graph asks of a node's parameters, without
/// parsing the map again.
pub trait Configured: fmt::Debug + Send + Sync {
    /// The parameters that decide what the processor computes, as a map of AFE names;
    /// two nodes with equal maps (and equal parents) compute the same thing and are
    /// shared.
    fn canonical(&self) -> &ParamMap;

    /// Builds the processor for parent outputs `inputs` (the dependency's, then those of
    /// the extra inputs; one per ear for preProc), in the graph's `context`.
    fn build(&self, inputs: &[SignalInfo], context: &BuildContext) -> Result<Built>;

    /// Whether any chunking gives the output of one call (false where the AFE itself
    /// depends on chunk boundaries).
    fn chunk_invariant(&self) -> bool;

    /// Where not chunk-invariant: the seconds of input a whole signal's first chunk must
    /// hold (or be the whole signal) for chunks of any size after it to give one call's
    /// output (the AGC seeds from a fixed prefix); `None` when one call is needed.
    fn one_call_prefix_s(&self) -> Option<f64>;

    /// Requests read beside the dependency (resolved with the same request parameters,
    /// so they are the nodes of the chain below when it has them). Per-ear processors
    /// get the same ear's output after their dependency's; binaural ones get left and
    /// right after theirs.
    fn extra_inputs(&self) -> &'static [&'static str];
}

/// What a processor module declares about the request it computes: its name, where its
/// input comes from, its typed parameters and how to build it. The registry turns it into
/// a [`RequestDef`] with [`request_def`]; a request's map is parsed once, into
/// `Self::Params`, which every other method takes.
pub trait Descriptor: 'static {
    /// The typed parameters (AFE names and defaults).
    type Params: Params + fmt::Debug + Send + Sync;
    /// The AFE request name, e.g. `ratemap`.
    const NAME: &'static str;
    /// The request this one is computed from (`input` for the raw ear signals).
    const DEPENDENCY: &'static str;
    /// Ear handling.
    const EARS: Ears;
    /// One-line meaning, for listings.
    const DESCRIPTION: &'static str;
    /// Unit of the output values, for listings (`""` when dimensionless).
    const OUTPUT_UNIT: &'static str;
    /// Parameters that cannot change at run time (as in the AFE).
    const FIXED: &'static [&'static str] = &[];
    /// The request lower in the chain that takes this processor's feedback output
    /// (see [`RequestDef::feeds_back_to`]).
    const FEEDS_BACK_TO: Option<&'static str> = None;

    /// This processor's parameters in a request's map (defaults filled, values checked).
    /// A processor whose parameters another processor of the chain changes (the DRNL
    /// turns off the pre-processing's unity compensation) applies that here, so that its
    /// node, its sharing and its listed parameters say what it computes.
    fn params(map: &ParamMap) -> Result<Self::Params> {
        Self::Params::from_map(map)
    }

    /// Builds the processor for the parents' outputs `inputs` (the dependency's, then
    /// those of the extra inputs).
    fn build(params: &Self::Params, inputs: &[SignalInfo]) -> Result<Built>;

    /// Builds it in the graph's `context`, for a processor that needs more than its
    /// inputs (the head's pose); the others are built by [`Descriptor::build`].
    fn build_in(
        params: &Self::Params,
        inputs: &[SignalInfo],
        _context: &BuildContext,
    ) -> Result<Built> {
        Self::build(params, inputs)
    }

    /// The parameters that decide what the processor computes; two nodes with equal maps
    /// (and equal parents) are shared.
    fn canonical(params: &Self::Params) -> Result<ParamMap> {
        Ok(params.to_map())
    }

    /// Whether any chunking gives the output of one call (false where the AFE itself
    /// depends on chunk boundaries).
    fn chunk_invariant(_: &Self::Params) -> bool {
        true
    }

    /// Where not chunk-invariant, the prefix of a whole signal (seconds) after which
    /// any chunking gives one call's output (see [`Configured::one_call_prefix_s`]).
    fn one_call_prefix_s(_: &Self::Params) -> Option<f64> {
        None
    }

    /// Requests read beside the dependency (see [`Configured::extra_inputs`]).
    fn extra_inputs(_: &Self::Params) -> &'static [&'static str] {
        &[]
    }
}

/// The type-erased registry entry of the processor described by `D`.
pub const fn request_def<D: Descriptor>() -> RequestDef {
    RequestDef {
        name: D::NAME,
        dependency: D::DEPENDENCY,
        ears: D::EARS,
        description: D::DESCRIPTION,
        output_unit: D::OUTPUT_UNIT,
        params: D::Params::SPECS,
        defaults: defaults::<D>,
        configure: configure::<D>,
        fixed: D::FIXED,
        feeds_back_to: D::FEEDS_BACK_TO,
    }
}

fn defaults<D: Descriptor>() -> ParamMap {
    D::Params::default().to_map()
}

fn configure<D: Descriptor>(map: &ParamMap) -> Result<Box<dyn Configured>> {
    let params = D::params(map)?;
    let canonical = D::canonical(&params)?;
    Ok(Box::new(Typed::<D> {
        params,
        canonical,
        descriptor: PhantomData,
    }))
}

/// The typed parameters of the processor described by `D`, with their canonical map.
struct Typed<D: Descriptor> {
    params: D::Params,
    canonical: ParamMap,
    descriptor: PhantomData<fn() -> D>,
}

impl<D: Descriptor> fmt::Debug for Typed<D> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct(D::NAME)
            .field("params", &self.params)
            .finish()
    }
}

impl<D: Descriptor> Configured for Typed<D> {
    fn canonical(&self) -> &ParamMap {
        &self.canonical
    }

    fn build(&self, inputs: &[SignalInfo], context: &BuildContext) -> Result<Built> {
        D::build_in(&self.params, inputs, context)
    }

    fn chunk_invariant(&self) -> bool {
        D::chunk_invariant(&self.params)
    }

    fn one_call_prefix_s(&self) -> Option<f64> {
        D::one_call_prefix_s(&self.params)
    }

    fn extra_inputs(&self) -> &'static [&'static str] {
        D::extra_inputs(&self.params)
    }
}
