//! Core types of `afe`: time-major signal blocks, the [`Processor`] contract, the
//! [`Descriptor`] a processor module declares for its request, AFE parameters, the error
//! type, and the DSP primitives the processors are built from
//! (DF2T filtering, Butterworth and `fir2` design, windows, the ERB scale, framing, the
//! analytic signal, the real FFT, Savitzky–Golay smoothing). Nothing here knows a processor by name.

// the kernels' clones name `::afe_core::cpu`, here as in the crates that call them
extern crate self as afe_core;

pub mod axis;
pub mod block;
pub mod butter;
pub mod cpu;
pub mod denormals;
pub mod descriptor;
pub mod erb;
pub mod error;
pub mod expected_source;
pub mod filter;
pub mod fir2;
pub mod framing;
pub mod from_above;
pub mod head_pose;
pub mod hilbert;
mod huge_pages;
pub mod interrupt;
pub mod lanes;
pub mod param_decl;
pub mod params;
pub mod plan;
pub mod power;
pub mod processor;
pub mod real_fft;
pub mod sgolay;
pub mod signal_info;
pub mod simd;
pub mod window;

pub use axis::{Axis, OtherAxis};
pub use block::Block;
pub use descriptor::{request_def, BuildContext, Built, Configured, Descriptor, Ears, RequestDef};
pub use error::{Error, Result};
pub use expected_source::ExpectedSource;
pub use from_above::FromAbove;
pub use head_pose::HeadPose;
pub use interrupt::CancelToken;
pub use params::{NoParams, ParamKind, ParamMap, ParamSpec, Params};
pub use plan::{Panel, Plan, PlanAxis, Scale};
pub use processor::{ChannelSplit, Feedback, Part, Processor, WholeSignal};
pub use signal_info::{DrawAs, SignalInfo, SignalKind};
