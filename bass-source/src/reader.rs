//! The block reader of BASS clients (BASC's `getAudioData`): contiguous frames from a
//! next-frame index, and an exact count of the frames lost when the reader fell behind.

use std::sync::Arc;

use crate::error::{Error, Result};
use crate::port::Port;
use crate::sample::Sample;

/// What one call of [`get_audio_data`] got.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Fetch {
    /// Frames copied to the front of every destination slice (n ≤ N); they are the
    /// frames `[nfr − n, nfr)` of the updated next-frame index `nfr`.
    pub frames: usize,
    /// Frames skipped before them because the writer had overwritten them (the reader
    /// was more than the port's length behind, or was lapped during its copy).
    pub lost: u64,
}

/// BASC's `getAudioData`: copies up to N frames (N = the shortest destination slice; one
/// slice per channel) starting at the next-frame index `*nfr`, and advances `*nfr`.
///
/// - Frames not published yet are not waited for: the call returns the n < N frames it
///   has (0 when `*nfr` is beyond the last frame index), and a later call continues.
/// - At most the port's length is returned at once: N larger than the port fills over
///   several calls.
/// - When `*nfr` is older than the oldest frame on the port, the reader restarts at the
///   oldest and reports `oldest − nfr` lost frames. If the writer overwrites frames
///   while they are being copied, those are lost too and never returned: every frame is
///   either returned once or counted as lost once.
///
/// ```
/// use afe_bass_source::{get_audio_data, Port, PortFormat};
/// let format = PortFormat { sample_rate: 8000, channels: 1, frames_per_chunk: 2, chunks_on_port: 2 };
/// let mut w = Port::<i32>::create(format)?;
/// let port = w.port();
/// for k in 0..3 {
///     w.publish(&[&[2 * k, 2 * k + 1]])?; // frames 0..6; the port keeps 2..6
/// }
/// let (mut nfr, mut block) = (0, [0; 3]);
/// let fetch = get_audio_data(&port, &mut [&mut block[..]], &mut nfr)?;
/// assert_eq!((fetch.frames, fetch.lost, nfr, block), (3, 2, 5, [2, 3, 4]));
/// let fetch = get_audio_data(&port, &mut [&mut block[..]], &mut nfr)?;
/// assert_eq!((fetch.frames, fetch.lost, nfr, block[0]), (1, 0, 6, 5));
/// # Ok::<(), afe_bass_source::Error>(())
/// ```
pub fn get_audio_data<S: Sample>(
    port: &Port<S>,
    dest: &mut [&mut [S]],
    nfr: &mut u64,
) -> Result<Fetch> {
    if dest.len() != port.channels() {
        return Err(Error::ChannelCount {
            expected: port.channels(),
            actual: dest.len(),
        });
    }
    let want = dest.iter().map(|d| d.len()).min().unwrap_or(0);
    let cap = port.capacity() as u64;
    let mut lost = 0;
    loop {
        let published = port.frames_published();
        let oldest = published.saturating_sub(cap);
        if *nfr < oldest {
            lost += oldest - *nfr;
            *nfr = oldest;
        }
        let n = want.min(published.saturating_sub(*nfr) as usize);
        if n == 0 {
            return Ok(Fetch { frames: 0, lost });
        }
        for (c, d) in dest.iter_mut().enumerate() {
            port.copy(c, *nfr, &mut d[..n]);
        }
        let intact = port.intact_from();
        if intact <= *nfr {
            *nfr += n as u64;
            return Ok(Fetch { frames: n, lost });
        }
        // The writer lapped this copy: frames below `intact` may be torn.
        let skip = intact - *nfr;
        if skip < n as u64 {
            let skip = skip as usize;
            for d in dest.iter_mut() {
                d.copy_within(skip..n, 0);
            }
            lost += skip as u64;
            *nfr += n as u64;
            return Ok(Fetch {
                frames: n - skip,
                lost,
            });
        }
        lost += skip;
        *nfr = intact;
    }
}

/// A client of a port: [`get_audio_data`] with its own next-frame index.
#[derive(Debug, Clone)]
pub struct Reader<S: Sample> {
    port: Arc<Port<S>>,
    nfr: u64,
}

impl<S: Sample> Reader<S> {
    /// A reader whose first frame is `start_offset` frames after the next frame to be
    /// published (BASC's `startOffs`: `nfr = startOffs + lastFrameIndex + 1`): 0 = the
    /// next frame, negative = frames already on the port (older than the port's oldest:
    /// reported lost by the first read), positive = a frame in the future. Frame indices
    /// below 0 (before the acquisition started) are skipped, not counted as lost.
    pub fn new(port: Arc<Port<S>>, start_offset: i64) -> Self {
        let next = port.frames_published();
        let nfr = if start_offset < 0 {
            next.saturating_sub(start_offset.unsigned_abs())
        } else {
            next.saturating_add(start_offset.unsigned_abs())
        };
        Reader { port, nfr }
    }

    /// The port read.
    pub fn port(&self) -> &Arc<Port<S>> {
        &self.port
    }

    /// Index of the next frame this reader will return (BASC's `nfr`).
    pub fn next_frame(&self) -> u64 {
        self.nfr
    }

    /// Copies up to N frames, one destination slice per channel: see [`get_audio_data`].
    pub fn read(&mut self, dest: &mut [&mut [S]]) -> Result<Fetch> {
        get_audio_data(&self.port, dest, &mut self.nfr)
    }

