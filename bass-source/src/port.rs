//! The BASS port: a sliding window of the last frames, published chunk by chunk, with a
//! 64-bit index of the last frame.
//!
//! One writer ([`PortWriter`]) and any number of readers share a [`Port`]. The writer
//! never waits: it overwrites the oldest chunk whether or not a reader has copied it.
//! A reader never sees a torn chunk: two sequence counters (seqlock style) tell it, after
//! its copy, which of the frames it copied the writer had started to overwrite.
//!
//! Memory ordering. Publishing frames `[p, p+k)`: `claimed = p+k` (relaxed), a release
//! fence, the samples (relaxed), then `published = p+k` (release). Reading frames
//! `[a, b)`: `published` (acquire) bounds `b`; the samples (relaxed); an acquire fence;
//! then `claimed` (relaxed). If the copy saw a sample of an overwrite, the fences order
//! that overwrite's `claimed` store before the reader's `claimed` load, which therefore
//! shows the overwrite: the copy of frame `f` is intact iff `claimed ≤ f + capacity`.

use std::sync::atomic::{fence, AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;

use crate::error::{Error, Result};
use crate::sample::Sample;

/// The shape of a port: BASS's `sampleRate`, `nFramesPerChunk`, `nChunksOnPort`, and the
/// number of channels (BASS: 2, left and right).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PortFormat {
    /// Sampling rate in Hz (BASS `sampleRate`).
    pub sample_rate: u32,
    /// Channels (1 = mono, 2 = left, right).
    pub channels: usize,
    /// Frames published at once, in frames (BASS `nFramesPerChunk`).
    pub frames_per_chunk: usize,
    /// Chunks the port keeps (BASS `nChunksOnPort`): the window is
    /// `frames_per_chunk · chunks_on_port` frames long.
    pub chunks_on_port: usize,
}

impl Default for PortFormat {
    /// BASS's defaults: 44100 Hz, 2 channels, 2205 frames (50 ms) per chunk, 20 chunks
    /// (1 s) on the port.
    fn default() -> Self {
        PortFormat {
            sample_rate: 44_100,
            channels: 2,
            frames_per_chunk: 2205,
            chunks_on_port: 20,
        }
    }
}

impl PortFormat {
    /// BASS's timing at another rate: chunks of 50 ms (`round(fs/20)` frames), 20 on the
    /// port (1 s).
    ///
    /// ```
    /// use afe_bass_source::PortFormat;
    /// assert_eq!(PortFormat::bass_timing(44100, 2), PortFormat::default());
    /// assert_eq!(PortFormat::bass_timing(16000, 1).frames_per_chunk, 800);
    /// ```
    pub fn bass_timing(sample_rate: u32, channels: usize) -> Self {
        PortFormat {
            sample_rate,
            channels,
            frames_per_chunk: ((f64::from(sample_rate) / 20.0).round() as usize).max(1),
            chunks_on_port: 20,
        }
    }

    /// Frames the port holds per channel: `frames_per_chunk · chunks_on_port`.
    pub fn capacity(&self) -> usize {
        self.frames_per_chunk * self.chunks_on_port
    }

    /// Refuses shapes that cannot hold audio, with a message naming the field.
    pub(crate) fn check(&self) -> Result<()> {
        let bad = |what: &str| Err(Error::InvalidFormat(what.to_string()));
        if self.sample_rate == 0 {
            return bad("the sampling rate must be at least 1 Hz");
        }
        if self.channels == 0 {
            return bad("a port needs at least one channel");
        }
        if self.frames_per_chunk == 0 || self.chunks_on_port == 0 {
            return bad("nFramesPerChunk and nChunksOnPort must be at least 1");
        }
        if self
            .frames_per_chunk
            .checked_mul(self.chunks_on_port)
            .and_then(|f| f.checked_mul(self.channels))
            .is_none()
        {
            return bad("nFramesPerChunk · nChunksOnPort · channels overflows");
        }
        Ok(())
    }
}

