//! Compute times of a stream's blocks in constant memory, however long the stream runs: a
//! log-spaced histogram for the percentiles, the exact maximum and which block took it,
//! and the indices of the first blocks that missed their deadline.

/// Histogram bins per decade: a percentile is the upper edge of its bin, at most
/// 10^(1/100) − 1 = 2.3 % above the true value (and never above the maximum).
const PER_DECADE: usize = 100;
/// Upper edge of the first bin, in s: faster blocks all land there.
const LOW_S: f64 = 1e-7;
/// Decades above [`LOW_S`] (up to 1000 s); slower blocks land in the last bin.
const DECADES: usize = 10;
/// How many missed blocks are named by index (the count goes on beyond).
pub const MISSED_KEPT: usize = 100;

/// Block compute times so far (see the module documentation).
#[derive(Debug, Clone)]
pub struct BlockTimes {
    counts: Box<[u64]>,
    blocks: u64,
    total_s: f64,
    max_s: f64,
    slowest: u64,
    misses: u64,
    missed: Vec<u64>,
}

impl Default for BlockTimes {
    fn default() -> Self {
        BlockTimes {
            counts: vec![0; PER_DECADE * DECADES + 1].into_boxed_slice(),
            blocks: 0,
            total_s: 0.0,
            max_s: 0.0,
            slowest: 0,
            misses: 0,
            missed: Vec::with_capacity(MISSED_KEPT),
        }
    }
}

/// The histogram bin of a compute time of `s` seconds.
fn bin(s: f64) -> usize {
    if s <= LOW_S {
        return 0;
    }
    let b = ((s / LOW_S).log10() * PER_DECADE as f64).ceil();
    (b as usize).min(PER_DECADE * DECADES)
}

/// Upper edge of bin `b`, in s.
fn upper_edge_s(b: usize) -> f64 {
    LOW_S * 10f64.powf(b as f64 / PER_DECADE as f64)
}

impl BlockTimes {
    /// Records the next block: `compute_s` seconds of compute for a block lasting
    /// `budget_s` seconds (a miss when it took longer). Does not allocate.
    pub fn record(&mut self, compute_s: f64, budget_s: f64) {
        self.counts[bin(compute_s)] += 1;
        if compute_s > self.max_s {
            self.max_s = compute_s;
            self.slowest = self.blocks;
        }
        if compute_s > budget_s {
            self.misses += 1;
            if self.missed.len() < MISSED_KEPT {
                self.missed.push(self.blocks);
            }
        }
        self.total_s += compute_s;
        self.blocks += 1;
    }

    /// Blocks recorded.
    pub fn blocks(&self) -> u64 {
        self.blocks
    }

    /// Total compute time, in s.
    pub fn total_s(&self) -> f64 {
        self.total_s
    }

    /// Longest compute time of a block, in s (0 before the first block).
    pub fn max_s(&self) -> f64 {
        self.max_s
    }

    /// Index (from 0) of the block that took [`BlockTimes::max_s`].
    pub fn slowest_block(&self) -> u64 {
        self.slowest
    }

    /// Blocks that took longer than they last.
    pub fn misses(&self) -> u64 {
        self.misses
    }

    /// Indices of the first [`MISSED_KEPT`] blocks that missed their deadline.
    pub fn missed_blocks(&self) -> &[u64] {
        &self.missed
    }

    /// The `p` quantile (0 < p ≤ 1) of the compute times, in s, rounded up to its bin's
    /// edge and capped at the maximum (0 before the first block).
    pub fn quantile_s(&self, p: f64) -> f64 {
        if self.blocks == 0 {
            return 0.0;
        }
        let rank = ((p * self.blocks as f64).ceil() as u64).clamp(1, self.blocks);
        let mut seen = 0;
        for (b, c) in self.counts.iter().enumerate() {
            seen += c;
            if seen >= rank {
                // the last bin is open-ended
                return match b == self.counts.len() - 1 {
                    true => self.max_s,
                    false => upper_edge_s(b).min(self.max_s),
                };
            }
        }
        self.max_s
    }

    /// The non-empty bins: (upper edge in ms, blocks), fastest first.
    pub fn histogram_ms(&self) -> Vec<(f64, u64)> {
        self.counts
            .iter()
            .enumerate()
            .filter(|(_, c)| **c > 0)
            .map(|(b, c)| (upper_edge_s(b) * 1e3, *c))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Quantiles are within one bin (2.3 %) above the sorted-list value and never above
    /// the maximum; misses are counted and named; the maximum names its block.
    #[test]
    fn quantiles_maximum_and_misses() {
        let mut t = BlockTimes::default();
        let times: Vec<f64> = (1..=1000).map(|i| i as f64 * 1e-5).collect();
        for (i, s) in times.iter().enumerate() {
            let s = if i == 700 { 0.5 } else { *s };
            t.record(s, 0.009005);
        }
        let mut sorted = times.clone();
        sorted[700] = 0.5;
        sorted.sort_by(f64::total_cmp);
        for p in [0.01, 0.5, 0.9, 0.99] {
            let exact = sorted[(p * 1000.0_f64).ceil() as usize - 1];
            let q = t.quantile_s(p);
            // (a time on a bin edge may sit one rounding below it)
            assert!(
                q >= exact * (1.0 - 1e-12) && q <= exact * 1.024,
                "p {p}: {q} vs {exact}"
            );
        }
        assert_eq!(t.quantile_s(1.0), 0.5);
        assert_eq!((t.max_s(), t.slowest_block()), (0.5, 700));
        // a 9-ms budget: blocks 900.. miss (10 µs per index), and block 700
        assert_eq!(t.misses(), 101);
        assert_eq!(t.missed_blocks().len(), MISSED_KEPT);
        assert_eq!(&t.missed_blocks()[..2], &[700, 900]);
        assert_eq!(t.histogram_ms().iter().map(|b| b.1).sum::<u64>(), 1000);
        assert!((t.total_s() - (sorted.iter().sum::<f64>())).abs() < 1e-9);
    }

    #[test]
    fn extremes_land_in_the_end_bins() {
        let mut t = BlockTimes::default();
        assert_eq!(t.quantile_s(0.5), 0.0);
        t.record(0.0, 1.0);
        t.record(1e6, 1.0);
        let h = t.histogram_ms();
        assert_eq!((h.len(), h[0].1, h[1].1), (2, 1, 1));
        assert_eq!(t.quantile_s(0.5), LOW_S);
        assert_eq!(t.quantile_s(1.0), 1e6);
    }
}
