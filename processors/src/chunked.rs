//! Test support: feeding a processor its input in chunks, as a stream would.

use afe_core::{Block, Processor};

/// Runs `p` over `x` (rows of `width` values) cut into chunks of the row counts that
/// `chunks` yields, until the input is used up (a chunk may be empty), and returns its
/// outputs (`out_width` values per row) joined.
pub(crate) fn feed<P: Processor>(
    p: &mut P,
    x: &[f64],
    width: usize,
    out_width: usize,
    chunks: impl IntoIterator<Item = usize>,
) -> Vec<f64> {
    let rows = x.len() / width;
    let mut out = vec![Block::new(out_width)];
    let mut all = Vec::new();
    let mut start = 0;
    for n in chunks {
        if start >= rows {
            break;
        }
        let end = start.saturating_add(n).min(rows);
        let block = Block::from_vec(x[start * width..end * width].to_vec(), width);
        p.process(&[&block], &mut out);
        all.extend_from_slice(out[0].as_slice());
        start = end;
    }
    all
}
