//! The Two!Ears AFE processors, one module each, and the registry that maps a request
//! name to its processor, dependency, parameters and constructor ([`Registry`]: each
//! manager holds one, to which code outside this crate can add its own processors).
//!
//! Each module holds the processor's parameter struct (AFE names, AFE defaults), its
//! design code and its tests; nothing here knows about graphs or threads.

pub mod adaptation;
pub mod ams_features;
pub mod autocorrelation;
pub mod butterworth;
mod correlation_peak;
pub mod crosscorrelation;
pub mod drnl;
pub mod duet;
mod even_inverse;
mod exp;
pub mod filterbank;
pub mod filterbank_params;
mod framed;
pub mod gabor;
pub mod gammatone;
pub mod ic;
pub mod ihc;
pub mod ild;
pub mod itd;
pub mod localisation;
pub mod middle_ear;
pub mod moc;
pub mod pitch;
pub mod pre_proc;
pub mod precedence;
pub mod ratemap;
mod registry;
pub mod spectral_features;
pub mod stft;
#[cfg(test)]
mod testing;
pub mod tracking;
pub mod transient;
pub mod transient_map;

pub use afe_core::descriptor::{Built, Ears, RequestDef};
pub use registry::{find_request, requests, Registry};
