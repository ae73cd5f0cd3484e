//! Reading WAV files into per-ear `f64` signals, full scale = 1.0.

use std::path::Path;

use thiserror::Error;

/// A decoded audio file.
#[derive(Debug, Clone, PartialEq)]
pub struct Audio {
    /// Sampling rate in Hz.
    pub fs: f64,
    /// One signal per channel (left, right), equal lengths.
    pub channels: Vec<Vec<f64>>,
}

/// Problems reading a WAV file.
#[derive(Debug, Error)]
pub enum WavError {
    /// The file cannot be opened.
    #[error("cannot open '{path}': {source}")]
    Open {
        /// The path as given.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// The file is not a WAV file this reader understands, or is corrupt.
    #[error("cannot read '{path}' as WAV: {reason}")]
    Format {
        /// The path as given.
        path: String,
        /// What is wrong.
        reason: String,
    },
}

/// Reads a PCM (8/16/24/32-bit) or IEEE-float WAV file, scaling integers to ±1.0.
///
/// ```
/// let path = concat!(env!("CARGO_MANIFEST_DIR"), "/data/example_binaural.wav");
/// let audio = afe::wav::read_wav(std::path::Path::new(path))?;
/// assert_eq!((audio.fs, audio.channels.len()), (44100.0, 2));
/// assert!(afe::wav::read_wav(std::path::Path::new("missing.wav")).is_err());
/// # Ok::<(), afe::wav::WavError>(())
/// ```
pub fn read_wav(path: &Path) -> Result<Audio, WavError> {
    let shown = path.display().to_string();
    let file = std::fs::File::open(path).map_err(|source| WavError::Open {
        path: shown.clone(),
        source,
    })?;
    let format = |reason: String| WavError::Format {
        path: shown.clone(),
        reason,
    };
    let mut reader =
        hound::WavReader::new(std::io::BufReader::new(file)).map_err(|e| format(e.to_string()))?;
    let spec = reader.spec();
    let nch = usize::from(spec.channels);
    if nch == 0 {
        return Err(format("the file declares 0 channels".into()));
    }
    let interleaved: Vec<f64> = match spec.sample_format {
        hound::SampleFormat::Float => reader
            .samples::<f32>()
            .map(|s| s.map(f64::from))
            .collect::<Result<_, _>>(),
        hound::SampleFormat::Int => {
            let scale = 1.0 / f64::from(1u32 << (spec.bits_per_sample.clamp(1, 32) - 1));
            reader
                .samples::<i32>()
                .map(|s| s.map(|v| f64::from(v) * scale))
                .collect::<Result<_, _>>()
        }
    }
    .map_err(|e| format(e.to_string()))?;
    let frames = interleaved.len() / nch;
    let channels = (0..nch)
        .map(|c| (0..frames).map(|t| interleaved[t * nch + c]).collect())
        .collect();
    Ok(Audio {
        fs: f64::from(spec.sample_rate),
        channels,
    })
}
