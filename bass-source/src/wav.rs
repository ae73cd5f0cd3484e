//! WAV replay: a file read as it plays, block by block, in the samples it stores.

use std::marker::PhantomData;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::port::PortFormat;
use crate::sample::Sample;
use crate::source::{Clock, Source};
use crate::wav_reader::{WavReadError, WavReader, WavSamples};

/// A WAV file ready to replay, in the sample type the file stores.
#[derive(Debug)]
pub enum WavSource {
    /// An integer PCM file (8 to 32 bits), as `i32` samples at full scale: a `b`-bit
    /// sample `v` becomes `v · 2^(32−b)`, so that `v / 2^(b−1)` = the `i32` / 2³¹.
    Int(WavFile<i32>),
    /// An IEEE-float file, as its `f32` samples.
    Float(WavFile<f32>),
}

/// Opens the WAV file at `path` for replay, from the start again after the end when
/// `looping`. The samples are read as they are played, so memory does not grow with the
/// file's length.
///
/// ```
/// let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/example_binaural.wav");
/// let wav = afe_bass_source::open_wav(std::path::Path::new(path), false)?;
/// let afe_bass_source::WavSource::Int(file) = wav else { panic!("a 16-bit file") };
/// assert_eq!(file.frames(), 44100);
/// # Ok::<(), afe_bass_source::Error>(())
/// ```
pub fn open_wav(path: &Path, looping: bool) -> Result<WavSource> {
    let reader = WavReader::open(path).map_err(|e| wav_error(path, e))?;
    let format = reader.format();
    if reader.frames() == 0 {
        return Err(Error::Wav {
            path: path.display().to_string(),
            reason: "the file holds no samples".into(),
        });
    }
    let port = PortFormat::bass_timing(format.sample_rate, usize::from(format.channels));
    port.check().map_err(|e| Error::Wav {
        path: path.display().to_string(),
        reason: e.to_string(),
    })?;
    Ok(if format.float {
        WavSource::Float(WavFile::new(
            reader,
            path,
            port,
            looping,
            WavSamples::Float(Vec::new()),
        ))
    } else {
        WavSource::Int(WavFile::new(
            reader,
            path,
            port,
            looping,
            WavSamples::Int(Vec::new()),
        ))
    })
}

fn wav_error(path: &Path, e: WavReadError) -> Error {
    match e {
        WavReadError::Open { path, source } => Error::Open {
            path,
            reason: source.to_string(),
        },
        WavReadError::Format { reason, .. } => Error::Wav {
            path: path.display().to_string(),
            reason,
        },
    }
}

/// The samples a WAV file stores, as one of the port's sample types.
pub trait Stored: Sample {
    /// The samples of `raw` (empty if `raw` holds the other type, which a [`WavFile`]
    /// of this type never reads).
    fn stored(raw: &WavSamples) -> &[Self];
}

impl Stored for i32 {
    fn stored(raw: &WavSamples) -> &[i32] {
        match raw {
            WavSamples::Int(v) => v,
            WavSamples::Float(_) => &[],
        }
    }
}

impl Stored for f32 {
    fn stored(raw: &WavSamples) -> &[f32] {
        match raw {
            WavSamples::Float(v) => v,
            WavSamples::Int(_) => &[],
        }
    }
}

/// A WAV file replayed as it is read: each chunk is read from the file when asked for.
#[derive(Debug)]
pub struct WavFile<S> {
    reader: WavReader,
    path: PathBuf,
    format: PortFormat,
    looping: bool,
    raw: WavSamples,
    samples: PhantomData<S>,
}

impl<S: Stored> WavFile<S> {
    fn new(
        reader: WavReader,
        path: &Path,
        format: PortFormat,
        looping: bool,
        raw: WavSamples,
    ) -> Self {
        WavFile {
            path: path.to_path_buf(),
            reader,
            format,
            looping,
            raw,
            samples: PhantomData,
        }
    }

    /// Length of the file in frames (one pass).
    pub fn frames(&self) -> u64 {
        self.reader.frames()
    }
}

impl<S: Stored> Source for WavFile<S> {
    type Sample = S;

    fn format(&self) -> PortFormat {
        self.format
    }

    fn clock(&self) -> Clock {
        Clock::OnDemand
    }