/// The BASS port: the last `capacity` frames of every channel, and the index of the
/// last frame published.
pub struct Port<S: Sample> {
    format: PortFormat,
    /// Frames published since the start of the acquisition (BASS `lastFrameIndex + 1`).
    published: AtomicU64,
    /// End of the frames the writer has started to write: `published`, plus the chunk
    /// being written.
    claimed: AtomicU64,
    closed: AtomicBool,
    /// Channel-major ring: frame `f` of channel `c` lives at `c·capacity + f % capacity`.
    cells: Box<[S::Cell]>,
}

impl<S: Sample> std::fmt::Debug for Port<S> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Port")
            .field("format", &self.format)
            .field("published", &self.published)
            .field("claimed", &self.claimed)
            .field("closed", &self.closed)
            .finish_non_exhaustive()
    }
}

/// The port seen as BASS publishes it, copied at one instant.
#[derive(Debug, Clone, PartialEq)]
pub struct PortSnapshot<S> {
    /// Sampling rate in Hz (BASS `sampleRate`).
    pub sample_rate: u32,
    /// Chunks on the port (BASS `nChunksOnPort`).
    pub n_chunks_on_port: usize,
    /// Frames per chunk (BASS `nFramesPerChunk`).
    pub n_frames_per_chunk: usize,
    /// Index of the last frame published, counted from 0 at the start of the
    /// acquisition (BASS `lastFrameIndex`); `None` before the first chunk.
    pub last_frame_index: Option<u64>,
    /// One array per channel of `nChunksOnPort · nFramesPerChunk` frames, oldest first,
    /// the last one being frame `last_frame_index`; zeros where nothing was published yet.
    pub channels: Vec<Vec<S>>,
}

impl<S: Sample> Port<S> {
    /// A port of `format`, all zeros, and its one writer. Readers get the port from
    /// [`PortWriter::port`].
    ///
    /// ```
    /// use afe_bass_source::{Port, PortFormat};
    /// let format = PortFormat { sample_rate: 16000, channels: 2, frames_per_chunk: 4, chunks_on_port: 2 };
    /// let mut writer = Port::<i32>::create(format)?;
    /// writer.publish(&[&[1, 2, 3, 4], &[-1, -2, -3, -4]])?;
    /// let snap = writer.port().snapshot();
    /// assert_eq!(snap.last_frame_index, Some(3));
    /// assert_eq!(snap.channels[1], [0, 0, 0, 0, -1, -2, -3, -4]);
    /// # Ok::<(), afe_bass_source::Error>(())
    /// ```
    pub fn create(format: PortFormat) -> Result<PortWriter<S>> {
        Self::create_at(format, 0)
    }

    /// As [`Port::create`], numbering the first frame `first_frame` instead of 0 (the
    /// port then behaves as if `first_frame` frames had been published and read).
    pub fn create_at(format: PortFormat, first_frame: u64) -> Result<PortWriter<S>> {
        format.check()?;
        let cells = (0..format.capacity() * format.channels)
            .map(|_| S::zero_cell())
            .collect();
        let port = Port {
            format,
            published: AtomicU64::new(first_frame),
            claimed: AtomicU64::new(first_frame),
            closed: AtomicBool::new(false),
            cells,
        };
        Ok(PortWriter {
            port: Arc::new(port),
        })
    }

    /// The port's shape.
    pub fn format(&self) -> PortFormat {
        self.format
    }

    /// Sampling rate in Hz (BASS `sampleRate`).
    pub fn sample_rate(&self) -> u32 {
        self.format.sample_rate
    }

    /// Number of channels.
    pub fn channels(&self) -> usize {
        self.format.channels
    }

    /// Frames per chunk (BASS `nFramesPerChunk`).
    pub fn n_frames_per_chunk(&self) -> usize {
        self.format.frames_per_chunk
    }

    /// Chunks on the port (BASS `nChunksOnPort`).
    pub fn n_chunks_on_port(&self) -> usize {
        self.format.chunks_on_port
    }

    /// Frames the port holds per channel (`nChunksOnPort · nFramesPerChunk`).
    pub fn capacity(&self) -> usize {
        self.format.capacity()
    }

    /// Frames published so far, i.e. the index the next frame will have
    /// (BASS `lastFrameIndex + 1`).
    pub fn frames_published(&self) -> u64 {
        self.published.load(Ordering::Acquire)
    }

