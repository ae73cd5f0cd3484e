//! The processor contract shared by every AFE processor.

use crate::block::Block;

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
}
