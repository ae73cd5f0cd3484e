//! The log bank's frame sums of `|w·x|`: over each windowed frame, or, for the default
//! rectangular window two hops long, from the sums of each hop. Apart from the processor
//! because both paths share one SIMD kernel and the hop sums keep a state of their own.

use afe_core::framing::Frame;

/// Frame sums for a rectangular window two hops long (the AFE's default), from the sums
/// of each hop's rows: frame `k` is hop `k`'s sum plus hop `k + 1`'s. Each row is summed
/// once and none is kept between chunks, where framing sums every row twice and copies
/// the rows of the next frame at each chunk. The values differ from one running sum over
/// the frame in rounding only (two partial sums added), and like it they do not depend on
/// the chunking.
#[derive(Debug, Clone)]
pub(super) struct HopSums {
    /// Rows per hop.
    pub(super) hop: usize,
    /// The sum of the current hop's rows so far, `[band][channel]`.
    current: Vec<f64>,
    /// How many rows `current` holds.
    rows: usize,
    /// The last complete hop's sum, valid once `has_last`.
    last: Vec<f64>,
    has_last: bool,
}

impl HopSums {
    pub(super) fn new(width: usize, hop: usize) -> Self {
        HopSums {
            hop,
            current: vec![0.0; width],
            rows: 0,
            last: vec![0.0; width],
            has_last: false,
        }
    }

    /// Frames completed by `rows` more rows.
    pub(super) fn frames_after(&self, rows: usize) -> usize {
        let hops = (self.rows + rows) / self.hop;
        (hops + usize::from(self.has_last)).saturating_sub(1)
    }

    /// Sums the rows of `banded` (`[time][band][channel]`) into hops, and writes each
    /// completed frame's sum divided by `w_len` into the rows of `out`
    /// (`[frame][channel][band]`, [`HopSums::frames_after`] of them). Allocates nothing.
    pub(super) fn run(
        &mut self,
        banded: &[f64],
        out: &mut [f64],
        (nc, nb): (usize, usize),
        w_len: f64,
    ) {
        let mut rows = banded.chunks_exact(self.current.len().max(1));
        let mut frames = out.chunks_exact_mut((nc * nb).max(1));
        loop {
            for row in rows.by_ref().take(self.hop - self.rows) {
                add_abs(&mut self.current, 1.0, row);
                self.rows += 1;
            }
            if self.rows < self.hop {
                return;
            }
            // the first hop completes no frame, so it takes no output row
            let frame = if self.has_last { frames.next() } else { None };
            if let Some(frame) = frame {
                let hops = self
                    .last
                    .chunks_exact(nc)
                    .zip(self.current.chunks_exact(nc));
                for (j, (a, b)) in hops.enumerate() {
                    for (c, (a, b)) in a.iter().zip(b).enumerate() {
                        frame[c * nb + j] = (a + b) / w_len;
                    }
                }
            }
            std::mem::swap(&mut self.current, &mut self.last);
            self.current.fill(0.0);
            self.has_last = true;
            self.rows = 0;
        }
    }

    pub(super) fn reset(&mut self) {
        self.current.fill(0.0);
        self.rows = 0;
        self.has_last = false;
    }
}

afe_core::simd_kernel!(
    fma,
    /// `acc += |w·row|`, element by element: one row of a frame's sums, weighted by its
    /// window value (the hop sums add whole rows with `w = 1`, which changes no bit).
    fn add_abs(acc: &mut [f64], w: f64, row: &[f64]) {
        for (a, v) in acc.iter_mut().zip(row) {
            *a += (w * v).abs();
        }
    }
);

/// Per column of `frame`, the sum over its rows of `|w·x|` with the window `win`, into `sums`.
pub(super) fn abs_sums(sums: &mut [f64], win: &[f64], frame: Frame<'_>) {
    sums.fill(0.0);
    for (w, z) in win.iter().zip(frame.rows()) {
        add_abs(sums, *w, z);
    }
}
