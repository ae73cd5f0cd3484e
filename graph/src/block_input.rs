//! The input of a whole-signal run in blocks: a signal held in memory, or one drawn block
//! by block from a source (a file decoded as it goes).

use afe_core::{Error, Result};

/// Input drawn block by block ([`crate::Manager::process_source`]): fills one vector per
/// ear (replacing their content) with up to the asked number of samples per ear and
/// returns how many it gave, 0 at the end.
pub type BlockSource<'a> = dyn FnMut(usize, &mut [Vec<f64>]) -> Result<usize> + 'a;

/// Where a run in blocks takes its next block from.
pub(crate) enum BlockInput<'s, 'a> {
    /// A signal in memory (one slice per ear), and the next sample to give.
    Signal(&'s [&'s [f64]], usize),
    /// A source, the vectors it fills, and a spare for a short read's remainder.
    Source(&'s mut BlockSource<'a>, Vec<Vec<f64>>, Vec<Vec<f64>>),
}

impl<'s, 'a> BlockInput<'s, 'a> {
    /// Input drawn from `source` for `ears` ears.
    pub(crate) fn source(source: &'s mut BlockSource<'a>, ears: usize) -> Self {
        BlockInput::Source(source, vec![Vec::new(); ears], vec![Vec::new(); ears])
    }

    /// The next block, one slice per ear: `samples` per ear, fewer only at the end of the
    /// input (a source's short reads are topped up), empty slices after it.
    pub(crate) fn next(&mut self, samples: usize) -> Result<Vec<&[f64]>> {
        match self {
            BlockInput::Signal(signal, pos) => {
                let start = *pos;
                let end = signal.first().map_or(0, |c| c.len()).min(start + samples);
                *pos = end;
                Ok(signal.iter().map(|c| &c[start..end]).collect())
            }
            BlockInput::Source(next, block, spare) => {
                // the counts the source returns are what it gave, whatever it left behind
                let mut got = gave(next(samples, block)?, block)?;
                block.iter_mut().for_each(|b| b.truncate(got));
                while got > 0 && got < samples {
                    let more = gave(next(samples - got, spare)?, spare)?;
                    if more == 0 {
                        break;
                    }
                    for (b, s) in block.iter_mut().zip(spare.iter()) {
                        b.extend_from_slice(&s[..more]);
                    }
                    got += more;
                }
                Ok(block.iter().map(Vec::as_slice).collect())
            }
        }
    }
}

/// The count a source returned, checked against the vectors it filled: each must hold at
/// least that many samples.
fn gave(count: usize, filled: &[Vec<f64>]) -> Result<usize> {
    match filled.iter().map(Vec::len).min() {
        Some(len) if len < count => Err(Error::InvalidInput(format!(
            "the input source said it gave {count} samples per ear but filled only {len}"
        ))),
        _ => Ok(count),
    }
}

/// A source of `x`, the same on every ear, that gives at most `most` samples a call.
#[cfg(test)]
pub(crate) fn slice_source(
    x: &[f64],
    most: usize,
) -> impl FnMut(usize, &mut [Vec<f64>]) -> Result<usize> + '_ {
    let mut pos = 0;
    move |n, out| {
        let end = x.len().min(pos + n.min(most));
        for o in out.iter_mut() {
            o.clear();
            o.extend_from_slice(&x[pos..end]);
        }
        let got = end - pos;
        pos = end;
        Ok(got)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A source that gives at most three samples a call is drawn in full blocks all the
    /// same, and its last block holds what is left.
    #[test]
    fn short_reads_are_topped_up_to_full_blocks() {
        let x: Vec<f64> = (0..11).map(f64::from).collect();
        let mut source = slice_source(&x, 3);
        let mut input = BlockInput::source(&mut source, 2);
        let mut blocks = Vec::new();
        loop {
            let b = input.next(5).expect("block");
            assert_eq!(b.len(), 2, "one slice per ear");
            assert_eq!(b[0], b[1]);
            if b[0].is_empty() {
                break;
            }
            blocks.push(b[0].to_vec());
        }
        assert_eq!(blocks, [&x[..5], &x[5..10], &x[10..]]);
    }

    /// A source that leaves its last block in the vectors when it says it is done still
    /// ends the input (its count is what counts).
    #[test]
    fn the_end_is_where_the_source_says_it_is() {
        let mut calls = 0;
        let mut source = |n: usize, out: &mut [Vec<f64>]| {
            calls += 1;
            if calls > 1 {
                return Ok(0); // the vectors still hold the first block
            }
            out[0].clear();
            out[0].extend((0..n).map(|t| t as f64));
            Ok(n)
        };
        let mut input = BlockInput::source(&mut source, 1);
        assert_eq!(input.next(4).expect("block")[0].len(), 4);
        assert!(input.next(4).expect("end")[0].is_empty());
    }

    /// A source that says it gave more samples than it wrote is an error, not a short
    /// block (a short first block would seed the AGC on too few samples).
    #[test]
    fn a_source_that_overstates_its_count_is_refused() {
        let mut source = |_: usize, out: &mut [Vec<f64>]| {
            out.iter_mut().for_each(|o| *o = vec![0.5; 3]);
            Ok(5)
        };
        let mut input = BlockInput::source(&mut source, 2);
        let e = input.next(8).expect_err("overstated");
        assert!(
            e.to_string()
                .contains("gave 5 samples per ear but filled only 3"),
            "{e}"
        );
    }

    /// A signal in memory is cut into blocks of the asked sizes.
    #[test]
    fn a_signal_is_cut_into_the_asked_blocks() {
        let x: Vec<f64> = (0..7).map(f64::from).collect();
        let signal = [x.as_slice()];
        let mut input = BlockInput::Signal(&signal, 0);
        let sizes: Vec<usize> = [4, 1, 4, 4]
            .iter()
            .map(|&n| input.next(n).expect("block")[0].len())
            .collect();
        assert_eq!(sizes, [4, 1, 2, 0]);
    }
}
