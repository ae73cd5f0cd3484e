//! The AFE framing rule (spec 00-overview §9): frames of `W` samples every `H` samples,
//! carried across chunks, with no padding and no flushing.

/// Buffer of not-yet-framed rows of a time-major signal.
///
/// Frame `j` of the stream always covers stream rows `[j·H, j·H + W)`, whatever the
/// chunking, which makes every framed processor chunk-invariant.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameBuffer {
    width: usize,
    window: usize,
    hop: usize,
    buf: Vec<f64>,
}

impl FrameBuffer {
    /// A buffer for rows of `width` values, frames of `window` rows every `hop` rows.
    ///
    /// # Panics
    /// If `hop` is zero or larger than `window`.
    pub fn new(width: usize, window: usize, hop: usize) -> Self {
        assert!(hop > 0 && hop <= window, "invalid framing {window}/{hop}");
        FrameBuffer {
            width,
            window,
            hop,
            buf: Vec::with_capacity(window * width * 2),
        }
    }

    /// Appends new rows (time-major, `width` values each).
    pub fn push(&mut self, rows: &[f64]) {
        debug_assert_eq!(rows.len() % self.width.max(1), 0);
        self.buf.extend_from_slice(rows);
    }

    /// Number of complete frames available: `max(0, floor((N − (W − H))/H))`.
    pub fn available(&self) -> usize {
        let n = self.buf.len() / self.width;
        let overlap = self.window - self.hop;
        if n < overlap {
            0
        } else {
            (n - overlap) / self.hop
        }
    }

    /// Frame `k` of the available ones: `window` rows, time-major.
    pub fn frame(&self, k: usize) -> &[f64] {
        let start = k * self.hop * self.width;
        &self.buf[start..start + self.window * self.width]
    }

    /// Drops the rows of the first `frames` frames' hops, keeping what later frames need.
    pub fn consume(&mut self, frames: usize) {
        let n = (frames * self.hop * self.width).min(self.buf.len());
        self.buf.copy_within(n.., 0);
        self.buf.truncate(self.buf.len() - n);
    }

    /// Empties the buffer.
    pub fn reset(&mut self) {
        self.buf.clear();
    }

    /// Frame length in rows.
    pub fn window(&self) -> usize {
        self.window
    }
}

/// Window length in samples, `2·round(w_size_s·fs/2)`, evaluated in that order.
pub fn window_samples(w_size_s: f64, fs: f64) -> usize {
    (2.0 * (w_size_s * fs / 2.0).round()).max(0.0) as usize
}

/// Hop length in samples, `round(h_size_s·fs)`.
pub fn hop_samples(h_size_s: f64, fs: f64) -> usize {
    (h_size_s * fs).round().max(0.0) as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_follow_the_stream_whatever_the_chunking() {
        let x: Vec<f64> = (0..23).map(f64::from).collect();
        let mut one = FrameBuffer::new(1, 6, 4);
        one.push(&x);
        let n = one.available();
        assert_eq!(n, (23 - 2) / 4);
        let whole: Vec<Vec<f64>> = (0..n).map(|k| one.frame(k).to_vec()).collect();
        let mut chunked = Vec::new();
        let mut fb = FrameBuffer::new(1, 6, 4);
        for part in x.chunks(3) {
            fb.push(part);
            let m = fb.available();
            chunked.extend((0..m).map(|k| fb.frame(k).to_vec()));
            fb.consume(m);
        }
        assert_eq!(whole, chunked);
        assert_eq!(whole[1], vec![4.0, 5.0, 6.0, 7.0, 8.0, 9.0]);
    }

    #[test]
    fn short_first_chunk_gives_no_frame() {
        let mut fb = FrameBuffer::new(2, 10, 4);
        fb.push(&[0.0; 2 * 5]);
        assert_eq!(fb.available(), 0);
    }

    #[test]
    fn lengths_use_matlab_rounding() {
        assert_eq!(window_samples(0.02, 44100.0), 882);
        assert_eq!(hop_samples(0.01, 22050.0), 221);
        assert_eq!(window_samples(0.02, 22050.0), 442);
    }
}