    fn read_chunk(&mut self, out: &mut [Vec<S>], max_frames: usize) -> Result<usize> {
        let fail = |e| wav_error(&self.path, e);
        let mut n = self.reader.read(max_frames, &mut self.raw).map_err(fail)?;
        if n == 0 && self.looping && max_frames > 0 {
            self.reader.rewind().map_err(fail)?;
            n = self.reader.read(max_frames, &mut self.raw).map_err(fail)?;
        }
        let channels = out.len();
        for (c, o) in out.iter_mut().enumerate() {
            o.clear();
            o.extend(S::stored(&self.raw).chunks_exact(channels).map(|f| f[c]));
        }
        Ok(n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Sample, Source};

    fn write(path: &Path, spec: hound::WavSpec, samples: &[i32]) {
        let mut w = hound::WavWriter::create(path, spec).expect("create");
        for s in samples {
            match spec.sample_format {
                hound::SampleFormat::Int => w.write_sample(*s).expect("write"),
                hound::SampleFormat::Float => w.write_sample(*s as f32 / 4.0).expect("write"),
            }
        }
        w.finalize().expect("finalize");
    }

    /// A path `name` in a folder of its own, removed with the returned guard.
    fn temp(name: &str) -> (tempfile::TempDir, std::path::PathBuf) {
        let dir = tempfile::tempdir().expect("temporary folder");
        let path = dir.path().join(name);
        (dir, path)
    }

    #[test]
    fn integer_files_keep_full_scale_and_float_files_their_values() {
        let (_dir, p) = temp("i16.wav");
        let spec = hound::WavSpec {
            channels: 2,
            sample_rate: 16000,
            bits_per_sample: 16,
            sample_format: hound::SampleFormat::Int,
        };
        write(&p, spec, &[-32768, 16384, 1, -1, 7, 8]);
        let WavSource::Int(mut r) = open_wav(&p, false).expect("open") else {
            panic!("integer file");
        };
        assert_eq!(r.format().sample_rate, 16000);
        let mut out = vec![Vec::new(), Vec::new()];
        assert_eq!(r.read_chunk(&mut out, 10).expect("read"), 3);
        let left: Vec<f64> = out[0].iter().map(|v| v.to_f64()).collect();
        let right: Vec<f64> = out[1].iter().map(|v| v.to_f64()).collect();
        assert_eq!(left, [-1.0, 1.0 / 32768.0, 7.0 / 32768.0]);
        assert_eq!(right, [0.5, -1.0 / 32768.0, 8.0 / 32768.0]);

        let (_dir, p) = temp("f32.wav");
        let spec = hound::WavSpec {
            channels: 1,
            sample_rate: 8000,
            bits_per_sample: 32,
            sample_format: hound::SampleFormat::Float,
        };
        write(&p, spec, &[1, -2]);
        let WavSource::Float(mut r) = open_wav(&p, true).expect("open") else {
            panic!("float file");
        };
        let mut out = vec![Vec::new()];
        r.read_chunk(&mut out, 3).expect("read");
        assert_eq!(out[0], [0.25, -0.5]);
        r.read_chunk(&mut out, 3).expect("read");
        assert_eq!(out[0], [0.25, -0.5], "looping");
    }

    /// The file is read as it plays: a looping replay reads it again from the first
    /// sample, each pass ending with the file.
    #[test]
    fn a_looping_file_is_read_again_pass_after_pass() {
        let (_dir, p) = temp("loop.wav");
        let spec = hound::WavSpec {
            channels: 2,
            sample_rate: 8000,
            bits_per_sample: 16,
            sample_format: hound::SampleFormat::Int,
        };
        write(&p, spec, &[1, -1, 2, -2, 3, -3, 4, -4, 5, -5]);
        let WavSource::Int(mut r) = open_wav(&p, true).expect("open") else {
            panic!("integer file");
        };
        assert_eq!(r.frames(), 5);
        let mut out = vec![Vec::new(), Vec::new()];
        let mut lengths = Vec::new();
        let mut left = Vec::new();
        for _ in 0..4 {
            lengths.push(r.read_chunk(&mut out, 3).expect("read"));
            left.extend(out[0].iter().map(|v| v >> 16));
            assert!(out[0].iter().zip(&out[1]).all(|(a, b)| *a == -*b));
        }
        assert_eq!(lengths, [3, 2, 3, 2]);
        assert_eq!(left, [1, 2, 3, 4, 5, 1, 2, 3, 4, 5]);
    }

    #[test]
    fn unreadable_files_are_clear_errors() {
        let missing = open_wav(Path::new("/nonexistent/x.wav"), false).expect_err("missing");
        assert!(missing
            .to_string()
            .starts_with("cannot open '/nonexistent/x.wav'"));
        let (_dir, p) = temp("text.wav");
        std::fs::write(&p, "not audio").expect("write");
        let err = open_wav(&p, false).expect_err("not wav");
        assert!(err.to_string().contains("not a WAV file"), "{err}");
        let (_dir, p) = temp("empty.wav");
        let spec = hound::WavSpec {
            channels: 2,
            sample_rate: 8000,
            bits_per_sample: 16,
            sample_format: hound::SampleFormat::Int,
        };
        write(&p, spec, &[]);
        let err = open_wav(&p, false).expect_err("empty");
        assert!(err.to_string().contains("holds no samples"), "{err}");
    }
}
