//! A remote server's raw audio as a local source: `afe stream --source zenoh:ENDPOINT`
//! runs a local graph on what the server's port publishes.

use std::time::Duration;

use afe::stream::{Observer, SourceSpec, StreamError, StreamJob, Streamed};
use afe_bass_source::{Clock, PortFormat, Source};
use zenoh::handlers::FifoChannelHandler;
use zenoh::pubsub::Subscriber;
use zenoh::sample::Sample;
use zenoh::Wait;

use super::client::Client;
use super::wire;
use super::{key, RemoteError};

/// How long a read waits for a block before checking that the server is still there.
const POLL: Duration = Duration::from_millis(100);

/// Opens the source `spec` names and streams it, as [`afe::stream::run_spec`] does, with
/// `zenoh:ENDPOINT[@NAME]` sources opened here.
pub fn run_spec(
    spec: &SourceSpec,
    job: &StreamJob,
    on_block: impl Observer,
) -> Result<Streamed, StreamError> {
    match spec {
        SourceSpec::Zenoh { endpoint, name } => {
            let source = RemoteSource::connect(endpoint, name.as_deref())
                .map_err(|e| afe_bass_source::Error::Remote(e.to_string()))?;
            afe::stream::run(source, job, on_block)
        }
        other => afe::stream::run_spec(other, job, on_block),
    }
}

/// The audio blocks a server publishes, in order; a gap in their frame indices (blocks
/// lost on the way) counts as an overrun, as a device's would.
pub struct RemoteSource {
    client: Client,
    subscriber: Subscriber<FifoChannelHandler<Sample>>,
    format: PortFormat,
    /// Interleaved samples received and not read yet, and the read position in frames.
    pending: Vec<f64>,
    read: usize,
    next_frame: Option<u64>,
    overruns: u64,
    lost_frames: u64,
}

impl RemoteSource {
    /// Connects to the server at `endpoint` (`name` picks one when several answer) and
    /// subscribes to its audio.
    pub fn connect(endpoint: &str, name: Option<&str>) -> Result<RemoteSource, RemoteError> {
        let client = Client::connect(endpoint, name)?;
        let c = client.catalogue();
        let bad = |what: &str| RemoteError::Malformed(format!("catalogue without {what}"));
        let fs = c["fs_hz"].as_f64().ok_or_else(|| bad("fs_hz"))?;
        let ears = c["ears"].as_u64().ok_or_else(|| bad("ears"))? as usize;
        let block = c["block_frames"]
            .as_u64()
            .ok_or_else(|| bad("block_frames"))? as usize;
        if fs.fract() != 0.0 || !(1.0..=1e6).contains(&fs) || ears == 0 || block == 0 {
            return Err(RemoteError::Malformed(format!(
                "catalogue with fs_hz {fs}, ears {ears}, block_frames {block}"
            )));
        }
        let subscriber = client
            .session()
            .declare_subscriber(key(client.name(), "audio"))
            .wait()?;
        Ok(RemoteSource {
            format: PortFormat {
                sample_rate: fs as u32,
                channels: ears,
                frames_per_chunk: block,
                // at least a second of audio on the port
                chunks_on_port: (fs as usize).div_ceil(block).max(2),
            },
            client,
            subscriber,
            pending: Vec::new(),
            read: 0,
            next_frame: None,
            overruns: 0,
            lost_frames: 0,
        })
    }

    /// Frames lost on the way from the server so far.
    pub fn lost_frames(&self) -> u64 {
        self.lost_frames
    }

    /// Index on the server's port of the next frame this source gives.
    pub fn next_frame(&self) -> Option<u64> {
        self.next_frame
            .map(|n| n - (self.pending.len() / self.format.channels - self.read) as u64)
    }

    /// Waits for the next audio block; `false` when the server has gone.
    fn receive(&mut self) -> afe_bass_source::Result<bool> {
        let failed = afe_bass_source::Error::Remote;
        loop {
            match self.subscriber.recv_timeout(POLL) {
                Ok(Some(sample)) => {
                    let (h, samples) = wire::read_audio(&sample.payload().to_bytes())
                        .map_err(|e| failed(e.to_string()))?;
                    if h.count as usize != self.format.channels {
                        return Err(failed(format!(
                            "a block of {} channels from a server of {}",
                            h.count, self.format.channels
                        )));
                    }
                    if let Some(expected) = self.next_frame {
                        if h.first_input_frame > expected {
                            self.overruns += 1;
                            self.lost_frames += h.first_input_frame - expected;
                        }
                    }
                    self.next_frame = Some(h.first_input_frame + u64::from(h.input_frames));
                    self.pending = samples;
                    self.read = 0;
                    return Ok(true);
                }
                Ok(None) if self.client.server_gone() => return Ok(false),
                Ok(None) => {}
                Err(e) => return Err(failed(e.to_string())),
            }
        }
    }
}

impl Source for RemoteSource {
    type Sample = f64;

    fn format(&self) -> PortFormat {
        self.format
    }

    fn clock(&self) -> Clock {
        Clock::Device
    }

    fn read_chunk(
        &mut self,
        out: &mut [Vec<f64>],
        max_frames: usize,
    ) -> afe_bass_source::Result<usize> {
        let ch = self.format.channels;
        if self.read * ch >= self.pending.len() && !self.receive()? {
            return Ok(0);
        }
        let available = self.pending.len() / ch - self.read;
        let n = available.min(max_frames);
        for (c, o) in out.iter_mut().enumerate() {
            o.clear();
            o.extend((self.read..self.read + n).map(|t| self.pending[t * ch + c]));
        }
        self.read += n;
        Ok(n)
    }

    fn overruns(&self) -> u64 {
        self.overruns
    }
}