    /// Index of the last frame published (BASS `lastFrameIndex`), `None` before the first.
    pub fn last_frame_index(&self) -> Option<u64> {
        self.frames_published().checked_sub(1)
    }

    /// Index of the oldest frame still on the port (BASC's `ofi`).
    pub fn oldest_frame_index(&self) -> u64 {
        self.frames_published()
            .saturating_sub(self.capacity() as u64)
    }

    /// Whether the writer is gone: no frame will be published any more.
    pub fn is_closed(&self) -> bool {
        self.closed.load(Ordering::Acquire)
    }

    /// The port as BASS shows it: its fields and the per-channel arrays, oldest frame
    /// first. Copies again while the writer overwrites the window during the copy (a
    /// writer publishing at real time leaves ample time between chunks).
    pub fn snapshot(&self) -> PortSnapshot<S> {
        let cap = self.capacity();
        let mut channels = vec![vec![S::default(); cap]; self.channels()];
        loop {
            let published = self.published.load(Ordering::Acquire);
            let first = published.saturating_sub(cap as u64);
            let n = (published - first) as usize;
            for (c, out) in channels.iter_mut().enumerate() {
                out[..cap - n].fill(S::default());
                self.copy(c, first, &mut out[cap - n..]);
            }
            if self.intact_from() <= first {
                return PortSnapshot {
                    sample_rate: self.format.sample_rate,
                    n_chunks_on_port: self.format.chunks_on_port,
                    n_frames_per_chunk: self.format.frames_per_chunk,
                    last_frame_index: published.checked_sub(1),
                    channels,
                };
            }
        }
    }

    /// Copies channel `c`'s frames `[first, first + out.len())` (relaxed loads; the
    /// caller checks [`Port::intact_from`] afterwards).
    pub(crate) fn copy(&self, c: usize, first: u64, out: &mut [S]) {
        let cap = self.capacity();
        let ring = &self.cells[c * cap..(c + 1) * cap];
        let start = (first % cap as u64) as usize;
        let head = out.len().min(cap - start);
        let (a, b) = out.split_at_mut(head);
        for (o, cell) in a.iter_mut().zip(&ring[start..]) {
            *o = S::load(cell);
        }
        for (o, cell) in b.iter_mut().zip(ring) {
            *o = S::load(cell);
        }
    }

    /// After a copy (and its acquire fence): the first frame index whose copy is
    /// certainly intact; every frame copied from an index below it may have been
    /// overwritten during the copy.
    pub(crate) fn intact_from(&self) -> u64 {
        fence(Ordering::Acquire);
        self.claimed
            .load(Ordering::Relaxed)
            .saturating_sub(self.capacity() as u64)
    }
}

/// The one writer of a [`Port`]. Dropping it closes the port.
#[derive(Debug)]
pub struct PortWriter<S: Sample> {
    port: Arc<Port<S>>,
}

impl<S: Sample> PortWriter<S> {
    /// The port, for readers.
    pub fn port(&self) -> Arc<Port<S>> {
        Arc::clone(&self.port)
    }

    /// Publishes one chunk, one slice per channel of 1..=`nFramesPerChunk` frames (the
    /// last chunk of a finite source may be shorter). The window shifts by that many
    /// frames; readers copying the overwritten frames learn it. Never waits.
    pub fn publish(&mut self, chunk: &[&[S]]) -> Result<()> {
        let port = &*self.port;
        if chunk.len() != port.channels() {
            return Err(Error::ChannelCount {
                expected: port.channels(),
                actual: chunk.len(),
            });
        }
        let k = chunk[0].len();
        let invalid = |reason: String| Err(Error::InvalidChunk { frames: k, reason });
        if k == 0 || k > port.n_frames_per_chunk() {
            return invalid(format!(
                "a chunk holds 1..={} frames (nFramesPerChunk)",
                port.n_frames_per_chunk()
            ));
        }
        if chunk.iter().any(|c| c.len() != k) {
            return invalid("every channel must hold the same number of frames".into());
        }
        let cap = port.capacity();
        let p = port.published.load(Ordering::Relaxed);
        port.claimed.store(p + k as u64, Ordering::Relaxed);
        fence(Ordering::Release);
        let start = (p % cap as u64) as usize;
        let head = k.min(cap - start);
        for (c, samples) in chunk.iter().enumerate() {
            let ring = &port.cells[c * cap..(c + 1) * cap];
            for (cell, v) in ring[start..start + head].iter().zip(&samples[..head]) {
                S::store(cell, *v);
            }
            for (cell, v) in ring.iter().zip(&samples[head..]) {
                S::store(cell, *v);
            }
        }
        port.published.store(p + k as u64, Ordering::Release);
        Ok(())
    }
}

