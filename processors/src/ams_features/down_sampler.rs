//! The decimation before the modulation analysis (spec 31-downSampler): the samples whose
//! index in the stream is a multiple of `ams_dsRatio`, without an anti-aliasing filter.
//! Apart from the processor because its phase across chunks is a state of its own, tested
//! on its own.

/// Keeps the stream samples whose global index is a multiple of the ratio, whatever the
/// chunking (spec 31-downSampler).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct DownSampler {
    pub(super) ratio: usize,
    /// Index, in the next chunk, of its first sample to keep.
    pub(super) skip: usize,
}

impl DownSampler {
    /// Appends the kept rows (`width` values each) of `input` to `out` (cleared first).
    pub(super) fn run(&mut self, input: &[f64], width: usize, out: &mut Vec<f64>) {
        out.clear();
        let n = input.len() / width.max(1);
        if n <= self.skip {
            self.skip -= n;
            return;
        }
        let kept = (n - self.skip - 1) / self.ratio + 1;
        for i in 0..kept {
            let r = self.skip + i * self.ratio;
            out.extend_from_slice(&input[r * width..(r + 1) * width]);
        }
        self.skip = self.skip + kept * self.ratio - n;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn downsampling_keeps_multiples_of_the_ratio_whatever_the_chunking() {
        let mut d = DownSampler { ratio: 4, skip: 0 };
        let mut kept = Vec::new();
        let mut out = Vec::new();
        let mut start = 0;
        for len in [10, 1, 1, 3, 7, 0, 2, 9] {
            let x: Vec<f64> = (start..start + len).map(|i| i as f64).collect();
            d.run(&x, 1, &mut out);
            kept.extend_from_slice(&out);
            start += len;
        }
        let expect: Vec<f64> = (0..start).step_by(4).map(|i| i as f64).collect();
        assert_eq!(kept, expect);
    }
}
