//! `afe`: a real-time binaural Auditory Front-End. It computes the 23 representations of the
//! Two!Ears Auditory Front-End (AFE) — gammatone and DRNL filterbanks, inner-hair-cell
//! envelope, ratemap, ILD, cross-correlation, ITD, IC, precedence cues, MOC feedback, pitch,
//! AMS, onsets, spectral and Gabor features, STFT, DUET and more — with the AFE's request
//! and parameter names and numbers.
//!
//! ```
//! use afe::{Manager, ParamMap};
//! let fs = 16000.0;
//! let left: Vec<f64> = (0..1600).map(|t| (0.3 * t as f64).sin()).collect();
//! let right: Vec<f64> = left.iter().map(|v| 0.5 * v).collect();
//!
//! let mut mgr = Manager::new(fs, 2)?;
//! let ild = mgr.add_request("ild", &ParamMap::new())?;
//! mgr.process_signal(&[&left, &right])?;
//! let out = &mgr.request_signals(ild)?[0];
//! // right is 6 dB softer than left in every frame of a steady tone's main channel
//! let channel = out.info.cf_hz().iter().position(|f| *f > 700.0).unwrap_or(0);
//! let last = out.new.row(out.new.frames() - 1);
//! assert!((last[channel] + 6.02).abs() < 0.1);
//! # Ok::<(), afe::Error>(())
//! ```

pub mod block_times;
pub mod bounded_read;
pub mod catalog;
pub mod extract;
pub mod frames;
pub mod host;
pub mod memory;
pub mod metadata;
pub mod npy;
pub mod output;
pub mod raa;
pub mod realtime;
mod recorder;
pub mod rss;
pub mod stream;
pub mod trial;
mod turning;
pub mod wav;

pub use afe_bass_source as bass_source;
/// Stopping long work on request (SIGINT, Ctrl-C): see [`afe_core::interrupt`].
pub use afe_core::interrupt;
pub use afe_core::{Block, Error, HeadPose, ParamMap, Result, SignalInfo, SignalKind};
pub use afe_graph::{Channel, Manager, RequestHandle, Signal};
pub use afe_processors::{find_request, requests, Registry, RequestDef};
pub use recorder::{Recorded, Recorder};
