//! The error type of the port, the readers and the sources.

use thiserror::Error;

/// Everything that can go wrong when building a port, publishing to it, reading from it,
/// or opening and running a source.
///
/// Each message names the offending value and says what would be accepted.
#[derive(Debug, Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum Error {
    /// A port shape that cannot hold audio (no channel, no frame, no chunk, no rate).
    #[error("invalid port format: {0}")]
    InvalidFormat(String),
    /// A chunk or a destination with the wrong number of channels.
    #[error("expected {expected} channel(s), got {actual}")]
    ChannelCount {
        /// Channels of the port.
        expected: usize,
        /// Channels given.
        actual: usize,
    },
    /// A chunk that cannot be published: empty, longer than `nFramesPerChunk`, or with
    /// channels of different lengths.
    #[error("cannot publish a chunk of {frames} frame(s): {reason}")]
    InvalidChunk {
        /// Frames in the (first channel of the) chunk.
        frames: usize,
        /// What is accepted instead.
        reason: String,
    },
    /// A file that cannot be opened.
    #[error("cannot open '{path}': {reason}")]
    Open {
        /// The path as given.
        path: String,
        /// The operating system's reason.
        reason: String,
    },
    /// A WAV file that cannot be replayed (corrupt, unsupported, empty, too many channels).
    #[error("cannot replay '{path}': {reason}")]
    Wav {
        /// The path as given.
        path: String,
        /// What is wrong.
        reason: String,
    },
    /// A synthetic-signal specification that does not parse or holds an invalid value.
    #[error("invalid synth spec '{spec}': {reason}")]
    SynthSpec {
        /// The specification as given.
        spec: String,
        /// What is wrong, and what is accepted.
        reason: String,
    },
    /// An ALSA capture device that does not exist or cannot be opened.
    #[error("cannot open ALSA capture device '{device}': {reason} (`afe devices` lists the capture devices)")]
    DeviceNotFound {
        /// The ALSA device name as given, e.g. `hw:1,0`.
        device: String,
        /// ALSA's reason.
        reason: String,
    },
    /// An ALSA capture device that cannot capture at the requested rate.
    #[error("ALSA device '{device}' cannot capture at {rate} Hz (it accepts {min}..={max} Hz; `plug:{device}` resamples)")]
    UnsupportedRate {
        /// The ALSA device name.
        device: String,
        /// The requested rate in Hz.
        rate: u32,
        /// Lowest rate the device accepts, in Hz.
        min: u32,
        /// Highest rate the device accepts, in Hz.
        max: u32,
    },
    /// An ALSA device that does not take the capture configuration BASS uses (two
    /// interleaved channels of signed 32-bit samples), or fails while capturing.
    #[error("ALSA device '{device}': {reason}")]
    Alsa {
        /// The ALSA device name.
        device: String,
        /// What failed.
        reason: String,
    },
    /// A remote source (a server's published audio) that fails: a malformed block, a
    /// channel count that changed, a lost session.
    #[error("remote source: {0}")]
    Remote(String),
}

/// Shorthand for results carrying [`enum@Error`].
pub type Result<T> = std::result::Result<T, Error>;