impl<S: Sample> Drop for PortWriter<S> {
    fn drop(&mut self) {
        self.port.closed.store(true, Ordering::Release);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn format(frames_per_chunk: usize, chunks_on_port: usize) -> PortFormat {
        PortFormat {
            sample_rate: 8000,
            channels: 2,
            frames_per_chunk,
            chunks_on_port,
        }
    }

    #[test]
    fn arrays_start_as_zeros_and_shift_by_one_chunk_per_publication() {
        let mut w = Port::<f64>::create(format(3, 2)).expect("port");
        let port = w.port();
        let s = port.snapshot();
        assert_eq!(
            (s.sample_rate, s.n_chunks_on_port, s.n_frames_per_chunk),
            (8000, 2, 3)
        );
        assert_eq!(s.last_frame_index, None);
        assert_eq!(s.channels, vec![vec![0.0; 6]; 2]);

        w.publish(&[&[1.0, 2.0, 3.0], &[-1.0, -2.0, -3.0]])
            .expect("publish");
        let s = port.snapshot();
        assert_eq!(s.last_frame_index, Some(2));
        assert_eq!(s.channels[0], [0.0, 0.0, 0.0, 1.0, 2.0, 3.0]);

        w.publish(&[&[4.0, 5.0, 6.0], &[-4.0, -5.0, -6.0]])
            .expect("publish");
        w.publish(&[&[7.0, 8.0, 9.0], &[-7.0, -8.0, -9.0]])
            .expect("publish");
        let s = port.snapshot();
        assert_eq!(s.last_frame_index, Some(8));
        assert_eq!(s.channels[0], [4.0, 5.0, 6.0, 7.0, 8.0, 9.0]);
        assert_eq!(s.channels[1], [-4.0, -5.0, -6.0, -7.0, -8.0, -9.0]);
        assert_eq!(port.oldest_frame_index(), 3);

        // a short last chunk shifts by its length
        w.publish(&[&[10.0], &[-10.0]]).expect("publish");
        assert_eq!(port.snapshot().channels[0], [5.0, 6.0, 7.0, 8.0, 9.0, 10.0]);
        assert!(!port.is_closed());
        drop(w);
        assert!(port.is_closed());
    }

    #[test]
    fn bad_formats_and_chunks_are_clear_errors() {
        assert!(matches!(
            Port::<i32>::create(format(0, 2)),
            Err(Error::InvalidFormat(_))
        ));
        let mut w = Port::<i32>::create(format(2, 2)).expect("port");
        assert_eq!(
            w.publish(&[&[1, 2]]),
            Err(Error::ChannelCount {
                expected: 2,
                actual: 1
            })
        );
        let err = w.publish(&[&[1, 2, 3], &[1, 2, 3]]).expect_err("too long");
        assert!(err.to_string().contains("1..=2 frames"), "{err}");
        assert!(w.publish(&[&[1], &[1, 2]]).is_err());
        assert!(w.publish(&[&[], &[]]).is_err());
        assert_eq!(w.port().last_frame_index(), None, "nothing published");
    }

    #[test]
    fn numbering_may_start_anywhere() {
        let start = (1u64 << 32) - 2;
        let mut w = Port::<i32>::create_at(format(4, 2), start).expect("port");
        assert_eq!(w.port().last_frame_index(), Some(start - 1));
        w.publish(&[&[1, 2, 3, 4], &[5, 6, 7, 8]]).expect("publish");
        assert_eq!(w.port().last_frame_index(), Some((1 << 32) + 1));
        assert_eq!(w.port().snapshot().channels[0], [0, 0, 0, 0, 1, 2, 3, 4]);
    }
}
