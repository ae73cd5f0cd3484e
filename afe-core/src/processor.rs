//! The processor contract shared by every AFE processor, and the capabilities a processor
//! may add to it: taking a whole signal at once, receiving feedback, splitting its
//! channels across workers. The engine asks a processor for each capability it uses.

use crate::block::Block;
use crate::framing::FrameBuffer;

/// One share of a split processor (see [`ChannelSplit::split`]).
pub struct Part {
    /// Computes the share.
    pub processor: Box<dyn Processor>,
    /// Width of each of its output blocks (values per row).
    pub widths: Vec<usize>,
}

/// One node's computation: a pure function of its state and the new input of a chunk.
///
/// `inputs` holds the new input of this chunk, one block per parent output (one for a
/// mono processor, left then right for a binaural one). The processor replaces the
/// content of each of its `outputs` with its new output (which may be zero rows, e.g. a
/// framed processor that has not completed a frame yet). No I/O, threads or locks.
/// Steady state does not allocate: blocks and buffers keep their capacity.
pub trait Processor: Send {
    /// Processes the new input of one chunk.
    fn process(&mut self, inputs: &[&Block], outputs: &mut [Block]);

    /// Returns to the just-constructed state (coefficients are kept).
    fn reset(&mut self);

    /// Values this processor computes per second of signal beyond what its outputs and
    /// their windows show (the graph's work estimate counts each output value, and each
    /// input value a window spans once per frame): e.g. a bank of filters run on every
    /// channel before framing. 0 by default.
    fn hidden_work_per_second(&self) -> f64 {
        0.0
    }

    /// Its [`WholeSignal`] capability, if it has one; none by default.
    fn whole_signal(&mut self) -> Option<&mut dyn WholeSignal> {
        None
    }

    /// Its [`Feedback`] capability, if it has one; none by default.
    fn feedback(&mut self) -> Option<&mut dyn Feedback> {
        None
    }

    /// Its [`ChannelSplit`] capability, if it has one; none by default.
    fn channel_split(&mut self) -> Option<&mut dyn ChannelSplit> {
        None
    }
}

/// A processor whose output depends on chunk boundaries but which can take a whole
/// signal block by block ([`WholeSignal::absorb`], then one [`WholeSignal::finish`]) and
/// give the output of one call: the whole input then need not be joined first (pitch
/// reads 45 MB of autocorrelation per second).
pub trait WholeSignal {
    /// Takes the next block of a whole signal's input.
    fn absorb(&mut self, inputs: &[&Block]);

    /// Writes the output of one call over every block absorbed since the last `finish`.
    fn finish(&mut self, outputs: &mut [Block]);
}

/// A processor that takes the feedback output (see [`crate::SignalInfo::feedback`]) a
/// processor above it in the chain wrote in the previous chunk, before it processes the
/// next chunk (the MOC's gains for the DRNL, spec 28-moc). Without it the feedback is
/// ignored, as the gammatone filterbank ignores the MOC in the AFE.
pub trait Feedback {
    /// Takes the feedback (called only with a non-empty block); [`Processor::reset`]
    /// undoes what it changed.
    fn receive_feedback(&mut self, feedback: &Block);
}

/// A processor whose channels are computed independently, so that workers can compute
/// ranges of them at once. While its parts run, the processor runs as their
/// [`ChannelSplit::join`] instead of [`Processor::process`]; when the parts are dropped
/// (at any chunk boundary), it takes back what they hold of its state in
/// [`ChannelSplit::rejoin`].
pub trait ChannelSplit {
    /// Up to `parts` processors over consecutive channel ranges, each starting from this
    /// one's state, reading the same inputs and writing its channels' share of each
    /// output row (in order, the shares make the row); `None` where it does not split
    /// into more than one (too few channels, or itself a part).
    fn split(&self, parts: usize) -> Option<Vec<Part>>;

    /// The frame buffers a part holds of its processor's state (a windowed processor's
    /// history of its channels), for [`ChannelSplit::rejoin`]; none by default.
    fn part_frames(&mut self) -> &[FrameBuffer] {
        &[]
    }

    /// Takes back the frame buffers its parts (in order, from
    /// [`ChannelSplit::part_frames`]) held while they ran, before they are dropped:
    /// afterwards it processes as if it had never been split. By default nothing: a join
    /// that keeps the whole state current needs nothing back.
    fn rejoin(&mut self, _parts: &[&[FrameBuffer]]) {}

    /// With the new input of a chunk and its parts' outputs of that chunk (`parts[p]`:
    /// part `p`'s output blocks), writes the whole outputs and moves on what its parts do
    /// not hold of its state.
    fn join(&mut self, inputs: &[&Block], parts: &[&[Block]], outputs: &mut [Block]);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Implements only what every processor must.
    struct Plain;

    impl Processor for Plain {
        fn process(&mut self, _inputs: &[&Block], _outputs: &mut [Block]) {}
        fn reset(&mut self) {}
    }

    #[test]
    fn a_processor_has_no_capability_unless_it_says_so() {
        let mut p = Plain;
        assert!(p.whole_signal().is_none());
        assert!(p.feedback().is_none());
        assert!(p.channel_split().is_none());
        assert_eq!(p.hidden_work_per_second(), 0.0);
    }
}
