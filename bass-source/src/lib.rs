//! The BASS-compatible audio source of `afe`.
//!
//! On a robot, the Binaural Audio Stream Server (BASS) publishes the live binaural
//! stream on a *port*: a sliding window of the last `nChunksOnPort · nFramesPerChunk`
//! frames per channel, shifted by one chunk per publication, with the 64-bit index of the
//! last frame (`lastFrameIndex`). Clients (BASC) fetch contiguous blocks from their own
//! next-frame index and learn exactly how many frames they lost when they fell behind.
//!
//! - [`Port`] / [`PortWriter`]: the port; one writer that never waits, any number of
//!   readers that never see a torn chunk.
//! - [`get_audio_data`] / [`Reader`]: BASC's block reader.
//! - [`Source`]: what feeds a port — [`WavSource`] (WAV replay), [`Synth`] (tones, noise,
//!   silence with an ITD and ILD), `AlsaSource` (ALSA capture, cargo feature `alsa`) —
//!   and [`Feeder`], which publishes a source's chunks at real time or on demand.
//! - [`Sample`]: the port stores what the source gives (`i32`, `f32`, `f64`); the AFE's
//!   input is [`Sample::to_f64`], full scale = 1.0.
//!
//! ```
//! use afe_bass_source::{Feeder, Reader, Sample, Synth};
//! let mut feeder = Feeder::new(Synth::parse("fs=16000,tone=1000,ild_db=-6")?, Some(1600))?;
//! let mut reader = Reader::new(feeder.port(), 0);
//! let (mut left, mut right) = (vec![0.0; 160], vec![0.0; 160]);
//! let mut frames = 0;
//! while !reader.at_end() {
//!     let got = reader.read(&mut [&mut left, &mut right])?;
//!     frames += got.frames;
//!     if got.frames == 0 {
//!         feeder.pump()?; // on demand; `Feeder::run_realtime` paces it instead
//!     }
//! }
//! assert_eq!(frames, 1600);
//! assert!((right[4].to_f64() / left[4] - 0.501).abs() < 1e-3);
//! # Ok::<(), afe_bass_source::Error>(())
//! ```

#[cfg(feature = "alsa")]
mod alsa;
mod error;
mod feeder;
mod placed;
mod port;
mod reader;
mod replay;
mod sample;
mod source;
mod synth;
mod wav;
mod wav_reader;

#[cfg(feature = "alsa")]
pub use alsa::{list_devices, AlsaConfig, AlsaSource, CaptureDevice};
pub use error::{Error, Result};
pub use feeder::{Feeder, Pacing};
pub use placed::Placed;
pub use port::{Port, PortFormat, PortSnapshot, PortWriter};
pub use reader::{get_audio_data, Fetch, Reader};
pub use replay::Replay;
pub use sample::Sample;
pub use source::{Clock, Source};
pub use synth::{Synth, SynthSpec};
pub use wav::{open_wav, Stored, WavFile, WavSource};
pub use wav_reader::{WavFormat, WavReadError, WavReader, WavSamples};
