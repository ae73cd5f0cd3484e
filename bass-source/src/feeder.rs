//! Driving a source into its port: chunk by chunk on demand, or paced at real time.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::error::Result;
use crate::port::{Port, PortWriter};
use crate::source::{Clock, Source};

/// How a stream runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pacing {
    /// Chunks are published when their last frame would have been captured: an
    /// on-demand source behaves like a live one.
    Realtime,
    /// Chunks are published as fast as the reader consumes them.
    Fast,
}

/// Owns a source and the writer of its port, and publishes the source's chunks.
#[derive(Debug)]
pub struct Feeder<Src: Source> {
    source: Src,
    writer: Option<PortWriter<Src::Sample>>,
    port: Arc<Port<Src::Sample>>,
    chunk: Vec<Vec<Src::Sample>>,
    limit: Option<u64>,
    fed: u64,
    /// Frames published at once at real time (at most `nFramesPerChunk`).
    pace: usize,
}

impl<Src: Source> Feeder<Src> {
    /// A feeder of `source` into a new port of the source's format, stopping after
    /// `limit` frames (`None`: at the end of the source).
    ///
    /// ```
    /// use afe_bass_source::{Feeder, Reader, Synth};
    /// let synth = Synth::parse("fs=16000,tone=500")?;
    /// let mut feeder = Feeder::new(synth, Some(1000))?;
    /// let mut reader = Reader::new(feeder.port(), 0);
    /// let (mut l, mut r) = (vec![0.0; 1000], vec![0.0; 1000]);
    /// while feeder.pump()? {}
    /// let fetch = reader.read(&mut [&mut l, &mut r])?;
    /// assert_eq!((fetch.frames, fetch.lost), (1000, 0));
    /// assert!(reader.at_end());
    /// # Ok::<(), afe_bass_source::Error>(())
    /// ```
    pub fn new(source: Src, limit: Option<u64>) -> Result<Self> {
        let format = source.format();
        let writer = Port::create(format)?;
        let chunk = (0..format.channels)
            .map(|_| Vec::with_capacity(format.frames_per_chunk))
            .collect();
        Ok(Feeder {
            source,
            port: writer.port(),
            writer: Some(writer),
            chunk,
            limit,
            fed: 0,
            pace: format.frames_per_chunk,
        })
    }

    /// The port fed, for readers.
    pub fn port(&self) -> Arc<Port<Src::Sample>> {
        Arc::clone(&self.port)
    }

    /// The source.
    pub fn source(&self) -> &Src {
        &self.source
    }

    /// Frames published so far.
    pub fn frames_fed(&self) -> u64 {
        self.fed
    }

    /// Has [`Feeder::run_realtime`] publish an on-demand source `frames` at a time (at
    /// most `nFramesPerChunk`, at least 1) instead of whole chunks: a reader taking blocks
    /// of that length gets each one as soon as its last frame is due, not with the
    /// chunk's last block.
    pub fn set_pace(&mut self, frames: usize) {
        self.pace = frames.clamp(1, self.port.n_frames_per_chunk());
    }

    /// Publishes the source's next chunk and returns `true`; returns `false` (and closes
    /// the port) at the end of the source or of the limit. An error closes the port too.
    pub fn pump(&mut self) -> Result<bool> {
        self.pump_at_most(self.port.n_frames_per_chunk())
    }

    /// [`Feeder::pump`] with chunks of at most `frames` frames.
    fn pump_at_most(&mut self, frames: usize) -> Result<bool> {
        let Some(writer) = self.writer.as_mut() else {
            return Ok(false);
        };
        let room = self.limit.map_or(u64::MAX, |l| l - self.fed);
        let max = (frames as u64).min(room) as usize;
        let n = if max == 0 {
            Ok(0)
        } else {
            self.source.read_chunk(&mut self.chunk, max)
        };
        let published = n.and_then(|n| {
            if n > 0 {
                let refs: Vec<&[Src::Sample]> = self.chunk.iter().map(|c| &c[..n]).collect();
                writer.publish(&refs)?;
            }
            Ok(n)
        });
        match published {
            Ok(n) if n > 0 => {
                self.fed += n as u64;
                Ok(true)
            }
            other => {
                self.writer = None;
                other.map(|_| false)
            }
        }
    }

