//! Replaying signals held in memory, once or in a loop.

use crate::error::{Error, Result};
use crate::port::PortFormat;
use crate::sample::Sample;
use crate::source::{Clock, Source};

/// A source replaying per-channel signals from memory (decoded WAV files, test signals).
#[derive(Debug, Clone)]
pub struct Replay<S: Sample> {
    format: PortFormat,
    channels: Vec<Vec<S>>,
    position: usize,
    looping: bool,
}

impl<S: Sample> Replay<S> {
    /// Replays `channels` (equal lengths, at least one frame) sampled at `sample_rate`
    /// Hz, from the start again after the end when `looping`. Chunks follow BASS's
    /// timing ([`PortFormat::bass_timing`]) until [`Replay::set_chunking`].
    pub fn new(sample_rate: u32, channels: Vec<Vec<S>>, looping: bool) -> Result<Self> {
        let format = PortFormat::bass_timing(sample_rate, channels.len());
        format.check()?;
        let frames = channels[0].len();
        if frames == 0 || channels.iter().any(|c| c.len() != frames) {
            return Err(Error::InvalidFormat(
                "a replay needs channels of equal, non-zero lengths".into(),
            ));
        }
        Ok(Replay {
            format,
            channels,
            position: 0,
            looping,
        })
    }

    /// Publishes chunks of `frames_per_chunk` frames on a port of `chunks_on_port` chunks.
    pub fn set_chunking(&mut self, frames_per_chunk: usize, chunks_on_port: usize) -> Result<()> {
        let format = PortFormat {
            frames_per_chunk,
            chunks_on_port,
            ..self.format
        };
        format.check()?;
        self.format = format;
        Ok(())
    }

    /// Length of the signal in frames (one pass).
    pub fn frames(&self) -> usize {
        self.channels[0].len()
    }
}

impl<S: Sample> Source for Replay<S> {
    type Sample = S;

    fn format(&self) -> PortFormat {
        self.format
    }

    fn clock(&self) -> Clock {
        Clock::OnDemand
    }

    fn read_chunk(&mut self, out: &mut [Vec<S>], max_frames: usize) -> Result<usize> {
        let len = self.frames();
        if self.looping && self.position == len {
            self.position = 0;
        }
        let n = max_frames.min(len - self.position);
        for (o, c) in out.iter_mut().zip(&self.channels) {
            o.clear();
            o.extend_from_slice(&c[self.position..self.position + n]);
        }
        self.position += n;
        Ok(n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replays_once_or_in_a_loop() {
        let mut once = Replay::new(8000, vec![vec![1.0f32, 2.0, 3.0]], false).expect("replay");
        let mut out = vec![Vec::new()];
        assert_eq!(once.read_chunk(&mut out, 2).expect("read"), 2);
        assert_eq!(once.read_chunk(&mut out, 2).expect("read"), 1);
        assert_eq!(out[0], [3.0]);
        assert_eq!(once.read_chunk(&mut out, 2).expect("read"), 0);

        let mut looped = Replay::new(8000, vec![vec![1, 2, 3]], true).expect("replay");
        let mut o = vec![Vec::new()];
        let mut got = Vec::new();
        for _ in 0..4 {
            assert!(looped.read_chunk(&mut o, 2).expect("read") > 0);
            got.extend_from_slice(&o[0]);
        }
        // chunks end at the end of each pass: [1, 2], [3], [1, 2], [3]
        assert_eq!(got, [1, 2, 3, 1, 2, 3]);
    }

    #[test]
    fn bad_signals_are_refused() {
        assert!(Replay::<f64>::new(8000, vec![], false).is_err());
        assert!(Replay::new(8000, vec![vec![1.0], vec![]], false).is_err());
        assert!(Replay::new(0, vec![vec![1.0]], false).is_err());
        let mut r = Replay::new(8000, vec![vec![1.0]], false).expect("replay");
        assert!(r.set_chunking(0, 3).is_err());
        assert_eq!(
            Replay::new(44100, vec![vec![0i32; 5]], false)
                .expect("r")
                .format()
                .frames_per_chunk,
            2205
        );
    }
}