    /// Whether the stream is over for this reader: the writer is gone and every frame it
    /// published was returned or counted as lost.
    pub fn at_end(&self) -> bool {
        self.port.is_closed() && self.nfr >= self.port.frames_published()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::port::{PortFormat, PortWriter};

    fn value(frame: u64, channel: usize) -> f64 {
        frame as f64 + 0.5 * channel as f64
    }

    fn port(frames_per_chunk: usize, chunks_on_port: usize, first: u64) -> PortWriter<f64> {
        let format = PortFormat {
            sample_rate: 8000,
            channels: 2,
            frames_per_chunk,
            chunks_on_port,
        };
        Port::create_at(format, first).expect("port")
    }

    /// Publishes the next `frames` frames of the pattern.
    fn publish(w: &mut PortWriter<f64>, frames: usize) {
        let first = w.port().frames_published();
        let ch: Vec<Vec<f64>> = (0..2)
            .map(|c| (0..frames as u64).map(|i| value(first + i, c)).collect())
            .collect();
        w.publish(&[&ch[0], &ch[1]]).expect("publish");
    }

    /// Reads up to `n` frames and checks they are the pattern's frames `[nfr − got, nfr)`.
    fn read(r: &mut Reader<f64>, n: usize) -> Fetch {
        let (mut l, mut rr) = (vec![f64::NAN; n], vec![f64::NAN; n]);
        let f = r.read(&mut [&mut l, &mut rr]).expect("read");
        let first = r.next_frame() - f.frames as u64;
        for i in 0..f.frames {
            assert_eq!(l[i], value(first + i as u64, 0));
            assert_eq!(rr[i], value(first + i as u64, 1));
        }
        f
    }

    #[test]
    fn a_reader_ahead_of_the_writer_gets_nothing_then_completes() {
        let mut w = port(4, 3, 0);
        publish(&mut w, 4);
        let mut r = Reader::new(w.port(), 2); // frame 6, two frames in the future
        assert_eq!(r.next_frame(), 6);
        assert_eq!(read(&mut r, 5), Fetch { frames: 0, lost: 0 });
        publish(&mut w, 4); // frames 4..8: 6 and 7 are there
        assert_eq!(read(&mut r, 5), Fetch { frames: 2, lost: 0 });
        publish(&mut w, 4);
        assert_eq!(read(&mut r, 3), Fetch { frames: 3, lost: 0 });
        assert_eq!(r.next_frame(), 11);
    }

    #[test]
    fn a_block_longer_than_the_port_fills_over_several_calls() {
        let mut w = port(4, 2, 0); // 8 frames on the port
        let mut r = Reader::new(w.port(), 0);
        let mut remaining = 20; // BASC's loop: N -= n until the block is complete
        let mut calls = 0;
        while remaining > 0 {
            publish(&mut w, 4);
            publish(&mut w, 4);
            let f = read(&mut r, remaining);
            assert_eq!(f.lost, 0);
            assert!(f.frames <= 8, "never more than the port: {}", f.frames);
            remaining -= f.frames;
            calls += 1;
        }
        assert_eq!((calls, r.next_frame()), (3, 20));
    }

    #[test]
    fn a_slow_reader_gets_every_frame_once_or_counts_it_lost() {
        let mut w = port(5, 3, 0);
        let mut r = Reader::new(w.port(), 0);
        let (mut got, mut lost) = (0u64, 0u64);
        // Injected delays: the reader reads 7 frames after every 0..=6 chunks.
        for step in 0..500u64 {
            for _ in 0..step % 7 {
                publish(&mut w, 5);
            }
            let f = read(&mut r, 7);
            got += f.frames as u64;
            lost += f.lost;
        }
        drop(w);
        while !r.at_end() {
            let f = read(&mut r, 7);
            got += f.frames as u64;
            lost += f.lost;
        }
        let published = r.port().frames_published();
        assert!(lost > 0, "the reader should have fallen behind");
        assert_eq!(published - got - lost, 0);
    }

    #[test]
    fn start_offsets_reach_into_the_past() {
        let mut w = port(4, 2, 0);
        for _ in 0..5 {
            publish(&mut w, 4); // frames 0..20, the port keeps 12..20
        }
        let mut r = Reader::new(w.port(), -3);
        assert_eq!(read(&mut r, 10), Fetch { frames: 3, lost: 0 });
        let mut r = Reader::new(w.port(), -11); // frame 9: 3 frames older than the port
        assert_eq!(read(&mut r, 10), Fetch { frames: 8, lost: 3 });
        let r = Reader::new(w.port(), -100); // before the start of the acquisition
        assert_eq!(r.next_frame(), 0);
    }

    #[test]
    fn the_frame_index_crosses_two_to_the_32() {
        let start = (1u64 << 32) - 10;
        let mut w = port(4, 3, start);
        let mut r = Reader::new(w.port(), 0);
        for _ in 0..5 {
            publish(&mut w, 4);
        }
        assert_eq!(w.port().last_frame_index(), Some(start + 19));
        // 20 frames published, 12 on the port: 8 lost across 2^32
        assert_eq!(
            read(&mut r, 100),
            Fetch {
                frames: 12,
                lost: 8
            }
        );
        assert_eq!(r.next_frame(), (1 << 32) + 10);
        publish(&mut w, 3);
        assert_eq!(read(&mut r, 100), Fetch { frames: 3, lost: 0 });
        let snap = r.port().snapshot();
        assert_eq!(snap.last_frame_index, Some((1 << 32) + 12));
        assert_eq!(snap.channels[0][11], value((1 << 32) + 12, 0));
    }

    #[test]
    fn destinations_must_match_the_channels() {
        let w = port(4, 2, 0);
        let mut r = Reader::new(w.port(), 0);
        let mut one = [0.0; 4];
        assert!(matches!(
            r.read(&mut [&mut one]),
            Err(Error::ChannelCount {
                expected: 2,
                actual: 1
            })
        ));
    }
}