    /// Publishes chunk after chunk until the end, the limit, or `stop`, then closes the
    /// port. An on-demand source's chunk is published when its last frame would have been
    /// captured (`start + frames/fs`); a device's chunks as the device delivers them.
    pub fn run_realtime(&mut self, stop: &AtomicBool) -> Result<()> {
        let start = Instant::now();
        let fs = f64::from(self.port.sample_rate());
        let paced = self.source.clock() == Clock::OnDemand;
        while !stop.load(Ordering::Relaxed) {
            let before = self.fed;
            let frames = if paced {
                let room = self.limit.map_or(u64::MAX, |l| l - before);
                let k = (self.pace as u64).min(room);
                let due = start + Duration::from_secs_f64((before + k) as f64 / fs);
                if let Some(wait) = due.checked_duration_since(Instant::now()) {
                    std::thread::sleep(wait);
                }
                self.pace
            } else {
                self.port.n_frames_per_chunk()
            };
            if !self.pump_at_most(frames)? {
                return Ok(());
            }
        }
        self.writer = None;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::replay::Replay;
    use crate::Reader;

    fn ramp(frames: usize) -> Replay<i32> {
        let left: Vec<i32> = (0..frames as i32).collect();
        let right: Vec<i32> = left.iter().map(|v| -v).collect();
        let mut r = Replay::new(8000, vec![left, right], false).expect("replay");
        r.set_chunking(100, 4).expect("chunking");
        r
    }

    #[test]
    fn pumping_publishes_the_source_then_closes_the_port() {
        let mut f = Feeder::new(ramp(250), None).expect("feeder");
        let port = f.port();
        assert!(f.pump().expect("pump"));
        assert!(f.pump().expect("pump"));
        assert!(f.pump().expect("pump"));
        assert_eq!(port.last_frame_index(), Some(249));
        assert!(!port.is_closed());
        assert!(!f.pump().expect("pump"));
        assert!(port.is_closed());
        assert_eq!(f.frames_fed(), 250);
    }

    #[test]
    fn a_paced_feeder_publishes_its_pace_at_a_time() {
        let mut f = Feeder::new(ramp(250), None).expect("feeder");
        f.set_pace(30);
        let port = f.port();
        let stop = AtomicBool::new(false);
        std::thread::scope(|s| {
            s.spawn(|| f.run_realtime(&stop).expect("run"));
            // 30 frames at 8 kHz are due every 3.75 ms: the first ones come alone
            let t = Instant::now();
            while port.frames_published() == 0 {
                assert!(t.elapsed() < Duration::from_secs(5), "nothing published");
                std::thread::sleep(Duration::from_micros(200));
            }
            // whole chunks (100 frames) would come first without the pace
            let first = port.frames_published();
            assert!(first % 30 == 0 && first < 100, "{first}");
        });
        assert_eq!(f.frames_fed(), 250);
    }

    #[test]
    fn a_limit_cuts_the_last_chunk() {
        let mut f = Feeder::new(ramp(1000), Some(130)).expect("feeder");
        while f.pump().expect("pump") {}
        let snap = f.port().snapshot();
        assert_eq!(snap.last_frame_index, Some(129));
        assert_eq!(snap.channels[1][399], -129);
    }

    #[test]
    fn real_time_pacing_takes_the_signal_duration() {
        // 400 frames at 8 kHz: 50 ms
        let mut f = Feeder::new(ramp(400), None).expect("feeder");
        let port = f.port();
        let stop = AtomicBool::new(false);
        let t = Instant::now();
        std::thread::scope(|s| {
            s.spawn(|| f.run_realtime(&stop).expect("run"));
            let mut r = Reader::new(port, 0);
            let mut first = None;
            let mut buf = (vec![0; 400], vec![0; 400]);
            while !r.at_end() {
                let got = r.read(&mut [&mut buf.0, &mut buf.1]).expect("read");
                if got.frames > 0 && first.is_none() {
                    first = Some(t.elapsed());
                }
                std::thread::sleep(Duration::from_millis(1));
            }
            let first = first.expect("frames arrived");
            assert!(first >= Duration::from_millis(12), "{first:?}");
        });
        assert!(t.elapsed() >= Duration::from_millis(50));
        assert_eq!(f.frames_fed(), 400);
    }
}
