//! The processor contract shared by every AFE processor.

use crate::block::Block;

/// One share of a split processor (see [`Processor::split`]).
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

    /// Whether this processor, though its output depends on chunk boundaries, can take a
    /// whole signal block by block ([`Processor::absorb`], then one
    /// [`Processor::finish`]) and give the output of one call: the whole input then
    /// need not be joined first (pitch reads 45 MB of autocorrelation per second).
    fn absorbs_whole_signal(&self) -> bool {
        false
    }

    /// Takes the next block of a whole signal's input, where
    /// [`Processor::absorbs_whole_signal`].
    fn absorb(&mut self, _inputs: &[&Block]) {}

    /// Writes the output of one call over every block absorbed since the last `finish`.
    fn finish(&mut self, _outputs: &mut [Block]) {}

    /// Takes the feedback output (see [`crate::SignalInfo::feedback`]) that a processor
    /// above this one in the chain wrote in the previous chunk, before this one
    /// processes the next chunk (the MOC's gains for the DRNL, spec 28-moc). Called only
    /// with a non-empty block; ignored by default, as the gammatone filterbank ignores
    /// the MOC in the AFE. [`Processor::reset`] undoes what it changed.
    fn receive_feedback(&mut self, _feedback: &Block) {}

    /// For a processor whose channels are computed independently: up to `parts`
    /// processors over consecutive channel ranges, each starting from this one's state,
    /// reading the same inputs and writing its channels' share of each output row (in
    /// order, the shares make the row). `None` where the processor does not split.
    /// While its parts run, this processor runs as their [`Processor::join`] instead of
    /// [`Processor::process`]; when the parts are dropped (at any chunk boundary), it takes
    /// back what they hold of its state in [`Processor::rejoin`].
    fn split(&self, _parts: usize) -> Option<Vec<Part>> {
        None
    }

    /// The frame buffers a part holds of its processor's state (a windowed processor's
    /// history of its channels), for [`Processor::rejoin`]; none by default.
    fn part_frames(&self) -> &[crate::framing::FrameBuffer] {
        &[]
    }

    /// Takes back the state its parts (in order) held while they ran, before they are
    /// dropped: afterwards it processes as if it had never been split. By default nothing:
    /// a join that keeps the whole state current needs nothing back.
    fn rejoin(&mut self, _parts: &[&dyn Processor]) {}

    /// With the new input of a chunk and its parts' outputs of that chunk (`parts[p]`:
    /// part `p`'s output blocks), writes the whole outputs and moves on what its parts do
    /// not hold of its state. Called only on a processor whose [`Processor::split`] gave
    /// parts.
    fn join(&mut self, _inputs: &[&Block], _parts: &[&[Block]], _outputs: &mut [Block]) {}
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
    fn a_processor_neither_absorbs_nor_splits_unless_it_says_so() {
        let p = Plain;
        assert!(!p.absorbs_whole_signal());
        assert!(p.split(2).is_none());
        assert!(p.part_frames().is_empty());
    }
}
