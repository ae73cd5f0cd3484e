//! What every audio source offers: its port format and its chunks.

use crate::error::Result;
use crate::port::PortFormat;
use crate::sample::Sample;

/// Who sets the pace of a source.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Clock {
    /// The source makes its chunks on demand (files, synthesis): a
    /// [`Feeder`](crate::Feeder) paces them at real time, or runs as fast as asked.
    OnDemand,
    /// A device captures at its own rate (ALSA): reading blocks until a chunk is there.
    Device,
}

/// An audio source behind the port: WAV replay, synthesis, ALSA capture.
pub trait Source: Send {
    /// The samples it produces.
    type Sample: Sample;

    /// Rate, channels, frames per chunk and chunks on port of the port it feeds.
    fn format(&self) -> PortFormat;

    /// Who sets the pace.
    fn clock(&self) -> Clock;

    /// Replaces the content of `out` (one vector per channel) with the next chunk of at
    /// most `max_frames` frames, and returns its length in frames; 0 at the end of the
    /// stream. Reuses the vectors' capacity.
    fn read_chunk(&mut self, out: &mut [Vec<Self::Sample>], max_frames: usize) -> Result<usize>;

    /// Overruns so far: times the device captured frames the source did not read in
    /// time (those frames never reach the port). 0 for on-demand sources.
    fn overruns(&self) -> u64 {
        0
    }
}
