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

/// A WAV file read block by block into per-ear `f64` signals (PCM 8/16/24/32-bit scaled
/// to ±1.0, or IEEE float), so that long files need not be held in memory whole.
pub struct WavBlocks {
    reader: hound::WavReader<std::io::BufReader<std::fs::File>>,
    path: String,
    fs: f64,
    channels: usize,
    /// `Some(1/2^(bits−1))` for integer samples.
    int_scale: Option<f64>,
}

impl std::fmt::Debug for WavBlocks {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WavBlocks")
            .field("path", &self.path)
            .field("fs", &self.fs)
            .field("channels", &self.channels)
            .finish_non_exhaustive()
    }
}

impl WavBlocks {
    /// Opens `path` and reads its header.
    pub fn open(path: &Path) -> Result<Self, WavError> {
        let shown = path.display().to_string();
        let file = std::fs::File::open(path).map_err(|source| WavError::Open {
            path: shown.clone(),
            source,
        })?;
        let reader =
            hound::WavReader::new(std::io::BufReader::new(file)).map_err(|e| WavError::Format {
                path: shown.clone(),
                reason: e.to_string(),
            })?;
        let spec = reader.spec();
        if spec.channels == 0 {
            return Err(WavError::Format {
                path: shown,
                reason: "the file declares 0 channels".into(),
            });
        }
        let int_scale = (spec.sample_format == hound::SampleFormat::Int)
            .then(|| 1.0 / f64::from(1u32 << (spec.bits_per_sample.clamp(1, 32) - 1)));
        Ok(WavBlocks {
            reader,
            path: shown,
            fs: f64::from(spec.sample_rate),
            channels: usize::from(spec.channels),
            int_scale,
        })
    }

    /// Sampling rate in Hz.
    pub fn fs(&self) -> f64 {
        self.fs
    }

    /// Number of channels.
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// Frames the header declares.
    pub fn frames(&self) -> u64 {
        u64::from(self.reader.duration())
    }

    /// Reads the rest of the file.
    pub fn read_all(mut self) -> Result<Audio, WavError> {
        let mut channels = vec![Vec::new(); self.channels];
        self.read(usize::MAX, &mut channels)?;
        Ok(Audio {
            fs: self.fs,
            channels,
        })
    }

    /// Reads up to `frames` frames into `out` (one vector per channel, replaced) and
    /// returns how many it read: 0 at the end of the file.
    pub fn read(&mut self, frames: usize, out: &mut [Vec<f64>]) -> Result<usize, WavError> {
        for o in out.iter_mut() {
            o.clear();
        }
        let nch = self.channels;
        let wanted = frames.saturating_mul(nch);
        let mut push = |i: usize, v: f64| out[i % nch].push(v);
        let result = match self.int_scale {
            None => self
                .reader
                .samples::<f32>()
                .take(wanted)
                .enumerate()
                .try_for_each(|(i, s)| s.map(|v| push(i, f64::from(v)))),
            Some(scale) => self
                .reader
                .samples::<i32>()
                .take(wanted)
                .enumerate()
                .try_for_each(|(i, s)| s.map(|v| push(i, f64::from(v) * scale))),
        };
        result.map_err(|e| WavError::Format {
            path: self.path.clone(),
            reason: e.to_string(),
        })?;
        // a truncated last frame is dropped
        let got = out.iter().map(Vec::len).min().unwrap_or(0);
        for o in out.iter_mut() {
            o.truncate(got);
        }
        Ok(got)
    }
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
    WavBlocks::open(path)?.read_all()
}
