//! WAV replay: a file decoded into the samples it stores, replayed through a port.

use std::path::Path;

use crate::error::{Error, Result};
use crate::replay::Replay;
use crate::wav_reader::{WavReadError, WavReader, WavSamples};

/// A WAV file ready to replay, in the sample type the file stores.
#[derive(Debug, Clone)]
pub enum WavSource {
    /// An integer PCM file (8 to 32 bits), as `i32` samples at full scale: a `b`-bit
    /// sample `v` becomes `v · 2^(32−b)`, so that `v / 2^(b−1)` = the `i32` / 2³¹.
    Int(Replay<i32>),
    /// An IEEE-float file, as its `f32` samples.
    Float(Replay<f32>),
}

/// Decodes the WAV file at `path` for replay, from the start again after the end when
/// `looping`.
///
/// ```
/// let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/example_binaural.wav");
/// let wav = afe_bass_source::open_wav(std::path::Path::new(path), false)?;
/// let afe_bass_source::WavSource::Int(replay) = wav else { panic!("a 16-bit file") };
/// assert_eq!(replay.frames(), 44100);
/// # Ok::<(), afe_bass_source::Error>(())
/// ```
pub fn open_wav(path: &Path, looping: bool) -> Result<WavSource> {
    let mut reader = WavReader::open(path).map_err(|e| match e {
        WavReadError::Open { path, source } => Error::Open {
            path,
            reason: source.to_string(),
        },
        WavReadError::Format { path, reason } => Error::Wav { path, reason },
    })?;
    let wav = |reason: String| Error::Wav {
        path: path.display().to_string(),
        reason,
    };
    let format = reader.format();
    if reader.frames() == 0 {
        return Err(wav("the file holds no samples".into()));
    }
    let nch = usize::from(format.channels);
    let mut samples = WavSamples::Int(Vec::new());
    reader
        .read(usize::MAX, &mut samples)
        .map_err(|e| wav(e.to_string()))?;
    match samples {
        WavSamples::Int(v) => {
            Replay::new(format.sample_rate, deinterleave(&v, nch), looping).map(WavSource::Int)
        }
        WavSamples::Float(v) => {
            Replay::new(format.sample_rate, deinterleave(&v, nch), looping).map(WavSource::Float)
        }
    }
    .map_err(|e| wav(e.to_string()))
}

/// Splits interleaved samples into `channels` signals (an incomplete last frame is dropped).
fn deinterleave<S: Copy>(samples: &[S], channels: usize) -> Vec<Vec<S>> {
    (0..channels)
        .map(|c| samples.chunks_exact(channels).map(|f| f[c]).collect())
        .collect()
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

    fn temp(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("afe-bass-wav-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        dir.join(name)
    }

    #[test]
    fn integer_files_keep_full_scale_and_float_files_their_values() {
        let p = temp("i16.wav");
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

        let p = temp("f32.wav");
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

    #[test]
    fn unreadable_files_are_clear_errors() {
        let missing = open_wav(Path::new("/nonexistent/x.wav"), false).expect_err("missing");
        assert!(missing
            .to_string()
            .starts_with("cannot open '/nonexistent/x.wav'"));
        let p = temp("text.wav");
        std::fs::write(&p, "not audio").expect("write");
        let err = open_wav(&p, false).expect_err("not wav");
        assert!(err.to_string().contains("not a WAV file"), "{err}");
        let p = temp("empty.wav");
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
