//! Reading WAV files into per-ear `f64` signals, full scale = 1.0.

use std::path::Path;

use afe_bass_source::{WavReader, WavSamples};

/// A decoded audio file.
#[derive(Debug, Clone, PartialEq)]
pub struct Audio {
    /// Sampling rate in Hz.
    pub fs: f64,
    /// One signal per channel (left, right), equal lengths.
    pub channels: Vec<Vec<f64>>,
}

/// Problems reading a WAV file (the reader's own error, shared with replay).
pub use afe_bass_source::WavReadError as WavError;

/// A WAV file read block by block into per-ear `f64` signals (PCM 8/16/24/32-bit scaled
/// to ±1.0, or IEEE float), so that long files need not be held in memory whole.
#[derive(Debug)]
pub struct WavBlocks {
    reader: WavReader,
    fs: f64,
    channels: usize,
    samples: WavSamples,
    /// Not a regular file (a FIFO, a device): opening and reading may block for ever.
    blocking: bool,
}

impl WavBlocks {
    /// Opens `path` and reads its header. A FIFO or device is opened and read inside an
    /// [`afe_core::interrupt::InputWait`], so that a signal stops a wait for its writer.
    pub fn open(path: &Path) -> Result<Self, WavError> {
        let blocking = std::fs::metadata(path).is_ok_and(|m| !m.is_file());
        let reader = {
            let _wait = blocking.then(afe_core::interrupt::InputWait::start);
            WavReader::open(path)?
        };
        let format = reader.format();
        Ok(WavBlocks {
            reader,
            fs: f64::from(format.sample_rate),
            channels: usize::from(format.channels),
            samples: WavSamples::Int(Vec::new()),
            blocking,
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
        self.reader.frames()
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
        let got = {
            let _wait = self.blocking.then(afe_core::interrupt::InputWait::start);
            self.reader.read(frames, &mut self.samples)?
        };
        let nch = self.channels;
        for (c, o) in out.iter_mut().enumerate().take(nch) {
            o.clear();
            match &self.samples {
                // integers come at 32-bit full scale: 2^-31 is exact
                WavSamples::Int(v) => o.extend(
                    v.iter()
                        .skip(c)
                        .step_by(nch)
                        .map(|s| f64::from(*s) / 2f64.powi(31)),
                ),
                WavSamples::Float(v) => {
                    o.extend(v.iter().skip(c).step_by(nch).map(|s| f64::from(*s)));
                }
            }
        }
        Ok(got)
    }
}

/// Opens a WAV file that afe can process: mono or two channels (left, right), not empty.
pub fn open_input(path: &Path) -> Result<WavBlocks, afe_core::Error> {
    let wav = WavBlocks::open(path).map_err(|e| afe_core::Error::InvalidInput(e.to_string()))?;
    check_input(path, &wav)?;
    Ok(wav)
}

/// Opens a WAV file of any number of channels (a robot's capture, its ears among them),
/// not empty.
pub fn open_capture(path: &Path) -> Result<WavBlocks, afe_core::Error> {
    let wav = WavBlocks::open(path).map_err(|e| afe_core::Error::InvalidInput(e.to_string()))?;
    check_not_empty(path, &wav)?;
    Ok(wav)
}

/// Checks that the open WAV file `wav` (from `path`) is one afe can process: mono or two
/// channels (left, right), not empty.
pub fn check_input(path: &Path, wav: &WavBlocks) -> Result<(), afe_core::Error> {
    if wav.channels() > 2 {
        return Err(afe_core::Error::InvalidInput(format!(
            "'{}' has {} channels: afe takes mono or two-channel (left, right) input",
            path.display(),
            wav.channels()
        )));
    }
    check_not_empty(path, wav)
}

fn check_not_empty(path: &Path, wav: &WavBlocks) -> Result<(), afe_core::Error> {
    if wav.frames() == 0 {
        return Err(afe_core::Error::InvalidInput(format!(
            "'{}' holds no samples",
            path.display()
        )));
    }
    Ok(())
}

/// Reads a PCM (8/16/24/32-bit) or IEEE-float WAV file, scaling integers to ±1.0.
///
/// ```
/// let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/example_binaural.wav");
/// let audio = afe::wav::read_wav(std::path::Path::new(path))?;
/// assert_eq!((audio.fs, audio.channels.len()), (44100.0, 2));
/// assert!(afe::wav::read_wav(std::path::Path::new("missing.wav")).is_err());
/// # Ok::<(), afe::wav::WavError>(())
/// ```
pub fn read_wav(path: &Path) -> Result<Audio, WavError> {
    WavBlocks::open(path)?.read_all()
}
