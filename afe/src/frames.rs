//! One block's new frames of every signal of a stream, as a local stream's observer and
//! a remote subscription both yield them.

use afe_graph::{Manager, Signal};

use crate::stream::Timing;

/// One signal's new frames in a block.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameBlock {
    /// Output name, as `afe extract` names it (e.g. `ratemap_left`).
    pub key: String,
    /// Index of the first new frame among all the frames of the signal.
    pub first_frame: u64,
    /// Shape of one frame (e.g. `[channels]`, `[channels, lags]`).
    pub frame_shape: Vec<usize>,
    /// Whether values are complex (pairs of real, imaginary in `values`).
    pub complex: bool,
    /// New frames.
    pub rows: usize,
    /// The values, time-major.
    pub values: Vec<f64>,
}

/// The new frames of one block of the server's stream.
#[derive(Debug, Clone, PartialEq)]
pub struct Frames {
    /// Message number of the subscription, from 0.
    pub seq: u64,
    /// Index of the block's first frame on the server's port.
    pub first_input_frame: u64,
    /// Frames in the block.
    pub input_frames: usize,
    /// Unix time in ns at which the block's last frame was on the server's port.
    pub t_ns: u64,
    /// Messages lost just before this one.
    pub lost_messages: u64,
    /// Each signal's new frames, in the subscription's order.
    pub signals: Vec<FrameBlock>,
}

impl FrameBlock {
    /// A signal's new frames after the last block.
    pub fn of(s: &Signal<'_>) -> Self {
        FrameBlock {
            key: s.key(),
            first_frame: s.first_frame,
            frame_shape: s.info.frame_shape(),
            complex: s.info.is_complex(),
            rows: s.new.frames(),
            values: s.new.as_slice().to_vec(),
        }
    }
}

impl Frames {
    /// The block a stream just computed: the new frames of every signal the graph shows,
    /// with `seq` as its number (the block's, from 0).
    ///
    /// ```
    /// use afe::frames::Frames;
    /// use afe::stream::{run, StreamJob, Timing};
    /// use afe_bass_source::Synth;
    /// let job = StreamJob { requests: vec!["ild".into()], duration_s: Some(0.1), ..StreamJob::default() };
    /// let mut blocks = Vec::new();
    /// let mut seq = 0;
    /// let observe = |t: &Timing, mgr: &mut afe::Manager, _: &[Vec<f64>]| {
    ///     blocks.push(Frames::capture(seq, t, mgr));
    ///     seq += 1;
    /// };
    /// run(Synth::parse("fs=16000,tone=1000")?, &job, afe::stream::Blocks(observe))?;
    /// assert_eq!(blocks.len(), 10);
    /// assert_eq!(blocks[3].first_input_frame, 480);
    /// assert_eq!(blocks[3].signals[0].key, "ild_mono");
    /// # Ok::<(), afe::stream::StreamError>(())
    /// ```
    pub fn capture(seq: u64, timing: &Timing, mgr: &Manager) -> Self {
        let signals: Vec<FrameBlock> = mgr.signals(false).iter().map(FrameBlock::of).collect();
        let input_frames = timing.last_block_frames();
        Frames {
            seq,
            first_input_frame: timing.input_end() - input_frames as u64,
            input_frames,
            t_ns: timing.block_end_unix_ns(),
            lost_messages: 0,
            signals,
        }
    }
}
